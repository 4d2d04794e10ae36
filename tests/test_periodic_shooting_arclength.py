"""Pseudo-arclength multiple shooting through a fold (taylorball.periodic_shooting_arclength)
and the stepping function shared by the continuations. The checks are independent of the
arclength code: the section integrator run afresh from each reported state, the level's
integrals evaluated on it, fresh fixed-level shooting solves from other guesses."""

import dataclasses

import numpy as np
import pytest

import taylorball as tb
from taylorball.errors import StateError, UsageError
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
from taylorball.periodic_catalog import FIG4A_SADDLE_K10
from taylorball.periodic_continuation import halving_step, toward
from taylorball.periodic_shooting import ShootingOptions, periodic_orbit_shooting, shoot_periodic_orbit
from taylorball.periodic_shooting_arclength import continue_shooting_arclength

EPS = np.finfo(float).eps

#: A saddle of the Fig. 4a saddle's family in H, 0.011 below its fold (H = 2.7456923, k =
#: 12): a start, taken from a pseudo-arclength run from FIG4A_SADDLE_K10 (2026-11-29).
NEAR_FOLD = [-1.600504268379789, 2.81670076907671, -3.591296012759447, 0.29293282865242726, -0.6897498424942606,
             -0.6621446312376401, -4.128224785267735, 7.431995659114177, -9.568166983566146]
#: its segments: the slow stretch near gamma = -e3 and the fast return after it are one
#: segment (the crossing between them sits near the chart's singular point M || e3, and a
#: branch that shoots to it stalls just past the fold)
KS12 = (1, 1, 1, 1, 5, 1, 1, 1)


def _points(state, k):
    sec = tb.poincare_section("reduced", FIG4_BALL, state, n_points=k - 1)
    return [np.asarray(state)] + [np.asarray(s) for s in sec.states]


def _shoot(points, ks, H):
    """A fixed-level shooting solve at ``M_gamma = H`` from the given section points (moved
    onto the section and the level first: ``section_tol = 1``)."""
    starts = np.concatenate([[0], np.cumsum(ks)[:-1]]).astype(int)
    return shoot_periodic_orbit("reduced", FIG4_BALL, [points[i] for i in starts], ks,
                                levels=dataclasses.replace(FIG4A_LEVELS, M_gamma=H), max_piece_time=1.0,
                                options=ShootingOptions(section_tol=1.0))


def _check_orbit(o, H):
    """Independent: the section integrator returns after k crossings, the level holds."""
    sec = tb.poincare_section("reduced", FIG4_BALL, o.state, n_points=o.k)
    scale = max(1.0, float(np.max(np.abs(o.state))))
    # the float64 integrator's error over ~25 time units (as test_periodic_shooting_family)
    assert float(np.max(np.abs(np.asarray(sec.states[-1]) - o.state))) <= 1e-12 * scale
    # M_gamma ~ 10 |M|: 64 eps of rounding in the projection onto the level, times 10
    assert abs(tb.integrals("reduced", FIG4_BALL, o.state)["M_gamma"] - H) <= 64 * EPS * 10
    # a product of ~25 pieces' maps (see test_periodic_shooting_family): 2^18 eps
    assert abs(np.prod(o.multipliers) - 1) <= 2.0**18 * EPS


@pytest.fixture(scope="module")
def saddle():
    e = FIG4A_SADDLE_K10
    return periodic_orbit_shooting(e.kind, e.ball, np.array(e.state), e.k, e.k, levels=e.levels, g0=e.g0)


def test_bad_input(saddle):
    go = continue_shooting_arclength
    with pytest.raises(UsageError, match="not 'Omega'"):
        go(saddle, FIG4A_LEVELS, "Omega", 2.1)
    with pytest.raises(UsageError, match="other than the start's M_gamma = 2.0"):
        go(saddle, FIG4A_LEVELS, "M_gamma", 2.0)
    with pytest.raises(UsageError, match=r"0 < ds_min <= ds <= ds_max, got ds_min=0.0001, ds=0.0"):
        go(saddle, FIG4A_LEVELS, "M_gamma", 2.1, ds=0.0)
    with pytest.raises(UsageError, match=r"0 < ds_min <= ds <= ds_max, got ds_min=-1"):
        go(saddle, FIG4A_LEVELS, "M_gamma", 2.1, ds_min=-1)
    with pytest.raises(UsageError, match="target is on the wrong side of a bound"):
        go(saddle, FIG4A_LEVELS, "M_gamma", 6.0, bounds=(1.0, 3.0))
    with pytest.raises(UsageError, match="direction must be None, 1 or -1"):
        go(saddle, FIG4A_LEVELS, "M_gamma", 2.1, direction=0)
    with pytest.raises(UsageError, match="adding up to the orbit's k = 10"):
        go(saddle, FIG4A_LEVELS, "M_gamma", 2.1, ks=(1, 2))
    with pytest.raises(UsageError, match="max_steps"):
        go(saddle, FIG4A_LEVELS, "M_gamma", 2.1, max_steps=0)
    with pytest.raises(UsageError, match="max_piece_time"):
        go(saddle, FIG4A_LEVELS, "M_gamma", 2.1, max_piece_time=-1.0)


def test_halving_step():
    """The shared stepping loop: a refused step is retried with half its used length until
    ``give_up``; the accepted proposal and its length are returned."""
    tried = []

    def attempt(w):
        tried.append(w)
        if w > 1.3:
            raise StateError("too far")
        return 2 * w

    out = halving_step(0.8, toward(1.0, 2.0), attempt, lambda n, h: h < 0.01)
    assert tried == [1.8, 1.4, 1.2] and out.result == 2.4 and out.halvings == 2 and out.failure is None
    assert out.value == 1.2 and abs(out.used - 0.2) <= 4 * EPS
    out = halving_step(0.8, toward(1.0, 2.0), attempt, lambda n, h: n >= 1)
    assert out.result is None and isinstance(out.failure, StateError) and out.value == 1.8
    # a step reaching the target lands on it exactly
    assert toward(1.0, 1.3)(0.5) == (1.3, abs(1.3 - 1.0)) and toward(1.0, 1.3, snap=False)(0.5)[0] == 1.3


def test_past_the_fold():
    """From a saddle 0.011 below the family's fold in H, upwards: the branch turns at the fold
    (H ~ 2.7567, where natural steps stopped: docs/skeleton.md) and comes back to H = 2.745 on
    the other branch, where the orbit is another saddle (middle multiplier below 1: a
    multiplier crossed +1 at the fold, a saddle-node). Both sides agree with fresh shooting
    solves at their level from other guesses. ~20 CPU s (measured 2026-11-29)."""
    H0 = tb.integrals("reduced", FIG4_BALL, NEAR_FOLD)["M_gamma"]
    start = _shoot(_points(NEAR_FOLD, 12), KS12, H0)
    lv = dataclasses.replace(FIG4A_LEVELS, M_gamma=H0)
    br = continue_shooting_arclength(start, lv, "M_gamma", 2.745, ks=KS12, max_piece_time=1.0, ds=0.2, ds_max=2.0,
                                     direction=1, max_steps=20)
    assert br.stopped == "reached" and br.values[-1] == 2.745
    folds = [ev for ev in br.events if ev["event"] == "fold"]
    assert len(folds) == 1
    # the fold where (mu - 1)^2 of the natural steps extrapolates to 0 (2.7567), to the
    # accuracy of one arclength step's quadratic model
    assert 2.7555 <= folds[0]["omega"] <= 2.758 and abs(folds[0]["multiplier"] - 1) < 0.2
    i_top = int(np.argmax(br.values))
    assert 0 < i_top < len(br.values) - 1 and np.all(np.diff(br.values[:i_top + 1]) > 0) \
        and np.all(np.diff(br.values[i_top:]) < 0)
    upper = br.orbits[-1]
    _check_orbit(upper, 2.745)
    mid = lambda o: float(np.sort(np.abs(o.multipliers))[1])  # noqa: E731
    assert upper.type == "saddle" and mid(upper) < 1.0
    # the near side: the orbit after the first step against a fresh solve from the start's points
    w1, o1 = float(br.values[1]), br.orbits[1]
    fresh1 = _shoot(_points(NEAR_FOLD, 12), KS12, w1)
    scale = max(1.0, float(np.max(np.abs(o1.state))))
    # two converged shooting solutions of one orbit (each to 256 eps |x|; the basis of the
    # section at the start differs): agreement to 1e-10 |x|
    assert float(np.max(np.abs(fresh1.state - o1.state))) <= 1e-10 * scale and mid(o1) > 1.0
    # the far side at H = 2.745: a fresh solve from the far orbit's points moved by 1e-3
    # (M only, off the orbit) converges to it, and one from the near side's start converges to the
    # other orbit of this level (the saddle-node's pair: middle multipliers on either side of 1)
    pts = _points(upper.state, upper.k)
    rng = np.random.default_rng(7)
    # M (the first three entries) moved: gamma and R keep their constraints
    moved = [np.concatenate([p[:3] + 1e-3 * rng.standard_normal(3), p[3:]]) for p in pts]
    assert upper.k == 12
    fresh_up = _shoot(moved, KS12, 2.745)
    assert float(np.max(np.abs(fresh_up.state - upper.state))) <= 1e-10 * scale
    lower = _shoot(_points(NEAR_FOLD, 12), KS12, 2.745)
    assert float(np.max(np.abs(lower.state - upper.state))) > 1e-2 and mid(lower) > 1.0


@pytest.mark.slow
def test_the_family_is_closed(saddle):
    """FIG4A_SADDLE_K10's family from H = 2 upwards (the slow segment and the fast return
    after it one segment) turns at a fold near H = 2.757, runs down as another saddle (a
    multiplier ~65 at H ~ 1.97) to a second fold near H = 1.420, and comes back up as the
    image of the start's branch under the rotation by pi about the body axis 3 (a symmetry of
    the reduced equations: the signs of M1, M2, gamma1, gamma2, R1, R2 flipped). So the family
    is a closed curve through the orbit and its image, between H ~ 1.420 and 2.757; it never
    reaches the Fig. 4b level H = 6 (measured 2026-11-29). The check: the orbit the branch
    reaches near H = 2 after both folds against the image of a fresh fixed-level solve from
    the catalogued saddle's own section points. ~120 CPU s (measured 2026-11-29, load ~10)."""
    ks = (1, 1, 1, 1, 3, 1, 1, 1)
    br = continue_shooting_arclength(saddle, FIG4A_LEVELS, "M_gamma", 6.0, ks=ks, max_piece_time=1.0, ds=0.2,
                                     ds_max=2.0, max_steps=45)
    assert br.stopped.startswith("max_steps = 45")
    folds = [ev["omega"] for ev in br.events if ev["event"] == "fold"]
    assert len(folds) == 2 and 2.755 <= folds[0] <= 2.758 and 1.41 <= folds[1] <= 1.43
    w = np.asarray(br.values)
    i1 = int(np.argmax(w))
    i2 = i1 + int(np.argmin(w[i1:]))
    # the far branch where it crosses H ~ 2: another saddle, strongly expanding
    ib = i1 + int(np.argmin(np.abs(w[i1:i2] - 2.0)))
    far = br.orbits[ib]
    _check_orbit(far, float(w[ib]))
    assert far.type == "saddle" and float(np.max(np.abs(far.multipliers))) > 30.0
    # back on the start's branch after the second fold
    ia = i2 + int(np.argmin(np.abs(w[i2:] - 2.0)))
    back = br.orbits[ia]
    _check_orbit(back, float(w[ia]))
    fresh = _shoot(_points(saddle.state, saddle.k), (1, 1, 1, 1, 2, 1, 1, 1, 1), float(w[ia]))
    scale = max(1.0, float(np.max(np.abs(back.state))))
    rot = np.array([-1.0, -1.0, 1.0] * 3)  # the rotation by pi about body axis 3, on M, gamma, R
    pts = _points(fresh.state, fresh.k)
    assert min(float(np.max(np.abs(rot * p - back.state))) for p in pts) <= 1e-10 * scale
    assert min(float(np.max(np.abs(p - back.state))) for p in pts) > 1e-2 * scale  # not the start's own
    assert float(np.max(np.abs(far.state - back.state))) > 1e-2 * scale


@pytest.mark.slow
def test_the_far_branch_at_h_2_is_the_time_reversed_saddle(saddle):
    """Round the fold at H ~ 2.757 the family of FIG4A_SADDLE_K10 comes back to the Fig. 4a
    level H = 2 as the catalogued FIG4A_SADDLE_K10_R, the saddle's image under sigma1 (time
    reversed; found independently by reflecting the state and shooting): the branch to 1.99 on
    the far side, then to 2.0 exactly, lands on one of its section points (measured 8.4e-13);
    an independent section run returns to it. ~45 CPU s (2026-11-29, load ~4)."""
    from taylorball.periodic_catalog import FIG4A_SADDLE_K10_R

    ks = (1, 1, 1, 1, 3, 1, 1, 1)
    br = continue_shooting_arclength(saddle, FIG4A_LEVELS, "M_gamma", 1.99, direction=1, ks=ks, max_piece_time=1.0,
                                     ds=0.2, ds_max=2.0, max_steps=40)
    assert br.stopped == "reached" and [ev["event"] for ev in br.events].count("fold") == 1
    br2 = continue_shooting_arclength(br.orbits[-1], dataclasses.replace(FIG4A_LEVELS, M_gamma=1.99), "M_gamma", 2.0,
                                      ks=ks, max_piece_time=1.0, ds=0.005, ds_max=0.02, max_steps=20)
    assert br2.stopped == "reached" and br2.values[-1] == 2.0
    far = br2.orbits[-1]
    _check_orbit(far, 2.0)
    scale = max(1.0, float(np.max(np.abs(far.state))))
    pts = _points(np.array(FIG4A_SADDLE_K10_R.state), FIG4A_SADDLE_K10_R.k)
    assert min(float(np.max(np.abs(far.state - p))) for p in pts) <= 1e-10 * scale  # measured 8.4e-13
