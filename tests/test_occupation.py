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
