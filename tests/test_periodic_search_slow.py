"""Segments chosen automatically for slow returns (periodic_shooting.shooting_segments), the
chart's regularity at section points (periodic_sections.chart_regularity), and the search's
multiple shooting of slow seeds (SearchOptions(slow_factor=...)). The references: the rules
written out by hand, a closed form of the regularity (Lagrange's identity), the section
integrator run afresh from a reported state."""

import math

import numpy as np
import pytest

import taylorball as tb
from taylorball._propagate import start_state
from taylorball.errors import UsageError
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
from taylorball.periodic import orbit_problem
from taylorball.periodic_catalog import FIG4A_SADDLE_K10
from taylorball.periodic_sections import chart_regularity
from taylorball.periodic_shooting import shooting_segments, time_splits

from .test_periodic_shooting import _moved

EPS = np.finfo(float).eps


def test_shooting_segments_rules():
    # the crossing ending the slow return (9.0) is no segment end: it joins segment 1, whose
    # 10.2 time units are cut in pieces of at most 2.5 (ceil(10.2 / 2.5) = 5 pieces, the
    # fifth ending at the crossing)
    starts, ks, sp = shooting_segments([1.0, 9.0, 1.2, 1.1], slow=3.0, max_piece_time=2.5)
    assert starts == (0, 1, 3) and ks == (1, 2, 1)
    assert sp == ((), time_splits([9.0 + 1.2], 2.5)[0], ()) and len(sp[1]) == 4
    # a section point below min_regularity is no segment end either (its segment stays whole
    # when no return in it is slow)
    starts, ks, sp = shooting_segments([1.0, 1.1, 1.2, 1.3], slow=3.0, max_piece_time=1.0,
                                       regularity=[0.9, 0.9, 0.05, 0.9], min_regularity=0.1)
    assert starts == (0, 1, 3) and ks == (1, 2, 1) and sp == ((), (), ())
    # without rotate the start x_0 is kept though the return ending at it (the last) is slow;
    # with rotate the first segment starts at the first good end and wraps round
    assert shooting_segments([1.0, 1.0, 8.0], slow=3.0, max_piece_time=4.0)[:2] == ((0, 1, 2), (1, 1, 1))
    starts, ks, sp = shooting_segments([1.0, 1.0, 8.0], slow=3.0, max_piece_time=4.0, rotate=True)
    assert starts == (1, 2) and ks == (1, 2) and sp == ((), (3.0, 3.0))  # 8 + 1 = 9 in 3 pieces
    # no good end at all (k = 1, a slow return): the one segment, split
    assert shooting_segments([7.0], slow=3.0, max_piece_time=2.0, rotate=True) == ((0,), (1,), ((1.75,) * 3,))
    # sum(ks) is k, and every point is a start or inside a segment, whatever the data
    rng = np.random.default_rng(0)
    for _ in range(200):
        k = int(rng.integers(1, 9))
        t = np.where(rng.random(k) < 0.4, rng.uniform(3.5, 20.0, k), rng.uniform(0.5, 2.0, k))
        st, ks, sp = shooting_segments(t, slow=3.0, max_piece_time=1.0, regularity=rng.uniform(0, 1, k),
                                       min_regularity=0.2, rotate=True)
        assert sum(ks) == k and len(st) == len(ks) == len(sp)
        assert [(st[0] + sum(ks[:i])) % k for i in range(len(ks))] == list(st)


def test_shooting_segments_bad_input():
    with pytest.raises(UsageError, match="times must hold"):
        shooting_segments([], slow=3.0, max_piece_time=1.0)
    with pytest.raises(UsageError, match="slow must be a positive finite flow time, got -1"):
        shooting_segments([1.0], slow=-1.0, max_piece_time=1.0)
    with pytest.raises(UsageError, match=r"regularity must hold one value per section point \(2\), got 1"):
        shooting_segments([1.0, 2.0], slow=3.0, max_piece_time=1.0, regularity=[0.5])
    with pytest.raises(UsageError, match="max_piece_time"):
        shooting_segments([5.0], slow=3.0, max_piece_time=0.0)
    for bad_reg in (float("nan"), -0.1, 1.0):  # NaN would silently keep every point as a segment end
        with pytest.raises(UsageError, match=r"min_regularity must be a number in \[0, 1\)"):
            shooting_segments([1.0, 2.0], slow=3.0, max_piece_time=1.0, regularity=[0.5, 0.5], min_regularity=bad_reg)
    for bad in (dict(slow_factor=1.0), dict(slow_factor=float("nan")), dict(max_piece_time=0.0),
                dict(min_regularity=1.5)):
        with pytest.raises(UsageError, match="SearchOptions." + next(iter(bad))):
            tb.SearchOptions(**bad)  # type: ignore[arg-type]


def test_chart_regularity_closed_form():
    """``sqrt(num^2 + den^2) / C^2`` equals ``sqrt((C^2 - M3^2)(C^2 - H^2)) / C^2``, ``H = (M,
    gamma)`` (Lagrange's identity with ``|gamma| = 1``), at the saddle's 10 section points
    and at a state moved towards ``M || e3``; to 64 eps (a few roundings of order-1 terms)."""
    prob = orbit_problem("reduced", FIG4_BALL)
    sec = tb.poincare_section("reduced", FIG4_BALL, FIG4A_SADDLE_K10.state, n_points=9)
    X = np.vstack([np.asarray(FIG4A_SADDLE_K10.state)[None, :], np.asarray(sec.states, dtype=float)])
    reg = chart_regularity(prob, X)
    for x, r in zip(X, reg):
        xi = np.asarray(start_state(prob, x, project_state=True), dtype=float)
        M, g = xi[0:3], xi[3:6]
        C2 = float(M @ M)
        ref = math.sqrt((C2 - M[2] ** 2) * (C2 - float(M @ g) ** 2)) / C2
        assert abs(r - ref) <= 64 * EPS, (r, ref)
    assert 0.0 < float(np.min(reg)) and float(np.max(reg)) <= 1.0


def test_a_slow_seed_is_solved_by_multiple_shooting():
    """The search's slow-seed path from the Fig. 4a saddle's state moved by 1e-3 (k = 10,
    return times up to 9.6 against the level's median ~1.06): the seed is shot with automatic
    segments (the slow returns' crossings no segment ends, their segments split) and converges
    to the catalogued saddle, which the section integrator run afresh confirms (<= 1e-12
    relative after 10 crossings)."""
    from taylorball.periodic_search import SearchReport, _shooting_plan, _solve_seeds, same_orbit

    prob = orbit_problem("reduced", FIG4_BALL)
    e = FIG4A_SADDLE_K10
    st = np.array(e.state, dtype=float)
    seed = np.asarray(_moved(prob, 0.0, st, np.array([1e-3, -1e-3, 1e-3])), dtype=float)  # on section and level
    opts = tb.SearchOptions(slow_factor=3.0)
    plan = _shooting_plan(prob, seed, 10, 0.0, 1, 3.0 * 1.06, opts)
    assert plan is not None
    starts, ks, splits = plan
    assert sum(ks) == 10 and len(starts) < 10 and any(len(s) > 0 for s in splits)
    rep = SearchReport(slow_time=3.0 * 1.06)
    found = _solve_seeds(prob, FIG4A_LEVELS, [(0.0, seed, 10)], rep, 0.0, 1, 40, False, opts)
    assert rep.shooting == 1 and rep.failures == 0 and len(found) == 1
    o = found[0]
    ref = tb.periodic_orbit("reduced", FIG4_BALL, st, 10, levels=FIG4A_LEVELS)
    assert o.k == 10 and same_orbit(o, ref, tol=1e-9)
    back = tb.poincare_section("reduced", FIG4_BALL, o.state, n_points=10)
    scale = max(1.0, float(np.max(np.abs(o.state))))
    # a 25-time-unit return of a saddle with multiplier ~9: 1e-12 relative = 2^-40 / (2^-52) ~ 4500 eps
    assert float(np.max(np.abs(np.asarray(back.states[-1]) - np.asarray(o.state)))) <= 4500 * EPS * scale
