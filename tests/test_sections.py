"""Poincaré sections by event detection: crossings on the section, in the right direction,
accurate against a quadruple-precision reference, reproducible across threads."""

import math

import heyoka as hy
import numpy as np
import pytest

import taylorball as tb
from taylorball.charts import g_angle_parts
from taylorball.sections import _event_cfunc, poincare_section, poincare_sections

from .conftest import FIG5, SYMMETRIC, demo_reduced_state, nearby_reduced_states, run_script

EPS = 2.0**-52


def _mpar_state():
    s = demo_reduced_state()
    return np.concatenate([[0.5, -1.0, 2.0], s[3:6]])


def _g_of(kind, params, public):
    """Section angle g of public states, from the paper's atan2 formula (independent of the
    event function): reduced uses M = Itilde omega - m a Omega R, mparallel uses K."""
    out = []
    for s in np.asarray(public, dtype=float):
        if kind == "reduced":
            c = tb.get_system("reduced").constants(params.pars)
            K = np.array(tb.model.K_from_omega(c.I, c.d, tuple(s[3:6]), tuple(s[0:3])))
            M = K - params.mass * params.radius * params.plane_rate * s[6:9]
        else:
            M = s[0:3]
        g = s[3:6]
        C = np.linalg.norm(M)
        out.append(math.atan2(C * (M[1] * g[0] - M[0] * g[1]), (M @ g) * M[2] - C * C * g[2]))
    return np.mod(np.array(out), 2 * math.pi)


@pytest.mark.parametrize("kind, params, state", [("reduced", FIG5, demo_reduced_state()),
                                                 ("mparallel", FIG5.to_mparallel(), _mpar_state())])
@pytest.mark.parametrize("g0", [0.0, 1.0, 4.0])
def test_crossings_lie_on_the_section(kind, params, state, g0):
    r = poincare_section(kind, params, state, n_points=60, g0=g0)
    assert r.ok and len(r) == 60 and r.outcome == "n_points"
    # after the Newton refinement the event function is rounding-size: |e| <= 1, and its
    # evaluation from ~10 roundings of O(1) quantities; 8 eps leaves a factor ~2 margin
    assert np.max(np.abs(r.residuals)) <= 8 * EPS, np.max(np.abs(r.residuals))
    g = _g_of(kind, params, r.states)
    dg = np.angle(np.exp(1j * (g - g0)))  # difference mod 2 pi, in (-pi, pi]
    # g from public states (omega -> M conversion, ~1e-15 relative) vs g0
    assert np.max(np.abs(dg)) <= 1e-12, np.max(np.abs(dg))
    assert np.all(np.diff(r.times) > 0)


@pytest.mark.parametrize("direction", [1, -1])
def test_direction_selects_sign_of_g_dot(direction):
    r = poincare_section("reduced", FIG5, demo_reduced_state(), n_points=40, direction=direction)
    f = _event_cfunc("reduced", (float, None), 0.0)
    pars = np.array(FIG5.pars)
    from taylorball.model import get_system

    system = get_system("reduced")
    for s in r.states:
        internal = np.array(system.to_internal(tuple(pars), tuple(s)))
        e, de = f(internal, pars)
        assert np.sign(de) == direction
        num, den = g_angle_parts(tuple(internal[0:3]), tuple(internal[3:6]))
        assert den > 0  # on the half-line g = 0, not g = pi


def test_both_directions_interleave():
    both = poincare_section("reduced", FIG5, demo_reduced_state(), n_points=40, direction=0)
    up = poincare_section("reduced", FIG5, demo_reduced_state(), n_points=20, direction=1)
    assert set(np.round(up.times, 9)) <= set(np.round(both.times, 9))


def test_points_match_real128_reference():
    """First 25 crossings: float64 points vs real128, to eps x the orbit's error growth.

    The growth G_i at crossing i is measured independently of the section code: the
    relative difference |x64(t_i) - x128(t_i)| / (eps |x64(t_i)|) of plain propagation to
    the crossing times (80 .. 2300 here: the flow amplifies rounding). Points are smooth
    functions of the state (plus a crossing-time shift), so their error is ~ eps G_i times
    their size; measured: at most 1.8 eps G_i |p|, and k = 16 leaves margin."""
    s = demo_reduced_state()
    a = poincare_section("reduced", FIG5, s, n_points=25)
    b = poincare_section("reduced", FIG5, s, n_points=25, fp_type=hy.real128)
    assert np.max(np.abs(b.residuals)) <= 8 * 2.0**-112
    x64 = tb.propagate("reduced", FIG5, s, a.times)
    x128 = tb.propagate("reduced", FIG5, s, a.times, fp_type=hy.real128).astype(float)
    G = np.maximum(np.max(np.abs(x64 - x128), axis=1) / (EPS * np.max(np.abs(x64), axis=1)), 1.0)
    scale = np.max(np.abs(b.points), axis=0)
    err = np.abs(a.points - b.points)
    ratio = np.max(err / (EPS * G[:, None] * scale[None, :]))
    print(f"float64 vs real128 section points: max err {np.max(err, axis=0)}, max err/(eps G |p|) = {ratio:.2f}")
    assert ratio <= 16
    assert np.all(np.abs(a.times - b.times) <= 16 * EPS * G * a.times)


def test_first_crossings_independent_of_n_points():
    s = demo_reduced_state()
    a = poincare_section("reduced", FIG5, s, n_points=50)
    b = poincare_section("reduced", FIG5, s, n_points=120)
    assert np.array_equal(a.points, b.points[:50])
    assert np.array_equal(a.times, b.times[:50])


def test_threads_are_bit_identical_to_serial():
    rng = np.random.default_rng(5)
    states = []
    for _ in range(4):
        s = demo_reduced_state()
        s[0:3] += 0.05 * rng.normal(size=3)
        states.append(s)
    serial = poincare_sections("reduced", SYMMETRIC, states, n_points=30, workers=1)
    threaded = poincare_sections("reduced", SYMMETRIC, states, n_points=30, workers=2)
    for a, b in zip(serial, threaded):
        assert np.array_equal(a.points, b.points) and np.array_equal(a.states, b.states)
    one = poincare_section("reduced", SYMMETRIC, states[2], n_points=30)
    assert np.array_equal(one.points, serial[2].points)


def test_t_max_outcome_says_what_to_do():
    r = poincare_section("reduced", FIG5, demo_reduced_state(), n_points=1000, t_end=20.0)
    assert r.outcome == "t_max" and not r.ok
    assert "increase t_end" in r.message
    assert 0 < len(r) < 1000 and r.t_end == pytest.approx(20.0)


def test_result_carries_evidence():
    r = poincare_section("reduced", FIG5, demo_reduced_state(), n_points=30)
    assert r.points.shape == (30, 3) and r.states.shape == (30, 9) and r.residuals.shape == (30,)
    assert set(r.integrals) == {"C2", "M_gamma", "E", "gamma2", "R_gamma"}
    assert all(v <= 1e-13 for v in r.drift.values()), r.drift
    assert set(r.levels) == {"C", "M_gamma", "h"}
    assert r.meta["fp_type"] == "float" and r.meta["heyoka"] == hy.__version__
    assert np.all((0 <= r.points[:, 0]) & (r.points[:, 0] < 2 * math.pi))
    m = poincare_section("mparallel", FIG5, _mpar_state(), n_points=10)
    assert m.points.shape == (10, 2) and np.all(np.abs(m.points[:, 1]) <= 1)


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        (dict(kind="full"), "kind must be one of"),
        (dict(n_points=0), "n_points must be a positive integer"),
        (dict(g0=7.0), "g0 must be a float in"),
        (dict(direction=2), "direction must be"),
        (dict(t_end=-1.0), "t_end must be > 0"),
    ],
)
def test_bad_arguments(kwargs, needle):
    base = dict(kind="reduced", n_points=5)
    base.update(kwargs)
    kind = base.pop("kind")
    state = demo_reduced_state() if kind != "full" else tb.reduced_to_full(FIG5, demo_reduced_state())
    with pytest.raises(tb.UsageError, match=needle):
        poincare_section(kind, FIG5, state, **base)


# --- batch mode (SIMD lanes; bit-identical across threads and groupings, not to scalar runs) ---


def _batch_states(n, seed=5):
    return nearby_reduced_states(n, seed)


def test_batch_bit_identical_across_threads_and_groupings():
    st = _batch_states(6)
    a = poincare_sections("reduced", FIG5, st, n_points=30, batch=True, workers=1)
    b = poincare_sections("reduced", FIG5, st, n_points=30, batch=True, workers=2)
    c = poincare_sections("reduced", FIG5, st[2:], n_points=30, batch=True, workers=2)  # other lane companions
    for x, y in zip(a, b):
        assert np.array_equal(x.points, y.points) and np.array_equal(x.times, y.times)
    for x, y in zip(a[2:], c):
        assert np.array_equal(x.points, y.points)


def test_batch_points_on_section_and_close_to_real128():
    st = _batch_states(2)
    r = poincare_sections("reduced", FIG5, st, n_points=10, batch=True)
    # Newton-refined residuals: rounding of an O(1) event function, as for scalar runs
    assert max(np.max(np.abs(x.residuals)) for x in r) <= 8 * EPS
    ref = poincare_section("reduced", FIG5, st[0], n_points=10, fp_type=hy.real128)
    sca = poincare_section("reduced", FIG5, st[0], n_points=10)
    # batch and scalar float64 are two roundings of the same orbit: the batch error must be
    # of the size of the scalar one (measured here: same order), not larger by orders
    eb = np.max(np.abs(r[0].points - ref.points))
    es = np.max(np.abs(sca.points - ref.points))
    assert eb <= 100 * max(es, EPS)


def test_batch_needs_float64():
    with pytest.raises(tb.UsageError, match="batch=True needs fp_type=float"):
        poincare_sections("reduced", FIG5, _batch_states(2), n_points=5, batch=True, fp_type=hy.real128)


def test_start_on_the_section_is_not_a_crossing():
    """A start built on the section (e = 0 to rounding) is never reported, whatever heyoka's
    root finder does at t ~ 1e-17: the points are the returns P(x0), P^2(x0), ..."""
    from taylorball.charts import section_admissible_sample, states_on_section

    pts = section_admissible_sample(FIG5, C=10.0, M_gamma=2.0, h=5.0, n=6, seed=4)["points"]
    starts = [states_on_section(FIG5, C=10.0, M_gamma=2.0, h=5.0, point=p, direction=1)[0] for p in pts]
    for r in poincare_sections("reduced", FIG5, starts, n_points=3) + poincare_sections(
            "reduced", FIG5, starts, n_points=3, batch=True):
        assert r.times[0] > 0.1, r.times  # a first return takes ~1 time unit here


SECTIONS_INTERRUPT = r"""
import os, signal, threading, time
import taylorball as tb
from tests.conftest import FIG5, demo_reduced_state
tb.poincare_sections("reduced", FIG5, [demo_reduced_state()], n_points=2)
threading.Timer(1.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
t0 = time.perf_counter()
try:
    tb.poincare_sections("reduced", FIG5, [demo_reduced_state()] * 8, n_points=10**6, workers=2)
except KeyboardInterrupt:
    print(f"interrupted after {time.perf_counter() - t0:.1f} s", flush=True)
"""


def test_ctrl_c_stops_a_threaded_section_run_promptly():
    """Ctrl-C during ``poincare_sections`` (threads, scalar): running orbits stop at their next
    chunk, queued ones are dropped, KeyboardInterrupt is re-raised within seconds (it used to
    wait for every orbit to finish) and the process exits normally."""
    import sys
    from pathlib import Path

    r = run_script([sys.executable, "-c", SECTIONS_INTERRUPT], timeout=300,
                       cwd=Path(__file__).resolve().parent.parent)
    assert r.returncode == 0 and "interrupted after" in r.stdout, (r.returncode, r.stdout, r.stderr)
    waited = float(r.stdout.split("interrupted after")[1].split()[0])
    # not a speed target: without the stop the run lasts hours (8 x 10^6 crossings); one chunk
    # of 100 time units takes ~0.01 s, so 60 s is only slack for a loaded machine
    assert waited < 60.0, r.stdout


def test_chart_points_refuses_a_kind_without_a_chart():
    """``chart_points`` of a system with no section chart (``"full"``) is a UsageError naming
    the valid kinds (it was a TypeError, calling the missing chart; found by mypy)."""
    from taylorball.sections import SECTION_KINDS, chart_points

    with pytest.raises(tb.UsageError, match=r"kind must be one of .*reduced.*mparallel.*got 'full'"):
        chart_points("full", np.zeros((1, 14)))
    assert set(SECTION_KINDS) == {"reduced", "mparallel"}
