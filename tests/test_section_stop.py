"""One ``poincare_section`` call stops at its last crossing and reuses integrator copies
, without changing a bit of what it returns.

The references are main's results before the change (commit 7bb9c84), pinned as hashes,
and runs of the same orbit that ask for more crossings (whose first crossings the
contract says are the same bits)."""

import copy
import hashlib
import threading

import heyoka as hy
import numpy as np
import pytest

import taylorball as tb
from taylorball._cache import working_copy
from taylorball._problem import problem
from taylorball._propagate import start_state
from taylorball.paper import FIG4_BALL
from taylorball.sections import Section

#: The first Fig. 4a orbit of benchmarks/bench_refactor.py and bench_section_call.py:
#: ``states_on_section(FIG4_BALL, C=10, M_gamma=2, h=5, direction=1, point=p)[0]`` with
#: ``p = section_admissible_sample(FIG4_BALL, n=16, direction=1, seed=0, C=10, M_gamma=2,
#: h=5)["points"][0]`` (the repr of those floats, so the test does not depend on the sampler).
X0 = np.array([3.3568058071497053, -5.244140975225709, 0.12591699591475092, 0.12552655716025565,
               -0.10514168532696051, -0.9865030711833084, 8.031006324798037, -13.818876887107375,
               2.494715578298574])
MPAR_X0 = np.concatenate([[0.5, -1.0, 2.0], X0[3:6]])


def _bytes(a):
    a = np.ascontiguousarray(a)
    if a.dtype == np.dtype(hy.real):  # the full decimal expansion (its bytes hold pointers)
        return "\n".join(repr(v) for v in a.reshape(-1)).encode()
    if a.dtype == np.longdouble and a.dtype.itemsize > 10:
        # x87 extended precision: 10 significant bytes, the rest is padding of undefined content
        return a.view(np.uint8).reshape(-1, a.dtype.itemsize)[:, :10].tobytes()
    return a.tobytes()


def _digest(r):
    h = hashlib.sha256()
    for a in (r.points, r.times, r.states, r.residuals, *(r.integrals[k] for k in sorted(r.integrals))):
        h.update(_bytes(a))
    return h.hexdigest()[:16]


# Made BEFORE the change, by this file's _digest on main at commit 7bb9c84 (the code that
# integrated every chunk to its end and copied the integrator template per call), run as
# ``PYTHONPATH=/work/main python pin.py`` with the same calls; each call was made twice in
# one process and gave the same hash both times (real128 and real: 6-14 s per call there,
# since main integrated the whole first chunk; 0.2-0.5 s now). Main's (t_end, n_steps) are kept for the
# record: a completed run now ends inside its last chunk.
PINNED = [
    # (kind, kwargs, n found, outcome, hash on main, main's t_end, main's n_steps)
    ("reduced", dict(n_points=120), 120, "n_points", "d460c12684420337", 200.0, 3287),
    ("reduced", dict(n_points=1), 1, "n_points", "3497dc29893d96a2", 100.0, 1525),
    ("reduced", dict(n_points=120, direction=0, g0=1.0), 120, "n_points", "cee2e1a4255304e4", 200.0, 3287),
    # long double: the pinned hash 7d0784447bbca706 held on the machines of 2026-11-25..27 but
    # not on the Intel Xeon (AVX-512) of 2026-11-28, with the same heyoka 7.13.2 and numpy
    # 2.4.6 and the same 1557 steps: x87 results of heyoka's compiled code depend on the CPU.
    # So no cross-machine hash: the run is checked against real128 instead (see the test).
    ("reduced", dict(n_points=40, fp_type=np.longdouble), 40, "n_points", None, 100.0, 1557),
    ("reduced", dict(n_points=300, t_end=250.0), 149, "t_max", "ce93a4cab82c405e", 250.0, 4063),
    ("reduced", dict(n_points=50, chunk=7.0), 50, "n_points", "19f1f7f2053bfa19", 98.0, 1520),
    ("mparallel", dict(n_points=30), 30, "n_points", "8fd1db07a4f9bc42", 300.0, 479),
    ("reduced", dict(n_points=3, fp_type=hy.real128), 3, "n_points", "e2c85c24a4495f53", 100.0, 1668),
    # 80-bit MPFR: ~5 s to compile (compact mode) under load, so with the slow tests
    pytest.param("reduced", dict(n_points=2, fp_type=hy.real, prec=80), 2, "n_points", "cf613eaeae245dba", 100.0,
                 1606, marks=pytest.mark.slow),
]


#: float64 runs since their Newton refinement moved from the event callback to one
#: evaluation on whole columns after each propagation (taylorball._section_events,
#: ``_Collector.refine``): main's hash above -> (the hash now, made after that change on the
#: Intel Xeon of 2026-11-28; the hash of the times alone, the same on main at a0d3432 and
#: now). The times keep their bits; the states (hence points, residuals, integrals) are the
#: first-order step ``x - delta f(x)`` instead of the dense output evaluated again, which
#: differ by the dense output's rounding (tests/test_sections_refine.py).
FLOAT64_SINCE = {
    "d460c12684420337": ("9d4de55e9aa1576f", "9567c8e572864cf4"),
    "3497dc29893d96a2": ("83470e1c0e206601", "76e89b92ad4eea54"),
    "cee2e1a4255304e4": ("f9f422b4d0aeabfa", "ca0d7555ef86ce40"),
    "ce93a4cab82c405e": ("96566c3634bef003", "7b4ddd9efb06601e"),
    "19f1f7f2053bfa19": ("6299fedba20dfbae", "d418be80c8d88fff"),
    "8fd1db07a4f9bc42": ("91c3d47e899a36f4", "286880f0ab987a4b"),
}


def _times_digest(r):
    return hashlib.sha256(_bytes(r.times)).hexdigest()[:16]


def _call(kind, kw):
    state, params = (X0, FIG4_BALL) if kind == "reduced" else (MPAR_X0, FIG4_BALL.to_mparallel())
    kw = dict(kw)
    moved = {k: kw.pop(k) for k in ("prec", "tol", "chunk") if k in kw}  # tb.SectionOptions' fields
    return tb.poincare_section(kind, params, state, options=tb.SectionOptions(**moved), **kw)


@pytest.mark.parametrize("kind, kw, n, outcome, pinned, main_t_end, main_steps", PINNED)
def test_bit_identical_to_main(kind, kw, n, outcome, pinned, main_t_end, main_steps):
    first = _call(kind, kw)
    again = _call(kind, kw)  # a reused integrator copy this time
    for r in (first, again):
        assert len(r) == n and r.outcome == outcome
        if pinned in FLOAT64_SINCE:
            now, times_on_main = FLOAT64_SINCE[pinned]
            assert _times_digest(r) == times_on_main
            assert _digest(r) == now
        else:
            assert _digest(r) == (_digest(first) if pinned is None else pinned)
        if outcome == "n_points":
            # stopped after the step of the last crossing: no later than main's chunk end,
            # fewer steps, and never before the crossing itself
            assert r.times[-1] <= r.t_end <= main_t_end and r.n_steps <= main_steps
        else:
            assert (r.t_end, r.n_steps) == (main_t_end, main_steps)
    assert (first.t_end, first.n_steps) == (again.t_end, again.n_steps)


@pytest.mark.parametrize("n", [1, 2, 7, 59, 60, 61, 120])
def test_prefix_of_a_longer_run(n):
    """The first n crossings of a run stopped at its n-th are those of a run asked for 50
    more (which goes on past the step where the shorter one stopped)."""
    a = _call("reduced", dict(n_points=n))
    b = _call("reduced", dict(n_points=n + 50))
    for x, y in ((a.points, b.points), (a.times, b.times), (a.states, b.states), (a.residuals, b.residuals)):
        assert np.array_equal(x, y[:n])
    assert a.t_end < b.times[n]  # the shorter run did stop before the next crossing


@pytest.mark.parametrize("n", [1, 120])
def test_stops_at_the_end_of_a_whole_step(n):
    """``t_end`` and ``n_steps`` of a completed run are those of heyoka's own steps: a copy
    of the same compiled integrator, propagated through the whole chunks before ``t_end``
    and then stepped one natural step (``ta.step()``, no time limit) at a time, lands
    exactly on ``t_end`` after ``n_steps`` steps in all; so the run stopped at the end of
    the step that brought its last crossing, not inside a step."""
    r = _call("reduced", dict(n_points=n))
    prob = problem("reduced", FIG4_BALL)
    ta = copy.copy(Section(prob, 0.0, 1).integrator())
    ta.state[:] = start_state(prob, X0)
    ta.pars[:] = prob.pars
    ta.time = 0.0
    steps = 0
    for k in range(1, int(r.t_end // 100.0) + 1):
        steps += int(ta.propagate_until(100.0 * k)[3])
    while float(ta.time) < r.t_end:
        assert ta.step()[0] == hy.taylor_outcome.success
        steps += 1
    assert float(ta.time) == r.t_end and steps == r.n_steps
    assert r.times[-1] <= r.t_end < r.times[-1] + ta.last_h + 1e-12


def test_threads_reuse_copies_bit_identically():
    """Threads borrowing reused integrator copies (in any order) give what a serial run and
    single calls give."""
    lev = dict(C=10.0, M_gamma=2.0, h=5.0)
    pts = tb.section_admissible_sample(FIG4_BALL, n=6, direction=1, seed=3, **lev)["points"]
    states = [tb.states_on_section(FIG4_BALL, point=tuple(p), direction=1, **lev)[0] for p in pts]
    serial = tb.poincare_sections("reduced", FIG4_BALL, states, n_points=25, workers=1)
    threaded = tb.poincare_sections("reduced", FIG4_BALL, states, n_points=25, workers=2)
    for i, s in enumerate(states):
        one = tb.poincare_section("reduced", FIG4_BALL, s, n_points=25)
        for r in (serial[i], threaded[i]):
            assert _digest(r) == _digest(one) and (r.t_end, r.n_steps) == (one.t_end, one.n_steps)


def test_interrupted_copy_is_not_reused():
    """A block that raises keeps its copy out of the pool (it may stop half-way through a
    step); a block that ends gives it back, and the next block gets it."""
    sec = Section(problem("reduced", FIG4_BALL), 0.0, 1)
    template = sec.integrator()
    with working_copy(template) as a:
        pass
    with working_copy(template) as b:
        assert b is a and b is not template
    with pytest.raises(RuntimeError):
        with working_copy(template) as c:
            assert c is a
            raise RuntimeError("stop")
    with working_copy(template) as d:
        assert d is not a


def test_copies_are_lent_to_one_block_at_a_time():
    template = Section(problem("reduced", FIG4_BALL), 0.0, 1).integrator()
    held, barrier = [], threading.Barrier(3)

    def borrow():
        with working_copy(template) as ta:
            held.append(ta)
            barrier.wait(timeout=20)  # all three blocks hold a copy at once

    threads = [threading.Thread(target=borrow) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=30)
    assert len({id(t) for t in held}) == 3


def test_the_template_is_never_lent():
    template = Section(problem("reduced", FIG4_BALL), 0.0, 1).integrator()
    before = (copy.copy(template.state), float(template.time))
    _call("reduced", dict(n_points=5))
    assert np.array_equal(template.state, before[0]) and float(template.time) == before[1]


def test_both_ways_of_ending_a_chunk_early_are_taken(monkeypatch):
    """On the 120-crossing run the first chunk drops its step callback after its first
    roots (it cannot bring 120 crossings: stopped, then propagated on without it) and the
    second stops at the last crossing; the results are the pinned ones above, so both
    paths keep the bits."""
    from taylorball import sections

    seen = []
    check = sections._Collector._check

    def spy(self):
        check(self)
        if self.paused or self.need <= 0:
            seen.append(("paused" if self.paused else "done", float(self.times[-1])))

    monkeypatch.setattr(sections._Collector, "_check", spy)
    r = _call("reduced", dict(n_points=120))
    assert _digest(r) == FLOAT64_SINCE[PINNED[0][4]][0]
    kinds = [k for k, _ in seen]
    assert kinds == ["paused", "done"], seen
    # the callback sees the recorded root; the refinement after the propagation moves it by
    # the Newton step, a few ulp of t (at most 64 ulp of |t| + |h| by construction)
    assert seen[0][1] < 100.0 < seen[1][1]
    assert abs(seen[1][1] - r.times[-1]) <= 128 * np.spacing(r.times[-1])


def test_long_double_agrees_with_real128():
    """The long-double row of PINNED has no cross-machine hash: its first crossings agree
    with a real128 run of the same orbit. Measured on 2026-11-28: 298, 391, 8.7e3 eps of
    long double at crossings 1, 5, 10 (a chaotic orbit: the difference grows with time), so
    1000 eps over the first five crossings is a 2.5x margin; a run that rounds through
    float64 anywhere (2048 eps of long double per rounding) fails."""
    ld = _call("reduced", dict(n_points=5, fp_type=np.longdouble))
    q = _call("reduced", dict(n_points=5, fp_type=hy.real128))
    ref = np.array([[np.longdouble(str(v)) for v in row] for row in q.points])
    err = np.abs(ld.points - ref) / np.maximum(1, np.abs(ref))
    assert float(err.max() / np.finfo(np.longdouble).eps) < 1000

