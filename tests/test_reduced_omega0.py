"""The reduced system as Omega -> 0 (docs/skeleton.md, "Omega -> 0 in the reduced system").

At Omega = 0 the (M, gamma) part is Chaplygin's ball on a fixed plane and R is a quadrature:
over a (relative) period of (M, gamma) the centre moves by a displacement D in the fixed
frame, which is a function of (M, gamma) alone, so a periodic orbit at finite R needs D = 0.
For Omega > 0 the reduced periodic orbits near a Chaplygin orbit with D != 0 hold the ball
in place: the plane's velocity at the centre, Omega z x R, cancels the mean rolling velocity
D / T, so Omega |R| -> |D| / T and the family comes in from infinity in R.

Every reference here comes from an integration of Chaplygin's equations written in this file
from the paper (secs. 1-3 with Omega = 0; scipy's DOP853, not taylorball.model) and from the
closed-form levels of the limit; the code under test only supplies start states and the
orbits that are checked against them."""

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import taylorball as tb
from taylorball.paper import FIG3_BALL, FIG4_BALL
from taylorball.periodic_continuation import continue_in_omega
from taylorball.periodic_held import held_in_place

from ._periodic_checks import rotate_public

#: DOP853's relative and absolute tolerance in the reference integrations.
RTOL = 1e-12
#: Agreement of a reference with the code under test after one period: 1e3 RTOL (about 10^3
#: DOP853 steps per period, each committing up to RTOL relative; measured <= 4e-13).
AGREE = 1e3 * RTOL


def _chaplygin(params, K0, gamma0, n_cross, t_end):
    """Chaplygin's ball on a fixed plane with the centre's position ``(x, y)`` in the fixed
    frame, from ``(K0, gamma0)``: ``K = Itilde omega``, ``Itilde = I + m a^2 (E - gamma
    gamma^T)``, ``dK/dt = K x omega``, ``dgamma/dt = gamma x omega``; the frame has ``beta``
    along the horizontal part of ``K`` (``F1 = 0``), ``alpha = beta x gamma``, and the centre
    moves by ``dx/dt = a (omega, beta)``, ``dy/dt = -a (omega, alpha)`` (paper eq. (10) [eq6] with
    ``Omega = 0``). Returns ``(t, z)`` of the first ``n_cross`` crossings of ``g = 0`` upwards
    (``M2 gamma1 - M1 gamma2`` increasing through 0 with ``(M, gamma) M3 - |M|^2 gamma3 > 0``)."""
    I = np.asarray(params.inertia, dtype=float)
    a = float(params.radius)
    d = float(params.mass) * a * a

    def rhs(t, z):
        K, g = z[0:3], z[3:6]
        w = np.linalg.solve(np.diag(I) + d * (np.eye(3) - np.outer(g, g)), K)
        be = K - (K @ g) * g
        be /= np.linalg.norm(be)
        al = np.cross(be, g)
        return np.concatenate([np.cross(K, w), np.cross(g, w), [a * (w @ be), -a * (w @ al)]])

    def event(t, z):
        return z[1] * z[3] - z[0] * z[4]

    event.direction = 1  # type: ignore[attr-defined]
    z0 = np.concatenate([K0, gamma0, [0.0, 0.0]])
    sol = solve_ivp(rhs, (0.0, t_end), z0, method="DOP853", rtol=RTOL, atol=RTOL, events=event)
    out = []
    for t, z in zip(sol.t_events[0], sol.y_events[0]):
        K, g = z[0:3], z[3:6]
        if t > 1e-6 and (K @ g) * K[2] - (K @ K) * g[2] > 0:
            out.append((float(t), z))
    assert len(out) >= n_cross, (len(out), n_cross)
    return out[n_cross - 1]


def _K(params, state):
    """``K = Itilde omega`` of a public reduced state, written here."""
    g = np.asarray(state[3:6], dtype=float)
    d = float(params.mass) * float(params.radius) ** 2
    Itilde = np.diag(np.asarray(params.inertia, dtype=float)) + d * (np.eye(3) - np.outer(g, g))
    return Itilde @ np.asarray(state[0:3], dtype=float)


def _frame(K, g):
    be = K - (K @ g) * g
    be /= np.linalg.norm(be)
    return np.cross(be, g), be


# ---------------------------------------------------------------------------------------
# The dynamically symmetric ball (Fig. 3's I = (2, 2, 3), m = 1, a = 5): every orbit of
# Chaplygin's ball is relatively periodic (k = 1), so the limit is non-degenerate.
# ---------------------------------------------------------------------------------------
SYM0 = dataclasses.replace(FIG3_BALL, plane_rate=0.0)
#: Chaplygin's level |K| = 10, (K, gamma) = 6, E = 7.2, started at the chart point (0.3, 0, 0).
SYM_TORUS = dict(C=10.0, M_gamma=6.0, h=7.2, point=(0.3, 0.0, 0.0))


@pytest.fixture(scope="module")
def sym_limit():
    """The Chaplygin orbit (reference integration), its drift and the limit level."""
    s = tb.states_on_section(SYM0, direction=1, **SYM_TORUS)[0]
    K0, g0 = _K(SYM0, s), np.asarray(s[3:6], dtype=float)
    T, z = _chaplygin(SYM0, K0, g0, 1, 6.0)
    D = z[6:8]
    al, be = _frame(K0, g0)
    W = np.array([-D[1], D[0]]) / T  # Omega R (fixed frame) that makes the plane cancel D / T
    Wb = W[0] * al + W[1] * be
    a, m = float(SYM0.radius), float(SYM0.mass)
    E = 0.5 * float(K0 @ np.asarray(s[0:3], dtype=float))
    levels = tb.Levels(C=float(np.linalg.norm(K0 - m * a * Wb)), M_gamma=float(K0 @ g0),
                       h=E - m * float(W @ W) / 2)
    theta = math.atan2(K0[0], K0[1]) - math.atan2(z[0], z[1])  # P x = S_theta x lowers l by theta
    return dict(state=s, K0=K0, gamma0=g0, T=T, z=z, D=D, W=W, Wb=Wb, levels=levels, theta=theta)


def test_omega0_chaplygin_orbit_drifts_so_R_is_not_periodic(sym_limit):
    """At Omega = 0 the reduced system's (M, gamma) returns after one crossing up to the
    rotation about axis 3 (a relative periodic orbit of Chaplygin's ball), and its R after the
    same time is R(0) moved by the centre's displacement D of the reference integration (the
    frame returns with (M, gamma)): |D| / T = 1.43, so no R makes this orbit periodic at
    Omega = 0."""
    lim = sym_limit
    s, T = lim["state"], lim["T"]
    sec = tb.poincare_section("reduced", SYM0, s, n_points=1)
    assert abs(float(sec.times[0]) - T) <= AGREE * T  # measured 3e-13
    back = np.asarray(rotate_public(np.asarray(s, dtype=float), lim["theta"]), dtype=float)
    x1 = np.asarray(sec.states[0], dtype=float)
    assert np.max(np.abs(x1[0:6] - back[0:6])) <= AGREE * np.max(np.abs(s))  # a relative periodic orbit
    # R from R(0) = 0: in the frame at time T it is the displacement of the reference
    al, be = _frame(_K(SYM0, x1), x1[3:6])
    assert np.max(np.abs([x1[6:9] @ al - lim["D"][0], x1[6:9] @ be - lim["D"][1]])) <= AGREE * np.linalg.norm(lim["D"])
    assert np.linalg.norm(lim["D"]) / T == pytest.approx(1.42998843, abs=1e-7)  # measured 1.429988433
    assert abs(lim["D"][1]) <= AGREE * abs(lim["D"][0])  # perpendicular to the horizontal K


def _limit_orbit(lim, omega):
    """The held-in-place orbit at ``omega`` from the code under test
    (:func:`taylorball.periodic_held.held_in_place`), its limit checked against the reference
    integration: period, drift and the closed-form limit level to AGREE (two integrations of
    one period, each to ~1e3 RTOL)."""
    r = held_in_place(SYM0, **SYM_TORUS, omega=omega)
    assert abs(r.period - lim["T"]) <= AGREE * lim["T"]
    assert np.max(np.abs(r.drift - lim["D"] / lim["T"])) <= AGREE * np.linalg.norm(lim["W"])
    lev = lim["levels"]
    for got, want in ((r.levels.C, lev.C), (r.levels.M_gamma, lev.M_gamma), (r.levels.h, lev.h)):
        # W off by AGREE |W| moves C = |K - m a W| by up to m a |W| AGREE = 7.1 AGREE, h by m |W|^2 AGREE = 2 AGREE
        assert abs(got - want) <= 10 * AGREE, (got, want)
    return r


def test_relative_periodic_orbit_holds_the_ball_in_place_as_omega_to_0(sym_limit):
    """On the limit level, Newton from the held-in-place guess converges at Omega = 0.02, and
    the natural continuation follows the same branch to Omega = 0.005. Along it Omega |R|,
    the period and the shift tend to the reference's |D| / T, T and theta linearly in Omega,
    tr A - 2 tends to 0 like Omega^2 (multipliers exp(+-i nu Omega), elliptic); K = M + m a
    Omega R and gamma tend to the reference orbit (|K|^2 and the energy (K, omega)/2 of its
    torus, linearly), and the lifted full motion returns the centre to its place in the fixed
    frame after one period."""
    lim = sym_limit
    r = _limit_orbit(lim, 0.02)
    br = continue_in_omega(r.orbit, r.levels, [0.01, 0.005])
    assert br.omega[-1] == 0.005, br.stopped
    by = {float(w): b for w, b in zip(br.omega, br.orbits)}
    errs = {}
    for w in (0.02, 0.01, 0.005):
        b = by[w]
        assert b.type == "elliptic" and np.allclose(np.abs(b.multipliers), 1.0, atol=1e-9)
        K = _K(ball := b.problem.params, b.state)
        errs[w] = (w * np.linalg.norm(b.state[6:9].astype(float)) - np.linalg.norm(lim["W"]),
                   b.period - lim["T"], b.shift - lim["theta"], b.trace - 2.0,
                   float(K @ K) - float(lim["K0"] @ lim["K0"]),  # the torus's |K|^2 (100) and energy (7.2)
                   0.5 * float(K @ b.state[0:3].astype(float)) - SYM_TORUS["h"])
        # the orbit returns in a fresh section run (up to the rotation about axis 3)
        x1 = np.asarray(tb.poincare_section("reduced", ball, b.state, n_points=1).states[0], dtype=float)
        back = np.asarray(rotate_public(np.asarray(b.state, dtype=float), b.shift), dtype=float)
        assert np.max(np.abs(x1 - back)) <= 1e-10 * np.max(np.abs(back))  # measured ~1e-13 relative
        # the fixed frame: the centre returns after one period (the ball held in place)
        f0 = tb.reduced_to_full(ball, b.state)
        fT = tb.propagate("full", ball, f0, b.period)
        assert np.max(np.abs(fT[12:14] - f0[12:14])) <= 1e-10 * np.linalg.norm(f0[12:14])
    # measured: Omega |R| - |W| = -5.70e-4, -2.85e-4, -1.42e-4 (-0.0285 Omega); period and
    # shift likewise linear; tr A - 2 = -3.98e-5, -9.94e-6, -2.48e-6 (-0.0995 Omega^2)
    for j, want in enumerate((2.0, 2.0, 2.0, 4.0, 2.0, 2.0)):  # halving Omega halves an O(Omega) error
        r1, r2 = errs[0.02][j] / errs[0.01][j], errs[0.01][j] / errs[0.005][j]
        assert abs(r1 - want) < 0.05 * want and abs(r2 - want) < 0.05 * want, (j, r1, r2)
    assert errs[0.005][3] < 0
    assert abs(errs[0.005][0]) < 0.05 * 0.005 and abs(errs[0.005][1]) < 0.05 * 0.005
    # (K, gamma) of the orbit at 0.005 starts a relative periodic orbit of Chaplygin's ball
    # (the reference) with the branch's period and drift to O(Omega); its trace by real128
    # central differences of the map of (r1, r2), without variational equations
    from ._periodic_checks import quotient_matrix_fd

    b = by[0.005]
    A = quotient_matrix_fd(b, b.problem.params, r.levels)
    assert abs(np.trace(A) - b.trace) < 1e-9 and np.trace(A) - 2 < -1e-6  # measured: -2.48e-6, 4e-14 apart
    T, z = _chaplygin(SYM0, _K(b.problem.params, b.state), b.state[3:6].astype(float), 1, 6.0)
    assert abs(T - b.period) < 0.01 * 0.005 * 100 and np.linalg.norm(z[6:8]) / T == pytest.approx(
        np.linalg.norm(lim["W"]), rel=0.01)


def test_the_limit_family_reaches_omega_2_elliptic(sym_limit):
    """The branch of the limit level followed up from Omega = 0.02 reaches Omega = 2 with no
    event (elliptic throughout, tr A falling to 1.5627); at 2 the trace by real128 central
    differences of the map of (r1, r2) agrees with the variational one, and the orbit returns
    in a fresh section run. With the branch down to 0.001 (docs) this is a family of the
    reduced system over all of (0, 2]."""
    from ._periodic_checks import quotient_matrix_fd

    lim = sym_limit
    r = _limit_orbit(lim, 0.02)
    br = continue_in_omega(r.orbit, r.levels, [0.5, 1.0, 1.5, 2.0])
    assert br.omega[-1] == 2.0 and not br.events, (br.stopped, br.events)
    assert all(b.type == "elliptic" for b in br.orbits)
    tr = [b.trace for b in br.orbits]
    assert np.all(np.diff(tr) < 0) and tr[-1] == pytest.approx(1.5627139, abs=1e-6)  # measured 1.56271390222
    b = br.orbits[-1]
    A = quotient_matrix_fd(b, b.problem.params, r.levels)
    assert abs(np.trace(A) - b.trace) < 1e-9  # measured 8e-13 (h = 1e-6: truncation ~1e-12)
    x1 = np.asarray(tb.poincare_section("reduced", b.problem.params, b.state, n_points=1).states[0], dtype=float)
    back = np.asarray(rotate_public(np.asarray(b.state, dtype=float), b.shift), dtype=float)
    assert np.max(np.abs(x1 - back)) <= 1e-10 * np.max(np.abs(back))


def test_the_bifurcation_figure_shows_the_family_over_0_2(sym_limit):
    """The data of panels (e, f) of the skeleton_bifurcation study (its quick configuration,
    ~3 CPU s): the held-in-place family over [0.001, 2] on one level, ascending in Omega, its
    limit (drift speed and period) equal to the reference's, and its first point, Omega =
    0.001, at the linear and quadratic rates of the test above."""
    from taylorball.figures import skeleton_bifurcation as S

    lim = sym_limit
    arrays, meta = S.held_family(S.QUICK)
    w, tr, wr = arrays["held_omega"], arrays["held_trace"], arrays["held_omega_R"]
    assert meta["omega_range"] == [0.001, 2.0] and meta["stopped"] == {"down": "reached", "up": "reached"}
    assert np.all(np.diff(w) > 0) and len(w) == meta["n_points"] == len(meta["types"])
    W = float(np.linalg.norm(lim["W"]))
    assert abs(meta["limit"]["drift_speed"] - W) <= AGREE * W and abs(meta["limit"]["period"] - lim["T"]) <= AGREE * lim["T"]
    for key, want in (("C", lim["levels"].C), ("M_gamma", lim["levels"].M_gamma), ("h", lim["levels"].h)):
        assert abs(meta["levels"][key] - want) <= 10 * AGREE  # as in _limit_orbit
    # Omega |R| - |W| = -0.0285 Omega and tr A - 2 = -0.0995 Omega^2 (rates of the test above,
    # ratios 2 and 4 to 5 %): at 0.001, -2.85e-5 and -9.9e-8; bounds twice the rates
    assert w[0] == 0.001 and -0.06 * w[0] < wr[0] - W < 0 and -0.2 * w[0] ** 2 < tr[0] - 2.0 < 0
    # no fold, period doubling or multiplier +1: the one event is the classification calling
    # tr A within its tolerance of 2 parabolic, below Omega = 0.004
    assert all(e["event"] == "stability change" and e["omega"] < 0.004 for e in meta["events"]), meta["events"]
    assert all(t == "elliptic" for t, x in zip(meta["types"], w) if x > 0.004)
    assert np.all(np.diff(tr) < 0) and tr[-1] == pytest.approx(1.5627139, abs=1e-6)  # as the test above


def test_held_in_place_rejects_bad_input():
    """A non-positive or non-finite omega and params that are not a ball are refused, naming
    the argument, before any integration."""
    with pytest.raises(tb.UsageError, match="omega"):
        held_in_place(SYM0, **SYM_TORUS, omega=0.0)
    with pytest.raises(tb.UsageError, match="omega"):
        held_in_place(SYM0, **SYM_TORUS, omega=float("nan"))
    with pytest.raises(tb.UsageError, match="params must be a BallParams"):
        held_in_place("ball", **SYM_TORUS, omega=0.05)


def _fixed_frame_means(ball, state, period, n):
    """Means over one period, in the fixed frame, of the lifted full motion sampled at ``n``
    equal steps (the motion is periodic there, so this is the trapezoid rule, exact to
    rounding for ``n`` well above the number of Taylor steps): ``<I omega>``, ``Omega <R>``,
    ``a <omega_h>``, ``(1/2) <(I omega, omega)>``, ``Var omega_h``, ``Var R``."""
    f0 = tb.reduced_to_full(ball, state)
    tr = tb.propagate("full", ball, f0, np.linspace(0.0, period, n + 1))[:-1].astype(float)
    I = np.asarray(ball.inertia, dtype=float)
    w, al, be, g = tr[:, 0:3], tr[:, 3:6], tr[:, 6:9], tr[:, 9:12]
    Iw = w * I
    Iw_fixed = np.column_stack([np.sum(Iw * v, axis=1) for v in (al, be, g)])
    wh = np.column_stack([np.sum(w * al, axis=1), np.sum(w * be, axis=1)])
    R = tr[:, 12:14]

    def var(u):
        return float(np.mean(np.sum(u * u, axis=1)) - np.sum(np.mean(u, axis=0) ** 2))

    return dict(Iw=Iw_fixed.mean(axis=0), OmR=float(ball.plane_rate) * R.mean(axis=0),
                awh=float(ball.radius) * wh.mean(axis=0), kin=0.5 * float(np.mean(np.sum(Iw * w, axis=1))),
                var_wh=var(wh), var_R=var(R), f0=f0)


@pytest.mark.parametrize("name", ["FIG3_SADDLE", "FIG4A_SADDLE_K10", "TZENOFF_D35_REFLECTION_SADDLE"])
def test_periodic_orbits_obey_the_mean_momentum_identity_and_the_energy_bound(name):
    """For every periodic orbit (the centre returns in the fixed frame): ``Omega <R> = a
    <omega_h>`` (the mean of dx/dt, dy/dt is 0), hence ``M = <I omega>`` in the fixed frame
    (``M = Itilde omega - m a Omega R`` and ``Itilde omega = I omega + m a^2 omega_h``) and
    ``h = <(I omega, omega)>/2 + (m a^2/2) Var omega_h - (m/2) Omega^2 Var R``. Since ``(I
    omega, omega) >= |I omega|^2 / I_max >= ...``, ``(m/2) Omega^2 Var R >= C^2/(2 I_max) -
    h``: on the paper's levels (h = 5 < C^2/(2 I_max) = 16.7, 12.5) the centre's excursion is
    at least ~1/Omega, so no family there can tend, as Omega -> 0, to an orbit with bounded
    excursion (a drift-free Chaplygin orbit, or the ball held in place). Checked on catalogued
    orbits of the paper's and Tzenoff's levels at their Omega."""
    from taylorball import periodic_catalog

    o = periodic_catalog.catalog_orbit(getattr(periodic_catalog, name))
    ball = o.problem.params
    mm = _fixed_frame_means(ball, o.state, o.period, 20000)
    ints = tb.integrals("full", ball, mm["f0"])
    M = np.array([float(ints["F1"]), float(ints["F2"]), float(ints["F3"])])
    h = float(ints["E"])
    m, d, Imax = float(ball.mass), float(ball.mass) * float(ball.radius) ** 2, max(ball.inertia)
    Om = float(ball.plane_rate)
    # rounding of 2e4-sample means of terms up to ~100 (energy) and ~14 (Omega R): 1e3 eps
    # times their size; measured <= 1e-12 (energy) and 5e-14 (momenta)
    tol = 1e3 * np.finfo(float).eps
    assert np.max(np.abs(mm["OmR"] - mm["awh"])) <= tol * 20
    assert np.max(np.abs(M - mm["Iw"])) <= tol * 20
    rhs = mm["kin"] + d / 2 * mm["var_wh"] - m / 2 * Om**2 * mm["var_R"]
    assert abs(h - rhs) <= tol * 200
    C2 = float(M @ M)
    assert mm["kin"] >= C2 / (2 * Imax) and h < C2 / (2 * Imax)
    assert m / 2 * Om**2 * mm["var_R"] >= C2 / (2 * Imax) - h  # measured 120 >= 11.7 (Fig. 3 saddle)


# ---------------------------------------------------------------------------------------
# The asymmetric ball (Fig. 4's I = (2, 3, 4)): the torus must be resonant, and the drift
# is the same on every orbit of a resonant torus (a circle of limits; no orbit was found).
# ---------------------------------------------------------------------------------------
def test_asymmetric_resonant_torus_has_one_drift_for_all_its_orbits():
    """Chaplygin's level |K| = 10, (K, gamma) = 2 of the Fig. 4 ball: the energy h* where the
    section map's rotation number is 1/12 (every point returns after 12 crossings), found by
    Brent on the section integrator; the reference integration from two points of that torus
    that are not on one orbit closes after 12 crossings, and both orbits move the centre by
    the same D / T (1.70984, perpendicular to the horizontal K) to 1e-9."""
    ball0 = dataclasses.replace(FIG4_BALL, plane_rate=0.0)

    def state(h, l0):
        return tb.states_on_section(ball0, C=10.0, M_gamma=2.0, h=h, point=(l0, 0.0, 0.0), direction=1)[0]

    def turn(h):
        pts = np.asarray(tb.poincare_section("reduced", ball0, state(h, 0.3), n_points=12).points, dtype=float)
        return float(np.unwrap(np.concatenate([[0.3], pts[:, 0]]))[12] - 0.3 - 2 * math.pi)

    h = brentq(turn, 2.21, 2.23, xtol=1e-13)
    assert h == pytest.approx(2.2229951181831846, abs=1e-10)
    drifts = []
    for l0 in (0.3, 0.55):  # 0.55 lies between the first orbit's section points 0.3 and 0.82
        s = state(h, l0)
        K0, g0 = _K(ball0, s), np.asarray(s[3:6], dtype=float)
        T, z = _chaplygin(ball0, K0, g0, 12, 120.0)
        assert np.max(np.abs(z[0:6] - np.concatenate([K0, g0]))) <= 1e4 * RTOL * 10  # 12 crossings, |K| = 10
        drifts.append(z[6:8] / T)
    assert drifts[0] == pytest.approx(drifts[1], abs=1e-9)
    assert drifts[0][0] == pytest.approx(1.70984239, abs=1e-7) and abs(drifts[0][1]) < 1e-9
