r"""The paper's three systems as backend-neutral formulas and heyoka expression graphs.

Notation (all vectors in the body frame, paper section 1):

* ``omega`` angular velocity, ``gamma`` upward normal of the plane, ``alpha``, ``beta`` the
  other fixed axes, ``(x, y)`` the centre's position in the fixed frame,
  ``R = x alpha + y beta`` the same in body axes;
* ``J = I + d E``, ``d = m a^2``, ``A = J^{-1} = diag(a_i)``, ``a_i = 1/(I_i + d)``;
* ``Itilde = J - d gamma gamma^T``, the inertia tensor about the contact point (paper sec. 3,
  Itilde, with ``gamma^2 = 1``);
* ``M = Itilde omega - m a Omega R`` the angular momentum (paper eq. (11) [eq13]), constant in space;
* ``K = M + m a Omega R = Itilde omega``; in the M||gamma case (section 5),
  ``K = lambda gamma + m a Omega R``.

Formulations
------------
The public state layouts are in the paper's variables (``omega``, ...). Internally each
system is integrated in the variables where its equations are simplest:

* ``"momentum"`` (default for ``full`` and ``reduced``): ``M`` instead of ``omega``, with
  ``dM/dt = M x omega`` (section 2) and ``omega = Itilde^{-1} K`` solved in closed form by
  Sherman--Morrison,

  .. math:: \omega = A K + \frac{d\,(\gamma, A K)}{1 - d\,(\gamma, A\gamma)}\, A\gamma ,

  which is also paper eq. (19) [sved].
* ``"omega"``: paper eqs. (8) [eq6] / (15) [eq10] literally, ``Itilde domega/dt = I omega x omega
  - m a Omega (omega, gamma) R x gamma - m a Omega (dR/dt x gamma) x gamma``.

``benchmarks/bench_formulation.py`` measures both; the momentum form takes fewer steps and
conserves ``|M|^2`` and ``(M, gamma)`` better (see ``docs/design.md``).

Nothing here integrates; :mod:`taylorball._propagate` compiles these graphs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import math

from ._vec import add, cross, dot, norm2, scale, sqrt, sub
from .errors import ConstraintError, ParameterError, UsageError
from ._typing import KindName, ParamsLike, Scalar, Vec3, VecLike
from .params import BallParams, MParallelParams

__all__ = [
    "KINDS",
    "Kind",
    "KIND_TABLE",
    "PUBLIC_NAMES",
    "System",
    "get_system",
    "ball_constants",
    "mparallel_constants",
    "omega_from_K",
    "K_from_omega",
]

KINDS: Tuple[KindName, ...] = ("full", "reduced", "mparallel")

_v3 = lambda s: tuple(f"{s}{i}" for i in (1, 2, 3))  # noqa: E731

#: Public state layouts, in the paper's variables.
PUBLIC_NAMES: Dict[str, Tuple[str, ...]] = {
    "full": (*_v3("omega"), *_v3("alpha"), *_v3("beta"), *_v3("gamma"), "x", "y"),
    "reduced": (*_v3("omega"), *_v3("gamma"), *_v3("R")),
    "mparallel": (*_v3("K"), *_v3("gamma")),
}


# ---------------------------------------------------------------------------------------
# Constants formed from the runtime parameters, in the working backend/precision.
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BallConstants:
    """Derived constants of a ball, as backend scalars (see :func:`ball_constants`)."""

    I: Vec3
    A: Vec3
    d: Scalar
    m: Scalar
    a: Scalar
    ma: Scalar
    Omega: Scalar


@dataclass(frozen=True)
class MParallelConstants:
    """Constants of the M||gamma system (see :func:`mparallel_constants`)."""

    A: Vec3
    d: Scalar
    Omega: Scalar


def ball_constants(pars: Sequence[Scalar]) -> BallConstants:
    """Constants from ``pars = (I1, I2, I3, m, a, Omega)`` (any backend).

    ``a_i = 1/(I_i + m a^2)`` are formed here, so they are exact to the working precision
    instead of being rounded to float64 by the caller."""
    i1, i2, i3, m, a, om = pars
    d = m * a * a
    return BallConstants(
        I=(i1, i2, i3), A=(1 / (i1 + d), 1 / (i2 + d), 1 / (i3 + d)), d=d, m=m, a=a, ma=m * a, Omega=om
    )


def mparallel_constants(pars: Sequence[Scalar]) -> MParallelConstants:
    """Constants from ``pars = (a1, a2, a3, d, Omega)``."""
    a1, a2, a3, d, om = pars
    return MParallelConstants(A=(a1, a2, a3), d=d, Omega=om)


def _diag(A, v):
    return (A[0] * v[0], A[1] * v[1], A[2] * v[2])


def omega_from_K(A: VecLike, d: Scalar, gamma: VecLike, K: VecLike) -> Vec3:
    r"""Solve ``Itilde omega = K`` for ``omega`` (Sherman--Morrison, paper eq. (19) [sved]).

    .. math:: \omega = A K + \frac{d (\gamma, A K)}{1 - d (\gamma, A \gamma)} A \gamma"""
    AK = _diag(A, K)
    Ag = _diag(A, gamma)
    coef = d * dot(gamma, AK) / (1 - d * dot(gamma, Ag))
    return add(AK, scale(coef, Ag))


def K_from_omega(I: VecLike, d: Scalar, gamma: VecLike, omega: VecLike) -> Vec3:
    r"""``Itilde omega = I omega + d (omega - gamma (gamma, omega))`` (|gamma| = 1)."""
    g_w = dot(gamma, omega)
    k1, k2, k3 = (I[k] * omega[k] + d * (omega[k] - gamma[k] * g_w) for k in range(3))
    return (k1, k2, k3)


# ---------------------------------------------------------------------------------------
# Vector fields, on tuples of backend scalars.
# ---------------------------------------------------------------------------------------
def _R_dot(c, omega, gamma, R):
    """Paper eq. (16) [eq10]: ``dR/dt = R x (omega - Omega gamma) - a gamma x omega``."""
    return sub(cross(R, sub(omega, scale(c.Omega, gamma))), scale(c.a, cross(gamma, omega)))


def _omega_dot_paper(c, omega, gamma, R, R_dot):
    """Paper eqs. (8) [eq6] / (15) [eq10] solved for ``domega/dt`` with the Sherman--Morrison
    inverse of Itilde."""
    Iw = _diag(c.I, omega)
    rhs = sub(
        sub(cross(Iw, omega), scale(c.ma * c.Omega * dot(omega, gamma), cross(R, gamma))),
        scale(c.ma * c.Omega, cross(cross(R_dot, gamma), gamma)),
    )
    return omega_from_K(c.A, c.d, gamma, rhs)


def reduced_rhs(c, M, gamma, R):
    """Reduced system, momentum form: ``(dM/dt, dgamma/dt, dR/dt)``."""
    omega = omega_from_K(c.A, c.d, gamma, add(M, scale(c.ma * c.Omega, R)))
    return (cross(M, omega), cross(gamma, omega), _R_dot(c, omega, gamma, R))


def reduced_rhs_omega(c, omega, gamma, R):
    """Reduced system, paper eqs. (15)-(16) [eq10]: ``(domega/dt, dgamma/dt, dR/dt)``."""
    R_dot = _R_dot(c, omega, gamma, R)
    return (_omega_dot_paper(c, omega, gamma, R, R_dot), cross(gamma, omega), R_dot)


def _xy_dot(c, omega, alpha, beta, x, y):
    """Paper eq. (10) [eq6]: ``dx/dt = -Omega y + a (omega, beta)``,
    ``dy/dt = Omega x - a (omega, alpha)``."""
    return (-c.Omega * y + c.a * dot(omega, beta), c.Omega * x - c.a * dot(omega, alpha))


def full_rhs(c, M, alpha, beta, gamma, x, y):
    """Full system, momentum form: ``(dM, dalpha, dbeta, dgamma, dx, dy)``."""
    R = add(scale(x, alpha), scale(y, beta))
    omega = omega_from_K(c.A, c.d, gamma, add(M, scale(c.ma * c.Omega, R)))
    return (
        cross(M, omega),
        cross(alpha, omega),
        cross(beta, omega),
        cross(gamma, omega),
        *_xy_dot(c, omega, alpha, beta, x, y),
    )


def full_rhs_omega(c, omega, alpha, beta, gamma, x, y):
    """Full system, paper eqs. (8)-(10) [eq6] literally."""
    R = add(scale(x, alpha), scale(y, beta))
    xd, yd = _xy_dot(c, omega, alpha, beta, x, y)
    R_dot = add(scale(xd, alpha), scale(yd, beta), cross(R, omega))
    return (
        _omega_dot_paper(c, omega, gamma, R, R_dot),
        cross(alpha, omega),
        cross(beta, omega),
        cross(gamma, omega),
        xd,
        yd,
    )


def mparallel_omega(c, K, gamma):
    """Paper eq. (19) [sved]: angular velocity of the M||gamma system."""
    return omega_from_K(c.A, c.d, gamma, K)


def mparallel_rhs(c, K, gamma):
    """Paper eq. (22) [Mpn2]: ``dK/dt = Omega gamma x K + (K - d Omega gamma) x omega``,
    ``dgamma/dt = gamma x omega``."""
    omega = mparallel_omega(c, K, gamma)
    K_dot = add(scale(c.Omega, cross(gamma, K)), cross(sub(K, scale(c.d * c.Omega, gamma)), omega))
    return (K_dot, cross(gamma, omega))


# ---------------------------------------------------------------------------------------
# What each system knows besides its vector field: named vectors of a state, first
# integrals and their scales (sections 2, 3, 5), the invariant density, the constraint
# manifold, the section chart and its levels (section 4/5). Every formula is written once,
# on tuples of backend scalars (see taylorball._vec); taylorball._integrals,
# taylorball.manifold and taylorball.sections evaluate them.
# ---------------------------------------------------------------------------------------
def _abs(x):
    # heyoka has no abs(); sqrt(x^2) is |x| (its derivative at 0 is never needed here).
    return sqrt(x * x) if _is_expr(x) else abs(x)


def _is_expr(x):
    return (type(x).__module__ or "").startswith("heyoka") and type(x).__name__ == "expression"


def _D(c, gamma):
    """``D = 1 - d (gamma, A gamma)``."""
    return 1 - c.d * dot(gamma, _diag(c.A, gamma))


def _norm(u):
    return sqrt(norm2(u))


# -- named vectors of an internal state ----------------------------------------------------
def _full_vectors(system, c, s) -> Dict[str, Any]:
    """Vectors of a full state: ``omega, M, K, alpha, beta, gamma, x, y, R``."""
    v: Dict[str, Any] = {}
    v["alpha"], v["beta"], v["gamma"] = s[3:6], s[6:9], s[9:12]
    v["x"], v["y"] = s[12], s[13]
    v["R"] = add(scale(v["x"], v["alpha"]), scale(v["y"], v["beta"]))
    return _ball_momenta(system, c, s, v)


def _reduced_vectors(system, c, s) -> Dict[str, Any]:
    """Vectors of a reduced state: ``omega, M, K, gamma, R``."""
    v: Dict[str, Any] = {}
    v["gamma"], v["R"] = s[3:6], s[6:9]
    return _ball_momenta(system, c, s, v)


def _ball_momenta(system, c, s, v):
    """Adds ``M``, ``K``, ``omega`` to the vectors ``v`` of a ball's state ``s``."""
    maOR = scale(c.ma * c.Omega, v["R"])
    if system.formulation == "momentum":
        v["M"] = s[0:3]
        v["K"] = add(v["M"], maOR)
        v["omega"] = omega_from_K(c.A, c.d, v["gamma"], v["K"])
    else:
        v["omega"] = s[0:3]
        v["K"] = K_from_omega(c.I, c.d, v["gamma"], v["omega"])
        v["M"] = tuple(k - r for k, r in zip(v["K"], maOR))
    return v


def _mparallel_vectors(system, c, s) -> Dict[str, Any]:
    K, gamma = s[0:3], s[3:6]
    return {"K": K, "gamma": gamma, "omega": omega_from_K(c.A, c.d, gamma, K)}


# -- first integrals (full: paper eqs. (12) [eq7], (13) [eq8]; reduced: sec. 3; mparallel: sec. 5)
def _full_integrals(c, v):
    M, g = v["M"], v["gamma"]
    E = dot(v["omega"], v["K"]) / 2 - c.m * c.Omega**2 * (v["x"] ** 2 + v["y"] ** 2) / 2
    return {"F1": dot(M, v["alpha"]), "F2": dot(M, v["beta"]), "F3": dot(M, g), "E": E}


def _reduced_integrals(c, v):
    M, R, g = v["M"], v["R"], v["gamma"]
    E = dot(v["omega"], v["K"]) / 2 - c.m * c.Omega**2 * norm2(R) / 2
    return {"C2": norm2(M), "M_gamma": dot(M, g), "E": E, "gamma2": norm2(g), "R_gamma": dot(R, g)}


def _mparallel_integrals(c, v):
    K, g = v["K"], v["gamma"]
    AK = _diag(c.A, K)
    return {
        "gamma2": norm2(g),
        "lambda": dot(K, g),
        "E": dot(K, AK) / 2 - norm2(K) / (2 * c.d) + c.d * dot(AK, g) ** 2 / (2 * _D(c, g)),
    }


# -- natural magnitude of each integral: a bound on the sum of magnitudes of its terms
#    (products of norms, by Cauchy--Schwarz), used to express drift relative to it --------
def _ball_energy_scale(c, v):
    return _norm(v["omega"]) * _norm(v["K"]) / 2 + _abs(c.m) * c.Omega**2 * norm2(v["R"]) / 2


def _full_scales(c, v):
    M, g, n = v["M"], v["gamma"], _norm
    return {"F1": n(M) * n(v["alpha"]), "F2": n(M) * n(v["beta"]), "F3": n(M) * n(g), "E": _ball_energy_scale(c, v)}


def _reduced_scales(c, v):
    M, R, g, n = v["M"], v["R"], v["gamma"], _norm
    return {"C2": norm2(M), "M_gamma": n(M) * n(g), "E": _ball_energy_scale(c, v), "gamma2": norm2(g),
            "R_gamma": n(R) * n(g)}


def _mparallel_scales(c, v):
    K, g, n = v["K"], v["gamma"], _norm
    AK = _diag(c.A, K)
    return {
        "gamma2": norm2(g),
        "lambda": n(K) * n(g),
        "E": n(K) * n(AK) / 2 + norm2(K) / (2 * c.d) + c.d * dot(AK, g) ** 2 / (2 * _abs(_D(c, g))),
    }


# -- geometric integrals: the values the constraints fix ------------------------------------
def _full_geometric(v):
    al, be, g = v["alpha"], v["beta"], v["gamma"]
    return {"alpha2": norm2(al), "beta2": norm2(be), "gamma2": norm2(g), "alpha_beta": dot(al, be),
            "beta_gamma": dot(be, g), "gamma_alpha": dot(g, al)}


def _reduced_geometric(v):
    return {"gamma2": norm2(v["gamma"]), "R_gamma": dot(v["R"], v["gamma"])}


def _mparallel_geometric(v):
    return {"gamma2": norm2(v["gamma"])}


# -- invariant density --------------------------------------------------------------------
def _internal_density(c, v):
    """``|D|^{-1/2}`` w.r.t. ``(M, ...)`` (full, reduced) and ``(K, gamma)`` (mparallel)."""
    return 1 / sqrt(_abs(_D(c, v["gamma"])))


def _ball_public_density(c, v):
    """W.r.t. the paper's ``(omega, ...)``: the Jacobian of ``omega -> M = Itilde omega -
    m a Omega R`` is ``det(Itilde) = det(J) D``, so ``rho = det(J) D |D|^{-1/2}``."""
    D = _D(c, v["gamma"])
    rho = 1 / sqrt(_abs(D))
    detJ = (c.I[0] + c.d) * (c.I[1] + c.d) * (c.I[2] + c.d)
    return detJ * D * rho


# -- constraint manifold, on the columns of public states ----------------------------------
def _full_constraints(c):
    a, b, g = c[3:6], c[6:9], c[9:12]
    return {
        "alpha2 - 1": norm2(a) - 1,
        "beta2 - 1": norm2(b) - 1,
        "gamma2 - 1": norm2(g) - 1,
        "(alpha, beta)": dot(a, b),
        "(beta, gamma)": dot(b, g),
        "(gamma, alpha)": dot(g, a),
    }


def _reduced_constraints(c):
    g, R = c[3:6], c[6:9]
    # relative to |R| for |R| >> 1, absolute for |R| << 1
    return {"gamma2 - 1": norm2(g) - 1, "(R, gamma)": dot(R, g) / (1 + sqrt(norm2(R)))}


def _mparallel_constraints(c):
    return {"gamma2 - 1": norm2(c[3:6]) - 1}


# -- the section chart (section 4: (l, r1, r2); section 5: (l, L/G)) and its levels --------
def _wrap_2pi(a):
    import numpy as np

    a = np.mod(np.asarray(a, dtype=float), 2 * math.pi)
    return np.where(a >= 2 * math.pi, 0.0, a)


def _reduced_chart(x):
    """``l = atan2(M1, M2)`` in ``[0, 2 pi)``, ``r1 = R1 gamma1 + R2 gamma2``,
    ``r2 = R1 gamma2 - R2 gamma1`` of internal (momentum) states ``x`` (n, 9)."""
    import numpy as np

    M, g, R = x[:, 0:3], x[:, 3:6], x[:, 6:9]
    l = _wrap_2pi(np.arctan2(M[:, 0], M[:, 1]))
    r1 = R[:, 0] * g[:, 0] + R[:, 1] * g[:, 1]
    r2 = R[:, 0] * g[:, 1] - R[:, 1] * g[:, 0]
    return np.column_stack([l, r1, r2])


def _mparallel_chart(x):
    """``l = atan2(K1, K2)`` in ``[0, 2 pi)``, ``L/G = K3/|K|`` of states ``x`` (n, 6)."""
    import numpy as np

    K = x[:, 0:3]
    l = _wrap_2pi(np.arctan2(K[:, 0], K[:, 1]))
    return np.column_stack([l, K[:, 2] / np.sqrt(np.sum(K * K, axis=1))])


def _reduced_levels(ints):
    return {"C": math.sqrt(float(ints["C2"])), "M_gamma": float(ints["M_gamma"]), "h": float(ints["E"])}


def _mparallel_levels(ints):
    return {"lambda": float(ints["lambda"]), "h": float(ints["E"])}


# -- projection onto the constraint manifold, on the columns of public states -------------
def _unit(v):
    import numpy as np

    n = sqrt(norm2(v))
    if np.any(np.asarray(n, dtype=float) == 0.0):
        raise ConstraintError("cannot project: a vector that must be normalised (gamma or alpha) is zero")
    return scale(1 / n, v)


def _frame_det(c):
    """``det Q`` of the frame ``(alpha, beta, gamma)`` of full states (columns ``c``)."""
    return dot(cross(c[3:6], c[6:9]), c[9:12])


def _full_project(c):
    """Gram--Schmidt from ``gamma`` (the contact normal keeps its direction exactly):
    ``alpha <- unit(alpha - (alpha, gamma) gamma)``, ``beta <- gamma x alpha``."""
    import numpy as np

    if np.any(np.asarray(_frame_det(c), dtype=float) <= 0):
        raise ConstraintError("cannot project a left-handed (alpha, beta, gamma) onto SO(3) (det Q <= 0)")
    g = _unit(tuple(c[9:12]))
    al = _unit(sub(tuple(c[3:6]), scale(dot(tuple(c[3:6]), g), g)))
    be = cross(g, al)
    c[3:6], c[6:9], c[9:12] = al, be, g
    return c


def _reduced_project(c):
    """``gamma <- gamma/|gamma|``, then ``R <- R - (R, gamma) gamma``."""
    g = _unit(tuple(c[3:6]))
    c[3:6] = g
    R = tuple(c[6:9])
    c[6:9] = sub(R, scale(dot(R, g), g))
    return c


def _mparallel_project(c):
    """``gamma <- gamma/|gamma|``."""
    c[3:6] = _unit(tuple(c[3:6]))
    return c


# -- tangent constraints: project a tangent vector ``d`` (float64, in place) at internal
#    state ``x`` onto the tangent space of the constraints (first order), in order; each
#    reads its vectors off ``x`` in the kind's internal layout (the same in every formulation:
#    only the first three entries, omega or M, differ) ------------------------------------
def _unit64(v):
    import numpy as np

    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _tangent_unit_gamma(x, d):
    g = _unit64(x[3:6])
    d[3:6] -= (d[3:6] @ g) * g  # keep |gamma| = 1 to first order


def _tangent_R_orthogonal_to_gamma(x, d):
    import numpy as np

    g, R = _unit64(x[3:6]), np.asarray(x[6:9], dtype=float)
    # (R, gamma) = 0 to first order: (dR, gamma) + (R, dgamma) = 0
    d[6:9] -= ((d[6:9] @ g) + (R @ d[3:6])) * g


def _tangent_frame(x, d):
    """The frame ``Q = (alpha, beta, gamma)`` stays in SO(3) to first order: its tangent
    space is ``dv = xi x v`` (``v = alpha, beta, gamma``, one ``xi`` in R^3), 3 of the 9
    directions. The orthogonal projection of ``(dalpha, dbeta, dgamma)`` on it: the map
    ``xi -> (xi x v)_v`` has Gram matrix ``sum_v (|xi|^2 - (xi, v)^2) = 2 |xi|^2`` for an
    orthonormal frame and adjoint ``(dv)_v -> sum_v v x dv``, so ``xi = (1/2) sum_v v x dv``.
    Every Gram constraint ``(v_i, v_j)`` then has the derivative ``(xi, v_i x v_j) +
    (xi, v_j x v_i) = 0`` exactly, whatever the rounding of the frame."""
    import numpy as np

    vs = [np.asarray(x[k : k + 3], dtype=float) for k in (3, 6, 9)]
    xi = 0.5 * sum(np.cross(v, d[k : k + 3]) for v, k in zip(vs, (3, 6, 9)))
    for v, k in zip(vs, (3, 6, 9)):
        d[k : k + 3] = np.cross(xi, v)


def _reduced_gamma_R(rest):
    """``gamma`` and ``R`` from a reduced state without its first three entries."""
    return tuple(rest[0:3]), tuple(rest[3:6])


def _full_gamma_R(rest):
    """``gamma`` and ``R = x alpha + y beta`` from a full state without its first three entries."""
    alpha, beta, gamma = tuple(rest[0:3]), tuple(rest[3:6]), tuple(rest[6:9])
    x, y = rest[9], rest[10]
    return gamma, add(scale(x, alpha), scale(y, beta))


# ---------------------------------------------------------------------------------------
# Reduced -> full (section 3), and the contact point.
# ---------------------------------------------------------------------------------------
def lift_reduced(params, x, *, psi: float = 0.0):
    r"""The full state over reduced public state(s) ``x`` (``(9,)`` or ``(n, 9)``, already
    checked): projected onto the constraints in ``x``'s type, then the fixed frame with
    ``F1 = (M, alpha) = 0``, ``F2 > 0`` (rotated by ``psi`` about the vertical) and
    ``x = (alpha, R)``, ``y = (beta, R)``. :func:`taylorball.manifold.reduced_to_full` is
    the checked public form (its docstring has the formulas).

    Raises
    ------
    ChartError
        When ``M`` is parallel to ``gamma`` (``C^2 = M_gamma^2``): the frame is undefined.
    """
    import numpy as np

    from .errors import ChartError

    x = _project_array(REDUCED, x)
    system = _SYSTEMS[("reduced", "omega")]
    pars = tuple(np.asarray(params.pars, dtype=x.dtype))
    v = system.vectors(system.constants(pars), _array_cols(x))
    M, g, R = v["M"], v["gamma"], v["R"]
    # work with M / max|M_i| so that a tiny |M| (e.g. 1e-160) cannot underflow norm2(perp)
    # into subnormals, where sqrt(norm2) loses digits and beta comes out non-unit
    m_max = np.maximum(np.maximum(np.abs(M[0]), np.abs(M[1])), np.abs(M[2]))
    zero = np.asarray(m_max, dtype=float) == 0.0
    m_max = np.where(zero, x.dtype.type(1), m_max)
    Ms = tuple(Mi / m_max for Mi in M)
    perp = sub(Ms, scale(dot(Ms, g), g))
    s = sqrt(norm2(perp))
    bad = zero | (np.asarray(s, dtype=float) <= 1e-12 * np.asarray(sqrt(norm2(Ms)), dtype=float))
    if np.any(bad):
        where = f" (state {int(np.argmax(bad))} of the stack)" if x.ndim > 1 else ""
        raise ChartError(
            f"reduced_to_full: M is parallel to gamma (or zero){where}, so the fixed frame (alpha, beta) with "
            "F1 = 0 is undefined (C^2 = M_gamma^2); such states lie on the invariant set M || gamma of "
            "section 5, integrate them with kind='mparallel'"
        )
    be = scale(1 / s, perp)
    al = cross(be, g)
    if psi:
        cp, sp = math.cos(psi), math.sin(psi)
        al, be = add(scale(cp, al), scale(sp, be)), add(scale(-sp, al), scale(cp, be))
    out = np.empty(x.shape[:-1] + (14,), dtype=x.dtype)
    for i, val in enumerate((*_array_cols(x)[0:3], *al, *be, *g, dot(al, R), dot(be, R))):
        out[..., i] = val
    return out


def _array_cols(x):
    return tuple(x[..., i] for i in range(x.shape[-1]))


def _project_array(info, state):
    """``info.project`` on the columns of a numpy array of public states (a copy)."""
    import numpy as np

    x = np.array(state, copy=True)
    c = info.project(list(_array_cols(x)))
    out = np.empty_like(x)
    for i, v in enumerate(c):
        out[..., i] = v
    return out


def _full_contact(params, x):
    """The contact point ``(x, y)`` in the fixed frame: the last two entries of full states."""
    return x[..., 12:14]


def _reduced_contact(params, x):
    """The contact point ``(x, y) = ((alpha, R), (beta, R))`` of reduced states, in the
    frame of :func:`lift_reduced` (``psi = 0``)."""
    return lift_reduced(params, x)[..., 12:14]


@dataclass(frozen=True)
class Kind:
    """Everything one of the paper's systems knows that does not depend on its
    formulation: layout, parameters, integrals, density, constraints, section chart.

    A new system is one :class:`Kind` and its :class:`System` formulations; the rest of
    the package asks these, never ``kind == "..."``."""

    name: KindName
    public_names: Tuple[str, ...]
    n_pars: int
    default_formulation: str
    public_formulation: str
    integral_names: Tuple[str, ...]
    geometric_names: Tuple[str, ...]
    manifold_text: str
    vectors: Callable
    integrals: Callable
    scales: Callable
    geometric: Callable
    public_density: Callable
    constraints: Callable
    project: Callable
    params: Callable
    orientation: Optional[Callable] = None
    gamma_R: Optional[Callable] = None
    contact: Optional[Callable] = None
    chart: Optional[Callable] = None
    chart_names: Tuple[str, ...] = ()
    levels: Optional[Callable] = None
    tangent_constraints: Tuple[Callable, ...] = ()
    #: Integrated variables that can grow without bound (the contact point, which rolls away
    #: at Omega = 0); the others (momenta, frame) stay on a compact set. MEGNO/FLI with
    #: ``norm="compact"`` measure the tangent vector on the compact part only.
    unbounded_names: Tuple[str, ...] = ()


# ---------------------------------------------------------------------------------------
# Systems: variable layouts, conversions public <-> internal, heyoka graphs.
# ---------------------------------------------------------------------------------------
def _split(state, sizes):
    out, k = [], 0
    for n in sizes:
        out.append(tuple(state[k : k + n]) if n > 1 else state[k])
        k += n
    return out


@dataclass(frozen=True)
class System:
    """One system of the paper in one formulation.

    Attributes
    ----------
    info : Kind
        What the system knows whatever its formulation (layout, integrals, constraints,
        section chart).
    formulation : str
        ``"momentum"`` or ``"omega"`` (``"native"`` for mparallel, whose variables are
        the paper's).
    internal_names : tuple of str
        Names of the integrated variables, in order.
    """

    info: Kind
    formulation: str
    internal_names: Tuple[str, ...]
    _sizes: Tuple[int, ...]
    _rhs: Callable
    _constants: Callable

    @property
    def kind(self) -> KindName:
        """``"full"``, ``"reduced"`` or ``"mparallel"``."""
        return self.info.name

    @property
    def public_names(self) -> Tuple[str, ...]:
        return self.info.public_names

    @property
    def dim(self) -> int:
        return len(self.internal_names)

    @property
    def n_pars(self) -> int:
        return self.info.n_pars

    @property
    def compact_indices(self) -> Tuple[int, ...]:
        """Positions of the integrated variables on the compact part of the phase space (all
        but the kind's :attr:`Kind.unbounded_names`): ``(M, gamma)`` of the reduced system,
        ``(M, alpha, beta, gamma)`` of the full one, every variable of M||gamma."""
        return tuple(i for i, v in enumerate(self.internal_names) if v not in self.info.unbounded_names)

    def check_params(self, params: object) -> ParamsLike:
        """``params`` as this system takes them, or a :class:`ParameterError` naming the valid
        form: a ball's :class:`BallParams` for every kind (converted to its M||gamma
        parameters for ``"mparallel"``), :class:`MParallelParams` for ``"mparallel"`` only."""
        return self.info.params(params)

    def constants(self, pars: Sequence[Scalar]) -> Union[BallConstants, MParallelConstants]:
        """Derived constants from a parameter vector of backend scalars."""
        return self._constants(pars)

    def vectors(self, c: Union[BallConstants, MParallelConstants],
                internal: Sequence[Scalar]) -> Dict[str, Any]:
        """Named vectors of an internal state with constants ``c``: ``omega``, ``gamma``
        and, as applicable, ``M``, ``K`` (``Itilde omega`` for a ball; the state variable
        for mparallel), ``R``, ``alpha``, ``beta``, ``x``, ``y``."""
        return self.info.vectors(self, c, tuple(internal))

    def rhs(self, pars: Sequence[Scalar], state: Sequence[Scalar]) -> Tuple[Scalar, ...]:
        """Right-hand side on internal variables, as a flat tuple (any backend)."""
        c = self._constants(pars)
        parts = self._rhs(c, *_split(state, self._sizes))
        flat: List[Scalar] = []
        for p in parts:
            flat.extend(p if isinstance(p, tuple) else (p,))
        return tuple(flat)

    def equations(self) -> List[Tuple[Any, Any]]:
        """The system as heyoka ``(variable, rhs)`` pairs with parameters ``hy.par[i]``."""
        import heyoka as hy

        xs = hy.make_vars(*self.internal_names)
        pars = [hy.par[i] for i in range(self.n_pars)]
        return list(zip(xs, self.rhs(pars, xs)))

    # -- public <-> internal ----------------------------------------------------------
    def to_internal(self, pars: Sequence[Scalar], public: Sequence[Scalar]) -> Tuple[Scalar, ...]:
        """Internal variables from a public state (tuple of backend scalars)."""
        if self.formulation != "momentum":
            return tuple(public)
        c = self._constants(pars)
        omega = tuple(public[0:3])
        rest = tuple(public[3:])
        assert self.info.gamma_R is not None  # the momentum formulations are the balls', which have R
        gamma, R = self.info.gamma_R(rest)
        M = sub(K_from_omega(c.I, c.d, gamma, omega), scale(c.ma * c.Omega, R))
        return (*M, *rest)

    def to_public(self, pars: Sequence[Scalar], internal: Sequence[Scalar]) -> Tuple[Scalar, ...]:
        """Public state from internal variables (tuple of backend scalars)."""
        if self.formulation != "momentum":
            return tuple(internal)
        c = self._constants(pars)
        M = tuple(internal[0:3])
        rest = tuple(internal[3:])
        assert self.info.gamma_R is not None  # the momentum formulations are the balls', which have R
        gamma, R = self.info.gamma_R(rest)
        omega = omega_from_K(c.A, c.d, gamma, add(M, scale(c.ma * c.Omega, R)))
        return (*omega, *rest)


def _check_mparallel_params(params):
    if isinstance(params, BallParams):
        return params.to_mparallel()
    if isinstance(params, MParallelParams):
        return params
    raise ParameterError(
        f"params for kind='mparallel' must be MParallelParams(a=(a1, a2, a3), d=d, plane_rate=Omega) "
        f"or BallParams, got {params!r}"
    )


def _ball_params_check(kind):
    def check(params):
        if isinstance(params, BallParams):
            return params
        raise ParameterError(
            f"params for kind={kind!r} must be BallParams(inertia=(I1, I2, I3), mass=m, radius=a, "
            f"plane_rate=Omega), got {params!r}"
            + (
                "; MParallelParams describes only the M||gamma system (kind='mparallel')"
                if isinstance(params, MParallelParams)
                else ""
            )
        )

    return check


FULL = Kind(
    name="full", public_names=PUBLIC_NAMES["full"], n_pars=6,
    default_formulation="momentum", public_formulation="omega",
    integral_names=("F1", "F2", "F3", "E"),
    geometric_names=("alpha2", "beta2", "gamma2", "alpha_beta", "beta_gamma", "gamma_alpha"),
    manifold_text="(alpha, beta, gamma) orthonormal and right-handed",
    vectors=_full_vectors, integrals=_full_integrals, scales=_full_scales, geometric=_full_geometric,
    public_density=_ball_public_density, constraints=_full_constraints, project=_full_project,
    params=_ball_params_check("full"), orientation=_frame_det, gamma_R=_full_gamma_R, contact=_full_contact,
    tangent_constraints=(_tangent_frame,),
    unbounded_names=("x", "y"),
)
REDUCED = Kind(
    name="reduced", public_names=PUBLIC_NAMES["reduced"], n_pars=6,
    default_formulation="momentum", public_formulation="omega",
    integral_names=("C2", "M_gamma", "E", "gamma2", "R_gamma"),
    geometric_names=("gamma2", "R_gamma"),
    manifold_text="|gamma| = 1 and (R, gamma) = 0",
    vectors=_reduced_vectors, integrals=_reduced_integrals, scales=_reduced_scales, geometric=_reduced_geometric,
    public_density=_ball_public_density, constraints=_reduced_constraints, project=_reduced_project,
    params=_ball_params_check("reduced"), gamma_R=_reduced_gamma_R, contact=_reduced_contact,
    chart=_reduced_chart, chart_names=("l", "r1", "r2"), levels=_reduced_levels,
    tangent_constraints=(_tangent_unit_gamma, _tangent_R_orthogonal_to_gamma),
    unbounded_names=_v3("R"),
)
MPARALLEL = Kind(
    name="mparallel", public_names=PUBLIC_NAMES["mparallel"], n_pars=5,
    default_formulation="native", public_formulation="native",
    integral_names=("gamma2", "lambda", "E"),
    geometric_names=("gamma2",),
    manifold_text="|gamma| = 1",
    vectors=_mparallel_vectors, integrals=_mparallel_integrals, scales=_mparallel_scales,
    geometric=_mparallel_geometric, public_density=_internal_density, constraints=_mparallel_constraints,
    project=_mparallel_project, params=_check_mparallel_params,
    chart=_mparallel_chart, chart_names=("l", "L/G"), levels=_mparallel_levels,
    tangent_constraints=(_tangent_unit_gamma,),
)

_SYSTEMS = {
    ("reduced", "momentum"): System(
        REDUCED, "momentum", (*_v3("M"), *_v3("gamma"), *_v3("R")), (3, 3, 3), reduced_rhs, ball_constants
    ),
    ("reduced", "omega"): System(
        REDUCED, "omega", PUBLIC_NAMES["reduced"], (3, 3, 3), reduced_rhs_omega, ball_constants
    ),
    ("full", "momentum"): System(
        FULL,
        "momentum",
        (*_v3("M"), *PUBLIC_NAMES["full"][3:]),
        (3, 3, 3, 3, 1, 1),
        full_rhs,
        ball_constants,
    ),
    ("full", "omega"): System(
        FULL, "omega", PUBLIC_NAMES["full"], (3, 3, 3, 3, 1, 1), full_rhs_omega, ball_constants
    ),
    ("mparallel", "native"): System(
        MPARALLEL, "native", PUBLIC_NAMES["mparallel"], (3, 3), mparallel_rhs, mparallel_constants
    ),
}


#: The three systems, by name.
KIND_TABLE: Dict[str, Kind] = {k.name: k for k in (FULL, REDUCED, MPARALLEL)}


def public_system(kind: str) -> System:
    """The formulation whose internal variables are the public layout of ``kind`` (the
    paper's variables): ``"omega"`` for the balls, ``"native"`` for mparallel."""
    return get_system(kind, KIND_TABLE[kind].public_formulation if kind in KIND_TABLE else None)


def get_system(kind: str, formulation: str | None = None) -> System:
    """The :class:`System` for ``kind`` in ``formulation`` (default: the measured best).

    Raises
    ------
    UsageError
        For an unknown kind or formulation.
    """
    if not isinstance(kind, str) or kind not in KINDS:
        raise UsageError(f"kind must be one of {KINDS}, got {kind!r}")
    if formulation is not None and not isinstance(formulation, str):
        raise UsageError(f"formulation must be a string (e.g. 'momentum'), got {formulation!r}")
    formulation = formulation or KIND_TABLE[kind].default_formulation
    try:
        return _SYSTEMS[(kind, formulation)]
    except KeyError:
        valid = sorted(f for k, f in _SYSTEMS if k == kind)
        raise UsageError(
            f"formulation must be one of {valid} for kind={kind!r}, got {formulation!r}"
        ) from None

