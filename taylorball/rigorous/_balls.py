r"""Ball arithmetic on the package's formulas: arb balls, Taylor series of balls, duals.

The vector fields are never retyped here: :meth:`taylorball.model.System.rhs` is written on
tuples of scalars with ``+ - * /`` only (see :mod:`taylorball._vec`), so it evaluates on

* ``flint.arb`` balls (rigorous enclosures of the field's range over a box),
* ``flint.arb_series`` (truncated Taylor series in time with ball coefficients; FLINT's
  series arithmetic is rigorous coefficientwise),
* :class:`Dual` (a value and its gradient with respect to a few parameters, each an arb or an
  arb_series): forward-mode differentiation in ball arithmetic, used for the variational
  equations and the Jacobians of the section map.

Precision is FLINT's global ``flint.ctx.prec``; :class:`working_precision` sets and restores it.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any, Iterator, List, Sequence, Tuple

from ..errors import UsageError

_flint: Any
arb: Any
arb_mat: Any
arb_series: Any
try:  # python-flint is the optional extra "rigorous"
    import flint as _flint_module

    _flint = _flint_module
    arb, arb_mat, arb_series = _flint_module.arb, _flint_module.arb_mat, _flint_module.arb_series
except ImportError:  # pragma: no cover - exercised only without the extra
    _flint = arb = arb_mat = arb_series = None

__all__ = ["require_flint", "working_precision", "Dual", "to_arb", "exact_arb", "coeff", "hull",
           "contains", "interval"]

_FLINT_HINT = "taylorball.rigorous needs python-flint>=0.6: pip install 'taylorball[rigorous]'"


def require_flint() -> Any:
    """The ``flint`` module, or an ImportError naming the extra to install."""
    if _flint is None:
        raise ImportError(_FLINT_HINT)
    return _flint


#: Series length FLINT may carry (``flint.ctx.cap``, 10 by default): arb_series operations
#: silently truncate beyond it, so it is raised inside :class:`working_precision` and every
#: series the package builds is checked against it (:func:`series_of`).
SERIES_CAP = 256


class working_precision:
    """Context manager: ``flint.ctx.prec = prec`` and ``flint.ctx.cap = SERIES_CAP`` inside
    (FLINT truncates series arithmetic at ``cap`` terms), both restored after."""

    def __init__(self, prec: int) -> None:
        require_flint()
        if isinstance(prec, bool) or not isinstance(prec, int) or not 53 <= prec <= 4096:
            raise UsageError(f"prec must be an integer number of bits in [53, 4096], got {prec!r}")
        self.prec = prec

    def __enter__(self) -> "working_precision":
        self._old = (_flint.ctx.prec, _flint.ctx.cap)
        _flint.ctx.prec = self.prec
        _flint.ctx.cap = SERIES_CAP
        return self

    def __exit__(self, *exc: object) -> None:
        _flint.ctx.prec, _flint.ctx.cap = self._old


def exact_arb(x: Any) -> Any:
    """An exact ball from a float (every float64 is a dyadic rational), an int, a Fraction
    (rounded to a ball at the working precision) or an arb (returned as is)."""
    if isinstance(x, arb):
        return x
    if isinstance(x, Fraction):
        return arb(x.numerator) / x.denominator
    if isinstance(x, int):
        return arb(x)
    xf = float(x)
    num, den = xf.as_integer_ratio()
    return arb(num) / den  # den is a power of two: exact


def to_arb(x: Any, radius: float = 0.0) -> Any:
    """``x`` as an exact ball, widened by ``radius`` (rounded up by FLINT)."""
    b = exact_arb(x)
    if radius:
        b = b + arb(0, radius)
    return b


def _up(x: Any) -> float:
    """A float >= every point of the ball ``x`` (rounded outward)."""
    import math

    v = float(x.upper().mid())
    while not exact_arb(v) >= x:
        v = math.nextafter(v, math.inf)
    return v


def interval(lo: Any, hi: Any) -> Any:
    """A ball enclosing ``[lo, hi]`` (arbs or floats), centred on the midpoint (FLINT's
    ``arb.union`` returns a ball centred at 0 here, far too wide)."""
    lo, hi = exact_arb(lo), exact_arb(hi)
    return hull(lo, hi)


def coeff(s: Any, k: int) -> Any:
    """Coefficient ``k`` of an arb_series (an arb or number is a constant series)."""
    if isinstance(s, arb_series):
        cs = s.coeffs()
        return cs[k] if k < len(cs) else arb(0)
    if k == 0:
        return s if isinstance(s, arb) else exact_arb(s)
    return arb(0)


def hull(a: Any, b: Any) -> Any:
    """A ball containing ``a`` and ``b``: centred on the middle of their hull, with the
    radius rounded up (python-flint's ``arb.union`` can return a ball centred at 0)."""
    lo = a.lower().min(b.lower())
    hi = a.upper().max(b.upper())
    m = arb(((lo + hi) / 2).mid())
    r = max(_up(hi - m), _up(m - lo), 0.0)
    return m + arb(0, r) if r > 0 else m


def contains(outer: Any, inner: Any) -> bool:
    """True only if ``inner`` certainly lies in ``outer`` (arbs or :class:`Dual`)."""
    if isinstance(outer, Dual):
        return contains(outer.v, inner.v) and all(contains(o, i) for o, i in zip(outer.g, inner.g))
    return bool(outer.contains(inner))


class Dual:
    r"""A value ``v`` and its gradient ``g`` (a tuple) with respect to a few parameters.

    ``v`` and the entries of ``g`` are arbs or arb_series. Supports ``+ - * /``, integer
    powers and ``sqrt``: the chain rule in ball arithmetic, so that evaluating a formula on
    duals encloses both its value and its derivative over the balls of the inputs."""

    __slots__ = ("v", "g")

    def __init__(self, v: Any, g: Sequence[Any]) -> None:
        self.v = v
        self.g = tuple(g)

    @staticmethod
    def _lift(o: Any, n: int) -> "Dual":
        return o if isinstance(o, Dual) else Dual(o, (0,) * n)

    def __add__(self, o: Any) -> "Dual":
        if isinstance(o, Dual):
            return Dual(self.v + o.v, tuple(a + b for a, b in zip(self.g, o.g)))
        return Dual(self.v + o, self.g)

    __radd__ = __add__

    def __neg__(self) -> "Dual":
        return Dual(-self.v, tuple(-a for a in self.g))

    def __sub__(self, o: Any) -> "Dual":
        if isinstance(o, Dual):
            return Dual(self.v - o.v, tuple(a - b for a, b in zip(self.g, o.g)))
        return Dual(self.v - o, self.g)

    def __rsub__(self, o: Any) -> "Dual":
        return Dual(o - self.v, tuple(-a for a in self.g))

    def __mul__(self, o: Any) -> "Dual":
        if isinstance(o, Dual):
            return Dual(self.v * o.v, tuple(a * o.v + self.v * b for a, b in zip(self.g, o.g)))
        return Dual(self.v * o, tuple(a * o for a in self.g))

    __rmul__ = __mul__

    def __truediv__(self, o: Any) -> "Dual":
        if isinstance(o, Dual):
            q = self.v / o.v
            return Dual(q, tuple((a - q * b) / o.v for a, b in zip(self.g, o.g)))
        return Dual(self.v / o, tuple(a / o for a in self.g))

    def __rtruediv__(self, o: Any) -> "Dual":
        q = o / self.v
        return Dual(q, tuple(-q * a / self.v for a in self.g))

    def __pow__(self, n: int) -> "Dual":
        if not isinstance(n, int) or n < 1:
            raise UsageError(f"Dual supports positive integer powers only, got {n!r}")
        out = self
        for _ in range(n - 1):
            out = out * self
        return out

    def sqrt(self) -> "Dual":
        r = self.v.sqrt()
        return Dual(r, tuple(a / (2 * r) for a in self.g))

    def sin(self) -> "Dual":
        """``sin`` of a dual whose value is an arb."""
        c = self.v.cos()
        return Dual(self.v.sin(), tuple(a * c for a in self.g))

    def cos(self) -> "Dual":
        """``cos`` of a dual whose value is an arb."""
        s = self.v.sin()
        return Dual(self.v.cos(), tuple(-a * s for a in self.g))

    def atan(self) -> "Dual":
        """``atan`` of a dual whose value is an arb."""
        d = 1 + self.v * self.v
        return Dual(self.v.atan(), tuple(a / d for a in self.g))

    def __iter__(self) -> Iterator[Any]:  # pragma: no cover - guard against misuse
        raise TypeError("a Dual is a scalar")

    def __repr__(self) -> str:
        return f"Dual({self.v!r}, {self.g!r})"


def series_of(coeffs: Sequence[Any], length: int) -> Any:
    """An arb_series with the given coefficients, known to ``O(t^length)``.

    Raises
    ------
    UsageError
        If ``length`` exceeds FLINT's series cap (the arithmetic would truncate silently)."""
    if length > _flint.ctx.cap:
        raise UsageError(f"series length {length} exceeds flint.ctx.cap = {_flint.ctx.cap}: use working_precision")
    return arb_series(list(coeffs), prec=length)


def arb_vector_mid_rad(xs: Sequence[Any]) -> Tuple[List[float], List[float]]:
    """Midpoints (rounded to nearest) and radii (rounded up) of arbs, as floats."""
    return [float(x.mid()) for x in xs], [float(x.rad()) for x in xs]


def matrix(rows: Sequence[Sequence[Any]]) -> Any:
    """An arb_mat from nested sequences of arbs."""
    return arb_mat([list(r) for r in rows])
