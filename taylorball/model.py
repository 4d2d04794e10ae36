r"""The paper's three systems as backend-neutral formulas and heyoka expression graphs.

Notation (all vectors in the body frame, paper section 1):

* ``omega`` angular velocity, ``gamma`` upward normal of the plane, ``alpha``, ``beta`` the
  other fixed axes, ``(x, y)`` the centre's position in the fixed frame,
  ``R = x alpha + y beta`` the same in body axes;
* ``J = I + d E``, ``d = m a^2``, ``A = J^{-1} = diag(a_i)``, ``a_i = 1/(I_i + d)``;
* ``Itilde = J - d gamma gamma^T``, the inertia tensor about the contact point (eq. 10, with
  ``gamma^2 = 1``);
* ``M = Itilde omega - m a Omega R`` the angular momentum (eq. 13), constant in space;
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

  which is also the paper's eq. (sved).
* ``"omega"``: the paper's eq. (6) / (10) literally, ``Itilde domega/dt = I omega x omega
  - m a Omega (omega, gamma) R x gamma - m a Omega (dR/dt x gamma) x gamma``.

``benchmarks/bench_formulation.py`` measures both; the momentum form takes fewer steps and
conserves ``|M|^2`` and ``(M, gamma)`` better (see ``docs/design.md``).

Nothing here integrates; :mod:`taylorball.propagate` compiles these graphs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Dict, Sequence, Tuple

from ._vec import add, cross, dot, scale, sub
from .errors import ParameterError, UsageError
from .params import BallParams, MParallelParams

__all__ = [
    "KINDS",
    "PUBLIC_NAMES",
    "System",
    "get_system",
    "ball_constants",
    "mparallel_constants",
    "omega_from_K",
    "K_from_omega",
]

KINDS = ("full", "reduced", "mparallel")

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

    I: tuple
    A: tuple
    d: object
    m: object
    a: object
    ma: object
    Omega: object


@dataclass(frozen=True)
class MParallelConstants:
    """Constants of the M||gamma system (see :func:`mparallel_constants`)."""

    A: tuple
    d: object
    Omega: object


def ball_constants(pars: Sequence) -> BallConstants:
    """Constants from ``pars = (I1, I2, I3, m, a, Omega)`` (any backend).

    ``a_i = 1/(I_i + m a^2)`` are formed here, so they are exact to the working precision
    instead of being rounded to float64 by the caller."""
    i1, i2, i3, m, a, om = pars
    d = m * a * a
    return BallConstants(
        I=(i1, i2, i3), A=(1 / (i1 + d), 1 / (i2 + d), 1 / (i3 + d)), d=d, m=m, a=a, ma=m * a, Omega=om
    )


def mparallel_constants(pars: Sequence) -> MParallelConstants:
    """Constants from ``pars = (a1, a2, a3, d, Omega)``."""
    a1, a2, a3, d, om = pars
    return MParallelConstants(A=(a1, a2, a3), d=d, Omega=om)


def _diag(A, v):
    return (A[0] * v[0], A[1] * v[1], A[2] * v[2])


def omega_from_K(A, d, gamma, K):
    r"""Solve ``Itilde omega = K`` for ``omega`` (Sherman--Morrison, paper eq. sved).

    .. math:: \omega = A K + \frac{d (\gamma, A K)}{1 - d (\gamma, A \gamma)} A \gamma"""
    AK = _diag(A, K)
    Ag = _diag(A, gamma)
    coef = d * dot(gamma, AK) / (1 - d * dot(gamma, Ag))
    return add(AK, scale(coef, Ag))


def K_from_omega(I, d, gamma, omega):
    r"""``Itilde omega = I omega + d (omega - gamma (gamma, omega))`` (|gamma| = 1)."""
    g_w = dot(gamma, omega)
    return tuple(I[k] * omega[k] + d * (omega[k] - gamma[k] * g_w) for k in range(3))


# ---------------------------------------------------------------------------------------
# Vector fields, on tuples of backend scalars.
# ---------------------------------------------------------------------------------------
def _R_dot(c, omega, gamma, R):
    """Eq. (10): ``dR/dt = R x (omega - Omega gamma) - a gamma x omega``."""
    return sub(cross(R, sub(omega, scale(c.Omega, gamma))), scale(c.a, cross(gamma, omega)))


def _omega_dot_paper(c, omega, gamma, R, R_dot):
    """Eq. (6)/(10) solved for ``domega/dt`` with the Sherman--Morrison inverse of Itilde."""
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
    """Reduced system, the paper's eq. (10): ``(domega/dt, dgamma/dt, dR/dt)``."""
    R_dot = _R_dot(c, omega, gamma, R)
    return (_omega_dot_paper(c, omega, gamma, R, R_dot), cross(gamma, omega), R_dot)


def _xy_dot(c, omega, alpha, beta, x, y):
    """Eq. (6): ``dx/dt = -Omega y + a (omega, beta)``, ``dy/dt = Omega x - a (omega, alpha)``."""
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
    """Full system, the paper's eq. (6) literally."""
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
    """Eq. (sved): angular velocity of the M||gamma system."""
    return omega_from_K(c.A, c.d, gamma, K)


def mparallel_rhs(c, K, gamma):
    """Eq. (Mpn2): ``dK/dt = Omega gamma x K + (K - d Omega gamma) x omega``,
    ``dgamma/dt = gamma x omega``."""
    omega = mparallel_omega(c, K, gamma)
    K_dot = add(scale(c.Omega, cross(gamma, K)), cross(sub(K, scale(c.d * c.Omega, gamma)), omega))
    return (K_dot, cross(gamma, omega))


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
    kind : str
        ``"full"``, ``"reduced"`` or ``"mparallel"``.
    formulation : str
        ``"momentum"`` or ``"omega"`` (``"native"`` for mparallel, whose variables are
        the paper's).
    internal_names : tuple of str
        Names of the integrated variables, in order.
    """

    kind: str
    formulation: str
    internal_names: Tuple[str, ...]
    _sizes: Tuple[int, ...]
    _rhs: Callable
    _constants: Callable

    @property
    def public_names(self) -> Tuple[str, ...]:
        return PUBLIC_NAMES[self.kind]

    @property
    def dim(self) -> int:
        return len(self.internal_names)

    @property
    def n_pars(self) -> int:
        return 5 if self.kind == "mparallel" else 6

    def check_params(self, params):
        """``params`` as this system takes them, or a :class:`ParameterError` naming the valid
        form: a ball's :class:`BallParams` for every kind (converted to its M||gamma
        parameters for ``"mparallel"``), :class:`MParallelParams` for ``"mparallel"`` only."""
        return _check_params(self.kind, params)

    def constants(self, pars):
        """Derived constants from a parameter vector of backend scalars."""
        return self._constants(pars)

    def rhs(self, pars, state):
        """Right-hand side on internal variables, as a flat tuple (any backend)."""
        c = self._constants(pars)
        parts = self._rhs(c, *_split(state, self._sizes))
        flat = []
        for p in parts:
            flat.extend(p if isinstance(p, tuple) else (p,))
        return tuple(flat)

    def equations(self):
        """The system as heyoka ``(variable, rhs)`` pairs with parameters ``hy.par[i]``."""
        import heyoka as hy

        xs = hy.make_vars(*self.internal_names)
        pars = [hy.par[i] for i in range(self.n_pars)]
        return list(zip(xs, self.rhs(pars, xs)))

    # -- public <-> internal ----------------------------------------------------------
    def to_internal(self, pars, public):
        """Internal variables from a public state (tuple of backend scalars)."""
        if self.formulation != "momentum":
            return tuple(public)
        c = self._constants(pars)
        omega = tuple(public[0:3])
        rest = tuple(public[3:])
        gamma, R = _gamma_R(self.kind, rest)
        M = sub(K_from_omega(c.I, c.d, gamma, omega), scale(c.ma * c.Omega, R))
        return (*M, *rest)

    def to_public(self, pars, internal):
        """Public state from internal variables (tuple of backend scalars)."""
        if self.formulation != "momentum":
            return tuple(internal)
        c = self._constants(pars)
        M = tuple(internal[0:3])
        rest = tuple(internal[3:])
        gamma, R = _gamma_R(self.kind, rest)
        omega = omega_from_K(c.A, c.d, gamma, add(M, scale(c.ma * c.Omega, R)))
        return (*omega, *rest)


def _check_params(kind, params):
    if kind == "mparallel":
        if isinstance(params, BallParams):
            return params.to_mparallel()
        if isinstance(params, MParallelParams):
            return params
        raise ParameterError(
            f"params for kind='mparallel' must be MParallelParams(a=(a1, a2, a3), d=d, plane_rate=Omega) "
            f"or BallParams, got {params!r}"
        )
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


def _gamma_R(kind, rest):
    """``gamma`` and ``R`` from the non-angular-velocity part of a full/reduced state."""
    if kind == "reduced":
        return tuple(rest[0:3]), tuple(rest[3:6])
    alpha, beta, gamma = tuple(rest[0:3]), tuple(rest[3:6]), tuple(rest[6:9])
    x, y = rest[9], rest[10]
    return gamma, add(scale(x, alpha), scale(y, beta))


_SYSTEMS = {
    ("reduced", "momentum"): System(
        "reduced", "momentum", (*_v3("M"), *_v3("gamma"), *_v3("R")), (3, 3, 3), reduced_rhs, ball_constants
    ),
    ("reduced", "omega"): System(
        "reduced", "omega", PUBLIC_NAMES["reduced"], (3, 3, 3), reduced_rhs_omega, ball_constants
    ),
    ("full", "momentum"): System(
        "full",
        "momentum",
        (*_v3("M"), *PUBLIC_NAMES["full"][3:]),
        (3, 3, 3, 3, 1, 1),
        full_rhs,
        ball_constants,
    ),
    ("full", "omega"): System(
        "full", "omega", PUBLIC_NAMES["full"], (3, 3, 3, 3, 1, 1), full_rhs_omega, ball_constants
    ),
    ("mparallel", "native"): System(
        "mparallel", "native", PUBLIC_NAMES["mparallel"], (3, 3), mparallel_rhs, mparallel_constants
    ),
}

DEFAULT_FORMULATION = {"full": "momentum", "reduced": "momentum", "mparallel": "native"}


def get_system(kind: str, formulation: str | None = None) -> System:
    """The :class:`System` for ``kind`` in ``formulation`` (default: the measured best).

    Raises
    ------
    UsageError
        For an unknown kind or formulation.
    """
    if kind not in KINDS:
        raise UsageError(f"kind must be one of {KINDS}, got {kind!r}")
    formulation = formulation or DEFAULT_FORMULATION[kind]
    try:
        return _SYSTEMS[(kind, formulation)]
    except KeyError:
        valid = sorted(f for k, f in _SYSTEMS if k == kind)
        raise UsageError(
            f"formulation must be one of {valid} for kind={kind!r}, got {formulation!r}"
        ) from None
