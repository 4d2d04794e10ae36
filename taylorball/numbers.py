"""Number types: float64, long double, real128 and arbitrary-precision real.

:func:`resolve_fp_type` turns the ``fp_type`` / ``prec`` arguments of the public API into
an :class:`FpSpec` that converts arrays exactly, gives the unit roundoff and says whether
heyoka must compile in compact mode.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Optional, Sequence, SupportsFloat, Type, TypeGuard

import numpy as np
from numpy.typing import ArrayLike

from ._typing import FpTypeLike, Scalar
from .errors import UsageError

__all__ = ["FpSpec", "resolve_fp_type", "FP_TYPE_NAMES", "real_number", "count", "times", "multiple_of",
           "MULTIPLE_EPS"]

FP_TYPE_NAMES = ("float", "longdouble", "real128", "real")

#: Range of ``prec`` (bits) for ``heyoka.real``. heyoka takes 2 bits on, but the package's
#: formulas mix reals with Python numbers (exact ints such as ``1 - x``, float constants),
#: and heyoka.real promotes such a mix to the larger precision (64 bits for an int, 53 for a
#: float): below 64 bits the states would come out in 64 bits and heyoka refuses them. Use
#: float (53 bits) or longdouble (64 bits) for fewer digits.
PREC_MIN, PREC_MAX = 64, 100_000


# ---------------------------------------------------------------------------------------
# Checks of the numbers the public API takes (times, steps, counts), in one place: they
# accept Python and numpy real scalars alike and name the argument when they refuse.
# ---------------------------------------------------------------------------------------
def _is_real_scalar(value: object) -> TypeGuard[SupportsFloat]:
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        return True  # a 0-d array, as numpy reductions and np.where hand back
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def real_number(name: str, value: object, *, lo: Optional[float] = None, hi: Optional[float] = None,
                lo_open: bool = False, error: Type[Exception] = UsageError) -> float:
    """``value`` as a finite float in ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``), or
    ``error`` naming ``name``, the value and the range. Python and numpy real scalars
    (``np.float32(10)``, ``np.int64(3)``, 0-d arrays) are accepted; bools, strings and arrays
    of more than one number are not."""
    rng = (f"{'(' if lo_open else '['}{'-inf' if lo is None else f'{lo:g}'}, "
           f"{'inf' if hi is None else f'{hi:g}'}]")
    where = "" if lo is None and hi is None else f" in {rng}"
    if not _is_real_scalar(value):
        raise error(f"{name} must be a finite real number{where}, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise error(f"{name} must be finite (a real number{where}), got {value!r}")
    if (lo is not None and (x <= lo if lo_open else x < lo)) or (hi is not None and x > hi):
        raise error(f"{name} must be in {rng}, got {value!r}")
    return x


def count(name: str, value: object, *, lo: int = 1, hi: Optional[int] = None,
          error: Type[Exception] = UsageError) -> int:
    """``value`` as an int in ``[lo, hi]`` (Python or numpy integer, not bool), or
    ``error`` naming ``name``."""
    rng = f"[{lo}, {'inf' if hi is None else hi}]"
    if not isinstance(value, (int, np.integer)) or isinstance(value, (bool, np.bool_)):
        raise error(f"{name} must be an integer in {rng}, got {value!r}")
    v = int(value)
    if v < lo or (hi is not None and v > hi):
        raise error(f"{name} must be an integer in {rng}, got {value!r}")
    return v


def one_of(name: str, value: object, valid: Sequence[str], *, error: Type[Exception] = UsageError) -> str:
    """``value`` if it is one of the strings ``valid``, or ``error`` naming ``name``, the
    value and the valid ones."""
    if not isinstance(value, str) or value not in valid:
        raise error(f"{name} must be one of {', '.join(map(repr, valid))}, got {value!r}")
    return value


#: How far ``a / b`` may be from an integer ``n`` for ``a`` to count as ``n`` times ``b``, in
#: units of float64's epsilon relative to ``n``. A time written in decimal (``0.3``, ``0.1``)
#: is within eps/2 (relative) of the number meant, and the division rounds once more
#: (eps/2), so ``a / b`` of an intended multiple is within ~1.5 eps n of ``n``; 4 leaves
#: room. A ratio further off is not a multiple: ``20.000000001`` is not twice ``10`` (a
#: looser rule, 1e-9 relative, once let such a run end at 20 and never count as complete,
#: and took ``0.30000000001`` as 3 sample steps of ``0.1``). Values within a few ulps of a
#: multiple (``0.30000000000000004``) are taken as the multiple: float64 cannot tell them
#: from a rounded decimal.
MULTIPLE_EPS = 4


def multiple_of(a: float, b: float) -> Optional[int]:
    """``n`` if ``a`` is ``n >= 1`` times ``b`` to within :data:`MULTIPLE_EPS` float64 eps
    relative (the rounding of times written in decimal), else ``None``; for positive
    finite ``b``. The one multiple check of sample grids, checkpoints and end times.

    Examples
    --------
    >>> from taylorball.numbers import multiple_of
    >>> multiple_of(0.3, 0.1), multiple_of(20.0, 10.0)   # 0.3 / 0.1 = 2.9999999999999996
    (3, 2)
    >>> multiple_of(20.000000001, 10.0) is None, multiple_of(0.05, 0.1) is None
    (True, True)
    """
    r = float(a) / float(b)
    if not math.isfinite(r):
        return None
    n = round(r)
    return int(n) if n >= 1 and abs(r - n) <= MULTIPLE_EPS * np.finfo(np.float64).eps * n else None


def times(name: str, t: object) -> None:
    """Refuse a time ``t`` (a number or a grid of numbers) that is not finite and real,
    naming ``name``; the values themselves are left to the caller (no conversion here, so
    high-precision inputs keep their digits)."""
    if isinstance(t, float) and math.isfinite(t):  # the common case, checked in ~0.1 us
        return

    def shown():
        r = repr(t)
        return r if len(r) <= 80 else r[:77] + "..."

    def bad():
        return UsageError(f"{name} must be a finite time or a 1-D grid of finite times, got {shown()}")

    if isinstance(t, (str, bytes, bool, np.bool_)):
        raise bad()
    try:
        arr = np.asarray(t)
    except Exception:
        raise bad() from None
    if arr.dtype.kind in "iu":
        return
    if arr.dtype.kind == "f":
        finite = bool(np.all(np.isfinite(arr)))
    elif arr.dtype.kind in "bcSUM m":
        raise bad()
    else:  # heyoka real128 / real, objects: element by element
        try:
            finite = all(math.isfinite(float(v)) for v in arr.reshape(-1))
        except (TypeError, ValueError):
            raise bad() from None
    if not finite:
        raise UsageError(f"{name} must be finite (no nan or inf), got {shown()}")


@dataclass(frozen=True)
class FpSpec:
    """A resolved number type.

    Attributes
    ----------
    name : str
        ``"float"``, ``"longdouble"``, ``"real128"`` or ``"real"``.
    fp_type : type
        What heyoka's ``fp_type`` argument takes.
    prec : int or None
        Bits of precision for ``real``; ``None`` otherwise.
    digits : int
        Significand bits (53, 64 on x86-64, 113, prec).
    """

    name: str
    fp_type: type
    prec: Optional[int]
    digits: int

    @property
    def eps(self) -> float:
        """Machine epsilon ``2^(1 - digits)``, as a Python float (it is representable
        for every type heyoka supports, down to 2^-1074)."""
        return 2.0 ** (1 - self.digits)

    @property
    def compact_mode(self) -> bool:
        """Whether heyoka should compile in compact mode: required for ``real`` (default
        mode did not finish compiling in 15 minutes here) and faster to compile for
        ``real128`` (0.7 s against 25 s, same run time)."""
        return self.name in ("real128", "real")

    @functools.cached_property
    def dtype(self) -> np.dtype:
        import heyoka as hy

        return {
            "float": np.dtype(np.float64),
            "longdouble": np.dtype(np.longdouble),
            "real128": np.dtype(hy.real128),
            "real": np.dtype(hy.real),
        }[self.name]

    def scalar(self, value: Scalar) -> Scalar:
        """One value in this type, converted without going through float64 when the
        input carries more digits (heyoka ``real128`` / ``real``, numpy long double)."""
        import heyoka as hy

        if self.name == "real":
            return hy.real(value, self.prec)
        if self.name == "real128":
            if isinstance(value, hy.real128):
                return value
            if isinstance(value, (hy.real, np.longdouble)):
                # numpy's shortest round-trip digits (repr() under numpy 2 is "np.longdouble('...')")
                return hy.real128(str(hy.real(value, 113)) if isinstance(value, hy.real)
                                  else np.format_float_scientific(value, unique=True))
            return hy.real128(float(value))
        if self.name == "longdouble":
            if isinstance(value, (hy.real, hy.real128)):
                return np.longdouble(str(value))
            return np.longdouble(value)
        return float(value)

    def array(self, values: ArrayLike) -> np.ndarray:
        """A numpy array of this type with the same shape as ``values``."""
        arr = np.asarray(values)
        if arr.dtype == self.dtype and self.name != "real":
            return arr.copy()
        flat = [self.scalar(v) for v in arr.reshape(-1)]
        out = np.empty(len(flat), dtype=self.dtype)
        for i, v in enumerate(flat):
            out[i] = v
        return out.reshape(arr.shape)

    def __str__(self) -> str:
        return f"real[{self.prec}]" if self.name == "real" else self.name


def resolve_fp_type(fp_type: FpTypeLike = float, prec: Optional[int] = None) -> FpSpec:
    """Resolve a number type.

    Parameters
    ----------
    fp_type : type or str
        ``float`` / ``numpy.float64`` / ``"float"``, ``numpy.longdouble`` /
        ``"longdouble"``, ``heyoka.real128`` / ``"real128"``, or ``heyoka.real`` /
        ``"real"`` (then ``prec`` is required).
    prec : int, optional
        Bits of precision, only for ``heyoka.real``: an integer in ``[64, 100000]``
        (see :data:`PREC_MIN`).

    Raises
    ------
    UsageError
        For an unknown type, a missing or out-of-range ``prec`` for ``real``, or a
        ``prec`` given for a fixed-precision type.
    """
    import heyoka as hy

    table = {
        float: "float",
        np.float64: "float",
        "float": "float",
        "float64": "float",
        np.longdouble: "longdouble",
        "longdouble": "longdouble",
        hy.real128: "real128",
        "real128": "real128",
        hy.real: "real",
        "real": "real",
    }
    try:
        name = table[fp_type]
    except (KeyError, TypeError):
        raise UsageError(
            f"fp_type must be one of float, numpy.longdouble, heyoka.real128, heyoka.real "
            f"(or their names {FP_TYPE_NAMES}), got {fp_type!r}"
        ) from None
    if name == "real":
        if prec is None:
            raise UsageError("fp_type=heyoka.real needs prec=<bits>, e.g. prec=256")
        prec = count("prec", prec, lo=PREC_MIN, hi=PREC_MAX)
        return FpSpec("real", hy.real, prec, prec)
    if prec is not None:
        raise UsageError(f"prec is only for fp_type=heyoka.real; fp_type={name} has fixed precision, got prec={prec!r}")
    digits = {"float": 53, "longdouble": int(np.finfo(np.longdouble).nmant) + 1, "real128": 113}[name]
    return FpSpec(name, {"float": float, "longdouble": np.longdouble, "real128": hy.real128}[name], None, digits)
