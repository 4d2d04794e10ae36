r"""Exact arithmetic for the checks of the paper's formulas (:mod:`taylorball.verify.formulas`).

* forward-mode dual numbers over :class:`fractions.Fraction` (:class:`Dual`): exact
  directional derivatives, divergences and Lie brackets of fields given on tuples;
* exact rational points of the constraint manifolds: unit vectors from the inverse
  stereographic projection, orthonormal frames from unnormalised integer quaternions, and
  random full, reduced and ``M || gamma`` states on which ``|gamma| = 1``, ``Q in SO(3)``
  and ``(R, gamma) = 0`` hold exactly;
* 3x3 linear algebra (determinant, Cramer's rule) over any field, :class:`Dual` included.
"""

from __future__ import annotations

import random
from fractions import Fraction
from typing import Callable, List, Sequence

from .._vec import dot, scale, sub

__all__ = [
    "Dual",
    "directional_derivative",
    "divergence",
    "lie_bracket",
    "rational_unit_vector",
    "rational_frame",
    "random_full_states",
    "random_reduced_states",
    "random_mparallel_states",
    "det3",
    "solve3",
]

F = Fraction


# ---------------------------------------------------------------------------------------
# Exact forward-mode differentiation.
# ---------------------------------------------------------------------------------------
class Dual:
    """``v + d eps`` with ``eps^2 = 0``, over exact rationals.

    Only ``+ - * /`` and integer powers are defined: every formula checked here is
    rational, and the backend-neutral formulas of :mod:`taylorball._vec` use nothing else.
    """

    __slots__ = ("v", "d")

    def __init__(self, v, d=0):
        self.v = v
        self.d = d

    @staticmethod
    def _c(o):
        return o if isinstance(o, Dual) else Dual(o, 0)

    def __add__(self, o):
        o = Dual._c(o)
        return Dual(self.v + o.v, self.d + o.d)

    __radd__ = __add__

    def __sub__(self, o):
        o = Dual._c(o)
        return Dual(self.v - o.v, self.d - o.d)

    def __rsub__(self, o):
        return Dual._c(o) - self

    def __neg__(self):
        return Dual(-self.v, -self.d)

    def __mul__(self, o):
        o = Dual._c(o)
        return Dual(self.v * o.v, self.v * o.d + self.d * o.v)

    __rmul__ = __mul__

    def __truediv__(self, o):
        o = Dual._c(o)
        return Dual(self.v / o.v, (self.d * o.v - self.v * o.d) / (o.v * o.v))

    def __rtruediv__(self, o):
        return Dual._c(o) / self

    def __pow__(self, n):
        if not isinstance(n, int) or n < 0:
            raise TypeError(f"Dual ** n needs a non-negative int n, got {n!r}")
        out = Dual(1, 0)
        for _ in range(n):
            out = out * self
        return out


def _flat(x):
    out = []
    for p in x if isinstance(x, (tuple, list)) else (x,):
        out.extend(_flat(p) if isinstance(p, (tuple, list)) else (p,))
    return out


def directional_derivative(fn: Callable, point: Sequence, direction: Sequence):
    """Exact ``d/ds fn(point + s direction)`` at ``s = 0`` (a flat list), and ``fn(point)``."""
    out = _flat(fn([Dual(p, q) for p, q in zip(point, direction)]))
    vals = [o.v if isinstance(o, Dual) else o for o in out]
    ders = [o.d if isinstance(o, Dual) else 0 for o in out]
    return ders, vals


def divergence(field: Callable, point: Sequence):
    """Exact ``div X`` at ``point`` and the terms ``dX_i/dx_i``."""
    n = len(point)
    terms = []
    for i in range(n):
        e = [0] * n
        e[i] = 1
        ders, _ = directional_derivative(field, point, e)
        terms.append(ders[i])
    return sum(terms), terms


def lie_bracket(u: Callable, X: Callable, point: Sequence):
    """Exact ``[u, X](p) = DX(p) u(p) - Du(p) X(p)`` and the sizes of the two terms."""
    up = _flat(u(list(point)))
    Xp = _flat(X(list(point)))
    DXu, _ = directional_derivative(X, point, up)
    DuX, _ = directional_derivative(u, point, Xp)
    br = [p - q for p, q in zip(DXu, DuX)]
    size = max(max(abs(v) for v in DXu), max(abs(v) for v in DuX))
    return br, size


def _rel(diffs, size) -> float:
    """Relative residual as a float (exactly 0.0 for an exact identity)."""
    m = max(abs(v) for v in diffs)
    if m == 0:
        return 0.0
    return float(m / size) if size != 0 else float(m)


# ---------------------------------------------------------------------------------------
# Exact rational points of the constraint manifolds.
# ---------------------------------------------------------------------------------------
def rational_unit_vector(s, t):
    """Inverse stereographic projection: an exactly unit rational vector."""
    n = 1 + s * s + t * t
    return (2 * s / n, 2 * t / n, (1 - s * s - t * t) / n)


def rational_frame(q):
    """Rows ``(alpha, beta, gamma)`` of the rotation of the integer quaternion ``q``
    (``Q = R(q)/|q|^2``): an exactly orthonormal right-handed rational frame."""
    w, x, y, z = (F(v) for v in q)
    n = w * w + x * x + y * y + z * z
    Q = (
        ((w * w + x * x - y * y - z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        (2 * (x * y + w * z), (w * w - x * x + y * y - z * z), 2 * (y * z - w * x)),
        (2 * (x * z - w * y), 2 * (y * z + w * x), (w * w - x * x - y * y + z * z)),
    )
    return tuple(tuple(v / n for v in row) for row in Q)


def _rq(rng, lo=-9, hi=9, den=5):
    return F(rng.randint(lo, hi), rng.randint(1, den))


def random_full_states(n: int, seed: int = 1) -> List[tuple]:
    """``n`` exact rational full states ``(omega, alpha, beta, gamma, x, y)`` on SO(3) x R^5."""
    rng = random.Random(seed)
    out: List[tuple] = []
    while len(out) < n:
        q = [rng.randint(-5, 5) for _ in range(4)]
        if not any(q):
            continue
        al, be, g = rational_frame(q)
        w = tuple(_rq(rng) for _ in range(3))
        out.append((*w, *al, *be, *g, _rq(rng), _rq(rng)))
    return out


def random_reduced_states(n: int, seed: int = 2) -> List[tuple]:
    """``n`` exact rational reduced states ``(omega, gamma, R)``: ``|gamma| = 1``, ``(R, gamma) = 0``."""
    rng = random.Random(seed)
    out = []
    for _ in range(n):
        g = rational_unit_vector(_rq(rng), _rq(rng))
        r = tuple(_rq(rng) for _ in range(3))
        R = sub(r, scale(dot(r, g), g))
        w = tuple(_rq(rng) for _ in range(3))
        out.append((*w, *g, *R))
    return out


def random_mparallel_states(n: int, seed: int = 3) -> List[tuple]:
    """``n`` exact rational states ``(K, gamma)`` with ``|gamma| = 1``."""
    rng = random.Random(seed)
    return [(*(_rq(rng) for _ in range(3)), *rational_unit_vector(_rq(rng), _rq(rng))) for _ in range(n)]


# ---------------------------------------------------------------------------------------
# Linear algebra in 3D, exact.
# ---------------------------------------------------------------------------------------
def det3(m):
    """Determinant of a 3x3 matrix given as rows."""
    return (
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    )


def solve3(m, b):
    """Solve ``m x = b`` (rows ``m``) by Cramer's rule (any field, incl. :class:`Dual`)."""
    D = det3(m)
    out = []
    for j in range(3):
        mj = [[b[i] if k == j else m[i][k] for k in range(3)] for i in range(3)]
        out.append(det3(mj) / D)
    return tuple(out)


def _matrix_of(op):
    """Rows of the matrix of a linear map ``op`` on 3-vectors."""
    cols = [op(tuple(1 if i == j else 0 for i in range(3))) for j in range(3)]
    return [[cols[j][i] for j in range(3)] for i in range(3)]


def _split_full(s):
    s = list(s)
    return tuple(s[0:3]), tuple(s[3:6]), tuple(s[6:9]), tuple(s[9:12]), s[12], s[13]
