r"""Periodic orbits by multiple shooting: :func:`shoot_periodic_orbit`, :func:`periodic_orbit_shooting`.

On a chaotic level the ``k``-th return map is strongly expanding (its multipliers grow like
``|mu|^k``), and Newton on ``P^k x = x`` from one state (:func:`taylorball.periodic_orbit`)
has a small basin: on the Fig. 4a level every one of 66 seeds failed (docs/skeleton.md).
Multiple shooting splits the orbit at ``m`` of its section points. The unknowns are the
internal states ``x_0, ..., x_{m-1}``, each on the section and the level, and the equations

.. math:: P^{k_i}(x_i) - x_{i+1} = 0 \qquad (i = 0, \dots, m - 1,\ x_m = x_0),

with ``k_0 + ... + k_{m-1} = k`` section crossings in all. Each point is varied in the
tangent space of section and level at it, ``\Delta x_i = B_i w_i`` (``B_i`` an orthonormal
basis of the null space of the section's and the integrals' gradients, as in the
single-shooting Newton's null-space method), and moved back onto section and level after
each step. The Jacobian is block-cyclic: row block ``i`` holds ``\Pi_i\Phi_i B_i`` in the
column of ``w_i`` and ``-B_{i+1}`` in that of ``w_{i+1}``, ``\Phi_i`` the fundamental matrix
of segment ``i`` (:class:`taylorball.tangent.TangentSystem`, compact mode, one compiled
variational integrator copied per segment) and ``\Pi_i`` the projection along the flow
that accounts for the variation of the return time. The ``9m`` (``6m``) rows and ``3m``
(``2m``) unknowns are solved by least squares (the system is consistent at a solution);
a step is the Gauss-Newton step (halved until it lowers ``|F|_2`` or ``max |F|``), else a
Levenberg-Marquardt step (shortened towards the gradient of ``|F|^2`` until it lowers it);
no state moves by more than a fifth of ``|x|`` in one step.

The multiplier matrix is the product of the segments' ``3 x 3`` (``2 x 2``) maps
``B_{i+1}^T \Pi_i\Phi_i B_i``, so it is never formed from one expanding propagation. The
result is a :class:`taylorball.periodic.PeriodicOrbit` like the single-shooting one; its
``k`` section points come from a separate run of the section integrator from ``x_0``, which
must cross the section at the segments' points (to ``1e-6``), so a solution whose segments
skip or add a crossing is refused.

Only maps without a continuous symmetry: a dynamically symmetric ball (``I1 = I2``, relative
periodic orbits with a shift ``theta``) is refused with a :class:`~taylorball.errors.UsageError`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import List, Optional, Sequence, Tuple, Union

import math

import numpy as np
from numpy.typing import ArrayLike

from ._problem import Problem
from ._propagate import public_state
from ._typing import Direction, FpTypeLike, KindName, ParamsLike
from .errors import IntegrationError, StateError, UsageError
from .periodic import (RETURN_FACTOR, T_MIN, LevelsLike, NewtonFailure, PeriodicOrbit, _crossing_time, _Ctx,
                       _eval_geo, _f64, _flow, _has_axial_symmetry, _internal_guess, _internal_rows, _jacobian,
                       _level_targets, _minimal_k, _on_branch, _symmetry_of, _tangent_basis, _to_level,
                       _var_start, multiplier_summary, orbit_problem)
from .sections import Section, chart_points

__all__ = ["ShootingOptions", "shoot_periodic_orbit", "periodic_orbit_shooting", "segment_lengths", "time_splits",
           "shooting_segments", "MAX_PIECES"]


@dataclass(frozen=True)
class ShootingOptions:
    """The less common options of :func:`shoot_periodic_orbit`.

    Attributes
    ----------
    max_iter : int
        Newton iterations.
    rtol : float, optional
        Convergence: ``max_i |P^{k_i}(x_i) - x_{i+1}| <= rtol * max(1, |x|)``; default
        ``256 eps`` of ``fp_type`` (float64: 5.7e-14).
    section_tol : float
        How far each guess state may be off the section (``|e|``) and off the level (relative).
    max_step : float
        The largest change of any state component in one step, relative to ``max(1, |x|)``.
    """

    max_iter: int = 40
    rtol: Optional[float] = None
    section_tol: float = 1e-8
    max_step: float = 0.2


def segment_lengths(k: int, m: int) -> Tuple[int, ...]:
    """``m`` segment lengths (crossings) summing to ``k``, as equal as possible, longer first.

    >>> from taylorball.periodic_shooting import segment_lengths
    >>> segment_lengths(8, 3)
    (3, 3, 2)
    """
    if not isinstance(m, (int, np.integer)) or isinstance(m, bool) or not 1 <= m <= k:
        raise UsageError(f"shooting (the number of segments) must be an integer in [1, k = {k}], got {m!r}")
    q, r = divmod(int(k), int(m))
    return tuple(q + 1 if i < r else q for i in range(int(m)))


def _segment(ctx: _Ctx, z: np.ndarray, T_guess=None):
    """``(P^{k}(z), Pi Phi (float64), T)`` of one segment (``ctx.k`` crossings)."""
    T = _crossing_time(ctx, z) if T_guess is None else T_guess
    zT, Phi, T = _flow(ctx, z, T)
    _, PP = _jacobian(ctx, z, 0.0, zT, Phi, _eval_geo(ctx.prob, ctx.g0, z))
    return zT, PP, T


def _time_piece(prob: Problem, z: np.ndarray, tau: float):
    """``(phi_tau(z), Phi (float64), tau)``: a piece of fixed flow time ``tau``."""
    spec = prob.spec
    ts, ta = _var_start(prob, z)
    n = len(z)
    oc = ta.propagate_until(spec.scalar(tau))[0]
    if str(oc) != "taylor_outcome.time_limit":
        raise IntegrationError(f"the variational integration of a time piece stopped at t = {ta.time} ({oc})")
    Phi = np.asarray(ts.tangent_matrix(ta.state), dtype=object).astype(float)
    return ta.state[:n].copy(), Phi, spec.scalar(tau)


def _level_basis(prob: Problem, g0: float, z: np.ndarray) -> np.ndarray:
    """Orthonormal basis (columns, float64) of the level's tangent space at ``z`` (the null
    space of the integrals' gradients; a state inside a segment is not on the section)."""
    G = _f64(_eval_geo(prob, g0, z).grad_c)
    _, s, Vt = np.linalg.svd(G)
    rank = int(np.sum(s > 1e-10 * s[0]))
    return Vt[rank:].T


def _onto_level(prob: Problem, g0: float, targets: np.ndarray, x: np.ndarray, scale: float) -> np.ndarray:
    """``x`` moved onto the level only (minimal-norm Gauss-Newton on ``c = c*``)."""
    spec = prob.spec
    x = x.copy()
    prob.system.info.project(x)
    for _ in range(12):
        geo = _eval_geo(prob, g0, x)
        r = _f64(geo.c - targets)
        if float(np.max(np.abs(r))) <= 8 * spec.eps * scale:
            return x
        x = x - spec.array(np.linalg.lstsq(_f64(geo.grad_c), r, rcond=None)[0])
        prob.system.info.project(x)
    r = _f64(_eval_geo(prob, g0, x).c - targets)
    if float(np.max(np.abs(r))) > 1e3 * spec.eps * scale:
        raise StateError(f"could not move a state inside a segment onto the level (residual "
                         f"{float(np.max(np.abs(r))):.1e})")
    return x


#: The most time pieces one segment may be cut into (each piece is one variational run and
#: four unknowns more): a bound against a ``max_piece_time`` tiny beside the return times.
MAX_PIECES = 1000


def time_splits(times: Sequence[float], max_piece_time: float) -> Tuple[Tuple[float, ...], ...]:
    """Time pieces cutting segments of flow times ``times`` so that no piece is longer than
    ``max_piece_time``: a segment of time ``T`` gets ``p - 1`` pieces of time ``T/p``,
    ``p = ceil(T / max_piece_time)`` (the ``p``-th piece is the rest up to the segment's
    crossing); the ``splits`` of :func:`shoot_periodic_orbit`.

    >>> from taylorball.periodic_shooting import time_splits
    >>> time_splits([1.0, 6.0], 2.5)
    ((), (2.0, 2.0))
    """
    if not isinstance(max_piece_time, (int, float, np.floating)) or isinstance(max_piece_time, bool) \
            or not math.isfinite(max_piece_time) or max_piece_time <= 0:
        raise UsageError(f"max_piece_time must be a positive finite flow time, got {max_piece_time!r}")
    out = []
    for T in times:
        if not (math.isfinite(float(T)) and float(T) > 0):
            raise UsageError(f"time_splits: the segments' flow times must be positive and finite, got {T!r}")
        p = max(1, math.ceil(float(T) / float(max_piece_time)))
        if p > MAX_PIECES:
            raise UsageError(f"max_piece_time={max_piece_time!r} cuts a segment of flow time {float(T)!r} into "
                             f"{p} pieces; at most {MAX_PIECES} per segment (max_piece_time >= "
                             f"{float(T) / MAX_PIECES!r})")
        out.append(tuple([float(T) / p] * (p - 1)))
    return tuple(out)


def shooting_segments(times: ArrayLike, *, slow: float, max_piece_time: float,
                      regularity: Optional[ArrayLike] = None, min_regularity: float = 0.0,
                      rotate: bool = False) -> Tuple[Tuple[int, ...], Tuple[int, ...], Tuple[Tuple[float, ...], ...]]:
    r"""Segment ends and time pieces of a multiple-shooting guess made of ``k`` consecutive
    section points ``x_0 .. x_{k-1}`` of a near-periodic orbit (``x_k ~ x_0``), ``times[j]``
    the flow time from ``x_j`` to the next: ``(starts, ks, splits)`` for
    :func:`shoot_periodic_orbit` with the states ``x_j, j in starts``.

    A point is no segment end (its crossing joins the segment before it) when the return
    ending at it is slow (longer than ``slow``: such a crossing is often a grazing of the
    section, where a small change adds or removes a pair of crossings) or when it lies near
    the chart's singular point ``M || e3`` (its ``regularity``, :func:`taylorball.periodic_sections.chart_regularity`,
    below ``min_regularity``: there the section's tangent space is ill-conditioned). A segment
    longer than ``slow`` is cut into time pieces of at most ``max_piece_time``
    (:func:`time_splits`). Without ``rotate`` the first segment starts at ``x_0``; with it, at
    the first point that is a segment end by these rules (failing that, the point after the
    fastest return), so ``starts`` may begin at any ``j`` and wrap round.

    >>> from taylorball.periodic_shooting import shooting_segments
    >>> shooting_segments([1.0, 9.0, 1.2, 1.1], slow=3.0, max_piece_time=2.5)
    ((0, 1, 3), (1, 2, 1), ((), (2.04, 2.04, 2.04, 2.04), ()))
    >>> shooting_segments([1.0, 9.0], slow=3.0, max_piece_time=5.0, rotate=True)
    ((1,), (2,), ((5.0,),))
    """
    times = [float(t) for t in np.atleast_1d(np.asarray(times, dtype=float))]
    k = len(times)
    if k < 1:
        raise UsageError("shooting_segments: times must hold the flow times of k >= 1 returns, got none")
    if not (isinstance(slow, (int, float, np.floating)) and math.isfinite(slow) and slow > 0):
        raise UsageError(f"slow must be a positive finite flow time, got {slow!r}")
    if not (isinstance(min_regularity, (int, float, np.floating)) and 0 <= min_regularity < 1):
        raise UsageError(f"min_regularity must be a number in [0, 1), got {min_regularity!r}")
    reg = None if regularity is None else [float(r) for r in np.atleast_1d(np.asarray(regularity, dtype=float))]
    if reg is not None and len(reg) != k:
        raise UsageError(f"regularity must hold one value per section point ({k}), got {len(reg)}")

    def joins(j: int) -> bool:
        return float(times[j - 1]) > slow or (reg is not None and reg[j] < min_regularity)

    s0 = 0
    if rotate:
        s0 = min(range(k), key=lambda j: (joins(j), float(times[j - 1])))
    starts, ks, seg_t = [s0], [1], [float(times[s0])]
    for i in range(1, k):
        j = (s0 + i) % k
        if joins(j):  # x_j ends a slow return, or is near the singular point: no segment starts there
            ks[-1] += 1
            seg_t[-1] += float(times[j])
        else:
            starts.append(j)
            ks.append(1)
            seg_t.append(float(times[j]))
    splits = tuple(time_splits([T], max_piece_time)[0] if T > slow else () for T in seg_t)
    return tuple(starts), tuple(ks), splits


def _check_splits(splits, m: int) -> Tuple[Tuple[float, ...], ...]:
    if splits is None:
        return tuple(() for _ in range(m))
    try:
        sp = tuple(tuple(float(t) for t in s) for s in splits)
    except (TypeError, ValueError):
        raise UsageError(f"splits must hold {m} sequences of flow times (one per segment), got {splits!r}") from None
    if len(sp) != m or any(not (math.isfinite(t) and t > 0) for s in sp for t in s):
        raise UsageError(f"splits must hold {m} sequences of positive finite flow times (one per segment; "
                         f"() for a segment not split), got {splits!r}")
    if any(len(s) >= MAX_PIECES for s in sp):
        raise UsageError(f"splits: at most {MAX_PIECES - 1} cuts per segment, got "
                         f"{max(len(s) for s in sp)}")
    return sp


def shoot_periodic_orbit(kind: Union[KindName, Problem], params: Optional[ParamsLike] = None,
                         states: Optional[Sequence[ArrayLike]] = None, ks: Optional[Sequence[int]] = None, *,
                         levels: LevelsLike = None, g0: float = 0.0, direction: Direction = 1,
                         fp_type: FpTypeLike = float, tol: Optional[float] = None, t_max: Optional[float] = None,
                         splits: Optional[Sequence[Sequence[float]]] = None, max_piece_time: Optional[float] = None,
                         options: Optional[ShootingOptions] = None) -> PeriodicOrbit:
    r"""A periodic orbit through guesses of ``m`` of its section points, by multiple shooting.

    Parameters
    ----------
    kind : {"reduced", "mparallel"} or Problem
    params : BallParams or MParallelParams (None with a Problem)
    states : sequence of array_like
        ``m >= 1`` public-layout states on the section ``g = g0``, each near the
        ``ks[i]``-th return of the one before and the last near the return to the first
        (e.g. consecutive section points of a chaotic orbit between a near-recurrence
        ``x_j ~ x_{j+k}``).
    ks : sequence of int, optional
        Crossings of each segment (default all 1: the orbit has ``k = m`` crossings).
    levels : Levels, MParallelLevels or dict, optional
        The level (default: the first guess's integrals); every guess must be on it to
        ``section_tol`` (relative).
    g0, direction
        The section (as :func:`taylorball.poincare_section`).
    fp_type, tol
        Number type and integrator tolerance (the Jacobian is float64).
    t_max : float, optional
        Time limit of each segment (default 1e4).
    splits : sequence of sequences of float, optional
        Segments split in time: ``splits[i] = (tau_1, ..., tau_p)`` cuts segment ``i`` into
        pieces of fixed flow times ``tau_1 .. tau_p`` and a last piece that ends at the first
        crossing after its start . The states between
        pieces are more unknowns, free in the level's tangent space (not on the section);
        their guesses are the flow of the segment's start up to half the segment's time
        (taken as ``tau_1 + ... + tau_p + tau_p``) and the backward flow of the next
        segment's start after that. Crossings inside a split
        segment are not counted by the equations, so one may appear or vanish where the
        orbit grazes the section; the orbit's ``k`` is counted at the solution. ``()`` (the
        default for every segment) leaves a segment whole, with the same bits as without
        ``splits``.
    max_piece_time : float, optional
        Instead of ``splits``: every segment whose return time at the guess exceeds this is
        split (:func:`time_splits`).
    options : ShootingOptions, optional

    Returns
    -------
    PeriodicOrbit
        With ``k = sum(ks)`` (without splits), ``state`` the first point, the multipliers of the product of
        the segments' maps on section and level, and the shooting residual and its history.

    Raises
    ------
    UsageError
        No states, ``ks`` of the wrong length or with an entry < 1, ``splits`` not one
        sequence of positive times per segment, both ``splits`` and ``max_piece_time``, a
        kind without a section, a
        dynamically symmetric ball.
    StateError
        A guess off the section, on the half-line ``g = g0 + pi``, or off the level.
    NewtonFailure
        Newton did not reach ``rtol``, or the solution's crossings are not those of the
        segments, or its minimal period is a proper divisor of ``k``.
    """
    return _shoot(kind, params, states, ks, levels=levels, g0=g0, direction=direction, fp_type=fp_type, tol=tol,
                  t_max=t_max, splits=splits, max_piece_time=max_piece_time, options=options)[0]


def _shoot(kind, params, states, ks, *, levels, g0, direction, fp_type, tol, t_max, splits, max_piece_time,
           options) -> Tuple[PeriodicOrbit, List[np.ndarray], List[float]]:
    """:func:`shoot_periodic_orbit`, also returning the segments' start states (public) and times."""
    return _finish(*_shoot_system(kind, params, states, ks, levels=levels, g0=g0, direction=direction,
                                  fp_type=fp_type, tol=tol, t_max=t_max, splits=splits,
                                  max_piece_time=max_piece_time, options=options))


def _shoot_system(kind, params, states, ks, *, levels, g0, direction, fp_type, tol, t_max, splits, max_piece_time,
                  options):
    """The checks and the Newton solve of :func:`shoot_periodic_orbit`: ``(pieces, last
    evaluation, residual history, rtol, scale)`` for :func:`_finish`."""
    opts = ShootingOptions() if options is None else options
    if not isinstance(opts, ShootingOptions):
        raise UsageError(f"options must be a taylorball.periodic_shooting.ShootingOptions, got {opts!r}")
    prob = orbit_problem(kind, params, fp_type=fp_type, tol=tol)
    if states is None or len(states) < 1:
        raise UsageError("states (guesses of m >= 1 section points of the orbit, public layout) are required")
    m = len(states)
    ks_t = tuple([1] * m if ks is None else ks)
    if len(ks_t) != m or any(not isinstance(q, (int, np.integer)) or isinstance(q, bool) or q < 1 for q in ks_t):
        raise UsageError(f"ks must hold {m} integers >= 1 (crossings of each segment), got {ks!r}")
    if splits is not None and max_piece_time is not None:
        raise UsageError("give splits (time pieces per segment) or max_piece_time, not both")
    sp = _check_splits(splits, m)
    if max_piece_time is not None:
        time_splits([1.0], max_piece_time)  # checks it
    if _has_axial_symmetry(prob):
        raise UsageError("multiple shooting is not implemented for a dynamically symmetric ball (I1 == I2: "
                         "relative periodic orbits); use taylorball.periodic_orbit")
    if not isinstance(opts.max_iter, (int, np.integer)) or opts.max_iter < 1:
        raise UsageError(f"max_iter must be an integer >= 1, got {opts.max_iter!r}")
    Section(prob, g0, direction)  # checks g0, direction
    spec = prob.spec
    rtol = 256 * spec.eps if opts.rtol is None else float(opts.rtol)
    t_max = 1e4 if t_max is None else float(t_max)
    xs = [_internal_guess(prob, s) for s in states]
    geo = _eval_geo(prob, g0, xs[0])
    targets_d = _level_targets(prob, geo.names, levels)
    targets = spec.array([targets_d[n] for n in geo.names]) if targets_d else geo.c.copy()
    for j, x in enumerate(xs):
        gj = _eval_geo(prob, g0, x)
        if abs(float(gj.e)) > opts.section_tol:
            raise StateError(f"states[{j}] is not on the section g = {g0!r}: the event function is "
                             f"{float(gj.e):.3e} (|e| <= section_tol = {opts.section_tol!r} needed)")
        if not _on_branch(prob, g0, x):
            raise StateError(f"states[{j}] is on the half-line g = g0 + pi, not on the section g = {g0!r}")
        off = _f64(gj.c - targets)
        for name, v, t in zip(gj.names, off, _f64(targets)):
            if abs(v) > opts.section_tol * max(1.0, abs(t)):
                raise StateError(f"states[{j}] is off the level: its {name} differs from the level's {t!r} by {v:.3e}")
    ctxs = [_Ctx(prob, float(g0), int(direction), int(q), targets, False, t_max) for q in ks_t]
    scale = max(1.0, max(float(np.max(np.abs(_f64(x)))) for x in xs))
    z = [_to_level(ctxs[0], x, scale) for x in xs]
    if max_piece_time is not None:
        sp = time_splits([float(_crossing_time(c, zi)) for c, zi in zip(ctxs, z)], max_piece_time)
    pcs = _pieces(prob, g0, ctxs, z, sp, scale)
    cur = _evaluate(pcs, pcs.z0, pcs.pctx)
    if cur is None:
        raise IntegrationError(f"a guess does not return to the section its segment's number of times "
                               f"(ks = {ks_t}, t_max = {t_max!r})")
    cur, hist = _newton(pcs, cur, opts, rtol, scale)
    return pcs, cur, hist, rtol, scale


def _finish(pcs: "_Pieces", cur, hist: List[float], rtol: float, scale: float
            ) -> Tuple[PeriodicOrbit, List[np.ndarray], List[float]]:
    """The orbit of a converged piece system (:func:`_result`'s checks), its segments' start
    states (public) and times."""
    prob, m = pcs.prob, len(pcs.ctxs)
    orbit = _result(prob, pcs.ctxs[0], pcs.ks, pcs.pseg, pcs.on_sec, cur, hist, rtol, scale, pcs.split)
    first = [pcs.pseg.index(i) for i in range(m)]
    times = [sum(float(s_[2]) for j, s_ in enumerate(cur[2]) if pcs.pseg[j] == i) for i in range(m)]
    return orbit, [public_state(prob.system, prob.pars, cur[1][j], prob.spec) for j in first], times


@dataclass
class _Pieces:
    """The pieces of a shooting system: ``pctx[j]`` the context of a piece ending at a crossing,
    ``None`` for a time piece (of flow time ``ptau[j]``); ``pseg[j]`` its segment; state ``j``
    is on the section iff piece ``j - 1`` ends there (``on_sec``); ``z0`` the states' guesses."""

    prob: Problem
    g0: float
    ctxs: List[_Ctx]
    pctx: List[Optional[_Ctx]]
    ptau: List[float]
    pseg: List[int]
    on_sec: List[bool]
    z0: List[np.ndarray]
    ks: Tuple[int, ...]
    split: bool

    @property
    def targets(self) -> np.ndarray:
        """The level's values (working type, ordered as the geometry's integral names)."""
        return self.ctxs[0].targets


def _pieces(prob: Problem, g0: float, ctxs: List[_Ctx], z: List[np.ndarray], sp: Tuple[Tuple[float, ...], ...],
            scale: float) -> _Pieces:
    """The pieces of the segments starting at ``z`` (on section and level), cut by ``sp``."""
    m = len(z)
    targets = ctxs[0].targets
    pctx: List[Optional[_Ctx]] = []
    ptau: List[float] = []
    pseg: List[int] = []
    zp: List[np.ndarray] = []
    for i in range(m):
        # the states inside a split segment: the flow of its start up to half its return
        # time, the backward flow of the next segment's start after it (the guesses' misfit
        # meets in the middle instead of being grown by the whole segment)
        T_i = sum(sp[i]) + sp[i][-1] if sp[i] else 0.0  # the last piece taken as long as tau_p
        y, t_i = z[i], 0.0
        for tau in sp[i]:
            zp.append(y)
            pctx.append(None)
            ptau.append(tau)
            pseg.append(i)
            t_i += tau
            src, dt = (y, tau) if t_i <= 0.5 * T_i else (z[(i + 1) % m], t_i - T_i)
            y = _onto_level(prob, float(g0), targets, _time_piece(prob, src, dt)[0], scale)
        # a split segment's last piece ends at the first crossing after its start
        zp.append(y if sp[i] else z[i])
        pctx.append(replace(ctxs[i], k=1) if sp[i] else ctxs[i])
        ptau.append(0.0)
        pseg.append(i)
    npc = len(pctx)
    on_sec = [pctx[j - 1] is not None for j in range(npc)]
    return _Pieces(prob, g0, ctxs, pctx, ptau, pseg, on_sec, zp, tuple(c.k for c in ctxs), any(sp))


def _evaluate(pcs: _Pieces, z: List[np.ndarray], cs: List[Optional[_Ctx]], Ts=None):
    """``(max |F|, z, segments, F)`` of the shooting equations at the states ``z`` (``None`` if
    a piece's integration fails or ``F`` is not finite); ``segments[j]`` is ``(end, Pi Phi, T)``."""
    npc = len(z)
    try:
        segs = [_segment(c, zi, None if Ts is None else Ts[i]) if c is not None
                else _time_piece(pcs.prob, zi, pcs.ptau[i]) for i, (c, zi) in enumerate(zip(cs, z))]
    except (IntegrationError, StateError):
        return None
    F = np.concatenate([_f64(segs[i][0] - z[(i + 1) % npc]) for i in range(npc)])
    res = float(np.max(np.abs(F)))
    return (res, z, segs, F) if np.isfinite(res) else None


def _shooting_jacobian(pcs: _Pieces, z: List[np.ndarray], segs) -> Tuple[np.ndarray, List[np.ndarray], np.ndarray]:
    """The shooting Jacobian in the states' tangent coordinates: ``(J, B, off)``, ``B[j]`` the
    basis of state ``j``'s tangent space (of section and level, or of the level inside a
    segment) and ``off[j]:off[j + 1]`` its columns; row block ``j`` holds ``Pi_j Phi_j B_j`` and
    ``-B_{j+1}``."""
    prob, g0, on_sec = pcs.prob, pcs.g0, pcs.on_sec
    n, npc = len(z[0]), len(z)
    Bs = [_tangent_basis(prob, g0, zi) if on_sec[i] else _level_basis(prob, g0, zi) for i, zi in enumerate(z)]
    off = np.concatenate([[0], np.cumsum([B.shape[1] for B in Bs])]).astype(int)
    J = np.zeros((n * npc, int(off[-1])))
    for i in range(npc):
        J[i * n:(i + 1) * n, off[i]:off[i + 1]] += segs[i][1] @ Bs[i]
        j = (i + 1) % npc
        J[i * n:(i + 1) * n, off[j]:off[j + 1]] -= Bs[j]
    return J, Bs, off


def _move(pcs: _Pieces, z: List[np.ndarray], steps: List[np.ndarray], scale: float,
          ctx0: Optional[_Ctx] = None) -> List[np.ndarray]:
    """The states ``z`` moved by ``steps`` (float64) and back onto section and level (the
    level of ``ctx0``, default the system's)."""
    c0 = pcs.ctxs[0] if ctx0 is None else ctx0
    spec = pcs.prob.spec
    return [_to_level(c0, zi + spec.array(s_), scale) if pcs.on_sec[i]
            else _onto_level(pcs.prob, float(pcs.g0), c0.targets, zi + spec.array(s_), scale)
            for i, (zi, s_) in enumerate(zip(z, steps))]


def _newton(pcs: _Pieces, cur, opts: ShootingOptions, rtol: float, scale: float):
    """Gauss-Newton / Levenberg-Marquardt on the shooting equations from ``cur``: the last
    evaluation and the residual history."""
    pctx = pcs.pctx
    hist: List[float] = []
    mu_lm: Optional[float] = None
    for _ in range(int(opts.max_iter)):
        # a trial segment taking RETURN_FACTOR times its current return time is not near this orbit
        pctx = [None if c is None else replace(c, t_max=min(c.t_max, RETURN_FACTOR * float(s[2])))
                for c, s in zip(pctx, cur[2])]
        hist.append(cur[0])
        if cur[0] <= rtol * scale:
            break
        if len(hist) >= 3 and hist[-1] > 0.5 * hist[-3] and hist[-1] < 1e3 * rtol * scale:
            break  # stagnation at the rounding floor
        res, z, segs, F = cur
        merit = float(F @ F)
        J, Bs, off = _shooting_jacobian(pcs, z, segs)
        npc = len(z)
        JtJ, g = J.T @ J, J.T @ F
        if mu_lm is None:
            mu_lm = 1e-3

        def attempt(w, lam=1.0):
            steps = [Bs[i] @ w[off[i]:off[i + 1]] for i in range(npc)]
            smax = max(float(np.max(np.abs(s_))) for s_ in steps)
            if smax > opts.max_step * scale:
                steps = [s_ * (opts.max_step * scale / smax) for s_ in steps]
                smax = opts.max_step * scale
            try:
                zn = _move(pcs, z, steps, scale)
                near = smax <= 1e-8 * scale  # the crossings followed near their times
                trial = _evaluate(pcs, zn, pctx, [s_[2] for s_ in segs] if near else None)
            except StateError:
                return None
            if trial is not None and (float(trial[3] @ trial[3]) < merit * (1 - 1e-4 * lam)
                                      or trial[0] < res * (1 - 1e-4 * lam) + 64 * pcs.prob.spec.eps * scale):
                return trial
            return None

        # the Gauss-Newton step, halved until it lowers |F|_2 or max |F|; failing that
        # Levenberg-Marquardt steps (shortened towards the gradient of |F|^2, mu raised
        # until a trial lowers |F|)
        w_gn = np.linalg.lstsq(J, -F, rcond=None)[0]
        nxt = None
        for lam in 0.5 ** np.arange(12):
            nxt = attempt(lam * w_gn, float(lam))
            if nxt is not None:
                mu_lm = max(mu_lm / 10.0, 1e-12 * float(np.max(np.diag(JtJ))))
                break
        for _ in range(0 if nxt is not None else 14):
            nxt = attempt(np.linalg.solve(JtJ + mu_lm * np.diag(np.maximum(np.diag(JtJ), 1e-12)), -g))
            if nxt is not None:
                break
            mu_lm *= 4.0
        if nxt is None:
            break
        cur = nxt
    else:
        hist.append(cur[0])
    if not hist or hist[-1] != cur[0]:
        hist.append(cur[0])
    return cur, hist


def _result(prob: Problem, c0: _Ctx, ks: Tuple[int, ...], pseg: List[int], on_sec: List[bool], cur,
            hist: List[float], rtol: float, scale: float, split: bool) -> PeriodicOrbit:
    res, z, segs, _ = cur
    spec = prob.spec
    k = int(sum(ks))
    m = len(ks)
    pub = public_state(prob.system, prob.pars, z[0], spec)
    if not res <= 1e3 * rtol * scale:
        raise NewtonFailure(f"multiple shooting ({m} segments, k = {k}) did not converge: best residual "
                            f"{res:.3e} (needed <= {1e3 * rtol * scale:.1e}); history "
                            f"{', '.join(f'{h:.1e}' for h in hist)}", res, hist, pub)
    periods = [0.0] * m
    for i, s in zip(pseg, segs):
        periods[i] += float(s[2])
    if min(periods) <= T_MIN:
        raise NewtonFailure(f"a segment converged to a zero return time ({min(periods)!r}): not a periodic orbit",
                            res, hist, pub)
    # the k section points by a separate run of the section integrator from x_0; it must
    # cross the section at the segments' points (the segment ends), to 1e-6
    T = sum(periods)
    if split:
        # a split segment ends at the first crossing after its last piece's start: the
        # crossings inside it are those of the solution (a grazing of the section may add
        # or remove some), so k is counted here
        run = c0.section.run(pub, n_points=4 * k + 16, t_end=(1 + 1e-3) * T + 1.0)
        keep = [i for i, t in enumerate(run.times) if T_MIN < float(t) <= T + 1e-6 * (1 + T)]
        k = len(keep)
        t_run = [float(run.times[i]) for i in keep]
        if not keep or any(min(abs(a - b) for a in t_run) > 1e-6 * (1 + T) for b in np.cumsum(periods)):
            raise NewtonFailure(f"the section's crossings (times {t_run}) do not include the segments' ends "
                                f"(times {list(np.cumsum(periods))}) ({run.message})", res, hist, pub)
    else:
        run = c0.section.run(pub, n_points=k + 1, t_end=(1 + 1e-3) * T + 1.0)
        keep = [i for i, t in enumerate(run.times) if float(t) > T_MIN][:k]
        if len(keep) < k:
            raise NewtonFailure(f"the solution does not cross the section {k} times in one period ({run.message})",
                                res, hist, pub)
        ends = np.cumsum(ks)
        t_run = [float(run.times[keep[e - 1]]) for e in ends]
        if any(abs(a - b) > 1e-6 * (1 + T) for a, b in zip(t_run, np.cumsum(periods))):
            raise NewtonFailure(f"the section's crossings (times {t_run}) are not the segments' ends (times "
                                f"{list(np.cumsum(periods))}): no orbit with ks = {ks} here", res, hist, pub)
    states = [run.states[i] for i in keep[:-1]]
    pts_int = np.vstack([np.asarray(z[0])[None, :], _internal_rows(prob, states)]) if k > 1 \
        else np.asarray(z[0])[None, :]
    pts_f = np.asarray(pts_int, dtype=object).astype(float)
    points = chart_points(prob.kind, pts_f)
    k_min = _minimal_k(points, k, False, 1e-7)
    if k_min < k:
        raise NewtonFailure(f"the orbit found closes after {k_min} crossings, not k = {k}: ask for k = {k_min}",
                            res, hist, pub)
    npc = len(z)
    Bs = [_tangent_basis(prob, c0.g0, zi) if on_sec[i] else _level_basis(prob, c0.g0, zi) for i, zi in enumerate(z)]
    A = np.eye(Bs[0].shape[1])
    for i in range(npc):
        A = (Bs[(i + 1) % npc].T @ segs[i][1] @ Bs[i]) @ A
    geo0 = _eval_geo(prob, c0.g0, z[0])
    lv = {name: float(v) for name, v in zip(geo0.names, geo0.c)}
    return PeriodicOrbit(
        kind=prob.kind, state=pub, period=float(T), k=k, points=points, **multiplier_summary(A),
        residual=res, residual_history=tuple(hist),
        converged=bool(res <= rtol * scale), symmetric=_symmetry_of(c0, pts_f, 1e-7), shift=0.0, levels=lv,
        g0=c0.g0, direction=c0.direction, fp_type=str(spec), internal=np.asarray(z[0]).copy(), problem=prob)


def periodic_orbit_shooting(kind: Union[KindName, Problem], params: Optional[ParamsLike] = None,
                            state: Optional[ArrayLike] = None, k: int = 1, shooting: int = 1, *,
                            levels: LevelsLike = None, g0: float = 0.0, direction: Direction = 1,
                            fp_type: FpTypeLike = float, tol: Optional[float] = None, t_max: Optional[float] = None,
                            max_piece_time: Optional[float] = None,
                            options: Optional[ShootingOptions] = None) -> PeriodicOrbit:
    """:func:`taylorball.periodic_orbit` by multiple shooting from one guess: the guess's own
    section points at the ends of ``shooting`` segments (:func:`segment_lengths` ``(k,
    shooting)`` crossings each) are the starts of :func:`shoot_periodic_orbit`.

    From one guess this gains little on an expanding map (the guess's section points carry
    its error grown by the map); the gain of multiple shooting is that its guesses need not be
    one orbit (:func:`shoot_periodic_orbit` with, e.g., the section points of a chaotic orbit
    between a near-recurrence). A guess with an exact orbit's state converges at once.
    ``max_piece_time`` splits long segments in time (see :func:`shoot_periodic_orbit`).

    Raises
    ------
    UsageError
        ``shooting`` not in ``[1, k]``, and as :func:`shoot_periodic_orbit`.
    IntegrationError
        The guess does not cross the section ``k - 1`` times before ``t_max``.
    """
    prob = orbit_problem(kind, params, fp_type=fp_type, tol=tol)
    if state is None:
        raise UsageError("state (a guess on the section, public layout) is required")
    if not isinstance(k, (int, np.integer)) or isinstance(k, bool) or k < 1:
        raise UsageError(f"k (section crossings per period) must be an integer >= 1, got {k!r}")
    ks = segment_lengths(int(k), shooting)
    t_max = 1e4 if t_max is None else float(t_max)
    if _has_axial_symmetry(prob):
        raise UsageError("multiple shooting is not implemented for a dynamically symmetric ball (I1 == I2: "
                         "relative periodic orbits); use taylorball.periodic_orbit")
    run = Section(prob, g0, direction).run(state, n_points=int(k) + 1, t_end=t_max)
    kept = [s for t, s in zip(run.times, run.states) if float(t) > T_MIN]
    if len(kept) < k - 1:
        raise IntegrationError(f"the guess does not cross the section {k - 1} times ({run.message})")
    ends = np.cumsum(ks)[:-1]
    states = [np.asarray(state)] + [kept[e - 1] for e in ends]
    return shoot_periodic_orbit(prob, None, states, ks, levels=levels, g0=g0, direction=direction, t_max=t_max,
                                max_piece_time=max_piece_time, options=options)
