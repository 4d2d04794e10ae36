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
from typing import Any, Dict, Mapping, Optional

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
#: The Fig. 4a level's 64 orbits extended to 1e7 (the store of ``taylorball run
#: studies/diffusion_h2_64_1e6.toml --extend 1e7``, reduced by :func:`reduce_stores`): the MSD
#: exponent per lag decade from 1e2 to 1e6, and 1e6 .. 5e6. The Fig. 4b level's store
#: (``diffusion_h6_64_1e6.toml``) is reduced alike with ``levels=("h6",)``.
FULL_1E7 = Config(levels=("h2",), n_orbits=64, t_end=1e7, workers=2, megno_jacobian=C.FULL_MEGNO_JACOBIAN,
                  lag_ranges=((1e-5, 1e-4), (1e-4, 1e-3), (1e-3, 1e-2), (1e-2, 1e-1), (1e-1, 0.5)))
#: The diffusion study's main lag range, as fractions of t_end: the figure's left panel shows its fit.
MAIN_LAGS = (0.01, 0.1)


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

    from .runner import DEFAULT_OUT

    workdir = Path(workdir if workdir is not None else DEFAULT_OUT / "longruns")
    workdir.mkdir(parents=True, exist_ok=True)
    arrays: Dict[str, np.ndarray] = {}
    meta: Dict[str, Any] = {"levels": {}, "backend": "lanes"}
    for label in cfg.levels:
        scfg = study_config(cfg, label, workdir)
        status = tb.run_study(scfg, progress=C.bar(f"diffusion_large {label}"))
        ds = tb.open_run(scfg.store)
        out = _reduce_level(cfg, label, scfg, ds, arrays)
        out["n_steps"] = [int(o["n_steps"]) for o in status.orbits]
        meta["levels"][label] = out
    return arrays, meta


def reduce_stores(cfg: Config, stores: Mapping[str, Any], *, reached_only: bool = False):
    """Reduce the stores of study files (``taylorball run``) with this study's orbits,
    observables and chunking, e.g. ``studies/diffusion_h2_64_1e6.toml`` extended to ``cfg.t_end``
    (:data:`FULL_1E7`): ``(arrays, meta)`` as :func:`compute`, nothing run. ``stores`` maps
    each label of ``cfg.levels`` to its store folder. A store's fingerprint must be the one
    :func:`study_config` gives for ``cfg`` (the same orbits and observables; a store of other
    orbits is refused); a store run beyond ``cfg.t_end`` is read to ``cfg.t_end`` (its bits
    there are those of a run to ``cfg.t_end``). Every orbit must have reached ``cfg.t_end``;
    with ``reached_only`` an unfinished store is reduced over the orbits that have (an unbiased
    subset when the orbits' order is not the dynamics': ``meta`` lists them).
    """
    import taylorball as tb

    from ..errors import UsageError

    if sorted(stores) != sorted(cfg.levels):
        raise UsageError(f"reduce_stores: stores must name a store for each of the levels {list(cfg.levels)}, "
                         f"got {sorted(stores)}")
    arrays: Dict[str, np.ndarray] = {}
    meta: Dict[str, Any] = {"levels": {}, "backend": "lanes"}
    n_chunks = int(round(cfg.t_end / cfg.checkpoint_every))
    n_times = int(round(cfg.t_end / cfg.angles_every)) + 1
    for label in cfg.levels:
        store = Path(stores[label])
        scfg = study_config(cfg, label, store.parent)
        ds = tb.open_run(store)
        if ds.attrs["fingerprint"] != scfg.fingerprint():
            raise UsageError(f"reduce_stores: store={str(store)!r} holds other orbits or observables than "
                             f"diffusion_large level {label!r} with {cfg.n_orbits} orbits (fingerprint "
                             f"{ds.attrs['fingerprint']} against {scfg.fingerprint()})")
        progress = np.asarray(ds.attrs["progress"], dtype=int)
        reached = np.flatnonzero(progress >= n_chunks)
        if reached.size < cfg.n_orbits and not reached_only:
            raise UsageError(f"reduce_stores: {reached.size} of {cfg.n_orbits} orbits of {str(store)!r} have "
                             f"reached t_end = {cfg.t_end:g}; run the study to the end or pass reached_only=True")
        if reached.size < 2:
            raise UsageError(f"reduce_stores: {reached.size} orbits of {str(store)!r} have reached t_end = "
                             f"{cfg.t_end:g}; at least 2 are needed")
        ds = ds.isel(orbit=reached, angles_time=slice(0, n_times), heading_time=slice(0, n_times),
                     extremes_chunk=slice(0, n_chunks), drift_chunk=slice(0, n_chunks))
        out = _reduce_level(cfg, label, scfg, ds, arrays, states=[scfg.initial_states[i] for i in reached])
        out.update(store=str(store), orbits=[int(i) for i in reached], n_orbits_study=cfg.n_orbits)
        meta["levels"][label] = out
    return arrays, meta


def _reduce_level(cfg: Config, label: str, scfg: Any, ds: Any, arrays: Dict[str, np.ndarray], *,
                  states: Optional[list] = None) -> Dict[str, Any]:
    """One level's reduction of its store's Dataset ``ds`` into ``arrays`` (keys prefixed by
    ``label``) and the returned metadata; ``states``: the orbits' initial states (default all
    of the study's)."""
    import taylorball as tb
    from .. import transport as T
    from ..contact import radius_bound

    _, omega, H, h = _level(label)
    dc = _diffusion_config(cfg)
    states = list(scfg.initial_states) if states is None else states
    t = np.asarray(ds["angles_time"].values, dtype=float)
    span = float(t[-1] - t[0])
    out: Dict[str, Any] = {"store": str(scfg.store), "fingerprint": scfg.fingerprint(), "Omega": omega,
                           "H": H, "h": h, "n_orbits": len(states), "t_end": cfg.t_end,
                           "radius_bound": float(radius_bound(scfg.params, scfg.levels.C, scfg.levels.h))}
    res = tb.megno_many("reduced", scfg.params, states, cfg.megno_T, norm="compact",
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
        main = results[MAIN_LAGS] if MAIN_LAGS in results else T.diffusion_exponent(
            t, x, lag_range=(MAIN_LAGS[0] * span, MAIN_LAGS[1] * span), n_boot=cfg.n_boot, seed=1)
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
    return out


def _chaotic_msd(arrays, lv, label: str, name: str):
    """``(lags, MSD)`` of the chaotic class of angle ``name`` where both are positive, on a
    level with a regular class too (mixed); else None."""
    key = f"{label}_{name}_msd_chaotic"
    if key not in arrays or not lv[name]["classes"].get("regular", {}).get("n", 0):
        return None
    lags, mc = np.asarray(arrays[f"{label}_{name}_lags"]), np.asarray(arrays[key])
    ok = (lags > 0) & (mc > 0)
    return lags[ok], mc[ok]


def plot(arrays, meta, outdir):
    plt = C.pyplot()
    labels = list(meta["levels"])
    fig, axes = plt.subplots(len(labels), 3, figsize=(16, 4.0 * len(labels)), constrained_layout=True,
                             squeeze=False)
    for row, label in zip(axes, labels):
        lv = meta["levels"][label]
        ax = row[0]
        for name, lab, col in (("l", r"$l$", "#0072B2"), ("heading", r"$\psi$", "#D55E00")):
            lags, m = np.asarray(arrays[f"{label}_{name}_lags"]), np.asarray(arrays[f"{label}_{name}_msd"])
            ok = (lags > 0) & (m > 0)
            f = next(f for f in lv[name]["fits"] if np.allclose(f["lag_range"], np.multiply(MAIN_LAGS, lv["t_end"])))
            ax.loglog(lags[ok], m[ok], color=col,
                      label=f"{lab}, all: $\\mu$ = {f['mu']:.3f} [{f['ci'][0]:.3f}, {f['ci'][1]:.3f}]")
            c = lv[name]["classes"].get("chaotic", {})
            cm = _chaotic_msd(arrays, lv, label, name)
            if cm is not None and "mu" in c:
                ax.loglog(*cm, color=col, ls="--",
                          label=f"{lab}, chaotic ({c['n']}): $\\mu$ = {c['mu']:.3f} "
                                f"[{c['ci'][0]:.3f}, {c['ci'][1]:.3f}]")
            ax.axvspan(*f["lag_range"], color="0.9", zorder=0)
        lags, m = np.asarray(arrays[f"{label}_l_lags"]), np.asarray(arrays[f"{label}_l_msd"])
        ok = (lags > 0) & (m > 0)
        ax.loglog(lags[ok], lags[ok] * (m[ok][-1] / lags[ok][-1]), "k:", lw=1, label="slope 1")
        ax.set_xlabel(r"lag $\tau$")
        ax.set_ylabel("MSD (mean rate of all / of the class removed)")
        of = f" of {lv['n_orbits_study']} (those that reached $t$ = {lv['t_end']:.0e})" \
            if lv.get("n_orbits_study", lv["n_orbits"]) != lv["n_orbits"] else ""
        ax.set_title(f"{label}: $\\Omega$ = {lv['Omega']:g}, H = {lv['H']:g}, h = {lv['h']:.4g}\n{lv['n_orbits']} "
                     f"orbits{of} ({lv['n_chaotic']} chaotic) to $t$ = {lv['t_end']:.0e}; grey: fit range",
                     fontsize=9)
        ax.legend(fontsize=7)
        ax = row[1]  # normal diffusion reads as a flat line: MSD / (2 tau), and mu per lag range
        rows, growth = [], 1.0
        for name, lab, col in (("l", r"$l$", "#0072B2"), ("heading", r"$\psi$", "#D55E00")):
            lags, m = np.asarray(arrays[f"{label}_{name}_lags"]), np.asarray(arrays[f"{label}_{name}_msd"])
            ok = (lags > 0) & (m > 0)
            d = m[ok] / (2 * lags[ok])
            ax.loglog(lags[ok], d, color=col, marker=".", ms=3, label=lab)
            if d.size:
                growth = max(growth, float(d[-1] / d[0]))
            cm = _chaotic_msd(arrays, lv, label, name)  # a mixed level: the chaotic class alone, as on the left
            if cm is not None:
                ax.loglog(cm[0], cm[1] / (2 * cm[0]), color=col, ls="--", lw=1, label=f"{lab}, chaotic class")
            rows += [f"{lab} {f['lag_range'][0]:.0e}..{f['lag_range'][1]:.0e}: $\\mu$ = {f['mu']:.3f} "
                     f"[{f['ci'][0]:.3f}, {f['ci'][1]:.3f}]" for f in lv[name]["fits"]]
        # the fits where the curves are not: between flat (normal) lines, above rising ones
        at = (0.02, 0.58, "center") if growth < 10 else (0.02, 0.98, "top")
        ax.text(at[0], at[1], "\n".join(rows), transform=ax.transAxes, fontsize=6, va=at[2], family="monospace",
                bbox={"facecolor": "white", "edgecolor": "0.8", "alpha": 0.9})
        ax.set_xlabel(r"lag $\tau$")
        ax.set_ylabel(r"MSD / (2 $\tau$)  (rad$^2$ per time unit)")
        ax.set_title(r"flat: normal diffusion; $\mu$ per lag range, 95 % bootstrap over orbits")
        ax.legend(fontsize=8, loc="upper right")
        ax = row[2]
        t = np.asarray(arrays[f"{label}_chunk_t"])
        ax.plot(t, np.asarray(arrays[f"{label}_r_max"]).T, color="#0072B2", lw=0.5, alpha=0.5)
        ax.plot(t, np.asarray(arrays[f"{label}_r_min"]).T, color="#009E73", lw=0.5, alpha=0.5)
        ax.axhline(lv["radius_bound"], color="k", ls="--", lw=1,
                   label=f"rigorous bound {lv['radius_bound']:.1f} (errata N1)")
        zero = int(np.sum(np.any(np.asarray(arrays[f"{label}_r_min"]) <= 0, axis=-1)))
        if zero:  # a log axis cannot show them: say so on the panel
            ax.text(0.02, 0.02, f"{zero} orbit(s) with a minimum of 0 (|R|$^2$'s interpolant below 0 at a close\n"
                    "pass of the axis: below its resolution), not drawn", transform=ax.transAxes, fontsize=7)
        ax.set_xscale("log")
        ax.set_yscale("log")  # the minima (~1) and maxima (~20) and the bound (~100) at once
        ax.set_xlabel("$t$")
        ax.set_ylabel(r"running max (blue) / min (green) of $|R|$")
        ax.legend(fontsize=8)
    fig.suptitle("Transport in the lifted angles, the ball of Fig. 4 (I = (2, 3, 4), m = 1, a = 5), G = 10, "
                 "SIMD lanes")
    return C.save_figure(fig, outdir, meta.get("stem", "diffusion_large"), meta)
