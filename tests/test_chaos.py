"""Chaos indicators: MEGNO separates the integrable homogeneous ball from the chaotic
symmetric one (Tzenoff's claim, paper section 4), and the FLI slope agrees with the
divergence of two nearby orbits computed independently in quadruple precision."""

import math

import numpy as np
import pytest

import taylorball as tb
from taylorball.chaos import megno

from .conftest import FIG5, HOMOGENEOUS, SYMMETRIC, demo_reduced_state, nearby_reduced_states


def test_homogeneous_ball_is_regular():
    r = megno("reduced", HOMOGENEOUS, demo_reduced_state(), 1000.0)
    # quasi-periodic: <Y> -> 2 from below (measured 1.2 .. 1.6 at t = 500 .. 2000)
    assert r.mean_megno < 3.0, r


def test_symmetric_ball_has_a_chaotic_orbit():
    r = megno("reduced", SYMMETRIC, demo_reduced_state(), 1000.0)
    # chaotic: <Y> ~ lambda t / 2 (measured 46 at t = 1000, lambda ~ 0.094)
    assert r.mean_megno > 20.0 and r.lyapunov > 0.05, r


def test_fli_slope_matches_two_orbit_divergence():
    """Largest Lyapunov exponent of the Fig. 5 demo orbit two ways: the FLI slope of the
    variational equations, and ln(separation growth)/t of two orbits started 1e-10 apart
    (at t = 150 the separation is ~1e-3: still linear, and 1e6 times the float64 rounding
    carried along, ~1e-16 e^{lambda t})."""
    s = demo_reduced_state()
    T = 150.0
    r = megno("reduced", FIG5, s, T + 1.0, t0=1.0)
    s2 = s.copy()
    s2[0] += 1e-10
    a = tb.propagate("reduced", FIG5, s, T)
    b = tb.propagate("reduced", FIG5, s2, T)
    sep = float(np.linalg.norm(a - b))
    lam2 = math.log(sep / 1e-10) / T
    print(f"lyapunov: FLI {r.lyapunov:.4f}, two orbits {lam2:.4f}")
    # two finite-time estimates from different initial tangent vectors: they agree to the
    # O(1/T) transient (measured 7 % at T = 300, 3 % at T = 150)
    assert abs(r.lyapunov - lam2) <= 0.2 * lam2
    assert sep < 1e-2


def test_bad_arguments():
    with pytest.raises(tb.UsageError, match="kind must be"):
        megno("full", FIG5, tb.reduced_to_full(FIG5, demo_reduced_state()), 10.0)
    with pytest.raises(tb.UsageError, match="t0 < t_end"):
        megno("reduced", FIG5, demo_reduced_state(), 0.5)


def test_stop_above_ends_a_chaotic_run_early_and_agrees_with_the_full_run():
    s = demo_reduced_state()
    full = megno("reduced", SYMMETRIC, s, 1000.0)
    early = megno("reduced", SYMMETRIC, s, 1000.0, stop_above=10.0)
    assert early.t < 1000.0 and early.mean_megno > 10.0
    # the same integration up to the stop: equal to a run that ends there
    same = megno("reduced", SYMMETRIC, s, early.t)
    assert same.mean_megno == early.mean_megno and full.mean_megno > early.mean_megno
    # a regular orbit is never stopped
    assert megno("reduced", HOMOGENEOUS, s, 300.0, stop_above=10.0).t == 300.0


# ---------------------------------------------------------------------------------------
# megno_many: batch lanes and threads.
# ---------------------------------------------------------------------------------------
def _nearby_states(n, seed=3):
    return nearby_reduced_states(n, seed)


def test_megno_many_is_bit_identical_across_threads_and_companions():
    """Each orbit's result depends on its own state only: alone in a batch, among others,
    on one thread or two, loaded into a lane freed by an orbit stopped early."""
    from taylorball.chaos import megno_many

    st = _nearby_states(3) + [demo_reduced_state()] + _nearby_states(3, seed=4)
    one = megno_many("reduced", SYMMETRIC, st, 400.0, stop_above=10.0, threads=1)
    two = megno_many("reduced", SYMMETRIC, st, 400.0, stop_above=10.0, threads=2)
    alone = [megno_many("reduced", SYMMETRIC, [s], 400.0, stop_above=10.0)[0] for s in st]
    assert one == two == alone
    assert any(r.t < 400.0 for r in one), "no orbit stopped early: the refill path is untested"


def test_megno_many_agrees_with_megno():
    """Batch (SIMD) and scalar code round differently; on the tori of the integrable
    homogeneous ball the two runs drift apart only slowly, and the chaotic symmetric-ball
    orbit is classified (and stopped) the same way."""
    from taylorball.chaos import megno_many

    st = _nearby_states(4)
    T = 300.0
    for s, a in zip(st, megno_many("reduced", HOMOGENEOUS, st, T)):
        b = megno("reduced", HOMOGENEOUS, s, T)
        # ~5200 steps to t = 300 on this torus (measured); the two codes' rounding differences
        # accumulate at most ~1 eps per step (measured <= 1.5 eps/step): bound 20 eps per step
        assert a.t == b.t == T
        assert abs(a.mean_megno - b.mean_megno) <= 20 * 2.2e-16 * 5200, (a, b)
    a = megno_many("reduced", SYMMETRIC, [demo_reduced_state()], 1000.0, stop_above=10.0)[0]
    b = megno("reduced", SYMMETRIC, demo_reduced_state(), 1000.0, stop_above=10.0)
    assert a.mean_megno > 10.0 and b.mean_megno > 10.0 and a.t < 1000.0 and b.t < 1000.0


def test_megno_many_bad_arguments():
    from taylorball.chaos import megno_many

    with pytest.raises(tb.UsageError, match="kind must be"):
        megno_many("full", FIG5, [demo_reduced_state()], 10.0)
    with pytest.raises(tb.UsageError, match="at least one initial state"):
        megno_many("reduced", FIG5, [], 10.0)
    with pytest.raises(tb.UsageError, match="t0 < t_end"):
        megno_many("reduced", FIG5, [demo_reduced_state()], 0.5)
