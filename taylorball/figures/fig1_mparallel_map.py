"""Fig. 1: the Poincaré map of the M||gamma system (paper eq. (22) [Mpn2]) on g = 0, in (l, L/G).

Caption: a1 = 1, a2 = 2, a3 = 3, d = 4, h = 100, lambda = 2, Omega = 0.5 (no real ball has
these values: I_i = 1/a_i - d < 0; the equations are integrated as given). The paper: "the
map exhibits chaotic trajectories and hence, in the general case, there is no additional
integral". Orbits start at chart points (l, L/G) spread over the section, G from the energy
equation (taylorball.charts.mparallel_states_on_section); orbits whose MEGNO exceeds 4 are
drawn in black. Random starts land on invariant curves; the chaos lives in the layer around
the separatrices through the hyperbolic points near (l, L/G) = (0, 0) and (pi, 0), so three
orbits are seeded there (measured: MEGNO 130-330 at t = 1000, Lyapunov exponent 0.3-0.6).

Run: ``python studies/fig1_mparallel_map.py [--full]``.
"""

from __future__ import annotations

import sys
import warnings
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..levels import MParallelLevels
from ..paper import FIG1_A, FIG1_D, FIG1_LEVELS, FIG1_PLANE_RATE
from . import _common as C


@dataclass(frozen=True)
class Config:
    """The caption (:mod:`taylorball.paper`), the number of orbits and points, MEGNO horizon,
    orbits seeded at chart points ``(l, L/G)``, and ``megno_compact``, the compile mode of the
    MEGNO tangent system (``None``: taylorball's choice by the amount of work, compact for the
    quick map: 0.4 s to compile against 9 s in default mode; the full map uses ``False``,
    default mode, kept in heyoka's disk cache, for 1.6x faster MEGNO on every run)."""

    a: tuple = FIG1_A
    d: float = FIG1_D
    plane_rate: float = FIG1_PLANE_RATE
    lam: float = FIG1_LEVELS.lam
    h: float = FIG1_LEVELS.h
    n_orbits: int = 16
    n_points: int = 400
    megno_t: float = 200.0
    seed: int = 1
    extra_points: tuple = ((0.0, 0.0), (3.141592653589793, 0.0), (3.141592653589793, 0.02))
    megno_compact: Optional[bool] = None
    megno_jacobian: str = C.QUICK_MEGNO_JACOBIAN


#: quick: MEGNO to t = 100, half the default's 200 (MEGNO is most of the figure's work): the
#: seeded orbits pass <Y> = 10 by t = 51 either way, the random ones read 1.2-2.3 at t = 100
#: (1.4-2.2 at 200), so the classes, and the image, are the same
QUICK = Config(megno_t=100.0)
# chaotic orbits here reach MEGNO ~90 by t = 300
FULL = Config(n_orbits=40, n_points=3000, megno_t=300.0, megno_compact=False,
              megno_jacobian=C.FULL_MEGNO_JACOBIAN)


def params(cfg):
    from ..params import MParallelParams, UnphysicalParametersWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnphysicalParametersWarning)
        return MParallelParams(a=cfg.a, d=cfg.d, plane_rate=cfg.plane_rate)


def compute(cfg):
    p = params(cfg)
    levels = MParallelLevels(lam=cfg.lam, h=cfg.h)
    states, starts, frac = C.mparallel_initial_states(p, **levels.as_kwargs(), n=cfg.n_orbits, seed=cfg.seed,
                                                     extra_points=cfg.extra_points)
    arrays, meta = C.map_orbits("mparallel", p, states, n_points=cfg.n_points, megno_t=cfg.megno_t,
                                megno_compact=cfg.megno_compact, megno_jacobian=cfg.megno_jacobian)
    arrays["start_points"] = starts
    meta.update(admissible_fraction=frac, physical=p.physical,
                n_chaotic=int(np.sum(arrays["orbit_megno"] > C.CHAOTIC_MEGNO)))
    return arrays, meta


def plot(arrays, meta, outdir):
    plt = C.pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    C.plot_map(ax, arrays["points"], arrays["orbit"], (0, 1), arrays.get("orbit_megno"), size=1.0,
               labels=C.AXIS_LABELS["mparallel"])
    cfg = meta["config"]
    ax.set_xlim(0, 2 * np.pi)
    ax.set_title(rf"Fig. 1: $M \parallel \gamma$ map, $a = {tuple(cfg['a'])}$, $d = {cfg['d']}$, $h = {cfg['h']}$, "
                 rf"$\lambda = {cfg['lam']}$, $\Omega = {cfg['plane_rate']}$" "\n"
                 f"{meta['n_orbits']} orbits, {meta['n_chaotic']} chaotic "
                 rf"(black, on top: MEGNO $\langle Y\rangle > {C.CHAOTIC_MEGNO:g}$)")
    return C.save_figure(fig, outdir, "fig1_mparallel_map", meta)


if __name__ == "__main__":
    from .runner import main

    sys.exit(main(sys.modules[__name__]))
