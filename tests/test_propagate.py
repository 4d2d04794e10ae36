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


# --- many states: the SIMD lanes -----------------------------------------------------------
def _many_states(n, seed=3):
    from .conftest import nearby_reduced_states

    return np.stack(nearby_reduced_states(n, seed))


def _raw_batch(prob, rows_internal, t_end):
    """Raw heyoka batch mode on the package's compiled batch system (a copy of the cached
    template, one state per lane, every lane to ``t_end``): what the lanes must equal."""
    import copy

    from taylorball._propagate import _batch_template

    ta = copy.copy(_batch_template(prob))
    size = ta.batch_size
    out = []
    for start in range(0, len(rows_internal), size):
        block = rows_internal[start : start + size]
        ta.set_time(np.zeros(size))
        for lane in range(size):
            ta.state[:, lane] = block[min(lane, len(block) - 1)]
            ta.pars[:, lane] = prob.pars
        ta.propagate_until(np.full(size, t_end))
        out.extend(np.array(ta.state[:, lane]) for lane in range(len(block)))
    return np.stack(out)


def test_many_states_are_raw_batch_bits_and_independent_of_company():
    """Rows of one call are bit-identical to raw heyoka batch mode on the same states,
    whatever the number of states, their order, and the workers."""
    from taylorball._propagate import public_states, start_state

    prob = tb.problem("reduced", FIG5)
    S = _many_states(11)
    t_end = 3.0
    many = tb.propagate(prob, S, t_end)
    assert many.shape == (11, 9) and many.dtype == np.float64
    raw = public_states(prob, _raw_batch(prob, [start_state(prob, s) for s in S], t_end))
    assert np.array_equal(many, raw)
    assert np.array_equal(tb.propagate(prob, S[::-1], t_end, workers=1), many[::-1])
    assert np.array_equal(tb.propagate(prob, S[4:5], t_end)[0], many[4])


def test_many_states_agree_with_one_state_calls_and_real128():
    """Batch mode rounds differently from scalar mode: both stay within the rounding error
    of a real128 reference. Bound: each step of either run rounds its Taylor polynomial's
    evaluation to a few ulp of the state, and over N steps these add up at most linearly;
    4 ulp per step (2 for each run's own rounding) x N steps x max|x| is that linear bound,
    valid while the orbit's error growth over the span stays O(1) (t = 3 on these orbits)."""
    prob = tb.problem("reduced", FIG5)
    S = _many_states(5)
    t_end = 3.0
    many = tb.propagate(prob, S, t_end)
    for i, s in enumerate(S):
        one = tb.propagate(prob, s, t_end)
        ref = tb.propagate(prob.replace(spec=tb.problem("reduced", FIG5, fp_type=hy.real128).spec), s,
                           t_end).astype(float)
        ta, _, _ = make_integrator(prob, s)
        steps = ta.propagate_until(t_end)[3]
        bound = 4 * steps * EPS * float(np.max(np.abs(ref)))
        assert float(np.max(np.abs(many[i] - ref))) <= bound, i
        assert float(np.max(np.abs(one - ref))) <= bound, i
        assert float(np.max(np.abs(many[i] - one))) <= 2 * bound, i


def test_many_states_on_a_grid_and_backwards():
    prob = tb.problem("reduced", FIG5)
    S = _many_states(3)
    grid = np.array([0.0, 0.5, 2.0])
    G = tb.propagate(prob, S, grid)
    assert G.shape == (3, 3, 9)
    assert np.array_equal(G[:, 2], tb.propagate(prob, S, 2.0))  # the grid's end is the lane's state there
    assert np.array_equal(G[:, 0], tb.propagate(prob, S, 0.0))  # time 0: the (projected) start states
    late = tb.propagate(prob, S, grid[1:])  # a grid not starting at 0
    assert late.shape == (3, 2, 9)
    assert np.array_equal(late, G[:, 1:])
    back = tb.propagate(prob, tb.propagate(prob, S, 2.0), -2.0)
    # there and back over t = 2: the linear rounding bound of the test above, twice the steps
    assert float(np.max(np.abs(back - S))) <= 4 * 2 * 100 * EPS * float(np.max(np.abs(S)))


def test_many_states_other_number_types_equal_one_state_calls():
    S = _many_states(2).astype(np.longdouble)
    many = tb.propagate("reduced", FIG5, S, 1.0, fp_type=np.longdouble)
    assert many.dtype == np.longdouble
    for i in range(2):
        assert np.array_equal(many[i], tb.propagate("reduced", FIG5, S[i], 1.0, fp_type=np.longdouble))


def test_many_states_bad_input_names_the_row():
    S = _many_states(3)
    S[1, 3] += 1e-3  # |gamma| != 1
    with pytest.raises(tb.ConstraintError, match=r"state\[1\]"):
        tb.propagate("reduced", FIG5, S, 1.0)
    with pytest.raises(tb.StateError, match=r"shape \(0, 9\)"):
        tb.propagate("reduced", FIG5, np.empty((0, 9)), 1.0)
    with pytest.raises(tb.StateError, match="9 entries"):
        tb.propagate("reduced", FIG5, np.zeros((2, 6)), 1.0)
    with pytest.raises(tb.UsageError, match="workers must be a positive integer"):
        tb.propagate("reduced", FIG5, _many_states(2), 1.0, workers=0)


def test_many_states_integration_error_names_the_row():
    with pytest.warns(tb.UnphysicalParametersWarning):
        q = tb.MParallelParams(a=(0.5, 2.0, 2.5), d=1.0, plane_rate=0.0)
    g = np.array([np.sqrt(2 / 3), np.sqrt(1 / 3), 0.0])  # 1 - d (g, A g) = 0 (to rounding)
    good = np.array([1.0, 1.0, 1.0, 0.0, 1.0, 0.0])  # reaches t = 1 (measured)
    with pytest.raises(tb.IntegrationError, match=r"state\[1\]"):
        tb.propagate("mparallel", q, np.stack([good, np.concatenate([[1.0, 1.0, 1.0], g])]), 1.0)


def test_propagate_reuses_its_working_copy_bit_identically():
    """propagate borrows an idle integrator copy: a call after others (another state, a
    grid, a failed run) gives the bits of the first call."""
    s = _state("reduced")
    first = tb.propagate("reduced", FIG5, s, 2.0)
    tb.propagate("reduced", FIG5, _many_states(1)[0], [0.5, 7.0])
    assert np.array_equal(tb.propagate("reduced", FIG5, s, 2.0), first)
