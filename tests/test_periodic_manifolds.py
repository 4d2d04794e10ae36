"""Invariant manifolds of the Fig. 3 level's period-4 saddle (grow_manifold) and its
symmetric homoclinic points (symmetric_homoclinic_points). Checks against computations the
code under test does not make: the section integrator run afresh (crossings counted, not
followed by time), the inverse map (backward steps), a long double solution."""

import dataclasses
import math

import numpy as np
import pytest

import taylorball as tb
from taylorball.errors import UsageError
from taylorball.paper import FIG3_BALL

from ._periodic_checks import polyline_distance
from ._periodic_checks import rr as _rr

EPS = np.finfo(float).eps


@pytest.fixture(scope="module")
def saddle():
    from taylorball.periodic_catalog import fig3_saddle

    return fig3_saddle()


@pytest.fixture(scope="module")
def wu(saddle):
    """The unstable manifold, branch +1, to chart arc length 0.8 (~8 CPU s): 17 levels, the
    first crossing of r2 = 0 at level 15."""
    from taylorball.periodic_manifolds import grow_manifold

    return grow_manifold(saddle, "unstable", length=0.8, branch=1)


def test_bad_input_is_refused_before_work(saddle):
    from taylorball.periodic_manifolds import grow_manifold

    for kw, word in ((dict(length=0.0), "length"), (dict(length=float("nan")), "length"),
                     (dict(length=1.0, branch=2), "branch"), (dict(length=1.0, s0=0.5), "s0"),
                     (dict(length=1.0, delta=0.01, delta_min=0.02), "delta_min"),
                     (dict(length=1.0, n_fund=1), "n_fund"), (dict(length=1.0, max_points=0), "max_points")):
        with pytest.raises(UsageError, match=word):
            grow_manifold(saddle, **kw)
    with pytest.raises(UsageError, match="which"):
        grow_manifold(saddle, "both", length=1.0)
    with pytest.raises(UsageError, match="PeriodicOrbit"):
        grow_manifold(np.zeros(9), length=1.0)
    ell = dataclasses.replace(saddle, stability="elliptic", multipliers=np.array([0.6 + 0.8j, 0.6 - 0.8j]))
    with pytest.raises(UsageError, match="saddle"):
        grow_manifold(ell, length=1.0)
    three = dataclasses.replace(saddle, multipliers=np.array([0.19, 1.01, 5.19]))
    with pytest.raises(UsageError, match="2D manifolds are not grown"):
        grow_manifold(three, length=1.0)


def test_first_levels_leave_at_the_multiplier(saddle, wu):
    """Points of one sigma on consecutive levels: near the saddle (linear regime, chart
    distance 1e-6..1e-3) the distance to the saddle's first point grows by mu_u per level."""
    x0 = saddle.points[0, 1:]
    mu = abs(saddle.multipliers[1])
    s = wu.sigma[wu.level == 0][5]
    d = [np.linalg.norm(wu.points[(wu.level == m) & (wu.sigma == s)][0] - x0) for m in range(2, 8)]
    r = np.array(d[1:]) / np.array(d[:-1])
    assert np.all(np.abs(r - mu) <= 2e-3 * mu), r  # O(s0 mu^m) nonlinear correction, s0 = 1e-6


def test_manifold_points_map_onto_the_manifold(saddle, wu):
    """(a) A mesh point's image by the section integrator (4 crossings counted, a separate
    run) is the stored point of the same sigma one level further, to 1e-9 (crossings
    followed by time and counted agree before any fold; levels 9..12). (b) A point of the
    fundamental domain that is not in the mesh, mapped 13 times by the section integrator,
    lies on the drawn curve within the polyline's chord error delta * alpha / 4 (a chord of
    length <= delta turning by <= alpha is within ~delta * alpha / 4 of the arc)."""
    from taylorball.periodic_manifolds import _SaddleMap

    for m in (9, 12):
        sel = np.flatnonzero(wu.level == m)
        for i in sel[:: max(1, len(sel) // 3)]:
            img = tb.poincare_section("reduced", FIG3_BALL, wu.states[i], n_points=4).states[-1]
            j = np.flatnonzero((wu.level == m + 1) & (wu.sigma == wu.sigma[i]))[0]
            assert np.linalg.norm(_rr(img).astype(float) - wu.points[j]) <= 1e-9
    sm = _SaddleMap(saddle)
    x = sm.start("unstable", 1, wu.s0 * sm.scale, 0.3183, 1)
    st = tb._propagate.public_state(saddle.problem.system, saddle.problem.pars, x, saddle.problem.spec)
    img = tb.poincare_section("reduced", FIG3_BALL, st, n_points=4 * 13).states[-1]
    p = _rr(img).astype(float)
    assert polyline_distance(p, wu.points) <= wu.delta * wu.alpha / 4
    assert np.linalg.norm(p - saddle.points[0, 1:]) > 0.05  # far out on the curve, not at the saddle


@pytest.fixture(scope="module")
def homoclinic(saddle, wu):
    from taylorball.periodic import refine
    from taylorball.periodic_homoclinic import symmetric_homoclinic_points

    h64 = symmetric_homoclinic_points(saddle, wu, max_points=1)
    ld = refine(saddle, (np.longdouble,))[-1]
    hld = symmetric_homoclinic_points(ld, wu, max_points=1)
    return h64, hld


def test_symmetric_homoclinic_point_float64_and_long_double(homoclinic):
    """The first symmetric homoclinic point on W^u (branch +1): on r2 = 0 to the shooting's
    noise (float64 images after 15 levels carry ~1e-8 of amplified rounding, long double
    ~1e-11), the same point in both types (r1 to 1e-10), fixed by the reversor in the state,
    and the angle between W^u and its mirror W^s the same in both types to 1e-3 relative (the
    float64 tangent's central differences at h = 1e-3 against noise ~1e-8; measured 2e-5)."""
    (a,), (b,) = homoclinic
    assert a.level == b.level == 15 and a.crossing == b.crossing == 0
    assert abs(a.point[1]) <= 1e-7 and abs(b.point[1]) <= 1e-10
    assert abs(a.point[0] - b.point[0]) <= 1e-10  # measured 4.7e-12
    assert abs(b.point[0] - (-0.358490060)) <= 1e-9
    assert a.symmetry_defect <= 1e-6 and b.symmetry_defect <= 1e-9
    assert 1e-4 < b.angle < 1e-2  # transversal: 9.75e-4 rad (0.05585 deg)
    assert abs(a.angle - b.angle) <= 1e-3 * b.angle


def test_homoclinic_orbit_approaches_the_saddle_at_the_multipliers(saddle, homoclinic):
    """The long double point's images, by the section integrator (forward, crossings
    counted) and by the inverse map (backward steps): their chart distance to the nearest
    section point of the saddle shrinks by mu_s = 0.4465 per period forward and by 1/mu_u
    per period backward (4 crossings), within 15 % over periods 4..8 (the approach is
    geometric once the orbit is near the saddle; the point's own error, ~1e-11, grown by
    2.24 per period, stays below the distance there)."""
    from taylorball.periodic_manifolds import inverse_map

    _, (b,) = homoclinic
    st = np.asarray(b.state, dtype=float)
    orbit_pts = saddle.points[:, 1:]
    mu_s, mu_u = abs(saddle.multipliers[0]), abs(saddle.multipliers[1])

    def dist(states):
        P = np.array([_rr(s).astype(float) for s in states])
        return np.min(np.linalg.norm(P[:, None, :] - orbit_pts[None, :, :], axis=2), axis=1)

    fwd = dist(tb.poincare_section("reduced", FIG3_BALL, st, n_points=36).states)[3::4]
    r = fwd[5:9] / fwd[4:8]
    assert np.all(np.abs(r - mu_s) <= 0.15 * mu_s), (fwd, r)
    bwd = dist(inverse_map(saddle, st, 36))[3::4]
    r = bwd[5:9] / bwd[4:8]
    assert np.all(np.abs(r - 1 / mu_u) <= 0.15 / mu_u), (bwd, r)


def test_symmetric_homoclinic_points_bad_input(saddle, wu):
    from taylorball.periodic_homoclinic import symmetric_homoclinic_points

    with pytest.raises(UsageError, match="manifold"):
        symmetric_homoclinic_points(saddle, "wu")
    with pytest.raises(UsageError, match="max_points"):
        symmetric_homoclinic_points(saddle, wu, max_points=0)
    with pytest.raises(UsageError, match="h_sigma"):
        symmetric_homoclinic_points(saddle, wu, h_sigma=1.0)


@pytest.mark.slow
def test_stable_manifold_by_the_backward_flow_meets_the_same_point(saddle, homoclinic):
    """W^s grown by the flow backwards (branch -1; no reversor used) crosses r2 = 0 at the
    W^u point, with its own tangent equal to the mirrored W^u tangent: the symmetric point
    is on both manifolds, and the angle is found from two independent sides (measured:
    1e-12 apart in r1 and tangents equal to 1e-11 in long double; float64 here, ~1e-8 noise).
    ~12 CPU s."""
    from taylorball.periodic_homoclinic import symmetric_homoclinic_points
    from taylorball.periodic_manifolds import grow_manifold

    (a,), _ = homoclinic
    ws = grow_manifold(saddle, "stable", length=1.5, branch=-1)
    pts = symmetric_homoclinic_points(saddle, ws, max_points=4)
    b = min(pts, key=lambda h: abs(h.point[0] - a.point[0]))
    assert abs(b.point[0] - a.point[0]) <= 1e-9
    assert np.linalg.norm(b.tangent_s - a.tangent_s) <= 1e-5  # the W^s tangent from W^s itself vs the mirror
    assert abs(b.angle - a.angle) <= 1e-3 * a.angle
