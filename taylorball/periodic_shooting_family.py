r"""A family of periodic orbits in a level value by multiple shooting: :func:`continue_shooting`.

The single-shooting continuations of :mod:`taylorball.periodic_continuation` solve ``P^k x =
x`` at each step, which fails on the chaotic Fig. 4 levels (docs/skeleton.md). Here every
step is a :func:`taylorball.periodic_shooting.shoot_periodic_orbit` solve: the orbit's ``k``
section points are the unknowns, long segments may be split in time (``max_piece_time``), and
the guess at the next level value is the secant through the last two solutions' section points
(the points themselves at the first step), moved onto the new level and the section.

Natural-parameter steps: a step that fails (no convergence, a jump to another orbit, a
change of ``k``) is halved down to ``h_min``; a step that succeeds doubles the next, up to
``h_max``. Between consecutive solutions the branch records the same events as
:func:`taylorball.periodic_continuation.continue_in_level` (a change of stability type, a
multiplier through -1 or +1). Natural steps end at a fold in the parameter; the branch then
stops with the reason (:mod:`taylorball.periodic_shooting_arclength` follows it through).
"""

from __future__ import annotations

from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from ._propagate import public_state, start_state
from .errors import IntegrationError, StateError, UsageError
from .levels import Levels
from .params import BallParams
from .periodic import PeriodicOrbit
from .periodic_continuation import Branch, _events, _levels_at, _start_value, halving_step, toward
from .periodic_shooting import ShootingOptions, _shoot, shoot_periodic_orbit, shooting_segments, time_splits
from .sections import Section

__all__ = ["continue_shooting", "orbit_section_states", "recurrence_shooting"]


def orbit_section_states(orbit: PeriodicOrbit) -> np.ndarray:
    """The ``k`` section points of ``orbit`` as public states (``k x n``), by a run of the
    section integrator from ``orbit.state``."""
    prob = orbit.problem
    if prob is None:
        raise UsageError("orbit has no problem attached (a PeriodicOrbit from periodic_orbit or the shooting)")
    first = np.asarray(orbit.state, dtype=float)
    if orbit.k == 1:
        return first[None, :]
    run = Section(prob, orbit.g0, orbit.direction).run(first, n_points=orbit.k,  # type: ignore[arg-type]
                                                          t_end=2.0 * orbit.period + 1.0)
    rest = [np.asarray(s, dtype=float) for t, s in zip(run.times, run.states) if float(t) > 1e-6][:orbit.k - 1]
    return np.vstack([first[None, :]] + [r[None, :] for r in rest])


def _onto_constraints(orbit: PeriodicOrbit, state: np.ndarray) -> np.ndarray:
    """A predicted public state moved onto the system's constraints (``|gamma| = 1``, ...)."""
    prob = orbit.problem
    x = start_state(prob, state, project_state=True)
    return np.asarray(public_state(prob.system, prob.pars, x, prob.spec), dtype=float)


def _check_family(orbit: PeriodicOrbit, levels: Levels, parameter: str, target: float,
                  steps: Sequence[Tuple[str, Any]], ks: Optional[Sequence[int]], options: Optional[ShootingOptions],
                  caller: str) -> Tuple[float, float, List[float], Tuple[int, ...], ShootingOptions]:
    """The checks of a shooting family's start (``caller`` names the function): the start's
    value, the target, the steps ``(least, first, largest)`` (``steps`` their names and values),
    the segments' crossings and Newton's options with ``section_tol`` raised to 1."""
    if orbit.problem is None or orbit.problem.kind != "reduced":
        raise UsageError(f"{caller} follows orbits of kind='reduced' (a PeriodicOrbit)")
    if not isinstance(levels, Levels):
        raise UsageError(f"levels must be a taylorball.Levels, got {levels!r}")
    if parameter == "Omega":
        raise UsageError(f"{caller} follows a level value ('C', 'M_gamma', 'h'), not 'Omega'")
    w0 = _start_value(orbit, levels, parameter)
    (n_lo, v_lo), (n_mid, v_mid), (n_hi, v_hi) = steps
    try:
        tgt = float(target)
        hs = [float(v_lo), float(v_mid), float(v_hi)]
    except (TypeError, ValueError):
        raise UsageError(f"target and the steps must be floats, got target={target!r}, {n_mid}={v_mid!r}, "
                         f"{n_lo}={v_lo!r}, {n_hi}={v_hi!r}") from None
    if not np.isfinite(tgt) or tgt == w0:
        raise UsageError(f"target must be a finite value other than the start's {parameter} = {w0!r}, got {target!r}")
    if not (np.all(np.isfinite(hs)) and 0 < hs[0] <= hs[1] <= hs[2]):
        raise UsageError(f"the steps must satisfy 0 < {n_lo} <= {n_mid} <= {n_hi}, got {n_lo}={v_lo!r}, "
                         f"{n_mid}={v_mid!r}, {n_hi}={v_hi!r}")
    base = options if options is not None else ShootingOptions()
    opts = ShootingOptions(max_iter=base.max_iter, rtol=base.rtol, section_tol=1.0, max_step=base.max_step)
    ks_t = tuple([1] * orbit.k if ks is None else ks)
    if sum(ks_t) != orbit.k or any(int(q) < 1 for q in ks_t):
        raise UsageError(f"ks must be integers >= 1 adding up to the orbit's k = {orbit.k}, got {ks!r}")
    return w0, tgt, hs, ks_t, opts


def continue_shooting(orbit: PeriodicOrbit, levels: Levels, parameter: str, target: float, *,
                      h0: float = 0.01, h_min: float = 1e-4, h_max: float = 0.2,
                      ks: Optional[Sequence[int]] = None, max_piece_time: Optional[float] = None,
                      max_steps: int = 500,
                      jump_ratio: float = 0.5, options: Optional[ShootingOptions] = None) -> Branch:
    r"""Follow ``orbit`` (on ``levels``) in the level value ``parameter`` towards ``target`` by
    multiple shooting (one segment per crossing).

    Parameters
    ----------
    orbit : PeriodicOrbit
        The start, of kind ``"reduced"``, on ``levels``.
    levels : Levels
    parameter : {"C", "M_gamma", "h"}
        The level value followed (the captions' ``G, H, h``); ``Omega`` and the others kept.
    target : float
        Where to go (the branch ends there or where it stops).
    h0, h_min, h_max : float
        First, least and largest step in ``parameter``.
    ks : sequence of int, optional
        Crossings per segment (default one each); e.g. a segment of 2 through a crossing
        that grazes the section, so that the grazing point is no unknown.
    max_piece_time : float, optional
        Split segments longer than this in time (:func:`~taylorball.periodic_shooting.shoot_periodic_orbit`;
        the pieces from the last solution's segment times).
    max_steps : int
        Successful steps at most.
    jump_ratio : float
        A solution farther than ``jump_ratio`` times the predicted change from the secant
        prediction (and farther than ``1e-6``) is refused as another orbit (from the second
        step on).
    options : ShootingOptions, optional
        Newton's options; its ``section_tol`` is raised to 1 (the predicted guesses are off
        the new level and are moved onto it).

    Returns
    -------
    Branch
        Its first orbit is ``orbit`` solved again by the shooting (``ks``, the splits).
        Then ``parameter``, the values reached, the orbits, the events, and ``stopped``
        (``"reached"`` or why not).

    Raises
    ------
    UsageError
        A start that is not a reduced-system orbit, ``levels`` not a :class:`Levels`, an
        unknown ``parameter``, steps that are not ``0 < h_min <= h0 <= h_max``.
    """
    w0, tgt, hs, ks_t, opts = _check_family(orbit, levels, parameter, target,
                                            (("h_min", h_min), ("h0", h0), ("h_max", h_max)), ks, options,
                                            "continue_shooting")
    sgn = 1.0 if tgt > w0 else -1.0
    params = orbit.problem.params
    all_pts = orbit_section_states(orbit)
    starts = np.concatenate([[0], np.cumsum(ks_t)[:-1]]).astype(int)

    def solve(guess, lv, seg_times):
        sp = None if max_piece_time is None or seg_times is None else time_splits(seg_times, max_piece_time)
        o, st, tm = _shoot("reduced", params, list(guess), ks_t, levels=lv, g0=orbit.g0, direction=orbit.direction,
                           fp_type=float, tol=None, t_max=None, splits=sp,
                           max_piece_time=max_piece_time if seg_times is None else None, options=opts)
        return o, np.array([np.asarray(x, dtype=float) for x in st]), tm

    first, p0, times = solve(all_pts[starts], levels, None)
    orbits = [first]
    values = [w0]
    pts = [p0]
    events: List[Dict[str, Any]] = []
    stopped = "reached"

    def attempt(w: float):
        w_from = values[-1]
        if len(pts) >= 2:
            pred = pts[-1] + (pts[-1] - pts[-2]) * ((w - w_from) / (values[-1] - values[-2]))
            pred = np.array([_onto_constraints(orbit, p) for p in pred])
        else:
            pred = pts[-1]
        new, new_pts, new_times = solve(pred, _levels_at(levels, parameter, w), times)
        if len(pts) >= 2:
            corr = float(np.max(np.abs(new_pts - pred)))
            chg = float(np.max(np.abs(pred - pts[-1])))
            if corr > jump_ratio * chg + 1e-6:
                raise StateError(f"the solution is {corr:.3g} from the secant prediction (predicted change "
                                 f"{chg:.3g}): another orbit")
        return new, new_pts, new_times

    h = hs[1]
    while abs(values[-1] - tgt) > 1e-12 * (1 + abs(tgt)):
        if len(orbits) > max_steps:
            stopped = f"max_steps = {max_steps} reached at {parameter} = {values[-1]!r}"
            break
        w_from = values[-1]
        # NewtonFailure is an IntegrationError: refused like a jump
        step = halving_step(h, toward(w_from, tgt, snap=False), attempt, lambda _n, h_next: h_next < hs[0])
        if step.failure is not None:
            stopped = (f"no solution at {parameter} = {step.value!r} with a step of {step.used:.3g} from "
                       f"{w_from!r} (steps halved below h_min = {hs[0]}; a fold in {parameter}, or the "
                       f"shooting's basin is smaller than the secant's error): {step.failure}")
            break
        new, new_pts, times = step.result
        events += _events(orbits[-1], new, w_from, step.value)
        orbits.append(new)
        values.append(step.value)
        pts.append(new_pts)
        h = min(2.0 * step.used, hs[2])
    return Branch(np.array(values), orbits, events, stopped, parameter=parameter)


def _recurrence_guess(X: np.ndarray, t: np.ndarray, i: int, k: int, slow: float, max_piece_time: float):
    """The shooting guess of the near-recurrence ``x_{i+k} ~ x_i`` of one orbit's section
    points ``X`` (public) at times ``t``: the points ``x_i .. x_{i+k-1}`` as segment starts,
    except the end of a slow return (:func:`~taylorball.periodic_shooting.shooting_segments`)."""
    starts, ks, splits = shooting_segments(np.diff(t[i:i + k + 1]), slow=slow, max_piece_time=max_piece_time)
    return [X[i + j] for j in starts], ks, list(splits)


def recurrence_shooting(params: BallParams, levels: Levels, *, k_range: Sequence[int] = (3, 12), n_orbits: int = 20,
                        n_points: int = 2000, per_k: int = 2, slow: float = 3.0, max_piece_time: float = 1.0,
                        max_dist: float = 1.0, seed: int = 1, g0: float = 0.0,
                        options: Optional[ShootingOptions] = None) -> Dict[str, Any]:
    r"""Periodic orbits of the reduced system on ``levels`` by multiple shooting from
    near-recurrences ``x_{i+k} ~ x_i`` of orbits started on a sample of the admissible region,
    slow returns split in time.

    The closest ``per_k`` local minima of ``max |x_{i+k} - x_i|`` (public state) per ``k`` in
    ``k_range`` (at most two per orbit and ``k``, none farther than ``max_dist``) are the seeds;
    each seed's ``k`` section points are the segment starts, except that a crossing ending a
    return slower than ``slow`` is not a segment end (it joins the next segment), and segments
    longer than ``slow`` are cut in time pieces of at most ``max_piece_time``
    (:func:`~taylorball.periodic_shooting.shoot_periodic_orbit`).

    Parameters
    ----------
    params : BallParams
    levels : Levels
    k_range : (int, int)
        Smallest and largest ``k``.
    n_orbits, n_points : int
        Orbits and section points per orbit.
    per_k, slow, max_piece_time, max_dist, seed, g0
        As above; ``seed`` of the sample of the admissible region.
    options : ShootingOptions, optional

    Returns
    -------
    dict
        ``{"seeds": int, "converged": int, "orbits": list of PeriodicOrbit (distinct),
        "failures": list of (k, distance, best residual), "cpu_s": float}``.

    Raises
    ------
    UsageError
        A bad ``k_range`` or count.
    """
    import time

    from .charts import section_admissible_sample
    from .periodic import NewtonFailure
    from .periodic_search import same_orbit
    from .sections import poincare_sections

    try:
        k_lo, k_hi = (int(k_range[0]), int(k_range[1]))
    except (TypeError, ValueError, IndexError):
        raise UsageError(f"k_range must be (k_min, k_max) integers, got {k_range!r}") from None
    if not 1 <= k_lo <= k_hi:
        raise UsageError(f"k_range must be (k_min, k_max) with 1 <= k_min <= k_max, got {k_range!r}")
    for name, v in (("n_orbits", n_orbits), ("n_points", n_points), ("per_k", per_k)):
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
            raise UsageError(f"{name} must be an integer >= 1, got {v!r}")
    if not isinstance(levels, Levels):
        raise UsageError(f"levels must be a taylorball.Levels, got {levels!r}")
    t0 = time.process_time()
    region = section_admissible_sample(params, **levels.as_kwargs(), g0=g0, n=4 * n_orbits, seed=seed)
    states = [st for sts in region["states"] for st in sts]
    starts = states[:: max(1, len(states) // n_orbits)][:n_orbits]
    runs = poincare_sections("reduced", params, starts, n_points=n_points, g0=g0, batch=True, t_end=100.0 * n_points)
    data = [(np.asarray(r.states, dtype=float), np.concatenate([[0.0], np.asarray(r.times, dtype=float)]))
            for r in runs]
    # the start state is the orbit's point 0 (time 0)
    data = [(np.vstack([np.asarray(s0, dtype=float)[None, :], X]), t) for s0, (X, t) in zip(starts, data)]
    seeds = []
    for k in range(k_lo, k_hi + 1):
        cands = []
        for j, (X, t) in enumerate(data):
            if len(X) <= k:
                continue
            dist = np.max(np.abs(X[k:] - X[:-k]), axis=1)
            for i in range(len(dist)):
                if (i == 0 or dist[i] <= dist[i - 1]) and (i == len(dist) - 1 or dist[i] <= dist[i + 1]) \
                        and dist[i] <= max_dist:
                    cands.append((float(dist[i]), j, i))
        cands.sort()
        used: Dict[int, int] = {}
        for d, j, i in cands:
            if used.get(j, 0) >= 2:
                continue
            used[j] = used.get(j, 0) + 1
            seeds.append((d, j, i, k))
            if sum(1 for s in seeds if s[3] == k) >= per_k:
                break
    found: List[PeriodicOrbit] = []
    failures = []
    n_conv = 0
    for d, j, i, k in seeds:
        X, t = data[j]
        guess, ks, splits = _recurrence_guess(X, t, i, k, slow, max_piece_time)
        try:
            o = shoot_periodic_orbit("reduced", params, guess, ks, levels=levels, g0=g0, splits=splits,
                                     options=options)
        except NewtonFailure as exc:
            failures.append((k, d, float(exc.residual)))
            continue
        except (IntegrationError, StateError):
            failures.append((k, d, float("nan")))
            continue
        n_conv += 1
        if not any(same_orbit(o, f) for f in found):
            found.append(o)
    return {"seeds": len(seeds), "converged": n_conv, "orbits": found, "failures": failures,
            "cpu_s": time.process_time() - t0}
