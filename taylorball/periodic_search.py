r"""All periodic orbits up to ``k_max`` crossings on a level: :func:`periodic_orbits`.

Seeds come from near-recurrences of orbits started on a sample of the admissible region
(a chart grid ranked by the return residual; regular and chaotic orbits alike: an orbit that comes back near where it was after ``k``
crossings passes near a periodic orbit of period ``k`` or through an island around one),
and, for the dynamically asymmetric ball, from the fixed sets of the reversors
``sigma_1, sigma_2`` on the section (``l in {0, pi}`` resp. ``{pi/2, 3 pi/2}``, ``r2 = 0``;
:func:`taylorball.periodic.reversors`). The seed orbits run in the SIMD lanes
(:func:`taylorball.poincare_sections` with ``batch=True``). Each seed goes to
:func:`taylorball.periodic_orbit`; failures are counted, never reported as orbits; an
orbit found from several seeds or phases (any of its ``k`` points) is kept once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, List, Literal, Optional, Tuple, Union

import numpy as np

from ._deprecation import moved, options_of
from ._problem import Problem
from ._typing import Direction, KindName, ParamsLike
from .errors import EmptyLevelError, IntegrationError, StateError, TaylorballError, UsageError
from .levels import Levels, MParallelLevels
from .periodic import NewtonOptions, PeriodicOrbit, _has_axial_symmetry, orbit_problem, periodic_orbit

__all__ = ["periodic_orbits", "SearchOptions", "SearchReport", "same_orbit"]

#: Time limit per crossing of the seed runs: a seed whose orbit does not come back to the
#: section (or comes back slowly) is dropped instead of running for ever.
T_MAX_SEED = 100.0


def _wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def same_orbit(a: PeriodicOrbit, b: PeriodicOrbit, tol: float = 1e-6) -> bool:
    """Whether two results are the same orbit: same ``k`` and a point of ``b`` within ``tol``
    (chart, ``l`` mod ``2 pi``; ``l`` ignored for a symmetric ball's relative orbits) of a
    point of ``a``."""
    if a.k != b.k:
        return False
    ignore_l = a.shift != 0.0 or b.shift != 0.0
    for p in b.points:
        d = a.points - p
        d[:, 0] = 0.0 if ignore_l else _wrap(d[:, 0])
        if float(np.min(np.max(np.abs(d), axis=1))) <= tol:
            return True
    return False


@dataclass
class SearchReport:
    """What a search did: seeds tried per source, Newton failures, duplicates, CPU time."""

    seeds: Dict[str, int] = field(default_factory=dict)
    failures: int = 0
    #: one ``(k, seed residual, best Newton residual or nan, how)`` per failed seed; ``how``
    #: is ``"single"`` or ``"shooting"`` (slow returns, :class:`SearchOptions` ``slow_factor``)
    failed: List[Tuple[int, float, float, str]] = field(default_factory=list)
    #: seeds solved by multiple shooting, and the return time above which a return was slow
    shooting: int = 0
    slow_time: Optional[float] = None
    duplicates: int = 0
    orbits: List[PeriodicOrbit] = field(default_factory=list)
    messages: List[str] = field(default_factory=list)


def _recurrence_seeds(results, k_max: int, per_k: int, symmetric: bool, max_dist: float):
    """``(distance, state, k)`` of the closest returns ``x_{i+k} ~ x_i`` per ``k``, measured
    on the states (public layout; for a symmetric ball after the rotation about the axis 3
    that carries ``l_i`` to ``l_{i+k}``). Not on chart points: near ``gamma3 = +-1`` the
    chart ``(r1, r2)`` hides differences in ``R`` (``R = (gamma1 r1 + gamma2 r2)/rho^2, ...``,
    ``rho^2 = gamma1^2 + gamma2^2``), and a chart point carries up to four states."""
    out = []
    for k in range(1, k_max + 1):
        cands: List[Tuple[float, int, int]] = []
        for j, r in enumerate(results):
            X = np.asarray(r.states, dtype=float)
            if len(X) <= k:
                continue
            A, B = X[:-k], X[k:]
            if symmetric:
                th = r.points[:-k, 0] - r.points[k:, 0]
                c, s = np.cos(th), np.sin(th)
                A = A.copy()
                for b0 in (0, 3, 6):
                    a1, a2 = A[:, b0].copy(), A[:, b0 + 1].copy()
                    A[:, b0], A[:, b0 + 1] = c * a1 - s * a2, s * a1 + c * a2
            dist = np.max(np.abs(B - A), axis=1)
            idx = [i for i in range(len(dist)) if (i == 0 or dist[i] <= dist[i - 1])
                   and (i == len(dist) - 1 or dist[i] <= dist[i + 1])]
            cands += [(float(dist[i]), j, i) for i in idx if dist[i] <= max_dist]
        cands.sort()
        used: Dict[int, int] = {}
        n = 0
        for dist, j, i in cands:
            if used.get(j, 0) >= 2:  # at most two seeds per orbit and k
                continue
            used[j] = used.get(j, 0) + 1
            out.append((dist, results[j].states[i], k))
            n += 1
            if n >= per_k:
                break
    return out


def _grid_seeds(states, runs, k_max: int, per_k: int, symmetric: bool):
    """``(residual, state, k)``: the ``per_k`` states of the grid with the smallest
    ``|x_k - S x_0|`` (state distance, rotation for a symmetric ball) per ``k``."""
    out = []
    for k in range(1, k_max + 1):
        ranked = []
        for x0, r in zip(states, runs):
            if len(r.states) < k:
                continue
            a = np.asarray(x0, dtype=float).copy()
            b = np.asarray(r.states[k - 1], dtype=float)
            if symmetric:
                th = _l_of_public(a) - _l_of_public(b)
                c, s = math.cos(th), math.sin(th)
                for b0 in (0, 3, 6):
                    a[b0], a[b0 + 1] = c * a[b0] - s * a[b0 + 1], s * a[b0] + c * a[b0 + 1]
            ranked.append((float(np.max(np.abs(b - a))), x0, k))
        ranked.sort(key=lambda t: t[0])
        out += ranked[:per_k]
    return out


def _l_of_public(x: np.ndarray) -> float:
    """An angle of a public reduced state that the rotation about the axis 3 by ``theta``
    lowers by ``theta`` (as it lowers ``l``): ``atan2(gamma1, gamma2)``; only differences
    are used."""
    return math.atan2(float(x[3]), float(x[4]))


def _search_mparallel(prob: Problem, levels: MParallelLevels, k_max: int, *, n_grid: int, per_k: int, g0: float,
                      direction: Literal[1, -1], max_iter: int, report: bool):
    """The M||gamma map: seeds from a chart grid ``(l, L/G)`` (every root), ranked by their
    ``k``-th return residual."""
    from .charts import mparallel_states_on_section
    from .sections import poincare_sections

    n_l = max(4, int(round(math.sqrt(2 * n_grid))))
    n_L = max(2, n_grid // n_l)
    states = []
    for l0 in np.linspace(0.0, 2 * math.pi, n_l, endpoint=False):
        for lg in np.linspace(-0.98, 0.98, n_L):
            try:
                states += list(mparallel_states_on_section(prob.params, **levels.as_kwargs(), point=(float(l0), float(lg)),
                                                           g0=g0))
            except (EmptyLevelError, StateError):
                continue
    if not states:
        raise EmptyLevelError(f"no state of the level {levels!r} on the section grid ({n_l} x {n_L} chart points)")
    runs = poincare_sections("mparallel", prob.params, states, n_points=k_max, g0=g0, direction=direction,
                             t_end=T_MAX_SEED * k_max)
    seeds = _grid_seeds(states, runs, k_max, per_k, False)
    rep = SearchReport(seeds={"grid": len(seeds)})
    return _solve_seeds(prob, levels, seeds, rep, g0, direction, max_iter, report)


@dataclass(frozen=True)
class SearchOptions:
    """The less common options of :func:`periodic_orbits`' seeding and Newton runs
    (``options=tb.SearchOptions(...)``; the old keywords of the same names are deprecated).

    Attributes
    ----------
    n_seeds : int
        Seed orbits sampled uniformly on the admissible region.
    per_k : int
        Recurrence seeds tried per ``k`` (the closest returns, at most two per orbit).
    n_grid : int
        Chart-grid seeds of the M||gamma system (``n_grid`` points ``(l, L/G)``).
    max_dist : float
        Largest chart distance of a recurrence used as a seed.
    reversor_seeds : int
        Points on each reversor's fixed set tried per ``k`` (asymmetric ball only).
    max_iter : int
        Newton iterations per seed.
    slow_factor : float, optional
        Slow returns (asymmetric ball of the reduced system): a seed whose ``k`` returns
        include one slower than ``slow_factor`` times the median return time of the grid's
        seed runs, or whose section points include one with chart regularity below
        ``min_regularity`` (:func:`taylorball.periodic_sections.chart_regularity`), is solved
        by multiple shooting (:func:`taylorball.periodic_shooting.shoot_periodic_orbit`)
        from its own section points, with the segments chosen by
        :func:`taylorball.periodic_shooting.shooting_segments` (``rotate=True``): no segment
        ends at a slow return's crossing or near the singular point, and the slow segments are
        cut into time pieces of at most ``max_piece_time``. ``None`` (default): every seed by
        :func:`taylorball.periodic_orbit`, as before.
    max_piece_time : float
        The longest time piece of a slow segment.
    min_regularity : float
        Section points less regular than this are no segment ends.
    """

    n_seeds: int = 48
    per_k: int = 12
    n_grid: int = 300
    max_dist: float = 0.5
    reversor_seeds: int = 8
    max_iter: int = 40
    slow_factor: Optional[float] = None
    max_piece_time: float = 1.0
    min_regularity: float = 0.1

    def __post_init__(self) -> None:
        if self.slow_factor is not None and not (isinstance(self.slow_factor, (int, float)) and
                                                 math.isfinite(self.slow_factor) and self.slow_factor > 1):
            raise UsageError(f"SearchOptions.slow_factor must be None or a finite number > 1 (times the median "
                             f"return time), got {self.slow_factor!r}")
        if not (isinstance(self.max_piece_time, (int, float)) and math.isfinite(self.max_piece_time)
                and self.max_piece_time > 0):
            raise UsageError(f"SearchOptions.max_piece_time must be a positive finite flow time, "
                             f"got {self.max_piece_time!r}")
        if not (isinstance(self.min_regularity, (int, float)) and 0 <= self.min_regularity < 1):
            raise UsageError(f"SearchOptions.min_regularity must be a number in [0, 1), got {self.min_regularity!r}")


@moved(SearchOptions, "n_seeds", "per_k", "n_grid", "max_dist", "reversor_seeds", "max_iter")
def periodic_orbits(kind: Union[KindName, Problem], params: Optional[ParamsLike] = None,
                    levels: Optional[Levels] = None, *, k_max: int = 3, n_points: int = 200, g0: float = 0.0,
                    direction: Direction = 1, seed: int = 0, report: bool = False,
                    options: Optional[SearchOptions] = None) -> Union[List[PeriodicOrbit], SearchReport]:
    r"""Periodic orbits with ``1 <= k <= k_max`` section crossings on a level (reduced or M||gamma system).

    Parameters
    ----------
    kind, params
        ``"reduced"`` and a :class:`~taylorball.BallParams`, or ``"mparallel"`` and its
        parameters (or a Problem, float64). For ``"mparallel"`` only the chart-grid seeds
        (``n_grid`` points ``(l, L/G)``, every root) are used.
    levels : Levels or MParallelLevels
        The level (``C, M_gamma, h``; ``lam, h``).
    k_max : int
        Largest period in crossings.
    n_points
        Crossings of each seed orbit.
    report : bool
        Return a :class:`SearchReport` (seeds, failures, duplicates) instead of the list.
    options : SearchOptions, optional
        ``n_seeds``, ``per_k``, ``n_grid``, ``max_dist``, ``reversor_seeds``, ``max_iter``
        (default ``SearchOptions()``; the keywords of the same names are their deprecated
        old form).

    Returns
    -------
    list of PeriodicOrbit (sorted by ``k``, then period), or a SearchReport.

    Raises
    ------
    UsageError
        ``k_max < 1``; a kind without a section; levels of the wrong type.
    EmptyLevelError
        A level with no admissible region.
    """
    from .charts import section_admissible_sample, states_on_section
    from .sections import poincare_sections

    options = options_of(options, SearchOptions, "periodic_orbits")
    n_seeds, per_k, n_grid, max_dist = options.n_seeds, options.per_k, options.n_grid, options.max_dist
    reversor_seeds, max_iter = options.reversor_seeds, options.max_iter

    prob = orbit_problem(kind, params)
    want = Levels if prob.kind == "reduced" else MParallelLevels
    if not isinstance(levels, want):
        raise UsageError(f"levels must be a taylorball.{want.__name__} for kind={prob.kind!r}, got {levels!r}")
    if direction not in (1, -1):
        raise UsageError(f"direction must be +1 or -1 (the crossings kept), got {direction!r}")
    sdir: Literal[1, -1] = 1 if direction == 1 else -1
    if not isinstance(k_max, (int, np.integer)) or isinstance(k_max, bool) or k_max < 1:
        raise UsageError(f"k_max must be an integer >= 1, got {k_max!r}")
    if prob.kind == "mparallel":
        assert isinstance(levels, MParallelLevels)
        return _search_mparallel(prob, levels, int(k_max), n_grid=n_grid, per_k=per_k, g0=g0, direction=sdir,
                                 max_iter=max_iter, report=report)
    assert isinstance(levels, Levels)
    ball = prob.params
    rep = SearchReport()
    sym = _has_axial_symmetry(prob)
    # 1. grid seeds: every state (all branches) of a sample of the admissible region, ranked
    #    by its own k-th return residual
    region = section_admissible_sample(ball, **levels.as_kwargs(), g0=g0, n=n_grid,  # type: ignore[arg-type]
                                       direction=sdir, seed=seed)
    grid_states = [st for sts in region["states"] for st in sts]
    grid_runs = poincare_sections("reduced", ball, grid_states, n_points=int(k_max), g0=g0, direction=direction,
                                  batch=True, t_end=T_MAX_SEED * int(k_max))
    seeds = _grid_seeds(grid_states, grid_runs, int(k_max), per_k, sym)
    rep.seeds["grid"] = len(seeds)
    if options.slow_factor is not None and not sym:
        # the level's median return time, from the grid's seed runs (k_max returns each)
        dts = np.concatenate([np.diff(np.concatenate([[0.0], np.asarray(r.times, dtype=float)])) for r in grid_runs])
        rep.slow_time = float(options.slow_factor) * float(np.median(dts)) if len(dts) else None
    # 2. near-recurrences of longer orbits (regular and chaotic)
    if n_seeds > 0:
        runs = poincare_sections("reduced", ball, grid_states[:: max(1, len(grid_states) // n_seeds)][:n_seeds],
                                 n_points=n_points, g0=g0, direction=direction, batch=True,
                                 t_end=T_MAX_SEED * n_points)
        rec = _recurrence_seeds(runs, int(k_max), per_k, sym, max_dist)
        rep.seeds["recurrence"] = len(rec)
        seeds += rec
    # 3. the reversors' fixed sets on the section (sections g0 = 0 or pi): lines r2 = 0 at
    #    l in {0, pi/2, pi, 3 pi/2} (the symmetric ball: l = 0 only, l being cyclic), every
    #    sheet; states ranked by their k-th return residual, local minima along each line
    if g0 in (0.0, math.pi) and reversor_seeds > 0:
        pts = region["points"]
        r1s = np.linspace(float(np.min(pts[:, 1])), float(np.max(pts[:, 1])), reversor_seeds + 2)[1:-1]
        lines: Dict[Tuple[float, int], List[np.ndarray]] = {}
        for l0 in ((0.0,) if sym else (0.0, math.pi / 2, math.pi, 3 * math.pi / 2)):
            for r1 in r1s:
                try:
                    sts = states_on_section(ball, **levels.as_kwargs(), point=(l0, float(r1), 0.0), g0=g0,  # type: ignore[arg-type]
                                            direction=sdir)
                except (EmptyLevelError, StateError):
                    continue
                for j, st in enumerate(sts):
                    lines.setdefault((l0, j), []).append(st)
        flat = [st for v in lines.values() for st in v]
        line_runs = poincare_sections("reduced", ball, flat, n_points=int(k_max), g0=g0, direction=direction,
                                      batch=True, t_end=T_MAX_SEED * int(k_max)) if flat else []
        n_rev, pos = 0, 0
        for v in lines.values():
            runs_v = line_runs[pos:pos + len(v)]
            pos += len(v)
            for k in range(1, int(k_max) + 1):
                ranked = _grid_seeds(v, runs_v, k, len(v), sym)
                ranked = [t for t in ranked if t[2] == k]
                # back in line order, then the local minima of the residual along the line
                order = {id(st): i for i, st in enumerate(v)}
                res = np.full(len(v), np.inf)
                for r_, st, _ in ranked:
                    res[order[id(st)]] = r_
                for i in range(len(v)):
                    if np.isfinite(res[i]) and (i == 0 or res[i] <= res[i - 1]) and \
                            (i == len(v) - 1 or res[i] <= res[i + 1]):
                        seeds.append((float(res[i]), v[i], k))
                        n_rev += 1
        rep.seeds["reversor"] = n_rev
    return _solve_seeds(prob, levels, seeds, rep, g0, direction, max_iter, report, options)


def _shooting_plan(prob: Problem, st, k: int, g0: float, direction: Literal[1, -1], slow: float,
                   options: SearchOptions):
    """For a seed with a slow return or a section point near the chart's singular point: its
    section points, segments and time pieces (:func:`shooting_segments`); ``None`` for a seed
    without either (solved by single shooting)."""
    from .periodic_sections import chart_regularity
    from .periodic_shooting import shooting_segments
    from .sections import Section

    run = Section(prob, g0, direction).run(st, n_points=k, t_end=T_MAX_SEED * k)
    if len(run.times) < k:
        return None  # no k returns: single shooting reports why
    pts = [np.asarray(st, dtype=float)] + [np.asarray(x, dtype=float) for x in run.states[:k - 1]]
    dt = np.diff(np.concatenate([[0.0], np.asarray(run.times[:k], dtype=float)]))
    reg = chart_regularity(prob, np.array(pts))
    if float(np.max(dt)) <= slow and float(np.min(reg)) >= options.min_regularity:
        return None
    starts, ks, splits = shooting_segments(dt, slow=slow, max_piece_time=options.max_piece_time, regularity=reg,
                                           min_regularity=options.min_regularity, rotate=True)
    return [pts[j] for j in starts], ks, splits


def _solve_seeds(prob, levels, seeds, rep: SearchReport, g0, direction, max_iter, report,
                 options: Optional[SearchOptions] = None):
    """Newton from each seed (multiple shooting for a slow seed when ``rep.slow_time`` is set);
    failures counted, duplicates dropped."""
    from .periodic import NewtonFailure
    from .periodic_shooting import ShootingOptions, shoot_periodic_orbit

    found: List[PeriodicOrbit] = []
    k_max = max((k for _, _, k in seeds), default=0)
    for d0, st, k in seeds:
        how = "single"
        try:
            plan = None if rep.slow_time is None or options is None else \
                _shooting_plan(prob, st, k, g0, direction, rep.slow_time, options)
            if plan is None:
                o = periodic_orbit(prob, None, st, k, levels=levels, g0=g0, direction=direction,
                                   options=NewtonOptions(max_iter=max_iter))
            else:
                how = "shooting"
                rep.shooting += 1
                o = shoot_periodic_orbit(prob, None, plan[0], plan[1], levels=levels, g0=g0, direction=direction,
                                         splits=plan[2], options=ShootingOptions(max_iter=max_iter))
        except (IntegrationError, StateError) as exc:
            rep.failures += 1
            rep.failed.append((k, float(d0), float(exc.residual) if isinstance(exc, NewtonFailure) else math.nan,
                               how))
            rep.messages.append(f"k={k}: {type(exc).__name__}: {str(exc)[:160]}")
            continue
        except TaylorballError as exc:  # pragma: no cover - reported, not raised
            rep.failures += 1
            rep.failed.append((k, float(d0), math.nan, how))
            rep.messages.append(str(exc)[:200])
            continue
        if o.k > k_max:  # a split segment's grazing crossings counted at the solution
            rep.messages.append(f"k={k} seed ({how}): an orbit with k = {o.k} > k_max, period {o.period!r}, "
                                f"state {list(map(float, o.state))!r}: not kept")
            continue
        if any(same_orbit(f, o) for f in found):
            rep.duplicates += 1
            continue
        found.append(o)
    found.sort(key=lambda o: (o.k, o.period))
    rep.orbits = found
    return rep if report else found
