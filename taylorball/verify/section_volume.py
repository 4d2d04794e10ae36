r"""The invariant volume form of the section-4 Poincaré map, and a numerical check of it.

The paper (section 4) states: *"Since the system (10) possesses an invariant measure, the
three-dimensional Poincaré map preserves some volume form."* This module derives that
volume form in the chart coordinates ``(l, r1, r2)`` and checks it on computed return maps.

Derivation
----------
1. *Level manifold.* In the internal variables ``x = (M, gamma, R)`` of the reduced system
   the invariant density is :math:`\rho_9 = |D|^{-1/2}`, :math:`D = 1 - d(\gamma, A\gamma)`
   (paper sec. 2; verified in :mod:`taylorball.verify.formulas`). The four functions
   :math:`c = (\gamma^2, (R,\gamma), |M|^2, (M,\gamma))` are first integrals, so
   :math:`\mu_9 = \rho_9\, d^9x = \rho_5(y)\, d^5y \wedge d^4c` with ``y = (K, r1, r2, l, g)``
   and :math:`\rho_5 = \rho_9\,|\det \partial\Phi/\partial(y, c)|` for any map
   :math:`\Phi(y, c)` that is the section-4 chart on the level ``c`` (coarea formula); the
   flow on :math:`\mathcal M^5` preserves :math:`\rho_5\,d^5y`. Here
   :math:`\Phi` scales ``gamma`` to :math:`|\gamma|^2 = c_1`, shifts ``R`` along ``gamma``
   to :math:`(R,\gamma) = c_2`, and uses :math:`C = \sqrt{c_3}`, :math:`(M,\gamma) = c_4`
   (:func:`chart_extension_mp`). The Jacobian factorises (``M`` in spherical coordinates,
   ``gamma`` on the cone about ``M``, ``R`` in the plane orthogonal to ``gamma`` seen
   through its horizontal projection):

   .. math:: \rho_5 = \frac{|D|^{-1/2}}{4\,C\,(\gamma_1^2 + \gamma_2^2)\,|\gamma_3|} .

   :func:`level_density` evaluates both this closed form and the 9x9 determinant in
   mpmath; :func:`liouville_residual` checks :math:`\operatorname{div}_y(\rho_5 \dot y) = 0`
   directly in chart coordinates (independently of :math:`\rho_9`).
2. *Energy level.* :math:`\rho_5\, dK\,dr_1\,dr_2\,dl\,dg = \frac{\rho_5}{|\partial E/\partial K|}
   dE\,dr_1\,dr_2\,dl\,dg`, so the flow on :math:`E = h` preserves
   :math:`\frac{\rho_5}{|\partial_K E|} dr_1\,dr_2\,dl\,dg` (``dE/dK`` at fixed
   ``r1, r2, l, g``).
3. *Section.* The first-return map to ``g = g0`` preserves the flux form

   .. math:: \sigma(l, r_1, r_2)\; dl\,dr_1\,dr_2,\qquad
             \sigma = \frac{\rho_5\,|\dot g|}{|\partial E/\partial K|},

   i.e. :math:`\sigma(P(x))\,|\det DP(x)| = \sigma(x)`
   (:func:`volume_preservation_check`). ``sigma`` depends on the crossing's branch ``K``
   (the energy equation can have several roots), so it is a function on the section
   *with* its branch.

Computation
-----------
The return map ``P`` is computed by heyoka event detection (:func:`taylorball.sections.poincare_section`)
in long double from initial states built in mpmath. Its Jacobian ``DP``
(:func:`return_map_jacobian`) in one of two ways:

* ``method="fd"``: central finite differences in ``(l, r1, r2)`` at two step sizes
  (the branch ``K`` of each perturbed start point is the root nearest the base point's
  ``K``, refined by Newton in mpmath). 13 integrations; the error is the step's ``s^2``
  truncation, estimated from the two steps.
* ``method="variational"`` (default): one integration of the reduced system with its first-order
  variational equations (:class:`taylorball.tangent.TangentSystem`, heyoka ``var_ode_sys``,
  compact mode) to the return time ``tau``, then
  :math:`DP = J_\mathrm{out}\,(I - f\,\nabla e^T/(\nabla e\cdot f))\,\Phi\,J_\mathrm{in}`:
  ``Phi`` the 9x9 state transition matrix, ``f`` the vector field and ``e`` the section event
  function at the image (the projector accounts for the variation of ``tau``),
  ``J_in = dx0/d(l, r1, r2)`` of the start state on the section and level (``K`` by the
  implicit function theorem, ``dK/dp = -(dE/dp)/(dE/dK)``) and ``J_out = d(l, r1, r2)/dx``
  at the image, all but ``Phi`` in mpmath. Accurate to the working type's rounding
  amplified by the orbit.

Measured residuals :math:`|\sigma(Px)|\det DP|/\sigma(x) - 1|` on the 14 points of
``taylorball verify --full --only sections`` (Fig. 4 levels ``C = 10``, ``h = 5``,
``M_gamma = 2, 6``, long double): with ``"fd"`` 4e-10..4e-8 at step 1e-4 (the ``s^2``
truncation error, which the two-step estimate predicts), <= 5.8e-13 Richardson-extrapolated;
with ``"variational"`` 4e-18..1.3e-16, i.e. 37..1.24e3 eps of long double (1.1e-19), at
about 0.07 s per point against 0.4 s. The two ``DP`` differ by the finite differences' error
estimate (to 0.1 %). With the orbit integrated in real128 (start state built in real128;
``fp_type=heyoka.real128`` itself stops in :meth:`taylorball.numbers.FpSpec.scalar` on the
long-double start state) the variational residual was 4e-30 and 8e-30 at the two base points
(the limit of the 40-digit mpmath ``sigma``): the long-double residual is integration rounding.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Optional

import numpy as np

from .._typing import FpTypeLike
from ..errors import ChartError, IntegrationError, UsageError
from ..params import BallParams

__all__ = [
    "chart_extension_mp",
    "chart_of_internal_mp",
    "level_density",
    "chart_velocity_mp",
    "liouville_residual",
    "energy_on_chart_mp",
    "section_density",
    "section_density_of_state",
    "return_map",
    "return_map_jacobian",
    "volume_preservation_check",
    "volume_preservation_residual",
]

_DPS = 40  # working digits of the mpmath parts (results are needed to ~20 digits)


# =======================================================================================
# mpmath building blocks
# =======================================================================================
def _mp():
    import mpmath

    return mpmath


def _consts(params):
    """Ball constants in mpmath at the current precision (``a_i = 1/(I_i + d)`` exact)."""
    from ..manifold import params_for
    from ..model import ball_constants

    mp = _mp()
    params = params_for("reduced", params)
    return ball_constants(tuple(mp.mpf(p) for p in params.pars))


def chart_extension_mp(y, cvals):
    r"""The section-4 chart extended to nearby constraint levels (mpmath).

    Parameters
    ----------
    y : sequence of 5 mpf
        ``(K, r1, r2, l, g)``.
    cvals : sequence of 4 mpf
        ``(c1, c2, c3, c4) = (|gamma|^2, (R, gamma), |M|^2, (M, gamma))``.

    Returns
    -------
    (M, gamma, R) : three 3-tuples of mpf
        With ``C = sqrt(c3)``, ``mu = c4 / (sqrt(c1) C)``, ``k = K/C``, ``q = sqrt(1-k^2)``,
        ``s = sqrt(1-mu^2)``: ``M = C (q sin l, q cos l, k)``,
        ``gamma = sqrt(c1) (mu Mhat - s (cos g u + sin g w))`` with
        ``u = (-k sin l, -k cos l, q)``, ``w = (-cos l, sin l, 0)``, and
        ``R = R0 + c2 gamma / c1`` where ``R0`` (orthogonal to ``gamma``) has
        ``R0_1 gamma1 + R0_2 gamma2 = r1``, ``R0_1 gamma2 - R0_2 gamma1 = r2``. On
        ``c = (1, 0, C^2, M_gamma)`` this is :func:`taylorball.charts.reduced_state_from_chart`
        (in the internal variables).
    """
    mp = _mp()
    K, r1, r2, l, g = y
    c1, c2, c3, c4 = cvals
    C = mp.sqrt(c3)
    k = K / C
    q = mp.sqrt(1 - k * k)
    mu = c4 / (mp.sqrt(c1) * C)
    s = mp.sqrt(1 - mu * mu)
    sl, cl, sg, cg = mp.sin(l), mp.cos(l), mp.sin(g), mp.cos(g)
    Mhat = (q * sl, q * cl, k)
    u = (-k * sl, -k * cl, q)
    w = (-cl, sl, mp.mpf(0))
    sc = mp.sqrt(c1)
    gam = tuple(sc * (mu * Mhat[i] - s * (cg * u[i] + sg * w[i])) for i in range(3))
    M = tuple(C * v for v in Mhat)
    g1, g2, g3 = gam
    rho2 = g1 * g1 + g2 * g2
    R0 = ((g1 * r1 + g2 * r2) / rho2, (g2 * r1 - g1 * r2) / rho2, -r1 / g3)
    R = tuple(R0[i] + c2 * gam[i] / c1 for i in range(3))
    return M, gam, R


def chart_of_internal_mp(M, gamma, R):
    """Section-4 chart ``(K, r1, r2, l, g)`` of internal vectors (mpmath; angles in
    ``(-pi, pi]``, unwrapped by the caller)."""
    mp = _mp()
    C2 = sum(v * v for v in M)
    C = mp.sqrt(C2)
    Mg = sum(M[i] * gamma[i] for i in range(3))
    num = C * (M[1] * gamma[0] - M[0] * gamma[1])
    den = Mg * M[2] - C2 * gamma[2]
    return (M[2], R[0] * gamma[0] + R[1] * gamma[1], R[0] * gamma[1] - R[1] * gamma[0],
            mp.atan2(M[0], M[1]), mp.atan2(num, den))


def _levels0(C, M_gamma):
    mp = _mp()
    return (mp.mpf(1), mp.mpf(0), mp.mpf(C) ** 2, mp.mpf(M_gamma))


def _D(c, gamma):
    return 1 - c.d * sum(c.A[i] * gamma[i] ** 2 for i in range(3))


def _fd4(f, h):
    """Fourth-order central difference of ``f(t)`` (vector of mpf) at ``t = 0``."""
    fp1, fm1, fp2, fm2 = f(h), f(-h), f(2 * h), f(-2 * h)
    return [(-a + 8 * b - 8 * cc + e) / (12 * h) for a, b, cc, e in zip(fp2, fp1, fm1, fm2)]


def _jacobian_mp(f, x, h):
    """Columns ``df/dx_j`` by :func:`_fd4` (mpmath)."""
    cols = []
    for j in range(len(x)):
        def fj(t, j=j):
            xx = list(x)
            xx[j] = xx[j] + t
            return f(xx)
        cols.append(_fd4(fj, h))
    return cols


def _check_levels(C, M_gamma):
    from ..charts import _check_levels as chk

    return chk(C, M_gamma)


def level_density(params, *, C, M_gamma, K, l, g, r1, r2, method: str = "closed", dps: int = _DPS):
    r"""Density :math:`\rho_5` of the invariant measure on the level manifold
    :math:`\mathcal M^5` (``|M| = C``, ``(M, gamma) = M_gamma``) w.r.t.
    ``dK dr1 dr2 dl dg`` (section-4 chart).

    Parameters
    ----------
    method : {"closed", "jacobian"}
        ``"closed"``: :math:`|D|^{-1/2} / (4 C (\gamma_1^2+\gamma_2^2) |\gamma_3|)`;
        ``"jacobian"``: :math:`|D|^{-1/2} |\det \partial\Phi/\partial(y, c)|` with the 9x9
        Jacobian of :func:`chart_extension_mp` by fourth-order differences in mpmath at
        ``dps + 20`` digits (an independent evaluation of the same quantity).
    dps : int
        Digits of the result.

    Returns
    -------
    mpmath.mpf
    """
    if method not in ("closed", "jacobian"):
        raise UsageError(f"method must be 'closed' or 'jacobian', got {method!r}")
    C, M_gamma = _check_levels(C, M_gamma)
    mp = _mp()
    with mp.workdps(dps + 20):
        c = _consts(params)
        y = [mp.mpf(v) for v in (K, r1, r2, l, g)]
        lev = list(_levels0(C, M_gamma))
        M, gam, R = chart_extension_mp(y, lev)
        rho9 = 1 / mp.sqrt(abs(_D(c, gam)))
        if method == "closed":
            out = rho9 / (4 * mp.mpf(C) * (gam[0] ** 2 + gam[1] ** 2) * abs(gam[2]))
        else:
            z0 = y + lev

            def phi(z):
                M_, g_, R_ = chart_extension_mp(z[:5], z[5:])
                return list(M_) + list(g_) + list(R_)

            cols = _jacobian_mp(phi, z0, mp.mpf(10) ** (-(dps + 20) // 4))
            J = mp.matrix(9, 9)
            for j in range(9):
                for i in range(9):
                    J[i, j] = cols[j][i]
            out = rho9 * abs(mp.det(J))
        return +out


def chart_velocity_mp(params, y, C, M_gamma):
    """``dy/dt`` of the reduced flow in chart coordinates ``y = (K, r1, r2, l, g)`` on the
    level ``(C, M_gamma)`` (mpmath, current precision): the derivative of the chart
    along the vector field :func:`taylorball.model.reduced_rhs`, by :func:`_fd4` in time."""
    from ..model import reduced_rhs

    mp = _mp()
    c = _consts(params)
    M, gam, R = chart_extension_mp(y, _levels0(C, M_gamma))
    Md, gd, Rd = reduced_rhs(c, M, gam, R)
    y0 = chart_of_internal_mp(M, gam, R)

    def along(t):
        yt = chart_of_internal_mp(tuple(M[i] + t * Md[i] for i in range(3)),
                                  tuple(gam[i] + t * gd[i] for i in range(3)),
                                  tuple(R[i] + t * Rd[i] for i in range(3)))
        # unwrap the angles around y0
        return [yt[0], yt[1], yt[2], y0[3] + _wrap_pm(yt[3] - y0[3]), y0[4] + _wrap_pm(yt[4] - y0[4])]

    return _fd4(along, mp.mpf(10) ** (-mp.mp.dps // 4))


def _wrap_pm(a):
    """Angle difference into ``(-pi, pi]`` (mpmath or float)."""
    mp = _mp()
    return a - 2 * mp.pi * mp.floor((a + mp.pi) / (2 * mp.pi))


def liouville_residual(params, *, C, M_gamma, y, density: str = "invariant", dps: int = 60):
    r"""Relative divergence :math:`|\sum_i \partial_i(\rho \dot y_i)| / \sum_i |\partial_i(\rho\dot y_i)|`
    of the 5D flow on :math:`\mathcal M^5` in chart coordinates ``y = (K, r1, r2, l, g)``.

    Zero (to the working precision) exactly when :math:`\rho\,d^5y` is invariant. Uses
    only the vector field, not :math:`\rho_9`: an independent check of
    :func:`level_density`.

    Parameters
    ----------
    density : {"invariant", "rho9", "one"}
        ``"invariant"``: :math:`\rho_5` (closed form); ``"rho9"``: :math:`|D|^{-1/2}`
        alone (the chart Jacobian forgotten); ``"one"``: 1. The latter two are wrong and
        must give residuals of order 1e-2..1.
    dps : int
        Working digits (nested fourth-order differences lose about half of them).
    """
    if density not in ("invariant", "rho9", "one"):
        raise UsageError(f"density must be 'invariant', 'rho9' or 'one', got {density!r}")
    C, M_gamma = _check_levels(C, M_gamma)
    mp = _mp()
    with mp.workdps(dps):
        c = _consts(params)
        y0 = [mp.mpf(v) for v in y]

        def rho(yy):
            if density == "one":
                return mp.mpf(1)
            _, gam, _ = chart_extension_mp(yy, _levels0(C, M_gamma))
            r = 1 / mp.sqrt(abs(_D(c, gam)))
            if density == "invariant":
                r = r / (4 * mp.mpf(C) * (gam[0] ** 2 + gam[1] ** 2) * abs(gam[2]))
            return r

        terms = []
        hout = mp.mpf(10) ** (-dps // 8)
        for i in range(5):
            def f(t, i=i):
                yy = list(y0)
                yy[i] = yy[i] + t
                with mp.workdps(mp.mp.dps + 20):  # the inner derivative in more digits
                    v = chart_velocity_mp(params, yy, C, M_gamma)[i] * rho(yy)
                return [v]
            terms.append(_fd4(f, hout)[0])
        return float(abs(mp.fsum(terms)) / mp.fsum(abs(t) for t in terms))


def energy_on_chart_mp(params, y, C, M_gamma):
    """Energy ``E = (omega, K)/2 - m Omega^2 |R|^2 / 2`` (sec. 3) at chart point ``y``
    (mpmath, current precision)."""
    from ..model import omega_from_K

    c = _consts(params)
    M, gam, R = chart_extension_mp(y, _levels0(C, M_gamma))
    Kv = tuple(M[i] + c.ma * c.Omega * R[i] for i in range(3))
    om = omega_from_K(c.A, c.d, gam, Kv)
    return sum(om[i] * Kv[i] for i in range(3)) / 2 - c.m * c.Omega ** 2 * sum(v * v for v in R) / 2


def _refine_K(params, C, M_gamma, h, l, r1, r2, g0, K0):
    """Root ``K`` of ``E(K; l, r1, r2, g0) = h`` near ``K0`` (mpmath, current precision;
    arguments may be mpf): Newton in ``theta`` with ``K = C cos(theta)`` (smooth through
    the poles ``K = +-C``, as in :func:`taylorball.charts.states_on_section`).

    Raises
    ------
    ChartError
        If Newton does not converge (``K0`` is no float approximation of a simple root).
    """
    mp = _mp()
    Cm = mp.mpf(C)

    def F(th):
        return energy_on_chart_mp(params, [Cm * mp.cos(th), r1, r2, l, g0], C, M_gamma) - h

    th = mp.acos(max(min(mp.mpf(K0) / Cm, mp.mpf(1)), mp.mpf(-1)))
    dh = mp.mpf(10) ** (-mp.mp.dps // 4)
    tol = mp.mpf(10) ** (-mp.mp.dps + 8)
    for _ in range(30):
        dF = _fd4(lambda t: [F(th + t)], dh)[0]
        step = F(th) / dF
        th = th - step
        if abs(step) <= tol * (1 + abs(th)):
            return Cm * mp.cos(th)
    raise ChartError(f"Newton for the energy root K near {float(K0)!r} did not converge (at the point "
                     f"l={float(l)!r}, r1={float(r1)!r}, r2={float(r2)!r}): a double root or no root there")


def _sigma_mp(params, C, M_gamma, y):
    """``sigma = rho5 |g_dot| / |dE/dK|`` at chart point ``y`` (mpmath)."""
    mp = _mp()
    c = _consts(params)
    _, gam, _ = chart_extension_mp(y, _levels0(C, M_gamma))
    rho5 = 1 / mp.sqrt(abs(_D(c, gam))) / (4 * mp.mpf(C) * (gam[0] ** 2 + gam[1] ** 2) * abs(gam[2]))
    gdot = chart_velocity_mp(params, y, C, M_gamma)[4]

    def EK(t):
        yy = list(y)
        yy[0] = yy[0] + t
        return [energy_on_chart_mp(params, yy, C, M_gamma)]

    dEdK = _fd4(EK, mp.mpf(10) ** (-mp.mp.dps // 4))[0]
    return rho5 * abs(gdot) / abs(dEdK), gdot, dEdK


def _pick_root(params, C, M_gamma, h, point, g0, K, direction):
    from ..charts import states_on_section

    _, info = states_on_section(params, C=C, M_gamma=M_gamma, h=h, point=point, g0=g0, direction=direction,
                                return_info=True)
    roots = info["K"]
    if K is None:
        if roots.size != 1:
            raise UsageError(
                f"the energy equation has {roots.size} roots K = {list(map(float, roots))} at point {tuple(point)!r}"
                f" (direction {direction!r}); pass K= to choose the branch (the nearest root is used)")
        return float(roots[0])
    return float(roots[int(np.argmin(np.abs(roots - float(K))))])


def section_density(params, *, C, M_gamma, h, point, g0: float = 0.0, K: Optional[float] = None,
                    direction: Optional[int] = 1, dps: int = _DPS) -> float:
    r"""Density :math:`\sigma = \rho_5 |\dot g| / |\partial E/\partial K|` of the volume
    form preserved by the section-4 Poincaré map, w.r.t. ``dl dr1 dr2``.

    Parameters
    ----------
    params : BallParams
    C, M_gamma, h : float
        Levels ``|M|``, ``(M, gamma)``, ``E``.
    point : (l, r1, r2)
        Point of the section ``g = g0``.
    K : float, optional
        Branch: the root of the energy equation nearest to ``K`` (required when there are
        several roots with ``dg/dt`` of sign ``direction``).
    direction : {1, -1, None}
        Crossing direction of the branches considered.

    Returns
    -------
    float

    Raises
    ------
    EmptyLevelError
        No state at this point; ``UsageError`` for an ambiguous branch.
    """
    C, M_gamma = _check_levels(C, M_gamma)
    l, r1, r2 = (float(v) for v in point)
    Kf = _pick_root(params, C, M_gamma, h, (l, r1, r2), g0, K, direction)
    mp = _mp()
    with mp.workdps(dps):
        Km = _refine_K(params, C, M_gamma, mp.mpf(h), mp.mpf(l), mp.mpf(r1), mp.mpf(r2), mp.mpf(g0), Kf)
        s, _, _ = _sigma_mp(params, C, M_gamma, [Km, mp.mpf(r1), mp.mpf(r2), mp.mpf(l), mp.mpf(g0)])
        return float(s)


def _to_mp(x):
    """Exact mpf of a float64 / long double number (of a real128 via its 36-digit decimal
    string, exact at the current precision when it exceeds ~36 digits)."""
    mp = _mp()
    if not isinstance(x, (float, int, np.floating)):
        return mp.mpf(str(x))
    hi = float(x)
    lo = float(np.longdouble(x) - np.longdouble(hi))
    return mp.mpf(hi) + mp.mpf(lo)


def _to_ld(v):
    """mpf -> long double (hi + lo)."""
    hi = float(v)
    return np.longdouble(hi) + np.longdouble(float(v - _mp().mpf(hi)))


def _from_mp(spec, v):
    """mpf -> a scalar of the working type ``spec`` (rounded)."""
    if spec.name == "longdouble":
        return _to_ld(v)
    if spec.name == "float":
        return float(v)
    import heyoka as hy

    return hy.real128(_mp().nstr(v, 45, strip_zeros=False))  # fp_type real128 (the only other type here)


def _internal_of_public_mp(params, state):
    from ..model import K_from_omega

    c = _consts(params)
    s = [_to_mp(v) for v in state]
    om, gam, R = tuple(s[0:3]), tuple(s[3:6]), tuple(s[6:9])
    Kv = K_from_omega(c.I, c.d, gam, om)
    M = tuple(Kv[i] - c.ma * c.Omega * R[i] for i in range(3))
    return M, gam, R


def section_density_of_state(params, state, *, dps: int = _DPS):
    """:func:`section_density` at a reduced state on the section (public layout; its own
    levels ``C``, ``M_gamma`` and its chart point, branch ``K = M3`` included).

    Returns
    -------
    (sigma, y) : float and the chart point ``(K, r1, r2, l, g)`` (mpf)
    """
    mp = _mp()
    with mp.workdps(dps):
        M, gam, R = _internal_of_public_mp(params, state)
        C = mp.sqrt(sum(v * v for v in M))
        Mg = sum(M[i] * gam[i] for i in range(3))
        y = list(chart_of_internal_mp(M, gam, R))
        # the chart of a state slightly off |gamma| = 1, (R, gamma) = 0 (float rounding):
        # evaluate at its own levels (C, M_gamma) -- the relative effect is ~eps
        s, _, _ = _sigma_mp(params, C, Mg, y)
        return float(s), y


# =======================================================================================
# Return map and its Jacobian
# =======================================================================================
def _start_state(params, C, M_gamma, h, g0, pt_mp, Kf):
    """Public long-double state on the section at ``pt_mp = (l, r1, r2)`` (mpf) on the
    branch nearest ``Kf``; returns ``(state, K)``."""
    from ..model import omega_from_K

    mp = _mp()
    l, r1, r2 = pt_mp
    K = _refine_K(params, C, M_gamma, mp.mpf(h), l, r1, r2, mp.mpf(g0), Kf)
    c = _consts(params)
    M, gam, R = chart_extension_mp([K, r1, r2, l, mp.mpf(g0)], _levels0(C, M_gamma))
    om = omega_from_K(c.A, c.d, gam, tuple(M[i] + c.ma * c.Omega * R[i] for i in range(3)))
    return np.array([_to_ld(v) for v in (*om, *gam, *R)], dtype=np.longdouble), K


def _first_return(params, state, g0, fp_type, tol, t_min):
    from ..sections import SectionOptions, poincare_section

    res = poincare_section("reduced", params, state, n_points=3, g0=g0, direction=1, fp_type=fp_type,
                           options=SectionOptions(tol=tol))
    keep = [i for i, t in enumerate(res.times) if t > t_min]
    if not keep:
        raise IntegrationError(f"no return to the section g = {g0!r} after t = {t_min!r} ({res.message})")
    i = keep[0]
    return res.states[i], float(res.times[i])


def return_map(params, *, C, M_gamma, h, point, K: Optional[float] = None, g0: float = 0.0,
               fp_type=np.longdouble, tol=None, t_min: float = 1e-6, dps: int = _DPS):
    """First return ``P(x)`` to ``g = g0`` (crossing direction +1) of the section point
    ``x = point = (l, r1, r2)`` on the branch ``K`` (see :func:`section_density`).

    The start state is built in mpmath (``K`` refined by Newton) and rounded to long
    double; the orbit is integrated by heyoka with event detection (crossings before
    ``t_min``, i.e. the start point itself, are skipped).

    Returns
    -------
    (Px, info) : ndarray (3,) ``(l, r1, r2)`` with ``l`` in ``[0, 2 pi)``, and a dict with
    ``K`` (start branch), ``K_image``, ``time``, ``state`` (the image state).
    """
    C, M_gamma = _check_levels(C, M_gamma)
    Kf = _pick_root(params, C, M_gamma, h, tuple(float(v) for v in point), g0, K, 1)
    mp = _mp()
    with mp.workdps(dps):
        st, Km = _start_state(params, C, M_gamma, h, g0, [mp.mpf(float(v)) for v in point], Kf)
    st1, t = _first_return(params, st, g0, fp_type, tol, t_min)
    with mp.workdps(dps):
        M, gam, R = _internal_of_public_mp(params, st1)
        y = chart_of_internal_mp(M, gam, R)
        Px = np.array([float(y[3]) % (2 * math.pi), float(y[1]), float(y[2])])
        return Px, {"K": float(Km), "K_image": float(y[0]), "time": t, "state": st1}


class _MapRun(NamedTuple):
    """The level, section and integration settings of one return-map evaluation."""

    params: BallParams
    C: float
    M_gamma: float
    h: float
    g0: float
    fp_type: FpTypeLike
    tol: Optional[float]
    t_min: float


def _image_chart(run: _MapRun, pt_mp, Kf):
    params, C, M_gamma, h, g0, fp_type, tol, t_min = run
    st, _ = _start_state(params, C, M_gamma, h, g0, pt_mp, Kf)
    st1, t = _first_return(params, st, g0, fp_type, tol, t_min)
    M, gam, R = _internal_of_public_mp(params, st1)
    y = chart_of_internal_mp(M, gam, R)
    return (y[3], y[1], y[2]), t, st1, y


_JAC_METHODS = ("fd", "variational")


def _check_method(method):
    if method not in _JAC_METHODS:
        raise UsageError(f"method must be one of {_JAC_METHODS} ('fd': central differences, 'variational': "
                         f"variational equations), got {method!r}")


def return_map_jacobian(params, *, C, M_gamma, h, point, K: Optional[float] = None, g0: float = 0.0,
                        step: float = 1e-4, fp_type=np.longdouble, tol=None, t_min: float = 1e-6,
                        dps: int = _DPS, method: str = "variational"):
    r"""Jacobian ``DP`` of the first-return map in ``(l, r1, r2)``.

    Parameters
    ----------
    method : {"variational", "fd"}
        ``"fd"``: central differences, ``DP[:, j] = (P(x + s e_j) - P(x - s e_j)) / (2 s)``
        (angles unwrapped) at ``s = step`` and at ``s = 2 step``; each perturbed start point
        takes the root ``K`` nearest the base point's ``K`` (branch followed by
        continuity). The difference of the two estimates, divided by 3 (central
        differences err like ``s^2``), estimates the truncation error of the first.
        ``"variational"`` (default): the first-order variational equations integrated
        along the orbit (see :func:`_variational_jacobian`); ``step`` is not used.
        Accurate to the rounding of ``fp_type`` amplified by the orbit (measured
        <= 1.3e-16 in long double against ~5e-13 for Richardson-extrapolated ``"fd"``)
        and about 6 times faster.

    Returns
    -------
    (Px, DP, info)
        ``Px`` ndarray (3,), ``DP`` ndarray (3, 3) (float64), and ``info`` with ``K``,
        ``K_image``, ``time``, ``state`` (public image state), ``y_image`` (its chart
        point, mpf), ``method``; for ``"fd"`` also ``DP2`` (at ``2 step``) and ``err``
        (max-entry error estimate ``|DP - DP2| / 3``); for ``"variational"`` also
        ``DP_mp`` (the 3x3 mpmath matrix, more digits than float64 holds), ``Phi`` (the
        9x9 state transition matrix, working type) and ``event_residual`` (the section
        event function at the image state).
    """
    _check_method(method)
    C, M_gamma = _check_levels(C, M_gamma)
    if not (isinstance(step, (int, float)) and step > 0):
        raise UsageError(f"step must be a float > 0, got {step!r}")
    base = tuple(float(v) for v in point)
    Kf = _pick_root(params, C, M_gamma, h, base, g0, K, 1)
    mp = _mp()
    if method == "variational":
        with mp.workdps(dps):
            return _variational_jacobian(_MapRun(params, C, M_gamma, h, g0, fp_type, tol, t_min),
                                         [mp.mpf(v) for v in base], Kf)
    with mp.workdps(dps):
        x0 = [mp.mpf(v) for v in base]
        P0, t0, st1, y1 = _image_chart(_MapRun(params, C, M_gamma, h, g0, fp_type, tol, t_min), x0, Kf)
        DPs = []
        for s in (step, 2 * step):
            s_mp = mp.mpf(s)
            DP = np.empty((3, 3))
            for j in range(3):
                imgs = []
                for sgn in (1, -1):
                    xx = list(x0)
                    xx[j] = xx[j] + sgn * s_mp
                    P, t, _, _ = _image_chart(_MapRun(params, C, M_gamma, h, g0, fp_type, tol, t_min), xx, Kf)
                    if abs(t - t0) > 0.5 * t0:
                        raise IntegrationError(
                            f"the perturbed orbit (step {s!r} along coordinate {j}) returned at t = {t!r}, the "
                            f"base orbit at t = {t0!r}: a different crossing; use a smaller step")
                    imgs.append([P0[0] + _wrap_pm(P[0] - P0[0]), P[1], P[2]])
                for i in range(3):
                    DP[i, j] = float((imgs[0][i] - imgs[1][i]) / (2 * s_mp))
            DPs.append(DP)
        Px = np.array([float(P0[0]) % (2 * math.pi), float(P0[1]), float(P0[2])])
        info = {"DP2": DPs[1], "err": float(np.max(np.abs(DPs[0] - DPs[1]))) / 3, "K": Kf,
                "K_image": float(y1[0]), "time": t0, "state": st1, "y_image": y1, "method": "fd"}
        return Px, DPs[0], info


# ---------------------------------------------------------------------------------------
# DP from the variational equations.
# ---------------------------------------------------------------------------------------
def _var_integrator(prob):
    """``(ts, ta)``: the reduced system with its first-order variational equations w.r.t.
    the initial state (:class:`taylorball.tangent.TangentSystem` with ``vectors="all"``) and
    a copy of its cached integrator (compact mode: the default mode takes minutes to
    compile, compact mode well under a second)."""
    import copy

    from ..tangent import TangentSystem

    ts = TangentSystem.of(prob, "all")
    return ts, copy.copy(ts.template(prob, compact_mode=True))


def _vec9(x):
    return tuple(x[0:3]), tuple(x[3:6]), tuple(x[6:9])


def _event_mp(x, g0):
    from ..charts import section_event_function

    M, gam, _ = _vec9(x)
    return section_event_function(M, gam, g0)


def _field_mp(c, x):
    from ..model import reduced_rhs

    return [v for part in reduced_rhs(c, *_vec9(x)) for v in part]


def _grad_mp(f, x):
    """Gradient of the scalar ``f`` at ``x`` (mpmath, fourth-order differences at 20 more
    digits: truncation ~h^4 = 10^-(dps+20), rounding ~10^-(3 (dps+20)/4))."""
    mp = _mp()
    with mp.workdps(mp.mp.dps + 20):
        cols = _jacobian_mp(lambda xx: [f(xx)], x, mp.mpf(10) ** (-(mp.mp.dps // 4)))
    return [col[0] for col in cols]


def _variational_jacobian(run: _MapRun, pt_mp, Kf):
    r"""``DP`` from the variational equations (mpmath at the current precision around a
    heyoka integration in ``fp_type``).

    With ``x0(p)`` the internal start state as a function of the chart point
    ``p = (l, r1, r2)`` (``K(p)`` from the energy equation, implicit function theorem:
    ``dK/dp = -(dE/dp)/(dE/dK)``), ``Phi = dx(tau)/dx0`` the state transition matrix to the
    return time ``tau``, ``f`` the vector field and ``e`` the section event function at the
    image ``x1``, the return time varies by ``dtau = -grad e . Phi dx0 / (grad e . f)``, so

    .. math:: DP = J_\mathrm{out}\,\Big(I - \frac{f\,\nabla e^T}{\nabla e\cdot f}\Big)\,\Phi\,J_\mathrm{in},

    ``J_in = dx0/dp`` (9x3), ``J_out = d(l, r1, r2)/dx`` at ``x1`` (3x9, the chart formulas of
    :func:`chart_of_internal_mp` on all of R^9). ``J_in``, ``J_out``, ``f``, ``grad e`` are
    evaluated in mpmath (fourth-order differences at 20 extra digits); ``tau`` is the
    crossing time of :func:`_first_return`, refined by Newton steps on ``e`` along the
    variational integration (the float64 time of the section result is ~1e-16 off).
    """
    params, C, M_gamma, h, g0, fp_type, tol, t_min = run
    from .._problem import problem
    from .._propagate import public_state, start_state

    mp = _mp()
    prob = problem("reduced", params, fp_type=fp_type, tol=tol)
    spec = prob.spec
    c = _consts(params)
    l, r1, r2 = pt_mp
    st, K = _start_state(params, C, M_gamma, h, g0, pt_mp, Kf)
    _, t_approx = _first_return(params, st, g0, fp_type, tol, t_min)
    system, pars, internal = prob.system, prob.pars, start_state(prob, st)

    # J_in: the start state on the section as a function of (l, r1, r2) at fixed levels
    lev = _levels0(C, M_gamma)
    y0 = [K, r1, r2, l]  # g = g0 fixed

    def start_and_energy(yy):
        y5 = list(yy) + [mp.mpf(g0)]
        M, gam, R = chart_extension_mp(y5, lev)
        return list(M) + list(gam) + list(R) + [energy_on_chart_mp(params, y5, C, M_gamma)]

    with mp.workdps(mp.mp.dps + 20):
        cols = _jacobian_mp(start_and_energy, y0, mp.mpf(10) ** (-(mp.mp.dps // 4)))
    dX = {name: cols[j] for j, name in enumerate(("K", "r1", "r2", "l"))}
    dEdK = dX["K"][9]
    if dEdK == 0:
        raise ChartError(f"dE/dK = 0 at the start point {tuple(map(float, pt_mp))!r}: K(l, r1, r2) is not "
                         "differentiable there (a double root of the energy equation)")
    J_in = mp.matrix(9, 3)
    for j, name in enumerate(("l", "r1", "r2")):
        ratio = dX[name][9] / dEdK
        for i in range(9):
            J_in[i, j] = dX[name][i] - dX["K"][i] * ratio

    # Phi to the return time
    ts, ta = _var_integrator(prob)
    ta.state[:] = np.concatenate([internal, ts.identity(spec)])
    ta.pars[:] = pars
    ta.time = spec.scalar(0.0)

    def advance(t):
        res = ta.propagate_until(t if not isinstance(t, float) else spec.scalar(t))
        if str(res[0]) != "taylor_outcome.time_limit":
            raise IntegrationError(f"the variational integration stopped at t = {float(ta.time)!r} before "
                                   f"t = {float(t)!r}: {res[0]}")

    advance(t_approx)
    ulp = spec.eps * max(1.0, abs(t_approx))
    for _ in range(4):
        x1 = [_to_mp(v) for v in ta.state[ts.x]]
        f1 = _field_mp(c, x1)
        ge = _grad_mp(lambda xx: _event_mp(xx, g0), x1)
        gf = mp.fsum(a * b for a, b in zip(ge, f1))
        if gf <= 0:
            raise IntegrationError(f"the return at t = {t_approx!r} does not cross g = {g0!r} upwards "
                                   f"(grad e . f = {float(gf)!r})")
        e1 = _event_mp(x1, g0)
        delta = e1 / gf
        if abs(delta) <= 4 * ulp:
            break
        if abs(delta) > 1e-6 * max(1.0, abs(t_approx)):
            raise IntegrationError(f"Newton step {float(delta)!r} on the return time {t_approx!r} is not small: "
                                   "the variational orbit does not follow the section orbit")
        advance(_from_mp(spec, _to_mp(ta.time) - delta))
    else:
        raise IntegrationError(f"Newton for the return time near {t_approx!r} did not converge "
                               f"(last step {float(delta)!r})")
    Phi_ld = ts.tangent_matrix(ta.state).copy()  # Phi[i, j] = dx_i(tau) / dx0_j
    Phi = mp.matrix([[_to_mp(v) for v in row] for row in Phi_ld])

    # J_out: (l, r1, r2) of the image state, l unwrapped around its value
    y1 = chart_of_internal_mp(*_vec9(x1))

    def chart3(xx):
        y = chart_of_internal_mp(*_vec9(xx))
        return [y1[3] + _wrap_pm(y[3] - y1[3]), y[1], y[2]]

    with mp.workdps(mp.mp.dps + 20):
        cols = _jacobian_mp(chart3, x1, mp.mpf(10) ** (-(mp.mp.dps // 4)))
    J_out = mp.matrix(3, 9)
    for j in range(9):
        for i in range(3):
            J_out[i, j] = cols[j][i]

    proj = mp.eye(9) - mp.matrix(f1) * mp.matrix(ge).T / gf
    DP_mp = J_out * proj * Phi * J_in
    DP = np.array([[float(DP_mp[i, j]) for j in range(3)] for i in range(3)])
    Px = np.array([float(y1[3]) % (2 * math.pi), float(y1[1]), float(y1[2])])
    st1 = public_state(system, pars, ta.state[ts.x], spec)
    info = {"K": Kf, "K_image": float(y1[0]), "time": float(_to_mp(ta.time)), "state": st1, "y_image": y1,
            "method": "variational", "DP_mp": DP_mp, "Phi": Phi_ld, "event_residual": float(e1)}
    return Px, DP, info


def volume_preservation_check(params, *, C, M_gamma, h, point, K: Optional[float] = None, g0: float = 0.0,
                              step: float = 1e-4, fp_type=np.longdouble, tol=None, dps: int = _DPS,
                              method: str = "variational"):
    r"""Check :math:`\sigma(P(x))\,|\det DP(x)| = \sigma(x)` at one section point.

    Parameters
    ----------
    method : {"variational", "fd"}
        How ``DP`` is computed (:func:`return_map_jacobian`; default ``"variational"``).

    Returns
    -------
    dict
        ``residual``: :math:`|\sigma(Px)|\det DP|/\sigma(x) - 1|` with the invariant
        density (evaluated in mpmath; with ``"variational"`` the determinant of the mpmath
        ``DP``); ``residual_unit_density``: ``||det DP| - 1|`` (``sigma = 1``, wrong);
        ``residual_rho9``: with :math:`\sigma' = |D|^{-1/2}|\dot g|/|\partial_K E|` (the
        chart factor :math:`1/((\gamma_1^2+\gamma_2^2)|\gamma_3|)` forgotten, wrong);
        ``det``, ``sigma_x``, ``sigma_Px``, ``Px``, ``DP``, ``K``, ``K_image``, ``time``,
        ``method``. With ``"fd"`` also ``residual_2step`` (``DP`` at twice the step),
        ``residual_richardson`` (with ``(4 DP(s) - DP(2 s)) / 3``, the ``s^2`` error term
        cancelled) and ``fd_error`` (the finite-difference error estimate of ``|det DP|``
        relative, ``|det DP - det DP2| / 3 / |det DP|``).
    """
    _check_method(method)
    C, M_gamma = _check_levels(C, M_gamma)
    Px, DP, info = return_map_jacobian(params, C=C, M_gamma=M_gamma, h=h, point=point, K=K, g0=g0, step=step,
                                       fp_type=fp_type, tol=tol, dps=dps, method=method)
    mp = _mp()
    with mp.workdps(dps):
        l, r1, r2 = (mp.mpf(float(v)) for v in point)
        K0 = _refine_K(params, C, M_gamma, mp.mpf(h), l, r1, r2, mp.mpf(g0), info["K"])
        y0 = [K0, r1, r2, l, mp.mpf(g0)]
        s0, _, _ = _sigma_mp(params, C, M_gamma, y0)
        # the image on the nominal levels (C, M_gamma) at its chart point and with g = g0
        y1 = list(info["y_image"])
        y1[4] = mp.mpf(g0)
        s1, _, _ = _sigma_mp(params, C, M_gamma, y1)

        def chartfac(y):
            _, gam, _ = chart_extension_mp(y, _levels0(C, M_gamma))
            return 4 * mp.mpf(C) * (gam[0] ** 2 + gam[1] ** 2) * abs(gam[2])

        w0, w1 = chartfac(y0), chartfac(y1)
        ratio = s1 / s0

        def det_mp(A):
            return abs(mp.det(mp.matrix([[mp.mpf(float(v)) for v in row] for row in A])))

        det = abs(mp.det(info["DP_mp"])) if method == "variational" else det_mp(DP)
        out = {
            "residual": float(abs(ratio * det - 1)),
            "residual_unit_density": float(abs(det - 1)),
            "residual_rho9": float(abs(s1 * w1 / (s0 * w0) * det - 1)),
            "det": float(det), "sigma_x": float(s0), "sigma_Px": float(s1), "Px": Px, "DP": DP,
            "K": info["K"], "K_image": info["K_image"], "time": info["time"], "method": method,
        }
        if method == "fd":
            det2 = det_mp(info["DP2"])
            detR = det_mp((4 * DP - info["DP2"]) / 3)
            out.update({
                "residual_2step": float(abs(ratio * det2 - 1)),
                "residual_richardson": float(abs(ratio * detR - 1)),
                "fd_error": float(abs(det - det2) / 3 / det),
            })
        return out


def volume_preservation_residual(params, **kwargs) -> float:
    r"""``|sigma(P x) |det DP(x)| / sigma(x) - 1|`` (see :func:`volume_preservation_check`;
    ``method=`` chooses how ``DP`` is computed)."""
    return volume_preservation_check(params, **kwargs)["residual"]
