"""Following tori onto their core (taylorball.invariant_circles: ``rotation_from_orbit(...,
near=...)`` and ``shrink_torus``): a closed-form torus signal, and the Fig. 4b tori around
circle A shrunk onto the state ``FIG4B_CORE_SEED``, which was found by another method (the
thickness of the tori's cut by a slab of ``l``, docs/skeleton.md)."""

import math

import numpy as np
import pytest

import taylorball as tb
from taylorball import invariant_circles as IC
from taylorball._propagate import internal_f64
from taylorball.errors import UsageError
from taylorball.paper import FIG4_BALL, FIG4B_LEVELS
from taylorball.periodic import orbit_problem

EPS = np.finfo(float).eps


def test_rotation_near_a_given_angle_on_a_torus_signal():
    """An orbit on a torus in R^4 written here in closed form: a circle of amplitude 1 turning by
    ``rho`` and a tube of amplitude 3 around it turning by ``nu``. The largest peak is the
    tube's (``nu``); with ``near`` the circle's ``rho`` comes back."""
    rho, nu = 0.4 * (math.sqrt(5) - 1), 1.3 * math.sqrt(2) / 1.1
    n = np.arange(1500)
    Y = np.stack([np.cos(n * rho) + 3 * np.cos(n * nu), np.sin(n * rho) + 3 * np.sin(n * nu),
                  0.5 * np.cos(2 * n * rho), 3 * np.cos(n * nu + 0.3)], axis=1)
    r0 = IC.rotation_from_orbit(Y)
    r1 = IC.rotation_from_orbit(Y, near=rho + 0.02)
    # 1e3 eps, as for the rigid rotation (the other peaks' leakage into the windowed peak
    # after 1500 points); measured 2026-11-29: 1.3e-14 (60 eps) for nu, 3.5e-14 (157 eps) for rho
    assert min(abs(r0 - nu), abs(r0 - (2 * math.pi - nu))) <= 1e3 * EPS, (r0, nu)
    assert min(abs(r1 - rho), abs(r1 - (2 * math.pi - rho))) <= 1e3 * EPS, (r1, rho)
    # the other orientation of near selects the same peak
    r2 = IC.rotation_from_orbit(Y, near=2 * math.pi - rho)
    assert r2 == r1
    for kw, msg in [(dict(near=float("nan")), "near must be a finite angle"),
                    (dict(near=0.5, window=0.0), "window must be an angle in \\(0, pi\\)"),
                    (dict(near=0.5, window=4.0), "window must be an angle in \\(0, pi\\)")]:
        with pytest.raises(UsageError, match=msg):
            IC.rotation_from_orbit(Y, **kw)


def test_shrink_torus_refuses_bad_input_before_any_work():
    Y = np.zeros((200, 9))  # never integrated: every call below fails in its checks
    for kw, msg in [(dict(rho=float("nan")), "rho must be a finite angle \\(radians\\), got nan"),
                    (dict(rho=0.1, window=-1.0), "window must be an angle in \\(0, pi\\)"),
                    (dict(rho=0.1, n_starts=0), "n_starts must be an integer >= 1, got 0"),
                    (dict(rho=0.1, n_nodes=40), "n_nodes must be an odd integer >= 5, got 40"),
                    (dict(rho=0.1, max_rounds=0), "max_rounds must be an integer >= 1, got 0"),
                    (dict(rho=0.1, n_points=100), "n_points must be an integer >= 4 \\* n_nodes = 164, got 100"),
                    (dict(rho=0.1, keep=3), "keep must be a callable"),
                    (dict(rho=0.1, section_tol=float("nan")), "section_tol must be a finite number >= 0"),
                    ]:
        with pytest.raises(UsageError, match=msg):
            IC.shrink_torus("reduced", FIG4_BALL, Y, **kw)
    with pytest.raises(UsageError, match="orbit must be finite crossings of shape \\(m, 9\\) with m >= 4 \\* n_nodes"):
        IC.shrink_torus("reduced", FIG4_BALL, Y[:50], rho=0.1)


def test_shrink_torus_onto_the_fig4b_core():
    """An orbit on the torus through ``r1 + 0.8`` (``l = pi/2``) around circle A, 600
    crossings, ~1.0 from the circle, shrunk in three rounds of 8 orbits: the RMS residual of
    the least-squares circle falls, the rotation angle tends to circle A's, and the kept
    orbit lies near the orbit of ``FIG4B_CORE_SEED`` (2.6e-4 from the circle; found from the
    thickness of a slab's cut, not by this code). ~3.5 CPU s."""
    lev = FIG4B_LEVELS.as_kwargs()
    pt, root = IC.FIG4B_CORE_SEED
    x0 = tb.states_on_section(FIG4_BALL, **lev, point=pt, direction=1)[root]
    seed = tb.poincare_section("reduced", FIG4_BALL, x0, n_points=1500).states
    roots = tb.states_on_section(FIG4_BALL, **lev, point=(pt[0], pt[1] + 0.8, pt[2]), direction=1)
    xs = roots[int(np.argmin([abs(s[2] - x0[2]) for s in roots]))]
    orbit = tb.poincare_section("reduced", FIG4_BALL, xs, n_points=600).states
    r = IC.shrink_torus("reduced", FIG4_BALL, orbit, rho=0.1464, n_points=600, n_starts=8, max_rounds=3,
                        levels=FIG4B_LEVELS)
    prob = orbit_problem("reduced", FIG4_BALL)
    S = internal_f64(prob, seed)

    def distance(states):  # largest distance (max norm) of the states to the seed's nearest crossing
        return max(float(np.min(np.max(np.abs(S - x), axis=1))) for x in internal_f64(prob, states))

    assert all(b < a for a, b in zip(r.residuals, r.residuals[1:])) and len(r.residuals) >= 2, r.residuals
    # measured 2026-11-29: residuals 0.32, 2.4e-3, 8.9e-4; distance 1.00 -> 0.045, where the
    # seed's crossings are ~0.03 apart along the circle (1500 points on a curve of length ~50):
    # the kept orbit is within a few spacings of the circle, the start 20 times further
    d0, d1 = distance(orbit), distance(r.states)
    assert d0 > 0.5 and d1 < 0.1, (d0, d1)
    # circle A's rotation angle 0.146429383 (Newton, docs/skeleton.md); the tori's angle tends
    # to it quadratically in their distance (1.9e-7 at distance ~0.02)
    assert abs(r.rho - 0.146429383) < 1e-5, r.rho
    assert r.starts == 24
