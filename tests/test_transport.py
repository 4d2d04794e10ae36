"""taylorball.transport on processes with known answers (docs/transport.md, "Validation").

Every random test has a fixed seed and a tolerance derived from the statistics of the
process, stated next to it; "4 sigma" bounds fail by chance with probability 6e-5 for a
correct implementation, so a failure means a wrong formula, not bad luck. Exact processes
(ballistic paths) are held to rounding, in units of float64's eps.
"""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

import taylorball as tb
from taylorball.errors import UsageError
from taylorball.transport import _moments, _msd_weighted

EPS = np.finfo(float).eps
Z4 = 4.0  # two-sided 4-sigma: P(|N(0,1)| > 4) = 6.3e-5


# ---------------------------------------------------------------------------------------
# processes with known answers (also used by docs/transport.md's table)
# ---------------------------------------------------------------------------------------
def brownian(n_orbits, n_times, dt, *, sigma=1.0, drift=0.0, seed=0):
    """x(t) = drift t + sigma W(t), x(0) = 0, sampled exactly on t_k = k dt."""
    rng = np.random.default_rng(seed)
    t = dt * np.arange(n_times)
    steps = sigma * math.sqrt(dt) * rng.standard_normal((n_orbits, n_times - 1))
    x = np.concatenate([np.zeros((n_orbits, 1)), np.cumsum(steps, axis=1)], axis=1)
    return t, x + drift * t[None, :]


def ballistic(n_orbits, n_times, dt, *, seed=0):
    """x_i(t) = v_i t with v_i ~ N(0, 1): MSD about the ensemble drift = var(v) tau^2 exactly."""
    rng = np.random.default_rng(seed)
    t = dt * np.arange(n_times)
    v = rng.standard_normal(n_orbits)
    return t, v[:, None] * t[None, :], v


def fbm(n_orbits, n_times, dt, *, hurst, seed=0):
    """Fractional Brownian motion, exactly (Davies & Harte 1987): the fGn autocovariance
    g(k) = dt^2H (|k+1|^2H - 2|k|^2H + |k-1|^2H) / 2 embedded in a circulant of size 2N, whose
    eigenvalues are >= 0 for H <= 1/2; B(0) = 0 and E (B(t + tau) - B(t))^2 = tau^2H, so
    MSD = 2 D tau^mu with mu = 2H, D = 1/2."""
    rng = np.random.default_rng(seed)
    t = dt * np.arange(n_times)
    N, h2 = n_times - 1, 2.0 * hurst
    k = np.arange(N + 1.0)
    g = 0.5 * dt**h2 * (np.abs(k + 1) ** h2 - 2 * k**h2 + np.abs(k - 1) ** h2)
    lam = np.fft.fft(np.concatenate([g, g[-2:0:-1]])).real
    assert lam.min() >= -1e-12 * lam.max()  # a valid embedding (rounding-size negatives only)
    z = rng.standard_normal((n_orbits, 2 * N)) + 1j * rng.standard_normal((n_orbits, 2 * N))
    fgn = np.fft.fft(np.sqrt(np.clip(lam, 0, None) / (2 * N)) * z, axis=1)[:, :N].real
    return t, np.concatenate([np.zeros((n_orbits, 1)), np.cumsum(fgn, axis=1)], axis=1)


def bm_first_passage_cdf(s, a, sigma=1.0):
    """P(T_a <= s) = 2 (1 - Phi(a / (sigma sqrt s))) = erfc(a / (sigma sqrt(2 s))) (reflection)."""
    s = np.asarray(s, dtype=float)
    out = np.zeros_like(s)
    pos = s > 0
    out[pos] = [math.erfc(a / (sigma * math.sqrt(2.0 * v))) for v in s[pos]]
    return out


def _boot_se(res):
    return float(np.std(res.mu_boot, ddof=1))


# ---------------------------------------------------------------------------------------
# the API and the layer rule
# ---------------------------------------------------------------------------------------
def _top_level_imports(path):
    top = set()
    for node in ast.parse(Path(path).read_text()).body:
        if isinstance(node, ast.Import):
            top |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            top.add("." * node.level + (node.module or ""))
    return top


def test_public_face_and_numpy_only_module():
    assert tb.transport.msd is tb.transport.__dict__["msd"]
    assert callable(tb.transport.diffusion_exponent)
    top = _top_level_imports(tb.transport.__file__)
    # typing and the annotation aliases (taylorball._typing: numpy, typing and the parameter classes)
    assert top <= {"__future__", "math", "warnings", "dataclasses", "numpy", ".errors", "typing", "numpy.typing",
                   "._typing", "._occupation"}, top
    # the occupation part of the module lives in taylorball._occupation, numpy only as well
    top = _top_level_imports(Path(tb.transport.__file__).with_name("_occupation.py"))
    assert top <= {"__future__", "math", "dataclasses", "numpy", ".errors", "typing", "numpy.typing"}, top


def test_msd_unpacks_and_default_lags():
    t, x = brownian(4, 101, 0.1, seed=1)
    res = tb.transport.msd(t, x)
    lags, m = res
    assert lags is res.lags and m is res.msd
    assert res.steps[0] == 1 and res.steps[-1] == 50
    assert np.all(np.diff(res.steps) > 0)
    np.testing.assert_allclose(lags, res.steps * 0.1, rtol=4 * EPS)  # k dt against (t[-1]-t[0])/(n-1): few ulps
    with pytest.raises(ValueError):
        res.msd[0] = 1.0  # read-only result


# ---------------------------------------------------------------------------------------
# Brownian paths: mu = 1, D = sigma^2 / 2
# ---------------------------------------------------------------------------------------
def test_brownian_msd_values_against_theory():
    """Each MSD value against sigma^2 tau (1 - tau / (n T)) (the factor is the exact bias of
    removing the estimated ensemble drift), within 4 standard deviations of the time- and
    ensemble-averaged estimator: relative variance (4k^2 + 2) / (3k (N - k + 1)) / n for one
    1-D path of N increments at lag k <= N/2 (Qian, Sheetz & Elson 1991, doubled for 1-D;
    an overestimate near N/2, so conservative), over n independent orbits."""
    n, n_times, dt, sigma = 200, 1001, 0.01, 1.3
    t, x = brownian(n, n_times, dt, sigma=sigma, seed=11)
    res = tb.transport.msd(t, x)
    N = n_times - 1
    T = t[-1]
    k = res.steps
    expected = sigma**2 * res.lags * (1.0 - res.lags / (n * T))
    rel_sd = np.sqrt((4 * k**2 + 2) / (3 * k * (N - k + 1)) / n)
    z = (res.msd / expected - 1.0) / rel_sd
    assert np.max(np.abs(z)) <= Z4, z


def test_brownian_exponent_and_coefficient():
    n, n_times, dt, sigma = 200, 1001, 0.01, 1.0
    t, x = brownian(n, n_times, dt, sigma=sigma, seed=2)
    res = tb.transport.diffusion_exponent(t, x, seed=3)
    assert res.ci[0] <= 1.0 <= res.ci[1]           # the brief's requirement (95 % interval)
    assert abs(res.mu - 1.0) <= Z4 * _boot_se(res)  # and the 4-sigma form of it
    assert res.ci[1] - res.ci[0] < 0.1              # an informative interval: 200 orbits, 3 decades
    assert res.regime == "normal"
    # D = sigma^2 / 2; the 95 % interval half-width is 1.96 standard errors
    se_D = (res.D_ci[1] - res.D_ci[0]) / (2 * 1.96)
    assert abs(res.D - sigma**2 / 2) <= Z4 * se_D
    assert res.n_boot_used == 1000


def test_bootstrap_msd_is_the_msd_of_the_resampled_ensemble():
    """The bootstrap's moment formula equals recomputing msd() on the drawn orbits (with that
    draw's own drift). Rounding: both sides sum ~10^3 squares of O(1) numbers (pairwise, so
    ~log2(10^3) ulps each) and differ in the order of the centring; 2**10 eps leaves margin."""
    t, x = brownian(30, 501, 0.02, drift=0.7, seed=4)
    mom = _moments(t, x, 0.02, tb.transport.msd(t, x).steps, True)
    rng = np.random.default_rng(5)
    for counts in rng.multinomial(30, np.full(30, 1 / 30), size=5):
        formula, drift = _msd_weighted(mom, counts)
        direct = tb.transport.msd(t, x[np.repeat(np.arange(30), counts)])
        np.testing.assert_allclose(formula[0], direct.msd, rtol=2**10 * EPS, atol=0)
        assert abs(drift[0] - direct.drift) <= 2**10 * EPS * abs(direct.drift)


# ---------------------------------------------------------------------------------------
# ballistic paths: mu = 2 exactly
# ---------------------------------------------------------------------------------------
def test_ballistic_exponent_is_two():
    """MSD = mean (v - vbar)^2 tau^2 exactly, in every resample too. Rounding: log MSD has
    relative error ~ a few ulps times log2(n_times) from the sums; the slope is a weighted
    sum of ~40 of them with weights summing in magnitude to ~2/log(range) < 1, so 2**10 eps
    is a wide margin."""
    t, x, v = ballistic(50, 201, 0.5, seed=6)
    res = tb.transport.diffusion_exponent(t, x, seed=7)
    assert abs(res.mu - 2.0) <= 2**10 * EPS
    assert abs(res.ci[0] - 2.0) <= 2**10 * EPS and abs(res.ci[1] - 2.0) <= 2**10 * EPS
    assert res.regime == "ballistic"
    # 2 D = mean (v - vbar)^2; exp of an intercept with error ~2**10 eps * |log tau| (<= 5)
    assert abs(res.D / (np.var(v) / 2) - 1.0) <= 2**13 * EPS
    assert abs(res.drift - np.mean(v)) <= 2**4 * EPS * np.max(np.abs(v))


# ---------------------------------------------------------------------------------------
# fractional Brownian motion, H = 0.25: mu = 0.5
# ---------------------------------------------------------------------------------------
def test_fbm_subdiffusive_exponent():
    t, x = fbm(200, 512, 0.1, hurst=0.25, seed=8)
    res = tb.transport.diffusion_exponent(t, x, seed=9)
    assert res.ci[1] < 1.0                          # the brief's requirement: 1 excluded
    assert abs(res.mu - 0.5) <= Z4 * _boot_se(res)
    assert res.regime == "subdiffusive"
    se_D = (res.D_ci[1] - res.D_ci[0]) / (2 * 1.96)
    assert abs(res.D - 0.5) <= Z4 * se_D


# ---------------------------------------------------------------------------------------
# drift plus Brownian noise
# ---------------------------------------------------------------------------------------
def test_drift_is_recovered_and_removed():
    n, n_times, dt, v0 = 100, 1001, 0.01, 3.0
    t, x = brownian(n, n_times, dt, drift=v0, seed=10)
    res = tb.transport.diffusion_exponent(t, x, seed=11)
    T = t[-1]
    se = 1.0 / math.sqrt(n * T)  # sd of mean_i x_i(T) / T for unit Brownian noise
    assert abs(res.drift - v0) <= Z4 * se
    assert abs(res.drift_se / se - 1.0) <= Z4 / math.sqrt(2 * (n - 1))  # sd of a sample sd
    assert res.drift_ci[0] < res.drift < res.drift_ci[1]
    assert res.ci[0] <= 1.0 <= res.ci[1] and res.regime == "normal"
    kept = tb.transport.diffusion_exponent(t, x, seed=11, remove_drift=False)
    # v0^2 tau^2 dominates sigma^2 tau beyond tau = 1/9: the long lags are ballistic
    assert kept.mu > 1.5 and kept.regime in ("superdiffusive", "ballistic")
    assert kept.drift == res.drift


# ---------------------------------------------------------------------------------------
# ballistic orbits among diffusive ones
# ---------------------------------------------------------------------------------------
def test_ballistic_orbits_found_and_only_they():
    """60 unit Brownian orbits and 6 with velocities of 20..30 diffusive spreads over the run
    (|v| T in [20, 30] sqrt(T)) plus the same noise. A ballistic one is missed only if its
    residual rms exceeds 0.05 * 20 sqrt(T) = sqrt(T), ~4 times the typical rms of a Brownian
    path about its line (~0.26 sqrt(T)); a diffusive one is taken only if it ends 5 robust
    spreads out (P = 6e-7 each; the 10 % of ballistic orbits widen the MAD, which only makes
    that rarer)."""
    n_diff, n_ball, n_times, dt = 60, 6, 1001, 0.01
    t, x = brownian(n_diff + n_ball, n_times, dt, seed=12)
    T = t[-1]
    rng = np.random.default_rng(13)
    which = np.sort(rng.choice(n_diff + n_ball, size=n_ball, replace=False))
    v = rng.uniform(20, 30, size=n_ball) * rng.choice([-1.0, 1.0], size=n_ball) * math.sqrt(T) / T
    x[which] += v[:, None] * t[None, :]
    found = tb.transport.ballistic_orbits(t, x)
    np.testing.assert_array_equal(found, which)
    assert tb.transport.ballistic_orbits(t, np.delete(x, which, axis=0)).size == 0


# ---------------------------------------------------------------------------------------
# first passage of Brownian motion through a level
# ---------------------------------------------------------------------------------------
def test_brownian_first_passage_distribution():
    """Empirical CDF of T_a against P(T <= s) = 2 (1 - Phi(a / sqrt s)) on the whole grid.
    Bound: the Kolmogorov-Smirnov critical value at alpha = 1e-3, 1.95 / sqrt(n), plus the
    discrete-monitoring bias: sampled every dt, BM is seen crossing a as if the level were
    a + 0.5826 sqrt(dt) (Broadie, Glasserman & Kou 1997), which lowers the CDF by at most
    |dF/da| * 0.5826 sqrt(dt) <= 2 max_u u phi(u) / a * 0.5826 sqrt(dt) = 0.484 * 0.5826 sqrt(dt) / a."""
    n, n_times, dt, a = 2000, 2001, 2e-3, 1.0
    t, x = brownian(n, n_times, dt, seed=14)
    esc = tb.transport.first_passage(t, x, a)
    ks = 1.95 / math.sqrt(n)
    bias = 2 * math.exp(-0.5) / math.sqrt(2 * math.pi) * 0.5826 * math.sqrt(dt) / a
    dev = esc.cdf(t) - bm_first_passage_cdf(t, a)
    assert np.max(np.abs(dev)) <= ks + bias, (np.max(np.abs(dev)), ks, bias)
    assert abs(esc.fraction_escaped - bm_first_passage_cdf([t[-1]], a)[0]) <= ks + bias
    # the median: F(median) = 1/2 -> a / sqrt(m) = Phi^-1(3/4) = 0.6744897...; the CDF band
    # above puts the empirical median where the true CDF is within 1/2 -+ (ks + bias)
    m_true = (a / 0.6744897501960817) ** 2
    lo_hi = bm_first_passage_cdf([esc.median], a)[0]
    assert abs(lo_hi - 0.5) <= ks + bias + 1.0 / n, (esc.median, m_true)
    assert np.all(np.isinf(esc.times) == (x.max(axis=1) < a))
    assert esc.quantile(0.5) <= esc.median


def test_first_passage_edges():
    t = 10.0 + np.arange(5.0)  # times are counted from the grid's start
    r = np.array([[0.0, 1.0, 2.0, 3.0, 4.0], [5.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 0.0]])
    esc = tb.transport.first_passage(t, r, 2.0)
    np.testing.assert_array_equal(esc.times, [2.0, 0.0, np.inf])
    assert esc.fraction_escaped == 2 / 3 and esc.median == 2.0
    np.testing.assert_array_equal(esc.survival([0.0, 1.0, 2.0, 10.0]), [2 / 3, 2 / 3, 1 / 3, 1 / 3])
    assert tb.transport.first_passage(t, r[2:], 2.0).median == math.inf


# ---------------------------------------------------------------------------------------
# single orbits, each about its own drift (msd_per_orbit)
# ---------------------------------------------------------------------------------------
def test_single_brownian_orbit_msd_is_a_bridge():
    """With its own endpoint drift removed a Brownian path is a Brownian bridge, whose
    increment over tau has variance sigma^2 tau (1 - tau / T) exactly: the mean over 400
    orbits of the time-averaged single-orbit MSD against it, within 4 standard errors
    (the orbits are independent; se from their own spread), at every lag."""
    sigma, dt = 1.3, 0.01
    t, x = brownian(400, 1001, dt, sigma=sigma, drift=0.7, seed=11)
    r = tb.transport.msd_per_orbit(t, x)
    assert r.msd.shape == (400, r.lags.size) and r.n_orbits == 400
    T = t[-1] - t[0]
    theory = sigma**2 * r.lags * (1 - r.lags / T)
    z = (r.msd.mean(axis=0) - theory) / (r.msd.std(axis=0, ddof=1) / math.sqrt(400))
    assert np.max(np.abs(z)) <= Z4, np.max(np.abs(z))
    np.testing.assert_allclose(r.velocities, (x[:, -1] - x[:, 0]) / T, rtol=0, atol=0)
    one = tb.transport.msd_per_orbit(t, x[3:4])  # one orbit is enough: no ensemble statistic
    np.testing.assert_array_equal(one.msd[0], r.msd[3])
    mu = r.exponents((0.01, 0.1))  # the bridge factor is within 1 - 0.1/10 here: mu ~ 1
    assert abs(np.median(mu) - 1.0) < 0.05, np.median(mu)


def test_straight_lines_have_zero_own_msd_but_a_ballistic_ensemble_msd():
    """x_i = v_i t: about its own line each orbit does not move (0 to rounding: the residual
    of v_i t - v_i t is a few ulps of |v_i| T), while the ensemble MSD (ensemble drift
    removed) is var(v) tau^2 (test_ballistic_exponent_is_two)."""
    t, x, v = ballistic(20, 201, 0.1, seed=2)
    r = tb.transport.msd_per_orbit(t, x)
    scale = (np.abs(v) * t[-1]) ** 2
    assert np.all(r.msd <= (2**6 * EPS) ** 2 * scale[:, None])  # (few ulps of |v| T)^2
    assert tb.transport.msd(t, x).msd[-1] > 1e3 * r.msd.max() + 1.0


def test_torus_orbit_has_a_bounded_own_msd():
    """x = v t + a sin(w t) (a rotation plus a quasi-periodic part, as on a torus), over a
    whole number of periods so the endpoint drift is v to rounding: the own-drift MSD is
    mean_j a^2 (sin(w(t_j + tau)) - sin(w t_j))^2 = a^2 (1 - cos w tau) + e with the exact
    bound |e| <= 2 a^2 sin^2(w tau / 2) / (M |sin(w dt)|) (the mean of cos^2 over M
    equally spaced angles is 1/2 plus half a Dirichlet sum), plus rounding (2^8 eps of (v T)^2)."""
    a, w, v, dt = 1.7, 2 * math.pi / 5.0, 0.9, 0.05
    t = dt * np.arange(20001)  # T = 1000 = 200 periods
    x = np.vstack([v * t + a * np.sin(w * t), -v * t + a * np.sin(w * t)])
    r = tb.transport.msd_per_orbit(t, x)
    np.testing.assert_allclose(r.velocities, [v, -v], rtol=2**8 * EPS)
    M = t.size - r.steps
    exact = a**2 * (1 - np.cos(w * r.lags))
    bound = 2 * a**2 * np.sin(w * r.lags / 2) ** 2 / (M * abs(math.sin(w * dt))) + 2**8 * EPS * (v * t[-1]) ** 2
    assert np.all(np.abs(r.msd - exact[None, :]) <= bound[None, :])
    assert r.msd.max() <= 2 * a**2 * 1.01  # bounded: never above 2 a^2 (up to the end effect)
    assert tb.transport.msd(t, x).msd[-1] > 100 * r.msd.max()  # the ensemble: two rates, ballistic


# ---------------------------------------------------------------------------------------
# input validation: before any work, naming the argument, the value and the valid form
# ---------------------------------------------------------------------------------------
_T = np.arange(10.0)
_X = np.zeros((3, 10)) + np.arange(10.0)


@pytest.mark.parametrize(
    "call, words",
    [
        (lambda: tb.transport.msd(_T, _X[0]), ["x", "(10,)", "(n_orbits, n_times)"]),
        (lambda: tb.transport.msd(_T, _X[:1]), ["x", "1 orbit", "n_orbits >= 2"]),
        (lambda: tb.transport.msd_per_orbit(_T, _X[0]), ["x", "(10,)", "(n_orbits, n_times)"]),
        (lambda: tb.transport.msd_per_orbit(_T, _X[:0]), ["x", "0 orbit", "n_orbits >= 1"]),
        (lambda: tb.transport.msd_per_orbit(_T, _X, lags=[0]), ["lags", "1 .. 9"]),
        (lambda: tb.transport.msd_per_orbit(_T, _X).exponents((7.5, 8.5)), ["lag_range", "at least 2"]),
        (lambda: tb.transport.msd(_T[:9], _X), ["t", "(9,)", "10 sample times"]),
        (lambda: tb.transport.msd(_T[::-1], _X), ["t", "strictly increasing"]),
        (lambda: tb.transport.msd(_T ** 1.5, _X), ["t", "uniform", "mean step"]),
        (lambda: tb.transport.msd(_T, np.where(_X == 4, np.nan, _X)), ["x", "finite", "nan"]),
        (lambda: tb.transport.msd(_T, _X, lags=[0, 3]), ["lags", "1 .. 9"]),
        (lambda: tb.transport.msd(_T, _X, lags=[1.5]), ["lags", "integer"]),
        (lambda: tb.transport.diffusion_exponent(_T, _X, lag_range=(7.5, 8.5)), ["lag_range", "at least 2"]),
        (lambda: tb.transport.diffusion_exponent(_T, _X, lag_range=3), ["lag_range", "pair"]),
        (lambda: tb.transport.diffusion_exponent(_T, _X, level=95), ["level", "95", "(0, 1)"]),
        (lambda: tb.transport.diffusion_exponent(_T, _X, n_boot=10), ["n_boot", "10", ">= 100"]),
        (lambda: tb.transport.ballistic_orbits(_T, _X, rel_tol=0), ["rel_tol", "> 0"]),
        (lambda: tb.transport.first_passage(_T, _X, float("nan")), ["level", "finite"]),
        (lambda: tb.transport.first_passage(_T, _X[0], 1.0), ["r", "(n_orbits, n_times)"]),
    ],
)
def test_usage_errors(call, words):
    with pytest.raises(UsageError) as info:
        call()
    msg = str(info.value)
    for w in words:
        assert w in msg, (w, msg)


def test_zero_msd_is_refused():
    """Paths that are one common line: after the drift, nothing moves; no exponent."""
    with pytest.raises(UsageError, match="zero"):
        tb.transport.diffusion_exponent(_T, _X)


# ---------------------------------------------------------------------------------------
# bad inputs: caps, drift-only paths, flags, level and seed, few orbits
# ---------------------------------------------------------------------------------------
def test_n_boot_is_capped_before_any_work():
    """n_boot = 1e7 took 12 GB of bootstrap weights; now refused at once, naming the cap."""
    with pytest.raises(UsageError, match=r"n_boot must be an integer in 100 \.\. 100000; got 10000000"):
        tb.transport.diffusion_exponent(_T, _X, n_boot=10_000_000)


def test_bootstrap_in_blocks_is_the_one_call_bootstrap():
    """Many orbits: the resamples are drawn and reduced in blocks of bounded memory (here 3
    blocks of 838 for 5000 orbits); the draws are those of one multinomial call, so the
    slopes agree with a direct computation to rounding (the BLAS reduction of a block may
    differ from that of the whole in the last bit: 8 ulp of slopes ~1)."""
    t, x = brownian(5000, 60, 1.0, seed=3)
    r = tb.transport.diffusion_exponent(t, x, lag_range=(1, 20), n_boot=2000, seed=4)
    mom = _moments(t, x, 1.0, r.lags.astype(np.int64), True)  # dt = 1: the lags in samples
    W = np.random.default_rng(4).multinomial(5000, np.full(5000, 1 / 5000), size=2000)
    bmsd, _ = _msd_weighted(mom, W)
    logtau = np.log(mom.tau[r.fit])
    y = np.log(bmsd[:, r.fit])
    X = logtau - logtau.mean()
    slopes = (y - y.mean(axis=1, keepdims=True)) @ X / (X @ X)
    assert r.n_boot_used == 2000
    assert np.max(np.abs(r.mu_boot - slopes)) <= 8 * np.finfo(float).eps


@pytest.mark.parametrize("offsets", [0.0, 1e6])
def test_drift_only_paths_have_no_exponent(offsets):
    """Straight lines with one common velocity (and any offsets): after the drift removal
    only rounding noise is left; it gave mu = 0.06, "subdiffusive". Now refused, saying so."""
    t = np.linspace(0.0, 100.0, 1001)
    x = offsets + np.arange(30)[:, None] * 0.1 + 0.3 * t[None, :]
    with pytest.raises(UsageError, match="rounding level of x"):
        tb.transport.diffusion_exponent(t, x)


def test_small_but_real_diffusion_is_not_taken_for_rounding():
    """Brownian paths of amplitude 1e-6 on an offset of 1 and a drift: far above the
    rounding floor ((64 eps)^2 ~ 2e-28 here), fitted as usual."""
    t, x = brownian(40, 1000, 1.0, sigma=1e-6, drift=0.3, seed=2)
    r = tb.transport.diffusion_exponent(t, 1.0 + x, lag_range=(1, 100))
    assert r.regime == "normal" and abs(r.mu - 1.0) < 0.05


@pytest.mark.parametrize("fn", ["msd", "msd_per_orbit", "diffusion_exponent"])
@pytest.mark.parametrize("flag", ["no", "False", 0, 1, None])
def test_remove_drift_must_be_a_bool(fn, flag):
    """remove_drift="no" was taken as True."""
    with pytest.raises(UsageError, match=f"remove_drift must be True or False, got {flag!r}"):
        getattr(tb.transport, fn)(_T, _X, remove_drift=flag)


@pytest.mark.parametrize("kw, words", [
    (dict(level="0.95"), ["level", "'0.95'"]),
    (dict(level=None), ["level", "None"]),
    (dict(level=True), ["level", "True"]),
    (dict(level=float("nan")), ["level", "nan"]),
    (dict(seed="abc"), ["seed", "'abc'"]),
    (dict(seed=-1), ["seed", "-1", ">= 0"]),
    (dict(seed=1.5), ["seed", "1.5"]),
    (dict(seed=[1, 2]), ["seed", "[1, 2]"]),
])
def test_bad_level_and_seed_are_named(kw, words):
    """These gave raw ValueError / TypeError from float() or numpy's default_rng."""
    with pytest.raises(UsageError) as info:
        tb.transport.diffusion_exponent(_T, _X, **kw)
    for w in words:
        assert w in str(info.value), (w, str(info.value))


def test_good_seeds_are_taken():
    t, x = brownian(25, 200, 1.0, seed=5)
    a = tb.transport.diffusion_exponent(t, x, seed=np.int64(7))
    b = tb.transport.diffusion_exponent(t, x, seed=np.random.SeedSequence(7))
    c = tb.transport.diffusion_exponent(t, x, seed=np.random.default_rng(7))
    assert a.ci == b.ci == c.ci


def test_few_orbits_warn_that_the_interval_is_too_narrow():
    t, x = brownian(5, 200, 1.0, seed=5)
    with pytest.warns(UserWarning, match="5 orbits; with fewer than 20 the bootstrap interval is too narrow"):
        tb.transport.diffusion_exponent(t, x)
    t, x = brownian(20, 200, 1.0, seed=5)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tb.transport.diffusion_exponent(t, x)


@pytest.mark.slow
def test_bootstrap_coverage_against_the_number_of_orbits():
    """The warning's premise, on Brownian paths (mu = 1 exactly): a nominal 95 % interval
    covers mu = 1 far less often with 5 orbits than with 30 (measured 0.81 and 0.92 with
    400 ensembles each; here 200, binomial standard error <= 0.03)."""
    import warnings

    t = np.arange(1000.0)
    cover = {}
    for n in (5, 30):
        rng = np.random.default_rng(1000 + n)
        hits = 0
        for r in range(200):
            x = np.cumsum(rng.normal(size=(n, 1000)), axis=1)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                f = tb.transport.diffusion_exponent(t, x, lag_range=(1, 100), n_boot=1000, seed=r)
            hits += f.ci[0] <= 1.0 <= f.ci[1]
        cover[n] = hits / 200
    assert cover[5] < 0.88 < cover[30], cover  # 0.88: > 2 standard errors from both
