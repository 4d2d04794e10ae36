"""MEGNO map of the Fig. 4b level: the asymmetric ball (I = (2, 3, 4), m = 1, a = 5,
Omega = 2) on H = 6, h = 5, G = 10, where the 3D map (l, r1, r2) is mixed. A grid of chart
points (r1, r2) in the slice l = const of the section g = 0 (crossings with dg/dt > 0, the
smallest root K; the roots exchange their order where a sheet crosses gamma3 = 0, i.e.
along r1 = 0, so the two halves are different sheets), each coloured by MEGNO <Y> at T
(tb.megno_map), with the
section points of a few regular orbits that pass near the slice (|l - l0| < slab, same
sheet) drawn over it: their invariant curves. Chaotic runs are stopped once <Y> > 10, as in
the figures (taylorball.figures._common.MEGNO_STOP), so the colour scale ends there.

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
    r1: tuple = (-5.5, 7.0, 10)
    r2: tuple = (-8.0, 8.0, 10)
    T: float = 100.0
    root: int = 0  # the sheet: index of the root K, ascending (>= 0: compared with tb.section_sheet)
    n_orbits: int = 4  # regular orbits drawn over the map
    n_points: int = 1000  # crossings per drawn orbit (a fraction slab / pi of them lands in the slab)
    slab: float = 0.05  # half-width in l of the slab whose points are drawn
    seed: int = 0


QUICK = Config()
FULL = Config(r1=(-5.5, 7.0, 100), r2=(-8.0, 8.0, 100), T=1000.0, n_orbits=10, n_points=40000, megno_compact=False)


def _curve_starts(values, n, rng):
    """Grid indices of ``n`` regular points (``<Y>`` below :data:`C.CHAOTIC_MEGNO`), spread over
    the range of their values (tori of different sizes), drawn with ``rng``."""
    idx = np.flatnonzero(np.isfinite(values.ravel()) & (values.ravel() < C.CHAOTIC_MEGNO))
    if idx.size == 0 or n == 0:
        return idx[:0]
    return np.sort(rng.choice(idx, size=min(n, idx.size), replace=False))


def _slab_points(params, levels, res, l0, slab, root, g0=0.0, direction=1):
    """Section points of the runs ``res`` within ``|l - l0| < slab`` (mod 2 pi) that lie on
    the map's sheet (:func:`taylorball.section_sheet` equal to ``root``). Returns
    ``(points (k, 3), orbit (k,))``."""
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
    keep = tb.section_sheet(params, states, **levels.as_kwargs(), g0=g0, direction=direction) == root
    return pts[keep], orbit[keep]


def compute(cfg):
    import taylorball as tb

    p = cfg.ball()
    levels = cfg.levels(cfg.H)
    from ..maps import _megno_map_fields  # tb.megno_map's arrays without xarray (~0.5 CPU s of imports)

    t0 = time.perf_counter()
    m = _megno_map_fields(p, levels, l=cfg.l, r1=cfg.r1, r2=cfg.r2, T=cfg.T, root=cfg.root,
                          stop_above=C.MEGNO_STOP, compact_mode=cfg.megno_compact, progress=True)
    t_map = time.perf_counter() - t0
    values, r1, r2 = m["values"], m["r1"], m["r2"]
    starts = _curve_starts(values, cfg.n_orbits, np.random.default_rng(cfg.seed))
    i2, i1 = np.unravel_index(starts, values.shape)
    states = [tb.states_on_section(p, **levels.as_kwargs(), point=(cfg.l, float(r1[a]), float(r2[b])),
                                   direction=1)[cfg.root] for a, b in zip(i1, i2)]
    curves, orbit = np.empty((0, 3)), np.empty(0, dtype=int)
    if states:
        res = tb.poincare_sections("reduced", p, states, n_points=cfg.n_points, batch=True, progress=True)
        curves, orbit = _slab_points(p, levels, res, cfg.l, cfg.slab, cfg.root)
    ok = np.isfinite(values)
    arrays = {"values": values, "r1": r1, "r2": r2, "K": m["K"], "n_roots": m["n_roots"],
              "t": m["t"], "curve_points": curves, "curve_orbit": orbit,
              "curve_starts": np.stack([r1[i1], r2[i2]], axis=-1)}
    meta = {
        "map_seconds": t_map,
        "n_points": int(values.size),
        "n_admissible": int(ok.sum()),
        "n_chaotic": int(np.sum(values[ok] > C.CHAOTIC_MEGNO)),
        "n_stopped": int(np.sum(m["t"][ok] < cfg.T)),
        "megno_stop": C.MEGNO_STOP,
        "chaotic_megno": C.CHAOTIC_MEGNO,
        "megno_range": [float(values[ok].min()), float(values[ok].max())] if ok.any() else None,
        "n_curve_points": int(len(curves)),
        "attrs": {k: v for k, v in m["attrs"].items() if k != "provenance"},
        "provenance": m["attrs"]["provenance"],
    }
    return arrays, meta


def plot_megno_map(ax, values, r1, r2, *, curves=None, vmax=None, label=r"MEGNO $\langle Y\rangle$"):
    """Draw a map ``values`` (n2, n1) over the axes ``r1`` (n1,), ``r2`` (n2,) on ``ax``
    (NaN: not admissible, left blank) with a colour bar, and ``curves`` (k, 2) points
    ``(r1, r2)`` over it (small black dots). Colour map ``cividis`` (colour-blind safe, no
    colour reads as black), from 0 to ``vmax`` (default: the largest value). Returns the mesh."""
    plt = C.pyplot()
    vmax = float(np.nanmax(values)) if vmax is None else vmax
    mesh = ax.pcolormesh(r1, r2, np.ma.masked_invalid(values), cmap="cividis", vmin=0.0, vmax=vmax, shading="nearest",
                         rasterized=True)
    plt.colorbar(mesh, ax=ax, label=label, extend="max")
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
    fig, ax = plt.subplots(figsize=(7.5, 7.5))
    curves = arrays["curve_points"][:, 1:] if len(arrays["curve_points"]) else None
    plot_megno_map(ax, arrays["values"], arrays["r1"], arrays["r2"], curves=curves, vmax=meta["megno_stop"])
    ax.set_facecolor("white")
    n1, n2 = len(arrays["r1"]), len(arrays["r2"])
    ax.set_title(f"MEGNO map, Fig. 4b level (I = (2, 3, 4), m = 1, a = 5, $\\Omega$ = 2; H = 6, h = 5, G = 10)\n"
                 f"slice $l$ = {cfg['l']:g}, section $g$ = 0 (dg/dt > 0, root {cfg['root']}): {n1} x {n2} grid, "
                 f"T = {cfg['T']:g}; {meta['n_chaotic']} of {meta['n_admissible']} admissible points with "
                 f"<Y> > {meta['chaotic_megno']:g}\nblack dots: {meta['n_curve_points']} section points of "
                 f"{len(arrays['curve_starts'])} regular orbits with |l - {cfg['l']:g}| < {cfg['slab']:g} "
                 "(dimensionless units)")
    return C.save_figure(fig, outdir, "megno_map")


if __name__ == "__main__":
    from .runner import main

    sys.exit(main(sys.modules[__name__]))
