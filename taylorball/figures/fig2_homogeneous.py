"""Fig. 2: homogeneous ball (I1 = I2 = I3 = 3, m = 1, a = 5, Omega = 2) on the levels
H = (M, gamma) = 6, h = E = 5, G = |M| = 10: (a) the section map, foliated by invariant
curves; (b) the contact point, which moves on a circle (Earnshaw).

Reading of the caption: G = C = |M|, H = M_gamma = (M, gamma), h = the Jacobi integral E;
these levels are non-empty (the admissible region of the section is sampled first).
For the homogeneous ball l is cyclic (symmetry fields u_1, u_2, u_3), so the map is shown
in (r1, r2). Check (b) against Earnshaw: the centre of a homogeneous ball circles with
angular frequency Omega I / (I + m a^2) (= 3/14 here); the measured frequency and radius
are saved in the sidecar.

Run: ``python studies/fig2_homogeneous.py [--full]``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

from ..paper import FIG2_BALL, FIG2_LEVELS
from . import _common as C
from ._fig_ball_map import BallMapConfig, compute_map_and_contact, plot_map_and_contact


@dataclass(frozen=True)
class Config(BallMapConfig):
    inertia: tuple = FIG2_BALL.inertia
    H: float = FIG2_LEVELS.M_gamma
    megno_t: float = 200.0


QUICK = Config()
FULL = Config(n_orbits=50, n_points=3000, megno_t=1000.0, contact_t=2000.0, megno_compact=False,
              megno_jacobian=C.FULL_MEGNO_JACOBIAN)


def compute(cfg):
    return compute_map_and_contact(cfg, pick="first")


def plot(arrays, meta, outdir):
    return plot_map_and_contact(
        arrays, meta, outdir, "fig2_homogeneous",
        "Fig. 2: homogeneous ball $I = (3, 3, 3)$, $m = 1$, $a = 5$, $H = 6$, $h = 5$, $G = 10$, $\\Omega = 2$  "
        f"(Earnshaw frequency {meta['earnshaw_frequency']:.6f}, measured {meta['contact_angular_frequency']:.6f})")


if __name__ == "__main__":
    from .runner import main

    sys.exit(main(sys.modules[__name__]))
