"""The precision study (taylorball.verify.precision, ``taylorball verify --precision``).

Short runs of the real machinery on two reference orbits, against the 256-bit reference,
with the reference itself checked by a 320-bit run. Bounds are in units of each type's
machine epsilon; each factor is justified where it is used. Everything here takes ~10 s;
the chaotic-rate test is ``slow``.
"""

import math

import numpy as np
import pytest

import taylorball as tb
from taylorball import cli
from taylorball.errors import ChartError, UsageError
from taylorball.verify.precision import (
    NUMBER_TYPES,
    REFERENCE_TYPE,
    fit_growth,
    format_report,
    mparallel_state_on_levels,
    PrecisionReport,
    reduced_state_on_levels,
    reference_orbits,
    report_markdown,
    run_type,
    study_orbit,
    time_grid,
)

ORBITS = {o.name: o for o in reference_orbits()}
LABELS = [lab for lab, _, _ in NUMBER_TYPES]


@pytest.fixture(scope="module")
def short_results():
    """mparallel-ball to t = 10 and reduced-fig4a to t = 2 (the chaotic orbit, short)."""
    out = {}
    for name, grid in (("mparallel-ball", [0.0, 0.5, 1.0, 2.0, 5.0, 10.0]), ("reduced-fig4a", [0.0, 0.5, 1.0, 2.0])):
        out[name] = study_orbit(ORBITS[name], grid, cheap_repeats=3)
    return out


# --- initial conditions on the paper's levels ---------------------------------------------
def test_reduced_state_hits_levels():
    """|M| = C, (M, gamma) = M_gamma, E = h, checked by an independent 50-digit mpmath
    evaluation; the constraints hold to rounding. The quadratic solve for |R| and the
    3x3 linear solve cost a few hundred eps at most (measured ~200 eps on E); 1e-12
    relative still rules out any formula error (which would be O(1))."""
    p = ORBITS["reduced-fig4a"].params
    s = reduced_state_on_levels(p, 10.0, 2.0, 5.0)
    v = tb.integrals_mp("reduced", p, s, dps=50)
    assert abs(float(v["C2"]) - 100.0) <= 1e-12 * 100.0
    assert abs(float(v["M_gamma"]) - 2.0) <= 1e-12 * 10.0  # scale |M||gamma| = 10
    assert abs(float(v["E"]) - 5.0) <= 1e-12 * 50.0  # energy terms are ~50 in size here
    assert abs(float(v["gamma2"]) - 1.0) <= 4 * 2.0**-52
    assert abs(float(v["R_gamma"])) <= 16 * 2.0**-52 * 16.0


def test_mparallel_state_hits_levels_fig1():
    o = ORBITS["mparallel-fig1"]
    v = tb.integrals_mp("mparallel", o.params, o.state, dps=50)
    assert abs(float(v["lambda"]) - 2.0) <= 1e-12 * 13.0
    assert abs(float(v["E"]) - 100.0) <= 1e-12 * 100.0


def test_levels_out_of_reach_raise():
    p = ORBITS["reduced-fig4a"].params
    with pytest.raises(ChartError, match="M_gamma"):
        reduced_state_on_levels(p, 1.0, 2.0, 5.0)
    with pytest.raises(ChartError, match="not reached"):
        mparallel_state_on_levels(ORBITS["mparallel-ball"].params, 2.0, 1e6)


# --- the comparison itself -----------------------------------------------------------------
@pytest.mark.parametrize("name", ["mparallel-ball", "reduced-fig4a"])
def test_digits_at_short_times_in_eps_units(short_results, name):
    """Up to t = 1 each type agrees with the reference to within 100 eps of its own kind:
    ~20 steps per time unit, each adding an O(eps) rounding error (random walk: sqrt(N) ~ 5),
    amplified by the flow by a factor of a few over one time unit; measured 0.4 .. 10 eps.
    A conversion through float64 anywhere in the long double or real128 pipeline (params,
    projection, output) would show as an error ~1e-16, i.e. 1e3 / 1e16 of their eps."""
    res = short_results[name]
    upto1 = res.times <= 1.0
    for lab in LABELS:
        eps = res.runs[lab].eps
        assert np.all(res.errors[lab][upto1] <= 100 * eps), (lab, res.errors[lab] / eps)


@pytest.mark.parametrize("name", ["mparallel-ball", "reduced-fig4a"])
def test_real128_far_more_digits_than_float64(short_results, name):
    """real128 has log10(2^60) = 18.1 more digits than float64, long double log10(2^11) =
    3.3 more. The errors are rounding random walks, so at one sample either run may sit
    well below its typical size; allow a factor 200 (2.3 digits) between the two runs'
    error constants: require 15.8, 1.0 and 12.5 more digits at every sample (measured
    gaps: 16.6 .. 18.1, 2.0 .. 3.4, 14.4 .. 15.0)."""
    res = short_results[name]
    d = res.digits
    assert np.all(d["real128"] >= d["float64"] + 15.8), (d["real128"], d["float64"])
    assert np.all(d["longdouble"] >= d["float64"] + 1.0), (d["longdouble"], d["float64"])
    assert np.all(d["real128"] >= d["longdouble"] + 12.5), (d["real128"], d["longdouble"])


@pytest.mark.parametrize("name", ["mparallel-ball", "reduced-fig4a"])
def test_digits_decrease_with_time(short_results, name):
    """The error at t = 0 is only the working-precision snap (< 1 eps); after tens of steps
    it has grown by more than a factor 3 (half a digit) in every type."""
    res = short_results[name]
    for lab in LABELS:
        assert res.digits[lab][-1] <= res.digits[lab][0] - 0.5, (lab, res.digits[lab])


@pytest.mark.parametrize("name", ["mparallel-ball", "reduced-fig4a"])
def test_reference_checked_by_higher_precision(short_results, name):
    """The 256-bit run agrees with the 320-bit run to >= 70 digits (256 bits = 77 digits;
    over t <= 10 the error grows by less than 10^7), far beyond real128's 34."""
    res = short_results[name]
    chk = res.reference_check
    assert chk is not None and len(chk["times"]) == len(res.times)
    assert np.all(np.asarray(chk["digits"]) >= 70.0), chk["digits"]


@pytest.mark.parametrize("name", ["mparallel-ball", "reduced-fig4a"])
def test_integral_drift_in_eps_units(short_results, name):
    """Drift of every first integral <= 8 sqrt(N) + 16 eps of the type after N steps: the
    rounding random walk of tests/test_propagate.py (K_DRIFT = 8), plus 16 eps for
    evaluating the integrals themselves in the working precision (sums of ~10 products)."""
    res = short_results[name]
    for lab, run in res.runs.items():
        bound = 8 * math.sqrt(max(int(run.steps[-1]), 1)) + 16
        for k, drift in run.drift().items():
            assert np.max(drift) / run.eps <= bound, (lab, k, np.max(drift) / run.eps, bound)


def test_order_and_cost_grow_with_precision(short_results):
    """heyoka picks the Taylor order from the tolerance (~ -ln(eps)/2): it increases
    strictly with precision. Cost: real128 is software arithmetic (~1000x float64 per
    step here), so > 10x float64 even on a loaded machine; real256 costs more than
    real128 (~7x)."""
    res = short_results["reduced-fig4a"]
    orders = [res.runs[lab].order for lab in [*LABELS, REFERENCE_TYPE[0]]]
    assert orders == sorted(orders) and len(set(orders)) == len(orders), orders
    assert res.cost_ratio("real128") > 10.0
    assert res.runs["real256"].wall_per_time > res.runs["real128"].wall_per_time
    for run in res.runs.values():
        assert run.steps_per_time > 0 and np.all(np.diff(run.steps) > 0)


def test_report_tables_have_expected_rows(short_results):
    rep = PrecisionReport(mode="test", date="today", machine="here", wall=0.0,
                          results=[short_results["mparallel-ball"], short_results["reduced-fig4a"]])
    text = format_report(rep)
    md = report_markdown(rep)
    for name in ("mparallel-ball", "reduced-fig4a"):
        assert name in text and f"### {name}" in md
    lines = text.splitlines()
    for lab in [*LABELS, "real256"]:
        # one cost row per type and orbit, one growth row per compared type and orbit
        assert sum(1 for ln in lines if ln.strip().startswith(lab + " ")) == (2 if lab == "real256" else 4), lab
    # digit rows: t = 0, the decades (1, 10) and the last sample, for mparallel-ball
    block = text.split("mparallel-ball (")[1].split("-- error growth")[0]
    rows = [ln.split()[0] for ln in block.splitlines() if ln.strip() and ln.strip()[0].isdigit()]
    assert rows == ["0", "1", "10"], rows
    assert "real256 vs real320" in text
    d = rep.as_dict()
    assert [r["orbit"]["name"] for r in d["results"]] == ["mparallel-ball", "reduced-fig4a"]


# --- helpers ---------------------------------------------------------------------------------
def test_fit_growth_on_synthetic_errors():
    t = np.linspace(0, 200, 41)
    fit = fit_growth(t, 1e-16 * np.exp(0.1 * t))
    assert fit.model == "exponential" and abs(fit.rate - 0.1) <= 1e-9
    fit = fit_growth(t, 1e-16 * t)
    assert fit.model == "power" and abs(fit.power - 1.0) <= 1e-9
    # saturated samples (>= 1e-2) and everything after them are left out
    fit = fit_growth(t, np.minimum(1e-16 * np.exp(0.2 * t), 1.0))
    assert fit.n == int(np.sum((t > 0) & (1e-16 * np.exp(0.2 * t) < 1e-2)))
    assert abs(fit.rate - 0.2) <= 1e-9
    assert fit_growth([0.0, 1.0], [1e-16, 2e-16]).model == "-"


def test_time_grid():
    g = time_grid(100.0)
    assert g[0] == 0.0 and g[-1] == 100.0 and np.all(np.diff(g) > 0)
    assert {1.0, 10.0, 50.0, 90.0} <= set(g.tolist())


def test_run_type_rejects_bad_grid():
    with pytest.raises(UsageError, match="increasing"):
        run_type(ORBITS["mparallel-ball"], [1.0, 2.0], "float")


def test_cli_unknown_orbit_and_short_run(capsys):
    assert cli.main(["verify", "--precision", "--only", "nope"]) == 2
    assert "unknown orbit" in capsys.readouterr().err
    assert cli.main(["verify", "--precision", "--only", "mparallel-ball", "--t-end", "2"]) == 0
    out = capsys.readouterr().out
    assert "correct digits" in out and "mparallel-ball" in out and "cost vs float64" in out


# --- slow: the chaotic orbit --------------------------------------------------------------
@pytest.mark.slow
def test_chaotic_rate_is_the_same_in_every_type():
    """On the chaotic Fig. 4a-type orbit, float64, long double and real128 errors grow
    exponentially at the same rate (a property of the flow, not of the number type):
    rates within 30% of each other (finite-time rates over ~100 time units fluctuate)."""
    res = study_orbit(ORBITS["reduced-fig4a"], time_grid(150.0), check=None)
    rates = {lab: res.growth[lab].rate for lab in LABELS}
    assert all(res.growth[lab].model == "exponential" for lab in LABELS), res.growth
    lo, hi = min(rates.values()), max(rates.values())
    assert lo > 0.02 and hi <= 1.3 * lo, rates
