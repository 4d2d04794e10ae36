"""Periodic orbits of the section maps (taylorball.periodic): checks independent of the
Newton code — a second propagation by the section integrator, the reversors on the vector
field itself, finite differences of the map, long double against float64."""

import math

import numpy as np
import pytest

import taylorball as tb
from taylorball import periodic as P
from taylorball.errors import StateError, UsageError
from taylorball.model import ball_constants, reduced_rhs
from taylorball.paper import FIG3_BALL, FIG3_LEVELS, FIG4_BALL

from ._periodic_checks import quotient_matrix_fd

EPS = np.finfo(float).eps

#: A guess near the Fig. 3 level's elliptic relative fixed point (k = 1): the second state
#: (energy root) at the chart point (l, r1, r2) = (0, -0.3, 0).
GUESS_POINT = (0.0, -0.3, 0.0)


def _rotate_public(x, theta):
    """Rotation of omega, gamma, R about the body axis 3 by theta (written here, not taken
    from the module under test)."""
    y = np.array(x, dtype=float)
    c, s = math.cos(theta), math.sin(theta)
    for b in (0, 3, 6):
        y[b], y[b + 1] = c * x[b] - s * x[b + 1], s * x[b] + c * x[b + 1]
    return y


@pytest.fixture(scope="module")
def fig3_orbit():
    st = tb.states_on_section(FIG3_BALL, **FIG3_LEVELS.as_kwargs(), point=GUESS_POINT, direction=1)[1]
    return P.periodic_orbit("reduced", FIG3_BALL, st, 1, levels=FIG3_LEVELS)


def test_orbit_returns_in_an_independent_propagation(fig3_orbit):
    o = fig3_orbit
    assert o.converged and o.k == 1
    # the section integrator (no variational equations, its own event and Newton-refined
    # crossing) from the reported state: after k crossings, the start rotated by theta,
    # P^k x = S_theta x
    sec = tb.poincare_section("reduced", FIG3_BALL, o.state, n_points=o.k)
    assert sec.ok
    assert abs(sec.times[-1] - o.period) <= 1e3 * EPS * o.period  # crossing time: rounding of t ~ 30
    err = float(np.max(np.abs(sec.states[-1] - _rotate_public(o.state, o.shift))))
    assert err <= 1e-12, err


def test_multipliers_area_preserving_pair(fig3_orbit):
    o = fig3_orbit
    mu = o.multipliers
    assert mu.shape == (2,)  # the symmetric ball's map of (r1, r2)
    # det 1 at a fixed point whatever the density; float64 fundamental matrix over t ~ 30
    # with entries ~1e2: 1e4 eps allowed
    assert abs(np.prod(mu) - 1) <= 1e4 * EPS
    assert abs(mu[0] * mu[1] - 1) <= 1e4 * EPS
    assert o.stability == "elliptic" and np.allclose(np.abs(mu), 1, atol=1e4 * EPS)
    assert o.symmetric is None and o.lyapunov == pytest.approx(0.0, abs=1e-10)


def test_jacobian_against_finite_differences(fig3_orbit):
    """The Newton Jacobian's map block (Pi Phi from the variational equations) against
    central differences of the k-th return, each image by the long-double section
    integrator, along an orthonormal basis of the section-and-level tangent space."""
    o = fig3_orbit
    prob = o.problem
    ctx = P._Ctx(prob, 0.0, 1, 1, P._eval_geo(prob, 0.0, o.internal).c.copy(), True, 1e4)
    x0 = o.internal
    _, _, _, xT, Phi, T, geo0 = P._residual_parts(ctx, x0, o.shift)
    _, PP = P._jacobian(ctx, x0, o.shift, xT, Phi, geo0)
    G = np.vstack([geo0.grad_e[None, :], geo0.grad_c])
    B = np.linalg.svd(G)[2][G.shape[0]:].T
    prob_ld = prob.replace(spec=tb.numbers.resolve_fp_type(np.longdouble), tol=None)
    ctx_ld = P._Ctx(prob_ld, 0.0, 1, 1, prob_ld.spec.array(ctx.targets), True, 1e4)

    def image(x):
        pub = P.public_state(prob_ld.system, prob_ld.pars, x, prob_ld.spec)
        sec = tb.poincare_section("reduced", FIG3_BALL, pub, n_points=1, fp_type=np.longdouble)
        return P.start_state(prob_ld, sec.states[-1]).astype(float)

    h = 1e-6  # central differences in long double: truncation ~h^2 |P'''| ~ 1e-10, rounding ~eps_ld/h
    xl = prob_ld.spec.array(x0)
    for j in range(B.shape[1]):
        xp = P._to_level(ctx_ld, xl + prob_ld.spec.array(h * B[:, j]), 20.0)
        xm = P._to_level(ctx_ld, xl - prob_ld.spec.array(h * B[:, j]), 20.0)
        fd = (image(xp) - image(xm)) / (2 * h)
        assert np.max(np.abs(fd - PP @ B[:, j])) <= 1e-7 * max(1.0, np.max(np.abs(fd)))


def test_refinement_in_long_double(fig3_orbit):
    ld = P.refine(fig3_orbit, (np.longdouble,), max_iter=4)
    assert len(ld) == 2 and ld[1].fp_type == "longdouble"
    assert ld[0].digits["float"] >= 12  # float64 state against the long-double solution
    assert ld[1].residual <= 256 * np.finfo(np.longdouble).eps * 30  # |x| ~ 20
    assert ld[1].period == pytest.approx(fig3_orbit.period, rel=1e-12)


def test_reversors_of_the_vector_field():
    """sigma_i x and -x reverse the reduced flow, f(S x) = -S f(x), on random states of an
    asymmetric ball (model.reduced_rhs, not the periodic module's code)."""
    c = ball_constants((2.0, 3.0, 4.0, 1.0, 5.0, 2.0))
    rng = np.random.default_rng(3)

    def f(x):
        return np.array([v for part in reduced_rhs(c, tuple(x[0:3]), tuple(x[3:6]), tuple(x[6:9])) for v in part])

    for name, S in P.reversors().items():
        for _ in range(3):
            x = rng.normal(size=9)
            x[3:6] /= np.linalg.norm(x[3:6])
            assert np.allclose(f(S * x), -S * f(x), rtol=0, atol=64 * EPS * np.max(np.abs(f(x)))), name
    # and the identity is not one (the check can fail)
    x = rng.normal(size=9)
    assert not np.allclose(f(x), -f(x))


def test_classify():
    rot = np.array([[math.cos(0.3), -math.sin(0.3)], [math.sin(0.3), math.cos(0.3)]])
    assert P.classify(rot) == ("elliptic", "elliptic")
    assert P.classify(np.diag([2.0, 0.5])) == ("hyperbolic", "saddle")
    assert P.classify(np.diag([-2.0, -0.5])) == ("hyperbolic", "reflection-saddle")
    assert P.classify(np.array([[1.0, 1.0], [0.0, 1.0]]))[0] == "parabolic"
    r3 = np.zeros((3, 3))
    r3[:2, :2] = rot
    r3[2, 2] = 1.0
    assert P.classify(r3)[0] == "elliptic"
    sf = np.zeros((3, 3))
    sf[:2, :2] = 1.2 * rot
    sf[2, 2] = 1 / 1.44
    assert P.classify(sf) == ("hyperbolic", "saddle-focus")
    assert P.classify(np.diag([2.0, 1.0, 0.5])) == ("hyperbolic", "saddle")


def test_bad_input(fig3_orbit):
    st = fig3_orbit.state
    with pytest.raises(UsageError, match="k"):
        P.periodic_orbit("reduced", FIG3_BALL, st, 0)
    with pytest.raises(UsageError, match="kind"):
        P.periodic_orbit("full", FIG3_BALL, np.zeros(15), 1)
    x = np.asarray(tb.propagate("reduced", FIG3_BALL, st, 0.05)).reshape(-1)[-9:]  # off the section
    with pytest.raises(StateError, match="not on the section"):
        P.periodic_orbit("reduced", FIG3_BALL, x, 1)
    with pytest.raises(StateError, match="off the level"):
        P.periodic_orbit("reduced", FIG3_BALL, st, 1, levels=tb.Levels(C=10.0, M_gamma=6.0, h=5.5))


def test_newton_failure_is_reported_not_returned():
    st = tb.states_on_section(FIG3_BALL, **FIG3_LEVELS.as_kwargs(), point=GUESS_POINT, direction=1)[0]
    with pytest.raises(P.NewtonFailure) as info:
        P.periodic_orbit("reduced", FIG3_BALL, st, 1, levels=FIG3_LEVELS, options=tb.NewtonOptions(max_iter=6))
    assert info.value.residual > 1e-6 and len(info.value.residual_history) >= 2


def test_asymmetric_ball_is_not_treated_as_symmetric():
    prob = P.orbit_problem("reduced", FIG4_BALL)
    assert not P._has_axial_symmetry(prob)
    assert P._has_axial_symmetry(P.orbit_problem("reduced", FIG3_BALL))


def test_search_bad_input():
    with pytest.raises(UsageError, match="k_max"):
        tb.periodic_orbits("reduced", FIG3_BALL, FIG3_LEVELS, k_max=0)
    with pytest.raises(UsageError, match="levels"):
        tb.periodic_orbits("reduced", FIG3_BALL, {"C": 10.0}, k_max=1)
    with pytest.raises(UsageError, match="MParallelLevels"):
        tb.periodic_orbits("mparallel", FIG3_BALL, FIG3_LEVELS, k_max=1)


def test_same_orbit_counts_phases_once(fig3_orbit):
    from dataclasses import replace

    from taylorball.periodic_search import same_orbit

    o = fig3_orbit
    moved = replace(o, points=o.points + np.array([0.0, 1e-3, 0.0]))
    assert same_orbit(o, o) and not same_orbit(o, moved)
    assert not same_orbit(o, replace(o, k=2))


def test_continuation_in_omega_gives_orbits(fig3_orbit):
    """One continuation step (Omega 2 -> 1.95): the continued state is a periodic orbit of
    the ball with Omega = 1.95 in an independent propagation, on the same levels."""
    import dataclasses

    from taylorball.periodic_continuation import continue_in_omega

    br = continue_in_omega(fig3_orbit, FIG3_LEVELS, [1.95])
    assert br.stopped == "reached" and list(br.omega) == [2.0, 1.95]
    o = br.orbits[-1]
    ball = dataclasses.replace(FIG3_BALL, plane_rate=1.95)
    sec = tb.poincare_section("reduced", ball, o.state, n_points=1)
    assert float(np.max(np.abs(sec.states[-1] - _rotate_public(o.state, o.shift)))) <= 1e-12
    lv = tb.integrals("reduced", ball, o.state)
    assert abs(lv["E"] - FIG3_LEVELS.h) <= 64 * EPS * 10  # energy scale ~10
    assert abs(lv["M_gamma"] - FIG3_LEVELS.M_gamma) <= 64 * EPS * 10
    assert abs(np.prod(o.multipliers) - 1) <= 1e4 * EPS


def test_continuation_bad_input(fig3_orbit):
    from taylorball.periodic_continuation import continue_in_omega

    with pytest.raises(UsageError, match="monoton"):
        continue_in_omega(fig3_orbit, FIG3_LEVELS, [1.9, 1.95])
    with pytest.raises(UsageError, match="levels"):
        continue_in_omega(fig3_orbit, {"C": 10}, [1.9])


def test_continuation_in_a_level_value_gives_orbits(fig3_orbit):
    """One step in the energy h (5 -> 5.05) and one in M_gamma (6 -> 5.97), Omega and the other
    level values kept: each continued state is a periodic orbit of its own level in an
    independent propagation, and the integrals (evaluated afresh) are that level's."""
    import dataclasses

    from taylorball.periodic_continuation import continue_in_level

    for name, value in (("h", 5.05), ("M_gamma", 5.97)):
        br = continue_in_level(fig3_orbit, FIG3_LEVELS, name, [value])
        assert br.stopped == "reached" and br.parameter == name and list(br.values) == [getattr(FIG3_LEVELS, name),
                                                                                          value]
        o = br.orbits[-1]
        sec = tb.poincare_section("reduced", FIG3_BALL, o.state, n_points=1)
        assert float(np.max(np.abs(sec.states[-1] - _rotate_public(o.state, o.shift)))) <= 1e-12
        lv = tb.integrals("reduced", FIG3_BALL, o.state)
        want = dataclasses.replace(FIG3_LEVELS, **{name: value})
        assert abs(lv["E"] - want.h) <= 64 * EPS * 10  # energy scale ~10
        assert abs(lv["M_gamma"] - want.M_gamma) <= 64 * EPS * 10
        assert abs(np.prod(o.multipliers) - 1) <= 1e4 * EPS
        # the orbit moved with the level (not the start returned)
        assert float(np.max(np.abs(o.state - fig3_orbit.state))) > 1e-4


@pytest.mark.slow
def test_period_doubling_in_M_gamma(fig3_orbit):
    """The Fig. 3 level's elliptic relative periodic orbit, followed down in M_gamma (the
    caption's H; Omega = 2, G = 10, h = 5 kept), turns into a reflection saddle between H =
    4.7 and 4.6: a multiplier through -1 (measured: tr A = -1.820 at 4.7, -2.275 at 4.6, the
    event interpolated at H = 4.6604). Each orbit returns in an independent propagation and
    has its level's integrals; on both sides of the event the traces by central differences
    of the map of (r1, r2) in real128 (tests/_periodic_checks.quotient_matrix_fd: no
    variational equations) straddle -2 and agree with the variational ones. (~35 s: the
    branch takes 12 steps; the quick check of level continuation is
    test_continuation_in_a_level_value_gives_orbits.)"""
    import dataclasses

    from taylorball.periodic_continuation import continue_in_level

    br = continue_in_level(fig3_orbit, FIG3_LEVELS, "M_gamma", [5.5, 5.0, 4.7, 4.6])
    assert br.stopped == "reached" and br.values[0] == 6.0 and br.values[-1] == 4.6 and 4.7 in list(br.values)
    assert np.all(np.diff(br.values) < 0)
    assert [o.type for o in br.orbits[-2:]] == ["elliptic", "reflection-saddle"]
    ev = [e for e in br.events if e["event"] == "period doubling"]
    assert len(ev) == 1 and ev[0]["between"] == (4.7, 4.6) and 4.6 < ev[0]["omega"] < 4.7
    for v, o in zip(br.values, br.orbits):
        sec = tb.poincare_section("reduced", FIG3_BALL, o.state, n_points=1)
        assert float(np.max(np.abs(sec.states[-1] - _rotate_public(o.state, o.shift)))) <= 1e-12
        assert abs(tb.integrals("reduced", FIG3_BALL, o.state)["M_gamma"] - v) <= 64 * EPS * 10  # scale ~10
    for o, v, side in ((br.orbits[-2], 4.7, 1.0), (br.orbits[-1], 4.6, -1.0)):
        A = quotient_matrix_fd(o, FIG3_BALL, dataclasses.replace(FIG3_LEVELS, M_gamma=v))
        # as test_trace_swing_is_real_finite_differences_in_real128: a float64 fundamental
        # matrix over t ~ 30 with entries ~1e2 against real128 differences
        assert abs(np.trace(A) - o.trace) <= 1e-9, (np.trace(A), o.trace)
        assert side * (np.trace(A) + 2.0) > 0.1  # measured +0.18 and -0.27


def test_arclength_in_a_level_value(fig1_saddle):
    """Pseudo-arclength in the M||gamma system's energy h (Omega and lam kept): two steps, each
    point an orbit of its own level (independent propagation, energy evaluated afresh)."""
    from taylorball.paper import FIG1_LEVELS
    from taylorball.periodic_continuation import continue_arclength

    p, o = fig1_saddle
    br = continue_arclength(o, FIG1_LEVELS, ds=0.5, n_steps=2, direction=1, parameter="h", bounds=(99.0, 102.0))
    assert br.stopped == "reached" and br.parameter == "h" and len(br.values) == 3
    assert br.values[0] == FIG1_LEVELS.h and np.all(np.diff(br.values) > 0)
    for h, orb in zip(br.values, br.orbits):
        sec = tb.poincare_section("mparallel", p, orb.state, n_points=1)
        assert float(np.max(np.abs(sec.states[-1] - orb.state))) <= 1e-12
        e = tb.integrals("mparallel", p, orb.state)["E"]
        assert abs(e - h) <= 64 * EPS * 100  # energy scale ~100


def test_level_continuation_bad_input(fig3_orbit):
    from taylorball.periodic_continuation import continue_arclength, continue_in_level

    with pytest.raises(UsageError, match=r"parameter must be 'Omega' or a level value .*'C', 'M_gamma', 'h'.*'G'"):
        continue_in_level(fig3_orbit, FIG3_LEVELS, "G", [10.1])
    with pytest.raises(UsageError, match="values must run monotonically away from the orbit's h = 5.0"):
        continue_in_level(fig3_orbit, FIG3_LEVELS, "h", [4.9, 5.1])
    with pytest.raises(UsageError, match="bounds must be a pair"):
        continue_arclength(fig3_orbit, FIG3_LEVELS, parameter="h", bounds=(6.0, 5.0))
    with pytest.warns(DeprecationWarning, match=r"omega_range=\.\.\.\) is deprecated: use bounds"):
        with pytest.raises(UsageError, match="bounds must be a pair"):
            continue_arclength(fig3_orbit, FIG3_LEVELS, omega_range=(2.0, 1.0))


@pytest.fixture(scope="module")
def fig1_saddle():
    """A hyperbolic fixed point of the M||gamma map on the Fig. 1 level, from the guess at
    the chart point (l, L/G) = (0, 0)."""
    from taylorball.charts import mparallel_states_on_section
    from taylorball.paper import FIG1_LEVELS, fig1_params

    with pytest.warns(tb.UnphysicalParametersWarning):
        p = fig1_params()
    st = mparallel_states_on_section(p, **FIG1_LEVELS.as_kwargs(), point=(0.0, 0.0))[0]
    return p, P.periodic_orbit("mparallel", p, st, 1, levels=FIG1_LEVELS)


def test_mparallel_saddle(fig1_saddle):
    p, o = fig1_saddle
    assert o.stability == "hyperbolic" and o.type == "saddle" and o.multipliers.shape == (2,)
    assert abs(np.prod(o.multipliers) - 1) <= 1e3 * EPS  # area preserved (det 1 at a fixed point)
    sec = tb.poincare_section("mparallel", p, o.state, n_points=1)
    assert float(np.max(np.abs(sec.states[-1] - o.state))) <= 1e-12
    assert abs(sec.times[-1] - o.period) <= 64 * EPS


def test_saddle_multiplier_is_the_lyapunov_exponent(fig1_saddle):
    """ln |mu| / T against lyapunov_spectrum started on the orbit (an independent tangent
    integration with QR). The finite-time exponent on a periodic orbit approaches the limit
    like 1/t; over 5 and 10 periods (before rounding lets the orbit leave the saddle, measured
    drift 3e-10 at 10 periods) the Richardson extrapolation 2 L(10 T) - L(5 T) agreed with
    ln |mu| / T to 1e-5 relative."""
    p, o = fig1_saddle
    lam = math.log(abs(o.multipliers[-1])) / o.period
    L5 = tb.lyapunov_spectrum("mparallel", p, o.state, 5 * o.period).exponents[0]
    L10 = tb.lyapunov_spectrum("mparallel", p, o.state, 10 * o.period).exponents[0]
    assert abs(L10 - lam) > 1e-3 * lam  # the plain finite-time value is not yet the limit ...
    assert abs((2 * L10 - L5) - lam) <= 1e-4 * lam  # ... its extrapolation is


def test_unstable_manifold_leaves_at_the_rate_mu(fig1_saddle):
    """Points of the fundamental domain at distance s ~ 1e-7 are mapped (by the section
    integrator) to distance |mu| s along the manifold: the local linear regime, to O(s)."""
    from taylorball.periodic_manifolds import unstable_manifold

    _, o = fig1_saddle
    m = unstable_manifold(o, n_fund=8, n_iter=3, s0=1e-7)
    pts, mu = m["points"], float(m["mu"])
    p0 = o.points[0]
    def dist(q):
        dl = (q[:, 0] - p0[0] + np.pi) % (2 * np.pi) - np.pi  # l is an angle
        return np.hypot(dl, q[:, 1] - p0[1])

    for branch in range(2):
        d0, d1 = dist(pts[branch, :, 0]), dist(pts[branch, :, 1])
        assert np.allclose(d1 / d0, abs(mu), rtol=1e-4)  # O(s |mu|) curvature, s |mu| < 4e-7
    with pytest.raises(UsageError, match="hyperbolic"):
        from dataclasses import replace

        unstable_manifold(replace(o, stability="elliptic"))


def test_mparallel_continuation_to_omega_zero(fig1_saddle):
    """The Fig. 1 saddle followed to the non-rotating plane: every solution is an orbit of its
    own parameters in an independent propagation, and the saddle persists at Omega = 0 (an
    isolated fixed point of a 2D map keeps multipliers off 1 where the map is integrable too:
    the 'all multipliers 1' of resonant tori concerns families, not separatrix saddles)."""
    import dataclasses

    from taylorball.paper import FIG1_LEVELS
    from taylorball.periodic_continuation import continue_in_omega

    p, o = fig1_saddle
    br = continue_in_omega(o, FIG1_LEVELS, [0.25, 0.0])
    assert br.stopped == "reached" and br.omega[-1] == 0.0
    for w, orb in zip(br.omega, br.orbits):
        with pytest.warns(tb.UnphysicalParametersWarning):
            pw = dataclasses.replace(p, plane_rate=float(w))
        sec = tb.poincare_section("mparallel", pw, orb.state, n_points=1)
        assert float(np.max(np.abs(sec.states[-1] - orb.state))) <= 1e-12
    assert br.orbits[-1].type == "saddle" and abs(br.orbits[-1].multipliers[-1]) > 3


def test_saddle_refined_in_real128(fig1_saddle):
    """float64 -> long double -> real128 refinement of the Fig. 1 saddle: digits reported from
    successive precisions, and the real128 state returns after one crossing, in an
    independent real128 section run, to ~1e3 eps of real128."""
    import heyoka as hy

    p, o = fig1_saddle
    f64, ld, q = P.refine(o, (np.longdouble, "real128"))
    assert f64.digits["float"] >= 14.5 and ld.digits["longdouble"] >= 18  # measured 15.7, 19.4
    assert q.fp_type == "real128" and q.residual <= 1e3 * 1.93e-34 * 11  # eps(real128) = 1.93e-34, |x| ~ 11
    sec = tb.poincare_section("mparallel", p, q.state, n_points=1, fp_type=hy.real128)
    err = max(abs(float(v)) for v in (sec.states[-1] - q.state))
    assert err <= 1e3 * 1.93e-34 * 11, err


def test_refined_onto_the_exact_level(fig1_saddle):
    """``refine(..., levels=...)`` solves on the given level's exact values, not on the float64
    orbit's integrals: the long-double orbit's energy and lambda round to the level's own
    floats (within 2 eps of float64, the rounding of a long-double value off by ~eps_ld); a
    level the orbit is not on is refused before any work."""
    from taylorball.errors import StateError
    from taylorball.levels import MParallelLevels
    from taylorball.paper import FIG1_LEVELS

    _, o = fig1_saddle
    ld = P.refine(o, (np.longdouble,), levels=FIG1_LEVELS)[-1]
    eps = np.finfo(float).eps
    assert abs(ld.levels["E"] - FIG1_LEVELS.h) <= 2 * eps * abs(FIG1_LEVELS.h), ld.levels
    assert abs(ld.levels["lambda"] - FIG1_LEVELS.lam) <= 2 * eps * abs(FIG1_LEVELS.lam), ld.levels
    with pytest.raises(StateError, match="off the level"):
        P.refine(o, (np.longdouble,), levels=MParallelLevels(lam=FIG1_LEVELS.lam, h=FIG1_LEVELS.h + 1.0))
    with pytest.raises(StateError, match="off the level"):
        P.refine(o, (np.longdouble,), levels={"lam": FIG1_LEVELS.lam, "h": float("nan")})


def test_search_of_the_fig1_map(fig1_saddle):
    """A 30-point chart grid on the Fig. 1 level: two saddles (l = 0, pi) and two elliptic
    points (l = pi/2, 3 pi/2), each counted once, the saddle of the fixture among them."""
    from taylorball.paper import FIG1_LEVELS
    from taylorball.periodic_search import same_orbit

    p, saddle = fig1_saddle
    rep = tb.periodic_orbits("mparallel", p, FIG1_LEVELS, k_max=1, report=True,
                             options=tb.SearchOptions(n_grid=30, per_k=4))
    types = sorted(o.type for o in rep.orbits)
    assert types == ["elliptic", "elliptic", "saddle", "saddle"], rep.orbits
    assert sum(same_orbit(o, saddle) for o in rep.orbits) == 1
    for o in rep.orbits:  # independent returns
        sec = tb.poincare_section("mparallel", p, o.state, n_points=1)
        assert float(np.max(np.abs(sec.states[-1] - o.state))) <= 1e-12


#: Fig. 3 branch states (public layout) at Omega = 1.8125 and 1.8, taken from a continuation
#: from Omega = 2 in steps of 0.0125: only guesses here (Newton solves again, and the check
#: below is against finite differences, not against these numbers).
_BRANCH_GUESS = {
    1.8125: ((-0.000435597252583586, 0.3055083960581676, -1.9906226699137681, -0.00019022399902108808,
              0.13341458993992267, -0.9910602963523423, 0.0011321971080972448, -0.7940723235994006,
              -0.1068966733877239), 6.351993483002521),
    1.8: ((-0.00046470439758342644, 0.2904761370327848, -1.9914737936132245, -0.0002016356424958823,
           0.12603784862704942, -0.9920254130094314, 0.0012780483263224959, -0.7988789059961283,
           -0.10149864610819301), 7.267125038255373),
}


@pytest.mark.parametrize("omega", [1.8125, 1.8])
def test_trace_swing_is_real_finite_differences_in_real128(omega):
    """The trace of the symmetric ball's 2x2 multiplier matrix swings from +1.04 to -1.02
    between Omega = 1.8 and 1.8125 on the Fig. 3 branch. Independent check: central
    differences of the map of (r1, r2) (the quotient map: r1, r2 are invariant under the
    rotation about the body axis 3), each image by the real128 section integrator, the
    chart written here. The trace of ``J C^-1`` (J: d(r1, r2)(P x)/ds, C: d(r1, r2)(x)/ds
    along two tangent directions) is the trace of the map in the chart (r1, r2), which is
    invariant under the change of coordinates, so it must equal the variational one."""
    import dataclasses

    pub, theta = _BRANCH_GUESS[omega]
    ball = dataclasses.replace(FIG3_BALL, plane_rate=omega)
    o = P.periodic_orbit("reduced", ball, np.array(pub), 1, levels=FIG3_LEVELS, options=P.NewtonOptions(shift=theta))
    assert o.converged and o.stability == "elliptic"
    A = quotient_matrix_fd(o, ball, FIG3_LEVELS)
    # 4.5e6 eps of float64: the variational matrix comes from a float64 fundamental matrix
    # over t ~ 32 with entries ~1e2 and a float64 fixed point (measured agreement 3e-11)
    assert abs(np.trace(A) - o.trace) <= 1e-9, (np.trace(A), o.trace)
    assert abs(np.linalg.det(A) - 1) <= 1e-9
    assert o.trace == pytest.approx({1.8125: -1.0220218840, 1.8: 1.0423233089}[omega], abs=1e-8)


def test_inverse_map_undoes_the_map(fig1_saddle):
    """P^-1 (backward flow) against P (the section integrator, forward): three crossings
    forward from a generic chart point, three back, to rounding (|x| ~ 10)."""
    from taylorball.charts import mparallel_states_on_section
    from taylorball.paper import FIG1_LEVELS
    from taylorball.periodic_manifolds import inverse_map

    p, o = fig1_saddle
    st = mparallel_states_on_section(p, **FIG1_LEVELS.as_kwargs(), point=(1.0, 0.3))[0]
    sec = tb.poincare_section("mparallel", p, st, n_points=3)
    back = inverse_map(o, sec.states[-1], 3)
    for got, want in zip(back, [sec.states[1], sec.states[0], st]):
        assert float(np.max(np.abs(got - want))) <= 1e3 * EPS * 10  # measured 1.1e-14
    with pytest.raises(UsageError, match="n "):
        inverse_map(o, st, 0)


def test_heteroclinic_point_of_the_fig1_saddles(fig1_saddle):
    """W^u(saddle at l = 0) crosses W^s(saddle at l = pi) transversally. Independent checks
    of the point found: its forward images (section integrator) approach the l = pi saddle at
    the rate of its stable multiplier, its backward images (inverse map) the l = 0 saddle at
    the rate 1/mu_u; the angle is not 0."""
    from taylorball.charts import mparallel_states_on_section
    from taylorball.paper import FIG1_LEVELS
    from taylorball.periodic_manifolds import homoclinic_points, inverse_map

    p, o0 = fig1_saddle
    o1 = P.periodic_orbit("mparallel", p, mparallel_states_on_section(p, **FIG1_LEVELS.as_kwargs(),
                                                                      point=(math.pi, 0.0))[0], 1, levels=FIG1_LEVELS)
    H = homoclinic_points(o0, target=o1, n_u=8, n_s=9, n_fund=30, s0=2.0396e-4, branches=((1, 1),), max_points=1)
    assert len(H) == 1
    q = H[0]
    assert q.residual <= 1e-11 and 0.002 < q.angle < 0.02  # measured 0.379 degrees
    mu_s, mu_u = abs(o1.multipliers[0]), abs(o0.multipliers[-1])
    # the point is homoclinic to 5e-12 in the chart: the images approach the saddle at the
    # rate mu until that error, grown by mu_u per iteration, takes over (measured: from ~1
    # to 2.6e-5 in 11 forward iterations, the ratios 0.280, 0.272 at 10, 11; then it leaves)
    fwd = tb.poincare_section("mparallel", p, q.state, n_points=11).states
    d = np.array([np.max(np.abs(s - o1.state)) for s in fwd])
    assert d[0] > 0.1 and d[-1] <= 1e-4, d
    assert np.allclose(d[6:10] / d[5:9], mu_s, rtol=0.05), d[6:10] / d[5:9]  # nonlinear terms O(d)
    bwd = inverse_map(o0, q.state, 11)
    d = np.array([np.max(np.abs(s - o0.state)) for s in bwd])
    assert d[0] > 0.1 and d[-1] <= 1e-4, d
    assert np.allclose(d[6:10] / d[5:9], 1 / mu_u, rtol=0.05), d[6:10] / d[5:9]


def test_heteroclinic_tangents_are_carried_by_the_jacobian(fig1_saddle):
    """At the heteroclinic point q the manifolds' tangents (central differences in the
    fundamental-domain parameter, n_u and n_s iterations) are carried by the variational
    Jacobian of the map, Pi Phi, onto the tangents at P(q) (differences with n_u + 1 and
    n_s - 1 iterations): the angle at P(q) from the manifolds agrees with the angle of the
    images. Measured: tangents to 2e-10 and 4e-10, angles 0.50104307 deg both."""
    from taylorball import periodic_manifolds as PM
    from taylorball.charts import mparallel_states_on_section
    from taylorball.paper import FIG1_LEVELS

    p, o0 = fig1_saddle
    o1 = P.periodic_orbit("mparallel", p, mparallel_states_on_section(p, **FIG1_LEVELS.as_kwargs(),
                                                                      point=(math.pi, 0.0))[0], 1, levels=FIG1_LEVELS)
    q = PM.homoclinic_points(o0, target=o1, n_u=8, n_s=9, n_fund=30, s0=2.0396e-4, branches=((1, 1),),
                             max_points=1)[0]
    prob = o0.problem
    x0, _, mu_u, vu, _, _ = PM._saddle_directions(o0)
    x1, _, _, _, mu_s, vs = PM._saddle_directions(o1)
    ctx = P._Ctx(prob, 0.0, 1, 1, P._eval_geo(prob, 0.0, x0).c.copy(), False, 1e4)

    def pu(sig, n):
        xi = P._to_level(ctx, x0 + q.s0 * abs(mu_u) ** sig * vu, 1.0)
        r = tb.poincare_section("mparallel", p, P.public_state(prob.system, prob.pars, xi, prob.spec), n_points=n)
        return P.start_state(prob, r.states[-1])

    def ps(sig, n):
        xi = P._to_level(ctx, x1 + q.s0 * abs(1 / mu_s) ** sig * vs, 1.0)
        for _ in range(n):
            xi = PM._previous_crossing(ctx, xi)
        return xi

    h = 1e-6  # central differences: truncation ~h^2 * |d^3/dsigma^3| (measured 2e-10 overall)

    def tangent(f, sig, n):
        return (f(sig + h, n) - f(sig - h, n)) / (2 * h)

    xq = pu(q.sigma_u, 8)
    T = P._crossing_time(ctx, xq)
    xT, Phi, T = P._flow(ctx, xq, T)
    _, PP = P._jacobian(ctx, xq, 0.0, xT, Phi, P._eval_geo(prob, 0.0, xq))
    tu, ts = tangent(pu, q.sigma_u, 8), tangent(ps, q.sigma_s, 9)
    tu1, ts1 = tangent(pu, q.sigma_u, 9), tangent(ps, q.sigma_s, 8)
    for a, b in ((PP @ tu, tu1), (PP @ ts, ts1)):
        assert np.linalg.norm(a - b) <= 1e-8 * np.linalg.norm(b)
    # the angle (8.7e-3 rad) from directions good to ~4e-10 each: 1e-8 rad absolute
    assert abs(PM._angle(PP @ tu, PP @ ts) - PM._angle(tu1, ts1)) <= 1e-8
    assert abs(PM._angle(tu, ts) - q.angle_state) <= 1e-6 * q.angle_state


def test_pseudo_arclength_passes_the_fold():
    """The Fig. 3 branch, elliptic at Omega = 1.87, has a fold near Omega = 1.8683 (a
    multiplier through +1, where natural-parameter continuation ends). Pseudo-arclength
    continuation passes it: Omega turns back, the orbits beyond are saddles (tr A > 2), and
    each is a periodic orbit of its own Omega in an independent propagation."""
    import dataclasses

    from taylorball.periodic_continuation import continue_arclength, continue_in_omega

    guess = (-8.646274238177287e-06, 0.27636477515113556, -1.9922375197704414, -3.726509010670753e-06,
             0.11911209309720228, -0.9928808132218674, 2.40386501643534e-05, -0.7683582462657492,
             -0.09217698421808275)  # from a continuation from Omega = 2 (a guess only)
    ball = dataclasses.replace(FIG3_BALL, plane_rate=1.87)
    o = P.periodic_orbit("reduced", ball, np.array(guess), 1, levels=FIG3_LEVELS, options=P.NewtonOptions(shift=2.366016361842101))
    assert o.type == "elliptic"
    # natural-parameter continuation stops before the fold, with the reason
    nat = continue_in_omega(o, FIG3_LEVELS, [1.86], max_halvings=2)
    assert nat.stopped != "reached" and "fold" in nat.stopped and min(nat.omega) > 1.868
    # the steps beyond the fold stall (residual ~2e-2 from the second iterate): Newton stops once the
    # residual has not halved over NEWTON_STALL = 4 iterations, not after max_iter = 20
    assert len(nat.stopped.split("history ")[-1].split(", ")) <= 1 + 4 + 1, nat.stopped
    br = continue_arclength(o, FIG3_LEVELS, ds=0.05, n_steps=8, direction=-1, bounds=(1.0, 2.0))
    folds = [e for e in br.events if e["event"] == "fold"]
    assert len(folds) == 1 and 1.8680 < folds[0]["omega"] < 1.8686, br.events
    assert any(e["event"] == "multiplier +1" for e in br.events)
    assert br.orbits[-1].type == "saddle" and br.orbits[-1].trace > 2 and br.omega[-1] > folds[0]["omega"]
    for w, orb in zip(br.omega[1:], br.orbits[1:]):
        bw = dataclasses.replace(FIG3_BALL, plane_rate=float(w))
        sec = tb.poincare_section("reduced", bw, orb.state, n_points=1)
        assert float(np.max(np.abs(sec.states[-1] - _rotate_public(orb.state, orb.shift)))) <= 1e-11


def test_symmetry_is_decided_on_states_not_on_chart_points():
    """``PeriodicOrbit.symmetric`` names a reversor only if it maps the section states onto
    themselves. sigma3 leaves the chart point (l, r1, r2) unchanged (the chart is blind to the
    signs of the third components), so a comparison of chart points called every orbit
    symmetric under sigma3: the Fig. 4a saddle's states are not (their sigma3 images are 11.9
    away), and a set that holds its sigma1 images is named sigma1."""
    from types import SimpleNamespace

    from taylorball.periodic import _symmetry_of, reversors
    from taylorball.periodic_catalog import FIG4A_SADDLE_K10
    from taylorball.sections import chart_points

    x = np.array(FIG4A_SADDLE_K10.state)[None, :]
    s3 = reversors()["sigma3"]
    assert np.array_equal(chart_points("reduced", x), chart_points("reduced", x * s3))  # the blind spot
    ctx = SimpleNamespace(prob=SimpleNamespace(kind="reduced"), symmetric=False)
    assert _symmetry_of(ctx, x, 1e-7) is None
    both = np.vstack([x, x * reversors()["sigma1"]])
    assert _symmetry_of(ctx, both, 1e-7) == "sigma1"
    moved = both.copy()
    moved[1, 3] += 1e-5  # one image moved off by 1e-5 (relative ~1e-6 > 1e-7): no longer symmetric
    assert _symmetry_of(ctx, moved, 1e-7) is None
