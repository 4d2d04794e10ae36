r"""The contact point's trajectory in the fixed frame (paper section 4, Figs. 2b, 3b, 5).

Since ``M`` is constant in space, the fixed frame can be chosen with ``F1 = (M, alpha) =
0``; then (section 3, with erratum E1)

.. math::
    \beta = \frac{M - M_\gamma\gamma}{\sqrt{C^2 - M_\gamma^2}},\quad
    \alpha = \frac{M\times\gamma}{\sqrt{C^2 - M_\gamma^2}},\quad
    x = (\alpha, R),\quad y = (\beta, R),

so ``(x, y)`` is an *algebraic* function of the reduced state: no extra quadrature is
needed (see ``docs/errata.md``, E-contact). :func:`contact_trajectory` propagates the
reduced system on a time grid and applies this map; the test suite checks it against
integrating the full system (paper eqs. (8)-(10) [eq6]) directly.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, Optional, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from ._problem import Problem, params_problem
from ._typing import FpTypeLike
from .errors import UsageError
from .manifold import reduced_to_full
from .params import BallParams
from .numbers import times
from ._propagate import propagate

__all__ = ["ContactTrajectory", "contact_trajectory", "fit_circle", "annulus", "bounding_circles"]


@dataclass(frozen=True)
class ContactTrajectory:
    """Contact point ``(x(t), y(t))`` on a time grid.

    Attributes
    ----------
    t : ndarray (n,)
    xy : ndarray (n, 2)
        Position of the contact point (= the centre's projection) in the fixed frame with
        ``F1 = 0`` rotated by ``psi``.
    reduced : ndarray (n, 9)
        The reduced states on the grid (public layout).
    """

    t: np.ndarray
    xy: np.ndarray
    reduced: np.ndarray

    @property
    def x(self) -> np.ndarray:
        return self.xy[:, 0]

    @property
    def y(self) -> np.ndarray:
        return self.xy[:, 1]


def contact_trajectory(
    params: Union[BallParams, Problem],
    state: ArrayLike,
    t: ArrayLike,
    *,
    fp_type: FpTypeLike = float,
    prec: Optional[int] = None,
    tol: Optional[float] = None,
    psi: float = 0.0,
) -> ContactTrajectory:
    """Contact-point trajectory from the reduced solution.

    Parameters
    ----------
    params : BallParams or Problem
        The ball; or a reduced :class:`taylorball.Problem` in its place (it then fixes
        ``fp_type``, ``prec`` and ``tol``).
    state : array_like (9,)
        Reduced initial state (omega, gamma, R).
    t : array_like (n,)
        Non-decreasing time grid starting at >= 0.
    psi : float
        Rotation of the fixed frame about the vertical (``psi = 0``: ``F1 = 0``).

    Raises
    ------
    ChartError
        If ``M`` is parallel to ``gamma`` (the frame is undefined there).
    """
    times("t", t)
    grid = np.asarray(t, dtype=float)
    if grid.ndim != 1 or grid.size < 1:
        raise UsageError(f"t must be a 1-D time grid, got shape {grid.shape}")
    prob = params_problem("contact_trajectory", "reduced", params, fp_type=fp_type, prec=prec, tol=tol)
    red = propagate(prob, state, grid)
    ball = prob.params
    assert isinstance(ball, BallParams)  # the reduced system's parameters
    full = reduced_to_full(ball, red, psi=psi)
    return ContactTrajectory(t=grid, xy=np.column_stack([full[:, 12], full[:, 13]]).astype(float), reduced=red)


def fit_circle(xy: ArrayLike) -> Tuple[np.ndarray, float]:
    """Least-squares (Kasa) circle through points: returns ``(centre (2,), radius)``."""
    p = np.asarray(xy, dtype=float)
    A = np.column_stack([2 * p[:, 0], 2 * p[:, 1], np.ones(len(p))])
    b = np.sum(p * p, axis=1)
    (cx, cy, c), *_ = np.linalg.lstsq(A, b, rcond=None)
    return np.array([cx, cy]), float(np.sqrt(c + cx * cx + cy * cy))


def annulus(xy: ArrayLike, centre: Optional[ArrayLike] = None) -> Tuple[np.ndarray, float, float]:
    """Inner and outer radius of the points about ``centre`` (default: the mean point,
    which for a trajectory filling an annulus over many turns is its centre).

    Returns ``(centre, r_min, r_max)``."""
    p = np.asarray(xy, dtype=float)
    c = p.mean(axis=0) if centre is None else np.asarray(centre, dtype=float)
    r = np.hypot(p[:, 0] - c[0], p[:, 1] - c[1])
    return c, float(r.min()), float(r.max())


def _refine_centre(p, objective, c0, span, n_iter=40, n_grid=9):
    """Coarse-to-fine grid search of a centre minimising ``objective(dist)``: a deterministic
    pattern search (each round keeps the best of an ``n_grid^2`` grid and shrinks it)."""
    c = np.asarray(c0, dtype=float)
    best = objective(np.hypot(p[:, 0] - c[0], p[:, 1] - c[1]))
    offs = np.linspace(-1.0, 1.0, n_grid)
    for _ in range(n_iter):
        centre = c  # the grid of this round is about the best centre of the last one
        for dx in offs * span:
            for dy in offs * span:
                q = centre + (dx, dy)
                v = objective(np.hypot(p[:, 0] - q[0], p[:, 1] - q[1]))
                if v < best:
                    best, c = v, q
        span *= 0.5
    return c, best


def bounding_circles(xy: ArrayLike, *, max_points: int = 4000) -> Dict[str, Any]:
    """The two circles a planar trajectory lies between (paper, section 4: the contact point
    "lies between two circles").

    * outer: the smallest enclosing circle (minimax centre);
    * inner: the largest circle inside the hole of the trajectory that contains no point
      (maximin centre, searched from the least-squares centre of the points).

    Both centres are found by a deterministic coarse-to-fine pattern search on at most
    ``max_points`` points (evenly strided), accurate to ~1e-6 of the trajectory's size.

    Returns
    -------
    dict
        ``outer_centre``, ``r_outer``, ``inner_centre``, ``r_inner`` (``r_inner = 0`` when
        the trajectory has no hole around its centre).
    """
    p = np.asarray(xy, dtype=float)
    if len(p) > max_points:
        p = p[:: int(np.ceil(len(p) / max_points))]
    centre, r_fit = fit_circle(p)
    size = float(np.ptp(p, axis=0).max()) or 1.0
    oc, r_out = _refine_centre(p, np.max, centre, size / 4)
    ic, neg_r_in = _refine_centre(p, lambda d: -np.min(d), centre, r_fit / 2)
    return {"outer_centre": oc, "r_outer": float(r_out), "inner_centre": ic, "r_inner": float(max(-neg_r_in, 0.0))}


def radius_bound(params: BallParams, C: float, h: float) -> float:
    r"""Rigorous bound on the contact point's distance from the rotation axis.

    For a real ball (``I_min = min I_i > 0``) on a rotating plane (``Omega != 0``), every
    orbit with ``|M| = C`` and Jacobi integral ``E = h`` satisfies
    ``sqrt(x^2 + y^2) = |R| <= radius_bound(params, C, h)`` for all time.

    Proof. With ``K = M + mu R``, ``mu = m a Omega``, ``E = (K, Itilde^{-1} K)/2 - m Omega^2
    R^2 / 2``. Since ``Itilde = I + d (E - gamma gamma^T) >= I_min``, ``|Itilde^{-1/2} M|^2 <=
    C^2 / I_min``; and for ``R`` perpendicular to ``gamma`` the Legendre form
    ``(R, Itilde^{-1} R) = sup_v [2 (R, v_perp) - (v, I v) - d |v_perp|^2] <= R^2/(I_min + d)``.
    Cauchy--Schwarz in the ``Itilde^{-1}`` inner product gives

    .. math::
        h = E \le \tfrac12\Big(\frac{C}{\sqrt{I_{min}}} + \frac{|\mu|\,|R|}{\sqrt{I_{min}+d}}\Big)^2
                  - \tfrac12 m\Omega^2 |R|^2,

    whose right side is a concave quadratic in ``|R|`` (its ``|R|^2`` coefficient is
    ``-m Omega^2 I_min / (2 (I_min + d)) < 0`` because ``mu^2 = m Omega^2 d``); ``|R|`` is at
    most its larger root. The paper (section 4) leaves the boundedness of the contact
    point open; this settles it (see ``docs/errata.md``). The bound is not sharp.

    Raises
    ------
    ParameterError
        If ``Omega = 0`` (no bound: on a fixed plane the ball can roll away).
    """
    import math

    from .errors import ParameterError

    i_min = min(params.inertia)
    d = params.d
    om = params.plane_rate
    mu = abs(params.mass * params.radius * om)
    a = 0.5 * (mu * mu / (i_min + d) - params.mass * om * om)  # -m Omega^2 I_min / (2 (I_min + d))
    if not a < 0.0:
        raise ParameterError(
            f"radius_bound needs plane_rate != 0 (got {om!r}, or so small that Omega^2 underflows): on a fixed "
            "plane the contact point is unbounded"
        )
    b = C * mu / math.sqrt(i_min * (i_min + d))
    c = 0.5 * C * C / i_min - h
    disc = b * b - 4 * a * c
    if disc < 0:
        from .errors import EmptyLevelError

        raise EmptyLevelError(f"no state has |M| = C = {C!r} and E = h = {h!r}: h exceeds every energy on |M| = C")
    return (-b - math.sqrt(disc)) / (2 * a)
