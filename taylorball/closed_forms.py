r"""The additional integral ``F3`` of the dynamically symmetric M||gamma system (section 5, item 3).

For ``a1 = a2`` the system of paper eq. (22) [Mpn2],

.. math:: \dot K = \Omega\,\gamma\times K + (K - d\,\Omega\,\gamma)\times\omega,\qquad
          \dot\gamma = \gamma\times\omega ,

with ``omega`` from paper eq. (19) [sved], has the integral, linear in ``K``,

.. math:: F_3 = \rho\,\Big[\gamma_3 (K_1\gamma_1 + K_2\gamma_2)
          - \big(1 - \gamma_3^2 - \tfrac{1}{a_1 d}\big) K_3\Big] + \Omega\,\Psi(\gamma_3),
          \qquad \rho = |D|^{-1/2},\quad D = 1 - d\,(\gamma, A\gamma).

Derivation (``taylorball verify --only closed_forms``, ``tests/test_closed_forms.py``)
------------------------------------------------------------------------------------
Write ``L`` for the bracket. On ``|gamma| = 1`` and with ``a1 = a2`` a symbolic
computation (sympy, reduced modulo ``gamma^2 - 1``) gives, along paper eq. (22) [Mpn2],

.. math:: \frac{d}{dt}\big(D^{-1/2} L\big)
          = \Omega\, D^{-1/2}\, \frac{(1 - a_1 d)^2}{a_1 d}\,(K_2\gamma_1 - K_1\gamma_2),
          \qquad \dot\gamma_3 = a_1 (K_2\gamma_1 - K_1\gamma_2).

So ``D^{-1/2} L`` is conserved at ``Omega = 0`` (the printed ``K``-linear part is right),
and ``F3`` is conserved for every ``Omega`` if and only if

.. math:: \Psi'(\gamma_3) = -\,d\,c^2\, |D(\gamma_3)|^{-1/2},\qquad
          c = 1 - \frac{1}{a_1 d},\qquad D(\gamma_3) = 1 - a_1 d - d (a_3 - a_1)\gamma_3^2 .

The same holds with ``|D|`` in place of ``D`` (``d|D|/|D| = dD/D``), which is what
taylorball uses: for the paper's kind of values (``d a_i > 1``) ``D < 0`` and the paper's
``rho = D^{-1/2}`` is imaginary. The real ``F3`` above equals ``i`` times the paper's
(principal branch) ``F3`` plus a piecewise constant (the principal branches jump).

Closed form (``Psi(0) = 0``, odd, smooth on ``[-1, 1]``)
---------------------------------------------------------
With ``s = sign(1 - a1 d)`` (``D`` has one sign on the whole sphere, required),
``P = |1 - a1 d|``, ``Q = s d (a3 - a1)``, so that ``|D| = P - Q gamma3^2``:

* ``Q > 0`` ("arctan" branch; physical balls with ``a3 > a1``, paper-kind values with
  ``a3 < a1``): ``Psi = -(d c^2/sqrt(Q)) arctan(gamma3 sqrt(Q) / sqrt(|D|))``;
* ``Q < 0`` ("arsinh" branch; physical ``a3 < a1``, paper-kind ``a3 > a1``):
  ``Psi = -(d c^2/sqrt(-Q)) arsinh(gamma3 sqrt(-Q/P))``
  ``= -(d c^2/sqrt(-Q)) artanh(gamma3 sqrt(-Q)/sqrt(|D|))``;
* ``Q = 0`` (``a3 = a1``, the limit of both): ``Psi = -d c^2 gamma3 / sqrt(P)``.

Against the printed formulas (``docs/errata.md``, E-Psi1..E-Psi3): the printed arctan form
has the right derivative but a jump of ``pi sqrt(d) c^2 / (2 sqrt(a3 - a1))`` at
``gamma3 = 0`` (its argument has ``gamma3`` in the denominator), so the printed ``F3`` jumps
when an orbit crosses the equator; the printed log form has the wrong derivative (the
``4 gamma3`` in ``xi`` must be ``2 gamma3`` and the overall sign is reversed); and for
``D < 0`` the branches are swapped with respect to the printed condition on ``a3 - a1``.
:func:`psi_printed` keeps the printed forms for these checks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional, Sequence, Union

import numpy as np
from numpy.typing import ArrayLike

from ._typing import ParamsLike, Scalar, VecLike
from .errors import ParameterError, StateError
from .params import BallParams, MParallelParams

__all__ = [
    "PsiBranch",
    "psi_branch",
    "symmetric_params",
    "psi",
    "psi_prime",
    "psi_mp",
    "psi_prime_mp",
    "psi_printed",
    "psi_expression",
    "symmetric_integral",
    "symmetric_integral_mp",
    "symmetric_integral_scale",
    "symmetric_integral_expression",
]

BRANCHES = ("arctan", "arsinh", "linear")


@dataclass(frozen=True)
class PsiBranch:
    """Which closed form of ``Psi`` applies (see the module docstring).

    Attributes
    ----------
    s : int
        ``sign(1 - a1 d)``: +1 for physical balls, -1 for values with ``d a_i > 1``.
    form : str
        ``"arctan"`` (``Q > 0``), ``"arsinh"`` (``Q < 0``) or ``"linear"`` (``Q = 0``), with
        ``Q = s d (a3 - a1)``.
    """

    s: int
    form: str


def symmetric_params(params: ParamsLike, name: str = "params") -> MParallelParams:
    """Check that ``params`` is a dynamically symmetric M||gamma system with ``D != 0``.

    Parameters
    ----------
    params : MParallelParams or BallParams
        ``MParallelParams`` with ``a1 == a2`` exactly, or a ``BallParams`` with
        ``I1 == I2`` exactly (converted by :meth:`BallParams.to_mparallel`).
    name : str
        Argument name used in error messages.

    Returns
    -------
    MParallelParams

    Raises
    ------
    ParameterError
        Not symmetric (``a1 != a2`` / ``I1 != I2``), a wrong type, or parameters for which
        ``D = 1 - d (gamma, A gamma)`` vanishes somewhere on ``|gamma| = 1`` (``1 - a1 d``
        and ``1 - a3 d`` zero or of opposite signs): the vector field (paper eq. (19) [sved]) is
        singular there and ``F3`` is not defined across it.
    """
    if isinstance(params, BallParams):
        if params.inertia[0] != params.inertia[1]:
            raise ParameterError(
                f"{name}=BallParams(inertia={params.inertia!r}, ...) is not dynamically symmetric: the "
                "integral F3 (section 5, item 3) needs I1 == I2 exactly"
            )
        params = params.to_mparallel()
    if not isinstance(params, MParallelParams):
        raise ParameterError(
            f"{name} must be MParallelParams(a=(a1, a1, a3), d=d, plane_rate=Omega) or a BallParams with "
            f"I1 == I2, got {params!r}"
        )
    a1, a2, a3 = params.a
    if a1 != a2:
        raise ParameterError(
            f"{name}.a={params.a!r} has a1 != a2: the integral F3 (section 5, item 3) exists only in the "
            "dynamically symmetric case a1 == a2 (exactly)"
        )
    d = params.d
    D0, D1 = 1.0 - a1 * d, 1.0 - a3 * d
    if D0 == 0.0 or D1 == 0.0 or (D0 > 0.0) != (D1 > 0.0):
        raise ParameterError(
            f"{name}=MParallelParams(a={params.a!r}, d={d!r}): D = 1 - d (gamma, A gamma) runs from "
            f"1 - a1 d = {D0!r} (gamma3 = 0) to 1 - a3 d = {D1!r} (gamma3 = +-1) and so vanishes on the "
            "sphere; the vector field (paper eq. (19) [sved]) is singular there and F3 is undefined across "
            "it. "
            "Valid: d a1 and d a3 both < 1 (every real ball) or both > 1"
        )
    return params


def psi_branch(params: ParamsLike) -> PsiBranch:
    """The :class:`PsiBranch` of symmetric parameters (see :func:`symmetric_params`)."""
    p = symmetric_params(params)
    a1, _, a3 = p.a
    s = 1 if 1.0 - a1 * p.d > 0.0 else -1
    q = s * (a3 - a1)
    return PsiBranch(s, "arctan" if q > 0 else ("arsinh" if q < 0 else "linear"))


# ---------------------------------------------------------------------------------------
# The formula, once, on backend scalars (numpy arrays, mpmath, heyoka expressions).
# ---------------------------------------------------------------------------------------
def _psi_formula(br: PsiBranch, a1, a3, d, g3, sqrt, atan, asinh):
    """``Psi(g3)`` on backend scalars; ``br`` fixes the branch."""
    s = br.s
    P = s * (1 - a1 * d)  # |1 - a1 d| > 0
    dc2 = (1 - a1 * d) ** 2 / (a1 * a1 * d)  # d c^2 = d (1 - 1/(a1 d))^2
    if br.form == "linear":
        return -dc2 * g3 / sqrt(P)
    Q = s * d * (a3 - a1)
    if br.form == "arctan":
        sq = sqrt(Q)
        return -dc2 / sq * atan(g3 * sq / sqrt(P - Q * g3 * g3))
    sq = sqrt(-Q)
    return -dc2 / sq * asinh(g3 * sqrt(-Q / P))


def _psi_prime_formula(br: PsiBranch, a1, a3, d, g3, sqrt):
    """The required ``Psi'(g3) = -d c^2 |D(g3)|^{-1/2}`` on backend scalars."""
    s = br.s
    absD = s * (1 - a1 * d - d * (a3 - a1) * g3 * g3)
    return -((1 - a1 * d) ** 2 / (a1 * a1 * d)) / sqrt(absD)


def _linear_part(s, A, d, K, g, sqrt):
    """``|D|^{-1/2} [gamma3 (K1 gamma1 + K2 gamma2) - (1 - gamma3^2 - 1/(a1 d)) K3]``."""
    D = 1 - d * (A[0] * g[0] * g[0] + A[1] * g[1] * g[1] + A[2] * g[2] * g[2])
    L = g[2] * (K[0] * g[0] + K[1] * g[1]) - (1 - g[2] * g[2] - 1 / (A[0] * d)) * K[2]
    return L / sqrt(s * D)


# ---------------------------------------------------------------------------------------
# numpy
# ---------------------------------------------------------------------------------------
def _float_dtype(x: np.ndarray) -> np.ndarray:
    import heyoka as hy

    if x.dtype.kind in "iub" or x.dtype == object:
        x = x.astype(np.float64)
    if x.dtype not in (np.dtype(np.float64), np.dtype(np.longdouble), np.dtype(hy.real128)):
        if x.dtype.kind == "f":
            return x.astype(np.float64)
        raise StateError(
            f"gamma3 must be real numbers (float64, long double or real128), got dtype {x.dtype}"
        )
    return x


def _check_gamma3(g3: np.ndarray, name: str = "gamma3"):
    from .manifold import default_constraint_tol

    tol = default_constraint_tol(g3.dtype)
    g = np.asarray(g3, dtype=float)
    if not np.all(np.isfinite(g)):
        raise StateError(f"{name} must be finite, got {g3!r}")
    worst = float(np.max(np.abs(g))) if g.size else 0.0
    if worst > 1.0 + tol:
        raise StateError(
            f"{name} must lie in [-1, 1] (a component of the unit normal gamma), got |{name}| = {worst!r} "
            f"(> 1 + {tol:.2g})"
        )


def _np_pars(p: MParallelParams, dtype):
    a1, _, a3 = (np.asarray(v, dtype=dtype)[()] for v in p.a)
    return a1, a3, np.asarray(p.d, dtype=dtype)[()], np.asarray(p.plane_rate, dtype=dtype)[()]


def psi(params: ParamsLike, gamma3: ArrayLike) -> Scalar:
    r"""``Psi(gamma3)`` of section 5, item 3, in the corrected closed form (numpy).

    .. math:: \Psi(\gamma_3) = -\,d\,c^2 \int_0^{\gamma_3}
              \frac{dt}{\sqrt{|1 - a_1 d - d (a_3 - a_1) t^2|}},\qquad c = 1 - \frac{1}{a_1 d},

    evaluated as ``arctan``, ``arsinh`` or the linear limit (module docstring). Continuous
    and odd on ``[-1, 1]``, unlike the printed arctan form (E-Psi1).

    Parameters
    ----------
    params : MParallelParams or BallParams
        Symmetric (``a1 == a2`` / ``I1 == I2`` exactly), see :func:`symmetric_params`.
    gamma3 : float or array_like
        ``gamma3`` in ``[-1, 1]`` (rounding excess up to ``sqrt(eps)/10`` accepted). The
        dtype (float64, long double, real128) is kept; parameters are converted to it.

    Returns
    -------
    scalar or numpy.ndarray
        Same shape and dtype as ``gamma3``.

    Raises
    ------
    ParameterError
        Non-symmetric parameters or ``D`` vanishing on the sphere.
    StateError
        ``|gamma3| > 1`` or non-finite / non-real ``gamma3``.
    """
    br = psi_branch(params)
    p = symmetric_params(params)
    g3 = _float_dtype(np.asarray(gamma3))
    _check_gamma3(g3)
    a1, a3, d, _ = _np_pars(p, g3.dtype)
    out = _psi_formula(br, a1, a3, d, g3, np.sqrt, np.arctan, np.arcsinh)
    return out[()] if isinstance(out, np.ndarray) and out.ndim == 0 else out


def psi_prime(params: ParamsLike, gamma3: ArrayLike) -> Scalar:
    r"""The derivative ``Psi'(gamma3) = -d c^2 |D(gamma3)|^{-1/2}`` required for ``dF3/dt = 0``
    (derived in the module docstring; numpy, same conventions as :func:`psi`)."""
    br = psi_branch(params)
    p = symmetric_params(params)
    g3 = _float_dtype(np.asarray(gamma3))
    _check_gamma3(g3)
    a1, a3, d, _ = _np_pars(p, g3.dtype)
    out = _psi_prime_formula(br, a1, a3, d, g3, np.sqrt)
    return out[()] if isinstance(out, np.ndarray) and out.ndim == 0 else out


def symmetric_integral(params: ParamsLike, state: ArrayLike, *, check: bool = True) -> Scalar:
    r"""The additional integral ``F3`` of the symmetric M||gamma system (numpy).

    .. math:: F_3 = |D|^{-1/2}\Big[\gamma_3 (K_1\gamma_1 + K_2\gamma_2)
              - \big(1 - \gamma_3^2 - \tfrac{1}{a_1 d}\big) K_3\Big] + \Omega\,\Psi(\gamma_3),

    ``D = 1 - d (gamma, A gamma)`` (paper sec. 5 item 3 with ``rho = |D|^{-1/2}`` and the
    corrected ``Psi`` of :func:`psi`).

    Parameters
    ----------
    params : MParallelParams or BallParams
        Symmetric, see :func:`symmetric_params`.
    state : array_like, shape (6,) or (n, 6)
        ``(K1, K2, K3, gamma1, gamma2, gamma3)``; dtype float64, long double or real128 kept.
    check : bool
        Reject states off ``|gamma| = 1`` (default; see :func:`taylorball.manifold.as_state`).

    Returns
    -------
    scalar or numpy.ndarray of shape (n,)

    Raises
    ------
    ParameterError, StateError, ConstraintError
    """
    from .manifold import as_state

    p = symmetric_params(params)
    br = psi_branch(p)
    x = _float_dtype(as_state("mparallel", state, params=p, check=check))
    a1, a3, d, om = _np_pars(p, x.dtype)
    K = tuple(x[..., i] for i in range(3))
    g = tuple(x[..., 3 + i] for i in range(3))
    _check_gamma3(g[2], "state[5] (gamma3)")
    F = _linear_part(br.s, (a1, a1, a3), d, K, g, np.sqrt) + om * _psi_formula(
        br, a1, a3, d, g[2], np.sqrt, np.arctan, np.arcsinh
    )
    return F[()] if isinstance(F, np.ndarray) and F.ndim == 0 else F


def symmetric_integral_scale(params: ParamsLike, state: ArrayLike, *, check: bool = True) -> Scalar:
    """Natural magnitude of ``F3``: the sum of the magnitudes of its terms,
    ``|D|^{-1/2} (|gamma3| |K1 gamma1 + K2 gamma2| + |1 - gamma3^2 - 1/(a1 d)| |K3|) +
    |Omega Psi(gamma3)|``; drift of ``F3`` is judged relative to it."""
    from .manifold import as_state

    p = symmetric_params(params)
    x = _float_dtype(as_state("mparallel", state, params=p, check=check))
    a1, a3, d, om = _np_pars(p, x.dtype)
    K = tuple(x[..., i] for i in range(3))
    g = tuple(x[..., 3 + i] for i in range(3))
    D = 1 - d * (a1 * (g[0] ** 2 + g[1] ** 2) + a3 * g[2] ** 2)
    lin = (
        np.abs(g[2] * (K[0] * g[0] + K[1] * g[1])) + np.abs((1 - g[2] ** 2 - 1 / (a1 * d)) * K[2])
    ) / np.sqrt(np.abs(D))
    out = lin + np.abs(om * psi(p, g[2]))
    return out[()] if isinstance(out, np.ndarray) and out.ndim == 0 else out


# ---------------------------------------------------------------------------------------
# mpmath
# ---------------------------------------------------------------------------------------
def _mp_pars(p: MParallelParams, mp):
    return mp.mpf(p.a[0]), mp.mpf(p.a[2]), mp.mpf(p.d), mp.mpf(p.plane_rate)


def _to_mpf(v, mp):
    """``v`` as an mpmath number, exactly for float64, long double and real128 values."""
    import heyoka as hy

    if isinstance(v, mp.mpf):
        return v
    if isinstance(v, (int, float, np.floating)) and not isinstance(v, np.longdouble):
        return mp.mpf(float(v)) if not isinstance(v, int) else mp.mpf(v)
    if isinstance(v, np.longdouble):
        n, m = v.as_integer_ratio()  # exact
        return mp.mpf(n) / m
    if isinstance(v, hy.real128):
        # str is the shortest round-trip decimal: parsing it at 113 bits gives v exactly
        with mp.workprec(113):
            x = mp.mpf(str(v))
        return x
    return mp.mpf(str(v))  # heyoka real and others: correct to their printed digits


def _mp_gamma3(g3, mp, name="gamma3"):
    x = _to_mpf(g3, mp)
    if not mp.isfinite(x) or abs(x) > 1 + mp.mpf(2) ** (-(mp.mp.prec // 2)):
        raise StateError(f"{name} must lie in [-1, 1], got {g3!r}")
    return x


def psi_mp(params: ParamsLike, gamma3: Scalar, dps: int = 50) -> Scalar:
    """:func:`psi` in mpmath at ``dps`` decimal digits.

    ``params`` values (float64) are taken exactly; ``gamma3`` may be a float, a string, an
    mpmath number, a numpy long double or a heyoka ``real128`` (all converted exactly).
    Returns an ``mpmath.mpf``."""
    import mpmath

    br = psi_branch(params)
    p = symmetric_params(params)
    with mpmath.workdps(dps):
        a1, a3, d, _ = _mp_pars(p, mpmath)
        g3 = _mp_gamma3(gamma3, mpmath)
        out = _psi_formula(br, a1, a3, d, g3, mpmath.sqrt, mpmath.atan, mpmath.asinh)
        return +out


def psi_prime_mp(params: ParamsLike, gamma3: Scalar, dps: int = 50) -> Scalar:
    """:func:`psi_prime` in mpmath at ``dps`` digits (conventions of :func:`psi_mp`)."""
    import mpmath

    br = psi_branch(params)
    p = symmetric_params(params)
    with mpmath.workdps(dps):
        a1, a3, d, _ = _mp_pars(p, mpmath)
        g3 = _mp_gamma3(gamma3, mpmath)
        return +_psi_prime_formula(br, a1, a3, d, g3, mpmath.sqrt)


def symmetric_integral_mp(params: ParamsLike, state: VecLike, dps: int = 50) -> Scalar:
    """:func:`symmetric_integral` of one state in mpmath at ``dps`` digits.

    The state's entries (float64, long double, real128, mpmath) are converted exactly; no
    constraint check (``F3`` is an integral on ``|gamma| = 1``). Returns an ``mpmath.mpf``."""
    import mpmath

    br = psi_branch(params)
    p = symmetric_params(params)
    vals = list(np.asarray(state).reshape(-1))
    if len(vals) != 6:
        raise StateError(f"state must have 6 entries (K1, K2, K3, gamma1, gamma2, gamma3), got {len(vals)}")
    with mpmath.workdps(dps):
        x = [_to_mpf(v, mpmath) for v in vals]
        a1, a3, d, om = _mp_pars(p, mpmath)
        K, g = x[0:3], x[3:6]
        _mp_gamma3(g[2], mpmath, "state[5] (gamma3)")
        F = _linear_part(br.s, (a1, a1, a3), d, K, g, mpmath.sqrt) + om * _psi_formula(
            br, a1, a3, d, g[2], mpmath.sqrt, mpmath.atan, mpmath.asinh
        )
        return +F


def psi_printed(params: ParamsLike, gamma3: Scalar, dps: int = 50, *, corrected: bool = False) -> Scalar:
    r"""The paper's printed ``Psi`` (section 5, item 3), literally, in mpmath; for the checks.

    ``a3 > a1``: ``sqrt(d)/(2 sqrt(a3 - a1)) c^2 arctan(rho (1 - a1 d - 2 d (a3 - a1) gamma3^2) /
    (2 gamma3 sqrt(d (a3 - a1))))``; ``a3 < a1``: ``sqrt(d)/(4 sqrt(a1 - a3)) c^2 (ln(xi + 1) -
    ln(xi - 1))``, ``xi = rho (1 - a1 d - 2 d (a3 - a1) gamma3^2) / (4 gamma3 sqrt(d (a1 - a3)))``;
    ``rho = (1 - d (gamma, A gamma))^{-1/2}`` on ``|gamma| = 1``, principal branch (imaginary
    when ``D < 0``), principal complex logarithms.

    Parameters
    ----------
    corrected : bool
        Apply erratum E-Psi2 to the log form: ``2 gamma3`` instead of ``4 gamma3`` in ``xi``
        and ``ln(xi - 1) - ln(xi + 1)``. The arctan form is returned unchanged (its
        derivative is right; its jump at ``gamma3 = 0``, E-Psi1, is not a local defect).

    Returns
    -------
    mpmath.mpf or mpmath.mpc

    Raises
    ------
    ParameterError
        Non-symmetric parameters, or ``a3 == a1`` (the printed forms divide by zero).
    StateError
        ``gamma3 == 0`` (the printed arguments divide by ``gamma3``) or ``|gamma3| > 1``.
    """
    import mpmath

    p = symmetric_params(params)
    a1f, _, a3f = p.a
    if a1f == a3f:
        raise ParameterError(
            f"params.a={p.a!r}: the printed Psi divides by sqrt(a3 - a1); with a3 == a1 it is undefined "
            "(the corrected Psi of psi() is then linear, -d c^2 gamma3 / sqrt|1 - a1 d|)"
        )
    with mpmath.workdps(dps):
        a1, a3, d, _ = _mp_pars(p, mpmath)
        g3 = _mp_gamma3(gamma3, mpmath)
        if g3 == 0:
            raise StateError("gamma3 = 0: the printed Psi has gamma3 in a denominator and is undefined there")
        c2 = (1 - 1 / (a1 * d)) ** 2
        rho = 1 / mpmath.sqrt(1 - a1 * d - d * (a3 - a1) * g3**2)  # complex when D < 0
        num = rho * (1 - a1 * d - 2 * d * (a3 - a1) * g3**2)
        if a3 > a1:
            return +(
                mpmath.sqrt(d)
                / (2 * mpmath.sqrt(a3 - a1))
                * c2
                * mpmath.atan(num / (2 * g3 * mpmath.sqrt(d * (a3 - a1))))
            )
        xi = num / ((2 if corrected else 4) * g3 * mpmath.sqrt(d * (a1 - a3)))
        logs = mpmath.log(xi + 1) - mpmath.log(xi - 1)
        return +(mpmath.sqrt(d) / (4 * mpmath.sqrt(a1 - a3)) * c2 * (-logs if corrected else logs))


# ---------------------------------------------------------------------------------------
# heyoka
# ---------------------------------------------------------------------------------------
def _branch_of(branch) -> PsiBranch:
    if isinstance(branch, PsiBranch):
        return branch
    return psi_branch(branch)


def psi_expression(branch: Union[ParamsLike, PsiBranch], gamma3: Optional[Any] = None) -> Any:
    """``Psi`` as a heyoka expression with parameters ``hy.par[0..4] = (a1, a2, a3, d, Omega)``.

    Parameters
    ----------
    branch : MParallelParams, BallParams or PsiBranch
        Fixes the closed form (``arctan`` / ``arsinh`` / ``linear`` and the sign of ``D``);
        the compiled expression is valid for every parameter vector of the same branch.
        Only ``a1 = par[0]``, ``a3 = par[2]``, ``d = par[3]`` enter.
    gamma3 : heyoka expression, optional
        Default: the variable ``gamma3``.
    """
    import heyoka as hy

    br = _branch_of(branch)
    g3 = hy.expression("gamma3") if gamma3 is None else gamma3
    return _psi_formula(br, hy.par[0], hy.par[2], hy.par[3], g3, hy.sqrt, hy.atan, hy.asinh)


def symmetric_integral_expression(branch: Union[ParamsLike, PsiBranch],
                                  state_vars: Optional[Sequence[Any]] = None) -> Any:
    """``F3`` as a heyoka expression of ``(K1, K2, K3, gamma1, gamma2, gamma3)`` with
    parameters ``hy.par[0..4] = (a1, a2, a3, d, Omega)`` (the :attr:`MParallelParams.pars`
    layout, as in the compiled integrators of :mod:`taylorball._propagate`).

    Parameters
    ----------
    branch : MParallelParams, BallParams or PsiBranch
        Fixes the closed form of ``Psi`` (see :func:`psi_expression`). ``rho`` uses the
        full ``(gamma, A gamma)`` with ``a2 = par[1]``; the bracket uses ``a1 = par[0]``.
    state_vars : sequence of 6 heyoka expressions, optional
        Default: variables named as :data:`taylorball.model.PUBLIC_NAMES` ``["mparallel"]``.
    """
    import heyoka as hy

    from .model import PUBLIC_NAMES

    br = _branch_of(branch)
    xs = hy.make_vars(*PUBLIC_NAMES["mparallel"]) if state_vars is None else list(state_vars)
    if len(xs) != 6:
        raise StateError(
            f"state_vars must be 6 expressions (K1, K2, K3, gamma1, gamma2, gamma3), got {len(xs)}"
        )
    K, g = xs[0:3], xs[3:6]
    A = (hy.par[0], hy.par[1], hy.par[2])
    return _linear_part(br.s, A, hy.par[3], K, g, hy.sqrt) + hy.par[4] * psi_expression(br, g[2])
