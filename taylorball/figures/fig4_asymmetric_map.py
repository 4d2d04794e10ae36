"""Fig. 4: the 3D Poincaré map (l, r1, r2) of a dynamically asymmetric ball (I = (2, 3, 4),
m = 1, a = 5, Omega = 2) on the levels h = 5, G = 10 with (a) H = 2: a chaotic trajectory,
so two additional integrals are absent; (b) H = 6: invariant tori. Measured: at H = 2 every
sampled orbit belongs to one chaotic sea (MEGNO ~50 at t = 1000); at H = 6 the map is mixed:
of 40 orbits 11 lie on invariant tori (MEGNO -> 2 to t = 6000), the rest in chaotic layers,
seven of them sticky (MEGNO below 4 at t = 1000; six at 8.8..47 by t = 6000, one later: the
full form runs the orbits' MEGNO to t = 6000 for that reason).

Each panel: an overview (a 3D scatter and two 2D projections, saturated at full density)
and thin slabs of l in (r1, r2), one row per sheet of the section (the root index of K at the
chart point, taylorball.section_sheet), where tori show as curves; Fig. 4b also a MEGNO map
(tb.megno_map) of one slice. Orbits with MEGNO <Y> > 4 (measured with the variational
equations) are drawn in black, on top of the regular ones in colour. The chart is the
paper's section-4 chart; K comes from the energy equation (all roots, branch dg/dt > 0).

Run: ``python studies/fig4_asymmetric_map.py [--full]``.
"""

from __future__ import annotations

import sys
from typing import Optional
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
    # MEGNO map of the H = 6 level (tb.megno_map) on the slice l = map_l, sheet 0, over an
    # map_n x map_n grid of (r1, r2) in the boxes below (they hold the slice's admissible
    # region), to t = megno_t like the orbits; 0 for none
    map_l: float = 0.5 * np.pi
    #: the map's horizon; None: ``megno_t``
    map_t: Optional[float] = None
    map_n: int = 8  # quick: an 8 x 8 glimpse, ~20 admissible cells (the full map is the megno_map study)
    map_r1: tuple = (-7.0, 10.5)
    map_r2: tuple = (-10.5, 10.5)


QUICK = Config()
# the orbits' MEGNO to t = 6000: at t = 1000 seven sticky chaotic orbits of H = 6 still read
# below 4 (docs/figures.md); the map stays at t = 1000 (its 32 x 32 cells to 6000 would cost ~6x)
FULL = Config(n_orbits=40, n_points=5000, megno_t=6000.0, megno_compact=False,
              megno_jacobian=C.FULL_MEGNO_JACOBIAN, map_n=32, map_t=1000.0)


def compute(cfg):
    p = cfg.ball()
    arrays, meta = {}, {"panels": {}}
    for tag, H in zip("ab", cfg.H):
        states, starts, region = C.reduced_initial_states(p, **cfg.levels(H).as_kwargs(), n=cfg.n_orbits,
                                                          seed=cfg.seed)
        a, m = C.map_orbits("reduced", p, states, n_points=cfg.n_points, megno_t=cfg.megno_t,
                            megno_compact=cfg.megno_compact, megno_jacobian=cfg.megno_jacobian,
                            sheet_levels=cfg.levels(H))
        arrays.update({f"{tag}_{k}": v for k, v in a.items()})
        arrays[f"{tag}_start_points"] = starts
        m.update(H=H, admissible_fraction=region["fraction"], r_box=region["r_box"],
                 n_chaotic=int(np.sum(a["orbit_megno"] > C.CHAOTIC_MEGNO)))
        meta["panels"][tag] = m
    if cfg.map_n:
        from ..maps import _megno_map_fields  # tb.megno_map's arrays without xarray (~0.5 CPU s)

        t_map = cfg.megno_t if cfg.map_t is None else cfg.map_t
        mp = _megno_map_fields(p, cfg.levels(cfg.H[1]), l=cfg.map_l, r1=(*cfg.map_r1, cfg.map_n),
                               r2=(*cfg.map_r2, cfg.map_n), t_end=t_map, root=0, stop_above=C.MEGNO_STOP,
                               compact_mode=cfg.megno_compact, jacobian=cfg.megno_jacobian, progress=C.bar(),
                               norm="full")
        arrays.update(b_map_values=mp["values"], b_map_r1=mp["r1"], b_map_r2=mp["r2"], b_map_t=mp["t"])
    return arrays, meta


#: Centres of the thin slabs of ``l`` shown in ``(r1, r2)``, and their smallest width: thin
#: enough that a 2-torus of the 3D map shows as a curve (its cross-section). Sparser maps (the
#: quick configuration) get wider slabs, up to :data:`SLAB_MAX_WIDTH`, to hold ~:data:`SLAB_POINTS`
#: points each. Plot choices, not data (no recompute when changed).
SLAB_CENTRES = tuple(k * np.pi / 4 for k in (1, 2, 3, 5, 6, 7))
SLAB_WIDTH = 0.06
SLAB_MAX_WIDTH = 0.3
SLAB_POINTS = 1500


def slab_width(n_points):
    """The slab width for a map of ``n_points`` points (see :data:`SLAB_WIDTH`)."""
    return float(np.clip(2 * np.pi * SLAB_POINTS / max(n_points, 1), SLAB_WIDTH, SLAB_MAX_WIDTH))


#: Sheets (root index of K) shown in rows of slabs; the few crossings on higher sheets are
#: in the overview panels only.
SLAB_SHEETS = (0, 1)


def _slab_mask(l, centre, width):
    """Points with ``l`` within ``width / 2`` of ``centre`` (mod 2 pi)."""
    return np.abs(np.mod(l - centre + np.pi, 2 * np.pi) - np.pi) <= width / 2


def plot_panel(points, orbit, megno, sheet, title, megno_map=None):
    """One level: (overview) the 3D map and its projections on ``(l, r1)`` and ``(l, r2)``
    with the slabs marked, and the MEGNO map ``megno_map`` (a dict ``l, values, r1, r2, T``) if
    given, then thin slabs of ``l`` in ``(r1, r2)``, one row per sheet (without saved sheets:
    one row, sheets overlaid). Returns the figure."""
    plt = C.pyplot()
    lab = C.AXIS_LABELS["reduced"]
    width = slab_width(len(points))
    rows = [(f"sheet {k}", sheet == k) for k in SLAB_SHEETS] if sheet is not None else [("sheets overlaid", None)]
    # the slab rows as tall as their equal-aspect boxes (a fixed height per row left an
    # empty band between them): 6 boxes across ~14.4 in, plus a title and tick labels
    s1, s2 = (float(np.ptp(points[:, 1])), float(np.ptp(points[:, 2]))) if len(points) else (1.0, 1.0)
    box = 14.4 / len(SLAB_CENTRES) * (min(max(s2 / s1, 0.3), 2.0) if s1 > 0 else 1.0)
    top_h, bottom_h = 3.6, len(rows) * (box + 0.45) + 0.4
    fig = plt.figure(figsize=(15, top_h + bottom_h), layout="constrained")
    top, bottom = fig.subfigures(2, 1, height_ratios=(top_h, bottom_h))
    n_top = 3 if megno_map is None else 4
    ax3 = top.add_subplot(1, n_top, 1, projection="3d")
    C.plot_map(ax3, points, orbit, (0, 1, 2), megno, size=0.3, labels=lab)
    ax3.set_title("(i) 3D map (saturated: see the slabs)", fontsize=8)
    for i, c in enumerate((1, 2)):
        a = top.add_subplot(1, n_top, 2 + i)
        C.plot_map(a, points, orbit, (0, c), megno, size=0.5, labels=(lab[0], lab[c]))
        for lc in SLAB_CENTRES:
            a.axvspan(lc - width / 2, lc + width / 2, color="0.5", alpha=0.35, lw=0)
        a.set_xlim(0, 2 * np.pi)
        a.set_title(f"({'ii' if i == 0 else 'iii'}) projection on $(l, {lab[c].strip('$')})$; grey: the slabs",
                    fontsize=8)
    C.map_legend(a, megno, fontsize=6)
    if megno_map is not None:
        _plot_megno_map(top.add_subplot(1, n_top, 4), megno_map, points, orbit, megno, sheet, width)
    top.suptitle(title, fontsize=10)
    axs = bottom.subplots(len(rows), len(SLAB_CENTRES), sharex=True, sharey=True, squeeze=False)
    for r, (name, smask) in enumerate(rows):
        for j, lc in enumerate(SLAB_CENTRES):
            ax = axs[r, j]
            m = _slab_mask(points[:, 0], lc, width)
            if smask is not None:
                m &= smask
            C.plot_map(ax, points, orbit, (1, 2), megno, size=1.5, mask=m,
                       labels=(lab[1] if r == len(rows) - 1 else None, f"{name}: {lab[2]}" if j == 0 else None))
            if r == 0:
                ax.set_title(f"$l$ = {C.pi_label(lc)} ± {width / 2:.2g}", fontsize=8)
            ax.text(0.02, 0.02, f"{int(m.sum())} pts", transform=ax.transAxes, fontsize=6, color="0.35")
            ax.set_aspect("equal", adjustable="box")
    hidden = "" if sheet is None else f"; {int(np.sum(sheet > max(SLAB_SHEETS)))} crossings on higher sheets not shown"
    bottom.suptitle(f"(iv) thin slabs of $l$ in $(r_1, r_2)$, one row per sheet of the section (root index of "
                    f"$K$): invariant tori cut as curves, chaotic layers as scattered black points{hidden}",
                    fontsize=9)
    return fig


def _saved_map(arrays, meta, tag):
    """The MEGNO map saved with panel ``tag`` (a dict for :func:`plot_panel`), or ``None``
    (panel a, or data saved before the map was part of the study)."""
    if f"{tag}_map_values" not in arrays:
        return None
    cfg = meta["config"]
    return {"l": cfg["map_l"], "T": cfg["megno_t"] if cfg.get("map_t") is None else cfg["map_t"],
            **{k: arrays[f"{tag}_map_{k}"] for k in ("values", "r1", "r2")}}


def _plot_megno_map(ax, mm, points, orbit, megno, sheet, width):
    """(v) the MEGNO map of a slice (sheet 0) with the section points of the regular orbits in
    the slab around it (same sheet) drawn over it in white: tori sit in the dark (``<Y> ~ 2``)."""
    from .megno_map import plot_megno_map

    plot_megno_map(ax, mm["values"], mm["r1"], mm["r2"], vmax=C.MEGNO_STOP)
    regular = np.flatnonzero(np.asarray(megno) <= C.CHAOTIC_MEGNO) if megno is not None else np.zeros(0, int)
    m = _slab_mask(points[:, 0], mm["l"], width) & np.isin(orbit, regular)
    if sheet is not None:
        m &= sheet == 0
    ax.plot(points[m, 1], points[m, 2], linestyle="none", marker="o", markersize=0.9, markeredgewidth=0,
            color="white", rasterized=True)
    ok = np.isfinite(mm["values"])
    n_ch = int(np.sum(mm["values"][ok] > C.CHAOTIC_MEGNO))
    ax.set_title(f"(v) MEGNO map, $l$ = {C.pi_label(mm['l'])}, sheet 0, $t$ = {mm['T']:g}: "
                 f"{n_ch} of {int(ok.sum())} points\n"
                 f"with $\\langle Y\\rangle > {C.CHAOTIC_MEGNO:g}$; white: regular orbits in the slab", fontsize=8)


def plot(arrays, meta, outdir):
    files = []
    for tag in "ab":
        m = meta["panels"][tag]
        fig = plot_panel(arrays[f"{tag}_points"], arrays[f"{tag}_orbit"], arrays.get(f"{tag}_orbit_megno"),
                         arrays.get(f"{tag}_sheet"),
                         f"Fig. 4{tag}: asymmetric ball $I = (2, 3, 4)$, $m = 1$, $a = 5$, $H = {m['H']:g}$, $h = 5$, "
                         f"$G = 10$, $\\Omega = 2$: {m['n_orbits']} orbits, {m['n_chaotic']} chaotic "
                         f"(black, MEGNO $\\langle Y\\rangle > {C.CHAOTIC_MEGNO:g}$"
                         + (f" by $t$ = {m['megno_t']:g})" if "megno_t" in m else ")"),
                         megno_map=_saved_map(arrays, meta, tag))
        files += C.save_figure(fig, outdir, f"fig4{tag}_asymmetric_map", meta)
    return files


if __name__ == "__main__":
    from .runner import main

    sys.exit(main(sys.modules[__name__]))
