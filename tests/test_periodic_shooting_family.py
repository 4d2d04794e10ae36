"""The Fig. 4a saddle's family in H by multiple shooting (taylorball.periodic_shooting_family).
The checks are independent of the shooting: the section integrator run afresh from each
reported state, the level's integrals evaluated on it, the multipliers' product."""

import numpy as np
import pytest

import taylorball as tb
from taylorball.errors import UsageError
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
from taylorball.periodic_catalog import FIG4A_SADDLE_K10
from taylorball.periodic_shooting import periodic_orbit_shooting
from taylorball.periodic_shooting_family import continue_shooting, recurrence_shooting

EPS = np.finfo(float).eps
#: the slow return of the saddle (times 9.6 and 6.4) is one segment of two crossings, cut in time
KS = (1, 1, 1, 1, 2, 1, 1, 1, 1)


@pytest.fixture(scope="module")
def saddle():
    e = FIG4A_SADDLE_K10
    return periodic_orbit_shooting(e.kind, e.ball, np.array(e.state), e.k, e.k, levels=e.levels, g0=e.g0)


def test_bad_input(saddle):
    with pytest.raises(UsageError, match="not 'Omega'"):
        continue_shooting(saddle, FIG4A_LEVELS, "Omega", 2.1)
    with pytest.raises(UsageError, match="parameter must be"):
        continue_shooting(saddle, FIG4A_LEVELS, "H", 2.1)
    with pytest.raises(UsageError, match="other than the start's M_gamma = 2.0"):
        continue_shooting(saddle, FIG4A_LEVELS, "M_gamma", 2.0)
    with pytest.raises(UsageError, match="0 < h_min <= h0 <= h_max"):
        continue_shooting(saddle, FIG4A_LEVELS, "M_gamma", 2.1, h0=1.0, h_max=0.1)
    with pytest.raises(UsageError, match="adding up to the orbit's k = 10"):
        continue_shooting(saddle, FIG4A_LEVELS, "M_gamma", 2.1, ks=(1, 2))
    with pytest.raises(UsageError, match="k_range"):
        recurrence_shooting(FIG4_BALL, FIG4A_LEVELS, k_range=(3, 2))
    with pytest.raises(UsageError, match="n_orbits"):
        recurrence_shooting(FIG4_BALL, FIG4A_LEVELS, n_orbits=0)


def test_family_in_H(saddle):
    """From H = 2 to 2.1: the saddle turns into a saddle-focus at once (between H = 2 and
    2.01) and its slow return grazes the section, so that it crosses g = 0 11 times from
    H = 2.07 (measured 2026-11-28). Every orbit returns to its state after its k crossings in
    a fresh run of the section integrator, lies on its level, and has multipliers of product 1."""
    br = continue_shooting(saddle, FIG4A_LEVELS, "M_gamma", 2.1, ks=KS, max_piece_time=1.0, h0=0.01, h_max=0.05)
    assert br.stopped == "reached" and br.values[-1] == 2.1 and br.parameter == "M_gamma"
    assert br.orbits[0].type == "saddle" and br.orbits[-1].type == "saddle-focus"
    assert br.events[0]["event"] == "stability change" and br.events[0]["between"] == (2.0, 2.01)
    assert br.orbits[-1].k == 11
    for w, o in zip(br.values, br.orbits):
        sec = tb.poincare_section("reduced", FIG4_BALL, o.state, n_points=o.k)
        scale = max(1.0, float(np.max(np.abs(o.state))))
        # as test_fig4_orbit_at_omega_2: the float64 integrator's error over ~25 time units
        assert float(np.max(np.abs(np.asarray(sec.states[-1]) - o.state))) <= 1e-12 * scale
        assert abs(float(sec.times[-1]) - o.period) <= 1e3 * EPS * o.period
        assert abs(tb.integrals("reduced", FIG4_BALL, o.state)["M_gamma"] - w) <= 64 * EPS * 10
        # a product of ~26 maps (pieces of at most 1 time unit, each from a variational run
        # with entries good to ~1e-13) against 10 for the whole segments of
        # test_fig4_orbit_at_omega_2 (allowed 2^16 eps there): measured |det - 1| up to 2.2e-11
        # along this stretch; allowed 2^18 eps = 5.8e-11
        assert abs(np.prod(o.multipliers) - 1) <= 2.0**18 * EPS


@pytest.mark.slow
def test_family_in_H_ends_at_a_fold(saddle):
    """Towards H = 2.8 the family turns back into a saddle (between H = 2.725 and 2.7375) and
    its middle multiplier falls towards +1 (1.75 at H = 2.75, 1.37 at 2.7547: measured
    2026-11-28): a fold near H = 2.757, where natural steps must end. ~500 CPU s (measured
    504 on the loaded machine: the steps halved down to h_min at the fold)."""
    br = continue_shooting(saddle, FIG4A_LEVELS, "M_gamma", 2.8, ks=KS, max_piece_time=1.0, h0=0.01, h_max=0.1)
    assert br.stopped.startswith("no solution at M_gamma")
    assert 2.75 <= br.values[-1] < 2.757
    back = [ev for ev in br.events if ev["from"] == "saddle-focus" and ev["to"] == "saddle"]
    assert back and 2.72 <= back[-1]["between"][0] < back[-1]["between"][1] <= 2.74
    mid = [float(np.sort(np.abs(o.multipliers))[1]) for o, w in zip(br.orbits, br.values) if w >= 2.74]
    assert all(b < a for a, b in zip(mid, mid[1:])) and 1.0 < mid[-1] < 1.8
    # the determinant of the last orbit's map (see test_family_in_H for the allowance)
    assert abs(np.prod(br.orbits[-1].multipliers) - 1) <= 2.0**18 * EPS
