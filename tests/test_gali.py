"""GALI_k (tb.gali; Skokos, Bountis & Antonopoulos 2007): on a chaotic orbit GALI_2 falls
like exp(-(lambda_1 - lambda_2) t) with the exponents of the independent Benettin spectrum
(tb.lyapunov_spectrum of the same orbit); on a regular orbit it stays of order one; the
sample times leave the run unchanged; bad arguments are refused before any work."""

import dataclasses
import math

import numpy as np
import pytest

import taylorball as tb
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS, FIG4B_LEVELS, demo_reduced_state

from .conftest import FIG5


def _fig4a_state():
    return tb.section_admissible_sample(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), n=1, seed=0)["states"][0][0]


def test_gali2_of_a_chaotic_orbit_falls_at_lambda1_minus_lambda2():
    """Fig. 4a orbit (reduced, chaotic): both deviation vectors align with the most unstable
    direction, |w1 ^ w2| grows like exp((lambda_1 + lambda_2) t) and each |w_i| like
    exp(lambda_1 t), so ln GALI_2 falls with slope lambda_1 - lambda_2. Slope fitted on
    [30, 300] where GALI_2 > 1e-12 (above the rounding floor ~eps, where the vectors' difference
    is lost); exponents from tb.lyapunov_spectrum to t = 300 (finite-time, lambda_2 ~ 0.014
    is the O(ln(t)/t) estimate of a zero). Measured: 0.0843 vs 0.0945 (three orbits: 0.084 /
    0.094, 0.092 / 0.097, 0.110 / 0.114). Bound 25 %: both are finite-time averages over the
    same 300 time units of a chaotic orbit, whose lambda_max fluctuates by ~10 % at this
    length (docs/chaos.md: +-0.0074 of 0.11 at t = 1000, sigma ~ 1/sqrt(t))."""
    x = _fig4a_state()
    g = tb.gali("reduced", FIG4_BALL, x, 300.0, k=2, sample=np.arange(10.0, 301.0, 10.0))
    lam = np.asarray(tb.lyapunov_spectrum("reduced", FIG4_BALL, x, 300.0).exponents, dtype=float)
    m = (g.values > 1e-12) & (g.times >= 30.0)
    rate = -np.polyfit(g.times[m], np.log(g.values[m]), 1)[0]
    print(f"GALI_2 rate {rate:.4f}, lambda1 - lambda2 {lam[0] - lam[1]:.4f}, fitted to t = {g.times[m].max()}")
    assert m.sum() >= 20, g.values  # the fit spans most of the run
    assert abs(rate - (lam[0] - lam[1])) <= 0.25 * (lam[0] - lam[1]), (rate, lam[:3])
    assert g.value < 1e-10 and np.all((g.values >= 0) & (g.values <= 1))


def test_gali2_and_gali3_of_a_regular_orbit_stay_of_order_one():
    """Chaplygin's integrable ball (Omega = 0) in the full system: the orbit lies on a 3-torus
    of (M, alpha, beta, gamma) (the reduced 2-torus and the rotation about the vertical) with
    (x, y) drifting linearly; the deviation vectors grow linearly along the torus directions
    and their normalised volume tends to a constant for k up to the number of sheared
    directions. Measured GALI_2 = 1.00, 0.96, 0.94, 0.93, 0.93 and GALI_3 = 0.52, 0.23, 0.27,
    0.28, 0.31 at t = 10, 30, 100, 300, 1000 (a chaotic orbit: GALI_2 ~ e^{-0.09 t}, 1e-13
    by t = 300). Bounds: GALI_2 >= 0.5, GALI_3 >= 0.1 throughout."""
    p = dataclasses.replace(FIG4_BALL, plane_rate=0.0)
    xf = tb.reduced_to_full(p, demo_reduced_state())
    smp = [10.0, 30.0, 100.0, 300.0, 1000.0]
    g2 = tb.gali("full", p, xf, 1000.0, k=2, sample=smp)
    g3 = tb.gali("full", p, xf, 1000.0, k=3, sample=smp)
    print("GALI_2", g2.values, "GALI_3", g3.values)
    assert np.all(g2.values >= 0.5) and np.all(g3.values >= 0.1), (g2.values, g3.values)


def test_sample_leaves_the_run_bit_identical_and_agrees_with_long_double():
    """The sample times are read off the continuous output, so the final value is
    bit-identical to the run without them, and a sample at a normalisation time equals the
    series recorded there. Long double: the same orbit to t = 20 (GALI_3 = 7.0e-5; the float64
    rounding amplified along the orbit, measured relative difference 2.3e-13: bound 1e-9)."""
    x = demo_reduced_state()
    a = tb.gali("reduced", FIG5, x, 20.0, k=3, renorm=2.0)
    b = tb.gali("reduced", FIG5, x, 20.0, k=3, renorm=2.0, sample=[3.5, 10.0, 20.0])
    assert a.value == b.value and b.values[-1] == a.value
    assert b.values[1] == a.values[list(a.times).index(10.0)]
    assert a.times.tolist() == [2.0 * i for i in range(1, 11)] and b.times.tolist() == [3.5, 10.0, 20.0]
    c = tb.gali("reduced", FIG5, x, 20.0, k=3, renorm=2.0, fp_type=np.longdouble)
    print(a.value, c.value)
    assert abs(c.value - a.value) <= 1e-9 * a.value


@pytest.mark.parametrize("kw,match", [
    (dict(k=1), "k must be an integer in \\[2, 7\\]"),
    (dict(k=8), "k must be an integer in \\[2, 7\\]"),
    (dict(k=2.0), "k must be an integer"),
    (dict(k="2"), "k must be an integer"),
    (dict(k=True), "k must be an integer"),
    (dict(renorm=0.0), "renorm"),
    (dict(renorm=float("nan")), "renorm"),
    (dict(renorm=1e-9), "MAX_CHUNKS"),
    (dict(t0=20.0), "t_end must be finite and > t0"),
    (dict(seed=-1), "seed must be an integer"),
    (dict(sample=[5.0, 3.0]), "sample must be"),
    (dict(sample=[0.0]), "sample must be"),
    (dict(fp_type="real128"), "fp_type"),
])
def test_bad_arguments(kw, match):
    with pytest.raises(tb.UsageError, match=match):
        tb.gali("reduced", FIG5, demo_reduced_state(), 10.0, **kw)


def test_bad_kind_state_and_k_per_kind():
    with pytest.raises(tb.UsageError, match="kind must be one of"):
        tb.gali("ful", FIG5, demo_reduced_state(), 10.0)
    with pytest.raises(tb.StateError):
        tb.gali("full", FIG5, demo_reduced_state(), 10.0)
    for t in (math.inf, math.nan):
        with pytest.raises(tb.UsageError, match="t_end must be finite"):
            tb.gali("reduced", FIG5, demo_reduced_state(), t)
    # the constraint manifold's dimension: full 14 - 6 = 8
    with pytest.raises(tb.UsageError, match="\\[2, 8\\]"):
        tb.gali("full", FIG5, tb.reduced_to_full(FIG5, demo_reduced_state()), 10.0, k=9)


def _fig4a_states(n):
    return [s[0] for s in tb.section_admissible_sample(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), n=n, seed=0)["states"]]


def test_nested_values_are_gali_of_the_first_j_vectors():
    """One run gives GALI_2 .. GALI_k: the first j columns' volume is the product of the
    first j diagonal entries of R. The last column is the run's own values (measured: equal);
    the first is GALI_2 of a k = 2 run with the same seed (its first two vectors) to
    rounding: the other columns change heyoka's step sizes (its error norm covers the whole
    state), and the float64 difference is amplified along the chaotic orbit (measured
    <= 7.2e-13 relative at t = 20 on five Fig. 4a orbits; bound 1e-9)."""
    x = _fig4a_states(1)[0]
    g4 = tb.gali("reduced", FIG4_BALL, x, 20.0, k=4, renorm=2.0)
    g2 = tb.gali("reduced", FIG4_BALL, x, 20.0, k=2, renorm=2.0)
    assert g4.nested_values.shape == (10, 3) and not g4.nested_values.flags.writeable
    assert np.allclose(g4.nested_values[:, -1], g4.values, rtol=8 * 2.2e-16, atol=0)  # cumprod vs prod
    assert np.allclose(g4.nested_values[:, 0], g2.values, rtol=1e-9, atol=0)
    assert np.all(np.diff(g4.nested_values, axis=1) <= 0)  # a unit vector more never adds volume


def test_gali_many_bit_identical_across_threads_companions_and_sampling():
    """gali_many runs the orbits in the lanes: an orbit's series depends only on its own
    state (not on the threads or the orbits beside it), the sample times leave the run
    unchanged (bit-identical final values), and it agrees with gali to rounding (heyoka's
    vectorised code rounds differently; measured <= 8.1e-13 relative at t = 20, bound 1e-9
    as above)."""
    xs = _fig4a_states(5)
    a = tb.gali_many("reduced", FIG4_BALL, xs, 20.0, k=3, renorm=2.0)
    b = tb.gali_many("reduced", FIG4_BALL, xs[::-1][:3], 20.0, k=3, renorm=2.0, workers=1)[::-1]
    c = tb.gali_many("reduced", FIG4_BALL, xs, 20.0, k=3, renorm=2.0, sample=[3.5, 10.0, 20.0])
    for g, h in zip(a[2:], b):
        assert np.array_equal(g.values, h.values) and np.array_equal(g.final_state, h.final_state)
    for g, h in zip(a, c):
        assert g.value == h.value and np.array_equal(g.final_state, h.final_state) and g.n_steps == h.n_steps
        assert h.times.tolist() == [3.5, 10.0, 20.0] and h.values[1] == g.values[4]
    one = tb.gali("reduced", FIG4_BALL, xs[1], 20.0, k=3, renorm=2.0)
    assert a[1].times.tolist() == one.times.tolist()
    assert np.allclose(a[1].values, one.values, rtol=1e-9, atol=0)
    assert np.allclose(a[1].nested_values, one.nested_values, rtol=1e-9, atol=0)


def test_gali_many_bad_arguments():
    x = demo_reduced_state()
    with pytest.raises(tb.UsageError, match="k must be an integer in \\[2, 7\\]"):
        tb.gali_many("reduced", FIG5, [x], 10.0, k=8)
    with pytest.raises(tb.UsageError, match="at least one"):
        tb.gali_many("reduced", FIG5, [], 10.0)
    with pytest.raises(tb.StateError, match="states"):
        tb.gali_many("reduced", FIG5, 5, 10.0)
    with pytest.raises(tb.UsageError, match="sample must be"):
        tb.gali_many("reduced", FIG5, [x], 10.0, sample=[11.0])


def _torus_exponents(d, n, ks):
    """Power of t in GALI_k on a d-torus whose linearised flow shears all d torus directions
    (rank d), in an n-dimensional tangent space (docs/chaos.md, GALI): singular values d ~ t,
    n - 2d ~ 1, d ~ 1/t, and GALI_k ~ (product of the k largest) / t^k."""
    return [0 if k <= d else (d - k if k <= n - d else n - 2 * k) for k in ks]


#: A regular orbit of the Fig. 4b level: the grid point (r1, r2) = (1.1, -2.625) of a 9 x 9
#: MEGNO map on l = 0 (r1 in [0.3, 3.5], r2 in [-7.5, -1], T = 2000, root 0: <Y> = 1.99;
#: of six points of that map with <Y> within 0.05 of 2 tried, four were sticky chaotic orbits
#: (GALI_2 falling exponentially by t ~ 3000), one had GALI_5 ~ const after t = 3000 (not
#: analysed), this one is a torus). <Y>(t) = 1.95, 1.94, 2.02 at t = 750, 1500, 3000.
REGULAR_4B_POINT = (0.0, 1.1, -2.625)


@pytest.mark.slow
def test_gali_on_a_torus_of_the_fig4b_level_decays_as_a_3_torus_predicts():
    """Reduced system, Fig. 4b level. Dimensions: 9 variables - 2 constraints (|gamma| = 1,
    (R, gamma) = 0) = 7 (the deviation vectors' space, n = 7); - 3 integrals (C2, M_gamma, E)
    = a 4-dimensional level. A regular orbit of the level's 3D volume-preserving section map
    lies on an invariant 2-torus of the map (one action, two angles), i.e. on a 3-torus of the
    flow: d = 3, and generically its 3 frequencies depend on the 4 transverse actions (the
    map's action and the 3 integrals) with rank 3. Prediction (_torus_exponents(3, 7)):
    GALI_2, GALI_3 ~ const, GALI_4 ~ t^-1, GALI_5 ~ t^-3; a 2-torus would give 0, -1, -2, -3.

    Measured (one k = 5 run, GALI_2..5 from nested_values, 4000 log-spaced samples on
    [10, 20000], least-squares slope of ln GALI_k on ln t over [2000, 20000], 1180 samples):
    -0.02, -0.10, -1.06, -2.92. GALI_k oscillates by 1-2 decades along the torus (the torus's
    shape in R^9 changes along the orbit, and the vectors nearly align at times), so the fit
    needs many samples: on every 10th sample (118) the exponents spread by +-0.15..0.3, on
    every 20th by +-0.3..0.6 (a 200-sample run gave 0.00, +0.10, -0.68, -2.67); the spread of
    the full fit is ~sqrt(10) smaller, ~0.1. Margin 0.3 per exponent (3x that, and the
    largest measured deviation is 0.10): 0.7 away from the d = 2 prediction at k = 3 and 4,
    which therefore fails the check (asserted).

    Independent count of the sheared directions: the linearised flow has d singular values
    ~t and d ~1/t, so d of the sorted running Lyapunov sums lambda_i(t) t fall like -ln t.
    Measured slopes of lambda_i t on ln t over [1000, 20000] (the same samples), the four
    smallest: -1.09, -1.06, -0.89, +0.07: three at -1 (d = 3; d = 2 would have two), margin
    0.25 (on every 20th sample: -1.12, -1.05, -0.84, +0.06)."""
    p = FIG4_BALL
    x = tb.states_on_section(p, **FIG4B_LEVELS.as_kwargs(), point=REGULAR_4B_POINT, direction=1)[0]
    T = 20000.0
    m = tb.megno("reduced", p, x, 3000.0, sample=[750.0, 1500.0, 3000.0])
    print("<Y>", m.mean_Y)
    assert np.all(np.abs(m.mean_Y - 2.0) < 0.1)  # MEGNO calls it regular
    smp = np.logspace(1.0, math.log10(T), 4000)
    smp[-1] = T
    g = tb.gali("reduced", p, x, T, k=5, sample=smp)
    w = g.times >= 2000.0
    slopes = [float(np.polyfit(np.log(g.times[w]), np.log(g.nested_values[w, j]), 1)[0]) for j in range(4)]
    print(f"GALI_2..5 exponents on {w.sum()} samples", np.round(slopes, 3))
    ks = [2, 3, 4, 5]
    assert np.all(np.abs(np.subtract(slopes, _torus_exponents(3, 7, ks))) <= 0.3), slopes
    assert not np.all(np.abs(np.subtract(slopes, _torus_exponents(2, 7, ks))) <= 0.3)  # a 2-torus fails
    r = tb.lyapunov_spectrum("reduced", p, x, T, sample=smp)
    w = r.times >= 1000.0
    L = r.partial.astype(float) * (r.times - r.t0)[:, None]
    rates = np.sort(np.polyfit(np.log(r.times[w]), L[w], 1)[0])
    print("slopes of lambda_i t on ln t, ascending", np.round(rates, 3))
    assert np.all(np.abs(rates[:3] + 1.0) <= 0.25) and abs(rates[3]) <= 0.25, rates
