"""Shared body of Figs. 2 and 3: the 2D map (r1, r2) of a dynamically symmetric ball (l is
cyclic) and the contact point of one orbit."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..paper import FIG2_LEVELS
from . import _common as C


@dataclass(frozen=True)
class BallMapConfig(C.BallCaption):
    """Figs. 2 and 3: the caption, the number of orbits and points, MEGNO horizon, the
    contact-point run, and orbits seeded at chart points ``(l, r1, r2, root_index)``."""

    H: float = FIG2_LEVELS.M_gamma  # Figs. 2 and 3: H = 6
    n_orbits: int = 12
    n_points: int = 300
    megno_t: float = 200.0
    contact_t: float = 200.0
    contact_dt: float = 0.05
    seed: int = 0
    extra_points: tuple = ()


def compute_map_and_contact(cfg, pick="max_megno"):
    """Section map of ``cfg.n_orbits`` orbits and the contact point of one of them
    (``pick``: the orbit with the largest MEGNO, or the first one)."""
    from taylorball.contact import bounding_circles, contact_trajectory, fit_circle, radius_bound

    p = cfg.ball()
    levels = cfg.levels(cfg.H)
    states, starts, region = C.reduced_initial_states(p, **levels.as_kwargs(), n=cfg.n_orbits,
                                                      seed=cfg.seed, extra_points=cfg.extra_points)
    arrays, meta = C.map_orbits("reduced", p, states, n_points=cfg.n_points, megno_t=cfg.megno_t,
                                megno_compact=cfg.megno_compact)
    k = C.most_chaotic(arrays["orbit_megno"], arrays["orbit_megno_t"]) if pick == "max_megno" else 0
    t = np.linspace(0.0, cfg.contact_t, int(cfg.contact_t / cfg.contact_dt) + 1)
    ct = contact_trajectory(p, states[k], t)
    centre, r_fit = fit_circle(ct.xy)
    bc = bounding_circles(ct.xy)
    phase = np.unwrap(np.arctan2(ct.y - centre[1], ct.x - centre[0]))
    freq = float(np.polyfit(t, phase, 1)[0])
    arrays.update(start_points=starts, contact_t=t, contact_xy=ct.xy)
    meta.update(
        admissible_fraction=region["fraction"],
        r_box=region["r_box"],
        n_chaotic=int(np.sum(arrays["orbit_megno"] > C.CHAOTIC_MEGNO)),
        contact_orbit=k,
        contact_orbit_megno=float(arrays["orbit_megno"][k]),
        contact_orbit_megno_t=float(arrays["orbit_megno_t"][k]),
        contact_centre=centre.tolist(),
        contact_radius_fit=r_fit,
        contact_inner_centre=bc["inner_centre"].tolist(),
        contact_r_inner=bc["r_inner"],
        contact_outer_centre=bc["outer_centre"].tolist(),
        contact_r_outer=bc["r_outer"],
        contact_angular_frequency=freq,
        # Earnshaw's frequency Omega I / (I + m a^2) is a claim for the homogeneous ball only
        earnshaw_frequency=(cfg.plane_rate * cfg.inertia[0] / (cfg.inertia[0] + cfg.mass * cfg.radius**2)
                            if len(set(cfg.inertia)) == 1 else None),
        radius_bound=radius_bound(p, levels.C, levels.h),
    )
    return arrays, meta


def plot_map_and_contact(arrays, meta, outdir, stem, title):
    plt = C.pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 5))
    C.plot_map(a, arrays["points"], arrays["orbit"], (1, 2), arrays.get("orbit_megno"), size=1.0,
               labels=("$r_1$", "$r_2$"))
    a.set_title(f"(a) map (r1, r2), l cyclic: {meta['n_orbits']} orbits, {meta['n_chaotic']} chaotic (black)")
    a.set_aspect("equal", adjustable="datalim")
    C.plot_contact(b, arrays["contact_xy"],
                   [(meta[f"contact_{w}_centre"], meta[f"contact_r_{w}"]) for w in ("inner", "outer")])
    b.set_title(f"(b) contact point, orbit {meta['contact_orbit']} (MEGNO {meta['contact_orbit_megno']:.1f} at "
                f"t = {meta['contact_orbit_megno_t']:g}), "
                f"t <= {arrays['contact_t'][-1]:g}\nbetween circles r = {meta['contact_r_inner']:.4g} and "
                f"{meta['contact_r_outer']:.4g}")
    fig.suptitle(title)
    return C.save_figure(fig, outdir, stem)
