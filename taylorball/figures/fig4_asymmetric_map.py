"""Fig. 4: the 3D Poincaré map (l, r1, r2) of a dynamically asymmetric ball (I = (2, 3, 4),
m = 1, a = 5, Omega = 2) on the levels h = 5, G = 10 with (a) H = 2: a chaotic trajectory,
so two additional integrals are absent; (b) H = 6: invariant tori. Measured: at H = 2 every
sampled orbit belongs to one chaotic sea (MEGNO ~50 at t = 1000); at H = 6 the map is mixed,
about half the orbits on invariant tori (MEGNO -> 2) and half in chaotic layers between them.

Each panel: a 3D scatter and its three 2D projections; orbits with MEGNO <Y> > 4 (measured
with the variational equations) are drawn in black, regular ones in colour. The chart is
the paper's section-4 chart; K comes from the energy equation (all roots, branch dg/dt > 0).

Run: ``python studies/fig4_asymmetric_map.py [--full]``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from ..paper import FIG4A_LEVELS, FIG4B_LEVELS
from . import _common as C


@dataclass(frozen=True)
class Config(C.BallCaption):
    H: tuple = (FIG4A_LEVELS.M_gamma, FIG4B_LEVELS.M_gamma)
    n_orbits: int = 10
    n_points: int = 400
    megno_t: float = 500.0  # the weaker chaos of H = 6 needs t ~ 500 to separate from tori
    seed: int = 0


QUICK = Config()
FULL = Config(n_orbits=40, n_points=5000, megno_t=1000.0, megno_compact=False)


def compute(cfg):
    p = cfg.ball()
    arrays, meta = {}, {"panels": {}}
    for tag, H in zip("ab", cfg.H):
        states, starts, region = C.reduced_initial_states(p, **cfg.levels(H).as_kwargs(), n=cfg.n_orbits,
                                                          seed=cfg.seed)
        a, m = C.map_orbits("reduced", p, states, n_points=cfg.n_points, megno_t=cfg.megno_t,
                            megno_compact=cfg.megno_compact)
        arrays.update({f"{tag}_{k}": v for k, v in a.items()})
        arrays[f"{tag}_start_points"] = starts
        m.update(H=H, admissible_fraction=region["fraction"], r_box=region["r_box"],
                 n_chaotic=int(np.sum(a["orbit_megno"] > C.CHAOTIC_MEGNO)))
        meta["panels"][tag] = m
    return arrays, meta


def plot(arrays, meta, outdir):
    files = []
    for tag in "ab":
        m = meta["panels"][tag]
        fig = C.plot_map_3d(arrays[f"{tag}_points"], arrays[f"{tag}_orbit"], arrays.get(f"{tag}_orbit_megno"),
                            f"Fig. 4{tag}: asymmetric ball I=(2,3,4), m=1, a=5, H={m['H']:g}, h=5, G=10, Omega=2: "
                            f"{m['n_orbits']} orbits, {m['n_chaotic']} chaotic (black, MEGNO > {C.CHAOTIC_MEGNO:g})")
        files += C.save_figure(fig, outdir, f"fig4{tag}_asymmetric_map")
    return files


if __name__ == "__main__":
    from .runner import main

    sys.exit(main(sys.modules[__name__]))
