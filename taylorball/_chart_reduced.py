r"""The section-4 chart of the reduced system and its inverse with ``K`` from the energy
(public from :mod:`taylorball.charts`, whose docstring describes the charts): the angle
``g`` and the section's event function, :func:`reduced_chart`,
:func:`reduced_state_from_chart`, :func:`states_on_section`, the root search and the
vectorised state search of a grid row (``_section_states``, with the sheet bookkeeping it
needs) that the sheets, the samplers and :func:`taylorball.megno_map` share.
"""

from __future__ import annotations

import math as _math
from typing import Any, Dict, Literal, Optional, Sequence, Tuple, overload

import numpy as _np
from numpy.typing import ArrayLike

from ._typing import FloatOrArray, Scalar, Vec3, VecLike
from ._vec import add as _add
from ._vec import dot, norm2, sqrt
from ._vec import scale as _scale
from .errors import ChartError, EmptyLevelError, UsageError
from .numbers import count, real_number
from .params import BallParams


def g_angle_parts(M: VecLike, gamma: VecLike) -> Tuple[Scalar, Scalar]:
    """Numerator and denominator of ``g`` (section 4): ``g = atan2(num, den)`` with
    ``num = C (M2 gamma1 - M1 gamma2)``, ``den = (M, gamma) M3 - C^2 gamma3``, where
    ``C = |M|``; both are of size ``C^2``."""
    C2 = norm2(M)
    num = sqrt(C2) * (M[1] * gamma[0] - M[0] * gamma[1])
    den = dot(M, gamma) * M[2] - C2 * gamma[2]
    return num, den


def section_event_function(M: VecLike, gamma: VecLike, g0: float = 0.0) -> Scalar:
    r"""Event function of the section ``g = g0``, scaled to order 1.

    .. math:: e = \frac{\mathrm{num}\cos g_0 - \mathrm{den}\sin g_0}{C^2}
              = \frac{\sqrt{\mathrm{num}^2 + \mathrm{den}^2}}{C^2}\,\sin(g - g_0)

    It vanishes on ``g = g0`` and on ``g = g0 + pi``; the crossings of ``g = g0`` are those
    where ``(num sin g0 + den cos g0) > 0``. It increases through zero when ``g``
    increases through ``g0``. ``|e| <= 1`` since ``num^2 + den^2 <= C^4``."""
    import math

    num, den = g_angle_parts(M, gamma)
    C2 = norm2(M)
    return (num * math.cos(g0) - den * math.sin(g0)) / C2


# =======================================================================================
# Inverse charts.
# =======================================================================================
# The angles l, g of the paper determine M (or K) and gamma on a level set. With
# ``k = K/C``, ``q = sqrt(1 - k^2)``, ``mu = M_gamma/C``, ``s = sqrt(1 - mu^2)`` and the
# orthonormal triple
#
#     Mhat = (q sin l, q cos l, k),  u = (-k sin l, -k cos l, q),  w = (-cos l, sin l, 0)
#
# (``u`` is the body's vertical axis e3 made orthogonal to M, ``w = e3 x Mhat / q``), the
# paper's definitions ``l = atan2(M1, M2)`` and
# ``g = atan2(C (M2 gamma1 - M1 gamma2), M_gamma K - C^2 gamma3)`` are inverted by
#
#     M = C Mhat,  gamma = mu Mhat - s (cos g u + sin g w),
#
# since then ``C (M2 gamma1 - M1 gamma2) = C^2 q s sin g`` and
# ``M_gamma K - C^2 gamma3 = C^2 q s cos g``. In components this is the Andoyer--Deprit
# chart of section 5 *with* a factor ``cos g`` in the second term of gamma1 and gamma2,
# which the paper omits (erratum E3: the printed gamma is not a unit vector off g = 0).
#: Below this, ``|gamma3|`` or ``sqrt(gamma1^2 + gamma2^2)`` make ``R`` unrecoverable from
#: ``(r1, r2)``: ``R3 = -r1/gamma3`` and ``|(R1, R2)| = |(r1, r2)|/|gamma_h|``, whose
#: absolute errors grow like ``eps |r| / tol^2`` (2e-8 |r| at 1e-4 in float64, while
#: ``|R|`` itself reaches ``|r| / tol``); closer to the singular set the chart is refused.
CHART_SINGULAR_TOL = 1e-4


def angles_to_vectors(C: FloatOrArray, M_gamma: float, K: FloatOrArray, l: FloatOrArray,
                      g: FloatOrArray) -> Tuple[Vec3, Vec3]:
    """``M`` and ``gamma`` from the chart values (works on numpy arrays, elementwise).

    Parameters
    ----------
    C : float
        ``|M| > 0`` (``G = |K|`` for the Andoyer--Deprit chart).
    M_gamma : float
        ``(M, gamma)``, with ``|M_gamma| <= C`` (``lambda`` in section 5).
    K : float or ndarray
        ``M3`` in ``[-C, C]`` (``L`` in section 5).
    l, g : float or ndarray
        The angles.

    Returns
    -------
    (M, gamma) : two 3-tuples
    """
    k = K / C
    q = _np.sqrt(_np.maximum(1.0 - k * k, 0.0))
    mu = M_gamma / C
    s = _np.sqrt(_np.maximum(1.0 - mu * mu, 0.0))
    sl, cl, sg, cg = _np.sin(l), _np.cos(l), _np.sin(g), _np.cos(g)
    Mhat = (q * sl, q * cl, k)
    gamma = (
        (mu * q + s * k * cg) * sl + s * sg * cl,
        (mu * q + s * k * cg) * cl - s * sg * sl,
        mu * k - s * q * cg,
    )
    return _scale(C, Mhat), gamma


def andoyer_deprit_printed(L: FloatOrArray, G: FloatOrArray, l: FloatOrArray, g: FloatOrArray,
                           lam: float) -> Tuple[Vec3, Vec3]:
    """The Andoyer--Deprit chart *as printed* in section 5 (for erratum E3; do not use).

    Returns ``(K, gamma)``; the printed ``gamma1, gamma2`` lack the factor ``cos g`` in
    their second term, so ``|gamma| != 1`` off ``g = 0``."""
    c = _np.sqrt(1.0 - (L / G) ** 2)
    s = _math.sqrt(1.0 - (lam / G) ** 2)
    a = lam / G * c + L / G * s
    K = (_np.sqrt(G * G - L * L) * _np.sin(l), _np.sqrt(G * G - L * L) * _np.cos(l), L)
    gamma = (a * _np.sin(l) + s * _np.sin(g) * _np.cos(l), a * _np.cos(l) - s * _np.sin(g) * _np.sin(l),
             lam * L / G**2 - c * s * _np.cos(g))
    return K, gamma


def _wrap(angle):
    """Angle(s) in ``[0, 2 pi)`` (``mod`` can round ``-tiny`` up to ``2 pi``)."""
    a = _np.mod(angle, 2 * _math.pi)
    a = _np.where(a >= 2 * _math.pi, 0.0, a)
    return a[()] if a.ndim == 0 else a  # a number for a number (it feeds g0= of the inverse)


def R_from_r(gamma: VecLike, r1: FloatOrArray, r2: FloatOrArray) -> Vec3:
    r"""``R`` with ``(R, gamma) = 0`` from ``r1 = R1 gamma1 + R2 gamma2``,
    ``r2 = R1 gamma2 - R2 gamma1`` (section 4):

    .. math:: R_1 = \frac{\gamma_1 r_1 + \gamma_2 r_2}{\gamma_1^2 + \gamma_2^2},\quad
              R_2 = \frac{\gamma_2 r_1 - \gamma_1 r_2}{\gamma_1^2 + \gamma_2^2},\quad
              R_3 = -\frac{r_1}{\gamma_3}.

    Raises
    ------
    ChartError
        Where ``|gamma3|`` or ``sqrt(gamma1^2 + gamma2^2)`` is below
        :data:`CHART_SINGULAR_TOL` (the plane is vertical in the body, or the body axis
        e3 is vertical): there ``(r1, r2)`` do not determine ``R``.
    """
    g1, g2, g3 = (_np.asarray(x, dtype=float) for x in gamma)
    rho2 = g1 * g1 + g2 * g2
    bad = (_np.abs(g3) < CHART_SINGULAR_TOL) | (rho2 < CHART_SINGULAR_TOL**2)
    if _np.any(bad):
        i = int(_np.argmax(_np.ravel(_np.broadcast_to(bad, _np.broadcast(g1, g3).shape))))
        b1, b2, b3 = (float(_np.ravel(_np.broadcast_to(v, bad.shape))[i]) for v in (g1, g2, g3))
        raise ChartError(
            f"R cannot be recovered from (r1, r2) where gamma = ({b1:.3g}, {b2:.3g}, {b3:.3g}): the section-4 chart needs |gamma3| >= {CHART_SINGULAR_TOL:g} and "
            f"sqrt(gamma1^2 + gamma2^2) >= {CHART_SINGULAR_TOL:g} (r1 = -R3 gamma3 and (r1, r2) are the "
            "horizontal components of R rotated by gamma's azimuth)"
        )
    return ((g1 * r1 + g2 * r2) / rho2, (g2 * r1 - g1 * r2) / rho2, -r1 / g3)


def _check_levels(C, M_gamma, name_C="C", name_Mg="M_gamma"):
    try:
        C, M_gamma = float(C), float(M_gamma)
    except (TypeError, ValueError):
        raise ChartError(f"{name_C} and {name_Mg} must be real numbers, got {C!r}, {M_gamma!r}") from None
    if not (_math.isfinite(C) and C > 0):
        raise ChartError(f"{name_C} = |M| must be a finite number > 0, got {C!r}")
    if not (_math.isfinite(M_gamma) and abs(M_gamma) < C):
        raise ChartError(
            f"{name_Mg} = (M, gamma) must satisfy |{name_Mg}| < {name_C} = {C!r}, got {M_gamma!r}"
            + ("; |M_gamma| = C means M || gamma: use kind='mparallel' (section 5)" if abs(M_gamma) == C else "")
        )
    return C, M_gamma


def _ball(params):
    from .manifold import params_for

    return params_for("reduced", params)


def reduced_state_from_chart(params: BallParams, *, C: float, M_gamma: float, K: ArrayLike, l: FloatOrArray,
                             g: FloatOrArray, r1: FloatOrArray, r2: FloatOrArray) -> _np.ndarray:
    """Public reduced state(s) ``(omega, gamma, R)`` from the section-4 chart values.

    ``omega = Itilde^{-1}(M + m a Omega R)`` (paper eq. (11) [eq13]). Inputs may be numpy arrays of one
    shape (vectorised); the result has shape ``(..., 9)``.

    Raises
    ------
    ChartError
        Bad levels, ``|K| > C``, or a point where ``R`` is not determined (see
        :func:`R_from_r`).
    """
    from .model import ball_constants, omega_from_K

    params = _ball(params)
    C, M_gamma = _check_levels(C, M_gamma)
    K = _np.asarray(K, dtype=float)
    if _np.any(_np.abs(K) > C):
        raise ChartError(f"K = M3 must lie in [-C, C] = [{-C!r}, {C!r}], got {K!r}")
    M, gamma = angles_to_vectors(C, M_gamma, K, l, g)
    R = R_from_r(gamma, r1, r2)
    c = ball_constants(params.pars)
    omega = omega_from_K(c.A, c.d, gamma, _add(M, _scale(c.ma * c.Omega, R)))
    cols = _np.broadcast_arrays(*omega, *gamma, *R)
    return _np.stack(cols, axis=-1)


def reduced_chart(params: BallParams, state: ArrayLike) -> Dict[str, Any]:
    """Section-4 chart of reduced state(s): ``dict`` with ``K, r1, r2, l, g`` and the
    levels ``C, M_gamma`` of the state itself (angles in ``[0, 2 pi)``).

    Raises
    ------
    ChartError
        At the chart's singular points: ``M`` along the body axis e3 (``l`` and ``g``
        undefined) or ``M`` parallel to ``gamma`` (``g`` undefined).

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> chart = tb.reduced_chart(FIG4_BALL, demo_reduced_state())
    >>> {k: round(float(v), 6) for k, v in chart.items()}
    {'K': 1.848131, 'r1': 0.1, 'r2': 0.55, 'l': 5.313081, 'g': 2.615099, 'C': 12.350251, 'M_gamma': 1.33923}
    """
    from ._integrals import state_vectors
    from .manifold import as_state
    from .model import get_system

    params = _ball(params)
    x = _np.asarray(as_state("reduced", state), dtype=float)
    system = get_system("reduced", "omega")
    c = system.constants(params.pars)
    v = state_vectors(system, c, tuple(x[..., i] for i in range(9)))
    M, gamma, R = v["M"], v["gamma"], v["R"]
    C2 = norm2(M)
    C = _np.sqrt(C2)
    if _np.any(C == 0):
        raise ChartError("the section-4 chart needs M != 0 (|M| = C > 0); this state has M = 0")
    num, den = g_angle_parts(M, gamma)
    horiz = _np.hypot(M[0], M[1])
    if _np.any(horiz <= 1e-12 * C) or _np.any(_np.hypot(num, den) <= 1e-12 * C2):
        raise ChartError(
            "the section-4 chart is singular at this state: M is along the body axis e3 (l, g undefined) "
            "or parallel to gamma (g undefined; that is the M || gamma case of section 5); g needs "
            "sin(M, e3) sin(M, gamma) > 1e-12"
        )
    return {
        "K": M[2],
        "r1": R[0] * gamma[0] + R[1] * gamma[1],
        "r2": R[0] * gamma[1] - R[1] * gamma[0],
        "l": _wrap(_np.arctan2(M[0], M[1])),
        "g": _wrap(_np.arctan2(num, den)),
        "C": C,
        "M_gamma": dot(M, gamma),
    }


# ---------------------------------------------------------------------------------------
# Section 4: K from the energy.
# ---------------------------------------------------------------------------------------
def _check_point(point, n, names):
    try:
        p = tuple(float(v) for v in point)
    except (TypeError, ValueError):
        raise ChartError(f"point must be {n} numbers {names}, got {point!r}") from None
    if len(p) != n or not all(_math.isfinite(v) for v in p):
        raise ChartError(f"point must be {n} finite numbers {names}, got {point!r}")
    return p


def _check_g0(g0):
    return real_number("g0 (an angle)", g0)


#: Grid sizes of the root searches: at least 3 points (an interior point to find double
#: roots), at most 1e7 (each point is one evaluation of the energy, vectorised).
N_GRID_MIN, N_GRID_MAX = 3, 10_000_000


def _check_grid(n_grid):
    return count("n_grid", n_grid, lo=N_GRID_MIN, hi=N_GRID_MAX)


def _check_direction(direction):
    if not (direction is None or (isinstance(direction, (int, _np.integer)) and not isinstance(direction, bool)
                                  and direction in (1, -1))):
        raise UsageError(f"direction must be None, +1 or -1, got {direction!r}")


def _rng(seed):
    """numpy's Generator for a seed: a non-negative integer, None, a Generator or a SeedSequence."""
    if not (seed is None or isinstance(seed, (_np.random.Generator, _np.random.SeedSequence))
            or (isinstance(seed, (int, _np.integer)) and not isinstance(seed, bool) and seed >= 0)):
        raise UsageError(f"seed must be a non-negative integer, None or a numpy Generator, got {seed!r}")
    return _np.random.default_rng(seed)


def _check_h(h, name="h"):
    """An energy level: a finite real number (else no level set is meant at all)."""
    return real_number(f"{name} (the energy level)", h, error=ChartError)


def _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g, theta, with_gdot=True, refuse=True):
    """Energy ``E`` and (if asked) ``dg/dt`` of the reduced system on the chart point, with
    ``K = C cos(theta)`` (arrays over theta). NaN where ``R`` is not determined: within
    :data:`CHART_SINGULAR_TOL` of the singular set, or (``refuse=False``, for counting the
    roots there, :func:`_pole_roots`) only on it."""
    from .model import ball_constants, omega_from_K, reduced_rhs

    K = C * _np.cos(theta)
    M, gamma = angles_to_vectors(C, M_gamma, K, l, g)
    g1, g2, g3 = gamma
    rho2 = g1 * g1 + g2 * g2
    tol = CHART_SINGULAR_TOL if refuse else 0.0
    ok = (_np.abs(g3) > 0.0) & (rho2 > 0.0) & (_np.abs(g3) >= tol) & (rho2 >= tol**2)
    with _np.errstate(divide="ignore", invalid="ignore"):
        R = ((g1 * r1 + g2 * r2) / rho2, (g2 * r1 - g1 * r2) / rho2, -r1 / g3)
    c = ball_constants(params.pars)
    Kvec = _add(M, _scale(c.ma * c.Omega, R))
    omega = omega_from_K(c.A, c.d, gamma, Kvec)
    E = dot(omega, Kvec) / 2 - c.m * c.Omega**2 * norm2(R) / 2
    if not with_gdot:
        return _np.where(ok, E, _np.nan), None
    Md, gd, _ = reduced_rhs(c, M, gamma, R)
    num, den = g_angle_parts(M, gamma)
    dnum = C * (Md[1] * g1 + M[1] * gd[0] - Md[0] * g2 - M[0] * gd[1])
    dden = M_gamma * Md[2] - C * C * gd[2]
    with _np.errstate(divide="ignore", invalid="ignore"):
        gdot = (dnum * den - num * dden) / (num * num + den * den)
    return _np.where(ok, E, _np.nan), _np.where(ok, gdot, _np.nan)


def _roots_1d(f, lo, hi, n_grid):
    """All roots of a scalar function ``f`` (vectorised) on ``[lo, hi]``: sign changes on
    a grid of ``n_grid`` points, refined by vectorised bisection to the last bit, plus
    double roots found as grid extrema of ``|f|`` refined by golden-section search and
    kept when ``f`` vanishes there to rounding. Values NaN (singular points) never bracket
    a root. Returns ``(roots, multiplicity)`` arrays (:func:`_roots_many` of one function)."""
    return _roots_many(lambda which, x: f(x), 1, lo, hi, n_grid)[0]


def _grid_brackets(f, n_fun, lo, hi, n_grid):
    """The bracketing step of the root searches (:func:`_roots_many`, and
    :func:`section_sheet`, which needs only the brackets): ``n_fun`` functions on the grid
    ``x = linspace(lo, hi, n_grid)``, ``f(which, x)`` evaluating function ``which[i]`` at
    ``x[i]``. Returns ``(x, which, X, y, finite, exact, sc)``: the grid, the function index
    and abscissa of every grid value (arrays ``(n_fun, n_grid)``), the values ``y``, where
    they are finite, where they are exactly zero, and ``sc`` ``(n_fun, n_grid - 1)``: a sign
    change between grid points ``j`` and ``j + 1`` (NaN, a singular point, brackets none)."""
    x = _np.linspace(lo, hi, n_grid)
    which_grid = _np.repeat(_np.arange(n_fun), n_grid).reshape(n_fun, n_grid)
    X = _np.broadcast_to(x, (n_fun, n_grid))
    y = f(which_grid, X)
    finite = _np.isfinite(y)
    exact = finite & (y == 0)
    sc = finite[:, :-1] & finite[:, 1:] & (y[:, :-1] * y[:, 1:] < 0)
    return x, which_grid, X, y, finite, exact, sc


def _roots_many(f, n_fun, lo, hi, n_grid):
    """:func:`_roots_1d` of ``n_fun`` functions at once: ``f(which, x)`` evaluates function
    ``which[i]`` at ``x[i]`` (arrays of one shape). Each function's roots are those
    :func:`_roots_1d` finds for it alone, bit for bit: the same elementwise evaluations,
    its own scale, and its golden-section brackets frozen from the iteration at which all
    of them converged (where the search of that function alone stops). Returns a list of
    ``(roots, multiplicity)`` per function."""
    x, which_grid, X, y, finite, exact, sc = _grid_brackets(f, n_fun, lo, hi, n_grid)
    any_finite = finite.any(axis=1)
    scale = _np.where(any_finite, _np.fmax.reduce(_np.abs(y), axis=1), 1.0)  # NaN ignored (not inf)
    tiny = _np.maximum(scale, 1e-300)
    roots = [[] for _ in range(n_fun)]
    mult = [[] for _ in range(n_fun)]

    def add(w, r, m):
        for wi, ri in zip(w, r):
            roots[wi].append(ri)
            mult[wi].append(m)

    add(which_grid[exact], X[exact], 1)
    a, b, wb = X[:, :-1][sc], X[:, 1:][sc], which_grid[:, :-1][sc]
    if a.size:
        m, keep = _bisect(f, wb, a, b, y[:, :-1][sc], tiny)
        add(wb[keep], m[keep], 1)
    # tangencies: interior grid minima of |f| that do not bracket a sign change, refined by
    # golden-section search on all of them at once (one evaluation of f per iteration)
    ay = _np.where(finite, _np.abs(y), _np.inf)
    i = _np.arange(1, n_grid - 1)
    cand = (_np.isfinite(ay[:, i]) & (ay[:, i] <= ay[:, i - 1]) & (ay[:, i] <= ay[:, i + 1]) & (y[:, i] != 0)
            & ~(y[:, i - 1] * y[:, i] < 0) & ~(y[:, i] * y[:, i + 1] < 0))
    wt, it = _np.nonzero(cand)
    it = i[it]
    if it.size:
        def af(w, v):
            fv = f(w, v)
            return _np.where(_np.isfinite(fv), _np.abs(fv), _np.inf)

        gr = (_math.sqrt(5) - 1) / 2
        p, q = x[it - 1], x[it + 1]
        c1, c2 = q - gr * (q - p), p + gr * (q - p)
        f1, f2 = af(_np.concatenate([wt, wt]), _np.concatenate([c1, c2])).reshape(2, -1)
        active = _np.ones(it.size, dtype=bool)
        for _ in range(100):  # the bracket shrinks by 0.618 per step: 2 grid steps -> ulp in ~75
            conv = q - p <= 4 * _np.spacing(_np.maximum(_np.abs(p), _np.abs(q)))
            # a function's search stops when all its brackets have converged
            done = _np.bincount(wt, weights=~conv, minlength=n_fun) == 0
            active = ~done[wt]
            if not active.any():
                break
            left = f1 < f2  # the minimum is in [p, c2]: drop (c2, q]; else drop [p, c1)
            q_new = _np.where(left, c2, q)
            p_new = _np.where(left, p, c1)
            new = _np.where(left, q_new - gr * (q_new - p_new), p_new + gr * (q_new - p_new))
            fn = af(wt, new)
            c1_new, c2_new = _np.where(left, new, c2), _np.where(left, c1, new)
            f1_new, f2_new = _np.where(left, fn, f2), _np.where(left, f1, fn)
            p, q = _np.where(active, p_new, p), _np.where(active, q_new, q)
            c1, c2 = _np.where(active, c1_new, c1), _np.where(active, c2_new, c2)
            f1, f2 = _np.where(active, f1_new, f1), _np.where(active, f2_new, f2)
        xm = 0.5 * (p + q)
        ok = af(wt, xm) <= 1e-12 * tiny[wt]
        add(wt[ok], xm[ok], 2)
    out = []
    for r, mu in zip(roots, mult):
        order = _np.argsort(r)
        out.append((_np.asarray(r, dtype=float)[order], _np.asarray(mu, dtype=int)[order]))
    return out


def _bisect(f, wb, a, b, fa, tiny):
    """Vectorised bisection of the sign-change brackets ``[a, b]`` of the functions ``wb``
    (``fa = f(wb, a)``) to the last bit. Returns ``(m, keep)``: the roots, and where ``f``
    is small there (a sign change across a pole, ``f -> +-inf``, is no root): ``|f(m)| <=
    1e-9 tiny[wb]``, ``tiny`` each function's scale."""
    for _ in range(200):
        m = 0.5 * (a + b)
        if _np.all((m == a) | (m == b)):
            break
        fm = f(wb, m)
        left = _np.sign(fm) == _np.sign(fa)
        a, fa = _np.where(left, m, a), _np.where(left, fm, fa)
        b = _np.where(left, b, m)
    m = 0.5 * (a + b)
    fm = f(wb, m)
    return m, _np.isfinite(fm) & (_np.abs(fm) <= 1e-9 * tiny[wb])


#: The root search next to a pole of the energy equation (:func:`_pole_brackets`): the
#: last ``_POLE_STEPS`` grid steps on each side of a pole, and at least ``_POLE_WIDTH``
#: radians in theta (ten times the zone the chart refuses, ``|gamma3| <
#: CHART_SINGULAR_TOL``, where ``|d gamma3 / d theta|`` is near 1, as on ``g0 = 0``), are
#: searched again on points approaching the pole geometrically, by the factor
#: ``_POLE_RATIO`` per point, down to ``_POLE_DEPTH`` (radians, ~``|gamma3|`` there).
_POLE_STEPS = 2
_POLE_WIDTH = 10 * CHART_SINGULAR_TOL
_POLE_RATIO = 2.0**-0.5
_POLE_DEPTH = 1e-12


def _pole_windows(x, poles):
    """The windows of the uniform grid ``x`` next to each pole ``theta_p`` strictly inside
    it, one per side: ``(lo, hi, sub)`` with ``(lo, hi)`` the open window (from the grid
    point ``_POLE_STEPS`` steps, or ``_POLE_WIDTH``, away to the pole) and ``sub`` its ascending sub-grid (the
    grid point, then points at ``w r^k`` from the pole, the last ``_POLE_DEPTH`` or more
    away)."""
    out = []
    for tp in poles:
        if not (x[0] < tp < x[-1]):
            continue
        j = int(_np.searchsorted(x, tp, side="right"))  # x[j - 1] <= tp < x[j]
        steps = max(_POLE_STEPS, int(_math.ceil(_POLE_WIDTH / (x[1] - x[0]))))
        lo = x[max(j - steps, 0)] if x[j - 1] < tp else x[max(j - 1 - steps, 0)]
        hi = x[min(j + steps - 1, x.size - 1)]
        for edge, sgn in ((lo, -1.0), (hi, 1.0)):
            w = abs(tp - edge)
            n = int(_math.floor(_math.log(_POLE_DEPTH / w) / _math.log(_POLE_RATIO))) if w > _POLE_DEPTH else 0
            d = w * _POLE_RATIO ** _np.arange(1, n + 1)
            sub = _np.concatenate([[edge], tp + sgn * d])
            out.append((lo, tp, sub) if sgn < 0 else (tp, hi, sub[::-1]))
    return out


def _pole_brackets(f, n_fun, x, poles):
    """Sign changes of the ``n_fun`` functions ``f(which, theta)`` on the sub-grids next to
    the poles (:func:`_pole_windows` of the uniform grid ``x``): where the roots of the
    energy equation crowd as ``r1 -> 0`` (``K*``) or ``(r1, r2) -> 0`` (``K**``), closer
    to each other and to the pole than a grid step. ``f`` should not refuse the singular
    set's neighbourhood (``refuse=False``), so that roots there are counted too. Returns
    ``(windows, brackets)``: the ``(lo, hi)`` of each window, and ``(win, rows, a, b, ya,
    yb)`` arrays over the brackets (the window, the function, the ends, the values)."""
    wins = _pole_windows(x, poles)
    parts = []
    for k, (_, _, sub) in enumerate(wins):
        which = _np.repeat(_np.arange(n_fun), sub.size).reshape(n_fun, sub.size)
        y = f(which, _np.broadcast_to(sub, (n_fun, sub.size)))
        sc = _np.isfinite(y[:, :-1]) & _np.isfinite(y[:, 1:]) & (y[:, :-1] * y[:, 1:] < 0)
        rows, j = _np.nonzero(sc)
        parts.append((_np.full(rows.size, k), rows, sub[j], sub[j + 1], y[rows, j], y[rows, j + 1]))
    if not parts:
        e = _np.empty(0)
        return [], (e.astype(int), e.astype(int), e, e, e, e)
    return [(lo, hi) for lo, hi, _ in wins], tuple(_np.concatenate(c) for c in zip(*parts))


def _pole_roots(f, n_fun, x, poles):
    """The roots of ``f`` in the windows next to the poles (:func:`_pole_brackets`),
    bisected to the last bit: ``(windows, win, rows, roots)``. A sub-grid stays on one side
    of its pole, where ``f`` is continuous: every sign change there brackets a root."""
    wins, (win, rows, a, b, ya, _) = _pole_brackets(f, n_fun, x, poles)
    if not rows.size:
        return wins, win, rows, a
    m, keep = _bisect(f, rows, a, b, ya, _np.full(n_fun, _np.inf))
    return wins, win[keep], rows[keep], m[keep]


@overload
def states_on_section(params: BallParams, *, C: float, M_gamma: float, h: float, point: Sequence[float],
                      g0: float = 0.0, direction: Optional[Literal[-1, 1]] = None, n_grid: int = 2001,
                      return_info: Literal[False] = False) -> _np.ndarray: ...
@overload
def states_on_section(params: BallParams, *, C: float, M_gamma: float, h: float, point: Sequence[float],
                      g0: float = 0.0, direction: Optional[Literal[-1, 1]] = None, n_grid: int = 2001,
                      return_info: Literal[True]) -> Tuple[_np.ndarray, Dict[str, _np.ndarray]]: ...
@overload
def states_on_section(params: BallParams, *, C: float, M_gamma: float, h: float, point: Sequence[float],
                      g0: float = 0.0, direction: Optional[Literal[-1, 1]] = None, n_grid: int = 2001,
                      return_info: bool) -> _np.ndarray | Tuple[_np.ndarray, Dict[str, _np.ndarray]]: ...
def states_on_section(params: BallParams, *, C: float, M_gamma: float, h: float, point: Sequence[float],
                      g0: float = 0.0, direction: Optional[Literal[-1, 1]] = None, n_grid: int = 2001,
                      return_info: bool = False) -> _np.ndarray | Tuple[_np.ndarray, Dict[str, _np.ndarray]]:
    r"""Every reduced state on the level set ``|M| = C``, ``(M, gamma) = M_gamma``,
    ``E = h`` with section-4 chart point ``point = (l, r1, r2)`` on the section ``g = g0``.

    ``K = M3`` is the unknown: the energy equation ``E(K; l, r1, r2, g0) = h`` can have no,
    one or several roots in ``[-C, C]``. They are found reliably by parametrising
    ``K = C cos(theta)`` (``E`` is smooth in ``theta`` on ``[0, pi]``, including the
    poles ``K = +-C``), bracketing sign changes on ``n_grid`` points, bisecting to the last
    bit, and searching grid extrema for double roots. Next to the poles of the energy
    equation (``K*``, where ``gamma3 = 0``, and ``K**``, where ``gamma = -e3``), where the
    roots crowd closer than a grid step as ``r1 -> 0``, they are bracketed again on points
    approaching the pole geometrically (docs/chaos.md, "Sheets").

    Parameters
    ----------
    params : BallParams
    C, M_gamma, h : float
        The levels ``|M|``, ``(M, gamma)``, ``E`` (the paper's captions: ``G``, ``H``,
        ``h``).
    point : (l, r1, r2)
    g0 : float
        The section angle.
    direction : {None, +1, -1}
        Keep only the states where ``g`` crosses ``g0`` increasing (+1) or decreasing
        (-1); ``None`` keeps all. The branch of each root is the sign of ``dg/dt`` there.
    return_info : bool
        Also return a dict with ``K``, ``g_dot``, ``multiplicity``, ``orientation`` (the
        sign of ``gamma3 dE/dK``), ``sheet`` (the sheet label of :func:`section_sheet`
        with ``label="sheet"``) and ``root`` (the index among all the roots, in increasing
        ``K``) per state, and ``refused_K``: the roots the chart refuses (within
        ``CHART_SINGULAR_TOL`` of ``gamma3 = 0`` or ``gamma = -+e3``, where ``R`` is not
        recovered from ``(r1, r2)``), which give no state but keep their place in
        ``root`` and ``sheet``.

    Returns
    -------
    states : ndarray, shape (n, 9)
        Public reduced states ``(omega, gamma, R)``, ordered by ``K``.

    Raises
    ------
    ChartError
        Bad levels or point.
    EmptyLevelError
        When no state has this chart point on this level set (the point is outside the
        admissible region, see :func:`section_admissible_sample`), or none in the
        requested ``direction``.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> xs, info = tb.states_on_section(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), point=(2.0, 2.5, 1.0),
    ...                                 return_info=True)
    >>> xs.shape                                   # two roots K of the energy equation
    (2, 9)
    >>> info["K"].round(4), info["g_dot"] > 0      # both cross g = 0 increasing
    (array([-0.4552,  9.1645]), array([ True,  True]))
    >>> d = tb.integrals("reduced", FIG4_BALL, xs)    # |M|^2 = C^2, (M, gamma), E: on the level
    >>> d["C2"].round(9), d["M_gamma"].round(9), d["E"].round(9)
    (array([100., 100.]), array([2., 2.]), array([5., 5.]))
    >>> chart = tb.reduced_chart(FIG4_BALL, xs)
    >>> chart["l"].round(9), chart["r1"].round(9), chart["r2"].round(9)
    (array([2., 2.]), array([2.5, 2.5]), array([1., 1.]))
    """
    params = _ball(params)
    C, M_gamma = _check_levels(C, M_gamma)
    l, r1, r2 = _check_point(point, 3, "(l, r1, r2)")
    g0 = _check_g0(g0)
    h = _check_h(h)
    n_grid = _check_grid(n_grid)
    _check_direction(direction)

    found = _section_states(params, C, M_gamma, h, l, [r1], [r2], g0, direction, n_grid)[0]
    if isinstance(found, ChartError):
        raise found
    states, info = found
    if len(states) == 0:
        which = "" if direction is None else f" with g crossing g0 in direction {direction:+d}"
        raise EmptyLevelError(
            f"no reduced state has chart point (l, r1, r2) = {point!r} on the section g = {g0!r}{which} "
            f"of the level set C = {C!r}, M_gamma = {M_gamma!r}, h = {h!r}: E(K) = h has no root K in "
            "[-C, C]; pick a point in the admissible region (taylorball.charts.section_admissible_sample)"
        )
    if return_info:
        return states, info
    return states


#: Relative distance from the given levels (and from ``g = g0``, in radians) beyond which
#: :func:`section_sheet` refuses a state: far above the drift of integrated crossings (at
#: most ~1e-12 of the scale in the figures), far below anything that could be a
#: different level.


def _degenerate_K(C, M_gamma, g0):
    r"""``K*``: the root ``K`` at which ``gamma3 = 0`` on the section ``g = g0`` of the level
    ``(C, M_gamma)`` (the pole of the energy equation, where ``R3 = -r1/gamma3``).

    On the chart, ``gamma3 = mu k - s q cos g0`` (``k = K/C``, ``q = sqrt(1 - k^2)``,
    ``mu = M_gamma/C``, ``s = sqrt(1 - mu^2)``), which vanishes in ``(-C, C)`` only at
    ``k* = sign(mu) s cos g0 / sqrt(mu^2 + s^2 cos^2 g0)`` (``K* = sqrt(C^2 - M_gamma^2)``
    on ``g0 = 0``, ``M_gamma > 0``), whatever ``l, r1, r2``. For ``M_gamma = 0`` it
    vanishes only at the poles ``K = +-C`` (or everywhere, on ``cos g0 = 0``, where the
    chart is singular): ``C`` is returned."""
    mu = M_gamma / C
    s = _math.sqrt(max(1.0 - mu * mu, 0.0))
    c = _math.cos(g0)
    if mu == 0.0:
        return C
    return C * _math.copysign(1.0, mu) * s * c / _math.hypot(mu, s * c)


def _sheet_poles(C, M_gamma, g0):
    r"""The poles of the energy equation in ``K`` on the section ``g = g0``: ``(K*, K**)``.

    ``K*`` (:func:`_degenerate_K`): ``gamma3 = 0``, ``R3 = -r1/gamma3``; a sheet crosses it
    only where ``r1 = 0``. ``K**``: ``gamma1 = gamma2 = 0``, ``|(R1, R2)| = |(r1, r2)| /
    |(gamma1, gamma2)|``; only on ``cos g0 = +-1`` (elsewhere ``|gamma3| <= sqrt(mu^2 + s^2
    cos^2 g0) < 1``), at ``K** = -M_gamma cos g0``. As ``|R|`` is bounded on a level (the
    Jacobi integral, errata N1), no sheet crosses ``K**`` away from ``r1 = r2 = 0``. ``None``
    for ``K**`` where there is none."""
    c = _math.cos(g0)
    far = -M_gamma * c if abs(c) == 1.0 else None
    return _degenerate_K(C, M_gamma, g0), far


def _side(K, K_star, K_far):
    """0 for ``K`` on the side of ``K**`` where ``K*`` is (or no ``K**``), 1 beyond it."""
    K = _np.asarray(K, dtype=float)
    if K_far is None:
        return _np.zeros(K.shape, dtype=int)
    return ((K - K_far) * (K_star - K_far) < 0).astype(int)


def _orientation(params, C, M_gamma, l, r1, r2, g0, th):
    """Orientation of the states ``K = C cos(th)`` at the chart points ``(l, r1, r2)``:
    ``sign(gamma3 dE/dK)`` (+1 or -1; +1 where it is zero or undetermined, at a fold or a
    singular point), ``dE/dK`` by a central difference in ``theta`` of step
    :data:`_SIGMA_DTHETA` (its sign is what counts), or a quarter of the distance to a pole
    of the energy equation where that is smaller (a root next to a pole)."""
    d = _np.full(_np.shape(th), _SIGMA_DTHETA)
    for k in _sheet_poles(C, M_gamma, g0):
        if k is not None:
            d = _np.minimum(d, 0.25 * _np.abs(th - _math.acos(k / C)))
    ep = _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g0, th + d, with_gdot=False, refuse=False)[0]
    em = _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g0, th - d, with_gdot=False, refuse=False)[0]
    _, gam = angles_to_vectors(C, M_gamma, C * _np.cos(th), l, g0)
    # dE/dK = (ep - em) / (2 d) / (-C sin th), sin th > 0 inside (0, pi)
    s = -(ep - em) * _np.asarray(gam[2])
    return _np.where(s < 0, -1, 1)


def _sheet_labels(K, orient, K_star, K_far):
    """Sheet labels of the roots ``K`` at one chart point (:func:`section_sheet` with
    ``label="sheet"``): ``4 rank + 2 side + (orient < 0)``, ``side`` that of ``K**``
    (:func:`_side`), ``rank`` the position of the root among those of its side and
    orientation ordered by ``|K - K*|`` (ties: by ``K``)."""
    K, orient = _np.asarray(K, dtype=float), _np.asarray(orient)
    side = _side(K, K_star, K_far)
    labels = _np.empty(K.size, dtype=int)
    for sd in (0, 1):
        for o in (1, -1):
            idx = _np.flatnonzero((orient == o) & (side == sd))
            order = _np.lexsort((K[idx], _np.abs(K[idx] - K_star)))
            labels[idx[order]] = 4 * _np.arange(idx.size) + 2 * sd + (o < 0)
    return labels


def _section_states(params, C, M_gamma, h, l, r1, r2, g0, direction, n_grid):
    """The work of :func:`states_on_section` (checked arguments) for the chart points
    ``(l, r1[i], r2[i])`` of one slice ``l`` at once, or ``(l[i], r1[i], r2[i])`` with ``l``
    an array of one angle per point (the root search vectorised over the points,
    :func:`_roots_many`; each point's states are bit-identical to a search of its own).
    Next to the poles of the energy equation the roots are searched again on a sub-grid
    (:func:`_pole_roots`), and where it finds more or fewer roots than the grid there, its
    roots replace the grid's. Returns per point ``(states (n, 9), info)`` ordered by ``K``
    (``n = 0`` where the point carries no state in ``direction``), or the
    :class:`ChartError` of that point. A root the chart refuses (within
    :data:`CHART_SINGULAR_TOL` of the singular set, where ``R`` is not recovered) gives no
    state, but keeps its place: ``info["root"]`` is each state's index among all the roots
    (in increasing ``K``), ``info["sheet"]`` its label among all of them, and
    ``info["refused_K"]`` holds the refused roots' ``K``."""
    r1 = _np.asarray(r1, dtype=float).reshape(-1)
    r2 = _np.asarray(r2, dtype=float).reshape(-1)
    per_point = _np.ndim(l) > 0
    ls = _np.asarray(l, dtype=float).reshape(-1) if per_point else None

    def f(which, th, refuse=True):
        lw = ls[which] if ls is not None else l
        return _reduced_energy_theta(params, C, M_gamma, lw, r1[which], r2[which], g0, th, with_gdot=False,
                                     refuse=refuse)[0] - h

    K_star, K_far = _sheet_poles(C, M_gamma, g0)
    poles = [_math.acos(k / C) for k in (K_star, K_far) if k is not None]
    wins, pwin, prow, proot = _pole_roots(lambda w, th: f(w, th, refuse=False), r1.size,
                                          _np.linspace(0.0, _math.pi, n_grid), poles)
    out = []
    for k, (th, mult) in enumerate(_roots_many(f, r1.size, 0.0, _math.pi, n_grid)):
        for wi, (lo, hi) in enumerate(wins):
            inside = (th > lo) & (th < hi)
            near = proot[(prow == k) & (pwin == wi)]
            if near.size != _np.count_nonzero(inside):
                th, mult = _np.concatenate([th[~inside], near]), _np.concatenate([mult[~inside], _np.ones(near.size, int)])
        a, b = float(r1[k]), float(r2[k])
        lk = float(ls[k]) if ls is not None else l
        K = C * _np.cos(th)
        gdot = (_reduced_energy_theta(params, C, M_gamma, lk, a, b, g0, th, refuse=False)[1] if th.size
                else _np.empty(0))
        if direction is not None:
            keep = _np.sign(gdot) == direction
            th, K, gdot, mult = th[keep], K[keep], gdot[keep], mult[keep]
        order = _np.argsort(K)
        K, gdot, mult, th = K[order], gdot[order], mult[order], th[order]
        _, (g1, g2, g3) = angles_to_vectors(C, M_gamma, K, lk, g0)
        ok = (_np.abs(g3) >= CHART_SINGULAR_TOL) & (g1 * g1 + g2 * g2 >= CHART_SINGULAR_TOL**2)
        try:
            states = (reduced_state_from_chart(params, C=C, M_gamma=M_gamma, K=K[ok], l=lk, g=g0, r1=a, r2=b)
                      if ok.any() else _np.empty((0, 9)))
        except ChartError as e:  # R not determined by (r1, r2) there: this point's error, not the others'
            out.append(e)
            continue
        orient = (_orientation(params, C, M_gamma, lk, a, b, g0, th) if th.size else _np.empty(0, dtype=int))
        sheet = _sheet_labels(K, orient, K_star, K_far)
        out.append((states, {"K": K[ok], "g_dot": gdot[ok], "multiplicity": mult[ok], "orientation": orient[ok],
                             "sheet": sheet[ok], "root": _np.flatnonzero(ok), "refused_K": K[~ok]}))
    return out


#: Step in theta (K = C cos theta) of the central difference for dE/dK in
#: :func:`section_sigma`: truncation ~1e-12 and rounding ~eps |E| / 1e-6 ~ 1e-10 relative.
_SIGMA_DTHETA = 1e-6
