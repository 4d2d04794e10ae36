"""Diffusion in the lifted angles (a question next to section 4's, which asks whether the
contact point's motion is finite: the bound N1 of docs/errata.md answers that): is transport normal,
anomalous or ballistic on the Fig. 4 levels, are there accelerator-mode-like orbits, does
the chaotic sea's occupation of its section converge to the invariant density, and how do
the extremes of |R| grow?

The ball of Fig. 4 (I = (2, 3, 4), m = 1, a = 5), G = |M| = 10, on three levels:

* ``h2``: Omega = 2, H = 2, h = 5 (Fig. 4a): one chaotic sea (100 / 100 orbits chaotic in the
  chaos atlas);
* ``h6``: Omega = 2, H = 6, h = 5 (Fig. 4b): mixed, tori and chaotic layers;
* ``weak``: Omega = 0.25, H = 2, h = 2.46648 (the chaos atlas's level at that rate,
  ``chaos_atlas.level_h(chaos_atlas.FULL, 2.0)``): the onset of chaos, where 35 / 100 orbits
  have MEGNO > 4 at T = 1000 and the chaotic fraction grows with T (slow, weak chaos in
  layers between tori; docs/figures.md, "the chaos atlas").

Each level is one study store written by :func:`taylorball.run_study` (orbits drawn on the
level's admissible section region; observables reduced on the fly: the lifted section angle
``l`` and the heading ``psi`` every ``angles_every``, the |R| extremes per chunk, the |R|
histogram, the section crossings) and read back (the arrays of :func:`taylorball.open_run`, as
numpy arrays: ``taylorball._store_read.read_arrays``, without xarray and dask). The
reductions: mean squared displacement of ``l`` and ``psi`` over lags with the ensemble
drift removed and reported, the exponent mu of MSD ~ lag^mu with its bootstrap interval over
orbits (:func:`taylorball.transport.diffusion_exponent`), ballistic orbits
(:func:`taylorball.transport.ballistic_orbits`), the running extremes of |R| against the
rigorous bound (:func:`taylorball.contact.radius_bound`), and, on the chaotic-sea level, the
total-variation distance between each orbit's crossings and the section map's invariant
density (:func:`taylorball.transport.occupation`) over time, the reference bin masses from
the fold-free Monte Carlo :func:`taylorball.section_sigma_sample` (the per-bin Gauss
quadrature of :func:`taylorball.section_sigma` is kept for comparison: it does not
converge, sigma diverging like ``d^-1/2`` at the folds), with the islands' share of sigma
from MEGNO on sigma-weighted points.

Orbit classes: each orbit's initial state is chaotic when its MEGNO ``<Y>`` (compact norm)
exceeds 4 at ``T = megno_T`` (the chaos atlas's test), and again at ``megno_T_long``; per
class the ensemble MSD about the class's mean rate, and per orbit its own time-averaged
MSD about its own rate (:func:`taylorball.transport.msd_per_orbit`): whether an ensemble's
ballistic spreading is transport along orbits or the spread of their mean rates.

Run: ``python studies/diffusion.py [--full] [--out DIR]`` (stores in ``DIR/longruns/``,
resumed when rerun). The cluster version (1e8 time units) is the study files
``studies/diffusion_*_1e8.toml`` (``taylorball run``, ``backend = "dask"``).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Optional, Tuple

import numpy as np

from ..paper import FIG4_BALL
from . import _common as C

#: ``(label, Omega, H, h)`` of the three levels (G = 10 for all); the weak-chaos ``h`` is
#: ``chaos_atlas.level_h(chaos_atlas.FULL, 2.0)`` (the middle of the R = 0 energy range).
LEVELS = (("h2", 2.0, 2.0, 5.0), ("h6", 2.0, 6.0, 5.0), ("weak", 0.25, 2.0, 2.466481324298602))


@dataclass(frozen=True)
class Config:
    inertia: tuple = FIG4_BALL.inertia
    mass: float = FIG4_BALL.mass
    radius: float = FIG4_BALL.radius
    G: float = 10.0
    levels: tuple = LEVELS
    n_orbits: int = 2  # per level
    seed: int = 1
    t_end: float = 400.0
    checkpoint_every: float = 200.0
    angles_every: float = 2.0
    sections: Any = "all"  # crossings recorded: "all" or every Nth
    histogram_bins: int = 50
    lag_range: Tuple[float, float] = (0.01, 0.1)  # fit range of mu, as fractions of t_end
    # further fit ranges (fractions of t_end), compared with the main one: the bootstrap
    # interval does not see a curvature of the MSD over a range (docs/transport.md)
    other_lag_ranges: tuple = ((0.1, 0.5),)
    n_boot: int = 1000
    occ_bins: Tuple[int, int, int] = (2, 2, 2)  # (l, r1, r2) bins of the occupation, h2 level
    # the reference: tb.section_sigma_sample with occ_mc draws in 16 batches (converges like
    # occ_mc^-1/2); occ_quad: Gauss points per coordinate of the old per-bin quadrature of
    # tb.section_sigma, compared with it on the pooled histogram (which does not converge)
    occ_mc: int = 2**16
    occ_quad: tuple = (1,)
    occ_times: int = 8
    # sigma-weighted points of the h2 level classified by MEGNO (the islands' share of the
    # invariant measure: the sea's occupation can differ from sigma by up to that much)
    occ_islands: int = 4
    megno_T: float = 1000.0  # MEGNO time of the orbit classes (the chaos atlas's: <Y> > 4 at T = 1000)
    megno_threshold: float = 4.0
    # a second, longer MEGNO time: orbits of slow (weak) chaos pass <Y> = 4 only later
    megno_T_long: Optional[float] = None
    megno_jacobian: str = C.QUICK_MEGNO_JACOBIAN
    workers: int = 2


QUICK = Config(n_boot=200)
FULL = Config(n_orbits=16, t_end=2e5, checkpoint_every=5000.0, angles_every=10.0, histogram_bins=200,
              other_lag_ranges=((0.001, 0.01), (0.1, 0.5)), occ_bins=(8, 6, 6), occ_quad=(1, 2, 3), occ_times=16,
              occ_mc=2**24, occ_islands=64, megno_T_long=1e4, megno_jacobian=C.FULL_MEGNO_JACOBIAN)


def ball(cfg: Config, omega: float):
    from ..params import BallParams

    return BallParams(inertia=tuple(cfg.inertia), mass=cfg.mass, radius=cfg.radius, plane_rate=float(omega))


def study_dict(cfg: Config, level: tuple, store: str) -> Dict[str, Any]:
    """The study file's tables (as :func:`taylorball.load_study` parses them) of one level."""
    _, omega, H, h = level
    return {
        "ball": {"inertia": [float(v) for v in cfg.inertia], "mass": cfg.mass, "radius": cfg.radius,
                 "plane_rate": float(omega)},
        "level": {"G": cfg.G, "H": float(H), "h": float(h)},
        "orbits": {"n": cfg.n_orbits, "seed": cfg.seed},
        "run": {"t_end": cfg.t_end, "checkpoint_every": cfg.checkpoint_every, "backend": "threads",
                "workers": cfg.workers},
        "observables": {"extremes": True, "angles_every": cfg.angles_every, "sections": cfg.sections,
                        "histogram": {"bins": cfg.histogram_bins}},
        "output": {"store": store},
    }


def study_config(cfg: Config, level: tuple, workdir: Path):
    """The level's :class:`taylorball.study.StudyConfig`; its store is
    ``workdir/diffusion_<label>_<fingerprint[:12]>`` (so another configuration never meets
    a store it would be refused by, and raising ``t_end`` resumes the same store)."""
    from ..study import StudyConfig

    d = study_dict(cfg, level, "store")
    fp = StudyConfig.from_dict(d, base=Path(workdir)).fingerprint()
    d["output"]["store"] = f"diffusion_{level[0]}_{fp[:12]}"
    return StudyConfig.from_dict(d, source=f"diffusion {level[0]}", base=Path(workdir))


def running_extremes(r_min: np.ndarray, r_max: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Running min and max over chunks (axis 1) of per-chunk extremes ``(orbit, chunk)``."""
    return np.minimum.accumulate(r_min, axis=1), np.maximum.accumulate(r_max, axis=1)


def _values(ds, name: str) -> np.ndarray:
    """Array ``name`` of a store read by :func:`taylorball.open_run` (an xarray Dataset) or by
    ``taylorball._store_read.read_arrays`` (a dict of numpy arrays)."""
    v = ds[name]
    return np.asarray(getattr(v, "values", v))


def extremes_summary(ds, checkpoint_every: float
                     ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, Dict[str, Any]]:
    """The running extremes of ``|R|`` of a study store's Dataset ``ds``: ``(r_min, r_max)``
    (orbit x chunk), the chunks' end times, and their summary: the final max and min over
    orbits and how far they moved over the run's second half (None for a single chunk)."""
    rmin, rmax = running_extremes(_values(ds, "extremes_r_min"), _values(ds, "extremes_r_max"))
    half = rmin.shape[1] // 2 - 1  # growth over the second half of the run
    grow = float(np.max(rmax[:, -1] - rmax[:, half])) if half >= 0 else None
    fall = float(np.max(rmin[:, half] - rmin[:, -1])) if half >= 0 else None
    summary = {"r_max_final": float(rmax[:, -1].max()), "r_min_final": float(rmin[:, -1].min()),
               "r_max_growth_second_half": grow, "r_min_decrease_second_half": fall}
    return rmin, rmax, checkpoint_every * np.arange(1, rmin.shape[1] + 1), summary


def _exponent(t: np.ndarray, x: np.ndarray, **kw: Any) -> Any:
    """:func:`taylorball.transport.diffusion_exponent` without its warning about few orbits:
    the figure says it instead (no interval below :data:`MIN_ORBITS_FOR_CI` orbits, and the
    title says the intervals are too narrow below ``FEW_ORBITS``)."""
    import warnings

    from .. import transport as T

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"diffusion_exponent: \d+ orbits; with fewer than")
        return T.diffusion_exponent(t, x, **kw)


def _transport(t: np.ndarray, x: np.ndarray, cfg: Config) -> Dict[str, Any]:
    from .. import transport as T

    lr = (cfg.lag_range[0] * cfg.t_end, cfg.lag_range[1] * cfg.t_end)
    res = _exponent(t, x, lag_range=lr, n_boot=cfg.n_boot, seed=cfg.seed)
    lags, m = T.msd(t, x)
    others = []
    for a, b in cfg.other_lag_ranges:
        r = _exponent(t, x, lag_range=(a * cfg.t_end, b * cfg.t_end), n_boot=cfg.n_boot, seed=cfg.seed)
        others.append({"lag_range": [a * cfg.t_end, b * cfg.t_end], "mu": float(r.mu),
                       "ci": [float(v) for v in r.ci], "regime": str(r.regime)})
    return {"other_fits": others, "mu": float(res.mu), "ci": [float(v) for v in res.ci], "D": float(res.D),
            "drift": float(res.drift), "drift_ci": [float(v) for v in res.drift_ci],
            "drift_spread": float(res.drift_spread), "regime": str(res.regime),
            "lag_range": list(lr), "ballistic": [int(i) for i in T.ballistic_orbits(t, x)],
            "lags": np.asarray(lags), "msd": np.asarray(m)}


def _occupation(cfg: Config, params, level: tuple, sec, at: np.ndarray, sample=None) -> Dict[str, Any]:
    """TV distance of each orbit's crossings from sigma at the times ``at``: bins over the
    crossings' range of every orbit of the level; the reference bin masses from
    :func:`taylorball.section_sigma_sample` (``cfg.occ_mc`` draws in 16 batches: their
    spread is the reference's error, and the TV of the reference from its first ``k``
    batches against all 16 shows its convergence); the pooled histogram of all orbits
    against the reference and against the per-bin Gauss quadrature of sigma (``occ_quad``);
    ``sample``: batch 0 of the reference if already drawn (:func:`_sigma_sample`)."""
    from .. import charts
    from .. import transport as T
    from ..levels import Levels

    lev = Levels.from_caption(G=cfg.G, H=level[2], h=level[3]).as_kwargs()
    l, r1, r2, t = (np.asarray(_values(sec, k), dtype=float) for k in ("l", "r1", "r2", "t"))
    ok = np.isfinite(t)
    lo1, hi1 = float(np.min(r1[ok])), float(np.max(r1[ok]))
    lo2, hi2 = float(np.min(r2[ok])), float(np.max(r2[ok]))
    pad1, pad2 = 1e-6 * (hi1 - lo1), 1e-6 * (hi2 - lo2)
    edges = [np.linspace(0.0, 2 * math.pi, cfg.occ_bins[0] + 1),
             np.linspace(lo1 - pad1, hi1 + pad1, cfg.occ_bins[1] + 1),
             np.linspace(lo2 - pad2, hi2 + pad2, cfg.occ_bins[2] + 1)]
    n_batch = 16
    per = max(1, cfg.occ_mc // n_batch)
    batches, totals = [], []
    for k in range(n_batch):
        smp = sample if k == 0 and sample is not None else _sigma_sample(cfg, params, level, k)
        batches.append(np.histogramdd(smp["points"], bins=edges, weights=smp["weights"])[0])
        totals.append(smp["total"])
    B = np.array(batches)
    ref = B.sum(axis=0)
    q = ref / ref.sum()
    def tv(a, b):
        return float(0.5 * np.abs(a / a.sum() - b / b.sum()).sum())

    # convergence: TV between two independent references of k batches each (k = 1 .. 8)
    # falls like k^-1/2 if the estimate converges; the full one (16) is ~1/sqrt(2) of the last
    tv_pairs = {str(k * per): tv(B[:k].sum(axis=0), B[k:2 * k].sum(axis=0)) for k in (1, 2, 4, 8)}
    inside = float(ref.sum() / np.sum(totals))  # sigma's share inside the crossings' box
    dist, floor, n = [], [], []
    pooled = np.zeros_like(q)
    for i in range(t.shape[0]):
        k = ok[i]
        pts = np.column_stack([np.mod(l[i, k], 2 * math.pi), r1[i, k], r2[i, k]])
        occ = T.occupation(pts, t[i, k], ref, edges, at=at)
        dist.append(occ.distance)
        floor.append(occ.floor)
        n.append(occ.n)
        pooled += np.histogramdd(pts, bins=edges)[0]
    p_pool = pooled / pooled.sum()
    gauss = {}
    for quad in cfg.occ_quad:
        g = T.occupation(np.full((1, 3), 0.5), [0.0], lambda x: charts.section_sigma(params, **lev, points=x),
                         edges, at=[0.0], quad=int(quad)).reference
        gauss[str(int(quad))] = float(0.5 * np.abs(p_pool - g).sum())
    return {"at": np.asarray(at), "distance": np.array(dist), "floor": np.array(floor), "n": np.array(n),
            "edges": [e.tolist() for e in edges],
            "reference": {"draws": int(per * n_batch), "batches": n_batch,
                          "tv_independent_pairs": tv_pairs, "mass_inside_bins": inside,
                          "pooled_tv": float(0.5 * np.abs(p_pool - q).sum()),
                          "pooled_floor": float(0.5 * np.sum(np.sqrt(2 * q * (1 - q) / (math.pi * pooled.sum())))),
                          "pooled_tv_gauss": gauss}}


def _sigma_sample(cfg: Config, params, level: tuple, k: int) -> Dict[str, Any]:
    """Batch ``k`` of the level's :func:`taylorball.section_sigma_sample` (``cfg.occ_mc``
    draws in 16 batches; batch 0 also gives the :func:`_island_states`)."""
    from .. import charts
    from ..levels import Levels

    lev = Levels.from_caption(G=cfg.G, H=level[2], h=level[3]).as_kwargs()
    return charts.section_sigma_sample(params, **lev, n=max(1, cfg.occ_mc // 16),
                                       seed=np.random.SeedSequence([cfg.seed, k]), direction=1)


def _island_states(cfg: Config, params, level: tuple, sample: Dict[str, Any]) -> np.ndarray:
    """``cfg.occ_islands`` states at points drawn with probability proportional to sigma
    (from a :func:`taylorball.section_sigma_sample`), for :func:`_islands`."""
    from ..charts import reduced_state_from_chart
    from ..levels import Levels

    lev = Levels.from_caption(G=cfg.G, H=level[2], h=level[3]).as_kwargs()
    w = sample["weights"]
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, 99]))
    pick = rng.choice(w.size, size=cfg.occ_islands, replace=True, p=w / w.sum())
    P = sample["points"][pick]
    return reduced_state_from_chart(params, C=lev["C"], M_gamma=lev["M_gamma"], K=sample["K"][pick], l=P[:, 0],
                                    g=0.0, r1=P[:, 1], r2=P[:, 2])


def _megno_pooled(cfg: Config, groups: Dict[Any, Tuple[Any, list]], t_end: float) -> Dict[Any, np.ndarray]:
    """MEGNO ``<Y>`` (norm "compact", stopped above 10) of every group's states, ``groups`` a
    dict ``key -> (params, states)``: the groups of one ball (the same rotation rate) share one
    :func:`taylorball.megno_many` call, whose lanes then run full (an orbit's ``<Y>`` depends
    only on its own state, not on the orbits around it). Returns ``key -> <Y>`` per state."""
    import taylorball as tb

    out: Dict[Any, np.ndarray] = {}
    by_ball: Dict[Any, list] = {}
    for key, (params, states) in groups.items():
        by_ball.setdefault(params, []).append((key, len(states)))
    for params, members in by_ball.items():
        states = [x for key, _ in members for x in groups[key][1]]
        res = tb.megno_many("reduced", params, states, t_end, norm="compact", stop_above=10.0, workers=cfg.workers,
                            options=tb.MegnoOptions(jacobian=cfg.megno_jacobian))
        Y = np.array([r.mean_megno for r in res])
        at = 0
        for key, n in members:
            out[key], at = Y[at:at + n], at + n
    return out


def _islands(cfg: Config, Y: np.ndarray) -> Dict[str, Any]:
    """The :func:`_island_states` classified by MEGNO ``Y`` like the orbits: the share of the
    invariant measure outside the chaotic sea (islands), with a Wilson interval."""
    from .._atlas import wilson_interval

    k = int(np.count_nonzero(Y <= cfg.megno_threshold))
    return {"n": int(cfg.occ_islands), "n_regular": k, "fraction_regular": k / cfg.occ_islands,
            "ci95": [float(v) for v in wilson_interval(k, cfg.occ_islands, 0.95)], "megno": Y.tolist(),
            "T": cfg.megno_T}


def _classes(cfg: Config, t: np.ndarray, x: np.ndarray, chaotic: np.ndarray) -> Dict[str, Any]:
    """Transport per orbit class (chaotic / regular by MEGNO) and per orbit: the class
    ensemble's MSD about the class's own mean rate (mu, drift, drift spread), each orbit's
    own time-averaged MSD about its own rate (:func:`taylorball.transport.msd_per_orbit`:
    its exponent over the main lag range), and at the top of that range the ensemble MSD
    against the mean of the orbits' own MSDs and against ``var(rate) tau^2``."""
    from .. import transport as T

    lr = (cfg.lag_range[0] * cfg.t_end, cfg.lag_range[1] * cfg.t_end)
    own = T.msd_per_orbit(t, x)
    mu_own = own.exponents(lr)
    ens = T.msd(t, x)
    k_top = int(np.flatnonzero(ens.lags <= lr[1] * (1 + 1e-9))[-1])
    tau = float(ens.lags[k_top])
    out: Dict[str, Any] = {
        "mu_own": [float(v) for v in mu_own], "rate": [float(v) for v in own.velocities],
        "top_lag": tau, "ensemble_msd_top": float(ens.msd[k_top]),
        "own_msd_mean_top": float(own.msd[:, k_top].mean()),
        # the spread term of the ensemble MSD: (1/n) sum_i (v_i - mean v)^2 tau^2 (population variance)
        "rate_var_tau2_top": float(np.var(own.velocities) * tau**2),
        "own_msd_curves": own.msd, "own_lags": own.lags, "class_msd": {},
    }
    for name, sel in (("chaotic", chaotic), ("regular", ~chaotic)):
        idx = np.flatnonzero(sel)
        c: Dict[str, Any] = {"orbits": [int(i) for i in idx], "n": int(idx.size)}
        if idx.size:
            c["rate_mean"] = float(np.mean(own.velocities[idx]))
            c["rate_sd"] = float(np.std(own.velocities[idx], ddof=1)) if idx.size > 1 else None
            c["mu_own_median"] = float(np.nanmedian(mu_own[idx]))
            c["mu_own_range"] = [float(np.nanmin(mu_own[idx])), float(np.nanmax(mu_own[idx]))]
            m_own = own.msd[idx].mean(axis=0)
            fit = (own.lags >= lr[0] * (1 - 1e-9)) & (own.lags <= lr[1] * (1 + 1e-9))
            c["mu_own_mean_curve"] = float(np.polyfit(np.log(own.lags[fit]), np.log(m_own[fit]), 1)[0])
            c["own_msd_mean_top"] = float(m_own[k_top])
        if idx.size >= 2:
            r = _exponent(t, x[idx], lag_range=lr, n_boot=cfg.n_boot, seed=cfg.seed)
            c.update(mu=float(r.mu), ci=[float(v) for v in r.ci], drift=float(r.drift),
                     drift_ci=[float(v) for v in r.drift_ci], drift_spread=float(r.drift_spread),
                     regime=str(r.regime), msd_top=float(r.msd[k_top]))
            out["class_msd"][name] = np.asarray(r.msd)
        out[name] = c
    return out


def compute(cfg: Config, workdir: Optional[Path] = None):
    """Run (or resume, or extend to a larger ``t_end``) one study store per level under
    ``workdir`` (default ``output/longruns``) and reduce it. Returns ``(arrays, meta)``:
    per level ``<label>_{l,heading}_{lags,msd}`` (MSD, ensemble drift removed),
    ``<label>_r_{min,max}`` (running extremes, orbit x chunk) at ``<label>_chunk_t``,
    ``<label>_r_histogram`` (time per |R| bin, summed over orbits), and for ``h2``
    ``occ_{at,distance,floor,n}`` (orbit x time); ``meta["levels"][label]`` holds mu, its
    interval, D, the drift and its interval, the regime, the ballistic orbits, the |R|
    extremes and their growth over the run's second half, the integrals' drift."""
    import taylorball as tb
    from .._store_read import read_arrays
    from ..contact import radius_bound
    from .runner import DEFAULT_OUT

    workdir = Path(workdir if workdir is not None else DEFAULT_OUT / "longruns")
    workdir.mkdir(parents=True, exist_ok=True)
    arrays: Dict[str, np.ndarray] = {}
    meta: Dict[str, Any] = {"levels": {}}
    # orbit classes: MEGNO of each orbit's initial state, as tb.chaotic_fraction does, and of
    # the island points of the chaotic sea (h2); the levels of one ball in one call
    scfgs = {level[0]: study_config(cfg, level, workdir) for level in cfg.levels}
    groups = {level[0]: (ball(cfg, level[1]), list(scfgs[level[0]].initial_states)) for level in cfg.levels}
    sea = next((lv for lv in cfg.levels if lv[0] == "h2"), None)
    sample0 = None
    if sea is not None:
        sample0 = _sigma_sample(cfg, ball(cfg, sea[1]), sea, 0)
        groups["islands"] = (ball(cfg, sea[1]), list(_island_states(cfg, ball(cfg, sea[1]), sea, sample0)))
    megno_by = _megno_pooled(cfg, groups, cfg.megno_T)
    megno_long_by = (_megno_pooled(cfg, {k: v for k, v in groups.items() if k != "islands"}, cfg.megno_T_long)
                     if cfg.megno_T_long is not None else {})
    for level in cfg.levels:
        label, omega, H, h = level
        scfg = scfgs[label]
        status = tb.run_study(scfg, progress=C.bar(f"diffusion {label}"))
        ds = read_arrays(scfg.store)  # tb.open_run's arrays, bit for bit, without xarray and dask
        t = np.asarray(ds["angles_time"], dtype=float)
        p = ball(cfg, omega)
        out: Dict[str, Any] = {"Omega": omega, "H": H, "h": h, "store": str(scfg.store),
                               "n_orbits": cfg.n_orbits, "t_end": cfg.t_end,
                               "radius_bound": float(radius_bound(p, cfg.G, h)),
                               "wall_per_chunk": [o["wall_per_chunk"] for o in status.orbits],
                               "n_steps": [int(o["n_steps"]) for o in status.orbits]}
        megno = megno_by[label]
        chaotic = megno > cfg.megno_threshold
        arrays[f"{label}_megno"] = megno
        out["classes"] = {"megno_T": cfg.megno_T, "threshold": cfg.megno_threshold, "stop_above": 10.0,
                          "chaotic": [int(i) for i in np.flatnonzero(chaotic)],
                          "regular": [int(i) for i in np.flatnonzero(~chaotic)]}
        chaotic_long = None
        if cfg.megno_T_long is not None:
            ml = megno_long_by[label]
            chaotic_long = ml > cfg.megno_threshold
            arrays[f"{label}_megno_long"] = ml
            out["classes_long"] = {"megno_T": cfg.megno_T_long, "threshold": cfg.megno_threshold,
                                   "chaotic": [int(i) for i in np.flatnonzero(chaotic_long)],
                                   "regular": [int(i) for i in np.flatnonzero(~chaotic_long)]}
        for name, var in (("l", "angles_l"), ("heading", "heading_heading")):
            x = np.asarray(ds[var], dtype=float)
            tr = _transport(t, x, cfg)
            arrays[f"{label}_{name}_lags"] = tr.pop("lags")
            arrays[f"{label}_{name}_msd"] = tr.pop("msd")
            cl = _classes(cfg, t, x, chaotic)
            arrays[f"{label}_{name}_own_msd"] = cl.pop("own_msd_curves")
            cl.pop("own_lags")
            for cname, m in cl.pop("class_msd").items():
                arrays[f"{label}_{name}_msd_{cname}"] = m
            tr["classes"] = cl
            if chaotic_long is not None:  # the same reductions for the longer MEGNO's classes
                cll = _classes(cfg, t, x, chaotic_long)
                for k in ("own_msd_curves", "own_lags", "class_msd"):
                    cll.pop(k)
                tr["classes_long"] = cll
            out[name] = tr
        rmin, rmax, chunk_t, summary = extremes_summary(ds, cfg.checkpoint_every)
        arrays[f"{label}_r_min"], arrays[f"{label}_r_max"], arrays[f"{label}_chunk_t"] = rmin, rmax, chunk_t
        out.update(summary)
        out["max_integral_drift"] = float(np.nanmax(ds["drift_drift"]))
        hist = np.asarray(ds["histogram_time"]) if "histogram_time" in ds else None
        if hist is not None:
            arrays[f"{label}_r_histogram"] = np.nansum(hist[:, -1, :], axis=0)
        out["n_crossings"] = int(np.isfinite(ds["sections_t"]).sum())
        if label == "h2":  # the chaotic sea: every orbit chaotic (chaos atlas: 100 / 100)
            sec = read_arrays(scfg.store, observable="sections")
            at = np.geomspace(min(100.0, cfg.t_end / 4), cfg.t_end, cfg.occ_times)
            occ = _occupation(cfg, p, level, sec, at, sample=sample0)
            for k in ("at", "distance", "floor", "n"):
                arrays[f"occ_{k}"] = occ[k]
            out["occupation"] = {"edges": occ["edges"], "reference": occ["reference"],
                                 "tv_final_median": float(np.median(occ["distance"][:, -1])),
                                 "tv_final_range": [float(np.min(occ["distance"][:, -1])),
                                                    float(np.max(occ["distance"][:, -1]))],
                                 "floor_final_median": float(np.median(occ["floor"][:, -1])),
                                 "islands": _islands(cfg, megno_by["islands"])}
        arrays[f"{label}_angles_t"] = t
        meta["levels"][label] = out
    return arrays, meta


#: Fewer orbits than this give no bootstrap interval in the figures: resampling 2-4 orbits
#: gives intervals that mean nothing (docs/transport.md: intervals are too narrow below ~20).
MIN_ORBITS_FOR_CI = 5


def plot(arrays, meta, outdir):
    """MSD vs lag of ``l`` and ``psi`` per level (log-log, fitted slopes dashed), the running
    |R| extremes vs time with each level's bound, the occupation distance vs time."""
    plt = C.pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(11, 8.6))
    axes = axes.ravel()
    cols = {"h2": C.REGULAR_COLORS[4], "h6": C.REGULAR_COLORS[3], "weak": C.REGULAR_COLORS[2]}
    names = {"h2": "H = 2 (Fig. 4a)", "h6": "H = 6 (Fig. 4b)", "weak": r"weak: $\Omega$ = 0.25, H = 2"}
    for ax, var, title in ((axes[0], "l", "section angle $l$"), (axes[1], "heading", r"heading $\psi$")):
        for label, lv in meta["levels"].items():
            lags, m = arrays[f"{label}_{var}_lags"], arrays[f"{label}_{var}_msd"]
            r = lv[var]
            # how many of the level's orbits are chaotic (MEGNO classes): a quick run's few
            # orbits can all be of one class where the full ensemble mixes both
            nc = len(lv["classes"]["chaotic"]) if "classes" in lv else None
            of = "" if nc is None else f"{nc} of {lv['n_orbits']} chaotic"
            ci = (f"[{r['ci'][0]:.2f}, {r['ci'][1]:.2f}]" + (f", {of}" if of else "")
                  if lv["n_orbits"] >= MIN_ORBITS_FOR_CI
                  else f"({of or str(lv['n_orbits']) + ' orbits'}: no interval)")
            ax.loglog(lags, m, color=cols.get(label, "k"), lw=1.2,
                      label=f"{names.get(label, label)}: $\\mu$ = {r['mu']:.2f} {ci}")
            lo, hi = r["lag_range"]
            sel = (lags >= lo) & (lags <= hi)
            if sel.any():
                tau = lags[sel]
                ax.loglog(tau, 2 * r["D"] * tau ** r["mu"], color="k", lw=0.8, ls="--")
        ax.set_xlabel("lag")
        ax.set_ylabel("MSD (drift removed)")
        ax.set_title(f"MSD of the lifted {title}\n(dashed: fit over the lag range)")
        ax.legend(fontsize=7)
        C.plain_log_ticks(ax)
    ax = axes[2]
    for label, lv in meta["levels"].items():
        tt = arrays[f"{label}_chunk_t"]
        for lo, hi in zip(arrays[f"{label}_r_min"], arrays[f"{label}_r_max"]):
            ax.plot(tt, hi, color=cols.get(label, "k"), lw=0.6)
            ax.plot(tt, lo, color=cols.get(label, "k"), lw=0.6, ls="--")
        ax.axhline(lv["radius_bound"], color=cols.get(label, "k"), lw=0.8, ls=":")
        ax.plot([], [], color=cols.get(label, "k"), lw=1.2, label=f"{names.get(label, label)} "
                f"({len(arrays[f'{label}_r_max'])} orbits)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    # the curves fill the panel from the smallest minimum to the largest bound: a band above
    # them (0.45 of their span in decades) takes the legend, which sat on the data before
    lo_y, hi_y = ax.get_ylim()
    ax.set_ylim(lo_y, hi_y * (hi_y / lo_y) ** 0.45)
    ax.legend(fontsize=7, loc="upper center", ncol=2)
    C.plain_log_ticks(ax)
    ax.set_xlabel("$t$")
    ax.set_ylabel("running max (solid), min (dashed) of $|R|$")
    ax.set_title("extremes of $|R|$ up to $t$ per orbit\n(dotted: rigorous bound of each level)")
    ax = axes[3]
    if "occ_at" in arrays:
        at = arrays["occ_at"]
        for d in arrays["occ_distance"]:
            ax.plot(at, d, color=cols["h2"], lw=0.6)
        ax.plot(at, np.median(arrays["occ_distance"], axis=0), color="k", lw=1.5, label="median over orbits")
        ax.plot(at, np.median(arrays["occ_floor"], axis=0), color="k", lw=1.0, ls="--",
                label="i.i.d. floor (median)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.legend(fontsize=7)
        C.plain_log_ticks(ax)
    ax.set_xlabel("$t$")
    ax.set_ylabel(r"total variation distance to $\sigma$")
    ax.set_title("occupation of the section by each H = 2 orbit's crossings\n"
                 r"vs the invariant density $\sigma$ (binned $(l, r_1, r_2)$, Monte Carlo reference)")
    lv0 = next(iter(meta["levels"].values()))
    from ..transport import FEW_ORBITS

    fig.suptitle(f"Diffusion in the lifted angles: ball I = (2, 3, 4), m = 1, a = 5, G = 10;\n"
                 f"{lv0['n_orbits']} orbits per level to t = {lv0['t_end']:g}; brackets: 95 % bootstrap "
                 f"intervals over orbits (given from {MIN_ORBITS_FOR_CI} orbits up)"
                 + (f"\nbelow {FEW_ORBITS} orbits the intervals are too narrow: with 3-15 orbits they covered "
                    "the exponent of Brownian paths 70-91 % of the time" if lv0["n_orbits"] < FEW_ORBITS else ""))
    fig.tight_layout()
    out = list(C.save_figure(fig, outdir, "diffusion", meta))
    if all("classes" in lv for lv in meta["levels"].values()):
        out += list(_plot_classes(plt, arrays, meta, outdir, names))
    return out


def _plot_classes(plt, arrays, meta, outdir, names):
    """Per level (columns) and angle (rows): the ensemble MSD about the ensemble drift
    (thick grey), about each class's own mean rate (:data:`~._common.CLASS_COLORS`: chaotic
    black, regular blue; dashed), and
    every orbit's own MSD about its own rate (thin, coloured by class)."""
    levels = list(meta["levels"])
    fig, axes = plt.subplots(2, len(levels), figsize=(5.2 * len(levels), 8.2), squeeze=False)
    colors = C.CLASS_COLORS
    for j, label in enumerate(levels):
        lv = meta["levels"][label]
        chaotic = set(lv["classes"]["chaotic"])
        for i, (var, title) in enumerate((("l", "$l$"), ("heading", r"$\psi$"))):
            ax = axes[i, j]
            lags = arrays[f"{label}_{var}_lags"]
            for k, m in enumerate(arrays[f"{label}_{var}_own_msd"]):
                ax.loglog(lags, np.where(m > 0, m, np.nan), lw=0.4, alpha=0.6,
                          color=colors["chaotic" if k in chaotic else "regular"])
            ax.loglog(lags, arrays[f"{label}_{var}_msd"], color="0.6", lw=3.0, label="all orbits, ensemble drift removed")
            cl = lv[var]["classes"]
            for cname in ("chaotic", "regular"):
                key = f"{label}_{var}_msd_{cname}"
                if key in arrays:
                    c = cl[cname]
                    ax.loglog(lags, arrays[key], color=colors[cname], lw=1.8, ls="--",
                              label=f"{cname} ({c['n']}): $\\mu$ = {c['mu']:.2f}, rate sd {c['drift_spread']:.2g}")
                elif cl[cname]["n"] == 1:
                    ax.plot([], [], color=colors[cname], lw=0.6, label=f"{cname} (1 orbit)")
            ax.plot([], [], color="gray", lw=0.6, label="each orbit about its own rate (thin)")
            lo, hi = lv[var]["lag_range"]
            ax.axvspan(lo, hi, color="0.92", zorder=0)
            ax.set_xlabel("lag")
            ax.set_ylabel("MSD")
            ax.set_title(f"{names.get(label, label)}: {title}", fontsize=10)
            ax.legend(fontsize=6.5, loc="upper left")
            C.plain_log_ticks(ax)
    lv0 = meta["levels"][levels[0]]
    fig.suptitle(f"Transport per orbit class (MEGNO <Y> > {lv0['classes']['threshold']:g} at T = "
                 f"{lv0['classes']['megno_T']:g}: chaotic) and per orbit; grey band: the fit range of $\\mu$")
    fig.tight_layout()
    return C.save_figure(fig, outdir, "diffusion_classes", meta)


if __name__ == "__main__":
    from .runner import main

    sys.exit(main(sys.modules[__name__]))
