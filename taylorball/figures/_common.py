"""Shared parts of the figure studies: plotting style and saving, the initial states and
section maps of many orbits, MEGNO screening, and the caption parameters of Figs. 2-5.

The runner (command line, output paths, saving the data) is :mod:`taylorball.figures.runner`.
"""

from __future__ import annotations

import dataclasses
import io
import math
from pathlib import Path
from typing import List, Optional

import numpy as np

from ..io import atomic_write_bytes
from ..levels import Levels
from ..palette import CHAOTIC_MEGNO, COLORS  # noqa: F401  (CHAOTIC_MEGNO: the figures' threshold too)
from ..paper import FIG4_BALL, FIG4A_LEVELS


# ---------------------------------------------------------------------------------------
# Plotting (matplotlib imported lazily, Agg backend).
# ---------------------------------------------------------------------------------------
def bar(label=True):
    """The ``progress`` argument of a figure's long computation: ``label`` (True or a
    label), or False when the package's log shows warnings only (``taylorball -q``: no
    progress lines)."""
    import logging

    return label if logging.getLogger("taylorball").isEnabledFor(logging.INFO) else False


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"figure.dpi": 110, "savefig.dpi": 150, "font.size": 9, "axes.titlesize": 9})
    return plt


#: Every figure says so (the paper's variables carry no units: ``m = 1``, ``a = 5``, ... are numbers).
UNITS_NOTE = "all quantities dimensionless"


def quick_note(study: str) -> str:
    """The line a quick figure carries: it is a preview, and the command of the full one."""
    return (f"QUICK PREVIEW (few orbits, short runs): qualitative only, not the result. "
            f"Full figure: taylorball reproduce --full --only {study}")


#: zlib level of a quick preview's PNG (:func:`save_figure`; Pillow's default is 6). Measured on
#: the quick figures (Xeon, 2026-11-28): encoding 0.114 -> 0.080 s (Fig. 4b) and 0.062 -> 0.043
#: s (Fig. 2) per image, files 430 -> 460 kB and 244 -> 253 kB.
PREVIEW_PNG_LEVEL = 3


def save_figure(fig, outdir: Path, stem: str, meta: Optional[dict] = None) -> List[Path]:
    """Save ``fig`` as ``stem.png`` and ``stem.pdf`` in ``outdir``, with the units note
    (:data:`UNITS_NOTE`) under its bottom-right corner, and close it. A figure of a quick run
    (``meta["quality"] == "quick"``, as the runner saves it) gets :func:`quick_note` in a
    box above its top edge and is saved as PNG only: a preview to look at, not to print (the
    PDF cost as much CPU as the PNG, ~10 s of the quick reproduce's ~60)."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    fig.text(0.995, 0.0, UNITS_NOTE, ha="right", va="top", fontsize=7, color="0.35", style="italic")
    if meta is not None and meta.get("quality") == "quick":
        fig.text(0.5, 1.015, quick_note(str(meta.get("study", stem))), ha="center", va="bottom", fontsize=10,
                 color="#7a3b00", weight="bold",
                 bbox={"boxstyle": "round,pad=0.35", "facecolor": "#fff3d6", "edgecolor": "#E69F00"})
    paths = []
    quick = meta is not None and meta.get("quality") == "quick"
    for ext in ("png",) if quick else ("png", "pdf"):
        p = outdir / f"{stem}.{ext}"
        buf = io.BytesIO()  # written atomically: a full disk leaves no half-written image
        # a preview's PNG at zlib level 3: the same pixels, ~30 % less CPU to encode than
        # level 6 (Pillow's default) for ~7 % more bytes
        kw = {"pil_kwargs": {"compress_level": PREVIEW_PNG_LEVEL}} if quick and ext == "png" else {}
        fig.savefig(buf, format=ext, bbox_inches="tight", **kw)
        atomic_write_bytes(p, buf.getvalue())
        paths.append(p)
        # the layout engine (constrained layout) has placed the axes: keep them there for
        # the next format instead of laying the figure out again (2 of its 4 layout passes)
        fig.set_layout_engine("none")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return paths


#: Okabe & Ito's colour-blind-safe palette (Color Universal Design, 2008) without its black,
#: which marks chaotic orbits, and without its yellow, which vanishes on white; cycled over
#: the regular orbits (neighbouring curves are random orbits, so rarely share a colour).
REGULAR_COLORS = ("#E69F00", "#56B4E9", "#009E73", "#0072B2", "#D55E00", "#CC79A7")

#: The one colour scheme of the figures for the two MEGNO classes: chaotic (MEGNO ``<Y>``
#: above :data:`CHAOTIC_MEGNO`) is black everywhere (section maps, where chaotic orbits are
#: drawn on top of the regular ones; per-class curves; the chaotic fraction of the atlas);
#: a regular orbit takes a palette colour of its own in the section maps, and the class
#: "regular" as a whole (a class curve, a class marker) is :data:`REGULAR_COLOR`.
CHAOTIC_COLOR = COLORS["chaotic"]
REGULAR_COLOR = COLORS["regular"]
CLASS_COLORS = {"chaotic": CHAOTIC_COLOR, "regular": REGULAR_COLOR}


def orbit_colors(n):
    """Colours of ``n`` orbits: :data:`REGULAR_COLORS`, cycled."""
    return [REGULAR_COLORS[k % len(REGULAR_COLORS)] for k in range(max(n, 1))]


def pi_label(angle: float, max_denominator: int = 16) -> str:
    """``angle`` as a multiple of pi in plain text with the Unicode letter (``"3π/4"``,
    ``"−π"``, ``"0"``): mathtext on every tick of the many map panels costs seconds per figure."""
    from fractions import Fraction

    f = Fraction(angle / math.pi).limit_denominator(max_denominator)
    num = {0: "0", 1: "π", -1: "−π"}.get(f.numerator, f"{f.numerator}π".replace("-", "−"))
    return num if f.denominator == 1 or f.numerator == 0 else f"{num}/{f.denominator}"


def pi_ticks(ax, axis: str = "x", lo: float = 0.0, hi: float = 2 * math.pi, denominator: int = 2) -> None:
    """Ticks of an angle axis (``axis`` "x", "y" or "z" of ``ax``) at the multiples of
    ``pi / denominator`` in ``[lo, hi]``, labelled by :func:`pi_label` (``0, π/2, π, 3π/2, 2π``)."""
    step = math.pi / denominator
    ticks = [k * step for k in range(math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9) + 1)]
    getattr(ax, f"set_{axis}ticks")(ticks)
    getattr(ax, f"set_{axis}ticklabels")([pi_label(t, denominator) for t in ticks])


#: Superscript digits and minus sign (DejaVu Sans, matplotlib's default font, has them).
_SUPERSCRIPT = str.maketrans("-\u22120123456789", "\u207b\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079")


def plain_math(label: str) -> str:
    r"""A log axis's tick label in plain text: ``$\mathdefault{10^{-2}}$`` -> ``10⁻²``,
    ``$\mathdefault{2\times10^{3}}$`` -> ``2×10³``; any other label as it is. Mathtext
    parsing of every tick label on every log panel cost ~0.3 CPU s of the quick diffusion
    figures (the same labels, drawn as text)."""
    import re

    m = re.fullmatch(r"\$\\mathdefault\{(.*)\}\$", label)
    if not m:
        return label
    text = re.sub(r"\^\{([-\u22120-9]+)\}", lambda g: g.group(1).translate(_SUPERSCRIPT), m.group(1))
    text = text.replace(r"\times", "\u00d7").replace("-", "\u2212")  # a sign left: mathtext's minus
    return label if any(c in text for c in "\\{}^$") else text


def plain_log_ticks(ax) -> None:
    """Tick labels of the log-scaled axes of ``ax`` in plain text (:func:`plain_math`):
    matplotlib's default log formatters (the same ticks labelled), their labels unparsed.
    Call it after the axis is made logarithmic (``loglog``, ``set_xscale("log")``)."""
    from matplotlib.ticker import LogFormatterSciNotation

    class Plain(LogFormatterSciNotation):
        def __call__(self, x, pos=None):
            return plain_math(super().__call__(x, pos))

    for axis in (ax.xaxis, ax.yaxis):
        if axis.get_scale() == "log":
            base = float(getattr(axis.get_major_formatter(), "_base", 10.0))
            axis.set_major_formatter(Plain(base))
            axis.set_minor_formatter(Plain(base, labelOnlyBase=False))


# ---------------------------------------------------------------------------------------
# Section maps shared by the figure studies.
# ---------------------------------------------------------------------------------------
def reduced_initial_states(params, *, C, M_gamma, h, n, seed=0, g0=0.0, direction=1, extra_points=()):
    """``n`` reduced states on the section ``g = g0`` of the level set, from chart points
    drawn uniformly in the admissible region; where the energy equation has several roots
    ``K``, successive orbits take successive roots so every branch is represented.
    ``extra_points`` ``(l, r1, r2, root_index)`` are prepended (orbits seeded where a scan
    found chaos, e.g. in a thin layer random sampling rarely hits).

    Returns ``(states (m, 9), points (m, 3), region)`` with ``region`` the sampler's dict."""
    from taylorball.charts import section_admissible_sample, states_on_section

    region = section_admissible_sample(params, C=C, M_gamma=M_gamma, h=h, g0=g0, n=n, seed=seed,
                                       direction=direction)
    states, points = [], []
    for e in extra_points:
        roots = states_on_section(params, C=C, M_gamma=M_gamma, h=h, point=e[:3], g0=g0, direction=direction)
        states.append(roots[int(e[3]) % len(roots)])
        points.append(e[:3])
    for i, (p, roots) in enumerate(zip(region["points"], region["states"])):
        states.append(roots[i % len(roots)])
        points.append(p)
    return np.array(states), np.array(points), region


def mparallel_initial_states(params, *, lam, h, n, seed=0, g0=0.0, extra_points=()):
    """``n`` M||gamma states on ``g = g0`` from random chart points ``(l, L/G)``
    (inadmissible points are skipped; successive roots ``G`` alternate), after the states of
    ``extra_points`` ``(l, L/G)`` (first root)."""
    from taylorball.charts import mparallel_states_on_section
    from taylorball.errors import EmptyLevelError

    rng = np.random.default_rng(seed)
    states = [mparallel_states_on_section(params, lam=lam, h=h, point=e, g0=g0)[0] for e in extra_points]
    points = [tuple(e) for e in extra_points]
    n = n + len(states)
    tries = 0
    while len(states) < n and tries < 50 * n:
        tries += 1
        p = (rng.uniform(0, 2 * math.pi), rng.uniform(-0.98, 0.98))
        try:
            roots = mparallel_states_on_section(params, lam=lam, h=h, point=p, g0=g0)
        except EmptyLevelError:
            continue
        states.append(roots[len(states) % len(roots)])
        points.append(p)
    return np.array(states), np.array(points), (len(states) - len(extra_points)) / max(tries, 1)


def map_orbits(kind, params, states, *, n_points, g0=0.0, direction=1, megno_t=None, megno_compact=None,
               megno_jacobian="symbolic", progress=None, sheet_levels=None):
    """Section points of many orbits (batch mode and threads) and, optionally, each orbit's
    MEGNO (``megno_compact``, ``megno_jacobian``: its tangent system, see :func:`megno_many`)
    and, given the section-4 ``sheet_levels`` (a :class:`~taylorball.levels.Levels`) of the
    states, the sheet of each crossing (:func:`taylorball.charts.section_sheet`).

    Returns ``(arrays, meta)``: ``points`` (N, k), ``orbit`` (N,), ``times`` (N,),
    ``orbit_megno`` (n,), ``orbit_drift`` (n,) the worst relative integral drift of each
    orbit, ``orbit_residual`` (n,) the worst event residual, ``sheet`` (N,); ``meta``
    summarises them."""
    import taylorball as tb

    # batch mode: orbits share SIMD lanes (2.3x the scalar throughput per core measured here);
    # the points agree with scalar runs to rounding and do not depend on the number of threads
    progress = bar() if progress is None else progress
    res = tb.poincare_sections(kind, params, list(states), n_points=n_points, g0=g0, direction=direction,
                               progress=progress, batch=True)
    pts = [r.points for r in res]
    arrays = {
        "points": np.concatenate(pts) if pts else np.empty((0, 3)),
        "orbit": np.concatenate([np.full(len(r), i) for i, r in enumerate(res)]).astype(int),
        "times": np.concatenate([r.times for r in res]),
        "orbit_drift": np.array([max(r.drift.values()) if r.drift else 0.0 for r in res]),
        "orbit_residual": np.array([float(np.max(np.abs(r.residuals))) if len(r) else 0.0 for r in res]),
        "initial_states": np.asarray(states, dtype=float),
    }
    if sheet_levels is not None:
        X = np.concatenate([r.states for r in res]) if res else np.empty((0, 9))
        arrays["sheet"] = tb.section_sheet(params, X, **sheet_levels.as_kwargs(), g0=g0, direction=direction)
    if megno_t is not None and np.all(np.asarray(megno_t) > 0):
        horizons = np.full(len(states), float(megno_t)) if np.ndim(megno_t) == 0 else np.asarray(megno_t, float)
        arrays["orbit_megno"], arrays["orbit_megno_t"] = megno_many(kind, params, states, horizons, megno_compact,
                                                                    progress=progress, jacobian=megno_jacobian)
        if np.ndim(megno_t):
            arrays["orbit_megno_horizon"] = horizons
    outcomes = [r.outcome for r in res]
    meta = {
        "n_orbits": len(res),
        "n_points_total": int(len(arrays["times"])),
        "outcomes": {o: outcomes.count(o) for o in set(outcomes)},
        "max_relative_drift": float(arrays["orbit_drift"].max()),
        "max_event_residual": float(arrays["orbit_residual"].max()),
        "crossings_per_time_unit": float(np.median([len(r) / r.times[-1] for r in res if len(r) and r.times[-1] > 0])),
        "levels": res[0].levels if res else {},
        "provenance": res[0].meta if res else {},
    }
    if "orbit_megno" in arrays:
        meta["megno_t"] = float(np.max(megno_t))
        meta["megno_stop"] = MEGNO_STOP
        meta["megno_range"] = [float(arrays["orbit_megno"].min()), float(arrays["orbit_megno"].max())]
    return arrays, meta


#: How the figures' MEGNO runs form the tangent equations' ``J d``
#: (:class:`taylorball.chaos.MegnoOptions` ``jacobian``, the configurations' ``megno_jacobian``):
#: the quick previews the forward form (~4x less CPU per MEGNO step, as accurate; a chaotic
#: orbit's ``<Y>`` differs from the symbolic form's by rounding amplified, and no quick
#: study's classes changed), the full configurations the symbolic one, whose bits their
#: documented numbers have.
QUICK_MEGNO_JACOBIAN, FULL_MEGNO_JACOBIAN = "forward", "symbolic"

#: A run whose MEGNO <Y> passes this is stopped there: far above every quasi-periodic value
#: seen in the figures (at most 3.6 at t = 1000), so the orbit is chaotic, and running on
#: would only make the number larger (chaotic orbits were 60-80 % of the MEGNO time).
MEGNO_STOP = 10.0


def megno_many(kind, params, states, t_end, compact_mode=None, progress=None, jacobian="symbolic"):
    """MEGNO ``<Y>`` of each state (:func:`taylorball.chaos.megno_many`: SIMD lanes and
    threads; each value depends only on its own state and horizon), runs stopped at
    ``t_end`` or when ``<Y>`` passes :data:`MEGNO_STOP`. ``t_end``: one horizon, or one per
    state (the states of each horizon share one call: an orbit's value does not depend on
    the orbits around it). ``compact_mode`` as there.

    Returns ``(Y, T)``: ``<Y>`` and the time it was measured at, per orbit."""
    from taylorball.chaos import MegnoOptions, megno_many as many

    states = list(states)
    progress = bar() if progress is None else progress
    horizons = np.broadcast_to(np.asarray(t_end, dtype=float), (len(states),))
    Y, T = np.empty(len(states)), np.empty(len(states))
    for h in np.unique(horizons):
        idx = np.flatnonzero(horizons == h)
        res = many(kind, params, [states[i] for i in idx], float(h), stop_above=MEGNO_STOP, progress=progress,
                   norm="full", options=MegnoOptions(compact_mode=compact_mode, jacobian=jacobian))  # the figures' published values (Omega != 0)
        Y[idx] = [r.mean_megno for r in res]
        T[idx] = [r.t for r in res]
    return Y, T


def most_chaotic(Y, T, horizon=None):
    """Index of the most chaotic orbit: among runs stopped early (``T`` short of its
    ``horizon``: chaotic), the one that passed :data:`MEGNO_STOP` first; otherwise the largest
    ``<Y>``. ``horizon``: the time each run was to end at (default: the longest ``T``, one
    horizon for all)."""
    Y, T = np.asarray(Y, dtype=float), np.asarray(T, dtype=float)
    horizon = np.full(T.shape, T.max()) if horizon is None else np.broadcast_to(np.asarray(horizon, float), T.shape)
    stopped = T < horizon
    return int(np.lexsort((-Y, np.where(stopped, T, np.inf)))[0])


def plot_map(ax, points, orbit, cols, megno=None, size=0.8, labels=None, angle_cols=(0,), mask=None):
    """Section points coloured by orbit (:data:`REGULAR_COLORS`); orbits with MEGNO above
    :data:`CHAOTIC_MEGNO` in :data:`CHAOTIC_COLOR`, drawn last so that they are on top.
    Axes of the columns in ``angle_cols`` (column 0, ``l``, of both section charts) get
    :func:`pi_ticks`; ``mask`` (N,) keeps a subset of the points (a slab, a sheet) while the
    colours stay those of the whole map."""
    n = int(orbit.max()) + 1 if len(orbit) else 0
    colors = orbit_colors(n)
    chaotic = np.zeros(n, bool) if megno is None else np.asarray(megno) > CHAOTIC_MEGNO
    if mask is not None:
        points, orbit = points[mask], orbit[mask]
    # markers of a line without the line (Line2D/Line3D): drawn in one call per orbit, many
    # times faster than scatter's collections for 10^5 points (no per-point sizes or depth
    # shading); ``size`` is a scatter-style area in points^2
    for k in list(np.flatnonzero(~chaotic)) + list(np.flatnonzero(chaotic)):
        m = orbit == k
        if not m.any():
            continue
        ax.plot(*(points[m, c] for c in cols), linestyle="none", marker="o", markersize=float(np.sqrt(size)),
                markeredgewidth=0, color=CHAOTIC_COLOR if chaotic[k] else colors[k], zorder=1.0)
    # the points of all orbits become one image per panel in vector output (one image per
    # orbit, as ``rasterized=True`` on each line gives, costs seconds on the many-panel maps)
    ax.set_rasterization_zorder(1.5)
    if labels:
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
        if len(cols) == 3:
            ax.set_zlabel(labels[2])
    for axis, c in zip("xyz", cols):
        if c in angle_cols:
            pi_ticks(ax, axis)


def map_legend(ax, megno, **kw):
    """A legend of the colours of :func:`plot_map`, under ``ax`` (off the data): regular
    orbits (palette colours) and chaotic ones (:data:`CHAOTIC_COLOR`), with their counts; a
    class without orbits is left out."""
    from matplotlib.legend_handler import HandlerTuple
    from matplotlib.lines import Line2D

    chaotic = np.asarray(megno) > CHAOTIC_MEGNO
    dot = {"linestyle": "none", "marker": "o", "markersize": 4}
    handles, labels = [], []
    if (~chaotic).any():
        handles.append(tuple(Line2D([], [], color=c, **dot) for c in REGULAR_COLORS[:3]))
        labels.append(f"regular: {int((~chaotic).sum())} orbits, a colour each")
    if chaotic.any():
        handles.append(Line2D([], [], color=CHAOTIC_COLOR, **dot))
        labels.append(rf"chaotic, MEGNO $\langle Y\rangle > {CHAOTIC_MEGNO:g}$: {int(chaotic.sum())} orbits")
    ax.legend(handles, labels, handler_map={tuple: HandlerTuple(ndivide=None)},
              **{"fontsize": 7, "loc": "upper center", "bbox_to_anchor": (0.5, -0.2), "ncol": 2, **kw})


AXIS_LABELS = {"reduced": ("$l$", "$r_1$", "$r_2$"), "mparallel": ("$l$", "$L/G$")}


@dataclasses.dataclass(frozen=True)
class BallCaption:
    """The caption parameters shared by Figs. 2-5 (:mod:`taylorball.paper`): the ball
    (``m = 1``, ``a = 5``, ``Omega = 2``; moments per figure, the Fig. 4/5 ball by default)
    and the levels ``G = |M| = 10``, ``h = E = 5`` (``H = (M, gamma)`` is per figure); and
    ``megno_compact``, the compile mode of the MEGNO tangent system (``None``: taylorball's
    choice by the amount of work; the full configurations use ``False``, default mode: ~28 s
    of compilation once per machine, kept in heyoka's disk cache, for ~1.8x faster MEGNO on
    every run); and ``megno_jacobian``, how the tangent equations' ``J d`` is formed
    (:data:`QUICK_MEGNO_JACOBIAN` in the quick previews, :data:`FULL_MEGNO_JACOBIAN` in the
    full configurations)."""

    inertia: tuple = FIG4_BALL.inertia
    mass: float = FIG4_BALL.mass
    radius: float = FIG4_BALL.radius
    plane_rate: float = FIG4_BALL.plane_rate
    h: float = FIG4A_LEVELS.h
    G: float = FIG4A_LEVELS.C
    megno_compact: Optional[bool] = None
    megno_jacobian: str = QUICK_MEGNO_JACOBIAN

    def ball(self):
        from ..params import BallParams

        return BallParams(inertia=self.inertia, mass=self.mass, radius=self.radius, plane_rate=self.plane_rate)

    def levels(self, H) -> Levels:
        """The levels of the caption with ``H = (M, gamma)``: ``Levels.from_caption(G, H, h)``."""
        return Levels.from_caption(G=self.G, H=H, h=self.h)


def plot_contact(ax, xy, circles, color=REGULAR_COLORS[3], lw=0.4):
    """A contact-point trajectory ``xy`` (n, 2) in the fixed frame with its bounding
    ``circles`` ``[(centre, radius), ...]``, at equal scale."""
    ax.plot(xy[:, 0], xy[:, 1], lw=lw, color=color)
    draw_circles(ax, circles)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("$x$")
    ax.set_ylabel("$y$")


def draw_circles(ax, circles, **kw):
    """Dashed circles ``[(centre, radius), ...]`` (e.g. a trajectory's bounding circles)."""
    th = np.linspace(0, 2 * np.pi, 400)
    for (cx, cy), r in circles:
        ax.plot(cx + r * np.cos(th), cy + r * np.sin(th), "--", lw=0.8, **{"color": "0.35", **kw})
