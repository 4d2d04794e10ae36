r"""Invariant manifolds of hyperbolic periodic points of 2D section maps.

:func:`grow_manifold`: the 1D stable or unstable manifold of a ``k``-periodic saddle of the
M||gamma map or of a symmetric ball's map of ``(r1, r2)`` (a relative periodic orbit,
``P^k x = S_theta x``), or the 1D manifold of a saddle of the asymmetric ball's 3D map of
``(l, r1, r2)`` (its 2D manifold: :mod:`taylorball.periodic_manifolds_3d`), grown by the ``k``-th return map ``F = S_theta^-1 P^k`` (or its
inverse, the flow backwards) from a fundamental domain to a requested chart arc length,
with Hobson's refinement (points inserted by distance and angle, interpolated on the
previous level); each crossing is followed by time along the curve, and where the section
map jumps the curve is marked broken (docs/skeleton.md).

The older, simpler tools for ``k = 1`` saddles of the M||gamma map:
:func:`unstable_manifold` and :func:`stable_manifold` iterate a fixed fundamental domain
(``x + s v``, ``s`` in ``[s0, |mu| s0)``, log-spaced, ``n_iter`` times, no refinement);
:func:`inverse_map` is ``P^-1``; :func:`homoclinic_points` locates crossings of the two
manifolds by Newton on the two fundamental-domain parameters. Symmetric homoclinic points of
the symmetric ball's saddles: :func:`taylorball.periodic_homoclinic.symmetric_homoclinic_points`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple

import numpy as np

from .errors import IntegrationError, StateError, UsageError
from .periodic import PeriodicOrbit, _eval_geo, _f64, _has_axial_symmetry, _Ctx, _to_level
from ._propagate import public_state
from .periodic_return_maps import TAU_JUMP, _previous_crossing, _SaddleMap, inverse_map  # noqa: F401

_log = logging.getLogger(__name__)

__all__ = ["unstable_manifold", "stable_manifold", "inverse_map", "homoclinic_points", "HomoclinicPoint", "grow_manifold",
           "Manifold", "iterate"]


#: The most section crossings (``q k``) :func:`iterate` builds an orbit of.
MAX_ITERATE_CROSSINGS = 100_000


def iterate(orbit: PeriodicOrbit, q: int) -> PeriodicOrbit:
    r"""The same periodic orbit seen as a fixed point of the ``q k``-th return map.

    ``k``, ``period`` and ``shift`` (``theta`` of a relative orbit, wrapped to ``(-pi, pi]``:
    ``S_theta^q = S_{q theta}``) times ``q``, the section points repeated ``q`` times, the
    multiplier matrix to the power ``q`` with its multipliers, traces and type; the state and
    the rest unchanged. What it is for: the manifolds of a reflection saddle (negative
    multipliers), which :func:`grow_manifold` grows by ``F^2`` from ``iterate(orbit, 2)``; each
    branch of the manifold of ``F^2`` is one branch of ``F``'s (``F`` maps one onto the other).

    Raises
    ------
    UsageError
        ``q`` not an integer >= 1, ``orbit`` not a :class:`PeriodicOrbit`, or ``q`` so large
        that the orbit's section points (``q k`` rows) exceed :data:`MAX_ITERATE_CROSSINGS` or
        the multipliers' ``q``-th powers overflow float64.
    """
    import dataclasses

    from .periodic import multiplier_summary

    if not isinstance(orbit, PeriodicOrbit):
        raise UsageError(f"orbit must be a taylorball.PeriodicOrbit (from periodic_orbit), got {type(orbit).__name__}")
    if not isinstance(q, (int, np.integer)) or isinstance(q, bool) or q < 1:
        raise UsageError(f"q must be an integer >= 1 (the number of times the orbit is run), got {q!r}")
    q = int(q)
    if q * orbit.k > MAX_ITERATE_CROSSINGS:
        raise UsageError(f"q = {q} makes q k = {q * orbit.k} section crossings, more than "
                         f"MAX_ITERATE_CROSSINGS = {MAX_ITERATE_CROSSINGS}; ask for a smaller q")
    mu_max = float(np.max(np.abs(orbit.multipliers)))
    if mu_max > 1.0 and q * np.log(mu_max) > np.log(np.finfo(float).max) - 8.0:
        raise UsageError(f"q = {q}: the largest multiplier {mu_max:.6g} to the power q overflows float64 "
                         f"(q ln|mu| = {q * np.log(mu_max):.1f}, at most ln(float64 max) - 8 = 701.8); ask for a smaller q")
    if q == 1:
        return orbit
    A = np.linalg.matrix_power(np.asarray(orbit.matrix, dtype=float), q)
    return dataclasses.replace(
        orbit, k=orbit.k * q, period=orbit.period * q, points=np.concatenate([orbit.points] * q),
        shift=float(np.angle(np.exp(1j * q * orbit.shift))) if orbit.shift else 0.0, **multiplier_summary(A))


def unstable_manifold(orbit: PeriodicOrbit, *, n_fund: int = 100, n_iter: int = 6, s0: float = 1e-6) -> Dict[str, np.ndarray]:
    r"""Chart points of the unstable manifold of a hyperbolic fixed point (``k = 1``, 2D map).

    Parameters
    ----------
    orbit : PeriodicOrbit
        A saddle (``stability == "hyperbolic"``) of a 2D map: kind ``"mparallel"``.
    n_fund : int
        Points of the fundamental domain per branch.
    n_iter : int
        Iterations of the section map.
    s0 : float
        Distance from the fixed point where the fundamental domain starts.

    Returns
    -------
    dict
        ``points`` (2, n_fund, n_iter + 1, chart dims): branch, point, iterate; ``s`` the
        fundamental-domain parameters; ``mu`` the unstable multiplier; ``direction`` the
        eigenvector in the internal variables.
    """
    from .sections import chart_points, poincare_sections

    x, _, mu, d, _, _ = _saddle_directions(orbit)
    prob = orbit.problem
    geo = _eval_geo(prob, orbit.g0, x)
    ctx = _Ctx(prob, orbit.g0, orbit.direction, 1, geo.c.copy(), False, 1e4)
    s = s0 * np.abs(mu) ** (np.arange(n_fund) / n_fund)
    starts = []
    for sign in (1.0, -1.0):
        for si in s:
            xi = _to_level(ctx, x + sign * si * d, 1.0)
            starts.append(public_state(prob.system, prob.pars, xi, prob.spec))
    runs = poincare_sections(prob.kind, prob.params, starts, n_points=n_iter, g0=orbit.g0, t_end=100.0 * n_iter,
                             direction=1 if orbit.direction == 1 else -1)
    dims = len(orbit.points[0])
    pts = np.full((2 * n_fund, n_iter + 1, dims), np.nan)
    for j, (st, r) in enumerate(zip(starts, runs)):
        pts[j, 0] = chart_points(prob.kind, np.asarray(st, dtype=float)[None, :])[0]
        pts[j, 1:1 + len(r.points)] = r.points
    return {"points": pts.reshape(2, n_fund, n_iter + 1, dims), "s": s, "mu": np.array(mu), "direction": d}


def _saddle_directions(orbit: PeriodicOrbit):
    """``(x, B, mu_u, v_u, mu_s, v_s)``: the saddle, the tangent basis of section and level,
    the multipliers and eigenvectors (internal variables, unit length)."""
    if orbit.stability != "hyperbolic" or orbit.multipliers.shape != (2,) or orbit.k != 1:
        raise UsageError(f"the invariant manifolds are grown for a hyperbolic fixed point (k = 1) of a 2D map, "
                         f"got {orbit!r}")
    prob = orbit.problem
    if _has_axial_symmetry(prob) or prob.kind != "mparallel":
        raise UsageError("the invariant manifolds are implemented for the M||gamma map (kind='mparallel')")
    x = np.asarray(orbit.internal, dtype=float)
    geo = _eval_geo(prob, orbit.g0, x)
    G = np.vstack([_f64(geo.grad_e)[None, :], _f64(geo.grad_c)])
    B = np.linalg.svd(G)[2][G.shape[0]:].T
    lam, V = np.linalg.eig(orbit.matrix)
    iu, is_ = int(np.argmax(np.abs(lam))), int(np.argmin(np.abs(lam)))
    vu, vs = B @ V[:, iu].real, B @ V[:, is_].real
    return x, B, float(lam[iu].real), vu / np.linalg.norm(vu), float(lam[is_].real), vs / np.linalg.norm(vs)


def stable_manifold(orbit: PeriodicOrbit, *, n_fund: int = 100, n_iter: int = 6, s0: float = 1e-6) -> Dict[str, np.ndarray]:
    r"""Chart points of the stable manifold of a hyperbolic fixed point of the M||gamma map:
    :func:`unstable_manifold` for the inverse map (the flow backwards). A fundamental domain
    ``x + s v_s``, ``s`` in ``[s0, s0/|mu_s|)``, iterated ``n_iter`` times by ``P^{-1}``.

    Returns
    -------
    dict
        as :func:`unstable_manifold` (``mu`` the stable multiplier, ``direction`` its
        eigenvector).
    """
    from .sections import chart_points

    x, _, _, _, mu, d = _saddle_directions(orbit)
    prob = orbit.problem
    geo = _eval_geo(prob, orbit.g0, x)
    ctx = _Ctx(prob, orbit.g0, orbit.direction, 1, geo.c.copy(), False, 1e4)
    s = s0 * np.abs(1.0 / mu) ** (np.arange(n_fund) / n_fund)
    dims = len(orbit.points[0])
    pts = np.full((2, n_fund, n_iter + 1, dims), np.nan)
    for b, sign in enumerate((1.0, -1.0)):
        for i, si in enumerate(s):
            xi = _to_level(ctx, x + sign * si * d, 1.0)
            row = [xi]
            try:
                for _ in range(n_iter):
                    row.append(_previous_crossing(ctx, row[-1]))
            except (IntegrationError, StateError):  # no previous crossing in time: keep what was found
                pass
            pts[b, i, :len(row)] = chart_points(prob.kind, np.asarray(row, dtype=float))
    return {"points": pts, "s": s, "mu": np.array(mu), "direction": d}


# ---------------------------------------------------------------------------------------
# Homoclinic points: intersections of the unstable and the stable manifold.
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class HomoclinicPoint:
    r"""A transverse intersection of the unstable and stable manifolds of a saddle.

    The point is ``P^{n_u}(x* + s_u v_u)`` on the unstable manifold and
    ``P^{-n_s}(x* + s_s v_s)`` on the stable one (``x*`` the saddle, ``v`` the eigenvectors,
    each start moved onto section and level), with ``s_u = s0 |mu_u|^{sigma_u}``,
    ``s_s = s0 |mu_s|^{-sigma_s}``; Newton on ``(sigma_u, sigma_s)`` makes the two chart
    points agree.

    Attributes
    ----------
    state : ndarray
        Public state of the point (the unstable-manifold side).
    point : ndarray
        Chart point ``(l, L/G)``.
    branch_u, branch_s : int
        ``+1`` or ``-1``: the side of the saddle each manifold branch leaves on.
    n_u, n_s : int
        Forward / backward iterations from the fundamental domains.
    sigma_u, sigma_s : float
        Parameters in the fundamental domains (``[0, 1)`` up to the Newton correction).
    s0 : float
    residual : float
        Chart distance between the two manifolds' points at the solution.
    angle : float
        Angle between the manifolds' tangents in the chart ``(l, L/G)`` (radians, in
        ``(0, pi/2]``).
    angle_state : float
        The same in the internal variables (Euclidean metric of ``(K, gamma)``).
    tangent_u, tangent_s : ndarray
        Unit tangents in the internal variables.
    """

    state: np.ndarray
    point: np.ndarray
    branch_u: int
    branch_s: int
    n_u: int
    n_s: int
    sigma_u: float
    sigma_s: float
    s0: float
    residual: float
    angle: float
    angle_state: float
    tangent_u: np.ndarray
    tangent_s: np.ndarray


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    c = abs(float(np.dot(a, b))) / (float(np.linalg.norm(a)) * float(np.linalg.norm(b)))
    return float(np.arccos(min(1.0, c)))


def _wrap_l(d: np.ndarray) -> np.ndarray:
    d = np.array(d, dtype=float)
    d[..., 0] = (d[..., 0] + np.pi) % (2 * np.pi) - np.pi
    return d


def _segment_crossings(a: np.ndarray, b: np.ndarray) -> List[Tuple[int, float, int, float]]:
    """Crossings of two chart polylines (``l`` wrapped: segments that jump are skipped):
    ``(i, t, j, u)`` with the point ``a[i] + t (a[i+1] - a[i]) = b[j] + u (b[j+1] - b[j])``."""
    out = []
    da, db = _wrap_l(np.diff(a, axis=0)), _wrap_l(np.diff(b, axis=0))
    for i in range(len(a) - 1):
        if not np.all(np.isfinite(da[i])) or abs(da[i, 0]) > 1.0:
            continue
        for j in range(len(b) - 1):
            if not np.all(np.isfinite(db[j])) or abs(db[j, 0]) > 1.0:
                continue
            r = _wrap_l(b[j] - a[i])
            M = np.array([[da[i, 0], -db[j, 0]], [da[i, 1], -db[j, 1]]])
            det = np.linalg.det(M)
            if abs(det) < 1e-300:
                continue
            t, u = np.linalg.solve(M, r)
            if 0.0 <= t < 1.0 and 0.0 <= u < 1.0:
                out.append((i, float(t), j, float(u)))
    return out


def homoclinic_points(orbit: PeriodicOrbit, *, target: "PeriodicOrbit | None" = None, n_u: int = 6, n_s: int = 6, n_fund: int = 60, s0: float = 1e-7,
                      branches: Tuple[Tuple[int, int], ...] = ((1, 1), (1, -1), (-1, 1), (-1, -1)),
                      max_points: int = 8, tol: float = 1e-11) -> List[HomoclinicPoint]:
    r"""Homoclinic points of a saddle of the M||gamma map: crossings of the ``n_u``-th
    iterate of the unstable manifold's fundamental domain with the ``n_s``-th backward
    iterate of the stable one, refined by Newton on the two fundamental-domain parameters.

    With ``target`` (another saddle of the same map and level) the stable manifold is the
    target's, and the points are heteroclinic (``W^u(orbit) & W^s(target)``).

    Each crossing of the two chart polylines (``n_fund`` points per domain) is a guess;
    Newton (finite-difference Jacobian in ``sigma``, every evaluation a fresh forward run of
    the section integrator from the unstable start and a backward run from the stable one)
    solves ``chart(P^{n_u} p_u(sigma_u)) = chart(P^{-n_s} p_s(sigma_s))``. Points whose
    Newton residual stays above ``tol`` are dropped; a point found twice is kept once.

    Returns
    -------
    list of HomoclinicPoint
        Sorted by chart ``l``.
    """
    from ._propagate import start_state
    from .sections import chart_points, poincare_section

    x, _, mu_u, vu, _, _ = _saddle_directions(orbit)
    target = orbit if target is None else target
    xs_, _, _, _, mu_s, vs = _saddle_directions(target)
    prob = orbit.problem
    if target.problem.params != prob.params or target.g0 != orbit.g0 or target.direction != orbit.direction:
        raise UsageError("target must be a saddle of the same map (parameters and section) as orbit")
    geo = _eval_geo(prob, orbit.g0, x)
    ctx = _Ctx(prob, orbit.g0, orbit.direction, 1, geo.c.copy(), False, 1e4)
    if float(np.max(np.abs(_f64(_eval_geo(prob, orbit.g0, xs_).c - geo.c)))) > 1e-9 * max(1.0, float(np.max(np.abs(_f64(geo.c))))):
        raise UsageError("target must lie on the same level as orbit")
    for name, v in (("n_u", n_u), ("n_s", n_s), ("n_fund", n_fund)):
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
            raise UsageError(f"{name} must be an integer >= 1, got {v!r}")

    def p_u(sig: float, sign: int) -> np.ndarray:
        xi = _to_level(ctx, x + sign * s0 * abs(mu_u) ** sig * vu, 1.0)
        r = poincare_section(prob.kind, prob.params, public_state(prob.system, prob.pars, xi, prob.spec),
                             n_points=n_u, g0=orbit.g0, t_end=100.0 * n_u, direction=1 if orbit.direction == 1 else -1)
        return start_state(prob, r.states[-1])

    def p_s(sig: float, sign: int) -> np.ndarray:
        xi = _to_level(ctx, xs_ + sign * s0 * abs(1.0 / mu_s) ** sig * vs, 1.0)
        for _ in range(n_s):
            xi = _previous_crossing(ctx, xi)
        return xi

    def chart(z):
        return chart_points(prob.kind, np.asarray(z, dtype=float)[None, :])[0]

    found: List[HomoclinicPoint] = []
    sig = np.arange(n_fund + 1) / n_fund
    for bu, bs in branches:
        cu = np.array([chart(p_u(q, bu)) for q in sig])
        cs = np.array([chart(p_s(q, bs)) for q in sig])
        for i, t, j, u in _segment_crossings(cu, cs):
            z = np.array([(i + t) / n_fund, (j + u) / n_fund])
            h = 1e-7
            res = np.inf
            for _ in range(12):
                a, b = p_u(z[0], bu), p_s(z[1], bs)
                F = _wrap_l(chart(a) - chart(b))
                res = float(np.max(np.abs(F)))
                if res <= tol:
                    break
                J = np.column_stack([_wrap_l(chart(p_u(z[0] + h, bu)) - chart(a)) / h,
                                     -_wrap_l(chart(p_s(z[1] + h, bs)) - chart(b)) / h])
                z = z - np.linalg.solve(J, F)
            if not res <= tol:
                _log.debug("homoclinic Newton from a polyline crossing stalled at %.1e", res)
                continue
            a = p_u(z[0], bu)
            pt = chart(a)
            if any(float(np.max(np.abs(_wrap_l(pt - q.point)))) <= 1e-8 for q in found):
                continue
            # tangents by central differences in sigma (internal variables and chart)
            hh = 1e-6
            tu = (p_u(z[0] + hh, bu) - p_u(z[0] - hh, bu)) / (2 * hh)
            ts = (p_s(z[1] + hh, bs) - p_s(z[1] - hh, bs)) / (2 * hh)
            cu_t = _wrap_l(chart(p_u(z[0] + hh, bu)) - chart(p_u(z[0] - hh, bu)))
            cs_t = _wrap_l(chart(p_s(z[1] + hh, bs)) - chart(p_s(z[1] - hh, bs)))
            found.append(HomoclinicPoint(
                state=public_state(prob.system, prob.pars, a, prob.spec), point=pt, branch_u=bu, branch_s=bs,
                n_u=n_u, n_s=n_s, sigma_u=float(z[0]), sigma_s=float(z[1]), s0=s0, residual=res,
                angle=_angle(cu_t, cs_t), angle_state=_angle(tu, ts), tangent_u=tu / np.linalg.norm(tu),
                tangent_s=ts / np.linalg.norm(ts)))
            if len(found) >= max_points:
                return sorted(found, key=lambda q: float(q.point[0]))
    return sorted(found, key=lambda q: float(q.point[0]))


@dataclass(frozen=True)
class Manifold:
    r"""A 1D stable or unstable manifold of a saddle of a 2D section map, grown to an arc length.

    The curve through the orbit's first section point ``orbit.points[0]`` is
    ``F^m(p(sigma))``, ``m = 0, 1, ...`` (``level``), ``sigma`` in ``[0, 1]`` a parameter of
    the fundamental domain ``p(sigma) = x* + branch s0 |mu|^(q sigma) v`` (``F = S_theta^-1
    P^k`` for the unstable manifold, its inverse for the stable one; ``q = 2`` for a negative
    multiplier, else 1); its images after ``j`` crossings lie on the manifolds of the other
    section points of the orbit.

    Attributes
    ----------
    which : {"unstable", "stable"}
    branch : int
        ``+1`` or ``-1``: the side of the saddle along the eigenvector.
    curves : ndarray, shape (k, n, 2)
        Chart points (``(r1, r2)`` for the symmetric ball, ``(l, L/G)`` for the M||gamma map);
        ``curves[i]`` lies on the manifold of the orbit's ``i``-th section point
        (``curves[0]`` the grown one). Consecutive levels meet at ``sigma = 1`` / ``0`` up to
        ``O(s0^2)``.
    points : ndarray, shape (n, 2)
        ``curves[0]``.
    states : ndarray, shape (n, dim)
        Public states of ``curves[0]``'s points.
    sigma, level : ndarray, shape (n,)
        Fundamental-domain parameter and iterate of each point.
    arc_length : float
        Chart arc length of ``curves[0]`` (``l`` differences wrapped to ``(-pi, pi]``).
    length : float
        The arc length asked for.
    complete : bool
        ``arc_length >= length``.
    stopped : str
        Why the growth ended (``"length reached"``, or the limit that stopped it).
    mu : float
        The multiplier of ``F`` along the manifold (``mu_u``, or ``mu_s`` for the stable one).
    s0, delta, alpha, delta_min : float
        The fundamental domain's offset and the refinement's parameters.
    times : ndarray, shape (n, k)
        Flow times of the ``k`` crossings that carry each point to the next level (followed
        by time from the neighbour's, not counted: see :meth:`_SaddleMap.track`; the
        intermediate curves are NaN where their crossing was lost, e.g. grazing the
        section).
    jumps, xjumps : ndarray of bool, shape (n,)
        ``jumps[i]``: the segment from point ``i`` to ``i + 1`` of the intermediate curves
        (``xjumps``: of ``curves[0]``) is a jump, not a piece of the curve. Where the
        crossing followed from the saddle folds (two crossings of the flow's invariant
        surface with the section meet and vanish), the map of the section jumps; past it the
        crossings are counted again and the curve goes on as a new piece, still on the
        manifold of the orbit (every crossing of the flow's invariant surface is) but no
        longer on that of the section point it is labelled with. Jumps are not counted in
        ``arc_length``; draw the curves broken there.
    stopped : str
        Also says where the crossing followed from the saddle was lost (a fold of the
        crossing: the growth ends there).
    map_calls : int
        Evaluations of ``F`` (or ``F^-1``).
    """

    which: str
    branch: int
    curves: np.ndarray
    states: np.ndarray
    sigma: np.ndarray
    level: np.ndarray
    arc_length: float
    length: float
    complete: bool
    stopped: str
    mu: float
    s0: float
    delta: float
    alpha: float
    delta_min: float
    times: np.ndarray
    jumps: np.ndarray
    xjumps: np.ndarray
    map_calls: int

    @property
    def points(self) -> np.ndarray:
        return self.curves[0]


#: A segment still too long when its fundamental-domain interval is this short is a jump of
#: the map (the refinement stops there): ~33 halvings of a unit interval.
SIGMA_GAP = 1e-10

def _chart_steps(C: np.ndarray, wrap: bool) -> np.ndarray:
    d = np.diff(C, axis=0)
    return _wrap_l(d) if wrap else d


def _step_lengths(d: np.ndarray) -> np.ndarray:
    """Euclidean lengths of chart steps (rows of ``d``; 2 or 3 columns)."""
    return np.hypot(d[:, 0], d[:, 1]) if d.shape[1] == 2 else np.sqrt(np.sum(d * d, axis=1))


def _bad_segments(curves: List[np.ndarray], wrap: bool, delta: float, alpha: float, delta_min: float) -> np.ndarray:
    """Segments ``i`` (between points ``i`` and ``i + 1``) to split: longer than ``delta`` in
    any curve, or longer than ``delta_min`` next to a turn of more than ``alpha``
    (Krauskopf-Osinga's distance and angle criteria)."""
    n = len(curves[0])
    bad = np.zeros(max(n - 1, 0), dtype=bool)
    for C in curves:
        d = _chart_steps(C, wrap)
        L = _step_lengths(d)
        bad |= np.isfinite(L) & (L > delta)  # a NaN segment: an intermediate crossing lost, not refined
        if n >= 3:
            a, b = d[:-1], d[1:]
            c = (a * b).sum(axis=1) / np.maximum(L[:-1] * L[1:], 1e-300)
            with np.errstate(invalid="ignore"):
                turn = np.arccos(np.clip(c, -1.0, 1.0))
            sharp = turn > alpha
            bad[:-1] |= sharp & (L[:-1] > delta_min)
            bad[1:] |= sharp & (L[1:] > delta_min)
    return bad


def _check_pos(name: str, v, *, integer: bool = False, upper: Optional[float] = None, low: float = 0) -> None:
    ok = isinstance(v, (int, np.integer)) and not isinstance(v, bool) if integer else \
        isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool) and math.isfinite(float(v))
    if not ok or not v > low or (upper is not None and not v < upper):
        rng = f"in ({low}, {upper})" if upper is not None else f"> {low}"
        raise UsageError(f"{name} must be a{'n integer' if integer else ' finite number'} {rng}, got {v!r}")


def _check_refinement(s0, delta, alpha, delta_min, max_points) -> None:
    """The fundamental domain's offset and the refinement options (also of the 2D surfaces)."""
    _check_pos("s0", s0, upper=0.1)
    _check_pos("delta", delta)
    _check_pos("alpha", alpha, upper=math.pi)
    _check_pos("delta_min", delta_min)
    if not delta_min < delta:
        raise UsageError(f"delta_min must be below delta, got delta_min = {delta_min!r}, delta = {delta!r}")
    _check_pos("max_points", max_points, integer=True)


def grow_manifold(orbit: PeriodicOrbit, which: str = "unstable", *, length: float, branch: int = 1,
                  s0: float = 1e-6, delta: float = 0.05, alpha: float = 0.3, delta_min: float = 1e-4,
                  n_fund: int = 20, max_points: int = 20000, max_levels: int = 200,
                  refine_all: bool = True) -> Manifold:
    r"""The stable or unstable manifold of a saddle of a 2D section map (or the 1D one of a
    saddle of the 3D map), to a chart arc length.

    For a ``k``-periodic saddle (``k >= 1``) of the M||gamma map or of the dynamically
    symmetric ball's map of ``(r1, r2)`` (a relative periodic orbit, ``P^k x* = S_theta
    x*``), or of the asymmetric ball's 3D map of ``(l, r1, r2)`` whose ``which`` manifold is
    1D (chart distances then in all three coordinates, ``l`` wrapped), the manifold of the section point ``x*`` is grown by iterating the ``k``-th return
    map ``F = S_theta^{-1} P^k`` (``F^{-1}`` for the stable manifold: the flow backwards)
    from a fundamental domain along the eigenvector of ``DF`` (from the variational
    equations), level by level. Each level starts as the images of the previous level's
    points; a segment that is too long (chart distance above ``delta``) or too bent (a turn
    above ``alpha`` radians at either end, if longer than ``delta_min``) gets a new point,
    the image of a point interpolated linearly in ``sigma`` on the previous level (already
    resolved): Hobson's method. The interpolation error across the curve contracts under
    ``F`` (the transverse direction is the contracting one), the error along it only moves
    the point along the curve. The criteria are applied to the manifolds of all ``k``
    section points (the intermediate crossings), so every drawn curve is resolved.

    For a relative orbit, ``theta`` is the float64 ``orbit.shift``; its rounding rotates the
    curve about the body axis 3, which the chart ``(r1, r2)`` does not see.

    Parameters
    ----------
    orbit : PeriodicOrbit
        A saddle (``stability == "hyperbolic"``) with two multipliers (a 2D map), or three
        with a 1D ``which`` manifold (the 3D map), any ``k``,
        any number type (the maps run in the orbit's type).
    which : {"unstable", "stable"}
    length : float
        Chart arc length to grow the manifold of ``orbit.points[0]`` to (``> 0``).
    branch : {1, -1}
        The side of the saddle along the eigenvector.
    s0 : float
        Offset of the fundamental domain from the saddle, in ``(0, 0.1)`` (relative to
        ``max(1, |x*|)``): the linear approximation is off the manifold by ``O(s0^2)``.
    delta, alpha, delta_min : float
        Refinement: largest chart distance between neighbours, largest turn (radians), and
        the distance below which turns are no longer refined.
    n_fund : int
        Initial points of the fundamental domain (``>= 2``).
    max_points, max_levels : int
        Limits (the growth stops with ``complete = False`` and says which).
    refine_all : bool
        Apply the refinement criteria to the curves of all ``k`` section points (default)
        or only to that of ``orbit.points[0]`` (the others are then drawn as computed: far
        cheaper where the intermediate curves are much longer, as for the stable manifold
        of the Fig. 4a saddle, docs/skeleton.md).

    Returns
    -------
    Manifold

    Raises
    ------
    UsageError
        An orbit that is not a saddle of a 2D map, or bad parameters (before any work).
    """
    if which not in ("unstable", "stable"):
        raise UsageError(f"which must be 'unstable' or 'stable', got {which!r}")
    if branch not in (1, -1) or isinstance(branch, bool):
        raise UsageError(f"branch must be 1 or -1 (the side of the saddle along the eigenvector), got {branch!r}")
    _check_pos("length", length)
    _check_refinement(s0, delta, alpha, delta_min, max_points)
    _check_pos("max_levels", max_levels, integer=True)
    if not isinstance(n_fund, (int, np.integer)) or isinstance(n_fund, bool) or n_fund < 2:
        raise UsageError(f"n_fund must be an integer >= 2, got {n_fund!r}")
    if not isinstance(refine_all, (bool, np.bool_)):
        raise UsageError(f"refine_all must be True or False, got {refine_all!r}")
    sm = _SaddleMap(orbit, f"the {which} manifolds", which)
    k, wrap = sm.k, orbit.kind == "mparallel" or not sm.symmetric  # the chart's l is an angle (dropped if symmetric)
    dims = 2 if sm.symmetric or orbit.kind == "mparallel" else 3
    mu = sm.mu_u if which == "unstable" else sm.mu_s
    if mu < 0:
        raise UsageError(f"the {which} multiplier is negative ({mu!r}, a reflection saddle): grow the manifold of "
                         f"F^2, from taylorball.periodic_manifolds.iterate(orbit, 2)")
    s0w = s0 * sm.scale
    t_orbit = sm.orbit_times(which)
    calls = 0

    def apply(x: np.ndarray, taus: np.ndarray) -> Tuple[List[Optional[np.ndarray]], np.ndarray]:
        nonlocal calls
        calls += 1
        return sm.track(x, taus, which)

    def chart_or_nan(z: Optional[np.ndarray]) -> np.ndarray:
        return np.full(dims, np.nan) if z is None else sm.chart(_f64(z)[None, :])[0]

    # a level: sigma, the points X (curve of orbit point 0), per point the k tracked crossings
    # (images: the intermediates and F X) with their times, and the chart rows (k, 2)
    class Level:
        def __init__(self) -> None:
            self.xbrk: List[bool] = []  # xbrk[i]: points i - 1 and i of X are on different pieces
            self.sig: List[float] = []
            self.X: List[np.ndarray] = []
            self.img: List[List[Optional[np.ndarray]]] = []
            self.tau: List[np.ndarray] = []
            self.brk: List[bool] = []  # brk[i]: the images of points i - 1 and i are on different pieces

        def charts(self) -> List[np.ndarray]:
            cx = sm.chart(np.array([_f64(x) for x in self.X]))
            out = [cx]
            for j in range(k - 1):
                out.append(np.array([chart_or_nan(r[j]) for r in self.img]))
            return out

        def jumps(self) -> np.ndarray:
            """Per segment: a jump in X or in the images."""
            return np.array([a or b for a, b in zip(self.xbrk[1:], self.brk[1:])], dtype=bool)

        def insert(self, i: int, sv: float, x: np.ndarray, img, tau, brk: bool = False) -> None:
            self.brk.insert(i, brk)
            self.sig.insert(i, sv)
            self.X.insert(i, x)
            self.img.insert(i, img)
            self.tau.insert(i, tau)

    def interp_tau(lv: "Level", sv: float) -> np.ndarray:
        S = np.array(lv.sig)
        Tm = np.array(lv.tau)
        out = np.empty(k)
        for j in range(k):
            ok = np.isfinite(Tm[:, j])
            out[j] = np.interp(sv, S[ok], Tm[ok, j]) if ok.any() else t_orbit[j]
        return out

    def point_on(prev: Optional["Level"], sv: float) -> Optional[np.ndarray]:
        """The point of parameter ``sv`` on the level after ``prev`` (level 0: exact)."""
        if prev is None:
            return sm.start(which, branch, s0w, sv, 1)
        i = int(np.clip(np.searchsorted(prev.sig, sv) - 1, 0, len(prev.sig) - 2))
        a, b = prev.X[i], prev.X[i + 1]
        w = (sv - prev.sig[i]) / (prev.sig[i + 1] - prev.sig[i])
        x = _to_level(sm.ctx, a + sm.spec.scalar(w) * (b - a), sm.scale)
        img, _ = apply(x, interp_tau(prev, sv))
        return img[-1]

    class Folded(Exception):
        pass

    def process(lv: "Level", prev: Optional["Level"], guess: np.ndarray) -> None:
        """Track the crossings of every point of ``lv`` in order along the curve, each from its
        predecessor's times; where a crossing is lost, split the segment (a point
        interpolated on ``prev`` and mapped) down to SIGMA_GAP; there the followed crossing
        folds, and the point's crossings are counted instead (a jump: a new piece)."""
        i = 0
        g = guess
        while i < len(lv.X):
            if i > 0 and lv.xbrk[i]:  # a new piece of X: its crossings counted
                g = sm.counted_times(lv.X[i], which)
            img, tau = apply(lv.X[i], g)
            if img[-1] is not None:
                lv.img[i], lv.tau[i] = img, tau
                g = np.where(np.isfinite(tau), tau, g)  # a lost intermediate keeps its last time
                i += 1
                continue
            if i > 0 and lv.sig[i] - lv.sig[i - 1] > SIGMA_GAP and len(lv.X) < max_points:
                sv = (lv.sig[i - 1] + lv.sig[i]) / 2
                x = point_on(prev, sv)
                if x is not None:
                    lv.insert(i, sv, x, None, None)
                    lv.xbrk.insert(i, False)
                    continue
            g = sm.counted_times(lv.X[i], which)
            img, tau = apply(lv.X[i], g)
            if img[-1] is None:
                raise Folded(f"no crossing at sigma = {lv.sig[i]!r}")
            lv.img[i], lv.tau[i], lv.brk[i] = img, tau, i > 0
            g = np.where(np.isfinite(tau), tau, g)
            i += 1

    def refine(lv: "Level", prev: Optional["Level"]) -> None:
        for _ in range(60):
            ch = lv.charts()
            bad = _bad_segments(ch if refine_all else ch[:1], wrap, delta, alpha, delta_min) & ~lv.jumps()
            idx = [i for i in np.flatnonzero(bad) if lv.sig[i + 1] - lv.sig[i] > SIGMA_GAP]
            if not idx or len(lv.X) + len(idx) > max_points:
                return
            for i in reversed(idx):
                sv = (lv.sig[i] + lv.sig[i + 1]) / 2
                x = point_on(prev, sv)
                if x is None:
                    continue
                ga, gb = lv.tau[i], lv.tau[i + 1]
                img, tau = apply(x, np.where(np.isfinite(ga + gb), (ga + gb) / 2, np.where(np.isfinite(ga), ga, gb)))
                if img[-1] is None:
                    continue
                lv.insert(int(i) + 1, sv, x, img, tau)
                lv.xbrk.insert(int(i) + 1, False)

    stopped = ""
    levels: List[Level] = []
    lv = Level()
    for sv in np.linspace(0.0, 1.0, int(n_fund)):
        lv.insert(len(lv.X), float(sv), sm.start(which, branch, s0w, float(sv), 1), None, None)
        lv.xbrk.append(False)
    prev: Optional[Level] = None
    guess = t_orbit
    total = 0.0
    while True:
        try:
            process(lv, prev, guess)
            refine(lv, prev)
        except Folded as exc:
            stopped = f"level {len(levels)}: {exc}"
            break
        except (IntegrationError, StateError) as exc:
            stopped = f"the map failed on level {len(levels)}: {exc}"
            break
        seg = np.where(np.array(lv.xbrk[1:], dtype=bool), 0.0, _step_lengths(_chart_steps(lv.charts()[0], wrap)))
        _log.debug("level %d: %d points, arc %.4g, %d map calls", len(levels), len(lv.X), float(np.sum(seg)), calls)
        if total + float(np.sum(seg)) >= length:  # cut the last level where the length is reached
            cut = int(np.searchsorted(np.cumsum(seg), length - total)) + 2
            total += float(np.sum(seg[:cut - 1]))
            for name in ("sig", "X", "img", "tau", "xbrk", "brk"):
                setattr(lv, name, getattr(lv, name)[:cut])
            levels.append(lv)
            break
        total += float(np.sum(seg))
        levels.append(lv)
        if len(levels) >= max_levels:
            stopped = f"max_levels = {max_levels} reached"
            break
        if sum(len(v.X) for v in levels) >= max_points:
            stopped = f"max_points = {max_points} reached"
            break
        nxt = Level()
        for sv, img, xb, ib in zip(lv.sig, lv.img, lv.xbrk, lv.brk):
            nxt.insert(len(nxt.X), sv, img[-1], None, None)  # type: ignore[arg-type]  # img[-1] is never None here
            nxt.xbrk.append(xb or ib)
        prev, guess, lv = lv, np.where(np.isfinite(lv.tau[-1]), lv.tau[-1], guess), nxt
    if not stopped:
        stopped = "length reached"
    curves = [np.vstack(c) for c in zip(*[v.charts() for v in levels])]
    order = [sm.orbit_point_index(which, j) for j in range(k)]
    out = np.empty((k, len(curves[0]), dims))
    for j, i in enumerate(order):
        out[i] = curves[j]
    prob = orbit.problem
    states = np.array([public_state(prob.system, prob.pars, x, prob.spec) for v in levels for x in v.X])
    return Manifold(which=which, branch=int(branch), curves=out, states=states,
                    sigma=np.concatenate([v.sig for v in levels]),
                    level=np.concatenate([np.full(len(v.sig), i) for i, v in enumerate(levels)]),
                    times=np.vstack([np.array(v.tau) for v in levels]),
                    jumps=np.concatenate([np.append(v.jumps(), False) for v in levels]),
                    xjumps=np.concatenate([np.append(np.array(v.xbrk[1:], dtype=bool), False) for v in levels]),
                    arc_length=total, length=float(length), complete=total >= length, stopped=stopped, mu=float(mu),
                    s0=float(s0), delta=float(delta), alpha=float(alpha), delta_min=float(delta_min),
                    map_calls=calls)
