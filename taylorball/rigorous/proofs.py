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
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from ..errors import IntegrationError
from ._balls import arb, exact_arb, working_precision
from ._run_state import check_workers, run_jobs
from .section import NotProved, section_map

__all__ = ["KrawczykResult", "krawczyk_operator", "krawczyk_fixed_point", "classify", "classify3", "ShootingResult",
           "krawczyk_periodic_orbit", "shooting_jobs", "shooting_verdict", "MAP_DIM"]


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


def krawczyk_operator(x: Sequence[Any], X: Sequence[Any], Fx: Sequence[Any], DF: Sequence[Sequence[Any]],
                      DF_mid: Any) -> Tuple[List[Any], bool, float]:
    r"""Krawczyk's operator and the inclusion test, for any dimension ``n``.

    .. math:: K(X) = x - C F(x) + (I - C [DF]) (X - x), \qquad C = \mathrm{fl}(\mathtt{DF\_mid}^{-1}),

    with ``x`` the (exact) centre, ``X`` the box (balls), ``Fx`` an enclosure of ``F(x)``,
    ``DF`` an ``n x n`` list of balls containing ``DF`` over ``X`` and ``DF_mid`` a float
    ``n x n`` array near its midpoint (``C`` is its float inverse, taken as exact: any ``C``
    makes the theorem hold). Returns ``(K, inside, over)``: the balls of ``K(X)``, whether
    ``K(X)`` lies in the interior of ``X`` (then ``F`` has exactly one zero in ``X``) and by
    how much ``K(X)`` sticks out of ``X`` at most (``<= 0`` when inside).

    The sums run in a fixed order (row ``i``: ``x_i - sum_j C_ij F_j``, then ``+ M_ij (X_j -
    x_j)`` for ``j = 0 .. n-1`` with ``M_ij = delta_ij - sum_k C_ik DF_kj``), so a proof
    re-checked on the same FLINT gives the same balls."""
    n = len(x)
    if len(X) != n or len(Fx) != n or len(DF) != n or any(len(row) != n for row in DF):
        from ..errors import UsageError

        raise UsageError(f"krawczyk_operator: x, X, F(x) (n each) and DF (n x n) must match, got n = {n}")
    Cf = np.linalg.inv(np.asarray(DF_mid, dtype=float))
    Cm = [[exact_arb(float(Cf[i][j])) for j in range(n)] for i in range(n)]
    zero = exact_arb(0)
    K = []
    for i in range(n):
        v = x[i] - sum((Cm[i][j] * Fx[j] for j in range(n)), zero)
        for j in range(n):
            Mij = (1 if i == j else 0) - sum((Cm[i][k] * DF[k][j] for k in range(n)), zero)
            v = v + Mij * (X[j] - x[j])
        K.append(v)
    inside = all(X[i].contains_interior(K[i]) for i in range(n))
    over = max(max(float(K[i].upper().mid()) - float(X[i].upper().mid()),
                   float(X[i].lower().mid()) - float(K[i].lower().mid())) for i in range(n))
    return K, inside, over


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
        DF = [[DP[i][j] - (1 if i == j else 0) for j in range(2)] for i in range(2)]
        F = [Pc.P[i] - xc[i] for i in range(2)]
        mid = np.array([[float(DP[i][j].mid()) for j in range(2)] for i in range(2)]) - np.eye(2)
        Kx, ok, over = krawczyk_operator(xc, X, F, DF, mid)
        okind, T, D = classify(DP)
        if ok:
            msg = (f"proved: a unique fixed point of the 2D section map in the box {center} +- {radius:g} "
                   f"({okind}; trace {T.str(6)}, return time {PX.tau.str(8)})")
        else:
            msg = (f"not proved: K(X) is not inside X (it sticks out by {over:.3g}; K(X) = "
                   f"[{Kx[0].str(6)}, {Kx[1].str(6)}])")
        return KrawczykResult(ok, msg, list(center), radius, Kx, DP, okind, T, D, PX.tau,
                              time.process_time() - cpu0)


def result_summary(r: KrawczykResult) -> Dict[str, Any]:
    """Human-readable numbers of a result (floats; not part of a certificate's proof)."""
    return {"proved": r.proved, "kind": r.kind, "message": r.message, "cpu_seconds": round(r.cpu_seconds, 2)}


# ---------------------------------------------------------------------------------------
# Multiple shooting: a periodic orbit of the symmetric ball's 2D map through m section points.
# ---------------------------------------------------------------------------------------
def _ser(x: Any) -> Tuple[int, int, float]:
    """An arb as ``(mantissa, exponent, radius)``: its midpoint exactly, its radius rounded up
    (for the worker processes: python-flint's balls do not pickle)."""
    from ._balls import _up

    man, exp = x.mid().man_exp()
    return int(man), int(exp), _up(x.rad()) if float(x.rad()) > 0 else 0.0


def _des(t: Sequence[Any]) -> Any:
    """The ball of :func:`_ser`'s triple (contains the original ball)."""
    man, exp, rad = t
    b = arb(man) * arb(2) ** exp if exp < 0 else arb(man * 2 ** exp)
    return b + arb(0, rad) if rad else b


def _shooting_segment(job: Tuple[Any, ...]) -> Dict[str, Any]:
    """One segment's section map (a worker's job): on the point ``center`` (``jac=False``) or
    on the box ``center +- radius`` with its Jacobian; balls returned as :func:`_ser` triples."""
    from .section import mparallel_section_map

    from .section import section_map3

    params, levels, center, radius, K_guess, tau_guess, prec, order, delta, jac, kind, l_branch = job
    cpu0 = time.process_time()
    with working_precision(prec):
        box = [exact_arb(v) + (arb(0, radius) if jac else 0) for v in center]
        try:
            if kind == "reduced3":
                se = section_map3(params, levels, box, K_guess, tau_guess, l_turns=int(l_branch), prec=prec,
                                  order=order, delta=delta, jac=jac)
            elif kind == "mparallel":
                se = mparallel_section_map(params, levels, box, K_guess, tau_guess, prec=prec, order=order,
                                           delta=delta, l_branch=l_branch, jac=jac)
            else:
                se = section_map(params, levels, box, K_guess, tau_guess, prec=prec, order=order, delta=delta, jac=jac)
        except (NotProved, IntegrationError) as exc:
            return {"ok": False, "message": str(exc), "cpu": time.process_time() - cpu0}
        return {"ok": True, "P": [_ser(p) for p in se.P], "DP": [[_ser(d) for d in row] for row in se.DP],
                "tau": _ser(se.tau), "steps": se.steps, "cpu": time.process_time() - cpu0}


@dataclass
class ShootingResult:
    r"""Outcome of :func:`krawczyk_periodic_orbit`: ``proved`` only if ``K(X) \subset int X``
    for the multiple-shooting map (``2 m`` unknowns)."""

    proved: bool
    message: str
    centers: List[List[Any]]
    radius: float
    K: List[Any]
    monodromy: List[List[Any]]
    kind: str
    trace: Optional[Any]
    det: Optional[Any]
    taus: List[Any]
    steps: int
    cpu_seconds: float


#: The dimension of each kind's section map (``"reduced3"``: the asymmetric ball's map of
#: ``(l, r1, r2)``, :func:`~taylorball.rigorous.section.section_map3`).
MAP_DIM = {"reduced": 2, "mparallel": 2, "reduced3": 3}


def shooting_jobs(params: Any, levels: Any, centers: Sequence[Sequence[Any]], radius: float,
                  K_guesses: Sequence[float], tau_guesses: Sequence[float], *, prec: int = 128,
                  order: Optional[int] = None, delta: float = 1e-3, kind: str = "reduced",
                  l_branches: Optional[Sequence[float]] = None) -> List[Tuple[Any, ...]]:
    """The ``2 m`` independent section-map jobs of :func:`krawczyk_periodic_orbit` (segment
    ``i``'s point job at ``2 i``, its box job at ``2 i + 1``), after checking the arguments
    (before any work). For ``kind="reduced3"`` segment ``i``'s ``l'`` is taken near the next
    centre's ``l`` (:func:`~taylorball.rigorous.section.quarter_turns`; ``l_branches`` must be
    None)."""
    from ..errors import UsageError
    from .section import L_BRANCHES, quarter_turns

    if kind not in MAP_DIM:
        raise UsageError(f"kind must be one of {sorted(MAP_DIM)}, got {kind!r}")
    d = MAP_DIM[kind]
    m = len(centers)
    if m < 1 or len(K_guesses) != m or len(tau_guesses) != m or any(len(c) != d for c in centers):
        raise UsageError(f"centers (m points of {d} components), K_guesses and tau_guesses (m each) must match, got "
                         f"{len(centers)}, {len(K_guesses)}, {len(tau_guesses)}")
    if not (isinstance(radius, float) and radius > 0):
        raise UsageError(f"radius must be a float > 0, got {radius!r}")
    if kind == "reduced3":
        if l_branches is not None:
            raise UsageError(f"l_branches is for kind='mparallel' (reduced3 takes l' near the next centre), "
                             f"got {l_branches!r}")
        lbs: List[float] = [float(quarter_turns(float(centers[(i + 1) % m][0]))) for i in range(m)]
    else:
        lbs = [0.0] * m if l_branches is None else [float(b) for b in l_branches]
        if len(lbs) != m or any(b not in L_BRANCHES for b in lbs):
            raise UsageError(f"l_branches must be {m} of 0, pi/2, pi, 3 pi/2 (math.pi multiples), got {l_branches!r}")
    return [(params, levels, list(centers[i]), radius, float(K_guesses[i]), float(tau_guesses[i]), prec, order, delta,
             jac, kind, lbs[i]) for i in range(m) for jac in (False, True)]


def krawczyk_periodic_orbit(params: Any, levels: Any, centers: Sequence[Sequence[float]], radius: float,
                            K_guesses: Sequence[float], tau_guesses: Sequence[float], *, prec: int = 128,
                            order: Optional[int] = None, delta: float = 1e-3, workers: int = 1,
                            kind: str = "reduced", l_branches: Optional[Sequence[float]] = None) -> ShootingResult:
    r"""Try to prove a periodic orbit of a section map through ``m`` points by multiple
    shooting.

    The unknowns are the ``m`` section points ``p_0 .. p_{m-1}`` (chart ``(r1, r2)``), each in
    the box ``centers[i] +- radius``; segment ``i`` is the local section map ``P_i`` of
    :func:`~taylorball.rigorous.section.section_map` near the return time ``tau_guesses[i]``
    on the energy root near ``K_guesses[i]``, and

    .. math:: F(p) = (P_0(p_0) - p_1, \ldots, P_{m-1}(p_{m-1}) - p_0).

    Krawczyk's operator on the ``d m``-dimensional box (``[DF]`` has the blocks ``[DP_i]`` on
    the diagonal and ``-I`` to their right, cyclically; ``C`` the float inverse of its midpoint)
    proves, if ``K(X) \subset int X``, exactly one zero of ``F`` in ``X``: one periodic orbit of
    the map through the ``m`` boxes. The product ``[DP_{m-1}] \cdots [DP_0]`` then contains
    the Jacobian of ``P^m`` at its fixed point; :func:`classify` (``d = 2``) or
    :func:`classify3` (``d = 3``) decides the type from it.

    The ``2 m`` section-map enclosures (a point and a box per segment,
    :func:`shooting_jobs`) are independent: with ``workers > 1`` they run in worker
    processes (the verdict is the same); :func:`shooting_verdict` makes the verdict from
    their results. ``centers``, ``K_guesses`` and ``tau_guesses`` come from a floating-point
    search, which is not part of the proof.

    ``kind="reduced"``: the symmetric ball's 2D map (a relative periodic orbit of the flow).
    ``kind="mparallel"``: the M||gamma map of ``(l, L/G)``
    (:func:`~taylorball.rigorous.section.mparallel_section_map`; ``K_guesses`` are the roots
    ``G = |K|``, and segment ``i``'s image ``l'`` is taken on the branch ``l_branches[i]``).
    ``kind="reduced3"``: the asymmetric ball's 3D map of ``(l, r1, r2)``
    (:func:`~taylorball.rigorous.section.section_map3`; a periodic orbit of the flow).
    ``centers`` may be floats or dyadic :class:`fractions.Fraction` (exact balls).
    """
    check_workers(workers)
    jobs = shooting_jobs(params, levels, centers, radius, K_guesses, tau_guesses, prec=prec, order=order, delta=delta,
                         kind=kind, l_branches=l_branches)
    cpu0 = time.process_time()
    got: Dict[int, Dict[str, Any]] = {}
    run_jobs(_shooting_segment, jobs, workers, lambda k, o: got.setdefault(k, o)["ok"])
    outs = [got[k] for k in sorted(got)]
    child = sum(o["cpu"] for o in outs) if workers > 1 and len(jobs) > 1 else 0.0
    return shooting_verdict(outs, centers, radius, prec=prec, kind=kind, cpu=time.process_time() - cpu0 + child)


def shooting_verdict(outs: Sequence[Dict[str, Any]], centers: Sequence[Sequence[Any]], radius: float, *, prec: int,
                     kind: str, cpu: float) -> ShootingResult:
    """The Krawczyk verdict of :func:`krawczyk_periodic_orbit` from the results of its jobs
    (:func:`shooting_jobs`, in order; a list that stops at a failed job is "not proved"
    with that job's reason)."""
    from ._balls import arb_mat

    m, d = len(centers), MAP_DIM[kind]
    cs = [list(c) for c in centers]
    for k, o in enumerate(outs):
        if not o["ok"]:
            return ShootingResult(False, f"not proved: segment {k // 2} ({'box' if k % 2 else 'point'}): "
                                  f"{o['message']}", cs, radius, [], [], "undecided", None, None, [], 0, cpu)
    if len(outs) != 2 * m:
        return ShootingResult(False, f"not proved: {len(outs)} of the {2 * m} section-map enclosures done", cs, radius,
                              [], [], "undecided", None, None, [], 0, cpu)
    with working_precision(prec):
        n = d * m
        x = [exact_arb(cs[i][j]) for i in range(m) for j in range(d)]
        X = [v + arb(0, radius) for v in x]
        Pc = [[_des(t) for t in outs[2 * i]["P"]] for i in range(m)]
        DPs = [[[_des(t) for t in row] for row in outs[2 * i + 1]["DP"]] for i in range(m)]
        if any(len(P) != d for P in Pc) or any(len(D) != d or any(len(r) != d for r in D) for D in DPs):
            return ShootingResult(False, f"not proved: a segment's result is not of dimension {d}", cs, radius, [], [],
                                  "undecided", None, None, [], 0, cpu)
        taus = [_des(outs[2 * i + 1]["tau"]) for i in range(m)]
        steps = sum(int(o["steps"]) for o in outs)
        zero, one = exact_arb(0), exact_arb(1)
        F = []
        for i in range(m):
            F += [Pc[i][a] - x[d * ((i + 1) % m) + a] for a in range(d)]
        DF = [[zero] * n for _ in range(n)]
        mid = np.zeros((n, n))
        for i in range(m):
            jn = (i + 1) % m
            for a in range(d):
                for b in range(d):
                    DF[d * i + a][d * i + b] = DPs[i][a][b]
                    mid[d * i + a, d * i + b] = float(DPs[i][a][b].mid())
                DF[d * i + a][d * jn + a] = DF[d * i + a][d * jn + a] - one
                mid[d * i + a, d * jn + a] -= 1.0
        Kx, ok, over = krawczyk_operator(x, X, F, DF, mid)
        Mono = arb_mat([[v for v in row] for row in DPs[0]])
        for i in range(1, m):
            Mono = arb_mat([[v for v in row] for row in DPs[i]]) * Mono
        mono = [[Mono[a, b] for b in range(d)] for a in range(d)]
        okind, T, D = classify(mono) if d == 2 else classify3(mono)
        if ok:
            msg = (f"proved: a unique periodic orbit of the {d}D section map through the {m} boxes "
                   f"(radius {radius:g}); {okind}, trace of D(P^{m}) {T.str(6)}, period "
                   f"{sum(taus, zero).str(10)}")
        else:
            msg = f"not proved: K(X) is not inside X (it sticks out by {over:.3g}; the largest radius of K(X) " \
                  f"{max(float(k.rad()) for k in Kx):.3g})"
        return ShootingResult(ok, msg, cs, radius, Kx, mono, okind, T, D, taus, steps, cpu)


def classify3(A: List[List[Any]]) -> tuple:
    r"""``("hyperbolic" | "undecided", trace, det)`` of an enclosure of a 3 x 3 map's Jacobian.

    With ``p(s) = det(s I - A) = s^3 - T s^2 + S s - D`` (``S`` the second trace): if the
    float eigenvalues of ``mid A`` are real, ``p`` is evaluated in ball arithmetic at ``-1``,
    ``1`` and at points between and beyond them; three proved sign changes, none across
    ``+-1`` (the signs at ``+-1`` proved), prove three real multipliers off the unit circle:
    "hyperbolic" (a saddle). Otherwise "undecided" (a complex pair is not classified)."""
    T = A[0][0] + A[1][1] + A[2][2]
    S = (A[0][0] * A[1][1] - A[0][1] * A[1][0]) + (A[0][0] * A[2][2] - A[0][2] * A[2][0]) + \
        (A[1][1] * A[2][2] - A[1][2] * A[2][1])
    D = (A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) - A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0])
         + A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0]))
    mu = np.linalg.eigvals(np.array([[float(v.mid()) for v in row] for row in A]))
    if np.max(np.abs(mu.imag)) > 0 or np.min(np.abs(np.abs(mu.real) - 1)) < 1e-3:
        return "undecided", T, D
    ev = np.sort(mu.real)
    big = 2 * float(np.max(np.abs(ev))) + 2
    pts = sorted(set([-big, big, -1.0, 1.0] + [float(v) for v in (ev[:-1] + ev[1:]) / 2]))
    signs = []
    for t in pts:
        s = exact_arb(t)
        p = ((s - T) * s + S) * s - D
        if p > 0:
            signs.append(1)
        elif p < 0:
            signs.append(-1)
        else:
            return "undecided", T, D
    changes = sum(1 for a, b in zip(signs, signs[1:]) if a != b)
    return ("hyperbolic" if changes == 3 else "undecided"), T, D
