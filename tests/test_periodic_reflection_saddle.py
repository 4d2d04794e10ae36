"""Reflection saddles of Tzenoff's case (the dynamically symmetric Fig. 3 ball on the level G =
10, H = 4, h = 5; the ball with d = 7/2 at Omega = 3 whose saddle docs/rigorous.md proves): the
catalogued orbits, their iterate (periodic_manifolds.iterate) and the manifolds of F^2 with
their symmetric homoclinic points. Checks against computations the code
under test does not make: the section integrator run afresh, and the same homoclinic point
found on the stable manifold grown by the backward flow (no reversor used)."""

import numpy as np
import pytest

import taylorball as tb
from taylorball.errors import UsageError

from ._periodic_checks import rotate_public

EPS = np.finfo(float).eps


@pytest.fixture(scope="module")
def saddle():
    from taylorball.periodic_catalog import SYMMETRIC_H4_REFLECTION_SADDLE, catalog_orbit

    return catalog_orbit(SYMMETRIC_H4_REFLECTION_SADDLE)


def _returns(o):
    sec = tb.poincare_section("reduced", o.problem.params, o.state, n_points=o.k, g0=o.g0)
    return float(np.max(np.abs((sec.states[-1] - rotate_public(o.state, o.shift)).astype(float))))


def test_reflection_saddle_and_its_iterate(saddle):
    """The catalogued orbit is a reflection saddle (tr A = -5.476, multipliers ~ -0.189 and
    -5.287); iterate(orbit, 2) is the same orbit with k = 2, period and shift doubled and the
    multipliers squared, and it too returns in an independent propagation (k = 1: P x =
    S_theta x; k = 2: P^2 x = S_{2 theta} x); grow_manifold refuses the negative multiplier
    and names the iterate."""
    from taylorball.periodic_manifolds import grow_manifold, iterate

    o = saddle
    assert o.type == "reflection-saddle" and o.k == 1 and o.trace < -5.4
    assert abs(np.prod(o.multipliers) - 1) <= 1e4 * EPS
    assert _returns(o) <= 1e-12
    o2 = iterate(o, 2)
    assert (o2.k, o2.type) == (2, "saddle") and o2.period == 2 * o.period
    assert np.allclose(np.sort(o2.multipliers.real), np.sort(o.multipliers.real ** 2), rtol=1e-12)
    assert _returns(o2) <= 1e-12
    assert iterate(o, 1) is o
    with pytest.raises(UsageError, match=r"iterate\(orbit, 2\)"):
        grow_manifold(o, "unstable", length=1.0)
    for bad in (0, 1.5, True, "2"):
        with pytest.raises(UsageError, match="q must be an integer >= 1"):
            iterate(o, bad)
    # refused before any work: too many crossings, or |mu|^q beyond float64 (|mu| = 5.287:
    # 5.287^420 ~ 1e304 passes the cut ln(float max) - 8 = 701.8 only up to q = 421)
    from taylorball.periodic_manifolds import MAX_ITERATE_CROSSINGS

    with pytest.raises(UsageError, match="MAX_ITERATE_CROSSINGS"):
        iterate(o, MAX_ITERATE_CROSSINGS + 1)
    with pytest.raises(UsageError, match="overflows float64"):
        iterate(o, 430)
    assert np.all(np.isfinite(iterate(o, 400).matrix))


@pytest.mark.slow
def test_homoclinic_points_at_large_angles(saddle):
    """W^u of F^2 (branch +1) grown to chart arc length 1.5 crosses the reversor's line r2 = 0
    at symmetric homoclinic points; one of them, r1 = 0.0192770, at 87.47 degrees between W^u
    and its mirror W^s (the Fig. 3 level's saddle: at most 0.62 degrees). W^s grown by the
    backward flow (no reversor) meets the line at the same point, with the same angle. ~1 min."""
    from taylorball.periodic_homoclinic import symmetric_homoclinic_points
    from taylorball.periodic_manifolds import grow_manifold, iterate

    o2 = iterate(saddle, 2)
    wu = grow_manifold(o2, "unstable", length=1.5, branch=1)
    hu = symmetric_homoclinic_points(o2, wu, max_points=8)
    a = min(hu, key=lambda h: abs(h.point[0] - 0.019277))
    assert abs(a.point[0] - 0.0192770) <= 1e-6 and abs(a.point[1]) <= 1e-8
    assert 80.0 < np.degrees(a.angle) < 90.0  # measured 87.47
    ws = grow_manifold(o2, "stable", length=1.5, branch=-1)
    hs = symmetric_homoclinic_points(o2, ws, max_points=8)
    b = min(hs, key=lambda h: abs(h.point[0] - a.point[0]))
    assert abs(b.point[0] - a.point[0]) <= 1e-9
    assert abs(b.angle - a.angle) <= 1e-6


def test_the_proved_saddles_homoclinic_point():
    """The reflection saddle of the d = 7/2 ball (Omega = 3; C = 10, M_gamma = 6, h = -20; proved
    in docs/rigorous.md): W^u of F^2 (branch +1, arc length 1.5) meets the reversor's line r2 =
    0 at r1 = 0.0103008 at 77.4 degrees; W^s grown by the backward flow (branch -1, no reversor
    used) meets it at the same point with the same angle (measured: 2.4e-9 apart in r1 and
    2.8e-7 degrees: the float64 shooting's noise after 5-6 levels). ~7 CPU s."""
    from taylorball.periodic_catalog import TZENOFF_D35_REFLECTION_SADDLE, catalog_orbit
    from taylorball.periodic_homoclinic import symmetric_homoclinic_points
    from taylorball.periodic_manifolds import grow_manifold, iterate

    o = catalog_orbit(TZENOFF_D35_REFLECTION_SADDLE)
    assert o.type == "reflection-saddle" and _returns(o) <= 1e-12
    o2 = iterate(o, 2)
    hu = symmetric_homoclinic_points(o2, grow_manifold(o2, "unstable", length=1.5, branch=1), max_points=8)
    hs = symmetric_homoclinic_points(o2, grow_manifold(o2, "stable", length=1.5, branch=-1), max_points=8)
    a = min(hu, key=lambda h: abs(h.point[0] - 0.0103008))
    b = min(hs, key=lambda h: abs(h.point[0] - a.point[0]))
    assert abs(a.point[0] - 0.0103008) <= 1e-6 and abs(a.point[1]) <= 1e-8
    assert 70.0 < np.degrees(a.angle) < 85.0  # measured 77.402
    assert abs(b.point[0] - a.point[0]) <= 1e-7  # measured 2.4e-9
    assert abs(b.angle - a.angle) <= 1e-6
