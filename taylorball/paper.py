"""The paper's parameter sets, the levels of its figures' captions, and the demo states, once.

Figure numbers are this project's (docs/figures.md); each constant names the caption of
``chaplygin-ball-rotating-plane.tex`` it comes from by its ``\\label``. The captions' levels
``G, H, h`` are read as ``C = |M|``, ``M_gamma = (M, gamma)``, ``h = E``
(:meth:`taylorball.levels.Levels.from_caption`; docs/errata.md, N2).

The Fig. 1 parameters describe no real ball (``I_i = 1/a_i - d < 0``), so they are built by
a function, :func:`fig1_params`, which warns :class:`~taylorball.UnphysicalParametersWarning`
on every call, as constructing them by hand does; importing this module does not warn.
"""

from __future__ import annotations

import math

import numpy as np

from .levels import Levels, MParallelLevels
from .params import BallParams, MParallelParams

__all__ = [
    "FIG1_A",
    "FIG1_D",
    "FIG1_PLANE_RATE",
    "FIG1_LEVELS",
    "fig1_params",
    "FIG2_BALL",
    "FIG2_LEVELS",
    "FIG3_BALL",
    "FIG3_LEVELS",
    "FIG4_BALL",
    "FIG4A_LEVELS",
    "FIG4B_LEVELS",
    "FIG5_BALL",
    "FIG5A_LEVELS",
    "FIG5B_LEVELS",
    "demo_reduced_state",
    "DEMO_STATES",
    "demo_state",
]

# --- Fig. 1: the M||gamma map (paper eq. (22) [Mpn2]) --------------------------------------
FIG1_A = (1.0, 2.0, 3.0)
"""Fig. 1 caption (``fig_map2d``): ``a1 = 1, a2 = 2, a3 = 3``."""

FIG1_D = 4.0
"""Fig. 1 caption (``fig_map2d``): ``d = 4``."""

FIG1_PLANE_RATE = 0.5
"""Fig. 1 caption (``fig_map2d``): ``Omega = 0.5``."""

FIG1_LEVELS = MParallelLevels(lam=2.0, h=100.0)
"""Fig. 1 caption (``fig_map2d``): ``lambda = 2``, ``h = 100``."""


def fig1_params() -> MParallelParams:
    """Fig. 1 caption (``fig_map2d``): ``MParallelParams(a=(1, 2, 3), d=4, plane_rate=0.5)``.

    Warns :class:`~taylorball.UnphysicalParametersWarning` (no real ball has these values;
    the equations are integrated as given)."""
    return MParallelParams(a=FIG1_A, d=FIG1_D, plane_rate=FIG1_PLANE_RATE)


# --- Figs. 2-5: the ball on the rotating plane ----------------------------------------------
FIG2_BALL = BallParams(inertia=(3.0, 3.0, 3.0), mass=1.0, radius=5.0, plane_rate=2.0)
"""Fig. 2 caption (``fig_Sym``, homogeneous ball):
``m = 1, a = 5, I1 = I2 = I3 = 3, Omega = 2``."""

FIG2_LEVELS = Levels.from_caption(G=10.0, H=6.0, h=5.0)
"""Fig. 2 caption (``fig_Sym``): ``H = 6, h = 5, G = 10``."""

FIG3_BALL = BallParams(inertia=(2.0, 2.0, 3.0), mass=1.0, radius=5.0, plane_rate=2.0)
"""Fig. 3 caption (``fig_DS``, dynamically symmetric ball):
``m = 1, a = 5, I1 = I2 = 2, I3 = 3, Omega = 2``."""

FIG3_LEVELS = Levels.from_caption(G=10.0, H=6.0, h=5.0)
"""Fig. 3 caption (``fig_DS``): ``H = 6, h = 5, G = 10``."""

FIG4_BALL = BallParams(inertia=(2.0, 3.0, 4.0), mass=1.0, radius=5.0, plane_rate=2.0)
"""Fig. 4 caption (``fig_map3d``, dynamically asymmetric ball):
``m = 1, a = 5, I1 = 2, I2 = 3, I3 = 4, Omega = 2``."""

FIG4A_LEVELS = Levels.from_caption(G=10.0, H=2.0, h=5.0)
"""Fig. 4a caption (``fig_map3d``): ``H = 2, h = 5, G = 10`` (chaotic)."""

FIG4B_LEVELS = Levels.from_caption(G=10.0, H=6.0, h=5.0)
"""Fig. 4b caption (``fig_map3d``): ``H = 6, h = 5, G = 10`` (invariant tori)."""

FIG5_BALL = FIG4_BALL
"""Fig. 5 caption (``fig_CP``): "parameters corresponding to Fig. 4", the ball of :data:`FIG4_BALL`."""

FIG5A_LEVELS = FIG4A_LEVELS
"""Fig. 5 caption (``fig_CP``): the levels of Fig. 4a, ``H = 2, h = 5, G = 10``."""

FIG5B_LEVELS = FIG4B_LEVELS
"""Fig. 5 caption (``fig_CP``): the levels of Fig. 4b, ``H = 6, h = 5, G = 10``."""


# --- the demo state -------------------------------------------------------------------------
def demo_reduced_state() -> np.ndarray:
    """The demo state of ``taylorball demo``, the tests and the benchmarks: reduced
    ``(omega, gamma, R) = ((0.1, 0.2, 0.3), (0.3, 0.4, sqrt(0.75)), (1, -0.5, R3))`` with
    ``R3`` such that ``(R, gamma) = 0`` (``|gamma| = 1`` to rounding). Not from the paper
    (no caption gives a state); a fresh array on every call."""
    g = np.array([0.3, 0.4, math.sqrt(0.75)])
    R = np.array([1.0, -0.5, 0.0])
    R[2] = -(R[0] * g[0] + R[1] * g[1]) / g[2]
    return np.array([0.1, 0.2, 0.3, *g, *R])


_FIG4A_DEMO = (3.356805807149699, -5.244140975225697, 0.12591699591475125, 0.12552655716025596,
               -0.10514168532696078, -0.9865030711833083, 8.03100632479802, -13.818876887107342, 2.4947155782985746)
_FIG4B_DEMO = (3.18287828402863, -4.8607886455481, -0.8694676792664636, 0.13883960156022565, -0.11629275930454501,
               -0.9834630441312642, 7.260929613420427, -12.493813148171355, 2.5024271063427044)

DEMO_STATES = {
    "fig2": (-5.0657461552081, 2.040558008162962, 0.39236147199408, -0.35686023727486843, 0.26637192322815395,
             -0.8953752116112323, -11.611650194436677, 3.793411442339271, 5.756463299621665),
    "fig3": (4.1781998845910975, -6.779236738025632, -1.3510330382886941, 0.10053785543759715, -0.08421102114966791,
             -0.9913630230853575, 10.02711436499514, -17.253561177627176, 2.4824857518500445),
    "fig4a": _FIG4A_DEMO,
    "fig4b": _FIG4B_DEMO,
    "fig5a": _FIG4A_DEMO,
    "fig5b": _FIG4B_DEMO,
}
"""A reduced state ``(omega, gamma, R)`` on the level of each figure's caption (Figs. 2-5;
the captions ``fig_Sym``, ``fig_DS``, ``fig_map3d``, ``fig_CP``): the first point of
``tb.section_admissible_sample(ball, **levels.as_kwargs(), n=1, seed=0)`` on the section
``g = 0`` (crossing upward), its first root ``K``, to the last digit. ``tests/test_levels.py``
checks with :func:`taylorball.integrals` that each lies on its level. Figs. 5a/5b share the
levels (and states) of Figs. 4a/4b."""

#: The ball and levels of each name of :data:`DEMO_STATES`.
DEMO_LEVELS = {"fig2": (FIG2_BALL, FIG2_LEVELS), "fig3": (FIG3_BALL, FIG3_LEVELS),
               "fig4a": (FIG4_BALL, FIG4A_LEVELS), "fig4b": (FIG4_BALL, FIG4B_LEVELS),
               "fig5a": (FIG5_BALL, FIG5A_LEVELS), "fig5b": (FIG5_BALL, FIG5B_LEVELS)}


def demo_state(figure: str) -> np.ndarray:
    """A reduced state ``(omega, gamma, R)`` on the level of a figure's caption, by name:
    ``"fig2"``, ``"fig3"``, ``"fig4a"``, ``"fig4b"``, ``"fig5a"``, ``"fig5b"`` (the ball and
    levels: :data:`DEMO_LEVELS`; the states: :data:`DEMO_STATES`). A fresh array on every call.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS, demo_state
    >>> I = tb.integrals("reduced", FIG4_BALL, demo_state("fig4a"))
    >>> round(float(I["C2"]) ** 0.5, 9), round(float(I["M_gamma"]), 9), round(float(I["E"]), 9)
    (10.0, 2.0, 5.0)
    """
    if figure not in DEMO_STATES:
        from .errors import UsageError

        raise UsageError(f"figure must be one of {sorted(DEMO_STATES)}, got {figure!r}")
    return np.array(DEMO_STATES[figure], dtype=float)
