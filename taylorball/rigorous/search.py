r"""Floating-point search for fixed points of the symmetric ball's 2D section map.

**Not part of any proof**: it only proposes a candidate ``(r1, r2)`` and a return time that
the validated code then checks. For ``I1 = I2`` the angle ``l`` is cyclic (paper section
4), so the section-4 map ``(l, r1, r2) -> (l', r1', r2')`` induces a 2D map
``(r1, r2) -> (r1', r2')``; it is evaluated here at ``l = 0`` with heyoka (float64), through
:func:`taylorball.states_on_section` and :func:`taylorball.poincare_section`.
"""

from __future__ import annotations

from typing import Any, Dict, Tuple

import numpy as np

__all__ = ["float_map", "newton_fixed_point", "fig1_heteroclinic_chain"]


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


# ---------------------------------------------------------------------------------------
# The Fig. 1 M||gamma map: h-sets along the heteroclinic cycle of its two saddles.
# ---------------------------------------------------------------------------------------
def _mparallel_float_map(params: Any, levels: Any, pt: Any, G_ref: float) -> Tuple[np.ndarray, float]:
    """``(P(pt), return time)`` of the M||gamma map at the chart point ``pt = (l, L/G)`` on the
    energy root ``G = |K|`` nearest ``G_ref`` (float64, heyoka)."""
    from .._chart_mparallel import mparallel_states_on_section
    from ..sections import poincare_section

    xs = mparallel_states_on_section(params, **levels.as_kwargs(), point=(float(pt[0]), float(pt[1])))
    G = np.linalg.norm(xs[:, :3], axis=1)
    j = int(np.argmin(np.abs(G - G_ref)))
    r = poincare_section("mparallel", params, xs[j], n_points=1, g0=0.0, direction=1)
    return np.asarray(r.points[0], dtype=float), float(r.times[0])


def _chart_jacobian(params: Any, levels: Any, pt: Any, G_ref: float, eps: float = 1e-7) -> np.ndarray:
    """Central-difference Jacobian of the chart map (``l`` differences wrapped to ``(-pi, pi]``)."""
    import math

    J = np.empty((2, 2))
    for j in range(2):
        d = np.zeros(2)
        d[j] = eps
        v = _mparallel_float_map(params, levels, pt + d, G_ref)[0] - _mparallel_float_map(params, levels, pt - d, G_ref)[0]
        v[0] = (v[0] + math.pi) % (2 * math.pi) - math.pi
        J[:, j] = v / (2 * eps)
    return J


def fig1_heteroclinic_chain(*, i_lo: int = -8, i_hi: int = 10, a_saddle: float = 5e-5, s_mid: float = 1e-5,
                            b_min: float = 2e-6, alpha: float = 1.4, pieces: int = 2, skew_deg: float = 10.0,
                            skew_pieces: int = 12, skip: Tuple[int, int] = (0, 1)) -> Dict[str, Any]:
    r"""h-sets of the Fig. 1 M||gamma map along its heteroclinic cycle (float64 design; not part
    of any proof): ``N0`` and ``Npi`` around the saddles at ``l = 0`` and ``l = pi`` (squares of
    half-width ``a_saddle`` in the saddles' eigenvector frames), and ``up{i}`` / ``down{i}``,
    ``i_lo <= i <= i_hi``, around the points ``z_i = P^i(z)`` of the heteroclinic orbits through
    ``z`` in ``W^u(0) & W^s(pi)`` (upper separatrix, ``L/G > 0``) and in ``W^u(pi) & W^s(0)``
    (:func:`taylorball.periodic_manifolds.homoclinic_points`).

    Each ``up{i}`` is ``z_i + a_i u_i [-1, 1] + b_i s_i [-1, 1]``, ``u_i`` the saddle's unstable
    eigenvector carried forward by the map's Jacobian (the tangent of ``W^u``), ``s_i`` the
    target saddle's stable one carried backward (the tangent of ``W^s``); with ``lambda_i``,
    ``sigma_i`` the stretching of ``u_i``, ``s_i`` by one step, the half-widths follow
    ``a_{i+1} <= lambda_i a_i / alpha`` and ``b_{i+1} >= alpha sigma_i b_i`` (``alpha`` the margin
    per step), ``a`` shrinking to ``s_mid`` at the heteroclinic point (where the two tangents
    meet at 0.38 degrees) and ``b >= b_min``. A relation whose target's two directions meet
    at less than ``skew_deg`` degrees (its coordinates amplify every error by ``1/sin(angle)``)
    is checked on ``skew_pieces`` strips of its source, the others on ``pieces``. The sets
    strictly between ``skip[0]`` and ``skip[1]`` are left out: the relation
    ``up{skip[0]} => up{skip[1]}`` is then for the map's ``skip[1] - skip[0]``-th iterate (the
    local section map near the sum of the return times), which avoids the h-sets where the
    tangents are nearly parallel.

    Returns
    -------
    dict
        ``hsets`` (list of :class:`~taylorball.rigorous.covering.HSet`), ``relations`` (list of
        :class:`~taylorball.rigorous.covering.Relation`), ``loops`` and ``paths`` (lists of
        set names), ``points`` (the chain's chart points by set name).
    """
    import math

    from .._chart_mparallel import mparallel_chart, mparallel_states_on_section
    from ..paper import FIG1_LEVELS, fig1_params
    from ..periodic import periodic_orbit
    from ..periodic_manifolds import homoclinic_points, inverse_map
    from ..sections import poincare_section
    from .covering import HSet, Relation

    params, levels = fig1_params(), FIG1_LEVELS
    n_back, n_fwd = -i_lo + 3, i_hi + 2
    orbs, sad = {}, {}
    for name, lb in (("N0", 0.0), ("Npi", math.pi)):
        x0 = mparallel_states_on_section(params, **levels.as_kwargs(), point=(lb, 0.0))[0]
        o = periodic_orbit("mparallel", params, x0, levels=levels)
        pt, G = np.asarray(o.points[0], dtype=float), float(mparallel_chart(o.state)["G"])
        w, V = np.linalg.eig(_chart_jacobian(params, levels, pt, G))
        iu = int(np.argmax(np.abs(w)))
        eu, es = V[:, iu].real, V[:, 1 - iu].real
        orbs[name] = o
        sad[name] = dict(pt=pt, G=G, tau=float(o.period), eu=eu / np.linalg.norm(eu), es=es / np.linalg.norm(es))

    def branch(l: float) -> Tuple[float, float]:
        k = int(round(l / (math.pi / 2)))
        return (k % 4) * math.pi / 2, l - (k - k % 4) * math.pi / 2

    hsets: Dict[str, Any] = {}
    points: Dict[str, Any] = {}

    def add(name: str, pt: Any, u: Any, a: float, s: Any, b: float, G: float) -> None:
        lb, l = branch(float(pt[0]))
        B = ((float(u[0] * a), float(s[0] * b)), (float(u[1] * a), float(s[1] * b)))
        hsets[name] = HSet(name, (l, float(pt[1])), B, lb, float(G))
        points[name] = (l, float(pt[1]))

    for name in ("N0", "Npi"):
        d = sad[name]
        add(name, d["pt"], d["eu"], a_saddle, d["es"], a_saddle, d["G"])
    relations = [Relation("N0", "N0", sad["N0"]["tau"], n_pieces=pieces),
                 Relation("Npi", "Npi", sad["Npi"]["tau"], n_pieces=pieces)]
    paths = []
    for chain, src, dst in (("up", "N0", "Npi"), ("down", "Npi", "N0")):
        het = [h for h in homoclinic_points(orbs[src], target=orbs[dst], n_u=8, n_s=9, n_fund=30, s0=2.0396e-4)
               if h.point[1] > 0][0]
        fw = poincare_section("mparallel", params, het.state, n_points=n_fwd, g0=0.0, direction=1)
        bw = inverse_map(orbs[src], het.state, n=n_back)
        states = list(bw[::-1]) + [np.asarray(het.state, dtype=float)] + [np.asarray(s, dtype=float) for s in fw.states]
        i0 = n_back
        pts = [np.array([mparallel_chart(s)["l"], mparallel_chart(s)["L/G"]], dtype=float) for s in states]
        Gs = [float(mparallel_chart(s)["G"]) for s in states]
        Js = [_chart_jacobian(params, levels, q, G) for q, G in zip(pts, Gs)]
        taus = [_mparallel_float_map(params, levels, q, G)[1] for q, G in zip(pts, Gs)]
        U, lam = {}, {}
        u = sad[src]["eu"].copy()
        for i in range(-i0, len(Js) - i0):
            U[i] = u
            v = Js[i + i0] @ u
            lam[i] = float(np.linalg.norm(v))
            u = v / lam[i]
        S, sig = {}, {}
        s = sad[dst]["es"].copy()
        for i in range(len(Js) - 1 - i0, -i0 - 1, -1):
            S[i] = s
            if i + i0 - 1 >= 0:
                v = np.linalg.solve(Js[i + i0 - 1], s)
                s = v / np.linalg.norm(v)
        for i in range(-i0, len(Js) - 1 - i0):
            sig[i] = float(np.linalg.norm(Js[i + i0] @ S[i]))
        a, b = {i_lo: a_saddle}, {i_lo: alpha * 0.6 * a_saddle}
        shrink = (s_mid / a_saddle) ** (1 / max(1, -i_lo))
        kept = [i for i in range(i_lo, i_hi + 1) if not skip[0] < i < skip[1]]
        for i in range(i_lo, i_hi):
            m = 1.0 if skip[0] < i + 1 < skip[1] else alpha  # one margin per relation
            grow = lam[i] * a[i] / m
            a[i + 1] = min(grow, max(s_mid, a[i] * shrink), a_saddle) if i + 1 <= 0 else min(grow, a_saddle)
            b[i + 1] = max(m * sig[i] * b[i], b_min)
        names = [src] + [f"{chain}{i}" for i in kept] + [dst]
        for i in kept:
            add(f"{chain}{i}", pts[i + i0], U[i], a[i], S[i], b[i], Gs[i + i0])
        nxt = kept[1:] + [kept[-1] + 1]
        tau = [sad[src]["tau"]] + [sum(taus[j + i0] for j in range(i, k)) for i, k in zip(kept, nxt)]
        skewed = {f"{chain}{i}" for i in kept if math.degrees(math.acos(min(1.0, abs(float(U[i] @ S[i]))))) < skew_deg}
        relations += [Relation(names[k], names[k + 1], tau[k], n_pieces=skew_pieces if names[k + 1] in skewed else pieces)
                      for k in range(len(names) - 1)]
        paths.append(names)
    return {"hsets": list(hsets.values()), "relations": relations, "loops": [["N0", "N0"], ["Npi", "Npi"]],
            "paths": paths, "points": points}
