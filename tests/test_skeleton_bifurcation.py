"""The bifurcation diagram in Omega (taylorball.periodic_bifurcation, figure
skeleton_bifurcation): the branch-point test on constructed families whose answer is known,
and the quick figure's events checked independently of the variational code (finite
differences of the section map, fresh propagations)."""

import dataclasses
import math
import warnings

import numpy as np
import pytest

import taylorball as tb
from taylorball import periodic_catalog as cat
from taylorball.errors import UsageError
from taylorball.paper import FIG1_LEVELS, fig1_params
from taylorball.periodic_bifurcation import branch_points, follow_family, resonances, unit_crossings

from ._periodic_checks import quotient_matrix_fd

EPS = np.finfo(float).eps


# ---------------------------------------------------------------------------------------
# Constructed families: an area-preserving map (x, y) -> (x + y', y'), y' = y + g(x; mu),
# Jacobian [[1 + g', 1], [g', 1]] (det 1, tr 2 + g'), fixed points y = 0, g(x; mu) = 0.
# ---------------------------------------------------------------------------------------
def _bordered_det(gx, gmu, t):
    """det [[A - I, G_mu], [t^T]] of the constructed map at a fixed point (written here from
    the map: G(x, y, mu) = (x' - x, y' - y) = (y + g, g), so A - I = [[g', 1], [g', 0]] and
    G_mu = (g_mu, g_mu))."""
    return float(np.linalg.det(np.array([[gx, 1.0, gmu], [gx, 0.0, gmu], list(t)])))


def _tangent(gx, gmu):
    """Unit kernel vector of [A - I, G_mu] (rows (gx, 1, gmu), (gx, 0, gmu)): y-component 0."""
    t = np.array([-gmu, 0.0, gx]) if abs(gx) + abs(gmu) > 0 else np.array([1.0, 0.0, 0.0])
    return t / np.linalg.norm(t)


def test_pitchfork_is_a_branch_point_and_a_fold_is_not():
    """g = mu x - x^3: the trivial branch x = 0 (tr A = 2 + mu) meets the pair x = +-sqrt(mu)
    at mu = 0, with mu running on: a branch point, where the bordered determinant changes
    sign. g = mu - x^2, followed in x (mu = x^2): tr A = 2 - 2x passes 2 at x = 0 where mu
    turns: a fold, where the bordered determinant keeps its sign."""
    mus = np.linspace(-0.5, 0.5, 11) + 0.013  # no point exactly on the event
    det_ami = []  # det(A - I) = 2 - tr A with det A = 1
    bord = []
    for mu in mus:
        gx, gmu = mu, 0.0  # g' = mu - 3 x^2 at x = 0; dg/dmu = x = 0
        A = np.array([[1 + gx, 1.0], [gx, 1.0]])
        det_ami.append(np.linalg.det(A - np.eye(2)))
        t = _tangent(gx, gmu)
        t *= np.sign(t[2]) if t[2] != 0 else 1.0  # mu increasing along the branch
        bord.append(_bordered_det(gx, gmu, t))
    ev = unit_crossings(mus, det_ami)
    assert [(i, k) for i, k, _ in ev] == [(4, "branch point")]
    assert ev[0][2] == pytest.approx(0.0, abs=1e-12)  # det(A - I) = -mu is linear: exact
    assert np.sign(bord[4]) != np.sign(bord[5])  # the bordered determinant changes sign
    assert all(np.sign(bord[i]) == np.sign(bord[i + 1]) for i in range(10) if i != 4)

    xs = np.linspace(-0.5, 0.5, 11) + 0.013
    mus_f = xs ** 2
    det_f, bord_f = [], []
    for j, x in enumerate(xs):
        gx, gmu = -2 * x, 1.0
        A = np.array([[1 + gx, 1.0], [gx, 1.0]])
        det_f.append(np.linalg.det(A - np.eye(2)))
        t = _tangent(gx, gmu)
        # the branch's sense: x increasing (t = (-gmu, 0, gx) has x-component -1: flip it)
        t *= -1.0
        bord_f.append(_bordered_det(gx, gmu, t))
    ev = unit_crossings(mus_f, det_f)
    assert [(i, k) for i, k, _ in ev] == [(4, "fold")]
    assert all(np.sign(bord_f[i]) == np.sign(bord_f[0]) for i in range(11))  # no sign change at a fold
    # and the identity the module uses: sign(bordered) = sign(det(A - I)) * sign(dmu/ds)
    for d, b, dmu in zip(det_f, bord_f, 2 * xs):
        assert np.sign(b) == np.sign(d) * np.sign(dmu)


def test_branch_points_on_a_branch():
    """branch_points reads a Branch (orbits with their multiplier matrices) and reports the
    constructed pitchfork with its reason and the orbit's symmetry; resonances finds tr A
    through -1 (1:3) and 0 (1:4)."""
    from types import SimpleNamespace

    from taylorball.periodic import classify

    def orbit(tr):
        A = np.array([[tr - 1.0, 1.0], [tr - 2.0, 1.0]])  # det 1, trace tr
        return SimpleNamespace(matrix=A, trace=tr, type=classify(A)[1], symmetric="sigma_1")

    ws = np.linspace(0.0, 1.0, 9)
    trs = np.linspace(-1.5, 2.5, 9) + 0.01  # through -1, 0 and +2, w monotone
    br = SimpleNamespace(omega=ws, orbits=[orbit(t) for t in trs], parameter="Omega")
    bp = branch_points(br)
    assert len(bp) == 1 and bp[0]["event"] == "branch point" and bp[0]["symmetric"] == "sigma_1"
    assert "without a fold" in bp[0]["reason"]
    w_exact = (2.0 - trs[0]) / (trs[-1] - trs[0])  # tr is linear in w here
    assert bp[0]["omega"] == pytest.approx(w_exact, abs=1e-12)
    res = {e["q"]: e["omega"] for e in resonances(br)}
    assert res[3] == pytest.approx((-1.0 - trs[0]) / (trs[-1] - trs[0]), abs=1e-12)
    assert res[4] == pytest.approx((0.0 - trs[0]) / (trs[-1] - trs[0]), abs=1e-12)


def test_unit_crossings_and_follow_family_bad_input():
    with pytest.raises(UsageError, match="values and dets"):
        unit_crossings([0.0, 1.0], [1.0])
    with pytest.raises(UsageError, match="values and dets"):
        unit_crossings([0.0, np.nan], [1.0, -1.0])
    o = cat.catalog_orbit(cat.TZENOFF_D35_REFLECTION_SADDLE)
    lev = cat.TZENOFF_D35_REFLECTION_SADDLE.levels
    with pytest.raises(UsageError, match="bounds"):
        follow_family(o, lev, bounds=(2.0, 1.0))
    with pytest.raises(UsageError, match="not inside bounds"):
        follow_family(o, lev, bounds=(0.0, 2.0))
    with pytest.raises(UsageError, match="sides"):
        follow_family(o, lev, bounds=(0.0, 3.0), sides=(0,))


# ---------------------------------------------------------------------------------------
# The quick figure, and its events checked independently.
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def quick():
    from taylorball.figures import skeleton_bifurcation as S

    return S.compute(S.QUICK)


def _fig1_params(w):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", tb.UnphysicalParametersWarning)
        return dataclasses.replace(fig1_params(), plane_rate=w)


def _chart_trace_fd(w, point, k=1, h=1e-6):
    """tr of the M||gamma map P^k in the chart (l, L/G) at ``point``: central differences,
    each image by the float64 section integrator (tolerance eps; error ~1e-16/h). The trace
    is the same in every coordinate system of the section-and-level."""
    p = _fig1_params(w)
    lev = FIG1_LEVELS.as_kwargs()
    J = np.zeros((2, 2))
    for j in range(2):
        img = []
        for s in (1, -1):
            q = np.array(point, dtype=float)
            q[j] += s * h
            st = tb.mparallel_states_on_section(p, **lev, point=tuple(q))[0]
            img.append(np.asarray(tb.poincare_section("mparallel", p, st, n_points=k).points[-1], dtype=float))
        d = img[0] - img[1]
        d[0] = (d[0] + np.pi) % (2 * np.pi) - np.pi
        J[:, j] = d / (2 * h)
    return float(np.trace(J))


def _fam(meta, name):
    return next(f for f in meta["families"] if f["name"] == name)


@pytest.mark.long
def test_quick_figure_families_and_omega_0(quick):
    """The quick figure: both fixed points followed over all of [0, 2]; at Omega = 0 they are
    isolated (tr A far from 2) and the period-3 orbit lies on a resonant torus (tr A = 2, the
    integrable system's |K|^2 equal at its section points); every orbit of the branches,
    sampled, returns in an independent propagation."""
    arrays, meta = quick
    for name in ("saddle l = 0", "elliptic l = pi/2"):
        f = _fam(meta, name)
        assert f["omega_range"] == [0.0, 2.0] and f["stopped"] == {"down": "reached 0.0", "up": "reached 2.0"}
    om0 = meta["omega0"]
    assert [round(f["trace"], 3) for f in om0["fixed_points"]] == [4.136, -1.748]  # measured 4.1358, -1.7484
    # float64 Jacobian over 3 crossings, entries ~10: measured 2.0e-13, allowed 4096 eps
    assert abs(om0["torus3"]["trace_minus_2"]) <= 4096 * EPS
    assert om0["torus3"]["K2_spread"] <= 64 * EPS * om0["torus3"]["K2"]  # |K|^2 ~ 188, measured 2.8e-13
    for key in ("fp0", "fp1", "p3_0"):
        w, st, k = arrays[f"{key}_omega"], arrays[f"{key}_states"], arrays[f"{key}_k"]
        for i in range(0, len(w), max(1, len(w) // 4)):
            p = _fig1_params(float(w[i]))
            sec = tb.poincare_section("mparallel", p, st[i], n_points=int(k[i]))
            # |x| ~ 15: measured <= 1e-12 (the period-3 orbit near the collision: slower Newton)
            assert float(np.max(np.abs(np.asarray(sec.states[-1], dtype=float) - st[i]))) <= 1e-10, (key, w[i])


@pytest.mark.long
def test_quick_figure_plots(quick, tmp_path):
    """The quick figure is drawn from the computed data (a PNG, as the runner saves it)."""
    from taylorball.figures import skeleton_bifurcation as S

    arrays, meta = quick
    paths = S.plot(arrays, {**meta, "quality": "quick", "study": "skeleton_bifurcation"}, tmp_path)
    assert [p.name for p in paths] == ["skeleton_bifurcation.png"] and paths[0].stat().st_size > 10_000


@pytest.mark.long
def test_the_1_3_resonance_and_the_end_of_the_period_3_branch(quick):
    """The elliptic fixed point's tr A passes -1 (the 1:3 resonance) between two branch
    points, by finite differences of the map; the period-3 branch ends on the fixed point
    there: its three points converge to it (chart distance ~sqrt(Omega* - Omega))."""
    arrays, meta = quick
    f = _fam(meta, "elliptic l = pi/2")
    ev = [e for e in f["events"] if e["event"] == "1:3 resonance"]
    assert len(ev) == 1 and 1.6 < ev[0]["omega"] < 1.62  # measured 1.60997 (coarse quick steps)
    wa, wb = ev[0]["between"]
    w, pts = arrays["fp1_omega"], arrays["fp1_points"]
    ia, ib = int(np.argmin(np.abs(w - wa))), int(np.argmin(np.abs(w - wb)))
    ta, tb_ = _chart_trace_fd(wa, pts[ia]), _chart_trace_fd(wb, pts[ib])
    assert (ta + 1.0) * (tb_ + 1.0) < 0, (ta, tb_)
    # float64 differences, h = 1e-6: error ~1e-9 against the variational trace
    assert abs(ta - arrays["fp1_trace"][ia]) <= 1e-6 and abs(tb_ - arrays["fp1_trace"][ib]) <= 1e-6
    p3 = _fam(meta, "period-3 elliptic")
    end = p3["end"]
    assert abs(end["omega"] - ev[0]["omega"]) <= 0.01
    assert end["max_chart_distance"] <= 0.02  # measured ~0.006
    # the fixed point at the end: trace -1 to first order in Omega* - Omega (slope ~1.1)
    assert abs(end["fixed_point_trace"] + 1.0) <= 0.02


@pytest.mark.long
def test_period_doubling_and_fold_of_the_tzenoff_branch(quick):
    """Tzenoff's case (d = 7/2): the proved reflection saddle, followed down from Omega = 3,
    passes tr A = -2 (period doubling, measured at 2.8733) and turns at a fold (2.7903) into a
    saddle. Checked by central differences of the quotient map in real128
    (tests/_periodic_checks.quotient_matrix_fd, no variational equations): the traces of the
    orbits on either side of the period doubling straddle -2; at the fold, the orbits on the
    two sides of the turn straddle +2 at one Omega side, and Omega turns. No branch point is
    reported on this branch (the multiplier +1 comes with the turn)."""
    arrays, meta = quick
    f = _fam(meta, "Tzenoff d = 7/2 reflection saddle")
    names = [e["event"] for e in f["events"]]
    assert "period doubling" in names and "fold" in names and "branch point" not in names
    e_ = cat.TZENOFF_D35_REFLECTION_SADDLE
    w, st, sh = arrays["tz_omega"], arrays["tz_states"], arrays["tz_shift"]

    def orbit(i):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", tb.UnphysicalParametersWarning)
            ball = dataclasses.replace(e_.ball, plane_rate=float(w[i]))
        o = tb.periodic_orbit("reduced", ball, st[i], int(arrays["tz_k"][i]), levels=e_.levels,
                              g0=float(arrays["tz_g0"][i]), options=tb.NewtonOptions(shift=float(sh[i])))
        return o, ball

    pd = next(e for e in f["events"] if e["event"] == "period doubling")
    assert 2.86 < pd["omega"] < 2.88
    level = {"period doubling": -2.0, "1:3 resonance": -1.0, "1:4 resonance": 0.0}
    checked = 0
    for ev in f["events"]:
        if ev["event"] not in level:
            continue
        trs = []
        for wv in ev["between"]:
            i = int(np.argmin(np.abs(w - wv)))
            o, ball = orbit(i)
            A = quotient_matrix_fd(o, ball, e_.levels)
            # float64 variational over t ~ 5, entries ~10, against real128 differences (h =
            # 1e-6: truncation ~1e-12): allowed 1e-8
            assert abs(np.trace(A) - arrays["tz_trace"][i]) <= 1e-8
            assert abs(np.linalg.det(A) - 1.0) <= 1e-8
            trs.append(float(np.trace(A)))
        c = level[ev["event"]]
        assert (trs[0] - c) * (trs[1] - c) < 0, (ev, trs)  # tr A passes the event's value
        checked += 1
    assert checked == 3  # the period doubling, the 1:3 and the 1:4 resonance
    fold = next(e for e in f["events"] if e["event"] == "fold")
    assert 2.78 < fold["omega"] < 2.80
    i = int(np.argmin(w))  # the turning point
    assert i not in (0, len(w) - 1) and w[i - 1] > w[i] < w[i + 1]
    trs = []
    for j in (i - 1, i + 1):
        o, ball = orbit(j)
        trs.append(float(np.trace(quotient_matrix_fd(o, ball, e_.levels))))
    assert (trs[0] - 2.0) * (trs[1] - 2.0) < 0, trs  # one side elliptic, the other a saddle


@pytest.mark.long
def test_the_h30_elliptic_orbit_is_born_at_a_fold_with_the_levels_saddle(quick):
    """The elliptic orbit proved on the h = -30 level, followed down from Omega = 3, turns at a
    fold at Omega ~ 2.995 into the saddle of the same level (at Omega = 3: (r1, r2) =
    (-0.72621, 0), multipliers 0.40318, 2.48030, as periodic_orbits found it there). The traces
    on the two sides of the turn, by real128 differences of the quotient map, straddle +2."""
    arrays, meta = quick
    f = _fam(meta, "Tzenoff h = -30 elliptic")
    assert f["stopped"] == {"down": "reached 3.0"}
    folds = [e for e in f["events"] if e["event"] == "fold"]
    assert len(folds) == 1 and 2.99 < folds[0]["omega"] < 3.0  # measured 2.99499
    assert "branch point" not in [e["event"] for e in f["events"]]
    e_ = cat.TZENOFF_D35_H30_ELLIPTIC
    w, st, sh = arrays["tz30_omega"], arrays["tz30_states"], arrays["tz30_shift"]
    i = int(np.argmin(w))
    assert i not in (0, len(w) - 1) and w[i - 1] > w[i] < w[i + 1]
    trs = []
    for j in (i - 1, i + 1):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", tb.UnphysicalParametersWarning)
            ball = dataclasses.replace(e_.ball, plane_rate=float(w[j]))
        o = tb.periodic_orbit("reduced", ball, st[j], int(arrays["tz30_k"][j]), levels=e_.levels,
                              g0=float(arrays["tz30_g0"][j]), options=tb.NewtonOptions(shift=float(sh[j])))
        trs.append(float(np.trace(quotient_matrix_fd(o, ball, e_.levels))))
    assert (trs[0] - 2.0) * (trs[1] - 2.0) < 0, trs
    # the other end, landed on Omega = 3: the level's saddle
    assert w[0] == 3.0 and abs(arrays["tz30_points"][0, 1] - (-0.72621)) <= 1e-4
    assert abs(arrays["tz30_trace"][0] - (0.40318 + 2.48030)) <= 1e-4


@pytest.mark.long
def test_period_doubling_is_a_branch_point_of_p2_and_the_switch_onto_the_doubled_family(quick):
    """On the Tzenoff branch det(A^2 - I) = 4 - (tr A)^2 (det A = 1) changes sign at the
    period doubling with Omega running on: a branch point of P^2. period_doubled_orbit, from
    the branch's orbit on the reflection-saddle side, finds the orbit of twice the period:
    it closes after 2 crossings (not 1) in an independent propagation, its period is about
    twice the branch's, and its two section points lie on either side of the branch's."""
    from taylorball.periodic_bifurcation import period_doubled_orbit

    from ._periodic_checks import rotate_public

    arrays, meta = quick
    w, tr = arrays["tz_omega"], arrays["tz_trace"]
    ev = unit_crossings(w, 4.0 - tr ** 2)
    pd = next(e for e in _fam(meta, "Tzenoff d = 7/2 reflection saddle")["events"] if e["event"] == "period doubling")
    bps = [(i, k, wz) for i, k, wz in ev if abs(wz - pd["omega"]) < 0.01]
    # two linear interpolations (of 4 - tr^2 and of tr + 2) over a step of 0.0035 in Omega:
    # they differ at second order (measured 3.2e-7)
    assert len(bps) == 1 and bps[0][1] == "branch point" and bps[0][2] == pytest.approx(pd["omega"], abs=1e-5)
    e_ = cat.TZENOFF_D35_REFLECTION_SADDLE
    i = int(np.argmin(np.abs(w - max(pd["between"]))))  # the reflection-saddle side
    assert tr[i] < -2.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", tb.UnphysicalParametersWarning)
        ball = dataclasses.replace(e_.ball, plane_rate=float(w[i]))
    o1 = tb.periodic_orbit("reduced", ball, arrays["tz_states"][i], 1, levels=e_.levels,
                           options=tb.NewtonOptions(shift=float(arrays["tz_shift"][i])))
    o2 = period_doubled_orbit(o1, e_.levels)
    assert o2.k == 2 and abs(o2.period / (2 * o1.period) - 1.0) <= 0.01  # measured 2e-4 at Omega = 2.877
    sec = tb.poincare_section("reduced", ball, o2.state, n_points=2)
    x0 = np.asarray(o2.state, dtype=float)
    back = np.asarray(sec.states[-1], dtype=float)
    assert float(np.max(np.abs(back - rotate_public(x0, o2.shift).astype(float)))) <= 1e-10  # |x| ~ 3
    once = np.asarray(sec.states[0], dtype=float)
    half = min(float(np.max(np.abs(once - rotate_public(x0, th).astype(float)))) for th in np.linspace(0, 2 * np.pi, 721))
    assert half > 1e-3  # not closed (up to a rotation about axis 3) after one crossing
    r1 = sorted(float(p[1]) for p in o2.points)
    assert r1[0] < float(o1.points[0, 1]) < r1[1]


def test_pitchforks_of_the_fig1_saddle_beyond_omega_2_and_the_switch():
    """The M||gamma saddle at l = 0, followed past Omega = 2, has tr A -> 2 from above; between
    Omega = 4.5 and 5 det(A - I) = 2 - tr A changes sign twice with Omega running on: two
    branch points (measured 4.74646, 4.89339), the symmetric saddle elliptic between them.
    Independently: float64 central differences of the map in the chart (no variational
    equations) give tr A - 2 of the same signs on both sides of each (|tr A - 2| ~ 1e-5
    against a differencing error ~1e-10). branch_orbits finds, just past the first, a pair of
    saddles mirror images under l -> -l (a pitchfork of the reversible map), and no other
    orbit from the same seeds before it."""
    from taylorball.periodic_bifurcation import branch_orbits
    from taylorball.periodic_continuation import continue_in_omega

    p = _fig1_params(0.5)
    st = tb.mparallel_states_on_section(p, **FIG1_LEVELS.as_kwargs(), point=(0.0, 0.0))[0]
    o = tb.periodic_orbit("mparallel", p, st, 1, levels=FIG1_LEVELS)
    start = continue_in_omega(o, FIG1_LEVELS, [1.0, 2.0, 3.0, 4.0, 4.5])
    assert start.stopped == "reached"
    fam = follow_family(start.orbits[-1], FIG1_LEVELS, bounds=(4.5, 5.0), ds=0.2, n_steps=40, sides=(1,))
    assert fam.stopped == {"up": "reached 5.0"} and np.all(np.diff(fam.omega) > 0)
    bps = [e for e in fam.events if e["event"] == "branch point"]
    assert [round(e["omega"], 2) for e in bps] == [4.75, 4.89]  # measured 4.74646, 4.89339
    for e in bps:
        signs = []
        for wv in e["between"]:
            i = int(np.argmin(np.abs(fam.omega - wv)))
            pt = fam.orbits[i].points[0].copy()
            pt[0] = (pt[0] + np.pi) % (2 * np.pi) - np.pi
            t_fd = _chart_trace_fd(wv, pt)
            # float64 differences (h = 1e-6): error ~1e-10; measured agreement ~1e-10
            assert abs(t_fd - fam.orbits[i].trace) <= 1e-8, (wv, t_fd, fam.orbits[i].trace)
            signs.append(np.sign(t_fd - 2.0))
        assert signs[0] != signs[1]
    inside = continue_in_omega(start.orbits[-1], FIG1_LEVELS, [4.7, 4.75])
    before, after = inside.orbits[1], inside.orbits[2]
    assert branch_orbits(before, FIG1_LEVELS) == []
    pair = branch_orbits(after, FIG1_LEVELS)
    assert len(pair) == 2
    l_ = sorted((float(q.points[0, 0]) + np.pi) % (2 * np.pi) - np.pi for q in pair)
    assert l_[0] == pytest.approx(-l_[1], abs=1e-9) and abs(l_[0]) > 0.05  # measured +-0.09895
    assert pair[0].points[0, 1] == pytest.approx(pair[1].points[0, 1], abs=1e-9)
    for q in pair:
        assert q.type == "saddle"
        sec = tb.poincare_section("mparallel", q.problem.params, q.state, n_points=1)
        assert float(np.max(np.abs(np.asarray(sec.states[-1], dtype=float) - np.asarray(q.state, dtype=float)))) <= 1e-10
