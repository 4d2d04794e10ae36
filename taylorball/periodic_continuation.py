r"""Continuation of a periodic orbit in the plane's rate ``Omega``: :func:`continue_in_omega`.

Natural-parameter continuation with a secant predictor: at each new ``Omega`` the internal
state predicted from the last two solutions is moved onto the section and the level (the
levels ``C, M_gamma, h`` are kept; the energy depends on ``Omega``) and Newton
(:mod:`taylorball.periodic`) corrects it. A failed step is halved (``max_halvings`` times);
when it still fails the branch ends there, with the reason (a fold of the branch in
``Omega``, where natural-parameter continuation must fail, or the orbit leaving the
admissible region). Pseudo-arclength (continuing through folds) is not implemented.

Between consecutive solutions the branch records events: a change of stability type, a
multiplier through -1 (period doubling: ``tr A + 2`` changes sign for a 2D map,
``sigma + tau + 2`` for a 3D one) and through +1 (``tr A - 2``; ``sigma - tau``), located at
the linear interpolation of the sign change.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy as np

from .errors import IntegrationError, StateError, UsageError
from .levels import Levels, MParallelLevels
from .periodic import (PeriodicOrbit, _Ctx, _eval_geo, _has_axial_symmetry, _level_targets, _solve, _to_level,
                       orbit_problem)

__all__ = ["Branch", "continue_in_omega"]


@dataclass(frozen=True)
class Branch:
    """A branch of periodic orbits against ``Omega``.

    Attributes
    ----------
    omega : ndarray
        The parameter values reached, in order.
    orbits : list of PeriodicOrbit
    events : list of dict
        ``{"event": "stability change" | "period doubling" | "multiplier +1", "omega": float,
        "between": (omega_a, omega_b), "from": type_a, "to": type_b}``.
    stopped : str
        Why the branch ended (``"reached"`` when every requested value was reached).
    """

    omega: np.ndarray
    orbits: List[PeriodicOrbit]
    events: List[Dict[str, Any]] = field(default_factory=list)
    stopped: str = "reached"

    @property
    def trace(self) -> np.ndarray:
        return np.array([o.trace for o in self.orbits])

    @property
    def period(self) -> np.ndarray:
        return np.array([o.period for o in self.orbits])


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


def continue_in_omega(orbit: PeriodicOrbit, levels: Union[Levels, MParallelLevels], omegas: Sequence[float], *,
                      max_halvings: int = 4, max_iter: int = 20) -> Branch:
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
        Halvings of a failed step before the branch is declared ended.

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
    prob0 = orbit.problem
    if prob0 is None or prob0.kind not in ("reduced", "mparallel"):
        raise UsageError("continue_in_omega follows orbits of kind='reduced' or 'mparallel' (a PeriodicOrbit "
                         "from periodic_orbit)")
    want = Levels if prob0.kind == "reduced" else MParallelLevels
    if not isinstance(levels, want):
        raise UsageError(f"levels must be a taylorball.{want.__name__} for kind={prob0.kind!r}, got {levels!r}")
    ws = np.asarray(list(omegas), dtype=float)
    w0 = float(getattr(prob0.params, "plane_rate"))
    if ws.size == 0 or not np.all(np.isfinite(ws)):
        raise UsageError(f"omegas must be a non-empty sequence of finite floats, got {omegas!r}")
    d = np.diff(np.concatenate([[w0], ws]))
    if not (np.all(d > 0) or np.all(d < 0)):
        raise UsageError(f"omegas must run monotonically away from the orbit's Omega = {w0!r}, got {list(ws)!r}")
    orbits = [orbit]
    omega = [w0]
    events: List[Dict[str, Any]] = []
    prev_x: Optional[np.ndarray] = None
    stopped = "reached"
    targets_base = levels
    for w_target in ws:
        w_from = omega[-1]
        step = w_target - w_from
        halvings = 0
        while True:
            w = w_from + step
            try:
                new = _solve_at(orbit=orbits[-1], prev_x=prev_x, w_prev2=omega[-2] if len(omega) > 1 else None,
                                w=w, w_from=w_from, targets_base=targets_base, max_iter=max_iter)
            except (IntegrationError, StateError) as exc:
                halvings += 1
                if halvings > max_halvings:
                    stopped = (f"Newton failed at Omega = {w!r} after {max_halvings} halvings of the step from "
                               f"Omega = {w_from!r} (a fold of the branch, or the orbit left the level): {exc}")
                    break
                step *= 0.5
                continue
            events += _events(orbits[-1], new, w_from, w)
            prev_x = np.asarray(orbits[-1].internal, dtype=float)
            orbits.append(new)
            omega.append(w)
            if abs(w - w_target) <= 1e-12 * (1 + abs(w_target)):
                break
            w_from, step = w, w_target - w
        if stopped != "reached":
            break
    return Branch(np.array(omega), orbits, events, stopped)


def _solve_at(*, orbit: PeriodicOrbit, prev_x, w_prev2, w: float, w_from: float, targets_base, max_iter: int):
    import warnings

    from .params import UnphysicalParametersWarning

    with warnings.catch_warnings():  # the caller was warned when the parameters were made
        warnings.simplefilter("ignore", UnphysicalParametersWarning)
        params = dataclasses.replace(orbit.problem.params, plane_rate=w)
    prob = orbit_problem(orbit.problem.kind, params)
    spec = prob.spec
    x = np.asarray(orbit.internal, dtype=float)
    if prev_x is not None and w_prev2 is not None and w_from != w_prev2:
        x = x + (x - prev_x) * (w - w_from) / (w_from - w_prev2)  # secant predictor
    x = spec.array(x)
    names = _eval_geo(prob, orbit.g0, x).names
    exact = _level_targets(prob, names, targets_base)
    targets = spec.array([exact[n] for n in names])
    ctx = _Ctx(prob, orbit.g0, orbit.direction, orbit.k, targets, _has_axial_symmetry(prob), 1e4)
    scale = max(1.0, float(np.max(np.abs(x.astype(float)))))
    x = _to_level(ctx, x, scale)
    return _solve(ctx, x, orbit.shift, max_iter=max_iter, rtol=256 * spec.eps)
