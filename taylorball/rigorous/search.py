r"""Floating-point search for fixed points of the symmetric ball's 2D section map.

**Not part of any proof**: it only proposes a candidate ``(r1, r2)`` and a return time that
the validated code then checks. For ``I1 = I2`` the angle ``l`` is cyclic (paper section
4), so the section-4 map ``(l, r1, r2) -> (l', r1', r2')`` induces a 2D map
``(r1, r2) -> (r1', r2')``; it is evaluated here at ``l = 0`` with heyoka (float64), through
:func:`taylorball.states_on_section` and :func:`taylorball.poincare_section`.
"""

from __future__ import annotations

from typing import Any, Tuple

import numpy as np

__all__ = ["float_map", "newton_fixed_point"]


def float_map(params: Any, levels: Any, p: Any, *, K_near: float = 0.0, g0: float = 0.0) -> Tuple[np.ndarray, float, np.ndarray]:
    """``(P(p), return time, start state)`` of the 2D map at ``p = (r1, r2)`` (float64), on
    the sheet whose root ``K = M3`` of the energy equation is nearest ``K_near``."""
    from ..charts import reduced_chart, states_on_section
    from ..sections import poincare_section

    xs = states_on_section(params, **levels.as_kwargs(), point=(0.0, float(p[0]), float(p[1])), g0=g0, direction=1)
    Ks = reduced_chart(params, xs)["K"]
    x0 = xs[int(np.argmin(np.abs(np.asarray(Ks) - K_near)))]
    res = poincare_section("reduced", params, x0, n_points=1, g0=g0, direction=1)
    return np.asarray(res.points[0][1:3], dtype=float), float(res.times[0]), x0


def newton_fixed_point(params: Any, levels: Any, p0: Any, *, K_near: float = 0.0, iters: int = 20,
                       step: float = 1e-7, max_step: float = 0.3) -> Tuple[np.ndarray, np.ndarray, float]:
    """Newton's method on ``P(p) - p`` with a central-difference Jacobian. Returns the
    candidate, ``DP`` there and the return time."""
    p = np.asarray(p0, dtype=float)
    for _ in range(iters):
        Pp, tau, _ = float_map(params, levels, p, K_near=K_near)
        J = np.empty((2, 2))
        for j in range(2):
            e = np.zeros(2)
            e[j] = step
            J[:, j] = (float_map(params, levels, p + e, K_near=K_near)[0] - float_map(params, levels, p - e, K_near=K_near)[0]) / (2 * step)
        F = Pp - p
        dp = np.linalg.solve(J - np.eye(2), -F)
        if np.max(np.abs(dp)) > max_step:  # damped: stay on the sheet
            dp *= max_step / np.max(np.abs(dp))
        p = p + dp
        if np.max(np.abs(dp)) < 1e-13:
            break
    Pp, tau, _ = float_map(params, levels, p, K_near=K_near)
    return p, J, tau
