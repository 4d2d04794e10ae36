"""The Lyapunov spectrum (Benettin / QR) pinned to the mechanics:

* its sum equals minus the change of the invariant density's logarithm over the run
  (Liouville: the flow preserves rho dx), to the precision of the run;
* it has as many (near-)zero exponents as the constraints, the first integrals, the flow
  direction and the reversibility of the reduced equations impose (see
  ``taylorball.chaos.lyapunov_spectrum``): 7 of 9 (reduced, Fig. 4a), 4 of 6 (M||gamma, Fig. 1);
* on Chaplygin's integrable ball (fixed plane, Omega = 0) the maximal exponent decays like
  ln(t)/t: lambda t = a + p ln t with p = 2 (nearby orbits shear apart quadratically);
* on the Fig. 4a level the maximal exponent is positive and agrees between float64 and long
  double and between re-orthonormalisation intervals 1 and 5 within its statistical error.

Measured numbers are in docs/chaos.md.
"""

import math
import warnings

import mpmath
import numpy as np
import pytest

import taylorball as tb
from taylorball.chaos import LyapunovSpectrum, lyapunov_spectrum
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS, demo_reduced_state, fig1_params
# the reference: the verify layer's own mpmath density at the exact (binary) end states
from taylorball.verify.chaos import _density_change
from taylorball.verify.invariant_measures import _mp

#: blocks of the running estimate used for the statistical error of lambda_max
BLOCK = 50.0
T_FIG4 = 1000.0
SAMPLE = np.arange(BLOCK, T_FIG4 + 1.0, BLOCK)


def fig4a_states(n, seed=0):
    lv = FIG4A_LEVELS
    smp = tb.section_admissible_sample(FIG4_BALL, C=lv.C, M_gamma=lv.M_gamma, h=lv.h, n=n, seed=seed)
    return [s[0] for s in smp["states"]]


def fig1():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", tb.UnphysicalParametersWarning)
        p = fig1_params()
    # the separatrix layer of Fig. 1 (chaotic by MEGNO, tests/test_paper.py)
    return p, tb.mparallel_states_on_section(p, lam=2.0, h=100.0, point=(0.0, 0.0))[0]


@pytest.fixture(scope="module")
def fig4a_float():
    return lyapunov_spectrum("reduced", FIG4_BALL, fig4a_states(1)[0], T_FIG4, sample=SAMPLE)


#: the long double run is 4x slower per time unit: shorter (12 blocks)
T_FIG4_LD = 600.0


@pytest.fixture(scope="module")
def fig4a_longdouble():
    return lyapunov_spectrum("reduced", FIG4_BALL, fig4a_states(1)[0], T_FIG4_LD, sample=SAMPLE[SAMPLE <= T_FIG4_LD],
                             fp_type=np.longdouble)


@pytest.fixture(scope="module")
def fig1_run():
    p, x = fig1()
    return lyapunov_spectrum("mparallel", p, x, 100.0)


def _log_density_error_bound(r: LyapunovSpectrum, x) -> float:
    r"""Bound on the rounding error of the package's ``ln rho`` at the public state ``x``
    (``chaos._log_density``), as it evaluates it, to first order in ``u = eps/2`` (the
    second-order terms are ~1e-16 of it). ``rho = 1 / sqrt|D|``, ``D = 1 - d S``,
    ``S = (p_1 + p_2) + p_3``, ``p_k = g_k (A_k g_k)`` (model._D, _internal_density), every
    operation rounded once (``|delta| <= u``):

    * constants (model.ball_constants): ``d = (m a) a`` (2 roundings: ``|dd| <= 2u d``),
      ``A_k = 1 / (I_k + d)`` (2 roundings and d's error: ``|dA_k| <= (2 + 2 d A_k) u A_k``);
      the M||gamma system takes ``a_k, d`` as given (exact);
    * ``p_k``: 2 roundings on top of ``A_k``'s: ``|dp_k| <= (alpha_k + 2) u p_k``;
    * ``S``: 2 additions of non-negative terms: ``|dS| <= sum |dp_k| + u (p_1 + p_2) + u S``;
    * ``P = d S``: ``|dP| <= d |dS| + (beta + 1) u d S`` (``beta`` = 2 or 0, d's roundings);
    * ``D = 1 - P``: ``|dD| <= |dP| + u |D|``. Here is the condition: ``d S / |D|`` is
      6 .. 12 at the Fig. 4a states (``D`` ~ 0.08 .. 0.14 is a difference of 1 and ~0.9), and
      it multiplies the relative errors of the terms;
    * ``rho = 1 / sqrt|D|``: ``|drho / rho| <= |dD| / (2 |D|) + 2u`` (sqrt, division);
    * ``ln``: ``+ 2u |ln rho|`` (glibc's ``log`` / ``logl``: at most 1 ulp <= ``2u |ln rho|``).

    Only the densities in the momentum variables (``|D|^{-1/2}``) are handled: the
    spectrum's problems integrate those (reduced and full ``momentum``, M||gamma native)."""
    prob = r.problem
    u = float(prob.spec.eps) / 2
    kind = prob.kind
    assert prob.formulation in ("momentum", "native"), prob.formulation
    p = np.asarray(prob.pars, dtype=float)
    g = np.abs(np.asarray(x[9:12] if kind == "full" else x[3:6], dtype=float))
    if kind == "mparallel":
        A, d, alpha, beta = p[0:3], p[3], np.zeros(3), 0.0
    else:
        d = p[3] * p[4] ** 2
        A = 1 / (p[0:3] + d)
        alpha, beta = 2 + 2 * d * A, 2.0
    pk = A * g * g
    S = pk.sum()
    dS = np.sum((alpha + 2) * u * pk) + u * (pk[0] + pk[1]) + u * S
    dP = d * dS + (beta + 1) * u * d * S
    D = abs(1 - d * S)
    dD = dP + u * D
    return dD / (2 * D) + 2 * u + 2 * u * abs(0.5 * math.log(D))


def _density_agrees(r: LyapunovSpectrum, liouville_residual: float, resid, change, show=True) -> bool:
    r"""The package's residual ``L = fl(sum + fl(fl(ln rho_1 - ln rho_0) / T))`` against the
    exact ``sum + Delta / T`` (``resid``; ``Delta`` from the independent mpmath density at
    the same states, ``change = Delta / T``, the package's own ``sum``): ``T |L - resid|`` is
    at most the errors of the two ``ln rho`` (:func:`_log_density_error_bound`, per state),
    the subtraction and the division (``u |Delta|`` each), the final addition (``u T |L|``,
    whose exact value is the tiny ``resid``) and the float64 roundings of ``L`` and ``resid``
    (``u64 T |resid|`` each). ``T = t - t0`` is formed in the working type (exact here)."""
    eps = float(r.problem.spec.eps)
    u, u64 = eps / 2, 2.0 ** -53
    T = r.t - r.t0
    delta = abs(float(change)) * T
    bound = (_log_density_error_bound(r, r.initial_state) + _log_density_error_bound(r, r.final_state)
             + 2 * u * delta + (u + 2 * u64) * T * abs(float(resid)))
    err = abs(liouville_residual - float(resid)) * T
    if show:
        print(f"  ln rho: |package - mpmath| over the run {err / eps:.2f} eps, derived bound {bound / eps:.1f} eps")
    return err <= bound


def _check_sum(r: LyapunovSpectrum):
    eps = r.problem.spec.eps
    with mpmath.workdps(40):
        change = _density_change(r)
        resid_mp = _mp(r.sum) + change
        resid = float(resid_mp)
    print(f"{r.kind} {r.problem.spec}: sum {float(r.sum):.3e}, residual {resid / eps:+.1f} eps "
          f"({resid * (r.t - r.t0) / eps:+.0f} eps in ln det over {r.n_steps} steps), bound {r.sum_error_bound / eps:.3g} eps")
    # the package's own residual (its density) agrees with the independent one to the
    # derived rounding error of its ln rho at the two end states (_density_agrees) ...
    assert _density_agrees(r, r.liouville_residual, resid, change)
    # ... and not if its ln rho at the end were off by 100 eps (the bound is below that)
    T = float(r.t - r.t0)
    for off in (-100.0, 100.0):
        assert not _density_agrees(r, r.liouville_residual + off * float(eps) / T, resid, change, show=False)
    # the bound: n eps sum_k c_k (1 + sqrt(steps_k)) / (t - t0), derived in lyapunov_spectrum
    assert abs(resid) <= r.sum_error_bound
    # the test can fail: the density term it corrects by is >= 100x the bound (with the
    # Lebesgue measure instead of rho dx, i.e. no correction, the check would fail)
    assert abs(float(change)) >= 100 * r.sum_error_bound


def test_sum_is_minus_the_density_change_reduced_float64(fig4a_float):
    _check_sum(fig4a_float)


def test_sum_is_minus_the_density_change_reduced_longdouble(fig4a_longdouble):
    _check_sum(fig4a_longdouble)


def test_sum_is_minus_the_density_change_mparallel(fig1_run):
    _check_sum(fig1_run)


def test_sum_is_minus_the_density_change_full():
    s = fig4a_states(1)[0]
    r = lyapunov_spectrum("full", FIG4_BALL, tb.reduced_to_full(FIG4_BALL, s), 100.0)
    assert r.exponents.shape == (14,)
    _check_sum(r)


def _count(r, frac_zero=0.2, frac_big=0.5):
    lam = np.asarray(r.exponents, dtype=float)
    lmax = abs(lam).max()
    return int(np.sum(abs(lam) < frac_zero * lmax)), int(np.sum(abs(lam) > frac_big * lmax))


def test_zero_exponents_reduced(fig4a_float):
    """6 zeros from the structure (gamma^2, (R, gamma), C2, M_gamma, E, the flow) and the
    middle exponent of the 3D map, zero by reversibility: 7 near zero, +-lambda outside.
    At t = 1000 the zeros are <= 0.016 (decaying like ln(t)/t), lambda_max ~ 0.11."""
    r = fig4a_float
    assert r.exponents.shape == (9,)
    assert np.all(np.diff(r.exponents.astype(float)) <= 0)  # sorted descending
    print("reduced Fig. 4a spectrum at t = 1000:", np.array2string(r.exponents.astype(float), precision=4))
    assert _count(r) == (7, 2)
    lam = r.exponents.astype(float)
    # the two non-zero ones are -+ each other (reversibility) to the spread of finite-time values
    assert abs(lam[0] + lam[-1]) <= 0.2 * lam[0]


def test_zero_exponents_mparallel(fig1_run):
    """gamma^2, lambda, E and the flow: 4 zeros; the area-preserving map: +-lambda."""
    r = fig1_run
    print("M||gamma Fig. 1 spectrum at t = 100:", np.array2string(r.exponents.astype(float), precision=4))
    assert r.exponents.shape == (6,)
    assert _count(r) == (4, 2)


@pytest.mark.slow
def test_zero_exponents_full():
    """11 zeros from the structure (6 frame constraints, F1, F2, F3, E, the flow) and the
    map's middle one: 12 of 14 near zero at t = 500."""
    s = fig4a_states(1)[0]
    r = lyapunov_spectrum("full", FIG4_BALL, tb.reduced_to_full(FIG4_BALL, s), 500.0)
    print("full spectrum at t = 500:", np.array2string(r.exponents.astype(float), precision=4))
    assert _count(r) == (12, 2)


def test_integrable_ball_max_exponent_decays_like_log_t_over_t():
    """Omega = 0 (Chaplygin's integrable ball): tangent vectors grow polynomially (|R|
    grows linearly, nearby orbits shear apart quadratically), so lambda(t) t = a + p ln t
    with p = 2; measured p = 1.94 over t = 30 .. 3000. A chaotic orbit's lambda(t) t grows
    linearly instead (checked on the Fig. 4a orbit below)."""
    ball0 = tb.BallParams(inertia=FIG4_BALL.inertia, mass=FIG4_BALL.mass, radius=FIG4_BALL.radius, plane_rate=0.0)
    ts = np.array([30.0, 100.0, 300.0, 1000.0, 3000.0])
    r = lyapunov_spectrum("reduced", ball0, demo_reduced_state(), 3000.0, sample=ts)
    lam = r.partial[:, 0].astype(float)
    y = lam * ts
    p, a = np.polyfit(np.log(ts), y, 1)
    fit = a + p * np.log(ts)
    print(f"Omega = 0: lambda_max(t) = {lam}, lambda t = {a:.3f} + {p:.3f} ln t, max misfit {abs(y - fit).max():.3f}")
    assert 1.7 <= p <= 2.3  # quadratic growth; measured 1.94
    assert abs(y - fit).max() <= 0.1 * p * math.log(10)  # a straight line in ln t to 10 % of a decade's rise
    assert lam[-1] < 0.005 and np.all(np.diff(lam) < 0)
    # every exponent decays: the whole spectrum tends to 0 (measured |lambda_i| <= 0.0041 at 3000)
    assert np.all(abs(r.exponents.astype(float)) < 0.005)


def _lmax_and_error(r):
    """lambda_max and its statistical error: the spread of its estimates over blocks of
    BLOCK time units (>> 1/lambda ~ 9), over sqrt(number of blocks)."""
    L = r.partial[:, 0].astype(float) * (r.times - r.t0)
    b = np.diff(np.concatenate([[0.0], L])) / BLOCK
    return r.maximal, b.std(ddof=1) / math.sqrt(len(b))


def _agree(a, b, label):
    (la, sa), (lb, sb) = _lmax_and_error(a), _lmax_and_error(b)
    print(f"{label}: {la:.4f} +- {sa:.4f} vs {lb:.4f} +- {sb:.4f}")
    assert la > 0.05 and lb > 0.05  # chaotic (measured 0.108 .. 0.113)
    assert abs(la - lb) <= 3 * math.hypot(sa, sb)  # 3 sigma


def test_fig4a_max_exponent_float64_vs_longdouble(fig4a_float, fig4a_longdouble):
    # measured: 0.1088 +- 0.0074 (float64, t = 1000), 0.1136 +- 0.0073 (long double, t = 600)
    _agree(fig4a_float, fig4a_longdouble, "Fig. 4a lambda_max float64 vs long double")


def test_fig4a_max_exponent_renorm_1_vs_5(fig4a_float):
    r5 = lyapunov_spectrum("reduced", FIG4_BALL, fig4a_states(1)[0], T_FIG4, sample=SAMPLE, renorm=5.0)
    # measured: 0.1088 +- 0.0074 (renorm 1), 0.1140 +- 0.0075 (renorm 5)
    _agree(fig4a_float, r5, "Fig. 4a lambda_max renorm 1 vs 5")
    # chaotic: lambda(t) t grows linearly, unlike the integrable ball's ln t
    lam = fig4a_float.partial[:, 0].astype(float)
    assert lam[-1] > 0.5 * lam[1]


@pytest.mark.slow
def test_fig4a_every_orbit_positive_and_agreeing():
    """Four orbits of the Fig. 4a level, t = 3000: lambda_max > 0 in each, float64 vs long
    double and renorm 1 vs 5 within 3 sigma."""
    sample = np.arange(BLOCK, 3000.0 + 1.0, BLOCK)
    for x in fig4a_states(4):
        a = lyapunov_spectrum("reduced", FIG4_BALL, x, 3000.0, sample=sample)
        b = lyapunov_spectrum("reduced", FIG4_BALL, x, 3000.0, sample=sample, fp_type=np.longdouble)
        c = lyapunov_spectrum("reduced", FIG4_BALL, x, 3000.0, sample=sample, renorm=5.0)
        _agree(a, b, "float64 vs long double")
        _agree(a, c, "renorm 1 vs 5")
        _check_sum(a)
        _check_sum(b)


def test_sampling_leaves_the_run_unchanged():
    """Running estimates at sample times come from heyoka's dense output; the run and its
    exponents are bit-identical with and without sampling."""
    x = fig4a_states(1)[0]
    a = lyapunov_spectrum("reduced", FIG4_BALL, x, 20.0, renorm=2.0)
    b = lyapunov_spectrum("reduced", FIG4_BALL, x, 20.0, renorm=2.0, sample=[0.5, 3.0, 7.25, 19.0, 20.0])
    assert np.array_equal(a.exponents, b.exponents) and np.array_equal(a.final_state, b.final_state)
    assert a.times.tolist() == [2.0 * k for k in range(1, 11)] and a.partial.shape == (10, 9)
    assert b.times.tolist() == [0.5, 3.0, 7.25, 19.0, 20.0]
    assert np.array_equal(b.partial[-1], a.partial[-1])  # at t, the sample is the result


def test_householder_qr_in_long_double_matches_lapack():
    from taylorball.chaos import _householder_qr

    rng = np.random.default_rng(1)
    A = rng.normal(size=(9, 9)) @ np.diag(np.logspace(0, 3, 9))
    Q, R = _householder_qr(A.astype(np.longdouble))
    eps = float(np.finfo(np.longdouble).eps)
    # backward error and orthogonality O(n eps) (factor 10 n: Householder's constant)
    assert np.max(np.abs(Q @ R - A)) <= 10 * 9 * eps * np.max(np.abs(A))
    assert np.max(np.abs(Q.T @ Q - np.eye(9))) <= 10 * 9 * eps
    assert np.all(np.tril(R, -1) == 0)
    R64 = np.linalg.qr(A)[1]
    # same |R_ii| as LAPACK up to float64 rounding (relative 100 n eps64 on this conditioning)
    assert np.allclose(np.abs(np.diagonal(R)).astype(float), np.abs(np.diagonal(R64)), rtol=100 * 9 * 2.2e-16)


def test_bad_arguments():
    x = demo_reduced_state()
    with pytest.raises(tb.UsageError, match="t_end must be finite and > t0"):
        lyapunov_spectrum("reduced", FIG4_BALL, x, 1.0, t0=1.0)
    with pytest.raises(tb.UsageError, match="t_end must be finite"):
        lyapunov_spectrum("reduced", FIG4_BALL, x, float("inf"))
    with pytest.raises(tb.UsageError, match="renorm"):
        lyapunov_spectrum("reduced", FIG4_BALL, x, 10.0, renorm=0.0)
    with pytest.raises(tb.UsageError, match="MAX_CHUNKS"):
        lyapunov_spectrum("reduced", FIG4_BALL, x, 1e9, renorm=1.0)
    with pytest.raises(tb.UsageError, match="fp_type"):
        import heyoka as hy

        lyapunov_spectrum("reduced", FIG4_BALL, x, 10.0, fp_type=hy.real128)
    with pytest.raises(tb.UsageError, match="sample"):
        lyapunov_spectrum("reduced", FIG4_BALL, x, 10.0, sample=[5.0, 11.0])
    with pytest.raises(tb.UsageError, match="sample"):
        lyapunov_spectrum("reduced", FIG4_BALL, x, 10.0, sample=[5.0, 4.0])
    with pytest.raises(tb.UsageError, match="kind"):
        lyapunov_spectrum("nope", FIG4_BALL, x, 10.0)
    off = x.copy()
    off[3] += 1e-3  # |gamma| != 1
    with pytest.raises((tb.ConstraintError, tb.StateError)):
        lyapunov_spectrum("reduced", FIG4_BALL, off, 10.0)


def test_reduced_equations_are_reversible():
    """The reason for the 7th zero exponent: (omega, gamma, R) -> (S omega, S gamma, S R),
    t -> -t maps orbits to orbits for S = -E and the reflections in principal planes. Run
    forward 5 time units, apply S, run forward again, apply S: back at the start to the
    integration error (measured 1.1e-14 on |x| ~ 1: ~50 eps64; bound 1000 eps64)."""
    x0 = demo_reduced_state()
    x1 = tb.propagate("reduced", FIG4_BALL, x0, 5.0)
    for s in ([-1.0, -1.0, -1.0], [-1.0, 1.0, 1.0], [1.0, 1.0, -1.0]):
        S = np.tile(s, 3)
        back = S * tb.propagate("reduced", FIG4_BALL, S * x1, 5.0)
        assert np.max(np.abs(back - x0)) <= 1000 * 2.2e-16
    # not a symmetry without the time reversal (the test can fail)
    S = np.tile([-1.0, -1.0, -1.0], 3)
    assert np.max(np.abs(S * tb.propagate("reduced", FIG4_BALL, S * x0, 5.0) - x1)) > 1e-3


def test_lanes_bit_identical_across_threads_and_companions_and_agree_with_scalar():
    from taylorball.chaos import lyapunov_spectra

    xs = fig4a_states(5)
    a = lyapunov_spectra("reduced", FIG4_BALL, xs, 20.0, renorm=2.0)
    b = lyapunov_spectra("reduced", FIG4_BALL, xs[::-1], 20.0, renorm=2.0, workers=1)[::-1]
    c = lyapunov_spectra("reduced", FIG4_BALL, xs[2:3], 20.0, renorm=2.0)
    for r, r2 in zip(a, b):
        assert np.array_equal(r.exponents, r2.exponents) and np.array_equal(r.partial, r2.partial)
    assert np.array_equal(a[2].exponents, c[0].exponents)
    s = lyapunov_spectrum("reduced", FIG4_BALL, xs[2], 20.0, renorm=2.0)
    assert a[2].times.tolist() == s.times.tolist() and a[2].n_chunks == s.n_chunks == 10
    # vectorised rounding differs: at t = 20 the orbits are still 1e-16 e^{0.1 t} ~ 1e-15
    # apart, the exponents ln(...)/20 agree to ~1e-14 (bound 1e4 eps64 / 20 on |lambda|, see above)
    assert np.max(np.abs(a[2].exponents - s.exponents)) <= 1e4 * 2.2e-16
    for r in a:
        _check_sum(r)


def test_lanes_bad_arguments():
    from taylorball.chaos import lyapunov_spectra

    with pytest.raises(tb.UsageError, match="at least one"):
        lyapunov_spectra("reduced", FIG4_BALL, [], 10.0)
    with pytest.raises(tb.UsageError, match="renorm"):
        lyapunov_spectra("reduced", FIG4_BALL, [demo_reduced_state()], 10.0, renorm=-1.0)


def test_longdouble_sum_over_a_span_inexact_in_float64():
    """The elapsed time ``t - t0`` is formed in the working type: with t0 = 0.1, t = 30 the
    float64 difference is rounded (the exact one needs 62 bits), and dividing the long double
    sum and density term by it put a relative error ~eps64 on them, i.e. ~|Delta ln rho| eps64
    ~ 1e3 eps_ld on T times the Liouville residual, far above the density's rounding bound."""
    t0, t = 0.1, 30.0
    with mpmath.workdps(40):
        assert mpmath.mpf(t - t0) != mpmath.mpf(t) - mpmath.mpf(t0)  # the float64 difference is rounded
    r = lyapunov_spectrum("reduced", FIG4_BALL, fig4a_states(1)[0], t, t0=t0, fp_type=np.longdouble)
    assert r.n_chunks == 30 and r.times[0] == 1.1
    _check_sum(r)


def test_lanes_sample_leaves_the_runs_bit_identical():
    """lyapunov_spectra(sample=): the running estimates at the sample times come from the lane
    engine's continuous output (LaneLoad.samples), so the exponents, sums and final states are
    bit-identical with and without sampling; a sample on a re-orthonormalisation time equals
    the estimate recorded there without sampling; an orbit's series does not depend on the
    threads or its companions; it agrees with lyapunov_spectrum(sample=) of the same state to
    rounding (vectorised code rounds differently; bound as in the test above)."""
    from taylorball.chaos import lyapunov_spectra

    xs = fig4a_states(5)
    smp = [0.5, 3.0, 7.25, 10.0, 19.0, 20.0]
    a = lyapunov_spectra("reduced", FIG4_BALL, xs, 20.0, renorm=2.0)
    b = lyapunov_spectra("reduced", FIG4_BALL, xs, 20.0, renorm=2.0, sample=smp)
    c = lyapunov_spectra("reduced", FIG4_BALL, xs[::-1][:3], 20.0, renorm=2.0, sample=smp, workers=1)[::-1]
    for r, s in zip(a, b):
        assert np.array_equal(r.exponents, s.exponents) and np.array_equal(r.final_state, s.final_state)
        assert r.sum == s.sum and r.liouville_residual == s.liouville_residual and r.n_steps == s.n_steps
        assert s.times.tolist() == smp and s.partial.shape == (6, 9)
        assert np.array_equal(s.partial[3], r.partial[4])  # t = 10: the 5th re-orthonormalisation
        assert np.array_equal(s.partial[-1], r.partial[-1])  # at t, the sample is the result
    for s, s2 in zip(b[2:], c):
        assert np.array_equal(s.partial, s2.partial)
    one = lyapunov_spectrum("reduced", FIG4_BALL, xs[1], 20.0, renorm=2.0, sample=smp)
    assert one.times.tolist() == smp
    assert np.max(np.abs(b[1].partial - one.partial)) <= 1e4 * 2.2e-16
    # the samples inside chunks are estimates of their own (not the chunk end's)
    assert not np.array_equal(b[1].partial[2], b[1].partial[3])
