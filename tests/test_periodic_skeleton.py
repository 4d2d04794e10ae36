"""The Fig. 3 level's saddle (periodic_catalog), the grazing of the section that stopped the
saddle branch, homoclinic orbits by multiple shooting (periodic_homoclinic) and refinement
in MPFR. Every check is against a computation the code under test does not make: the
section integrator run afresh, finite differences in real128, the inverse map."""

import dataclasses
import math

import numpy as np
import pytest

import taylorball as tb
from taylorball import periodic as P
from taylorball.errors import UsageError
from taylorball.paper import FIG3_BALL, FIG3_LEVELS

EPS = np.finfo(float).eps


from ._periodic_checks import quotient_matrix_fd, rotate_public as _rotate_public, rr as _rr


@pytest.fixture(scope="module")
def saddle():
    from taylorball.periodic_catalog import fig3_saddle

    return fig3_saddle()


def test_fig3_saddle_in_an_independent_propagation(saddle):
    """The catalogued orbit: a saddle of the Fig. 3 map with period 4 on the paper's section
    g = 0. The section integrator from its state returns to the state rotated by theta after
    4 crossings; its 4 section points are mirror images under r2 -> -r2 (the reversor of the
    map of (r1, r2)); the multipliers are a pair (mu, 1/mu)."""
    o = saddle
    assert o.k == 4 and o.g0 == 0.0 and o.stability == "hyperbolic" and o.type == "saddle"
    sec = tb.poincare_section("reduced", FIG3_BALL, o.state, n_points=4)
    assert sec.ok and abs(sec.times[-1] - o.period) <= 1e3 * EPS * o.period
    err = float(np.max(np.abs((sec.states[-1] - _rotate_public(o.state, o.shift)).astype(float))))
    assert err <= 1e-11, err  # measured 3e-13 (|x| ~ 12, t ~ 30)
    mu = o.multipliers
    assert abs(mu[0] * mu[1] - 1) <= 1e4 * EPS  # float64 fundamental matrix over t ~ 30
    assert abs(mu[1] - 2.23987) <= 1e-5 and mu.imag.max() == 0.0
    pts = np.array([_rr(s).astype(float) for s in sec.states])
    mirror = pts * np.array([1.0, -1.0])
    assert max(float(np.min(np.max(np.abs(pts - m), axis=1))) for m in mirror) <= 1e-9
    assert o.lyapunov == pytest.approx(math.log(abs(mu[1])) / o.period)


def test_fig3_saddle_trace_from_finite_differences_in_real128(saddle):
    """The trace of the 2x2 multiplier matrix against central differences of P^4 in the
    chart (r1, r2) (invariant under the rotation about axis 3, so it carries the quotient
    map), every image by the real128 section integrator: trace of J C^-1."""
    o = saddle
    A = quotient_matrix_fd(o, FIG3_BALL, FIG3_LEVELS)
    # the variational trace: float64 fundamental matrix over t ~ 30 with entries up to ~1e2
    assert abs(np.trace(A) - o.trace) <= 1e-8, (np.trace(A), o.trace)
    assert abs(np.linalg.det(A) - 1) <= 1e-8


def test_fig3_saddle_multiplier_is_the_lyapunov_exponent(saddle):
    """ln |mu| / T against lyapunov_spectrum started on the orbit (an independent tangent
    integration with QR, in the 9 variables). The finite-time exponent approaches the limit
    like 1/t; over 10 and 20 periods (the orbit's own error, 3e-13 grown by 2.24^20, stays
    below 1e-5) the Richardson extrapolation 2 L(20 T) - L(10 T) agreed with ln |mu| / T to
    6e-4 relative (0.0267036 against 0.0266886)."""
    o = saddle
    lam = math.log(abs(o.multipliers[-1])) / o.period
    L10 = tb.lyapunov_spectrum("reduced", FIG3_BALL, o.state, 10 * o.period).exponents[0]
    L20 = tb.lyapunov_spectrum("reduced", FIG3_BALL, o.state, 20 * o.period).exponents[0]
    assert abs(L20 - lam) > 0.05 * lam  # the plain finite-time value is not the limit (0.0296) ...
    assert abs((2 * L20 - L10) - lam) <= 2e-3 * lam  # ... its extrapolation is


def test_the_saddle_on_other_sections(saddle):
    """section_windows counts the orbit's increasing crossings of each g = g0 (4 on the
    paper's g = 0, 9 on g = 3.83, at least 3 everywhere: g winds 3 times per period), and
    on_section solves the same orbit on g = 3.83 with k = 9: the same period, the same
    multipliers (a conjugate map), a state that the section integrator returns to after 9
    crossings."""
    from taylorball.periodic_continuation import on_section, section_windows

    W = section_windows(saddle)
    count = {round(g0, 2): int(c) for g0, c, _ in W}
    assert count[0.0] == 4 and count[3.83] == 9 and min(count.values()) == 3
    o9 = on_section(saddle, 3.83)
    assert o9.k == 9 and o9.g0 == 3.83
    assert abs(o9.period - saddle.period) <= 1e-9 * saddle.period
    assert abs(o9.trace - saddle.trace) <= 1e-8
    sec = tb.poincare_section("reduced", FIG3_BALL, o9.state, n_points=9, g0=3.83)
    assert float(np.max(np.abs((sec.states[-1] - _rotate_public(o9.state, o9.shift)).astype(float)))) <= 1e-11


def test_fig4_ball_orbit_on_the_fig4b_level():
    """The catalogued orbit of the Fig. 4 ball (I = (2, 3, 4), Fig. 4b level, Omega = 1.24994):
    the section integrator returns to the state after its 30 crossings of g = 0.55; the
    state is on the Fig. 4b level; the points 15 crossings apart differ by the rotation by pi
    about the body axis 3 (l + pi, the same r1, r2; a symmetry of every ball, checked here on
    the chart only); three real multipliers with product 1."""
    from taylorball.paper import FIG4B_LEVELS
    from taylorball.periodic_catalog import FIG4B_SADDLE_SLOW, catalog_orbit

    e = FIG4B_SADDLE_SLOW
    o = catalog_orbit(e)
    assert o.k == 30 and o.stability == "hyperbolic" and o.multipliers.shape == (3,)
    sec = tb.poincare_section("reduced", e.ball, o.state, n_points=30, g0=0.55)
    assert abs(sec.times[-1] - o.period) <= 1e3 * EPS * o.period
    err = float(np.max(np.abs(sec.states[-1] - o.state)))
    assert err <= 1e-10, err  # measured 4.3e-12 (multiplier 5.19, t ~ 79)
    lv = tb.integrals("reduced", e.ball, o.state)
    assert abs(lv["E"] - FIG4B_LEVELS.h) <= 64 * EPS * 10 and abs(lv["M_gamma"] - FIG4B_LEVELS.M_gamma) <= 64 * EPS * 10
    pts = o.points
    dl = (pts[15:, 0] - pts[:15, 0]) % (2 * np.pi)
    assert np.allclose(dl, np.pi, atol=1e-9) and np.allclose(pts[15:, 1:], pts[:15, 1:], atol=1e-9)
    # det 1 at a fixed point; float64 fundamental matrix over t ~ 79 through 30 crossings,
    # entries up to ~1e4: measured 5.1e-11, allowed 1e6 eps
    assert abs(np.prod(o.multipliers).real - 1) <= 1e6 * EPS and np.all(o.multipliers.imag == 0)


#: A state of the saddle branch at Omega = 1.8867893301703142 on the section g = 0 (from a
#: pseudo-arclength continuation; a guess only: Newton solves again).
_GRAZING = ((-6.888577139774679e-07, 0.02204283336438234, -2.000100372617707, 1.5864561139758313e-07,
             -0.0050765004125750465, -0.9999871144887499, 2.3587312897415954e-05, -0.7547701280750913,
             0.003831640242958002), 1.8867893301703142, 2.9149406518929206)


def test_the_saddle_branch_grazes_the_section_g0():
    """Why the continuation on g = 0 stalled near Omega = 1.8897: the orbit's crossing of
    g = 0 becomes tangent to the section (dg/dt at the crossing -> 0). At Omega = 1.88679
    the event's time derivative at the section point is already small, and the same orbit
    solved on the section g = 1 (a state from the section integrator) has the same period
    and the same trace: the orbit is fine, its crossing of g = 0 is not."""
    state, w, theta = _GRAZING
    ball = dataclasses.replace(FIG3_BALL, plane_rate=w)
    o = P.periodic_orbit("reduced", ball, np.array(state), 1, levels=FIG3_LEVELS, options=P.NewtonOptions(shift=theta))
    de = float(P._eval_geo(o.problem, 0.0, o.internal).de)
    assert 0 < de < 0.03  # measured 0.0176 (0.158 at Omega = 1.8692; it falls to 0 near 1.8900)
    on1 = tb.poincare_section("reduced", ball, o.state, n_points=1, g0=1.0).states[-1]
    o1 = P.periodic_orbit("reduced", ball, on1, 1, g0=1.0, levels=FIG3_LEVELS, options=P.NewtonOptions(shift=theta))
    assert abs(o1.period - o.period) <= 1e-9 * o.period
    assert abs(o1.trace - o.trace) <= 1e-7  # a conjugate map: the same multipliers
    assert float(P._eval_geo(o1.problem, 1.0, o1.internal).de) > 10 * de


#: The Fig. 3 saddle branch where theta = pi (Omega = 1.9133543369), on the section g = 0.55
#: (from a continuation; a guess only: Newton solves again).
_THETA_PI = ((0.2028399204794309, 0.7202322562571303, -2.1555353143739686, 0.4753849934676245, 0.2642186138510082,
              -0.8391648420188005, -2.2142723431300344, -0.38641541281306996, -1.3760466719990123),
             1.9133543369247183, 3.1415926535899366)


def test_inertia_homotopy_to_an_asymmetric_ball():
    """From the relative orbit with theta = pi (a circle of k = 2 orbits of the symmetric
    ball) to I = (2, 2.01, 3.01) with Omega free: the end point is a periodic orbit of that
    asymmetric ball at the Omega found, in an independent propagation, on the same level;
    Omega moved by O(the change of inertia) (measured 1.91335 -> 1.90678)."""
    from taylorball.periodic_continuation import inertia_homotopy

    state, w, theta = _THETA_PI
    o = P.periodic_orbit("reduced", dataclasses.replace(FIG3_BALL, plane_rate=w), np.array(state), 1, g0=0.55,
                         levels=FIG3_LEVELS, options=P.NewtonOptions(shift=theta))
    h = inertia_homotopy(o, FIG3_LEVELS, (2.0, 2.01, 3.01), phase=1.14, ds=0.01, ds_max=0.25)
    assert h.stopped == "reached" and h.s[-1] == 1.0 and h.orbit is not None
    assert 0.001 < w - h.omega[-1] < 0.02
    ball = dataclasses.replace(FIG3_BALL, plane_rate=float(h.omega[-1]), inertia=(2.0, 2.01, 3.01))
    e = h.orbit
    assert e.k == 2 and e.stability == "hyperbolic" and e.multipliers.shape == (3,)
    sec = tb.poincare_section("reduced", ball, e.state, n_points=e.k, g0=0.55)
    assert float(np.max(np.abs(sec.states[-1] - e.state))) <= 1e-11
    lv = tb.integrals("reduced", ball, e.state)
    assert abs(lv["E"] - FIG3_LEVELS.h) <= 64 * EPS * 10
    with pytest.raises(UsageError, match="q theta"):
        inertia_homotopy(o, FIG3_LEVELS, (2.0, 2.01, 3.01), q=3)


# ---------------------------------------------------------------------------------------
# Homoclinic orbits of the Fig. 1 saddle.
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def fig1_pair():
    from taylorball.charts import mparallel_states_on_section
    from taylorball.paper import FIG1_LEVELS, fig1_params

    with pytest.warns(tb.UnphysicalParametersWarning):
        p = fig1_params()
    lv = FIG1_LEVELS.as_kwargs()
    o0 = P.periodic_orbit("mparallel", p, mparallel_states_on_section(p, **lv, point=(0.0, 0.0))[0], 1, levels=FIG1_LEVELS)
    o1 = P.periodic_orbit("mparallel", p, mparallel_states_on_section(p, **lv, point=(math.pi, 0.0))[0], 1,
                          levels=FIG1_LEVELS)
    return p, o0, o1


@pytest.fixture(scope="module")
def heteroclinic(fig1_pair):
    """W^u(saddle 0) & W^s(saddle pi), and W^u(saddle pi) & W^s(saddle 0), by the
    fundamental-domain method (periodic_manifolds.homoclinic_points)."""
    from taylorball.periodic_manifolds import homoclinic_points

    p, o0, o1 = fig1_pair
    kw = dict(n_u=8, n_s=9, n_fund=30, s0=2.0396e-4, max_points=1)
    out = homoclinic_points(o0, target=o1, branches=((1, 1),), **kw)[0]
    back = homoclinic_points(o1, target=o0, branches=((1, -1),), **kw)[0]
    return out, back


@pytest.fixture(scope="module")
def homoclinic(fig1_pair, heteroclinic):
    from taylorball.periodic_homoclinic import connecting_orbit, homoclinic_chain

    p, o0, o1 = fig1_pair
    return connecting_orbit(o0, o0, homoclinic_chain(o0, o1, *heteroclinic))


def test_homoclinic_orbit_in_an_independent_propagation(fig1_pair, homoclinic):
    """Each point of the shooting solution is the section integrator's image of the one
    before; the ends are on the saddle's linear manifolds within 1e-6; from the point after
    the passage by the partner saddle the forward images approach the saddle at the rate
    mu_s, and from the reported point the backward images (inverse map) at 1/mu_u."""
    from taylorball.periodic_manifolds import inverse_map

    p, o0, o1 = fig1_pair
    h = homoclinic
    assert h.residual <= 1e-12 and 40 <= len(h) <= 70  # measured 3.3e-14, 57 points
    for i in range(len(h) - 1):
        img = tb.poincare_section("mparallel", p, h.states[i], n_points=1).states[-1]
        assert float(np.max(np.abs(img - h.states[i + 1]))) <= 1e-12, i
    assert max(abs(h.a), abs(h.b)) <= 1e-6
    assert abs(h.point[1] - 0.65376346) <= 1e-8 and abs(h.point[0] - 0.70831308) <= 1e-8  # the l = 0.708 crossing
    mu_s, mu_u = abs(o0.multipliers[0]), abs(o0.multipliers[-1])
    # the point two thirds along (after the partner, l ~ 3.85): forward to the saddle (l = 2 pi)
    j = int(np.argmin(np.abs(h.points[:, 0] - 3.85)))
    fwd = tb.poincare_section("mparallel", p, h.states[j], n_points=12).states
    d = np.array([np.max(np.abs(s - o0.state)) for s in fwd])
    assert d[-1] <= 1e-5 and np.allclose(d[6:11] / d[5:10], mu_s, rtol=0.05), d
    bwd = inverse_map(o0, h.state, 12)
    d = np.array([np.max(np.abs(s - o0.state)) for s in bwd])
    assert d[-1] <= 1e-5 and np.allclose(d[6:11] / d[5:10], 1 / mu_u, rtol=0.05), d


def test_homoclinic_tangents_against_finite_differences(fig1_pair, heteroclinic, homoclinic):
    """The manifolds' tangents the shooting carries along the orbit with the variational
    Jacobians, against central differences in long double: of P^i (the section integrator)
    at z_0 along the unstable eigenvector, at the reported point i; of the inverse map at
    z_N along the stable one, at the point j after the passage by the partner saddle. The
    angle at the reported point against the heteroclinic point's (its orbit passes ~10
    iterations near the partner saddle, so the manifolds there are C^1-close to the
    heteroclinic ones), whose tangents come from central differences of the
    fundamental-domain runs."""
    from taylorball.periodic_manifolds import _saddle_directions, inverse_map

    p, o0, _ = fig1_pair
    h = homoclinic
    o_ld = P.refine(o0, (np.longdouble,))[-1]
    prob = o_ld.problem
    ctx = P._Ctx(prob, 0.0, 1, 1, P._eval_geo(prob, 0.0, o_ld.internal).c.copy(), False, 1e4)
    _, _, _, vu, _, vs = _saddle_directions(o0)
    i, n = h.index, len(h) - 1
    j = int(np.argmin(np.abs(h.points[:, 0] - 3.85)))
    eps = 1e-12  # grown by ~mu^14 to ~5e-5: truncation ~5e-5 relative; start rounding 1e-18/eps

    def ends(z, v):
        zl = prob.spec.array(z)
        return [P.public_state(prob.system, prob.pars, P._to_level(ctx, zl + prob.spec.array(s * eps * v), 10.0),
                               prob.spec) for s in (1, -1)]

    a, b = ends(h.internal[0], vu)
    ia, ib = (tb.poincare_section("mparallel", p, x, n_points=i, fp_type=np.longdouble).states[-1] for x in (a, b))
    tu = (P.start_state(prob, ia) - P.start_state(prob, ib)).astype(float)
    a, b = ends(h.internal[n], vs)
    sa, sb = (inverse_map(o_ld, x, n - j)[-1] for x in (a, b))
    tsd = (P.start_state(prob, sa) - P.start_state(prob, sb)).astype(float)
    for fd, t in ((tu, h.tangent_u[i]), (tsd, h.tangent_s[j])):
        fd = fd / np.linalg.norm(fd)
        assert min(np.linalg.norm(fd - t), np.linalg.norm(fd + t)) <= 1e-3, (fd, t)
    out, _ = heteroclinic
    assert abs(h.angle_state - out.angle_state) <= 1e-6 * out.angle_state  # measured 0.5010430729 deg both
    assert 0.002 < h.angle < 0.02  # 0.3792 degrees in the chart


def test_homoclinic_point_digits_from_long_double(fig1_pair, homoclinic):
    """The same shooting in long double moves the point by less than 1e-12 (the float64
    solution's accuracy; measured 3.7e-14 in the chart)."""
    from taylorball.periodic_homoclinic import connecting_orbit

    _, o0, _ = fig1_pair
    hl = connecting_orbit(o0, o0, homoclinic.states, fp_type=np.longdouble)
    assert hl.residual <= 1e3 * np.finfo(np.longdouble).eps * 10  # |x| ~ 10
    assert float(np.max(np.abs(hl.points[homoclinic.index] - homoclinic.point))) <= 1e-12


def test_connecting_orbit_bad_input(fig1_pair, homoclinic):
    from taylorball.periodic_homoclinic import connecting_orbit

    _, o0, _ = fig1_pair
    with pytest.raises(UsageError, match="at least 3"):
        connecting_orbit(o0, o0, homoclinic.states[:2])
    with pytest.raises(UsageError, match="hyperbolic"):
        connecting_orbit(dataclasses.replace(o0, stability="elliptic"), o0, homoclinic.states)
    with pytest.raises(UsageError, match="prec"):
        P.refine(o0, (("real", 160, 3),))


@pytest.mark.slow
def test_refinement_in_mpfr(fig1_pair):
    """float64 -> real128 -> MPFR (160 bits) refinement of the Fig. 1 saddle: the real128
    state is correct to >= 30 digits by the MPFR solution, and the MPFR state returns after
    one crossing, in an independent MPFR section run, to 1e3 eps of 160 bits."""
    import heyoka as hy

    p, o0, _ = fig1_pair
    f64, q, m = P.refine(o0, ("real128", ("real", 160)))
    assert q.digits["real128"] >= 30 and m.fp_type.startswith("real")
    eps160 = 2.0 ** -159
    assert m.residual <= 1e3 * eps160 * 11
    sec = tb.poincare_section(tb.problem("mparallel", p, fp_type=hy.real, prec=160), m.state, n_points=1)
    err = max(abs(float(v)) for v in (sec.states[-1] - m.state))
    assert err <= 1e3 * eps160 * 11, err
