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
    """x = (alpha, R), y = (beta, R) from the reduced solution vs eq. (6) integrated."""
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
