"""The chaos atlas: the chaotic fraction of a level, its binomial interval, the
levels the atlas uses, and the power-law fit, each against an independent answer."""

import math

import numpy as np
import pytest

import taylorball as tb
from taylorball._atlas import wilson_interval
from taylorball.figures import chaos_atlas as atlas
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS


@pytest.mark.parametrize("k,n", [(0, 12), (6, 12), (12, 12), (1, 100), (37, 400), (400, 400)])
def test_wilson_interval_matches_scipy(k, n):
    """Reference: scipy's binomtest(...).proportion_ci(method="wilson"), an independent
    implementation. Tolerance 64 eps: a dozen float operations and a normal quantile
    (scipy's and the stdlib's agree to a few eps)."""
    from scipy.stats import binomtest

    ref = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    lo, hi = wilson_interval(k, n, 0.95)
    eps = np.finfo(float).eps
    assert abs(lo - ref.low) <= 64 * eps and abs(hi - ref.high) <= 64 * eps, (lo, hi, ref)


def test_wilson_interval_bad_input():
    for args, match in [((5, 4), "k must be at most n"), ((0, 0), "n"), ((-1, 4), "k"), ((1, 4, 1.0), "level"),
                        ((1, 4, float("nan")), "level"), ((1.5, 4), "k")]:
        with pytest.raises(tb.UsageError, match=match):
            wilson_interval(*args)


def test_rest_energy_range_against_an_independent_kinetic_energy():
    """[E_lo, E_hi] of T(M, gamma) on |M| = 10, (M, gamma) = 2 at R = 0 from the chart grid,
    against T = (omega, K)/2 with omega = Itilde^{-1} K solved by numpy.linalg.solve from the
    3x3 matrix Itilde = I + m a^2 (E - gamma gamma^T) (not Sherman--Morrison as the model
    does) at 20 000 random (M, gamma) on the level. Both are inner estimates of the true
    extremes (measured: they agree to 3e-6); bound 1e-3: at a smooth extremum a grid of step
    2 pi / 96 misses by at most ~ curvature * (pi / 96)^2 / 2 ~ 1e-3 * curvature, and the
    curvature here is O(1) (the range is 0.6 wide over angles of O(1))."""
    lo, hi = atlas.rest_energy_range(FIG4_BALL, 10.0, 2.0)
    rng = np.random.default_rng(0)
    I, d = np.diag(FIG4_BALL.inertia), FIG4_BALL.mass * FIG4_BALL.radius**2
    E = []
    for _ in range(20000):
        g = rng.normal(size=3)
        g /= np.linalg.norm(g)
        u = rng.normal(size=3)
        u -= (u @ g) * g
        u /= np.linalg.norm(u)
        M = 2.0 * g + math.sqrt(100.0 - 4.0) * u
        w = np.linalg.solve(I + d * (np.eye(3) - np.outer(g, g)), M)
        E.append(w @ M / 2)
    print(f"grid [{lo:.6f}, {hi:.6f}], random [{min(E):.6f}, {max(E):.6f}]")
    assert abs(min(E) - lo) < 1e-3 and abs(hi - max(E)) < 1e-3


def test_power_law_fit_recovers_a_known_exponent():
    """Binomial counts drawn from f = min(1, 8 Omega^3) (100 per rate, the FULL atlas's
    sizes): the ML exponent's 95 % profile interval is finite, narrower than 2, and contains 3
    for at least 17 of 20 seeds (a 95 % interval misses 1 time in 20; more than 3 misses of
    20 has probability 1.6 %, and the seeds are fixed)."""
    om = np.array([0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5])
    f = np.minimum(1.0, 8.0 * om**3)
    hits = 0
    for seed in range(20):
        k = np.random.default_rng(seed).binomial(100, f)
        fit = atlas.power_law_fit(om, k, np.full(om.size, 100))
        lo, hi = fit["p_ci"]
        assert lo is not None and hi is not None and hi - lo < 2.0, fit
        hits += lo <= 3.0 <= hi
    assert hits >= 17, hits
    none = atlas.power_law_fit(om, np.zeros(om.size), np.full(om.size, 100))
    assert none["p"] is None  # no chaotic orbit: no power law


def test_power_law_fit_goodness_of_fit_rejects_a_step():
    """The deviance test: counts from a power law pass it (p-value 0.23 for seed 1 of
    f = min(1, 8 Omega^3), 100 per rate), counts from a step (f = 0.02 below Omega = 0.25,
    0.9 above: an onset, not a power law) fail it (gof_p < 1e-3). The reference is the
    process the counts were drawn from."""
    om = np.array([0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5])
    rng = np.random.default_rng(1)
    power = atlas.power_law_fit(om, rng.binomial(100, np.minimum(1.0, 8.0 * om**3)), np.full(om.size, 100))
    step = atlas.power_law_fit(om, rng.binomial(100, np.where(om < 0.25, 0.02, 0.9)), np.full(om.size, 100))
    print(power["gof_p"], step["gof_p"])
    assert power["dof"] == 6 and power["gof_p"] > 0.01
    assert 0.0 < step["gof_p"] < 1e-3
    # the tail probability against scipy's chi^2 survival function (an independent
    # implementation), also far out in the tail where 1 - CDF would round to 0; 1e-9
    # relative: mpmath's regularized incomplete gamma at 15 digits, rounded to float64
    from scipy.stats import chi2

    for fit in (power, step):
        ref = chi2.sf(fit["deviance"], fit["dof"])
        assert abs(fit["gof_p"] - ref) <= 1e-9 * ref, (fit, ref)
    far = atlas.power_law_fit(om, np.array([0, 0, 0, 1, 35, 61, 86, 94])[: om.size], np.full(om.size, 100))
    assert far["gof_p"] > 0.0 and abs(far["gof_p"] - chi2.sf(far["deviance"], far["dof"])) <= 1e-9 * far["gof_p"]


def test_omega_half_interpolates():
    assert atlas.omega_half(np.array([0.0, 0.2, 0.3]), np.array([0.0, 0.25, 0.75])) == pytest.approx(0.25, abs=1e-15)
    assert atlas.omega_half(np.array([0.0, 1.0]), np.array([0.0, 0.2])) is None


def test_chaotic_fraction_omega_zero_is_regular_and_fig4a_is_chaotic():
    """Known answers at the two ends: at Omega = 0 Chaplygin's ball is integrable, so no
    orbit of the level is chaotic (with norm="compact": the full norm's shear would put them
    at <Y> ~ 4); the Fig. 4a level is one chaotic sea (docs/chaos.md: lambda_max ~ 0.11 on
    every orbit). T = 300, 8 orbits: measured <Y> 1.8 .. 2.2 at Omega = 0, all > 10 on Fig. 4a.
    Bounds: every Omega = 0 orbit below 3 (half-way between 2 and the chaos threshold 4)."""
    import dataclasses

    b0 = dataclasses.replace(FIG4_BALL, plane_rate=0.0)
    h = atlas.level_h(atlas.QUICK, 2.0)
    cf0 = tb.chaotic_fraction(b0, tb.Levels(C=10.0, M_gamma=2.0, h=h), n=8, t_end=300.0, workers=1)
    cfa = tb.chaotic_fraction(FIG4_BALL, FIG4A_LEVELS, n=8, t_end=300.0, workers=1)
    print(cf0, cf0.mean_megno, cfa, cfa.mean_megno)
    assert cf0.n_chaotic == 0 and np.all(cf0.mean_megno < 3.0), cf0.mean_megno
    assert cfa.n_chaotic == 8 and cfa.ci[0] > cf0.ci[1]
    assert cf0.r_box == 4096.0  # at Omega = 0 the region is unbounded in R: the sampler's cap


def test_chaotic_fraction_bad_input_is_refused_before_work():
    good = dict(n=4, t_end=100.0)
    cases = [
        ((FIG4_BALL, (10.0, 2.0, 5.0)), good, tb.UsageError, "levels must be"),
        ((tb.MParallelParams(a=(1.0, 2.0, 3.0), d=4.0, plane_rate=0.5), FIG4A_LEVELS), good, tb.ParameterError,
         "BallParams"),
        ((FIG4_BALL, FIG4A_LEVELS), dict(n=0, t_end=100.0), tb.UsageError, "n"),
        ((FIG4_BALL, FIG4A_LEVELS), dict(n=4, t_end=float("nan")), tb.UsageError, "t_end"),
        ((FIG4_BALL, FIG4A_LEVELS), dict(good, threshold=-1.0), tb.UsageError, "threshold"),
        ((FIG4_BALL, FIG4A_LEVELS), dict(good, stop_above=3.0), tb.UsageError, "stop_above must exceed"),
        ((FIG4_BALL, FIG4A_LEVELS), dict(good, norm="R"), tb.UsageError, "norm must be"),
        ((FIG4_BALL, FIG4A_LEVELS), dict(good, level=1.5), tb.UsageError, "level"),
        ((FIG4_BALL, FIG4A_LEVELS), dict(good, seed=-1), tb.UsageError, "seed"),
    ]
    for args, kw, err, match in cases:
        with pytest.raises(err, match=match):
            tb.chaotic_fraction(*args, **kw)


def test_fraction_over_time_ends_at_chaotic_fraction():
    """The atlas reads each orbit's <Y> at T/4, T/2 and T from one run (megno_many's
    sample=): its count at T is tb.chaotic_fraction's on the same sample (the runs are the
    same; sampling leaves their bits alone). (The count at earlier times can fall as well as
    rise: <Y> is an average and can dip below 4 after passing it.)"""
    import dataclasses

    import taylorball as tb

    cfg = dataclasses.replace(atlas.QUICK, n_orbits=4, megno_t=120.0, megno_times=(0.25, 0.5, 1.0), threads=1)
    lv = tb.Levels.from_caption(G=cfg.G, H=2.0, h=atlas.level_h(cfg, 2.0))
    p = atlas.ball(cfg, 2.0)
    times, k, n, Y, pts, r_box = atlas.fractions_over_time(p, lv, cfg)
    ref = tb.chaotic_fraction(p, lv, n=cfg.n_orbits, t_end=cfg.megno_t, seed=cfg.seed, workers=1,
                              options=tb.MegnoOptions(t0=1.0, jacobian=cfg.megno_jacobian))
    assert list(times) == [30.0, 60.0, 120.0] and n == ref.n == 4
    assert k[-1] == ref.n_chaotic and np.array_equal(Y, ref.mean_megno)
    assert np.array_equal(pts, ref.points) and r_box == ref.r_box
    assert np.all((k >= 0) & (k <= n)), k


def test_plot_draws_only_fits_that_fit_and_keeps_its_legends_off_the_data(monkeypatch, tmp_path):
    """The figure from saved data (no runs): a rejected power law is named in the title but
    not drawn, an accepted one is drawn over its range; panel (b) colours the rates by a
    colour bar; the legends sit under their panels, not on the data."""
    import dataclasses

    from taylorball.figures import _common as Cm

    omegas, Hs = (0.0, 0.1, 0.2, 0.5, 1.0, 2.0), (2.0, 6.0)
    n = 100
    k = np.array([[0, 1, 10, 80, 100, 100], [0, 0, 0, 1, 2, 41]])
    table = np.zeros((2, len(omegas), 8))
    for a, H in enumerate(Hs):
        for b, om in enumerate(omegas):
            lo, hi = wilson_interval(int(k[a, b]), n)
            table[a, b] = [H, om, k[a, b], n, k[a, b] / n, lo, hi, 16.0]
    ft = np.stack([table[:, :, 4] * s for s in (0.25, 0.5, 1.0)], axis=-1)
    fit_bad = atlas.power_law_fit(omegas[1:4], k[0, 1:4], [n] * 3)
    fit_bad["fits"] = False
    fit_good = {**fit_bad, "fits": True}
    cfg = dataclasses.asdict(dataclasses.replace(atlas.FULL, omegas=omegas))
    meta = {"config": cfg, "levels": {str(H): {"h": 2.4665 if H == 2 else 7.8944} for H in Hs},
            "fits": {"2.0": fit_bad, "6.0": None}, "megno_times": [250.0, 500.0, 1000.0],
            "fig4a_anchor": {"omega": 2.0, "fraction": 1.0, "ci": [0.963, 1.0]}}
    figs = []
    monkeypatch.setattr(Cm, "save_figure", lambda fig, outdir, stem, meta=None: figs.append(fig) or [])
    atlas.plot({"table": table, "fraction_t": ft}, meta, tmp_path)
    atlas.plot({"table": table, "fraction_t": ft}, {**meta, "fits": {"2.0": fit_good, "6.0": None}}, tmp_path)
    for fig, drawn in zip(figs, (False, True)):
        a, b = fig.axes[:2]
        fit_lines = [ln for ln in a.get_lines() if ln.get_label().startswith("fit ")]
        assert bool(fit_lines) == drawn
        assert ("rejected, not drawn" in fig._suptitle.get_text()) == (not drawn)
        assert len(fig.axes) == 3 and fig.axes[2].get_ylabel() == r"$\Omega$"  # the colour bar
        assert len(b.get_lines()) == len(Hs) * len(omegas)
        fig.canvas.draw()
        for ax in (a, b):
            leg, box = ax.get_legend().get_window_extent(), ax.get_window_extent()
            assert leg.y1 <= box.y0, (leg, box)  # under the panel (display y grows upwards)
