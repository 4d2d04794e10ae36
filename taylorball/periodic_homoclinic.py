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

from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from ._propagate import public_state, start_state
from ._typing import FpTypeLike
from .errors import StateError, UsageError
from .numbers import resolve_fp_type
from .periodic import PeriodicOrbit, _crossing_time, _Ctx, _eval_geo, _f64, _flow, _jacobian, _to_level
from .periodic_manifolds import HomoclinicPoint, _angle, _saddle_directions, _wrap_l

__all__ = ["HomoclinicOrbit", "connecting_orbit", "homoclinic_chain"]


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


def _basis(prob, g0: float, z: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the tangent space of section and level at ``z`` (float64)."""
    geo = _eval_geo(prob, g0, z)
    G = np.vstack([_f64(geo.grad_e)[None, :], _f64(geo.grad_c)])
    return np.linalg.svd(G)[2][G.shape[0]:].T


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
        Bs = [_basis(prob, ctx.g0, zi) for zi in z]
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

