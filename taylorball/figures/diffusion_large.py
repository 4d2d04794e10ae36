"""Transport in the lifted angles from many orbits in the SIMD lanes.

The diffusion study (:mod:`taylorball.figures.diffusion`) runs 16 orbits per level; this one
runs the Fig. 4 levels (``h2``: the chaotic sea, G = 10, H = 2, h = 5; ``h6``: mixed, H = 6)
with the orbits and observables of ``studies/diffusion_<label>_1e8.toml`` (seed 1: its first
``n_orbits`` initial states) in the study runner's ``lanes`` backend, into resumable stores
under ``OUT/longruns``, and reduces them with the same tools: the MSD exponent ``mu`` of the lifted
section angle ``l`` and of the heading ``psi`` (:func:`taylorball.transport.diffusion_exponent`,
ensemble drift removed, a bootstrap interval over orbits) on three lag ranges, each orbit's
own exponent about its own drift (:func:`taylorball.transport.msd_per_orbit`), ballistic
orbits, the orbit classes (chaotic / regular by MEGNO, as the diffusion study) with each
class's transport, the running extremes of ``|R|`` against their rigorous bound, the
integrals' drift.

QUICK: 8 orbits per level to t = 2e4 (seconds). FULL: 64 orbits per level to 1e6 (~32 min
per level on one core; the h2 store is the one ``taylorball run
studies/diffusion_h2_64_1e6.toml`` makes; rerun to resume, raise ``t_end`` to extend
bit-identically).
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
    levels: tuple = ("h2", "h6")  # labels of taylorball.figures.diffusion.LEVELS
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
    megno_T: float = 1000.0  # orbit classes: <Y> > megno_threshold at megno_T (compact norm)
    megno_threshold: float = 4.0
    megno_jacobian: str = C.QUICK_MEGNO_JACOBIAN


QUICK = Config()
FULL = Config(n_orbits=64, t_end=1e6, workers=1, megno_jacobian=C.FULL_MEGNO_JACOBIAN)


def _level(label: str) -> tuple:
    return dict((lv[0], lv) for lv in D.LEVELS)[label]


def _diffusion_config(cfg: Config):
    """The diffusion study's Config with this study's orbits, run and observables (its
    ``study_dict`` and ``_classes`` read them)."""
    return dataclasses.replace(D.FULL, n_orbits=cfg.n_orbits, t_end=cfg.t_end,
                               checkpoint_every=cfg.checkpoint_every, angles_every=cfg.angles_every,
                               sections=cfg.sections, histogram_bins=cfg.histogram_bins, workers=cfg.workers,
                               lag_range=(0.01, 0.1),
                               n_boot=cfg.n_boot, megno_T=cfg.megno_T, megno_threshold=cfg.megno_threshold)


def study_config(cfg: Config, label: str, workdir: Path):
    """The :class:`taylorball.study.StudyConfig` of level ``label`` (lanes backend; store
    ``workdir/diffusion_large_<label>_<fingerprint[:12]>``)."""
    from ..study import StudyConfig

    d = D.study_dict(_diffusion_config(cfg), _level(label), "store")
    d["run"]["backend"] = "lanes"
    fp = StudyConfig.from_dict(d, base=Path(workdir)).fingerprint()
    d["output"]["store"] = f"diffusion_large_{label}_{fp[:12]}"
    return StudyConfig.from_dict(d, source=f"diffusion_large {label}", base=Path(workdir))


def compute(cfg: Config, workdir: Optional[Path] = None):
    """Run (or resume) each level's store and reduce it: ``(arrays, meta)``, arrays and
    ``meta["levels"][label]`` per level."""
    import taylorball as tb
    from .. import transport as T
    from ..contact import radius_bound
    from .runner import DEFAULT_OUT

    workdir = Path(workdir if workdir is not None else DEFAULT_OUT / "longruns")
    workdir.mkdir(parents=True, exist_ok=True)
    dc = _diffusion_config(cfg)
    arrays: Dict[str, np.ndarray] = {}
    meta: Dict[str, Any] = {"levels": {}, "backend": "lanes"}
    for label in cfg.levels:
        _, omega, H, h = _level(label)
        scfg = study_config(cfg, label, workdir)
        status = tb.run_study(scfg, progress=C.bar(f"diffusion_large {label}"))
        ds = tb.open_run(scfg.store)
        t = np.asarray(ds["angles_time"].values, dtype=float)
        span = float(t[-1] - t[0])
        out: Dict[str, Any] = {"store": str(scfg.store), "fingerprint": scfg.fingerprint(), "Omega": omega,
                               "H": H, "h": h, "n_orbits": cfg.n_orbits, "t_end": cfg.t_end,
                               "radius_bound": float(radius_bound(scfg.params, scfg.levels.C, scfg.levels.h))}
        res = tb.megno_many("reduced", scfg.params, list(scfg.initial_states), cfg.megno_T, norm="compact",
                            stop_above=10.0, workers=cfg.workers, options=tb.MegnoOptions(jacobian=cfg.megno_jacobian))
        megno = np.array([r.mean_megno for r in res])
        chaotic = megno > cfg.megno_threshold
        arrays[f"{label}_megno"] = megno
        out["n_chaotic"] = int(chaotic.sum())
        arrays[f"{label}_t"] = t
        for name, var in (("l", "angles_l"), ("heading", "heading_heading")):
            x = np.asarray(ds[var].values, dtype=float)
            own = T.msd_per_orbit(t, x)
            fits, results = [], {}
            for a, b in cfg.lag_ranges:
                lr = (a * span, b * span)
                r = T.diffusion_exponent(t, x, lag_range=lr, n_boot=cfg.n_boot, seed=1)
                results[(a, b)] = r
                mu_own = own.exponents(lr)
                fits.append({"lag_range": list(lr), "mu": float(r.mu), "ci": [float(v) for v in r.ci],
                             "regime": str(r.regime), "D": float(r.D),
                             "own_mu_median": float(np.median(mu_own)),
                             "own_mu_range": [float(mu_own.min()), float(mu_own.max())]})
            # the drift from the diffusion study's main range, (0.01, 0.1) of t_end (fitted above if listed)
            main = results[(0.01, 0.1)] if (0.01, 0.1) in results else T.diffusion_exponent(
                t, x, lag_range=(0.01 * span, 0.1 * span), n_boot=cfg.n_boot, seed=1)
            lags, m = T.msd(t, x)
            arrays[f"{label}_{name}_lags"], arrays[f"{label}_{name}_msd"] = np.asarray(lags), np.asarray(m)
            cl = D._classes(dc, t, x, chaotic)
            for k in ("own_msd_curves", "own_lags"):
                cl.pop(k)
            for cname, cm in cl.pop("class_msd").items():
                arrays[f"{label}_{name}_msd_{cname}"] = cm
            out[name] = {"fits": fits, "drift": float(main.drift),
                         "drift_ci": [float(v) for v in main.drift_ci],
                         "drift_spread": float(main.drift_spread),
                         "ballistic": [int(i) for i in T.ballistic_orbits(t, x)], "classes": cl}
        rmin, rmax, chunk_t, out["r"] = D.extremes_summary(ds, cfg.checkpoint_every)
        arrays[f"{label}_r_min"], arrays[f"{label}_r_max"], arrays[f"{label}_chunk_t"] = rmin, rmax, chunk_t
        out["max_integral_drift"] = float(np.nanmax(ds["drift_drift"].values))
        out["n_steps"] = [int(o["n_steps"]) for o in status.orbits]
        meta["levels"][label] = out
    return arrays, meta


def plot(arrays, meta, outdir):
    plt = C.pyplot()
    labels = list(meta["levels"])
    fig, axes = plt.subplots(len(labels), 2, figsize=(11, 4.0 * len(labels)), constrained_layout=True,
                             squeeze=False)
    for row, label in zip(axes, labels):
        lv = meta["levels"][label]
        ax = row[0]
        for name, lab, col in (("l", r"$l$", "#0072B2"), ("heading", r"$\psi$", "#D55E00")):
            lags, m = np.asarray(arrays[f"{label}_{name}_lags"]), np.asarray(arrays[f"{label}_{name}_msd"])
            ok = (lags > 0) & (m > 0)
            f = lv[name]["fits"][1]
            ax.loglog(lags[ok], m[ok], color=col,
                      label=f"{lab}, all: $\\mu$ = {f['mu']:.3f} [{f['ci'][0]:.3f}, {f['ci'][1]:.3f}]")
            key = f"{label}_{name}_msd_chaotic"
            c = lv[name]["classes"].get("chaotic", {})
            if key in arrays and lv[name]["classes"].get("regular", {}).get("n", 0) and "mu" in c:
                mc = np.asarray(arrays[key])
                okc = (lags > 0) & (mc > 0)
                ax.loglog(lags[okc], mc[okc], color=col, ls="--",
                          label=f"{lab}, chaotic ({c['n']}): $\\mu$ = {c['mu']:.3f} "
                                f"[{c['ci'][0]:.3f}, {c['ci'][1]:.3f}]")
            ax.axvspan(*f["lag_range"], color="0.9", zorder=0)
        lags, m = np.asarray(arrays[f"{label}_l_lags"]), np.asarray(arrays[f"{label}_l_msd"])
        ok = (lags > 0) & (m > 0)
        ax.loglog(lags[ok], lags[ok] * (m[ok][-1] / lags[ok][-1]), "k:", lw=1, label="slope 1")
        ax.set_xlabel(r"lag $\tau$")
        ax.set_ylabel("MSD (mean rate of all / of the class removed)")
        ax.set_title(f"{label}: H = {lv['H']:g}, {lv['n_orbits']} orbits ({lv['n_chaotic']} chaotic) to "
                     f"$t$ = {lv['t_end']:.0e}; grey: fit range")
        ax.legend(fontsize=7)
        ax = row[1]
        t = np.asarray(arrays[f"{label}_chunk_t"])
        ax.plot(t, np.asarray(arrays[f"{label}_r_max"]).T, color="#0072B2", lw=0.5, alpha=0.5)
        ax.plot(t, np.asarray(arrays[f"{label}_r_min"]).T, color="#009E73", lw=0.5, alpha=0.5)
        ax.axhline(lv["radius_bound"], color="k", ls="--", lw=1,
                   label=f"rigorous bound {lv['radius_bound']:.1f} (errata N1)")
        ax.set_xscale("log")
        ax.set_yscale("log")  # the minima (~1) and maxima (~20) and the bound (~100) at once
        ax.set_xlabel("$t$")
        ax.set_ylabel(r"running max (blue) / min (green) of $|R|$")
        ax.legend(fontsize=8)
    fig.suptitle("Transport in the lifted angles, Fig. 4 levels (G = 10, h = 5, $\\Omega$ = 2), SIMD lanes")
    return C.save_figure(fig, outdir, "diffusion_large", meta)
