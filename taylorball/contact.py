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
integrating the full system (eq. 6) directly.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from .errors import UsageError
from .manifold import reduced_to_full
from .propagate import propagate

__all__ = ["ContactTrajectory", "contact_trajectory", "fit_circle", "annulus"]


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
    def x(self):
        return self.xy[:, 0]

    @property
    def y(self):
        return self.xy[:, 1]


def contact_trajectory(
    params,
    state,
    t,
    *,
    fp_type=float,
    prec: Optional[int] = None,
    tol=None,
    psi: float = 0.0,
) -> ContactTrajectory:
    """Contact-point trajectory from the reduced solution.

    Parameters
    ----------
    params : BallParams
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
    grid = np.asarray(t, dtype=float)
    if grid.ndim != 1 or grid.size < 1:
        raise UsageError(f"t must be a 1-D time grid, got shape {grid.shape}")
    red = propagate("reduced", params, state, grid, fp_type=fp_type, prec=prec, tol=tol)
    full = reduced_to_full(params, red, psi=psi)
    return ContactTrajectory(t=grid, xy=np.column_stack([full[:, 12], full[:, 13]]).astype(float), reduced=red)


def fit_circle(xy) -> tuple:
    """Least-squares (Kasa) circle through points: returns ``(centre (2,), radius)``."""
    p = np.asarray(xy, dtype=float)
    A = np.column_stack([2 * p[:, 0], 2 * p[:, 1], np.ones(len(p))])
    b = np.sum(p * p, axis=1)
    (cx, cy, c), *_ = np.linalg.lstsq(A, b, rcond=None)
    return np.array([cx, cy]), float(np.sqrt(c + cx * cx + cy * cy))


def annulus(xy, centre=None) -> tuple:
    """Inner and outer radius of the points about ``centre`` (default: the mean point,
    which for a trajectory filling an annulus over many turns is its centre).

    Returns ``(centre, r_min, r_max)``."""
    p = np.asarray(xy, dtype=float)
    c = p.mean(axis=0) if centre is None else np.asarray(centre, dtype=float)
    r = np.hypot(p[:, 0] - c[0], p[:, 1] - c[1])
    return c, float(r.min()), float(r.max())
