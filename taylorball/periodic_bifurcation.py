r"""Branch points, resonances and whole families over a parameter interval: the data of a
bifurcation diagram of periodic orbits.

:func:`taylorball.periodic_continuation.continue_arclength` records the events two
neighbouring points of a branch show: a multiplier through -1 or +1, a change of type, a fold
(the parameter turns back). This module adds what needs the whole branch:

* **Branch points** (:func:`branch_points`). Along a pseudo-arclength branch the bordered
  (extended) Jacobian of the fixed-point equation ``G(y, w) = P(y; w) - y`` in coordinates
  ``y`` of section and level is

  .. math:: \begin{pmatrix} A - I & G_w \\ t_y^T & t_w \end{pmatrix},

  ``(t_y, t_w)`` the unit tangent (its kernel vector). Where ``A - I`` is invertible, the
  Schur complement gives its determinant as :math:`\det(A - I)\,|t|^2 / t_w`
  (``t_y = -(A - I)^{-1} G_w t_w``), so its sign is
  :math:`\mathrm{sign}\det(A - I)\cdot\mathrm{sign}(dw/ds)`. At a fold both factors change
  sign and the determinant keeps its sign; at a simple branch point ``det(A - I)`` changes
  sign with ``w`` running on: the determinant changes sign. ``det(A - I)`` is the same in every
  basis of the tangent space (the basis along a branch is an SVD's, whose orientation is
  arbitrary), which is why the sign is computed from this product and not from the bordered
  matrix itself. For a 2D map with ``det A = 1``, ``det(A - I) = 2 - tr A``; for a 3D one,
  ``tau - sigma`` (trace and second trace). For reversible maps a symmetric orbit meets a
  pair of asymmetric ones there (a pitchfork with a multiplier +1); in a generic family with
  no symmetry a multiplier +1 is a fold.
* **Resonances** (:func:`resonances`) of a 2D map: ``tr A`` through ``2 cos(2 pi p / q)``
  (``q = 3``: -1; ``q = 4``: 0), where orbits of period ``q k`` bifurcate from the branch.
  A ``1:3`` resonance is not a sign change of ``det(A^3 - I) = -(t + 1)^2 (t - 2)``
  (``t = tr A``): it touches 0, so the bordered-determinant test cannot see it.
* **Switching branches**: :func:`branch_orbits` (the other orbits of the same ``k`` next to
  one near a branch point) and :func:`period_doubled_orbit` (the orbit of twice the period
  next to one near a period doubling), by Newton from seeds along the tangent space of
  section and level.
* **A family over an interval** (:func:`follow_family`): pseudo-arclength from one orbit in
  both senses of the parameter, each side landed on the interval's end by natural
  continuation, merged into one :class:`Family` with every event.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from .errors import IntegrationError, StateError, UsageError
from .levels import Levels, MParallelLevels
from .periodic import PeriodicOrbit
from .periodic_continuation import AlongOrbits, Branch
from .periodic_sections import SectionSwitch

__all__ = ["det_a_minus_i", "unit_crossings", "branch_points", "resonances", "Family", "follow_family",
           "period_doubled_orbit", "branch_orbits"]


def det_a_minus_i(orbit: PeriodicOrbit, power: int = 1) -> float:
    """``det(A^power - I)`` of the orbit's multiplier matrix ``A`` (the section map on the
    level; for a symmetric ball the quotient map): 0 where a multiplier is +1 (``power = 2``:
    +1 or -1, a period doubling being a branch point of ``P^2``)."""
    A = np.asarray(orbit.matrix, dtype=float)
    return float(np.linalg.det(np.linalg.matrix_power(A, int(power)) - np.eye(A.shape[0])))


def unit_crossings(values: ArrayLike, dets: ArrayLike) -> List[Tuple[int, str, float]]:
    r"""Where ``det(A - I)`` changes sign along a branch, and whether each is a fold or a branch point.

    Parameters
    ----------
    values : sequence of float
        The parameter at the branch's points, in the order of the arclength.
    dets : sequence of float
        ``det(A - I)`` at the same points.

    Returns
    -------
    list of (int, str, float)
        ``(i, kind, w)``: a sign change between points ``i`` and ``i + 1``; ``kind`` is
        ``"fold"`` when the parameter turns back at point ``i`` or ``i + 1`` (the sign of the
        bordered determinant, ``sign det(A - I) * sign(dw/ds)``, is kept) and ``"branch
        point"`` when it runs on over points ``i - 1 .. i + 2`` (the bordered determinant
        changes sign); ``w`` the linear interpolation of the zero of ``det(A - I)``.

    Raises
    ------
    UsageError
        Arrays of different lengths or with non-finite values.
    """
    w = np.asarray(values, dtype=float)
    d = np.asarray(dets, dtype=float)
    if w.shape != d.shape or w.ndim != 1 or not (np.all(np.isfinite(w)) and np.all(np.isfinite(d))):
        raise UsageError(f"values and dets must be 1D finite arrays of one length, got shapes {w.shape}, {d.shape}")
    dw = np.diff(w)
    out: List[Tuple[int, str, float]] = []
    for i in range(len(w) - 1):
        if not d[i] * d[i + 1] < 0:
            continue
        near = dw[max(0, i - 1): i + 2]  # the steps into i, from i to i + 1, out of i + 1
        turns = bool(np.any(near[:-1] * near[1:] < 0)) if len(near) > 1 else False
        wz = float(w[i] + (w[i + 1] - w[i]) * d[i] / (d[i] - d[i + 1]))
        out.append((i, "fold" if turns else "branch point", wz))
    return out


def branch_points(branch: Branch, power: int = 1) -> List[Dict[str, Any]]:
    """The branch points of a :class:`~taylorball.periodic_continuation.Branch` (from
    :func:`~taylorball.periodic_continuation.continue_arclength`), as events.

    Parameters
    ----------
    branch : Branch
    -------
    power : int
        ``2``: the branch points of ``P^2`` (``det(A^2 - I)``): the period doublings, where a
        family of twice the period branches off, besides those of ``P``.

    Returns
    -------
    list of dict
        ``{"event": "branch point", "omega": w, "between": (w_i, w_i1), "from": type, "to":
        type, "symmetric": the orbit's reversor or None, "reason": str}``; ``"omega"`` is a
        value of the branch's ``parameter``. A symmetric orbit's branch point is the expected
        pitchfork of a reversible map (a pair of asymmetric orbits branches off).
    """
    orbits = branch.orbits
    if not isinstance(power, (int, np.integer)) or power < 1:
        raise UsageError(f"power must be an integer >= 1, got {power!r}")
    dets = [det_a_minus_i(o, power) for o in orbits]
    out: List[Dict[str, Any]] = []
    for i, kind, wz in unit_crossings(branch.omega, dets):
        if kind != "branch point":
            continue
        a, b = orbits[i], orbits[i + 1]
        sym = a.symmetric if a.symmetric == b.symmetric else None
        out.append({"event": "branch point" if power == 1 else f"branch point of P^{int(power)}", "omega": wz, "between": (float(branch.omega[i]), float(branch.omega[i + 1])),
                    "from": a.type, "to": b.type, "symmetric": sym,
                    "reason": (f"det(A{'' if power == 1 else f'^{int(power)}'} - I) changed sign ({dets[i]:.3g} -> {dets[i + 1]:.3g}) while "
                               f"{branch.parameter} ran on without turning: the bordered Jacobian's determinant "
                               "changed sign without a fold"
                               + (f" (a pitchfork of the orbit symmetric under {sym})" if sym else ""))})
    return out


def resonances(branch: Branch, qs: Sequence[int] = (3, 4)) -> List[Dict[str, Any]]:
    """``1:q`` resonances of a branch of a 2D map: ``tr A`` through ``2 cos(2 pi / q)``, where
    orbits of ``q`` times the period meet the branch; an empty list for a 3D map.

    Returns
    -------
    list of dict
        ``{"event": "1:q resonance", "omega": w, "between": (w_i, w_i1), "q": q, "from":
        type, "to": type}``, ``w`` the linear interpolation.
    """
    orbits = branch.orbits
    if not orbits or np.asarray(orbits[0].matrix).shape != (2, 2):
        return []
    tr = np.array([o.trace for o in orbits])
    w = np.asarray(branch.omega, dtype=float)
    out: List[Dict[str, Any]] = []
    for q in qs:
        c = 2.0 * np.cos(2.0 * np.pi / int(q))
        f = tr - c
        for i in np.nonzero(f[:-1] * f[1:] < 0)[0]:
            wz = float(w[i] + (w[i + 1] - w[i]) * f[i] / (f[i] - f[i + 1]))
            out.append({"event": f"1:{int(q)} resonance", "omega": wz, "between": (float(w[i]), float(w[i + 1])),
                        "q": int(q), "from": orbits[i].type, "to": orbits[i + 1].type})
    return out


@dataclass(frozen=True)
class Family(AlongOrbits):
    """A family of periodic orbits followed over a parameter interval (:func:`follow_family`).

    Attributes
    ----------
    omega : ndarray
        The parameter along the family, in the order of the arclength (from the low-side end
        through the start to the high-side end; not monotone through a fold).
    orbits : list of PeriodicOrbit
    events : list of dict
        Those of :func:`~taylorball.periodic_continuation.continue_arclength` (folds,
        multipliers through +-1, changes of type), :func:`branch_points` and
        :func:`resonances`, sorted by ``"omega"``.
    stopped : dict
        ``{"down": reason, "up": reason}``: why each side ended (``"reached <bound>"`` when it
        was landed on the interval's end).
    start : int
        Index of the start orbit in ``orbits``.
    cpu_s : float
        Process CPU seconds of the whole computation.
    """

    omega: np.ndarray
    orbits: List[PeriodicOrbit]
    events: List[Dict[str, Any]] = field(default_factory=list)
    stopped: Dict[str, str] = field(default_factory=dict)
    start: int = 0
    cpu_s: float = 0.0

    @property
    def types(self) -> List[str]:
        """The stability type along the family."""
        return [o.type for o in self.orbits]


def _side(orbit: PeriodicOrbit, levels, direction: int, bounds: Tuple[float, float], ds: float, n_steps: int,
          switch) -> Tuple[List[float], List[PeriodicOrbit], List[Dict[str, Any]], str]:
    """One side of :func:`follow_family`: the arclength branch, its last point outside the
    bounds replaced by the orbit on the bound itself."""
    from .periodic_continuation import continue_arclength, continue_in_omega

    b = continue_arclength(orbit, levels, ds=ds, n_steps=n_steps, bounds=bounds, direction=direction, switch=switch)
    w, orbits = list(b.omega), list(b.orbits)
    events = list(b.events)
    stopped = b.stopped
    if stopped == "reached":  # continue_arclength's word when its n_steps ran out
        stopped = f"n_steps = {n_steps} taken, at Omega = {float(w[-1])!r}"
    lo, hi = bounds
    if len(w) >= 2 and not lo <= w[-1] <= hi:
        edge = lo if w[-1] < lo else hi
        outside = w.pop()
        orbits.pop()
        events = [e for e in events if lo <= e["omega"] <= hi]
        try:
            land = continue_in_omega(orbits[-1], levels, [edge])
            if land.stopped == "reached":
                w.append(float(edge))
                orbits.append(land.orbits[-1])
                events += land.events
                stopped = f"reached {edge!r}"
            else:
                stopped = f"the step to {edge!r} failed: {land.stopped}"
        except (IntegrationError, StateError) as exc:
            stopped = f"the step to {edge!r} from {w[-1]!r} failed (the arclength step went to {outside!r}): {exc}"
    part = Branch(np.array(w), orbits, [], stopped, parameter=b.parameter)
    events += branch_points(part) + resonances(part)
    return w, orbits, events, stopped


def follow_family(orbit: PeriodicOrbit, levels: Union[Levels, MParallelLevels], *,
                  bounds: Sequence[float] = (0.0, 2.0), ds: float = 0.1, n_steps: int = 100,
                  sides: Sequence[int] = (-1, 1), switch: Optional[SectionSwitch] = None) -> Family:
    r"""Follow ``orbit`` in ``Omega`` over ``bounds`` in both senses, with every event.

    Each side is :func:`~taylorball.periodic_continuation.continue_arclength` (through folds)
    from ``orbit`` in the sense ``-1`` (down) or ``+1`` (up); where it leaves ``bounds``, its
    last point (outside) is replaced by the orbit on the bound itself
    (:func:`~taylorball.periodic_continuation.continue_in_omega` from the last point inside).
    Branch points (:func:`branch_points`) and ``1:3``, ``1:4`` resonances
    (:func:`resonances`) are added to the events.

    Parameters
    ----------
    orbit : PeriodicOrbit
        The start, of kind ``"reduced"`` or ``"mparallel"``, at an ``Omega`` inside ``bounds``.
    levels : Levels or MParallelLevels
        Kept along the family.
    bounds : (float, float)
        The interval of ``Omega``.
    ds, n_steps
        Arclength step and the largest number of steps per side.
    sides : sequence of int
        The senses to follow: ``(-1, 1)``, ``(-1,)`` or ``(1,)``.
    switch : SectionSwitch, optional
        Section switching (reduced system), as for ``continue_arclength``.

    Returns
    -------
    Family

    Raises
    ------
    UsageError
        Bad ``bounds`` (not ``low < high``, or not containing the orbit's ``Omega``), ``sides``
        or ``n_steps``; the errors of ``continue_arclength`` for the rest.
    """
    try:
        lo, hi = (float(v) for v in bounds)
    except (TypeError, ValueError):
        raise UsageError(f"bounds must be a pair (low, high) of floats, got {bounds!r}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise UsageError(f"bounds must be a finite pair (low, high) with low < high, got {bounds!r}")
    w0 = float(getattr(getattr(orbit.problem, "params", None), "plane_rate", np.nan))
    if not lo <= w0 <= hi:
        raise UsageError(f"the orbit's Omega = {w0!r} is not inside bounds = {(lo, hi)!r}")
    if not sides or any(s not in (-1, 1) for s in sides) or len(set(sides)) != len(list(sides)):
        raise UsageError(f"sides must be (-1, 1), (-1,) or (1,), got {sides!r}")
    c0 = time.process_time()
    ws: Dict[int, List[float]] = {}
    os_: Dict[int, List[PeriodicOrbit]] = {}
    events: List[Dict[str, Any]] = []
    stopped: Dict[str, str] = {}
    for s in sides:
        w, o, ev, st = _side(orbit, levels, int(s), (lo, hi), float(ds), n_steps, switch)
        ws[s], os_[s] = w, o
        events += ev
        stopped["down" if s < 0 else "up"] = st
    down_w, down_o = (ws[-1][::-1], os_[-1][::-1]) if -1 in ws else ([w0], [orbit])
    up_w, up_o = (ws[1][1:], os_[1][1:]) if 1 in ws else ([], [])
    events.sort(key=lambda e: e["omega"])
    return Family(np.array(down_w + up_w), down_o + up_o, events, stopped, len(down_w) - 1,
                  time.process_time() - c0)


def _seed_states(orbit: PeriodicOrbit, levels, displacements: Sequence[float]):
    """Public states near ``orbit``: its internal state moved by each of ``displacements``
    (max-norm units of the internal state) along each direction of the tangent space of
    section and level, both signs, put back on the level (a seed that cannot be is skipped)."""
    from ._propagate import public_state
    from .periodic import _tangent_basis, _to_level
    from .periodic_continuation import _ctx_at

    prob = orbit.problem
    x = np.asarray(orbit.internal, dtype=float)
    V = _tangent_basis(prob, orbit.g0, prob.spec.array(x)).T  # directions of section and level
    ctx = _ctx_at(orbit, levels, float(getattr(prob.params, "plane_rate")))
    scale = max(1.0, float(np.max(np.abs(x))))
    for e in displacements:
        for v in V:
            for sgn in (1.0, -1.0):
                try:
                    y = _to_level(ctx, prob.spec.array(x + sgn * float(e) * v), scale)
                except (IntegrationError, StateError):
                    continue
                yield public_state(prob.system, prob.pars, y, prob.spec)


def _newton_near(orbit: PeriodicOrbit, levels, state, k: int, shift: Any) -> PeriodicOrbit:
    from .periodic import NewtonOptions, periodic_orbit

    return periodic_orbit(orbit.problem, state=state, k=k, levels=levels, g0=orbit.g0,
                          direction=orbit.direction,  # type: ignore[arg-type]
                          options=NewtonOptions(shift=shift))


def _check_kind(orbit: PeriodicOrbit, caller: str) -> None:
    prob = orbit.problem
    if prob is None or prob.kind not in ("reduced", "mparallel"):
        raise UsageError(f"{caller} needs an orbit of kind='reduced' or 'mparallel'")


def period_doubled_orbit(orbit: PeriodicOrbit, levels: Union[Levels, MParallelLevels], *,
                         eps: Sequence[float] = (0.05, 0.1, 0.2)) -> PeriodicOrbit:
    r"""The orbit of twice the period next to ``orbit`` (near a period doubling): a switch onto
    the family that branches off there.

    Newton (:func:`taylorball.periodic_orbit`, ``2 k`` crossings, shift ``2 theta``) from the
    orbit's state moved by each of ``eps`` along each direction of the tangent space of section
    and level (both signs), the moved state put back on the level; the first solution whose
    minimal number of crossings is ``2 k`` is returned (Newton refuses one that closes after
    ``k``: the start orbit itself).

    Parameters
    ----------
    orbit : PeriodicOrbit
        Of kind ``"reduced"`` or ``"mparallel"``, near a multiplier -1 (on the side of the
        period doubling where the doubled family exists; the caller tries both).
    levels : Levels or MParallelLevels
        The orbit's level.
    eps : sequence of float
        Displacements of the internal state tried, in order.

    Returns
    -------
    PeriodicOrbit
        With ``k = 2 orbit.k``.

    Raises
    ------
    StateError
        No seed converged to an orbit of twice the period (the message counts the seeds).
    """
    _check_kind(orbit, "period_doubled_orbit")
    shift = 2.0 * float(orbit.shift) if orbit.shift else None
    tried = 0
    for st in _seed_states(orbit, levels, [float(e) for e in eps]):
        tried += 1
        try:
            return _newton_near(orbit, levels, st, 2 * orbit.k, shift)
        except (IntegrationError, StateError):
            continue
    raise StateError(f"no orbit with k = {2 * orbit.k} found from {tried} seeds within eps = {list(eps)!r} of "
                     f"the orbit (Omega = {getattr(orbit.problem.params, 'plane_rate')!r}, tr A = {orbit.trace:.6g})")


def branch_orbits(orbit: PeriodicOrbit, levels: Union[Levels, MParallelLevels], *,
                  eps: Sequence[float] = (0.02, 0.05, 0.1, 0.2)) -> List[PeriodicOrbit]:
    r"""Other orbits with the same ``k`` next to ``orbit`` (near a branch point): a switch onto
    the branch that crosses its family there.

    Newton (:func:`taylorball.periodic_orbit`, ``k`` crossings) from the orbit's state moved
    by ``eps * max(1, |x|)`` along each direction of the tangent space of section and level
    (both signs), put back on the level; the solutions that are not ``orbit`` itself
    (:func:`taylorball.periodic_search.same_orbit`), each once.

    Parameters
    ----------
    orbit : PeriodicOrbit
        Of kind ``"reduced"`` or ``"mparallel"``, on the side of a branch point where the
        other branch exists (the caller tries both).
    levels : Levels or MParallelLevels
        The orbit's level.
    eps : sequence of float
        Displacements relative to ``max(1, |x|)`` (max norm of the internal state).

    Returns
    -------
    list of PeriodicOrbit
        Possibly empty.
    """
    from .periodic_search import same_orbit

    _check_kind(orbit, "branch_orbits")
    scale = max(1.0, float(np.max(np.abs(np.asarray(orbit.internal, dtype=float)))))
    shift = float(orbit.shift) if orbit.shift else None
    found: List[PeriodicOrbit] = []
    for st in _seed_states(orbit, levels, [float(e) * scale for e in eps]):
        try:
            o = _newton_near(orbit, levels, st, orbit.k, shift)
        except (IntegrationError, StateError):
            continue
        if not any(same_orbit(o, q) for q in [orbit] + found):
            found.append(o)
    return found
