"""Occupation of a region against a reference density (tb.transport.occupation) on
processes with known answers, and the section map's invariant density with its sheets
merged (tb.section_sigma) against the mpmath evaluation in verify.section_volume."""
from __future__ import annotations

import numpy as np
import pytest

import taylorball as tb
from taylorball.errors import ChartError, UsageError
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS

EPS = np.finfo(float).eps
EDGES = [np.linspace(0.0, 1.0, 6)] * 3           # 5 x 5 x 5 bins of the unit cube


def _beta22(p):
    """Beta(2, 2) in each coordinate: 6 x (1 - x), a polynomial of degree 2 per coordinate."""
    return np.prod(6 * p * (1 - p), axis=1)


def _beta22_bins():
    cdf = lambda x: 3 * x * x - 2 * x ** 3   # noqa: E731
    q1 = np.diff(cdf(EDGES[0]))
    return np.einsum("i,j,k->ijk", q1, q1, q1)


def _uniform_bins():
    return np.full((5, 5, 5), 1 / 125)


def test_reference_from_a_callable_is_exact_for_polynomials():
    """quad = 4 Gauss points integrate degree 7 exactly: the bin probabilities of
    Beta(2, 2)^3 equal the closed form to rounding (16 eps: sums of 64 products per bin)."""
    occ = tb.transport.occupation(np.full((1, 3), 0.5), [0.0], _beta22, EDGES, at=[0.0])
    np.testing.assert_allclose(occ.reference, _beta22_bins(), rtol=16 * EPS, atol=0)


def test_iid_samples_converge_like_n_to_the_minus_half():
    """Draws from the reference itself: the mean distance over 16 seeds equals the i.i.d.
    expectation (floor) within 10 % (the sd of the mean of distance/floor is ~2-3 %) at every
    n from 100 to 10^5, and falls like n^-0.5 (fitted slope within 0.03)."""
    at = np.geomspace(100, 100_000, 7) - 1
    rows = []
    for seed in range(16):
        pts = np.random.default_rng(seed).beta(2, 2, size=(100_000, 3))
        occ = tb.transport.occupation(pts, np.arange(100_000.0), _beta22, EDGES, at=at)
        rows.append(occ.distance)
    mean = np.mean(rows, axis=0)
    assert np.all(np.abs(mean / occ.floor - 1) <= 0.1)
    slope = np.polyfit(np.log(occ.n), np.log(mean), 1)[0]
    assert abs(slope + 0.5) <= 0.03


@pytest.mark.parametrize("metric", ["tv", "hellinger"])
def test_samples_from_another_density_converge_to_the_known_distance(metric):
    """Uniform draws against the Beta(2, 2)^3 reference: the distance tends to the distance
    between the binned distributions (closed form), within 3 i.i.d. floors at n = 2e5."""
    p, q = _uniform_bins(), _beta22_bins()
    true = 0.5 * np.abs(p - q).sum() if metric == "tv" else np.sqrt(1 - np.sqrt(p * q).sum())
    pts = np.random.default_rng(3).uniform(size=(200_000, 3))
    occ = tb.transport.occupation(pts, np.arange(200_000.0), _beta22, EDGES, at=[999.0, 199_999.0],
                                  metric=metric)
    assert abs(occ.distance[-1] - true) <= 3 * occ.floor[-1]
    assert true > 10 * occ.floor[-1]               # the test can tell the two densities apart
    assert occ.outside == 0.0


def test_points_outside_the_bins_count_against_the_reference():
    pts = np.array([[0.5, 0.5, 0.5], [2.0, 0.5, 0.5]])   # one inside, one outside
    occ = tb.transport.occupation(pts, [0.0, 1.0], _uniform_bins(), EDGES, at=[0.0, 1.0])
    # at t = 0: all mass in one of 125 bins: TV = 1 - 1/125; at t = 1 half of it outside
    np.testing.assert_allclose(occ.distance, [1 - 1 / 125, 0.5 * (0.5 - 1 / 125) + 0.5 * (1 - 1 / 125) + 0.5 * 0.5],
                               rtol=8 * EPS)
    assert occ.outside == 0.5


@pytest.mark.parametrize("kwargs, words", [
    (dict(points=np.zeros((3, 2))), "bins must give edges for each of the 2"),
    (dict(points=np.full((3, 3), np.nan)), "finite"),
    (dict(times=[2.0, 1.0, 3.0]), "non-decreasing"),
    (dict(times=[1.0, 2.0]), "times must have shape"),
    (dict(metric="kl"), "metric"),
    (dict(metric=np.array([])), "metric"),  # not a string (an array reached "in" and raised ValueError)
    (dict(quad=0), "quad"),
    (dict(quad=17), "quad"),
    (dict(bins=[np.array([0.0, 1.0, 0.5])] * 3), "strictly increasing"),
    (dict(density=np.ones((4, 4, 4))), "shape"),
    (dict(density=-np.ones((5, 5, 5))), ">= 0"),
    (dict(density=np.zeros((5, 5, 5))), "zero mass"),
    (dict(density=lambda p: -np.ones(len(p))), ">= 0"),
    (dict(density=lambda p: np.ones(3)), "one value per point"),
    (dict(at=[np.inf]), "at must be finite"),
])
def test_bad_inputs_are_refused(kwargs, words):
    args = dict(points=np.full((3, 3), 0.5), times=[0.0, 1.0, 2.0], density=_uniform_bins(), bins=EDGES)
    args.update(kwargs)
    with pytest.raises(UsageError, match=words):
        tb.transport.occupation(args.pop("points"), args.pop("times"), args.pop("density"), args.pop("bins"), **args)


def test_section_sigma_against_mpmath():
    """The numpy density summed over the sheets equals the sum of verify.section_volume's
    mpmath section_density over the roots (independent code: mpmath, fourth-order
    differences). Measured: <= 1.3e-9 relative (the central difference in theta of dE/dK);
    tolerance 1e-8."""
    from taylorball.verify.section_volume import section_density

    lev = FIG4A_LEVELS.as_kwargs()
    for p in [(2.0, 2.5, 1.0), (0.5, -1.0, 0.3), (4.0, 1.0, -2.0)]:
        s = tb.section_sigma(FIG4_BALL, **lev, points=[p])[0]
        _, info = tb.states_on_section(FIG4_BALL, **lev, point=p, direction=1, return_info=True)
        ref = sum(section_density(FIG4_BALL, **lev, point=p, K=K) for K in info["K"])
        assert abs(s / ref - 1) <= 1e-8


def test_section_sigma_directions_and_outside():
    lev = FIG4A_LEVELS.as_kwargs()
    pts = [(2.0, 2.5, 1.0), (1.0, 0.5, -0.5), (2.0, 50.0, 0.0)]
    up, down, both = (tb.section_sigma(FIG4_BALL, **lev, points=pts, direction=d) for d in (1, -1, None))
    np.testing.assert_allclose(up + down, both, rtol=4 * EPS)  # the same terms summed in another order
    assert both[2] == 0.0                         # outside the admissible region
    with pytest.raises(ChartError, match="points"):
        tb.section_sigma(FIG4_BALL, **lev, points=[(1.0, np.nan, 0.0)])
    with pytest.raises(ChartError, match="points"):
        tb.section_sigma(FIG4_BALL, **lev, points=[1.0, 2.0])


# ---------------------------------------------------------------------------------------
# the fold-free Monte Carlo sample of sigma (tb.section_sigma_sample)
# ---------------------------------------------------------------------------------------
def _gauss_box(lev, lo, hi, q):
    """q^3-point Gauss-Legendre integral of tb.section_sigma over the box [lo, hi]."""
    x, w = np.polynomial.legendre.leggauss(q)
    c, hw = (lo + hi) / 2, (hi - lo) / 2
    grid = np.array(np.meshgrid(*[c[k] + hw[k] * x for k in range(3)], indexing="ij")).reshape(3, -1).T
    W = np.einsum("i,j,k->ijk", w, w, w).ravel() * np.prod(hw)
    return float(np.sum(tb.section_sigma(FIG4_BALL, **lev, points=grid) * W))


def test_sigma_sample_measures_boxes_as_the_density_does():
    """On boxes away from every fold, where the Gauss quadrature of tb.section_sigma (checked
    against mpmath above) converges (3 and 4 points per coordinate agree to 0.3 %), the
    sample's weight in the box equals that integral within 4 Monte Carlo standard errors
    (se from the sample's own second moment; measured at this seed -0.1 and -2.3 se; the
    second box with 1.6e7 other draws +0.24 se, and max weight / mean weight 3.3: bounded). A sample from
    another density, or weights missing the 1/sqrt(det Q) or sin(theta) factor, miss by
    tens of se."""
    lev = FIG4A_LEVELS.as_kwargs()
    s = tb.section_sigma_sample(FIG4_BALL, **lev, n=4_000_000, seed=7)
    P, w, n = s["points"], s["weights"], s["n"]
    hw = np.array([0.3, 0.75, 0.75])
    for c in (np.array([5.7, -1.4, 1.5]), np.array([2.0, 2.5, 1.0])):
        g3, g4 = _gauss_box(lev, c - hw, c + hw, 3), _gauss_box(lev, c - hw, c + hw, 4)
        assert abs(g3 / g4 - 1) < 3e-3, (g3, g4)  # the box is smooth: the reference has converged
        inb = np.all((P >= c - hw) & (P < c + hw), axis=1)
        est = w[inb].sum()
        se = np.sqrt(n * np.sum(w[inb] ** 2) - est**2) / np.sqrt(n)  # sd of n w 1[box] over sqrt(n)
        assert abs(est - g4) <= 4 * se, (c, est, g4, se)
        assert se < 0.03 * g4  # the test has power: a 12 % error fails


def test_sigma_sample_points_are_on_the_level_and_split_by_direction():
    """Each sampled point with its K is a state of the level (C, M_gamma, h) (tb.integrals
    against tb.integral_scales: measured 10 eps of the energy's scale, bound 2^6 eps), on the section g = 0 crossing upward; the draws
    are the same for every direction, so the +1 and -1 samples partition the None one."""
    from taylorball.charts import reduced_state_from_chart

    lev = FIG4A_LEVELS.as_kwargs()
    s = tb.section_sigma_sample(FIG4_BALL, **lev, n=2000, seed=3)
    X = reduced_state_from_chart(FIG4_BALL, C=lev["C"], M_gamma=lev["M_gamma"], K=s["K"], l=s["points"][:, 0],
                                 g=0.0, r1=s["points"][:, 1], r2=s["points"][:, 2])
    for x in X[:50]:
        I, S = tb.integrals("reduced", FIG4_BALL, x), tb.integral_scales("reduced", FIG4_BALL, x)
        assert abs(I["E"] - lev["h"]) <= 2**6 * EPS * S["E"]
        assert abs(I["C2"] - lev["C"] ** 2) <= 2**6 * EPS * S["C2"]
        assert abs(I["M_gamma"] - lev["M_gamma"]) <= 2**6 * EPS * S["M_gamma"]
        g = tb.reduced_chart(FIG4_BALL, x)["g"]
        assert min(abs(g), abs(g - 2 * np.pi)) <= 2**6 * EPS * 2 * np.pi  # g = 0 mod 2 pi
    both, up, down = (tb.section_sigma_sample(FIG4_BALL, **lev, n=2000, seed=3, direction=d) for d in (None, 1, -1))
    np.testing.assert_array_equal(np.sort(both["weights"]), np.sort(np.concatenate([up["weights"], down["weights"]])))
    assert up["n"] == 2000 and len(up["weights"]) <= 2000 and up["total"] == pytest.approx(up["weights"].sum())


def test_sigma_sample_refuses_bad_input():
    from taylorball.params import BallParams

    lev = FIG4A_LEVELS.as_kwargs()
    still = BallParams(inertia=FIG4_BALL.inertia, mass=1.0, radius=5.0, plane_rate=0.0)
    with pytest.raises(ChartError, match="plane_rate"):
        tb.section_sigma_sample(still, **lev, n=10)
    with pytest.raises(UsageError, match="n"):
        tb.section_sigma_sample(FIG4_BALL, **lev, n=0)
    with pytest.raises(UsageError, match="direction"):
        tb.section_sigma_sample(FIG4_BALL, **lev, n=10, direction=2)
