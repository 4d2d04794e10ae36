"""Charts of the paper: the section-4 variables (K, r1, r2, l, g) with the inverse from the
energy equation, and the Andoyer--Deprit chart of section 5 (corrected, erratum E3)."""

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import assume, given
from hypothesis import strategies as st

import taylorball as tb
from taylorball.charts import (
    CHART_SINGULAR_TOL,
    andoyer_deprit_printed,
    angles_to_vectors,
    mparallel_chart,
    mparallel_state_from_chart,
    mparallel_states_on_section,
    reduced_chart,
    reduced_state_from_chart,
    section_admissible_sample,
    states_on_section,
)
from taylorball.sections import _event_cfunc

from .conftest import FIG5, HOMOGENEOUS, SYMMETRIC, reduced_states

EPS = 2.0**-52
TAU = 2 * math.pi
FIG1 = None


def fig1():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", tb.UnphysicalParametersWarning)
        return tb.MParallelParams(a=(1.0, 2.0, 3.0), d=4.0, plane_rate=0.5)


def _angle_diff(a, b):
    return abs(math.remainder(float(a) - float(b), TAU))


# ---------------------------------------------------------------------------------------
# The chart formulas, symbolically.
# ---------------------------------------------------------------------------------------
def test_chart_formulas_satisfy_the_constraints_identically():
    """|gamma|^2 = 1 and (M, gamma) = M_gamma for all (K, l, g): sympy, not numbers. The
    paper's printed Andoyer--Deprit gamma fails both (erratum E3) but agrees at g = 0."""
    C, Mg = sp.symbols("C M_gamma", positive=True)
    K, l, g = sp.symbols("K l g", real=True)
    q = sp.sqrt(1 - K**2 / C**2)
    mu, s = Mg / C, sp.sqrt(1 - Mg**2 / C**2)
    M = [C * q * sp.sin(l), C * q * sp.cos(l), K]
    gam = [(mu * q + s * K / C * sp.cos(g)) * sp.sin(l) + s * sp.sin(g) * sp.cos(l),
           (mu * q + s * K / C * sp.cos(g)) * sp.cos(l) - s * sp.sin(g) * sp.sin(l),
           mu * K / C - s * q * sp.cos(g)]
    assert sp.simplify(sp.expand(sum(x**2 for x in gam)) - 1) == 0
    assert sp.simplify(sp.expand(sum(a * b for a, b in zip(M, gam))) - Mg) == 0
    # the numerical implementation is the same formula
    vals = {C: 10.0, Mg: 6.0, K: 3.0, l: 1.1, g: 2.3}
    M_num, g_num = angles_to_vectors(10.0, 6.0, 3.0, 1.1, 2.3)
    for a, b in zip(gam, g_num):
        assert abs(float(a.subs(vals)) - float(b)) <= 4 * EPS  # a few roundings of O(1) terms
    # printed chart: |gamma|^2 - 1 and (K, gamma) - lambda are far from 0 at g = 2.3 ...
    Kp, gp = andoyer_deprit_printed(3.0, 10.0, 1.1, 2.3, 6.0)
    assert abs(sum(x * x for x in gp) - 1) > 1e-2
    assert abs(sum(a * b for a, b in zip(Kp, gp)) - 6.0) > 1e-2
    # ... and it coincides with the corrected one on the section g = 0
    Kp, gp = andoyer_deprit_printed(3.0, 10.0, 1.1, 0.0, 6.0)
    _, gc = angles_to_vectors(10.0, 6.0, 3.0, 1.1, 0.0)
    assert max(abs(a - b) for a, b in zip(gp, gc)) <= 4 * EPS


# ---------------------------------------------------------------------------------------
# Round trips.
# ---------------------------------------------------------------------------------------
@given(reduced_states(omega_scale=1.0, r_scale=3.0))
def test_state_chart_state_round_trip(state):
    try:
        ch = reduced_chart(FIG5, state)
    except tb.ChartError:
        # refused only at (near) a singular point of the chart
        c = tb.get_system("reduced").constants(FIG5.pars)
        K = np.array(tb.model.K_from_omega(c.I, c.d, tuple(state[3:6]), tuple(state[0:3])))
        M = K - c.ma * c.Omega * state[6:9]
        C = np.linalg.norm(M)
        if C == 0:
            return  # refused with "M != 0"
        # g = atan2(num, den) with |(num, den)| = C^2 q s: q = sin(M, e3), s = sin(M, gamma);
        # the chart refuses q s <= 1e-12 (and q <= 1e-12 for l)
        q = math.hypot(M[0], M[1]) / C
        s = np.linalg.norm(np.cross(M, state[3:6])) / C
        assert q <= 1e-11 or q * s <= 1e-11, (q, s)
        return
    g = state[3:6]
    args = {k: float(ch[k]) for k in ("C", "M_gamma", "K", "l", "g", "r1", "r2")}
    if min(abs(g[2]), math.hypot(g[0], g[1])) < 0.99 * CHART_SINGULAR_TOL:
        with pytest.raises(tb.ChartError, match="gamma3"):
            reduced_state_from_chart(FIG5, **args)
        return
    assume(min(abs(g[2]), math.hypot(g[0], g[1])) > 1.01 * CHART_SINGULAR_TOL)
    back = reduced_state_from_chart(FIG5, **args)
    # conditioning: R from (r1, r2) divides by gamma3 and |gamma_h|^2; omega by Itilde
    cond = 1 / min(abs(g[2]), math.hypot(g[0], g[1])) ** 2 * (1 + np.linalg.norm(state))
    err = np.max(np.abs(back - state))
    assert err <= 256 * EPS * cond, (err, cond)  # ~30 roundings through M, angles, R, omega


@given(st.floats(0.5, 20.0), st.floats(-0.95, 0.95), st.floats(-0.999, 0.999),
       st.floats(0, TAU, exclude_max=True), st.floats(0, TAU, exclude_max=True),
       st.floats(-5, 5), st.floats(-5, 5))
def test_chart_state_chart_round_trip(C, mg, k, l, g, r1, r2):
    M_gamma, K = mg * C, k * C
    try:
        x = reduced_state_from_chart(SYMMETRIC, C=C, M_gamma=M_gamma, K=K, l=l, g=g, r1=r1, r2=r2)
    except tb.ChartError:
        _, gam = angles_to_vectors(C, M_gamma, K, l, g)
        assert abs(gam[2]) < CHART_SINGULAR_TOL or math.hypot(gam[0], gam[1]) < CHART_SINGULAR_TOL
        return
    ch = reduced_chart(SYMMETRIC, x)
    q = math.sqrt(1 - k * k)
    s = math.sqrt(1 - mg * mg)
    # the chart recomputes M = Itilde omega - m a Omega R from the state: rounding of the
    # larger of its two terms, relative to C
    amp = 1 + (1 + SYMMETRIC.mass * SYMMETRIC.radius * abs(SYMMETRIC.plane_rate)) * np.linalg.norm(x[6:9]) / C
    # l is ill-conditioned as q -> 0 (M along e3), g as q s -> 0 (and M || gamma)
    assert _angle_diff(ch["l"], l) <= 64 * EPS * amp / q
    assert _angle_diff(ch["g"], g) <= 64 * EPS * amp / (q * s)
    for key, ref in (("C", C), ("M_gamma", M_gamma), ("K", K)):
        assert abs(float(ch[key]) - ref) <= 64 * EPS * C * amp, key
    assert abs(float(ch["r1"]) - r1) <= 64 * EPS * (abs(r1) + abs(r2) + 1)
    assert abs(float(ch["r2"]) - r2) <= 64 * EPS * (abs(r1) + abs(r2) + 1)


def test_singular_points_give_clear_errors():
    # gamma3 = 0: choose K, g with mu k = s q cos g
    with pytest.raises(tb.ChartError, match="gamma3"):
        reduced_state_from_chart(FIG5, C=10.0, M_gamma=0.0, K=0.0, l=0.3, g=math.pi / 2, r1=1.0, r2=0.5)
    with pytest.raises(tb.ChartError, match="mparallel"):
        states_on_section(FIG5, C=10.0, M_gamma=10.0, h=5.0, point=(0.1, 0.2, 0.3))
    with pytest.raises(tb.ChartError, match="C = |M|"):
        states_on_section(FIG5, C=-1.0, M_gamma=0.0, h=5.0, point=(0.1, 0.2, 0.3))
    with pytest.raises(tb.ChartError, match=r"\[-C, C\]"):
        reduced_state_from_chart(FIG5, C=1.0, M_gamma=0.0, K=2.0, l=0.0, g=0.0, r1=0.0, r2=0.0)
    with pytest.raises(tb.ChartError, match="point"):
        states_on_section(FIG5, C=10.0, M_gamma=6.0, h=5.0, point=(0.1, 0.2))
    # M parallel to gamma: the forward chart refuses it
    g = np.array([0.0, 0.6, 0.8])
    w = tb.model.omega_from_K(tb.get_system("reduced").constants(FIG5.pars).A, FIG5.d, tuple(g), tuple(3.0 * g))
    with pytest.raises(tb.ChartError, match="parallel"):
        reduced_chart(FIG5, np.concatenate([w, g, [0.0, 0.0, 0.0]]))


# ---------------------------------------------------------------------------------------
# K from the energy: all roots, the right levels, the branch.
# ---------------------------------------------------------------------------------------
CAPTIONS = [(HOMOGENEOUS, 6.0), (SYMMETRIC, 6.0), (FIG5, 2.0), (FIG5, 6.0)]


@pytest.mark.parametrize("params, H", CAPTIONS, ids=["fig2", "fig3", "fig4a", "fig4b"])
def test_states_on_section_lie_on_the_level_set(params, H):
    sample = section_admissible_sample(params, C=10.0, M_gamma=H, h=5.0, n=12, seed=1, direction=None)
    assert 0 < sample["fraction"] <= 1
    event = _event_cfunc("reduced", (float, None), 0.0)
    sysm = tb.get_system("reduced")
    pars = np.array(params.pars)
    for p in sample["points"][:4]:
        states, info = states_on_section(params, C=10.0, M_gamma=H, h=5.0, point=p, return_info=True)
        for x, gdot in zip(states, info["g_dot"]):
            I = tb.integrals("reduced", params, x)
            S = tb.integral_scales("reduced", params, x)
            # levels to rounding: the bisection stops at the last bit of theta, and E, C2,
            # M_gamma are sums of ~20 rounded products of O(scale) terms
            assert abs(I["C2"] - 100.0) <= 64 * EPS * S["C2"]
            assert abs(I["M_gamma"] - H) <= 64 * EPS * S["M_gamma"]
            assert abs(I["E"] - 5.0) <= 1024 * EPS * S["E"]  # root in theta: |dE/dtheta| eps amplification
            ch = reduced_chart(params, x)
            assert _angle_diff(ch["l"], p[0]) <= 1e-12 and _angle_diff(ch["g"], 0.0) <= 1e-12
            assert abs(ch["r1"] - p[1]) <= 1e-12 * (1 + abs(p[1])) and abs(ch["r2"] - p[2]) <= 1e-12 * (1 + abs(p[2]))
            # branch: the sign of dg/dt agrees with the sign of de/dt of the section's event
            # function, derived by heyoka (hy.diff) from its own expression
            internal = np.array(sysm.to_internal(tuple(pars), tuple(x)))
            e, de = event(internal, pars)
            assert abs(e) <= 64 * EPS and np.sign(de) == np.sign(gdot)


def _brute_force_root_count(params, C, Mg, h, point, n=200_001):
    """Sign changes of E(K) - h on a fine grid in K itself (not theta), with E from the
    public integrals of the chart states: an independent count."""
    K = np.linspace(-C, C, n)[1:-1]
    _, gam = angles_to_vectors(C, Mg, K, point[0], 0.0)
    ok = np.minimum(np.abs(gam[2]), np.hypot(gam[0], gam[1])) >= CHART_SINGULAR_TOL
    E = np.full(K.shape, np.nan)
    x = reduced_state_from_chart(params, C=C, M_gamma=Mg, K=K[ok], l=point[0], g=0.0, r1=point[1], r2=point[2])
    E[ok] = tb.integrals("reduced", params, x, check=False)["E"] - h
    return int(np.sum(E[:-1] * E[1:] < 0))  # NaN (singular K) never counts


@pytest.mark.parametrize("params, H", CAPTIONS[2:], ids=["fig4a", "fig4b"])
def test_every_root_is_found(params, H):
    rng = np.random.default_rng(7)
    seen_multi = False
    for _ in range(12):
        p = (rng.uniform(0, TAU), rng.uniform(-6, 6), rng.uniform(-6, 6))
        try:
            states, info = states_on_section(params, C=10.0, M_gamma=H, h=5.0, point=p, return_info=True)
            n = len(states)
        except tb.EmptyLevelError:
            n = 0
        assert n == _brute_force_root_count(params, 10.0, H, 5.0, p), p
        seen_multi |= n >= 2
    assert seen_multi  # the test exercised points with several roots


def test_empty_point_and_direction_filter():
    with pytest.raises(tb.EmptyLevelError, match="admissible region"):
        states_on_section(FIG5, C=10.0, M_gamma=2.0, h=5.0, point=(0.0, 40.0, 40.0))
    p = section_admissible_sample(FIG5, C=10.0, M_gamma=2.0, h=5.0, n=5, seed=3)["points"][0]
    _, info = states_on_section(FIG5, C=10.0, M_gamma=2.0, h=5.0, point=p, return_info=True)
    for d in (1, -1):
        if np.any(np.sign(info["g_dot"]) == d):
            _, i2 = states_on_section(FIG5, C=10.0, M_gamma=2.0, h=5.0, point=p, direction=d, return_info=True)
            assert np.all(np.sign(i2["g_dot"]) == d)
        else:
            with pytest.raises(tb.EmptyLevelError, match="direction"):
                states_on_section(FIG5, C=10.0, M_gamma=2.0, h=5.0, point=p, direction=d)


def test_section_points_are_chart_points_of_their_states():
    """The section engine and the inverse chart agree: each crossing's (l, r1, r2) maps back
    (through the energy equation) to a set of states that contains the crossing state."""
    p = section_admissible_sample(FIG5, C=10.0, M_gamma=6.0, h=5.0, n=5, seed=2)["points"][0]
    x0 = states_on_section(FIG5, C=10.0, M_gamma=6.0, h=5.0, point=p, direction=1)[0]
    r = tb.poincare_section("reduced", FIG5, x0, n_points=5)
    for pt, x in zip(r.points, r.states):
        cands = states_on_section(FIG5, C=10.0, M_gamma=6.0, h=5.0, point=pt, direction=1)
        # the crossing state drifts off the exact levels by ~eps per step: 1e-9 relative
        assert np.min(np.max(np.abs(cands - x), axis=1)) <= 1e-9 * (1 + np.max(np.abs(x)))


# ---------------------------------------------------------------------------------------
# Andoyer--Deprit chart (section 5).
# ---------------------------------------------------------------------------------------
@given(st.floats(-3, 3).filter(lambda v: abs(v) > 1e-3), st.floats(1.01, 20.0), st.floats(-0.999, 0.999),
       st.floats(0, TAU, exclude_max=True), st.floats(0, TAU, exclude_max=True))
def test_andoyer_deprit_round_trip(lam, G_over, ratio, l, g):
    G = abs(lam) * G_over
    x = mparallel_state_from_chart(lam=lam, L=ratio * G, G=G, l=l, g=g)
    assert abs(x[3:] @ x[3:] - 1) <= 8 * EPS
    assert abs(x[:3] @ x[3:] - lam) <= 16 * EPS * G
    ch = mparallel_chart(x)
    q, s = math.sqrt(1 - ratio**2), math.sqrt(1 - 1 / G_over**2)
    assert abs(ch["G"] - G) <= 16 * EPS * G and abs(ch["L/G"] - ratio) <= 16 * EPS
    assert _angle_diff(ch["l"], l) <= 64 * EPS / q
    assert _angle_diff(ch["g"], g) <= 64 * EPS / (q * s)


def test_mparallel_states_on_section_fig1():
    p = fig1()
    rng = np.random.default_rng(5)
    for _ in range(6):
        pt = (rng.uniform(0, TAU), rng.uniform(-0.99, 0.99))
        states = mparallel_states_on_section(p, lam=2.0, h=100.0, point=pt)
        for x in states:
            I = tb.integrals("mparallel", p, x)
            S = tb.integral_scales("mparallel", p, x)
            assert abs(I["lambda"] - 2.0) <= 32 * EPS * S["lambda"]
            assert abs(I["E"] - 100.0) <= 1024 * EPS * S["E"]  # root of lambda^2 Q(mu) = h mu^2
            ch = mparallel_chart(x)
            assert _angle_diff(ch["l"], pt[0]) <= 1e-12 and abs(ch["L/G"] - pt[1]) <= 1e-12
            assert _angle_diff(ch["g"], 0.0) <= 1e-12
    with pytest.raises(tb.ChartError, match="L/G"):
        mparallel_states_on_section(p, lam=2.0, h=100.0, point=(0.0, 1.5))


def test_root_finder_finds_double_roots_and_no_false_ones():
    """The 1D root search behind states_on_section on functions with known roots: simple
    roots by bisection, double roots (no sign change) by the golden-section search of
    grid minima of |f|, and nothing where |f| has a minimum that is not a zero."""
    from taylorball.charts import _roots_1d

    cases = [
        (lambda x: (x - 1) ** 2, [1.0], [2]),
        (lambda x: (x - 1) ** 2 * (x - 2), [1.0, 2.0], [2, 1]),
        (lambda x: (x - 0.3) ** 2 * (x - 2.5) ** 2, [0.3, 2.5], [2, 2]),
        (lambda x: np.cos(x) ** 2, [np.pi / 2], [2]),
        (lambda x: (x - 1) ** 2 + 1e-6, [], []),  # a minimum 1e-6 above zero: no root
        (lambda x: np.sin(3 * x) + 1.5, [], []),
    ]
    for f, roots, mult in cases:
        r, m = _roots_1d(f, 0.0, np.pi, 801)
        assert list(m) == mult, (r, m, roots)
        # simple roots to the last bits; a double root only to ~sqrt(eps) (|f| ~ (x - x*)^2
        # is flat there): 1e-6 on the bracket of 2 grid steps
        for a, b, k in zip(r, roots, m):
            assert abs(a - b) <= (4 * np.spacing(b) if k == 1 else 1e-6), (a, b)


def test_root_search_of_many_functions_is_each_ones_own():
    """_roots_many (the vectorised search megno_map uses for a grid row) gives each function
    exactly the roots and multiplicities _roots_1d gives it alone, bit for bit: the double
    roots' golden-section brackets converge at different iterations (different minima), and
    a function's brackets are frozen when its own search would stop."""
    from taylorball.charts import _roots_1d, _roots_many

    shifts = np.array([0.3, 1.0, 1.7, 2.5, 0.9])
    fs = [lambda x, s=s: (x - s) ** 2 * (x - 2.9) for s in shifts]  # a double and a simple root each
    fs += [lambda x: np.cos(x) ** 2, lambda x: np.sin(3 * x) + 1.5, lambda x: (x - 1) ** 2 + 1e-6]

    def many(which, x):
        return np.choose(which, [f(x) for f in fs])

    got = _roots_many(many, len(fs), 0.0, np.pi, 801)
    for f, (r, m) in zip(fs, got):
        r1, m1 = _roots_1d(f, 0.0, np.pi, 801)
        assert np.array_equal(r, r1) and np.array_equal(m, m1), (r, r1, m, m1)
    assert [list(m) for _, m in got[:5]] == [[2, 1]] * 4 + [[2, 1]] and len(got[6][0]) == 0


def test_chart_of_one_state_feeds_its_inverse(fig5):
    """reduced_chart of one state gives numbers (not 0-d arrays), so its g can be handed to
    states_on_section as g0 and the state comes back among the roots (found by helper H12:
    a 0-d g was refused as g0)."""
    from taylorball.paper import FIG4A_LEVELS

    lv = FIG4A_LEVELS.as_kwargs()
    reg = tb.section_admissible_sample(fig5, **lv, n=2)
    x0 = tb.states_on_section(fig5, **lv, point=reg["points"][0], direction=1)[0]
    ch = tb.reduced_chart(fig5, x0)
    assert all(np.ndim(ch[k]) == 0 and not isinstance(ch[k], np.ndarray) for k in ("l", "g", "K", "r1", "r2"))
    xs = tb.states_on_section(fig5, **lv, point=(ch["l"], ch["r1"], ch["r2"]), g0=ch["g"])
    # the chart and its inverse are each exact to rounding: a few hundred eps of the state's size
    assert min(np.max(np.abs(x - x0)) for x in xs) <= 512 * np.finfo(float).eps * np.max(np.abs(x0))


@pytest.mark.parametrize("params, H", CAPTIONS, ids=["fig2", "fig3", "fig4a", "fig4b"])
def test_section_sheet_is_the_root_index(params, H):
    """The sheet of a state is its index in the list states_on_section gives for its chart
    point (a root finder with bisection and double-root search on a 2001-point grid, versus
    sign changes on 801 points here)."""
    sample = section_admissible_sample(params, C=10.0, M_gamma=H, h=5.0, n=40, seed=2, direction=1)
    n_multi = 0
    for p in sample["points"]:
        states, info = states_on_section(params, C=10.0, M_gamma=H, h=5.0, point=p, direction=1, return_info=True)
        theta = np.arccos(np.clip(info["K"] / 10.0, -1, 1))
        if len(theta) > 1 and np.min(np.abs(np.diff(theta))) < 3 * math.pi / 800:
            continue  # two roots within a grid step (next to a fold): documented as ambiguous
        sheet = tb.section_sheet(params, states, C=10.0, M_gamma=H, h=5.0)
        assert sheet.tolist() == list(range(len(states))), (p, info["K"])
        n_multi += len(states) > 1
    assert n_multi >= 3  # the test exercised points with several sheets


def test_section_sheet_rejects_bad_input():
    from taylorball.paper import FIG4A_LEVELS

    lev = FIG4A_LEVELS.as_kwargs()
    x = states_on_section(FIG5, **lev, point=(2.0, 2.5, 1.0), direction=1)
    with pytest.raises(tb.ChartError, match="level set"):
        tb.section_sheet(FIG5, x, **{**lev, "M_gamma": 6.0})
    with pytest.raises(tb.UsageError, match="direction"):
        tb.section_sheet(FIG5, x, **lev, direction=0)
    with pytest.raises(tb.ChartError, match="shape"):
        tb.section_sheet(FIG5, x[:, :6], **lev)
    with pytest.raises(tb.ChartError, match="shape"):
        tb.section_sheet(FIG5, "abc", **lev)
    with pytest.raises(tb.UsageError, match="chunk"):
        tb.section_sheet(FIG5, x, **lev, chunk=0)
    with pytest.raises(tb.ChartError, match="h"):
        tb.section_sheet(FIG5, x, **{**lev, "h": float("nan")})
    assert tb.section_sheet(FIG5, np.empty((0, 9)), **lev).shape == (0,)


@pytest.mark.parametrize("H, direction, kw", [(2.0, 1, {}), (6.0, None, {}), (2.0, -1, {"r_box": 8.0}),
                                             (6.0, 1, {"max_candidates": 7})])
def test_admissible_sample_blocks_equal_one_candidate_at_a_time(H, direction, kw):
    """section_admissible_sample searches its candidates in blocks (one vectorised root
    search): its points, roots, states and counts are bit-identical to drawing the same
    candidates one at a time and asking states_on_section about each (the reference here),
    and a Generator passed as the seed is left in the same state."""
    from taylorball.errors import ChartError, EmptyLevelError

    lv = dict(C=10.0, M_gamma=H, h=5.0)
    n = 15

    def one(p):
        try:
            return states_on_section(FIG5, **lv, point=p, direction=direction, n_grid=801, return_info=True)
        except (EmptyLevelError, ChartError):
            return None

    def reference(rng):
        r_box = kw.get("r_box")
        if r_box is None:
            r_box = 1.0
            for _ in range(12):
                edge = [(rng.uniform(0, 2 * math.pi), r_box * math.cos(a), r_box * math.sin(a))
                        for a in rng.uniform(0, 2 * math.pi, 48)]
                if all(one(p) is None for p in edge):
                    break
                r_box *= 2.0
        pts, Ks, states, n_cand = [], [], [], 0
        while len(pts) < n and n_cand < kw.get("max_candidates", 100 * n):
            n_cand += 1
            p = (rng.uniform(0, 2 * math.pi), rng.uniform(-r_box, r_box), rng.uniform(-r_box, r_box))
            found = one(p)
            if found is not None:
                pts.append(p)
                Ks.append(found[1]["K"][0])
                states.append(found[0])
        return r_box, n_cand, np.array(pts), np.array(Ks), states

    for seed, ref_rng in ((4, np.random.default_rng(4)), (np.random.default_rng(9), np.random.default_rng(9))):
        got = section_admissible_sample(FIG5, **lv, n=n, seed=seed, direction=direction, **kw)
        r_box, n_cand, pts, Ks, states = reference(ref_rng)
        assert got["r_box"] == r_box and got["n_candidates"] == n_cand
        assert np.array_equal(got["points"], pts) and np.array_equal(got["K"], Ks)
        assert len(got["states"]) == len(states)
        assert all(np.array_equal(a, b) for a, b in zip(got["states"], states))
        if isinstance(seed, np.random.Generator):
            assert seed.uniform() == ref_rng.uniform()
