r"""The validated Taylor step: a priori enclosure, Taylor series of balls, remainder, Lohner.

One step of length ``h`` from a set ``X = c + A r`` (``c`` a vector of balls, ``A`` an exact
matrix, ``r`` a box around 0; Lohner's representation):

1. **A priori enclosure** (Picard--Lindelof): a box ``B`` with ``X + [0, h] f(B) \subset B``
   proves that every solution from ``X`` stays in ``B`` on ``[0, h]`` (first-order Picard
   operator, iterated with inflation; the step is halved when it fails). With duals (value and
   Jacobian) the same operator encloses the variational equation's solution ``W``.
2. **Taylor series**: the solution's coefficients ``x_k`` to order ``N`` by the recursion
   ``x_{k+1} = f(x)_k / (k+1)`` on :class:`flint.arb_series` (FLINT's rigorous series
   arithmetic), from the point ``c``.
3. **Remainder**: ``x(h) - \sum_{k \le N} x_k h^k = x_{N+1}(\xi) h^{N+1}`` where
   ``x_{N+1}(\xi)`` is the (N+1)-th coefficient of the solution through a point of ``B``
   (Lagrange), enclosed by running the recursion from the box ``B``.
4. **Wrapping control** (Lohner's QR method): the Jacobian ``J`` of the Taylor polynomial over
   ``X`` (duals with the identity as gradient), the mean-value form
   ``x(h) \in T(c) + Z + J A r``, and the new frame ``A' = Q`` of a QR factorisation of
   ``mid(J A)`` (columns ordered by their size on ``r``), ``r' = (A'^{-1} J A) r + A'^{-1} s``
   with ``A'^{-1}`` enclosed by FLINT (:meth:`arb_mat.inv`).

For the C^1 enclosure the step also returns an enclosure of the flow's Jacobian over ``X``:
``\sum_k D x_k(X) h^k + D x_{N+1}(B) W h^{N+1}`` (the remainder of the variational equation).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, List, Optional, Sequence, Tuple

import numpy as np

from ..errors import IntegrationError
from ._balls import Dual, arb, arb_mat, coeff, contains, exact_arb, hull, interval, series_of

Rhs = Callable[[Sequence[Any]], Sequence[Any]]

__all__ = ["taylor_coeffs", "horner", "apriori", "LohnerSet", "lohner_step", "default_order", "VarSet",
           "c1_lohner_update", "sliced_remainder"]


def default_order(prec: int) -> int:
    """Taylor order for a working precision: 18 at 53 bits, 28 at 128, 44 at 256 (capped:
    the series cost grows like the cube of the order)."""
    return int(min(12 + prec // 8, 44))


def _mk(cl: Sequence[Any], length: int) -> Any:
    if isinstance(cl[0], Dual):
        ng = len(cl[0].g)
        return Dual(series_of([c.v for c in cl], length),
                    tuple(series_of([c.g[j] for c in cl], length) for j in range(ng)))
    return series_of(cl, length)


def _co(s: Any, k: int, ng: int) -> Any:
    if isinstance(s, Dual):
        return Dual(coeff(s.v, k), tuple(coeff(g, k) for g in s.g))
    if ng:
        return Dual(coeff(s, k), (arb(0),) * ng)
    return coeff(s, k)


def taylor_coeffs(rhs: Rhs, x0: Sequence[Any], order: int) -> List[List[Any]]:
    """Taylor coefficients ``x_0 .. x_order`` of the solution of ``x' = rhs(x)`` through
    ``x0`` (arbs, or :class:`Dual` of arbs for the coefficients' derivatives)."""
    ng = len(x0[0].g) if isinstance(x0[0], Dual) else 0
    cs: List[List[Any]] = [[x] for x in x0]
    for k in range(order):
        xs = [_mk(c, k + 1) for c in cs]
        f = rhs(xs)
        for i in range(len(cs)):
            cs[i].append(_co(f[i], k, ng) / (k + 1))
    return cs


def horner(cl: Sequence[Any], t: Any) -> Any:
    """``sum_k cl[k] t^k`` (t a ball, possibly an interval)."""
    out = cl[-1]
    for c in reversed(cl[:-1]):
        out = out * t + c
    return out


def _inflate(b: Any, f: float) -> Any:
    if isinstance(b, Dual):
        return Dual(_inflate(b.v, f), tuple(_inflate(g, f) for g in b.g))
    w = float(b.rad()) * f + float(abs(b.mid())) * 1e-15 + 1e-300
    return b + arb(0, w)


def _hull(a: Any, b: Any) -> Any:
    if isinstance(a, Dual):
        return Dual(hull(a.v, b.v), tuple(hull(x, y) for x, y in zip(a.g, b.g)))
    return hull(a, b)


def _finite(b: Any) -> bool:
    if isinstance(b, Dual):
        return _finite(b.v) and all(_finite(g) for g in b.g)
    return bool(b.is_finite())


def apriori(rhs: Rhs, X: Sequence[Any], h: Any, iters: int = 12) -> Optional[List[Any]]:
    r"""A box ``B`` with ``X + [0, h] rhs(B) \subset B`` (so every solution from ``X`` stays in
    ``B`` on ``[0, h]``), returned as ``X + [0, h] rhs(B)``; ``None`` if not found."""
    H = interval(0, h)
    f = rhs(list(X))
    B = [_inflate(x + H * fi, 1.0) for x, fi in zip(X, f)]
    for it in range(iters):
        f = rhs(B)
        Bn = [x + H * fi for x, fi in zip(X, f)]
        if not all(_finite(b) for b in Bn):
            return None
        if all(contains(b, bn) for b, bn in zip(B, Bn)):
            return Bn
        B = [_inflate(_hull(b, bn), 0.5 + it) for b, bn in zip(B, Bn)]
    return None


def apriori_high_order(rhs: Rhs, P: Sequence[Any], h: Any, order: int, iters: int = 8) -> Optional[Tuple[List[Any], List[List[Any]]]]:
    r"""High-order a priori enclosure (Nedialkov, Jackson & Pryce, Reliable Computing 7,
    2001): with ``P = sum_{k<N} x_k(X) [0,h]^k`` (the coefficients over the initial box), a box
    ``B`` with ``P + x_N(B) [0,h]^N \subset B`` encloses every solution from ``X`` on
    ``[0, h]``. Returns ``B`` and the coefficients of the solution through ``B`` to order
    ``N + 1`` (for the remainder), or ``None``."""
    H = interval(0, h)
    HN = H ** order
    B = [_inflate(p, 0.5) for p in P]
    for it in range(iters):
        try:
            cB = taylor_coeffs(rhs, B, order + 1)
        except (ValueError, ZeroDivisionError):  # a denominator's ball contains 0 on B
            return None
        Bn = [p + cB[i][order] * HN for i, p in enumerate(P)]
        if not all(_finite(b) for b in Bn):
            return None
        if all(contains(b, bn) for b, bn in zip(B, Bn)):
            return B, cB
        B = [_inflate(_hull(b, bn), 1.0 + it) for b, bn in zip(B, Bn)]
    return None


@dataclass
class LohnerSet:
    """``{c + A r : r in r}``: ``c`` balls (n), ``A`` an exact arb_mat (n x n), ``r`` balls
    around 0 (n). With a parameter part (the doubleton form, as CAPD's doubleton sets):
    ``{c + P q + A r}``, ``P`` an exact arb_mat (n x m) and ``q`` balls (m) that stay fixed:
    the set's parameters (e.g. the coordinates of an h-set's piece) are carried by ``P``
    (``P' = mid(J P)``, the rest of ``J P q`` goes into ``r``) and never wrapped."""

    c: List[Any]
    A: Any
    r: List[Any]
    P: Any = None
    q: Optional[List[Any]] = None

    @classmethod
    def from_box(cls, X: Sequence[Any]) -> "LohnerSet":
        n = len(X)
        c = [exact_arb(x.mid()) if hasattr(x, "mid") else exact_arb(x) for x in X]
        eye = arb_mat([[1 if i == j else 0 for j in range(n)] for i in range(n)])
        return cls(c, eye, [x - ci for x, ci in zip(X, c)])

    def box(self) -> List[Any]:
        n = len(self.c)
        out = [self.c[i] + sum((self.A[i, j] * self.r[j] for j in range(n)), exact_arb(0)) for i in range(n)]
        if self.P is not None and self.q is not None:
            m = len(self.q)
            out = [out[i] + sum((self.P[i, j] * self.q[j] for j in range(m)), exact_arb(0)) for i in range(n)]
        return out


@dataclass
class StepResult:
    set: LohnerSet
    box: List[Any]
    B: List[Any]
    jac: Optional[Any]
    T_coeffs: List[List[Any]]
    J_coeffs: Optional[List[List[Any]]]
    rem: List[Any]
    rem_jac: Optional[List[List[Any]]]
    A_old: Any = None
    Ainv: Any = None


def _eye_duals(X: Sequence[Any]) -> List[Dual]:
    n = len(X)
    return [Dual(X[i], tuple(exact_arb(1) if j == i else exact_arb(0) for j in range(n))) for i in range(n)]


def _qr_frame(Mmid: np.ndarray, rr: np.ndarray) -> np.ndarray:
    """Lohner's QR: Q of mid(J A) with its columns ordered by their size on r."""
    n = Mmid.shape[0]
    order = np.argsort(-(np.linalg.norm(Mmid, axis=0) * rr))
    Q, _ = np.linalg.qr(Mmid[:, order])
    if not np.all(np.isfinite(Q)) or abs(np.linalg.det(Q)) < 0.5:
        return np.eye(n)
    return Q


def sliced_remainder(rhs: Rhs, cX: Sequence[Sequence[Any]], cB: Sequence[Sequence[Any]], h: Any, order: int,
                     slices: int) -> Optional[List[Any]]:
    r"""The coefficient ``x_{N+1}`` enclosed over the solution's tube on ``[0, h]`` in
    ``slices`` time slices, instead of over the one a priori box ``B``.

    On slice ``T_j = [j h/m, (j+1) h/m]`` every solution from ``X`` lies in
    ``B_j = sum_{k<N} x_k(X) T_j^k + x_N(B) T_j^N`` (Taylor's formula of order ``N`` with
    Lagrange's remainder, ``x(xi) in B``); so ``x_{N+1}(x(xi))``, ``xi in [0, h]``, lies in the
    hull of the ``x_{N+1}(B_j)``. The slices are ``m`` times narrower than ``B`` and the ball
    recursion's radii grow much faster with the box's width than linearly (on the Fig. 3
    saddle at order 18, ``h = 4e-3``: 1.8e-7 over ``B``, 2.4e-17 over 16 slices).
    ``cX``: the coefficients over the initial box (to ``N``), ``cB``: over ``B`` (to ``N + 1``).
    Returns the enclosures of ``x_{N+1}`` (one per component), or ``None`` if a slice's
    recursion fails (a denominator's ball contains 0)."""
    n = len(cX)
    out: List[Any] = []
    for j in range(slices):
        Tj = interval(h * j / slices, h * (j + 1) / slices)
        Bj = [horner(list(cX[i][:order]), Tj) + cB[i][order] * Tj ** order for i in range(n)]
        try:
            cj = taylor_coeffs(rhs, Bj, order + 1)
        except (ValueError, ZeroDivisionError):
            return None
        xs = [cj[i][order + 1] for i in range(n)]
        out = xs if not out else [hull(a, b) for a, b in zip(out, xs)]
    return out


def lohner_step(rhs: Rhs, S: LohnerSet, h: Any, order: int, *, jac: bool = False,
                wrapping: str = "qr", remainder_scale: int = 1, slices: int = 0,
                rem_limit: Optional[float] = None) -> Optional[StepResult]:
    """One validated step of length ``h`` (an exact ball) from ``S``; ``None`` if the a
    priori enclosure fails (the caller halves ``h``). ``wrapping``: ``"qr"`` (Lohner's QR
    method, columns ordered by their size on ``r``), ``"parallelepiped"`` (``A' = mid(J A)``)
    or ``"box"`` (``A' = I``: the direct interval method). ``remainder_scale = 0`` drops the remainder: wrong on purpose, for the
    tests that the checker can fail. ``slices > 0`` (C^0 steps, high-order a priori box only):
    the remainder from :func:`sliced_remainder` (the tighter of it and the one over ``B``),
    computed before the Jacobian's series; with ``rem_limit`` the step returns ``None`` as
    soon as the remainder exceeds it (the caller halves ``h``)."""
    n = len(S.c)
    X = S.box()
    early = slices > 0 and not jac  # the remainder first, the Jacobian's series only if it passes
    cJ: Any = None
    try:
        if early:
            cX = taylor_coeffs(rhs, X, order)
        else:
            cJ = taylor_coeffs(rhs, _eye_duals(X), order)
            cX = [[x.v for x in c] for c in cJ]
    except (ValueError, ZeroDivisionError):  # a denominator's ball contains 0 on the set's box
        return None
    H = interval(0, h)
    P = [horner(c[:-1], H) for c in cJ] if jac else [horner(c[:-1], H) for c in cX]
    found = apriori_high_order(rhs, P, h, order)
    if found is None:  # the first-order Picard operator as a fallback
        Bd = apriori(rhs, _eye_duals(X), h) if jac else apriori(rhs, X, h)
        if Bd is None:
            return None
        try:
            cB = taylor_coeffs(rhs, Bd, order + 1)
        except (ValueError, ZeroDivisionError):
            return None
    else:
        Bd, cB = found
    B = [b.v for b in Bd] if jac else Bd
    hN = h ** (order + 1)
    rem = [cB[i][order + 1] * hN for i in range(n)]
    if early and found is not None:
        xs = sliced_remainder(rhs, cX, cB, h, order, slices)
        if xs is not None:  # both enclose the same remainder: keep the narrower per component
            rem = [x * hN if float(abs(x * hN).upper()) < float(abs(r).upper()) else r for x, r in zip(xs, rem)]
    if early:
        if rem_limit is not None and not max(float(abs(r).upper()) for r in rem) * remainder_scale <= rem_limit:
            return None  # the caller would reject the step: spare the Jacobian's series
        try:
            cJ = taylor_coeffs(rhs, _eye_duals(X), order)
        except (ValueError, ZeroDivisionError):
            return None
    rem_v = [r.v if isinstance(r, Dual) else r for r in rem]
    rem_v = [r * remainder_scale for r in rem_v]
    if not all(r.is_finite() for r in rem_v):
        return None
    cc = taylor_coeffs(rhs, S.c, order)
    T = [horner(c, h) for c in cc]
    TJ = [horner(c, h) for c in cJ]
    J = arb_mat([[TJ[i].g[j] for j in range(n)] for i in range(n)])
    u = [T[i] + rem_v[i] for i in range(n)]
    c_new = [exact_arb(x.mid()) for x in u]
    s = [x - cn for x, cn in zip(u, c_new)]
    P_new = None
    if S.P is not None and S.q is not None:  # the parameter part: P' = mid(J P), the rest into s
        JP = J * S.P
        P_new = arb_mat([[exact_arb(JP[i, j].mid()) for j in range(JP.ncols())] for i in range(n)])
        E = (JP - P_new) * arb_mat([[x] for x in S.q])
        s = [s[i] + E[i, 0] for i in range(n)]
    M = J * S.A
    if wrapping == "box":
        A_new = np.eye(n)
    else:
        Mmid = np.array([[float(M[i, j].mid()) for j in range(n)] for i in range(n)])
        if wrapping == "parallelepiped":
            A_new = Mmid if abs(np.linalg.det(Mmid)) > 1e-300 else np.eye(n)
        else:
            rr = np.array([float(abs(x).upper()) for x in S.r])
            A_new = _qr_frame(Mmid, rr)
    A_arb = arb_mat([[exact_arb(float(A_new[i, j])) for j in range(n)] for i in range(n)])
    try:
        Ainv = A_arb.inv()
    except ZeroDivisionError:
        raise IntegrationError("the Lohner frame matrix is singular in ball arithmetic") from None
    C = Ainv * M
    sv = arb_mat([[x] for x in s])
    rv = arb_mat([[x] for x in S.r])
    r_new_m = C * rv + Ainv * sv
    r_new = [r_new_m[i, 0] for i in range(n)]
    new = LohnerSet(c_new, A_arb, r_new, P_new, S.q)
    box = new.box()
    jac_m = None
    rem_jac = None
    if jac:
        rem_jac = [[rem[i].g[j] * remainder_scale for j in range(n)] for i in range(n)]
        jac_m = arb_mat([[TJ[i].g[j] + rem_jac[i][j] for j in range(n)] for i in range(n)])
    return StepResult(new, box, B, jac_m, cc, cJ, rem_v, rem_jac, S.A, Ainv)


@dataclass
class VarSet:
    r"""An enclosure of a set of matrices in Lohner form: ``{C + A R : R in R}``.

    ``C`` (n x m) balls of tiny radius, ``A`` (n x n) an exact frame, ``R`` (n x m) balls
    around 0. Used for the variational matrix ``V`` of the flow (the C^1 Lohner algorithm):
    each column of ``V`` is carried like the state's set, in the state's QR frame, so the
    product of the steps' interval Jacobians does not wrap."""

    C: Any
    A: Any
    R: Any

    @classmethod
    def identity(cls, n: int) -> "VarSet":
        eye = arb_mat([[1 if i == j else 0 for j in range(n)] for i in range(n)])
        return cls(eye, eye, arb_mat(n, n))

    def matrix(self) -> Any:
        """The interval matrix ``C + A R`` (an enclosure of every matrix of the set)."""
        return self.C + self.A * self.R

    def left(self, L: Any) -> Any:
        """An enclosure of ``L V`` for every ``V`` of the set and ``L`` in the interval
        matrix ``L``: ``L C + (L A) R`` (tighter than ``L (C + A R)``)."""
        return L * self.C + (L * self.A) * self.R


def _exact_mid(M: Any) -> Any:
    return arb_mat([[exact_arb(M[i, j].mid()) for j in range(M.ncols())] for i in range(M.nrows())])


def c1_lohner_update(V: VarSet, step: StepResult, mode: str = "lohner") -> VarSet:
    r"""The variational matrix after a step: ``V' = [J] V`` with ``[J]`` the step's
    Jacobian enclosure over the step's initial set (``step.jac``).

    ``mode="lohner"`` (the C^1 Lohner algorithm): with the state's new frame ``A'`` (exact,
    ``A'^{-1}`` enclosed as ``step.Ainv``),
    ``C' = mid([J] C)``, ``R' = (A'^{-1} ([J] A)) R + A'^{-1} ([J] C - C')``, so that
    ``[J] (C + A R) \subset C' + A' R'``. ``mode="product"``: the plain product of interval
    matrices ``V' = [J] V`` (kept as ``C' = V'``, ``R' = 0``), which wraps; for comparison."""
    J = step.jac
    if J is None:
        raise ValueError("c1_lohner_update needs a step computed with jac=True")
    n = J.nrows()
    if mode == "product":
        return VarSet(J * V.matrix(), arb_mat([[1 if i == j else 0 for j in range(n)] for i in range(n)]),
                      arb_mat(n, V.C.ncols()))
    JC = J * V.C
    Cn = _exact_mid(JC)
    Ainv = step.Ainv
    A_new = step.set.A
    Rn = (Ainv * (J * V.A)) * V.R + Ainv * (JC - Cn)
    return VarSet(Cn, A_new, Rn)


def max_rad(xs: Sequence[Any]) -> float:
    """The largest radius of a vector of balls (rounded up)."""
    return max(float(x.rad()) for x in xs)


def step_size_guess(rhs: Rhs, c: Sequence[Any], order: int, tol: float) -> float:
    """Jorba--Zou step from the point Taylor coefficients: ``rho tol^(1/N)``, with ``rho``
    the radius of convergence estimated from the last two coefficients."""
    cc = taylor_coeffs(rhs, c, order)
    norms = [max(abs(float(cc[i][k].mid())) for i in range(len(cc))) for k in range(len(cc[0]))]
    scale = max(norms[0], 1.0)
    rho = min(((scale / norms[k]) ** (1.0 / k)) if norms[k] > 0 else np.inf for k in (order - 1, order))
    if not np.isfinite(rho):
        rho = 1.0
    return float(rho * (tol ** (1.0 / order)) * 0.5)


def tuple_rhs(fn: Callable[[Tuple[Any, ...]], Tuple[Any, ...]]) -> Rhs:
    """Adapts a function of a tuple to :data:`Rhs`."""
    return lambda xs: fn(tuple(xs))
