"""Contact-point trajectory: algebraic reconstruction vs integrating the full system, and
the classical Earnshaw result for the homogeneous ball."""

import math

import numpy as np
import pytest

import taylorball as tb
from taylorball.contact import annulus, contact_trajectory, fit_circle

from .conftest import FIG5, HOMOGENEOUS, demo_reduced_state

EPS = 2.0**-52


def test_algebraic_contact_point_equals_full_integration():
    """x = (alpha, R), y = (beta, R) from the reduced solution vs paper eqs. (8)-(10) [eq6] integrated."""
    s = demo_reduced_state()
    T = np.linspace(0.0, 20.0, 41)
    ct = contact_trajectory(FIG5, s, T)
    full = tb.propagate("full", FIG5, tb.reduced_to_full(FIG5, s), T)
    ref = tb.propagate("full", FIG5, tb.reduced_to_full(FIG5, s), T, fp_type=np.longdouble).astype(float)
    # both float64 paths carry the orbit's error growth; compare each to long double and
    # to each other at the level the full run itself reaches against long double
    own = np.max(np.abs(full[:, 12:14] - ref[:, 12:14]))
    diff = np.max(np.abs(ct.xy - full[:, 12:14]))
    scale = np.max(np.abs(ref[:, 12:14]))
    print(f"contact point: algebraic vs full {diff:.2e}; full float64 vs long double {own:.2e}")
    assert diff <= 16 * max(own, EPS * scale)


def test_homogeneous_ball_moves_on_earnshaw_circle():
    """Earnshaw: the centre of a homogeneous ball on a plane rotating at Omega moves on a
    circle with angular frequency Omega I / (I + m a^2) (= 3/14 for the Fig. 2 ball)."""
    s = demo_reduced_state()
    T = np.linspace(0.0, 200.0, 2001)
    ct = contact_trajectory(HOMOGENEOUS, s, T)
    centre, r = fit_circle(ct.xy)
    d = np.hypot(ct.x - centre[0], ct.y - centre[1])
    # radius constant to rounding of the orbit (positions ~20, ~1e3 steps)
    assert np.max(np.abs(d - r)) <= 1e3 * EPS * r, np.max(np.abs(d - r))
    angle = np.unwrap(np.arctan2(ct.y - centre[1], ct.x - centre[0]))
    nu = np.polyfit(T, angle, 1)[0]
    I, m, a, om = 3.0, HOMOGENEOUS.mass, HOMOGENEOUS.radius, HOMOGENEOUS.plane_rate
    expected = om * I / (I + m * a * a)
    assert abs(nu - expected) <= 1e3 * EPS * expected, (nu, expected)


def test_annulus_of_a_circle():
    t = np.linspace(0, 2 * math.pi, 400, endpoint=False)
    xy = np.column_stack([3 + 2 * np.cos(t), -1 + 2 * np.sin(t)])
    c, rmin, rmax = annulus(xy)
    assert np.allclose(c, [3, -1], atol=1e-12) and abs(rmin - 2) < 1e-12 and abs(rmax - 2) < 1e-12


def test_contact_rejects_bad_grid():
    with pytest.raises(tb.UsageError):
        contact_trajectory(FIG5, demo_reduced_state(), [[0.0, 1.0]])


from hypothesis import assume, given, settings  # noqa: E402

from taylorball.contact import radius_bound  # noqa: E402

from .conftest import STATES, ball_params  # noqa: E402


@settings(max_examples=200)
@given(params=ball_params(), state=STATES["reduced"](omega_scale=3.0, r_scale=30.0))
def test_energy_estimate_behind_radius_bound(params, state):
    """The lemma: E <= (C/sqrt(I_min) + |mu||R|/sqrt(I_min + d))^2/2 - m Omega^2 R^2/2 at
    every admissible state; equivalently |R| <= radius_bound(C, E)."""
    assume(abs(params.plane_rate) > 1e-3)  # radius_bound rejects Omega ~ 0 (tested below)
    ints = tb.integrals("reduced", params, state)
    C, h = math.sqrt(ints["C2"]), ints["E"]
    R = float(np.linalg.norm(state[6:9]))
    # the bound is a root of a quadratic computed in float64: relative rounding ~1e-15
    assert R <= radius_bound(params, C, h) * (1 + 1e-12) + 1e-12


def test_orbit_stays_inside_radius_bound():
    s = demo_reduced_state()
    ints = tb.integrals("reduced", FIG5, s)
    bound = radius_bound(FIG5, math.sqrt(ints["C2"]), ints["E"])
    ct = contact_trajectory(FIG5, s, np.linspace(0.0, 2000.0, 20001))
    r = np.hypot(ct.x, ct.y)
    print(f"max |R| on [0, 2000] = {r.max():.3f} <= bound {bound:.3f}")
    assert r.max() <= bound


def test_radius_bound_needs_a_rotating_plane():
    p = tb.BallParams(inertia=(2, 3, 4), mass=1, radius=5, plane_rate=0.0)
    with pytest.raises(tb.ParameterError, match="plane_rate != 0"):
        radius_bound(p, 10.0, 5.0)


def _itilde(params, g):
    J = np.diag(np.array(params.inertia) + params.d)
    return J - params.d * np.outer(g, g)


@settings(max_examples=100)
@given(params=ball_params(), state=STATES["reduced"]())
def test_lemma_parts_and_their_equality_cases(params, state):
    """(M, Itilde^{-1} M) <= |M|^2 / I_min and, for R perpendicular to gamma,
    (R, Itilde^{-1} R) <= |R|^2 / (I_min + d); both are attained, so neither constant can
    be improved (a wrong constant, e.g. I_max for I_min, fails the equality cases)."""
    g, R = state[3:6], state[6:9]
    It = _itilde(params, g)
    M = state[0:3]  # any vector
    i_min, d = min(params.inertia), params.d
    assert M @ np.linalg.solve(It, M) <= (M @ M) / i_min * (1 + 1e-12) + 1e-300
    assert R @ np.linalg.solve(It, R) <= (R @ R) / (i_min + d) * (1 + 1e-12) + 1e-300
    k = int(np.argmin(params.inertia))
    e = np.eye(3)
    j = (k + 1) % 3
    # equality cases: gamma = e_k for the first, gamma = e_j, R = e_k for the second
    assert abs(e[k] @ np.linalg.solve(_itilde(params, e[k]), e[k]) - 1 / i_min) <= 1e-12 / i_min
    assert abs(e[k] @ np.linalg.solve(_itilde(params, e[j]), e[k]) - 1 / (i_min + d)) <= 1e-12 / (i_min + d)


def test_radius_bound_is_the_root_of_the_estimate():
    C, h = 10.0, 5.0
    r = radius_bound(FIG5, C, h)
    i_min, d = 2.0, 25.0
    mu, m, om = 10.0, 1.0, 2.0
    rhs = 0.5 * (C / math.sqrt(i_min) + mu * r / math.sqrt(i_min + d)) ** 2 - 0.5 * m * om**2 * r**2
    assert abs(rhs - h) <= 1e-12 * abs(0.5 * m * om**2 * r**2)


def test_bounding_circles_of_known_shapes():
    from taylorball.contact import bounding_circles

    th = np.linspace(0.0, 2 * math.pi, 2001)
    # a circle: both circles are it
    b = bounding_circles(np.c_[3 + 2 * np.cos(th), -1 + 2 * np.sin(th)])
    assert np.allclose(b["outer_centre"], (3, -1), atol=1e-6) and abs(b["r_outer"] - 2) <= 1e-6
    assert np.allclose(b["inner_centre"], (3, -1), atol=1e-6) and abs(b["r_inner"] - 2) <= 1e-6
    # a band between non-concentric circles, filled densely (like a trajectory over many
    # turns): outer radius 5 about the origin, hole of radius 1 about (1, 0); both boundary
    # circles carry points too
    rng = np.random.default_rng(0)
    q = rng.uniform(-5, 5, (40_000, 2))
    q = q[(np.hypot(*q.T) < 5) & (np.hypot(q[:, 0] - 1, q[:, 1]) > 1)]
    pts = np.r_[q, np.c_[5 * np.cos(th), 5 * np.sin(th)], np.c_[1 + np.cos(th), np.sin(th)]]
    b = bounding_circles(pts, max_points=len(pts))
    assert np.allclose(b["outer_centre"], (0, 0), atol=1e-5) and abs(b["r_outer"] - 5) <= 1e-5
    # the hole is bounded by 2001 points on its circle: its centre and radius to ~1e-5
    assert np.allclose(b["inner_centre"], (1, 0), atol=1e-4) and abs(b["r_inner"] - 1) <= 1e-4
