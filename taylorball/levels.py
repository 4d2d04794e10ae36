"""Levels of the first integrals: the vocabulary the paper's captions are written in.

* :class:`Levels` -- the reduced system (paper eqs. (15)-(16) [eq10]) on ``C = |M|``, ``M_gamma = (M, gamma)``
  and ``h = E`` (the Jacobi integral, section 3). The captions of Figs. 2-5 name them
  ``G, H, h``; :meth:`Levels.from_caption` reads them as ``G = C``, ``H = M_gamma``, ``h = E``
  (docs/errata.md, N2).
* :class:`MParallelLevels` -- the M||gamma system (paper eq. (22) [Mpn2]) of section 5 on
  ``lambda = (K, gamma)`` and ``h = Etilde`` (the caption of Fig. 1).

Both are frozen and validated on construction: every level a finite real number, ``C > 0``
and ``|M_gamma| <= C`` (``|(M, gamma)| <= |M| |gamma|``, ``|gamma| = 1``); a bad value raises
:class:`~taylorball.errors.ParameterError` naming the field, the value and the valid form.
``as_kwargs()`` gives the keyword arguments of the chart functions
(:func:`taylorball.states_on_section`, :func:`taylorball.section_admissible_sample`, ...).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Dict, TypedDict

from .errors import ParameterError


class LevelsKwargs(TypedDict):
    """``Levels.as_kwargs()``: typed per key, so ``f(**levels.as_kwargs())`` type-checks."""

    C: float
    M_gamma: float
    h: float


class MParallelLevelsKwargs(TypedDict):
    """``MParallelLevels.as_kwargs()``."""

    lam: float
    h: float

__all__ = ["Levels", "MParallelLevels"]


def _real(cls: str, name: str, value) -> float:
    """``value`` as a finite float, or ParameterError naming ``cls.name``."""
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool)
    x = float(value) if ok else math.nan
    if not (ok and math.isfinite(x)):
        raise ParameterError(f"{cls}: {name} must be a finite real number, got {value!r}")
    return x


@dataclass(frozen=True)
class Levels:
    """Levels of the reduced system's integrals.

    Parameters
    ----------
    C : float
        ``|M|``, the length of the angular momentum about the contact point (> 0); the
        captions' ``G``.
    M_gamma : float
        The area integral ``(M, gamma)``, ``|M_gamma| <= C``; the captions' ``H``.
    h : float
        The Jacobi integral ``E``; the captions' ``h``.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> levels = tb.Levels.from_caption(G=10, H=2, h=5)   # the Fig. 4a caption
    >>> levels
    Levels(C=10.0, M_gamma=2.0, h=5.0)
    >>> levels == FIG4A_LEVELS, levels.caption
    (True, {'G': 10.0, 'H': 2.0, 'h': 5.0})
    >>> levels.as_kwargs()                         # for the charts' keyword arguments
    {'C': 10.0, 'M_gamma': 2.0, 'h': 5.0}
    >>> tb.states_on_section(FIG4_BALL, **levels.as_kwargs(), point=(2.0, 2.5, 1.0)).shape
    (2, 9)
    """

    C: float
    M_gamma: float
    h: float

    def __post_init__(self) -> None:
        C = _real("Levels", "C", self.C)
        M_gamma = _real("Levels", "M_gamma", self.M_gamma)
        h = _real("Levels", "h", self.h)
        if not C > 0.0:
            raise ParameterError(f"Levels: C = |M| must be > 0, got {self.C!r}")
        if abs(M_gamma) > C:
            raise ParameterError(
                f"Levels: M_gamma = (M, gamma) must satisfy |M_gamma| <= C = {C!r} "
                f"(|(M, gamma)| <= |M| for |gamma| = 1), got {self.M_gamma!r}"
            )
        object.__setattr__(self, "C", C)
        object.__setattr__(self, "M_gamma", M_gamma)
        object.__setattr__(self, "h", h)

    @classmethod
    def from_caption(cls, G: float, H: float, h: float) -> "Levels":
        """The levels of a caption ``G, H, h``: ``C = G = |M|``, ``M_gamma = H = (M, gamma)``,
        ``h = E``.

        Examples
        --------
        >>> import taylorball as tb
        >>> tb.Levels.from_caption(G=10, H=2, h=5)    # Fig. 4a: G = |M|, H = (M, gamma), h = E
        Levels(C=10.0, M_gamma=2.0, h=5.0)
        """
        return cls(C=G, M_gamma=H, h=h)

    @property
    def caption(self) -> Dict[str, float]:
        """The levels in the captions' names ``{"G": C, "H": M_gamma, "h": h}``."""
        return {"G": self.C, "H": self.M_gamma, "h": self.h}

    def as_kwargs(self) -> LevelsKwargs:
        """``{"C": ..., "M_gamma": ..., "h": ...}``: the keyword arguments of the chart functions."""
        return {"C": self.C, "M_gamma": self.M_gamma, "h": self.h}


@dataclass(frozen=True)
class MParallelLevels:
    """Levels of the M||gamma system (paper eq. (22) [Mpn2]): ``lam = lambda = (K, gamma)`` and ``h = Etilde``
    (finite reals)."""

    lam: float
    h: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "lam", _real("MParallelLevels", "lam", self.lam))
        object.__setattr__(self, "h", _real("MParallelLevels", "h", self.h))

    def as_kwargs(self) -> MParallelLevelsKwargs:
        """``{"lam": ..., "h": ...}``: the keyword arguments of the M||gamma chart functions."""
        return {"lam": self.lam, "h": self.h}
