"""Periodic orbits by multiple shooting (taylorball.periodic_shooting) and the orbits of the
Fig. 4 ball at the paper's Omega = 2 it found. Every check is against a computation the code
under test does not make: the section integrator run afresh from the reported state, central
differences of that integrator's k-th return, the single-shooting Newton of periodic_orbit."""

import numpy as np
import pytest

import taylorball as tb
from taylorball import periodic as P
from taylorball._propagate import public_state, start_state
from taylorball.errors import StateError, UsageError
from taylorball.paper import FIG3_BALL, FIG4_BALL, FIG4A_LEVELS
from taylorball.periodic_catalog import (FIG4A_ORBITS, FIG4A_SADDLE_FOCUS_K14, FIG4A_SADDLE_K10, FIG4B_SADDLE_Q1,
                                         catalog_orbit)
from taylorball.periodic_shooting import (ShootingOptions, periodic_orbit_shooting, segment_lengths, shoot_periodic_orbit,
                                         time_splits)

EPS = np.finfo(float).eps


def _tangent_basis(prob, g0, x):
    """Orthonormal basis of the tangent space of section and level (SVD written here)."""
    geo = P._eval_geo(prob, g0, x)
    G = np.vstack([np.asarray(geo.grad_e, dtype=float)[None, :], np.asarray(geo.grad_c, dtype=float)])
    return np.linalg.svd(G)[2][G.shape[0]:].T


def _moved(prob, g0, state, v, scale=20.0):
    """A public state moved by the tangent vector ``B v`` of section and level, back onto both."""
    x = start_state(prob, state)
    geo = P._eval_geo(prob, g0, x)
    ctx = P._Ctx(prob, g0, 1, 1, geo.c.copy(), False, 1e4)
    return public_state(prob.system, prob.pars, P._to_level(ctx, x + _tangent_basis(prob, g0, x) @ v, scale),
                        prob.spec)


def _orbit_points(o):
    """The orbit's k section points (public states) by the section integrator run afresh."""
    sec = tb.poincare_section("reduced", o.problem.params, o.state, n_points=o.k - 1, g0=o.g0)
    return [np.asarray(o.state)] + [np.asarray(s) for s in sec.states]


# ---------------------------------------------------------------------------------------
# Bad input: clear errors before any work.
# ---------------------------------------------------------------------------------------
def test_bad_input():
    e = FIG4A_SADDLE_K10
    st = np.array(e.state)
    with pytest.raises(UsageError, match="states"):
        shoot_periodic_orbit("reduced", FIG4_BALL, [])
    with pytest.raises(UsageError, match="ks must hold 2"):
        shoot_periodic_orbit("reduced", FIG4_BALL, [st, st], ks=(1,))
    with pytest.raises(UsageError, match="ks must hold 1"):
        shoot_periodic_orbit("reduced", FIG4_BALL, [st], ks=(0,))
    with pytest.raises(UsageError, match="dynamically symmetric"):
        shoot_periodic_orbit("reduced", FIG3_BALL, [st])
    with pytest.raises(UsageError, match="ShootingOptions"):
        shoot_periodic_orbit("reduced", FIG4_BALL, [st], options={"max_iter": 3})  # type: ignore[arg-type]
    other = np.array(FIG4B_SADDLE_Q1.state)  # on the section g = 3.15, not g = 0
    with pytest.raises(StateError, match=r"states\[1\] is not on the section"):
        shoot_periodic_orbit("reduced", FIG4_BALL, [st, other])
    with pytest.raises(UsageError, match=r"shooting .* must be an integer in \[1, k = 10\], got 11"):
        periodic_orbit_shooting("reduced", FIG4_BALL, st, 10, 11)
    with pytest.raises(UsageError, match=r"got 0"):
        periodic_orbit_shooting("reduced", FIG4_BALL, st, 10, 0)
    with pytest.raises(UsageError, match="max_iter"):
        shoot_periodic_orbit("reduced", FIG4_BALL, [st], options=ShootingOptions(max_iter=0))
    assert segment_lengths(10, 3) == (4, 3, 3) and segment_lengths(5, 5) == (1,) * 5


# ---------------------------------------------------------------------------------------
# Multiple and single shooting find the same orbit.
# ---------------------------------------------------------------------------------------
def test_shooting_agrees_with_single_shooting():
    """The Fig. 4b orbit at Omega = 1.42312 (k = 19, single shooting's catalogue entry) from a
    guess moved by 0.01 along a tangent of section and level: 19 segments of one crossing
    give the single-shooting orbit's period and trace (measured 6e-14 and 1.2e-11)."""
    e = FIG4B_SADDLE_Q1
    ref = catalog_orbit(e)
    guess = _moved(ref.problem, e.g0, np.asarray(ref.state), 0.01 * np.array([1.0, 0.7, -0.4]) / 1.3)
    o = periodic_orbit_shooting(e.kind, e.ball, guess, e.k, e.k, g0=e.g0)
    assert o.converged and o.k == e.k and o.type == ref.type
    assert abs(o.period - ref.period) <= 1e4 * EPS * ref.period  # 37.3 time units of float64 rounding
    # the trace of P^19 (3.80) is a product of 19 one-crossing maps: its rounding ~cond * eps;
    # measured 1.2e-11, allowed 2^20 eps = 2.3e-10
    assert abs(o.trace - ref.trace) <= 2.0**20 * EPS * abs(ref.trace)
    assert same_points(o, ref)


def same_points(a, b, tol=1e-8):
    """Every chart point of ``a`` within ``tol`` of one of ``b`` (l mod 2 pi)."""
    for p in a.points:
        d = b.points - p
        d[:, 0] = (d[:, 0] + np.pi) % (2 * np.pi) - np.pi
        if float(np.min(np.max(np.abs(d), axis=1))) > tol:
            return False
    return True


def test_shooting_from_a_pseudo_orbit():
    """The Fig. 4a saddle's 10 section points, each moved by 0.05 (max norm of the tangent
    coordinates, independent random directions): the 10 guesses are no orbit of the map, but
    multiple shooting reaches the catalogued orbit (single shooting from the first guess
    failed here, best residual 2.05: measured 2026-11-28)."""
    ref = catalog_orbit(FIG4A_SADDLE_K10)
    rng = np.random.default_rng(1)
    guess = []
    for q in _orbit_points(ref):
        v = rng.normal(size=3)
        guess.append(_moved(ref.problem, 0.0, q, 0.05 * v / np.max(np.abs(v))))
    o = shoot_periodic_orbit("reduced", FIG4_BALL, guess, levels=FIG4A_LEVELS)
    assert o.k == 10 and abs(o.period - ref.period) <= 1e4 * EPS * ref.period and same_points(o, ref)


# ---------------------------------------------------------------------------------------
# The catalogued orbits of the Fig. 4 ball at Omega = 2.
# ---------------------------------------------------------------------------------------
def _map_matrix_fd(o, h=1e-6):
    """3x3 matrix of P^k on the tangent space of section and level: central differences of the
    float64 section integrator along an orthonormal tangent basis, ``J C^-1`` in that basis.
    For the Fig. 4a saddle (k = 10) the multipliers' error was measured as 1.8e-2, 1.9e-4,
    2.7e-6, 2.1e-4 at h = 1e-4, 1e-5, 1e-6, 1e-7: truncation ~2e4 h^2 (P^10 is strongly
    curved), rounding ~2e-11 / h; h = 1e-6 is near the best."""
    prob = o.problem
    x = o.internal
    V = _tangent_basis(prob, o.g0, x)
    J, C = np.zeros((3, 3)), np.zeros((3, 3))
    for j in range(3):
        img, dom = [], []
        for sgn in (1, -1):
            p = _moved(prob, o.g0, o.state, sgn * h * np.eye(3)[j])
            sec = tb.poincare_section("reduced", prob.params, p, n_points=o.k, g0=o.g0)
            img.append(np.asarray(start_state(prob, sec.states[-1], project_state=True), dtype=float))
            dom.append(np.asarray(start_state(prob, p), dtype=float))
        J[:, j] = V.T @ ((img[0] - img[1]) / (2 * h))
        C[:, j] = V.T @ ((dom[0] - dom[1]) / (2 * h))
    return J @ np.linalg.inv(C)


@pytest.mark.parametrize("entry", FIG4A_ORBITS, ids=lambda e: e.name)
def test_fig4_orbit_at_omega_2(entry):
    """A catalogued orbit of the Fig. 4 ball at Omega = 2: the section integrator, run afresh
    from the reported state, returns to it after k crossings to 1e-12 relative (max over the
    public components / max(1, |x|)); it is on the level; the multipliers' product is 1 and
    they agree with central differences of the section integrator's P^k. Solved by multiple
    shooting (k segments) from the stored state; the single-shooting Newton of catalog_orbit
    gives the same orbit."""
    e = entry
    o = periodic_orbit_shooting(e.kind, e.ball, np.array(e.state), e.k, e.k, levels=e.levels, g0=e.g0)
    single = catalog_orbit(e)
    assert same_points(o, single) and abs(o.trace - single.trace) <= 1e-8 * abs(o.trace)
    assert o.problem.params.plane_rate == 2.0
    assert o.k == e.k and o.stability == "hyperbolic" and o.symmetric is None  # not a symmetric orbit
    sec = tb.poincare_section("reduced", e.ball, o.state, n_points=o.k, g0=e.g0)
    scale = max(1.0, float(np.max(np.abs(o.state))))
    # measured 5.8e-14 .. 2.3e-13 relative over the four Fig. 4a orbits: the float64
    # integrator's own error over ~25 time units grown by the multipliers, not the orbit's
    assert float(np.max(np.abs(np.asarray(sec.states[-1]) - o.state))) <= 1e-12 * scale
    assert abs(float(sec.times[-1]) - o.period) <= 1e3 * EPS * o.period
    lv = tb.integrals("reduced", e.ball, o.state)
    assert abs(lv["E"] - e.levels.h) <= 64 * EPS * 10 and abs(lv["M_gamma"] - e.levels.M_gamma) <= 64 * EPS * 10
    # the product of k one-crossing maps, each from ~600 Taylor steps at tol = eps (its
    # entries good to ~1e-13): measured |det - 1| = 2.1e-13 .. 8.9e-12 over the four orbits,
    # allowed 2^16 eps = 1.5e-11 (the single-shooting matrix of one variational run over the
    # whole period of FIG4A_SADDLE_K10 is off by 1.7e-10)
    assert abs(np.prod(o.multipliers) - 1) <= 2.0**16 * EPS
    A = _map_matrix_fd(o)
    mu = np.sort(np.abs(np.linalg.eigvals(A)))
    big = float(np.max(np.abs(o.multipliers)))
    # central differences at h = 1e-6 (see _map_matrix_fd): measured up to 3.0e-7 * max|mu| in
    # the moduli of the multipliers and 5.2e-7 * max|mu| in the trace; allowed 2e-6 * max|mu|
    assert np.allclose(mu, np.sort(np.abs(o.multipliers)), rtol=0, atol=2e-6 * big), (mu, o.multipliers)
    assert abs(np.trace(A) - o.trace) <= 2e-6 * big


# ---------------------------------------------------------------------------------------
# Segments split in time.
# ---------------------------------------------------------------------------------------
def test_split_bad_input():
    st = np.array(FIG4A_SADDLE_K10.state)
    with pytest.raises(UsageError, match="splits must hold 2"):
        shoot_periodic_orbit("reduced", FIG4_BALL, [st, st], splits=[(1.0,)])
    with pytest.raises(UsageError, match="positive finite"):
        shoot_periodic_orbit("reduced", FIG4_BALL, [st], splits=[(-1.0,)])
    with pytest.raises(UsageError, match="splits must hold 1"):
        shoot_periodic_orbit("reduced", FIG4_BALL, [st], splits=[("a",)])
    with pytest.raises(UsageError, match="not both"):
        shoot_periodic_orbit("reduced", FIG4_BALL, [st], splits=[()], max_piece_time=2.0)
    with pytest.raises(UsageError, match="max_piece_time must be a positive finite flow time, got 0"):
        shoot_periodic_orbit("reduced", FIG4_BALL, [st], max_piece_time=0)
    with pytest.raises(UsageError, match="max_piece_time"):
        time_splits([1.0], float("nan"))
    assert time_splits([1.0, 6.0, 2.0], 2.5) == ((), (2.0, 2.0), ())
    # a piece time tiny beside a return time must not build millions of pieces (memory, hang)
    with pytest.raises(UsageError, match="1000000 pieces; at most 1000 per segment"):
        time_splits([1.0], 1e-6)
    assert len(time_splits([1.0], 1e-3)[0]) == 999  # the bound itself is allowed
    with pytest.raises(UsageError, match="positive and finite"):
        time_splits([float("inf")], 1.0)
    with pytest.raises(UsageError, match="at most 999 cuts per segment, got 1000"):
        shoot_periodic_orbit("reduced", FIG4_BALL, [st], splits=[(1e-3,) * 1000])


@pytest.mark.parametrize("entry", [FIG4A_SADDLE_K10, FIG4A_SADDLE_FOCUS_K14], ids=lambda e: e.name)
def test_split_segments_give_the_same_orbit(entry):
    """The slow crossings of a catalogued orbit (return times 6.4 .. 9.6 against ~1.2) cut into
    time pieces of at most 2 (5 and 4 pieces for the K10 saddle): the same orbit as without
    splitting, to 1e-12 in the state (measured 1.8e-13 and 3.7e-14), the same period and
    multipliers; the pieces' product of maps has determinant 1."""
    e = entry
    a = periodic_orbit_shooting(e.kind, e.ball, np.array(e.state), e.k, e.k, levels=e.levels, g0=e.g0)
    b = periodic_orbit_shooting(e.kind, e.ball, np.array(e.state), e.k, e.k, levels=e.levels, g0=e.g0,
                                max_piece_time=2.0)
    assert b.converged and b.k == e.k and b.type == a.type
    scale = max(1.0, float(np.max(np.abs(a.state))))
    assert float(np.max(np.abs(np.asarray(a.state) - np.asarray(b.state)))) <= 1e-12 * scale
    assert abs(a.period - b.period) <= 1e3 * EPS * a.period
    # the multipliers from two different products of maps (10 against 17 factors), each with
    # entries good to ~1e-13: measured agreement 1e-10 of the largest; allowed 2^24 eps
    big = float(np.max(np.abs(a.multipliers)))
    assert np.allclose(np.sort_complex(a.multipliers), np.sort_complex(b.multipliers), rtol=0,
                       atol=2.0**24 * EPS * big)
    assert abs(np.prod(b.multipliers) - 1) <= 2.0**16 * EPS  # as test_fig4_orbit_at_omega_2


def test_fig4b_orbit_at_omega_2():
    """The reflection saddle on the Fig. 4b level at Omega = 2 (found with its slow returns
    split in time): the section integrator, run afresh from the stored state, returns to it
    after 11 crossings to 1e-12 relative (measured 5.2e-14); it is on the level; the shooting
    with the slow returns split finds it again from the stored state, with multipliers of
    product 1, none of them 1 (a generic orbit of the 3D map, docs/skeleton.md "Method")."""
    from taylorball.paper import FIG4B_LEVELS
    from taylorball.periodic_catalog import FIG4B_REFLECTION_SADDLE_K11 as e

    st = np.array(e.state)
    sec = tb.poincare_section("reduced", e.ball, st, n_points=e.k)
    scale = max(1.0, float(np.max(np.abs(st))))
    assert float(np.max(np.abs(np.asarray(sec.states[-1]) - st))) <= 1e-12 * scale
    assert abs(float(sec.times[-1]) - e.period) <= 1e3 * EPS * e.period
    assert max(np.diff(np.concatenate([[0.0], np.asarray(sec.times, dtype=float)]))) > 19.0  # the slow returns
    lv = tb.integrals("reduced", e.ball, st)
    assert abs(lv["M_gamma"] - FIG4B_LEVELS.M_gamma) <= 64 * EPS * 10 and abs(lv["E"] - FIG4B_LEVELS.h) <= 64 * EPS * 10
    assert e.ball.plane_rate == 2.0
    o = periodic_orbit_shooting(e.kind, e.ball, st, e.k, e.k, levels=e.levels, g0=e.g0, max_piece_time=1.0)
    assert o.converged and o.k == 11 and o.type == "reflection-saddle" and o.symmetric is None
    assert abs(o.period - e.period) <= 1e3 * EPS * e.period
    # a product of ~90 pieces' maps (pieces of at most 1 time unit): measured |det - 1| = 2.5e-13;
    # allowed 2^18 eps as for the family's orbits (test_periodic_shooting_family)
    assert abs(np.prod(o.multipliers) - 1) <= 2.0**18 * EPS
    assert np.allclose(np.sort(np.real(o.multipliers)), np.sort(e.multipliers), rtol=1e-5)
    assert min(abs(abs(m) - 1) for m in o.multipliers) > 0.1
