r"""Periodic orbits found on the paper's levels, stored as start states: :func:`fig3_saddle`,
:func:`catalog_orbit`.

Each entry is a state on the section with what Newton needs to find the orbit again
(``k``, the section, the shift ``theta``, the level). The numbers of an entry are a
*guess*: :func:`fig3_saddle` solves the orbit again by :func:`taylorball.periodic_orbit`
(all its checks run) and compares the result with the stored period and trace, so an entry
that no longer describes an orbit fails loudly instead of being returned.

``FIG3_SADDLE``: a hyperbolic relative periodic orbit of the dynamically symmetric ball on
the Fig. 3 level (``I = (2, 2, 3)``, ``Omega = 2``, ``G = 10, H = 6, h = 5``), crossing the
paper's section ``g = 0`` (increasing) 4 times per period. How it was found (docs/skeleton.md,
"The saddle branch of the symmetric ball"): the elliptic relative fixed point of the Fig. 3
level followed in ``Omega`` down to its fold at ``Omega = 1.86834``, where the branch turns
back as a saddle, and the saddle branch followed back up to ``Omega = 2`` by
pseudo-arclength, on sections ``g = g0`` changed where the orbit grazed the current one
(``g0 = 0, 1, 0.55, 5.75, 5.92, 3.83``), and finally put on ``g = 0``, where it is a
fixed point of ``P^4``.

``FIG4A_SADDLE_K10``, ``FIG4A_SADDLE_FOCUS_K14`` and their images under the reversor
``sigma1`` (``..._R``; all four in ``FIG4A_ORBITS``): the Fig. 4 ball on the Fig. 4a level at
the paper's ``Omega = 2``, a saddle with 10 and a saddle-focus with 14 crossings of ``g = 0``
per period, found by multiple shooting from near-recurrences of chaotic orbits (docs/skeleton.md, "The Fig. 4a and 4b levels at
Omega = 2").

``FIG4B_REFLECTION_SADDLE_K11`` (in ``FIG4B_ORBITS``): the Fig. 4 ball on the Fig. 4b level at
``Omega = 2``, a reflection saddle with 11 crossings, found by multiple shooting with its slow
returns split in time (docs/skeleton.md, "Segments split in time").

``FIG4B_SADDLE_SLOW``: the Fig. 4 ball (``I = (2, 3, 4)``) on the Fig. 4b level at
``Omega = 1.24994``: a saddle with 30 crossings of ``g = 0.55`` per period, reached from the
Fig. 3 saddle branch by a homotopy in the inertia (docs/skeleton.md). Not yet followed to
``Omega = 2``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Tuple

import numpy as np

from ._typing import KindName
from .levels import Levels
from .paper import FIG3_BALL, FIG3_LEVELS, FIG4_BALL, FIG4A_LEVELS, FIG4B_LEVELS
from .params import BallParams
from .errors import IntegrationError
from .periodic import NewtonOptions, PeriodicOrbit, periodic_orbit

__all__ = ["CatalogOrbit", "FIG3_SADDLE", "FIG4B_SADDLE_SLOW", "FIG4B_SADDLE_Q1", "SYMMETRIC_H4_REFLECTION_SADDLE",
           "TZENOFF_D35_REFLECTION_SADDLE", "TZENOFF_D35_H30_ELLIPTIC", "FIG4A_SADDLE_K10", "FIG4A_SADDLE_K10_R",
           "FIG4A_SADDLE_FOCUS_K14", "FIG4A_SADDLE_FOCUS_K14_R", "FIG4A_ORBITS", "FIG4B_REFLECTION_SADDLE_K11",
           "FIG4B_ORBITS", "catalog_orbit", "fig3_saddle"]


@dataclass(frozen=True)
class CatalogOrbit:
    """A stored start for :func:`taylorball.periodic_orbit` and what the orbit must come out as.

    Attributes
    ----------
    name : str
    kind : str
    ball : BallParams
        The parameters (``plane_rate`` included).
    levels : Levels
    state : tuple of float
        Public-layout state on the section (float64, 17 significant digits).
    k : int
    g0 : float
    direction : int
    shift : float
        ``theta`` of a relative periodic orbit (0 else).
    period, trace : float
        Of the float64 solution (the checks of :func:`fig3_saddle`).
    multipliers : tuple of float
        Of the float64 solution (for the reader; not checked).
    note : str
    """

    name: str
    kind: KindName
    ball: BallParams
    levels: Levels
    state: Tuple[float, ...]
    k: int
    g0: float
    direction: int
    shift: float
    period: float
    trace: float
    multipliers: Tuple[float, ...]
    note: str


FIG3_SADDLE = CatalogOrbit(
    name="fig3_saddle",
    kind="reduced",
    ball=FIG3_BALL,
    levels=FIG3_LEVELS,
    state=(0.6785509090333981, 2.201650715331273, -5.260353171233687, -0.3213445392329366, -0.7243600458664989,
           -0.6099509907012656, 2.948288083858613, 8.460544931794171, -11.600763173690869),
    k=4,
    g0=0.0,
    direction=1,
    shift=3.8251251718562975,
    period=30.215844801841875,
    trace=2.6863282199482015,
    multipliers=(0.446454, 2.23987),
    note=("Fig. 3 level (paper.FIG3_BALL, paper.FIG3_LEVELS), Omega = 2: a saddle of the symmetric ball's map "
          "of (r1, r2) with period 4 (relative periodic orbit, P^4 x = S_theta x), its section points at "
          "(r1, r2) = (-7.0759, +-0.5831), (-0.17667, +-0.44586); found 2026-11-28."),
)
"""The Fig. 3 level's saddle (see the module docstring)."""


FIG4B_SADDLE_SLOW = CatalogOrbit(
    name="fig4b_saddle_slow",
    kind="reduced",
    ball=BallParams(inertia=FIG4_BALL.inertia, mass=FIG4_BALL.mass, radius=FIG4_BALL.radius,
                    plane_rate=1.2499370629362423),
    levels=FIG4B_LEVELS,
    state=(-0.809434648995873, 0.6785674165151954, -1.4707440367630988, -0.18172146229816757, 0.6363548373290473,
           -0.7496864885724815, -0.9715944030829559, -2.1483929289381996, -1.5881047548175005),
    k=30,
    g0=0.55,
    direction=1,
    shift=0.0,
    period=78.72606278229765,
    trace=6.397246462529807,
    multipliers=(0.189925, 1.01381, 5.19351),
    note=("The Fig. 4 ball (I = (2, 3, 4)) on the Fig. 4b level, but at Omega = 1.24994 (not 2): a periodic "
          "orbit with 30 increasing crossings of g = 0.55 per period, points 15 apart related by the rotation "
          "by pi about the body axis 3 (a symmetry of every ball). From the Fig. 3 saddle branch at theta = pi "
          "(Omega = 1.9133543369) by a homotopy in the inertia I = (2, 2 + s, 3 + s) with Omega as an unknown; "
          "found 2026-11-28."),
)
"""An orbit of the Fig. 4 ball on the Fig. 4b level at ``Omega = 1.24994`` (see its note)."""


FIG4B_SADDLE_Q1 = CatalogOrbit(
    name="fig4b_saddle_q1",
    kind="reduced",
    ball=BallParams(inertia=FIG4_BALL.inertia, mass=FIG4_BALL.mass, radius=FIG4_BALL.radius,
                    plane_rate=1.4231153420351856),
    levels=FIG4B_LEVELS,
    state=(-0.9778882429884245, 3.966133740626496, -2.639356965597298, -0.6212950960111386, 0.7052139539973052,
           0.3415635852370635, 2.524601117596155, 8.516731402095328, -12.992004198509623),
    k=19,
    g0=3.15,
    direction=1,
    shift=0.0,
    period=37.307582931950236,
    trace=3.8044085292701704,
    multipliers=(0.421755, 0.991655, 2.39100),
    note=("The Fig. 4 ball (I = (2, 3, 4)) on the Fig. 4b level at Omega = 1.42312 (not 2): a saddle with 19 "
          "increasing crossings of g = 3.15 per period, symmetric under no reversor. From the Fig. 3 saddle branch "
          "where theta = 2 pi (Omega = 2.30775788322, reached by continue_arclength with section switching) by "
          "inertia_homotopy with q = 1, phase 0 (I = (2, 2 + s, 3 + s), Omega an unknown); found 2026-11-28."),
)
"""An orbit of the Fig. 4 ball on the Fig. 4b level at ``Omega = 1.42312`` (see its note)."""


SYMMETRIC_H4_REFLECTION_SADDLE = CatalogOrbit(
    name="symmetric_h4_reflection_saddle",
    kind="reduced",
    ball=FIG3_BALL,
    levels=Levels.from_caption(G=10.0, H=4.0, h=5.0),
    state=(-2.0096777939297383e-06, 0.7625166684045395, -1.2442583745630325, -6.80678724117843e-07,
           0.2582647202795352, -0.9660741867260869, -4.396194868197657e-07, 0.16680145694402843,
           0.04459174275855269),
    k=1,
    g0=0.0,
    direction=1,
    shift=-4.3953578472979355,
    period=29.473799468328068,
    trace=-5.476026592462107,
    multipliers=(-0.189148, -5.28688),
    note=("The Fig. 3 ball (dynamically symmetric, Tzenoff's case) at Omega = 2 on the level G = 10, H = 4, "
          "h = 5: a reflection saddle of the map of (r1, r2) at (0.043079, 0), a relative periodic orbit "
          "with k = 1. The Fig. 3 level's elliptic relative orbit (H = 6) followed down in H by "
          "continue_in_level; it period-doubles at H = 4.6604. Its manifolds (of F^2: "
          "periodic_manifolds.iterate(orbit, 2)) cross the reversor's line r2 = 0 at angles up to 87 degrees; "
          "found 2026-11-28."),
)
"""A strongly hyperbolic relative periodic orbit of Tzenoff's case (see its note)."""


TZENOFF_D35_REFLECTION_SADDLE = CatalogOrbit(
    name="tzenoff_d35_reflection_saddle",
    kind="reduced",
    ball=BallParams(inertia=(2.0, 2.0, 3.0), mass=3.5, radius=1.0, plane_rate=3.0),
    levels=Levels(C=10.0, M_gamma=6.0, h=-20.0),
    state=(2.607446466749703, -0.37055647578101175, -1.5049479378525874, 0.9735696270266728, -0.13835855674081962,
           -0.18171156019291296, -0.2567863856140836, 0.03649312048976138, -1.4035901781867497),
    k=1,
    g0=0.0,
    direction=1,
    shift=2.364230014584476,
    period=4.7064832371655,
    trace=-3.740901680530986,
    multipliers=(-0.289759, -3.45114),
    note=("A dynamically symmetric ball (Tzenoff's case) with d = m a^2 = 7/2, the smallest physical for I = "
          "(2, 2, 3), at Omega = 3 on the level C = 10, M_gamma = 6, h = -20: a reflection saddle of the map of "
          "(r1, r2) at (-0.255049, 0), k = 1; the orbit proved by Krawczyk in docs/rigorous.md. Its manifolds (of "
          "F^2: periodic_manifolds.iterate(orbit, 2)) cross the reversor's line r2 = 0 at r1 = 0.0103008, 77.4 "
          "degrees; found 2026-11-28."),
)
"""The reflection saddle of Tzenoff's case proved in docs/rigorous.md (see its note)."""


TZENOFF_D35_H30_ELLIPTIC = CatalogOrbit(
    name="tzenoff_d35_h30_elliptic",
    kind="reduced",
    ball=BallParams(inertia=(2.0, 2.0, 3.0), mass=3.5, radius=1.0, plane_rate=3.0),
    levels=Levels(C=10.0, M_gamma=6.0, h=-30.0),
    state=(0.0, 1.7724177283544267, -2.274172773180445, 0.0, 0.9146722083972939, -0.4041964264879361, 0.0,
           -0.6767622484385177, -1.5314722738095574),
    k=1,
    g0=0.0,
    direction=1,
    shift=-2.831673465245669,
    period=4.630377928247846,
    trace=1.0635940048828738,
    multipliers=(0.531797, 0.846872),
    note=("Tzenoff's case with d = m a^2 = 7/2 at Omega = 3 on the level C = 10, M_gamma = 6, h = -30: the "
          "elliptic relative periodic orbit proved in docs/rigorous.md, at (r1, r2) = (-0.619016, 0), k = 1 "
          "(multipliers 0.531797 +- 0.846872 i). Followed down in Omega it meets the level's saddle at "
          "(-0.72621, 0) at a fold at Omega ~ 2.995 (docs/skeleton.md); found 2026-11-28."),
)
"""The elliptic relative periodic orbit of Tzenoff's case proved in docs/rigorous.md (see its note)."""


FIG4A_SADDLE_K10 = CatalogOrbit(
    name="fig4a_saddle_k10",
    kind="reduced",
    ball=FIG4_BALL,
    levels=FIG4A_LEVELS,
    state=(-2.9246995769487554, 0.5171937199678931, -3.951755491135914, 0.8469368235424024, -0.2574510200305668,
           -0.4652063942092007, -5.995795403692148, 0.8703106991679885, -11.39735471622332),
    k=10,
    g0=0.0,
    direction=1,
    shift=0.0,
    period=25.30133177801756,
    trace=16.163009349115868,
    multipliers=(0.0155365, 7.16786, 8.97961),
    note=("The Fig. 4 ball (I = (2, 3, 4)) on the Fig. 4a level (G = 10, H = 2, h = 5) at the paper's Omega = 2: "
          "a saddle with 10 increasing crossings of g = 0 per period, symmetric under no reversor. Found by multiple "
          "shooting (periodic_shooting.shoot_periodic_orbit, 10 segments of one crossing) from a near-recurrence "
          "x_i ~ x_{i+10} of a chaotic orbit (internal-state distance 0.27); found 2026-11-28."),
)
"""A saddle of the Fig. 4 ball on the Fig. 4a level at ``Omega = 2`` (see its note)."""


FIG4A_SADDLE_K10_R = CatalogOrbit(
    name="fig4a_saddle_k10_r",
    kind="reduced",
    ball=FIG4_BALL,
    levels=FIG4A_LEVELS,
    state=(2.924699576948787, 0.5171937199677896, -3.9517554911359025, -0.8469368235424126, -0.2574510200305342,
           -0.4652063942092001, 5.995795403692167, 0.8703106991677587, -11.397354716223312),
    k=10,
    g0=0.0,
    direction=1,
    shift=0.0,
    period=25.30133177801754,
    trace=64.61548021371496,
    multipliers=(0.111363, 0.139512, 64.3646),
    note=("The image of FIG4A_SADDLE_K10 under the reversor sigma1 (time reversed: its multipliers are the "
          "inverses of that orbit's), solved by multiple shooting from the reflected state; found 2026-11-28."),
)
"""The ``sigma1`` image of :data:`FIG4A_SADDLE_K10` (see its note)."""


FIG4A_SADDLE_FOCUS_K14 = CatalogOrbit(
    name="fig4a_saddle_focus_k14",
    kind="reduced",
    ball=FIG4_BALL,
    levels=FIG4A_LEVELS,
    state=(1.9160806487243598, 2.481651644561508, -3.1684485113824423, 0.05065717079834614, -0.7923615132363814,
           -0.6079449674012106, 5.194079441141384, 6.62544177856886, -8.202432739023537),
    k=14,
    g0=0.0,
    direction=1,
    shift=0.0,
    period=26.246576687011146,
    trace=3.931058155480308,
    multipliers=(0.0214337, 6.83048, 6.83048),
    note=("The Fig. 4 ball on the Fig. 4a level at Omega = 2: a saddle-focus (multipliers 0.0214337 and "
          "1.95481 +- 6.54478 i) with 14 increasing crossings of g = 0 per period, symmetric under no reversor. Found by "
          "multiple shooting (14 segments of one crossing) from a near-recurrence x_i ~ x_{i+14} of a chaotic "
          "orbit (internal-state distance 0.27); found 2026-11-28."),
)
"""A saddle-focus of the Fig. 4 ball on the Fig. 4a level at ``Omega = 2`` (see its note)."""


FIG4A_SADDLE_FOCUS_K14_R = CatalogOrbit(
    name="fig4a_saddle_focus_k14_r",
    kind="reduced",
    ball=FIG4_BALL,
    levels=FIG4A_LEVELS,
    state=(-0.522123639118462, 0.30635030698186794, -0.7192914478859134, 0.5325041318564518, 0.24200718532984566,
           -0.8110930105755643, -1.2979783493731107, 0.9085703776650446, -0.581065633883549),
    k=14,
    g0=0.0,
    direction=1,
    shift=0.0,
    period=26.24657668701113,
    trace=46.73922170494693,
    multipliers=(0.146402, 0.146402, 46.6554),
    note=("The image of FIG4A_SADDLE_FOCUS_K14 under the reversor sigma1 (multipliers 0.0418989 +- 0.140279 i "
          "and 46.6554, the inverses of that orbit's); found by the same search from another near-recurrence "
          "(distance 0.44), 2026-11-28."),
)
"""The ``sigma1`` image of :data:`FIG4A_SADDLE_FOCUS_K14` (see its note)."""


#: The catalogued orbits of the Fig. 4 ball on the Fig. 4a level at ``Omega = 2``.
FIG4A_ORBITS = (FIG4A_SADDLE_K10, FIG4A_SADDLE_K10_R, FIG4A_SADDLE_FOCUS_K14, FIG4A_SADDLE_FOCUS_K14_R)


FIG4B_REFLECTION_SADDLE_K11 = CatalogOrbit(
    name="fig4b_reflection_saddle_k11",
    kind="reduced",
    ball=FIG4_BALL,
    levels=FIG4B_LEVELS,
    state=(0.24204948921073632, 0.7112058520696758, 4.072639644942961, -0.25035964496941526, 0.9344111456406329,
           0.25336901758768443, 1.7751617485703735, -2.1948486902000597, 9.848559891066712),
    k=11,
    g0=0.0,
    direction=1,
    shift=0.0,
    period=89.88673592121674,
    trace=-2.5261542646758057,
    multipliers=(-0.190511, 1.40372, -3.73937),
    note=("The Fig. 4 ball (I = (2, 3, 4)) on the Fig. 4b level (G = 10, H = 6, h = 5) at the paper's Omega = 2: "
          "a reflection saddle with 11 increasing crossings of g = 0 per period (four slow returns of 19..22 "
          "time units among seven of ~1.1), symmetric under no reversor. Found by multiple shooting with the slow "
          "returns split in time (periodic_shooting_family.recurrence_shooting, segments ks = (3, 2, 1, 1, 1, "
          "2, 1)) from a near-recurrence x_i ~ x_{i+11} of an orbit of the level; found 2026-11-28."),
)
"""A reflection saddle of the Fig. 4 ball on the Fig. 4b level at ``Omega = 2`` (see its note)."""

FIG4B_ORBITS = (FIG4B_REFLECTION_SADDLE_K11,)


def catalog_orbit(entry: CatalogOrbit) -> PeriodicOrbit:
    """The orbit of a catalogue entry, solved by Newton (float64) from its stored state.

    Raises
    ------
    IntegrationError
        (:class:`taylorball.periodic.NewtonFailure`) if the entry does not give an orbit, or
        one whose period or trace differs from the stored ones (by more than 1e-9 relative).
    """
    e = entry
    o = periodic_orbit(e.kind, e.ball, np.array(e.state), e.k, levels=e.levels, g0=e.g0,
                       direction=e.direction,  # type: ignore[arg-type]
                       options=NewtonOptions(shift=e.shift if e.shift else None))
    if abs(o.period - e.period) > 1e-9 * e.period or abs(o.trace - e.trace) > 1e-9 * abs(e.trace):
        raise IntegrationError(f"{e.name}: Newton found an orbit with period {o.period!r} and trace {o.trace!r}, "
                               f"not the stored {e.period!r}, {e.trace!r}")
    return o


def fig3_saddle() -> PeriodicOrbit:
    """The Fig. 3 level's hyperbolic relative periodic orbit, solved by Newton (float64) from
    :data:`FIG3_SADDLE`. For more digits:
    ``taylorball.periodic.refine(fig3_saddle(), (numpy.longdouble, "real128", ("real", 192)))``.
    """
    return catalog_orbit(FIG3_SADDLE)
