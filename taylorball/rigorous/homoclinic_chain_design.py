r"""Float64 designs of chains of covering relations (not part of any proof): Tzenoff's case
(:func:`tzenoff_chain_design`, :func:`tzenoff_chain_record`) and the Henon map's known answer
(:func:`henon_chain`, :func:`henon_chain_certificate`). The long run's command line::

    nice -n 10 python -m taylorball.rigorous.homoclinic_chain_design STATE.json \
        [--design DESIGN.json] [--workers 2] [--only 29 28 ...]

starts the state file ``STATE.json`` from a design (or resumes it) and proves the relations
not done yet, each written to the file as it finishes
(:func:`taylorball.rigorous.homoclinic_chain_cert.run_chain`).

**Tzenoff's case.**

It only proposes numbers that :mod:`taylorball.rigorous.homoclinic_chain` then checks in ball
arithmetic: the centres ``c_1 .. c_n`` of the h-sets (a pseudo-orbit of the 2D section map
``F`` of the proved saddle's level from its local unstable manifold to the reversor's line
``r2 = 0``), their frames, sizes, cone constants, and the energy root, return time and
precision of each relation.

* **The orbit** by multiple shooting (float64, heyoka): unknowns ``c_1 .. c_n``; equations
  ``F(c_i) = c_{i+1}`` (``i < n``), ``c_1`` on the unstable eigen-line of the saddle
  (its stable coordinate in :data:`~taylorball.rigorous.homoclinic_cert.TZENOFF_FRAME` zero),
  ``r2(c_n) = 0``; Newton with central-difference Jacobians. The start: the symmetric
  homoclinic point ``q`` of ``W^u`` of ``F^2`` (:func:`taylorball.periodic_homoclinic.symmetric_homoclinic_points`)
  and its backward orbit ``F^{-k}(q) = R F^k(q)``; nearer the saddle, the eigen-line.
* **Frames**: ``T_i = (U_i, S_i)``, ``U_i`` the unstable eigenvector carried forward by
  ``DF`` (the tangent of ``W^u``), ``S_i`` the tangent of ``W^s`` carried backward from
  ``S_n = R U_n`` (``W^s = R W^u``); both unit vectors.
* **Sizes**: ``N_0`` the proved local h-set; ``a_1`` as large as ``F(N_0)`` allows (its exit
  edges reach ``|u| = lambda a_0`` around ``F(c_0)``), ``a_{i+1} = min(lambda_i a_i / margin,
  a_cap)``, ``b_{i+1} = max(margin sigma_i b_i, ratio a_{i+1})`` (``lambda_i``, ``sigma_i`` the
  stretching of ``U_i``, ``S_i`` by ``DF(c_i)``), the cone constants ``g_0 = c b_0 / a_0``
  (rounded down) and ``g_i = 1``.
* **Precision** of relation ``i``: 128 bits while the target's ``b_{i+1}`` is below
  ``prec_switch`` (the point map's enclosure at 80 bits is ~1e-13 wide over one return),
  else 80 bits.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any, Dict, List, Tuple

import numpy as np

__all__ = ["tzenoff_chain_design", "float_return", "henon_chain", "henon_chain_certificate", "tzenoff_chain_record"]


def float_return(params: Any, levels: Any, pt: Any, K_near: float) -> Tuple[np.ndarray, float, float, float]:
    """``(F(pt), return time, K at pt, K at F(pt))``: the first return of the chart point
    ``pt = (r1, r2)`` at ``l = 0`` on the energy root ``K = M3`` nearest ``K_near`` (float64)."""
    from ..charts import reduced_chart, states_on_section
    from ..sections import poincare_section

    xs = states_on_section(params, **levels.as_kwargs(), point=(0.0, float(pt[0]), float(pt[1])), g0=0.0, direction=1)
    Ks = np.asarray(reduced_chart(params, xs)["K"], dtype=float)
    j = int(np.argmin(np.abs(Ks - K_near)))
    r = poincare_section("reduced", params, xs[j], n_points=1, g0=0.0, direction=1)
    K1 = float(np.asarray(reduced_chart(params, np.asarray(r.states))["K"], dtype=float)[0])
    return np.asarray(r.points[0][1:3], dtype=float), float(r.times[0]), float(Ks[j]), K1


def _jacobian(params: Any, levels: Any, pt: np.ndarray, K: float, eps: float = 1e-7) -> np.ndarray:
    J = np.empty((2, 2))
    for j in range(2):
        e = np.zeros(2)
        e[j] = eps
        J[:, j] = (float_return(params, levels, pt + e, K)[0] - float_return(params, levels, pt - e, K)[0]) / (2 * eps)
    return J


def _along(params: Any, levels: Any, c: List[np.ndarray], Kg: List[float]) -> Tuple[List[np.ndarray], List[float],
                                                                                   List[float], List[np.ndarray]]:
    """``F(c_i)``, the return times, the energy roots at ``c_i`` and ``DF(c_i)`` along the points."""
    out: Tuple[List[Any], List[float], List[float], List[Any]] = ([], [], [], [])
    for ci, Ki in zip(c, Kg):
        y, tau, K0, _ = float_return(params, levels, ci, Ki)
        for lst, v in zip(out, (y, tau, K0, _jacobian(params, levels, ci, Ki))):
            lst.append(v)
    return out


def _homoclinic_orbit(params: Any, levels: Any, m: int) -> Tuple[List[np.ndarray], List[float]]:
    """``q`` and ``R F^k(q)``, ``k = 1 .. m`` (the backward orbit), with their energy roots."""
    from ..charts import reduced_chart
    from ..periodic_catalog import TZENOFF_D35_REFLECTION_SADDLE, catalog_orbit
    from ..periodic_homoclinic import symmetric_homoclinic_points
    from ..periodic_manifolds import grow_manifold, iterate
    from ..sections import poincare_section

    o2 = iterate(catalog_orbit(TZENOFF_D35_REFLECTION_SADDLE), 2)
    hu = symmetric_homoclinic_points(o2, grow_manifold(o2, "unstable", length=1.5, branch=1), max_points=8)
    h = min(hu, key=lambda z: abs(z.point[0] - 0.0103008))
    st = np.asarray(h.state, dtype=float)
    r = poincare_section("reduced", params, st, n_points=m, g0=0.0, direction=1)
    pts = [np.array([h.point[0], 0.0])] + [np.array([p[1], -p[2]], dtype=float) for p in r.points]
    Ks = [float(reduced_chart(params, st[None])["K"][0])] + [float(k) for k in reduced_chart(params, np.asarray(r.states))["K"]]
    return pts, Ks


def tzenoff_chain_design(*, n: int = 30, m: int = 13, margin: float = 1.3, ratio: float = 0.3, a_cap: float = 1e-11,
                         prec_switch: float = 2e-12, newton_iters: int = 4, log: Any = None) -> Dict[str, Any]:
    """The chain's design (module docstring) as a JSON-ready dict: ``sets`` (``n + 1``
    :class:`~taylorball.rigorous.homoclinic_chain.ChainSet` JSON forms), ``K``, ``tau``,
    ``prec`` per relation (index 0: the local map of the saddle certificate), and the Newton
    residuals of the pseudo-orbit (``defects``: ``|F(c_i) - c_{i+1}|`` in float64)."""
    from .certificates import CERT_DIR, _read_exact, load_certificate, tzenoff_ball, tzenoff_levels
    from .homoclinic_cert import SIGMA1, TZENOFF_FRAME, TZENOFF_HSET
    from .homoclinic_chain import ChainSet

    say = log or (lambda *a: None)
    P, L = tzenoff_ball(), tzenoff_levels(-20.0)
    wu = load_certificate(CERT_DIR / "tzenoff_d3.5_saddle_wu_cert.json")
    K_loc, tau_loc = _read_exact(wu["map"]["K_local"], "K"), _read_exact(wu["map"]["tau_local"], "tau")
    p = np.array(TZENOFF_FRAME[0])
    T0 = np.array(TZENOFF_FRAME[1])
    eu, es = T0[:, 0], T0[:, 1]
    T0i = np.linalg.inv(T0)
    a0, b0, c0 = TZENOFF_HSET["a"], TZENOFF_HSET["b"], TZENOFF_HSET["c"]
    Rm = np.array(SIGMA1, dtype=float)
    # 1. the start: q, R F^k(q) (k = 1 .. m), then the eigen-line (factor 1/mu_u per step back)
    pts, Ks = _homoclinic_orbit(P, L, m)
    ev = np.linalg.eigvals(_jacobian(P, L, p, K_loc)).real
    mu, mu_s = float(ev[np.argmax(np.abs(ev))]), float(ev[np.argmin(np.abs(ev))])
    u_m = float((T0i @ (pts[m] - p))[0])
    guess = [pts[k] for k in range(m, -1, -1)]  # c_{n-m} .. c_n
    Kg = [Ks[k] for k in range(m, -1, -1)]
    for j in range(1, n - m):
        guess.insert(0, p + u_m * mu ** (-j) * eu)
        Kg.insert(0, K_loc)
    say(f"start: mu_u = {mu:.6g}, u(c_1) guess = {u_m * mu ** (-(n - m - 1)):.3g}")
    c = [np.array(g, dtype=float) for g in guess]  # c_1 .. c_n (index 0 is c_1)
    # 2. multiple shooting
    for it in range(newton_iters):
        imgs, taus, Kg, Js = _along(P, L, c, Kg)
        F = np.zeros(2 * n)
        A = np.zeros((2 * n, 2 * n))
        for i in range(n - 1):
            F[2 * i:2 * i + 2] = imgs[i] - c[i + 1]
            A[2 * i:2 * i + 2, 2 * i:2 * i + 2] = Js[i]
            A[2 * i:2 * i + 2, 2 * i + 2:2 * i + 4] = -np.eye(2)
        F[2 * n - 2] = (T0i @ (c[0] - p))[1]
        A[2 * n - 2, 0:2] = T0i[1]
        F[2 * n - 1] = c[n - 1][1]
        A[2 * n - 1, 2 * n - 1] = 1.0
        dz = np.linalg.solve(A, -F)
        for i in range(n):
            c[i] = c[i] + dz[2 * i:2 * i + 2]
        say(f"newton {it}: max residual {np.max(np.abs(F)):.3g}, max step {np.max(np.abs(dz)):.3g}")
    imgs, taus, Kn, Js = _along(P, L, c, Kg)
    defects = [float(np.max(np.abs(imgs[i] - c[i + 1]))) for i in range(n - 1)]
    # 3. frames
    U = [eu / np.linalg.norm(eu)]
    for i in range(n - 1):
        v = Js[i] @ U[-1]
        U.append(v / np.linalg.norm(v))
    S = [Rm @ U[-1]]
    for i in range(n - 2, -1, -1):
        v = np.linalg.solve(Js[i], S[0])
        S.insert(0, v / np.linalg.norm(v))
    # 4. sizes: F(N_0) reaches |u| = |mu| a_0 around F(c_0) ~ p in the frame of p
    u1 = float((T0i @ (c[0] - p))[0])
    a = [(abs(mu) * a0 - abs(u1)) / margin]
    b = [max(margin * abs(mu_s) * b0, ratio * a[0])]
    for i in range(n - 1):
        lam, sig = float(np.linalg.norm(Js[i] @ U[i])), float(np.linalg.norm(Js[i] @ S[i]))
        a.append(min(lam * a[-1] / margin, a_cap))
        b.append(max(margin * sig * b[-1], ratio * a[-1]))
    sets = [ChainSet(TZENOFF_FRAME[0], TZENOFF_FRAME[1], a0, b0, math.nextafter(c0 * b0 / a0, 0.0))]
    for i in range(n):
        T = ((float(U[i][0]), float(S[i][0])), (float(U[i][1]), float(S[i][1])))
        sets.append(ChainSet((float(c[i][0]), float(c[i][1])), T, float(a[i]), float(b[i]), 1.0))
    Krel = [K_loc] + Kn  # relation i starts at c_i (c_0: the saddle's centre)
    taurel = [tau_loc] + taus
    precs = [128 if sets[i + 1].b < prec_switch else 80 for i in range(n)]
    angle = math.degrees(math.acos(abs(float(U[-1] @ S[-1]))))
    return {"sets": [s.as_json() for s in sets], "K": [float(k).hex() for k in Krel[:n]],
            "tau": [float(t).hex() for t in taurel[:n]], "prec": precs, "defects": defects,
            "angle_deg": angle, "u1": u1, "mu_u": mu,
            "sizes": [(s.a, s.b) for s in sets], "returns": [float(t) for t in taurel[:n]]}


def henon_chain(*, n: int = 6, a1: float = 1e-3, b1: float = 5e-4, margin: float = 1.3, ratio: float = 0.3,
                g: float = 1.0) -> Dict[str, Any]:
    r"""A float64 chain design for the Henon map :data:`~taylorball.rigorous.homoclinic_cert.HENON_T`
    (not part of any proof): the local h-set of the Henon certificate as ``N_0``; the pseudo-orbit
    ``c_1 = u_1 e_u``, ``c_{i+1} = f(c_i)``, ``u_1`` the float64 root of ``x - y`` at ``f^n`` on the
    unstable eigen-line (bisection); ``T_i``'s columns the unstable tangent carried forward and the
    stable tangent carried backward from ``R`` of the last unstable tangent (normalised); sizes
    ``a_{i+1} = lambda_i a_i / margin``, ``b_{i+1} = max(margin sigma_i b_i, ratio a_{i+1})`` from ``a1, b1``
    (``lambda_i``, ``sigma_i`` the stretching of the two tangents by ``Df(c_i)``). Returns ``{"sets",
    "local"}`` (``local``: ``(frame, a, b, c)`` of the certificate)."""

    from .homoclinic_cert import HENON_PROOF, HENON_T, henon_frame
    from .homoclinic_chain import ChainSet

    t = float(HENON_T)
    fr = henon_frame()
    h: Dict[str, Any] = dict(HENON_PROOF)
    eu = np.array([fr.T[0][0], fr.T[1][0]])
    fmap = lambda x: np.array([x[1], -x[0] + t * x[1] + x[1] ** 2])  # noqa: E731
    jac = lambda x: np.array([[0.0, 1.0], [-1.0, t + 2 * x[1]]])  # noqa: E731

    def orbit(u: float) -> List[Any]:
        xs = [u * eu]
        for _ in range(n - 1):
            xs.append(fmap(xs[-1]))
        return xs

    lo, hi = h["us"]  # the certificate's bracket (on f^6 of the eigen-line): x - y changes sign
    ev = lambda u: (lambda z: z[0] - z[1])(fmap(orbit(u)[-1]))  # noqa: E731
    flo = ev(lo)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if (ev(mid) > 0) == (flo > 0):
            lo, flo = mid, ev(mid)
        else:
            hi = mid
    xs = orbit(0.5 * (lo + hi))
    xs.append(fmap(xs[-1]))  # x_0 on the eigen-line, c_i = f^i(x_0), i = 1 .. n, c_n near x = y
    U = [eu]
    for x in xs[:-1]:
        v = jac(x) @ U[-1]
        U.append(v / np.linalg.norm(v))
    S = [np.array([U[-1][1], U[-1][0]])]  # R of the last unstable tangent: the tangent of W^s there
    for x in xs[-2:0:-1]:
        v = np.linalg.solve(jac(x), S[0])
        S.insert(0, v / np.linalg.norm(v))
    a, b = [a1], [b1]
    for x, u, sv in zip(xs[1:-1], U[1:-1], S[:-1]):
        a.append(float(np.linalg.norm(jac(x) @ u)) * a[-1] / margin)
        b.append(max(float(np.linalg.norm(jac(x) @ sv)) * b[-1] * margin, ratio * a[-1]))
    sets = [ChainSet(fr.center, fr.T, h["a"], h["b"], math.nextafter(h["c"] * h["b"] / h["a"], 0.0))]
    for x, u, s, ai, bi in zip(xs[1:], U[1:], S, a, b):
        T = ((float(u[0]), float(s[0])), (float(u[1]), float(s[1])))
        sets.append(ChainSet((float(x[0]), float(x[1])), T, float(ai), float(bi), float(g)))
    return {"sets": sets, "local": (fr, h["a"], h["b"], h["c"])}


def henon_chain_certificate(**design: Any) -> Dict[str, Any]:
    """The chain proof of the Henon map's homoclinic point (:func:`~taylorball.rigorous.homoclinic_chain.henon_chain`,
    53 bits, milliseconds): a known answer for the chain checker."""
    from .homoclinic import HenonMap
    from .homoclinic_cert import HENON_T
    from .homoclinic_chain_cert import _run_jobs, chain_record, finish_chain

    d = henon_chain(**design)
    fr, a, b, c = d["local"]
    rec = chain_record(HenonMap(Fraction(HENON_T)), d["sets"], [53] * (len(d["sets"]) - 1),
                       {"frame": fr, "a": a, "b": b, "c": c, "prec": 53}, [[0, 1], [1, 0]],
                       title="the area-preserving Henon map f(x, y) = (y, -x + 4 y + y^2), reversible with R(x, y) = "
                             "(y, x), has a transversal homoclinic point of its saddle (0, 0) on the line x = y (near "
                             "(-2.6366, -2.6366)), by a chain of covering relations")
    res: Dict[int, Dict[str, Any]] = {}
    def keep(r: Dict[str, Any]) -> bool:
        res[r["i"]] = r
        return True

    _run_jobs(rec, [-1] + list(range(len(d["sets"]) - 1)), 1, keep)
    rec["relations"] = {str(i): r for i, r in res.items() if i >= 0}
    rec["local_result"] = res.get(-1)
    return finish_chain(rec)


def tzenoff_chain_record(design: Dict[str, Any]) -> Dict[str, Any]:
    """The record of Tzenoff's chain from a design of
    :func:`~taylorball.rigorous.homoclinic_chain_design.tzenoff_chain_design`."""
    from .certificates import tzenoff_ball, tzenoff_levels
    from .homoclinic import Frame, SectionBallMap
    from .homoclinic_cert import SIGMA1, TZENOFF_FRAME, TZENOFF_HSET
    from .homoclinic_chain import ChainSet
    from .homoclinic_chain_cert import chain_record

    Ks = [float.fromhex(v) for v in design["K"]]
    taus = [float.fromhex(v) for v in design["tau"]]
    f = SectionBallMap(tzenoff_ball(), tzenoff_levels(-20.0), Ks[0], taus[0], Ks, taus, prec=128, start="doubleton")
    sets: List[Any] = [ChainSet.from_json(s) for s in design["sets"]]
    h = TZENOFF_HSET
    return chain_record(f, sets, design["prec"], {"frame": Frame(*TZENOFF_FRAME), "a": h["a"], "b": h["b"], "c": h["c"],
                                                  "prec": 128}, SIGMA1, start="doubleton",
                        title="Tzenoff's case (I = (2, 2, 3), m = 7/2, a = 1, Omega = 3; C = 10, M_gamma = 6, h = -20): "
                              "the reduced flow has a transversal homoclinic orbit to the relative periodic orbit "
                              "of the section map's saddle near (r1, r2) = (-0.255049, 0); it crosses the section "
                              "on the reversor's line r2 = 0 near r1 = 0.0103008")


if __name__ == "__main__":  # pragma: no cover - the long run's command line
    import argparse
    import json
    import logging

    ap = argparse.ArgumentParser(description="prove the relations of a chain state file (resumable)")
    ap.add_argument("state")
    ap.add_argument("--design", help="a design JSON (tzenoff_chain_design) to start a new state file from")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--only", type=int, nargs="*")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    from .homoclinic_chain_cert import run_chain

    rec0 = None
    if args.design:
        with open(args.design) as fh:
            rec0 = tzenoff_chain_record(json.load(fh))
    out = run_chain(args.state, workers=args.workers, record=rec0, only=args.only)
    print(out["message"])
