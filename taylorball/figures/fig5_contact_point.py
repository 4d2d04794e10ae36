"""Fig. 5: contact-point trajectories of the asymmetric ball for the parameters of Fig. 4
(I = (2, 3, 4), m = 1, a = 5, Omega = 2, h = 5, G = 10; H = 2 and H = 6).

The paper: the trajectories are bounded, lie between two circles and look quasi-periodic
even when the reduced orbit is chaotic (Fig. 4a). For each H, orbits on the section are
screened by MEGNO; the most chaotic one (H = 2) and the most regular one (H = 6) are
followed, (x, y) from the reduced solution (x = (alpha, R), y = (beta, R) in the frame with
F1 = 0). Reported: the two circles (the smallest enclosing one and the largest empty one in
the hole, each with its own centre: taylorball.contact.bounding_circles), and
the rigorous bound |R| <= radius_bound(C, h) from the Jacobi integral
(taylorball.contact.radius_bound).

Run: ``python studies/fig5_contact_point.py [--full]``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from ..paper import FIG5A_LEVELS, FIG5B_LEVELS
from . import _common as C


@dataclass(frozen=True)
class Config(C.BallCaption):
    H: tuple = (FIG5A_LEVELS.M_gamma, FIG5B_LEVELS.M_gamma)
    n_candidates: int = 8
    megno_t: float = 200.0
    contact_t: float = 500.0
    contact_dt: float = 0.05
    seed: int = 0


QUICK = Config()
FULL = Config(n_candidates=30, megno_t=1000.0, contact_t=5000.0, megno_compact=False,
              megno_jacobian=C.FULL_MEGNO_JACOBIAN)


def compute(cfg):
    from taylorball.contact import bounding_circles, contact_trajectory, radius_bound

    p = cfg.ball()
    arrays, meta = {}, {"panels": {}}
    t = np.linspace(0.0, cfg.contact_t, int(round(cfg.contact_t / cfg.contact_dt)) + 1)
    for tag, H in zip("ab", cfg.H):
        levels = cfg.levels(H)
        states, _, _ = C.reduced_initial_states(p, **levels.as_kwargs(), n=cfg.n_candidates, seed=cfg.seed)
        Y, T = C.megno_many("reduced", p, states, cfg.megno_t, cfg.megno_compact, jacobian=cfg.megno_jacobian)
        k = C.most_chaotic(Y, T) if tag == "a" else int(np.argmin(Y))
        ct = contact_trajectory(p, states[k], t)
        bc = bounding_circles(ct.xy)
        arrays[f"{tag}_xy"] = ct.xy
        arrays[f"{tag}_megno"] = Y
        meta["panels"][tag] = dict(H=H, orbit=k, megno=float(Y[k]), megno_t=float(T[k]),
                                   inner_centre=bc["inner_centre"].tolist(), r_inner=bc["r_inner"],
                                   outer_centre=bc["outer_centre"].tolist(), r_outer=bc["r_outer"],
                                   r_axis_max=float(np.max(np.hypot(*ct.xy.T))),
                                   radius_bound=radius_bound(p, levels.C, levels.h))
    arrays["t"] = t
    return arrays, meta


def plot(arrays, meta, outdir):
    plt = C.pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2))
    for ax, tag in zip(axes, "ab"):
        m = meta["panels"][tag]
        # one colour for one meaning, as in every figure: the orbit's MEGNO class
        C.plot_contact(ax, arrays[f"{tag}_xy"], [(m[f"{w}_centre"], m[f"r_{w}"]) for w in ("inner", "outer")],
                       color=C.CHAOTIC_COLOR if m["megno"] > C.CHAOTIC_MEGNO else C.REGULAR_COLOR, lw=0.3)
        cls = "chaotic" if m["megno"] > C.CHAOTIC_MEGNO else "regular"
        ax.set_title(rf"({tag}) $H = {m['H']:g}$: a {cls} orbit, MEGNO $\langle Y\rangle$ = {m['megno']:.1f} at "
                     f"$t$ = {m['megno_t']:g}; $t \\leq$ {arrays['t'][-1]:g}\n"
                     f"between circles $r$ = {m['r_inner']:.4g} about ({m['inner_centre'][0]:.2f}, "
                     f"{m['inner_centre'][1]:.2f})\nand $r$ = {m['r_outer']:.4g} about ({m['outer_centre'][0]:.2f}, "
                     f"{m['outer_centre'][1]:.2f})")
    fig.suptitle(r"Fig. 5: contact point of the asymmetric ball $I = (2, 3, 4)$, $m = 1$, $a = 5$, $h = 5$, $G = 10$, "
                 r"$\Omega = 2$", y=1.05)
    return C.save_figure(fig, outdir, "fig5_contact_point", meta)


if __name__ == "__main__":
    from .runner import main

    sys.exit(main(sys.modules[__name__]))
