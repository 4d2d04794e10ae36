"""The observables reduced on the fly from the orbit (taylorball/_orbit_reductions.py):
extremes and histogram of |R|, section crossings with K's sheet, the lifted heading.
Each is checked against an independent computation on the same orbit, for bit-stability
(resume from a carry, thinning) and for leaving the orbit's bits alone."""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import pytest

import taylorball as tb
from taylorball._orbit_reductions import _jets, hermite_quadrature, sheet_signs, time_in_bins
from taylorball.observables import Extremes, Heading, Histogram, Sections
from taylorball._problem import problem
from taylorball.errors import UsageError
from taylorball.observables import build_observables, builders
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS

from ._orbit_driver import concat, run_chunks

EPS = np.finfo(float).eps
T, CE, DT = 200.0, 100.0, 0.25


@dataclass(frozen=True)
class _Keep:
    """Keeps the public states of every chunk (the reference sampling)."""

    name: str = "keep"

    def options(self):
        return {}

    def events(self, prob):
        return []

    def init(self, prob, x0, t0):
        return {}

    def chunk(self, carry, d):
        return carry, {"t": d.t, "p": d.public}


@pytest.fixture(scope="module")
def orbit():
    prob = problem("reduced", FIG4_BALL)
    x0 = tb.states_on_section(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), point=(2.0, 2.5, 1.0), direction=1)[0]
    obs = [Extremes(), Histogram(), Heading(10.0, 40), Sections()]
    car, rec, ta = run_chunks(prob, x0, obs, t_end=T, checkpoint_every=CE, sample_dt=DT)
    # the same orbit on a 1/512 grid: propagate_grid's bits do not depend on the grid
    _, fine, ta_f = run_chunks(prob, x0, [_Keep()], t_end=T, checkpoint_every=CE, sample_dt=1 / 512)
    tf = np.concatenate([r["t"] for r in fine[0]])
    pf = np.concatenate([r["p"] for r in fine[0]])
    return dict(prob=prob, x0=x0, obs=obs, car=car, rec=rec, ta=ta, tf=tf, pf=pf, ta_f=ta_f)


def test_observables_leave_the_orbit_bits_alone(orbit):
    """With the section event on, the orbit is bit-identical to the run without events
    (same final state and time); an event written with omega would change it."""
    ta, ta_f = orbit["ta"], orbit["ta_f"]
    assert np.array_equal(ta.state, ta_f.state)
    assert ta.time == ta_f.time


def test_R_is_the_distance_from_the_axis_in_the_fixed_frame(orbit):
    """|R|^2 = x^2 + y^2 for the fixed-frame contact point (contact_trajectory): the
    extremes of |R| are those of the contact point's distance from the rotation axis."""
    ct = tb.contact_trajectory(FIG4_BALL, orbit["x0"], np.linspace(0.0, 20.0, 81))
    R2 = np.sum(ct.reduced[:, 6:9] ** 2, axis=1)
    # 8 eps: x, y are dot products of R with unit vectors built from M (a few roundings each)
    np.testing.assert_allclose(ct.x ** 2 + ct.y ** 2, R2, rtol=8 * EPS, atol=0)


def test_extremes_against_a_fine_sampling(orbit):
    """Per chunk, the fine grid's max (min) of |R| cannot exceed (undercut) the true one;
    ours is within the interpolant's error of the true one. Measured: max 1.1e-7 above the
    1/512 grid's, min 2.2e-6 below it (the grid misses the true min by up to
    max|f''| (dt/2)^2 / (4 r_min) ~ 1e-4)."""
    R = np.linalg.norm(orbit["pf"][:, 6:9], axis=1)
    J = _jets("reduced")(orbit["pf"], FIG4_BALL.pars)
    for k, rec in enumerate(orbit["rec"][0]):
        sel = (orbit["tf"] >= k * CE) & (orbit["tf"] <= (k + 1) * CE)
        fmax, fmin = R[sel].max(), R[sel].min()
        # how far the fine grid can fall short of the true extreme: |f''| (dt/2)^2 / 2 in f = |R|^2
        slack = np.abs(J[2][sel]).max() * (1 / 1024) ** 2 / 2 / (2 * fmin)
        hermite = 1e-6  # bound on the quintic Hermite error measured at sample_dt = 0.25 (<= 2.2e-6 * 0.5)
        assert fmax - hermite <= rec["r_max"][0] <= fmax + slack + hermite
        assert fmin - slack - hermite <= rec["r_min"][0] <= fmin + hermite
        i = int(np.argmin(np.abs(orbit["tf"] - rec["t_r_max"][0])))
        assert abs(R[i] - rec["r_max"][0]) <= 1e-4  # the time is where the maximum is
    car = orbit["car"][0]
    assert car["r_max"][0] == max(r["r_max"][0] for r in orbit["rec"][0])
    assert car["r_min"][0] == min(r["r_min"][0] for r in orbit["rec"][0])


def test_time_in_bins_is_exact_for_a_broken_line():
    t = np.array([0.0, 10.0, 15.0])
    r = np.array([0.0, 10.0, 5.0])   # up at speed 1 over 10, down at speed 1 over 5
    occ = time_in_bins(t, r, np.arange(0.0, 11.0))
    want = np.zeros(12)
    want[1:11] = 1.0
    want[6:11] += 1.0                # [5, 10) twice
    want[11] = 0.0                   # r = 10 only at an instant
    np.testing.assert_allclose(occ, want, rtol=0, atol=16 * EPS * 15)  # 16 eps of the span: sums of a few terms
    assert abs(occ.sum() - 15.0) <= 4 * EPS * 15


def test_histogram_against_a_fine_sampling(orbit):
    """Counts sum to the elapsed time (to rounding) and agree with the broken line through
    the 1/512 grid of the same orbit: measured L1 difference 0.061 time units of 200 (3e-4),
    largest bin 0.009."""
    car = orbit["car"][1]
    assert abs(car["time"].sum() - T) <= 64 * EPS * T  # ~10^5 positive terms summed per chunk
    assert car["time"][-1] == 0.0                     # nothing above the rigorous bound
    R = np.linalg.norm(orbit["pf"][:, 6:9], axis=1)
    ref = time_in_bins(orbit["tf"], R, np.linspace(0.0, car["r_max"][0], 201))[1:]
    assert np.abs(ref - car["time"]).sum() <= 2e-3 * T
    assert np.abs(ref - car["time"]).max() <= 0.02
    snaps = orbit["rec"][1]
    assert [len(s["t_snapshot"]) for s in snaps] == [1, 1]  # after chunks 0 and 1 (k + 1 = 1, 2)


def test_heading_against_an_independent_integration(orbit):
    """psi = int (omega, gamma) dt against psi' = (omega, gamma) appended to the reduced
    system in long double (paper eqs. (15)-(16) [eq10]). The quadrature's error at
    sample_dt = 0.25 is measured at 2.6e-3 rad per 10 time units on this chaotic orbit and
    shrinks like h^7 (2.2e-5 at 0.125, 1.4e-8 at 0.0625): docs/longruns.md."""
    import heyoka as hy

    from taylorball._vec import dot
    from taylorball.model import public_system

    sysp = public_system("reduced")
    xs = hy.make_vars(*sysp.internal_names)
    psi = hy.make_vars("psi")
    pars = [hy.par[i] for i in range(6)]
    v = sysp.vectors(sysp.constants(pars), xs)
    ta = hy.taylor_adaptive(sysp.equations() + [(psi, dot(v["omega"], v["gamma"]))], [np.longdouble(0)] * 10,
                            pars=np.asarray(FIG4_BALL.pars, dtype=np.longdouble), fp_type=np.longdouble)
    ta.state[:9] = np.asarray(orbit["x0"], dtype=np.longdouble)
    out = ta.propagate_grid(np.arange(0.0, T + 1.0, 10.0).astype(np.longdouble))
    ref = out[-1][:, 9].astype(float)
    ours = concat(orbit["rec"][2], "heading")
    assert len(ours) == len(ref)                     # records at t = 0, 10, ..., T
    assert np.max(np.abs(ours - ref)) <= 0.05        # 2.6e-3 per 10 t.u., 20 intervals: 0.031 measured
    assert np.max(np.abs(ours - ref)) > 0             # (it is a quadrature, not the reference)
    # order 6: on the 1/16 subgrid of the fine sampling the error over [0, 10] falls below 1e-7
    J = _jets("reduced")(orbit["pf"], FIG4_BALL.pars)
    sl = slice(0, 5121, 32)
    q = hermite_quadrature(orbit["tf"][sl], J[3][sl], J[4][sl], J[5][sl]).sum()
    assert abs(q - ref[1]) <= 1e-7


def test_sections_match_poincare_section(orbit):
    """The crossings equal tb.poincare_section's to rounding: the run integrates with
    propagate_grid in chunks of 100, poincare_section with propagate_until in chunks of 100
    (heyoka's two loops round differently: not bit-identical); the first 20 crossings
    (t < 35) agree to 1e-10, the orbit's separation from rounding by then."""
    rec = orbit["rec"][3]
    sec = tb.poincare_section("reduced", FIG4_BALL, orbit["x0"], n_points=20)
    t = concat(rec, "t")
    assert len(t) >= 20
    np.testing.assert_allclose(t[:20], sec.times, rtol=0, atol=1e-10)
    pts = np.column_stack([concat(rec, k) for k in ("l", "r1", "r2")])[:20]
    np.testing.assert_allclose(pts, sec.points, rtol=0, atol=1e-9)
    assert orbit["car"][3]["n"][0] == len(t)


def test_sheet_sign_against_mpmath():
    """sign(dE/dK) at fixed (l, r1, r2, g0) from the central difference agrees with an
    mpmath difference of the energy on the chart (verify.section_volume, 40 digits), and
    the two roots of the energy equation at a chart point lie on opposite sheets."""
    import mpmath

    from taylorball._propagate import start_state
    from taylorball.verify.section_volume import energy_on_chart_mp

    prob = problem("reduced", FIG4_BALL)
    lev = FIG4A_LEVELS.as_kwargs()
    for point in [(2.0, 2.5, 1.0), (0.5, -1.0, 0.3), (4.0, 1.0, -2.0)]:
        xs = tb.states_on_section(FIG4_BALL, **lev, point=point)
        X = np.array([start_state(prob, x) for x in xs])
        s = sheet_signs(FIG4_BALL, X)
        with mpmath.workdps(40):
            for x, si in zip(X, s):
                K = mpmath.mpf(float(x[2]))
                y = [K, mpmath.mpf(point[1]), mpmath.mpf(point[2]), mpmath.mpf(point[0]), mpmath.mpf(0)]
                dK = mpmath.mpf("1e-12")
                e = [energy_on_chart_mp(FIG4_BALL, [y[0] + sg * dK] + y[1:], lev["C"], lev["M_gamma"]) for sg in (1, -1)]
                assert si == (1 if e[0] > e[1] else -1)
        if len(s) == 2:
            assert s[0] == -s[1]


def test_resume_from_the_carry_is_bit_identical(orbit):
    """Stop after chunk 0, restart from the integrator state, time and the carries: the
    records and carries equal the uninterrupted run's bit for bit."""
    prob, x0, obs = orbit["prob"], orbit["x0"], orbit["obs"]
    car1, rec1, ta1 = run_chunks(prob, x0, obs, t_end=CE, checkpoint_every=CE, sample_dt=DT)
    car2, rec2, _ = run_chunks(prob, x0, obs, t_end=T, checkpoint_every=CE, sample_dt=DT, k_start=1,
                               resume=(ta1.state.copy(), ta1.time, copy.deepcopy(car1)))
    for i in range(len(obs)):
        for a, b in zip(rec1[i] + rec2[i], orbit["rec"][i]):
            assert a.keys() == b.keys()
            for key in a:
                np.testing.assert_array_equal(a[key], b[key])
        for key in car2[i]:
            np.testing.assert_array_equal(car2[i][key], orbit["car"][i][key])


def test_sections_thinning_is_by_the_running_count(orbit):
    prob, x0 = orbit["prob"], orbit["x0"]
    _, rec, _ = run_chunks(prob, x0, [Sections(every=3)], t_end=T, checkpoint_every=CE, sample_dt=DT)
    np.testing.assert_array_equal(concat(rec[0], "t"), concat(orbit["rec"][3], "t")[::3])


@pytest.mark.parametrize("make, words", [
    (lambda: Histogram(bins=0), "bins"),
    (lambda: Histogram(bins=2.5), "bins"),
    (lambda: Histogram(r_max=-1.0), "r_max"),
    (lambda: Histogram(r_max=float("nan")), "r_max"),
    (lambda: Sections(every=0), "every"),
    (lambda: Sections(every="all"), "every"),
    (lambda: Sections(g0=7.0), "g0"),
    (lambda: build_observables({"histogram": {"bins": 0}}, 0.25), "observables.histogram bins"),
    (lambda: build_observables({"histogram": {"bin": 10}}, 0.25), "observables.histogram must be"),
    (lambda: build_observables({"histogram": "yes"}, 0.25), "observables.histogram must be"),
    (lambda: build_observables({"sections": "every"}, 0.25), "observables.sections must be"),
    (lambda: build_observables({"sections": 0}, 0.25), "observables.sections must be"),
    (lambda: build_observables({"sections": True}, 0.25), "observables.sections must be"),
    (lambda: build_observables({"extremes": 1}, 0.25), "observables.extremes must be true or false"),
    (lambda: build_observables({"angles_every": 0.3}, 0.25), "observables.angles_every must be"),
    (lambda: build_observables({"angles_every": float("inf")}, 0.25), "observables.angles_every must be"),
])
def test_bad_options_are_refused(make, words):
    with pytest.raises(UsageError, match=words.replace(".", r"\.")):
        make()


def test_keys_build_the_observables():
    objs = build_observables({"histogram": {"bins": 50, "r_max": 30.0}, "sections": 7, "angles_every": 5.0}, 0.25)
    by = {o.name: o for o in objs}
    assert by["histogram"] == Histogram(50, 30.0) and by["sections"] == Sections(7)
    assert by["heading"] == Heading(5.0, 20) and by["extremes"] == Extremes()
    names = {o.name for o in build_observables({}, 0.25)}
    assert {"extremes", "heading"} <= names and not {"histogram", "sections"} & names   # the defaults
    assert by["heading"].layout(None)["heading"].step == 5.0
    angles = [b for b in builders() if "angles_every" in b.keys]
    assert len({b.defaults["angles_every"] for b in angles}) == 1   # l and the heading agree


def test_a_system_without_R_is_refused():
    prob = problem("mparallel", FIG4_BALL)
    for ob in (Extremes(), Histogram(), Heading(10.0, 40)):
        with pytest.raises(UsageError, match="reduced"):
            ob.init(prob, None, 0.0)
    with pytest.raises(UsageError, match="reduced"):
        Sections().events(prob)


def _study_text(observables: str, store: str) -> str:
    """The diffusion study file (studies/h2.toml) made small: 2 orbits to t = 100 in chunks of
    50, serially, with the given [observables] table and store."""
    import pathlib
    import re

    text = (pathlib.Path(__file__).resolve().parents[1] / "studies" / "h2.toml").read_text()
    text = re.sub(r"(?m)^n = \d+", "n = 2", text)
    text = re.sub(r"(?m)^t_end = .*$", "t_end = 100.0", text)
    text = re.sub(r"(?m)^checkpoint_every = .*$", 'checkpoint_every = 50.0\nbackend = "serial"', text)
    text = re.sub(r"(?ms)^\[observables\].*?(?=^\[output\])", "[observables]\n" + observables + "\n\n", text)
    return re.sub(r'(?m)^store = .*$', f'store = "{store}"', text)


def test_through_the_runner(tmp_path):
    """The study runner with every observable of this module on: the store holds them,
    the orbit's other records (drift, angles) are bit-identical to a run without them
    (the section event leaves the orbit alone), and the records equal the test driver's."""
    from taylorball.study import load_study, open_run, run_study

    obs_on = 'extremes = true\nangles_every = 10.0\nsections = "all"\nhistogram = {bins = 50}'
    obs_off = 'extremes = false\nangles_every = 10.0\nsections = false\nhistogram = false'
    for name, obs in (("on", obs_on), ("off", obs_off)):
        (tmp_path / f"{name}.toml").write_text(_study_text(obs, f"store_{name}"))
        assert run_study(tmp_path / f"{name}.toml").complete
    on, off = open_run(tmp_path / "store_on"), open_run(tmp_path / "store_off")
    shared = [v for v in off.data_vars if v.startswith(("drift_", "angles_"))]
    assert any(v.startswith("angles_") for v in shared) and any(v.startswith("drift_") for v in shared)
    for v in shared:
        np.testing.assert_array_equal(on[v].values, off[v].values)
    assert "extremes_r_max" in on and "heading_heading" in on and "sections_K" in on
    assert "extremes_r_max" not in off and "sections_K" not in off
    assert on["histogram_time"].sizes["histogram_bin"] == 51
    # the same observables through the test driver from orbit 0's initial state
    from taylorball.store import RunStore

    cfg = load_study(tmp_path / "on.toml")
    x0 = np.array(RunStore(cfg.store).orbit(0).attrs()["initial_state"], dtype=float)
    objs = [o for o in cfg.observable_objects() if o.name in ("extremes", "sections", "heading", "histogram")]
    _, rec, _ = run_chunks(cfg.problem(), x0, objs, t_end=100.0, checkpoint_every=50.0, sample_dt=cfg.sample_dt)
    by = {o.name: r for o, r in zip(objs, rec)}
    n = len(concat(by["sections"], "t"))
    np.testing.assert_array_equal(on["sections_t"].values[0, :n], concat(by["sections"], "t"))
    np.testing.assert_array_equal(on["extremes_r_max"].values[0], concat(by["extremes"], "r_max"))
    np.testing.assert_array_equal(on["heading_heading"].values[0], concat(by["heading"], "heading"))
