"""A Problem stands in for ``(kind, params)`` in every public function that takes a system.

Each function called with a :class:`taylorball.Problem` (``params`` left out, the later
positional arguments moving one place left) gives the same bits as its string form; a
Problem given together with an option it fixes is refused with a message naming it.
"""

import numpy as np
import pytest

import taylorball as tb
from taylorball.errors import UsageError
from taylorball.paper import FIG4_BALL, FIG4B_LEVELS, demo_reduced_state

X0 = demo_reduced_state()
PROB = tb.problem("reduced", FIG4_BALL)


def test_propagate_and_make_integrator():
    ref = tb.propagate("reduced", FIG4_BALL, X0, [0.5, 1.0])
    for got in (tb.propagate(PROB, X0, [0.5, 1.0]), tb.propagate(PROB, X0, t=[0.5, 1.0]),
                tb.propagate(PROB, state=X0, t=[0.5, 1.0])):
        assert np.array_equal(got, ref)
    ta, system, spec = tb.make_integrator(PROB, X0)
    ta_ref, _, _ = tb.make_integrator("reduced", FIG4_BALL, X0)
    ta.propagate_until(1.0)
    ta_ref.propagate_until(1.0)
    assert np.array_equal(ta.state, ta_ref.state) and system is PROB.system and spec == PROB.spec


def test_integrals_family():
    for f in (tb.integrals, tb.integral_scales, tb.geometric_integrals, tb.density):
        assert f(PROB, X0) == f("reduced", FIG4_BALL, X0), f.__name__
    assert tb.integrals_mp(PROB, X0, dps=30) == tb.integrals_mp("reduced", FIG4_BALL, X0, dps=30)
    mp = tb.problem("mparallel", FIG4_BALL)  # the ball converted to its M||gamma parameters, as the string form does
    k0 = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 1.0])
    assert tb.integrals(mp, k0) == tb.integrals("mparallel", FIG4_BALL, k0)


def test_chaos_indicators_one_orbit():
    assert tb.megno(PROB, X0, 30.0) == tb.megno("reduced", FIG4_BALL, X0, 30.0)
    a, b = tb.lyapunov_spectrum(PROB, X0, 5.0), tb.lyapunov_spectrum("reduced", FIG4_BALL, X0, 5.0)
    assert np.array_equal(a.exponents, b.exponents) and a.problem == b.problem
    g, h = tb.gali(PROB, X0, 5.0, k=3), tb.gali("reduced", FIG4_BALL, X0, 5.0, k=3)
    assert np.array_equal(g.values, h.values)


def test_chaos_indicators_in_lanes():
    xs = [X0, X0]
    assert tb.megno_many(PROB, xs, 30.0, workers=1) == tb.megno_many("reduced", FIG4_BALL, xs, 30.0, workers=1)
    a = tb.lyapunov_spectra(PROB, xs, 3.0, workers=1)
    b = tb.lyapunov_spectra("reduced", FIG4_BALL, xs, 3.0, workers=1)
    assert all(np.array_equal(u.exponents, v.exponents) for u, v in zip(a, b))
    g = tb.gali_many(PROB, xs, 3.0, workers=1)
    h = tb.gali_many("reduced", FIG4_BALL, xs, 3.0, workers=1)
    assert all(np.array_equal(u.values, v.values) for u, v in zip(g, h))


def test_functions_of_the_reduced_system_take_a_reduced_problem():
    t = np.linspace(0.0, 2.0, 5)
    a, b = tb.contact_trajectory(PROB, X0, t), tb.contact_trajectory(FIG4_BALL, X0, t)
    assert np.array_equal(a.xy, b.xy)
    kw = dict(l=0.0, r1=(-4, 4, 3), r2=(-6, 6, 2), t_end=10.0, workers=1)
    m, n = tb.megno_map(PROB, FIG4B_LEVELS, **kw), tb.megno_map(FIG4_BALL, FIG4B_LEVELS, **kw)
    assert np.array_equal(m.values, n.values, equal_nan=True)
    from taylorball.paper import FIG4A_LEVELS

    c = tb.chaotic_fraction(PROB, FIG4A_LEVELS, n=2, t_end=20.0, workers=1)
    d = tb.chaotic_fraction(FIG4_BALL, FIG4A_LEVELS, n=2, t_end=20.0, workers=1)
    assert np.array_equal(c.mean_megno, d.mean_megno)


def test_conflicts_and_wrong_problems_are_named():
    with pytest.raises(UsageError, match=r"propagate got a Problem .* also params="):
        tb.propagate(PROB, FIG4_BALL, X0, 1.0)
    with pytest.raises(UsageError, match=r"megno got a Problem .* also fp_type="):
        tb.megno(PROB, X0, 10.0, fp_type=np.longdouble)
    with pytest.raises(UsageError, match=r"lyapunov_spectrum got a Problem .* also tol=1e-10"):
        tb.lyapunov_spectrum(PROB, X0, 1.0, tol=1e-10)
    with pytest.raises(UsageError, match=r"contact_trajectory got a Problem .* also prec=113"):
        tb.contact_trajectory(PROB, X0, [0.0, 1.0], prec=113)
    with pytest.raises(UsageError, match=r"propagate needs t"):
        tb.propagate(PROB, X0)
    with pytest.raises(UsageError, match=r"megno_many runs float64 batch integrators"):
        tb.megno_many(tb.problem("reduced", FIG4_BALL, fp_type=np.longdouble), [X0], 10.0)
    with pytest.raises(UsageError, match=r"megno_map works on the 'reduced' system"):
        tb.megno_map(tb.problem("full", FIG4_BALL), FIG4B_LEVELS, r1=(-4, 4, 3), r2=(-6, 6, 2), t_end=10.0)
