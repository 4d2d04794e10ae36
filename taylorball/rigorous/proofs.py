r"""Krawczyk proofs of fixed points of the 2D section maps (symmetric ball; M||gamma system).

**Theorem used (Krawczyk 1969; Moore 1977).** Let ``F: R^2 -> R^2`` be C^1 on a box ``X``
with midpoint ``x``, ``C`` any 2 x 2 matrix, ``[DF]`` an interval matrix containing
``DF(y)`` for every ``y`` in ``X``, and

.. math:: K(X) = x - C F(x) + (I - C [DF]) (X - x).

If ``K(X)`` lies in the interior of ``X`` then ``F`` has exactly one zero in ``X`` (and it
lies in ``K(X)``). Here ``F(p) = P(p) - p`` with ``P`` the section map of
:mod:`taylorball.rigorous.section`, ``C = (mid [DP] - I)^{-1}`` rounded to floats.

The type of the orbit follows from ``[DP]`` (which contains ``DP`` at the fixed point):
see :func:`classify`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Dict, List, Optional

import numpy as np

from ..errors import IntegrationError
from ._balls import arb, exact_arb, working_precision
from .section import NotProved, section_map

__all__ = ["KrawczykResult", "krawczyk_fixed_point", "classify"]


@dataclass
class KrawczykResult:
    r"""Outcome of :func:`krawczyk_fixed_point`: ``proved`` only if ``K(X) \subset int X``."""

    proved: bool
    message: str
    center: List[float]
    radius: float
    K: List[Any]
    DP: List[List[Any]]
    kind: str
    trace: Optional[Any]
    det: Optional[Any]
    tau: Optional[Any]
    cpu_seconds: float


def classify(DP: List[List[Any]]) -> tuple:
    r"""``("hyperbolic" | "elliptic" | "undecided", trace, det)`` from an enclosure of DP.

    With ``p(s) = s^2 - T s + D`` the characteristic polynomial: ``p(1) < 0 < p(-1)`` proves
    real eigenvalues ``-1 < s_1 < 1 < s_2`` (a saddle); ``p(-1) < 0 < p(1)`` proves
    ``s_1 < -1 < s_2 < 1`` (a reflection saddle); both are "hyperbolic". ``T^2 - 4 D < 0``
    proves a complex pair ("elliptic"; on the unit circle when ``det DP = 1``, which is not
    used). Otherwise "undecided"."""
    T = DP[0][0] + DP[1][1]
    D = DP[0][0] * DP[1][1] - DP[0][1] * DP[1][0]
    p1, pm1 = 1 - T + D, 1 + T + D
    if (p1 < 0 and pm1 > 0) or (pm1 < 0 and p1 > 0):
        return "hyperbolic", T, D
    if T * T - 4 * D < 0:
        return "elliptic", T, D
    return "undecided", T, D


def krawczyk_fixed_point(params: Any, levels: Any, center: List[float], radius: float, K_guess: float,
                         tau_guess: float, *, prec: int = 128, delta: float = 1e-3, kind: str = "reduced",
                         l_branch: float = 0.0, c1: str = "lohner") -> KrawczykResult:
    r"""Try to prove a unique fixed point of the 2D section map in the box ``center +- radius``.

    ``kind="reduced"``: the symmetric ball's map of ``(r1, r2)``
    (:func:`~taylorball.rigorous.section.section_map`; ``K_guess`` the energy root ``M3``);
    ``kind="mparallel"``: the M||gamma map of ``(l, L/G)``
    (:func:`~taylorball.rigorous.section.mparallel_section_map`; ``K_guess`` is the root
    ``G = |K|``, ``l'`` on the branch ``l_branch``). ``center``, ``K_guess`` and ``tau_guess``
    come from a floating-point search, which is not part of the proof."""
    from ..errors import UsageError
    from .section import mparallel_section_map

    if kind not in ("reduced", "mparallel"):
        raise UsageError(f"kind must be 'reduced' or 'mparallel', got {kind!r}")
    cpu0 = time.process_time()
    with working_precision(prec):
        xc = [exact_arb(v) for v in center]
        X = [v + arb(0, radius) for v in xc]

        def P(box: List[Any], jac: bool) -> Any:
            if kind == "mparallel":
                return mparallel_section_map(params, levels, box, K_guess, tau_guess, prec=prec, delta=delta,
                                             l_branch=l_branch, jac=jac, c1=c1)
            return section_map(params, levels, box, K_guess, tau_guess, prec=prec, delta=delta, jac=jac, c1=c1)

        try:
            Pc = P(xc, False)
            PX = P(X, True)
        except (NotProved, IntegrationError) as exc:  # an inclusion failed, or no validated step
            return KrawczykResult(False, f"not proved: {exc}", list(center), radius, [], [], "undecided", None, None,
                                  None, time.process_time() - cpu0)
        DP = PX.DP
        A = np.array([[float(DP[i][j].mid()) for j in range(2)] for i in range(2)]) - np.eye(2)
        Cf = np.linalg.inv(A)
        Cm = [[exact_arb(float(Cf[i][j])) for j in range(2)] for i in range(2)]
        F = [Pc.P[i] - xc[i] for i in range(2)]
        DF = [[DP[i][j] - (1 if i == j else 0) for j in range(2)] for i in range(2)]
        Kx = []
        for i in range(2):
            v = xc[i] - sum((Cm[i][j] * F[j] for j in range(2)), exact_arb(0))
            for j in range(2):
                Mij = (1 if i == j else 0) - sum((Cm[i][k] * DF[k][j] for k in range(2)), exact_arb(0))
                v = v + Mij * (X[j] - xc[j])
            Kx.append(v)
        ok = all(X[i].contains_interior(Kx[i]) for i in range(2))
        okind, T, D = classify(DP)
        if ok:
            msg = (f"proved: a unique fixed point of the 2D section map in the box {center} +- {radius:g} "
                   f"({okind}; trace {T.str(6)}, return time {PX.tau.str(8)})")
        else:
            over = max(max(float(Kx[i].upper().mid()) - float(X[i].upper().mid()),
                           float(X[i].lower().mid()) - float(Kx[i].lower().mid())) for i in range(2))
            msg = (f"not proved: K(X) is not inside X (it sticks out by {over:.3g}; K(X) = "
                   f"[{Kx[0].str(6)}, {Kx[1].str(6)}])")
        return KrawczykResult(ok, msg, list(center), radius, Kx, DP, okind, T, D, PX.tau,
                              time.process_time() - cpu0)


def result_summary(r: KrawczykResult) -> Dict[str, Any]:
    """Human-readable numbers of a result (floats; not part of a certificate's proof)."""
    return {"proved": r.proved, "kind": r.kind, "message": r.message, "cpu_seconds": round(r.cpu_seconds, 2)}
