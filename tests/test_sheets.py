"""Sheets of the section-4 map across gamma3 = 0 (docs/chaos.md, "Sheets of the section
across gamma3 = 0"): the energy equation in K has a pole at the one root K* of gamma3 = 0,
two roots pass through each other there as r1 changes sign (a node, slopes -M_gamma / u with
u the contact point's height R3 at gamma3 = 0), and the sheet label (orientation
sign(gamma3 dE/dK), distance |K - K*|) follows each branch where the root index swaps."""

import math

import numpy as np
import pytest

import taylorball as tb
from taylorball.charts import _degenerate_K, angles_to_vectors
from taylorball.model import ball_constants, omega_from_K
from taylorball.paper import FIG4_BALL, FIG4B_LEVELS

EPS = 2.0**-52
C, MG, H = FIG4B_LEVELS.C, FIG4B_LEVELS.M_gamma, FIG4B_LEVELS.h
LEV = FIG4B_LEVELS.as_kwargs()


def test_gamma3_vanishes_at_one_K_whatever_the_chart_point():
    """K* of the closed form is where the chart's gamma3 vanishes, for every l (and g0);
    sqrt(C^2 - M_gamma^2) on g0 = 0. gamma3 is a sum of products of order 1: a few eps."""
    assert _degenerate_K(C, MG, 0.0) == pytest.approx(math.sqrt(C * C - MG * MG), rel=4 * EPS)
    for g0 in (0.0, 0.4, 1.3, 2.0, -2.9):
        for mg in (6.0, -3.0, 0.5):
            ks = _degenerate_K(C, mg, g0)
            assert abs(ks) < C
            l = np.linspace(0.0, 2 * math.pi, 7)
            g3 = angles_to_vectors(C, mg, np.full(l.size, ks), l, g0)[1][2]
            assert np.max(np.abs(g3)) <= 8 * EPS, (g0, mg, g3)
            # and gamma3 changes sign there (a simple zero: the pole of the energy equation)
            lo, hi = (angles_to_vectors(C, mg, ks + s * 1e-3, 0.0, g0)[1][2] for s in (-1, 1))
            assert lo * hi < 0


def test_second_pole_only_on_g0_0_and_pi():
    """K** = -M_gamma cos g0, where gamma1 = gamma2 = 0 (|gamma3| = 1), exists on g0 = 0 and
    pi only: elsewhere |gamma3| <= sqrt(mu^2 + s^2 cos^2 g0) < 1 on the whole K range."""
    from taylorball.charts import _sheet_poles

    for g0 in (0.0, math.pi):
        ks, kf = _sheet_poles(C, MG, g0)
        assert kf == -MG * math.cos(g0)
        g = angles_to_vectors(C, MG, kf, 0.7, g0)[1]
        assert math.hypot(g[0], g[1]) <= 8 * EPS and ks == pytest.approx(_degenerate_K(C, MG, g0), abs=0)
    for g0 in (0.3, 2.0, -1.0):
        assert _sheet_poles(C, MG, g0)[1] is None
        K = np.linspace(-C, C, 2001)
        g3 = angles_to_vectors(C, MG, K, 0.7, g0)[1][2]
        mu = MG / C
        bound = math.sqrt(mu * mu + (1 - mu * mu) * math.cos(g0) ** 2)
        assert np.max(np.abs(g3)) <= bound + 8 * EPS < 1


def _heights_at_gamma3_zero(l, r2):
    """The roots u of E(R3) = h for the states with K = K*, gamma3 = 0, chart r1 = 0, r2 (R
    built directly with (R, gamma) = 0, the energy from tb.integrals: not the chart's energy
    equation). E is quadratic in R3; three samples determine it exactly up to rounding."""
    c = ball_constants(FIG4_BALL.pars)
    ks = _degenerate_K(C, MG, 0.0)
    M, gam = angles_to_vectors(C, MG, ks, l, 0.0)
    rho2 = gam[0] ** 2 + gam[1] ** 2

    def energy(t):
        R = (r2 * gam[1] / rho2, -r2 * gam[0] / rho2, t)
        Kv = tuple(M[i] + c.ma * c.Omega * R[i] for i in range(3))
        x = np.array([*omega_from_K(c.A, c.d, gam, Kv), *gam, *R], dtype=float)
        return float(tb.integrals("reduced", FIG4_BALL, x)["E"])

    em, e0, ep = energy(-1.0), energy(0.0), energy(1.0)
    e2, e1 = (em + ep - 2 * e0) / 2, (ep - em) / 2
    # the R3^2 coefficient at gamma3 = 0: -m Omega^2 I3 / (2 (I3 + m a^2)) = -8/29
    assert e2 == pytest.approx(-8.0 / 29.0, rel=1e-12)
    return np.sort(np.roots([e2, e1, e0 - H]).real)


@pytest.mark.parametrize("r2", [-4.7, 0.3])
def test_two_roots_cross_at_K_star_with_slopes_minus_M_gamma_over_u(r2):
    """At r1 -> 0 two roots K pass through K* with dK/dr1 = -M_gamma / u (u: the two
    heights R3 at gamma3 = 0, computed independently): the symmetric difference over
    r1 = +-delta matches to O(delta^2) (measured rel. 2.7e-4 and 4e-8 at delta = 0.005 for
    r2 = -4.7), and their order in K is exchanged, while the sheet label of each is kept."""
    u = _heights_at_gamma3_zero(0.0, r2)
    ks = _degenerate_K(C, MG, 0.0)
    d = 0.005
    found = {s: tb.states_on_section(FIG4_BALL, **LEV, point=(0.0, s * d, r2), direction=None, return_info=True)
             for s in (-1, 1)}
    for uu in u:
        slope = -MG / uu
        idx = {s: int(np.argmin(np.abs(found[s][1]["K"] - (ks + slope * s * d)))) for s in (-1, 1)}
        Km, Kp = (float(found[s][1]["K"][idx[s]]) for s in (-1, 1))
        # second-order error: |K''| d / |slope| with K'' up to ~100 (the steep branch): 1e-3
        assert (Kp - Km) / (2 * d) == pytest.approx(slope, rel=1e-3), (uu, Km, Kp)
        # the states converge to the one state with gamma3 = 0 and R3 = u
        xm, xp = (found[s][0][idx[s]] for s in (-1, 1))
        assert abs(xm[5]) < 0.02 and abs(xp[5]) < 0.02 and xm[5] * xp[5] < 0  # gamma3 changes sign
        assert xm[8] == pytest.approx(uu, abs=0.02) and xp[8] == pytest.approx(uu, abs=0.02)
        # same sheet label on both sides; the root index of the pair is exchanged
        assert found[-1][1]["sheet"][idx[-1]] == found[1][1]["sheet"][idx[1]]
    ids = {s: [int(np.argmin(np.abs(found[s][1]["K"] - (ks - MG / uu * s * d)))) for uu in u] for s in (-1, 1)}
    order = {s: np.argsort(found[s][1]["K"][ids[s]]) for s in (-1, 1)}
    assert list(order[-1]) == list(order[1][::-1])  # the pair's order in K is reversed


def _line(r2, r1s, direction=1):
    from taylorball.charts import _ball, _section_states

    return _section_states(_ball(FIG4_BALL), C, MG, H, 0.0, r1s, np.full(r1s.size, r2), 0.0, direction, 2001)


@pytest.mark.parametrize("r2, labels", [(-4.7, (0, 1)), (0.3, (0,))])
def test_sheet_labelled_states_are_continuous_across_r1_zero(r2, labels):
    """On a fine line of chart points through r1 = 0 the state of each sheet label moves
    continuously: its K by at most the grid step times a bound on |dK/dr1| (twice the
    largest node slope M_gamma / |u|, 13.5 at r2 = -4.7: the steep branch is steepest near
    the node; measured 15.8 step at most), the whole state by at most 10 steps (measured 4.7:
    the steep branch, |dx/dK| < 1). Under root index 0 (r2 = -4.7) the state jumps at r1 = 0
    by the difference of the two heights u (9.1): the two branches meet at K* (K itself only
    kinks there, min of two crossing lines), not in state space."""
    r1s = np.linspace(-0.5, 0.5, 200)  # r1 = 0 itself is not a grid point (R3 = 0/0 there)
    step = r1s[1] - r1s[0]
    u = _heights_at_gamma3_zero(0.0, r2)
    bound = 2 * MG / np.min(np.abs(u)) * step
    pts = _line(r2, r1s)
    assert not any(isinstance(f, Exception) for f in pts)
    for k in labels:
        assert all(np.sum(f[1]["sheet"] == k) == 1 for f in pts), k  # the sheet lives on the whole line
        K = np.array([f[1]["K"][f[1]["sheet"] == k][0] for f in pts])
        X = np.array([f[0][f[1]["sheet"] == k][0] for f in pts])
        assert np.max(np.abs(np.diff(K))) <= bound, (k, np.max(np.abs(np.diff(K))), bound)
        assert np.max(np.abs(np.diff(X, axis=0))) <= 10 * step, k
    # the root index of sheet 0 changes along the line (the pair through K* swaps)
    assert len({int(np.flatnonzero(f[1]["sheet"] == 0)[0]) for f in pts}) > 1
    if r2 == -4.7:  # two states on the whole line: root 0 is sheet 0 on one side, sheet 1 on the other
        X0 = np.array([f[0][0] for f in pts])
        jump = np.max(np.abs(np.diff(X0, axis=0)), axis=1)
        assert np.argmax(jump) == 99 and np.max(jump) >= (u[1] - u[0]) / 2, (np.argmax(jump), np.max(jump), u)


def test_section_sheet_of_integrated_crossings_names_their_state():
    """The flow as an independent source of states: crossings of orbits of the Fig. 4b level
    (integrated, not built by the chart). section_sheet(label="sheet") of each, from the
    brackets of the energy on its theta grid, names the state states_on_section builds at
    its chart point under that label (refined roots, orientation by a central difference):
    the very crossing, to the integration's accuracy (first integrals drift ~1e-13; the
    chart inverse is exact to rounding: 1e-9 of the state's size leaves a wide margin, the
    next root is ~0.1 or more away). Crossings next to a fold (two roots within two grid
    steps, ambiguous for both searches) are skipped."""
    reg = tb.section_admissible_sample(FIG4_BALL, **LEV, n=8, seed=5, direction=1)
    res = tb.poincare_sections("reduced", FIG4_BALL, [s[0] for s in reg["states"]], n_points=40, batch=True)
    ys = np.concatenate([np.asarray(r.states, dtype=float).reshape(-1, 9) for r in res])
    labels = tb.section_sheet(FIG4_BALL, ys, **LEV, label="sheet")
    roots = tb.section_sheet(FIG4_BALL, ys, **LEV)
    checked = near_zero = 0
    combos = set()  # (root index, sheet label) pairs met
    for y, k, r in zip(ys, labels, roots):
        ch = tb.reduced_chart(FIG4_BALL, y)
        xs, info = tb.states_on_section(FIG4_BALL, **LEV, point=(ch["l"], ch["r1"], ch["r2"]), direction=1,
                                        return_info=True)
        th = np.arccos(np.clip(info["K"] / C, -1, 1))
        if len(th) > 1 and np.min(np.abs(np.diff(np.sort(th)))) < 2 * math.pi / 800:
            continue
        i = np.flatnonzero(info["sheet"] == k)
        assert i.size == 1, (k, info)
        assert np.max(np.abs(xs[i[0]] - y)) <= 1e-9 * np.max(np.abs(y)), (k, info, y)
        assert info["sheet"][r] == k  # the same state under its root index
        checked += 1
        combos.add((int(r), int(k)))
        near_zero += abs(ch["r1"]) < 0.5
    # the labels are not the root order renamed: root 0 is sheet 0 at some crossings and sheet 1 at
    # others, and so is root 1 (measured: 316 checked, 71 with |r1| < 0.5)
    assert {(0, 0), (0, 1), (1, 0), (1, 1)} <= combos, combos
    assert checked >= 250 and near_zero >= 20, (checked, near_zero)


# ---------------------------------------------------------------------------------------
# Roots next to the pole K*: as r1 -> 0 the roots of a pair crowd within a grid step of K*
# (and of each other); the root search and section_sheet search there again on points
# approaching K* geometrically, and a root the chart refuses (|gamma3| < 1e-4) keeps its
# place among the others.
# ---------------------------------------------------------------------------------------

def _energy_scan_roots(levels, l, r1, r2):
    """Every root K of E(K) = h at the chart point (l, r1, r2) of g0 = 0, found without the
    chart's energy equation: states built from (K, l) and R = (R1, R2, -r1/gamma3) directly,
    the energy from tb.integrals, sign changes on a K grid of 200001 points plus points
    approaching K* geometrically (factor 1.1, down to 1e-13 in K), each bracket bisected
    40 times. Roots within 1e-13 of K* or 1e-9 of K** = -M_gamma (where gamma1 = gamma2 = 0),
    where R is not determined, are not looked for."""
    c = ball_constants(FIG4_BALL.pars)
    Cl, Mg, h = levels.C, levels.M_gamma, levels.h
    ks = _degenerate_K(Cl, Mg, 0.0)
    d = 1e-2 * 1.1 ** -np.arange(0, 300)
    d = d[d > 1e-13]
    K = np.unique(np.concatenate([np.linspace(-Cl, Cl, 200001)[1:-1], ks - d, ks + d]))
    K = K[(np.abs(K - ks) > 1e-13) & (np.abs(K + Mg) > 1e-9)]  # R undetermined at K* and at K** = -M_gamma

    def energy(Kv):
        M, gam = angles_to_vectors(Cl, Mg, Kv, l, 0.0)
        rho2 = gam[0] ** 2 + gam[1] ** 2
        R = ((gam[0] * r1 + gam[1] * r2) / rho2, (gam[1] * r1 - gam[0] * r2) / rho2, -r1 / gam[2])
        Kt = tuple(M[i] + c.ma * c.Omega * R[i] for i in range(3))
        x = np.column_stack([*omega_from_K(c.A, c.d, gam, Kt), *gam, *R])
        return tb.integrals("reduced", FIG4_BALL, x)["E"] - h

    e = energy(K)
    i = np.flatnonzero(np.isfinite(e[:-1]) & np.isfinite(e[1:]) & (e[:-1] * e[1:] < 0))
    i = i[(K[i] - ks) * (K[i + 1] - ks) > 0]  # not across the pole
    a, b, fa = K[i], K[i + 1], e[i]
    for _ in range(40):
        m = 0.5 * (a + b)
        fm = energy(m)
        left = np.sign(fm) == np.sign(fa)
        a, fa, b = np.where(left, m, a), np.where(left, fm, fa), np.where(left, b, m)
    return 0.5 * (a + b)


# (levels, chart point): pairs of roots next to K* closer than a step of the 801-point grid
_NEAR_POLE = [("4a", (0.5, 0.002, -2.0)), ("4a", (2.0, 0.003, 1.0)), ("4b", (2.0, 0.003, 1.0)),
              ("4b", (2.0, 0.002, 1.0)), ("4b", (0.5, 0.002, -2.0))]


def _levels(name):
    from taylorball.paper import FIG4A_LEVELS

    return FIG4A_LEVELS if name == "4a" else FIG4B_LEVELS


@pytest.mark.parametrize("name, point", _NEAR_POLE)
def test_roots_next_to_K_star_are_all_found_and_labelled_apart(name, point):
    """Next to K* (|r1| <= 0.003) the roots the independent energy scan finds are all found
    by states_on_section, with the default grid and with 801 points (K to 1e-9: the scan's
    bisection stops at ~2e-12 in K, and K's condition near the pole is ~1e3); section_sheet
    (801-point grid, the default) gives the states of one branch their index in increasing K
    and distinct sheet labels, as states_on_section's own labels."""
    lev = _levels(name)
    ref = _energy_scan_roots(lev, *point)
    for n_grid in (2001, 801):
        xs, info = tb.states_on_section(FIG4_BALL, **lev.as_kwargs(), point=point, direction=None, n_grid=n_grid,
                                        return_info=True)
        assert info["K"].size == ref.size and np.allclose(info["K"], ref, rtol=0, atol=1e-9), (n_grid, info["K"], ref)
    xs, info = tb.states_on_section(FIG4_BALL, **lev.as_kwargs(), point=point, direction=1, return_info=True)
    assert len(xs) >= 2
    assert list(tb.section_sheet(FIG4_BALL, xs, **lev.as_kwargs())) == list(range(len(xs)))
    lab = tb.section_sheet(FIG4_BALL, xs, **lev.as_kwargs(), label="sheet")
    assert len(set(lab.tolist())) == len(xs) and list(lab) == list(info["sheet"])


def test_a_refused_root_keeps_its_place():
    """At (l, r1, r2) = (0.5, 5e-4, -2.0) on the Fig. 4b level a root next to K* has
    |gamma3| < 1e-4, where the chart does not recover R: no state is made for it, but the
    others keep their indices (0, 2, 3 of the four roots the independent scan finds, in
    increasing K), in states_on_section, section_sheet and megno_map(root=...)."""
    from taylorball.charts import CHART_SINGULAR_TOL, _ball
    from taylorball.maps import _row_states

    point = (0.5, 5e-4, -2.0)
    ref = _energy_scan_roots(FIG4B_LEVELS, *point)
    xs, info = tb.states_on_section(FIG4_BALL, **LEV, point=point, direction=1, return_info=True)
    assert ref.size == 4 and len(xs) == 3
    assert list(info["root"]) == [0, 2, 3]
    assert info["refused_K"].size == 1 and abs(info["refused_K"][0] - ref[1]) < 1e-9
    _, gam = angles_to_vectors(C, MG, info["refused_K"][0], point[0], 0.0)
    assert abs(gam[2]) < CHART_SINGULAR_TOL
    assert np.allclose(info["K"], ref[[0, 2, 3]], rtol=0, atol=1e-9)
    assert list(tb.section_sheet(FIG4_BALL, xs, **LEV)) == [0, 2, 3]
    lab = tb.section_sheet(FIG4_BALL, xs, **LEV, label="sheet")
    assert list(lab) == list(info["sheet"]) and len(set(lab.tolist())) == 3
    for root, want in ((0, 0), (1, None), (2, 1), (3, 2), (-1, 2), (-3, None)):
        states, K, _, index = _row_states(_ball(FIG4_BALL), FIG4B_LEVELS, point[0], np.array([point[1]]), point[2],
                                          0.0, 1, root, 2001)
        if want is None:  # the refused root: no state there, not the next root's
            assert np.isnan(K[0]) and index[0] == -1, root
        else:
            assert K[0] == info["K"][want] and index[0] == info["root"][want], root
