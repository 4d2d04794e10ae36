r"""Invariant measures checked along trajectories: the Liouville relation.

If ``rho`` is the density of an invariant measure of ``x' = X(x)``, i.e.
``div(rho X) = 0``, then along every solution, with ``Phi(t) = dx(t)/dx(0)`` the
fundamental matrix of the variational equations ``Phi' = DX(x(t)) Phi``, ``Phi(0) = E``,

.. math:: \rho(x(t)) \det \Phi(t) = \rho(x(0)),

because ``d/dt ln det Phi = div X`` (Liouville's formula) and
``d/dt ln rho(x(t)) = X . grad ln rho = -div X``. :func:`liouville_residual` integrates the
system together with its variational equations (:class:`taylorball.tangent.TangentSystem`
with ``vectors="all"``: ``hy.var_ode_sys``, order 1, compact mode) and returns
``|rho(x(t)) det Phi(t) / rho(x(0)) - 1|``. The determinant and the densities are
evaluated in mpmath with more digits than the working type, so the residual measures the
integration error of ``x`` and ``Phi`` only.

Densities, with ``J = I + m a^2 E``, ``A = J^{-1}``, ``D = 1 - m a^2 (gamma, A gamma)`` and
``Itilde = J - m a^2 gamma (x) gamma``:

================  =====================  ==============================================
kind              variables              ``density="paper"``
================  =====================  ==============================================
full              omega form (default)   ``det(Itilde) / sqrt|D|``, the paper's (sec. 2)
full              momentum form          ``|D|^{-1/2}`` (``omega -> M`` has Jacobian
                                         ``det Itilde``)
reduced           omega form (default)   ``det(Itilde) / sqrt|D|`` (not printed in the
                                         paper; derived, see ``taylorball verify``)
reduced           momentum form          ``|D|^{-1/2}``
mparallel         ``(K, gamma)``         ``|D|^{-1/2}`` with ``D = 1 - d (gamma, A gamma)``
                                         (sec. 5)
================  =====================  ==============================================

``density="one"`` (Lebesgue measure, not invariant) shows what a wrong density gives.
The full system's flow is integrated in the ambient ``R^14`` (``R^9`` for the reduced
one); its divergence involves only derivatives along the constraint manifold, so the
relation holds for the ambient ``Phi``.

Expected size of the residual: each column of ``Phi`` is a tangent vector integrated with
the same per-step relative error ``~ eps`` as the state; random-walk accumulation over
``N`` steps gives ``~ eps sqrt(N)`` per entry and, through ``det``, about
``n eps sqrt(N) kappa`` (``n`` the dimension, ``kappa`` a condition factor of ``Phi`` that
stays O(1)--O(10^2) on the short orbits used here).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Literal, Optional

import numpy as np
from numpy.typing import ArrayLike

from .._typing import FpTypeLike, KindName, ParamsLike, Scalar, VecLike
from ..errors import UsageError

__all__ = ["LiouvilleResult", "liouville", "liouville_residual", "density_mp", "DENSITIES"]

DENSITIES = ("paper", "one")

@dataclass(frozen=True)
class LiouvilleResult:
    """Outcome of :func:`liouville`.

    Attributes
    ----------
    residual : float
        ``|rho(x(t)) det Phi(t) / rho(x(0)) - 1|``.
    det_phi : float
        ``det Phi(t)``.
    rho_ratio : float
        ``rho(x(0)) / rho(x(t))`` (what ``det Phi`` must equal).
    n_steps : int
        Taylor steps taken.
    cond : float
        2-norm condition number of ``Phi(t)`` (float64 estimate): the amplification of
        entry-wise errors of ``Phi`` into its determinant.
    eps : float
        Machine epsilon of the working type.
    kind, formulation, density, fp_type : str
        What was run.
    """

    residual: float
    det_phi: float
    rho_ratio: float
    n_steps: int
    cond: float
    eps: float
    kind: str
    formulation: str
    density: str
    fp_type: str


def _mp(x):
    """``x`` as an mpmath number, exactly for float64, long double and real128 (at least 64
    bits of working precision): a decimal string of a long double is only its shortest
    round-trip form, up to half an ulp off, which the density's condition (``~10`` at the
    Fig. 4 states) would turn into a few eps of the reference's error."""
    import mpmath

    from ..closed_forms import _to_mpf

    return _to_mpf(x, mpmath)


def density_mp(kind: KindName, formulation: str, pars: VecLike, internal: VecLike,
               density: Literal["paper", "one"] = "paper") -> Scalar:
    """The density of the table above at an internal state, in mpmath (current precision).

    Written from the paper's formulas (``det`` of the 3x3 matrix ``Itilde`` literally),
    independently of :func:`taylorball._integrals.density`.

    Parameters
    ----------
    pars : sequence
        ``(I1, I2, I3, m, a, Omega)`` or, for ``"mparallel"``, ``(a1, a2, a3, d, Omega)``.
    internal : sequence
        Internal variables of the system (``get_system(kind, formulation).internal_names``).
    """
    import mpmath

    if density == "one":
        return mpmath.mpf(1)
    if density != "paper":
        raise UsageError(f"density must be one of {DENSITIES}, got {density!r}")
    p = [_mp(v) for v in pars]
    x = [_mp(v) for v in internal]
    if kind == "mparallel":
        A, d = p[0:3], p[3]
        g = x[3:6]
        return 1 / mpmath.sqrt(abs(1 - d * sum(A[k] * g[k] ** 2 for k in range(3))))
    d = p[3] * p[4] ** 2
    J = [p[k] + d for k in range(3)]
    g = x[9:12] if kind == "full" else x[3:6]
    D = 1 - d * sum(g[k] ** 2 / J[k] for k in range(3))
    rho = 1 / mpmath.sqrt(abs(D))
    if formulation == "momentum":
        return rho
    It = mpmath.matrix([[(J[i] if i == j else 0) - d * g[i] * g[j] for j in range(3)] for i in range(3)])
    return mpmath.det(It) * rho


def liouville(kind: KindName, params: ParamsLike, state: ArrayLike, t: float, *,
              density: Literal["paper", "one"] = "paper", formulation: Optional[str] = None,
              fp_type: FpTypeLike = float, prec: Optional[int] = None,
              tol: Optional[float] = None) -> LiouvilleResult:
    """Integrate ``kind`` with its variational equations and test ``rho(x(t)) det Phi(t) = rho(x(0))``.

    Parameters
    ----------
    kind : {"full", "reduced", "mparallel"}
    params : BallParams or MParallelParams
    state : array_like
        Initial state in the public layout (projected onto the constraints in the working
        precision).
    t : float
        Final time (> 0).
    density : {"paper", "one"}
        The invariant density (see the module table) or the Lebesgue measure.
    formulation : {"omega", "momentum"}, optional
        Integration variables of the full and reduced systems; default ``"omega"``, the
        paper's variables, in which the paper's density is written.
    fp_type, prec, tol
        Number type (float, numpy.longdouble, heyoka.real128, heyoka.real + prec) and
        integrator tolerance (default: its epsilon). Always compiled in compact mode.

    Returns
    -------
    LiouvilleResult

    Raises
    ------
    UsageError
        Unknown kind, formulation or density, or ``t <= 0``.
    IntegrationError
        If the integrator stops early.
    """
    import mpmath

    from ..model import public_system
    from .._problem import problem
    from .._propagate import _check_outcome, start_state
    from ..tangent import TangentSystem

    if density not in DENSITIES:
        raise UsageError(f"density must be one of {DENSITIES}, got {density!r}")
    if formulation is None:  # the paper's variables
        formulation = public_system(kind).formulation
    try:
        tf = float(t)
    except (TypeError, ValueError):
        raise UsageError(f"t must be a positive number, got {t!r}") from None
    if not tf > 0:
        raise UsageError(f"t must be > 0, got {t!r}")
    prob = problem(kind, params, fp_type=fp_type, prec=prec, tol=tol, formulation=formulation)
    spec = prob.spec
    system, pars, internal = prob.system, prob.pars, start_state(prob, state)
    ts = TangentSystem.of(prob, "all")
    ta = copy.copy(ts.template(prob, compact_mode=True))  # var systems: minutes to compile otherwise
    ta.state[ts.x] = internal
    ta.state[ts.tangents] = ts.identity(spec)
    ta.pars[:] = pars
    ta.time = spec.scalar(0.0)
    res = ta.propagate_until(spec.scalar(t))
    _check_outcome(ta, res, t)
    dps = int(spec.digits * 0.30103) + 15
    with mpmath.workdps(dps):
        phi = mpmath.matrix([[_mp(v) for v in row] for row in ts.tangent_matrix(ta.state)])
        det = mpmath.det(phi)
        r0 = density_mp(kind, system.formulation, pars, internal, density)
        r1 = density_mp(kind, system.formulation, pars, ta.state[ts.x], density)
        residual = abs(r1 * det / r0 - 1)
        cond = float(np.linalg.cond(np.array(phi.tolist(), dtype=float)))
        return LiouvilleResult(residual=float(residual), det_phi=float(det), rho_ratio=float(r0 / r1),
                               n_steps=int(res[3]), cond=cond, eps=spec.eps, kind=kind, formulation=system.formulation,
                               density=density, fp_type=str(spec))


def liouville_residual(kind: KindName, params: ParamsLike, state: ArrayLike, t: float, *,
                       density: Literal["paper", "one"] = "paper", fp_type: FpTypeLike = float,
                       prec: Optional[int] = None, formulation: Optional[str] = None,
                       tol: Optional[float] = None) -> float:
    """``|rho(x(t)) det Phi(t) / rho(x(0)) - 1|`` (see :func:`liouville`)."""
    return liouville(kind, params, state, t, density=density, formulation=formulation, fp_type=fp_type, prec=prec,
                     tol=tol).residual
