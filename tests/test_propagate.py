"""propagate(): layout contract, number types, options, errors, and integral drift.

Drift bound: a Taylor integrator at tol = eps makes a rounding-size error per step that
behaves like a random walk, so the drift of a first integral after N steps is expected at
~eps * sqrt(N) times the integral's scale (measured: 0.01 .. 1.1 for every integral of the
three systems over 1e3 .. 1e4 time units and 8e3 .. 8e5 steps). K_DRIFT = 8 allows the
tail of the walk's maximum excursion; a linear (secular) drift of a wrong formula would be
~eps * N, 300 .. 900 times larger at these step counts.
"""

import warnings

import heyoka as hy
import numpy as np
import pytest

import taylorball as tb
from taylorball._integrals import integrals_cfunc
from taylorball.model import PUBLIC_NAMES
from taylorball._propagate import make_integrator

from .conftest import FIG5, SYMMETRIC, demo_reduced_state

EPS = 2.0**-52
K_DRIFT = 8


def _state(kind):
    s = demo_reduced_state()
    if kind == "reduced":
        return s
    if kind == "full":
        return tb.reduced_to_full(FIG5, s)
    return np.concatenate([[0.5, -1.0, 2.0], s[3:6]])


def _params(kind):
    return FIG5.to_mparallel() if kind == "mparallel" else FIG5


# --- contract ----------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["full", "reduced", "mparallel"])
@pytest.mark.parametrize(
    "fp_type, prec", [(float, None), (np.longdouble, None), (hy.real128, None), (hy.real, 128)]
)
def test_layout_and_dtype_contract(kind, fp_type, prec):
    """Every system, every number type: public layout in, public layout out, same dtype,
    and the initial point is returned unchanged (up to the working-precision snap)."""
    s = _state(kind)
    out = tb.propagate(kind, _params(kind), s, 0.0, fp_type=fp_type, prec=prec)
    assert out.shape == (len(PUBLIC_NAMES[kind]),)
    assert out.dtype == np.dtype(fp_type)
    assert np.max(np.abs(out.astype(float) - s)) <= 16 * EPS * (1 + np.max(np.abs(s)))
    out = tb.propagate(kind, _params(kind), s, 0.5, fp_type=fp_type, prec=prec)
    assert np.all(np.isfinite(out.astype(float)))


def test_public_names():
    assert PUBLIC_NAMES["full"] == (
        "omega1", "omega2", "omega3", "alpha1", "alpha2", "alpha3", "beta1", "beta2", "beta3",
        "gamma1", "gamma2", "gamma3", "x", "y",
    )
    assert PUBLIC_NAMES["reduced"] == ("omega1", "omega2", "omega3", "gamma1", "gamma2", "gamma3", "R1", "R2", "R3")
    assert PUBLIC_NAMES["mparallel"] == ("K1", "K2", "K3", "gamma1", "gamma2", "gamma3")


def test_time_grid_matches_single_calls():
    s = _state("reduced")
    grid = np.array([0.0, 0.5, 2.0])
    out = tb.propagate("reduced", FIG5, s, grid)
    assert out.shape == (3, 9)
    one = tb.propagate("reduced", FIG5, s, 2.0)
    # dense output at a grid point vs stepping onto it: a few eps of the state's size
    assert np.max(np.abs(out[-1] - one)) <= 64 * EPS * np.max(np.abs(one))


def test_backward_in_time_returns_to_start():
    s = _state("reduced")
    fwd = tb.propagate("reduced", FIG5, s, 3.0, fp_type=hy.real128)
    back = tb.propagate("reduced", FIG5, fwd, -3.0, fp_type=hy.real128)
    # error growth over t = 3 is < 1e2 here: 2^16 eps_128 ~ 1e-29 is still ~1e-13 of eps_64
    assert float(np.max(np.abs(back - tb.project("reduced", s.astype(hy.real128))))) <= 2**16 * 2.0**-112


def test_formulations_agree():
    """Momentum form vs paper eqs. (15)-(16) [eq10] literally: same orbit to rounding x growth."""
    s = _state("reduced")
    a = tb.propagate("reduced", FIG5, s, 5.0, fp_type=hy.real128, formulation="momentum")
    b = tb.propagate("reduced", FIG5, s, 5.0, fp_type=hy.real128, formulation="omega")
    assert float(np.max(np.abs(a - b))) <= 2**16 * 2.0**-112
    for kind in ("full",):
        f = _state(kind)
        a = tb.propagate(kind, FIG5, f, 5.0, fp_type=hy.real128, formulation="momentum")
        b = tb.propagate(kind, FIG5, f, 5.0, fp_type=hy.real128, formulation="omega")
        assert float(np.max(np.abs(a - b))) <= 2**16 * 2.0**-112 * (1 + float(np.max(np.abs(a))))


def test_real_precision_agrees_with_real128():
    s = _state("mparallel")
    q = FIG5.to_mparallel()
    a = tb.propagate("mparallel", q, s, 2.0, fp_type=hy.real128)
    b = tb.propagate("mparallel", q, s, 2.0, fp_type=hy.real, prec=200)
    assert b[0].prec == 200
    # both projected from the same float64 state; real128 accuracy limits the agreement
    assert float(np.max(np.abs(a - b.astype(hy.real128)))) <= 2**12 * 2.0**-112


# --- bad input ---------------------------------------------------------------------------
def test_bad_kind_and_options():
    s = _state("reduced")
    with pytest.raises(tb.UsageError, match="kind must be one of"):
        tb.propagate("reduce", FIG5, s, 1.0)
    with pytest.raises(tb.UsageError, match="fp_type must be one of"):
        tb.propagate("reduced", FIG5, s, 1.0, fp_type=np.float32)
    with pytest.raises(tb.UsageError, match="needs prec"):
        tb.propagate("reduced", FIG5, s, 1.0, fp_type=hy.real)
    with pytest.raises(tb.UsageError, match="prec is only for"):
        tb.propagate("reduced", FIG5, s, 1.0, prec=100)
    with pytest.raises(tb.UsageError, match="formulation must be one of"):
        tb.propagate("reduced", FIG5, s, 1.0, formulation="lagrange")
    with pytest.raises(tb.UsageError, match="strictly increasing"):
        tb.propagate("reduced", FIG5, s, [0.0, 2.0, 1.0])


def test_wrong_params_type():
    with pytest.raises(tb.ParameterError, match="must be BallParams"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tb.propagate("reduced", tb.MParallelParams(a=(1, 2, 3), d=4), _state("reduced"), 1.0)


def test_singular_configuration_raises_integration_error():
    """d a_i straddling 1: the field is singular where d (gamma, A gamma) = 1."""
    with pytest.warns(tb.UnphysicalParametersWarning):
        q = tb.MParallelParams(a=(0.5, 2.0, 2.5), d=1.0, plane_rate=0.0)
    g = np.array([np.sqrt(2 / 3), np.sqrt(1 / 3), 0.0])  # 1 - d (g, A g) = 0 (to rounding)
    with pytest.raises(tb.IntegrationError, match="non-finite|singular"):
        tb.propagate("mparallel", q, np.concatenate([[1.0, 1.0, 1.0], g]), 10.0)


# --- drift ---------------------------------------------------------------------------------
def _drift_ratios(kind, params, state, T, n=64):
    """max_t |I(t) - I(0)| / (eps sqrt(steps) max_t scale(t)) for every integral."""
    ta, system, spec = make_integrator(kind, params, state)
    res = ta.propagate_grid(np.linspace(0.0, T, n))
    steps = res[3]
    X = res[-1]
    vals = integrals_cfunc(kind)(X, ta.pars)
    scales = integrals_cfunc(kind, which="scales")(X, ta.pars)
    return steps, {
        k: float(np.max(np.abs(vals[k] - vals[k][0]))) / (EPS * np.sqrt(steps) * float(np.max(np.abs(scales[k]))))
        for k in vals
    }


@pytest.mark.parametrize("kind, T", [("reduced", 2000.0), ("full", 1000.0), ("mparallel", 5000.0)])
def test_integral_drift_float64(kind, T):
    steps, ratios = _drift_ratios(kind, _params(kind), _state(kind), T)
    print(f"{kind}: {steps} steps to t={T}; drift / (eps sqrt(steps) scale): "
          + ", ".join(f"{k}={v:.2f}" for k, v in ratios.items()))
    for k, r in ratios.items():
        assert r <= K_DRIFT, f"{kind}: {k} drift {r:.2f} eps sqrt(steps) > {K_DRIFT}"


@pytest.mark.slow
@pytest.mark.parametrize("params", [FIG5, SYMMETRIC], ids=["fig5", "symmetric"])
def test_integral_drift_float64_long(params):
    """1e5 time units (~8e6 steps): drift stays a random walk."""
    steps, ratios = _drift_ratios("reduced", params, _state("reduced"), 1e5, n=256)
    print(f"reduced 1e5: {steps} steps; " + ", ".join(f"{k}={v:.2f}" for k, v in ratios.items()))
    for k, r in ratios.items():
        assert r <= K_DRIFT, k


def test_long_double_values_convert_to_real128_exactly():
    """A long double handed to a real128 run keeps all its bits (it went through repr(),
    which numpy 2 spells "np.longdouble('...')", and raised)."""
    from taylorball.numbers import resolve_fp_type

    spec = resolve_fp_type(hy.real128)
    for v in (np.longdouble(1) / 3, -np.longdouble(2) ** -70 * 7, np.longdouble("1e-4000"), np.longdouble(0)):
        q = spec.scalar(v)
        assert isinstance(q, hy.real128)
        assert np.longdouble(str(q)) == v  # round trip: every bit of the 64-bit mantissa
