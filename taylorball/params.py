"""Physical parameters of the Chaplygin ball on a rotating plane.

Two parameter sets are used by the paper:

* :class:`BallParams` -- a real ball: principal moments of inertia ``I = (I1, I2, I3)``
  about the centre (which is also the centre of mass), mass ``m``, radius ``a`` and the
  angular velocity ``Omega`` of the supporting plane. It serves the full system (paper
  eqs. (8)-(10) [eq6]) and the reduced system (paper eqs. (15)-(16) [eq10]).
* :class:`MParallelParams` -- the parameters of the closed system (paper eq. (22) [Mpn2]) of section 5,
  ``a_i = 1/(I_i + m a^2)``, ``d = m a^2`` and ``Omega``. The paper's Fig. 1 uses
  ``a = (1, 2, 3)``, ``d = 4``, which no real body has (it needs ``I_i < 0``); such values
  are accepted, with a :class:`UnphysicalParametersWarning`.

Both are frozen dataclasses validated on construction; bad values raise
:class:`~taylorball.errors.ParameterError` naming the field, the value and the valid form.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Tuple

from .errors import ParameterError

__all__ = ["BallParams", "MParallelParams", "UnphysicalParametersWarning"]


class UnphysicalParametersWarning(UserWarning):
    """Parameters that define a well-posed system but correspond to no real rigid ball."""


def _finite(name: str, value) -> float:
    if isinstance(value, (str, bytes, bool)) or type(value).__name__ == "bool_":
        raise ParameterError(f"{name} must be a real number, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a real number, got {value!r}") from None
    if not math.isfinite(x):
        raise ParameterError(f"{name} must be finite, got {value!r}")
    return x


# The float64 range the equations can use. The code squares momenta (the integral C2 =
# |M|^2, |K|^2 and their scales, with |M| ~ (I_i + m a^2) |omega|), the plane rate
# (Omega**2 in the energy, formed as a Python float, which raises OverflowError above
# ~1.3e154) and lengths (|R|^2 ~ a^2). A square stays a normal float64 number (2.2e-308 ..
# 1.8e308) when the scale is within 1e-150 .. 1e150; the margin, a factor 1e8 in the
# squares, is for the state's own size relative to these scales (rates up to ~1e4 times
# |Omega| or 1 in the parameters' units). Beyond it C2 is inf (I_i = 1e200), E is -inf
# (Omega = 1e160), or C2 underflows to 0 and carries no digit (I_i = m = 1e-300).
_SCALE_MAX = 1e150
_SCALE_MIN = 1e-150
_SCALE_WHY = ("the equations square these scales (|M|^2 ~ ((I_i + m a^2) omega)^2, Omega^2, |R|^2 ~ a^2), "
              "and a square must stay a normal float64 number with room for the state; rescale the units "
              "of mass, length or time")


def _in_scale(given: str, what: str, value: float, *, lo: bool = True) -> None:
    """Refuse ``value`` (named ``what``, computed from the fields ``given``) outside
    ``[_SCALE_MIN, _SCALE_MAX]`` in magnitude (``lo=False``: only above)."""
    if abs(value) > _SCALE_MAX or (lo and abs(value) < _SCALE_MIN):
        rng = f"in {_SCALE_MIN:g} .. {_SCALE_MAX:g}" if lo else f"at most {_SCALE_MAX:g}"
        raise ParameterError(f"{given}: {what} = {value!r} is out of range: it must be {rng}; {_SCALE_WHY}")


def _plane_rate_in_range(plane_rate: float, scale: float, scale_name: str) -> None:
    """``|Omega|`` and ``|Omega| * scale`` (a momentum per unit rate) at most 1e150."""
    bound = _SCALE_MAX / max(1.0, scale)
    if abs(plane_rate) > bound:
        raise ParameterError(
            f"plane_rate={plane_rate!r} is out of range: |Omega| and |Omega| * {scale_name} "
            f"(= {abs(plane_rate) * scale:.3g}) must be at most {_SCALE_MAX:g}, so here |plane_rate| <= "
            f"{bound:.3g}; {_SCALE_WHY}")


def _positive(name: str, value) -> float:
    x = _finite(name, value)
    if not x > 0.0:
        raise ParameterError(f"{name} must be > 0, got {value!r}")
    return x


def _triple(name: str, value) -> Tuple[float, float, float]:
    if isinstance(value, (str, bytes)):  # "234" is not the triple (2, 3, 4)
        raise ParameterError(
            f"{name} must be a sequence of three numbers (x1, x2, x3), got the string {value!r}"
        )
    try:
        items = tuple(value)
    except TypeError:
        raise ParameterError(
            f"{name} must be a sequence of three numbers (x1, x2, x3), got {value!r}"
        ) from None
    if len(items) != 3:
        raise ParameterError(
            f"{name} must have exactly three components (x1, x2, x3), got {len(items)}: {value!r}"
        )
    x1, x2, x3 = (_positive(f"{name}[{i}]", v) for i, v in enumerate(items))
    return (x1, x2, x3)


@dataclass(frozen=True)
class BallParams:
    """A balanced ball rolling without slipping on a plane rotating at a constant rate.

    Parameters
    ----------
    inertia : (3,) sequence of float
        Principal moments of inertia ``(I1, I2, I3)`` about the centre; each > 0 and
        obeying the triangle inequalities ``I_i + I_j >= I_k`` of a rigid body.
    mass : float
        Mass ``m > 0``.
    radius : float
        Radius ``a > 0``.
    plane_rate : float
        Angular velocity ``Omega`` of the plane about the vertical (any finite real; 0 is
        the classical Chaplygin ball on a fixed plane).

    Raises
    ------
    ParameterError
        On a non-finite or non-positive moment, mass or radius, a non-finite plane rate,
        moments violating a triangle inequality, or scales the float64 equations cannot
        carry: each ``I_i + m a^2`` and the radius must lie in ``1e-150 .. 1e150``, and
        ``|Omega|`` and ``|Omega| max_i (I_i + m a^2)`` be at most ``1e150`` (the equations
        square momenta, ``Omega`` and lengths; a square must stay a normal float64 number
        with room for the state's own size: rescale the units of mass, length or time).

    Warns
    -----
    UnphysicalParametersWarning
        If ``I1 + I2 + I3 > 2 m a^2``: all mass of a body inside a sphere of radius ``a``
        gives ``I1 + I2 + I3 = 2 sum m_k r_k^2 <= 2 m a^2``, so such a ball cannot exist,
        although the equations stay well posed.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL
    >>> ball = tb.BallParams(inertia=(2, 3, 4), mass=1, radius=5, plane_rate=2)
    >>> ball
    BallParams(inertia=(2.0, 3.0, 4.0), mass=1.0, radius=5.0, plane_rate=2.0)
    >>> ball == FIG4_BALL                          # the ball of Figs. 4 and 5
    True
    >>> ball.to_mparallel().d                      # m a^2
    25.0
    >>> tb.BallParams(inertia=(1, 1, 3), mass=1, radius=1)
    Traceback (most recent call last):
    ...
    taylorball.errors.ParameterError: inertia=(1.0, 1.0, 3.0) violates the rigid-body triangle inequality ...
    """

    inertia: Tuple[float, float, float]
    mass: float
    radius: float
    plane_rate: float = 0.0

    def __post_init__(self) -> None:
        inertia = _triple("inertia", self.inertia)
        object.__setattr__(self, "inertia", inertia)
        object.__setattr__(self, "mass", _positive("mass", self.mass))
        object.__setattr__(self, "radius", _positive("radius", self.radius))
        object.__setattr__(self, "plane_rate", _finite("plane_rate", self.plane_rate))
        d = self.mass * self.radius**2 if self.radius < 1e154 else math.inf
        if not (math.isfinite(d) and d > 0 and all(math.isfinite(i + d) and 1.0 / (i + d) > 0 for i in inertia)
                and math.isfinite(sum(inertia))):
            raise ParameterError(
                f"mass={self.mass!r}, radius={self.radius!r} with inertia={inertia!r}: d = m a^2 = {d!r} and "
                "I_i + m a^2 must be finite, nonzero float64 numbers with finite nonzero inverses "
                "(the equations use 1/(I_i + m a^2)); rescale the units of mass or length"
            )
        given = f"inertia={inertia!r}, mass={self.mass!r}, radius={self.radius!r}"
        for k, i in enumerate(inertia):
            _in_scale(given, f"I{k + 1} + m a^2 (a momentum per unit rate)", i + d)
        _in_scale(f"radius={self.radius!r}", "the radius a (|R| ~ a)", self.radius)
        _plane_rate_in_range(self.plane_rate, max(inertia) + d, "max_i (I_i + m a^2)")
        for k in range(3):
            i, j = [n for n in range(3) if n != k]
            if inertia[i] + inertia[j] < inertia[k]:
                raise ParameterError(
                    f"inertia={inertia!r} violates the rigid-body triangle inequality "
                    f"I{i + 1} + I{j + 1} >= I{k + 1} ({inertia[i]} + {inertia[j]} < {inertia[k]}); "
                    "principal moments of a real body satisfy I_i + I_j >= I_k for all i, j, k"
                )
        if sum(inertia) > 2.0 * self.mass * self.radius**2:
            warnings.warn(
                f"inertia={inertia!r} with mass={self.mass!r}, radius={self.radius!r}: "
                f"I1 + I2 + I3 = {sum(inertia)!r} > 2 m a^2 = {2.0 * self.mass * self.radius**2!r}, "
                "so no body inside a sphere of that radius has these moments",
                UnphysicalParametersWarning,
                stacklevel=3,
            )

    # -- derived quantities -------------------------------------------------------------
    @property
    def d(self) -> float:
        """``d = m a^2`` (section 5)."""
        return self.mass * self.radius**2

    @property
    def pars(self) -> Tuple[float, ...]:
        """Runtime parameter vector of the full and reduced systems:
        ``(I1, I2, I3, m, a, Omega)``; derived constants are formed inside the expression
        graph in the working precision."""
        return (*self.inertia, self.mass, self.radius, self.plane_rate)

    @property
    def symmetry(self) -> str:
        """``"homogeneous"`` (I1 = I2 = I3), ``"symmetric"`` (I1 = I2 != I3) or
        ``"asymmetric"``; only the I1 = I2 symmetry of the paper (axis x3) counts."""
        i1, i2, i3 = self.inertia
        if i1 == i2 == i3:
            return "homogeneous"
        if i1 == i2:
            return "symmetric"
        return "asymmetric"

    def to_mparallel(self) -> "MParallelParams":
        """Parameters ``a_i = 1/(I_i + m a^2)``, ``d = m a^2`` of the M||gamma system.

        Rounded to float64; code that needs them in higher precision forms them from
        :attr:`pars` in that precision."""
        d = self.d
        a1, a2, a3 = (1.0 / (i + d) for i in self.inertia)
        return MParallelParams(a=(a1, a2, a3), d=d, plane_rate=self.plane_rate)


@dataclass(frozen=True)
class MParallelParams:
    """Parameters of the M||gamma system (paper eq. (22) [Mpn2]) of section 5.

    Parameters
    ----------
    a : (3,) sequence of float
        ``(a1, a2, a3)``, each > 0; for a real ball ``a_i = 1/(I_i + m a^2)``.
    d : float
        ``d = m a^2 > 0``.
    plane_rate : float
        ``Omega``, any finite real.

    Raises
    ------
    ParameterError
        On non-positive or non-finite ``a_i`` or ``d``, non-finite ``plane_rate``; ``a_i``
        outside ``1e-150 .. 1e150``, ``d`` above ``1e150``, or ``|Omega|`` or
        ``|Omega| max(d, 1/a_i)`` above ``1e150`` (as for :class:`BallParams`).

    Warns
    -----
    UnphysicalParametersWarning
        When the implied moments ``I_i = 1/a_i - d`` are not those of a rigid body
        (some ``I_i <= 0`` or a triangle inequality fails). The paper's Fig. 1 values
        ``a = (1, 2, 3)``, ``d = 4`` are of this kind. Also when ``1 - d (gamma, A gamma)``
        changes sign on the sphere ``|gamma| = 1`` (``min d a_i < 1 < max d a_i``): the
        vector field is then singular on a cone of directions ``gamma``.

    Notes
    -----
    :attr:`physical` tells whether a real ball has these parameters.

    Examples
    --------
    >>> import warnings
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL
    >>> p = FIG4_BALL.to_mparallel()              # a_i = 1/(I_i + m a^2), d = m a^2
    >>> [round(a, 6) for a in p.a], p.d, p.physical
    ([0.037037, 0.035714, 0.034483], 25.0, True)
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     fig1 = tb.MParallelParams(a=(1, 2, 3), d=4, plane_rate=0.5)   # the paper's Fig. 1
    >>> fig1.physical, caught[0].category.__name__
    (False, 'UnphysicalParametersWarning')
    """

    a: Tuple[float, float, float]
    d: float
    plane_rate: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", _triple("a", self.a))
        object.__setattr__(self, "d", _positive("d", self.d))
        object.__setattr__(self, "plane_rate", _finite("plane_rate", self.plane_rate))
        for k, ai in enumerate(self.a):  # a_i = 1/(I_i + m a^2)
            _in_scale(f"a={self.a!r}", f"a{k + 1} = 1/(I{k + 1} + m a^2)", ai)
        _in_scale(f"d={self.d!r}", "d = m a^2", self.d, lo=False)
        _plane_rate_in_range(self.plane_rate, max(self.d, 1.0 / min(self.a)), "max(d, 1/a_i)")
        if not self.physical:
            warnings.warn(
                f"MParallelParams(a={self.a!r}, d={self.d!r}) implies moments of inertia "
                f"I_i = 1/a_i - d = {self.inertia!r}, which no rigid body has "
                "(need I_i > 0 and I_i + I_j >= I_k); the equations are still integrated as given",
                UnphysicalParametersWarning,
                stacklevel=3,
            )
        da = [self.d * ai for ai in self.a]
        if min(da) < 1.0 < max(da):
            warnings.warn(
                f"MParallelParams(a={self.a!r}, d={self.d!r}): d*a_i = {tuple(da)!r} straddle 1, "
                "so 1 - d (gamma, A gamma) vanishes on a cone of directions gamma and the "
                "angular velocity (paper eq. (19) [sved]) is singular there",
                UnphysicalParametersWarning,
                stacklevel=3,
            )

    @property
    def inertia(self) -> Tuple[float, float, float]:
        """Implied principal moments ``I_i = 1/a_i - d`` (negative for unphysical values)."""
        i1, i2, i3 = (1.0 / ai - self.d for ai in self.a)
        return (i1, i2, i3)

    @property
    def physical(self) -> bool:
        """True when some real rigid body (``I_i > 0``, triangle inequalities) has these
        parameters."""
        i = self.inertia
        if min(i) <= 0.0:
            return False
        return all(i[p] + i[q] >= i[r] * (1.0 - 1e-12) for p, q, r in ((0, 1, 2), (1, 2, 0), (2, 0, 1)))

    @property
    def pars(self) -> Tuple[float, ...]:
        """Runtime parameter vector of the M||gamma system: ``(a1, a2, a3, d, Omega)``."""
        return (*self.a, self.d, self.plane_rate)

    @property
    def symmetric(self) -> bool:
        """True when ``a1 == a2`` (section 5, item 3: the integrable case)."""
        return self.a[0] == self.a[1]
