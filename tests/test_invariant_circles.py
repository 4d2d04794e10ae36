"""Invariant circles of the section maps (taylorball.invariant_circles): checks independent
of the Newton code — a closed-form rotation, exact trigonometric interpolation, a second
propagation by the section integrator, and the limit of the rotation number at an
elliptic fixed point found by the periodic-orbit Newton (another computation)."""

import math
import warnings

import numpy as np
import pytest

import taylorball as tb
from taylorball import invariant_circles as IC
from taylorball.errors import StateError, UsageError
from taylorball.paper import FIG1_LEVELS, FIG4_BALL, FIG4B_LEVELS, fig1_params

EPS = np.finfo(float).eps


def _closed_form_curve(theta):
    """A closed curve in R^5 winding once (harmonics 1..3), written here."""
    return np.stack([3 * np.cos(theta) + 0.4 * np.cos(2 * theta), 2 * np.sin(theta) - 0.3 * np.sin(3 * theta),
                     0.5 * np.cos(theta + 0.3) + 0.2 * np.sin(2 * theta), 0.1 * np.cos(3 * theta), 1.0 + 0 * theta],
                    axis=1)


def test_rotation_from_orbit_of_a_rigid_rotation():
    """An orbit ``K(0.7 + n rho)`` of a rigid rotation on a curve with three harmonics: the
    rotation angle (or ``2 pi - rho``: the orientation of the principal plane) comes back."""
    rho = 2 * math.pi * (math.sqrt(5) - 1) / 2 * 0.37
    Y = _closed_form_curve(0.7 + rho * np.arange(1500))
    r = IC.rotation_from_orbit(Y)
    err = min(abs(r - rho), abs(r - (2 * math.pi - rho)))
    # 1e3 eps: the leakage of the other harmonics into the windowed peak after 1500 points
    # and the rounding of the peak's slope; measured 2026-11-29: 3.4e-14 (150 eps)
    assert err <= 1e3 * EPS, (r, rho)
    with pytest.raises(UsageError, match="points must be an array of shape"):
        IC.rotation_from_orbit(Y[:10])


def test_shift_matrix_is_exact_on_trigonometric_polynomials():
    """``T_rho`` applied to the nodes of a trigonometric polynomial of degree <= (N - 1)/2
    gives its values at ``theta_j + rho``, ``D_rho`` their derivative in ``rho``: closed forms."""
    n, rho = 9, 0.83
    th = 2 * np.pi * np.arange(n) / n
    X = _closed_form_curve(th)
    T, D = IC._shift_matrices(n, rho)
    h = 1e-6
    # 64 eps of the curve's size 4: a 9 x 9 solve and product (measured 2026-11-29: ~4 eps)
    assert np.max(np.abs(T @ X - _closed_form_curve(th + rho))) <= 64 * EPS * 4
    dnum = (_closed_form_curve(th + rho + h) - _closed_form_curve(th + rho - h)) / (2 * h)
    # central difference with h = 1e-6: error h^2 |K'''| / 6 ~ 1e-11 plus rounding 4 eps / h ~ 1e-9
    assert np.max(np.abs(D @ X - dnum)) <= 1e-8


def test_bad_inputs_are_refused_before_any_work():
    p = FIG4_BALL
    Y = np.zeros((200, 9))
    for kw, msg in [(dict(n_nodes=40), "n_nodes must be odd \\(an integer in \\[5, inf\\]\\), got 40"),
                    (dict(n_nodes=3), "n_nodes must be an integer in \\[5, inf\\], got 3"),
                    (dict(n_nodes=True), "n_nodes must be an integer in \\[5, inf\\], got True"),
                    (dict(max_iter=0), "max_iter must be an integer in \\[1, inf\\], got 0"),
                    (dict(rtol=-1.0), "rtol must be in \\(0, inf\\], got -1.0"),
                    (dict(rho=float("nan")), "rho \\(an angle in radians\\) must be finite"),
                    (dict(rho=True), "rho \\(an angle in radians\\) must be a finite real number, got True"),
                    (dict(section_tol=float("nan")),
                     "section_tol must be finite \\(a real number in \\[0, inf\\]\\), got nan"),
                    (dict(section_tol=-1e-8), "section_tol must be in \\[0, inf\\]")]:
        with pytest.raises(UsageError, match=msg):
            IC.invariant_circle("reduced", p, Y, **kw)
    with pytest.raises(UsageError, match="orbit .* is required"):
        IC.invariant_circle("reduced", p)
    with pytest.raises(UsageError, match=r"orbit must be finite crossings of shape \(m, 9\) with m >= 4 \* n_nodes"):
        IC.invariant_circle("reduced", p, Y[:100], n_nodes=41)
    with pytest.raises(UsageError, match=r"shape \(m, 9\)"):
        IC.invariant_circle("reduced", p, np.zeros((200, 6)))
    with pytest.raises(UsageError, match="kind must be 'reduced' or 'mparallel'"):
        IC.invariant_circle("full", p, Y)
    (pt, root) = IC.FIG4B_CORE_SEED
    x = tb.states_on_section(FIG4_BALL, **FIG4B_LEVELS.as_kwargs(), point=pt, direction=1)[root]
    off = np.tile(x, (200, 1))
    off[7, 6] += 1e-3  # R1 of one state: off the level (energy, (R, gamma))
    with pytest.raises(StateError, match="orbit state 7 is off the section"):
        IC.invariant_circle("reduced", p, off, levels=FIG4B_LEVELS)


@pytest.fixture(scope="module")
def fig1_curves():
    """The Fig. 1 (M||gamma) map's elliptic fixed point near ``(l, L/G) = (pi/2, -0.037)``
    and the invariant curves through the chart points ``L/G`` above it by 0.005 and 0.02."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", tb.UnphysicalParametersWarning)
        p = fig1_params()
    lev = FIG1_LEVELS.as_kwargs()
    s0 = tb.mparallel_states_on_section(p, **lev, point=(math.pi / 2, -0.037))[0]
    fixed = tb.periodic_orbit("mparallel", p, s0, 1, levels=FIG1_LEVELS)
    curves = {}
    for d in (0.005, 0.02):
        s = tb.mparallel_states_on_section(p, **lev, point=(fixed.points[0][0], fixed.points[0][1] + d))[0]
        orbit = tb.poincare_section("mparallel", p, s, n_points=400).states
        curves[d] = IC.invariant_circle("mparallel", p, orbit, n_nodes=21, levels=FIG1_LEVELS)
    return p, fixed, curves


def _phase_and_distance(p, c, js, n=200):
    """The largest ``|P^i(K(theta_j)) - K(theta_j + i rho)|`` (public states, ``i <= n``), by
    :func:`poincare_section` from the nodes ``js``, and the largest distance of those
    crossings to the curve."""
    err = dist = 0.0
    for j in js:
        sec = tb.poincare_section(c.kind, p, c.states[j], n_points=n)
        pred = c.evaluate(2 * math.pi * j / c.n_nodes + c.rho * np.arange(1, n + 1), public=True)
        err = max(err, float(np.max(np.abs(pred - sec.states))))
        dist = max(dist, float(np.max(c.distance(sec.states[::20]))))
    return err, dist


def test_fig1_curve_is_invariant_under_an_independent_section_run(fig1_curves):
    """From three nodes, 200 crossings of :func:`poincare_section` land on ``K(theta_j + i
    rho)``: the curve is invariant and the map on it is the rotation by ``rho``."""
    p, _, curves = fig1_curves
    c = curves[0.02]
    assert c.kind == "mparallel" and c.n_nodes == 21 and 0 <= c.rho < 2 * math.pi
    assert c.fourier_tail < 1e-9  # an analytic curve: 21 nodes resolve it (measured 7e-12)
    err, dist = _phase_and_distance(p, c, (0, 7, 14))
    # the node residual (measured 1.4e-11 on states of size 16) misplaces an image by at most
    # about itself per iterate along the curve (the error of rho) and by about itself across
    # it; measured 2026-11-29: 3.0e-10 after 200 iterates (1.5e-12 per iterate), 3e-12 across
    assert err <= 200 * c.residual, (err, c.residual)
    assert dist <= 10 * c.residual, (dist, c.residual)


def test_newton_from_a_wrong_rotation_angle(fig1_curves):
    """With ``rho`` off by 2e-3, the least-squares guess is 5e-3 off and Newton converges
    quadratically (measured 4.9e-3, 3.3e-5, 7.0e-9, 1.8e-13), to a curve of the same family
    (a 2D map's invariant curves are not isolated: here one 6e-3 away, rho 1.4e-5 lower),
    which passes the same independent check."""
    p, _, curves = fig1_curves
    c0 = curves[0.02]
    orbit = tb.poincare_section("mparallel", p, c0.states[0], n_points=400).states
    c = IC.invariant_circle("mparallel", p, orbit, n_nodes=21, levels=FIG1_LEVELS, rho=c0.rho + 2e-3)
    h = c.residual_history
    assert h[0] > 1e-3 and len(h) >= 3 and h[-1] <= 1e-11 * 16  # rtol 1e-11 of max(1, |x|) = 16
    assert all(b < 0.05 * a for a, b in zip(h, h[1:]))  # each step gains more than 20x
    assert abs(c.rho - c0.rho) < 1e-3
    err, dist = _phase_and_distance(p, c, (3,))
    assert err <= 200 * max(c.residual, 64 * EPS * 16) and dist <= 10 * max(c.residual, 64 * EPS * 16)


def test_fig1_rotation_number_tends_to_the_elliptic_point_s(fig1_curves):
    """As the curves shrink onto the elliptic fixed point, their rotation number tends to the
    angle of its multipliers (``arg mu / 2 pi`` or ``1 - arg mu / 2 pi``, by orientation), from
    the periodic-orbit Newton's variational matrix: another computation. The difference
    falls with the square of the distance (twist): measured 3.6e-6 and 5.7e-5."""
    _, fixed, curves = fig1_curves
    a = abs(float(np.angle(fixed.multipliers[0]))) / (2 * math.pi)
    diff = {d: min(abs(c.rotation_number - a), abs(c.rotation_number - (1 - a))) for d, c in curves.items()}
    assert diff[0.005] < 1e-5
    assert 8 <= diff[0.02] / diff[0.005] <= 32, diff  # quadratic: 16 for a 4x larger distance


@pytest.mark.slow
def test_fig4b_core_is_an_invariant_circle():
    """The core of the Fig. 4b tori around ``l = pi/2`` (docs/skeleton.md, "The tori of
    Fig. 4b and their cores"; ~25 CPU s): Newton from the seed's orbit; an independent
    :func:`poincare_section` from a node follows ``K(theta + n rho)``; the rotation angle of
    that orbit by frequency analysis equals Newton's; the circle is symmetric under the
    reversor sigma2 and its image under the rotation by pi about the body axis 3 is invariant
    too; nearby orbits stay at distances proportional to their offset."""
    from taylorball.periodic import reversors

    (pt, root) = IC.FIG4B_CORE_SEED
    lev = FIG4B_LEVELS.as_kwargs()
    x0 = tb.states_on_section(FIG4_BALL, **lev, point=pt, direction=1)[root]
    orbit = tb.poincare_section("reduced", FIG4_BALL, x0, n_points=1500).states
    c = IC.invariant_circle("reduced", FIG4_BALL, orbit, n_nodes=141, levels=FIG4B_LEVELS)
    assert c.residual <= 1e-7  # measured 2.6e-8 (2026-11-29): the 141-node interpolation's floor
    sec = tb.poincare_section("reduced", FIG4_BALL, c.states[0], n_points=1500)
    err = np.max(np.abs(c.evaluate(c.rho * np.arange(1, 301), public=True) - sec.states[:300]))
    assert err <= 2e-6, err  # measured 5e-7 over 300 and 7e-7 over 1000 iterates
    r = IC.rotation_from_orbit(sec.states)
    assert min(abs(r - c.rho), abs(r - (2 * math.pi - c.rho))) <= 1e-8  # measured 2e-10 (1500 points; 3e-6 from 300)
    assert np.max(c.distance(c.states * reversors("reduced")["sigma2"])) <= 1e-6  # measured 5e-8
    assert min(c.rotation_number, 1 - c.rotation_number) == pytest.approx(0.0233049601, abs=1e-8)
    for d in (0.05, 0.2):
        y = tb.states_on_section(FIG4_BALL, **lev, point=(pt[0], pt[1] + d, 0.0), direction=1)
        y = y[int(np.argmin([abs(s[2] - x0[2]) for s in y]))]
        dist = c.distance(tb.poincare_section("reduced", FIG4_BALL, y, n_points=300).states[::3])
        assert 0.1 * d <= dist.min() and dist.max() <= 2 * d  # measured 0.19 d .. 1.3 d


def test_too_few_nodes_for_the_fig4b_core_fail_with_the_residual():
    """21 nodes cannot resolve the Fig. 4b core (its harmonics fall to 2.4e-3 only at k = 20):
    Newton ends at the interpolation's floor and says so, with its history and last nodes."""
    (pt, root) = IC.FIG4B_CORE_SEED
    x0 = tb.states_on_section(FIG4_BALL, **FIG4B_LEVELS.as_kwargs(), point=pt, direction=1)[root]
    orbit = tb.poincare_section("reduced", FIG4_BALL, x0, n_points=200).states
    with pytest.raises(IC.InvariantCircleFailure, match="Newton did not reach an invariant circle") as info:
        IC.invariant_circle("reduced", FIG4_BALL, orbit, n_nodes=21, levels=FIG4B_LEVELS, max_iter=4)
    e = info.value
    assert e.residual > 1e-3 and e.residual == e.residual_history[-1] and e.states.shape == (21, 9)


def test_symmetric_ball_s_relative_orbit_is_an_invariant_circle():
    """For the symmetric ball (``I1 = I2``, the Fig. 3 level) ``l`` is cyclic, and the
    elliptic relative fixed point near ``(l, r1, r2) = (0, -0.28, 0)`` is, in the 3D map, an
    invariant circle: the state rotated about the body axis 3, the map a rotation by the
    relative orbit's shift. Newton from that orbit's crossings finds it: ``(r1, r2)`` constant,
    ``l`` equally spaced around the whole circle, ``rho`` the advance of ``l`` per crossing of
    an independent :func:`poincare_section` run (sign fixed by the nodes' orientation)."""
    from taylorball.paper import FIG3_BALL, FIG3_LEVELS

    st = tb.states_on_section(FIG3_BALL, **FIG3_LEVELS.as_kwargs(), point=(0.0, -0.3, 0.0), direction=1)[1]
    o = tb.periodic_orbit("reduced", FIG3_BALL, st, 1, levels=FIG3_LEVELS)
    sec = tb.poincare_section("reduced", FIG3_BALL, o.state, n_points=88)
    c = IC.invariant_circle("reduced", FIG3_BALL, sec.states, n_nodes=21, levels=FIG3_LEVELS)
    pts = sec.points
    dl = math.remainder(pts[1, 0] - pts[0, 0], 2 * math.pi)  # l's advance per crossing, section run
    step = np.array([math.remainder(a, 2 * math.pi) for a in np.diff(np.append(c.points[:, 0], c.points[0, 0]))])
    orient = float(np.sign(step[0]))
    # nodes 2 pi / 21 apart in l, in one orientation: l fills the circle uniformly. The nodes
    # are Newton's, correct to its residual (~1e4 eps of states ~20 after t ~ 30); measured
    # 2026-11-29: 4.7e3 eps; 5e4 eps allowed
    assert np.max(np.abs(step - orient * 2 * math.pi / 21)) <= 5e4 * EPS, step
    # (r1, r2) constant on the circle and equal to the relative orbit's; measured 5.5e2 eps
    assert np.max(np.abs(c.points[:, 1:] - pts[0, 1:])) <= 1e4 * EPS
    # rho against the section run's advance of l (the crossings' rounding after t ~ 30, ~1e3
    # eps) and against the relative orbit's shift (l' = l - shift); measured 7.5e2 and 2.6e2 eps
    assert abs(math.remainder(c.rho - orient * dl, 2 * math.pi)) <= 1e4 * EPS, (c.rho, dl)
    assert abs(math.remainder(c.rho + orient * o.shift, 2 * math.pi)) <= 1e4 * EPS
