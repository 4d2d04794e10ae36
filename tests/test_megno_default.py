"""MEGNO's default never calls an integrable orbit chaotic.

On a plane at rest (Omega = 0) the contact point rolls away and nearby orbits shear apart
quadratically in R, so MEGNO of the whole tangent vector (``norm="full"``) creeps to 4, the
chaos threshold, on a regular orbit. The default ``norm="compact"`` leaves R out, and every
entry point (megno, megno_many, megno_map, chaotic_fraction) reads the torus value ~2 and
says which norm it used. The homogeneous ball (integrable for every Omega) reads regular too.
"""

import math

import numpy as np

import taylorball as tb
from taylorball.paper import FIG2_BALL, FIG4B_LEVELS, demo_reduced_state

AT_REST = tb.BallParams(inertia=(2.0, 3.0, 4.0), mass=1.0, radius=5.0, plane_rate=0.0)
X0 = demo_reduced_state()
T_END = 1000.0
#: <Y> of a quasi-periodic orbit tends to 2; at t = 1000 these orbits read 1.89 .. 2.02
#: (compact) while the old default read 3.77 on X0: 2.5 separates the two with margin.
REGULAR = 2.5


def _level_of(params, x):
    d = tb.integrals("reduced", params, x)
    return tb.Levels(C=math.sqrt(d["C2"]), M_gamma=d["M_gamma"], h=d["E"])


def test_megno_and_megno_many_default_to_the_compact_norm():
    one = tb.megno("reduced", AT_REST, X0, T_END)
    many = tb.megno_many("reduced", AT_REST, [X0], T_END, workers=1)
    assert one.norm == many[0].norm == "compact"
    assert one.mean_megno < REGULAR and many[0].mean_megno < REGULAR
    old = tb.megno("reduced", AT_REST, X0, T_END, norm="full")  # still there, and what the old default read
    assert old.norm == "full" and old.mean_megno > 3.5


def test_megno_map_and_chaotic_fraction_default_to_the_compact_norm():
    lev = _level_of(AT_REST, X0)
    m = tb.megno_map(AT_REST, lev, l=3.4, r1=(-1000.0, 1000.0, 2), r2=(-500.0, 1000.0, 2), t_end=T_END, workers=1)
    assert m.attrs["norm"] == "compact"
    v = m.values[np.isfinite(m.values)]
    assert v.size == 4 and np.all(v < REGULAR)
    cf = tb.chaotic_fraction(AT_REST, lev, n=3, t_end=T_END, workers=1)
    assert cf.n_chaotic == 0 and np.all(cf.mean_megno < REGULAR)


def test_the_homogeneous_ball_reads_regular_by_default():
    x = tb.states_on_section(FIG2_BALL, **FIG4B_LEVELS.as_kwargs(), point=(0.0, 4.0, 0.0), direction=1)[0]
    assert tb.megno("reduced", FIG2_BALL, x, T_END).mean_megno < REGULAR
    assert tb.megno_many("reduced", FIG2_BALL, [x], T_END, workers=1)[0].mean_megno < REGULAR
    m = tb.megno_map(FIG2_BALL, FIG4B_LEVELS, l=0.0, r1=(-4.0, 4.0, 3), r2=(-6.0, 6.0, 3), t_end=T_END, workers=1)
    v = m.values[np.isfinite(m.values)]
    assert v.size >= 2 and np.all(v < REGULAR)
    cf = tb.chaotic_fraction(FIG2_BALL, FIG4B_LEVELS, n=3, t_end=T_END, workers=1)
    assert cf.n_chaotic == 0
