"""Sections of the user's choosing (``tb.Section(problem, event=..., direction=..., chart=...)``)
against raw heyoka events written here, independently of taylorball.sections; the T_MAX
outcome of a function that never vanishes; bad events; the Problem-first calls and the
``t_max`` alias of ``t_end``."""

import heyoka as hy
import numpy as np
import pytest

import taylorball as tb
from taylorball.paper import FIG4_BALL, FIG4B_LEVELS

EPS = np.finfo(float).eps
# 1e-12 relative (4500 eps) is the agreement promised for the same orbit. Measured (float64,
# 6 crossings by t ~ 19): times 1.5e-14 and states 6.5e-13 against the paper's omega
# formulation (a different integration, whose rounding grows with time); times 9e-15 and
# states 2.5e-13 against the same variables, where the raw event reports heyoka's root
# rounded to ulp(t) (~3.6e-15 at t = 19) without the Newton step, so its states are off by
# |dx/dt| ulp(t).
TOL = 1e-12


@pytest.fixture(scope="module")
def x0():
    # a regular orbit (Fig. 4b's level, invariant tori): rounding differences stay small
    return tb.states_on_section(FIG4_BALL, **FIG4B_LEVELS.as_kwargs(), point=(2.0, 2.5, 1.0), direction=1)[0]


def _raw_crossings(system, x_internal, event, direction, t_end):
    """Crossings of a raw heyoka integrator of ``system`` with its own non-terminal event
    ``event`` (an expression in the system's variables): times as heyoka reports them and
    the dense output there, in the system's variables."""
    rec = []

    def cb(ta, t, d_sgn):
        rec.append((float(t), ta.update_d_output(t).copy()))

    ev = hy.nt_event(event, cb, direction=direction)
    prob = tb.problem(system.kind, FIG4_BALL)
    ta = hy.taylor_adaptive(system.equations(), x_internal, pars=prob.pars, nt_events=[ev])
    ta.propagate_until(t_end)
    return np.array([t for t, _ in rec]), np.array([x for _, x in rec])


def _rel(a, b):
    return float(np.max(np.abs(a - b) / np.maximum(1.0, np.abs(b))))


def test_gamma3_crossings_agree_with_a_raw_heyoka_event(x0):
    prob = tb.problem("reduced", FIG4_BALL)
    r = tb.Section(prob, event="gamma3", direction=1, chart=("R1", "R2")).run(x0, n_points=6)
    assert r.ok and len(r) == 6
    # raw: the paper's equations in the paper's variables (the omega formulation, paper eqs. (15)-(16) [eq10]),
    # whose state is the public one, with an event on gamma3 written here
    system = tb.get_system("reduced", "omega")
    xs = hy.make_vars(*system.internal_names)
    t, X = _raw_crossings(system, np.asarray(x0, dtype=float), xs[5], hy.event_direction.positive,
                          float(r.times[-1]) + 0.5)
    assert len(t) >= 6
    assert _rel(r.times, t[:6]) < TOL
    assert _rel(r.states, X[:6]) < TOL
    assert np.array_equal(r.points, r.states[:, [6, 7]])  # chart=("R1", "R2")
    assert np.max(np.abs(r.states[:, 5])) < 64 * EPS  # on gamma3 = 0 to rounding
    assert np.max(np.abs(r.residuals)) < 64 * EPS


def _omega(M, gamma, R, ball):
    """Paper eq. (19) [sved]: ``omega = A K + d (gamma, A K) / (1 - d (gamma, A gamma)) A gamma`` with
    ``K = M + m a Omega R``, ``A = diag(1 / (I_i + m a^2))``, written here on heyoka
    expressions or numpy columns."""
    I1, I2, I3, m, a, Om = ball.pars
    d = m * a * a
    A = (1 / (I1 + d), 1 / (I2 + d), 1 / (I3 + d))
    K = [M[i] + m * a * Om * R[i] for i in range(3)]
    AK = [A[i] * K[i] for i in range(3)]
    Ag = [A[i] * gamma[i] for i in range(3)]
    c = d * sum(gamma[i] * AK[i] for i in range(3)) / (1 - d * sum(gamma[i] * Ag[i] for i in range(3)))
    return [AK[i] + c * Ag[i] for i in range(3)]


def test_a_mixed_function_agrees_with_a_raw_heyoka_event(x0):
    """``R1 - omega2 / 2`` mixes a state variable with one the momentum formulation computes
    (omega from M): the raw event is written here in M from paper eq. (19) [sved], on the same
    integrated variables (``tb.get_system("reduced")``), so the rewriting is checked too."""
    R1, w2 = hy.make_vars("R1", "omega2")
    prob = tb.problem("reduced", FIG4_BALL)
    r = tb.Section(prob, event=R1 - 0.5 * w2, direction=0, chart=("R1", "omega2")).run(x0, n_points=6)
    assert r.ok and len(r) == 6
    system = tb.get_system("reduced")
    assert system.internal_names[:3] == ("M1", "M2", "M3")
    xs = hy.make_vars(*system.internal_names)
    event = xs[6] - 0.5 * _omega(xs[0:3], xs[3:6], xs[6:9], FIG4_BALL)[1]
    x_int = np.asarray(x0, dtype=float).copy()
    # M = Itilde omega - m a Omega R (paper eq. (11) [eq13]), Itilde omega = I omega + d (omega - gamma (gamma, omega))
    I1, I2, I3, m, a, Om = FIG4_BALL.pars
    w, g, R = x_int[0:3], x_int[3:6], x_int[6:9]
    x_int[0:3] = np.array([I1, I2, I3]) * w + m * a * a * (w - g * (g @ w)) - m * a * Om * R
    t, X = _raw_crossings(system, x_int, event, hy.event_direction.any, float(r.times[-1]) + 0.5)
    assert _rel(r.times, t[:6]) < TOL
    assert _rel(r.states[:, 3:9], X[:6, 3:9]) < TOL  # gamma, R
    omega = np.array(_omega(X[:6, 0:3].T, X[:6, 3:6].T, X[:6, 6:9].T, FIG4_BALL)).T
    assert _rel(r.states[:, 0:3], omega) < TOL
    assert np.max(np.abs(r.points[:, 0] - 0.5 * r.points[:, 1])) < 64 * EPS * np.max(np.abs(r.points))


def test_every_system_takes_a_user_section(x0):
    full = tb.problem("full", FIG4_BALL)
    rf = tb.poincare_section(full, tb.reduced_to_full(FIG4_BALL, x0), n_points=3,
                             options=tb.SectionOptions(event="gamma3", chart=("x", "y")))
    assert rf.ok and rf.points.shape == (3, 2) and set(rf.levels) == {"F1", "F2", "F3", "E"}
    assert np.max(np.abs(rf.states[:, 11])) < 64 * EPS
    mp = tb.problem("mparallel", FIG4_BALL)
    xm = np.array([1.0, 2.0, 3.0, 0.6, 0.0, 0.8])
    rm = tb.Section(mp, event="gamma2", direction=1).run(xm, n_points=3)
    assert rm.ok and rm.points.shape == (3, 2)  # the kind's chart (l, L/G) by default
    assert np.max(np.abs(rm.states[:, 4])) < 64 * EPS


def test_a_large_event_is_weighted_to_leave_the_steps_alone(x0):
    """heyoka's step size takes the event's Taylor coefficients into account: ``1e10 gamma3``
    unweighted changes the steps; weighted (w = 1e-10 here) it gives the steps and
    crossings of ``gamma3``."""
    prob = tb.problem("reduced", FIG4_BALL)
    a = tb.Section(prob, event="gamma3").run(x0, n_points=5)
    b = tb.Section(prob, event=1e10 * hy.make_vars("gamma3")).run(x0, n_points=5)
    assert a.n_steps == b.n_steps and np.array_equal(a.times, b.times)
    assert tb.Section(prob, event="gamma3").extra_pars(tb.sections.start_state(prob, x0)) == (1.0,)


def test_a_function_that_never_vanishes_ends_with_t_max(x0):
    prob = tb.problem("reduced", FIG4_BALL)
    r = tb.Section(prob, event=hy.make_vars("gamma3") - 2.0).run(x0, n_points=3, t_end=20.0)
    assert r.outcome is tb.Outcome.T_MAX and len(r) == 0 and not r.ok
    assert "0 of 3 crossings" in r.message and "increase t_end" in r.message
    assert "never vanish" in r.message


@pytest.mark.parametrize("event, needle", [
    ("gamma4", "public variables of kind='reduced' (omega1, omega2, omega3, gamma1, gamma2, gamma3, R1, R2, R3)"),
    (hy.make_vars("z") + 1.0, "unknown variable(s) z"),
    (hy.expression(1.0), "constant expression"),
    (hy.make_vars("gamma3") + hy.par[0], "without runtime parameters"),
    (3.0, "of type float"),
])
def test_bad_events_name_the_valid_ones(event, needle):
    with pytest.raises(tb.UsageError, match="event must be") as e:
        tb.Section(tb.problem("reduced", FIG4_BALL), event=event)
    assert needle in str(e.value)


def test_bad_chart_and_g0_with_an_event():
    prob = tb.problem("reduced", FIG4_BALL)
    with pytest.raises(tb.UsageError, match="chart must name .* among l, r1, r2, omega1"):
        tb.Section(prob, event="gamma3", chart=("gamma9",))
    with pytest.raises(tb.UsageError, match="g0 is the angle of the paper's section"):
        tb.Section(prob, 1.0, event="gamma3")


def test_a_problem_first_is_the_string_call(x0):
    prob = tb.problem("reduced", FIG4_BALL)
    a = tb.poincare_section(prob, x0, n_points=4)
    b = tb.poincare_section("reduced", FIG4_BALL, x0, n_points=4)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.times, b.times)
    many = tb.poincare_sections(prob, [x0], n_points=4, workers=1)
    assert np.array_equal(many[0].points, b.points)
    with pytest.raises(tb.UsageError, match=r"got a Problem .* and also params=BallParams.*pass the Problem alone"):
        tb.poincare_section(prob, FIG4_BALL, x0, n_points=4)


def test_batch_user_sections_agree_with_scalar_ones(x0):
    prob = tb.problem("reduced", FIG4_BALL)
    s = tb.poincare_section(prob, x0, n_points=5, options=tb.SectionOptions(event="gamma3"))
    b = tb.poincare_sections(prob, [x0, x0], n_points=5, batch=True, options=tb.SectionOptions(event="gamma3"))
    for r in b:
        assert _rel(r.times, s.times) < TOL and _rel(r.states, s.states) < TOL


def test_t_max_is_a_deprecated_alias_of_t_end(x0):
    with pytest.warns(DeprecationWarning, match="use t_end"):
        a = tb.poincare_section("reduced", FIG4_BALL, x0, n_points=50, t_max=10.0)
    b = tb.poincare_section("reduced", FIG4_BALL, x0, n_points=50, t_end=10.0)
    assert np.array_equal(a.times, b.times) and a.outcome is tb.Outcome.T_MAX
    with pytest.warns(DeprecationWarning, match="use t_end"):
        tb.poincare_sections("reduced", FIG4_BALL, [x0], n_points=1, t_max=10.0, workers=1)
    with pytest.raises(tb.UsageError, match="pass only t_end"):
        tb.poincare_section("reduced", FIG4_BALL, x0, n_points=5, t_end=1.0, t_max=1.0)


def test_on_chunk_sees_the_run_without_changing_it(x0):
    prob = tb.problem("reduced", FIG4_BALL)
    seen = []
    sec = tb.Section(prob, event="gamma3", chart=("R1", "R2"))
    r = sec.run(x0, n_points=40, chunk=5.0, on_chunk=lambda t, p, s: seen.append((t, p, s)))
    assert len(seen) > 1
    assert np.array_equal(np.concatenate([t for t, _, _ in seen]), r.times)
    assert np.array_equal(np.concatenate([p for _, p, _ in seen]), r.points)
    assert np.array_equal(np.concatenate([s for _, _, s in seen]), r.states)
    assert np.array_equal(sec.run(x0, n_points=40, chunk=5.0).points, r.points)

    class Stop(Exception):
        pass

    def stop(t, p, s):
        raise Stop

    with pytest.raises(Stop):
        sec.run(x0, n_points=40, chunk=5.0, on_chunk=stop)
    with pytest.raises(tb.UsageError, match="on_chunk must be a callable"):
        sec.run(x0, n_points=4, on_chunk=3)
