"""The package's one colour scheme for orbits classified by MEGNO.

An orbit is *chaotic* when its time-averaged MEGNO ``<Y>`` exceeds :data:`CHAOTIC_MEGNO`
(quasi-periodic orbits tend to 2, chaotic ones grow like ``lambda_max t / 2``), *regular*
otherwise, and *pending* while ``<Y>`` is not known yet. ``taylorball explore`` colours
its crossings with these, and the figures (``taylorball.figures._common``) take theirs from
here: one colour for one meaning everywhere.
Plain data, no imports: any layer may use it.
"""

from __future__ import annotations

from typing import Dict, Optional

__all__ = ["CHAOTIC_MEGNO", "COLORS", "STABILITY_COLORS", "megno_class", "color_of"]

#: The chaos threshold on ``<Y>`` (the package's vocabulary: ``<Y> > 4`` is chaotic).
CHAOTIC_MEGNO = 4.0

#: Colours of the classes (CSS / matplotlib names or hex).
COLORS: Dict[str, str] = {
    "regular": "#0072B2",  # blue (Okabe & Ito's colour-blind-safe palette)
    "chaotic": "#000000",  # black
    "pending": "#a6a6a6",  # grey: <Y> not known yet
}

#: Colours of periodic orbits by the stability of their multipliers
#: (:attr:`taylorball.PeriodicOrbit.stability`; Okabe & Ito's palette, apart from the classes').
STABILITY_COLORS: Dict[str, str] = {
    "elliptic": "#009E73",  # bluish green
    "hyperbolic": "#D55E00",  # vermillion
    "parabolic": "#E69F00",  # orange
}


def megno_class(mean_Y: Optional[float]) -> str:
    """``"chaotic"`` if ``mean_Y > CHAOTIC_MEGNO``, ``"regular"`` if not, ``"pending"`` for
    ``None`` (or NaN: not known)."""
    if mean_Y is None or mean_Y != mean_Y:
        return "pending"
    return "chaotic" if mean_Y > CHAOTIC_MEGNO else "regular"


def color_of(mean_Y: Optional[float]) -> str:
    """The colour of an orbit with ``<Y> = mean_Y`` (see :func:`megno_class`)."""
    return COLORS[megno_class(mean_Y)]
