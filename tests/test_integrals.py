"""First integrals and invariant measures: conserved along the field, consistent forms.

The Lie derivative ``dI/dt = sum_i (dI/dx_i) f_i`` is built symbolically by heyoka from
the integral's expression and the vector field, compiled in quadruple precision and
evaluated at random admissible states projected onto the constraints in quadruple
precision. A correct integral gives a residual of rounding size (~1e-33 relative); a wrong
formula gives O(1). The tolerance is ``K_LIE * eps_128`` relative to ``sum_i |dI/dx_i f_i|``:
each term is a product of sums of ~10^2 roundings, so K_LIE = 2**10 leaves margin while
staying 25 orders of magnitude below a formula error.
"""

import math

import heyoka as hy
import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import taylorball as tb
from taylorball._integrals import INTEGRAL_NAMES, integral_expressions
from taylorball.model import get_system
from taylorball.numbers import resolve_fp_type

from .conftest import FIG5, STATES, ball_params

EPS128 = 2.0**-112
K_LIE = 2**10

_LIE = {}


def _lie_cfunc(kind, formulation, modify=None):
    """Compiled gradients dI/dx_i of every integral, the field f and omega, in real128.
    ``modify(exprs, xs)`` may alter the integrals' expressions (to test the test)."""
    key = (kind, formulation, modify)
    if key not in _LIE:
        system = get_system(kind, formulation)
        xs = hy.make_vars(*system.internal_names)
        pars = [hy.par[i] for i in range(system.n_pars)]
        f = system.rhs(pars, xs)
        exprs = integral_expressions(kind, formulation)
        if modify is not None:
            exprs = modify(exprs, xs)
        names = [k for k in INTEGRAL_NAMES[kind] if k in exprs]
        grads = [hy.diff(exprs[k], x) for k in names for x in xs]
        from taylorball._integrals import state_vectors

        omega = state_vectors(system, system.constants(pars), xs)["omega"]
        cf = hy.cfunc([*grads, *f, *omega], xs, fp_type=hy.real128, compact_mode=True)
        _LIE[key] = (system, names, cf)
    return _LIE[key]


def lie_residuals(kind, params, state, formulation=None, modify=None):
    """|dI/dt| / ref for every integral at one state, in real128.

    ``ref = sum_i |dI/dx_i| * B`` with ``B = (|x| + 1 + a + d)(|omega| + |Omega|)`` a bound on
    the magnitude of the terms that make up each component of the field (cross products of
    state vectors with omega or Omega gamma, a gamma x omega, d Omega gamma x omega), so
    that ``ref * eps`` bounds the rounding of the computed derivative even where the field
    itself vanishes (e.g. M parallel to omega)."""
    system, names, cf = _lie_cfunc(kind, formulation or get_system(kind).formulation, modify)
    spec = resolve_fp_type(hy.real128)
    from taylorball._propagate import working_state

    _, pars, internal = working_state(kind, params, state, spec, formulation=system.formulation)
    out = list(cf(internal, pars=pars))  # real128: sum before rounding to float
    n, m = system.dim, len(names)
    f = out[m * n : m * n + n]
    omega = [float(w) for w in out[m * n + n :]]
    p = [float(v) for v in pars]
    a_plus_d = p[4] + p[3] * p[4] ** 2 if kind != "mparallel" else p[3]
    size = math.sqrt(sum(float(v) ** 2 for v in internal)) + 1.0 + a_plus_d
    rate = math.sqrt(sum(w * w for w in omega)) + abs(p[-1])
    res = {}
    for j, k in enumerate(names):
        grad = out[j * n : (j + 1) * n]
        total = float(sum(gi * fi for gi, fi in zip(grad, f)))
        ref = sum(abs(float(gi)) for gi in grad) * size * rate
        res[k] = abs(total) / ref if ref > 0 else abs(total)
    return res


@pytest.mark.parametrize("kind", ["full", "reduced"])
@pytest.mark.parametrize("formulation", ["momentum", "omega"])
@settings(max_examples=25)
@given(data=st.data())
def test_integrals_have_zero_lie_derivative_ball(kind, formulation, data):
    params = data.draw(ball_params())
    state = data.draw(STATES[kind]())
    rel = lie_residuals(kind, params, state, formulation)
    for k, r in rel.items():
        assert r <= K_LIE * EPS128, f"{kind}/{formulation}: d{k}/dt relative residual {r:.3g}"


@settings(max_examples=25)
@given(state=STATES["mparallel"](), data=st.data())
def test_integrals_have_zero_lie_derivative_mparallel(state, data):
    params = data.draw(ball_params()).to_mparallel()
    rel = lie_residuals("mparallel", params, state)
    for k, r in rel.items():
        assert r <= K_LIE * EPS128, f"mparallel: d{k}/dt relative residual {r:.3g}"


def _perturb_C2(exprs, xs):
    return {**exprs, "C2": exprs["C2"] + sum(x * x for x in xs[6:9])}


def test_lie_derivative_detects_a_wrong_integral(fig5):
    """The check has teeth: (M, M) + (R, R) is not conserved, and it shows O(1)."""
    from .conftest import demo_reduced_state

    res = lie_residuals("reduced", fig5, demo_reduced_state(), modify=_perturb_C2)
    assert res["C2"] > 1e20 * K_LIE * EPS128  # measured 1.3e-4: 27 orders above tolerance
    assert res["E"] <= K_LIE * EPS128


def test_paper_fig1_params_integrals_conserved():
    """Unphysical parameters (D < 0 everywhere) keep the same integrals."""
    with pytest.warns(tb.UnphysicalParametersWarning):
        q = tb.MParallelParams(a=(1, 2, 3), d=4, plane_rate=0.5)
    s = np.array([0.3, -1.2, 0.8, 0.6, 0.0, 0.8])
    for k, r in lie_residuals("mparallel", q, s).items():
        assert r <= K_LIE * EPS128, k


# --- consistency of the different forms --------------------------------------------------
def test_integrals_numpy_match_mpmath(fig5):
    """numpy float64 evaluation against mpmath at 50 digits (same formulas, independent
    arithmetic): agreement to a few eps of each integral's scale."""
    from .conftest import demo_reduced_state

    s = demo_reduced_state()
    i64 = tb.integrals("reduced", fig5, s)
    scales = tb.integral_scales("reduced", fig5, s)
    imp = tb.integrals_mp("reduced", fig5, s, dps=50)
    for k in i64:
        # ~30 roundings in omega -> M -> E; 64 eps of the scale bounds their sum
        assert abs(i64[k] - float(imp[k])) <= 64 * 2.0**-52 * scales[k], k


def test_mparallel_energy_is_reduced_energy_minus_constant(fig5):
    """E~(K, gamma) = E_reduced - lambda^2 / (2 d) on M = lambda gamma (section 5)."""
    d = fig5.d
    g = np.array([0.36, 0.48, 0.8])
    lam = 1.7
    R = np.array([0.4, -0.3, 0.0])
    R[2] = -(R[0] * g[0] + R[1] * g[1]) / g[2]
    ma_om = fig5.mass * fig5.radius * fig5.plane_rate
    K = lam * g + ma_om * R
    # omega from K for the reduced public state
    c = get_system("reduced").constants(fig5.pars)
    omega = np.array(tb.model.omega_from_K(c.A, c.d, tuple(g), tuple(K)))
    red = tb.integrals("reduced", fig5, np.concatenate([omega, g, R]))
    mp = tb.integrals("mparallel", fig5, np.concatenate([K, g]))
    assert abs(red["M_gamma"] - lam) <= 8 * 2.0**-52 * abs(lam)
    scale = tb.integral_scales("reduced", fig5, np.concatenate([omega, g, R]))["E"]
    assert abs(mp["E"] - (red["E"] - lam**2 / (2 * d))) <= 64 * 2.0**-52 * scale


def test_reduced_energy_equals_paper_form(fig5):
    """Section 3 writes E = (M, omega)/2 + m a Omega (omega, R)/2 - m Omega^2 (R,R)/2."""
    from .conftest import demo_reduced_state

    s = demo_reduced_state()
    v = tb.integrals("reduced", fig5, s)
    omega, R = s[0:3], s[6:9]
    c = get_system("reduced").constants(fig5.pars)
    K = np.array(tb.model.K_from_omega(c.I, c.d, tuple(s[3:6]), tuple(omega)))
    M = K - fig5.mass * fig5.radius * fig5.plane_rate * R
    m, a, om = fig5.mass, fig5.radius, fig5.plane_rate
    paper = M @ omega / 2 + m * a * om * (omega @ R) / 2 - m * om**2 * (R @ R) / 2
    scale = tb.integral_scales("reduced", fig5, s)["E"]
    assert abs(v["E"] - paper) <= 32 * 2.0**-52 * scale
    assert abs(v["C2"] - M @ M) <= 32 * 2.0**-52 * (M @ M)


# --- densities ---------------------------------------------------------------------------
def _divergence_cfunc(kind, formulation):
    system = get_system(kind, formulation)
    xs = hy.make_vars(*system.internal_names)
    pars = [hy.par[i] for i in range(system.n_pars)]
    f = system.rhs(pars, xs)
    rho = integral_expressions(kind, formulation, which="density")["rho"]
    terms = [hy.diff(rho * fi, x) for x, fi in zip(xs, f)]
    return system, hy.cfunc(terms, xs, fp_type=hy.real128, compact_mode=True)


@pytest.mark.parametrize("kind, formulation", [("full", "momentum"), ("reduced", "momentum"),
                                               ("reduced", "omega"), ("mparallel", None)])
def test_density_is_invariant(kind, formulation):
    """div(rho f) = 0 at admissible states (Liouville), in quadruple precision."""
    system, cf = _divergence_cfunc(kind, formulation)
    from taylorball._propagate import working_state

    rng = np.random.default_rng(7)
    params = FIG5 if kind != "mparallel" else FIG5.to_mparallel()
    for _ in range(5):
        g = rng.normal(size=3)
        g /= np.linalg.norm(g)
        if kind == "full":
            from .conftest import orthonormal_frame

            al, be, g = orthonormal_frame(*rng.random(3))
            s = np.concatenate([rng.normal(size=3), al, be, g, rng.normal(size=2)])
        elif kind == "reduced":
            R = rng.normal(size=3)
            s = np.concatenate([rng.normal(size=3), g, R - (R @ g) * g])
        else:
            s = np.concatenate([rng.normal(size=3), g])
        _, pars, internal = working_state(kind, params, s, resolve_fp_type(hy.real128), formulation=system.formulation)
        t = cf(internal, pars=pars)
        rel = abs(float(sum(t))) / float(sum(abs(v) for v in t))
        assert rel <= K_LIE * EPS128, f"{kind}/{system.formulation}: div(rho f) relative {rel:.3g}"


def test_density_in_arbitrary_precision_uses_full_precision_parameters():
    """a_i = 1/(I_i + m a^2) must be formed in the state's precision: a 256-bit density agrees
    with mpmath at 256 bits to ~eps_256, not to float64's eps."""
    import heyoka as hy

    from taylorball.numbers import resolve_fp_type

    from .conftest import FIG5, demo_reduced_state

    spec = resolve_fp_type(hy.real, 256)
    s = tb.project("reduced", spec.array(demo_reduced_state()))
    r = tb.density("reduced", FIG5, s, coords="internal")
    with mpmath.workprec(300):
        g = [mpmath.mpf(str(v)) for v in s[3:6]]
        A = [1 / (mpmath.mpf(i) + FIG5.d) for i in FIG5.inertia]
        ref = 1 / mpmath.sqrt(abs(1 - FIG5.d * sum(a * x * x for a, x in zip(A, g))))
        err = abs(mpmath.mpf(str(r)) - ref) / ref
    assert err <= 64 * spec.eps, float(err)  # ~10 roundings at 256 bits
