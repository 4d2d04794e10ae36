"""The variational equations (taylorball.tangent.TangentSystem): the tangent vector field
against finite differences of the vector field in mpmath, the fundamental matrix of a
short run against finite differences of the flow in real128, the seed's tangency to the
constraints, and one compile per cache key."""

import copy
import logging
import threading

import heyoka as hy
import mpmath
import numpy as np
import pytest

from taylorball._cache import cached_keys
from taylorball.errors import UsageError
from taylorball.paper import demo_reduced_state
from taylorball.model import get_system
from taylorball.numbers import resolve_fp_type
from taylorball._problem import problem
from taylorball._propagate import integrator, working_state
from taylorball.tangent import TangentSystem

from .conftest import FIG5, nearby_reduced_states

EPS = float(np.finfo(float).eps)
EPS_LD = float(np.finfo(np.longdouble).eps)
MPAR_STATE = np.array([0.3, -1.2, 0.8, 0.6, 0.0, 0.8])
CASES = [("reduced", "momentum"), ("reduced", "omega"), ("mparallel", None)]


def _state(kind):
    return {"reduced": demo_reduced_state, "mparallel": MPAR_STATE.copy}[kind]()


def _mp(v):
    """A long double (or float) as an exact mpf: its float64 head plus the float64 tail."""
    hi = float(v)
    return mpmath.mpf(hi) + mpmath.mpf(float(np.longdouble(v) - np.longdouble(hi)))


def test_layout():
    red = get_system("reduced")
    one = TangentSystem(red, "one", indicators=True)
    assert (one.x, one.tangents, one.indicators_slice) == (slice(0, 9), slice(9, 18), slice(18, 21))
    assert (one.size, one.n_vectors, one.megno_y, one.megno_w, one.fli) == (21, 1, 18, 19, 20)
    assert [str(v) for v, _ in one.equations()][-3:] == ["megno_y", "megno_w", "fli"]
    full = TangentSystem(red, "all")
    assert (full.x, full.tangents, full.size, full.n_vectors) == (slice(0, 9), slice(9, 90), 90, 9)
    st = np.arange(90.0)
    Phi = full.tangent_matrix(st)
    assert Phi.shape == (9, 9) and Phi[2, 5] == 9 + 2 * 9 + 5  # row-major: entry (i, j) at n + i n + j
    assert full.tangent_matrix(np.tile(st[:, None], (1, 4))).shape == (9, 9, 4)
    assert TangentSystem(red, "one").tangent_matrix(np.arange(18.0)).shape == (9, 1)
    assert len(full.equations().sys) == 90  # a hy.var_ode_sys
    with pytest.raises(UsageError, match="vectors"):
        TangentSystem(red, "two")
    with pytest.raises(UsageError, match="indicators"):
        TangentSystem(red, "all", indicators=True)
    with pytest.raises(UsageError, match="MEGNO"):
        full.indicators_slice
    with pytest.raises(UsageError, match="identity"):
        one.identity(resolve_fp_type(float))


@pytest.mark.parametrize("kind,formulation", CASES)
def test_tangent_field_is_the_jacobian_vector_product(kind, formulation):
    """d' = J d (and the MEGNO/FLI integrands) evaluated in long double agree with a central
    difference of the vector field in mpmath (50 digits, step 1e-15: truncation ~1e-30,
    rounding ~1e-35), to a few long double eps of the largest term."""
    ts = TangentSystem(get_system(kind, formulation), "one", indicators=True)
    eqs = ts.equations()
    # a test-only cfunc of the augmented right-hand side (the package compiles only integrators of it)
    cf = hy.cfunc([r for _, r in eqs], [v for v, _ in eqs], fp_type=np.longdouble, compact_mode=True)
    spec = resolve_fp_type(np.longdouble)
    system, pars, x = working_state(kind, FIG5, _state(kind), spec, formulation=formulation)
    d = spec.array(ts.seed(x, np.random.default_rng(7)))
    y, w, t = np.longdouble(0.3), np.longdouble(0.7), np.longdouble(2.5)
    out = cf(np.concatenate([x, d, np.array([y, w, 0.0], dtype=np.longdouble)]), pars=pars, time=t)
    n = ts.n
    with mpmath.workdps(50):
        pm, xm, dm = [_mp(v) for v in pars], [_mp(v) for v in x], [_mp(v) for v in d]
        h = mpmath.mpf("1e-15")
        fp = system.rhs(pm, [a + h * b for a, b in zip(xm, dm)])
        fm = system.rhs(pm, [a - h * b for a, b in zip(xm, dm)])
        Jd = [(a - b) / (2 * h) for a, b in zip(fp, fm)]
        f = system.rhs(pm, xm)
        lam = mpmath.fsum(a * b for a, b in zip(dm, Jd)) / mpmath.fsum(a * a for a in dm)
        ref = list(f) + Jd + [_mp(t) * lam, 2 * _mp(y) / _mp(t), lam]
        err = [abs(_mp(o) - r) for o, r in zip(out, ref)]
    scale_f = max(abs(float(v)) for v in f)
    scale_jd = max(abs(float(v)) for v in Jd)
    # 16 eps: sums of ~10-30 rounded products per component (measured <= 6 eps of the scale)
    assert max(err[:n]) <= 16 * EPS_LD * scale_f, (kind, formulation, [float(e) for e in err[:n]])
    assert max(err[n : 2 * n]) <= 16 * EPS_LD * scale_jd, (kind, formulation, [float(e) for e in err[n : 2 * n]])
    # lambda = (d, J d)/(d, d) may cancel: its rounding scale is sum |d_i (J d)_i| / (d, d)
    scale_lam = float(mpmath.fsum(abs(a * b) for a, b in zip(dm, Jd)) / mpmath.fsum(a * a for a in dm))
    assert float(err[ts.megno_y]) <= 16 * EPS_LD * float(_mp(t)) * scale_lam, float(err[ts.megno_y])
    assert float(err[ts.megno_w]) <= 4 * EPS_LD * abs(float(ref[ts.megno_w])), float(err[ts.megno_w])
    assert float(err[ts.fli]) <= 16 * EPS_LD * scale_lam, float(err[ts.fli])


def test_fundamental_matrix_agrees_with_finite_differences_of_the_flow():
    """Phi(t) of vectors="all" (long double, t = 2) against fourth-order central differences
    of propagate's real128 integrator over x(0) + s e_j (s = 1e-6: truncation ~1e-24,
    rounding ~1e-28, both far below long double)."""
    T = 2.0
    prob = problem("reduced", FIG5, fp_type=np.longdouble)
    spec = prob.spec
    ts = TangentSystem.of(prob, "all")
    ta = copy.copy(ts.template(prob, compact_mode=True))
    system, pars, x0 = working_state("reduced", FIG5, demo_reduced_state(), spec)
    ta.state[ts.x] = x0
    ta.state[ts.tangents] = ts.identity(spec)
    ta.pars[:] = pars
    ta.time = spec.scalar(0.0)
    res = ta.propagate_until(spec.scalar(T))
    assert res[0] == hy.taylor_outcome.time_limit
    n_steps = res[3]
    Phi = ts.tangent_matrix(ta.state)

    q = resolve_fp_type(hy.real128)
    tmpl = integrator(problem("reduced", FIG5, fp_type=hy.real128))
    x0q, parsq = q.array(x0), q.array(pars)
    s = q.scalar(1e-6)

    def flow(j, k):
        tq = copy.copy(tmpl)
        st = x0q.copy()
        st[j] = st[j] + k * s
        tq.state[:] = st
        tq.pars[:] = parsq
        tq.time = q.scalar(0.0)
        tq.propagate_until(q.scalar(T))
        return np.array(tq.state)

    fd = np.empty((9, 9), dtype=np.longdouble)
    for j in range(9):
        col = (-flow(j, 2) + 8 * flow(j, 1) - 8 * flow(j, -1) + flow(j, -2)) / (12 * s)
        fd[:, j] = [np.longdouble(str(v)) for v in col]
    err = float(np.max(np.abs(Phi - fd)))
    scale = float(np.max(np.abs(fd)))
    # 32 eps: 12 Taylor steps of rounding in each entry, relative to max |Phi| (measured 5.8 eps)
    assert err <= 32 * EPS_LD * scale, (err / (EPS_LD * scale), n_steps)


def test_batch_lanes_agree_with_the_scalar_fundamental_matrix():
    """The float64 batch template of vectors="all" (what a Lyapunov spectrum on the lane
    pool runs): each lane's Phi(t) equals the scalar integrator's to rounding."""
    T = 2.0
    prob = problem("reduced", FIG5)
    ts = TangentSystem.of(prob, "all")
    bt = copy.copy(ts.batch_template(compact_mode=True))
    lanes = bt.state.shape[1]
    states = nearby_reduced_states(lanes, seed=5)
    work = [working_state("reduced", FIG5, s, prob.spec) for s in states]
    for k, (_, pars, x) in enumerate(work):
        bt.state[ts.x, k] = x
        bt.state[ts.tangents, k] = ts.identity(prob.spec)
        bt.pars[:, k] = pars
    bt.set_time(0.0)
    bt.propagate_until(T)
    Phis = ts.tangent_matrix(bt.state)
    for k, (_, pars, x) in enumerate(work):
        ta = copy.copy(ts.template(prob, compact_mode=True))
        ta.state[:] = np.concatenate([x, ts.identity(prob.spec)])
        ta.pars[:] = pars
        ta.propagate_until(T)
        Phi = ts.tangent_matrix(ta.state)
        # 16 eps: the same equations; vectorised code may round differently (measured: identical here)
        assert np.max(np.abs(Phis[:, :, k] - Phi)) <= 16 * EPS * np.max(np.abs(Phi))


@pytest.mark.parametrize("kind,formulation", CASES)
def test_seed_is_a_unit_vector_tangent_to_the_constraints(kind, formulation):
    """|gamma| = 1 and (reduced) (R, gamma) = 0 to first order along the seed, to a few
    float64 eps (one projection each: the residual is the rounding of a 3-term dot
    product and an axpy)."""
    ts = TangentSystem(get_system(kind, formulation), "one")
    _, _, x = working_state(kind, FIG5, _state(kind), resolve_fp_type(float), formulation=formulation)
    for seed in range(20):
        d = ts.seed(x, np.random.default_rng(seed))
        g, dg = x[3:6], d[3:6]
        assert abs(np.linalg.norm(d) - 1) <= 4 * EPS
        assert abs(g @ dg) <= 8 * EPS, (seed, g @ dg)  # d|gamma|^2/2 = (gamma, dgamma)
        if kind == "reduced":
            R, dR = x[6:9], d[6:9]
            assert abs(dR @ g + R @ dg) <= 8 * EPS * (1 + np.linalg.norm(R)), seed  # d(R, gamma)


@pytest.mark.parametrize("formulation", ["momentum", "omega"])
def test_full_seed_is_the_orthogonal_projection_on_the_tangent_space_of_so3(formulation):
    """Full system: the frame (alpha, beta, gamma) stays orthonormal to first order along the
    seed, i.e. each Gram entry (v_i, v_j) has derivative (dv_i, v_j) + (v_i, dv_j) = 0, to
    8 float64 eps (each term a 3-term dot product of unit-size vectors: a few eps of rounding);
    the projection is orthogonal (the removed part is orthogonal to every tangent direction
    eta x v, eta = e1, e2, e3, to 8 eps of its size) and leaves M (or omega) and (x, y) alone."""
    from taylorball.model import FULL
    from taylorball.manifold import reduced_to_full

    ts = TangentSystem(get_system("full", formulation), "one")
    _, _, x = working_state("full", FIG5, reduced_to_full(FIG5, demo_reduced_state()), resolve_fp_type(float),
                            formulation=formulation)
    vs = [x[k : k + 3] for k in (3, 6, 9)]
    for seed in range(20):
        d = ts.seed(x, np.random.default_rng(seed))
        assert abs(np.linalg.norm(d) - 1) <= 4 * EPS
        dvs = [d[k : k + 3] for k in (3, 6, 9)]
        for i in range(3):
            for j in range(i, 3):
                assert abs(dvs[i] @ vs[j] + vs[i] @ dvs[j]) <= 8 * EPS, (seed, i, j)
        raw = np.random.default_rng(seed).normal(size=14)
        proj = raw.copy()
        FULL.tangent_constraints[0](x, proj)
        assert np.array_equal(proj[:3], raw[:3]) and np.array_equal(proj[12:], raw[12:])
        removed = [raw[k : k + 3] - proj[k : k + 3] for k in (3, 6, 9)]
        for eta in np.eye(3):
            dot = sum(r @ np.cross(eta, v) for r, v in zip(removed, vs))
            assert abs(dot) <= 8 * EPS * np.linalg.norm(np.concatenate(removed)), (seed, eta, dot)


def test_one_compile_per_key(caplog):
    """Concurrent and repeated requests (and the Liouville check, a client) build a key
    once; a different tolerance is a different key. tol=1e-13 is used by no other test."""
    from taylorball.verify import liouville

    caplog.set_level(logging.DEBUG, logger="taylorball.compile")
    prob = problem("reduced", FIG5, tol=1e-13)
    ts = TangentSystem.of(prob, "all")
    got = []

    def ask():
        got.append(TangentSystem.of(prob, "all").template(prob, compact_mode=True))

    threads = [threading.Thread(target=ask) for _ in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    liouville("reduced", FIG5, demo_reduced_state(), 0.5, formulation="momentum", tol=1e-13)
    got.append(ts.template(prob, compact_mode=True))
    assert all(g is got[0] for g in got)
    key = ("tangent", "all", False, "reduced", "momentum", "float", 1e-13, True)
    assert cached_keys().count(key) == 1
    built = [r.getMessage() for r in caplog.records if r.getMessage().startswith("built tangent all False reduced "
                                                                                "momentum float 1e-13 True")]
    assert len(built) == 1, built
    other = ts.template(problem("reduced", FIG5, tol=2e-13), compact_mode=True)
    assert other is not got[0]
    assert ("tangent", "all", False, "reduced", "momentum", "float", 2e-13, True) in cached_keys()
    with pytest.raises(UsageError, match="not this tangent system"):
        ts.template(problem("mparallel", FIG5), compact_mode=True)
