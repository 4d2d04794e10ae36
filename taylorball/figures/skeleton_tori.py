"""The cores of the Fig. 4b tori: two invariant circles of the 3D section map.

The Fig. 4 ball (``I = (2, 3, 4)``, ``Omega = 2``) on the Fig. 4b level (``G = 10, H = 6,
h = 5``): the tori around ``l = pi/2`` surround an invariant circle ``K`` with
``P(K(theta)) = K(theta + rho)`` (:func:`taylorball.invariant_circles.invariant_circle`,
from the orbit of ``invariant_circles.FIG4B_CORE_SEED``), and its image under the rotation by
``pi`` about the body axis 3 is the core of the tori around ``l = 3 pi/2``. (a) the circles
and nearby tori (orbits from ``r1 + delta`` at ``l = pi/2``) projected on ``(l, r1)``; (b) the
tori's cuts by the slab ``|l - pi/2| < slab / 2`` in ``(r1, r2)``, around the circle's
crossing; (c) the independent check: ``|P^n(K(0)) - K(n rho)|`` along a
:func:`taylorball.poincare_section` run from the first node; (d) the tori's rotation angle (by
frequency analysis) against ``delta``: it tends to the circle's ``rho``.

Run: ``taylorball reproduce --only skeleton_tori`` or ``python studies/skeleton_tori.py [--full] [--out DIR]``.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Config:
    #: crossings of the seed's orbit (Newton's guess), nodes of the circle
    n_seed: int = 1500
    n_nodes: int = 141
    #: offsets in r1 of the tori's starts at l = pi/2, and their crossings
    deltas: tuple = (0.05, 0.2, 0.8, 1.6)
    n_points: int = 1500
    #: crossings of the independent check from the first node
    n_check: int = 300


QUICK = Config()
FULL = Config(deltas=(0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.6, 2.4), n_points=6000, n_check=2000)

#: Half width of the slab of ``l`` around ``pi/2`` in panel (b) (a plot choice).
SLAB_HALF = 0.05


def compute(cfg: Config):
    import taylorball as tb
    from taylorball.invariant_circles import FIG4B_CORE_SEED, invariant_circle, rotation_from_orbit
    from taylorball.paper import FIG4_BALL, FIG4B_LEVELS
    from taylorball.sections import chart_points

    lev = FIG4B_LEVELS.as_kwargs()
    (pt, root) = FIG4B_CORE_SEED
    x0 = tb.states_on_section(FIG4_BALL, **lev, point=pt, direction=1)[root]
    t0 = time.process_time()
    seed_orbit = tb.poincare_section("reduced", FIG4_BALL, x0, n_points=cfg.n_seed).states
    c = invariant_circle("reduced", FIG4_BALL, seed_orbit, n_nodes=cfg.n_nodes, levels=FIG4B_LEVELS)
    t_circle = time.process_time() - t0
    theta = np.linspace(0.0, 2 * np.pi, 2001)
    curve = chart_points("reduced", c.evaluate(theta))  # the chart of internal states
    image = curve.copy()
    image[:, 0] = np.mod(image[:, 0] + np.pi, 2 * np.pi)  # rotation by pi about body axis 3: l + pi
    t0 = time.process_time()
    check = tb.poincare_section("reduced", FIG4_BALL, c.states[0], n_points=cfg.n_check)
    phase_err = np.max(np.abs(c.evaluate(c.rho * np.arange(1, cfg.n_check + 1), public=True) - check.states), axis=1)
    starts = []
    for d in cfg.deltas:
        roots = tb.states_on_section(FIG4_BALL, **lev, point=(pt[0], pt[1] + d, pt[2]), direction=1)
        starts.append(roots[int(np.argmin([abs(s[2] - x0[2]) for s in roots]))])
    secs = tb.poincare_sections("reduced", FIG4_BALL, starts, n_points=cfg.n_points, batch=True)
    rho_tori = []
    for s in secs:
        r = rotation_from_orbit(s.states)
        rho_tori.append(min(abs(r - c.rho), abs(r - (2 * np.pi - c.rho))))  # orientation-free difference
    t_rest = time.process_time() - t0
    arrays = {"curve": curve, "image": image, "nodes": c.points, "phase_err": phase_err,
              "tori_points": np.vstack([s.points for s in secs]),
              "tori_index": np.concatenate([np.full(len(s.points), i) for i, s in enumerate(secs)]),
              "deltas": np.array(cfg.deltas, dtype=float), "rho_diff": np.array(rho_tori)}
    meta = {"rho": c.rho, "rotation_number": c.rotation_number, "residual": c.residual,
            "residual_history": list(c.residual_history), "fourier_tail": c.fourier_tail,
            "cpu_s_circle": t_circle, "cpu_s_checks": t_rest}
    return arrays, meta


def plot(arrays, meta, outdir):
    from . import _common as C

    plt = C.pyplot()
    fig, ax = plt.subplots(1, 4, figsize=(20, 5.2), layout="constrained")
    cmap = plt.get_cmap("viridis")
    P, idx, ds = arrays["tori_points"], arrays["tori_index"], arrays["deltas"]
    n = max(1, len(ds) - 1)
    for i, d in enumerate(ds):
        Q = P[idx == i]
        ax[0].plot(Q[:, 0], Q[:, 1], ".", ms=0.8, color=cmap(i / n), label=f"torus, $\\delta$ = {d:g}")
        s = np.abs(Q[:, 0] - np.pi / 2) < SLAB_HALF
        ax[1].plot(Q[s, 1], Q[s, 2], ".", ms=2.5, color=cmap(i / n))
    for key, style, lab in (("curve", "k-", "circle (core, $l \\sim \\pi/2$)"),
                            ("image", "r-", "its image: rotation by $\\pi$ about axis 3")):
        K = arrays[key]
        jumps = np.flatnonzero(np.abs(np.diff(K[:, 0])) > np.pi)  # the wrap of l at 2 pi
        for seg in np.split(np.arange(len(K)), jumps + 1):
            ax[0].plot(K[seg, 0], K[seg, 1], style, lw=1.5, label=lab if seg[0] == 0 else None)
    K = arrays["curve"]
    k = np.flatnonzero((np.abs(K[:, 0] - np.pi / 2) < SLAB_HALF) & (K[:, 1] > 3))
    if len(k):
        ax[1].plot(K[k, 1], K[k, 2], "k.", ms=1.5, zorder=3, label="the circle in the slab (a short arc)")
        ax[1].legend(fontsize=7, markerscale=6)
    ax[0].set(xlabel="$l$", ylabel="$r_1$", xlim=(0, 2 * np.pi))
    ax[0].legend(fontsize=7, loc="upper right", markerscale=8)
    ax[0].set_title(f"(a) Fig. 4b level: invariant circle, rotation number {meta['rotation_number']:.8f}\n"
                    f"(141 nodes, residual {meta['residual']:.1e}), its image, nearby tori on $(l, r_1)$",
                    fontsize=8)
    ax[1].set(xlabel="$r_1$", ylabel="$r_2$")
    ax[1].set_title("(b) the tori cut by $|l - \\pi/2| < 0.05$, $r_1 > 3$ part: nested around the circle",
                    fontsize=8)
    ax[1].set_xlim(3, None)
    e = arrays["phase_err"]
    ax[2].semilogy(np.arange(1, len(e) + 1), e, "k-", lw=0.8)
    ax[2].set(xlabel="crossing $n$", ylabel="$\\max |P^n(K(0)) - K(n\\rho)|$ (public state)")
    ax[2].set_title("(c) independent check: a float64 section run from the first node\n"
                    "follows the rotation on the circle", fontsize=8)
    rd = arrays["rho_diff"]
    ax[3].loglog(ds, rd, "o-", color="tab:blue", label="torus (frequency analysis)")
    ax[3].loglog(ds, rd[0] * (ds / ds[0]) ** 2, "--", color="0.5", label="slope 2")
    ax[3].set(xlabel="offset $\\delta$ of the torus's start in $r_1$", ylabel="$|\\rho_{torus} - \\rho|$")
    ax[3].legend(fontsize=7)
    ax[3].set_title("(d) the tori's rotation angle tends to the circle's", fontsize=8)
    return C.save_figure(fig, outdir, "skeleton_tori", meta)


if __name__ == "__main__":
    from taylorball.figures import skeleton_tori as study  # by its name (not __main__): the data files' name
    from taylorball.figures.runner import main

    sys.exit(main(study))

