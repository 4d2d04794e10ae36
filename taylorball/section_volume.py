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

The return map ``P`` is computed by heyoka event detection (:func:`taylorball.sections.poincare_section`)
in long double from initial states built in mpmath; its Jacobian ``DP`` by central finite
differences in ``(l, r1, r2)`` at two step sizes (the branch ``K`` of each perturbed start
point is the root nearest the base point's ``K``, refined by Newton in mpmath).
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from .errors import ChartError, IntegrationError, UsageError

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
    from .manifold import params_for
    from .model import ball_constants

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
    from .charts import _check_levels as chk

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
    from .model import reduced_rhs

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
    from .model import omega_from_K

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
    from .charts import states_on_section

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
    """Exact mpf of a float64 / long double number."""
    mp = _mp()
    hi = float(x)
    lo = float(np.longdouble(x) - np.longdouble(hi))
    return mp.mpf(hi) + mp.mpf(lo)


def _to_ld(v):
    """mpf -> long double (hi + lo)."""
    hi = float(v)
    return np.longdouble(hi) + np.longdouble(float(v - _mp().mpf(hi)))


def _internal_of_public_mp(params, state):
    from .model import K_from_omega

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
    from .model import omega_from_K

    mp = _mp()
    l, r1, r2 = pt_mp
    K = _refine_K(params, C, M_gamma, mp.mpf(h), l, r1, r2, mp.mpf(g0), Kf)
    c = _consts(params)
    M, gam, R = chart_extension_mp([K, r1, r2, l, mp.mpf(g0)], _levels0(C, M_gamma))
    om = omega_from_K(c.A, c.d, gam, tuple(M[i] + c.ma * c.Omega * R[i] for i in range(3)))
    return np.array([_to_ld(v) for v in (*om, *gam, *R)], dtype=np.longdouble), K


def _first_return(params, state, g0, fp_type, tol, t_min):
    from .sections import poincare_section

    res = poincare_section("reduced", params, state, n_points=3, g0=g0, direction=1, fp_type=fp_type, tol=tol)
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


def _image_chart(params, C, M_gamma, h, g0, pt_mp, Kf, fp_type, tol, t_min):
    st, _ = _start_state(params, C, M_gamma, h, g0, pt_mp, Kf)
    st1, t = _first_return(params, st, g0, fp_type, tol, t_min)
    M, gam, R = _internal_of_public_mp(params, st1)
    y = chart_of_internal_mp(M, gam, R)
    return (y[3], y[1], y[2]), t, st1, y


def return_map_jacobian(params, *, C, M_gamma, h, point, K: Optional[float] = None, g0: float = 0.0,
                        step: float = 1e-4, fp_type=np.longdouble, tol=None, t_min: float = 1e-6,
                        dps: int = _DPS):
    r"""Jacobian ``DP`` of the first-return map in ``(l, r1, r2)`` by central differences.

    ``DP[:, j] = (P(x + s e_j) - P(x - s e_j)) / (2 s)`` (angles unwrapped) at ``s = step``
    and at ``s = 2 step``; each perturbed start point takes the root ``K`` nearest the
    base point's ``K`` (branch followed by continuity). The difference of the two
    estimates, divided by 3 (central differences err like ``s^2``), estimates the
    truncation error of the first.

    Returns
    -------
    (Px, DP, info)
        ``Px`` ndarray (3,), ``DP`` ndarray (3, 3) at ``step``, and ``info`` with ``DP2``
        (at ``2 step``), ``err`` (max-entry error estimate ``|DP - DP2| / 3``), ``K``,
        ``K_image``, ``time``, ``state`` (image state), ``y_image`` (its chart point, mpf).
    """
    C, M_gamma = _check_levels(C, M_gamma)
    if not (isinstance(step, (int, float)) and step > 0):
        raise UsageError(f"step must be a float > 0, got {step!r}")
    base = tuple(float(v) for v in point)
    Kf = _pick_root(params, C, M_gamma, h, base, g0, K, 1)
    mp = _mp()
    with mp.workdps(dps):
        x0 = [mp.mpf(v) for v in base]
        P0, t0, st1, y1 = _image_chart(params, C, M_gamma, h, g0, x0, Kf, fp_type, tol, t_min)
        DPs = []
        for s in (step, 2 * step):
            s_mp = mp.mpf(s)
            DP = np.empty((3, 3))
            for j in range(3):
                imgs = []
                for sgn in (1, -1):
                    xx = list(x0)
                    xx[j] = xx[j] + sgn * s_mp
                    P, t, _, _ = _image_chart(params, C, M_gamma, h, g0, xx, Kf, fp_type, tol, t_min)
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
                "K_image": float(y1[0]), "time": t0, "state": st1, "y_image": y1}
        return Px, DPs[0], info


def volume_preservation_check(params, *, C, M_gamma, h, point, K: Optional[float] = None, g0: float = 0.0,
                              step: float = 1e-4, fp_type=np.longdouble, tol=None, dps: int = _DPS):
    r"""Check :math:`\sigma(P(x))\,|\det DP(x)| = \sigma(x)` at one section point.

    Returns
    -------
    dict
        ``residual``: :math:`|\sigma(Px)|\det DP|/\sigma(x) - 1|` with the invariant
        density; ``residual_2step``: the same with ``DP`` at twice the step;
        ``residual_richardson``: the same with ``(4 DP(s) - DP(2 s)) / 3`` (the ``s^2``
        error term cancelled);
        ``fd_error``: the finite-difference error estimate of ``|det DP|`` relative
        (``|det DP - det DP2| / 3 / |det DP|``); ``residual_unit_density``:
        ``||det DP| - 1|`` (``sigma = 1``, wrong); ``residual_rho9``: with
        :math:`\sigma' = |D|^{-1/2}|\dot g|/|\partial_K E|` (the chart factor
        :math:`1/((\gamma_1^2+\gamma_2^2)|\gamma_3|)` forgotten, wrong); ``det``,
        ``sigma_x``, ``sigma_Px``, ``Px``, ``K``, ``K_image``, ``time``.
    """
    C, M_gamma = _check_levels(C, M_gamma)
    Px, DP, info = return_map_jacobian(params, C=C, M_gamma=M_gamma, h=h, point=point, K=K, g0=g0, step=step,
                                       fp_type=fp_type, tol=tol, dps=dps)
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
        det = abs(float(np.linalg.det(DP)))
        det2 = abs(float(np.linalg.det(info["DP2"])))
        detR = abs(float(np.linalg.det((4 * DP - info["DP2"]) / 3)))
        ratio = float(s1 / s0)
        return {
            "residual": abs(ratio * det - 1),
            "residual_2step": abs(ratio * det2 - 1),
            "residual_richardson": abs(ratio * detR - 1),
            "fd_error": abs(det - det2) / 3 / det,
            "residual_unit_density": abs(det - 1),
            "residual_rho9": abs(float(s1 * w1 / (s0 * w0)) * det - 1),
            "det": det, "sigma_x": float(s0), "sigma_Px": float(s1), "Px": Px, "DP": DP,
            "K": info["K"], "K_image": info["K_image"], "time": info["time"],
        }


def volume_preservation_residual(params, **kwargs) -> float:
    r"""``|sigma(P x) |det DP(x)| / sigma(x) - 1|`` (see :func:`volume_preservation_check`)."""
    return volume_preservation_check(params, **kwargs)["residual"]
