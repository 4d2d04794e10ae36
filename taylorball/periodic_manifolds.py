r"""The unstable manifold of a hyperbolic fixed point of a 2D section map.

For a saddle ``x`` of the M||gamma map or of a symmetric ball's map of ``(r1, r2)`` with
unstable multiplier ``mu`` (``|mu| > 1``) and eigenvector ``v`` (in the tangent space of
section and level), the local unstable manifold is tangent to ``v``. A fundamental domain
``x + s v``, ``s`` in ``[s0, |mu| s0)`` (log-spaced, moved onto section and level), iterated
``n_iter`` times by the section map, traces the manifold: iterate ``n`` covers
``[|mu|^n s0, |mu|^{n+1} s0)`` along it. Both branches (``+v`` and ``-v``); for a negative
``mu`` the two branches alternate, which the union covers.

Only the unstable manifold is grown (the stable one needs the inverse map, i.e. the flow
backwards, which the section runs do not offer); homoclinic points are not located.
"""

from __future__ import annotations

from typing import Dict

import numpy as np

from .errors import UsageError
from .periodic import PeriodicOrbit, _eval_geo, _f64, _has_axial_symmetry, _Ctx, _to_level
from ._propagate import public_state

__all__ = ["unstable_manifold"]


def unstable_manifold(orbit: PeriodicOrbit, *, n_fund: int = 100, n_iter: int = 6, s0: float = 1e-6) -> Dict[str, np.ndarray]:
    r"""Chart points of the unstable manifold of a hyperbolic fixed point (``k = 1``, 2D map).

    Parameters
    ----------
    orbit : PeriodicOrbit
        A saddle (``stability == "hyperbolic"``) of a 2D map: kind ``"mparallel"``.
    n_fund : int
        Points of the fundamental domain per branch.
    n_iter : int
        Iterations of the section map.
    s0 : float
        Distance from the fixed point where the fundamental domain starts.

    Returns
    -------
    dict
        ``points`` (2, n_fund, n_iter + 1, chart dims): branch, point, iterate; ``s`` the
        fundamental-domain parameters; ``mu`` the unstable multiplier; ``direction`` the
        eigenvector in the internal variables.
    """
    from .sections import chart_points, poincare_sections

    if orbit.stability != "hyperbolic" or orbit.multipliers.shape != (2,) or orbit.k != 1:
        raise UsageError(f"unstable_manifold needs a hyperbolic fixed point (k = 1) of a 2D map, got {orbit!r}")
    prob = orbit.problem
    if _has_axial_symmetry(prob) or prob.kind != "mparallel":
        raise UsageError("unstable_manifold is implemented for the M||gamma map (kind='mparallel')")
    x = np.asarray(orbit.internal, dtype=float)
    geo = _eval_geo(prob, orbit.g0, x)
    G = np.vstack([_f64(geo.grad_e)[None, :], _f64(geo.grad_c)])
    B = np.linalg.svd(G)[2][G.shape[0]:].T
    lam, V = np.linalg.eig(orbit.matrix)
    i = int(np.argmax(np.abs(lam)))
    mu = float(lam[i].real)
    d = B @ V[:, i].real
    d /= np.linalg.norm(d)
    ctx = _Ctx(prob, orbit.g0, orbit.direction, 1, geo.c.copy(), False, 1e4)
    s = s0 * np.abs(mu) ** (np.arange(n_fund) / n_fund)
    starts = []
    for sign in (1.0, -1.0):
        for si in s:
            xi = _to_level(ctx, x + sign * si * d, 1.0)
            starts.append(public_state(prob.system, prob.pars, xi, prob.spec))
    runs = poincare_sections(prob.kind, prob.params, starts, n_points=n_iter, g0=orbit.g0, t_end=100.0 * n_iter,
                             direction=1 if orbit.direction == 1 else -1)
    dims = len(orbit.points[0])
    pts = np.full((2 * n_fund, n_iter + 1, dims), np.nan)
    for j, (st, r) in enumerate(zip(starts, runs)):
        pts[j, 0] = chart_points(prob.kind, np.asarray(st, dtype=float)[None, :])[0]
        pts[j, 1:1 + len(r.points)] = r.points
    return {"points": pts.reshape(2, n_fund, n_iter + 1, dims), "s": s, "mu": np.array(mu), "direction": d}
