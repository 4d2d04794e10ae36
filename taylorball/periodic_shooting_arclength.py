r"""A family of periodic orbits in a level value by multiple shooting, through folds:
:func:`continue_shooting_arclength`.

Natural-parameter steps (:func:`taylorball.periodic_shooting_family.continue_shooting`) fix the
level value ``w`` and solve for the orbit; at a fold of the family in ``w`` (a multiplier
through +1, the family turning back) the shooting Jacobian turns singular and no orbit exists
beyond it. Here ``w`` is one more unknown. With ``z`` the shooting states (each in the tangent
space of section and level at it, as in :func:`~taylorball.periodic_shooting.shoot_periodic_orbit`)
the equations are the shooting equations ``F(z, w) = 0`` and the pseudo-arclength condition

.. math:: t_X \cdot (X - X_p) + t_w (w - w_p) = 0,

``X`` the segments' start states, ``(X_p, w_p) = (X_0, w_0) + \Delta s\, t`` the prediction
along the unit tangent ``t = (t_X, t_w)`` of the branch at the last orbit. The corrector's
matrix is the shooting Jacobian bordered by the column ``\partial F/\partial w`` and the row
of the arclength condition:

.. math:: \begin{pmatrix} J & \partial_w F \\ t_X^T B & t_w + t_X^T n \end{pmatrix}.

``\partial_w F`` needs no further integration: a change ``dw`` of the level moves each state
``z_j`` off its level by the minimal-norm normal ``n_j\,dw`` (``G_j n_j = \partial c^*/\partial
w``, ``G_j`` the gradients of the section and the integrals, or of the integrals alone for a
state inside a split segment), so row block ``j`` of ``\partial_w F`` is ``\Pi_j\Phi_j n_j -
n_{j+1}`` with the segments' maps already computed for ``J``. The tangent at a solution is the
null vector of ``[J, \partial_w F]`` (its smallest right singular vector), oriented along the
previous one; a **fold** is where its ``w`` component changes sign.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .errors import IntegrationError, StateError, UsageError
from .levels import Levels
from .periodic import PeriodicOrbit, _constrained_step, _eval_geo, _f64, _level_targets, _to_level
from .periodic_continuation import Branch, _events, _levels_at, halving_step
from .periodic_shooting import (ShootingOptions, _evaluate, _finish, _move, _pieces, _Pieces, _shoot_system,
                                _shooting_jacobian, time_splits)
from .periodic_shooting_family import _check_family, orbit_section_states

__all__ = ["continue_shooting_arclength"]

#: The half-width of the central difference of the level's values in ``w`` (they are
#: linear or quadratic in ``w``: the difference is exact to rounding).
_DW = 1e-3


@dataclass
class _Sol:
    """A solution on the branch: the orbit, its pieces and last evaluation, ``w``, the
    segments' start states (internal, float64), their flow times, the unit tangent."""

    orbit: PeriodicOrbit
    pcs: _Pieces
    cur: Any
    w: float
    X: np.ndarray
    times: List[float]
    t: np.ndarray
    dz: List[np.ndarray]
    null_ratio: float


def _targets_at(pcs: _Pieces, levels: Levels, parameter: str, w: float, names: Tuple[str, ...]) -> np.ndarray:
    spec = pcs.prob.spec
    d = _level_targets(pcs.prob, names, _levels_at(levels, parameter, w))
    return spec.array([d[n] for n in names])


def _bordered(pcs: _Pieces, z: List[np.ndarray], segs, dc: np.ndarray):
    """``(J, B, off, normals, dF/dw)`` at the states ``z``: the shooting Jacobian and its
    border column (module docstring)."""
    J, Bs, off = _shooting_jacobian(pcs, z, segs)
    normals = []
    for j, zj in enumerate(z):
        geo = _eval_geo(pcs.prob, pcs.g0, zj)
        if pcs.on_sec[j]:
            G = np.vstack([_f64(geo.grad_e)[None, :], _f64(geo.grad_c)])
            rhs = np.concatenate([[0.0], dc])
        else:
            G, rhs = _f64(geo.grad_c), dc
        normals.append(np.linalg.lstsq(G, rhs, rcond=None)[0])
    npc = len(z)
    dF = np.concatenate([segs[j][1] @ normals[j] - normals[(j + 1) % npc] for j in range(npc)])
    return J, Bs, off, normals, dF


def _first(pcs: _Pieces) -> List[int]:
    """The pieces that start the segments."""
    return [pcs.pseg.index(i) for i in range(len(pcs.ctxs))]


def _tangent(pcs: _Pieces, cur, dc: np.ndarray) -> Tuple[np.ndarray, List[np.ndarray], float]:
    """The unit tangent ``(dX, dw)`` of the branch at a solution (on the segments' start
    states), the same tangent on every piece's state (scaled alike), and the ratio of the
    bordered Jacobian's two smallest singular values (small: a one-dimensional null space, a
    regular point of the branch)."""
    _, z, segs, _ = cur
    J, Bs, off, normals, dF = _bordered(pcs, z, segs, dc)
    _, s, Vt = np.linalg.svd(np.hstack([J, dF[:, None]]))
    v = Vt[-1]
    dz = [Bs[j] @ v[off[j]:off[j + 1]] + normals[j] * v[-1] for j in range(len(z))]
    t = np.concatenate([dz[j] for j in _first(pcs)] + [[v[-1]]])
    norm = float(np.linalg.norm(t))
    return t / norm, [d / norm for d in dz], float(s[-1] / s[-2])


def _keeps_pieces(sol: _Sol) -> bool:
    """Whether the next step may keep ``sol``'s time pieces: every split segment's last piece
    (up to its crossing) between a fifth and three times the length of its time pieces."""
    pcs, segs = sol.pcs, sol.cur[2]
    for j, c in enumerate(pcs.pctx):
        if c is not None and j > 0 and pcs.pctx[j - 1] is None and pcs.pseg[j - 1] == pcs.pseg[j]:
            tau = pcs.ptau[j - 1]
            if not 0.2 * tau <= float(segs[j][2]) <= 3.0 * tau:
                return False
    return True


def _correct(sol: _Sol, X_p: np.ndarray, w_p: float, t: np.ndarray, steps: Optional[List[np.ndarray]], *,
             levels: Levels, parameter: str, names: Tuple[str, ...], max_piece_time: Optional[float],
             opts: ShootingOptions, rtol: float, scale: float):
    """Newton on the bordered system from the prediction ``(X_p, w_p)`` with the condition
    ``t . ((X, w) - (X_p, w_p)) = 0``: ``(pieces, evaluation, history, w)``. With ``steps``
    (the predicted change of every piece's state) the pieces of ``sol`` are kept and their
    states predicted; without, the segments are cut afresh from ``sol``'s segment times and
    the states inside them guessed by flows from the predicted segment starts."""
    pcs0 = sol.pcs
    n = len(sol.X) // len(pcs0.ctxs)
    m = len(pcs0.ctxs)
    w = float(w_p)
    tg = _targets_at(pcs0, levels, parameter, w, names)
    ctxs = [replace(c, targets=tg) for c in pcs0.ctxs]
    spec = pcs0.prob.spec
    if steps is not None:
        pcs = replace(pcs0, ctxs=ctxs, pctx=[None if c is None else replace(c, targets=tg) for c in pcs0.pctx])
        pcs = replace(pcs, z0=_move(pcs, sol.cur[1], steps, scale))
    else:
        z0 = [_to_level(ctxs[0], spec.array(X_p[i * n:(i + 1) * n]), scale) for i in range(m)]
        sp = tuple(() for _ in range(m)) if max_piece_time is None else time_splits(sol.times, max_piece_time)
        pcs = _pieces(pcs0.prob, pcs0.g0, ctxs, z0, sp, scale)
    first = _first(pcs)
    tX, tw = t[:-1], float(t[-1])
    natural = not np.any(tX)  # the condition w = w_p: w is not moved (exactly the level asked for)

    def arc(z: List[np.ndarray], ww: float) -> float:
        X = np.concatenate([_f64(z[j]) for j in first])
        return float(tX @ (X - X_p) + tw * (ww - w_p))

    def dc_at(ww: float) -> np.ndarray:
        return _f64(_targets_at(pcs, levels, parameter, ww + _DW, names)
                    - _targets_at(pcs, levels, parameter, ww - _DW, names)) / (2 * _DW)

    cur = _evaluate(pcs, pcs.z0, pcs.pctx)
    if cur is None:
        raise IntegrationError("a predicted state does not return to the section its segment's number of times")
    g = arc(cur[1], w)
    hist: List[float] = []
    for _ in range(int(opts.max_iter)):
        hist.append(cur[0])
        if cur[0] <= rtol * scale and abs(g) <= 1e-8 * scale:
            break
        if len(hist) >= 3 and hist[-1] > 0.5 * hist[-3] and hist[-1] < 1e3 * rtol * scale:
            break  # stagnation at the rounding floor
        res, z, segs, F = cur
        J, Bs, off, normals, dF = _bordered(pcs, z, segs, dc_at(w))
        row = np.zeros(int(off[-1]) + 1)
        for i, j in enumerate(first):
            row[off[j]:off[j + 1]] = tX[i * n:(i + 1) * n] @ Bs[j]
        row[-1] = tw + sum(float(tX[i * n:(i + 1) * n] @ normals[j]) for i, j in enumerate(first))
        # the shooting rows by least squares, the arclength row exactly (null-space method)
        step = _constrained_step(np.vstack([np.hstack([J, dF[:, None]]), row[None, :]]),
                                 np.concatenate([F, [g]]), len(F))
        if natural:
            step[-1] = 0.0
        merit = float(F @ F) + g * g
        nxt = None
        for lam in 0.5 ** np.arange(12):
            dw = float(lam * step[-1])
            steps = [Bs[j] @ (lam * step[off[j]:off[j + 1]]) + normals[j] * dw for j in range(len(z))]
            smax = max(float(np.max(np.abs(s_))) for s_ in steps)
            if smax > opts.max_step * scale:
                continue
            try:
                c_new = replace(ctxs[0], targets=_targets_at(pcs, levels, parameter, w + dw, names))
                zn = _move(pcs, z, steps, scale, c_new)
            except StateError:
                continue
            trial = _evaluate(pcs, zn, pcs.pctx)
            if trial is None:
                continue
            g_new = arc(zn, w + dw)
            if float(trial[3] @ trial[3]) + g_new * g_new < merit * (1 - 1e-4 * lam) \
                    or trial[0] < res * (1 - 1e-4 * lam) + 64 * spec.eps * scale:
                nxt, w, g = trial, w + dw, g_new
                break
        if nxt is None:
            break
        cur = nxt
    if not hist or hist[-1] != cur[0]:
        hist.append(cur[0])
    tg = _targets_at(pcs, levels, parameter, w, names)
    pcs = replace(pcs, ctxs=[replace(c, targets=tg) for c in pcs.ctxs])
    return pcs, cur, hist, w


def continue_shooting_arclength(orbit: PeriodicOrbit, levels: Levels, parameter: str, target: float, *,
                                ds: float = 0.05, ds_min: float = 1e-4, ds_max: float = 0.5,
                                ks: Optional[Sequence[int]] = None, max_piece_time: Optional[float] = None,
                                direction: Optional[int] = None, bounds: Optional[Sequence[float]] = None,
                                max_steps: int = 200,
                                jump_ratio: float = 0.5, options: Optional[ShootingOptions] = None) -> Branch:
    r"""Follow ``orbit`` (on ``levels``) in the level value ``parameter`` by pseudo-arclength
    multiple shooting (module docstring), through folds, until ``parameter`` reaches
    ``target``.

    The branch starts towards ``target`` (or in the sense ``direction``); after a fold
    ``parameter`` runs back, and the branch goes on until it reaches ``target`` (the last
    orbit is then solved at ``target`` exactly: the same corrector with the condition ``w =
    target``), leaves ``bounds``, or stops.

    Parameters
    ----------
    orbit, levels, parameter
        As :func:`taylorball.periodic_shooting_family.continue_shooting`: a reduced-system
        orbit on ``levels`` and the level value followed (``"C"``, ``"M_gamma"``, ``"h"``).
    target : float
        The value to reach (not the start's).
    ds, ds_min, ds_max : float
        First, least and largest arclength step (in the norm of the segments' start states,
        internal layout, and ``parameter`` together). A refused step is halved; below
        ``ds_min`` the branch stops. A step accepted without a halving doubles the next.
    ks, max_piece_time
        As :func:`taylorball.periodic_shooting_family.continue_shooting` (segments of ``ks``
        crossings, cut in time pieces of at most ``max_piece_time``, re-cut at every step from
        the last orbit's segment times).
    direction : {1, -1}, optional
        The sense in which ``parameter`` starts (default: towards ``target``); e.g. away
        from a ``target`` that the branch reaches after a fold.
    bounds : (float, float), optional
        The branch stops when ``parameter`` leaves ``[low, high]`` (default: no bound; a level
        that is not admissible stops it). Must contain the start and ``target``.
    max_steps : int
        Accepted steps at most.
    jump_ratio : float
        A corrected point farther than ``jump_ratio * ds`` (and ``1e-6``) from the prediction
        is refused as another orbit.
    options : ShootingOptions, optional
        Newton's options (``max_iter``, ``rtol``, ``max_step``).

    Returns
    -------
    Branch
        ``values`` (not monotone through a fold), ``orbits`` (the first is ``orbit`` solved
        again by the shooting), ``events``: those of
        :func:`~taylorball.periodic_continuation.continue_in_level` and ``"fold"`` where the
        ``parameter`` component of the tangent changes sign (``"omega"`` the turning value, with
        that component taken linear in the arclength over the step; ``"multiplier"`` the
        multiplier nearest +1 of the two orbits beside it),
        ``stopped`` (``"reached"`` or why not).

    Raises
    ------
    UsageError
        A start that is not a reduced-system orbit, ``levels`` not a :class:`Levels`, an
        unknown ``parameter`` or ``'Omega'``, a ``target`` equal to the start's value or not
        finite, steps that are not ``0 < ds_min <= ds <= ds_max``, ``bounds`` not holding the
        start and ``target``, ``direction`` not ``None``, 1 or -1, ``ks`` not adding up to
        ``orbit.k``, ``max_steps < 1``, ``jump_ratio`` not in ``(0, 1]``.
    """
    w0, tgt, hs, ks_t, opts = _check_family(orbit, levels, parameter, target,
                                            (("ds_min", ds_min), ("ds", ds), ("ds_max", ds_max)), ks, options,
                                            "continue_shooting_arclength")
    lo, hi = -np.inf, np.inf
    if bounds is not None:
        try:
            lo, hi = (float(v) for v in bounds)
        except (TypeError, ValueError):
            raise UsageError(f"bounds must be a pair (low, high) of floats, got {bounds!r}") from None
        if not (lo <= min(w0, tgt) and max(w0, tgt) <= hi):
            raise UsageError(f"bounds = {tuple(bounds)!r} must hold the start's {parameter} = {w0!r} and the "
                             f"target {tgt!r}: the target is on the wrong side of a bound")
    if direction not in (None, 1, -1) or isinstance(direction, bool):
        raise UsageError(f"direction must be None, 1 or -1 (the sense in which {parameter} starts), got {direction!r}")
    if not isinstance(max_steps, (int, np.integer)) or isinstance(max_steps, bool) or max_steps < 1:
        raise UsageError(f"max_steps must be an integer >= 1, got {max_steps!r}")
    if not 0.0 < float(jump_ratio) <= 1.0:
        raise UsageError(f"jump_ratio must be in (0, 1], got {jump_ratio!r}")
    if max_piece_time is not None:
        time_splits([1.0], max_piece_time)  # checks it
    params = orbit.problem.params
    starts = np.concatenate([[0], np.cumsum(ks_t)[:-1]]).astype(int)
    guess = list(orbit_section_states(orbit)[starts])
    pcs, cur, hist, rtol, scale = _shoot_system("reduced", params, guess, ks_t, levels=levels, g0=orbit.g0,
                                                direction=orbit.direction, fp_type=float, tol=None, t_max=None,
                                                splits=None, max_piece_time=max_piece_time, options=opts)
    o0, _, times0 = _finish(pcs, cur, hist, rtol, scale)
    names = _eval_geo(pcs.prob, pcs.g0, cur[1][0]).names
    sgn = float(direction) if direction is not None else (1.0 if tgt > w0 else -1.0)

    def make(pcs: _Pieces, cur, o: PeriodicOrbit, w: float, times: List[float], t_prev: Optional[np.ndarray]) -> _Sol:
        dc = _f64(_targets_at(pcs, levels, parameter, w + _DW, names)
                  - _targets_at(pcs, levels, parameter, w - _DW, names)) / (2 * _DW)
        t, dz, ratio = _tangent(pcs, cur, dc)
        if (t_prev is None and t[-1] * sgn < 0) or (t_prev is not None and float(t @ t_prev) < 0):
            t, dz = -t, [-d for d in dz]
        X = np.concatenate([_f64(cur[1][j]) for j in _first(pcs)])
        return _Sol(o, pcs, cur, w, X, times, t, dz, ratio)

    sols = [make(pcs, cur, o0, w0, times0, None)]
    events: List[Dict[str, Any]] = []
    stopped = "reached"
    corrector = dict(levels=levels, parameter=parameter, names=names, max_piece_time=max_piece_time, opts=opts,
                     rtol=rtol, scale=scale)

    def solve(X_p: np.ndarray, w_p: float, t: np.ndarray, h: float, steps: Optional[List[np.ndarray]]) -> _Sol:
        last = sols[-1]
        pcs, cur, hist, w = _correct(last, X_p, w_p, t, steps, **corrector)
        o, _, times = _finish(pcs, cur, hist, rtol, scale)  # NewtonFailure (an IntegrationError) refuses
        X = np.concatenate([_f64(cur[1][j]) for j in _first(pcs)])
        dist = float(np.linalg.norm(np.concatenate([X - X_p, [w - w_p]])))
        if dist > jump_ratio * h + 1e-6:
            raise StateError(f"the corrected point is {dist:.3g} from the prediction (step {h:.3g}): another orbit")
        return make(pcs, cur, o, w, times, last.t)

    def attempt(h: float) -> _Sol:
        last = sols[-1]
        steps = [h * d for d in last.dz] if _keeps_pieces(last) else None
        return solve(last.X + h * last.t[:-1], last.w + h * float(last.t[-1]), last.t, h, steps)

    h = hs[1]
    while True:
        if len(sols) > max_steps:
            stopped = f"max_steps = {max_steps} reached at {parameter} = {sols[-1].w!r}"
            break
        step = halving_step(h, lambda hh: (hh, hh), attempt, lambda _n, h_next: h_next < hs[0],
                            errors=(IntegrationError, StateError, np.linalg.LinAlgError))
        if step.failure is not None:
            stopped = (f"the corrector failed with steps halved below ds_min = {hs[0]} at {parameter} = "
                       f"{sols[-1].w!r}: {step.failure}")
            break
        a, b = sols[-1], step.result
        if a.t[-1] * b.t[-1] < 0:
            ta, tb = float(a.t[-1]), float(b.t[-1])
            mus = [mu for o in (a.orbit, b.orbit) for mu in np.atleast_1d(o.multipliers)]
            # dw/ds linear across the step: the fold at s* = ds ta / (ta - tb), where
            # w = w_a + ta s* / 2 (the parameter is quadratic in s there, not linear)
            events.append({"event": "fold", "omega": float(a.w + 0.5 * step.used * ta * ta / (ta - tb)),
                           "between": (a.w, b.w), "from": a.orbit.type, "to": b.orbit.type,
                           "multiplier": complex(min(mus, key=lambda mu: abs(mu - 1.0)))})
        events += _events(a.orbit, b.orbit, a.w, b.w)
        if (a.w - tgt) * (b.w - tgt) <= 0 and b.w != tgt:
            # the target passed: solve there, from the chord between the two solutions
            r = (tgt - a.w) / (b.w - a.w)
            same = a.pcs.ptau == b.pcs.ptau and a.pcs.pseg == b.pcs.pseg
            chord = [r * (_f64(zb) - _f64(za)) for za, zb in zip(a.cur[1], b.cur[1])] if same else None
            try:
                end = solve(a.X + r * (b.X - a.X), tgt, np.concatenate([np.zeros(len(a.X)), [1.0]]),
                            max(float(np.linalg.norm(b.X - a.X)), 1e-3), chord)
            except (IntegrationError, StateError) as exc:
                sols.append(b)
                stopped = f"no orbit at the target {parameter} = {tgt!r} between {a.w!r} and {b.w!r}: {exc}"
                break
            sols.append(end)
            break
        sols.append(b)
        if b.w == tgt:
            break
        if not lo <= b.w <= hi:
            stopped = f"{parameter} left bounds = {(lo, hi)!r} at {b.w!r}"
            break
        h = min(2.0 * step.used, hs[2]) if step.halvings == 0 else step.used
    return Branch(np.array([s.w for s in sols]), [s.orbit for s in sols], events, stopped, parameter=parameter)
