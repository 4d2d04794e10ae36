"""The section's crossings without its event (``sections_method = "samples"``): the
interpolant's count on constructed curves against their closed-form crossings, the study
runner's records against the event method's on the Fig. 4a level, the re-integration
path, resume and extension, stores and fingerprints, bad input."""

import math

import numpy as np
import pytest

import taylorball as tb
from taylorball import _angle_lift, _section_samples
from taylorball._section_samples import SectionSamplesError, classify
from taylorball.errors import StoreError, UsageError
from taylorball.observables import Sections, build_observables
from taylorball.store import RunStore, unpack_carry
from tests.test_study import assert_same_store, store_content, write_study

EPS = np.finfo(float).eps


# ---------------------------------------------------------------------------------------
# the interpolant's count on curves with known crossings
# ---------------------------------------------------------------------------------------
def _angle_jets(theta, dtheta, ddtheta):
    """``e = sin(theta)``, ``b = cos(theta)`` and two exact time derivatives, for an angle
    ``theta(t)`` given with its derivatives: the section of ``theta = 0 mod 2 pi`` (``e``
    upwards, ``b > 0``), as the paper's ``e``, ``b`` are for ``g = g0``."""
    s, c = np.sin(theta), np.cos(theta)
    return np.array([s, c, c * dtheta, -s * dtheta, -s * dtheta ** 2 + c * ddtheta,
                     -c * dtheta ** 2 - s * ddtheta])


@pytest.mark.parametrize("rate,accel", [(1.0, 0.0), (7.0, 0.0), (-5.0, 0.0), (3.0, 0.1), (1.0, -0.05)])
def test_counts_on_a_turning_angle_equal_the_closed_form(rate, accel):
    """``theta = rate t + accel t^2 / 2 + 0.3``: the upward crossings of ``e = sin theta``
    with ``b = cos theta > 0`` are the ``theta = 2 pi k`` passed while ``theta`` increases
    (exact, from ``theta`` at the interval's ends and its turning point). Every interval the
    interpolant decides has that count; for these smooth curves at most a few are left to
    the re-integration."""
    t = np.arange(0, 161) * 0.25
    th = rate * t + 0.5 * accel * t ** 2 + 0.3
    J = _angle_jets(th, rate + accel * t, np.full_like(t, accel))
    count, stats = classify(J, np.diff(t), np.zeros(t.size - 1, dtype=bool))
    ref = np.zeros(t.size - 1, dtype=np.int64)
    for j in range(t.size - 1):
        a, b = th[j], th[j + 1]
        ends = [a, b]
        if accel != 0:  # theta's turning point inside the interval
            tc = -rate / accel
            if t[j] < tc < t[j + 1]:
                ends = [a, rate * tc + 0.5 * accel * tc ** 2 + 0.3, b]
        for lo, hi in zip(ends[:-1], ends[1:]):
            if hi > lo:  # theta increasing: upward crossings of sin at 2 pi k in (lo, hi]
                ref[j] += math.floor(hi / (2 * math.pi)) - math.floor(lo / (2 * math.pi))
    decided = count >= 0
    np.testing.assert_array_equal(count[decided], ref[decided])
    assert stats["undecided"] == int(np.count_nonzero(~decided)) <= 4, stats
    assert ref.sum() > 0 or rate < 0


def test_a_grazing_pass_is_left_to_the_reintegration():
    """``e = (t - c)^2 - d^2`` with ``d = 1e-4``: two crossings 2e-4 apart inside one
    interval (down, then up), far below what the interpolant's margin can separate; the
    interval is not decided by the interpolant. With ``d = 0.05`` (crossings 0.1 apart)
    the pieces decide it: one upward crossing."""
    t = np.array([0.0, 0.25, 0.5, 0.75])
    c = 0.37
    for d, expect in ((1e-4, -1), (0.05, 1)):
        e = (t - c) ** 2 - d * d
        J = np.array([e, np.ones_like(t), 2 * (t - c), np.zeros_like(t), np.full_like(t, 2.0), np.zeros_like(t)])
        count, _ = classify(J, np.diff(t), np.zeros(3, dtype=bool))
        assert count[1] == expect, (d, count)


# ---------------------------------------------------------------------------------------
# through the runner, against the event method
# ---------------------------------------------------------------------------------------
def _pair(tmp_path, backend, every, t_end=500.0, ce=250.0, n=4):
    out = {}
    for method in ("events", "samples"):
        f = write_study(tmp_path / method, orbits={"n": n, "seed": 1},
                        run={"t_end": t_end, "checkpoint_every": ce, "backend": backend},
                        observables={"sections": every, "sections_method": method, "samples_every": None,
                                     "angles_every": 50.0})
        tb.run_study(f)
        out[method] = (tmp_path / method / "store", tb.open_run(tmp_path / method / "store", observable="sections"))
    return out


@pytest.mark.parametrize("backend,every", [("lanes", 1), ("lanes", 7), ("serial", 3)])
def test_samples_match_events_through_the_runner(tmp_path, backend, every):
    """Fig. 4a level, 4 orbits to 500: the section event is non-terminal and built from
    the state alone, so both runs integrate the same steps (the checkpoints are the same
    bits); the same crossings are recorded (same count per orbit, the same thinning), each
    from a new integration of its sample interval: its time and chart point differ from the
    event method's by the two integrations' rounding."""
    runs = _pair(tmp_path, backend, every)
    (sa, ea), (sb, eb) = runs["events"], runs["samples"]
    ca, cb = store_content(sa), store_content(sb)
    for i in ca:
        for key in ("state", "dtime", "n_steps", "t"):
            assert ca[i][0][key] == cb[i][0][key], (i, key)
        n_a = unpack_carry(RunStore(sa).orbit(i).checkpoint()["carries"]["sections"])["n"]
        n_b = unpack_carry(RunStore(sb).orbit(i).checkpoint()["carries"]["sections"])["n"]
        assert n_a == n_b  # every crossing on the branch counted, the same number
    ta, tb_ = ea.t.values, eb.t.values
    assert ta.shape == tb_.shape and ta.shape[1] > 20 and np.array_equal(np.isnan(ta), np.isnan(tb_))
    ok = ~np.isnan(ta)
    # each time is heyoka's root Newton-refined to rounding, relative to its own step's end:
    # within ~1 ulp of t of the crossing each, 4 eps |t| between the two (measured: 1 ulp)
    assert np.all(np.abs(ta[ok] - tb_[ok]) <= 4 * EPS * np.abs(ta[ok]))
    for v in ("l", "r1", "r2", "K"):
        x, y = ea[v].values[ok], eb[v].values[ok]
        # the state at each method's own crossing time: the two integrations' rounding over one
        # sample interval plus the times' difference (<= 1 ulp of t <= 500) times the variable's
        # rate; measured on these orbits to t = 1000 (2026-11-29): <= 23 eps of the variable's
        # scale (r1; l 2, K 11, r2 14). 64 eps of the scale
        scale = max(1.0, float(np.max(np.abs(x))))
        assert np.max(np.abs(x - y)) <= 64 * EPS * scale, v
    np.testing.assert_array_equal(ea.dEdK_sign.values[ok], eb.dEdK_sign.values[ok])


def test_every_interval_integrated_again_gives_the_same_records(tmp_path, monkeypatch):
    """With the margin made infinite no interval is decided by the interpolant: every one is
    integrated again from its sample with the section's event, and counted from that. A
    recorded crossing comes from the same re-integration of its interval either way, so the
    records are those of the ordinary samples run, to the bit; the carry counts every
    interval."""
    obs = {"sections": 5, "sections_method": "samples", "samples_every": None, "angles_every": 50.0}
    tb.run_study(write_study(tmp_path / "a", run={"t_end": 50.0}, observables=obs))
    monkeypatch.setattr(_angle_lift, "E_SAFETY", math.inf)
    tb.run_study(write_study(tmp_path / "b", run={"t_end": 50.0}, observables=obs))
    a, b = store_content(tmp_path / "a" / "store"), store_content(tmp_path / "b" / "store")
    for i in a:
        assert a[i][1] == b[i][1], i
    again = unpack_carry(RunStore(tmp_path / "b" / "store").orbit(0).checkpoint()["carries"]["sections"])["again"]
    assert int(again[0]) == 200  # 50 time units of 0.25


def test_a_reintegration_that_contradicts_the_interpolant_raises(tmp_path, monkeypatch):
    """If a recorded crossing's interval, integrated again, has another count than the
    interpolant certified, the run stops with an error naming the interval and the remedy."""
    real = _section_samples.classify

    def wrong(J, h, near_start):
        count, stats = real(J, h, near_start)
        count[count == 0] = 1  # claim a crossing in every interval without one
        return count, stats

    monkeypatch.setattr(_section_samples, "classify", wrong)
    f = write_study(tmp_path, orbits={"n": 1}, run={"t_end": 25.0},
                    observables={"sections": 1, "sections_method": "samples", "samples_every": None})
    with pytest.raises(SectionSamplesError, match=r"integrated again has 0 crossing\(s\).*sections_method = 'events'"):
        tb.run_study(f)


def test_samples_resume_and_extend_bit_identically(tmp_path):
    obs = {"sections": 3, "sections_method": "samples", "samples_every": None}
    short = write_study(tmp_path / "a", run={"t_end": 50.0}, observables=obs)
    tb.run_study(short)
    tb.run_study(short, extend=100.0)
    tb.run_study(write_study(tmp_path / "b", observables=obs))
    assert_same_store(tmp_path / "a" / "store", tmp_path / "b" / "store")


# ---------------------------------------------------------------------------------------
# stores, fingerprints, bad input
# ---------------------------------------------------------------------------------------
def test_the_event_method_keeps_the_old_options_and_fingerprint(tmp_path):
    """A study file without ``sections_method`` (every store made before the option) is the
    event method, with the options (and so the fingerprint) it always had."""
    (obj,) = [o for o in build_observables({"sections": 30}, 0.25) if isinstance(o, Sections)]
    assert obj.method == "events" and obj.options() == {"every": 30, "g0": 0.0, "direction": 1}
    assert obj.events_key() == ("sections", 0.0, 1) and not obj.uses_grid()
    old = tb.load_study(write_study(tmp_path, name="old.toml", observables={"sections": 30}))
    same = tb.load_study(write_study(tmp_path, name="same.toml",
                                     observables={"sections": 30, "sections_method": "events"}))
    new = tb.load_study(write_study(tmp_path, name="new.toml",
                                    observables={"sections": 30, "sections_method": "samples"}))
    assert old.fingerprint() == same.fingerprint() != new.fingerprint()


def test_a_store_refuses_the_other_method(tmp_path):
    tb.run_study(write_study(tmp_path, run={"t_end": 25.0}, observables={"sections": 3}))
    other = write_study(tmp_path, name="other.toml", run={"t_end": 25.0},
                        observables={"sections": 3, "sections_method": "samples"})
    with pytest.raises(StoreError, match="another study"):
        tb.run_study(other)


@pytest.mark.parametrize("bad", ["fast", "Samples", 1, True, ""])
def test_a_bad_method_is_refused_by_name(tmp_path, bad):
    f = write_study(tmp_path, observables={"sections": 3, "sections_method": bad})
    with pytest.raises(UsageError, match=r"observables\.sections_method must be one of 'events', 'samples'"):
        tb.load_study(f)
    assert not (tmp_path / "store").exists()
    with pytest.raises(UsageError, match="sections_method"):
        Sections(3, method=bad)


def test_long_double_runs_and_matches_events(tmp_path):
    """In long double the jets are evaluated in float64 from the rounded states (only the
    count depends on them) and an interval is integrated again from the long double state;
    the records (stored as float64) are the event method's crossings."""
    got = {}
    for method in ("events", "samples"):
        f = write_study(tmp_path / method, run={"t_end": 50.0, "fp_type": "longdouble"},
                        observables={"sections": 2, "sections_method": method, "samples_every": None})
        tb.run_study(f)
        got[method] = tb.open_run(tmp_path / method / "store", observable="sections")
    a, b = got["events"], got["samples"]
    assert a.t.shape == b.t.shape and a.t.shape[1] >= 10
    ok = ~np.isnan(a.t.values)
    # stored as float64: the long double crossings rounded to float64, 4 eps |t| and 64 eps of
    # the scale as in float64 (the long double integrations differ by less)
    assert np.all(np.abs(a.t.values[ok] - b.t.values[ok]) <= 4 * EPS * np.abs(a.t.values[ok]))
    assert np.max(np.abs(a.K.values[ok] - b.K.values[ok])) <= 64 * EPS * np.max(np.abs(a.K.values[ok]))
