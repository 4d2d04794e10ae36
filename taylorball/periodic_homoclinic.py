r"""Connecting orbits of saddles of a 2D section map by multiple shooting: homoclinic orbits.

A homoclinic orbit of a saddle ``x*`` of the M||gamma map leaves ``x*`` along its unstable
manifold and comes back along its stable one. Located as a crossing of the two manifolds
grown from fundamental domains (:func:`taylorball.periodic_manifolds.homoclinic_points`),
each evaluation runs ``n_u`` iterations forward and ``n_s`` backward, and the rounding of
the start, grown by ``|mu|^n``, limits the accuracy: after ~30 iterations (what a
homoclinic orbit that passes the partner saddle needs) nothing is left in float64.

Multiple shooting removes that growth. The unknowns are the orbit's points ``z_0, ..., z_N``
on the section and the level, each varied in the 2D tangent space there, with ``z_0`` on the
linear unstable manifold of the source saddle and ``z_N`` on the linear stable manifold of the
target saddle:

.. math:: z_0 = x_s + a\,v_u,\qquad z_N = x_t + b\,v_s,\qquad
          B_{i+1}^T\,(P(z_i) - z_{i+1}) = 0\quad (i = 0, \dots, N-1),

``2N`` equations for ``a, b`` and the ``2(N-1)`` tangent coordinates of the interior points
(``B_i`` an orthonormal basis of the tangent space of section and level at ``z_i``). Newton
with the block-bidiagonal Jacobian ``B_{i+1}^T \Pi\Phi_i B_i`` (the variational equations of
one crossing each); the equations are well conditioned because the orbit is hyperbolic, so
the accuracy is that of one map iteration. Near the ends the linear manifolds are off the
true ones by ``O(a^2)``; that error contracts along the orbit (``|mu_s|`` per iteration
forward from ``z_0``, ``1/|mu_u|`` backward from ``z_N``), so with ``a, b ~ 1e-5`` it is below
rounding ten iterations in.

The guess is a chain of states (e.g. the backward and forward images of two heteroclinic
points, :func:`homoclinic_chain`); each solution is one homoclinic (or heteroclinic) orbit.
The tangents of the two manifolds along it are carried by the same Jacobians (forward from
``v_u``, backward from ``v_s``), which gives the angle of the intersection at every point.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from ._propagate import public_state, start_state
from ._typing import FpTypeLike
from .errors import StateError, UsageError
from .numbers import resolve_fp_type
from .periodic import (PeriodicOrbit, _crossing_time, _Ctx, _eval_geo, _f64, _flow, _jacobian, _tangent_basis,
                       _to_level)
from .periodic_manifolds import HomoclinicPoint, Manifold, _angle, _saddle_directions, _wrap_l

_log = logging.getLogger(__name__)

__all__ = ["HomoclinicOrbit", "connecting_orbit", "homoclinic_chain", "SymmetricHomoclinicPoint",
           "symmetric_homoclinic_points"]


@dataclass(frozen=True)
class HomoclinicOrbit:
    r"""A connecting orbit of two saddles of a 2D section map (homoclinic if they are one).

    Attributes
    ----------
    states : ndarray, shape (N + 1, dim)
        Public states ``z_0, ..., z_N`` on the section (working number type): ``z_0`` near
        the source saddle on its unstable manifold, ``z_N`` near the target on its stable one.
    points : ndarray, shape (N + 1, 2)
        Chart points ``(l, L/G)``.
    index : int
        The point reported as *the* intersection point (``state``, ``point``, ``angle``).
    state, point : ndarray
        ``states[index]``, ``points[index]``.
    a, b : float
        Offsets of ``z_0`` along the unstable eigenvector of the source, of ``z_N`` along the
        stable eigenvector of the target.
    residual : float
        ``max_i |P(z_i) - z_{i+1}|`` (internal variables, working type).
    residual_history : tuple of float
        The largest tangent-space mismatch at each Newton iterate.
    angles : ndarray, shape (N + 1,)
        Angle between the manifolds' tangents at each point, in the chart (radians).
    angles_state : ndarray
        The same in the internal variables (Euclidean metric of ``(K, gamma)``).
    angle, angle_state : float
        ``angles[index]``, ``angles_state[index]``.
    tangent_u, tangent_s : ndarray, shape (N + 1, dim_internal)
        Unit tangents of the unstable / stable manifold at each point (internal variables).
    fp_type : str
    internal : ndarray
        The internal states.
    """

    states: np.ndarray
    points: np.ndarray
    index: int
    a: float
    b: float
    residual: float
    residual_history: Tuple[float, ...]
    angles: np.ndarray
    angles_state: np.ndarray
    tangent_u: np.ndarray
    tangent_s: np.ndarray
    fp_type: str
    internal: np.ndarray

    @property
    def state(self) -> np.ndarray:
        return self.states[self.index]

    @property
    def point(self) -> np.ndarray:
        return self.points[self.index]

    @property
    def angle(self) -> float:
        return float(self.angles[self.index])

    @property
    def angle_state(self) -> float:
        return float(self.angles_state[self.index])

    def __len__(self) -> int:
        return len(self.states)


def _step(ctx: _Ctx, z: np.ndarray):
    """``(P(z), Pi Phi)``: one crossing with its Jacobian (working type, float64)."""
    T = _crossing_time(ctx, z)
    zT, Phi, _ = _flow(ctx, z, T)
    _, PP = _jacobian(ctx, z, 0.0, zT, Phi, _eval_geo(ctx.prob, ctx.g0, z))
    return zT, PP


def connecting_orbit(source: PeriodicOrbit, target: PeriodicOrbit, guess: Sequence[ArrayLike], *,
                     fp_type: Union[FpTypeLike, Tuple[FpTypeLike, int], None] = None, max_iter: int = 20, rtol: Optional[float] = None,
                     near: Optional[ArrayLike] = None) -> HomoclinicOrbit:
    r"""A connecting orbit from ``source`` to ``target`` (one saddle: a homoclinic orbit) by
    multiple shooting from a chain of guess states (see the module docstring).

    Parameters
    ----------
    source, target : PeriodicOrbit
        Saddles (``k = 1``) of the same M||gamma map and level; ``target`` may be ``source``.
    guess : sequence of array_like
        ``N + 1 >= 3`` public states on the section and level: the first near ``source``, the
        last near ``target``, each near the map's image of the one before (e.g.
        :func:`homoclinic_chain`).
    fp_type : number type, optional
        Of the residual and the states (default: the saddles'); the Jacobian is float64.
        The saddles are solved again in this type first.
    max_iter : int
        Newton iterations.
    rtol : float, optional
        Convergence: the tangent-space mismatch below ``rtol * max(1, |z|)``; default
        ``256 eps`` of ``fp_type``.
    near : array_like, optional
        A chart point: the orbit's point closest to it is the reported one (``index``);
        default the point farthest from the saddles and from every point where the orbit
        lingers (moves by less than ``1e-3 max(1, |x|)`` in one iteration: near a saddle).

    Returns
    -------
    HomoclinicOrbit

    Raises
    ------
    UsageError
        Saddles that are not saddles of one M||gamma map and level, a chain shorter than 3.
    StateError
        A guess state off the section or level, or Newton that did not converge (with the
        mismatch reached).
    """
    from .periodic import refine
    from .sections import chart_points

    x_s, _, mu_u, v_u, _, _ = _saddle_directions(source)
    x_t, _, _, _, mu_s, v_s = _saddle_directions(target)
    prob = source.problem
    if target.problem.params != prob.params or target.g0 != source.g0 or target.direction != source.direction:
        raise UsageError("source and target must be saddles of the same map (parameters and section)")
    if len(guess) < 3:
        raise UsageError(f"guess must hold at least 3 states (a chain from source to target), got {len(guess)}")
    if not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise UsageError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    spec = prob.spec if fp_type is None else resolve_fp_type(*fp_type) if isinstance(fp_type, tuple) \
        else resolve_fp_type(fp_type)
    if fp_type is not None and spec != prob.spec:  # the saddles in the working type (the float64 level)
        same = target is source
        source = refine(source, (fp_type,))[-1]
        target = source if same else refine(target, (fp_type,))[-1]
        prob = source.problem
    xs_w, xt_w = source.internal, target.internal
    geo0 = _eval_geo(prob, source.g0, xs_w)
    lev = _f64(_eval_geo(prob, target.g0, xt_w).c - geo0.c)
    if float(np.max(np.abs(lev))) > 1e-9 * max(1.0, float(np.max(np.abs(_f64(geo0.c))))):
        raise UsageError("source and target must lie on the same level")
    ctx = _Ctx(prob, source.g0, source.direction, 1, geo0.c.copy(), False, 1e4)
    rtol = 256 * spec.eps if rtol is None else float(rtol)
    scale = max(1.0, float(np.max(np.abs(_f64(xs_w)))))
    z: List[np.ndarray] = []
    for j, g in enumerate(guess):
        x = start_state(prob, np.asarray(g))
        geo = _eval_geo(prob, ctx.g0, x)
        off = max(abs(float(geo.e)), float(np.max(np.abs(_f64(geo.c - ctx.targets)))))
        if off > 1e-6 * scale:
            raise StateError(f"guess[{j}] is off the section or the level by {off:.1e}")
        z.append(_to_level(ctx, x, scale))
    N = len(z) - 1
    a = float(np.dot(_f64(z[0] - xs_w), v_u))
    b = float(np.dot(_f64(z[N] - xt_w), v_s))
    z[0] = _to_level(ctx, xs_w + spec.array(a * v_u), scale)
    z[N] = _to_level(ctx, xt_w + spec.array(b * v_s), scale)
    hist: List[float] = []
    for _ in range(int(max_iter)):
        Bs = [_tangent_basis(prob, ctx.g0, zi) for zi in z]
        imgs, PPs = zip(*[_step(ctx, zi) for zi in z[:-1]])
        F = np.concatenate([Bs[i + 1].T @ _f64(imgs[i] - z[i + 1]) for i in range(N)])
        hist.append(float(np.max(np.abs(F))))
        if hist[-1] <= rtol * scale:
            break
        J = np.zeros((2 * N, 2 * N))  # columns: a, w_1 (2), ..., w_{N-1} (2), b
        for i in range(N):
            r = slice(2 * i, 2 * i + 2)
            if i == 0:
                J[r, 0] = Bs[1].T @ PPs[0] @ v_u
            else:
                J[r, 2 * i - 1:2 * i + 1] = Bs[i + 1].T @ PPs[i] @ Bs[i]
            if i + 1 == N:
                J[r, 2 * N - 1] = -(Bs[N].T @ v_s)
            else:
                J[r, 2 * i + 1:2 * i + 3] = -np.eye(2)
        d = np.linalg.solve(J, -F)
        a += float(d[0])
        b += float(d[-1])
        z[0] = _to_level(ctx, xs_w + spec.array(a * v_u), scale)
        z[N] = _to_level(ctx, xt_w + spec.array(b * v_s), scale)
        for i in range(1, N):
            z[i] = _to_level(ctx, z[i] + spec.array(Bs[i] @ d[2 * i - 1:2 * i + 1]), scale)
    else:
        raise StateError(f"the shooting Newton did not converge in {max_iter} iterations: tangent mismatch "
                         f"{hist[-1]:.1e} (needed {rtol * scale:.1e}); history "
                         f"{', '.join(f'{h:.1e}' for h in hist)}")
    residual = max(float(np.max(np.abs(_f64(imgs[i] - z[i + 1])))) for i in range(N))
    # the manifolds' tangents along the orbit, carried by the map's Jacobians
    M = [Bs[i + 1].T @ PPs[i] @ Bs[i] for i in range(N)]
    u = [Bs[0].T @ v_u]
    for i in range(N):
        w = M[i] @ u[-1]
        u.append(w / np.linalg.norm(w))
    s = [Bs[N].T @ v_s]
    for i in reversed(range(N)):
        w = np.linalg.solve(M[i], s[0])
        s.insert(0, w / np.linalg.norm(w))
    tu = np.array([Bs[i] @ u[i] for i in range(N + 1)])
    ts = np.array([Bs[i] @ s[i] for i in range(N + 1)])
    Z = np.array([_f64(zi) for zi in z])
    pts = chart_points(prob.kind, Z)
    h = 1e-7  # the chart's derivative along a tangent: central differences, truncation ~h^2

    def chart_dir(zz: np.ndarray, t: np.ndarray) -> np.ndarray:
        return _wrap_l(chart_points(prob.kind, np.array([zz + h * t]))[0]
                       - chart_points(prob.kind, np.array([zz - h * t]))[0]) / (2 * h)

    angles = np.array([_angle(chart_dir(Z[i], tu[i]), chart_dir(Z[i], ts[i])) for i in range(N + 1)])
    angles_state = np.array([_angle(tu[i], ts[i]) for i in range(N + 1)])
    if near is None:  # the point farthest from where the orbit lingers (near a saddle)
        step = np.max(np.abs(np.diff(Z, axis=0)), axis=1)
        slow = Z[:-1][step < 1e-3 * scale]
        slow = np.vstack([slow, _f64(xs_w)[None, :], _f64(xt_w)[None, :]])
        dist = np.min(np.max(np.abs(Z[:, None, :] - slow[None, :, :]), axis=2), axis=1)
        # a symmetric orbit has two such points, mirror images (l, L/G) and (2 pi - l, L/G) at
        # distances equal up to rounding: of the points within 1e-6 of the largest distance,
        # the one of smallest l in [0, 2 pi), so that rounding never decides which is reported
        cand = np.flatnonzero(dist >= dist.max() * (1.0 - 1e-6))
        index = int(cand[np.argmin(np.mod(pts[cand, 0], 2.0 * np.pi))])
    else:
        index = int(np.argmin(np.max(np.abs(_wrap_l(pts - np.asarray(near, dtype=float))), axis=1)))
    states = np.array([public_state(prob.system, prob.pars, zi, spec) for zi in z])
    return HomoclinicOrbit(states=states, points=pts, index=index, a=a, b=b, residual=residual,
                           residual_history=tuple(hist), angles=angles, angles_state=angles_state, tangent_u=tu,
                           tangent_s=ts, fp_type=str(spec), internal=np.array(z))


def homoclinic_chain(saddle: PeriodicOrbit, partner: PeriodicOrbit, out: HomoclinicPoint, back: HomoclinicPoint,
                     *, max_steps: int = 40) -> List[np.ndarray]:
    r"""A guess for :func:`connecting_orbit` from two heteroclinic points: ``out`` on
    ``W^u(saddle) & W^s(partner)`` and ``back`` on ``W^u(partner) & W^s(saddle)``
    (from :func:`taylorball.periodic_manifolds.homoclinic_points` with ``target``).

    The chain is: the backward images of ``out`` down to its closest approach to ``saddle``,
    ``out``, its forward images to the closest approach to ``partner``; then the backward
    images of ``back`` from its closest approach to ``partner``, ``back``, and its forward
    images to the closest approach to ``saddle``. A homoclinic orbit of ``saddle`` that
    shadows the two heteroclinic orbits is near this chain (the gap at ``partner`` is the
    distance of the two approaches, small).

    Returns
    -------
    list of ndarray
        Public states, source end first.
    """
    from .periodic_manifolds import inverse_map
    from .sections import poincare_section

    prob = saddle.problem

    def closest(states: np.ndarray, x: np.ndarray) -> int:
        d = np.max(np.abs(np.asarray(states, dtype=float) - np.asarray(x, dtype=float)), axis=1)
        return int(np.argmin(d))

    def fwd(st) -> np.ndarray:
        r = poincare_section(prob.kind, prob.params, st, n_points=max_steps, g0=saddle.g0, t_end=100.0 * max_steps,
                             direction=1 if saddle.direction == 1 else -1)
        return np.asarray(r.states)

    def bwd(st, orbit) -> np.ndarray:
        return inverse_map(orbit, st, max_steps)

    b1 = bwd(out.state, saddle)
    f1 = fwd(out.state)
    b2 = bwd(back.state, partner)
    f2 = fwd(back.state)
    i1, j1 = closest(b1, saddle.state), closest(f1, partner.state)
    i2, j2 = closest(b2, partner.state), closest(f2, saddle.state)
    chain = list(b1[:i1 + 1][::-1]) + [np.asarray(out.state)] + list(f1[:j1 + 1])
    chain += list(b2[:i2 + 1][::-1]) + [np.asarray(back.state)] + list(f2[:j2 + 1])
    if len(chain) < 3:
        raise StateError("the heteroclinic points do not approach the saddles: no chain")
    return chain



# ---------------------------------------------------------------------------------------
# Symmetric homoclinic points of a symmetric ball's saddle: 1D shooting to the reversor's
# fixed set.
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SymmetricHomoclinicPoint:
    r"""A homoclinic point of a saddle of the symmetric ball's map of ``(r1, r2)`` on the
    fixed set ``r2 = 0`` of the map's reversor.

    The reversor ``sigma_1`` (the reflection of the body axis 1 with time reversed; in the
    chart ``(r1, r2) -> (r1, -r2)``) keeps the section and maps the map onto its inverse.
    The orbit is symmetric, so ``sigma_1 W^u(orbit) = W^s(orbit)``, and a point of
    ``W^u(orbit)`` with ``r2 = 0`` is fixed by ``sigma_1`` (up to the rotation about the body
    axis 3): it lies on ``W^s(orbit)`` too. It is found by a 1D shooting problem, a root of
    ``sigma -> r2(P^j F^m p(sigma))`` (``p`` the fundamental domain of
    :func:`taylorball.periodic_manifolds.grow_manifold`), bracketed and solved by the
    Illinois method in the orbit's number type.

    Attributes
    ----------
    point : ndarray, shape (2,)
        ``(r1, r2)`` (``r2`` the residual, float64).
    state : ndarray
        Public state (working type).
    level, crossing : int
        ``m`` and ``j``: the point is ``P^j F^m p(sigma)``.
    sigma : float
        The fundamental-domain parameter (``numpy.longdouble``).
    s0 : float
        The fundamental domain's offset (relative to ``max(1, |x*|)``).
    branch : int
    tangent_u : ndarray, shape (2,)
        Unit tangent of ``W^u`` at the point in the chart (central differences in
        ``sigma``; for a stable ``manifold``, ``tangent_s`` reflected).
    tangent_s : ndarray, shape (2,)
        Of ``W^s``: ``tangent_u`` reflected, ``(t1, -t2)`` (the reversor); for a stable
        ``manifold``, from central differences along it.
    angle : float
        Between the two, in the chart ``(r1, r2)`` (radians, in ``(0, pi/2]``).
    symmetry_defect : float
        ``min_psi |S_psi sigma_1 z - z|`` for the internal state ``z`` (max norm): how far
        the point is from the reversor's fixed set in the state (the chart ``(r1, r2)``
        alone does not tell the energy sheets apart).
    fp_type : str
    evaluations : int
        Shooting evaluations (each ``m k + j`` crossings).
    """

    point: np.ndarray
    state: np.ndarray
    level: int
    crossing: int
    sigma: float
    s0: float
    branch: int
    tangent_u: np.ndarray
    tangent_s: np.ndarray
    angle: float
    symmetry_defect: float
    fp_type: str
    evaluations: int


#: A root of ``r2`` whose state is farther than this (times ``max(1, |x|)``) from the
#: reversor's fixed set is not a symmetric point: ``r2 = 0`` also holds where ``r1 = r2 = 0``
#: (``gamma1 = gamma2 = 0``), and the chart does not tell the energy sheets apart. A
#: symmetric point found in float64 is off by ~1e-8 (the noise of the far images).
SYMMETRY_TOL = 1e-5


def _symmetry_defect(x: np.ndarray) -> float:
    """``min_psi |S_psi sigma_1 x - x|`` (max norm, float64): the rotation about axis 3 that
    brings ``sigma_1 x`` back to ``x`` in its ``M`` components, then the largest difference."""
    from .periodic import _rotate3, reversors

    xf = _f64(x)
    y = xf * reversors()["sigma1"]
    psi = math.atan2(xf[1], xf[0]) - math.atan2(y[1], y[0])
    return float(np.max(np.abs(_rotate3(y, math.cos(psi), math.sin(psi)) - xf)))


def _illinois(g, a, b, ga: float, gb: float, tol, max_iter: int = 200):
    """A root of ``g`` in ``[a, b]`` (``ga gb < 0``) by the Illinois variant of regula falsi,
    falling back to bisection when it stalls; stops when the bracket is below ``tol``."""
    side = 0
    n = 0
    while abs(b - a) > tol and n < max_iter:
        c = (a * gb - b * ga) / (gb - ga) if gb != ga else (a + b) / 2
        if not (min(a, b) < c < max(a, b)) or n % 8 == 7:
            c = (a + b) / 2
        gc = g(c)
        n += 1
        if gc == 0.0:
            return c, n
        if (gc > 0) == (gb > 0):
            b, gb = c, gc
            if side == 1:
                ga /= 2
            side = 1
        else:
            a, ga = c, gc
            if side == -1:
                gb /= 2
            side = -1
    return (a + b) / 2, n


def symmetric_homoclinic_points(orbit: PeriodicOrbit, manifold: Manifold, *, max_points: int = 8, levels_extra: int = 0,
                                h_sigma: Optional[float] = None) -> List[SymmetricHomoclinicPoint]:
    r"""Homoclinic points of a saddle of the symmetric ball's map on the reversor's fixed set.

    Every sign change of ``r2`` between neighbours (not across a jump) of the curves of
    ``manifold`` (an unstable manifold from
    :func:`taylorball.periodic_manifolds.grow_manifold`) brackets a root of ``sigma ->
    r2(P^j F^m p(sigma))``; each is solved afresh from the fundamental domain in the number
    type of ``orbit`` (which may be a refined one, e.g. ``refine(o, (np.longdouble,))[-1]``:
    the manifold then only supplies the brackets).

    Parameters
    ----------
    orbit : PeriodicOrbit
        A saddle of the symmetric ball's map (``I1 = I2``), symmetric under ``sigma_1``.
    manifold : Manifold
        Its unstable manifold (grown from ``orbit`` or from the same orbit in float64), or
        its stable one: the same symmetric points are then found on ``W^s`` by the flow
        backwards, with ``tangent_s`` from ``W^s`` itself and ``tangent_u`` its reflection
        (an independent check of the unstable side's points and angles).
    max_points : int
        At most this many points (the first along the manifold).
    h_sigma : float, optional
        Step in ``sigma`` of the central differences for the tangent. The images far out on
        the manifold carry the start's rounding amplified by the flow (measured: ~1e-8 in
        the chart after 15 levels of the Fig. 3 saddle in float64, ~1e-11 in long double), so
        the step must be large against that noise: default ``1e-3`` in float64, ``1e-5``
        in long double and beyond (truncation ~``h^2``).
    levels_extra : int
        Start the shooting ``levels_extra`` levels nearer the saddle (``s0 |mu|^-levels_extra``
        and ``m + levels_extra``): the same points, with a smaller linearisation error
        ``O(s0^2)`` (for long double and beyond).

    Returns
    -------
    list of SymmetricHomoclinicPoint
        In the order along the manifold.

    Raises
    ------
    UsageError
        An orbit that is not a saddle of the symmetric ball's map, a manifold that is not an
        unstable one of it, bad counts.
    """
    from .periodic import _has_axial_symmetry
    from .periodic_manifolds import _SaddleMap

    if not isinstance(manifold, Manifold):
        raise UsageError(f"manifold must be a Manifold from grow_manifold, got {type(manifold).__name__}")
    which = manifold.which
    if not isinstance(orbit, PeriodicOrbit) or not _has_axial_symmetry(orbit.problem):
        raise UsageError("orbit must be a saddle of the dynamically symmetric ball (I1 = I2, kind 'reduced'): "
                         "the reversor's fixed set r2 = 0 is that map's")
    for name, v in (("max_points", max_points), ("levels_extra", levels_extra + 1)):
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
            raise UsageError(f"{name} must be an integer >= {1 if name == 'max_points' else 0}, got {v!r}")
    if manifold.curves.shape[0] != orbit.k:
        raise UsageError(f"manifold has {manifold.curves.shape[0]} curves, the orbit k = {orbit.k}: not its manifold")
    sm = _SaddleMap(orbit, "homoclinic points")
    spec = sm.spec
    if h_sigma is None:
        h_sigma = 1e-3 if spec.eps > 1e-17 else 1e-5
    elif not (isinstance(h_sigma, float) and 0 < h_sigma < 0.1):
        raise UsageError(f"h_sigma must be a float in (0, 0.1), got {h_sigma!r}")
    mu = sm.mu_u if which == "unstable" else 1.0 / sm.mu_s
    s0w = manifold.s0 * sm.scale * abs(mu) ** (-levels_extra)
    q = 1 if mu > 0 else 2
    evals = 0

    t_orbit = sm.orbit_times(which)
    lv_idx = [np.flatnonzero(manifold.level == m) for m in range(int(manifold.level.max()) + 1)]

    def guess(m: int, sig) -> np.ndarray:
        idx = lv_idx[m]
        S, Tm = manifold.sigma[idx], manifold.times[idx]
        out = np.array(t_orbit, dtype=float)
        for c in range(orbit.k):
            ok = np.isfinite(Tm[:, c])
            if ok.any():
                out[c] = np.interp(float(sig), S[ok], Tm[ok, c])
        return out

    class Lost(Exception):
        pass

    def image(sig, m: int, j: int) -> np.ndarray:
        """``P^j F^m p(sigma)``, every crossing followed by time from the manifold's."""
        nonlocal evals
        evals += 1
        x = _start_ld(sm, which, manifold.branch, s0w, sig, q)
        for lev in range(-levels_extra, m + (1 if j > 0 else 0)):
            img, _ = sm.track(x, t_orbit if lev < 0 else guess(lev, sig), which)
            y = img[-1] if lev < m else img[j - 1]
            if y is None:
                raise Lost(f"a crossing was lost at sigma = {sig!r}, level {lev}")
            x = y
        return x

    def r2(sig, m: int, j: int) -> float:
        return float(sm.chart(image(sig, m, j)[None, :])[0, 1])

    found: List[SymmetricHomoclinicPoint] = []
    n = len(manifold.sigma)
    for i in range(n - 1):
        if manifold.level[i] != manifold.level[i + 1]:
            continue
        m = int(manifold.level[i])
        for j in range(orbit.k):
            if (manifold.xjumps if j == 0 else manifold.jumps)[i]:
                continue
            c = manifold.curves[sm.orbit_point_index(which, j)]  # the j-th crossings' images
            a_, b_ = c[i, 1], c[i + 1, 1]
            if not (np.isfinite(a_) and np.isfinite(b_)) or (a_ > 0) == (b_ > 0):
                continue
            sa, sb = np.longdouble(manifold.sigma[i]), np.longdouble(manifold.sigma[i + 1])
            try:
                ga, gb = r2(sa, m, j), r2(sb, m, j)
            except Lost as exc:
                _log.debug("bracket skipped: %s", exc)
                continue
            if (ga > 0) == (gb > 0):
                _log.debug("no sign change from scratch in [%r, %r] (level %d, crossing %d)", sa, sb, m, j)
                continue
            tol = np.longdouble(4) * np.finfo(np.longdouble).eps if spec.eps < 1e-17 else np.longdouble(4e-16)
            sig, _ = _illinois(lambda s_: r2(s_, m, j), sa, sb, ga, gb, tol)
            z = image(sig, m, j)
            defect = _symmetry_defect(z)
            if not defect <= SYMMETRY_TOL * sm.scale:
                _log.debug("r2 = 0 at %s is not on the reversor's fixed set (defect %.1e)", sm.chart(z[None, :])[0], defect)
                continue
            h = np.longdouble(h_sigma)
            cp = sm.chart(image(sig + h, m, j)[None, :])[0]
            cm = sm.chart(image(sig - h, m, j)[None, :])[0]
            tu = (cp - cm) / np.linalg.norm(cp - cm)
            ts = tu * np.array([1.0, -1.0])
            if which == "stable":  # the curve's own tangent is the stable one
                tu, ts = ts, tu
            prob = orbit.problem
            found.append(SymmetricHomoclinicPoint(
                point=sm.chart(z[None, :])[0], state=public_state(prob.system, prob.pars, z, spec), level=m,
                crossing=j, sigma=sig, s0=float(manifold.s0), branch=manifold.branch, tangent_u=tu, tangent_s=ts,
                angle=_angle(tu, ts), symmetry_defect=defect, fp_type=str(spec), evaluations=evals))
            evals = 0
            if len(found) >= max_points:
                return found
    return found


def _start_ld(sm, which: str, branch: int, s0w: float, sigma, q: int) -> np.ndarray:
    """The fundamental domain's point at a long double ``sigma`` (the parameter's rounding
    must not limit a long double solution)."""
    from .periodic import _to_level

    mu, vec = (sm.mu_u, sm.v_u) if which == "unstable" else (1.0 / sm.mu_s, sm.v_s)
    f = np.longdouble(branch) * np.longdouble(s0w) * np.longdouble(abs(mu)) ** (np.longdouble(q) * sigma)
    d = np.array([f * np.longdouble(v) for v in vec])
    return _to_level(sm.ctx, sm.x + sm.spec.array(d), sm.scale)
