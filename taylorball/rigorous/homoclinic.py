r"""Transversal homoclinic points of a reversible planar map, proved by cone conditions.

The chain of the proof (all in ball arithmetic; the floating-point search that proposes the
numbers is not part of it), for a C^1 map ``f`` of the plane with a reversor ``R`` (a linear
involution with ``R f R = f^{-1}``) and a hyperbolic fixed point ``p``:

1. **Local unstable manifold** (:func:`local_unstable_manifold`). An h-set
   ``N = {c + T (u, s) : |u| <= a, |s| <= b}`` (``c`` a centre near ``p``, the columns of ``T``
   near the unstable and stable eigenvectors, all exact floats) and the quadratic form
   ``Q(u, s) = u^2 - c_Q^2 s^2``. With ``A = T^{-1} [Df](N) T`` (an interval matrix containing
   ``Df`` on the box hull of ``N``) and ``d = T^{-1} (f(c) - c)``, the mean value theorem gives
   ``f(c + T q) \in c + T (d + A q)`` for ``q`` in ``N``'s coordinates. Checked:

   * *covering* ``N => N`` (Zgliczynski & Gidea, J. Differential Equations 202 (2004), the
     sufficient conditions for one exit direction): the images of the exit edges ``u = -a``
     and ``u = a`` lie in ``|u| > a`` on opposite sides, and the whole image has ``|s| < b``;
   * *cone condition* (Zgliczynski, "Covering relations, cone conditions and the stable
     manifold theorem", J. Differential Equations 246 (2009)): ``A^T Q A - Q`` positive definite
     for every matrix in ``A`` (so ``Q(f(x) - f(y)) > Q(x - y)`` for ``x != y`` in ``N``);
   * *expansion in the cone*: ``lambda = min |A_11| - max |A_12| / c_Q > 1``.

   Then ``f`` has exactly one fixed point ``p`` in ``N`` (covering: a fixed point; cone: at
   most one), and the set ``W^u_N`` of points of ``N`` with a full backward orbit in ``N`` is
   the graph ``{c + T (u, w(u)) : |u| <= a}`` of a function with ``|w| <= b`` and
   ``|w(u) - w(u')| <= |u - u'| / c_Q``; every point of it tends to ``p`` under ``f^{-1}``, so
   it is a piece of ``W^u(p)`` (docs/rigorous.md gives the argument).

2. **Sign change** (:func:`sign_change`). For ``u_1 < u_2`` in ``[-a, a]``, the vertical
   segments ``{u_i} x [-b, b]`` contain the points of ``W^u_N`` over ``u_i``. If ``f^n`` of the
   two segments is enclosed on opposite sides of ``Fix(R) = {l_-(x) = 0}`` (``l_-`` a nonzero
   row of ``(I - R)/2``), the image of the connected arc of ``W^u_N`` between them meets
   ``Fix(R)`` at some ``q``: ``q \in W^u(p)`` and ``q = R q \in R W^u(p) = W^s(R p)``; and
   ``R p = p`` is proved (``R p`` is a fixed point of ``f``; it is checked to lie in ``N``,
   where the fixed point is unique). So ``q`` is a homoclinic point of ``p``.

3. **Transversality** (:func:`transversality`). The tangents of ``W^u_N`` lie in the cone
   ``{T (1, sigma) : |sigma| <= 1/c_Q}`` (limits of chords). The arc ``[u_1, u_2]`` is cut into
   pieces; a piece whose image under ``f^n`` is enclosed off ``Fix(R)`` holds no such ``q``;
   on every other piece ``[Df^n]`` (the product of the steps' interval Jacobians over the
   chained boxes) maps the cone to vectors ``w`` with ``l_+(w) != 0`` and ``l_-(w) != 0``
   (``l_+`` a nonzero row of ``(I + R)/2``): the tangent ``w`` of ``W^u`` at ``q`` is an
   eigenvector of neither eigen-direction of ``R``, so it differs from ``R w``, the tangent of
   ``W^s = R W^u`` at ``q``: the intersection is transversal.

The maps: :class:`HenonMap` (the area-preserving Henon map, a known answer for the tests)
and :class:`SectionBallMap` (the 2D section map of the dynamically symmetric ball,
:func:`taylorball.rigorous.section.section_map`; one return-time guess per iterate).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any, Dict, List, Optional, Protocol, Sequence, Tuple

from ..errors import UsageError
from ._balls import arb, arb_mat, exact_arb, hull, interval

__all__ = ["BallMap", "HenonMap", "SectionBallMap", "Frame", "ManifoldResult", "local_unstable_manifold",
           "sign_change", "transversality", "HomoclinicResult", "prove_homoclinic_point", "reversor_forms"]

Box = List[Any]
Mat = List[List[Any]]


class BallMap(Protocol):
    """A C^1 map of the plane enclosed in ball arithmetic. ``k``: which application along
    the orbit (``None``: the map near the fixed point); a map that is the same everywhere
    ignores it."""

    def image(self, box: Sequence[Any], k: Optional[int]) -> Box:
        """An enclosure of ``f(box)``."""
        ...

    def c1(self, box: Sequence[Any], k: Optional[int]) -> Tuple[Box, Mat]:
        """An enclosure of ``f(box)`` and of ``Df`` over ``box``."""
        ...


@dataclass(frozen=True)
class HenonMap:
    r"""``f(x, y) = (y, -x + t y + y^2)``: area preserving, reversible with ``R(x, y) = (y, x)``
    (``R f R = f^{-1}``), a saddle at the origin for ``t > 2`` (multipliers
    ``lambda + 1/lambda = t``). ``t`` exact (a Fraction)."""

    t: Fraction

    def image(self, box: Sequence[Any], k: Optional[int] = None) -> Box:
        x, y = box
        return [y, -x + exact_arb(self.t) * y + y * y]

    def c1(self, box: Sequence[Any], k: Optional[int] = None) -> Tuple[Box, Mat]:
        x, y = box
        zero, one = exact_arb(0), exact_arb(1)
        return self.image(box), [[zero, one], [-one, exact_arb(self.t) + 2 * y]]


@dataclass
class SectionBallMap:
    r"""The symmetric ball's 2D section map of ``(r1, r2)``
    (:func:`taylorball.rigorous.section.section_map`): near the fixed point with the energy
    root ``K_local`` and return time ``tau_local``; application ``k`` along the orbit with
    ``K_guesses[k]``, ``tau_guesses[k]`` (each a local return map near that time, its
    crossing proved unique in ``tau +- delta``). ``start``: the start set of
    :func:`~taylorball.rigorous.section.section_map` (``"box"`` or ``"doubleton"``)."""

    params: Any
    levels: Any
    K_local: float
    tau_local: float
    K_guesses: Sequence[float] = field(default_factory=list)
    tau_guesses: Sequence[float] = field(default_factory=list)
    prec: int = 128
    order: Optional[int] = None
    delta: float = 1e-3
    steps: int = 0
    start: str = "box"

    def _guess(self, k: Optional[int]) -> Tuple[float, float]:
        if k is None:
            return self.K_local, self.tau_local
        return float(self.K_guesses[k]), float(self.tau_guesses[k])

    def _run(self, box: Sequence[Any], k: Optional[int], jac: bool) -> Any:
        from .section import section_map

        K, tau = self._guess(k)
        se = section_map(self.params, self.levels, list(box), K, tau, prec=self.prec, order=self.order,
                         delta=self.delta, jac=jac, start=self.start)
        self.steps += se.steps
        return se

    def image(self, box: Sequence[Any], k: Optional[int]) -> Box:
        return list(self._run(box, k, False).P)

    def c1(self, box: Sequence[Any], k: Optional[int]) -> Tuple[Box, Mat]:
        se = self._run(box, k, True)
        return list(se.P), [list(r) for r in se.DP]


@dataclass(frozen=True)
class Frame:
    """Coordinates ``x = center + T q`` (``q = (u, s)``), ``T``'s first column the unstable
    direction; every number an exact float."""

    center: Tuple[float, float]
    T: Tuple[Tuple[float, float], Tuple[float, float]]

    def balls(self) -> Tuple[Box, Any, Any]:
        c = [exact_arb(v) for v in self.center]
        T = arb_mat([[exact_arb(v) for v in row] for row in self.T])
        return c, T, T.inv()

    def box(self, u: Any, s: Any) -> Box:
        """The chart box hull of ``center + T (u, s)`` for balls ``u, s``."""
        c, T, _ = self.balls()
        return [c[i] + T[i, 0] * u + T[i, 1] * s for i in range(2)]

    def coords(self, x: Sequence[Any]) -> Box:
        """``T^{-1} (x - center)`` enclosed."""
        c, _, Ti = self.balls()
        d = [x[0] - c[0], x[1] - c[1]]
        return [Ti[i, 0] * d[0] + Ti[i, 1] * d[1] for i in range(2)]


def _check_frame(frame: Frame, a: float, b: float, cq: float) -> None:
    for name, v in (("a", a), ("b", b), ("c", cq)):
        if not (isinstance(v, float) and v > 0 and v < float("inf")):
            raise UsageError(f"{name} must be a float > 0, got {v!r}")
    if len(frame.center) != 2 or len(frame.T) != 2 or any(len(r) != 2 for r in frame.T):
        raise UsageError(f"the frame needs a centre (2 floats) and T (2 x 2 floats), got {frame!r}")
    det = frame.T[0][0] * frame.T[1][1] - frame.T[0][1] * frame.T[1][0]
    if not abs(det) > 0:
        raise UsageError(f"the frame's T must be invertible, got {frame.T!r}")


def _matmul(A: Mat, B: Mat) -> Mat:
    return [[A[i][0] * B[0][j] + A[i][1] * B[1][j] for j in range(2)] for i in range(2)]


def _in_frame(frame: Frame, J: Mat) -> Mat:
    """``T^{-1} J T`` (balls)."""
    _, T, Ti = frame.balls()
    Tl = [[T[i, j] for j in range(2)] for i in range(2)]
    Til = [[Ti[i, j] for j in range(2)] for i in range(2)]
    return _matmul(_matmul(Til, J), Tl)


def reversor_forms(R: Sequence[Sequence[int]]) -> Tuple[Tuple[Any, Any], Tuple[Any, Any]]:
    r"""``(l_plus, l_minus)``: nonzero rows of ``(I + R)/2`` and ``(I - R)/2`` for a linear
    involution ``R != +-I`` (integer entries); ``Fix(R) = {l_minus = 0}``, ``R``'s
    ``-1`` eigen-line is ``{l_plus = 0}``."""
    Rm = [[int(v) for v in row] for row in R]
    if len(Rm) != 2 or any(len(r) != 2 for r in Rm):
        raise UsageError(f"the reversor must be a 2 x 2 integer matrix, got {R!r}")
    sq = [[sum(Rm[i][k] * Rm[k][j] for k in range(2)) for j in range(2)] for i in range(2)]
    if sq != [[1, 0], [0, 1]] or Rm in ([[1, 0], [0, 1]], [[-1, 0], [0, -1]]):
        raise UsageError(f"the reversor must be a linear involution other than +-I, got {R!r}")
    out = []
    for sign in (1, -1):
        M = [[Fraction((1 if i == j else 0) + sign * Rm[i][j], 2) for j in range(2)] for i in range(2)]
        row = M[0] if any(M[0]) else M[1]
        out.append((exact_arb(row[0]), exact_arb(row[1])))
    return out[0], out[1]


def _form(l: Tuple[Any, Any], x: Sequence[Any]) -> Any:
    return l[0] * x[0] + l[1] * x[1]


def _sign(x: Any) -> int:
    return 1 if x > 0 else (-1 if x < 0 else 0)


@dataclass
class ManifoldResult:
    """Outcome of :func:`local_unstable_manifold`; ``ok`` only if every condition holds."""

    ok: bool
    message: str
    A: Mat
    d: Box
    expansion: Optional[Any] = None
    cone_det: Optional[Any] = None
    fixed_point: Optional[Box] = None
    margins: Dict[str, float] = field(default_factory=dict)


def local_unstable_manifold(f: BallMap, frame: Frame, a: float, b: float, cq: float, *,
                            reversor: Optional[Sequence[Sequence[int]]] = None) -> ManifoldResult:
    r"""Check the covering ``N => N``, the cone condition for ``Q = u^2 - c_Q^2 s^2`` and the
    expansion in the cone on ``N = frame(|u| <= a, |s| <= b)`` (module docstring, step 1).
    Must run inside :class:`~taylorball.rigorous._balls.working_precision`.

    ``reversor``: also prove ``R p = p`` (``R p`` lies in ``N``, where the fixed point is
    unique; ``R f R = f^{-1}`` is the caller's lemma). The fixed point is enclosed by
    ``q_p \in (I - A)^{-1} d`` (``p - c = (I - A_p)^{-1} d`` for some ``A_p`` in ``A``)."""
    _check_frame(frame, a, b, cq)
    A_, B_, C_ = exact_arb(a), exact_arb(b), exact_arb(cq)
    X = frame.box(interval(-a, a), interval(-b, b))  # the box hull of N
    fc = f.image([exact_arb(v) for v in frame.center], None)
    _, J = f.c1(X, None)
    A = _in_frame(frame, J)
    d = frame.coords(fc)
    res = ManifoldResult(False, "", A, d)
    Ib = interval(-b, b)
    # covering: exit edges to opposite sides outside |u| <= a, the whole image inside |s| < b
    left = d[0] + A[0][0] * (-A_) + A[0][1] * Ib
    right = d[0] + A[0][0] * A_ + A[0][1] * Ib
    if not ((left < -A_ and right > A_) or (left > A_ and right < -A_)):
        res.message = (f"not proved: the exit edges' images are not on opposite sides outside |u| <= a "
                       f"(u' on the left edge {left.str(5)}, on the right edge {right.str(5)}, a = {a:g})")
        return res
    s_img = d[1] + A[1][0] * interval(-a, a) + A[1][1] * Ib
    if not abs(s_img) < B_:
        res.message = (f"not proved: the image of N reaches |s| >= b (s' in {s_img.str(5)}, b = {b:g}): "
                       "no covering N => N")
        return res
    # cone condition: M = A^T Q A - Q positive definite, Q = diag(1, -c^2)
    c2 = C_ * C_
    m11 = A[0][0] * A[0][0] - c2 * A[1][0] * A[1][0] - 1
    m22 = A[0][1] * A[0][1] - c2 * A[1][1] * A[1][1] + c2
    m12 = A[0][0] * A[0][1] - c2 * A[1][0] * A[1][1]
    det = m11 * m22 - m12 * m12
    res.cone_det = det
    if not (m11 > 0 and det > 0):
        res.message = (f"not proved: the cone condition fails (A^T Q A - Q: m11 in {m11.str(5)}, "
                       f"det in {det.str(5)}; c = {cq:g})")
        return res
    lam = abs(A[0][0]).lower() - abs(A[0][1]).upper() / C_
    res.expansion = lam
    if not lam > 1:
        res.message = f"not proved: the expansion in the cone is not > 1 (|A11| - |A12|/c >= {lam.str(5)})"
        return res
    one, zero = exact_arb(1), exact_arb(0)
    IA = arb_mat([[(one if i == j else zero) - A[i][j] for j in range(2)] for i in range(2)])
    try:
        IAi = IA.inv()
    except ZeroDivisionError:
        res.message = "not proved: I - A is not proved invertible (no enclosure of the fixed point)"
        return res
    qp = [IAi[i, 0] * d[0] + IAi[i, 1] * d[1] for i in range(2)]
    res.fixed_point = frame.box(qp[0], qp[1])
    res.margins = {"exit": float(min((abs(left) - A_).lower(), (abs(right) - A_).lower())),
                   "entry": float((B_ - abs(s_img)).lower())}
    if reversor is not None:
        Rm = [[exact_arb(int(v)) for v in row] for row in reversor]
        Rp = [Rm[i][0] * res.fixed_point[0] + Rm[i][1] * res.fixed_point[1] for i in range(2)]
        qr = frame.coords(Rp)
        if not (abs(qr[0]) < A_ and abs(qr[1]) < B_):
            res.message = (f"not proved: R p is not proved to lie in N (its coordinates {qr[0].str(5)}, "
                           f"{qr[1].str(5)}), so R p = p is not proved")
            return res
    res.ok = True
    res.message = (f"proved: covering N => N, cone condition (c = {cq:g}), expansion in the cone >= "
                   f"{float(lam.lower()):.6g}; a unique fixed point in N, W^u_N the graph of a "
                   f"1/c-Lipschitz function over |u| <= {a:g}")
    return res


def _chain(f: BallMap, U: Any, S: Any, frame: Frame, n: int) -> Tuple[Box, Any, List[Mat]]:
    """``f^n`` of the frame set ``{center + T (u, s) : u in U, s in S}`` as an affine set
    ``x + M r`` (``r`` in ``[-1, 1]^2``, ``M`` an interval matrix, never wrapped into a box):
    a step maps it to ``f(x) + [Df](hull) M r`` (mean value theorem; ``hull`` the box of
    ``x + M r``). Returns ``(x, M, [the steps' Jacobians])``."""
    c, T, _ = frame.balls()
    um, ur = exact_arb(U.mid()), exact_arb(_rad_up(U))
    sm, sr = exact_arb(S.mid()), exact_arb(_rad_up(S))
    x = [c[i] + T[i, 0] * um + T[i, 1] * sm for i in range(2)]
    M = [[T[i, 0] * ur, T[i, 1] * sr] for i in range(2)]
    Js: List[Mat] = []
    one = arb(0, 1)
    for k in range(n):
        hullk = [x[i] + M[i][0] * one + M[i][1] * one for i in range(2)]
        _, J = f.c1(hullk, k)
        x = f.image(x, k)
        M = _matmul(J, M)
        Js.append(J)
    return x, M, Js


def _rad_up(x: Any) -> float:
    from ._balls import _up

    return _up(x.rad()) if float(x.rad()) > 0 else 0.0


def _form_affine(l: Tuple[Any, Any], x: Box, M: Any) -> Any:
    """``l`` over ``x + M r``, ``r`` in ``[-1, 1]^2``."""
    one = arb(0, 1)
    return _form(l, x) + _form(l, [M[0][0], M[1][0]]) * one + _form(l, [M[0][1], M[1][1]]) * one


def sign_change(f: BallMap, frame: Frame, us: Sequence[float], b: float, n: int,
                reversor: Sequence[Sequence[int]]) -> Tuple[List[int], List[Any]]:
    """The side of ``Fix(R)`` (``sign l_-``: ``+1``, ``-1`` or 0 for undecided) of ``f^n`` of
    each vertical segment ``{u_i} x [-b, b]``, and the enclosures of ``l_-`` there."""
    _, lm = reversor_forms(reversor)
    sides, vals = [], []
    for u in us:
        x, M, _ = _chain(f, exact_arb(u), interval(-b, b), frame, n)
        v = _form_affine(lm, x, M)
        sides.append(_sign(v))
        vals.append(v)
    return sides, vals


def transversality(f: BallMap, frame: Frame, u1: float, u2: float, b: float, cq: float, n: int,
                   reversor: Sequence[Sequence[int]], pieces: int = 1) -> Tuple[bool, str, List[Dict[str, Any]]]:
    """Module docstring, step 3: ``(ok, message, per-piece records)``."""
    lp, lm = reversor_forms(reversor)
    _, T, _ = frame.balls()
    sig = interval(-1.0 / cq, 1.0 / cq)
    v = [T[i, 0] + T[i, 1] * sig for i in range(2)]
    recs = []
    for j in range(pieces):
        lo = Fraction(u1) + (Fraction(u2) - Fraction(u1)) * j / pieces
        hi = Fraction(u1) + (Fraction(u2) - Fraction(u1)) * (j + 1) / pieces
        x, M, Js = _chain(f, hull(exact_arb(lo), exact_arb(hi)), interval(-b, b), frame, n)
        side = _sign(_form_affine(lm, x, M))
        one = arb(0, 1)
        img = [x[i] + M[i][0] * one + M[i][1] * one for i in range(2)]
        rec: Dict[str, Any] = {"piece": j, "u": (float(lo), float(hi)), "off_fix": side != 0,
                               "image": [(float(v.lower().mid()), float(v.upper().mid())) for v in img]}
        if side == 0:
            w = v
            for J in Js:
                w = [J[i][0] * w[0] + J[i][1] * w[1] for i in range(2)]
            ap, am = _form(lp, w), _form(lm, w)
            rec["l_plus"], rec["l_minus"] = ap.str(5), am.str(5)
            rec["transversal"] = bool(_sign(ap) != 0 and _sign(am) != 0)
            if not rec["transversal"]:
                recs.append(rec)
                return False, (f"not proved: on piece {j} (u in [{float(lo):.6g}, {float(hi):.6g}]) the image cone "
                               f"of W^u's tangents is not kept off R's eigen-lines (l+ {ap.str(5)}, l- {am.str(5)})"), recs
        recs.append(rec)
    crossing = sum(1 for r in recs if not r["off_fix"])
    if crossing == 0:
        return False, "not proved: every piece's image is enclosed off Fix(R) (no crossing there)", recs
    return True, f"transversal on the {crossing} piece(s) whose image can meet Fix(R) (of {pieces})", recs


@dataclass
class HomoclinicResult:
    """Outcome of :func:`prove_homoclinic_point`: ``proved`` only if all three steps hold."""

    proved: bool
    message: str
    manifold: Optional[ManifoldResult]
    sides: List[int]
    pieces: List[Dict[str, Any]]
    cpu_seconds: float


def prove_homoclinic_point(f: BallMap, frame: Frame, a: float, b: float, cq: float, us: Tuple[float, float],
                           n: int, reversor: Sequence[Sequence[int]], *, pieces: int = 1) -> HomoclinicResult:
    """Steps 1-3 of the module docstring; returns at the first that fails and says why. Must
    run inside :class:`~taylorball.rigorous._balls.working_precision`."""
    cpu0 = time.process_time()
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise UsageError(f"n (the number of iterates) must be an integer >= 1, got {n!r}")
    if isinstance(pieces, bool) or not isinstance(pieces, int) or pieces < 1:
        raise UsageError(f"pieces must be an integer >= 1, got {pieces!r}")
    u1, u2 = (float(u) for u in us)
    if not (-a <= u1 < u2 <= a):
        raise UsageError(f"us must be (u1, u2) with -a <= u1 < u2 <= a (a = {a!r}), got {us!r}")
    reversor_forms(reversor)
    man = local_unstable_manifold(f, frame, a, b, cq, reversor=reversor)
    cpu = lambda: time.process_time() - cpu0  # noqa: E731
    if not man.ok:
        return HomoclinicResult(False, f"local manifold: {man.message}", man, [], [], cpu())
    sides, vals = sign_change(f, frame, (u1, u2), b, n, reversor)
    if not (sides[0] * sides[1] == -1):
        return HomoclinicResult(False, f"sign change: not proved (l_- of f^{n} of the segments at u1, u2: "
                                f"{vals[0].str(5)}, {vals[1].str(5)})", man, sides, [], cpu())
    ok, msg, recs = transversality(f, frame, u1, u2, b, cq, n, reversor, pieces)
    if not ok:
        return HomoclinicResult(False, f"transversality: {msg}", man, sides, recs, cpu())
    return HomoclinicResult(True, f"proved: a transversal homoclinic point q = f^{n}(x), x on W^u_N with u in "
                            f"[{u1:.6g}, {u2:.6g}], q on Fix(R); {man.message}; {msg}", man, sides, recs, cpu())
