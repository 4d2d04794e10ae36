"""Transport in the lifted angles from many orbits in the SIMD lanes (issue 10).

The diffusion study (:mod:`taylorball.figures.diffusion`) runs 16 orbits per level; this one
runs the Fig. 4a level (the chaotic sea, G = 10, H = 2, h = 5) with the orbits and
observables of ``studies/diffusion_h2_1e8.toml`` (seed 1: its first ``n_orbits`` initial
states) in the study runner's ``lanes`` backend, into a resumable store under
``OUT/longruns``, and reduces it with the same tools: the MSD exponent ``mu`` of the lifted
section angle ``l`` and of the heading ``psi`` (:func:`taylorball.transport.diffusion_exponent`,
ensemble drift removed, a bootstrap interval over orbits) on three lag ranges, each orbit's
own exponent about its own drift (:func:`taylorball.transport.msd_per_orbit`), ballistic
orbits, the running extremes of ``|R|`` against their rigorous bound, the integrals' drift.

QUICK: 8 orbits to t = 2e4 (seconds). FULL: 64 orbits to 1e6 (~35 min on 2 cores; the same
store as ``taylorball run studies/diffusion_h2_64_1e6.toml`` would make; rerun to resume,
raise ``t_end`` to extend bit-identically).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Optional

import numpy as np

from . import _common as C
from . import diffusion as D


@dataclass(frozen=True)
class Config:
    n_orbits: int = 8
    t_end: float = 2e4
    checkpoint_every: float = 5000.0
    angles_every: float = 50.0
    sections: Any = 30
    histogram_bins: int = 200
    workers: int = 2
    # lag ranges of the fits, as fractions of t_end: the diffusion study's main one (0.01, 0.1)
    # and two others (whether the MSD curves over the lags)
    lag_ranges: tuple = ((0.001, 0.01), (0.01, 0.1), (0.1, 0.5))
    n_boot: int = 1000


QUICK = Config()
FULL = Config(n_orbits=64, t_end=1e6, workers=1)
LEVEL = D.LEVELS[0]  # ("h2", Omega = 2, H = 2, h = 5)


def study_config(cfg: Config, workdir: Path):
    """The :class:`taylorball.study.StudyConfig` (lanes backend; store
    ``workdir/diffusion_large_h2_<fingerprint[:12]>``)."""
    from ..study import StudyConfig

    dc = dataclasses.replace(D.FULL, n_orbits=cfg.n_orbits, t_end=cfg.t_end, checkpoint_every=cfg.checkpoint_every,
                             angles_every=cfg.angles_every, sections=cfg.sections,
                             histogram_bins=cfg.histogram_bins, workers=cfg.workers)
    d = D.study_dict(dc, LEVEL, "store")
    d["run"]["backend"] = "lanes"
    fp = StudyConfig.from_dict(d, base=Path(workdir)).fingerprint()
    d["output"]["store"] = f"diffusion_large_{LEVEL[0]}_{fp[:12]}"
    return StudyConfig.from_dict(d, source=f"diffusion_large {LEVEL[0]}", base=Path(workdir))


def compute(cfg: Config, workdir: Optional[Path] = None):
    """Run (or resume) the store and reduce it: ``(arrays, meta)``."""
    import taylorball as tb
    from .. import transport as T
    from ..contact import radius_bound
    from .runner import DEFAULT_OUT

    workdir = Path(workdir if workdir is not None else DEFAULT_OUT / "longruns")
    workdir.mkdir(parents=True, exist_ok=True)
    scfg = study_config(cfg, workdir)
    status = tb.run_study(scfg, progress="diffusion_large h2")
    ds = tb.open_run(scfg.store)
    t = np.asarray(ds["angles_time"].values, dtype=float)
    span = float(t[-1] - t[0])
    meta: Dict[str, Any] = {"store": str(scfg.store), "fingerprint": scfg.fingerprint(), "backend": "lanes",
                            "Omega": LEVEL[1], "H": LEVEL[2], "h": LEVEL[3],
                            "radius_bound": float(radius_bound(scfg.params, scfg.levels.C, scfg.levels.h))}
    arrays: Dict[str, np.ndarray] = {"t": t}
    for name, var in (("l", "angles_l"), ("heading", "heading_heading")):
        x = np.asarray(ds[var].values, dtype=float)
        own = T.msd_per_orbit(t, x)
        fits = []
        for a, b in cfg.lag_ranges:
            lr = (a * span, b * span)
            r = T.diffusion_exponent(t, x, lag_range=lr, n_boot=cfg.n_boot, seed=1)
            mu_own = own.exponents(lr)
            fits.append({"lag_range": list(lr), "mu": float(r.mu), "ci": [float(v) for v in r.ci],
                         "regime": str(r.regime), "D": float(r.D), "own_mu_median": float(np.median(mu_own)),
                         "own_mu_range": [float(mu_own.min()), float(mu_own.max())]})
        main = T.diffusion_exponent(t, x, lag_range=(0.01 * span, 0.1 * span), n_boot=cfg.n_boot, seed=1)
        lags, m = T.msd(t, x)
        arrays[f"{name}_lags"], arrays[f"{name}_msd"] = np.asarray(lags), np.asarray(m)
        meta[name] = {"fits": fits, "drift": float(main.drift), "drift_ci": [float(v) for v in main.drift_ci],
                      "drift_spread": float(main.drift_spread),
                      "ballistic": [int(i) for i in T.ballistic_orbits(t, x)]}
    rmin, rmax = D.running_extremes(np.asarray(ds["extremes_r_min"].values), np.asarray(ds["extremes_r_max"].values))
    arrays["r_min"], arrays["r_max"] = rmin, rmax
    arrays["chunk_t"] = cfg.checkpoint_every * np.arange(1, rmax.shape[1] + 1)
    half = rmax.shape[1] // 2 - 1  # growth over the run's second half
    meta["r"] = {"max_final": float(rmax[:, -1].max()), "min_final": float(rmin[:, -1].min()),
                 "max_growth_second_half": float(np.max(rmax[:, -1] - rmax[:, half])) if half >= 0 else None,
                 "min_decrease_second_half": float(np.max(rmin[:, half] - rmin[:, -1])) if half >= 0 else None}
    meta["max_integral_drift"] = float(np.nanmax(ds["drift_drift"].values))
    meta["n_steps"] = [int(o["n_steps"]) for o in status.orbits]
    meta["wall_per_chunk_median"] = float(np.median([o["wall_per_chunk"] for o in status.orbits]))
    return arrays, meta


def plot(arrays, meta, outdir):
    plt = C.pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    ax = axes[0]
    for name, lab, col in (("l", r"section angle $l$", "#0072B2"), ("heading", r"heading $\psi$", "#D55E00")):
        lags, m = np.asarray(arrays[f"{name}_lags"]), np.asarray(arrays[f"{name}_msd"])
        ok = (lags > 0) & (m > 0)
        f = meta[name]["fits"][1]
        ax.loglog(lags[ok], m[ok], color=col,
                  label=f"{lab}: $\\mu$ = {f['mu']:.3f} [{f['ci'][0]:.3f}, {f['ci'][1]:.3f}]")
        ax.axvspan(*f["lag_range"], color="0.9", zorder=0)
    lags, m = np.asarray(arrays["l_lags"]), np.asarray(arrays["l_msd"])
    ok = (lags > 0) & (m > 0)
    ax.loglog(lags[ok], lags[ok] * (m[ok][-1] / lags[ok][-1]), "k:", lw=1, label="slope 1 (normal diffusion)")
    ax.set_xlabel(r"lag $\tau$")
    ax.set_ylabel("MSD (ensemble drift removed)")
    n_orbits = np.asarray(arrays["r_max"]).shape[0]
    ax.set_title(f"{n_orbits} orbits to $t$ = {float(arrays['t'][-1]):.0e} (grey: fit range)")
    ax.legend(fontsize=8)
    ax = axes[1]
    t = np.asarray(arrays["chunk_t"])
    ax.plot(t, np.asarray(arrays["r_max"]).T, color="#0072B2", lw=0.5, alpha=0.5)
    ax.plot(t, np.asarray(arrays["r_min"]).T, color="#009E73", lw=0.5, alpha=0.5)
    ax.axhline(meta["radius_bound"], color="k", ls="--", lw=1,
               label=f"rigorous bound {meta['radius_bound']:.1f} (errata N1)")
    ax.set_xscale("log")
    ax.set_xlabel("$t$")
    ax.set_ylabel(r"running max (blue) / min (green) of $|R|$")
    ax.legend(fontsize=8)
    fig.suptitle(f"Fig. 4a level (G = 10, H = {meta['H']:g}, h = {meta['h']:g}, $\\Omega$ = {meta['Omega']:g}): "
                 "transport in the lifted angles")
    return C.save_figure(fig, outdir, "diffusion_large")
