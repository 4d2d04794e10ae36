"""The tangent equation's ``J d`` formed two ways (taylorball.tangent, ``jacobian``):
``"forward"`` (forward-mode differentiation of the vector field, an option of the lane
runs) and ``"symbolic"`` (heyoka's derivative of each component, the equations of earlier
releases). Both are checked against a directional derivative computed by mpmath at 40
digits; the forward runs' MEGNO against long double runs; ``"symbolic"`` against the bits
of the earlier releases; bad values are refused before any work."""

import hashlib

import numpy as np
import pytest

import taylorball as tb
from taylorball.model import get_system
from taylorball.paper import FIG4_BALL, FIG4B_LEVELS
from taylorball.tangent import SEED_KINDS, TangentSystem

EPS = np.finfo(float).eps


def _pars(kind):
    """The parameter vector of FIG4_BALL for ``kind`` (``(a1, a2, a3, d, Omega)`` for M||gamma)."""
    from taylorball._problem import problem

    return [float(v) for v in problem(kind, FIG4_BALL).pars]


@pytest.mark.parametrize("kind", SEED_KINDS)
def test_J_d_of_both_forms_matches_an_mpmath_directional_derivative(kind):
    import heyoka as hy
    import mpmath

    system = get_system(kind)
    n = system.dim
    pars = _pars(kind)
    rng = np.random.default_rng(7)
    points = [(rng.normal(size=n), rng.normal(size=n)) for _ in range(4)]
    got = {}
    for jac in ("forward", "symbolic"):
        eqs = TangentSystem(system, "one", jacobian=jac).equations()
        cf = hy.cfunc([rhs for _, rhs in eqs[n:]], vars=[v for v, _ in eqs], compact_mode=True)
        got[jac] = [cf(np.concatenate([x, d]), pars=pars) for x, d in points]
    with mpmath.workdps(40):
        mp_pars = [mpmath.mpf(p) for p in pars]
        for k, (x, d) in enumerate(points):
            def g(s, i):
                return system.rhs(mp_pars, [mpmath.mpf(a) + s * mpmath.mpf(b) for a, b in zip(x, d)])[i]

            ref = np.array([float(mpmath.diff(lambda s: g(s, i), 0)) for i in range(n)])
            # the derivative's terms are of the size of |J| |d|, larger than J d itself where
            # they cancel: the error is measured against the largest component; each component
            # is a few dozen roundings of such terms (measured <= 16 eps for both forms), so
            # 256 eps allows a factor ~10 more without letting a wrong term (O(1)) through
            scale = np.max(np.abs(ref))
            for jac in ("forward", "symbolic"):
                err = np.max(np.abs(got[jac][k] - ref)) / scale
                assert err <= 256 * EPS, f"{kind}, {jac}, point {k}: J d off by {err / EPS:.1f} eps"


def test_symbolic_is_the_default_and_forward_is_the_smaller_graph():
    # the default keeps the bits the figures' documented numbers were made with
    assert tb.MegnoOptions().jacobian == "symbolic" and tb.MegnoMapOptions().jacobian == "symbolic"
    sys_ = get_system("reduced")
    fwd = TangentSystem(sys_, "one", True, "compact", "forward")
    sym = TangentSystem(sys_, "one", True, "compact", "symbolic")
    # the forward form shares the field's intermediate results: far fewer operations
    import heyoka as hy

    sizes = {}
    for name, ts in (("forward", fwd), ("symbolic", sym)):
        eqs = ts.equations()
        ta = hy.taylor_adaptive(eqs, [0.1] * len(eqs), pars=[0.0] * sys_.n_pars, compact_mode=True)
        sizes[name] = len(ta.decomposition) - 2 * len(eqs)
    assert sizes == {"forward": 223, "symbolic": 599}, sizes


def test_symbolic_form_is_the_equations_of_earlier_releases():
    """``jacobian="symbolic"`` builds exactly the expressions of earlier releases (written
    out here as they were: ``sum_j diff(f_i, x_j) d_j``)."""
    import heyoka as hy

    for kind in SEED_KINDS:
        system = get_system(kind)
        xs = hy.make_vars(*system.internal_names)
        ds = hy.make_vars(*[f"d_{v}" for v in system.internal_names])
        f = system.rhs([hy.par[i] for i in range(system.n_pars)], xs)
        old = list(zip(xs, f)) + [(d, hy.sum([hy.diff(fi, xj) * dj for xj, dj in zip(xs, ds)])) for d, fi in zip(ds, f)]
        new = TangentSystem(system, "one", jacobian="symbolic").equations()
        assert [(str(a), str(b)) for a, b in new] == [(str(a), str(b)) for a, b in old], kind


#: sha256 of the values and times of an 8 x 8 map of the Fig. 4b level (l = 0, T = 100,
#: compact mode, one worker), computed by the code of 2026-11-28 before the forward form
#: existed (heyoka 7.13.2, numpy 2.4.6, 4 float64 lanes, Intel Xeon). A batch integrator's
#: bits can depend on the SIMD width and the CPU: elsewhere only the other checks run.
SYMBOLIC_MAP_SHA256 = "b1e20268059ac03334c4858e065a07e5b12e2745e9faff681becd01a1c22cd9f"


def _map(jacobian):
    return tb.megno_map(FIG4_BALL, FIG4B_LEVELS, l=0.0, r1=(-5.5, 7.0, 8), r2=(-8.0, 8.0, 8), t_end=100.0,
                        workers=1, options=tb.MegnoMapOptions(compact_mode=True, jacobian=jacobian))


def test_symbolic_map_keeps_the_bits_of_earlier_releases_and_forward_agrees_to_rounding():
    from taylorball.sections import batch_size

    sym, fwd = _map("symbolic"), _map("forward")
    assert sym.attrs["jacobian"] == "symbolic" and fwd.attrs["jacobian"] == "forward"
    if batch_size() == 4:
        digest = hashlib.sha256(sym.values.tobytes() + sym.t.values.tobytes()).hexdigest()
        assert digest == SYMBOLIC_MAP_SHA256
    ok = np.isfinite(sym.values)
    assert np.array_equal(ok, np.isfinite(fwd.values)) and ok.sum() >= 10
    a, b = sym.values[ok], fwd.values[ok]
    assert not np.array_equal(a, b)  # the option reaches the runs
    # to rounding: these 32 orbits are regular or not yet chaotic by T = 100 (<Y> < 4);
    # measured <= 9e3 eps of <Y> apart; 1e6 eps allows ~100x that, a wrong J d is O(1) off
    assert np.all(a < 4)
    assert np.max(np.abs(a - b) / np.spacing(a)) <= 1e6


def test_forward_megno_is_as_accurate_as_symbolic_against_long_double():
    """MEGNO of regular orbits of the Fig. 4b level to T = 200 in float64, both forms, against
    a long double run (64-bit mantissa: its own error ~2000x below float64's). Measured here
    (these three orbits): errors 4e3 .. 1e4 eps of <Y> (forward), 2e3 .. 1.1e4 (symbolic);
    on ten regular orbits of the 12 x 12 map at T = 1000: 4e3 .. 2e5 (forward), 7e3 .. 6e5
    (symbolic): neither form is the more accurate."""
    from taylorball.maps import _row_states
    from taylorball.manifold import params_for

    p = params_for("reduced", FIG4_BALL)
    rows = [_row_states(p, FIG4B_LEVELS, 0.0, np.linspace(-5.5, 7.0, 12), b, 0.0, 1, 0, 2001)[0]
            for b in np.linspace(-8.0, 8.0, 12)[1:3]]
    states = np.concatenate(rows)
    states = states[np.isfinite(states[:, 0])][[0, 1, 3]]
    T = 200.0
    errs = {}
    ref = np.array([float(tb.megno("reduced", FIG4_BALL, x, T, fp_type=np.longdouble).mean_megno) for x in states])
    assert np.all((ref > 1.0) & (ref < 3.0)), ref  # regular orbits: the float64 error is not chaos's
    for jac in ("forward", "symbolic"):
        got = np.array([r.mean_megno for r in tb.megno_many("reduced", FIG4_BALL, states, T, workers=1,
                                                             options=tb.MegnoOptions(jacobian=jac))])
        errs[jac] = np.abs(got - ref) / np.spacing(ref)
    # a float64 run's own error on 200 t.u. (each orbit's rounding amplified linearly on a
    # torus): measured <= 1.1e4 eps; 1e5 eps leaves a factor ~9; a wrong J d is off by O(1)
    assert np.all(errs["forward"] <= 1e5), errs
    assert np.all(errs["symbolic"] <= 1e5), errs


@pytest.mark.parametrize("bad", ["Forward", "exact", None, 1])
def test_bad_jacobian_is_refused_before_any_work(bad, monkeypatch):
    import taylorball.charts as charts

    def no_work(*a, **k):
        raise AssertionError("work started before the arguments were checked")

    monkeypatch.setattr(charts, "states_on_section", no_work)
    monkeypatch.setattr(charts, "_section_states", no_work)
    monkeypatch.setattr(charts, "section_admissible_sample", no_work)
    with pytest.raises(tb.UsageError, match="jacobian must be one of"):
        tb.megno_map(FIG4_BALL, FIG4B_LEVELS, l=0.0, r1=(-5.5, 7.0, 4), r2=(-8.0, 8.0, 4), t_end=10.0,
                     options=tb.MegnoMapOptions(jacobian=bad))
    with pytest.raises(tb.UsageError, match="jacobian must be one of"):
        tb.megno_many("reduced", FIG4_BALL, [np.full(9, np.nan)], 10.0, options=tb.MegnoOptions(jacobian=bad))
    with pytest.raises(tb.UsageError, match="jacobian must be one of"):
        tb.chaotic_fraction(FIG4_BALL, FIG4B_LEVELS, n=2, t_end=10.0, options=tb.MegnoOptions(jacobian=bad))
    with pytest.raises(tb.UsageError, match="jacobian must be one of"):
        TangentSystem(get_system("reduced"), "one", jacobian=bad)
    with pytest.raises(tb.UsageError, match="needs vectors='one'"):
        TangentSystem(get_system("reduced"), "all", jacobian="forward")
