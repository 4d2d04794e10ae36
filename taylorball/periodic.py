r"""Periodic orbits of the section maps: fixed points of the ``k``-th return map on a level.

A periodic orbit that crosses the section ``g = g0`` (paper section 4; section 5 for the
M||gamma system) ``k`` times per period is a fixed point of ``P^k``, the ``k``-th return map
of the section restricted to a level of the integrals. :func:`periodic_orbit` finds one by
Newton's method from a guess; :class:`PeriodicOrbit` is the result.

Method (docs/skeleton.md)
-------------------------
The unknown is the internal state ``x`` (``(M, gamma, R)``: 9 numbers; ``(K, gamma)``: 6),
not a chart point, so no energy root has to be followed. The equations are

.. math:: \phi_{T(x)}(x) - S_\theta x = 0,\qquad e(x) = 0,\qquad c(x) = c^*,

``T(x)`` the time of the ``k``-th crossing, ``e`` the section event function, ``c`` all
first integrals and constraints of the system (``C^2, M_\gamma, E, |\gamma|^2, (R,\gamma)``;
``|\gamma|^2, \lambda, E``) at their levels ``c^*``. ``S_\theta`` is the identity, except
for a dynamically symmetric ball (``I1 = I2``) where it is the rotation by ``theta`` about
the body axis 3 (the symmetry field ``u_3`` of paper section 4: ``l`` is cyclic and the
section map reduces to a 2D map of ``(r1, r2)``; its periodic orbits are relative periodic
orbits, ``P^k x = S_\theta x``, and ``theta`` is one more unknown, with the phase condition
``(u_3(x), \Delta x) = 0``).

The system is overdetermined but consistent; it is solved by Gauss-Newton (least squares
steps, quadratic convergence on a consistent system with a Jacobian of full column rank).
The Jacobian of the first block is :math:`\Pi\Phi - S_\theta` with ``Phi`` the fundamental
matrix of the variational equations (:class:`taylorball.tangent.TangentSystem`,
``vectors="all"``) to ``T(x)`` and :math:`\Pi = I - f\,\nabla e^T / (\nabla e\cdot f)` the
projection along the flow that accounts for the variation of the return time.

Multipliers: at the solution, with ``B`` an orthonormal basis of the tangent space of
section-and-level (the null space of the gradients of ``e`` and ``c``), the map's
derivative on the level is :math:`A = B^T S_\theta^{-1}\Pi\Phi B` (3x3 for the reduced
system; 2x2 for M||gamma; for a symmetric ball the quotient by ``u_3``, 2x2). ``det A = 1``
at a fixed point whatever the density (``sigma(Px) |det DP| = sigma(x)`` with ``Px = x``).

Precision: the residual is computed in the working type (float64, long double, real128),
the Jacobian in float64; the steps (tiny after the float64 stage) are exact enough in
float64, so a long double / real128 refinement converges in two or three steps.
:func:`refine` reports the number of correct digits by comparing successive precisions.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field, replace
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from ._cache import compiled
from ._problem import Problem, problem
from ._propagate import public_state, start_state
from ._typing import Direction, FpTypeLike, KindName, ParamsLike
from ._deprecation import moved, options_of
from .errors import IntegrationError, StateError, UsageError
from .levels import Levels, MParallelLevels
from .numbers import FpSpec, resolve_fp_type
from ._section_events import _event_parts
from .sections import Section, chart_points
from .tangent import TangentSystem

__all__ = ["PeriodicOrbit", "NewtonFailure", "NewtonOptions", "periodic_orbit", "refine", "classify", "reversors",
           "orbit_problem"]

LevelsLike = Union[Levels, MParallelLevels, Dict[str, float], None]

#: Tolerance of "1" for ``I1 == I2`` (the symmetric ball): equal as floats.
_SYMMETRY_KINDS = ("reduced",)


# ---------------------------------------------------------------------------------------
# Compiled geometry: event, its gradient, the field, the integrals and their gradients.
# ---------------------------------------------------------------------------------------
def _geometry(prob: Problem, g0: float):
    """``x -> [e, de/dt, grad e (n), f (n), c (m), grad c (m x n)]`` compiled in the
    problem's number type (cached); returns ``(cfunc, names)``."""
    spec = prob.spec

    def build():
        import heyoka as hy

        system = prob.system
        xs, e, de, rhs = _event_parts(prob.kind, g0)
        c = system.constants([hy.par[i] for i in range(system.n_pars)])
        ints = system.info.integrals(c, system.vectors(c, xs))
        names = tuple(ints)
        outs = [e, de] + [hy.diff(e, x) for x in xs] + list(rhs) + [ints[k] for k in names]
        for k in names:
            outs += [hy.diff(ints[k], x) for x in xs]
        kw: Dict[str, Any] = dict(fp_type=spec.fp_type, compact_mode=True)
        if spec.prec is not None:
            kw["prec"] = spec.prec
        return hy.cfunc(outs, xs, **kw), names

    return compiled(("cfunc", "periodic geometry", prob.kind, prob.formulation, str(spec), float(g0)), build)


@dataclass
class _Geo:
    e: Any
    de: Any
    grad_e: np.ndarray
    f: np.ndarray
    c: np.ndarray
    grad_c: np.ndarray
    names: Tuple[str, ...]


def _eval_geo(prob: Problem, g0: float, x: np.ndarray) -> _Geo:
    cf, names = _geometry(prob, g0)
    n, m = len(x), len(names)
    out = cf(np.ascontiguousarray(x), pars=prob.pars[:cf.nparams] if cf.nparams else None) \
        if cf.nparams else cf(np.ascontiguousarray(x))
    i = 2
    grad_e = out[i:i + n]
    f = out[i + n:i + 2 * n]
    c = out[i + 2 * n:i + 2 * n + m]
    grad_c = out[i + 2 * n + m:].reshape(m, n)
    return _Geo(out[0], out[1], grad_e, f, c, grad_c, names)



def _tangent_basis(prob: Problem, g0: float, z: np.ndarray) -> np.ndarray:
    """Orthonormal basis (columns, float64) of the tangent space of section and level at
    ``z``: the null space of the section's and the integrals' gradients (by SVD, rows of
    rank below ``1e-10`` of the largest singular value counted as dependent)."""
    geo = _eval_geo(prob, g0, z)
    G = np.vstack([_f64(geo.grad_e)[None, :], _f64(geo.grad_c)])
    _, s, Vt = np.linalg.svd(G)
    rank = int(np.sum(s > 1e-10 * s[0]))
    return Vt[rank:].T

# ---------------------------------------------------------------------------------------
# The symmetry of a dynamically symmetric ball, and the reversors.
# ---------------------------------------------------------------------------------------
def _has_axial_symmetry(prob: Problem) -> bool:
    if prob.kind not in _SYMMETRY_KINDS or prob.formulation != "momentum":
        return False
    inertia = getattr(prob.params, "inertia")
    I1, I2 = inertia[0], inertia[1]
    return I1 == I2


def _rotate3(x: np.ndarray, cth, sth) -> np.ndarray:
    """Rotation of every 3-vector of ``x`` by ``theta`` about the body axis 3."""
    y = x.copy()
    for b in range(0, len(x), 3):
        y[b] = cth * x[b] - sth * x[b + 1]
        y[b + 1] = sth * x[b] + cth * x[b + 1]
    return y


def _u3(x: np.ndarray) -> np.ndarray:
    """The generator ``d/dtheta`` of :func:`_rotate3` at ``theta = 0`` (paper's ``u_3``)."""
    y = np.zeros_like(x)
    for b in range(0, len(x), 3):
        y[b] = -x[b + 1]
        y[b + 1] = x[b]
    return y


def reversors(kind: KindName = "reduced") -> Dict[str, np.ndarray]:
    r"""The linear reversors of the reduced equations (time reversal with a reflection).

    For ``x = (M, gamma, R)`` and ``S = diag(s, s, s)`` with ``s`` a reflection of the body
    frame, ``f(S x) = -S f(x)``: the reflections ``sigma_1, sigma_2, sigma_3`` of one body
    axis and ``-E``. ``sigma_1, sigma_2`` keep the section ``g = 0`` (and ``g = pi``) with
    its direction (``g -> -g`` under the reflection, time reversed); ``sigma_3`` and ``-E``
    map ``g`` to ``pi - g``. Found by testing all diagonal sign matrices on the vector field
    (tests/test_periodic.py repeats the check); returned as the 9 diagonal signs.
    """
    if kind != "reduced":
        raise UsageError(f"reversors are tabulated for kind='reduced', got {kind!r}")
    out = {}
    for i in range(3):
        s = np.ones(3)
        s[i] = -1.0
        out[f"sigma{i + 1}"] = np.tile(s, 3)
    out["minus_identity"] = -np.ones(9)
    return out


# ---------------------------------------------------------------------------------------
# Classification.
# ---------------------------------------------------------------------------------------
def multiplier_summary(A: ArrayLike) -> Dict[str, Any]:
    r"""The fields of a :class:`PeriodicOrbit` that its multiplier matrix ``A`` decides.

    ``matrix`` (``A`` as float), ``multipliers`` (eigenvalues sorted by modulus), ``trace``,
    ``second_trace`` (``sigma = (tr^2 - tr A^2) / 2`` of a 3x3 ``A``; 1 for a 2x2 one, whose
    determinant it is) and ``stability``, ``type`` (:func:`classify`): one computation for
    every solver, so that orbits found by different methods are described alike.
    """
    A = np.asarray(A, dtype=float)
    mu = np.linalg.eigvals(A)
    mu = mu[np.argsort(np.abs(mu))]
    tr = float(np.trace(A))
    st2 = float((tr * tr - np.trace(A @ A)) / 2) if A.shape == (3, 3) else 1.0
    stability, typ = classify(A)
    return {"matrix": A, "multipliers": mu, "trace": tr, "second_trace": st2, "stability": stability, "type": typ}


def classify(A: ArrayLike, *, tol: float = 1e-6) -> Tuple[str, str]:
    r"""Stability of a fixed point from its multiplier matrix ``A`` (2x2 or 3x3, det 1).

    2D (area preserving): ``|tr A| < 2`` elliptic, ``tr A > 2`` hyperbolic (type
    ``"saddle"``), ``tr A < -2`` hyperbolic (``"reflection-saddle"``), within ``tol`` of
    ``+-2`` parabolic.

    3D (volume preserving, Dullin & Meiss 2009): with trace ``tau`` and second trace
    ``sigma`` the characteristic polynomial is ``l^3 - tau l^2 + sigma l - 1``; a multiplier 1
    on the line ``sigma = tau``, -1 on ``sigma = -tau - 2``, a double multiplier on the
    discriminant curve. All three multipliers on the unit circle (``1, e^{+-i phi}``): elliptic;
    a complex pair off the circle: hyperbolic (``"saddle-focus"``); three real multipliers,
    not all of modulus 1: hyperbolic (``"saddle"``, ``"reflection-saddle"`` with negative
    ones); within ``tol`` of a collision at ``+-1``: parabolic.

    Returns
    -------
    (stability, type) : str, str
    """
    A = np.asarray(A, dtype=float)
    lam = np.linalg.eigvals(A)
    mod = np.abs(lam)
    if A.shape == (2, 2):
        tr = float(np.trace(A))
        if abs(abs(tr) - 2) <= tol:
            return "parabolic", "parabolic"
        if abs(tr) < 2:
            return "elliptic", "elliptic"
        return "hyperbolic", "saddle" if tr > 0 else "reflection-saddle"
    if A.shape != (3, 3):
        raise UsageError(f"A must be a 2x2 or 3x3 matrix, got shape {A.shape}")
    if np.all(np.abs(mod - 1) <= tol):
        real = np.abs(lam.imag) <= tol
        if np.all(real) or np.any(np.abs(lam[np.abs(lam.imag) > tol] - 1) <= tol):
            return "parabolic", "parabolic"
        return "elliptic", "elliptic"
    cplx = np.abs(lam.imag) > tol * np.maximum(1.0, mod)
    if np.any(cplx):
        return "hyperbolic", "saddle-focus"
    if np.any(np.abs(mod - 1) <= tol) and np.sum(np.abs(mod - 1) <= tol) >= 2:
        return "parabolic", "parabolic"
    return "hyperbolic", "reflection-saddle" if np.any(lam.real < 0) else "saddle"


# ---------------------------------------------------------------------------------------
# Results.
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PeriodicOrbit:
    r"""A periodic orbit: a fixed point of the ``k``-th return map on a level.

    Attributes
    ----------
    kind : str
    state : ndarray
        Public-layout state on the section (working number type).
    period : float
        Flow time of ``k`` crossings.
    k : int
        Section crossings per period (the minimal one: a guess given with a multiple of it
        is reported with the minimal ``k``).
    points : ndarray, shape (k, 3) or (k, 2)
        The ``k`` section points in the chart, ``(l, r1, r2)`` or ``(l, L/G)``.
    multipliers : ndarray (complex)
        Of the section map restricted to the level (3 for the reduced system; 2 for the
        M||gamma system and for a symmetric ball's map of ``(r1, r2)``), sorted by modulus.
    matrix : ndarray
        The multiplier matrix ``A`` (float64; see the module docstring).
    trace, second_trace : float
        ``tr A`` and (3x3) ``((tr A)^2 - tr A^2)/2``.
    stability : {"elliptic", "hyperbolic", "parabolic"}
    type : str
        ``"elliptic"``, ``"saddle"``, ``"reflection-saddle"``, ``"saddle-focus"``, ``"parabolic"``.
    residual : float
        ``max |phi_T(x) - S x|`` (internal variables, working type) at the returned state.
    residual_history : tuple of float
        The residual at each Newton iterate.
    converged : bool
    symmetric : str or None
        The reversor (``"sigma1"``, ...) that maps the orbit's section points onto themselves
        (time reversed; compared as states), or ``None``.
    shift : float
        ``theta`` of a symmetric ball's relative periodic orbit (``P^k x = S_theta x``; 0 else).
    levels : dict of str -> float
        The integrals at ``state``.
    g0, direction : the section.
    fp_type : str
    digits : dict or None
        Correct digits of ``state`` per number type, from :func:`refine`.
    internal : ndarray
        The internal state.
    """

    kind: str
    state: np.ndarray
    period: float
    k: int
    points: np.ndarray
    multipliers: np.ndarray
    matrix: np.ndarray
    trace: float
    second_trace: float
    stability: str
    type: str
    residual: float
    residual_history: Tuple[float, ...]
    converged: bool
    symmetric: Optional[str]
    shift: float
    levels: Dict[str, float]
    g0: float
    direction: int
    fp_type: str
    internal: np.ndarray
    problem: Problem = field(repr=False, compare=False, default=None)  # type: ignore[assignment]
    digits: Optional[Dict[str, float]] = None

    @property
    def lyapunov(self) -> float:
        """``ln max |mu| / period``: the orbit's largest Lyapunov exponent (0 if elliptic)."""
        return float(np.log(np.max(np.abs(self.multipliers))) / self.period)

    def __repr__(self) -> str:
        mu = ", ".join(f"{m.real:.6g}" + (f"{m.imag:+.3g}j" if abs(m.imag) > 0 else "") for m in self.multipliers)
        return (f"PeriodicOrbit(kind={self.kind!r}, k={self.k}, period={self.period:.12g}, {self.stability} "
                f"({self.type}), multipliers=[{mu}], residual={self.residual:.1e}, symmetric={self.symmetric}, "
                f"fp_type={self.fp_type})")


class NewtonFailure(IntegrationError):
    """Newton's method did not converge to a periodic orbit; ``.residual`` and
    ``.residual_history`` say how far it got and ``.state`` where it ended."""

    def __init__(self, message: str, residual: float, history: Sequence[float], state: Optional[np.ndarray]) -> None:
        super().__init__(message)
        self.residual = residual
        self.residual_history = tuple(history)
        self.state = state


# ---------------------------------------------------------------------------------------
# Argument handling.
# ---------------------------------------------------------------------------------------
def orbit_problem(kind: Union[KindName, Problem], params: Optional[ParamsLike] = None, *,
                  fp_type: FpTypeLike = float, tol: Optional[float] = None) -> Problem:
    """The :class:`Problem` of a periodic-orbit computation (a system with a section chart)."""
    prob = problem(kind, params, fp_type=fp_type, tol=tol) if not isinstance(kind, Problem) else problem(kind)
    if prob.system.info.chart is None:
        raise UsageError(f"periodic orbits are fixed points of a section map: kind must be 'reduced' or "
                         f"'mparallel', got {prob.kind!r}")
    return prob


def _check_k(k) -> int:
    if not isinstance(k, (int, np.integer)) or isinstance(k, bool) or k < 1:
        raise UsageError(f"k (section crossings per period) must be an integer >= 1, got {k!r}")
    return int(k)


def _level_targets(prob: Problem, names: Tuple[str, ...], levels: LevelsLike) -> Dict[str, float]:
    """The exact values of the level constraints named ``names`` for ``levels``."""
    if levels is None:
        return {}
    d = dict(levels) if isinstance(levels, dict) else {k: float(v) for k, v in levels.as_kwargs().items()}  # type: ignore[arg-type]
    out: Dict[str, float] = {"gamma2": 1.0}
    if prob.kind == "reduced":
        try:
            out.update(C2=float(d["C"]) ** 2, M_gamma=float(d["M_gamma"]), E=float(d["h"]), R_gamma=0.0)
        except KeyError as exc:
            raise UsageError(f"levels of kind='reduced' need C, M_gamma, h (a Levels), got {levels!r}") from exc
    else:
        try:
            out.update({"lambda": float(d["lam"]), "E": float(d["h"])})
        except KeyError as exc:
            raise UsageError(f"levels of kind='mparallel' need lam, h (an MParallelLevels), got {levels!r}") from exc
    return {k: out[k] for k in names}


@dataclass
class _Ctx:
    """One periodic-orbit problem: the problem, section, k, level targets."""

    prob: Problem
    g0: float
    direction: int
    k: int
    targets: np.ndarray  # working type, ordered as the geometry's integral names
    symmetric: bool
    t_max: float

    @property
    def section(self) -> Section:
        return Section(self.prob, self.g0, self.direction)  # type: ignore[arg-type]


# ---------------------------------------------------------------------------------------
# The k-th return with its fundamental matrix.
# ---------------------------------------------------------------------------------------
def _var_template(prob: Problem):
    return TangentSystem.of(prob, "all").template(prob, compact_mode=True)


#: Crossings earlier than this are the start point itself (a state on the section to
#: rounding can cross it again within ~1e-11 when its event's time derivative is small;
#: ``Section`` drops only those within 1e-12): a return time is never this short here.
T_MIN = 1e-6


def _crossing_time(ctx: _Ctx, x: np.ndarray) -> float:
    """Time of the ``k``-th crossing after ``T_MIN`` from internal ``x`` (by :class:`Section`)."""
    prob = ctx.prob
    pub = public_state(prob.system, prob.pars, x, prob.spec)
    res = ctx.section.run(pub, n_points=ctx.k + 1, t_end=ctx.t_max)
    times = [t for t in res.times if float(t) > T_MIN]
    if len(times) < ctx.k:
        raise IntegrationError(f"the orbit did not cross the section {ctx.k} times before t = {ctx.t_max!r} "
                               f"({res.message})")
    return times[ctx.k - 1]


def _var_start(prob: Problem, x: np.ndarray):
    """``(TangentSystem, integrator)``: a copy of the compiled variational integrator at
    ``t = 0`` from ``x`` with the identity as the tangent matrix."""
    spec = prob.spec
    ts = TangentSystem.of(prob, "all")
    ta = copy.copy(_var_template(prob))
    n = len(x)
    ta.state[:n] = x
    ta.state[n:] = ts.identity(spec)
    ta.pars[:] = prob.pars
    ta.time = spec.scalar(0.0)
    return ts, ta


def _flow(ctx: _Ctx, x: np.ndarray, T) -> Tuple[np.ndarray, np.ndarray, Any]:
    """``(x(T*), Phi (float64), T*)`` with ``T*`` the crossing near ``T`` (time-Newton)."""
    prob, spec = ctx.prob, ctx.prob.spec
    ts, ta = _var_start(prob, x)
    n = len(x)
    T = spec.scalar(T)
    T0 = float(T)
    for _ in range(6):
        oc = ta.propagate_until(T)[0]
        if str(oc) not in ("taylor_outcome.time_limit",):
            raise IntegrationError(f"the variational integration stopped at t = {ta.time} ({oc})")
        geo = _eval_geo(prob, ctx.g0, ta.state[:n])
        delta = geo.e / geo.de
        T = T - delta
        if abs(float(T) - T0) > 1e-3 * (1 + T0):
            raise IntegrationError(f"the crossing near t = {T0!r} moved to {float(T)!r}: recount the crossings")
        if abs(float(delta)) <= 4 * spec.eps * (1 + abs(float(T))):
            oc = ta.propagate_until(T)[0]
            break
    Phi = np.asarray(ts.tangent_matrix(ta.state), dtype=object).astype(float)
    return ta.state[:n].copy(), Phi, T


def _residual_parts(ctx: _Ctx, x: np.ndarray, theta, T_guess=None):
    prob = ctx.prob
    T = _crossing_time(ctx, x) if T_guess is None else T_guess
    xT, Phi, T = _flow(ctx, x, T)
    if ctx.symmetric:
        cth, sth = np.cos(theta), np.sin(theta)
        Sx = _rotate3(x, cth, sth)
    else:
        Sx = x
    geo0 = _eval_geo(prob, ctx.g0, x)
    r_map = xT - Sx
    r_sec = np.array([geo0.e])
    r_lev = geo0.c - ctx.targets
    return r_map, r_sec, r_lev, xT, Phi, T, geo0


def _jacobian(ctx: _Ctx, x, theta, xT, Phi, geo0):
    prob = ctx.prob
    geoT = _eval_geo(prob, ctx.g0, xT)
    fT = np.asarray(geoT.f, dtype=float)
    gT = np.asarray(geoT.grad_e, dtype=float)
    Pi = np.eye(len(x)) - np.outer(fT, gT) / float(np.dot(gT, fT))
    PP = Pi @ Phi
    n = len(x)
    xf = np.asarray(x, dtype=float)
    if ctx.symmetric:
        th = float(theta)
        Rm = np.array([_rotate3(col, math.cos(th), math.sin(th)) for col in np.eye(n)]).T
        dS = _u3(_rotate3(xf, math.cos(th), math.sin(th)))
        top = np.hstack([PP - Rm, -dS[:, None]])
        rows = [top, np.hstack([np.asarray(geo0.grad_e, dtype=float)[None, :], [[0.0]]]),
                np.hstack([np.asarray(geo0.grad_c, dtype=float), np.zeros((len(geo0.c), 1))]),
                np.hstack([_u3(xf)[None, :], [[0.0]]])]
    else:
        rows = [PP - np.eye(n), np.asarray(geo0.grad_e, dtype=float)[None, :],
                np.asarray(geo0.grad_c, dtype=float)]
    return np.vstack(rows), PP


def _multiplier_matrix(ctx: _Ctx, x, theta, PP, geo0) -> np.ndarray:
    """``A = B^T S^{-1} Pi Phi B`` on the tangent space of section and level (see module doc)."""
    G = np.vstack([np.asarray(geo0.grad_e, dtype=float)[None, :], np.asarray(geo0.grad_c, dtype=float)])
    _, s, Vt = np.linalg.svd(G)
    n = G.shape[1]
    rank = int(np.sum(s > 1e-10 * s[0]))
    B = Vt[rank:].T  # orthonormal basis of ker G
    M = PP
    if ctx.symmetric:
        th = float(theta)
        Rinv = np.array([_rotate3(col, math.cos(-th), math.sin(-th)) for col in np.eye(n)]).T
        M = Rinv @ PP
        u = _u3(np.asarray(x, dtype=float))
        u = B @ (B.T @ u)
        u /= np.linalg.norm(u)
        rest = B - np.outer(u, u @ B)
        U, sv, _ = np.linalg.svd(rest, full_matrices=False)
        B2 = U[:, : B.shape[1] - 1]
        return B2.T @ M @ B2  # the quotient by u3 (M u = u, B2 orthogonal to u)
    return B.T @ M @ B


# ---------------------------------------------------------------------------------------
# Newton.
# ---------------------------------------------------------------------------------------
#: Newton's trial points may take at most this many times the current iterate's return time
#: to return ``k`` times (an iterate near a periodic orbit returns in about its period; a
#: trial that never returns otherwise ran to ``t_max`` = 1e4 in every backtracking step:
#: minutes per failed seed on the Fig. 1 level).
RETURN_FACTOR = 4.0


def _newton(ctx: _Ctx, x0: np.ndarray, theta0, *, max_iter: int, rtol: float, T_guess=None, stall: int = 0):
    """Gauss-Newton with backtracking on ``|F|``; returns ``(best, history)`` with
    ``best = (residual, x, theta, T, (xT, Phi, geo0))``. ``stall > 0``: also stop when the residual, above
    the acceptance bound ``1e3 rtol`` (relative), has not halved over the last ``stall`` iterations."""
    spec = ctx.prob.spec
    x = spec.array(x0)
    theta = spec.scalar(theta0) if ctx.symmetric else spec.scalar(0.0)
    hist: List[float] = []
    scale = max(1.0, float(np.max(np.abs(np.asarray(x, dtype=object).astype(float)))))
    n = len(x)

    def evaluate(x, theta, T):
        try:
            r_map, r_sec, r_lev, xT, Phi, T, geo0 = _residual_parts(ctx, x, theta, T)
        except (IntegrationError, StateError):
            return None
        F = np.concatenate([_f64(r_map), _f64(r_sec), _f64(r_lev)])
        res = float(np.max(np.abs(F)))
        return (res, x, theta, T, (xT, Phi, geo0), F) if np.isfinite(res) else None

    cur = evaluate(x, theta, T_guess)
    if cur is None:
        raise IntegrationError(f"the guess does not return to the section {ctx.k} times (t_max = {ctx.t_max!r})")
    for it in range(max_iter):
        # a trial whose k-th return takes more than RETURN_FACTOR times the current one is not
        # near this orbit: it fails (and the step is halved) instead of running to t_max
        ctx = replace(ctx, t_max=min(ctx.t_max, RETURN_FACTOR * float(cur[3])))
        hist.append(cur[0])
        if cur[0] <= rtol * scale:
            break
        # stagnation at the rounding floor: two iterates without a 2x gain
        if len(hist) >= 3 and hist[-1] > 0.5 * hist[-3] and hist[-1] < 1e3 * rtol * scale:
            break
        if stall and len(hist) > stall and hist[-1] > 0.5 * hist[-1 - stall] and hist[-1] > 1e3 * rtol * scale:
            break  # stalled far from a solution: the step fails now, not after max_iter iterations
        res, x, theta, T, (xT, Phi, geo0), F = cur
        J, _ = _jacobian(ctx, x, theta, xT, Phi, geo0)
        rhs = np.concatenate([F, [0.0]]) if ctx.symmetric else F
        step = _constrained_step(J, rhs, n)
        smax = float(np.max(np.abs(step)))
        if smax > 0.2 * scale:  # never move by more than a fifth of the state's scale at once
            step *= 0.2 * scale / smax
        lam, nxt = 1.0, None
        for _ in range(14):
            xn = x + spec.array(lam * step[:n])
            try:
                xn = _to_level(ctx, xn, scale)  # back onto section and level (a retraction)
            except StateError:
                lam *= 0.5
                continue
            thn = theta + spec.scalar(lam * float(step[n])) if ctx.symmetric else theta
            near = lam * smax <= 1e-8 * scale and T_guess is not None
            trial = evaluate(xn, thn, T if near else None)
            if trial is not None and trial[0] < res * (1 - 1e-4 * lam) + 64 * spec.eps * scale:
                nxt = trial
                break
            lam *= 0.5
        if nxt is None:
            break
        cur = nxt
    else:
        hist.append(cur[0])
    if not hist or hist[-1] != cur[0]:
        hist.append(cur[0])
    return cur[:5], hist


def _constrained_step(J: np.ndarray, rhs: np.ndarray, n: int) -> np.ndarray:
    """Least-squares step for the map rows (the first ``n``) subject to the linearised
    section, level and phase rows (the rest) holding exactly: the null-space method
    (``Delta = Delta_p + N z``), i.e. Newton on the section map restricted to the level."""
    Jm, Jc = J[:n], J[n:]
    Fm, Fc = rhs[:n], rhs[n:]
    dp = np.linalg.lstsq(Jc, -Fc, rcond=None)[0]
    _, s, Vt = np.linalg.svd(Jc)
    rank = int(np.sum(s > 1e-12 * s[0]))
    N = Vt[rank:].T
    z = np.linalg.lstsq(Jm @ N, -(Fm + Jm @ dp), rcond=None)[0]
    return dp + N @ z


def _to_level(ctx: _Ctx, x: np.ndarray, scale: float) -> np.ndarray:
    """``x`` moved onto the section and the level (Gauss-Newton on ``e = 0``, ``c = c*``,
    minimal-norm corrections) in the working type."""
    spec = ctx.prob.spec
    x = x.copy()
    ctx.prob.system.info.project(x)
    for _ in range(12):
        geo = _eval_geo(ctx.prob, ctx.g0, x)
        r = np.concatenate([_f64(np.array([geo.e])), _f64(geo.c - ctx.targets)])
        if float(np.max(np.abs(r))) <= 8 * spec.eps * scale:
            return x
        G = np.vstack([_f64(geo.grad_e)[None, :], _f64(geo.grad_c)])
        x = x - spec.array(np.linalg.lstsq(G, r, rcond=None)[0])
        ctx.prob.system.info.project(x)
    geo = _eval_geo(ctx.prob, ctx.g0, x)
    r = np.concatenate([_f64(np.array([geo.e])), _f64(geo.c - ctx.targets)])
    if float(np.max(np.abs(r))) > 1e3 * spec.eps * scale or not _on_branch(ctx.prob, ctx.g0, x):
        raise StateError(f"could not move the state onto the section and level (residual {float(np.max(np.abs(r))):.1e})")
    return x


def _f64(a) -> np.ndarray:
    return np.asarray(a, dtype=object).astype(float)


def _internal_guess(prob: Problem, state) -> np.ndarray:
    return start_state(prob, state)


def _minimal_k(points: np.ndarray, k: int, ignore_l: bool, tol: float) -> int:
    """The least divisor ``d`` of ``k`` with ``p_d = p_0`` (``l`` ignored for the relative
    orbits of a symmetric ball)."""
    for d in range(1, k):
        if k % d == 0:
            diff = points[d] - points[0]
            diff[0] = 0.0 if ignore_l else (diff[0] + math.pi) % (2 * math.pi) - math.pi
            if float(np.max(np.abs(diff))) <= tol:
                return d
    return k


def _symmetry_of(ctx: _Ctx, xs_int: np.ndarray, tol: float) -> Optional[str]:
    """The reversor mapping the orbit's section points onto themselves (time reversed): every
    image ``S x_i`` of an internal section state is one of the ``x_j`` to ``tol`` relative
    (max norm over the 9 variables, scaled by ``max(1, |x|)``). States, not chart points: the
    chart ``(l, r1, r2)`` does not see ``sigma3`` (it changes the signs of ``M3, gamma3, R3``
    and maps ``g`` to ``pi - g``, and the chart point is the same), so a comparison of chart
    points called every orbit symmetric under it. A reversor that maps the section to another
    one (``sigma3`` and ``-E`` for ``g = 0``) cannot map the section points onto themselves,
    and is not reported: whether the orbit's points on the other section are its images is not
    tested here."""
    if ctx.prob.kind != "reduced" or ctx.symmetric:
        return None
    pts = np.asarray(xs_int, dtype=float)
    scale = max(1.0, float(np.max(np.abs(pts))))
    for name, s in reversors().items():
        img = pts * s
        if all(float(np.min(np.max(np.abs(pts - p), axis=1))) <= tol * scale for p in img):
            return name
    return None


@dataclass(frozen=True)
class NewtonOptions:
    """The less common options of :func:`periodic_orbit`'s Newton iteration
    (``options=tb.NewtonOptions(...)``; the old keywords of the same names are deprecated).

    Attributes
    ----------
    max_iter : int
        Newton iterations.
    rtol : float, optional
        Convergence: ``max |residual| <= rtol * max(1, |x|)``; default ``256 eps`` of
        ``fp_type`` (float64: 5.7e-14).
    shift : float, optional
        Initial ``theta`` of a symmetric ball's relative periodic orbit (default: the change
        of ``l`` over ``k`` crossings of the guess).
    section_tol : float
        How far the guess may be off the section (``|e|``) and off ``levels`` (relative).
    """

    max_iter: int = 30
    rtol: Optional[float] = None
    shift: Optional[float] = None
    section_tol: float = 1e-8


@moved(NewtonOptions, "max_iter", "rtol", "shift", "section_tol")
def periodic_orbit(kind: Union[KindName, Problem], params: Optional[ParamsLike] = None,
                   state: Optional[ArrayLike] = None, k: int = 1, *, levels: LevelsLike = None,
                   g0: float = 0.0, direction: Direction = 1, fp_type: FpTypeLike = float,
                   tol: Optional[float] = None, t_max: Optional[float] = None,
                   options: Optional[NewtonOptions] = None) -> PeriodicOrbit:
    r"""A periodic orbit crossing the section ``k`` times per period, by Newton from a guess.

    Parameters
    ----------
    kind : {"reduced", "mparallel"} or Problem
    params : BallParams or MParallelParams (None with a Problem)
    state : array_like
        The guess: a public-layout state on the section ``g = g0`` (``|e| <= section_tol``),
        e.g. from :func:`taylorball.states_on_section`.
    k : int
        Section crossings per period (>= 1).
    levels : Levels, MParallelLevels or dict, optional
        The level the orbit must lie on; the guess must be on it to ``section_tol`` (relative).
        Default: the guess's own integrals.
    g0, direction
        The section (as :func:`taylorball.poincare_section`).
    fp_type, tol
        Number type and integrator tolerance of the Newton iteration.
    t_max : float, optional
        Time limit of ``k`` crossings (default 1e4).
    options : NewtonOptions, optional
        ``max_iter``, ``rtol``, ``shift``, ``section_tol`` (default ``NewtonOptions()``;
        the keywords of the same names are their deprecated old form).

    Returns
    -------
    PeriodicOrbit

    Raises
    ------
    UsageError
        ``k < 1``, a kind without a section.
    StateError
        A guess off the section or off ``levels``.
    NewtonFailure
        Newton did not reach ``rtol`` (the residual and its history are attached).
    """
    options = options_of(options, NewtonOptions, "periodic_orbit")
    max_iter, rtol, shift, section_tol = options.max_iter, options.rtol, options.shift, options.section_tol
    prob = orbit_problem(kind, params, fp_type=fp_type, tol=tol)
    k = _check_k(k)
    if state is None:
        raise UsageError("state (a guess on the section, public layout) is required")
    if not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise UsageError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    Section(prob, g0, direction)  # checks g0, direction
    spec = prob.spec
    rtol = 256 * spec.eps if rtol is None else float(rtol)
    t_max = 1e4 if t_max is None else float(t_max)
    x0 = _internal_guess(prob, state)
    geo = _eval_geo(prob, g0, x0)
    if abs(float(geo.e)) > section_tol:
        raise StateError(f"state is not on the section g = {g0!r}: the event function is {float(geo.e):.3e} "
                         f"(|e| <= section_tol = {section_tol!r} needed); start from tb.states_on_section")
    if not _on_branch(prob, g0, x0):
        raise StateError(f"state is on the half-line g = g0 + pi, not on the section g = {g0!r}")
    targets_d = _level_targets(prob, geo.names, levels)
    if targets_d:
        for name in geo.names:
            v, t = float(geo.c[geo.names.index(name)]), targets_d[name]
            if abs(v - t) > section_tol * max(1.0, abs(t)):
                raise StateError(f"state is off the level {levels!r}: its {name} is {v!r}, the level's {t!r}")
        targets = spec.array([targets_d[n] for n in geo.names])
    else:
        targets = geo.c.copy()
    ctx = _Ctx(prob, float(g0), int(direction), k, targets, _has_axial_symmetry(prob), t_max)
    theta0 = 0.0
    if ctx.symmetric:
        if shift is None:
            res = ctx.section.run(public_state(prob.system, prob.pars, x0, spec), n_points=k + 1, t_end=t_max)
            pk = [p for t, p in zip(res.times, res.points) if float(t) > T_MIN]
            if len(pk) < k:
                raise IntegrationError(f"the guess does not cross the section {k} times ({res.message})")
            p0 = chart_points(prob.kind, x0[None, :])[0]
            theta0 = float(p0[0] - pk[k - 1][0])  # l = atan2(M1, M2): rotation by theta lowers l by theta
            theta0 = (theta0 + math.pi) % (2 * math.pi) - math.pi
        else:
            theta0 = float(shift)
    return _solve(ctx, x0, theta0, max_iter=max_iter, rtol=rtol)


def _on_branch(prob, g0, x) -> bool:
    from ._section_run import _on_branch as on_branch

    return bool(on_branch(x, g0))


def _solve(ctx: _Ctx, x0, theta0, *, max_iter: int, rtol: float, T_guess=None, stall: int = 0) -> PeriodicOrbit:
    prob, spec = ctx.prob, ctx.prob.spec
    best, hist = _newton(ctx, x0, theta0, max_iter=max_iter, rtol=rtol, T_guess=T_guess, stall=stall)
    res, x, theta, T, (xT, Phi, geo0) = best
    scale = max(1.0, float(np.max(np.abs(np.asarray(x, dtype=object).astype(float)))))
    if not res <= 1e3 * rtol * scale:
        raise NewtonFailure(f"Newton did not converge to a periodic orbit with k = {ctx.k}: best residual "
                            f"{res:.3e} (needed <= {1e3 * rtol * scale:.1e}); history "
                            f"{', '.join(f'{h:.1e}' for h in hist)}", res, hist,
                            public_state(prob.system, prob.pars, x, spec))
    converged = res <= rtol * scale
    # the orbit's section points: k crossings from x (they also confirm the count)
    pub = public_state(prob.system, prob.pars, x, spec)
    if not float(T) > T_MIN:
        raise NewtonFailure(f"Newton converged to a zero return time (T = {float(T)!r}): the start point itself, "
                            f"not a periodic orbit", res, hist, pub)
    run = ctx.section.run(pub, n_points=ctx.k + 1, t_end=ctx.t_max)
    keep = [i for i, t in enumerate(run.times) if float(t) > T_MIN][: ctx.k]
    run_states = [run.states[i] for i in keep]
    run_times = [run.times[i] for i in keep]
    if len(run_times) < ctx.k:
        raise NewtonFailure(f"the solution does not cross the section {ctx.k} times", res, hist, pub)
    pts_int = np.vstack([np.asarray(x)[None, :], _internal_rows(prob, run_states[:-1])]) if ctx.k > 1 \
        else np.asarray(x)[None, :]
    points = chart_points(prob.kind, np.asarray(pts_int, dtype=object).astype(float))
    if abs(float(run_times[-1]) - float(T)) > 1e-6 * (1 + abs(float(T))):
        raise NewtonFailure(f"the Newton solution's k-th crossing (t = {float(T)!r}) is not the section's "
                            f"{ctx.k}-th crossing (t = {float(run_times[-1])!r}): no orbit with k = {ctx.k} here",
                            res, hist, pub)
    k_min = _minimal_k(points, ctx.k, ctx.symmetric, 1e-7)
    _, PP = _jacobian(ctx, x, theta, xT, Phi, geo0)
    A = _multiplier_matrix(ctx, x, theta, PP, geo0)
    lv = {n: float(v) for n, v in zip(geo0.names, geo0.c)}
    orbit = PeriodicOrbit(
        kind=prob.kind, state=pub, period=float(T), k=ctx.k, points=points, **multiplier_summary(A),
        residual=res, residual_history=tuple(hist),
        converged=bool(converged), symmetric=_symmetry_of(ctx, np.asarray(pts_int, dtype=object).astype(float), 1e-7),
        shift=float(theta), levels=lv, g0=ctx.g0, direction=ctx.direction, fp_type=str(spec),
        internal=np.asarray(x).copy(), problem=prob)
    if k_min < ctx.k:
        raise NewtonFailure(f"the orbit found closes after {k_min} crossings, not k = {ctx.k}: ask for "
                            f"k = {k_min}", res, hist, pub)
    return orbit


def _internal_rows(prob: Problem, states) -> np.ndarray:
    return np.vstack([start_state(prob, s, project_state=True) for s in states])


def refine(orbit: PeriodicOrbit, fp_types: Sequence[Union[FpTypeLike, Tuple[FpTypeLike, int]]] = (np.longdouble, "real128"),
           *, max_iter: int = 8, levels: LevelsLike = None) -> List[PeriodicOrbit]:
    """The orbit solved again in each number type of ``fp_types`` (each started from the
    previous one), with ``digits``: correct decimal digits of each but the last, from the
    largest difference to the next (relative to ``max(1, |x|)``).

    Parameters
    ----------
    orbit : PeriodicOrbit
    fp_types : sequence
        Number types in increasing precision: ``numpy.longdouble``, ``"real128"``, and MPFR
        as ``("real", prec)`` (``heyoka.real`` with ``prec`` bits, compact mode).
    max_iter : int
        Newton iterations per type (the float64 Jacobian makes each a quasi-Newton step that
        gains ~13 digits; two or three suffice).
    levels : Levels, MParallelLevels or dict, optional
        The exact level for every solution (``orbit`` on it to 1e-9); default ``orbit.levels``,
        its float64 integrals (off the level it was solved for by its residual, ~1e-14).

    Returns
    -------
    list of PeriodicOrbit
        ``[orbit, refined in fp_types[0], ...]``, every one with ``digits`` filled in.
    """
    out = [orbit]
    prob0 = orbit.problem
    for ft in fp_types:
        if isinstance(ft, tuple):
            if len(ft) != 2:
                raise UsageError(f"an MPFR number type is given as (\"real\", prec), got {ft!r}")
            spec = resolve_fp_type(ft[0], ft[1])
        else:
            spec = resolve_fp_type(ft)
        prob = prob0.replace(spec=spec, tol=None)
        prev = out[-1]
        x0 = spec.array(np.asarray(prev.internal))
        geo = _eval_geo(prob, prev.g0, x0)
        names = geo.names
        exact = _level_targets(prob, names, levels)  # {} without levels: the float64 orbit's
        for n in (n for n in exact if not abs(orbit.levels[n] - exact[n]) <= 1e-9 * max(1.0, abs(exact[n]))):  # NaN too
            raise StateError(f"orbit is off the level {levels!r}: its {n} is {orbit.levels[n]!r}")
        if prob0.kind == "reduced":
            exact.update(gamma2=1.0, R_gamma=0.0)
        targets = spec.array([exact.get(n, prev.levels[n]) for n in names])
        ctx = _Ctx(prob, prev.g0, prev.direction, prev.k, targets, _has_axial_symmetry(prob), 1e4)
        out.append(_solve(ctx, x0, prev.shift, max_iter=max_iter, rtol=256 * spec.eps,
                          T_guess=spec.scalar(prev.period)))
    final = []
    for i, o in enumerate(out):
        digits: Dict[str, float] = {}
        if i + 1 < len(out):
            a = np.asarray(o.internal, dtype=object).astype(float)
            d = np.asarray(out[i + 1].internal - out[i + 1].problem.spec.array(o.internal), dtype=object).astype(float)
            err = float(np.max(np.abs(d))) / max(1.0, float(np.max(np.abs(a))))
            digits[o.fp_type] = float(-math.log10(err)) if err > 0 else float("inf")
        final.append(replace(o, digits=digits or None))
    return final
