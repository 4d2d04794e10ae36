"""Shared body of Figs. 2 and 3: the 2D map (r1, r2) of a dynamically symmetric ball (l is
cyclic) and the contact point of one orbit."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..paper import FIG2_LEVELS
from . import _common as C


@dataclass(frozen=True)
class BallMapConfig(C.BallCaption):
    """Figs. 2 and 3: the caption, the number of orbits and points, MEGNO horizon, the
    contact-point run, and orbits seeded at chart points ``(l, r1, r2, root_index)``;
    ``random_megno_t``: a shorter MEGNO horizon for the random orbits than for the seeded
    ones (``None``: ``megno_t`` for all), where the seeded orbits' weak chaos needs a long run
    and the random orbits are tori, which read ``<Y> ~ 2`` long before."""

    H: float = FIG2_LEVELS.M_gamma  # Figs. 2 and 3: H = 6
    n_orbits: int = 12
    n_points: int = 300
    megno_t: float = 200.0
    contact_t: float = 200.0
    contact_dt: float = 0.05
    seed: int = 0
    extra_points: tuple = ()
    random_megno_t: Optional[float] = None


def compute_map_and_contact(cfg, pick="max_megno"):
    """Section map of ``cfg.n_orbits`` orbits and the contact point of one of them
    (``pick``: the orbit with the largest MEGNO, or the first one)."""
    from taylorball.contact import bounding_circles, contact_trajectory, fit_circle, radius_bound

    p = cfg.ball()
    levels = cfg.levels(cfg.H)
    states, starts, region = C.reduced_initial_states(p, **levels.as_kwargs(), n=cfg.n_orbits,
                                                      seed=cfg.seed, extra_points=cfg.extra_points)
    horizon = np.full(len(states), float(cfg.megno_t))
    if cfg.random_megno_t is not None:
        horizon[len(cfg.extra_points):] = min(cfg.random_megno_t, cfg.megno_t)
    arrays, meta = C.map_orbits("reduced", p, states, n_points=cfg.n_points,
                                megno_t=horizon if cfg.random_megno_t is not None else cfg.megno_t,
                                megno_compact=cfg.megno_compact, megno_jacobian=cfg.megno_jacobian,
                                sheet_levels=levels)
    k = (C.most_chaotic(arrays["orbit_megno"], arrays["orbit_megno_t"], horizon) if pick == "max_megno" else 0)
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


#: A sheet gets a panel of its own when it holds at least this share of the crossings; the
#: crossings on the other (higher) sheets, a few near r1 = 0, are counted in the title only
#: (a panel of a few dozen points in a box sized for thousands reads as empty).
MIN_SHEET_SHARE = 0.05


def _sheet_panels(sheet):
    """``([(title, mask), ...], n_hidden, hidden_sheets)``: one panel per sheet (root index
    of ``K``) holding at least :data:`MIN_SHEET_SHARE` of the crossings (sheet 0 always),
    and the number and labels of the crossings on the sheets left out."""
    n = max(len(sheet), 1)
    counts = np.bincount(sheet) if len(sheet) else np.zeros(1, int)
    shown = [k for k, c in enumerate(counts) if k == 0 or c >= MIN_SHEET_SHARE * n]
    out = []
    for k in shown:
        m = sheet == k
        rank = ["smallest", "2nd", "3rd"][k] if k < 3 else f"{k + 1}th"
        out.append((f"sheet {k}: {rank} root $K$ ({int(m.sum())} pts)", m))
    hidden = [k for k, c in enumerate(counts) if k not in shown and c > 0]
    return out, int(sum(counts[k] for k in hidden)), hidden


def _radial_profile(ax, xy, centre, r_fit, circles):
    """Distance of the contact point from the fitted centre minus the fitted radius, against
    the polar angle about that centre, with the bounding circles in the same coordinates:
    the annulus, magnified to its width."""
    cx, cy = centre
    phi = np.mod(np.arctan2(xy[:, 1] - cy, xy[:, 0] - cx), 2 * np.pi)
    rho = np.hypot(xy[:, 0] - cx, xy[:, 1] - cy) - r_fit
    ax.plot(phi, rho, linestyle="none", marker="o", markersize=0.6, markeredgewidth=0, color="#0072B2",
            rasterized=True)
    th = np.linspace(0, 2 * np.pi, 721)
    u = np.stack([np.cos(th), np.sin(th)])
    for (ccx, ccy), r in circles:
        d = np.array([ccx - cx, ccy - cy])
        ud = d @ u
        s = ud + np.sqrt(np.maximum(ud**2 - d @ d + r * r, 0.0))  # ray from the fitted centre meets the circle
        ax.plot(th, s - r_fit, "--", lw=0.8, color="0.35")
    C.pi_ticks(ax, "x")
    ax.set_xlim(0, 2 * np.pi)
    ax.set_xlabel(r"polar angle $\varphi$ about the fitted centre")
    ax.set_ylabel(r"$|(x, y) - c| - r_{\rm fit}$")


def _zoom_box(points, orbit, megno, sheet, pad=0.15):
    """``(sheet, (x0, x1), (y0, y1))`` around the chaotic orbits' points on the sheet that
    holds most of them (in ``(r1, r2)``), or ``None`` without chaotic orbits."""
    if megno is None or not np.any(np.asarray(megno) > C.CHAOTIC_MEGNO):
        return None
    ch = np.isin(orbit, np.flatnonzero(np.asarray(megno) > C.CHAOTIC_MEGNO))
    k = int(np.bincount(sheet[ch]).argmax()) if sheet is not None else None
    sel = ch & (sheet == k) if sheet is not None else ch
    lo, hi = np.percentile(points[sel][:, 1:3], [0.5, 99.5], axis=0)
    w = np.maximum(hi - lo, 1e-9) * pad
    return k, (lo[0] - w[0], hi[0] + w[0]), (lo[1] - w[1], hi[1] + w[1])


def plot_map_and_contact(arrays, meta, outdir, stem, title):
    """(a) the map in ``(r1, r2)``, one panel per sheet (data saved before the sheets were
    recorded: one panel with the sheets overlaid), (zoom) the chaotic layer if there is one,
    (b) the contact point with its bounding circles and (c) its distance from the fitted
    centre, which shows the annulus at its width."""
    from matplotlib.patches import Rectangle

    plt = C.pyplot()
    pts, orbit, megno = arrays["points"], arrays["orbit"], arrays.get("orbit_megno")
    sheet = arrays.get("sheet")
    if sheet is not None:
        panels, n_hidden, hidden = _sheet_panels(sheet)
    else:
        panels, n_hidden, hidden = [("sheets overlaid (recompute to separate them)", None)], 0, []
    zoom = _zoom_box(pts, orbit, megno, sheet)
    n_top = len(panels)
    fig = plt.figure(figsize=(3.3 * max(n_top, 3), 7.6), layout="constrained")
    top, bottom = fig.subfigures(2, 1, height_ratios=(1.0, 1.05))
    axs = top.subplots(1, n_top, sharex=True, sharey=True, squeeze=False)[0]
    for i, (ax, (name, mask)) in enumerate(zip(axs, panels)):
        C.plot_map(ax, pts, orbit, (1, 2), megno, size=1.0, labels=("$r_1$", "$r_2$" if i == 0 else None),
                   mask=mask)
        ax.set_title(f"(a{i + 1}) {name}", fontsize=8)
        ax.set_aspect("equal", adjustable="box")
        if zoom is not None and (sheet is None or f"sheet {zoom[0]}:" in name):
            (x0, x1), (y0, y1) = zoom[1], zoom[2]
            ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, lw=0.8, ls=":", color="0.2"))
    C.map_legend(axs[0], megno if megno is not None else np.zeros(meta["n_orbits"]), fontsize=6,
                 loc="upper left", bbox_to_anchor=(0.0, -0.22), ncol=1)
    rest = (f"; {n_hidden} crossings on sheet{'s' if len(hidden) > 1 else ''} "
            f"{', '.join(map(str, hidden))} not shown" if n_hidden else "")
    top.suptitle(f"(a) map in $(r_1, r_2)$ on $g = 0$, $l$ cyclic: {meta['n_orbits']} orbits, "
                 f"{meta['n_chaotic']} chaotic; one panel per sheet of the section (root index of $K = M_3$){rest}",
                 fontsize=9)
    bot = bottom.subplots(1, 3 if zoom is not None else 2, squeeze=False)[0]
    if zoom is not None:
        z = bot[0]
        k, xr, yr = zoom
        mask = None if sheet is None else (sheet == k)
        C.plot_map(z, pts, orbit, (1, 2), megno, size=2.5, labels=("$r_1$", "$r_2$"), mask=mask)
        z.set_xlim(*xr)
        z.set_ylim(*yr)
        z.set_title(f"(a{n_top + 1}) zoom on the chaotic layer"
                    f"{'' if k is None else f' (sheet {k}, dotted box)'}", fontsize=8)
        bot = bot[1:]
    b, c = bot
    circles = [(meta[f"contact_{w}_centre"], meta[f"contact_r_{w}"]) for w in ("inner", "outer")]
    C.plot_contact(b, arrays["contact_xy"], circles)
    r_in, r_out = meta["contact_r_inner"], meta["contact_r_outer"]
    where = (f"a circle: $r$ = {r_in:.4g} to within {r_out - r_in:.2g} (rounding)" if r_out - r_in < 1e-9 * r_out
             else f"between circles $r$ = {r_in:.4g} and {r_out:.4g}")
    # titles of three lines at most: three bottom panels side by side leave ~3 inches each
    b.set_title(f"(b) contact point, orbit {meta['contact_orbit']} (MEGNO {meta['contact_orbit_megno']:.1f}\n"
                f"at $t$ = {meta['contact_orbit_megno_t']:g}), $t \\leq$ {arrays['contact_t'][-1]:g}\n{where}",
                fontsize=8)
    _radial_profile(c, arrays["contact_xy"], meta["contact_centre"], meta["contact_radius_fit"], circles)
    c.set_title(f"(c) the annulus magnified: distance from the\nfitted centre minus $r$ = "
                f"{meta['contact_radius_fit']:.4g}; width {meta['contact_r_outer'] - meta['contact_r_inner']:.2g}\n"
                "(dashed: the bounding circles)", fontsize=8)
    fig.suptitle(title)
    return C.save_figure(fig, outdir, stem, meta)
