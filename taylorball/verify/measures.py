"""Checks of the paper: invariant measures along trajectories (see :mod:`taylorball.verify`).

Each row integrates a system with its variational equations (heyoka, compact mode) on the
chaotic Fig. 5 ball and measures the Liouville residual
``|rho(x(t)) det Phi(t) / rho(x(0)) - 1|``
(:func:`taylorball.verify.invariant_measures.liouville`). The tolerance is the
first-order bound ``n eps sqrt(N) cond(Phi)`` (dimension ``n``, ``N`` steps; derived in
:mod:`taylorball.verify.invariant_measures`); the row also requires the Lebesgue measure
(``rho = 1``) to fail it by a factor 100 at least, so the check can tell a density from a
non-density. Quick mode: float64, ``t = 10``; full mode adds real128.
"""

from __future__ import annotations

import math

from . import CheckResult

_ROWS = [
    ("full", "omega", "paper's density of eqs. (8)-(10) [eq6] in (omega, alpha, beta, gamma, x, y)",
     "sec. 2"),
    ("full", "momentum", "|D|^(-1/2) for eqs. (8)-(10) [eq6] in (M, alpha, beta, gamma, x, y)", "sec. 2"),
    ("reduced", "omega", "det(Itilde)|D|^(-1/2) for eqs. (15)-(16) [eq10] in (omega, gamma, R) "
     "(derived, not printed)", "sec. 3"),
    ("reduced", "momentum", "|D|^(-1/2) for eqs. (15)-(16) [eq10] in (M, gamma, R)", "sec. 3"),
    ("mparallel", None, "(1 - d (gamma, A gamma))^(-1/2) for eq. (22) [Mpn2]", "sec. 5"),
]


def _row(kind, formulation, text, ref, fp_type, t):
    from .invariant_measures import liouville
    from ..model import get_system
    from ..manifold import reduced_to_full

    import numpy as np

    from ..paper import FIG5_BALL as ball

    g = np.array([0.3, 0.4, math.sqrt(0.75)])
    R = np.array([1.0, -0.5, -(1.0 * 0.3 - 0.5 * 0.4) / math.sqrt(0.75)])
    red = np.array([0.1, 0.2, 0.3, *g, *R])
    state = {"full": lambda: reduced_to_full(ball, red), "reduced": lambda: red,
             "mparallel": lambda: np.array([0.3, -1.2, 0.8, 0.6, 0.0, 0.8])}[kind]()
    r = liouville(kind, ball, state, t, formulation=formulation, fp_type=fp_type)
    one = liouville(kind, ball, state, t, formulation=formulation, fp_type=fp_type, density="one")
    n = get_system(kind, formulation).dim
    tol = n * r.eps * math.sqrt(max(r.n_steps, 1)) * r.cond
    ok = r.residual <= tol and one.residual >= 100 * tol
    return CheckResult(
        claim=f"Liouville rho det Phi = const ({r.fp_type}): {text}", reference=ref,
        verdict="verified" if ok else "failed", residual=r.residual, tolerance=tol,
        detail=f"t = {t}, {r.n_steps} steps, cond(Phi) = {r.cond:.3g}, residual = {r.residual / r.eps:.3g} eps; "
               f"rho = 1 gives {one.residual:.3g} ({one.residual / max(r.residual, 1e-300):.2g} x larger)")


def check_liouville(full=False):
    """Liouville relation along trajectories for all three systems."""
    import heyoka as hy

    out = [_row(k, f, text, ref, float, 10.0) for k, f, text, ref in _ROWS]
    if full:
        out += [_row(k, f, text, ref, hy.real128, 2.0) for k, f, text, ref in _ROWS]
    return out


#: check functions f(full: bool) -> CheckResult | list[CheckResult]
CHECKS: list = [check_liouville]
