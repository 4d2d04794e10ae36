"""The volume form preserved by the section-4 Poincaré map (taylorball.verify.section_volume)."""

from __future__ import annotations


import mpmath
import numpy as np
import pytest

from taylorball.paper import FIG4_BALL
from taylorball.verify import section_volume as sv
from taylorball.charts import reduced_state_from_chart, section_admissible_sample, states_on_section
from taylorball.errors import UsageError

FIG4 = FIG4_BALL
C, H = 10.0, 5.0
# admissible points of the Fig. 4 levels (found by section_admissible_sample(seed=3)),
# with their branch K (direction +1)
PT = (6.157, -4.178, 0.806)
EPS_LD = float(np.finfo(np.longdouble).eps)


def _root(Mg, pt=PT):
    _, info = states_on_section(FIG4, C=C, M_gamma=Mg, h=H, point=pt, direction=1, return_info=True)
    return float(info["K"][0])


def test_chart_extension_is_the_chart_on_the_level():
    """chart_extension_mp on c = (1, 0, C^2, M_gamma) gives charts.reduced_state_from_chart."""
    K, l, g, r1, r2 = 3.1, 0.7, 2.2, 1.3, -0.4
    st = reduced_state_from_chart(FIG4, C=C, M_gamma=2.0, K=K, l=l, g=g, r1=r1, r2=r2)
    with mpmath.workdps(30):
        M, gam, R = sv.chart_extension_mp([mpmath.mpf(v) for v in (K, r1, r2, l, g)], sv._levels0(C, 2.0))
        # gamma and R are public variables too; 8 eps: a few roundings in the float64 chart
        for a, b in zip((*gam, *R), st[3:9]):
            assert abs(float(a) - b) <= 8 * np.finfo(float).eps * max(1.0, abs(b))
        # and the chart of the extension's output is y again (to the working precision)
        y = sv.chart_of_internal_mp(M, gam, R)
        for a, b in zip(y, (K, r1, r2, l, g)):
            assert abs(a - b) < mpmath.mpf(10) ** -25


@pytest.mark.parametrize("Mg,y", [(2.0, (3.1, 1.3, -0.4, 0.7, 2.2)), (6.0, (-5.0, -2.0, 4.0, 4.0, 0.1))])
def test_closed_form_density_equals_9x9_jacobian(Mg, y):
    """rho5 = |D|^-1/2 / (4 C (g1^2+g2^2)|g3|) equals |D|^-1/2 |det dPhi/d(y,c)| (mpmath
    fourth-order differences at 50 digits; agreement to 1e-25 is far beyond any float)."""
    K, r1, r2, l, g = y
    a = sv.level_density(FIG4, C=C, M_gamma=Mg, K=K, l=l, g=g, r1=r1, r2=r2, method="closed", dps=30)
    b = sv.level_density(FIG4, C=C, M_gamma=Mg, K=K, l=l, g=g, r1=r1, r2=r2, method="jacobian", dps=30)
    with mpmath.workdps(60):  # compare the two 50-digit results exactly
        assert abs(a / b - 1) < mpmath.mpf(10) ** -25


def test_liouville_in_chart_coordinates():
    """div_y(rho5 ydot) = 0 for the derived density (an independent check: only the vector
    field enters), while rho = 1 and rho = |D|^-1/2 (chart factor forgotten) fail."""
    y = (_root(2.0), PT[1], PT[2], PT[0], 0.3)
    good = sv.liouville_residual(FIG4, C=C, M_gamma=2.0, y=y, dps=60)
    # nested 4th-order differences at 60 digits: outer step 1e-7 -> error ~1e-28
    assert good < 1e-20
    for wrong in ("one", "rho9"):
        assert sv.liouville_residual(FIG4, C=C, M_gamma=2.0, y=y, density=wrong, dps=60) > 1e-3


def test_section_density_usage_errors():
    with pytest.raises(UsageError):
        sv.level_density(FIG4, C=C, M_gamma=2.0, K=1.0, l=0.1, g=0.2, r1=0.1, r2=0.1, method="bogus")
    with pytest.raises(UsageError):
        # two roots with direction None at this point: the branch must be given
        sv.section_density(FIG4, C=C, M_gamma=2.0, h=H, point=(4.97502663, 5.61108062, -2.50868616),
                           direction=None)
    with pytest.raises(UsageError):
        sv.return_map_jacobian(FIG4, C=C, M_gamma=2.0, h=H, point=PT, K=_root(2.0), step=-1.0)


@pytest.mark.parametrize("fn", [sv.return_map_jacobian, sv.volume_preservation_check])
def test_jacobian_method_usage_error(fn):
    """A bad method names the argument, the value and the valid choices (before any work)."""
    with pytest.raises(UsageError, match=r"method.*'fd'.*'variational'.*'adjoint'"):
        fn(FIG4, C=C, M_gamma=2.0, h=H, point=PT, K=_root(2.0), method="adjoint")


def test_section_density_matches_state_form():
    """sigma from the chart point and branch equals sigma from the state built there."""
    K = _root(6.0)
    s = sv.section_density(FIG4, C=C, M_gamma=6.0, h=H, point=PT, K=K)
    st = states_on_section(FIG4, C=C, M_gamma=6.0, h=H, point=PT, direction=1)
    s2, y = sv.section_density_of_state(FIG4, st[0])
    # the float64 state is ~eps off the chart point; sigma's condition number is O(10)
    assert abs(s2 / s - 1) < 1e3 * np.finfo(float).eps


# Tolerance of the volume-preservation residual (Richardson-extrapolated central differences
# at step s = 1e-4 of long-double return maps): the integration error of each return
# (<~ 1e3 steps x eps_ld, amplified <~ 1e2 by the flow) divided by s gives
# k = 1e3 * 1e2 / 1e-4 = 1e9 units of eps_ld (~1.1e-10); the s^4 remainder is ~1e-16.
VOL_TOL = 1e9 * EPS_LD


def test_return_map_preserves_sigma_volume():
    """sigma(Px) |det DP(x)| = sigma(x) on the Fig. 4 level (M_gamma = 2); sigma = 1 and the
    density without the chart factor fail by > 8 orders of magnitude more."""
    r = sv.volume_preservation_check(FIG4, C=C, M_gamma=2.0, h=H, point=PT, K=_root(2.0), method="fd")
    assert r["residual_richardson"] < VOL_TOL
    # the plain central difference is off by its s^2 truncation error, which the two-step
    # estimate predicts (to 10 %)
    assert abs(r["residual"] - r["fd_error"]) <= 0.1 * r["fd_error"] + VOL_TOL
    assert r["residual_unit_density"] > 1e-2
    assert r["residual_rho9"] > 1e-2


@pytest.mark.slow
@pytest.mark.parametrize("Mg", [2.0, 6.0])
def test_return_map_preserves_sigma_volume_sampled(Mg):
    pts = section_admissible_sample(FIG4, C=C, M_gamma=Mg, h=H, n=6, seed=11)
    for pt, K in zip(pts["points"], pts["K"]):
        r = sv.volume_preservation_check(FIG4, C=C, M_gamma=Mg, h=H, point=pt, K=K, method="fd")
        assert r["residual_richardson"] < VOL_TOL, (pt, K, r)
        assert r["residual_unit_density"] > 1e3 * VOL_TOL


# Tolerance of the volume-preservation residual with DP from the variational equations
# (long double): DP = J_out (I - f grad_e^T / (grad_e . f)) Phi J_in with J_in, J_out, f,
# grad_e in mpmath (~1e-30), so the error is the integration's: ~30 Taylor steps per return,
# each with a relative error ~eps_ld in the 90-component state, whose variational part carries
# the scale |Phi| <~ 3e2 (measured 46..271 on the 14 points of the verify check), gives
# k = 30 * 3e2 ~ 1e4 units of eps_ld (1.1e-15). Measured: 765 eps (M_gamma = 2), 202 eps
# (M_gamma = 6) at PT, at most 1.24e3 eps on the 12 sampled points; real128 gives 4e-30 (the
# mpmath sigma's limit at 40 digits), so the long-double residual is integration rounding.
VAR_TOL = 1e4 * EPS_LD


@pytest.mark.parametrize("Mg", [2.0, 6.0])
def test_variational_jacobian_matches_finite_differences(Mg):
    """DP from the variational equations equals the central-difference DP (an independent
    computation: integrated perturbed orbits) to within the latter's error estimate."""
    K = _root(Mg)
    Px_f, DP_f, info_f = sv.return_map_jacobian(FIG4, C=C, M_gamma=Mg, h=H, point=PT, K=K, method="fd")
    Px_v, DP_v, info_v = sv.return_map_jacobian(FIG4, C=C, M_gamma=Mg, h=H, point=PT, K=K)  # the default
    assert info_v["method"] == "variational" and info_f["method"] == "fd"
    # same image point (both integrate the same long-double start to the same crossing)
    assert np.max(np.abs(Px_v - Px_f)) < 1e-14
    assert abs(info_v["time"] - info_f["time"]) < 1e-14
    # the crossing refined by Newton: the event function at the image is rounding-size
    assert abs(info_v["event_residual"]) < 1e3 * EPS_LD
    # err = |DP(s) - DP(2 s)| / 3 estimates the s^2 error of DP(s) (measured: the
    # difference to the variational DP is err to 0.1 %); factor 2 is the margin
    assert np.max(np.abs(DP_v - DP_f)) <= 2 * info_f["err"]
    assert info_f["err"] > 1e-9  # the comparison is not vacuous: FD's error is visible
    # the Richardson-extrapolated FD DP, good to its own tolerance VOL_TOL (s^4 remainder
    # and integration error / s; measured 6e-14 at M_gamma = 2, 1.7e-13 at M_gamma = 6)
    DP_r = (4 * DP_f - info_f["DP2"]) / 3
    assert np.max(np.abs(DP_v - DP_r)) < VOL_TOL
    # the mpmath DP carries the float64 DP
    assert all(float(info_v["DP_mp"][i, j]) == DP_v[i, j] for i in range(3) for j in range(3))


@pytest.mark.parametrize("Mg", [2.0, 6.0])
def test_return_map_preserves_sigma_volume_variational(Mg):
    """sigma(Px) |det DP(x)| = sigma(x) to ~1e3 eps_ld with DP from the variational
    equations; sigma = 1 and rho9 without the chart factor fail by > 10 orders of magnitude."""
    r = sv.volume_preservation_check(FIG4, C=C, M_gamma=Mg, h=H, point=PT, K=_root(Mg), method="variational")
    assert r["method"] == "variational"
    assert r["residual"] < VAR_TOL
    assert "residual_richardson" not in r  # finite-difference keys only with method="fd"
    assert r["residual_unit_density"] > 1e10 * VAR_TOL
    assert r["residual_rho9"] > 1e10 * VAR_TOL


@pytest.mark.slow
@pytest.mark.parametrize("Mg", [2.0, 6.0])
def test_return_map_preserves_sigma_volume_variational_sampled(Mg):
    pts = section_admissible_sample(FIG4, C=C, M_gamma=Mg, h=H, n=6, seed=11)
    for pt, K in zip(pts["points"], pts["K"]):
        r = sv.volume_preservation_check(FIG4, C=C, M_gamma=Mg, h=H, point=pt, K=K, method="variational")
        assert r["residual"] < VAR_TOL, (pt, K, r)
        assert min(r["residual_unit_density"], r["residual_rho9"]) > 1e10 * VAR_TOL
