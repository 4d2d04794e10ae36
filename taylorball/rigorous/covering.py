r"""Covering relations of h-sets for the M||gamma section map (a topological horseshoe).

An **h-set** here is a parallelogram of the Andoyer--Deprit chart ``(l, L/G)`` of the
M||gamma map, ``N = c + B [-1, 1]^2`` with ``B`` an invertible 2 x 2 matrix whose first
column spans the *exit* (unstable) direction; its coordinates are ``q = B^{-1} (p - c)``.
Its *exit edges* are ``q_1 = -1`` (left) and ``q_1 = +1`` (right).

**Covering relation** ``N => M`` for a continuous map ``f`` (Zgliczynski & Gidea, "Covering
relations for multidimensional dynamical systems", J. Differential Equations 202 (2004);
the sufficient conditions for one exit direction, as checked by CAPD's ``covrel``
examples): with ``f_c = c_M o f o c_N^{-1}`` in the sets' coordinates ``(x, y)``,

1. every point of ``f_c(N_c)`` has ``|x| > 1`` or ``|y| < 1`` (the image crosses ``M``
   without touching its entry edges ``|y| = 1, |x| <= 1``);
2. ``f_c`` maps the left exit edge into ``x < -1`` and the right one into ``x > 1`` (or the
   left one into ``x > 1`` and the right one into ``x < -1``).

Both are checked on pieces: ``N``'s coordinate square is cut into ``n_pieces`` strips along
``x``, each cut into ``n_edge`` cells along ``y`` (condition 1 on each), and each exit edge
into ``n_edge`` segments (condition 2 on each); each piece's image is enclosed in ball
arithmetic by :func:`image_coordinates`.

**Enclosing the image of a piece** (:func:`image_coordinates`): the chart points of the piece
``p = c + B q``, ``q`` in a box ``Q`` with midpoint ``q_c``; ``G = |K|`` from the energy
equation by the interval Newton operator (unique in an interval around the candidate's
``G``); the start states by the mean-value form ``x_0(q) \in x_0(q_c) + [D x_0](Q) (q - q_c)``
written as a doubleton set ``c + P q + A r`` (``P = mid [D x_0]`` carries the piece's
coordinates, never wrapped; :class:`~taylorball.rigorous._taylor.LohnerSet`); the validated
flow of that set to ``t_a = tau_guess - delta`` (Lohner's QR method for ``A r``); the crossing
of ``g = 0`` proved unique in ``[t_a, t_a + 2 delta]`` for every state of the set (interval
Newton in time, ``dg/dt > 0``, on ``g = 0`` not ``g = pi``); then, with ``c_a`` the set's
centre at ``t_a`` and ``\hat P(x) = \phi_{\tau(x)}(x)`` the map to the crossing,

.. math:: \mathrm{chart}(\hat P(x)) \in \mathrm{chart}(\hat P(c_a)) + [D(\mathrm{chart} \circ \hat P)]\, (P_a q + A_a r_a),

``[D(chart o P)] = [D chart] (I - f \nabla e^T / (\nabla e, f)) [D\phi]`` enclosed over the
set (one C^1 step), and ``chart(P(c_a))`` from the point ``c_a`` alone (interval Newton for
its crossing time, on its own states). The target's coordinates are ``B_M^{-1} (chart - c_M)``
with ``B_M^{-1}`` enclosed by FLINT and the products ``B_M^{-1} [D] P_a``, ``B_M^{-1} [D] A_a``
formed before they meet ``q`` and ``r_a`` (so the thin set is not wrapped into a box in the
chart).

Like the fixed-point proofs, the map is the local section map near the candidate's return
time ``tau_guess``: the crossing of ``g = 0`` with ``g`` increasing in ``[t_a, t_a + 2 delta]``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any, List, Optional, Sequence, Tuple

import numpy as np

from ..errors import IntegrationError, UsageError
from ._balls import Dual, arb, arb_mat, exact_arb, interval, working_precision
from ._taylor import LohnerSet, default_order, lohner_step
from .enclosure import ball_pars, ball_rhs, integrate_set
from .section import (L_BRANCHES, NotProved, _branch_uv, _event, _mparallel_energy, _newton_root, _unit,
                      isolate_crossing, mparallel_chart_lr, mparallel_start_state, section_projection)

__all__ = ["HSet", "Relation", "RelationResult", "image_coordinates", "check_relation"]


@dataclass(frozen=True)
class HSet:
    r"""``N = center + B [-1, 1]^2`` in the chart ``(l, L/G)``; ``B``'s first column is the
    exit direction. ``l_branch`` (a key of :data:`taylorball.rigorous.section.L_BRANCHES`) is
    the branch on which ``l`` of points near the set is read (``center``'s ``l`` must lie in
    ``l_branch + (-pi/2, pi/2)``); ``G_guess`` the candidate's ``G = |K|`` (it only places the
    interval Newton box of the energy root)."""

    name: str
    center: Tuple[float, float]
    B: Tuple[Tuple[float, float], Tuple[float, float]]
    l_branch: float
    G_guess: float

    def __post_init__(self) -> None:
        if self.l_branch not in L_BRANCHES:
            raise UsageError(f"HSet {self.name!r}: l_branch must be one of 0, pi/2, pi, 3 pi/2, got {self.l_branch!r}")
        B = np.array(self.B, dtype=float)
        if B.shape != (2, 2) or not np.all(np.isfinite(B)) or abs(np.linalg.det(B)) == 0:
            raise UsageError(f"HSet {self.name!r}: B must be an invertible 2 x 2 matrix of finite floats, got {self.B!r}")
        if not abs(self.center[0] - self.l_branch) < math.pi / 2:
            raise UsageError(f"HSet {self.name!r}: the centre's l = {self.center[0]!r} is not in l_branch + (-pi/2, pi/2)")


@dataclass(frozen=True)
class Relation:
    """A covering relation ``source => target`` to check for the section map near return
    time ``tau_guess`` (the source centre's float return time), on ``n_pieces`` strips of the
    source (each cut into ``n_edge`` cells along ``y``) and ``n_edge`` segments per exit
    edge."""

    source: str
    target: str
    tau_guess: float
    n_pieces: int = 1
    n_edge: int = 1


@dataclass
class RelationResult:
    """Outcome of :func:`check_relation`. ``proved`` only if every piece's enclosure meets its
    condition; ``message`` names the first piece that fails and by how much; ``pieces``
    lists ``(what, x, y)`` with the enclosed target coordinates as ``(lo, hi)`` floats."""

    proved: bool
    message: str
    pieces: List[Tuple[str, Tuple[float, float], Tuple[float, float]]] = field(default_factory=list)
    cpu_seconds: float = 0.0


def _lo_hi(b: Any) -> Tuple[float, float]:
    return float(b.lower().mid()), float(b.upper().mid())


def _ball_matrix(M: Sequence[Sequence[float]]) -> Any:
    return arb_mat([[exact_arb(float(v)) for v in row] for row in M])


def image_coordinates(params: Any, levels: Any, N: HSet, M: HSet, Q: Sequence[Any], tau_guess: float, *,
                      prec: int = 53, order: Optional[int] = None, delta: float = 1e-3,
                      wrapping: str = "qr") -> Tuple[Any, Any]:
    r"""Enclose ``c_M(P(c_N^{-1}(Q)))``: the coordinates in the h-set ``M`` of the section map's
    images of the points of ``N`` with coordinates in the box ``Q`` (two arbs inside
    ``[-1, 1]``). Must run inside :class:`~taylorball.rigorous._balls.working_precision`.

    Raises
    ------
    NotProved
        When an inclusion fails (energy root not isolated, crossing not isolated, not on
        ``g = 0``, the image's ``l`` not on ``M``'s branch).
    IntegrationError
        When no validated step is found.
    """
    order = default_order(prec) if order is None else order
    pars = ball_pars("mparallel", params)
    from ..model import get_system

    system = get_system("mparallel")
    cst = system.constants(pars)
    rhs = ball_rhs("mparallel", pars)
    lam, h = exact_arb(levels.lam), exact_arb(levels.h)
    one, zero = exact_arb(1), exact_arb(0)
    c = [exact_arb(v) for v in N.center]
    B = [[exact_arb(v) for v in row] for row in N.B]
    qc = [exact_arb(q.mid()) for q in Q]

    def chart_pt(q: Sequence[Any]) -> Tuple[Any, Any]:
        return (c[0] + B[0][0] * q[0] + B[0][1] * q[1], c[1] + B[1][0] * q[0] + B[1][1] * q[1])

    def G_root(l: Any, rho: Any) -> Any:
        def energy(G: Any) -> Any:
            if isinstance(G, Dual):
                return _mparallel_energy(cst, mparallel_start_state(lam, G, Dual(l, (zero,)), Dual(rho, (zero,)))) - h
            return _mparallel_energy(cst, mparallel_start_state(lam, G, l, rho)) - h

        NG = _newton_root(energy, N.G_guess, (1e-6, 1e-4, 1e-2), "G")
        # a second Newton step from the first image's midpoint, in a box a little wider than
        # that image: the first box is centred on the candidate's G, not on this piece's root
        return _newton_root(energy, float(NG.mid()), (4 * float(NG.rad()) + 1e-14 * abs(float(NG.mid())),
                                                      1e-6, 1e-4, 1e-2), "G")

    # 1. start states: x0(qc) (a point) and [D x0](Q) (duals in q over the piece)
    lc, rc = chart_pt(qc)
    x0c = mparallel_start_state(lam, G_root(lc, rc), lc, rc)
    lQ, rQ = chart_pt(Q)
    NG = G_root(lQ, rQ)
    dl, dr = (B[0][0], B[0][1]), (B[1][0], B[1][1])
    Fg = _mparallel_energy(cst, mparallel_start_state(lam, Dual(NG, (zero, zero, one)), Dual(lQ, (*dl, zero)),
                                                      Dual(rQ, (*dr, zero)))) - h
    dG = (-Fg.g[0] / Fg.g[2], -Fg.g[1] / Fg.g[2])
    x0d = mparallel_start_state(lam, Dual(NG, dG), Dual(lQ, dl), Dual(rQ, dr))
    Dx0 = arb_mat([[x.g[j] for j in range(2)] for x in x0d])
    # 2. the doubleton set c + P q + A r: P = mid [D x0] carries the piece's coordinates
    #    q - q_c exactly; ([D x0] - P)(Q - q_c) and x0(q_c) - c go into r
    n = 6
    P0 = arb_mat([[exact_arb(Dx0[i, j].mid()) for j in range(2)] for i in range(n)])
    dq = [Q[j] - qc[j] for j in range(2)]
    cs = [exact_arb(x.mid()) for x in x0c]
    rm = arb_mat([[x0c[i] - cs[i]] for i in range(n)]) + (Dx0 - P0) * arb_mat([[d] for d in dq])
    eye = arb_mat([[1 if i == j else 0 for j in range(n)] for i in range(n)])
    S0 = LohnerSet(cs, eye, [rm[i, 0] for i in range(n)], P0, dq)
    # 3. the flow to t_a, then the crossing
    t_a = Fraction(tau_guess) - Fraction(delta)
    S_a, _, _, _ = integrate_set(rhs, S0, t_a, prec=prec, order=order, tol=2.0 ** (-prec), wrapping=wrapping)
    ev = _event
    Ns, dGdt = isolate_crossing(rhs, S_a, delta, order)
    s_m = exact_arb(delta)
    cross = lohner_step(rhs, S_a, Ns, order, jac=True)
    if cross is None or cross.jac is None:
        raise NotProved("no validated step to the crossing")
    Xc = cross.box
    kq = L_BRANCHES[M.l_branch]
    if not _branch_uv(Xc[0:3], kq)[1] > 0:
        raise NotProved(f"the image's l is not proved to lie in {M.l_branch!r} + (-pi/2, pi/2)")
    Pi = section_projection(rhs, Xc)
    rd = mparallel_chart_lr([Dual(Xc[i], _unit(n, i)) for i in range(n)], M.l_branch)
    Dch = arb_mat([[rd[a].g[j] for j in range(n)] for a in range(2)])
    # the centre c_a alone: its crossing time by interval Newton, first with dg/dt over the
    # set's step box, then over the centre's own states near the crossing
    ca = list(S_a.c)
    if not all(b.contains(x) for b, x in zip(S_a.box(), ca)):
        raise NotProved("the Lohner set's centre is not in its box")
    Pc = LohnerSet.from_box(ca)
    s1 = s_m
    for _ in range(2):  # coarse: dg/dt enclosed over the set's step box
        st = lohner_step(rhs, Pc, s1, order)
        if st is None:
            raise NotProved("no validated step for the centre's crossing")
        Ns_c = s1 - ev(st.box) / dGdt
        if not Ns.contains(Ns_c):
            raise NotProved("the centre's crossing time left the set's crossing interval")
        s1 = exact_arb(Ns_c.mid())
    for _ in range(2):  # fine: dg/dt over the centre's own states for s in I = s1 +- w
        w = 4 * float(Ns_c.rad()) + 1e-15
        I = s1 + arb(0, w)
        sI, st = lohner_step(rhs, Pc, I, order), lohner_step(rhs, Pc, s1, order)
        if sI is None or st is None:
            raise NotProved("no validated step for the centre's crossing")
        eI = ev([Dual(sI.box[i], _unit(n, i)) for i in range(n)])
        fI = rhs(sI.box)
        dI = sum((eI.g[i] * fI[i] for i in range(n)), zero)
        Nf = s1 - ev(st.box) / dI
        if not I.contains_interior(Nf):
            raise NotProved(f"the centre's crossing time is not isolated in {I.str(5)} (Newton image {Nf.str(5)})")
        Ns_c, s1 = Nf, exact_arb(Nf.mid())
    cp = lohner_step(rhs, Pc, Ns_c, order)
    if cp is None:
        raise NotProved("no validated step to the centre's crossing")
    if not _branch_uv(cp.box[0:3], kq)[1] > 0:
        raise NotProved("the centre's image l is not on the target's branch")
    pc = mparallel_chart_lr(cp.box, M.l_branch)
    # 4. the target's coordinates
    BMinv = _ball_matrix(M.B).inv()
    cM = [exact_arb(v) for v in M.center]
    y0 = BMinv * arb_mat([[pc[0] - cM[0]], [pc[1] - cM[1]]])
    L = ((BMinv * Dch) * Pi) * cross.jac
    rv = arb_mat([[x] for x in S_a.r])
    qv = arb_mat([[x] for x in dq])
    y = y0 + (L * S_a.A) * rv + (L * S_a.P) * qv
    return y[0, 0], y[1, 0]


def _cuts(n: int) -> List[Tuple[Fraction, Fraction]]:
    return [(Fraction(-1) + Fraction(2 * k, n), Fraction(-1) + Fraction(2 * (k + 1), n)) for k in range(n)]


def _iv(a: Fraction, b: Fraction) -> Any:
    return interval(exact_arb(a), exact_arb(b))


def check_relation(params: Any, levels: Any, N: HSet, M: HSet, rel: Relation, *, prec: int = 53,
                   delta: float = 1e-3, fail_fast: bool = True) -> RelationResult:
    """Check the covering relation ``N => M`` (module docstring): condition 1 on ``n_pieces``
    strips of ``N`` (each cut into ``n_edge`` cells), condition 2 on ``n_edge`` segments of
    each exit edge; the orientation
    (left edge to the left or to the right) is taken from the first left segment."""
    for name, v in (("n_pieces", rel.n_pieces), ("n_edge", rel.n_edge)):
        if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= 4096:
            raise UsageError(f"relation {rel.source} => {rel.target}: {name} must be an integer in [1, 4096], got {v!r}")
    cpu0 = time.process_time()
    out: List[Tuple[str, Tuple[float, float], Tuple[float, float]]] = []
    fails: List[str] = []
    with working_precision(prec):
        one = exact_arb(1)
        side = 0
        jobs: List[Tuple[str, Any, Any]] = []
        for sgn, nm in ((-1, "left"), (1, "right")):
            for a, b in _cuts(rel.n_edge):
                jobs.append((f"{nm} edge y in [{float(a):g}, {float(b):g}]", exact_arb(sgn), _iv(a, b)))
        for a, b in _cuts(rel.n_pieces):
            for c, d in _cuts(rel.n_edge):
                jobs.append((f"strip x in [{float(a):g}, {float(b):g}], y in [{float(c):g}, {float(d):g}]",
                             _iv(a, b), _iv(c, d)))
        for what, qx, qy in jobs:
            try:
                x, y = image_coordinates(params, levels, N, M, [qx, qy], rel.tau_guess, prec=prec, delta=delta)
            except (NotProved, IntegrationError) as exc:
                fails.append(f"{what}: {exc}")
                if fail_fast:
                    break
                continue
            out.append((what, _lo_hi(x), _lo_hi(y)))
            if what.startswith("strip"):
                ok = bool(abs(x) > one) or bool(abs(y) < one)
                if not ok:
                    fails.append(f"{what}: the image touches the entry edges (x in [{x.str(5)}], y in [{y.str(5)}]; "
                                 f"|y| < 1 misses by {float((abs(y) - one).upper().mid()):.3g})")
            else:
                want = -1 if what.startswith("left") else 1
                if side == 0:
                    side = 1 if bool(x < -one) else (-1 if bool(x > one) else 0)
                    if side == 0:
                        fails.append(f"{what}: the image is not beyond an exit edge of {M.name} (x in [{x.str(5)}])")
                elif not ((side * want < 0 and bool(x < -one)) or (side * want > 0 and bool(x > one))):
                    fails.append(f"{what}: the image is not beyond the exit edge of {M.name} on the required side "
                                 f"(x in [{x.str(5)}])")
            if fails and fail_fast:
                break
    cpu = time.process_time() - cpu0
    if fails:
        return RelationResult(False, f"not proved: {N.name} => {M.name}: {fails[0]}", out, cpu)
    return RelationResult(True, f"proved: {N.name} => {M.name} ({len(out)} pieces)", out, cpu)
