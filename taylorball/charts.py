r"""Charts of the paper: the section-4 variables (K, r1, r2, l, g) and Andoyer--Deprit.

Section 4 (reduced system, level set ``|M| = C``, ``(M, gamma) = M_gamma``):

.. math::
    K = M_3,\quad r_1 = R_1\gamma_1 + R_2\gamma_2,\quad r_2 = R_1\gamma_2 - R_2\gamma_1,\quad
    l = \operatorname{atan2}(M_1, M_2),\quad
    g = \operatorname{atan2}\big(C(M_2\gamma_1 - M_1\gamma_2),\ M_\gamma K - C^2\gamma_3\big),

with ``l, g`` taken in ``[0, 2 pi)``. The same ``g`` with ``M -> K``, ``C -> G = |K|``,
``M_gamma -> lambda`` is the Andoyer--Deprit angle of section 5.

Contents:

* the angle ``g`` and the section's event function, backend-neutral (see
  :mod:`taylorball._vec`: the same code gives numbers and heyoka expressions);
* the section-4 chart and its inverse (numpy): :func:`reduced_chart`,
  :func:`reduced_state_from_chart`, and :func:`states_on_section`, which solves the energy
  equation for every root ``K``; :func:`section_admissible_sample` samples the region of
  ``(l, r1, r2)`` that carries states;
* the Andoyer--Deprit chart of section 5 (corrected: erratum E3) and its inverse with ``G``
  from the energy: :func:`mparallel_chart`, :func:`mparallel_state_from_chart`,
  :func:`mparallel_states_on_section`.

Singular sets (clear :class:`~taylorball.errors.ChartError` there): ``M`` along the body
axis e3 (``l``, ``g`` undefined), ``M`` parallel to ``gamma`` (``g`` undefined; the M||gamma
case), and for the inverse ``|gamma3|`` or ``|(gamma1, gamma2)|`` below
:data:`CHART_SINGULAR_TOL` (``R`` not determined by ``(r1, r2)``).
"""

from __future__ import annotations

import math as _math
from typing import TYPE_CHECKING

from typing import Any, Dict, Literal, Optional, Sequence, Tuple, overload

import numpy as _np
from numpy.typing import ArrayLike

from ._typing import FloatOrArray, ParamsLike, Scalar, SeedLike, Vec3, VecLike
from ._vec import add as _add
from ._vec import dot, norm2, sqrt
from ._vec import scale as _scale
from .errors import ChartError, EmptyLevelError, UsageError
from .params import BallParams
from .numbers import count, real_number

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from .params import BallParams

__all__ = [
    "g_angle_parts",
    "section_event_function",
    "angles_to_vectors",
    "andoyer_deprit_printed",
    "R_from_r",
    "reduced_state_from_chart",
    "reduced_chart",
    "states_on_section",
    "section_admissible_sample",
    "section_sheet",
    "section_sigma",
    "section_sigma_sample",
    "mparallel_chart",
    "mparallel_state_from_chart",
    "mparallel_states_on_section",
    "CHART_SINGULAR_TOL",
]


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


def _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g, theta, with_gdot=True):
    """Energy ``E`` and (if asked) ``dg/dt`` of the reduced system on the chart point, with
    ``K = C cos(theta)`` (arrays over theta). NaN where ``R`` is not determined."""
    from .model import ball_constants, omega_from_K, reduced_rhs

    K = C * _np.cos(theta)
    M, gamma = angles_to_vectors(C, M_gamma, K, l, g)
    g1, g2, g3 = gamma
    rho2 = g1 * g1 + g2 * g2
    ok = (_np.abs(g3) >= CHART_SINGULAR_TOL) & (rho2 >= CHART_SINGULAR_TOL**2)
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
        fa = y[:, :-1][sc]
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
        # a sign change across a pole (f -> +-inf) is no root: require a small value
        keep = _np.isfinite(fm) & (_np.abs(fm) <= 1e-9 * tiny[wb])
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
    bit, and searching grid extrema for double roots.

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
        sign of ``gamma3 dE/dK``) and ``sheet`` (the sheet label of
        :func:`section_sheet` with ``label="sheet"``) per state.

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
_SHEET_LEVEL_TOL = 1e-6


def section_sheet(params: BallParams, states: ArrayLike, *, C: float, M_gamma: float, h: float, g0: float = 0.0,
                  direction: int = 1, n_grid: int = 801, chunk: int = 2048,
                  label: Literal["root", "sheet"] = "root") -> _np.ndarray:
    r"""The sheet of the section-4 map each state lies on: the index of its ``K = M3`` among
    the roots ``K`` of the energy equation at its chart point, in increasing ``K``
    (``label="root"``), or the sheet label that follows a sheet across ``gamma3 = 0``
    (``label="sheet"``).

    Over one chart point ``(l, r1, r2)`` the section ``g = g0`` of the level set can carry
    several states (the roots ``K`` of ``E(K; l, r1, r2, g0) = h``, paper sec. 4, section
    chart; :func:`states_on_section`), so a picture in ``(r1, r2)`` overlays several sheets.
    The index here is the position of the state in the list :func:`states_on_section` returns
    for its chart point and ``direction``: within one index the chart is one-to-one, so
    points of one sheet never stand for two different states. Sheets meet at folds (double
    roots), where the index of an orbit's crossings changes.

    The root index is not a sheet label across ``gamma3 = 0``: there (``r1 = -R3 gamma3 =
    0``, at the one value ``K*`` of :func:`_degenerate_K`, ``sqrt(C^2 - M_gamma^2)`` on
    ``g0 = 0``) the energy equation has a pole, and two roots pass through each other at
    ``K*`` as ``r1`` changes sign, so their order in ``K`` is exchanged while each state
    moves smoothly (docs/chaos.md, "Sheets of the section"). ``label="sheet"`` numbers the
    states by quantities continuous on a sheet instead: the orientation ``o = sign(gamma3
    dE/dK)`` of the chart map (constant on a sheet, opposite on the two sheets of a fold),
    the side of the second pole ``K** = -M_gamma cos g0`` (``gamma1 = gamma2 = 0``; on
    ``g0 = 0, pi`` only), which no sheet crosses, and the distance ``|K - K*|``; a state's
    label is ``4 rank + 2 side + (o < 0)``, ``rank`` its position among the states of its
    side and orientation at its chart point in increasing ``|K - K*|``.
    :func:`taylorball.megno_map` with ``sheet=`` maps them. Where a sheet nearer ``K*`` of
    the same side and orientation appears or ends, the rank of the others shifts (as the
    root index does where a root appears below).

    Parameters
    ----------
    params : BallParams
    states : array_like, shape (n, 9) or (9,)
        Public reduced states on the section ``g = g0`` of the level set (e.g. the
        ``states`` of a :class:`~taylorball.sections.SectionResult`).
    C, M_gamma, h : float
        The levels ``|M|``, ``(M, gamma)``, ``E`` the states lie on.
    g0 : float
        The section angle.
    direction : {+1, -1}
        The branch the crossings are on (``dg/dt`` of this sign; the figures use +1).
    n_grid : int
        Grid in ``theta`` (``K = C cos(theta)``) on which roots are bracketed, as in
        :func:`states_on_section`. Two roots closer than a grid step (next to a fold) can
        be counted as one there: the index of such a crossing is then off by one.
    chunk : int
        States evaluated at once (memory: ``chunk * n_grid`` numbers per temporary array;
        fewer states when that would pass ~4 million).
    label : {"root", "sheet"}
        The root index in increasing ``K`` (the index of :func:`states_on_section` and of
        ``megno_map(root=...)``), or the sheet label (``megno_map(sheet=...)``; the
        ``"sheet"`` entry of :func:`states_on_section`'s info).

    Returns
    -------
    ndarray of int, shape (n,)
        ``label="root"``: ``0`` for the smallest root ``K`` with ``dg/dt`` of sign
        ``direction``, ``1`` for the next, ... ``label="sheet"``: the sheet label.

    Raises
    ------
    ChartError
        Bad levels, or a state not on them or not on the section ``g = g0`` (relative
        distance above 1e-6).
    UsageError
        Bad ``direction``, ``n_grid``, ``chunk`` or ``label``.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> xs = tb.states_on_section(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), point=(2.0, 2.5, 1.0), direction=1)
    >>> tb.section_sheet(FIG4_BALL, xs, **FIG4A_LEVELS.as_kwargs())
    array([0, 1])
    >>> tb.section_sheet(FIG4_BALL, xs, **FIG4A_LEVELS.as_kwargs(), label="sheet")   # orientation -1 and +1
    array([1, 0])
    """
    params = _ball(params)
    C, M_gamma = _check_levels(C, M_gamma)
    g0 = _check_g0(g0)
    h = _check_h(h)
    n_grid = _check_grid(n_grid)
    if direction not in (1, -1) or isinstance(direction, bool):
        raise UsageError(f"direction must be +1 or -1 (the branch of the crossings), got {direction!r}")
    chunk = count("chunk", chunk, lo=1, hi=10_000_000)
    if not (isinstance(label, str) and label in ("root", "sheet")):
        raise UsageError(f"label must be 'root' (the index of K among the roots) or 'sheet' (the sheet label), "
                         f"got {label!r}")
    try:
        x = _np.asarray(states, dtype=float)
    except (TypeError, ValueError):
        raise ChartError(f"states must be reduced states of shape (n, 9) or (9,), got {states!r}") from None
    if x.ndim not in (1, 2) or x.shape[-1] != 9:
        raise ChartError(f"states must be reduced states of shape (n, 9) or (9,), got shape {x.shape}")
    x = x.reshape(-1, 9)
    if x.shape[0] == 0:
        return _np.zeros(0, dtype=int)
    ch = reduced_chart(params, x)
    off_g = _np.abs(_wrap(ch["g"] - g0 + _math.pi) - _math.pi)
    bad = ((_np.abs(ch["C"] - C) > _SHEET_LEVEL_TOL * C) | (_np.abs(ch["M_gamma"] - M_gamma) > _SHEET_LEVEL_TOL * C)
           | (off_g > _SHEET_LEVEL_TOL))
    if _np.any(bad):
        i = int(_np.flatnonzero(bad)[0])
        raise ChartError(
            f"states must lie on the section g = {g0!r} of the level set C = {C!r}, M_gamma = {M_gamma!r}; "
            f"state {i} has C = {ch['C'][i]!r}, M_gamma = {ch['M_gamma'][i]!r}, g = {ch['g'][i]!r}"
        )
    theta_state = _np.arccos(_np.clip(ch["K"] / C, -1.0, 1.0))
    if label == "sheet":
        K_star, K_far = _sheet_poles(C, M_gamma, g0)
        theta_poles = [_math.acos(k / C) for k in (K_star, K_far) if k is not None]
        side_state = _side(ch["K"], K_star, K_far)
        orient_state = _orientation(params, C, M_gamma, ch["l"], ch["r1"], ch["r2"], g0, theta_state)
    # temporaries of at most ~4 M numbers (32 MB) each, whatever chunk and n_grid ask for
    chunk = max(1, min(chunk, (1 << 22) // n_grid))
    out = _np.empty(x.shape[0], dtype=int)
    for s in range(0, x.shape[0], chunk):
        sl = slice(s, s + chunk)
        l, r1, r2 = (ch[k][sl] for k in ("l", "r1", "r2"))

        def f(which, th):
            return _reduced_energy_theta(params, C, M_gamma, l[which], r1[which], r2[which], g0, th,
                                         with_gdot=False)[0] - h

        grid, _, _, E, _, exact, sc = _grid_brackets(f, l.size, 0.0, _math.pi, n_grid)
        # a root in (grid[j], grid[j+1]] where E changes sign; located by linear interpolation
        # for the sign of dg/dt there (the branch)
        change = sc | (exact[:, 1:] & ~exact[:, :-1])
        rows, j = _np.nonzero(change)
        e0, e1 = E[rows, j], E[rows, j + 1]
        th = grid[j] + (grid[j + 1] - grid[j]) * e0 / (e0 - e1)
        gdot = _reduced_energy_theta(params, C, M_gamma, l[rows], r1[rows], r2[rows], g0, th)[1]
        branch = _np.sign(gdot) == direction
        if label == "root":
            # K = C cos(theta) decreases with theta: the roots with smaller K than the state's
            # own are those in brackets entirely beyond the state's theta (its own root lies
            # in the bracket that contains theta_state)
            below = (grid[j] > theta_state[sl][rows]) & branch
            out[sl] = _np.bincount(rows[below], minlength=E.shape[0])
            continue
        # the sheet label (_sheet_labels): the other roots of the branch on the state's side
        # of K** with the state's orientation (dE/dtheta has the sign of e1 - e0 across a
        # bracket; dK/dtheta < 0) nearer K* than the state's own root (ties: smaller K) come
        # before it. A bracket can hold a pole (K* or K**: E -> -inf) besides the root: the
        # root then lies between the pole and the end where E > h, and gamma3 has its sign
        # (and K its side of K**) at that end; elsewhere they are one over the bracket
        pos = _np.where(e0 > 0, grid[j], grid[j + 1])
        for tp in theta_poles:
            pole = (grid[j] < tp) & (tp < grid[j + 1])
            if _np.any(pole):
                th = _np.where(pole, 0.5 * (tp + pos), th)
                gdot = _reduced_energy_theta(params, C, M_gamma, l[rows], r1[rows], r2[rows], g0, th)[1]
                branch = _np.sign(gdot) == direction
        _, gam = angles_to_vectors(C, M_gamma, C * _np.cos(pos), l[rows], g0)
        orient = _np.where(_np.sign(e1 - e0) * gam[2] > 0, -1, 1)
        own = (grid[j] <= theta_state[sl][rows]) & (theta_state[sl][rows] <= grid[j + 1])
        K_b, K_s = C * _np.cos(th), C * _np.cos(theta_state[sl][rows])
        d_b, d_s = _np.abs(K_b - K_star), _np.abs(K_s - K_star)
        before = (branch & ~own & (orient == orient_state[sl][rows])
                  & (_side(C * _np.cos(pos), K_star, K_far) == side_state[sl][rows])
                  & ((d_b < d_s) | ((d_b == d_s) & (K_b < K_s))))
        rank = _np.bincount(rows[before], minlength=E.shape[0])
        out[sl] = 4 * rank + 2 * side_state[sl] + (orient_state[sl] < 0)
    return out


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
    :data:`_SIGMA_DTHETA` (its sign is what counts)."""
    d = _SIGMA_DTHETA
    ep = _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g0, th + d, with_gdot=False)[0]
    em = _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g0, th - d, with_gdot=False)[0]
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
    Returns per point ``(states (n, 9), info)`` ordered by ``K`` (``n = 0`` where the point
    carries no state in ``direction``), or the :class:`ChartError` of that point."""
    r1 = _np.asarray(r1, dtype=float).reshape(-1)
    r2 = _np.asarray(r2, dtype=float).reshape(-1)
    per_point = _np.ndim(l) > 0
    ls = _np.asarray(l, dtype=float).reshape(-1) if per_point else None

    def f(which, th):
        lw = ls[which] if ls is not None else l
        return _reduced_energy_theta(params, C, M_gamma, lw, r1[which], r2[which], g0, th, with_gdot=False)[0] - h

    K_star, K_far = _sheet_poles(C, M_gamma, g0)
    out = []
    for k, (th, mult) in enumerate(_roots_many(f, r1.size, 0.0, _math.pi, n_grid)):
        a, b = float(r1[k]), float(r2[k])
        lk = float(ls[k]) if ls is not None else l
        K = C * _np.cos(th)
        gdot = _reduced_energy_theta(params, C, M_gamma, lk, a, b, g0, th)[1] if th.size else _np.empty(0)
        if direction is not None:
            keep = _np.sign(gdot) == direction
            th, K, gdot, mult = th[keep], K[keep], gdot[keep], mult[keep]
        order = _np.argsort(K)
        K, gdot, mult = K[order], gdot[order], mult[order]
        try:
            states = (reduced_state_from_chart(params, C=C, M_gamma=M_gamma, K=K, l=lk, g=g0, r1=a, r2=b) if K.size
                      else _np.empty((0, 9)))
        except ChartError as e:  # R not determined by (r1, r2) there: this point's error, not the others'
            out.append(e)
            continue
        th = th[order]
        orient = (_orientation(params, C, M_gamma, lk, a, b, g0, th) if th.size else _np.empty(0, dtype=int))
        out.append((states, {"K": K, "g_dot": gdot, "multiplicity": mult, "orientation": orient,
                             "sheet": _sheet_labels(K, orient, K_star, K_far)}))
    return out


#: Step in theta (K = C cos theta) of the central difference for dE/dK in
#: :func:`section_sigma`: truncation ~1e-12 and rounding ~eps |E| / 1e-6 ~ 1e-10 relative.
_SIGMA_DTHETA = 1e-6


def section_sigma(params: BallParams, *, C: float, M_gamma: float, h: float, points: ArrayLike,
                  g0: float = 0.0, direction: Optional[int] = 1, n_grid: int = 2001) -> _np.ndarray:
    r"""Density of the invariant volume form of the section-4 map, summed over the sheets.

    At a chart point ``(l, r1, r2)`` of the section ``g = g0`` on the level ``(C, M_gamma,
    h)``, every root ``K`` of the energy equation (a sheet; :func:`states_on_section`) with
    ``dg/dt`` of sign ``direction`` carries the density

    .. math:: \sigma = \frac{\rho_5\,|\dot g|}{|\partial E/\partial K|},\qquad
              \rho_5 = \frac{|D|^{-1/2}}{4\,C\,(\gamma_1^2 + \gamma_2^2)\,|\gamma_3|},\quad
              D = 1 - d\,(\gamma, A\gamma)

    (w.r.t. ``dl dr1 dr2``; the return map preserves ``sigma dl dr1 dr2``). This returns the
    sum over those sheets: the density of the section map's invariant measure in ``(l, r1,
    r2)`` with the sheets merged, what a histogram of an orbit's crossings over ``(l, r1,
    r2)`` converges to if the orbit is ergodic on its level (up to normalisation). The
    derivation and its mpmath check (the map preserves it: ``sigma(P x) |det DP| = sigma(x)``)
    are in :mod:`taylorball.verify.section_volume`, which evaluates the same formula
    independently in mpmath; here it is numpy, with ``dg/dt`` in closed form and ``dE/dK``
    by a central difference in ``theta`` (``K = C cos theta``; relative error ~1e-9).
    ``sigma`` is infinite at a fold (a double root, ``dE/dK = 0``); double roots are left
    out (measure zero).

    Parameters
    ----------
    params : BallParams
    C, M_gamma, h : float
        The levels ``|M|``, ``(M, gamma)``, ``E``.
    points : array_like (m, 3)
        Chart points ``(l, r1, r2)``.
    g0 : float
    direction : {1, -1, None}
        Sheets with ``g`` crossing ``g0`` increasing (+1), decreasing (-1), or all.
    n_grid : int
        Grid of the root search in ``theta`` (as :func:`states_on_section`).

    Returns
    -------
    ndarray (m,)
        ``0`` outside the admissible region.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> s = tb.section_sigma(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), points=[(2.0, 2.5, 1.0), (2.0, 50.0, 0.0)])
    >>> bool(s[0] > 0), float(s[1])              # the second point is outside the region
    (True, 0.0)
    """
    from .model import ball_constants

    params = _ball(params)
    C, M_gamma = _check_levels(C, M_gamma)
    h = _check_h(h)
    g0 = _check_g0(g0)
    _check_direction(direction)
    n_grid = _check_grid(n_grid)
    try:
        pts = _np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise ChartError(f"points must be an array of chart points (l, r1, r2), shape (m, 3); got {points!r}") from None
    if pts.ndim != 2 or pts.shape[1] != 3 or not _np.all(_np.isfinite(pts)):
        raise ChartError(f"points must be a finite array of chart points (l, r1, r2), shape (m, 3); got shape "
                         f"{pts.shape}" + ("" if _np.all(_np.isfinite(pts)) else " with non-finite entries"))
    c = ball_constants(params.pars)
    out = _np.zeros(len(pts))
    for j, (l, r1, r2) in enumerate(pts):
        def f(th):
            return _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g0, th, with_gdot=False)[0] - h

        th, mult = _roots_1d(f, 0.0, _math.pi, n_grid)
        th = th[(mult == 1) & (th > 0.0) & (th < _math.pi)]
        if th.size == 0:
            continue
        gdot = _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g0, th)[1]
        if direction is not None:
            th, gdot = th[_np.sign(gdot) == direction], gdot[_np.sign(gdot) == direction]
        if th.size == 0:
            continue
        ep = _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g0, th + _SIGMA_DTHETA, with_gdot=False)[0]
        em = _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g0, th - _SIGMA_DTHETA, with_gdot=False)[0]
        dEdK = (ep - em) / (2 * _SIGMA_DTHETA) / (-C * _np.sin(th))
        rho5 = _sigma_rho5(c, C, M_gamma, th, l, g0)
        out[j] = float(_np.sum(rho5 * _np.abs(gdot) / _np.abs(dEdK)))
    return out


def _sigma_rho5(c, C, M_gamma, theta, l, g0):
    """``rho5 = |D|^(-1/2) / (4 C (gamma_1^2 + gamma_2^2) |gamma_3|)`` of :func:`section_sigma`
    at ``K = C cos(theta)`` (elementwise)."""
    _, gam = angles_to_vectors(C, M_gamma, C * _np.cos(theta), l, g0)
    D = 1 - c.d * (c.A[0] * gam[0] ** 2 + c.A[1] * gam[1] ** 2 + c.A[2] * gam[2] ** 2)
    return 1.0 / _np.sqrt(_np.abs(D)) / (4 * C * (gam[0] ** 2 + gam[1] ** 2) * _np.abs(gam[2]))


_SIGMA_SAMPLE_BLOCK = 1 << 18  # draws per vectorised block (~100 MB of temporaries)


def section_sigma_sample(params: BallParams, *, C: float, M_gamma: float, h: float, n: int, g0: float = 0.0,
                         direction: Optional[int] = 1, seed: SeedLike = 0) -> Dict[str, Any]:
    r"""Monte Carlo sample of the section map's invariant measure ``sigma dl dr1 dr2``
    (:func:`section_sigma`), with weights, free of its fold singularities.

    :func:`section_sigma` is ``sum_K rho5 |dg/dt| / |dE/dK|`` and diverges like
    ``1/sqrt(distance)`` at a fold of the level set over the chart (``dE/dK = 0``: the
    edge of the admissible region and the lines where two sheets meet), so quadrature of it
    over a bin that a fold cuts converges slowly and erratically. The same measure in
    the coordinates ``(l, theta, alpha)`` is smooth: for fixed ``l`` and ``K = C cos
    theta`` the energy is a quadratic form in ``(r1, r2)`` (``R`` is linear in them and the
    energy quadratic in ``R``) with a definite Hessian ``Q`` (``Omega > 0``), so the level
    ``E = h`` is an ellipse, parametrised by ``alpha``, and (coarea formula)

    .. math:: \int f\,\sigma\,dl\,dr_1\,dr_2 = \int dl\int_0^\pi C\sin\theta\,d\theta
              \oint \frac{\rho_5\,|\dot g|}{\sqrt{\det Q}}\,f\,d\alpha ,

    with ``(r1, r2)`` on the ellipse at angle ``alpha`` (``r = r0 + V diag(sqrt(2 Delta /
    lambda)) (cos alpha, sin alpha)``, ``Q = V diag(lambda) V^T``, ``r0`` the centre,
    ``Delta = h - E(r0)``) and only points with ``dg/dt`` of sign ``direction`` counted.
    The integrand is bounded where the chart is regular. This draws ``n`` points uniformly
    in ``(l, theta, alpha) in [0, 2 pi) x (0, pi) x [0, 2 pi)``, keeps those on an ellipse
    with the right sign of ``dg/dt`` and weights each by ``4 pi^3 C sin(theta) rho5 |dg/dt|
    / (sqrt(det Q) n)``: ``sum_i w_i f(p_i)`` is an unbiased estimate of ``int f sigma`` with
    finite variance (e.g. ``np.histogramdd(points, edges, weights=w)`` estimates the
    measure of each bin). ``Q``, the centre and ``Delta`` come from the energy at six
    points ``r = 0, +-e1, +-e2, e1 + e2`` (exact for a quadratic, to rounding).

    Parameters
    ----------
    params : BallParams
        ``plane_rate > 0`` (at ``Omega = 0`` the energy does not depend on ``R``: the region
        is unbounded).
    C, M_gamma, h : float
        The levels ``|M|``, ``(M, gamma)``, ``E``.
    n : int
        Draws (``1 .. 10^9``); about ``2.5 s`` of one core per ``10^6``.
    g0 : float
    direction : {1, -1, None}
        As for :func:`section_sigma`.
    seed : int, None, numpy Generator or SeedSequence
        For ``numpy.random.default_rng``.

    Returns
    -------
    dict
        ``points`` (k, 3) chart points ``(l, r1, r2)`` (``l`` in ``[0, 2 pi)``), ``K`` (k,)
        their sheets (``M3``), ``weights`` (k,), ``n`` the draws (``k <= n``: draws off
        every ellipse, with the other sign of ``dg/dt`` or on the chart's singular set are
        dropped); ``total`` the estimate of ``int sigma`` (the sum of the weights).

    Raises
    ------
    ChartError
        Bad levels or ``h``; ``Omega = 0`` or an indefinite energy form (no ellipse).

    Examples
    --------
    >>> import numpy as np
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> s = tb.section_sigma_sample(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), n=20000, seed=1)
    >>> s["points"].shape[1], bool(np.all(s["weights"] > 0))
    (3, True)
    """
    from .model import ball_constants

    params = _ball(params)
    C, M_gamma = _check_levels(C, M_gamma)
    h = _check_h(h)
    g0 = _check_g0(g0)
    _check_direction(direction)
    n = count("n", n, lo=1, hi=10**9)
    rng = _rng(seed)
    if not params.plane_rate > 0:
        raise ChartError(f"section_sigma_sample needs plane_rate > 0 (at plane_rate = {params.plane_rate!r} the "
                         "energy does not depend on R and the section region is unbounded in (r1, r2))")
    c = ball_constants(params.pars)
    parts: Dict[str, list] = {"points": [], "K": [], "weights": []}
    for lo in range(0, n, _SIGMA_SAMPLE_BLOCK):
        m = min(_SIGMA_SAMPLE_BLOCK, n - lo)
        l = rng.uniform(0.0, 2 * _math.pi, m)
        th = rng.uniform(0.0, _math.pi, m)
        al = rng.uniform(0.0, 2 * _math.pi, m)

        def energy(a, b):
            return _reduced_energy_theta(params, C, M_gamma, l, a, b, g0, th, with_gdot=False)[0]

        zero, one = _np.zeros(m), _np.ones(m)
        e0, e1p, e1m, e2p, e2m, e12 = (energy(zero, zero), energy(one, zero), energy(-one, zero),
                                       energy(zero, one), energy(zero, -one), energy(one, one))
        b = _np.stack([(e1p - e1m) / 2, (e2p - e2m) / 2], axis=-1)
        q11, q22, q12 = e1p + e1m - 2 * e0, e2p + e2m - 2 * e0, e12 - e1p - e2p + e0
        det = q11 * q22 - q12 * q12
        ok = _np.isfinite(det)  # False on the chart's singular set (E is NaN there)
        if _np.any(ok & ~(det > 0)):
            raise ChartError(f"the energy is not a definite quadratic form in (r1, r2) at some (l, K) of the level "
                             f"(C={C!r}, M_gamma={M_gamma!r}); the section region is not bounded")
        Q = _np.stack([_np.stack([q11, q12], -1), _np.stack([q12, q22], -1)], -2)
        Q[~ok] = _np.eye(2)
        b[~ok] = 0.0
        r0 = -_np.linalg.solve(Q, b[..., None])[..., 0]
        delta = h - (e0 + 0.5 * _np.einsum("ni,ni->n", b, r0))
        lam, V = _np.linalg.eigh(Q)
        on = ok & (delta * lam[:, 0] > 0)  # lambda_1, lambda_2 of one sign: delta of that sign
        ax = _np.sqrt(_np.where(on[:, None], 2 * delta[:, None] / lam, 0.0))
        u = _np.stack([_np.cos(al), _np.sin(al)], axis=-1)
        r = r0 + _np.einsum("nij,nj->ni", V, ax * u)
        _, gdot = _reduced_energy_theta(params, C, M_gamma, l, r[:, 0], r[:, 1], g0, th)
        keep = on & _np.isfinite(gdot) & (gdot != 0)
        if direction is not None:
            keep &= _np.sign(gdot) == direction
        rho5 = _sigma_rho5(c, C, M_gamma, th[keep], l[keep], g0)
        w = (4 * _math.pi**3 / n) * C * _np.sin(th[keep]) * rho5 * _np.abs(gdot[keep]) / _np.sqrt(det[keep])
        parts["points"].append(_np.column_stack([l[keep], r[keep]]))
        parts["K"].append(C * _np.cos(th[keep]))
        parts["weights"].append(w)
    out: Dict[str, Any] = {k: _np.concatenate(v) for k, v in parts.items()}
    out["n"] = n
    out["total"] = float(out["weights"].sum())
    return out


#: Candidates :func:`section_admissible_sample` draws ahead and searches at once (one
#: vectorised root search instead of 32: ~10x less time in the figures' samples).
_SAMPLE_BLOCK = 32


def section_admissible_sample(params: BallParams, *, C: float, M_gamma: float, h: float, g0: float = 0.0,
                              n: int = 100, direction: Optional[Literal[-1, 1]] = 1, seed: SeedLike = 0,
                              r_box: Optional[float] = None, n_grid: int = 801,
                              max_candidates: Optional[int] = None) -> Dict[str, Any]:
    """Sample the admissible region of the section-4 map: ``n`` chart points
    ``(l, r1, r2)`` on ``g = g0`` that carry at least one state of the level set (with
    ``dg/dt`` of sign ``direction``, unless ``None``).

    Candidates are drawn uniformly in ``l in [0, 2 pi)`` and ``(r1, r2)`` in the box
    ``[-r_box, r_box]^2`` (at most ``max_candidates``, default ``100 n``); each is kept
    when the energy equation has a root, so the points are uniform in the region. With
    ``r_box=None`` the box is grown from 1 until a ring of candidates at its edge is
    entirely inadmissible (the energy falls like ``-|R|^2`` for large ``R``, so the region
    is bounded).

    Returns
    -------
    dict
        ``points`` (k, 3) admissible points (``k = n`` unless the candidates ran out),
        ``K`` (k,) the first root of each, ``states`` (list of k arrays (n_roots, 9): the
        states of each point, as :func:`states_on_section` gives them), ``fraction`` of candidates admissible (an
        estimate of the region's share of the box), ``r_box`` used, ``n_candidates``.

    Raises
    ------
    EmptyLevelError
        When no candidate is admissible (an empty level set, or one too thin to sample).

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> region = tb.section_admissible_sample(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), n=3)
    >>> region["points"].shape, len(region["states"])   # 3 chart points (l, r1, r2)
    ((3, 3), 3)
    >>> x0 = tb.states_on_section(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), point=region["points"][0],
    ...                           direction=1)[0]
    >>> round(float(tb.integrals("reduced", FIG4_BALL, x0)["E"]), 9)
    5.0
    """
    params = _ball(params)
    C, M_gamma = _check_levels(C, M_gamma)
    g0 = _check_g0(g0)
    _check_h(h)
    _check_grid(n_grid)
    n = count("n", n, lo=1, hi=1_000_000)
    _check_direction(direction)
    if r_box is not None:
        r_box = real_number("r_box", r_box, lo=0.0, lo_open=True)
    if max_candidates is not None:
        count("max_candidates", max_candidates, lo=1, hi=100_000_000)
    # a Generator of the caller's advances exactly as if the candidates were drawn one at a
    # time; a sampler of our own draws candidates ahead and searches a block of them at once
    block = 1 if isinstance(seed, _np.random.Generator) else _SAMPLE_BLOCK
    rng = _rng(seed)

    def admissible(ps):
        """Per candidate ``(l, r1, r2)``: ``(states, info)`` as :func:`states_on_section`
        gives them (bit for bit: :func:`_section_states`), or None where it has none."""
        found = _section_states(params, C, M_gamma, h, _np.array([p[0] for p in ps]), [p[1] for p in ps],
                                [p[2] for p in ps], g0, direction, n_grid)
        return [None if isinstance(f, ChartError) or not len(f[0]) else f for f in found]

    if r_box is None:
        r_box = 1.0
        for _ in range(12):
            edge = [(rng.uniform(0, 2 * _math.pi), r_box * _math.cos(a), r_box * _math.sin(a))
                    for a in rng.uniform(0, 2 * _math.pi, 48)]
            if all(f is None for f in admissible(edge)):
                break
            r_box *= 2.0
    pts: list[Tuple[float, float, float]] = []
    Ks, states = [], []
    n_cand = 0
    max_candidates = 100 * n if max_candidates is None else int(max_candidates)
    while len(pts) < n and n_cand < max_candidates:
        cands = [(rng.uniform(0, 2 * _math.pi), rng.uniform(-r_box, r_box), rng.uniform(-r_box, r_box))
                 for _ in range(min(block, max_candidates - n_cand))]
        for p, found in zip(cands, admissible(cands)):
            n_cand += 1
            if found is not None:
                pts.append(p)
                Ks.append(found[1]["K"][0])
                states.append(found[0])
                if len(pts) == n:
                    break
    if not pts:
        raise EmptyLevelError(
            f"no admissible chart point found among {n_cand} candidates in r1, r2 in [-{r_box:g}, {r_box:g}] for "
            f"C = {C!r}, M_gamma = {M_gamma!r}, h = {h!r}, g0 = {g0!r}, direction = {direction!r}: the level set "
            "is empty or does not meet this section"
        )
    return {"points": _np.array(pts), "K": _np.array(Ks), "states": states, "fraction": len(pts) / n_cand,
            "r_box": r_box, "n_candidates": n_cand}


# ---------------------------------------------------------------------------------------
# Section 5: the Andoyer--Deprit chart of the M || gamma system.
# ---------------------------------------------------------------------------------------
def mparallel_chart(state: ArrayLike) -> Dict[str, Any]:
    """Andoyer--Deprit coordinates of mparallel state(s) ``(K, gamma)``: ``dict`` with
    ``L = K3``, ``G = |K|``, ``l = atan2(K1, K2)``, ``g`` (the section-4 formula with
    ``M -> K``, ``C -> G``, ``M_gamma -> lambda``), ``L/G`` and ``lambda = (K, gamma)``.

    Raises
    ------
    ChartError
        Where ``K`` is along e3 (``l`` undefined) or parallel to ``gamma``.
    """
    from .manifold import as_state

    x = _np.asarray(as_state("mparallel", state), dtype=float)
    K, gamma = tuple(x[..., i] for i in range(3)), tuple(x[..., i] for i in range(3, 6))
    G2 = norm2(K)
    G = _np.sqrt(G2)
    num, den = g_angle_parts(K, gamma)
    if _np.any(_np.hypot(K[0], K[1]) <= 1e-12 * G) or _np.any(_np.hypot(num, den) <= 1e-12 * G2):
        raise ChartError("the Andoyer-Deprit chart is singular here: K along e3 or K parallel to gamma")
    return {"L": K[2], "G": G, "l": _wrap(_np.arctan2(K[0], K[1])), "g": _wrap(_np.arctan2(num, den)),
            "L/G": K[2] / G, "lambda": dot(K, gamma)}


def mparallel_state_from_chart(*, lam: float, L: FloatOrArray, G: FloatOrArray, l: FloatOrArray,
                               g: FloatOrArray) -> _np.ndarray:
    """mparallel state(s) ``(K, gamma)`` from Andoyer--Deprit variables (corrected chart,
    erratum E3): ``|gamma| = 1`` and ``(K, gamma) = lambda`` hold identically.

    Raises
    ------
    ChartError
        Unless ``G > |lambda|`` and ``|L| <= G``.
    """
    G_arr = _np.asarray(G, dtype=float)
    if _np.any(~(G_arr > abs(lam))) or _np.any(_np.abs(_np.asarray(L, dtype=float)) > G_arr):
        raise ChartError(f"Andoyer-Deprit variables need G > |lambda| = {abs(lam)!r} and |L| <= G, got "
                         f"G = {G!r}, L = {L!r}")
    Ks, gamma = angles_to_vectors(G_arr, lam, L, l, g)
    return _np.stack(_np.broadcast_arrays(*Ks, *gamma), axis=-1)


def _mparallel_energy_mu(params, lam, ratio, l, g, mu):
    """``Etilde`` on the chart point ``(l, L/G = ratio)`` at ``g``, with ``G = lambda/mu``,
    written as ``Etilde = G^2 Q(mu)``: returns ``Q`` (homogeneity of degree 2 in K)."""
    from .model import mparallel_constants

    c = mparallel_constants(params.pars)
    Khat, gamma = angles_to_vectors(1.0, mu, ratio, l, g)  # C = 1: K/G and gamma at mu = lambda/G
    AK = tuple(c.A[i] * Khat[i] for i in range(3))
    D = 1 - c.d * dot(gamma, tuple(c.A[i] * gamma[i] for i in range(3)))
    return dot(Khat, AK) / 2 - norm2(Khat) / (2 * c.d) + c.d * dot(AK, gamma) ** 2 / (2 * D)


def mparallel_states_on_section(params: ParamsLike, *, lam: float, h: float, point: Sequence[float],
                                g0: float = 0.0, n_grid: int = 4001) -> _np.ndarray:
    r"""Every M||gamma state with ``(K, gamma) = lambda``, ``Etilde = h`` and
    Andoyer--Deprit chart point ``point = (l, L/G)`` on the section ``g = g0``.

    ``Etilde`` is homogeneous of degree 2 in ``K`` for fixed ``gamma``; on the chart,
    ``gamma`` depends on ``G`` only through ``mu = lambda/G``, so ``Etilde = G^2 Q(mu)``
    and the energy equation becomes ``lambda^2 Q(mu) = h mu^2`` for ``mu`` in ``(0, 1)``
    (``lambda > 0``; mirrored for ``lambda < 0``): a smooth equation on a bounded interval,
    solved like :func:`states_on_section`. For ``lambda = 0``, ``G = sqrt(h / Q(0))``.

    Returns
    -------
    ndarray, shape (n, 6)
        States ``(K, gamma)`` ordered by ``G``.

    Raises
    ------
    ChartError, EmptyLevelError
    """
    from .manifold import params_for

    params = params_for("mparallel", params)
    l, ratio = _check_point(point, 2, "(l, L/G)")
    if not -1.0 <= ratio <= 1.0:
        raise ChartError(f"L/G must lie in [-1, 1], got {ratio!r}")
    g0 = _check_g0(g0)
    lam, h = real_number("lam", lam, error=ChartError), _check_h(h)
    n_grid = _check_grid(n_grid)
    if lam == 0.0:
        Q = float(_mparallel_energy_mu(params, 0.0, ratio, l, g0, _np.array(0.0)))
        Gs = _np.array([_math.sqrt(h / Q)]) if Q != 0 and h / Q > 0 else _np.empty(0)
    else:
        sgn = 1.0 if lam > 0 else -1.0

        def f(mu_abs):
            mu = sgn * mu_abs
            return lam * lam * _mparallel_energy_mu(params, lam, ratio, l, g0, mu) - h * mu * mu

        # mu = 1 is G = |lambda| (K || gamma); mu -> 0 is G -> infinity
        roots, _ = _roots_1d(f, 0.0, 1.0, n_grid)
        roots = roots[(roots > 0) & (roots < 1)]
        Gs = _np.sort(abs(lam) / roots)
    if Gs.size == 0:
        raise EmptyLevelError(
            f"no M||gamma state has chart point (l, L/G) = {point!r} on g = {g0!r} with lambda = {lam!r}, "
            f"Etilde = {h!r}: the energy equation has no root G > |lambda|"
        )
    return _np.stack([mparallel_state_from_chart(lam=lam, L=ratio * G, G=G, l=l, g=g0) for G in Gs])
