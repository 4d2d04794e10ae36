"""Does the contact point diffuse? Long runs of the Fig. 4/5 ball (I = (2, 3, 4), m = 1,
a = 5, Omega = 2, levels G = 10, h = 5; H = 2 chaotic, H = 6 mixed).

Section 4 of the paper asks whether the contact point's motion is bounded. The Jacobi
integral bounds it rigorously (|R| <= taylorball.contact.radius_bound, errata N1), so it
cannot escape; what is left is whether it slowly spreads inside that bound. This study
follows orbits for a long time with taylorball.longrun (atomic checkpoints, bit-exact
resume: an interrupted study continues where it stopped when rerun) and records the
running extremes of the distance |R| = sqrt(x^2 + y^2) from the rotation axis at
log-spaced times. Saturating extremes mean the contact point stays in a fixed annulus;
extremes that keep growing decade after decade would mean diffusion.

The extremes are taken over samples every ``sample_dt`` (not over the continuous
trajectory), so they are inner estimates of the true ones, to ~|dR/dt| sample_dt / 2.

Run: ``python studies/contact_diffusion.py [--full] [--out DIR]`` (the long runs live in
``DIR/longruns/``; rerun to resume).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..paper import FIG4A_LEVELS, FIG4B_LEVELS
from . import _common as C


@dataclass(frozen=True)
class Config(C.BallCaption):
    H: tuple = (FIG4A_LEVELS.M_gamma, FIG4B_LEVELS.M_gamma)
    n_orbits: int = 2  # per H
    t_end: float = 2000.0
    sample_dt: float = 0.5
    checkpoint_dt: float = 500.0
    n_log: int = 40  # log-spaced times at which the running extremes are reported
    seed: int = 0


QUICK = Config()
FULL = Config(n_orbits=4, t_end=1e6, sample_dt=2.0, checkpoint_dt=2e4)


def _member(item):
    """One long run (top level: picklable for process or dask ensembles); ``item`` is
    ``(config, folder)``."""
    from taylorball.longrun import _long_run

    cfg, path = item
    return _long_run(cfg, path)


def running_extremes(t, r, times):
    """Running min and max of ``r`` over ``t <= T`` for each ``T`` in ``times``."""
    rmax = np.maximum.accumulate(r)
    rmin = np.minimum.accumulate(r)
    idx = np.searchsorted(t, times, side="right") - 1
    return rmin[idx], rmax[idx]


def compute(cfg, workdir=None):
    from taylorball import integral_scales
    from taylorball.contact import radius_bound
    from taylorball.ensemble import call, run_many
    from taylorball.longrun import LongRunConfig

    p = cfg.ball()
    from .runner import DEFAULT_OUT

    workdir = Path(workdir if workdir is not None else DEFAULT_OUT / "longruns")
    runs, tags = [], []
    for tag, H in zip("ab", cfg.H):
        states, _, _ = C.reduced_initial_states(p, **cfg.levels(H).as_kwargs(), n=cfg.n_orbits, seed=cfg.seed)
        for s in states:
            lr = LongRunConfig(kind="reduced", params=p, state=tuple(s), t_end=cfg.t_end, sample_dt=cfg.sample_dt,
                               checkpoint_dt=cfg.checkpoint_dt)
            runs.append((lr, workdir / f"contact_diffusion_{lr.fingerprint()}"))
            tags.append(tag)
    # one bar over the runs, advanced chunk by chunk (resumed chunks count as done)
    results = run_many([call(_member, r) for r in runs], backend="threads", progress=f"long runs to t={cfg.t_end:g}")
    times = np.geomspace(min(10.0, cfg.t_end), cfg.t_end, cfg.n_log)
    rmin, rmax, drift, tail = [], [], [], []
    for res in results:
        r = np.hypot(res.xy[:, 0], res.xy[:, 1])
        lo, hi = running_extremes(res.t, r, times)
        rmin.append(lo)
        rmax.append(hi)
        # drift of each integral relative to its natural scale (taylorball.integral_scales)
        sc = integral_scales("reduced", p, res.states[0])
        drift.append(max(float(np.max(np.abs(v - v[0]))) / sc[k] for k, v in res.integrals.items() if k in sc))
        tail.append(res.xy[-min(len(res.xy), 20000):])
    rmin, rmax = np.array(rmin), np.array(rmax)
    # growth of the extremes over the last decade of time (0 if saturated)
    j = int(np.searchsorted(times, cfg.t_end / 10.0))
    arrays = {"times": times, "r_min": rmin, "r_max": rmax, "H": np.array([cfg.H["ab".index(t)] for t in tags]),
              "tail_xy": np.array(tail)}
    meta = {
        "H_of_orbit": [cfg.H["ab".index(t)] for t in tags],
        "run_folders": [str(path) for _, path in runs],
        "radius_bound": radius_bound(p, cfg.G, cfg.h),
        "r_max_final": rmax[:, -1].tolist(),
        "r_min_final": rmin[:, -1].tolist(),
        "r_max_growth_last_decade": (rmax[:, -1] - rmax[:, j]).tolist(),
        "r_min_decrease_last_decade": (rmin[:, j] - rmin[:, -1]).tolist(),
        "max_relative_integral_drift": float(max(drift)),
        "n_steps": [int(res.n_steps) for res in results],
    }
    return arrays, meta


def plot(arrays, meta, outdir):
    plt = C.pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.8))
    t = arrays["times"]
    for k, (lo, hi) in enumerate(zip(arrays["r_min"], arrays["r_max"])):
        col = C.REGULAR_COLORS[4] if meta["H_of_orbit"][k] == 2.0 else C.REGULAR_COLORS[3]
        a.plot(t, hi, color=col, lw=1)
        a.plot(t, lo, color=col, lw=1, ls="--")
    a.axhline(meta["radius_bound"], color="k", lw=0.8)
    a.text(t[0], meta["radius_bound"] * 0.97, "rigorous bound (Jacobi integral)", va="top", fontsize=8)
    a.set_xscale("log")
    a.set_yscale("log")
    a.set_xlabel("$t$")
    a.set_ylabel("running max (solid) and min (dashed) of $|R|$")
    a.set_title("(a) extremes of $|R|$ up to $t$ (vermillion: $H = 2$, blue: $H = 6$)")
    k = int(np.argmax(np.asarray(meta["H_of_orbit"]) == 2.0))
    xy = arrays["tail_xy"][k]
    b.plot(xy[:, 0], xy[:, 1], lw=0.2, color=C.REGULAR_COLORS[4])
    b.set_aspect("equal", adjustable="datalim")
    b.set_xlabel("$x$")
    b.set_ylabel("$y$")
    b.set_title(f"(b) contact point, $H = 2$, last {len(xy)} samples to $t$ = {t[-1]:g}")
    fig.suptitle(r"Contact point of the asymmetric ball $I = (2, 3, 4)$, $m = 1$, $a = 5$, $h = 5$, $G = 10$, "
                 r"$\Omega = 2$ over long times")
    return C.save_figure(fig, outdir, "contact_diffusion", meta)


if __name__ == "__main__":
    from .runner import main

    sys.exit(main(sys.modules[__name__]))
