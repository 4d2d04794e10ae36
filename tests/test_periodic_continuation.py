"""Continuation that switches sections by itself (periodic_continuation), and the families of
periodic orbits on the resonant tori of the integrable non-rotating case (Omega = 0), with
their break-up for small Omega. Every check is against a computation the code under test does
not make: the section integrator run afresh, the extra integral |K|^2 of the Chaplygin ball
on a fixed plane, the catalogued orbit solved by Newton on the paper's section."""

import dataclasses
import math
import warnings

import numpy as np
import pytest

import taylorball as tb
from taylorball import periodic as P
from taylorball.errors import UsageError
from taylorball.paper import FIG1_LEVELS, FIG3_BALL, FIG3_LEVELS, fig1_params

from ._periodic_checks import rotate_public

EPS = np.finfo(float).eps

#: A state of the Fig. 3 saddle branch at Omega = 1.8867893301703142 on the section g = 0,
#: where its crossing of g = 0 is nearly tangent (a guess only: Newton solves again).
_GRAZING = ((-6.888577139774679e-07, 0.02204283336438234, -2.000100372617707, 1.5864561139758313e-07,
             -0.0050765004125750465, -0.9999871144887499, 2.3587312897415954e-05, -0.7547701280750913,
             0.003831640242958002), 1.8867893301703142, 2.9149406518929206)


def _grazing_orbit():
    state, w, theta = _GRAZING
    ball = dataclasses.replace(FIG3_BALL, plane_rate=w)
    return P.periodic_orbit("reduced", ball, np.array(state), 1, levels=FIG3_LEVELS,
                            options=P.NewtonOptions(shift=theta))


def _returns(o):
    """max |P^k x - S_theta x| by the section integrator run afresh (public state)."""
    ball = o.problem.params
    sec = tb.poincare_section("reduced", ball, o.state, n_points=o.k, g0=o.g0)
    return float(np.max(np.abs((sec.states[-1] - rotate_public(o.state, o.shift)).astype(float))))


def test_switch_passes_the_grazing_of_g0():
    """On g = 0 the saddle branch's crossing grazes the section (transversality 0.0014 at
    Omega = 1.88679, where the steps on g = 0 had shrunk to ~1e-5 and stalled short of
    1.8900). With switching the branch moves by itself to a section it crosses
    transversally, records it, and passes 1.89; every point is an orbit of its own Omega in an
    independent propagation."""
    from taylorball.periodic_continuation import SectionSwitch, continue_arclength, crossing_transversality

    o = _grazing_orbit()
    assert float(np.min(crossing_transversality(o))) < 0.005  # measured 0.0014
    br = continue_arclength(o, FIG3_LEVELS, ds=0.1, n_steps=2, direction=1, bounds=(1.8, 2.01),
                            switch=SectionSwitch())
    assert br.stopped == "reached" and len(br.switches) == 1, (br.stopped, br.switches)
    sw = br.switches[0]
    assert sw["from"] == (0.0, 1) and sw["to"][0] != 0.0 and sw["omega"] == _GRAZING[1]
    assert sw["transversality"][1] >= 0.02  # measured 0.020 on g0 = 6.11
    assert br.omega[-1] > 1.8897  # measured 1.89277
    for w, orb in zip(br.omega, br.orbits):
        assert orb.g0 == sw["to"][0]
        assert abs(orb.problem.params.plane_rate - w) == 0.0
        assert _returns(orb) <= 1e-10  # |x| ~ 10, multiplier ~1.7 over t ~ 31: measured ~1e-12
    # the same orbit on both sections at the switch: the same period and trace
    assert abs(br.orbits[0].period - o.period) <= 1e-9 * o.period
    assert abs(br.orbits[0].trace - o.trace) <= 1e-6


def test_switch_bad_input():
    from taylorball.periodic_continuation import SectionSwitch, continue_arclength, section_scan

    with pytest.raises(UsageError, match="min_transversality"):
        SectionSwitch(min_transversality=0.0)
    with pytest.raises(UsageError, match="accept_transversality"):
        SectionSwitch(min_transversality=0.05, accept_transversality=0.01)
    with pytest.raises(UsageError, match="candidates"):
        SectionSwitch(candidates=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", tb.UnphysicalParametersWarning)
        p = dataclasses.replace(fig1_params(), plane_rate=0.0)
    st = tb.mparallel_states_on_section(p, **FIG1_LEVELS.as_kwargs(), point=(math.pi / 2, 0.0))[0]
    e = P.periodic_orbit("mparallel", p, st, 1, levels=FIG1_LEVELS)
    with pytest.raises(UsageError, match="kind='reduced'"):
        continue_arclength(e, FIG1_LEVELS, switch=SectionSwitch())
    with pytest.raises(UsageError, match="kind='reduced'"):
        section_scan(e)


def test_natural_continuations_name_themselves_in_errors():
    """continue_in_omega and continue_in_level refuse an object that is not an orbit of the
    reduced or M||gamma system with their own names in the message."""
    from types import SimpleNamespace

    from taylorball.periodic_continuation import continue_in_level, continue_in_omega

    not_an_orbit = SimpleNamespace(problem=None)
    with pytest.raises(UsageError, match="^continue_in_omega follows"):
        continue_in_omega(not_an_orbit, FIG1_LEVELS, [0.1])  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="^continue_in_level follows"):
        continue_in_level(not_an_orbit, FIG1_LEVELS, "h", [0.1])  # type: ignore[arg-type]


@pytest.mark.slow
def test_switching_continuation_reaches_omega_2_and_the_catalogued_saddle():
    """From the grazing point the branch runs to Omega >= 2 with no manual help (the
    switches: the grazing of g = 0, then the passage of M near the body axis 3 at Omega =
    1.98932, where the winding of g changes); continued to Omega = 2 on its last section and
    moved to the paper's g = 0 it is the catalogued Fig. 3 saddle (found by hand on six
    sections): the same period and trace to Newton's accuracy."""
    from taylorball.periodic_catalog import FIG3_SADDLE
    from taylorball.periodic_continuation import (SectionSwitch, continue_arclength, continue_in_omega,
                                                  on_section)

    o = _grazing_orbit()
    br = continue_arclength(o, FIG3_LEVELS, ds=0.2, n_steps=60, direction=1, bounds=(1.8, 2.004),
                            switch=SectionSwitch())
    assert br.omega[-1] > 2.0, (br.stopped, br.switches)
    assert len(br.switches) >= 2
    i = int(np.argmax(br.omega > 2.0))
    last = br.orbits[i]
    assert _returns(last) <= 1e-10
    at2 = continue_in_omega(last, FIG3_LEVELS, [2.0]).orbits[-1]
    on0 = on_section(at2, 0.0)
    assert on0.k == FIG3_SADDLE.k
    # Newton's tolerance on a state of size ~10 is 256 eps; the period and the trace of the
    # float64 solutions agree to ~1e-12 relative (measured), allowed 1e-9 / 1e-8
    assert abs(on0.period - FIG3_SADDLE.period) <= 1e-9 * FIG3_SADDLE.period
    assert abs(on0.trace - FIG3_SADDLE.trace) <= 1e-8


# ---------------------------------------------------------------------------------------
# Omega = 0: families on resonant tori; Omega > 0: their break-up (Poincare-Birkhoff).
# ---------------------------------------------------------------------------------------
#: The elliptic fixed point of the M||gamma map on the Fig. 1 level at Omega = 0 (chart
#: (l, L/G); Newton from (pi/2, 0) finds it, period 0.3822252187), and the chart point above
#: it on the invariant curve with rotation number -1/3 (a root of the rotation number
#: measured over 300 iterations, 2026-11-28): the seed of the period-3 family.
_CENTRE = (math.pi / 2, -0.16103199)
_SEED3 = (math.pi / 2, 0.51408210)


def _params(w):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", tb.UnphysicalParametersWarning)
        return dataclasses.replace(fig1_params(), plane_rate=w)


def _state(p, point):
    return tb.mparallel_states_on_section(p, **FIG1_LEVELS.as_kwargs(), point=point)[0]


def _K2(state):
    return float(np.sum(np.asarray(state[:3], dtype=float) ** 2))


def _on_torus(p, alpha, K2):
    """The state on the ray from the centre at angle alpha (chart) with |K|^2 = K2: a point
    of the invariant curve of the integrable map (|K|^2 is its extra integral at Omega = 0)."""
    from scipy.optimize import brentq

    def f(r):
        return _K2(_state(p, (_CENTRE[0] + r * math.cos(alpha), _CENTRE[1] + r * math.sin(alpha)))) - K2

    r_max = min(0.95, (1 + _CENTRE[1]) / max(1e-9, -math.sin(alpha)) - 1e-9)
    r = brentq(f, 0.3, r_max, xtol=1e-15)
    point = (_CENTRE[0] + r * math.cos(alpha), _CENTRE[1] + r * math.sin(alpha))
    return _state(p, point), point


@pytest.fixture(scope="module")
def torus3():
    p = _params(0.0)
    o = P.periodic_orbit("mparallel", p, _state(p, _SEED3), 3, levels=FIG1_LEVELS)
    return p, o


def test_period3_orbit_at_omega_0_lies_on_a_torus_of_fixed_points(torus3):
    """At Omega = 0 (the Chaplygin ball on a fixed plane: integrable, |K|^2 conserved) Newton
    finds a period-3 orbit whose multipliers are both 1 (a parabolic shear along its family).
    Its whole invariant curve consists of period-3 points: points of the curve |K|^2 = const
    at six other places, built from the chart and the integral alone (no Newton), return to
    themselves after 3 crossings of the section integrator; a curve with |K|^2 changed by
    1e-3 relative does not (a control: the check can fail)."""
    p, o = torus3
    assert o.k == 3 and o.stability == "parabolic"
    # tr A - 2 = 0 at a resonant torus; float64 Jacobian over 3 crossings, entries ~10:
    # measured 9.9e-14, allowed 4096 eps
    assert abs(o.trace - 2.0) <= 4096 * EPS
    # a Jordan-like block: rounding e splits the double multiplier by ~sqrt(e |shear|);
    # measured |mu - 1| = 3.2e-7, allowed 1e-5
    assert np.all(np.abs(o.multipliers - 1.0) <= 1e-5)
    K2 = _K2(o.state)
    sec = tb.poincare_section("mparallel", p, o.state, n_points=3)
    for s in sec.states:  # |K|^2 is an integral along the orbit
        assert abs(_K2(s) - K2) <= 64 * EPS * K2
    for alpha in np.linspace(0.3, 2 * np.pi + 0.3, 6, endpoint=False):
        x, _ = _on_torus(p, float(alpha), K2)
        run = tb.poincare_section("mparallel", p, x, n_points=3)
        d1 = float(np.max(np.abs(np.asarray(run.states[0], dtype=float) - np.asarray(x, dtype=float))))
        d3 = float(np.max(np.abs(np.asarray(run.states[-1], dtype=float) - np.asarray(x, dtype=float))))
        assert d1 > 0.1  # a different point after one crossing: a period-3 point, not a fixed point
        assert d3 <= 1e-11, (alpha, d3)  # |K| ~ 14: measured <= 2.8e-13
    x, _ = _on_torus(p, 0.3, K2 * (1 + 1e-3))
    run = tb.poincare_section("mparallel", p, x, n_points=3)
    assert float(np.max(np.abs(np.asarray(run.states[-1], dtype=float) - np.asarray(x, dtype=float)))) > 1e-4


def test_newton_at_omega_0_converges_to_other_points_of_the_family(torus3):
    """Newton started off the orbit along l converges to other period-3 orbits: the fixed
    points of P^3 are not isolated but a curve, on the same torus (|K|^2 the same)."""
    p, o = torus3
    K2 = _K2(o.state)
    pts = [o.points[0]]
    for dl in (0.05, 0.1):
        q = o.points[0] + np.array([dl, 0.0])
        n = P.periodic_orbit("mparallel", p, _state(p, tuple(q)), 3, levels=FIG1_LEVELS)
        assert abs(n.trace - 2.0) <= 1e-9
        assert abs(_K2(n.state) - K2) <= 1e-9 * K2  # measured <= 1e-12 relative
        assert min(float(np.max(np.abs(n.points[0] - q0))) for q0 in pts) > 0.01
        pts.append(n.points[0])
        sec = tb.poincare_section("mparallel", p, n.state, n_points=3)
        assert float(np.max(np.abs(np.asarray(sec.states[-1] - n.state, dtype=float)))) <= 1e-10


def test_poincare_birkhoff_pair_for_small_omega(torus3):
    """For Omega > 0 the resonant torus breaks into an elliptic and a hyperbolic period-3
    orbit (Poincare-Birkhoff), found by Newton from points of the Omega = 0 torus above and
    below the centre; tr A - 2 has opposite signs and, at first order, grows like Omega
    (measured -0.11275 Omega and +0.11275 Omega at Omega = 0.005 and 0.02)."""
    from taylorball.periodic_search import same_orbit

    _, o = torus3
    K2 = _K2(o.state)
    p0 = _params(0.0)
    split = {}
    for w in (0.005, 0.02):
        p = _params(w)
        found = {}
        for name, alpha in (("top", math.pi / 2), ("bottom", 1.5 * math.pi)):
            _, point = _on_torus(p0, alpha, K2)  # a chart point of the Omega = 0 torus
            found[name] = P.periodic_orbit("mparallel", p, _state(p, point), 3, levels=FIG1_LEVELS)
        e, h = found["top"], found["bottom"]
        assert e.stability == "elliptic" and h.type == "saddle" and not same_orbit(e, h)
        for x in (e, h):
            assert abs(np.prod(x.multipliers) - 1) <= 1e3 * EPS
            sec = tb.poincare_section("mparallel", p, x.state, n_points=3)
            assert float(np.max(np.abs(np.asarray(sec.states[-1] - x.state, dtype=float)))) <= 1e-11
        split[w] = (e.trace - 2.0, h.trace - 2.0)
        assert split[w][0] < 0 < split[w][1]
    # first order in Omega: the ratio 4 of the splittings to 1 % (measured 3.997)
    for j in (0, 1):
        assert abs(split[0.02][j] / split[0.005][j] - 4.0) <= 0.04


# ---------------------------------------------------------------------------------------
# The Fig. 4 ball: an orbit from the q = 1 resonance of the Fig. 3 saddle branch.
# ---------------------------------------------------------------------------------------
def _map_matrix_fd_real128(o, levels, h=1e-7):
    """3x3 matrix of P^k on the tangent space of section and level at the asymmetric ball's
    orbit ``o``: central differences along an orthonormal tangent basis (SVD written here),
    every image by the real128 section integrator, ``J C^-1`` in that basis."""
    import heyoka as hy

    from taylorball._propagate import start_state

    probq = o.problem.replace(spec=tb.numbers.resolve_fp_type(hy.real128), tol=None)
    geo = P._eval_geo(o.problem, o.g0, o.internal)
    tq = P._level_targets(probq, geo.names, levels)
    ctxq = P._Ctx(probq, o.g0, 1, o.k, probq.spec.array([tq[n] for n in geo.names]), False, 1e4)
    G = np.vstack([np.asarray(geo.grad_e, dtype=float)[None, :], np.asarray(geo.grad_c, dtype=float)])
    V = np.linalg.svd(G)[2][G.shape[0]:].T
    assert V.shape == (9, 3)
    xq = probq.spec.array(o.internal)
    J, C = np.zeros((3, 3)), np.zeros((3, 3))
    for j in range(3):
        img, dom = [], []
        for sgn in (1, -1):
            xs = P._to_level(ctxq, xq + probq.spec.array(sgn * h * V[:, j]), 20.0)
            p = P.public_state(probq.system, probq.pars, xs, probq.spec)
            sec = tb.poincare_section("reduced", o.problem.params, p, n_points=o.k, g0=o.g0, fp_type=hy.real128)
            img.append(np.asarray(start_state(probq, sec.states[-1], project_state=True), dtype=object))
            dom.append(np.asarray(xs, dtype=object))
        J[:, j] = V.T @ ((img[0] - img[1]).astype(float) / (2 * h))
        C[:, j] = V.T @ ((dom[0] - dom[1]).astype(float) / (2 * h))
    return J @ np.linalg.inv(C)


def test_fig4b_orbit_from_the_q1_resonance():
    """The catalogued orbit of the Fig. 4 ball on the Fig. 4b level at Omega = 1.42312 (from
    the saddle branch's theta = 2 pi): the section integrator returns to it after 19
    crossings; it is on the level; its multipliers agree with central differences of the
    real128 section map (not the variational equations)."""
    from taylorball.paper import FIG4B_LEVELS
    from taylorball.periodic_catalog import FIG4B_SADDLE_Q1, catalog_orbit

    e = FIG4B_SADDLE_Q1
    o = catalog_orbit(e)
    assert o.k == 19 and o.type == "saddle" and o.symmetric is None  # no reversor maps its points onto themselves
    sec = tb.poincare_section("reduced", e.ball, o.state, n_points=o.k, g0=e.g0)
    assert abs(sec.times[-1] - o.period) <= 1e3 * EPS * o.period
    assert float(np.max(np.abs(sec.states[-1] - o.state))) <= 1e-10  # multiplier 2.39 over t ~ 37
    lv = tb.integrals("reduced", e.ball, o.state)
    assert abs(lv["E"] - FIG4B_LEVELS.h) <= 64 * EPS * 10 and abs(lv["M_gamma"] - FIG4B_LEVELS.M_gamma) <= 64 * EPS * 10
    A = _map_matrix_fd_real128(o, FIG4B_LEVELS)
    mu = np.sort(np.linalg.eigvals(A).real)
    # h = 1e-7: truncation ~h^2 |P'''|, real128 rounding ~1e-32 / h; measured agreement 5e-13
    # (trace 3.804408529279013 against 3.8044085292794736), allowed 1e-9
    assert np.allclose(mu, np.sort(o.multipliers.real), rtol=0, atol=1e-9), (mu, o.multipliers)
    assert abs(np.linalg.det(A) - 1) <= 1e-9  # volume preserved on the level: measured 1.6e-13
