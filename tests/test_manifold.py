"""State validation, projection and the full <-> reduced maps (section 3)."""

import math

import heyoka as hy
import numpy as np
import pytest
from hypothesis import assume, given

import taylorball as tb
from taylorball.manifold import as_state, constraint_residuals

from .conftest import FIG5, STATES, demo_reduced_state

EPS = 2.0**-52


@pytest.mark.parametrize("kind, n", [("full", 14), ("reduced", 9), ("mparallel", 6)])
def test_wrong_length_is_rejected_with_layout(kind, n):
    with pytest.raises(tb.StateError, match=f"must have {n} entries"):
        as_state(kind, np.zeros(n + 1))


def test_non_numeric_and_non_finite_states_are_rejected():
    with pytest.raises(tb.StateError, match="real numbers"):
        as_state("reduced", ["a"] * 9)
    s = demo_reduced_state()
    s[0] = np.nan
    with pytest.raises(tb.StateError, match="non-finite"):
        as_state("reduced", s)


@pytest.mark.parametrize(
    "kind, mutate, needle",
    [
        ("reduced", lambda s: s.__setitem__(5, s[5] * 1.01), "gamma2 - 1"),
        ("reduced", lambda s: s.__setitem__(6, s[6] + 0.1), "(R, gamma)"),
        ("mparallel", lambda s: s.__setitem__(3, 2.0), "gamma2 - 1"),
        ("full", lambda s: s.__setitem__(3, s[3] + 1e-3), "alpha2 - 1"),
    ],
)
def test_off_manifold_states_are_rejected(kind, mutate, needle):
    s = _state(kind)
    mutate(s)
    with pytest.raises(tb.ConstraintError, match=needle.replace("(", r"\(").replace(")", r"\)")) as info:
        tb.propagate(kind, FIG5, s, 1.0)
    assert "project=True" in str(info.value)


def test_left_handed_frame_is_rejected():
    s = _state("full")
    s[6:9] = -s[6:9]  # beta -> -beta
    with pytest.raises(tb.ConstraintError, match="left-handed"):
        tb.propagate("full", FIG5, s, 1.0)


def _state(kind):
    s = demo_reduced_state()
    if kind == "reduced":
        return s
    if kind == "full":
        return tb.reduced_to_full(FIG5, s)
    return np.concatenate([[0.5, -1.0, 2.0], s[3:6]])


@pytest.mark.parametrize("kind", ["full", "reduced", "mparallel"])
def test_project_puts_states_on_the_manifold(kind):
    s = _state(kind)
    rng = np.random.default_rng(1)
    bad = s + 1e-3 * rng.normal(size=s.size)
    for dtype, eps in [(np.float64, EPS), (hy.real128, 2.0**-112)]:
        p = tb.project(kind, bad.astype(dtype))
        assert p.dtype == np.dtype(dtype)
        for name, r in constraint_residuals(kind, p).items():
            # a normalisation and one orthogonalisation: a few roundings per entry
            assert abs(float(r)) <= 8 * eps, (name, float(r))


def test_project_true_accepts_and_fixes_off_manifold_state():
    s = demo_reduced_state()
    s[3:6] *= 1.1
    out = tb.propagate("reduced", FIG5, s, 0.0, project=True)
    assert abs(out[3:6] @ out[3:6] - 1) <= 4 * EPS


def test_within_tolerance_states_are_snapped_in_working_precision():
    """A float64 state is ~1e-16 off the manifold; in real128 it is snapped onto it."""
    s = demo_reduced_state()
    out = tb.propagate("reduced", FIG5, s, 0.0, fp_type=hy.real128)
    res = constraint_residuals("reduced", out)
    assert all(abs(float(v)) <= 8 * 2.0**-112 for v in res.values())


# --- full <-> reduced ------------------------------------------------------------------------
@given(s=STATES["reduced"]())
def test_reduced_to_full_frame_has_F1_zero(s):
    """Section 3 (erratum E1): beta = (M - M_gamma gamma)/sqrt(C^2 - M_gamma^2), alpha = beta x gamma."""
    c = tb.get_system("reduced").constants(FIG5.pars)
    p = tb.project("reduced", s)
    K = np.array(tb.model.K_from_omega(c.I, c.d, tuple(p[3:6]), tuple(p[0:3])))
    M = K - c.ma * c.Omega * p[6:9]
    # |M| scaled by max|M_i| (hypothesis finds |M| ~ 1e-160 and 1e-299, whose square is
    # subnormal or zero: np.linalg.norm underflows there)
    m_max = float(np.max(np.abs(M)))
    C = m_max * float(np.linalg.norm(M / m_max)) if m_max > 0 else 0.0
    Mg = float(M @ p[3:6])
    # reduced_to_full refuses M || gamma when sin(M, gamma) <= 1e-12 (relative); the sine
    # from |M x gamma| (no cancellation, unlike C^2 - Mg^2); a gray zone around the threshold
    sin_mg = float(np.linalg.norm(np.cross(M / m_max, p[3:6]))) * m_max / C if C > 0 else 0.0
    if sin_mg <= 1e-13:
        with pytest.raises(tb.ChartError):
            tb.reduced_to_full(FIG5, s)
        return
    assume(sin_mg > 1e-11)
    f = tb.reduced_to_full(FIG5, s)
    F = tb.integrals("full", FIG5, f)  # also checks the frame is orthonormal, right-handed
    # rounding of M = Itilde omega - m a Omega R, relative to its terms (they can cancel to
    # a much smaller C), amplified by 1/F2 through the frame; the full integrals re-form M
    # from (omega, alpha, beta, gamma, x, y), a second such rounding
    terms = np.linalg.norm(K) + abs(c.ma * c.Omega) * np.linalg.norm(p[6:9])
    scale = (C + terms) * 8 * EPS / math.sqrt(1 - (Mg / C) ** 2)
    assert abs(F["F1"]) <= scale
    assert abs(F["F2"] - C * math.sqrt(1 - (Mg / C) ** 2)) <= scale  # no squares: |M| may be 1e-180
    assert abs(F["F3"] - Mg) <= scale
    back = tb.full_to_reduced(f)
    assert np.max(np.abs(back - tb.project("reduced", s))) <= 16 * EPS * (1 + np.max(np.abs(s)))


def test_reduced_to_full_rejects_M_parallel_gamma():
    p = FIG5
    g = np.array([0.0, 0.6, 0.8])
    c = tb.get_system("reduced").constants(p.pars)
    K = 2.0 * g  # M = 2 gamma, R = 0
    omega = tb.model.omega_from_K(c.A, c.d, tuple(g), tuple(K))
    with pytest.raises(tb.ChartError, match="parallel to gamma"):
        tb.reduced_to_full(p, np.concatenate([omega, g, [0, 0, 0]]))


def test_psi_rotates_F1_F2_as_eq_11():
    """Rotating the fixed frame by psi (the flow of u_s, paper eq. (14) [eq9]) rotates (F1, F2)
    as paper eq. (17) [eq11] says."""
    s = demo_reduced_state()
    f0 = tb.integrals("full", FIG5, tb.reduced_to_full(FIG5, s))
    psi = 0.7
    f1 = tb.integrals("full", FIG5, tb.reduced_to_full(FIG5, s, psi=psi))
    c, sn = math.cos(psi), math.sin(psi)
    tol = 16 * EPS * abs(f0["F2"])
    assert abs(f1["F1"] - (c * f0["F1"] + sn * f0["F2"])) <= tol
    assert abs(f1["F2"] - (-sn * f0["F1"] + c * f0["F2"])) <= tol
    assert abs(f1["F3"] - f0["F3"]) <= tol and abs(f1["E"] - f0["E"]) <= 64 * EPS * abs(f0["E"]) + tol


def test_full_then_reduce_equals_reduce_then_full():
    """Propagating the full system and reducing equals propagating the reduced system.

    In real128, with the lift built in real128 (so both start at the same point to
    ~eps_128). The tolerance is 16 eps_128 times the orbit's error growth G, measured here
    independently as |float64 - real128| / eps_64 of the reduced run (G ~ 5e3 at t = 10)."""
    T = 10.0
    s64 = demo_reduced_state()
    s = tb.project("reduced", s64.astype(hy.real128))
    f = tb.reduced_to_full(FIG5, s)
    a = tb.propagate("reduced", FIG5, s, T, fp_type=hy.real128)
    b = tb.full_to_reduced(tb.propagate("full", FIG5, f, T, fp_type=hy.real128))
    a64 = tb.propagate("reduced", FIG5, s64, T)
    growth = max(1.0, float(np.max(np.abs(a64 - a.astype(float)))) / EPS)
    diff = float(np.max(np.abs(a - b)))
    print(f"full vs reduced at t={T}: {diff:.3g} (eps128 * growth = {2.0**-112 * growth:.3g})")
    assert diff <= 16 * 2.0**-112 * growth


def test_reduced_to_full_keeps_high_precision():
    s = tb.project("reduced", demo_reduced_state().astype(hy.real128))
    f = tb.reduced_to_full(FIG5, s)
    assert f.dtype == np.dtype(hy.real128)
    F = tb.integrals("full", FIG5, f)
    assert abs(float(F["F1"])) <= 64 * 2.0**-112 * math.sqrt(float(tb.integrals("reduced", FIG5, s)["C2"]))
