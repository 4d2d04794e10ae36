"""The Newton refinement of a float64 section's crossings, done after each propagation on
whole columns (taylorball._section_events._Collector, deferred) instead of in the event
callback: the crossing times are the callback's bit for bit, the states agree with the
callback's to the dense output's rounding, and both lie on the section to rounding, the
event function evaluated exactly (mpmath, 50 digits) at the returned states."""

import heyoka as hy
import mpmath
import numpy as np

import taylorball as tb
from taylorball._problem import problem
from taylorball._propagate import start_state
from taylorball.charts import section_event_function
from taylorball.paper import FIG4_BALL
from taylorball.sections import START_TOL, Section

EPS = np.finfo(float).eps


def _start():
    lev = dict(C=10.0, M_gamma=2.0, h=5.0)
    pts = tb.section_admissible_sample(FIG4_BALL, n=16, direction=1, seed=0, **lev)["points"]
    return tb.states_on_section(FIG4_BALL, point=tuple(pts[0]), direction=1, **lev)[0]


def _in_callback(sec, x0, t_end):
    """Crossings refined in the event callback (the collector the study runner uses): the
    section's event in a fresh integrator, propagated through the chunk ends of a section
    run (multiples of 100) to ``t_end``, the end of the step of the run's last crossing
    (so every step is the run's)."""
    prob = sec.problem
    system = prob.system
    ta = hy.taylor_adaptive(system.equations(), list(start_state(prob, x0)), pars=list(prob.pars),
                            nt_events=[sec.event(deferred=False)])
    for end in [100.0 * k for k in range(1, int(t_end // 100.0) + 1)] + [t_end]:
        ta.propagate_until(end)
    cb = ta.nt_events[0].callback
    keep = sec.on_branch(cb.states) & (np.array(cb.times) > START_TOL)
    return np.array(cb.times)[keep], np.array(cb.states)[keep]


def test_deferred_refinement_keeps_the_times_and_the_states_to_rounding():
    x0 = _start()
    prob = problem("reduced", FIG4_BALL)
    sec = Section(prob, 0.0, 1)
    r = sec.run(x0, n_points=300)
    assert r.ok
    t_cb, X_cb = _in_callback(sec, x0, r.t_end)
    assert len(t_cb) == 300
    # the same time bit for bit: the same Newton step from the same e, de/dt
    assert np.array_equal(r.times, t_cb)
    X = np.array([prob.system.to_internal(tuple(prob.pars), tuple(s)) for s in r.states])
    Xpub_cb = np.array([prob.system.to_public(tuple(prob.pars), tuple(x)) for x in X_cb])
    # the state: x - delta f(x) here, the dense output at the refined time there; both are
    # the dense output to O(delta^2) ~ 1e-26, so they differ by the dense output's own
    # rounding (a Taylor polynomial of order 20 evaluated in float64): measured <= 19 eps of
    # the state's largest component over 2000 crossings (mean 0.2); 64 eps leaves ~3x
    scale = np.max(np.abs(X_cb), axis=1, keepdims=True)
    d = np.abs(X - X_cb) / (EPS * scale)
    assert d.max() <= 64, d.max()
    # the public states are the same conversion of the two
    assert np.max(np.abs(r.states - Xpub_cb) / (EPS * np.max(np.abs(Xpub_cb), axis=1, keepdims=True))) <= 256


def test_refined_states_lie_on_the_section_evaluated_exactly():
    """The event function at the crossings' internal states, evaluated in mpmath at 50
    digits (exact for the float64 inputs): the deferred states are as close to the section
    as the callback's, closer in the median (the first-order step from the recorded state
    lands on the section to O(delta^2), the callback's second dense output evaluation adds
    its rounding)."""
    from taylorball.ensemble import run_many
    from taylorball.sections import _Run, _SectionJob

    x0 = _start()
    prob = problem("reduced", FIG4_BALL)
    sec = Section(prob, 0.0, 1)
    got = []
    run_many([_SectionJob(sec, x0, _Run(120, None, 100.0, lambda ts, xs: got.extend(xs)))], backend="serial")
    X = np.array(got)
    _, X_cb = _in_callback(sec, x0, sec.run(x0, n_points=120).t_end)
    assert X.shape == X_cb.shape == (120, 9)

    def exact(rows):
        with mpmath.workdps(50):
            return np.array([abs(float(section_event_function(tuple(mpmath.mpf(float(v)) for v in x[0:3]),
                                                              tuple(mpmath.mpf(float(v)) for v in x[3:6]), 0.0)))
                             for x in rows])

    e_def, e_cb = exact(X), exact(X_cb)
    print(f"|e| exact: deferred max {e_def.max():.2e} median {np.median(e_def):.2e}; "
          f"callback max {e_cb.max():.2e} median {np.median(e_cb):.2e}")
    # |e| <= 1 by construction and O(1) gradient: a state off by k eps is off the section
    # by ~k eps; measured max MAXDEF (deferred) and MAXCB (callback)
    assert e_def.max() <= 4 * EPS and e_cb.max() <= 4 * EPS
    assert np.median(e_def) <= np.median(e_cb)


def test_root_by_root_and_column_refinement_give_the_same_bits(monkeypatch):
    """A deferred collector refines a few roots one by one and many on whole columns: the
    same operations on each root, so forcing either way gives the same run."""
    from taylorball import _section_events

    x0 = _start()
    runs = []
    for few in (0, 10**9):
        monkeypatch.setattr(_section_events, "_FEW_ROOTS", few)
        runs.append(tb.poincare_section("reduced", FIG4_BALL, x0, n_points=150))
    a, b = runs
    for k in ("times", "states", "points", "residuals"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
