r"""The reference orbits of the precision study (:mod:`taylorball.verify.precision`), the
float64 states on given levels they start from, and their sample times.

:func:`reduced_state_on_levels` and :func:`mparallel_state_on_levels` place a state on
prescribed values of the first integrals (section 3, section 5);
:func:`reference_orbits` lists the orbits of the study (:class:`Orbit`) and
:func:`time_grid` the times at which each run is sampled.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import List

import numpy as np

from .._typing import KindName, ParamsLike
from ..paper import FIG5_BALL
from ..params import BallParams, MParallelParams, UnphysicalParametersWarning

__all__ = [
    "Orbit",
    "reference_orbits",
    "reduced_state_on_levels",
    "mparallel_state_on_levels",
    "time_grid",
]


@dataclass(frozen=True)
class Orbit:
    """An initial condition to study.

    Attributes
    ----------
    name : str
        Short identifier (used by ``--only``).
    kind : {"full", "reduced", "mparallel"}
    params : BallParams or MParallelParams
    state : numpy.ndarray
        float64 public state (shared by every number type).
    description : str
        Where it comes from (levels of the integrals, figure of the paper).
    t_quick, t_full : float
        Final time of the quick and ``--full`` runs.
    """

    name: str
    kind: KindName
    params: ParamsLike
    state: np.ndarray
    description: str
    t_quick: float = 100.0
    t_full: float = 1000.0


def _tangent_frame(gamma):
    g = np.asarray(gamma, dtype=float)
    g = g / np.linalg.norm(g)
    t = np.array([1.0, 0.0, 0.0]) if abs(g[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(g, t)
    e1 /= np.linalg.norm(e1)
    return g, e1, np.cross(g, e1)


def _solve_quadratic(f, target, root):
    """Root of ``f(s) = target`` for ``f`` a quadratic polynomial in ``s`` (fitted exactly
    from three values); ``root`` 0 / 1 picks the smaller / larger root."""
    f0, fp, fm = f(0.0), f(1.0), f(-1.0)
    a, b, c = (fp + fm) / 2 - f0, (fp - fm) / 2, f0 - target
    disc = b * b - 4 * a * c
    if a == 0 or disc < 0:
        return None
    roots = sorted(((-b - math.sqrt(disc)) / (2 * a), (-b + math.sqrt(disc)) / (2 * a)))
    return roots[root]


def reduced_state_on_levels(params: BallParams, C: float, M_gamma: float, E: float, *,
                            gamma=(0.3, 0.4, math.sqrt(0.75)), psi: float = 0.3, phi: float = 0.5,
                            root: int = 1) -> np.ndarray:
    r"""A reduced state ``(omega, gamma, R)`` with ``|M| = C``, ``(M, gamma) = M_gamma`` and
    energy ``E`` (section 3).

    ``M = M_gamma gamma + sqrt(C^2 - M_gamma^2) (cos psi e1 + sin psi e2)`` and
    ``R = r (cos phi e1 + sin phi e2)`` with ``(e1, e2)`` a tangent frame at ``gamma``;
    ``omega = Itilde^{-1} (M + m a Omega R)`` (paper eq. (11) [eq13]) and ``r`` solves the energy equation
    ``E = (omega, Itilde omega)/2 - m Omega^2 r^2 / 2``, a quadratic in ``r``.

    Raises
    ------
    ChartError
        If ``|M_gamma| > C`` or the energy level is not reached along that ray.
    """
    from ..errors import ChartError

    if not abs(M_gamma) <= C:
        raise ChartError(f"need |M_gamma| <= C, got M_gamma={M_gamma!r}, C={C!r}")
    g, e1, e2 = _tangent_frame(gamma)
    M = M_gamma * g + math.sqrt(C * C - M_gamma * M_gamma) * (math.cos(psi) * e1 + math.sin(psi) * e2)
    e = math.cos(phi) * e1 + math.sin(phi) * e2
    It = np.diag(params.inertia) + params.d * (np.eye(3) - np.outer(g, g))
    maO = params.mass * params.radius * params.plane_rate

    def energy(r):
        K = M + maO * r * e
        return 0.5 * float(np.linalg.solve(It, K) @ K) - params.mass * params.plane_rate**2 * r * r / 2

    r = _solve_quadratic(energy, E, root)
    if r is None:
        raise ChartError(f"energy E={E!r} is not reached on the ray phi={phi!r} at C={C!r}, M_gamma={M_gamma!r}")
    K = M + maO * r * e
    return np.concatenate([np.linalg.solve(It, K), g, r * e])


def mparallel_state_on_levels(params: MParallelParams, lam: float, E: float, *,
                              gamma=(0.3, 0.4, math.sqrt(0.75)), psi: float = 0.7, root: int = 1) -> np.ndarray:
    r"""A state ``(K, gamma)`` of paper eq. (22) [Mpn2] with ``(K, gamma) = lambda`` and energy ``E``
    (section 5): ``K = lambda gamma + s (cos psi e1 + sin psi e2)``, ``s`` solving the
    energy equation (quadratic in ``s`` at fixed ``gamma``).

    Raises
    ------
    ChartError
        If the level is not reached along that ray.
    """
    from ..errors import ChartError
    from .._integrals import integrals

    g, e1, e2 = _tangent_frame(gamma)
    u = math.cos(psi) * e1 + math.sin(psi) * e2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnphysicalParametersWarning)
        f = lambda s: float(integrals("mparallel", params, np.concatenate([lam * g + s * u, g]))["E"])  # noqa: E731
        s = _solve_quadratic(f, E, root)
    if s is None:
        raise ChartError(f"energy E={E!r} is not reached on the ray psi={psi!r} at lambda={lam!r}")
    return np.concatenate([lam * g + s * u, g])


def reference_orbits() -> List[Orbit]:
    """The orbits of the study.

    * ``reduced-fig4a`` / ``full-fig4a``: the Fig. 4 ball (``I = (2, 3, 4)``, ``m = 1``,
      ``a = 5``, ``Omega = 2``) on the levels of Fig. 4a read as ``C = |M| = G = 10``,
      ``M_gamma = H = 2``, ``E = h = 5`` (the caption's letters are not defined in the
      text; the growth fit shows whether the orbit is chaotic); the full state is its lift
      by :func:`taylorball.reduced_to_full`.
    * ``mparallel-ball``: the same ball converted by ``BallParams.to_mparallel()``, levels
      ``lambda = 2``, ``E = 0.1``.
    * ``mparallel-fig1``: the paper's Fig. 1 values ``a = (1, 2, 3)``, ``d = 4``,
      ``Omega = 0.5``, ``h = 100``, ``lambda = 2`` (unphysical: negative moments).
    """
    from ..manifold import reduced_to_full

    red = reduced_state_on_levels(FIG5_BALL, 10.0, 2.0, 5.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnphysicalParametersWarning)
        fig1 = MParallelParams(a=(1.0, 2.0, 3.0), d=4.0, plane_rate=0.5)
    ballm = FIG5_BALL.to_mparallel()
    levels = "C = 10, M_gamma = 2, E = 5 (Fig. 4a levels read as G = C, H = M_gamma, h = E)"
    return [
        # final times: the 256-bit reference costs ~0.4 s per time unit on the Fig. 4 ball
        # and ~2 s on Fig. 1 (135 steps per time unit), so quick mode stays near 30 s
        Orbit("reduced-fig4a", "reduced", FIG5_BALL, red, f"Fig. 4 ball, {levels}", 20.0, 600.0),
        Orbit("full-fig4a", "full", FIG5_BALL, reduced_to_full(FIG5_BALL, red),
              f"lift of reduced-fig4a (F1 = 0), {levels}", 10.0, 300.0),
        Orbit("mparallel-ball", "mparallel", ballm, mparallel_state_on_levels(ballm, 2.0, 0.1),
              "Fig. 4 ball as M||gamma system, lambda = 2, E = 0.1", 50.0, 1000.0),
        Orbit("mparallel-fig1", "mparallel", fig1, mparallel_state_on_levels(fig1, 2.0, 100.0),
              "Fig. 1 values a = (1, 2, 3), d = 4, Omega = 0.5, lambda = 2, E = h = 100", 4.0, 50.0),
    ]


def time_grid(t_end: float) -> np.ndarray:
    """Sample times: 0, the 1-2-5 sequence below ``t_end``, and ``t_end/10`` steps up to
    ``t_end`` (dense late samples for the growth fit)."""
    pts = {0.0, float(t_end)}
    k = -3
    while True:
        base = 10.0**k
        done = False
        for m in (1.0, 2.0, 5.0):
            v = m * base
            if v >= t_end:
                done = True
                break
            if v >= 1e-2 * t_end:
                pts.add(v)
        if done:
            break
        k += 1
    pts.update(t_end * j / 10.0 for j in range(1, 10))
    return np.array(sorted(pts))
