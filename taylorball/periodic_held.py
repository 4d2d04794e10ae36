r"""The reduced system's periodic orbit that holds the ball in place, for small ``Omega``: :func:`held_in_place`.

At ``Omega = 0`` the ``(M, gamma)`` part of the reduced system is Chaplygin's ball on a fixed
plane, and the centre moves in the fixed frame by a displacement ``D`` over a period ``T`` of
``(M, gamma)`` (docs/skeleton.md, "Omega -> 0 in the reduced system"). For small ``Omega > 0``
a periodic orbit near that Chaplygin orbit has ``Omega R`` (fixed frame) near ``W = (-D_y,
D_x) / T``: the plane's velocity at the centre cancels the mean rolling velocity. On the level
``C = |K - m a W|``, ``M_gamma = (K, gamma)``, ``h = (K, omega)/2 - m |W|^2/2`` (``K = Itilde
omega`` of the Chaplygin orbit) the reduced system's family of such orbits comes in from
infinity in ``R`` as ``Omega -> 0``, with ``Omega |R| -> |D| / T`` (the drift speed).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Literal, Sequence

import numpy as np

from .levels import Levels
from .numbers import real_number
from .params import BallParams
from .periodic import PeriodicOrbit

__all__ = ["HeldInPlace", "held_in_place"]


@dataclass(frozen=True)
class HeldInPlace:
    """The limit ``Omega -> 0`` of a held-in-place family and its orbit at one ``Omega``.

    Attributes
    ----------
    levels : Levels
        The limit level ``C = |K - m a W|``, ``M_gamma = (K, gamma)``, ``h = (K, omega)/2 - m
        |W|^2/2`` (``C^2`` and ``E`` of the state with ``Omega R = W``), kept along the family.
    period : float
        ``T``: the Chaplygin orbit's time to its first return to the section (``Omega = 0``).
    drift : ndarray
        ``D / T``: the centre's mean velocity over that period, in the fixed frame
        (``(x, y)`` of :func:`taylorball.reduced_to_full`, ``psi = 0``, at the start).
    drift_speed : float
        ``|D| / T``: the limit of ``Omega |R|`` along the family.
    orbit : PeriodicOrbit
        Newton's periodic orbit at ``omega`` on :attr:`levels`, from the Chaplygin state with
        ``R = W / Omega``.
    """

    levels: Levels
    period: float
    drift: np.ndarray
    drift_speed: float
    orbit: PeriodicOrbit


def held_in_place(params: BallParams, *, C: float, M_gamma: float, h: float, point: Sequence[float],
                  omega: float, direction: Literal[-1, 1] = 1) -> HeldInPlace:
    r"""The held-in-place periodic orbit at ``omega`` over the Chaplygin orbit at ``point``.

    The Chaplygin orbit is the reduced system's at ``Omega = 0`` (``params`` with
    ``plane_rate = 0``) from the section state of ``(C, M_gamma, h)`` at chart ``point``
    (:func:`taylorball.states_on_section`, ``R = 0``). One crossing of the section integrator
    gives its period ``T`` and, by :func:`taylorball.reduced_to_full`, the centre's
    displacement ``D``; the limit level is that of the state with ``Omega R = W = (-D_y, D_x) /
    T``, and Newton (:func:`taylorball.periodic_orbit`, ``k = 1``) at ``omega`` starts from the
    first crossing of the state with ``R = W / omega``. Follow the family with
    :func:`taylorball.periodic_continuation.continue_in_omega` on ``result.levels``.

    Only a relative periodic orbit of Chaplygin's ball (after one crossing) has such a limit:
    the dynamically symmetric ball (``I1 = I2``), where every orbit is one, is the case this
    was made for (docs/skeleton.md). The limit level lies close to ``M || gamma``: ``C`` comes
    out small where the drift is large.

    Raises
    ------
    UsageError
        ``omega`` not a positive number, or ``params`` not a :class:`BallParams`.
    IntegrationError, StateError
        Newton did not converge (as :func:`taylorball.periodic_orbit`).

    Examples
    --------
    >>> from taylorball.paper import FIG3_BALL
    >>> from taylorball.periodic_held import held_in_place
    >>> r = held_in_place(FIG3_BALL, C=10.0, M_gamma=6.0, h=7.2, point=(0.3, 0.0, 0.0), omega=0.05)
    >>> round(r.drift_speed, 6), round(r.levels.C, 6), r.orbit.type
    (1.429988, 6.059917, 'elliptic')
    """
    from .errors import UsageError
    from .manifold import reduced_to_full
    from .periodic import periodic_orbit
    from .sections import poincare_section
    from .charts import states_on_section
    from ._integrals import integrals

    if not isinstance(params, BallParams):
        raise UsageError(f"held_in_place: params must be a BallParams (the reduced system's ball), got {params!r}")
    omega = real_number("omega (the plane's rate of the orbit)", omega, lo=0.0, lo_open=True)
    ball0 = dataclasses.replace(params, plane_rate=0.0)
    s = np.array(states_on_section(ball0, C=C, M_gamma=M_gamma, h=h, point=point, direction=direction)[0],
                 dtype=np.float64)
    s[6:9] = 0.0
    sec = poincare_section("reduced", ball0, s, n_points=1)
    T = float(sec.times[0])
    D = np.asarray(reduced_to_full(ball0, np.asarray(sec.states[0], dtype=float))[12:14], dtype=float)
    W = np.array([-D[1], D[0]]) / T
    f0 = np.asarray(reduced_to_full(ball0, s), dtype=float)
    Wb = W[0] * f0[3:6] + W[1] * f0[6:9]  # W in the body, at the start
    # the level of the state with Omega R = W (Omega = 1, R = W): C^2 = |K - m a W|^2, and E
    held = s.copy()
    held[6:9] = Wb
    ints = integrals("reduced", dataclasses.replace(params, plane_rate=1.0), held)
    levels = Levels(C=math.sqrt(float(ints["C2"])), M_gamma=float(ints["M_gamma"]), h=float(ints["E"]))
    ball = dataclasses.replace(params, plane_rate=omega)
    seed = s.copy()
    seed[6:9] = Wb / omega
    guess = np.asarray(poincare_section("reduced", ball, seed, n_points=1).states[0], dtype=float)
    orbit = periodic_orbit("reduced", ball, guess, 1, levels=levels)
    return HeldInPlace(levels=levels, period=T, drift=D / T, drift_speed=float(np.hypot(*D)) / T, orbit=orbit)
