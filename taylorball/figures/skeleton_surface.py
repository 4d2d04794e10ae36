"""The 2D unstable and 1D stable manifolds of the Fig. 4a saddle of the 3D section map.

The Fig. 4 ball (``I = (2, 3, 4)``, ``Omega = 2``) on the Fig. 4a level (``G = 10, H = 2,
h = 5``): the catalogued saddle ``periodic_catalog.FIG4A_SADDLE_K10`` (10 crossings of
``g = 0``, multipliers 0.0155, 7.17, 8.98) has a 2D unstable manifold, grown as leaves
(closed curves, images of a ring of the unstable plane:
:func:`taylorball.periodic_manifolds_3d.grow_surface`), and a 1D stable manifold, grown by
the flow backwards (:func:`taylorball.periodic_manifolds.grow_manifold`, both branches).
(a) the leaves in the chart projected on ``(l, r1)``, coloured by iterate, with the stable
curve and the orbit's first point; (b) the same on ``(r1, r2)``; (c) the surface's trace on
the plane ``r2 = r2*`` through the orbit's point (the leaves' crossings of that plane,
joined per ring), with the stable curve's crossings of the plane.

Run: ``taylorball reproduce --only skeleton_surface`` or ``python studies/skeleton_surface.py [--full] [--out DIR]``.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Config:
    #: grow_surface: iterates, chart extent, offset, rings, refinement distance.
    n_iter: int = 4
    extent: float = 0.3
    s0: float = 1e-4
    n_rings: int = 4
    delta: float = 0.05
    #: grow_manifold for the stable curve: chart arc length per branch, refinement distance.
    stable_length: float = 0.05
    stable_delta: float = 0.05


QUICK = Config()
FULL = Config(n_iter=6, extent=1.0, n_rings=8, delta=0.02, stable_length=0.3, stable_delta=0.02)


def compute(cfg: Config):
    from taylorball.periodic_catalog import FIG4A_SADDLE_K10, catalog_orbit
    from taylorball.periodic_manifolds import grow_manifold
    from taylorball.periodic_manifolds_3d import grow_surface, surface_trace

    t0 = time.process_time()
    o = catalog_orbit(FIG4A_SADDLE_K10)
    S = grow_surface(o, n_iter=cfg.n_iter, extent=cfg.extent, s0=cfg.s0, n_rings=cfg.n_rings, delta=cfg.delta)
    t_surface = time.process_time() - t0
    t0 = time.process_time()
    ws = [grow_manifold(o, "stable", length=cfg.stable_length, branch=b, delta=cfg.stable_delta, refine_all=False)
          for b in (1, -1)]
    t_stable = time.process_time() - t0
    p0 = o.points[0]
    tr = surface_trace(S, 2, float(p0[2]))
    stable_cross = []
    for w in ws:
        P = w.points
        a = P[:-1, 2] - p0[2]
        b = P[1:, 2] - p0[2]
        for i in np.flatnonzero((np.sign(a) != np.sign(b)) & np.isfinite(a + b)):
            stable_cross.append(P[i] + a[i] / (a[i] - b[i]) * (P[i + 1] - P[i]))
    arrays = {
        "leaf_points": np.vstack(S.leaves),
        "leaf_index": np.concatenate([np.full(len(C), j) for j, C in enumerate(S.leaves)]),
        "leaf_iterate": S.iterate, "leaf_tau": S.tau,
        "stable_plus": ws[0].points, "stable_minus": ws[1].points, "orbit_points": o.points,
        "trace_points": np.array([p for p, _, _ in tr]).reshape(-1, 3),
        "trace_tau": np.array([t for _, t, _ in tr]), "trace_iterate": np.array([i for _, _, i in tr]),
        "stable_crossings": np.array(stable_cross).reshape(-1, 3),
    }
    meta = {"multipliers": [float(abs(m)) for m in o.multipliers], "period": o.period, "k": o.k,
            "surface": repr(S), "surface_stopped": S.stopped, "map_calls": S.map_calls,
            "stable_arc": [w.arc_length for w in ws], "stable_calls": [w.map_calls for w in ws],
            "cpu_s_surface": t_surface, "cpu_s_stable": t_stable}
    return arrays, meta


def plot(arrays, meta, outdir):
    from . import _common as C

    plt = C.pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(17, 5.8), layout="constrained")
    P, idx, its = arrays["leaf_points"], arrays["leaf_index"], arrays["leaf_iterate"]
    cmap = plt.get_cmap("viridis")
    top = max(1, int(its.max()))
    p0 = arrays["orbit_points"][0]
    for ax, (i, j, names) in zip(axes[:2], ((0, 1, ("$l$", "$r_1$")), (1, 2, ("$r_1$", "$r_2$")))):
        for leaf in range(len(its)):
            Q = P[idx == leaf]
            Q = np.vstack([Q, Q[:1]])
            ax.plot(Q[:, i], Q[:, j], "-", lw=0.7, color=cmap(its[leaf] / top))
        for key, c in (("stable_plus", "tab:red"), ("stable_minus", "tab:orange")):
            ax.plot(arrays[key][:, i], arrays[key][:, j], "-", lw=1.4, color=c,
                    label=f"$W^s$, branch {'+1' if key.endswith('plus') else '-1'}")
        ax.plot(p0[i], p0[j], "x", color="k", ms=9, mew=2, label="saddle (point 1 of 10)")
        ax.set_xlabel(names[0])
        ax.set_ylabel(names[1])
    axes[0].legend(loc="best", fontsize=7)
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(0, top))
    fig.colorbar(sm, ax=axes[1], label="iterate $n$ of $F = P^{10}$")
    mu = meta["multipliers"]
    axes[0].set_title(f"(a) Fig. 4a level, saddle k = 10 (multipliers {mu[0]:.4f}, {mu[1]:.3f}, {mu[2]:.3f}):\n"
                      f"leaves of $W^u$ (2D) and $W^s$ (1D), projected on $(l, r_1)$", fontsize=8)
    axes[1].set_title("(b) the same on $(r_1, r_2)$", fontsize=8)
    bx = axes[2]
    T, tt, ti = arrays["trace_points"], arrays["trace_tau"], arrays["trace_iterate"]
    # per ring: the leaves' crossings ordered by iterate, on each side of the saddle
    for tau in np.unique(tt):
        sel = tt == tau
        for side in (1, -1):
            Q = T[sel]
            Q = Q[np.sign((Q[:, 0] - p0[0])) == side]
            Q = Q[np.argsort(np.linalg.norm(Q - p0, axis=1))]
            bx.plot(Q[:, 0], Q[:, 1], "o-", ms=2.5, lw=0.8, color=cmap(float(tau)))
    sc = arrays["stable_crossings"]
    sc = sc[np.linalg.norm(sc - p0, axis=1) > 1e-9] if len(sc) else sc  # the saddle itself is on both
    if len(sc):
        bx.plot(sc[:, 0], sc[:, 1], "*", color="tab:red", ms=11, label="$W^s$ crosses the plane")
        bx.legend(loc="best", fontsize=7)
    bx.plot(p0[0], p0[1], "x", color="k", ms=9, mew=2)
    bx.set_xlabel("$l$")
    bx.set_ylabel("$r_1$")
    note = "" if len(sc) else "; the grown $W^s$ meets the plane only at the saddle"
    bx.set_title(f"(c) trace of $W^u$ on the plane $r_2$ = {p0[2]:.5f} through the saddle\n"
                 f"(leaf crossings joined per ring, coloured by ring $\\tau${note})", fontsize=8)
    return C.save_figure(fig, outdir, "skeleton_surface", meta)


if __name__ == "__main__":
    from taylorball.figures import skeleton_surface as study  # by its name (not __main__): the data files' name
    from taylorball.figures.runner import main

    sys.exit(main(study))
