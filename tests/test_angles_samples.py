"""The lifted angle without an event (``angles_method = "samples"``): the interpolant's
winding on constructed curves against an independent fine unwrap, the study runner's
records against the event method's on the Fig. 4a and 4b levels, the re-integration path,
stores and fingerprints, bad input."""

import math

import numpy as np
import pytest

import taylorball as tb
from taylorball import _angle_lift
from taylorball._angle_lift import angle_increments, count_changes, hermite_coefficients
from taylorball._orbit_reductions import _hermite5
from taylorball.errors import StoreError, UsageError
from taylorball.observables import LiftedAngle, build_observables
from tests.test_study import assert_same_store, store_content, write_study

EPS = np.finfo(float).eps


def test_hermite_coefficients_are_the_hermite5_polynomial():
    rng = np.random.default_rng(3)
    v = rng.normal(size=(6, 50))
    h = 0.25
    a = hermite_coefficients(*v, h)
    for s in (0.0, 0.1, 0.37, 0.5, 0.9, 1.0):
        ref = _hermite5(*v, h, s)
        mine = sum(a[k] * s ** k for k in range(6))
        # a sum of six terms with factors up to 15 of values O(1): 64 eps of the terms' size
        assert np.max(np.abs(mine - ref)) <= 64 * EPS * np.max(np.abs(v)) * 15


def _circle_jets(t, centre, omega, radius=1.0):
    """``(x1, x2) = centre + radius (sin w t, -cos w t)`` and two exact derivatives."""
    s, c = np.sin(omega * t), np.cos(omega * t)
    return np.array([centre[0] + radius * s, centre[1] - radius * c, radius * omega * c, radius * omega * s,
                     -radius * omega ** 2 * s, radius * omega ** 2 * c])


def _fine_unwrap(t0, t1, centre, omega, n=200_001):
    """Independent reference: the continuous angle change of the exact curve by numpy's
    unwrap on a grid fine enough that no step exceeds pi/2 (checked)."""
    tt = np.linspace(t0, t1, n)
    J = _circle_jets(tt, centre, omega)
    th = np.arctan2(J[0], J[1])
    assert np.max(np.abs(np.angle(np.exp(1j * np.diff(th))))) < math.pi / 2
    u = np.unwrap(th)
    return u[-1] - u[0]


def test_a_curve_winding_fast_inside_one_interval():
    """A circle about the origin turning by 4 rad per sample interval (more than pi:
    unwrapping the samples is wrong on every interval) is counted right, and the cut
    crossings follow; the reference is the exact curve's fine unwrap."""
    t = np.arange(9) * 0.25
    J = _circle_jets(t, (0.0, 0.0), 16.0)
    d, stats = angle_increments(J, np.diff(t))
    ref = np.array([_fine_unwrap(t[j], t[j + 1], (0.0, 0.0), 16.0) for j in range(8)])
    assert stats["undecided"] == 0 and stats["pieces"] == 8  # every interval needed pieces
    # the angle change of the interpolant equals the curve's (same ends, homotopic): only
    # the rounding of the samples' atan2 and of the wrapped sums, 64 eps of 2 pi
    np.testing.assert_allclose(d, ref, rtol=0, atol=64 * EPS * 2 * math.pi)
    a = np.mod(np.arctan2(J[0], J[1]), 2 * math.pi)
    naive = np.angle(np.exp(1j * np.diff(a)))
    assert np.all(np.abs(naive - ref) > 1.0)  # the samples alone would lose a turn each interval
    d0, dpi = count_changes(d, a)
    # the lift a + 2 pi n0 is the continuous angle (exact integers from the increments)
    lifted = a + 2 * math.pi * np.concatenate([[0], np.cumsum(d0)])
    np.testing.assert_allclose(np.diff(lifted), ref, rtol=0, atol=64 * EPS * 40)
    liftpi = np.where(a >= math.pi, a - 2 * math.pi, a) + 2 * math.pi * np.concatenate([[0], np.cumsum(dpi)])
    np.testing.assert_allclose(np.diff(liftpi), ref, rtol=0, atol=64 * EPS * 40)


@pytest.mark.parametrize("gap", [1e-3, -1e-3, 1e-6, -1e-6])
def test_a_pass_near_the_origin_on_either_side(gap):
    """A unit circle whose lowest point passes ``gap`` above (or below: around) the origin
    inside a sample interval: the angle turns by about pi (above: x2 > 0) or by about -pi
    (below) within ~gap time units. Decided and right, against the fine unwrap."""
    t = np.array([-0.3, -0.05, 0.2, 0.45])
    centre = (0.0, 1.0 + gap)
    J = _circle_jets(t, centre, 1.0)
    d, stats = angle_increments(J, np.diff(t))
    assert stats["undecided"] == 0
    ref = np.array([_fine_unwrap(t[j], t[j + 1], centre, 1.0, n=2_000_001) for j in range(3)])
    np.testing.assert_allclose(d, ref, rtol=0, atol=64 * EPS * 2 * math.pi)
    assert abs(abs(d[1]) - math.pi) < 0.3 and np.sign(d[1]) == np.sign(gap)


def test_a_pass_within_the_margin_is_left_undecided():
    """The same circle passing 1e-13 from the origin: below the margin (interpolation error
    estimate and rounding), the interval is not decided by the interpolant (the runner
    integrates it again with the cut event)."""
    t = np.array([-0.3, -0.05, 0.2, 0.45])
    J = _circle_jets(t, (0.0, 1.0 + 1e-13), 1.0)
    d, stats = angle_increments(J, np.diff(t))
    assert stats["undecided"] == 1 and np.isnan(d[1]) and np.all(np.isfinite(d[[0, 2]]))


# ---------------------------------------------------------------------------------------
# through the runner, against the event method
# ---------------------------------------------------------------------------------------
def _pair(tmp_path, backend, H, t_end, ce, n=4, every=0.25):
    out = {}
    for method in ("events", "samples"):
        f = write_study(tmp_path / method, orbits={"n": n, "seed": 1}, level={"H": H},
                        run={"t_end": t_end, "checkpoint_every": ce, "backend": backend},
                        observables={"angles_every": every, "angles_method": method, "samples_every": None})
        tb.run_study(f)
        out[method] = (tmp_path / method / "store", tb.open_run(tmp_path / method / "store", observable="angles"))
    return out


@pytest.mark.parametrize("backend,H", [("lanes", 2.0), ("lanes", 6.0), ("serial", 2.0)])
def test_samples_equal_events_through_the_runner(tmp_path, backend, H):
    """Fig. 4a (H = 2) and 4b (H = 6) levels, 4 orbits: the event on x1 = 0 is non-terminal
    and built from a state variable alone, so the two runs integrate the same steps (the
    checkpoints' states and times are the same bits, checked); the lifted angles, counted
    by heyoka's event in one and by the interpolant in the other, are then the same numbers.
    The runs include intervals where l turns by more than pi/2 in one sample step (near
    M || e3)."""
    runs = _pair(tmp_path, backend, H, t_end=600.0, ce=200.0)
    (sa, ea), (sb, eb) = runs["events"], runs["samples"]
    ca, cb = store_content(sa), store_content(sb)
    for i in ca:
        for key in ("state", "dtime", "n_steps", "t"):
            assert ca[i][0][key] == cb[i][0][key], (i, key)
    la, lb = ea.l.values, eb.l.values
    assert la.shape == (4, 2401)
    np.testing.assert_array_equal(la, lb)
    fast = np.abs(np.diff(lb, axis=1)) > math.pi / 2
    assert fast.sum() > 0
    assert np.all(eb.fallback.values >= 0) and eb.fallback.values[:, 0].sum() == 0
    print(f"H={H} {backend}: intervals integrated again per orbit {eb.fallback.values.sum(axis=1)}; "
          f"sample steps of l above pi/2: {int(fast.sum())}")


def test_every_interval_integrated_again_equals_events(tmp_path, monkeypatch):
    """With the margin made infinite no interval passes the disk test: every one is
    integrated again from its sample with the cut event (the fallback path), and the lifted
    angle is still the event method's, to the bit."""
    monkeypatch.setattr(_angle_lift, "E_SAFETY", math.inf)
    runs = _pair(tmp_path, "serial", 2.0, t_end=40.0, ce=20.0, n=2)
    np.testing.assert_array_equal(runs["events"][1].l.values, runs["samples"][1].l.values)
    fb = runs["samples"][1].fallback.values
    assert fb[:, 0] == pytest.approx(0) and np.all(fb[:, 1:] == 1)  # one interval per record of 0.25


def test_samples_resume_and_extend_bit_identically(tmp_path):
    obs = {"angles_method": "samples", "angles_every": 1.25}  # records every 5 intervals, chunks of 25 t.u.
    short = write_study(tmp_path / "a", run={"t_end": 50.0}, observables=obs)
    tb.run_study(short)
    tb.run_study(short, extend=100.0)
    tb.run_study(write_study(tmp_path / "b", observables=obs))
    assert_same_store(tmp_path / "a" / "store", tmp_path / "b" / "store")


def test_angles_every_not_a_multiple_of_the_chunk_carries_the_fallback_count(tmp_path, monkeypatch):
    """Records every 15 time units, chunks of 25: the intervals integrated again after a
    chunk's last record are counted in the next chunk's first record (carry ``pending``);
    with every interval integrated again each record counts the intervals since the
    previous one (60 = 15 / 0.25)."""
    monkeypatch.setattr(_angle_lift, "E_SAFETY", math.inf)
    f = write_study(tmp_path, orbits={"n": 1}, run={"t_end": 75.0},
                    observables={"angles_method": "samples", "angles_every": 15.0, "samples_every": None})
    tb.run_study(f)
    fb = tb.open_run(tmp_path / "store", observable="angles").fallback.values[0]
    assert list(fb) == [0, 60, 60, 60, 60, 60]


# ---------------------------------------------------------------------------------------
# stores, fingerprints, bad input
# ---------------------------------------------------------------------------------------
def test_the_event_method_keeps_the_old_options_and_fingerprint(tmp_path):
    """A study file without ``angles_method`` (every store made before the option) is the
    event method, with the options (and so the fingerprint) it always had."""
    (obj,) = [o for o in build_observables({}, 0.25) if isinstance(o, LiftedAngle)]
    assert obj.method == "events" and obj.options() == {"every": 50.0}
    old = tb.load_study(write_study(tmp_path, name="old.toml"))
    same = tb.load_study(write_study(tmp_path, name="same.toml", observables={"angles_method": "events"}))
    new = tb.load_study(write_study(tmp_path, name="new.toml", observables={"angles_method": "samples"}))
    assert old.fingerprint() == same.fingerprint() != new.fingerprint()


@pytest.mark.parametrize("first,second", [("events", "samples"), ("samples", "events")])
def test_a_store_refuses_the_other_method(tmp_path, first, second):
    tb.run_study(write_study(tmp_path, run={"t_end": 25.0}, observables={"angles_method": first}))
    other = write_study(tmp_path, name="other.toml", run={"t_end": 25.0}, observables={"angles_method": second})
    with pytest.raises(StoreError, match="another study"):
        tb.run_study(other)
    with pytest.raises(StoreError, match="another study"):
        tb.run_study(other, extend=50.0)


@pytest.mark.parametrize("bad", ["fast", "Samples", 1, True, ""])
def test_a_bad_method_is_refused_by_name(tmp_path, bad):
    f = write_study(tmp_path, observables={"angles_method": bad})
    with pytest.raises(UsageError, match=r"observables\.angles_method must be one of 'events', 'samples'"):
        tb.load_study(f)
    assert not (tmp_path / "store").exists()
    with pytest.raises(UsageError, match="angles_method"):
        LiftedAngle(50.0, 200, method=bad)


def test_reexpansion_on_a_piece():
    """``reexpand``: the coefficients of ``p(lo + w u)`` evaluate to ``p`` there (random
    quintics, against direct evaluation)."""
    rng = np.random.default_rng(1)
    a = rng.normal(size=(6, 2, 40))
    lo, w = rng.uniform(size=40), rng.uniform(size=40) * 0.3
    c = _angle_lift.reexpand(a, lo, w)
    for u in (0.0, 0.3, 1.0):
        p = sum(a[k] * (lo + w * u) ** k for k in range(6))
        q = sum(c[k] * u ** k for k in range(6))
        # |a| ~ 1, |lo + w u| <= 1.3: sums of ~30 terms of size up to 10 * 1.3^5: 256 eps of that
        assert np.max(np.abs(p - q)) <= 256 * EPS * 40


def test_long_double_runs_and_its_reintegration(tmp_path, monkeypatch):
    """In long double the jets are evaluated in float64 from the rounded states (only the
    count depends on them) and an interval integrated again starts from the long double
    state: the records equal the event method's, with and without every interval
    integrated again."""
    runs = {}
    for label, safety in (("events", None), ("samples", 16.0), ("again", math.inf)):
        monkeypatch.setattr(_angle_lift, "E_SAFETY", 16.0 if safety is None else safety)
        f = write_study(tmp_path / label, run={"t_end": 20.0, "checkpoint_every": 10.0, "fp_type": "longdouble"},
                        observables={"angles_every": 0.25, "angles_method": "events" if safety is None else "samples",
                                     "samples_every": None})
        tb.run_study(f)
        runs[label] = tb.open_run(tmp_path / label / "store", observable="angles")
    np.testing.assert_array_equal(runs["events"].l.values, runs["samples"].l.values)
    np.testing.assert_array_equal(runs["events"].l.values, runs["again"].l.values)
    assert int(runs["again"].fallback.values.sum()) == 2 * 80  # 2 orbits, every interval of 20 time units
