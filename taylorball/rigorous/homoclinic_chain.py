r"""A transversal homoclinic point by a chain of covering relations with cone conditions.

The one-piece proof of :mod:`taylorball.rigorous.homoclinic` carries the whole arc of the
local unstable manifold through all iterates as one affine set, and the C^1 enclosure over
its growing hull loses the sign after a few iterates. Here (Wilczak & Zgliczynski, Comm.
Math. Phys. 234 (2003); Zgliczynski, J. Differential Equations 246 (2009)) the orbit is
followed by a chain of small h-sets

.. math:: N_i = c_i + T_i \left([-a_i, a_i] \times [-b_i, b_i]\right), \qquad i = 0, \dots, n,

one covering relation ``N_i => N_{i+1}`` per iterate, each checked on its own small set, so
the enclosures do not grow along the chain. ``N_0`` is the h-set of a proved local unstable
manifold (:func:`~taylorball.rigorous.homoclinic.local_unstable_manifold`: ``W^u_{N_0}`` is the
graph over ``u`` of a ``1/c``-Lipschitz function).

**One relation** (:func:`check_relation`), all in ball arithmetic. In the scaled coordinates
``x = (u/a_i, s/b_i)`` of ``N_i`` and ``y`` of ``N_{i+1}``, with ``S_i = diag(a_i, b_i)``,

.. math:: y \in d + B x, \quad d = S_{i+1}^{-1} T_{i+1}^{-1} (f(c_i) - c_{i+1}), \quad
          B = S_{i+1}^{-1} T_{i+1}^{-1} [Df](N_i) T_i S_i,

for ``x`` in ``[-1, 1]^2`` (the mean value theorem; ``f(c_i)`` is enclosed from the point
``c_i`` alone, ``[Df](N_i)`` over the box hull of ``N_i``, which is convex and contains it).
Checked:

* *covering* ``N_i => N_{i+1}`` (Zgliczynski & Gidea, J. Differential Equations 202 (2004),
  the sufficient conditions for one exit direction, either orientation): the exit edges
  ``x_1 = -1`` and ``x_1 = 1`` map into ``y_1 < -1`` and ``y_1 > 1`` (or ``> 1`` and ``< -1``:
  a negative multiplier swaps them), and the whole image has ``|y_2| < 1``;
* *cone condition* with ``Q_i(x) = x_1^2 - g_i^2 x_2^2``: ``B^T Q_{i+1} B - Q_i`` positive
  definite for every matrix in ``B`` (``m11 > 0`` and ``det > 0`` of the interval matrix).

**The chain's conclusion** (:func:`check_end` and the argument in docs/rigorous.md). A
*horizontal disc* of ``N_i`` is a continuous curve in ``N_i`` joining its two exit edges on
which ``Q_i(x - x') >= 0`` for any two points. ``W^u_{N_0}`` is one if ``g_0 <= c b_0 / a_0``
(its slope ``|ds/du| <= 1/c`` is ``<= 1/g_0`` in scaled coordinates; checked). If ``D`` is a
horizontal disc of ``N_i``, its image crosses ``N_{i+1}`` from one exit edge to the other
inside ``|y_2| < 1`` (covering), so ``f(D) \cap N_{i+1}`` contains a connected arc joining
the exit edges, and on it ``Q_{i+1}(f(x) - f(x')) > Q_i(x - x') >= 0`` (cone): a horizontal
disc of ``N_{i+1}``. By induction ``f^n(W^u_{N_0}) \supset D_n``, a horizontal disc of
``N_n`` in ``W^u(p)``. At the end (``R`` a linear reversor, ``l_-`` a nonzero row of
``(I - R)/2``, ``l_+`` one of ``(I + R)/2``):

* *existence*: ``l_-`` has opposite signs on the two exit edges of ``N_n`` (each enclosed as
  a whole segment), so the connected ``D_n`` meets ``Fix(R) = {l_- = 0}`` at some ``q``:
  ``q \in W^u(p)`` and ``q = R q \in R W^u(p) = W^s(R p) = W^s(p)`` (``R p = p`` is part of the
  local manifold's proof);
* *transversality*: every tangent of ``D_n`` lies in the closed cone
  ``{T_n S_n (1, t) : |t| <= 1/g_n}`` (limits of chords), and ``l_+`` and ``l_-`` are proved
  nonzero on it: the tangent ``w`` of ``W^u`` at ``q`` is on neither eigen-line of ``R``, so it
  and ``R w``, the tangent of ``W^s = R W^u`` at ``q``, are independent.

The float64 design of a chain (centres on a pseudo-orbit, ``T_i``'s columns the tangents of
``W^u`` carried forward and of ``W^s`` carried backward) is not part of the proof; for the
Henon map and for Tzenoff's case it is in :mod:`taylorball.rigorous.homoclinic_chain_design`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Sequence, Tuple

from ..errors import UsageError
from ._balls import arb_mat, exact_arb, interval
from .homoclinic import BallMap, Frame, reversor_forms

__all__ = ["ChainSet", "RelationCheck", "check_relation", "check_start", "check_end", "EndCheck",
           "prove_chain", "ChainResult"]


@dataclass(frozen=True)
class ChainSet:
    """The h-set ``center + T ([-a, a] x [-b, b])`` (``T``'s first column the exit direction)
    with the cone constant ``g`` of ``Q(x) = x_1^2 - g^2 x_2^2`` in its scaled coordinates
    ``x = (u/a, s/b)``; every number an exact float."""

    center: Tuple[float, float]
    T: Tuple[Tuple[float, float], Tuple[float, float]]
    a: float
    b: float
    g: float

    def __post_init__(self) -> None:
        for name, v in (("a", self.a), ("b", self.b), ("g", self.g)):
            if not (isinstance(v, float) and 0 < v < math.inf):
                raise UsageError(f"ChainSet: {name} must be a finite float > 0, got {v!r}")
        vals = [*self.center, *self.T[0], *self.T[1]]
        if len(self.center) != 2 or len(self.T) != 2 or any(len(r) != 2 for r in self.T) or not all(
                isinstance(v, float) and math.isfinite(v) for v in vals):
            raise UsageError(f"ChainSet: center must be 2 finite floats and T 2 x 2 finite floats, got {self!r}")
        if not abs(self.T[0][0] * self.T[1][1] - self.T[0][1] * self.T[1][0]) > 0:
            raise UsageError(f"ChainSet: T must be invertible, got {self.T!r}")

    @property
    def frame(self) -> Frame:
        return Frame(self.center, self.T)

    def scaled(self) -> Tuple[List[Any], Any, Any]:
        """``(c, T S, (T S)^{-1})`` as balls, ``S = diag(a, b)``."""
        c, T, _ = self.frame.balls()
        A_, B_ = exact_arb(self.a), exact_arb(self.b)
        TS = arb_mat([[T[0, 0] * A_, T[0, 1] * B_], [T[1, 0] * A_, T[1, 1] * B_]])
        return c, TS, TS.inv()

    def hull(self) -> List[Any]:
        """The chart box hull of the set."""
        return self.frame.box(interval(-self.a, self.a), interval(-self.b, self.b))

    def as_json(self) -> Dict[str, Any]:
        return {"center": [v.hex() for v in self.center], "T": [[v.hex() for v in r] for r in self.T],
                "a": self.a.hex(), "b": self.b.hex(), "g": self.g.hex()}

    @staticmethod
    def from_json(d: Dict[str, Any]) -> "ChainSet":
        try:
            fx = float.fromhex
            return ChainSet((fx(d["center"][0]), fx(d["center"][1])),
                            ((fx(d["T"][0][0]), fx(d["T"][0][1])), (fx(d["T"][1][0]), fx(d["T"][1][1]))),
                            fx(d["a"]), fx(d["b"]), fx(d["g"]))
        except (KeyError, IndexError, TypeError, ValueError) as exc:
            raise UsageError(f"a chain set must be {{center, T, a, b, g}} as float.hex strings, got {d!r} "
                             f"({exc})") from None


def _iv(x: Any) -> str:
    """``[lo, hi]`` of a ball (arb's own ``str`` shows a ball near 0 as ``[+/- r]``)."""
    lo, hi = _lohi(x)
    return f"[{lo:.5g}, {hi:.5g}]"


def _lohi(x: Any) -> List[float]:
    return [float(x.lower().mid()), float(x.upper().mid())]


@dataclass
class RelationCheck:
    """Outcome of :func:`check_relation`: ``ok`` only if the covering and the cone condition
    hold. ``margins``: lower bounds of ``|y_1| - 1`` on the exit edges (``exit``),
    ``1 - |y_2|`` on the image (``entry``), and of ``m11`` and ``det`` of the cone matrix;
    ``orientation`` +1 when the left exit edge maps to the left, -1 when to the right."""

    ok: bool
    message: str
    orientation: int = 0
    margins: Dict[str, float] = field(default_factory=dict)
    enclosures: Dict[str, List[float]] = field(default_factory=dict)
    cpu_seconds: float = 0.0


def check_relation(f: BallMap, k: Optional[int], N: ChainSet, M: ChainSet) -> RelationCheck:
    """Check ``N => M`` for ``f`` (application ``k`` along the orbit) with the cone condition
    ``B^T Q_M B - Q_N > 0`` (module docstring). Must run inside
    :class:`~taylorball.rigorous._balls.working_precision`."""
    cpu0 = time.process_time()
    cN, TSN, _ = N.scaled()
    cM, _, TSMi = M.scaled()
    fc = f.image(list(cN), k)
    _, J = f.c1(N.hull(), k)
    dv = [fc[0] - cM[0], fc[1] - cM[1]]
    d = [TSMi[i, 0] * dv[0] + TSMi[i, 1] * dv[1] for i in range(2)]
    JT = [[J[i][0] * TSN[0, j] + J[i][1] * TSN[1, j] for j in range(2)] for i in range(2)]
    B = [[TSMi[i, 0] * JT[0][j] + TSMi[i, 1] * JT[1][j] for j in range(2)] for i in range(2)]
    one, I1 = exact_arb(1), interval(-1, 1)
    left = d[0] - B[0][0] + B[0][1] * I1
    right = d[0] + B[0][0] + B[0][1] * I1
    s_img = d[1] + B[1][0] * I1 + B[1][1] * I1
    g2N, g2M = exact_arb(N.g) ** 2, exact_arb(M.g) ** 2
    m11 = B[0][0] * B[0][0] - g2M * B[1][0] * B[1][0] - one
    m22 = B[0][1] * B[0][1] - g2M * B[1][1] * B[1][1] + g2N
    m12 = B[0][0] * B[0][1] - g2M * B[1][0] * B[1][1]
    det = m11 * m22 - m12 * m12
    res = RelationCheck(False, "", enclosures={"d": _lohi(d[0]) + _lohi(d[1]),
                                               "B": [v for r in B for x in r for v in _lohi(x)],
                                               "left": _lohi(left), "right": _lohi(right), "s": _lohi(s_img)})
    res.margins = {"exit": float(min((abs(left) - one).lower(), (abs(right) - one).lower())),
                   "entry": float((one - abs(s_img)).lower()), "m11": float(m11.lower()), "det": float(det.lower())}
    res.cpu_seconds = time.process_time() - cpu0
    if left < -one and right > one:
        res.orientation = 1
    elif left > one and right < -one:
        res.orientation = -1
    else:
        res.message = (f"not proved: the exit edges' images are not beyond opposite exit edges (y1 on the left edge "
                       f"{_iv(left)}, on the right edge {_iv(right)}; needs |y1| > 1 with opposite signs)")
        return res
    if not abs(s_img) < one:
        res.message = f"not proved: the image reaches |y2| >= 1 (y2 in {_iv(s_img)}): it touches the entry edges"
        return res
    if not (m11 > 0 and det > 0):
        res.message = (f"not proved: the cone condition fails (B^T Q_M B - Q_N: m11 in {_iv(m11)}, det in "
                       f"{_iv(det)}; g_N = {N.g:g}, g_M = {M.g:g})")
        return res
    res.ok = True
    res.message = (f"proved: covering (orientation {res.orientation:+d}, exit margin {res.margins['exit']:.3g}, "
                   f"entry margin {res.margins['entry']:.3g}) and cone condition (m11 >= {res.margins['m11']:.3g})")
    return res


def check_start(N0: ChainSet, frame: Frame, a: float, b: float, c: float) -> Tuple[bool, str]:
    """``N_0`` is the proved local h-set ``frame +- (a, b)`` (same centre, ``T``, ``a``, ``b``)
    and ``W^u_{N_0}`` (slope ``<= 1/c`` in ``frame``'s coordinates) is a horizontal disc for
    ``Q_0``: ``g_0 <= c b / a``, checked in exact rational arithmetic."""
    from fractions import Fraction

    if N0.center != tuple(frame.center) or N0.T != tuple(tuple(r) for r in frame.T) or (N0.a, N0.b) != (a, b):
        return False, (f"not proved: N_0 is not the proved local h-set (centre {N0.center} vs {frame.center}, "
                       f"T {N0.T} vs {frame.T}, a, b = {N0.a:g}, {N0.b:g} vs {a:g}, {b:g})")
    if not Fraction(N0.g) <= Fraction(c) * Fraction(b) / Fraction(a):
        return False, f"not proved: g_0 = {N0.g:g} > c b/a = {c * b / a:g}: W^u_N0 is not a horizontal disc of N_0"
    return True, f"N_0 is the proved local h-set and W^u_N0 (slope <= 1/{c:g}) is a horizontal disc for g_0 = {N0.g:g}"


@dataclass
class EndCheck:
    """Outcome of :func:`check_end`: ``sides`` the signs of ``l_-`` on the left and right exit
    edges of ``N_n``, ``l_plus``/``l_minus`` the enclosures on the tangent cone."""

    ok: bool
    message: str
    sides: Tuple[int, int] = (0, 0)
    l_plus: str = ""
    l_minus: str = ""


def check_end(Nn: ChainSet, reversor: Sequence[Sequence[int]]) -> EndCheck:
    """Existence and transversality at the end of the chain (module docstring). Must run
    inside :class:`~taylorball.rigorous._balls.working_precision`."""
    lp, lm = reversor_forms(reversor)
    c, TS, _ = Nn.scaled()
    I1 = interval(-1, 1)

    def lmin(x1: Any, x2: Any) -> Any:  # l_-(c + T S x), each x_j entering once
        return ((lm[0] * c[0] + lm[1] * c[1]) + (lm[0] * TS[0, 0] + lm[1] * TS[1, 0]) * x1
                + (lm[0] * TS[0, 1] + lm[1] * TS[1, 1]) * x2)

    one = exact_arb(1)
    vl, vr = lmin(-one, I1), lmin(one, I1)
    side = lambda v: 1 if v > 0 else (-1 if v < 0 else 0)  # noqa: E731
    sides = (side(vl), side(vr))
    if not sides[0] * sides[1] == -1:
        return EndCheck(False, f"not proved: the exit edges of N_n are not on opposite sides of Fix(R) "
                               f"(l_- on them {_iv(vl)}, {_iv(vr)})", sides)
    t = interval(-1.0 / Nn.g, 1.0 / Nn.g)
    # l(w) = l(col_0) + l(col_1) t for w = T S (1, t): t enters once (no dependency loss)
    form = lambda l: (l[0] * TS[0, 0] + l[1] * TS[1, 0]) + (l[0] * TS[0, 1] + l[1] * TS[1, 1]) * t  # noqa: E731
    ap, am = form(lp), form(lm)
    if not (side(ap) != 0 and side(am) != 0):
        return EndCheck(False, f"not proved: the tangent cone of N_n meets an eigen-line of R (l_+ {_iv(ap)}, "
                               f"l_- {_iv(am)})", sides, _iv(ap), _iv(am))
    return EndCheck(True, f"the exit edges of N_n lie on opposite sides of Fix(R) and its tangent cone meets neither "
                          f"eigen-line of R (l_+ in {_iv(ap)}, l_- in {_iv(am)})", sides, _iv(ap), _iv(am))


@dataclass
class ChainResult:
    """Outcome of :func:`prove_chain`: ``proved`` only if the start, every relation and the
    end check; ``relations`` the per-relation records in order (up to the first failure)."""

    proved: bool
    message: str
    relations: List[RelationCheck]
    end: Optional[EndCheck]
    cpu_seconds: float


def prove_chain(f: BallMap, sets: Sequence[ChainSet], reversor: Sequence[Sequence[int]], *,
                local: Tuple[Frame, float, float, float], fail_fast: bool = True) -> ChainResult:
    """Check the whole chain in this process: :func:`check_start` against the proved local
    h-set ``local = (frame, a, b, c)``, the relations ``sets[i] => sets[i+1]`` (application
    ``k = i``; ``k = None`` for ``i = 0``, the map near the fixed point) and :func:`check_end`.
    The local manifold itself is proved separately (its certificate). Must run inside
    :class:`~taylorball.rigorous._balls.working_precision`."""
    cpu0 = time.process_time()
    if len(sets) < 2:
        raise UsageError(f"a chain needs at least 2 h-sets, got {len(sets)}")
    reversor_forms(reversor)
    ok, msg = check_start(sets[0], *local)
    if not ok:
        return ChainResult(False, f"start: {msg}", [], None, time.process_time() - cpu0)
    recs: List[RelationCheck] = []
    failed = []
    for i in range(len(sets) - 1):
        r = check_relation(f, None if i == 0 else i, sets[i], sets[i + 1])
        recs.append(r)
        if not r.ok:
            failed.append(f"relation {i} => {i + 1}: {r.message}")
            if fail_fast:
                break
    end = check_end(sets[-1], reversor)
    cpu = time.process_time() - cpu0
    if failed:
        return ChainResult(False, failed[0], recs, end, cpu)
    if not end.ok:
        return ChainResult(False, f"end: {end.message}", recs, end, cpu)
    return ChainResult(True, f"proved: {len(recs)} covering relations with cone conditions from the local unstable "
                             f"manifold to N_{len(sets) - 1}; {end.message}", recs, end, cpu)
