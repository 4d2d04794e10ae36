"""Transport of lifted coordinates: mean squared displacement, its exponent, ballistic
orbits and first-passage times.

The input is an ensemble of *lifted* paths ``x`` of shape ``(n_orbits, n_times)`` -- an
angle followed continuously, without reduction mod 2 pi -- on one common uniform time
grid ``t`` of shape ``(n_times,)``. Everything here is numpy on float64; nothing is
integrated. The formulas, the conventions and the validation on processes with known
answers are in ``docs/transport.md``.

Conventions
-----------
* Drift. Orbit ``i``'s velocity is the endpoint estimator ``v_i = (x_i(T) - x_i(0)) / T``
  (``T = t[-1] - t[0]``); the drift is the *ensemble* mean ``v = mean_i v_i`` (the mean
  rotation number of a lifted angle). The ensemble drift, not each orbit's own, is removed:
  removing every orbit's own line would also remove the orbit-to-orbit spread of
  velocities, i.e. the ballistic transport (accelerator modes) one is looking for, and
  would bias a diffusive MSD down at long lags. The endpoint estimator is the maximum
  likelihood estimate of a Brownian drift (the increments are independent) and, unlike a
  least-squares slope, keeps the bootstrap below exact (see :func:`diffusion_exponent`).
* MSD. ``MSD(tau_k) = mean_i mean_j (x_i(t_{j+k}) - x_i(t_j) - v tau_k)^2`` over all
  ``n_times - k`` windows of every orbit, ``tau_k = k dt``.
* Exponent and coefficient. ``MSD(tau) = 2 D tau^mu`` fitted by least squares on
  ``log MSD = log(2 D) + mu log tau`` (so a Brownian path with ``<dx^2> = sigma^2 dt`` has
  ``mu = 1`` and ``D = sigma^2 / 2``; ``D`` is in units of ``x^2 / t^mu``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Callable, Iterator, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from ._typing import SeedLike
from .errors import UsageError
from ._occupation import OCCUPATION_METRICS, Occupation, _check_int, _readonly, occupation  # noqa: F401

__all__ = [
    "MSD",
    "OrbitMSD",
    "DiffusionExponent",
    "EscapeTimes",
    "msd",
    "msd_per_orbit",
    "diffusion_exponent",
    "ballistic_orbits",
    "first_passage",
    "REGIMES",
    "Occupation",
    "occupation",
]

REGIMES = ("subdiffusive", "normal", "superdiffusive", "ballistic", "undetermined")

# A grid is uniform when every step is within this relative distance of the mean step:
# far above the rounding of any grid built as t0 + k dt or by accumulation (<= n eps),
# far below a non-uniformity that would change a lag by a visible amount.
_UNIFORM_RTOL = 1e-6
_ORBIT_CHUNK_ELEMENTS = 1 << 22  # orbits per block of lag differences: <= 32 MB of float64
# Bootstrap resamples: a percentile interval needs ~1e3-1e4 of them; with 1e5 the Monte
# Carlo error of a 2.5 % quantile is ~sqrt(q (1 - q) / n_boot) / f(quantile) ~ 0.3 % of the
# interval's width, far below its sampling error, while n_boot = 1e7 took 12 GB of weights.
# The resamples are drawn and reduced in blocks of <= 2^22 weights (32 MB): memory stays
# bounded for any n_orbits, and the draws are those of one call (the generator draws row
# after row).
MAX_BOOT = 100_000
# Fewer orbits than this: the bootstrap interval of diffusion_exponent covers the true
# exponent less often than its level says, and a warning says so. Measured on Brownian
# paths (mu = 1 exactly; 1000 unit steps, lags 1..100, n_boot = 1000, 400 ensembles per
# row, 2026-11-28; standard errors 0.01-0.02): a nominal 95 % interval covered mu = 1 in
#   orbits    3     5     10    15    20    30    50
#   coverage  0.70  0.81  0.90  0.91  0.94  0.92  0.95
# i.e. from ~20 orbits on it is within its sampling error of 0.95; below, it is too narrow
# (the percentile bootstrap of a mean of n heavy-tailed per-orbit terms needs n >~ 20).
FEW_ORBITS = 20


# ---------------------------------------------------------------------------------------
# validation
# ---------------------------------------------------------------------------------------
def _paths(t: ArrayLike, x: ArrayLike, *, name: str = "x",
           min_orbits: int = 2) -> Tuple[np.ndarray, np.ndarray, float]:
    """(t, x, dt) as float64 arrays after checking shapes, finiteness and the time grid."""
    try:
        t = np.asarray(t, dtype=float)
    except (TypeError, ValueError) as exc:
        raise UsageError(f"t must be a 1-D array of real times; got {type(t).__name__} ({exc})") from None
    try:
        x = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise UsageError(
            f"{name} must be a real array of shape (n_orbits, n_times); got {type(x).__name__} ({exc})"
        ) from None
    if x.ndim != 2:
        raise UsageError(
            f"{name} must be a 2-D array of shape (n_orbits, n_times), one lifted path per row; "
            f"got shape {x.shape} (use x[None, :] for a single orbit)"
        )
    n_orbits, n_times = x.shape
    if n_orbits < min_orbits:
        raise UsageError(
            f"{name} has {n_orbits} orbit(s) (shape {x.shape}); ensemble statistics need "
            f"n_orbits >= {min_orbits} rows"
        )
    if t.ndim != 1 or t.shape[0] != n_times:
        raise UsageError(
            f"t must be a 1-D array of the {n_times} sample times of {name} (its second axis); "
            f"got shape {t.shape}"
        )
    if n_times < 3:
        raise UsageError(f"t has {n_times} sample time(s); need at least 3 (a lag and a fit)")
    if not np.all(np.isfinite(t)):
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        raise UsageError(f"t must be finite; t[{bad}] = {t[bad]!r}")
    if not np.all(np.isfinite(x)):
        i, j = (int(k) for k in np.argwhere(~np.isfinite(x))[0])
        raise UsageError(f"{name} must be finite; {name}[{i}, {j}] = {x[i, j]!r}")
    step = np.diff(t)
    if not np.all(step > 0):
        bad = int(np.flatnonzero(step <= 0)[0])
        raise UsageError(
            f"t must be strictly increasing; t[{bad}] = {t[bad]!r} >= t[{bad + 1}] = {t[bad + 1]!r}"
        )
    dt = (t[-1] - t[0]) / (n_times - 1)
    worst = float(np.max(np.abs(step - dt)))
    if worst > _UNIFORM_RTOL * dt:
        bad = int(np.argmax(np.abs(step - dt)))
        raise UsageError(
            f"t must be a uniform grid (steps equal to within {_UNIFORM_RTOL:g} relative); "
            f"t[{bad + 1}] - t[{bad}] = {step[bad]!r} but the mean step is {dt!r}"
        )
    return t, x, float(dt)


def _lag_steps(lags, n_times):
    """Integer lags (in samples): ~log-spaced 1 .. n_times // 2 by default, else validated."""
    if lags is None:
        hi = max(n_times // 2, 1)
        k = np.unique(np.round(np.geomspace(1, hi, num=min(hi, 40))).astype(np.int64))
        return k
    arr = np.asarray(lags)
    if arr.ndim != 1 or arr.size == 0 or not np.issubdtype(arr.dtype, np.integer):
        raise UsageError(
            f"lags must be a non-empty 1-D sequence of integer lags in samples (1 <= k <= "
            f"{n_times - 1}); got {lags!r}"
        )
    if arr.min() < 1 or arr.max() > n_times - 1:
        raise UsageError(f"lags must lie in 1 .. {n_times - 1} (samples); got min {arr.min()}, max {arr.max()}")
    return np.unique(arr.astype(np.int64))


def _check_bool(name, value):
    """``remove_drift="no"`` is a true value: only a real bool is taken."""
    if not isinstance(value, (bool, np.bool_)):
        raise UsageError(f"{name} must be True or False, got {value!r}")
    return bool(value)


# ---------------------------------------------------------------------------------------
# per-orbit moments of the increments: everything the MSD and its bootstrap need
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Moments:
    steps: np.ndarray     # (L,) integer lags
    tau: np.ndarray       # (L,) lag times
    A: np.ndarray         # (n, L) mean_j (dy)^2 per orbit, y = x - v (t - t0) (or x)
    B: np.ndarray         # (n, L) mean_j dy per orbit
    u: np.ndarray         # (n,) per-orbit velocity of y (endpoint estimator)
    v: np.ndarray         # (n,) per-orbit velocity of x
    center: float         # the drift subtracted from x to make y (0.0 if not removed)
    remove_drift: bool


def _moments(t, x, dt, steps, remove_drift):
    T = t[-1] - t[0]
    v = (x[:, -1] - x[:, 0]) / T
    center = float(np.mean(v)) if remove_drift else 0.0
    # subtract the ensemble drift first: the moments are then of the fluctuations, and the
    # bootstrap's A - 2 d tau B + d^2 tau^2 cancels only at the size of the fluctuations
    y = x - center * (t - t[0])[None, :] if remove_drift else x
    A, B = _increment_moments(y, steps)
    u = (y[:, -1] - y[:, 0]) / T
    return _Moments(steps, steps * dt, A, B, u, v, center, remove_drift)


def _increment_moments(y, steps):
    """Per orbit (row of ``y``) and lag ``k``: ``mean_j dy^2`` and ``mean_j dy`` over the
    ``n_times - k`` windows, ``dy = y[j + k] - y[j]``; in blocks of rows (bounded memory)."""
    n, m = y.shape
    A = np.empty((n, steps.size))
    B = np.empty((n, steps.size))
    rows = max(1, _ORBIT_CHUNK_ELEMENTS // m)
    for lo in range(0, n, rows):
        block = y[lo:lo + rows]
        for c, k in enumerate(steps):
            d = block[:, k:] - block[:, :-k]
            A[lo:lo + rows, c] = np.mean(d * d, axis=1)
            B[lo:lo + rows, c] = np.mean(d, axis=1)
    return A, B


def _msd_weighted(mom, W):
    """MSD for orbit weights W (rows sum to n_orbits: 1 each, or bootstrap counts), with
    the weighted ensemble's own drift removed. Returns (msd (..., L), drift (...,))."""
    n = mom.A.shape[0]
    W = np.atleast_2d(W).astype(float)
    A = W @ mom.A / n
    drift = W @ mom.v / n
    if not mom.remove_drift:
        return A, drift
    d = W @ mom.u / n                      # drift of the weighted ensemble minus the centre
    B = W @ mom.B / n
    tau = mom.tau[None, :]
    msd = A - 2.0 * d[:, None] * tau * B + (d[:, None] * tau) ** 2
    return msd, drift


# ---------------------------------------------------------------------------------------
# MSD
# ---------------------------------------------------------------------------------------
class _LagsAndMsd:
    """Unpacks as ``lags, msd = result`` (the results of :func:`msd` and :func:`msd_per_orbit`)."""

    lags: np.ndarray
    msd: np.ndarray

    def __iter__(self) -> Iterator[np.ndarray]:
        return iter((self.lags, self.msd))

    def __len__(self) -> int:
        return 2


@dataclass(frozen=True)
class MSD(_LagsAndMsd):
    """Mean squared displacement of an ensemble; unpacks as ``lags, msd = result``.

    ``lags`` are lag times (``steps * dt``), ``msd`` the time- and ensemble-averaged MSD at
    each, ``steps`` the integer lags in samples. ``drift`` is the ensemble drift
    ``mean_i v_i`` (removed from ``msd`` iff ``drift_removed``), ``drift_spread`` the
    standard deviation of the per-orbit velocities ``velocities`` (ddof 1), ``drift_se``
    the standard error of ``drift`` (``drift_spread / sqrt(n_orbits)``)."""

    lags: np.ndarray
    msd: np.ndarray
    steps: np.ndarray
    drift: float
    drift_spread: float
    drift_se: float
    velocities: np.ndarray
    drift_removed: bool
    n_orbits: int


def msd(t: ArrayLike, x: ArrayLike, *, lags: Optional[ArrayLike] = None, remove_drift: bool = True) -> MSD:
    """Time- and ensemble-averaged mean squared displacement of lifted paths.

    ``t``: the common uniform time grid, shape ``(n_times,)``, strictly increasing.
    ``x``: lifted paths, shape ``(n_orbits, n_times)`` with ``n_orbits >= 2``, finite.
    ``lags``: integer lags in samples (``1 <= k <= n_times - 1``); default ~40 log-spaced
    unique integers from 1 to ``n_times // 2``.
    ``remove_drift``: subtract the ensemble drift ``v = mean_i (x_i(T) - x_i(0)) / T``
    (module docstring: why the ensemble's and not each orbit's).

    Returns an :class:`MSD`; ``lags, m = msd(t, x)`` gives the lag times and
    ``m_k = mean_i mean_j (x_i(t_{j+k}) - x_i(t_j) - v k dt)^2``. For diffusive paths the
    estimated drift biases ``m`` by the factor ``1 - tau / (n_orbits T)`` (docs/transport.md).

    Examples
    --------
    >>> import numpy as np
    >>> import taylorball as tb
    >>> t = np.arange(1000.0)
    >>> x = np.cumsum(np.random.default_rng(6).normal(size=(50, 1000)), axis=1)   # 50 random walks
    >>> lags, m = tb.transport.msd(t, x)
    >>> lags[:4], (m[:4] / lags[:4]).round(1)      # MSD = tau for unit steps
    (array([1., 2., 3., 4.]), array([1., 1., 1., 1.]))
    """
    remove_drift = _check_bool("remove_drift", remove_drift)
    t, x, dt = _paths(t, x)
    steps = _lag_steps(lags, x.shape[1])
    mom = _moments(t, x, dt, steps, remove_drift)
    m, _ = _msd_weighted(mom, np.ones(x.shape[0]))
    n = x.shape[0]
    spread = float(np.std(mom.v, ddof=1))
    return MSD(
        lags=_readonly(mom.tau), msd=_readonly(m[0]), steps=_readonly(steps),
        drift=float(np.mean(mom.v)), drift_spread=spread, drift_se=spread / math.sqrt(n),
        velocities=_readonly(mom.v), drift_removed=bool(remove_drift), n_orbits=n,
    )


@dataclass(frozen=True)
class OrbitMSD(_LagsAndMsd):
    """Time-averaged mean squared displacement of each orbit alone, with its *own* drift
    removed (:func:`msd_per_orbit`); unpacks as ``lags, msd = result``.

    ``lags`` (``steps * dt``) and ``steps`` as in :class:`MSD`; ``msd`` has shape
    ``(n_orbits, n_lags)``: row ``i`` is orbit ``i``'s MSD about its own line
    ``v_i t``; ``velocities`` the per-orbit drifts ``v_i`` (removed iff ``drift_removed``).
    ``msd.mean(axis=0)`` is the ensemble MSD with each orbit's own drift removed: the
    orbit-to-orbit spread of the drifts, which :func:`msd` keeps, is gone from it."""

    lags: np.ndarray
    msd: np.ndarray
    steps: np.ndarray
    velocities: np.ndarray
    drift_removed: bool
    n_orbits: int

    def exponents(self, lag_range: Optional[Tuple[float, float]] = None) -> np.ndarray:
        """Per orbit, the least-squares slope ``mu_i`` of ``log msd_i`` against ``log tau``
        over the lags with ``low <= tau <= high`` (``lag_range``, lag times; default all):
        shape ``(n_orbits,)``, ``nan`` for an orbit whose MSD is not positive at every
        fitted lag (e.g. an exactly straight path)."""
        fit = _fit_mask(self.lags, lag_range)
        mu, _ = _loglog_fit(np.log(self.lags[fit]), self.msd[:, fit])
        return mu


def msd_per_orbit(t: ArrayLike, x: ArrayLike, *, lags: Optional[ArrayLike] = None,
                  remove_drift: bool = True) -> OrbitMSD:
    """Time-averaged MSD of every orbit alone, each about its own drift.

    ``t``, ``x`` (here ``n_orbits >= 1``), ``lags``: as in :func:`msd`. With
    ``remove_drift`` orbit ``i``'s own endpoint velocity ``v_i = (x_i(T) - x_i(0)) / T`` is
    removed: ``msd[i, k] = mean_j (x_i(t_{j+k}) - x_i(t_j) - v_i tau_k)^2``. This is the
    single-orbit (time-averaged) MSD: a path on an invariant torus, a straight line plus a
    bounded quasi-periodic part, has a *bounded* one; a diffusing path grows like
    ``tau^mu``. Comparing it with :func:`msd` (ensemble drift removed) separates transport
    along each orbit from the spread of the orbits' mean rates (docs/transport.md).

    Returns an :class:`OrbitMSD`.

    Examples
    --------
    >>> import numpy as np
    >>> import taylorball as tb
    >>> t = np.linspace(0.0, 1000.0, 10001)
    >>> x = np.array([0.3 * t + np.sin(t), -0.1 * t + 2.0 * np.sin(1.3 * t)])   # two "tori"
    >>> bool(tb.transport.msd(t, x).msd[-1] > 1e4)             # the ensemble spreads: rates differ
    True
    >>> r = tb.transport.msd_per_orbit(t, x)              # each orbit alone stays bounded
    >>> bool(np.all(r.msd < 2 * (1 + 4)))                 # <= 2 a^2 (a = 1, 2), up to end effects
    True
    """
    remove_drift = _check_bool("remove_drift", remove_drift)
    t, x, dt = _paths(t, x, min_orbits=1)
    steps = _lag_steps(lags, x.shape[1])
    v = (x[:, -1] - x[:, 0]) / (t[-1] - t[0])
    y = x - v[:, None] * (t - t[0])[None, :] if remove_drift else x
    A, _ = _increment_moments(y, steps)
    return OrbitMSD(lags=_readonly(steps * dt), msd=_readonly(A), steps=_readonly(steps),
                    velocities=_readonly(v), drift_removed=bool(remove_drift), n_orbits=x.shape[0])


def _fit_mask(tau, lag_range):
    """The lags (times) inside ``lag_range`` (inclusive, a few ulps of slack); at least 2."""
    if lag_range is None:
        fit = np.ones(tau.size, dtype=bool)
    else:
        try:
            lo, hi = (float(v) for v in lag_range)
        except (TypeError, ValueError):
            raise UsageError(f"lag_range must be a pair (low, high) of lag times; got {lag_range!r}") from None
        # the lag times are k * dt in floating point: widen by a few ulps so an endpoint
        # given as k * dt (or a rounding of it) is inside
        slack = 4 * np.finfo(float).eps * max(abs(lo), abs(hi))
        fit = (tau >= lo - slack) & (tau <= hi + slack)
    if fit.sum() < 2:
        raise UsageError(
            f"lag_range {lag_range!r} holds {int(fit.sum())} of the lags {tau.tolist()}; "
            f"the fit needs at least 2 (lag times between {tau[0]:g} and {tau[-1]:g})"
        )
    return fit


# ---------------------------------------------------------------------------------------
# the exponent mu with a bootstrap over orbits
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DiffusionExponent:
    """Fit ``MSD(tau) = 2 D tau^mu`` over a lag range, with bootstrap intervals over orbits.

    ``mu``, ``D``, ``drift``: the estimates from the whole ensemble; ``ci``, ``D_ci``,
    ``drift_ci``: percentile bootstrap intervals at ``level``; ``drift_spread``,
    ``drift_se``: as in :class:`MSD`; ``lags``, ``msd``: the full MSD curve, ``fit``: the
    boolean mask of the lags used; ``lag_range``: the (low, high) lag times used;
    ``regime``: see :func:`diffusion_exponent`; ``mu_boot``: the bootstrap slopes (finite
    ones); ``n_boot_used``: their number (resamples whose MSD is not positive at every
    fitted lag, e.g. one ballistic orbit drawn n times, have no log-log fit and are left out).
    """

    mu: float
    ci: tuple
    D: float
    D_ci: tuple
    drift: float
    drift_ci: tuple
    drift_spread: float
    drift_se: float
    regime: str
    lags: np.ndarray
    msd: np.ndarray
    fit: np.ndarray
    lag_range: tuple
    level: float
    n_boot_used: int
    n_orbits: int
    mu_boot: np.ndarray = field(repr=False)


def _regime(lo, hi):
    has1 = lo <= 1.0 <= hi
    has2 = lo <= 2.0 <= hi
    if has1 and has2:
        return "undetermined"
    if has1:
        return "normal"
    if has2 or lo > 2.0:
        return "ballistic"
    return "subdiffusive" if hi < 1.0 else "superdiffusive"


def _loglog_fit(logtau, msd):
    """Least-squares slope and intercept of log msd vs logtau, row-wise; rows with a
    non-positive MSD give NaN."""
    msd = np.atleast_2d(msd)
    ok = np.all(msd > 0, axis=1)
    y = np.full(msd.shape, np.nan)
    y[ok] = np.log(msd[ok])
    X = logtau - logtau.mean()
    slope = (y - y.mean(axis=1, keepdims=True)) @ X / (X @ X)
    intercept = y.mean(axis=1) - slope * logtau.mean()
    return slope, intercept


def diffusion_exponent(t: ArrayLike, x: ArrayLike, *, lag_range: Optional[Tuple[float, float]] = None,
                       lags: Optional[ArrayLike] = None, n_boot: int = 1000, seed: SeedLike = 0,
                       level: float = 0.95, remove_drift: bool = True) -> DiffusionExponent:
    """Exponent ``mu`` of ``MSD ~ tau^mu`` with a bootstrap confidence interval over orbits.

    ``t``, ``x``, ``lags``, ``remove_drift``: as in :func:`msd`. ``lag_range``: ``(low, high)``
    lag *times*, inclusive; the fit uses the lags of the grid inside it (at least two);
    default all lags. ``n_boot`` resamples of the orbits with replacement (``>= 100``),
    at most ``MAX_BOOT`` (1e5), ``seed`` for numpy's ``default_rng`` (None, an integer >= 0, a
    ``SeedSequence`` or a ``Generator``), ``level`` in (0, 1). ``remove_drift`` must be a bool.

    ``mu`` and ``log(2 D)`` are the least-squares slope and intercept of ``log MSD`` against
    ``log tau`` on the fitted lags. Each bootstrap resample draws ``n_orbits`` orbits with
    replacement, removes *its own* ensemble drift, recomputes the MSD (exactly, from per-orbit
    moments of the increments) and refits; ``ci`` is the ``(1 - level) / 2`` and
    ``(1 + level) / 2`` percentile of the slopes, likewise ``D_ci`` and ``drift_ci``. The
    interval measures the orbit-to-orbit sampling error only (not a systematic curvature
    of the MSD over the lag range); with few orbits it is too narrow: below ``FEW_ORBITS``
    (20) orbits a ``UserWarning`` says so. Measured on Brownian paths (``mu = 1``; 1000 unit
    steps, lags 1..100, 400 ensembles each), a nominal 95 % interval covered ``mu = 1`` with
    probability 0.70, 0.81, 0.90, 0.91, 0.94, 0.92, 0.95 for 3, 5, 10, 15, 20, 30, 50 orbits
    (standard errors 0.01-0.02).

    Paths whose MSD at a fitted lag is at the rounding level of ``x`` (straight lines: pure
    drift, ``(64 eps max|x|)^2`` or less after the drift is removed) have no exponent: a
    ``UsageError`` says so instead of fitting rounding noise.

    ``regime`` is decided from ``ci`` against the two reference exponents 1 and 2:
    ``"normal"`` if it contains 1 and not 2; ``"ballistic"`` if it contains 2 and not 1, or
    lies above 2; ``"subdiffusive"`` if it lies below 1; ``"superdiffusive"`` if it lies
    strictly between 1 and 2; ``"undetermined"`` if it contains both 1 and 2 (too few orbits
    or too short a lag range to tell).

    Examples
    --------
    >>> import numpy as np
    >>> import taylorball as tb
    >>> t = np.arange(1000.0)
    >>> rng = np.random.default_rng(6)
    >>> walks = np.cumsum(rng.normal(size=(50, 1000)), axis=1)   # 50 random walks
    >>> fit = tb.transport.diffusion_exponent(t, walks, lag_range=(1, 100))
    >>> round(fit.mu, 2), fit.regime               # a 95 % interval: 1 seed in 20 misses mu = 1
    (1.0, 'normal')
    >>> flights = rng.normal(size=(50, 1)) * t                   # 50 constant velocities
    >>> tb.transport.diffusion_exponent(t, flights, lag_range=(1, 100)).regime
    'ballistic'
    """
    remove_drift = _check_bool("remove_drift", remove_drift)
    n_boot = _check_int("n_boot", n_boot, 100)
    if n_boot > MAX_BOOT:
        raise UsageError(f"n_boot must be an integer in 100 .. {MAX_BOOT}; got {n_boot!r} (a percentile interval "
                         "needs ~1e3-1e4 resamples; more only costs time and memory)")
    level = _check_level(level)
    rng = _check_seed(seed)
    t, x, dt = _paths(t, x)
    steps = _lag_steps(lags, x.shape[1])
    tau = steps * dt
    fit = _fit_mask(tau, lag_range)
    mom = _moments(t, x, dt, steps, remove_drift)
    n = x.shape[0]
    curve, drift = _msd_weighted(mom, np.ones(n))
    logtau = np.log(tau[fit])
    _check_above_rounding(x, tau[fit], curve[0, fit], remove_drift)
    mu, c = _loglog_fit(logtau, curve[:, fit])
    if not np.isfinite(mu[0]):
        raise UsageError(
            "x has a mean squared displacement that is zero at a fitted lag (identical or "
            "drift-only paths); there is no exponent to fit"
        )
    if n < FEW_ORBITS:
        warnings.warn(
            f"diffusion_exponent: {n} orbits; with fewer than {FEW_ORBITS} the bootstrap interval is too narrow "
            "(for Brownian paths a nominal 95 % interval covered the exponent 70 % of the time with 3 orbits, "
            "81 % with 5, 90 % with 10); use more orbits, or read ci as a lower bound on the uncertainty",
            UserWarning, stacklevel=2)
    q = [(1.0 - level) / 2.0, (1.0 + level) / 2.0]
    rows = max(1, _ORBIT_CHUNK_ELEMENTS // n)  # resamples per block: bounded memory
    bmu_, bc_, bdrift_ = [], [], []
    for lo in range(0, n_boot, rows):
        W = rng.multinomial(n, np.full(n, 1.0 / n), size=min(rows, n_boot - lo))
        bmsd, bd = _msd_weighted(mom, W)
        m_, c_ = _loglog_fit(logtau, bmsd[:, fit])
        bmu_.append(m_)
        bc_.append(c_)
        bdrift_.append(bd)
    bmu, bc, bdrift = np.concatenate(bmu_), np.concatenate(bc_), np.concatenate(bdrift_)
    good = np.isfinite(bmu)
    ci = tuple(float(v) for v in np.quantile(bmu[good], q))
    D_ci = tuple(float(v) for v in np.quantile(np.exp(bc[good]) / 2.0, q))
    drift_ci = tuple(float(v) for v in np.quantile(bdrift, q))
    spread = float(np.std(mom.v, ddof=1))
    return DiffusionExponent(
        mu=float(mu[0]), ci=ci, D=float(np.exp(c[0]) / 2.0), D_ci=D_ci,
        drift=float(drift[0]), drift_ci=drift_ci, drift_spread=spread,
        drift_se=spread / math.sqrt(n), regime=_regime(*ci), lags=_readonly(tau),
        msd=_readonly(curve[0]), fit=_readonly(fit), lag_range=(float(tau[fit][0]), float(tau[fit][-1])),
        level=level, n_boot_used=int(good.sum()), n_orbits=n, mu_boot=_readonly(bmu[good]),
    )


# The residual MSD of paths that are a straight line (plus a constant) in floating point:
# every x_ij carries a rounding of up to eps/2 |x_ij|, and removing the drift line adds a
# few more of the same size, so an increment is rounding noise of size ~ eps max|x| and its
# square ~ (eps max|x|)^2. An MSD below (_ROUNDING_FACTOR eps max|x|)^2 at a fitted lag is
# that noise, not transport: its log-log slope is meaningless (pure linear drift gave mu =
# 0.06, "subdiffusive"). 64 allows for the few roundings of each increment with room; a
# genuine MSD at this level is not resolvable in float64 anyway.
_ROUNDING_FACTOR = 64.0


def _check_above_rounding(x, tau_fit, msd_fit, remove_drift):
    floor = (_ROUNDING_FACTOR * np.finfo(float).eps * float(np.max(np.abs(x)))) ** 2
    low = msd_fit <= floor
    if np.any(low):
        k = int(np.flatnonzero(low)[0])
        raise UsageError(
            f"x has a mean squared displacement of {msd_fit[k]:.3g} at the fitted lag {tau_fit[k]:g}: zero or at "
            f"the rounding level of x ({floor:.3g} = ({_ROUNDING_FACTOR:g} eps max|x|)^2); what is left "
            + ("after removing the drift " if remove_drift else "")
            + "is rounding noise (the paths are straight lines, e.g. pure drift), so there is no exponent to fit"
        )


def _check_level(level):
    if isinstance(level, (bool, np.bool_)) or not isinstance(level, (int, float, np.integer, np.floating)):
        raise UsageError(f"level must be a confidence level in (0, 1), e.g. 0.95; got {level!r}")
    level = float(level)
    if not 0.0 < level < 1.0:
        raise UsageError(f"level must be a confidence level in (0, 1), e.g. 0.95; got {level!r}")
    return level


def _check_seed(seed):
    """numpy's generator for ``seed`` (None, an integer >= 0, a SeedSequence or a Generator)."""
    if isinstance(seed, (bool, np.bool_)) or not (
            seed is None or isinstance(seed, (int, np.integer, np.random.SeedSequence, np.random.Generator))):
        raise UsageError(f"seed must be None, an integer >= 0, a numpy SeedSequence or Generator; got {seed!r}")
    if isinstance(seed, (int, np.integer)) and seed < 0:
        raise UsageError(f"seed must be an integer >= 0 (numpy's default_rng); got {seed!r}")
    return np.random.default_rng(seed)


# ---------------------------------------------------------------------------------------
# ballistic (accelerator-mode-like) orbits
# ---------------------------------------------------------------------------------------
def ballistic_orbits(t: ArrayLike, x: ArrayLike, *, reference: Optional[float] = None, rel_tol: float = 0.05,
                     n_sigma: float = 5.0) -> np.ndarray:
    """Indices (sorted, int array) of the orbits that move ballistically relative to the rest.

    For orbit ``i`` let ``x_i(t) ~ a_i + w_i t`` be the least-squares line, ``rms_i`` the
    root-mean-square of its residuals, ``T = t[-1] - t[0]``, ``v_ref = reference`` (default
    the median over orbits of the endpoint velocities ``(x_i(T) - x_i(0)) / T``: a robust
    mean rotation that a minority of ballistic orbits does not move),
    ``Delta_i = x_i(T) - x_i(0) - v_ref T`` the end displacement relative to the reference,
    and ``s = 1.4826 * median_i |Delta_i - median Delta|`` the ensemble's robust (MAD)
    spread of end displacements -- the diffusive spread at the end while at most half the
    orbits are ballistic. Orbit ``i`` is *ballistic* iff both

    1. persistence: ``rms_i <= rel_tol * |w_i - v_ref| T`` (the displacement relative to
       the reference is a straight line to within ``rel_tol`` of its size, so the velocity
       persisted over the whole run: a diffusive path's residual is ~0.3 of its
       displacement, a burst or a long flight followed by a stop leaves a large residual);
    2. significance: ``|w_i - v_ref| T > n_sigma * s`` (the line carries the orbit
       ``n_sigma`` diffusive spreads away: with Gaussian spreading a diffusive orbit does
       so with probability ``P(|N(0,1)| > 5) = 6e-7``).

    Needs ``n_orbits >= 2``; with most orbits ballistic, ``s`` is the ballistic spread and
    only the outliers among them are returned (pass ``reference`` and think about ``s``).
    """
    t, x, _ = _paths(t, x)
    rel_tol = float(rel_tol)
    n_sigma = float(n_sigma)
    if not rel_tol > 0:
        raise UsageError(f"rel_tol must be > 0 (a fraction, e.g. 0.05); got {rel_tol!r}")
    if not n_sigma > 0:
        raise UsageError(f"n_sigma must be > 0 (e.g. 5); got {n_sigma!r}")
    T = t[-1] - t[0]
    v_end = (x[:, -1] - x[:, 0]) / T
    if reference is None:
        v_ref = float(np.median(v_end))
    else:
        v_ref = float(reference)
        if not math.isfinite(v_ref):
            raise UsageError(f"reference must be a finite velocity; got {reference!r}")
    s_ = t - t.mean()
    xc = x - x.mean(axis=1, keepdims=True)
    w = xc @ s_ / (s_ @ s_)
    resid = xc - w[:, None] * s_[None, :]
    rms = np.sqrt(np.mean(resid * resid, axis=1))
    delta = (v_end - v_ref) * T
    spread = 1.4826 * float(np.median(np.abs(delta - np.median(delta))))
    shift = np.abs(w - v_ref) * T
    persistent = rms <= rel_tol * shift
    significant = shift > n_sigma * spread
    return np.flatnonzero(persistent & significant)


# ---------------------------------------------------------------------------------------
# first passage
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EscapeTimes:
    """First-passage times of an ensemble through ``r >= level``.

    ``times``: per orbit, the first sample time ``t_j - t[0]`` with ``r_ij >= level``
    (measured from the start of the grid), ``inf`` if never before ``t_end``; ``t_end``:
    ``t[-1] - t[0]`` (the censoring time); ``fraction_escaped``; ``median``: the median of the
    first-passage time over all orbits (``inf`` if at most half escaped: the never-escaped
    ones count as later than ``t_end``). ``survival(s)``: the empirical ``P(T > s)``;
    ``cdf(s) = 1 - survival(s)``; ``quantile(q)``."""

    times: np.ndarray
    level: float
    t_end: float
    fraction_escaped: float
    median: float
    n_orbits: int

    def survival(self, s: ArrayLike) -> Union[float, np.ndarray]:
        s = np.asarray(s, dtype=float)
        srt = np.sort(self.times)
        return (self.n_orbits - np.searchsorted(srt, s, side="right")) / self.n_orbits

    def cdf(self, s: ArrayLike) -> Union[float, np.ndarray]:
        s = np.asarray(s, dtype=float)
        return np.searchsorted(np.sort(self.times), s, side="right") / self.n_orbits

    def quantile(self, q: float) -> float:
        """The empirical ``q``-quantile of the first-passage time (lower, no interpolation;
        ``inf`` if fewer than a fraction ``q`` escaped)."""
        q = float(q)
        if not 0.0 < q < 1.0:
            raise UsageError(f"q must be in (0, 1); got {q!r}")
        srt = np.sort(self.times)
        return float(srt[int(math.ceil(q * self.n_orbits)) - 1])


def first_passage(t: ArrayLike, r: ArrayLike, level: float) -> EscapeTimes:
    """First time each orbit's observable reaches ``level``: ``min{t_j - t_0 : r_ij >= level}``.

    ``t``: uniform grid ``(n_times,)``; ``r``: shape ``(n_orbits, n_times)``, finite, one row
    per orbit (e.g. ``|R|`` or a lifted angle's distance from its start); ``level``: a finite
    number. The time is that of the first *sample* at or above the level: a path sampled
    every ``dt`` is seen crossing later than it does (for Brownian motion the delay is the
    shift of the level by ``0.5826 sigma sqrt(dt)``, docs/transport.md). An orbit that
    starts at or above the level has time 0. Returns an :class:`EscapeTimes`.
    """
    t, r, _ = _paths(t, r, name="r", min_orbits=1)
    try:
        level = float(level)
    except (TypeError, ValueError):
        raise UsageError(f"level must be a real number; got {level!r}") from None
    if not math.isfinite(level):
        raise UsageError(f"level must be finite; got {level!r}")
    hit = r >= level
    first = np.argmax(hit, axis=1)
    any_hit = hit[np.arange(r.shape[0]), first]
    times = np.where(any_hit, t[first] - t[0], np.inf)
    n = r.shape[0]
    srt = np.sort(times)
    median = float(srt[(n - 1) // 2]) if n % 2 else float(0.5 * (srt[n // 2 - 1] + srt[n // 2]))
    return EscapeTimes(
        times=_readonly(times), level=level, t_end=float(t[-1] - t[0]),
        fraction_escaped=float(np.mean(any_hit)), median=median, n_orbits=n,
    )
