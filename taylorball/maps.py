"""Chaos-indicator maps on a section level: :func:`megno_map`.

A grid of chart points ``(r1, r2)`` at fixed ``l`` on the section ``g = g0`` of a level
``|M| = C``, ``(M, gamma) = M_gamma``, ``E = h`` of the reduced system (paper section 4: the
3D map in ``(l, r1, r2)``, sliced at ``l``; for a dynamically symmetric ball ``I1 = I2``,
``l`` is cyclic and the slice is the whole 2D map). Each admissible point becomes a state
(:func:`taylorball.states_on_section`, the energy equation solved for ``K``), each state an
orbit whose MEGNO / FLI is computed in the SIMD lanes of the many-orbit engine
(:func:`taylorball.megno_many`); the result is an ``xarray.DataArray`` over ``(r2, r1)``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, fields, replace
from typing import Any, Optional, Tuple, Union

import numpy as np

from ._deprecation import moved
from ._problem import Problem
from .errors import EmptyLevelError, UsageError
from .levels import Levels
from .numbers import count, real_number
from .params import BallParams

__all__ = ["megno_map", "MegnoMapOptions", "MAP_INDICATORS", "MAX_MAP_POINTS"]

#: The indicators a map can show: fields of :class:`taylorball.ChaosIndicators`.
MAP_INDICATORS = ("mean_megno", "megno", "fli", "lyapunov")

#: Most grid points one map accepts (``n1 * n2``): 250 000 orbits are ~7 hours at T = 1000
#: on the 2-core machine of docs/benchmarks.md; a larger request is refused before any work.
MAX_MAP_POINTS = 250_000


@dataclass(frozen=True)
class MegnoMapOptions:
    """The less common options of :func:`megno_map`: the section's branch and how each
    orbit's MEGNO runs (``megno_map(..., options=tb.MegnoMapOptions(...))``; a field given
    to :func:`megno_map` as a keyword of the same name is the deprecated old form).

    Attributes
    ----------
    g0 : float
        The section angle.
    direction : {1, -1}
        The branch: crossings of ``g = g0`` with ``g`` increasing (1) or decreasing (-1).
    t0, chunk, seed, stop_above, compact_mode, norm
        As for :func:`taylorball.megno_many` (``stop_above`` ends a run early: its value is
        then at the coordinate ``t`` of that point; ``norm`` default ``"compact"``).
    n_grid : int
        Grid of the root search in ``K`` (:func:`taylorball.states_on_section`).
    jacobian : {"forward", "symbolic"}
        As for :class:`taylorball.MegnoOptions`: ``"symbolic"`` (default) the equations
        of earlier releases, whose maps it reproduces bit for bit, ``"forward"`` the tangent
        equations ~4x faster per step.
    """

    g0: float = 0.0
    direction: int = 1
    t0: float = 1.0
    chunk: float = 50.0
    seed: int = 0
    stop_above: Optional[float] = None
    compact_mode: Optional[bool] = None
    norm: str = "compact"
    n_grid: int = 2001
    jacobian: str = "symbolic"


_OPTION_NAMES = tuple(f.name for f in fields(MegnoMapOptions))
#: The fields that were keywords of megno_map before they moved into MegnoMapOptions.
_MOVED_NAMES = tuple(n for n in _OPTION_NAMES if n != "jacobian")


def _options(options: Optional[MegnoMapOptions], given: dict) -> MegnoMapOptions:
    """``options`` (default :class:`MegnoMapOptions`) with the keywords ``given`` put in."""
    if options is None:
        options = MegnoMapOptions()
    elif not isinstance(options, MegnoMapOptions):
        raise UsageError(f"options must be a taylorball.MegnoMapOptions(...), got {options!r}")
    unknown = sorted(set(given) - set(_OPTION_NAMES))
    if unknown:
        raise UsageError(f"megno_map got unknown keyword(s) {', '.join(unknown)}; its options are r1, r2, t_end, l, "
                         f"root, sheet, indicator, workers, progress, options and the fields of MegnoMapOptions: "
                         f"{', '.join(_OPTION_NAMES)}")
    return replace(options, **given) if given else options


def _axis(name: str, spec) -> np.ndarray:
    """``(lo, hi, n)`` -> ``linspace(lo, hi, n)``: finite ``lo < hi``, ``2 <= n <= MAX_MAP_POINTS``."""
    form = f"{name} must be (lo, hi, n): finite numbers lo < hi and an integer n >= 2"
    if isinstance(spec, (str, bytes)) or not hasattr(spec, "__len__") or len(spec) != 3:
        raise UsageError(f"{form}, got {spec!r}")
    lo = real_number(f"{name} lower bound", spec[0])
    hi = real_number(f"{name} upper bound", spec[1])
    if not lo < hi:
        raise UsageError(f"{form}, got lo = {spec[0]!r} >= hi = {spec[1]!r}")
    n = count(f"{name} number of points n", spec[2], lo=2, hi=MAX_MAP_POINTS)
    return np.linspace(lo, hi, n)


def _check(params, levels, l, r1, r2, T, t0, g0, direction, root, sheet, indicator, n_grid):
    from .charts import _check_direction, _check_grid, _check_levels
    from .manifold import params_for

    params = params_for("reduced", params)
    if not isinstance(levels, Levels):
        raise UsageError(f"levels must be a taylorball.Levels (C, M_gamma, h of the reduced system), got {levels!r}")
    _check_levels(levels.C, levels.M_gamma)  # |M_gamma| = C is the M||gamma case: no section-4 chart
    l = real_number("l (the slice's angle)", l, lo=0.0, hi=2 * math.pi)
    g0 = real_number("g0 (an angle)", g0)
    a1, a2 = _axis("r1", r1), _axis("r2", r2)
    if a1.size * a2.size > MAX_MAP_POINTS:
        raise UsageError(f"the grid has {a1.size} x {a2.size} = {a1.size * a2.size} points, more than "
                         f"MAX_MAP_POINTS = {MAX_MAP_POINTS}: use a coarser grid (or several maps)")
    T = real_number("t_end", T)
    t0 = real_number("t0", t0, lo=0.0, lo_open=True)
    if not T > t0:
        raise UsageError(f"need 0 < t0 < t_end, got t0={t0!r}, t_end={T!r}")
    if direction is None:
        raise UsageError("direction must be +1 or -1 (the branch of the section), got None")
    _check_direction(direction)
    if not (root is None or isinstance(root, (int, np.integer)) and not isinstance(root, (bool, np.bool_))):
        raise UsageError(f"root must be an integer index into the roots K (ascending; -1 the largest), got {root!r}")
    if sheet is not None:
        if not (isinstance(sheet, (int, np.integer)) and not isinstance(sheet, (bool, np.bool_)) and sheet >= 0):
            raise UsageError(f"sheet must be a sheet label: an integer >= 0 (taylorball.section_sheet with "
                             f"label='sheet'), got {sheet!r}")
        if root is not None:
            raise UsageError(f"give root (the index of K among the roots) or sheet (the sheet label), not both: "
                             f"got root={root!r}, sheet={sheet!r}")
    if not (isinstance(indicator, str) and indicator in MAP_INDICATORS):
        raise UsageError(f"indicator must be one of {MAP_INDICATORS}, got {indicator!r}")
    _check_grid(n_grid)
    return params, float(l), float(g0), a1, a2, float(T), float(t0)


def _row_states(params, levels, l, r1s, r2, g0, direction, root, n_grid, sheet=None):
    """The states of one grid row (fixed ``r2``): ``(states (n, 9) with NaN rows where there
    is none, K (n,), number of roots (n,), root index (n,) of the state taken, -1 where
    none)``: the root of index ``root`` or, if ``sheet`` is given, the state of that sheet
    label. One vectorised root search for the row, each point's states bit-identical to
    :func:`taylorball.states_on_section` there."""
    from .charts import _section_states

    states = np.full((r1s.size, 9), np.nan)
    K = np.full(r1s.size, np.nan)
    n_roots = np.zeros(r1s.size, dtype=np.int64)
    index = np.full(r1s.size, -1, dtype=np.int64)
    found = _section_states(params, levels.C, levels.M_gamma, levels.h, l, r1s, np.full(r1s.size, r2), g0,
                            direction, n_grid)
    for i, f in enumerate(found):
        if isinstance(f, Exception):  # a singular chart point: no state there
            continue
        xs, info = f
        n_roots[i] = len(xs)
        # the root index counts the roots the chart refuses too (info["root"]), so that one
        # refused root never shifts the others' indices; a refused root's point stays NaN
        n_all = len(xs) + len(info["refused_K"])
        if sheet is not None:
            hit = np.flatnonzero(info["sheet"] == sheet)
        elif -n_all <= root < n_all:
            hit = np.flatnonzero(info["root"] == root % n_all)
        else:
            hit = np.zeros(0, dtype=np.int64)
        if hit.size:
            states[i], K[i], index[i] = xs[hit[0]], info["K"][hit[0]], info["root"][hit[0]]
    return states, K, n_roots, index


@moved(MegnoMapOptions, *_MOVED_NAMES, renamed={"T": "t_end", "threads": "workers"})
def megno_map(params: Union[BallParams, Problem], levels: Levels, *, r1: Tuple[float, float, int],
              r2: Tuple[float, float, int], t_end: float, l: float = 0.0, root: Optional[int] = None,
              sheet: Optional[int] = None, indicator: str = "mean_megno", workers: Optional[int] = None,
              progress: bool = False, options: Optional[MegnoMapOptions] = None) -> Any:
    r"""A map of a chaos indicator over a grid of initial conditions on a section level.

    The chart points ``(l, r1, r2)`` of the section-4 chart (paper section 4) with ``l``
    fixed and ``(r1, r2)`` on a grid, on the section ``g = g0`` of the level ``|M| = C``,
    ``(M, gamma) = M_gamma``, ``E = h`` of the reduced system (paper eqs. (15)-(16) [eq10]).
    Each point is turned into a state by :func:`taylorball.states_on_section` (the energy
    equation solved for ``K = M3``; crossings with ``dg/dt`` of sign ``direction``); where it
    has several roots the one of index ``root`` in ascending ``K`` is taken (the section of
    an asymmetric ball is multi-sheeted over ``(l, r1, r2)``: on the Fig. 4b level most
    admissible points carry two states, ``root=0`` and ``root=1`` map them). The order of
    the roots is not a sheet label everywhere: where a sheet passes through ``gamma3 = 0``
    (``r1 = -R3 gamma3 = 0``) the roots exchange their order, so a map of one ``root`` can
    join two sheets along ``r1 = 0`` (docs/figures.md, the MEGNO map). ``sheet=k`` maps
    the states of sheet label ``k`` instead (:func:`taylorball.section_sheet` with
    ``label="sheet"``: ordered by orientation and distance from the root ``K*`` where
    ``gamma3 = 0``, quantities continuous on a sheet), which follows a sheet across
    ``r1 = 0``. The
    orbits run together through :func:`taylorball.megno_many` (SIMD lanes, compact or
    default mode chosen by the amount of work as there), to ``t_end``, and each point is
    coloured by ``indicator`` at ``t_end`` (or where ``stop_above`` stopped it).

    For a dynamically symmetric ball (``I1 = I2``) ``l`` is cyclic: every ``l`` gives the
    same map, the whole 2D section in ``(r1, r2)`` (paper section 4).

    Parameters
    ----------
    params : BallParams or Problem
        The ball; or a reduced :class:`taylorball.Problem` (float64, default tolerance) in
        its place.
    levels : Levels
        The level ``C, M_gamma, h`` (e.g. :data:`taylorball.paper.FIG4B_LEVELS`).
    r1, r2 : (lo, hi, n)
        The grid axes: ``n >= 2`` points from ``lo`` to ``hi`` (finite, ``lo < hi``), at most
        :data:`MAX_MAP_POINTS` points in all.
    t_end : float
        End of each run (> t0): the indicators are over ``[t0, t_end]`` (``T=`` is its
        deprecated old name).
    l : float
        The slice, in ``[0, 2 pi]``.
    root : int, optional
        Index of the root ``K`` (ascending, negative from the end) where a point carries
        several states; points with fewer roots are NaN, and so are points whose root of
        that index the chart refuses (``|gamma3| < 1e-4``: it keeps its index, the others
        are not shifted). Default 0 (unless ``sheet`` is given).
    sheet : int, optional
        Instead of ``root``: the sheet label (an integer >= 0; 0 the sheet of orientation
        +1 nearest ``K*``, 1 that of orientation -1, 2 and 3 those beyond ``K**``, 4 the
        next of orientation +1 ...; :func:`taylorball.section_sheet`); points without a
        state of this label are NaN. The label changes at ``r1 = r2 = 0``, where branches
        pass through ``gamma = -e3`` (docs/chaos.md, "Sheets").
    indicator : {"mean_megno", "megno", "fli", "lyapunov"}
        ``<Y>(t_end)``, ``Y(t_end)``, ``FLI(t_end)`` or ``FLI(t_end) / (t_end - t0)``.
    workers, progress
        As for :func:`taylorball.megno_many`.
    options : MegnoMapOptions, optional
        The section's angle ``g0`` and branch ``direction``, the MEGNO runs' ``t0``,
        ``chunk``, ``seed``, ``stop_above``, ``compact_mode``, ``norm`` (default
        ``"compact"``) and the root search's ``n_grid``.
        Each field as a keyword of its own (``stop_above=10.0``) is the deprecated old
        form.

    Returns
    -------
    xarray.DataArray, shape (n2, n1)
        Dims ``("r2", "r1")`` with coordinates ``r1``, ``r2``; NaN where the point carries no
        state of index ``root`` (outside the admissible region). Further coordinates over
        ``(r2, r1)``: ``K`` (the root taken), ``n_roots`` (states at the point, 0 outside)
        and ``t`` (the time the indicator is at); with ``sheet``, also ``root`` (the index
        in ascending ``K`` of the state taken, -1 where none). ``attrs``: the kind,
        indicator, ``norm``, ``t_end``, ``t0``, ``l``, ``g0``, ``direction``, ``root`` (or ``sheet``),
        the levels ``C, M_gamma, h``, the
        ball's ``inertia, mass, radius, plane_rate``, ``seed``, ``chunk``, ``stop_above``
        (NaN for none), and ``provenance`` (JSON text of :func:`taylorball.io.provenance`).

    Raises
    ------
    UsageError
        A bad grid (not ``(lo, hi, n)``, NaN bounds, ``lo >= hi``, ``n < 2``, more than
        :data:`MAX_MAP_POINTS` points), ``l`` outside ``[0, 2 pi]``, bad times, direction,
        root, sheet (or both given) or indicator; before any work.
    ParameterError, ChartError
        Bad ball parameters or levels (``|M_gamma| = C``).
    EmptyLevelError
        When no grid point carries a state (the grid misses the admissible region).

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4B_LEVELS
    >>> m = tb.megno_map(FIG4_BALL, FIG4B_LEVELS, l=0.0, r1=(-4, 4, 3), r2=(-6, 6, 3), t_end=20.0)
    >>> m.dims, m.shape, m.name
    (('r2', 'r1'), (3, 3), 'mean_megno')
    >>> m.n_roots.values                           # states per chart point (0: not admissible)
    array([[0, 0, 2],
           [1, 0, 2],
           [0, 0, 2]])
    >>> import numpy as np
    >>> bool(np.isnan(m.values[0, 0])), bool(np.isfinite(m.values[1, 0]))
    (True, True)
    """
    f = _megno_map_fields(params, levels, r1=r1, r2=r2, t_end=t_end, l=l, root=root, sheet=sheet,
                          indicator=indicator, workers=workers, progress=progress, options=options)
    return _data_array(f)


def _megno_map_fields(params: Union[BallParams, Problem], levels: Levels, *, r1: Tuple[float, float, int],
                      r2: Tuple[float, float, int], t_end: float, l: float = 0.0, root: Optional[int] = None,
                      sheet: Optional[int] = None, indicator: str = "mean_megno", workers: Optional[int] = None,
                      progress: bool = False, options: Optional[MegnoMapOptions] = None, **run_options: Any) -> dict:
    """:func:`megno_map` as plain arrays, without xarray (importing it and building the
    DataArray cost ~0.5 CPU s, a tenth of a quick figure): a dict with ``values``, ``r1``,
    ``r2``, ``K``, ``n_roots``, ``t`` (NumPy arrays: the DataArray's values and coordinates),
    ``extra`` (further coordinates over ``(r2, r1)``: ``root`` with ``sheet``) and ``attrs``
    (its attributes). Arguments as for :func:`megno_map`."""
    from ._problem import lane_problem, params_problem
    from .chaos import MegnoOptions, _check_args, megno_many
    from .ensemble import call, run_many
    from .io import jsonable, provenance

    o = _options(options, run_options)
    g0, direction, t0, chunk, seed, stop_above = o.g0, o.direction, o.t0, o.chunk, o.seed, o.stop_above
    prob = lane_problem("megno_map", params_problem("megno_map", "reduced", params))
    ball, l, g0, r1s, r2s, T, t0 = _check(prob.params, levels, l, r1, r2, t_end, t0, g0, direction, root, sheet,
                                            indicator, o.n_grid)
    if sheet is None and root is None:
        root = 0
    _check_args("reduced", t0, T, chunk, stop_above, o.norm, o.jacobian)  # megno_many's own checks, before the root search
    count("seed", seed, lo=0)
    if workers is not None:
        count("workers", workers)
    rows = run_many([call(_row_states, ball, levels, l, r1s, float(r2), g0, direction,
                          None if root is None else int(root), o.n_grid, None if sheet is None else int(sheet))
                     for r2 in r2s], backend="serial", progress="map: states on the section" if progress is True
                    else progress)
    states = np.concatenate([r[0] for r in rows])
    K = np.stack([r[1] for r in rows])
    n_roots = np.stack([r[2] for r in rows])
    extra = {} if sheet is None else {"root": (("r2", "r1"), np.stack([r[3] for r in rows]))}
    ok = np.flatnonzero(np.isfinite(states[:, 0]))
    if ok.size == 0:
        label = f"root index {root}" if sheet is None else f"sheet label {sheet}"
        raise EmptyLevelError(
            f"no point of the grid r1 in [{r1s[0]:g}, {r1s[-1]:g}], r2 in [{r2s[0]:g}, {r2s[-1]:g}] at l = {l:g} "
            f"carries a state of {label} on the section g = {g0:g} (direction {direction:+d}) of "
            f"{levels}: the grid misses the admissible region (see taylorball.section_admissible_sample)")
    res = megno_many(prob, states[ok], T, stop_above=stop_above, norm=o.norm, workers=workers,
                     progress=progress, options=MegnoOptions(t0=t0, chunk=chunk, seed=seed,
                                                             compact_mode=o.compact_mode, jacobian=o.jacobian))
    values = np.full(states.shape[0], np.nan)
    t_at = np.full(states.shape[0], np.nan)
    values[ok] = [getattr(r, indicator) for r in res]
    t_at[ok] = [r.t for r in res]
    which = {"root": int(root)} if root is not None else {"sheet": int(sheet)} if sheet is not None else {}
    attrs = dict(
        kind="reduced", indicator=indicator, norm=o.norm, jacobian=o.jacobian, t_end=T, t0=t0, l=l, g0=g0, direction=int(direction), **which,
        C=levels.C, M_gamma=levels.M_gamma, h=levels.h, inertia=list(ball.inertia), mass=ball.mass,
        radius=ball.radius, plane_rate=ball.plane_rate, seed=int(seed), chunk=float(chunk),
        stop_above=math.nan if stop_above is None else float(stop_above),
        provenance=json.dumps(jsonable(provenance())))
    return {"values": values.reshape(K.shape), "r1": r1s, "r2": r2s, "K": K, "n_roots": n_roots,
            "t": t_at.reshape(K.shape), "extra": extra, "attrs": attrs}


def _data_array(f):
    """The DataArray of :func:`megno_map` from the fields of :func:`_megno_map_fields`."""
    import xarray as xr

    dims = ("r2", "r1")
    return xr.DataArray(f["values"], dims=dims, name=f["attrs"]["indicator"],
                        coords={"r1": f["r1"], "r2": f["r2"], "K": (dims, f["K"]), "n_roots": (dims, f["n_roots"]),
                                "t": (dims, f["t"]), **f["extra"]}, attrs=f["attrs"])
