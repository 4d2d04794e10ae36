"""Checks of the paper: the Poincaré map of section 4 preserves a volume form (see
:mod:`taylorball.verify`).

The paper asserts (sec. 4) that the 3D map ``(l, r1, r2) -> P(l, r1, r2)`` on ``g = g0``
preserves "some volume form" but does not give it. :mod:`taylorball.verify.section_volume`
derives it, ``sigma dl dr1 dr2`` with
``sigma = rho5 |dg/dt| / |dE/dK|``, ``rho5 = |D|^(-1/2) / (4 C (gamma1^2 + gamma2^2) |gamma3|)``,
and these rows check (1) ``rho5`` against the 9x9 coarea Jacobian (mpmath), (2) ``rho5``
against the Liouville equation of the 5D flow in chart coordinates, (3) the map itself:
``sigma(Px) |det DP| = sigma(x)`` on the Fig. 4 levels (``C = 10``, ``h = 5``,
``M_gamma = 2, 6``) with ``DP`` from the variational equations (to ~1e3 eps of long double),
(4) that ``DP`` against central differences of integrated return maps (an independent
computation, to their own error), with the wrong densities ``sigma = 1`` and ``rho9``
without the chart factor as controls that must fail.
"""

from __future__ import annotations

import math

import numpy as np

from . import CheckResult

_C, _H = 10.0, 5.0
_PT = (6.157, -4.178, 0.806)  # admissible on both Fig. 4 levels (direction +1)
_EPS_LD = float(np.finfo(np.longdouble).eps)
#: DP from the variational equations (long double; chart Jacobians, vector field and event
#: gradient in mpmath to ~1e-30): the error is the integration's, ~30 Taylor steps per return
#: each with a relative error ~eps_ld in the 90-component state, whose variational part has
#: the scale |Phi| <~ 3e2 (measured 46..271 on the 14 points of --full): k = 30 * 3e2 ~ 1e4
#: units of eps_ld (1.1e-15). Measured: at most 1.24e3 eps_ld (1.3e-16) on the 14 points.
_VOL_TOL = 1e4 * _EPS_LD
#: The cross-check by Richardson-extrapolated central differences (step 1e-4) of long-double
#: return maps: the return's integration error (<~ 1e3 steps x eps_ld, amplified <~ 1e2)
#: divided by the step gives k = 1e3 * 1e2 / 1e-4 = 1e9 units of eps_ld (1.1e-10); the
#: step^4 remainder ~1e-16. Measured: at most 1.5e-12 (entries of DP).
_FD_TOL = 1e9 * _EPS_LD
#: The wrong densities must miss by 10 orders of magnitude more than the true one may.
_WRONG_MIN = 1e10 * _VOL_TOL


def _ball():
    from ..paper import FIG4_BALL

    return FIG4_BALL


def _K(ball, Mg, pt):
    from ..charts import states_on_section

    _, info = states_on_section(ball, C=_C, M_gamma=Mg, h=_H, point=pt, direction=1, return_info=True)
    return float(info["K"][0])


def check_level_density(full=False):
    """rho5 on M^5: closed form vs 9x9 coarea Jacobian; Liouville in chart coordinates."""
    import mpmath

    from . import section_volume as sv

    ball = _ball()
    ys = [(2.0, (3.1, 1.3, -0.4, 0.7, 2.2)), (6.0, (-5.0, -2.0, 4.0, 4.0, 0.1))]
    if full:
        rng = np.random.default_rng(5)
        for _ in range(6):
            ys.append((float(rng.choice([2.0, 6.0])),
                       (rng.uniform(-9, 9), rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(0, 2 * math.pi),
                        rng.uniform(0, 2 * math.pi))))
    worst_j = 0.0
    for Mg, (K, r1, r2, l, g) in ys:
        a = sv.level_density(ball, C=_C, M_gamma=Mg, K=K, l=l, g=g, r1=r1, r2=r2, method="closed", dps=30)
        b = sv.level_density(ball, C=_C, M_gamma=Mg, K=K, l=l, g=g, r1=r1, r2=r2, method="jacobian", dps=30)
        with mpmath.workdps(60):  # compare the two 50-digit results exactly
            worst_j = max(worst_j, float(abs(a / b - 1)))
    tol_j = 1e-25  # 30 digits, fourth-order differences at step 1e-12.5 -> ~1e-30; margin 1e5
    row1 = CheckResult(
        claim="invariant density on M^5 in (K, r1, r2, l, g): |D|^-1/2 / (4 C (g1^2+g2^2)|g3|) = coarea Jacobian",
        reference="sec. 4 (derived)", verdict="verified" if worst_j <= tol_j else "failed",
        residual=worst_j, tolerance=tol_j,
        detail=f"{len(ys)} chart points; closed form vs rho9 |det dPhi/d(y, c)| (9x9, mpmath 50 digits)")
    ys_l = ys[:2] if not full else ys[:4]
    worst, wrong = 0.0, math.inf
    for Mg, y in ys_l:
        worst = max(worst, sv.liouville_residual(ball, C=_C, M_gamma=Mg, y=y, dps=60))
        for d in ("one", "rho9"):
            wrong = min(wrong, sv.liouville_residual(ball, C=_C, M_gamma=Mg, y=y, density=d, dps=60))
    tol_l = 1e-20  # nested fourth-order differences at 60 digits: ~1e-28 expected
    ok = worst <= tol_l and wrong >= 1e3 * tol_l
    row2 = CheckResult(
        claim="Liouville div_y(rho5 ydot) = 0 of the 5D flow in chart coordinates (rho = 1, |D|^-1/2 fail)",
        reference="sec. 4 (derived)", verdict="verified" if ok else "failed", residual=worst, tolerance=tol_l,
        detail=f"{len(ys_l)} points; relative divergence; wrong densities give >= {wrong:.3g}")
    return [row1, row2]


def check_map_volume(full=False):
    """The 3D Poincaré map preserves sigma dl dr1 dr2 (sigma = 1 does not)."""
    from . import section_volume as sv
    from ..charts import section_admissible_sample

    ball = _ball()
    cases = [(Mg, _PT, _K(ball, Mg, _PT)) for Mg in (2.0, 6.0)]
    if full:
        for Mg in (2.0, 6.0):
            s = section_admissible_sample(ball, C=_C, M_gamma=Mg, h=_H, n=6, seed=11)
            cases += [(Mg, tuple(p), float(k)) for p, k in zip(s["points"], s["K"])]
    res = [sv.volume_preservation_check(ball, C=_C, M_gamma=Mg, h=_H, point=pt, K=K, method="variational")
           for Mg, pt, K in cases]
    worst = max(r["residual"] for r in res)
    one = min(r["residual_unit_density"] for r in res)
    rho9 = min(r["residual_rho9"] for r in res)
    dets = [r["det"] for r in res]
    ok = worst <= _VOL_TOL
    row = CheckResult(
        claim="the 3D Poincare map preserves sigma dl dr1 dr2, sigma = rho5 |g_dot| / |dE/dK|",
        reference="sec. 4", verdict="verified" if ok else "failed", residual=worst, tolerance=_VOL_TOL,
        detail=(f"{len(res)} points on Fig. 4 levels C=10, h=5, M_gamma=2,6; |sigma(Px) det DP / sigma(x) - 1| with DP "
                f"from the variational equations (long double): at most {worst / _EPS_LD:.3g} eps_ld; "
                f"|det DP| in [{min(dets):.3g}, {max(dets):.3g}]"))
    # DP cross-checked by an independent computation: central differences of integrated maps
    dev_r, dev_fd = 0.0, 0.0
    for (Mg, pt, K), r in zip(cases, res):
        _, DP, info = sv.return_map_jacobian(ball, C=_C, M_gamma=Mg, h=_H, point=pt, K=K, method="fd")
        dev_r = max(dev_r, float(np.max(np.abs(r["DP"] - (4 * DP - info["DP2"]) / 3))))
        dev_fd = max(dev_fd, float(np.max(np.abs(r["DP"] - DP))) / info["err"])
    ok2 = dev_r <= _FD_TOL and dev_fd <= 2.0
    cross = CheckResult(
        claim="DP of the Poincare map from the variational equations = DP by central differences",
        reference="sec. 4", verdict="verified" if ok2 else "failed", residual=dev_r, tolerance=_FD_TOL,
        detail=(f"{len(res)} points; max entry difference to the Richardson-extrapolated differences (steps 1e-4, "
                f"2e-4); to the step-1e-4 differences at most {dev_fd:.4g} x their error estimate (must be <= 2)"))
    ok1 = one >= _WRONG_MIN and rho9 >= _WRONG_MIN
    ctrl = CheckResult(
        claim="control: sigma = 1 (and rho9 without the chart factor) is NOT preserved by the map",
        reference="sec. 4", verdict="verified" if ok1 else "failed", residual=min(one, rho9), tolerance=_WRONG_MIN,
        detail=f"min over the points of ||det DP| - 1| = {one:.3g}, of the rho9-only residual = {rho9:.3g} "
               "(must exceed 1e10 x the tolerance of the true density)")
    return [row, cross, ctrl]


#: check functions ``f(full: bool) -> CheckResult | list[CheckResult]``
CHECKS: list = [check_level_density, check_map_volume]
