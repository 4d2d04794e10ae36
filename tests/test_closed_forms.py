"""F3 / Psi(gamma3) of the symmetric M||gamma case (paper sec. 5 item 3; taylorball.closed_forms).

References are independent of the code under test: the required Psi' comes from a sympy
derivation along paper eq. (22) [Mpn2] (taylorball.verify.closed_forms.derive_required_psi_prime),
evaluated in mpmath at 50 digits; numpy values are compared with mpmath values of the same
formula at 60 digits; conservation is checked by the Lie derivative in mpmath and along heyoka
solutions in float64 and real128.

Tolerances
----------
* TOL_MP = 1e-40 (relative) for 50-digit identities: mpmath.diff of a 120-digit function is
  good to ~1e-50; an erroneous formula gives O(1).
* numpy vs mpmath: K_PSI = 32 eps relative for Psi, K_EVAL = 32 eps * scale for F3. Psi is
  ~10 rounded operations with relative condition <= 1 (atan, asinh, sqrt), except the
  cancellation in 1 - a1 d, which amplifies the rounding of a1 d by a1 d/|1 - a1 d| <= 12.5
  for the sets here; measured worst cases at 1200 random points: 7 eps (Psi), 9 eps * scale (F3).
* drift: |F3(t) - F3(0)| <= eps * scale * (K_EVAL + K_DRIFT sqrt(steps)), K_DRIFT = 8: two
  evaluation errors plus a random walk of per-step rounding (see tests/test_propagate.py);
  a formula error gives O(1) * Omega instead.
"""

import math
import warnings

import heyoka as hy
import mpmath
import numpy as np
import pytest

import taylorball as tb
from taylorball import closed_forms as cf
from taylorball.errors import ConstraintError, ParameterError, StateError
from taylorball.verify import closed_forms as V

TOL_MP = V.TOL_MP
K_PSI = 32.0
K_EVAL = V.K_EVAL
K_DRIFT = V.K_DRIFT
EPS = {
    np.dtype(np.float64): 2.0**-52,
    np.dtype(np.longdouble): float(np.finfo(np.longdouble).eps),
    np.dtype(hy.real128): 2.0**-112,
}

SETS = V.PARAM_SETS
PHYS_A3_GT = SETS["ball I=(3,3,2)"]
PHYS_A3_LT = SETS["ball I=(2,2,3)"]
PAPER_A3_GT = SETS["a=(1,1,3),d=4"]
PAPER_A3_LT = SETS["a=(3,3,1.5),d=4"]
NONZERO = [x for x in V.GAMMA3_POINTS if float(x) != 0.0]


def _mp(x):
    return cf._to_mpf(x, mpmath)


def _required(p, x, absolute=True):
    return V.required_psi_prime_mp(p, x, absolute=absolute)


def _deriv_residual(fn, p, pts, absolute=True):
    worst = 0.0
    with mpmath.workdps(50):
        for x in pts:
            x = mpmath.mpf(x)
            num, req = mpmath.diff(fn, x), _required(p, x, absolute)
            worst = max(worst, float(abs(num - req) / abs(req)))
    return worst


# --- derivation ------------------------------------------------------------------------------
def test_derivation_symbolic():
    """The printed K-linear part is an integral at Omega = 0; F3 needs Psi' = p D^(-1/2) with
    p = -(1 - a1 d)^2/(a1^2 d) = -d (1 - 1/(a1 d))^2, and then dF3/dt = 0 identically."""
    import sympy as sp

    der = V.derive_required_psi_prime()
    a1, a3, d = der["symbols"]
    assert der["remainder_omega0"] == 0
    assert der["remainder"] == 0
    assert sp.simplify(der["p"] + d * (1 - 1 / (a1 * d)) ** 2) == 0
    assert a3 not in der["p"].free_symbols


@pytest.mark.parametrize("name", list(SETS))
def test_psi_prime_is_the_derived_one(name):
    p = SETS[name]
    with mpmath.workdps(50):
        for x in list(V.GAMMA3_POINTS) + ["0", "1", "-1"]:
            req = _required(p, x)
            assert abs(cf.psi_prime_mp(p, x) - req) <= TOL_MP * abs(req)


# --- the corrected closed form ------------------------------------------------------------
@pytest.mark.parametrize("name", list(SETS))
def test_psi_derivative_mpmath(name):
    p = SETS[name]
    res = _deriv_residual(lambda t: cf.psi_mp(p, t, 120), p, list(V.GAMMA3_POINTS) + ["0"])
    assert res <= TOL_MP, res


@pytest.mark.parametrize("name", list(SETS))
def test_psi_difference_vs_quad(name):
    p = SETS[name]
    with mpmath.workdps(50):
        for a, b in [(-1, 1), ("0.1", "0.2"), ("-0.999", "-0.5"), ("-0.3", "0")]:
            a, b = mpmath.mpf(a), mpmath.mpf(b)
            lhs = cf.psi_mp(p, b, 60) - cf.psi_mp(p, a, 60)
            rhs = mpmath.quad(lambda t: _required(p, t), [a, b])
            assert abs(lhs - rhs) <= TOL_MP * abs(rhs)


@pytest.mark.parametrize("name", list(SETS))
def test_psi_odd_and_continuous_at_zero(name):
    p = SETS[name]
    with mpmath.workdps(50):
        assert cf.psi_mp(p, 0) == 0
        for x in ("1e-45", "0.3", "0.999"):
            assert cf.psi_mp(p, x) == -cf.psi_mp(p, "-" + x)
        assert abs(cf.psi_mp(p, "1e-45")) < 1e-43


def test_branches():
    assert cf.psi_branch(PHYS_A3_GT) == cf.PsiBranch(1, "arctan")
    assert cf.psi_branch(PHYS_A3_LT) == cf.PsiBranch(1, "arsinh")
    assert cf.psi_branch(PAPER_A3_GT) == cf.PsiBranch(-1, "arsinh")  # swapped for D < 0 (E-Psi3)
    assert cf.psi_branch(PAPER_A3_LT) == cf.PsiBranch(-1, "arctan")
    assert cf.psi_branch(SETS["ball I=(3,3,3)"]).form == "linear"


@pytest.mark.parametrize("s", [1, -1])
def test_linear_branch_is_the_limit(s):
    """a3 -> a1: both closed forms tend to the linear one (no jump in the package's Psi)."""
    a1, d = (0.04, 20.0) if s > 0 else (1.0, 4.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lin = tb.MParallelParams(a=(a1, a1, a1), d=d)
        near = [tb.MParallelParams(a=(a1, a1, a1 * (1 + e)), d=d) for e in (1e-9, -1e-9)]
    assert {cf.psi_branch(q).form for q in near} == {"arctan", "arsinh"}
    with mpmath.workdps(50):
        for q in near:
            for x in ("0.5", "-0.9"):
                assert abs(cf.psi_mp(q, x) - cf.psi_mp(lin, x)) < 1e-7 * abs(cf.psi_mp(lin, x))


# --- the printed forms ---------------------------------------------------------------------
def test_printed_arctan_form_has_right_derivative_but_jumps_at_zero():
    p = PHYS_A3_GT
    assert _deriv_residual(lambda t: cf.psi_printed(p, t, 120), p, NONZERO) <= TOL_MP
    with mpmath.workdps(50):
        a1, a3, d = _mp(p.a[0]), _mp(p.a[2]), _mp(p.d)
        jump = mpmath.pi / 2 * mpmath.sqrt(d) * (1 - 1 / (a1 * d)) ** 2 / mpmath.sqrt(a3 - a1)
        assert abs(V.printed_jump_at_zero(p) - jump) <= TOL_MP * jump
        # printed = corrected + sign(gamma3) jump/2 (E-Psi1)
        for x in NONZERO:
            sgn = 1 if float(x) > 0 else -1
            assert abs(cf.psi_printed(p, x) - cf.psi_mp(p, x) - sgn * jump / 2) <= TOL_MP * jump


def test_printed_F3_jumps_along_an_orbit_crossing_the_equator():
    p = PHYS_A3_GT
    x = tb.propagate("mparallel", p, V.orbit_state(p, V.ORBIT_STATES[1]), np.linspace(0.0, 20.0, 201))
    assert np.sum(np.diff(np.sign(x[:, 5])) != 0) >= 2
    F = cf.symmetric_integral(p, x)
    sc = float(np.max(cf.symmetric_integral_scale(p, x)))
    assert np.ptp(F) <= 1e-12 * sc  # conserved (the drift bound is tested in test_drift_*)
    a1, a3, d = p.a[0], p.a[2], p.d
    rows = x[x[:, 5] != 0]
    D = 1 - d * (a1 * (rows[:, 3] ** 2 + rows[:, 4] ** 2) + a3 * rows[:, 5] ** 2)
    L = (
        rows[:, 5] * (rows[:, 0] * rows[:, 3] + rows[:, 1] * rows[:, 4])
        - (1 - rows[:, 5] ** 2 - 1 / (a1 * d)) * rows[:, 2]
    )
    Fp = L / np.sqrt(D) + p.plane_rate * np.array(
        [float(cf.psi_printed(p, float(g), 30)) for g in rows[:, 5]]
    )
    jump = p.plane_rate * math.pi / 2 * math.sqrt(d) * (1 - 1 / (a1 * d)) ** 2 / math.sqrt(a3 - a1)
    assert np.ptp(Fp) == pytest.approx(jump, rel=1e-9)  # two levels, F3 +- jump/2


def test_printed_log_form_fails_and_corrected_holds():
    p = PHYS_A3_LT
    assert _deriv_residual(lambda t: cf.psi_printed(p, t, 120), p, NONZERO) > 0.1  # E-Psi2
    assert _deriv_residual(lambda t: cf.psi_printed(p, t, 120, corrected=True), p, NONZERO) <= TOL_MP
    with mpmath.workdps(50):
        for x in NONZERO:  # the corrected printed-style form is the package's Psi itself
            assert abs(cf.psi_printed(p, x, corrected=True) - cf.psi_mp(p, x)) <= TOL_MP


@pytest.mark.parametrize("p", [PAPER_A3_GT, PAPER_A3_LT], ids=["a3>a1", "a3<a1"])
def test_negative_D_printed_forms_are_imaginary_but_complex_consistent(p):
    """d a_i > 1: the printed rho is imaginary; as complex functions (log form with E-Psi2)
    the printed Psi has Psi' = p D^(-1/2), i.e. i*F3_printed = F3 + piecewise const (E-Psi3)."""
    with mpmath.workdps(50):
        assert abs(mpmath.im(cf.psi_printed(p, "0.3", corrected=True))) > 0.1
    res = _deriv_residual(lambda t: cf.psi_printed(p, t, 120, corrected=True), p, NONZERO, absolute=False)
    assert res <= TOL_MP
    with mpmath.workdps(50):
        # i*Psi_printed - Psi is piecewise constant: the principal branches jump at gamma3 = 0
        # and (log form) where xi - 1 crosses the cut of ln, gamma3^2 = (a1 d - 1)/(2 d (a1 - a3))
        cut = (p.a[0] * p.d - 1) / (2 * p.d * (p.a[0] - p.a[2])) if p.a[2] < p.a[0] else 2.0
        pieces = {}
        for x in NONZERO:
            key = (float(x) > 0, float(x) ** 2 > cut)
            pieces.setdefault(key, []).append(1j * cf.psi_printed(p, x, corrected=True) - cf.psi_mp(p, x))
        for vals in pieces.values():
            assert all(abs(v - vals[0]) <= TOL_MP for v in vals)
        assert any(abs(v[0]) > 0.1 for v in pieces.values())  # the constants are not all 0


# --- numpy, heyoka -------------------------------------------------------------------------
def _states(n, seed, dtype):
    out = []
    for s in V._random_states(n, seed):
        x = (
            np.array([hy.real128(repr(float(v))) for v in s], dtype=hy.real128)
            if dtype == hy.real128
            else np.array(s, dtype=dtype)
        )
        x[3:] = x[3:] / np.sqrt(np.sum(x[3:] ** 2))
        out.append(x)
    return np.stack(out)


@pytest.mark.parametrize(
    "dtype", [np.float64, np.longdouble, hy.real128], ids=["float64", "longdouble", "real128"]
)
def test_numpy_psi_and_F3_match_mpmath(dtype):
    eps = EPS[np.dtype(dtype)]
    X = _states(40, 7, dtype)
    for name, p in SETS.items():
        ps = cf.psi(p, X[:, 5])
        F = cf.symmetric_integral(p, X)
        sc = cf.symmetric_integral_scale(p, X)
        assert ps.dtype == np.dtype(dtype) and F.dtype == np.dtype(dtype)
        with mpmath.workdps(60):
            for i in range(len(X)):
                ref = cf.psi_mp(p, X[i, 5], 60)
                assert abs(_mp(ps[i]) - ref) <= K_PSI * eps * abs(ref), (name, i)
                refF = cf.symmetric_integral_mp(p, X[i], 60)
                assert abs(_mp(F[i]) - refF) <= K_EVAL * eps * _mp(sc[i]), (name, i)


def test_heyoka_expression_matches_numpy():
    names = tb.model.PUBLIC_NAMES["mparallel"]
    X = _states(16, 11, np.float64).T.copy()
    for name, p in SETS.items():
        fn = hy.cfunc([cf.symmetric_integral_expression(p), cf.psi_expression(p)], vars=hy.make_vars(*names))
        out = fn(X, pars=np.repeat(np.array(p.pars)[:, None], X.shape[1], axis=1))
        sc = cf.symmetric_integral_scale(p, X.T)
        with mpmath.workdps(60):
            for i in range(X.shape[1]):
                refF = cf.symmetric_integral_mp(p, X[:, i], 60)
                assert abs(out[0, i] - refF) <= K_EVAL * 2.0**-52 * float(sc[i]), name
                refP = cf.psi_mp(p, X[5, i], 60)
                assert abs(out[1, i] - refP) <= K_PSI * 2.0**-52 * abs(float(refP)), name


def test_ballparams_accepted_when_exactly_symmetric():
    b = tb.BallParams(inertia=(2.0, 2.0, 3.0), mass=1.0, radius=5.0, plane_rate=2.0)
    assert cf.psi(b, 0.3) == cf.psi(b.to_mparallel(), 0.3)
    s = np.array([1.0, 2.0, 3.0, 0.6, 0.0, 0.8])
    assert cf.symmetric_integral(b, s) == cf.symmetric_integral(b.to_mparallel(), s)


# --- conservation --------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(SETS))
def test_lie_derivative_vanishes_mpmath(name):
    p = SETS[name]
    for s in V._random_states(2, seed=5):
        with mpmath.workdps(50):
            g = [mpmath.mpf(v) for v in s[3:]]
            n = mpmath.sqrt(mpmath.fsum(v * v for v in g))
            lie, mag = V.lie_derivative_mp(p, [mpmath.mpf(v) for v in s[:3]] + [v / n for v in g])
        assert abs(lie) <= TOL_MP * mag


def _printed_F3(corrected):
    def F(p, x, dps):
        with mpmath.workdps(dps):
            a1, a3, d = _mp(p.a[0]), _mp(p.a[2]), _mp(p.d)
            D = 1 - d * (a1 * (x[3] ** 2 + x[4] ** 2) + a3 * x[5] ** 2)
            L = x[5] * (x[0] * x[3] + x[1] * x[4]) - (1 - x[5] ** 2 - 1 / (a1 * d)) * x[2]
            return L / mpmath.sqrt(D) + _mp(p.plane_rate) * cf.psi_printed(p, x[5], dps, corrected=corrected)

    return F


@pytest.mark.parametrize("corrected", [False, True], ids=["printed", "corrected"])
def test_lie_derivative_of_printed_log_form_F3(corrected):
    """The same Lie-derivative test detects E-Psi2: the printed F3 (log form) is not
    conserved, the corrected printed-style one is."""
    p = PHYS_A3_LT
    with mpmath.workdps(50):
        x = [mpmath.mpf(v) for v in (20, -10, 5)] + [
            mpmath.mpf(3) / 5,
            mpmath.mpf(0),
            mpmath.mpf(4) / 5,
        ]  # |gamma| = 1
        lie, mag = V.lie_derivative_mp(p, x, F=_printed_F3(corrected))
    if corrected:
        assert abs(lie) <= TOL_MP * mag
    else:
        assert abs(lie) > 1e-6 * mag  # measured 2.8e-4: 1e36 times the corrected residual bound


@pytest.mark.parametrize("name", list(SETS))
def test_drift_float64(name):
    p = SETS[name]
    crossings = 0
    for s in V.ORBIT_STATES:
        steps, drift, c = V.drift_ratios(p, V.orbit_state(p, s), 200.0)
        crossings += c
        bound = K_EVAL + K_DRIFT * math.sqrt(steps)
        print(
            f"{name}: {steps} steps, {c} crossings, drift/eps: F3 {drift['F3']:.1f} E {drift['E']:.1f}, bound {bound:.0f}"
        )
        assert drift["F3"] <= bound
    assert crossings > 0  # orbits that cross gamma3 = 0 are included


@pytest.mark.parametrize("name", ["ball I=(3,3,2)", "a=(1,1,3),d=4"])
def test_drift_real128(name):
    p = SETS[name]
    steps, drift, c = V.drift_ratios(p, V.orbit_state(p, V.ORBIT_STATES[1]), 3.0, fp_type=hy.real128, n=11)
    print(f"{name} real128: {steps} steps, {c} crossings, drift/eps: {drift}")
    assert c >= 1
    assert drift["F3"] <= K_EVAL + K_DRIFT * math.sqrt(steps)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SETS))
def test_drift_long(name):
    p = SETS[name]
    steps, drift, _ = V.drift_ratios(p, V.orbit_state(p, V.ORBIT_STATES[0]), 2e4, n=401)
    assert drift["F3"] <= K_EVAL + K_DRIFT * math.sqrt(steps)
    steps, drift, _ = V.drift_ratios(p, V.orbit_state(p, V.ORBIT_STATES[1]), 30.0, fp_type=hy.real128, n=31)
    assert drift["F3"] <= K_EVAL + K_DRIFT * math.sqrt(steps)


# --- errors --------------------------------------------------------------------------------
def test_errors():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(ParameterError, match="I1 == I2"):
            cf.psi(tb.BallParams(inertia=(2.0, 3.0, 3.0), mass=1.0, radius=5.0), 0.1)
        with pytest.raises(ParameterError, match="a1 != a2"):
            cf.psi(tb.MParallelParams(a=(1.0, 2.0, 3.0), d=4.0), 0.1)
        with pytest.raises(ParameterError, match="vanishes on the sphere"):
            cf.psi(tb.MParallelParams(a=(0.1, 0.1, 0.5), d=4.0), 0.1)
        with pytest.raises(ParameterError, match="vanishes on the sphere"):
            cf.psi(tb.MParallelParams(a=(0.25, 0.25, 0.5), d=4.0), 0.1)  # a1 d = 1
        with pytest.raises(ParameterError, match="MParallelParams"):
            cf.symmetric_integral("ball", np.zeros(6))
        with pytest.raises(ParameterError, match="a3 == a1"):
            cf.psi_printed(tb.MParallelParams(a=(1.0, 1.0, 1.0), d=4.0), 0.3)
    p = PHYS_A3_GT
    with pytest.raises(StateError, match=r"gamma3 must lie in \[-1, 1\]"):
        cf.psi(p, 1.5)
    with pytest.raises(StateError, match="finite"):
        cf.psi(p, np.array([0.1, np.nan]))
    with pytest.raises(StateError, match="gamma3 = 0"):
        cf.psi_printed(p, 0.0)
    with pytest.raises(StateError, match="6 entries"):
        cf.symmetric_integral(p, np.zeros(5))
    with pytest.raises(ConstraintError):
        cf.symmetric_integral(p, np.array([1.0, 2.0, 3.0, 0.6, 0.0, 0.9]))
    assert cf.psi(p, 1.0 + 1e-12) == pytest.approx(cf.psi(p, 1.0), rel=1e-10)  # rounding excess accepted


def test_verify_checks_quick_pass():
    from taylorball.verify import run_checks

    results = run_checks(False, modules=("closed_forms",))
    assert results and all(r.ok for r in results), [
        (r.claim, r.verdict, r.detail) for r in results if not r.ok
    ]
    verdicts = {r.claim: r.verdict for r in results}
    assert verdicts["Psi log form (a3 < a1): dPsi/dgamma3"] == "erratum corrected"
    assert verdicts["Psi arctan form (a3 > a1): dPsi/dgamma3"] == "verified"
