"""MEGNO maps of the Fig. 4b level: the asymmetric ball (I = (2, 3, 4), m = 1, a = 5,
Omega = 2) on H = 6, h = 5, G = 10, where the 3D map (l, r1, r2) is mixed. A grid of chart
points (r1, r2) in the slice l = const of the section g = 0 (crossings with dg/dt > 0), one
panel per sheet: by default the sheet labels 0 and 1 (tb.megno_map(sheet=k),
tb.section_sheet(label="sheet"): labels that follow a sheet across gamma3 = 0, where the
order of the roots K is exchanged along r1 = 0; docs/chaos.md), or with label="root" the
root indices in ascending K. Each point is coloured by MEGNO <Y> at T, with the section
points of a few regular orbits that pass near the slice (|l - l0| < slab) and lie on the
panel's sheet drawn over it: their invariant curves. Chaotic runs are stopped once
<Y> > 10, as in the figures (taylorball.figures._common.MEGNO_STOP), so the colour scale
ends there.

Run: ``python studies/megno_map.py [--full]``.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from ..paper import FIG4B_LEVELS
from . import _common as C


@dataclass(frozen=True)
class Config(C.BallCaption):
    H: float = FIG4B_LEVELS.M_gamma
    l: float = 0.0
    r1: tuple = (-5.5, 7.0, 8)
    r2: tuple = (-8.0, 8.0, 8)
    T: float = 500.0  # chaos on this level is slow: at T = 100 no point of the map reads chaotic
    label: str = "sheet"  # "sheet": panels by sheet label (continuous across gamma3 = 0); "root": by root index
    panels: tuple = (0, 1, 2)  # the sheet labels (or root indices, >= 0) mapped, one panel each
    n_orbits: int = 4  # regular orbits drawn over the maps (started at regular points of the panels)
    n_points: int = 1000  # crossings per drawn orbit (a fraction slab / pi of them lands in the slab)
    slab: float = 0.05  # half-width in l of the slab whose points are drawn
    seed: int = 0


QUICK = Config()
FULL = Config(r1=(-5.5, 7.0, 100), r2=(-8.0, 8.0, 100), T=1000.0, n_orbits=10, n_points=40000, megno_compact=False,
              megno_jacobian=C.FULL_MEGNO_JACOBIAN)


def _curve_starts(values, n, rng):
    """Grid indices of ``n`` regular points (``<Y>`` below :data:`C.CHAOTIC_MEGNO`), spread over
    the range of their values (tori of different sizes), drawn with ``rng``."""
    idx = np.flatnonzero(np.isfinite(values.ravel()) & (values.ravel() < C.CHAOTIC_MEGNO))
    if idx.size == 0 or n == 0:
        return idx[:0]
    return np.sort(rng.choice(idx, size=min(n, idx.size), replace=False))


def _slab_points(params, levels, res, l0, slab, sheet, g0=0.0, direction=1, label="root"):
    """Section points of the runs ``res`` within ``|l - l0| < slab`` (mod 2 pi) that lie on
    the map's sheet (:func:`taylorball.section_sheet` with ``label`` equal to ``sheet``).
    Returns ``(points (k, 3), orbit (k,))``."""
    import taylorball as tb

    pts, orbit, states = [], [], []
    for k, r in enumerate(res):
        near = np.abs((r.points[:, 0] - l0 + math.pi) % (2 * math.pi) - math.pi) < slab
        pts.append(r.points[near])
        orbit.append(np.full(int(near.sum()), k))
        states.append(np.asarray(r.states[near], dtype=float).reshape(-1, 9))
    if not pts or not sum(len(p) for p in pts):
        return np.empty((0, 3)), np.empty(0, dtype=int)
    pts, orbit, states = np.concatenate(pts), np.concatenate(orbit), np.concatenate(states)
    keep = tb.section_sheet(params, states, **levels.as_kwargs(), g0=g0, direction=direction, label=label) == sheet
    return pts[keep], orbit[keep]


def compute(cfg):
    import taylorball as tb

    p = cfg.ball()
    levels = cfg.levels(cfg.H)
    from ..maps import _megno_map_fields  # tb.megno_map's arrays without xarray (~0.5 CPU s of imports)

    maps, t_map = [], []
    for k in cfg.panels:
        t0 = time.perf_counter()
        which = {"sheet": k} if cfg.label == "sheet" else {"root": k}
        maps.append(_megno_map_fields(p, levels, l=cfg.l, r1=cfg.r1, r2=cfg.r2, t_end=cfg.T, stop_above=C.MEGNO_STOP,
                                      compact_mode=cfg.megno_compact, jacobian=cfg.megno_jacobian, progress=C.bar(),
                                      norm="full", **which))
        t_map.append(time.perf_counter() - t0)
    values = np.stack([m["values"] for m in maps])
    m = maps[0]
    r1, r2 = m["r1"], m["r2"]
    # regular orbits started at regular points of all panels, their slab points split by sheet
    starts = _curve_starts(values, cfg.n_orbits, np.random.default_rng(cfg.seed))
    ip, i2, i1 = np.unravel_index(starts, values.shape)
    states = []
    for a, b, c in zip(ip, i2, i1):
        xs, info = tb.states_on_section(p, **levels.as_kwargs(), point=(cfg.l, float(r1[c]), float(r2[b])),
                                        direction=1, return_info=True)
        lab = info["sheet"] if cfg.label == "sheet" else np.arange(len(xs))
        states.append(xs[int(np.flatnonzero(lab == cfg.panels[a])[0])])
    curves, orbit, panel = np.empty((0, 3)), np.empty(0, dtype=int), np.empty(0, dtype=int)
    if states:
        res = tb.poincare_sections("reduced", p, states, n_points=cfg.n_points, batch=True, progress=C.bar())
        got = [_slab_points(p, levels, res, cfg.l, cfg.slab, k, label=cfg.label) for k in cfg.panels]
        curves = np.concatenate([g[0] for g in got])
        orbit = np.concatenate([g[1] for g in got])
        panel = np.concatenate([np.full(len(g[0]), a) for a, g in enumerate(got)])
    ok = np.isfinite(values)
    arrays = {"values": values, "r1": r1, "r2": r2, "K": np.stack([x["K"] for x in maps]),
              "n_roots": m["n_roots"], "t": np.stack([x["t"] for x in maps]), "curve_points": curves,
              "curve_orbit": orbit, "curve_panel": panel,
              "curve_starts": np.stack([ip, r1[i1], r2[i2]], axis=-1)}
    if cfg.label == "sheet":
        arrays["root"] = np.stack([x["extra"]["root"][1] for x in maps])
    per = [{"panel": int(k), "map_seconds": t, "n_admissible": int(o.sum()),
            "n_chaotic": int(np.sum(v[o] > C.CHAOTIC_MEGNO)), "n_stopped": int(np.sum(tt[o] < cfg.T)),
            "n_chaotic_r1_neg": int(np.sum((v > C.CHAOTIC_MEGNO) & o & (r1[None, :] < 0))),
            "n_admissible_r1_neg": int(np.sum(o & (r1[None, :] < 0))),
            "megno_range": [float(v[o].min()), float(v[o].max())] if o.any() else None,
            "n_curve_points": int(np.sum(panel == a))}
           for a, (k, t, v, o, tt) in enumerate(zip(cfg.panels, t_map, values, ok, arrays["t"]))]
    meta = {
        "map_seconds": float(sum(t_map)),
        "n_points": int(values[0].size),
        "panels": per,
        "megno_stop": C.MEGNO_STOP,
        "chaotic_megno": C.CHAOTIC_MEGNO,
        "attrs": {k: v for k, v in m["attrs"].items() if k != "provenance"},
        "provenance": m["attrs"]["provenance"],
    }
    return arrays, meta


def mark_megno_colorbar(cb, vmax) -> None:
    """Mark ``<Y> = 2`` (quasi-periodic orbits tend to it) and ``<Y> = 4`` (the chaos
    threshold, :data:`~._common.CHAOTIC_MEGNO`) on a MEGNO colour bar ``cb``."""
    ticks = sorted({0.0, 2.0, C.CHAOTIC_MEGNO, *np.arange(0.0, vmax + 1e-9, 2.0)})
    cb.set_ticks(ticks)
    names = {2.0: "2 torus", float(C.CHAOTIC_MEGNO): f"{C.CHAOTIC_MEGNO:g} chaos"}
    cb.set_ticklabels([names.get(float(t), f"{t:g}") for t in ticks])
    for v, ls in ((2.0, ":"), (C.CHAOTIC_MEGNO, "-")):
        cb.ax.axhline(v, color="white", lw=2.4, ls=ls)
        cb.ax.axhline(v, color="black", lw=1.4, ls=ls)


def plot_megno_map(ax, values, r1, r2, *, curves=None, vmax=None, label=r"MEGNO $\langle Y\rangle$"):
    """Draw a map ``values`` (n2, n1) over the axes ``r1`` (n1,), ``r2`` (n2,) on ``ax``
    (NaN: not admissible, left blank) with a colour bar, and ``curves`` (k, 2) points
    ``(r1, r2)`` over it (small black dots). Colour map ``cividis`` (colour-blind safe, no
    colour reads as black), from 0 to ``vmax`` (default: the largest value); the colour bar
    marks ``<Y> = 2`` and the chaos threshold 4 (:func:`mark_megno_colorbar`). Returns the mesh."""
    plt = C.pyplot()
    vmax = float(np.nanmax(values)) if vmax is None else vmax
    mesh = ax.pcolormesh(r1, r2, np.ma.masked_invalid(values), cmap="cividis", vmin=0.0, vmax=vmax, shading="nearest",
                         rasterized=True)
    cb = plt.colorbar(mesh, ax=ax, label=label, extend="max")
    mark_megno_colorbar(cb, vmax)
    if curves is not None and len(curves):
        ax.plot(curves[:, 0], curves[:, 1], linestyle="none", marker="o", markersize=1.2, markeredgewidth=0,
                color="k", rasterized=True)
    ax.set_xlabel("$r_1$")
    ax.set_ylabel("$r_2$")
    ax.set_aspect("equal")
    return mesh


def plot(arrays, meta, outdir):
    plt = C.pyplot()
    cfg = meta["config"]
    values = np.asarray(arrays["values"])
    n1, n2 = len(arrays["r1"]), len(arrays["r2"])
    if values.ndim == 2:  # data saved before the panels: one map, of root index cfg["root"]
        values = values[None]
        label = "root"
        panels = [dict(panel=cfg["root"], **{k: meta[k] for k in ("n_chaotic", "n_admissible", "n_curve_points")})]
        curve_panel = np.zeros(len(arrays["curve_points"]), dtype=int)
    else:
        label, panels, curve_panel = cfg["label"], meta["panels"], np.asarray(arrays["curve_panel"])
    fig, axs = plt.subplots(1, len(panels), figsize=(6.8 * len(panels), 7.6), squeeze=False, layout="constrained")
    for a, (ax, v, pn) in enumerate(zip(axs[0], values, panels)):
        pts = np.asarray(arrays["curve_points"])[curve_panel == a]
        plot_megno_map(ax, v, arrays["r1"], arrays["r2"], curves=pts[:, 1:] if len(pts) else None,
                       vmax=meta["megno_stop"])
        ax.set_facecolor("white")
        ax.set_title(f"{label} {pn['panel']}: <Y> > {meta['chaotic_megno']:g} at {pn['n_chaotic']} of "
                     f"{pn['n_admissible']} points\nblack: {pn['n_curve_points']} section points, "
                     f"|l - {cfg['l']:g}| < {cfg['slab']:g}, this {label}", fontsize=10)
    how = ("sheet labels: follow a sheet across $\\gamma_3 = 0$ ($r_1 = 0$)" if label == "sheet"
           else "root index in ascending K (exchanged where a sheet crosses $r_1 = 0$)")
    fig.suptitle(f"MEGNO maps, Fig. 4b level (I = (2, 3, 4), m = 1, a = 5, $\\Omega$ = 2; H = 6, h = 5, G = 10); "
                 f"slice $l$ = {cfg['l']:g}, section $g$ = 0 (dg/dt > 0)\n{n1} x {n2} grid, T = {cfg['T']:g}, "
                 f"{len(arrays['curve_starts'])} regular orbits drawn; {how} (dimensionless units)", fontsize=11)
    return C.save_figure(fig, outdir, "megno_map", meta)


if __name__ == "__main__":
    from .runner import main

    sys.exit(main(sys.modules[__name__]))
