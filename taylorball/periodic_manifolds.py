r"""The unstable manifold of a hyperbolic fixed point of a 2D section map.

For a saddle ``x`` of the M||gamma map or of a symmetric ball's map of ``(r1, r2)`` with
unstable multiplier ``mu`` (``|mu| > 1``) and eigenvector ``v`` (in the tangent space of
section and level), the local unstable manifold is tangent to ``v``. A fundamental domain
``x + s v``, ``s`` in ``[s0, |mu| s0)`` (log-spaced, moved onto section and level), iterated
``n_iter`` times by the section map, traces the manifold: iterate ``n`` covers
``[|mu|^n s0, |mu|^{n+1} s0)`` along it. Both branches (``+v`` and ``-v``); for a negative
``mu`` the two branches alternate, which the union covers.

Only the unstable manifold is grown (the stable one needs the inverse map, i.e. the flow
backwards, which the section runs do not offer); homoclinic points are not located.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Dict, List, Tuple

from numpy.typing import ArrayLike

import numpy as np

from .errors import IntegrationError, StateError, UsageError
from .periodic import PeriodicOrbit, _eval_geo, _f64, _has_axial_symmetry, _Ctx, _to_level
from ._propagate import public_state

_log = logging.getLogger(__name__)

__all__ = ["unstable_manifold", "stable_manifold", "inverse_map", "homoclinic_points", "HomoclinicPoint"]


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


# ---------------------------------------------------------------------------------------
# The inverse map (the flow backwards to the previous crossing) and the stable manifold.
# ---------------------------------------------------------------------------------------
def _previous_crossing(ctx: _Ctx, x: np.ndarray, t_max: float = 100.0) -> np.ndarray:
    """``P^{-1}(x)``: the internal state at the previous crossing of the section (same
    direction, same half-line ``g = g0``), by stepping the problem's integrator backwards
    and Newton in time on the event function."""
    import copy

    from ._propagate import integrator
    from ._section_run import _on_branch
    from .periodic import T_MIN

    prob, spec = ctx.prob, ctx.prob.spec
    ta = copy.copy(integrator(prob))
    ta.state[:] = x
    ta.pars[:] = prob.pars
    ta.time = spec.scalar(0.0)
    e_prev = None
    t_prev = 0.0
    while float(ta.time) > -t_max:
        oc = ta.step_backward()[0]
        if "success" not in str(oc):
            raise IntegrationError(f"the backward integration stopped at t = {float(ta.time)!r} ({oc})")
        t_now = float(ta.time)
        geo = _eval_geo(prob, ctx.g0, ta.state)
        e_now = float(geo.e)
        if e_prev is not None and t_now < -T_MIN:
            up = e_prev > 0.0 >= e_now if ctx.direction == 1 else e_prev < 0.0 <= e_now
            if up:
                T = t_prev + (t_now - t_prev) * e_prev / (e_prev - e_now)  # interpolated crossing
                for _ in range(20):
                    ta.propagate_until(spec.scalar(T))
                    g = _eval_geo(prob, ctx.g0, ta.state)
                    dT = float(g.e) / float(g.de)
                    T -= dT
                    if abs(dT) <= 4 * float(spec.eps) * (1 + abs(T)):
                        break
                ta.propagate_until(spec.scalar(T))
                if _on_branch(ta.state, ctx.g0) and T < -T_MIN:
                    return np.asarray(ta.state).copy()
                ta.propagate_until(spec.scalar(t_now))
        e_prev, t_prev = e_now, t_now
    raise IntegrationError(f"no previous crossing of the section within t = -{t_max!r}")


def inverse_map(orbit: PeriodicOrbit, state: ArrayLike, n: int = 1) -> np.ndarray:
    r"""``P^{-n}`` of a public state on the orbit's section and level (``n >= 1``): the public
    states of the ``n`` previous crossings, most recent first, shape ``(n, dim)``.

    The flow is run backwards (the integrator's backward steps) to each previous crossing of
    the section in the section's direction; the crossing time is refined by Newton on the
    event function. ``P(P^{-1}(x)) = x`` to rounding (tests/test_periodic.py)."""
    from ._propagate import start_state

    if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 1:
        raise UsageError(f"n (backward iterations) must be an integer >= 1, got {n!r}")
    prob = orbit.problem
    ctx = _Ctx(prob, orbit.g0, orbit.direction, 1, _eval_geo(prob, orbit.g0, orbit.internal).c.copy(), False, 1e4)
    x = start_state(prob, state)
    out = []
    for _ in range(n):
        x = _previous_crossing(ctx, x)
        out.append(public_state(prob.system, prob.pars, x, prob.spec))
    return np.array(out)


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
