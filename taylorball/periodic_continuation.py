r"""Continuation of a periodic orbit in the plane's rate ``Omega``: :func:`continue_in_omega`.

Natural-parameter continuation with a tangent (Euler) predictor: at each new ``Omega`` the
internal state and ``theta`` predicted from the branch's tangent at the last solution (the
implicit function theorem on Newton's equations, ``dF/dOmega`` by a forward difference) is moved onto the section and the level (the
levels ``C, M_gamma, h`` are kept; the energy depends on ``Omega``) and Newton
(:mod:`taylorball.periodic`) corrects it. A failed step is halved (``max_halvings`` times);
when it still fails the branch ends there, with the reason (a fold of the branch in
``Omega``, where natural-parameter continuation must fail, or the orbit leaving the
admissible region). A step whose Newton solution is far from the tangent prediction
(relative to the predicted change) is refused as a jump to another orbit: near a fold
Newton converges to some other periodic orbit beyond it, which a branch must not silently
take in. :func:`continue_arclength` follows a branch through its folds (pseudo-arclength).

Between consecutive solutions the branch records events: a change of stability type, a
multiplier through -1 (period doubling: ``tr A + 2`` changes sign for a 2D map,
``sigma + tau + 2`` for a 3D one) and through +1 (``tr A - 2``; ``sigma - tau``), located at
the linear interpolation of the sign change.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Type, Union

import numpy as np

from ._deprecation import renamed
from .errors import IntegrationError, StateError, UsageError
from .levels import Levels, MParallelLevels
from .periodic import (PeriodicOrbit, _constrained_step, _Ctx, _eval_geo, _f64, _has_axial_symmetry, _jacobian,
                       _level_targets, _residual_parts, _solve, _to_level, orbit_problem)
from .periodic_sections import (SectionScan, SectionSwitch, _switch, _switch_reason, crossing_transversality,
                                on_section, section_scan, section_windows)

__all__ = ["Branch", "continue_in_omega", "continue_in_level", "continue_arclength", "section_windows", "on_section", "inertia_homotopy",
           "InertiaHomotopy", "SectionSwitch", "SectionScan", "section_scan", "crossing_transversality"]


class AlongOrbits:
    """``trace`` and ``period`` along a sequence of orbits (an ``orbits`` attribute)."""

    orbits: List[PeriodicOrbit]

    @property
    def trace(self) -> np.ndarray:
        """``tr A`` along the orbits."""
        return np.array([o.trace for o in self.orbits])

    @property
    def period(self) -> np.ndarray:
        """The period (flow time) along the orbits."""
        return np.array([o.period for o in self.orbits])


@dataclass(frozen=True)
class Branch(AlongOrbits):
    """A branch of periodic orbits against a parameter: the plane's rate ``Omega`` or a level value.

    Attributes
    ----------
    omega : ndarray
        The values of the branch's ``parameter`` reached, in order (``Omega`` by default; the
        field keeps the name it had when ``Omega`` was the only parameter; :attr:`values` is
        the same array). Likewise the ``"omega"`` entries of ``events`` and ``switches``
        are values of ``parameter``.
    orbits : list of PeriodicOrbit
    events : list of dict
        ``{"event": "stability change" | "period doubling" | "multiplier +1", "omega": float,
        "between": (omega_a, omega_b), "from": type_a, "to": type_b}``.
    stopped : str
        Why the branch ended (``"reached"`` when every requested value was reached).
    switches : list of dict
        Where the branch moved to another section (:func:`continue_arclength` with
        ``switch``): ``{"omega": float, "from": (g0, k), "to": (g0, k), "reason": str,
        "transversality": (before, after)}``; the orbit at that ``Omega`` is kept in
        ``orbits`` on the new section.
    parameter : str
        ``"Omega"`` (the plane's rate, with the level kept) or the name of the level value
        followed (``"C"``, ``"M_gamma"``, ``"h"``; ``"lam"``, ``"h"`` for the M||gamma
        system), with ``Omega`` and the other level values kept.
    """

    omega: np.ndarray
    orbits: List[PeriodicOrbit]
    events: List[Dict[str, Any]] = field(default_factory=list)
    stopped: str = "reached"
    switches: List[Dict[str, Any]] = field(default_factory=list)
    parameter: str = "Omega"

    @property
    def values(self) -> np.ndarray:
        """The values of :attr:`parameter` reached, in order (the array :attr:`omega`)."""
        return self.omega



def _indicators(o: PeriodicOrbit):
    if o.matrix.shape == (2, 2):
        return {"period doubling": o.trace + 2.0, "multiplier +1": o.trace - 2.0}
    return {"period doubling": o.second_trace + o.trace + 2.0, "multiplier +1": o.second_trace - o.trace}


def _events(a: PeriodicOrbit, b: PeriodicOrbit, wa: float, wb: float) -> List[Dict[str, Any]]:
    out: List[Dict[str, Any]] = []
    ia, ib = _indicators(a), _indicators(b)
    for name in ia:
        if ia[name] * ib[name] < 0:
            w = wa + (wb - wa) * ia[name] / (ia[name] - ib[name])
            out.append({"event": name, "omega": float(w), "between": (wa, wb), "from": a.type, "to": b.type})
    if a.type != b.type and not out:
        out.append({"event": "stability change", "omega": float(0.5 * (wa + wb)), "between": (wa, wb),
                    "from": a.type, "to": b.type})
    return out


@dataclass(frozen=True)
class HalvingStep:
    """The outcome of :func:`halving_step`.

    Attributes
    ----------
    result : Any
        What the accepted attempt returned (``None`` after a failure).
    value : Any
        The proposal tried last (the accepted one, or the last refused one).
    used : float
        Its step length.
    halvings : int
        Refused attempts before the outcome.
    failure : Exception or None
        The last refusal's error when the step was given up, else ``None``.
    """

    result: Any
    value: Any
    used: float
    halvings: int
    failure: Optional[BaseException]


def halving_step(h: float, propose: Callable[[float], Tuple[Any, float]], attempt: Callable[[Any], Any],
                 give_up: Callable[[int, float], bool],
                 errors: Tuple[Type[BaseException], ...] = (IntegrationError, StateError)) -> HalvingStep:
    """One accepted continuation step, or the reason there is none: the acceptance and
    halving loop shared by the continuations.

    ``propose(h)`` gives the proposal for a step of length ``h`` and the length it uses
    (``(value, used)``); ``attempt(value)`` computes the step and raises one of ``errors`` to
    refuse it. A refused step is tried again with half the used length, until ``give_up(halvings,
    h)`` (the number of refusals so far, the next length) is true.
    """
    halvings = 0
    while True:
        value, used = propose(h)
        try:
            return HalvingStep(attempt(value), value, used, halvings, None)
        except errors as exc:
            halvings += 1
            h = 0.5 * used
            if give_up(halvings, h):
                return HalvingStep(None, value, used, halvings, exc)


def toward(w_from: float, target: float, snap: bool = True) -> Callable[[float], Tuple[float, float]]:
    """The proposal of a natural-parameter step from ``w_from`` towards ``target`` (for
    :func:`halving_step`): ``w_from + h`` in the target's sense, ``target`` itself when within
    ``h`` of it (with ``snap``, also when within ``1e-12`` relative of it); the length used is
    ``|w - w_from|``."""
    sgn = float(np.sign(target - w_from))

    def propose(h: float) -> Tuple[float, float]:
        if not snap:
            w = target if abs(target - w_from) <= h else w_from + sgn * h
            return w, abs(w - w_from)
        w = w_from + sgn * min(h, abs(target - w_from))
        if abs(w - target) <= 1e-12 * (1 + abs(target)):
            w = float(target)
        return w, abs(w - w_from)
    return propose


def continue_in_omega(orbit: PeriodicOrbit, levels: Union[Levels, MParallelLevels], omegas: Sequence[float], *,
                      max_halvings: int = 8, max_iter: int = 20, jump_ratio: float = 0.5,
                      max_trace_change: float = 0.5) -> Branch:
    r"""Follow ``orbit`` (of the reduced or the M||gamma system) through the plane rates ``omegas`` on ``levels``.

    Parameters
    ----------
    orbit : PeriodicOrbit
        The start, at ``orbit.problem.params.plane_rate``.
    levels : Levels or MParallelLevels
        The level kept along the branch.
    omegas : sequence of float
        The values to reach, in order (monotone, starting next to the orbit's ``Omega``).
    max_halvings : int
        Consecutive halvings of a refused step before the branch is declared ended. The step
        starts as the largest gap of ``omegas`` and doubles after each accepted step.
    max_trace_change : float
        A step is refused (halved) if ``tr A`` (3D: ``tr A`` or the second trace) changes by
        more than this: steps resolve the turning of the multipliers, so that a passage of
        ``tr A`` through ``+-2`` is seen as an event and not stepped over.
    jump_ratio : float
        A step is accepted only if Newton's correction of the tangent prediction is at most
        ``jump_ratio`` times the predicted change of the state (``|x - x_pred| <=
        jump_ratio |x_pred - x_last|``; on a smooth branch the ratio is ``O(step)``). A larger
        correction means Newton left the branch (near a fold it converges to another periodic
        orbit on the far side): the step is halved instead, and after ``max_halvings`` the
        branch ends there, with the reason.
    max_iter : int
        Newton iterations of a step at most. A step's Newton also stops, and the step is
        refused (halved), when its residual is above the acceptance bound and has not halved
        over the last ``NEWTON_STALL`` (4) iterations: from the tangent prediction Newton
        converges fast where the branch goes on (such a step takes the same iterations and
        gives the same orbit to the bit as without this stop), and a residual that stalls
        (beyond a fold, say) would have the step refused after ``max_iter`` iterations
        anyway. A step whose Newton would creep to convergence after such a stall is
        refused and halved instead.

    Returns
    -------
    Branch
        Starts with ``orbit`` itself.

    Raises
    ------
    UsageError
        An orbit that is not of the reduced system, levels that are not a ``Levels``, a
        non-monotone or non-finite ``omegas``.
    """
    return _natural(orbit, levels, "Omega", omegas, "omegas", "continue_in_omega", max_halvings=max_halvings,
                    max_iter=max_iter, jump_ratio=jump_ratio, max_trace_change=max_trace_change)


def continue_in_level(orbit: PeriodicOrbit, levels: Union[Levels, MParallelLevels], parameter: str,
                      values: Sequence[float], *, max_halvings: int = 8, max_iter: int = 20, jump_ratio: float = 0.5,
                      max_trace_change: float = 0.5) -> Branch:
    r"""Follow ``orbit`` through the values ``values`` of one level value, ``Omega`` and the
    other level values kept: :func:`continue_in_omega` with a level value as the parameter.

    Parameters
    ----------
    orbit : PeriodicOrbit
        The start, on ``levels``.
    levels : Levels or MParallelLevels
        The start's level.
    parameter : str
        ``"C"``, ``"M_gamma"`` or ``"h"`` (the paper's ``G``, ``H``, ``h``) for the reduced
        system; ``"lam"`` or ``"h"`` for the M||gamma system.
    values : sequence of float
        The values to reach, in order (monotone, starting next to the level's own).
    max_halvings, max_iter, jump_ratio, max_trace_change
        As for :func:`continue_in_omega`.

    Returns
    -------
    Branch
        ``parameter`` names the level value; ``omega`` (also ``values``) holds its values.

    Raises
    ------
    UsageError
        As :func:`continue_in_omega`, and a ``parameter`` that is not a level value of the
        orbit's system.
    """
    return _natural(orbit, levels, parameter, values, "values", "continue_in_level", max_halvings=max_halvings,
                    max_iter=max_iter, jump_ratio=jump_ratio, max_trace_change=max_trace_change)


def _check_start(orbit: PeriodicOrbit, levels, parameter: Any, caller: str) -> float:
    prob0 = orbit.problem
    if prob0 is None or prob0.kind not in ("reduced", "mparallel"):
        raise UsageError(f"{caller} follows orbits of kind='reduced' or 'mparallel' (a PeriodicOrbit "
                         "from periodic_orbit)")
    want = Levels if prob0.kind == "reduced" else MParallelLevels
    if not isinstance(levels, want):
        raise UsageError(f"levels must be a taylorball.{want.__name__} for kind={prob0.kind!r}, got {levels!r}")
    return _start_value(orbit, levels, parameter)


def _natural(orbit: PeriodicOrbit, levels, parameter: str, values: Sequence[float], arg: str, caller: str, *,
             max_halvings: int, max_iter: int, jump_ratio: float, max_trace_change: float) -> Branch:
    """Natural-parameter continuation in ``parameter`` (``arg``: the values' argument name,
    ``caller``: the public function's name, for its error messages)."""
    w0 = _check_start(orbit, levels, parameter, caller)
    try:
        ws = np.asarray(list(values), dtype=float)
    except (TypeError, ValueError):
        raise UsageError(f"{arg} must be a non-empty sequence of finite floats, got {values!r}") from None
    if ws.ndim != 1 or ws.size == 0 or not np.all(np.isfinite(ws)):
        raise UsageError(f"{arg} must be a non-empty sequence of finite floats, got {values!r}")
    d = np.diff(np.concatenate([[w0], ws]))
    if not (np.all(d > 0) or np.all(d < 0)):
        raise UsageError(f"{arg} must run monotonically away from the orbit's {parameter} = {w0!r}, got {list(ws)!r}")
    if not (0.0 < float(jump_ratio) < 1.0):
        raise UsageError(f"jump_ratio must be in (0, 1), got {jump_ratio!r}")
    orbits = [orbit]
    omega = [w0]
    events: List[Dict[str, Any]] = []
    stopped = "reached"
    tangent = _tangent(orbit, levels, w0, parameter)
    h = float(np.max(np.abs(np.diff(np.concatenate([[w0], ws])))))  # the step length, adapted

    def attempt(w: float):
        new, x_pred = _solve_at(orbit=orbits[-1], tangent=tangent, w=w, w_from=omega[-1],
                                targets_base=levels, max_iter=max_iter, parameter=parameter)
        _check_on_branch(new, x_pred, orbits[-1], jump_ratio)
        dtr = _trace_change(orbits[-1], new)
        if dtr > max_trace_change:
            raise StateError(f"the multiplier matrix changed by {dtr:.3g} in trace over the step (more "
                             f"than max_trace_change = {max_trace_change})")
        return new, _tangent(new, levels, w, parameter)

    for w_target in ws:
        while abs(omega[-1] - w_target) > 1e-12 * (1 + abs(w_target)):
            w_from = omega[-1]
            step = halving_step(h, toward(w_from, float(w_target)), attempt,
                                lambda halvings, _h: halvings > max_halvings)
            if step.failure is not None:
                stopped = (f"no solution on the branch at {parameter} = {step.value!r} after {max_halvings} "
                           f"halvings of the step from {parameter} = {w_from!r} (a fold of the branch in {parameter}, where "
                           f"natural-parameter continuation ends, or the orbit left the level; last "
                           f"tr A = {orbits[-1].trace:.6g}): {step.failure}")
                break
            new, tangent = step.result
            events += _events(orbits[-1], new, w_from, step.value)
            orbits.append(new)
            omega.append(step.value)
            h = 2.0 * step.used
        if stopped != "reached":
            break
    return Branch(np.array(omega), orbits, events, stopped, parameter=parameter)


#: The level values a branch can follow besides ``Omega``, per system.
LEVEL_PARAMETERS = {"reduced": ("C", "M_gamma", "h"), "mparallel": ("lam", "h")}


def _start_value(orbit: PeriodicOrbit, levels, parameter: Any) -> float:
    """The value of ``parameter`` at the start ``orbit`` on ``levels``; a bad name is refused."""
    kind = orbit.problem.kind
    if parameter == "Omega":
        return float(getattr(orbit.problem.params, "plane_rate"))
    if not isinstance(parameter, str) or parameter not in LEVEL_PARAMETERS[kind]:
        raise UsageError(f"parameter must be 'Omega' or a level value of kind={kind!r} "
                         f"({', '.join(repr(n) for n in LEVEL_PARAMETERS[kind])}), got {parameter!r}")
    return float(getattr(levels, parameter))


def _levels_at(levels, parameter: str, w: float):
    """``levels`` with ``parameter`` (a level value, or ``"Omega"``: unchanged) set to ``w``;
    a value the level does not admit is a :class:`StateError` (the branch ends there)."""
    if parameter == "Omega":
        return levels
    try:
        return dataclasses.replace(levels, **{parameter: float(w)})
    except (UsageError, ValueError) as exc:
        raise StateError(f"the level with {parameter} = {w!r} is not admissible: {exc}") from None


def _ctx_at(orbit: PeriodicOrbit, levels, w: float, parameter: str = "Omega") -> _Ctx:
    import warnings

    from .params import UnphysicalParametersWarning

    if parameter == "Omega":
        with warnings.catch_warnings():  # the caller was warned when the parameters were made
            warnings.simplefilter("ignore", UnphysicalParametersWarning)
            params = dataclasses.replace(orbit.problem.params, plane_rate=w)
    else:
        params = orbit.problem.params
        levels = _levels_at(levels, parameter, w)
    prob = orbit_problem(orbit.problem.kind, params)
    names = _eval_geo(prob, orbit.g0, prob.spec.array(np.asarray(orbit.internal, dtype=float))).names
    exact = _level_targets(prob, names, levels)
    targets = prob.spec.array([exact[n] for n in names])
    return _Ctx(prob, orbit.g0, orbit.direction, orbit.k, targets, _has_axial_symmetry(prob), 1e4)


#: Step in ``Omega`` of the forward difference ``dF/dOmega`` (relative error of the tangent
#: ``O(delta)``, ample for a predictor).
_DELTA_OMEGA = 1e-6


def _tangent(orbit: PeriodicOrbit, levels, w: float, parameter: str = "Omega") -> np.ndarray:
    r"""``d(x, theta)/dOmega`` along the branch at ``orbit``: the solution of
    :math:`J_x \dot x = -\partial F/\partial\Omega` (the implicit function theorem; ``J_x``
    Newton's Jacobian, section, level and phase rows imposed exactly),
    ``dF/dOmega`` by a forward difference of the residual (the flow to the crossing, the
    level rows) at fixed ``(x, theta)``. Near a fold ``J_x`` turns singular and the tangent
    grows without bound, which shrinks the accepted steps."""
    x = np.asarray(orbit.internal, dtype=float)
    theta = float(orbit.shift)
    n = len(x)
    F = []
    for ww in (w, w + _DELTA_OMEGA):
        ctx = _ctx_at(orbit, levels, ww, parameter)
        spec = ctx.prob.spec
        r_map, r_sec, r_lev, xT, Phi, T, geo0 = _residual_parts(ctx, spec.array(x), spec.scalar(theta),
                                                                  spec.scalar(orbit.period))
        F.append(np.concatenate([_f64(r_map), _f64(r_sec), _f64(r_lev)] + ([[0.0]] if ctx.symmetric else [])))
        if ww == w:
            J, _ = _jacobian(ctx, spec.array(x), spec.scalar(theta), xT, Phi, geo0)
    dF = (F[1] - F[0]) / _DELTA_OMEGA
    d = _constrained_step(J, dF, n)  # J d = -dF
    return d if ctx.symmetric else np.concatenate([d, [0.0]])


#: A natural-continuation step's Newton stops (the step is refused) when its residual, above the
#: acceptance bound, has not halved over this many iterations (:func:`continue_in_omega`, ``max_iter``).
NEWTON_STALL = 4


def _solve_at(*, orbit: PeriodicOrbit, tangent: np.ndarray, w: float, w_from: float, targets_base, max_iter: int,
              parameter: str = "Omega"):
    ctx = _ctx_at(orbit, targets_base, w, parameter)
    spec = ctx.prob.spec
    n = len(orbit.internal)
    x_pred = np.asarray(orbit.internal, dtype=float) + tangent[:n] * (w - w_from)  # Euler predictor
    theta = float(orbit.shift) + float(tangent[n]) * (w - w_from)
    scale = max(1.0, float(np.max(np.abs(x_pred))))
    x = _to_level(ctx, spec.array(x_pred), scale)
    return _solve(ctx, x, theta, max_iter=max_iter, rtol=256 * spec.eps, stall=NEWTON_STALL), x_pred


def _trace_change(a: PeriodicOrbit, b: PeriodicOrbit) -> float:
    d = abs(b.trace - a.trace)
    return max(d, abs(b.second_trace - a.second_trace)) if a.matrix.shape == (3, 3) else d


def _check_on_branch(new: PeriodicOrbit, x_pred: np.ndarray, last: PeriodicOrbit, ratio: float) -> None:
    """Raise :class:`StateError` if Newton's solution ``new`` is not the continuation of
    ``last``: its distance from the tangent prediction exceeds ``ratio`` times the predicted
    change (``O(step^2)`` against ``O(step)`` on a smooth branch)."""
    x_new = np.asarray(new.internal, dtype=float)
    x_last = np.asarray(last.internal, dtype=float)
    corr = float(np.linalg.norm(x_new - x_pred))
    pred = float(np.linalg.norm(x_pred - x_last))
    floor = 1e-9 * max(1.0, float(np.max(np.abs(x_last))))  # Newton's own accuracy
    if corr > ratio * pred + floor:
        raise StateError(f"Newton's solution is {corr:.3g} from the tangent prediction, more than {ratio} x the "
                         f"predicted change {pred:.3g}: another orbit, not the continuation of the branch")


def _extended_residual(orbit: PeriodicOrbit, levels, x: np.ndarray, theta: float, w: float, T_guess: float,
                       parameter: str = "Omega"):
    """``(F, J_x, dF/dw, T)`` of Newton's equations at ``(x, theta)`` and ``parameter = w``."""
    out = []
    J = None
    T = T_guess
    for ww in (w, w + _DELTA_OMEGA):
        ctx = _ctx_at(orbit, levels, ww, parameter)
        spec = ctx.prob.spec
        r_map, r_sec, r_lev, xT, Phi, TT, geo0 = _residual_parts(ctx, spec.array(x), spec.scalar(theta),
                                                                   spec.scalar(T))
        out.append(np.concatenate([_f64(r_map), _f64(r_sec), _f64(r_lev)] + ([[0.0]] if ctx.symmetric else [])))
        if J is None:
            J, _ = _jacobian(ctx, spec.array(x), spec.scalar(theta), xT, Phi, geo0)
            T = float(TT)
    return out[0], J, (out[1] - out[0]) / _DELTA_OMEGA, T


@renamed(omega_range="bounds")
def continue_arclength(orbit: PeriodicOrbit, levels: Union[Levels, MParallelLevels], *, ds: float = 0.05,
                       n_steps: int = 20, bounds: Optional[Sequence[float]] = None, direction: int = -1,
                       max_halvings: int = 5, max_iter: int = 8, switch: Optional["SectionSwitch"] = None,
                       parameter: str = "Omega") -> Branch:
    r"""Pseudo-arclength continuation of ``orbit`` in ``(x, theta, Omega)``: through folds.

    ``parameter`` (default ``"Omega"``) may instead name a level value (``"C"``, ``"M_gamma"``,
    ``"h"``; ``"lam"``, ``"h"`` for the M||gamma system): the continuation is then in ``(x,
    theta, value)`` with ``Omega`` and the other level values kept, and ``Omega`` below reads as
    that value. ``bounds``: the branch ends when the parameter leaves ``(low, high)``; default
    ``(0, 2)`` for ``Omega`` (the paper's range), no bound for a level value (a level that is
    not admissible ends the branch). (``omega_range=`` is its deprecated old name.)

    The unknowns are the internal state, ``theta`` (symmetric ball) and ``Omega``; the
    equations are Newton's (map, section, level, phase) and the arclength condition
    ``t . (z - z_pred) = 0`` with ``t`` the unit secant of the last two points (the first
    tangent from the implicit function theorem, in the sense ``direction`` of ``Omega``) and
    ``z_pred = z_last + ds t``. ``dF/dOmega`` by a forward difference. Each corrected point
    is solved again at its ``Omega`` by :func:`taylorball.periodic_orbit`'s Newton (the
    checks of a periodic orbit); a point where that fails is skipped. A failed corrector
    halves ``ds`` up to ``max_halvings`` times; the branch ends there with the reason, or when
    ``Omega`` leaves ``omega_range``.

    With ``switch`` (a :class:`SectionSwitch`) the branch changes its section by itself:
    before each step it measures how transversally the orbit crosses its section
    (:func:`crossing_transversality`) and how near it passes the chart's singular point
    ``M || e3``; when either degrades below ``switch``'s thresholds (or a step fails) it
    moves the orbit to the section of :func:`section_scan` with the largest margin whose
    crossings are all transversal and whose crossing count the singular passage cannot
    change (:func:`on_section`), recomputes the tangent there and goes on. Each switch is
    recorded in ``Branch.switches``.

    Returns
    -------
    Branch
        ``omega`` is not monotone through a fold; ``events`` as for :func:`continue_in_omega`
        plus ``"fold"`` where ``Omega`` turns back.
    """
    w0 = _check_start(orbit, levels, parameter, "continue_arclength")
    prob0 = orbit.problem
    if not (isinstance(ds, (int, float)) and np.isfinite(ds) and ds > 0):
        raise UsageError(f"ds must be a positive finite arclength step, got {ds!r}")
    if direction not in (1, -1):
        raise UsageError(f"direction must be +1 or -1 (the initial sense of {parameter}), got {direction!r}")
    if not isinstance(n_steps, (int, np.integer)) or n_steps < 1:
        raise UsageError(f"n_steps must be an integer >= 1, got {n_steps!r}")
    if bounds is None:
        bounds = (0.0, 2.0) if parameter == "Omega" else (-np.inf, np.inf)
    try:
        lo, hi = (float(v) for v in bounds)
    except (TypeError, ValueError):
        raise UsageError(f"bounds must be a pair (low, high) of floats, got {bounds!r}") from None
    if not lo < hi:
        raise UsageError(f"bounds must be a pair (low, high) with low < high, got {bounds!r}")
    n = len(orbit.internal)
    symmetric = _has_axial_symmetry(prob0)

    def pack(o: PeriodicOrbit, w: float) -> np.ndarray:
        return np.concatenate([np.asarray(o.internal, dtype=float), [float(o.shift)] if symmetric else [], [w]])

    d = _tangent(orbit, levels, w0, parameter)
    t = np.concatenate([d[:n], d[n:n + 1] if symmetric else [], [1.0]]) * direction
    t /= np.linalg.norm(t)
    orbits, omega = [orbit], [w0]
    events: List[Dict[str, Any]] = []
    switches: List[Dict[str, Any]] = []
    stopped = "reached"
    h = float(ds)
    if switch is not None and prob0.kind != "reduced":
        raise UsageError("switch (section switching) needs an orbit of kind='reduced'")

    def do_switch(reason: Optional[str], scan: Optional[SectionScan], tr: float) -> np.ndarray:
        """Move the last orbit to a new section; returns the new unit tangent."""
        o, w = orbits[-1], omega[-1]
        if scan is None:
            scan = section_scan(o, n_samples=switch.n_samples)  # type: ignore[union-attr]
        new_o, tr_new = _switch(o, _levels_at(levels, parameter, w), scan, switch)  # type: ignore[arg-type]
        switches.append({"omega": float(w), "from": (float(o.g0), int(o.k)), "to": (float(new_o.g0), int(new_o.k)),
                         "reason": reason, "transversality": (tr, tr_new)})
        orbits[-1] = new_o
        dd = _tangent(new_o, levels, w, parameter)
        tt = np.concatenate([dd[:n], dd[n:n + 1] if symmetric else [], [1.0]])
        tt *= 1.0 if tt[-1] * t[-1] >= 0 else -1.0  # the sense of Omega the branch had
        return tt / np.linalg.norm(tt)

    for _ in range(int(n_steps)):
        if switch is not None:
            reason, scan, tr = _switch_reason(orbits[-1], switch)
            if reason is None and h < 1e-3 * float(ds) and not (switches and switches[-1]["omega"] == omega[-1]):
                reason = f"the steps shrank to ds = {h:.3g} on g0 = {orbits[-1].g0}"
            if reason is not None:
                try:
                    t = do_switch(reason, scan, tr)
                    h = float(ds)
                except (IntegrationError, StateError) as exc:
                    stopped = f"no section to switch to at {parameter} = {omega[-1]!r} ({reason}): {exc}"
                    break
        z_last = pack(orbits[-1], omega[-1])
        halvings = 0
        switched_here = False
        while True:
            try:
                new, w_new = _arclength_step(orbits[-1], levels, z_last, t, h, n, symmetric, max_iter, parameter)
                break
            except (IntegrationError, StateError, np.linalg.LinAlgError) as exc:
                halvings += 1
                h *= 0.5
                if halvings > max_halvings:
                    if switch is not None and not switched_here:
                        try:  # a step that fails on this section: try the orbit on another one
                            tr0 = float(np.min(crossing_transversality(orbits[-1])))
                            t = do_switch(f"the step failed ({str(exc)[:120]})", None, tr0)
                        except (IntegrationError, StateError) as exc2:
                            stopped = (f"the corrector failed after {max_halvings} halvings of ds at {parameter} ~ "
                                       f"{omega[-1]!r}: {exc}; no section to switch to: {exc2}")
                            break
                        switched_here, halvings, h = True, 0, float(ds)
                        z_last = pack(orbits[-1], omega[-1])
                        continue
                    stopped = f"the corrector failed after {max_halvings} halvings of ds at {parameter} ~ {omega[-1]!r}: {exc}"
                    break
        if stopped != "reached":
            break
        z_new = pack(new, w_new)
        if len(omega) >= 2 and (w_new - omega[-1]) * (omega[-1] - omega[-2]) < 0:
            events.append({"event": "fold", "omega": float(omega[-1]), "between": (omega[-2], w_new),
                           "from": orbits[-1].type, "to": new.type})
        events += _events(orbits[-1], new, omega[-1], w_new)
        t = z_new - z_last
        if not float(np.linalg.norm(t)) > 0.0:
            stopped = f"the branch stalled at {parameter} = {omega[-1]!r} (a step of ds = {h:.3g} gave the same point)"
            break
        t /= np.linalg.norm(t)
        orbits.append(new)
        omega.append(w_new)
        if halvings == 0:
            h = min(2.0 * h, float(ds))
        if not lo <= w_new <= hi:
            stopped = f"{parameter} left bounds = {(lo, hi)!r}"
            break
    return Branch(np.array(omega), orbits, events, stopped, switches, parameter=parameter)


def _arclength_step(orbit: PeriodicOrbit, levels, z_last: np.ndarray, t: np.ndarray, h: float, n: int,
                    symmetric: bool, max_iter: int, parameter: str = "Omega"):
    z_pred = z_last + h * t
    z = z_pred.copy()
    T = float(orbit.period)
    scale = max(1.0, float(np.max(np.abs(z_last[:n]))))
    for it in range(max_iter):
        w = float(z[-1])
        ctx = _ctx_at(orbit, levels, w, parameter)
        x = _f64(_to_level(ctx, ctx.prob.spec.array(z[:n]), scale))
        z[:n] = x
        theta = float(z[n]) if symmetric else 0.0
        F, J, dF, T = _extended_residual(orbit, levels, x, theta, w, T, parameter)
        res = float(np.max(np.abs(F)))
        if res <= 1e-7 * scale:  # the fixed-Omega Newton below polishes to rounding
            break
        Jz = np.hstack([J, dF[:, None]])
        Jfull = np.vstack([Jz, t[None, :]])
        rhs = np.concatenate([F, [float(np.dot(t, z - z_pred))]])
        # map rows least squares, section/level/phase/arclength rows exactly
        step = _constrained_step(Jfull, rhs, n)
        z = z + step
    else:
        raise StateError(f"the pseudo-arclength corrector did not converge (residual {res:.1e})")
    w = float(z[-1])
    ctx = _ctx_at(orbit, levels, w, parameter)
    spec = ctx.prob.spec
    o = _solve(ctx, spec.array(z[:n]), float(z[n]) if symmetric else 0.0, max_iter=6, rtol=256 * spec.eps)
    moved = float(np.max(np.abs(np.asarray(o.internal, dtype=float) - z[:n])))
    if moved > 1e-5 * scale:
        raise StateError(f"the fixed-{parameter} Newton moved the corrected point by {moved:.1e}: another orbit")
    return o, w


# ---------------------------------------------------------------------------------------
# From the symmetric ball to an asymmetric one: a homotopy in the inertia, Omega free.
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class InertiaHomotopy:
    """A path of periodic orbits along ``I(s) = I0 + s (I1 - I0)`` with ``Omega`` free.

    Attributes
    ----------
    s, omega, period : ndarray
        The path parameter reached, the plane rate and the period at each point.
    states : list of ndarray
        Public states on the section (of each point's own ball).
    orbit : PeriodicOrbit or None
        The last point solved again by :func:`taylorball.periodic_orbit` (its crossings
        counted afresh), or ``None`` if that failed.
    stopped : str
        ``"reached"`` at ``s = 1``, else why the path ended.
    """

    s: np.ndarray
    omega: np.ndarray
    period: np.ndarray
    states: List[np.ndarray]
    orbit: Optional[PeriodicOrbit]
    stopped: str


def inertia_homotopy(orbit: PeriodicOrbit, levels: Levels, inertia: Sequence[float], *, q: int = 2,
                     phase: float = 0.0, ds: float = 1e-4, ds_max: float = 0.05, max_steps: int = 400,
                     max_iter: int = 12) -> InertiaHomotopy:
    r"""Periodic orbits of an asymmetric ball from a relative periodic orbit of the symmetric one.

    A relative periodic orbit ``P^k x = S_theta x`` of the symmetric ball with ``q theta = 0``
    (mod ``2 pi``) is a circle of periodic orbits of ``P^{kq}`` (the states ``S_phi x``). When
    the inertia moves away from ``I1 = I2`` the circle breaks; the orbits that survive (to
    first order, for ``q = 1, 2``: the breaking enters as ``cos 2 phi``) sit at a ``phi`` for
    each ``Omega`` in a narrow window. So ``Omega`` is an unknown and the phase is fixed:
    Newton on ``(x, Omega)`` with

    .. math:: \phi_{T}(x) - x = 0,\quad e(x) = 0,\quad c(x) = c^*,\quad
              (u_3(x_0), x - x_0) = 0,

    ``x_0 = S_phase x*`` (``T`` the crossing near the last period: the number of crossings may
    change along the path without harm), regular at ``s = 0``. The inertia runs along
    ``I(s) = I0 + s (I1 - I0)`` with a secant predictor and an adapted step.

    Parameters
    ----------
    orbit : PeriodicOrbit
        A relative periodic orbit of a symmetric ball (kind ``"reduced"``, ``I1 = I2``).
    levels : Levels
        Kept along the path.
    inertia : sequence of 3 floats
        ``I1``, the end of the path.
    q : int
        ``q theta = 0`` mod ``2 pi`` is required (to 1e-8).
    phase : float
        ``phi`` of the start state ``S_phi x*`` on the circle.
    ds, ds_max, max_steps, max_iter
        First and largest step in ``s``, steps, Newton iterations per step.

    Returns
    -------
    InertiaHomotopy
    """
    import warnings

    from ._propagate import public_state
    from .params import BallParams, UnphysicalParametersWarning
    from .periodic import (_residual_parts, _rotate3, _u3, orbit_problem, periodic_orbit)
    from .sections import poincare_section

    prob0 = orbit.problem
    if prob0 is None or prob0.kind != "reduced" or not _has_axial_symmetry(prob0):
        raise UsageError("inertia_homotopy starts from a relative periodic orbit of a symmetric ball (I1 = I2)")
    if not isinstance(levels, Levels):
        raise UsageError(f"levels must be a taylorball.Levels, got {levels!r}")
    if not isinstance(q, (int, np.integer)) or q < 1:
        raise UsageError(f"q must be an integer >= 1, got {q!r}")
    th = float(orbit.shift) * int(q)
    if abs((th + np.pi) % (2 * np.pi) - np.pi) > 1e-8:
        raise UsageError(f"q theta must be 0 mod 2 pi: theta = {orbit.shift!r}, q = {q}")
    ball0 = prob0.params
    assert isinstance(ball0, BallParams)
    I0 = np.array(ball0.inertia, dtype=float)
    I1 = np.array([float(v) for v in inertia])
    if I1.shape != (3,) or not np.all(np.isfinite(I1)) or np.any(I1 <= 0):
        raise UsageError(f"inertia must be 3 positive finite floats, got {inertia!r}")
    K = orbit.k * int(q)

    def ctx_at(s: float, w: float) -> _Ctx:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnphysicalParametersWarning)
            I_s = I0 + s * (I1 - I0)
            params = dataclasses.replace(ball0, inertia=(float(I_s[0]), float(I_s[1]), float(I_s[2])), plane_rate=w)
        prob = orbit_problem("reduced", params)
        names = _eval_geo(prob, orbit.g0, prob.spec.array(np.asarray(orbit.internal, dtype=float))).names
        exact = _level_targets(prob, names, levels)
        return _Ctx(prob, orbit.g0, orbit.direction, K, prob.spec.array([exact[n] for n in names]), False, 1e4)

    c, sn = np.cos(phase), np.sin(phase)
    x0 = np.asarray(_rotate3(np.asarray(orbit.internal, dtype=float), c, sn), dtype=float)
    u = _u3(x0)
    u = u / np.linalg.norm(u)
    scale = max(1.0, float(np.max(np.abs(x0))))

    def solve(s: float, x: np.ndarray, w: float, T: float):
        res = np.inf
        for _ in range(int(max_iter)):
            ctx = ctx_at(s, w)
            x = _f64(_to_level(ctx, ctx.prob.spec.array(x), scale))
            r_map, r_sec, r_lev, xT, Phi, TT, geo0 = _residual_parts(ctx, ctx.prob.spec.array(x), 0.0,
                                                                     ctx.prob.spec.scalar(T))
            F = np.concatenate([_f64(r_map), _f64(r_sec), _f64(r_lev), [float(np.dot(u, x - x0))]])
            res = float(np.max(np.abs(F)))
            T = float(TT)
            if res <= 1e-11 * scale:
                return x, w, T
            J, _ = _jacobian(ctx, x, 0.0, xT, Phi, geo0)
            ctx2 = ctx_at(s, w + _DELTA_OMEGA)
            r2 = _residual_parts(ctx2, ctx2.prob.spec.array(x), 0.0, ctx2.prob.spec.scalar(T))
            F2 = np.concatenate([_f64(r2[0]), _f64(r2[1]), _f64(r2[2])])
            dF = (F2 - F[:-1]) / _DELTA_OMEGA
            Jz = np.vstack([np.hstack([J, dF[:, None]]), np.concatenate([u, [0.0]])[None, :]])
            step = _constrained_step(Jz, F, len(x))
            if abs(step[-1]) > 0.02 or float(np.max(np.abs(step[:-1]))) > 0.1 * scale:
                raise StateError(f"Newton step too large (Omega by {abs(step[-1]):.1e})")
            x, w = x + step[:-1], w + float(step[-1])
        raise StateError(f"Newton on (x, Omega) did not converge (residual {res:.1e})")

    w0 = float(ball0.plane_rate)
    pts = [(0.0, x0, w0, float(orbit.period) * int(q))]
    s, h, stopped = 0.0, float(ds), "reached"
    for _ in range(int(max_steps)):
        if s >= 1.0:
            break
        s_new = min(1.0, s + h)
        if len(pts) >= 2:
            (s1, xa, wa, Ta), (s2, xb, wb, Tb) = pts[-2], pts[-1]
            r = (s_new - s2) / (s2 - s1)
            guess = (xb + r * (xb - xa), wb + r * (wb - wa), Tb + r * (Tb - Ta))
        else:
            guess = (pts[-1][1], pts[-1][2], pts[-1][3])
        try:
            x, w, T = solve(s_new, *guess)
        except (IntegrationError, StateError) as exc:
            h *= 0.5
            if h < 1e-7:
                stopped = f"no solution beyond s = {s!r} (Omega = {pts[-1][2]!r}): {exc}"
                break
            continue
        pts.append((s_new, x, w, T))
        s = s_new
        h = min(2.0 * h, float(ds_max))
    else:
        stopped = f"max_steps = {max_steps} reached at s = {s!r}"
    states = []
    for sp, x, w, _ in pts:
        p = ctx_at(sp, w).prob
        states.append(public_state(p.system, p.pars, p.spec.array(x), p.spec))
    final: Optional[PeriodicOrbit] = None
    s_end, x_end, w_end, T_end = pts[-1]
    if s_end > 0.0:
        ctx = ctx_at(s_end, w_end)
        run = poincare_section(ctx.prob, states[-1], n_points=4096, g0=orbit.g0, t_end=T_end * (1 + 1e-7),
                               direction=1 if orbit.direction == 1 else -1)
        k_end = sum(1 for t in run.times if 1e-6 < float(t) <= T_end * (1 + 1e-7))
        try:
            final = periodic_orbit(ctx.prob, state=states[-1], k=k_end, g0=orbit.g0,
                                   direction=orbit.direction, levels=levels)  # type: ignore[arg-type]
        except (IntegrationError, StateError):
            final = None
    return InertiaHomotopy(np.array([p[0] for p in pts]), np.array([p[2] for p in pts]),
                           np.array([p[3] for p in pts]), states, final, stopped)


