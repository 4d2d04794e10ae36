"""Does the contact point diffuse? Long runs of the Fig. 4/5 ball (I = (2, 3, 4), m = 1,
a = 5, Omega = 2, levels G = 10, h = 5; H = 2 chaotic, H = 6 mixed).

Section 4 of the paper asks whether the contact point's motion is bounded. The Jacobi
integral bounds it rigorously (|R| <= taylorball.contact.radius_bound, errata N1), so it
cannot escape; what is left is whether it slowly spreads inside that bound. This study
follows orbits for a long time with the study runner (:func:`taylorball.run_study`, one
store per level; atomic commits, bit-exact resume: an interrupted study continues where it
stopped when rerun) and records the
running extremes of the distance |R| = sqrt(x^2 + y^2) from the rotation axis at
log-spaced times. Saturating extremes mean the contact point stays in a fixed annulus;
extremes that keep growing decade after decade would mean diffusion.

The extremes are taken over samples every ``sample_dt`` (not over the continuous
trajectory), so they are inner estimates of the true ones, to ~|dR/dt| sample_dt / 2.

Run: ``python studies/contact_diffusion.py [--full] [--out DIR]`` (the stores live in
``DIR/longruns/contact_diffusion_H<H>_<fingerprint>``, one per level; rerun to resume; raising
``t_end`` extends them). Each store is an ordinary study store: ``tb.open_run(store)``.
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


def studies(cfg, workdir):
    """The study of each level ``H`` (reduced system, float64, the orbits drawn as
    :func:`compute` draws them): every state sampled (``samples_every = sample_dt``) and
    the integrals' drift at the chunk ends, in the store
    ``workdir/contact_diffusion_H<H>_<fingerprint>`` (the fingerprint names what the
    orbits' bits depend on, so another configuration gets another store and a rerun of this
    one resumes it)."""
    import taylorball as tb

    p = cfg.ball()
    prob = tb.problem("reduced", p)
    out = []
    for H in cfg.H:
        states, _, _ = C.reduced_initial_states(p, **cfg.levels(H).as_kwargs(), n=cfg.n_orbits, seed=cfg.seed)
        kw = dict(states=states, t_end=cfg.t_end, checkpoint_every=cfg.checkpoint_dt, sample_dt=cfg.sample_dt,
                  backend="threads",
                  observables={"samples_every": cfg.sample_dt, "drift": True, "angles_every": 0.0, "extremes": False})
        fp = tb.StudyConfig.from_problem(prob, store=workdir, **kw).fingerprint()  # not of the store
        out.append(tb.StudyConfig.from_problem(prob, store=workdir / f"contact_diffusion_H{H:g}_{fp[:16]}", **kw))
    return out


def running_extremes(t, r, times):
    """Running min and max of ``r`` over ``t <= T`` for each ``T`` in ``times``."""
    rmax = np.maximum.accumulate(r)
    rmin = np.minimum.accumulate(r)
    idx = np.searchsorted(t, times, side="right") - 1
    return rmin[idx], rmax[idx]


def compute(cfg, workdir=None):
    import taylorball as tb
    from taylorball.contact import radius_bound
    from taylorball.model import KIND_TABLE

    p = cfg.ball()
    from .runner import DEFAULT_OUT

    workdir = Path(workdir if workdir is not None else DEFAULT_OUT / "longruns")
    contact = KIND_TABLE["reduced"].contact
    times = np.geomspace(min(10.0, cfg.t_end), cfg.t_end, cfg.n_log)
    rmin, rmax, drift, tail, n_steps, tags, stores = [], [], [], [], [], [], []
    for H, study in zip(cfg.H, studies(cfg, workdir)):
        status = tb.run_study(study, progress=C.bar(f"long runs H={H:g} to t={cfg.t_end:g}"))
        ds = tb.open_run(study.store)
        for i in range(study.n_orbits):
            t = ds["samples_t"][i].values
            keep = t <= cfg.t_end  # a store extended further by an earlier run holds more
            t = t[keep]
            xy = contact(p, ds["samples_state"][i].values[keep])  # the contact point (x, y) of each sample
            r = np.hypot(xy[:, 0], xy[:, 1])
            lo, hi = running_extremes(t, r, times)
            rmin.append(lo)
            rmax.append(hi)
            # drift of the integrals at the chunk ends, relative to their natural scales
            # (taylorball.integral_scales), in the working precision
            drift.append(float(np.max(ds["drift_drift"][i].values[ds["drift_t"][i].values <= cfg.t_end])))
            tail.append(xy[-min(len(xy), 20000):])
            n_steps.append(int(status.orbits[i]["n_steps"]))  # to the store's end
            tags.append(H)
        stores.append(str(study.store))
    rmin, rmax = np.array(rmin), np.array(rmax)
    # growth of the extremes over the last decade of time (0 if saturated)
    j = int(np.searchsorted(times, cfg.t_end / 10.0))
    arrays = {"times": times, "r_min": rmin, "r_max": rmax, "H": np.array(tags), "tail_xy": np.array(tail)}
    meta = {
        "H_of_orbit": tags,
        "stores": stores,
        "radius_bound": radius_bound(p, cfg.G, cfg.h),
        "r_max_final": rmax[:, -1].tolist(),
        "r_min_final": rmin[:, -1].tolist(),
        "r_max_growth_last_decade": (rmax[:, -1] - rmax[:, j]).tolist(),
        "r_min_decrease_last_decade": (rmin[:, j] - rmin[:, -1]).tolist(),
        "max_relative_integral_drift": float(max(drift)),
        "n_steps": n_steps,
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
