"""The skeleton of the Fig. 3 map: periodic orbits found by Newton on the section map.

Dynamically symmetric ball (Fig. 3: I = (2, 2, 3), m = 1, a = 5, Omega = 2, levels
G = 10, H = 6, h = 5). ``l`` is cyclic, so the periodic orbits of the map of ``(r1, r2)``
are relative periodic orbits of the 3D map (``P^k x = S_theta x``, ``S_theta`` the rotation
about the body axis 3): :func:`taylorball.periodic_orbit` solves for ``x`` and ``theta``.
(a) the map in ``(r1, r2)`` (background orbits) with the orbits found, marked by type;
(b) Newton's residual at each iterate (quadratic convergence down to the rounding floor);
(c) the first orbit continued in ``Omega`` (the plane's rate) on the same levels: trace of
its multiplier matrix and period against ``Omega`` (a bifurcation diagram: ``|tr| < 2``
elliptic, ``tr = +-2`` the lines where a multiplier passes +1 or -1; the trace is checked
against real128 finite differences of the map, and it turns fast: below ``Omega = 1.94`` the
rotation number changes by ~14 per unit of ``Omega``; the branch ends at a fold, tr -> 2,
near ``Omega = 1.868``);
(d) the M||gamma map on the Fig. 1 level: a saddle and an elliptic fixed point found by
Newton, and the saddle's unstable manifold grown from a fundamental domain
(:func:`taylorball.periodic_manifolds.unstable_manifold`) over a few background orbits.

A second figure, ``skeleton_manifolds``: the Fig. 3 section ``(r1, r2)`` with the period-4
saddle ``periodic_catalog.fig3_saddle()``, its unstable (and, in the full run, stable)
manifolds grown with refinement (:func:`taylorball.periodic_manifolds.grow_manifold`, drawn
broken where the section map jumps), and its symmetric homoclinic points on ``r2 = 0``
(:func:`taylorball.periodic_homoclinic.symmetric_homoclinic_points`).

A third figure, ``skeleton_fig4``: the Fig. 4 ball (``I = (2, 3, 4)``, ``Omega = 2``) on the
Fig. 4a and 4b levels: the periodic orbits catalogued there (found by multiple shooting from
near-recurrences of chaotic orbits, :mod:`taylorball.periodic_shooting`; solved again here
from their stored states, no search), their section points marked by type over the MEGNO map
of the slice ``l = l0`` of the sheet of the orbit's first point (``l0`` its ``l``); points
within ``FIG4_SLAB`` of ``l0`` on that sheet are filled, the others (projected from other
``l``) hollow; and, where a family is configured (``fig4_family``), a third panel with the
family in a level value (the Fig. 4a saddle in ``H``, :func:`taylorball.periodic_shooting_family.continue_shooting`;
in the full form :func:`taylorball.periodic_shooting_arclength.continue_shooting_arclength`, round its folds):
the logarithms of its multipliers' moduli against ``H``, coloured by type, the events dotted.

Guesses are chart points with the energy root (sheet) index and ``k``; a guess whose Newton
iteration fails is recorded as failed (never drawn as an orbit).

Run: ``python studies/skeleton.py [--full]``.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np

from ..paper import FIG3_BALL, FIG3_LEVELS


@dataclass(frozen=True)
class Config:
    n_orbits: int = 12
    n_points: int = 150
    seed: int = 0
    #: Guesses: (l, r1, r2, sheet index, k).
    guesses: tuple = ((0.0, -0.3, 0.0, 1, 1), (4.4927, -4.5966, 0.0, 1, 1), (0.0, -2.0, 0.0, 1, 1),
                      (0.0, -2.5, -4.8, 0, 1))
    #: Fig. 1 (M||gamma) guesses (l, L/G), background orbits and manifold iterations.
    fig1_guesses: tuple = ((0.0, 0.0), (1.5707963, 0.0))
    fig1_orbits: int = 8
    fig1_points: int = 300
    manifold_iter: int = 24
    #: Plane rates the first orbit is continued to (from the caption's Omega = 2), all before
    #: the branch's fold near Omega = 1.868 (natural continuation cannot pass a fold).
    omegas: tuple = (1.95,)
    #: The Fig. 3 saddle's manifolds (figure skeleton_manifolds): (which, branch, chart arc length).
    manifolds: tuple = (("unstable", 1, 0.8),)
    manifold_delta: float = 0.05
    n_homoclinic: int = 2
    #: Figure skeleton_fig4: catalogued orbits (names in taylorball.periodic_catalog) per level
    #: ("a", "b"), and the MEGNO maps under them (fig4_map_n x fig4_map_n cells to fig4_megno_t).
    fig4_orbits: tuple = (("a", "FIG4A_SADDLE_K10"), ("a", "FIG4A_SADDLE_K10_R"), ("a", "FIG4A_SADDLE_FOCUS_K14"),
                          ("a", "FIG4A_SADDLE_FOCUS_K14_R"), ("b", "FIG4B_REFLECTION_SADDLE_K11"))
    fig4_map_n: int = 10
    fig4_megno_t: float = 100.0
    #: A family in a level value by multiple shooting (taylorball.periodic_shooting_family):
    #: (catalogued start, parameter, target, ks, max_piece_time[, "arclength", max_steps]); ()
    #: for none. The quick form follows the Fig. 4a saddle a few natural steps in H, the full
    #: form by pseudo-arclength (taylorball.periodic_shooting_arclength) towards the Fig. 4b
    #: level H = 6: the family is closed, so it goes once round its two folds (45 steps).
    fig4_family: tuple = ("FIG4A_SADDLE_K10", "M_gamma", 2.1, (1, 1, 1, 1, 2, 1, 1, 1, 1), 1.0)


QUICK = Config()
FULL = Config(n_orbits=40, n_points=1500, omegas=(1.95, 1.9, 1.875),
              manifolds=(("unstable", 1, 3.0), ("unstable", -1, 3.0), ("stable", 1, 3.0), ("stable", -1, 3.0)),
              manifold_delta=0.02, n_homoclinic=8, fig4_map_n=40, fig4_megno_t=1000.0,
              fig4_family=("FIG4A_SADDLE_K10", "M_gamma", 6.0, (1, 1, 1, 1, 3, 1, 1, 1), 1.0, "arclength", 45))


def compute(cfg):
    import taylorball as tb
    from taylorball.periodic import periodic_orbit

    lev = FIG3_LEVELS.as_kwargs()
    t0 = time.process_time()
    region = tb.section_admissible_sample(FIG3_BALL, **lev, n=cfg.n_orbits, seed=cfg.seed)
    states = [s[0] for s in region["states"]]
    runs = tb.poincare_sections("reduced", FIG3_BALL, states, n_points=cfg.n_points, batch=True)
    pts = np.full((len(runs), cfg.n_points, 3), np.nan)
    for i, r in enumerate(runs):
        pts[i, : len(r.points)] = r.points
    t_map = time.process_time() - t0
    found, failed, hist = [], [], []
    t0 = time.process_time()
    for l0, r1, r2, sheet, k in cfg.guesses:
        sts = tb.states_on_section(FIG3_BALL, **lev, point=(l0, r1, r2), direction=1)
        if sheet >= len(sts):
            failed.append((l0, r1, r2, sheet, k, np.nan))
            continue
        try:
            o = periodic_orbit("reduced", FIG3_BALL, sts[sheet], k, levels=FIG3_LEVELS)
        except tb.errors.TaylorballError as exc:
            failed.append((l0, r1, r2, sheet, k, float(getattr(exc, "residual", np.nan))))
            continue
        found.append(o)
        hist.append(o.residual_history)
    t_newton = time.process_time() - t0
    from taylorball.periodic_continuation import continue_in_omega

    t0 = time.process_time()
    branch = continue_in_omega(found[0], FIG3_LEVELS, cfg.omegas) if found and cfg.omegas else None
    t_cont = time.process_time() - t0
    n_h = max((len(h) for h in hist), default=0)
    H = np.full((len(hist), n_h), np.nan)
    for i, h in enumerate(hist):
        H[i, : len(h)] = h
    fig1 = _fig1(cfg)
    man, man_meta = _manifolds(cfg)
    f4, f4_meta = _fig4(cfg)
    arrays = {
        **fig1,
        **man,
        **f4,
        "points": pts,
        "orbit_points": np.array([o.points[0] for o in found]).reshape(-1, 3),
        "orbit_states": np.array([np.asarray(o.state, dtype=float) for o in found]).reshape(-1, 9),
        "orbit_period": np.array([o.period for o in found]),
        "orbit_shift": np.array([o.shift for o in found]),
        "orbit_trace": np.array([o.trace for o in found]),
        "orbit_residual": np.array([o.residual for o in found]),
        "residual_history": H,
        "failed": np.array(failed, dtype=float).reshape(-1, 6),
        "branch_omega": branch.omega if branch else np.zeros(0),
        "branch_trace": branch.trace if branch else np.zeros(0),
        "branch_period": branch.period if branch else np.zeros(0),
    }
    meta = {"types": [o.type for o in found], "stability": [o.stability for o in found],
            "multipliers": [[str(complex(m)) for m in o.multipliers] for o in found],
            "cpu_s_map": t_map, "cpu_s_newton": t_newton, "cpu_s_continuation": t_cont,
            "branch_stopped": branch.stopped if branch else "no orbit", "branch_events": branch.events if branch else [],
            "branch_types": [o.type for o in branch.orbits] if branch else [], "n_found": len(found), "n_failed": len(failed),
            "levels": FIG3_LEVELS.caption, **man_meta, "fig4": f4_meta}
    return arrays, meta


#: Half-width in ``l`` of the slab around the MEGNO map's slice in which an orbit's points are
#: drawn filled (plot choice).
FIG4_SLAB = 0.3


def _fig4(cfg):
    """The Fig. 4 ball's catalogued periodic orbits at Omega = 2 (multiple shooting from their
    stored states) and a MEGNO map of each level's slice through an orbit's first point."""
    from taylorball import periodic_catalog as cat
    from taylorball._chart_sheets import section_sheet
    from taylorball.maps import _megno_map_fields
    from taylorball.paper import FIG4_BALL, FIG4A_LEVELS, FIG4B_LEVELS
    from taylorball.periodic_shooting import periodic_orbit_shooting

    from . import _common as C

    t0 = time.process_time()
    arrays, meta = {}, {"levels": {}, "orbits": []}
    for tag, lev in (("a", FIG4A_LEVELS), ("b", FIG4B_LEVELS)):
        orbits = []
        for t_, name in cfg.fig4_orbits:
            if t_ != tag:
                continue
            e = getattr(cat, name)
            o = periodic_orbit_shooting(e.kind, e.ball, np.array(e.state), e.k, e.k, levels=e.levels, g0=e.g0,
                                        direction=e.direction)
            orbits.append((name, o))
        roots = [section_sheet(FIG4_BALL, np.asarray(o.state, dtype=float)[None, :], **lev.as_kwargs())[0]
                 for _, o in orbits]
        l0 = float(orbits[0][1].points[0, 0]) if orbits else 0.5 * np.pi
        root = int(roots[0]) if orbits else 0
        box = 10.5
        mp = _megno_map_fields(FIG4_BALL, lev, l=l0, r1=(-box, box, cfg.fig4_map_n), r2=(-box, box, cfg.fig4_map_n),
                               t_end=cfg.fig4_megno_t, root=root, stop_above=C.MEGNO_STOP, compact_mode=True,
                               jacobian=C.QUICK_MEGNO_JACOBIAN if cfg.fig4_map_n <= 16 else C.FULL_MEGNO_JACOBIAN,
                               norm="full")
        arrays.update({f"fig4{tag}_map_values": mp["values"], f"fig4{tag}_map_r1": mp["r1"],
                       f"fig4{tag}_map_r2": mp["r2"]})
        for j, (name, o) in enumerate(orbits):
            sheets = section_sheet(FIG4_BALL, _orbit_states(o), **lev.as_kwargs())
            arrays[f"fig4{tag}_orbit{j}_points"] = o.points
            arrays[f"fig4{tag}_orbit{j}_sheets"] = np.asarray(sheets)
            meta["orbits"].append({"level": tag, "index": j, "name": name, "k": o.k, "period": o.period,
                                   "type": o.type, "stability": o.stability, "trace": o.trace,
                                   "multipliers": [str(complex(m)) for m in o.multipliers],
                                   "residual": o.residual, "symmetric": o.symmetric})
        meta["levels"][tag] = {"caption": ", ".join(f"{k} = {v:g}" for k, v in lev.caption.items()), "l0": l0, "root": root, "n_orbits": len(orbits),
                               "megno_t": cfg.fig4_megno_t}
    if cfg.fig4_family:
        arr, meta["family"] = _fig4_family(cfg.fig4_family)
        arrays.update(arr)
    meta["cpu_s"] = time.process_time() - t0
    return arrays, meta


def _fig4_family(spec):
    """A catalogued orbit followed in a level value by multiple shooting: the values, the
    logarithms of the multipliers' moduli and the types along the branch."""
    from taylorball import periodic_catalog as cat
    from taylorball.periodic_shooting import periodic_orbit_shooting
    from taylorball.periodic_shooting_family import continue_shooting

    name, parameter, target, ks, mpt = spec[:5]
    method = spec[5] if len(spec) > 5 else "natural"
    max_steps = int(spec[6]) if len(spec) > 6 else 600
    e = getattr(cat, name)
    o = periodic_orbit_shooting(e.kind, e.ball, np.array(e.state), e.k, e.k, levels=e.levels, g0=e.g0,
                                direction=e.direction)
    if method == "arclength":
        from taylorball.periodic_shooting_arclength import continue_shooting_arclength

        br = continue_shooting_arclength(o, e.levels, parameter, target, ks=ks, max_piece_time=mpt, ds=0.2,
                                         ds_max=2.0, max_steps=max_steps)
    else:
        br = continue_shooting(o, e.levels, parameter, target, ks=ks, max_piece_time=mpt, h0=0.01, h_max=0.1)
    logmu = np.array([np.sort(np.log(np.abs(np.asarray(x.multipliers)))) for x in br.orbits])
    arrays = {"fig4_family_values": np.asarray(br.values, dtype=float), "fig4_family_logmu": logmu}
    meta = {"name": name, "parameter": parameter, "target": float(target), "ks": list(ks), "max_piece_time": mpt,
            "method": method,
            "types": [x.type for x in br.orbits], "k": [int(x.k) for x in br.orbits],
            "period": [float(x.period) for x in br.orbits], "stopped": br.stopped,
            "events": [{k_: (list(v) if isinstance(v, tuple) else [v.real, v.imag] if isinstance(v, complex) else v)
                        for k_, v in ev.items()} for ev in br.events]}
    return arrays, meta


def _orbit_states(o) -> np.ndarray:
    """The k public states of an orbit's section points, by the section integrator."""
    import taylorball as tb

    if o.k == 1:
        return np.asarray(o.state, dtype=float)[None, :]
    sec = tb.poincare_section(o.kind, o.problem.params, o.state, n_points=o.k - 1, g0=o.g0)
    return np.vstack([np.asarray(o.state, dtype=float)[None, :], np.asarray(sec.states, dtype=float)])


def _broken(curve: np.ndarray, jumps: np.ndarray) -> np.ndarray:
    """A polyline with a NaN row after every jump (drawn broken there)."""
    rows = []
    for p_, j in zip(curve, jumps):
        rows.append(p_)
        if j:
            rows.append([np.nan, np.nan])
    return np.array(rows).reshape(-1, 2)


def _manifolds(cfg):
    """The Fig. 3 saddle (period 4), its manifolds grown to the configured lengths and the
    symmetric homoclinic points on the unstable ones (r2 = 0, the reversor's fixed line)."""
    from taylorball.periodic_catalog import fig3_saddle
    from taylorball.periodic_homoclinic import symmetric_homoclinic_points
    from taylorball.periodic_manifolds import grow_manifold

    t0 = time.process_time()
    o = fig3_saddle()
    arrays = {"saddle_points": o.points[:, 1:].copy()}
    keys, info, hps = [], [], []
    for which, branch, length in cfg.manifolds:
        m = grow_manifold(o, which, length=length, branch=branch, delta=cfg.manifold_delta)
        key = f"manifold_{which}_{'p' if branch > 0 else 'm'}"
        curves = [_broken(m.curves[i], m.xjumps if i == 0 else m.jumps) for i in range(o.k)]
        n = max(len(c) for c in curves)
        arr = np.full((o.k, n, 2), np.nan)
        for i, c in enumerate(curves):
            arr[i, :len(c)] = c
        arrays[key] = arr
        keys.append(key)
        info.append({"key": key, "which": which, "branch": branch, "length": length, "arc_length": m.arc_length,
                     "points": len(m.sigma), "levels": int(m.level.max()) + 1, "jumps": int(m.xjumps.sum()),
                     "stopped": m.stopped, "map_calls": m.map_calls, "mu": m.mu})
        if which == "unstable" and len(hps) < cfg.n_homoclinic:
            hps += symmetric_homoclinic_points(o, m, max_points=cfg.n_homoclinic - len(hps))
    arrays["homoclinic_points"] = np.array([h.point for h in hps]).reshape(-1, 2)
    arrays["homoclinic_angle_deg"] = np.array([np.degrees(h.angle) for h in hps])
    arrays["homoclinic_tangent_u"] = np.array([h.tangent_u for h in hps]).reshape(-1, 2)
    meta = {"manifolds": info, "manifold_keys": keys, "cpu_s_manifolds": time.process_time() - t0,
            "saddle": {"period": o.period, "multipliers": [float(abs(v)) for v in o.multipliers], "k": o.k},
            "homoclinic": [{"point": [float(v) for v in h.point], "angle_deg": float(np.degrees(h.angle)),
                            "level": h.level, "crossing": h.crossing, "sigma": str(h.sigma),
                            "symmetry_defect": h.symmetry_defect} for h in hps]}
    return arrays, meta


def _fig1(cfg):
    import warnings

    import taylorball as tb
    from taylorball.charts import mparallel_states_on_section
    from taylorball.paper import FIG1_LEVELS, fig1_params
    from taylorball.periodic_manifolds import unstable_manifold

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", tb.UnphysicalParametersWarning)
        p = fig1_params()
    lev = FIG1_LEVELS.as_kwargs()
    orbits = []
    for l0, lg in cfg.fig1_guesses:
        try:
            st = mparallel_states_on_section(p, **lev, point=(l0, lg))[0]
            orbits.append(tb.periodic_orbit("mparallel", p, st, 1, levels=FIG1_LEVELS))
        except tb.errors.TaylorballError:
            continue
    rng = np.random.default_rng(cfg.seed)
    starts = []
    while len(starts) < cfg.fig1_orbits:
        try:
            starts.append(mparallel_states_on_section(p, **lev, point=(rng.uniform(0, 2 * np.pi),
                                                                       rng.uniform(-0.9, 0.9)))[0])
        except tb.errors.TaylorballError:
            continue
    runs = tb.poincare_sections("mparallel", p, starts, n_points=cfg.fig1_points, t_end=100.0 * cfg.fig1_points)
    bg = np.full((len(runs), cfg.fig1_points, 2), np.nan)
    for i, r in enumerate(runs):
        bg[i, : len(r.points)] = r.points
    saddles = [o for o in orbits if o.stability == "hyperbolic"]
    man = unstable_manifold(saddles[0], n_iter=cfg.manifold_iter, s0=1e-7)["points"] if saddles else np.zeros((0, 2))
    return {"fig1_background": bg, "fig1_manifold": man.reshape(-1, 2),
            "fig1_orbit_points": np.array([o.points[0] for o in orbits]).reshape(-1, 2),
            "fig1_orbit_hyperbolic": np.array([o.stability == "hyperbolic" for o in orbits]),
            "fig1_orbit_mu": np.array([float(np.max(np.abs(o.multipliers))) for o in orbits])}


def plot(arrays, meta, outdir):
    from . import _common as C

    plt = C.pyplot()
    fig, ((ax, bx), (cx, dx)) = plt.subplots(2, 2, figsize=(12, 10), layout="constrained")
    pts = arrays["points"]
    for i in range(pts.shape[0]):
        ax.plot(pts[i, :, 1], pts[i, :, 2], ".", ms=0.8, color="0.6")
    style = {"elliptic": ("o", "tab:green"), "hyperbolic": ("x", "tab:red"), "parabolic": ("s", "tab:orange")}
    seen = set()
    for j, (p, st, tr, T) in enumerate(zip(arrays["orbit_points"], meta["stability"], arrays["orbit_trace"],
                                           arrays["orbit_period"])):
        m, c = style[st]
        ax.plot(p[1], p[2], m, color=c, ms=8, mfc="none", mew=1.6, label=None if st in seen else st)
        # labels alternately above and below their points: neighbouring orbits' labels overlapped
        ax.annotate(f"T={T:.2f}, tr={tr:.2f}", (p[1], p[2]), fontsize=7, xytext=(4, 6 if j % 2 == 0 else -12),
                    textcoords="offset points")
        seen.add(st)
    for f in arrays["failed"]:
        ax.plot(f[1], f[2], "+", color="k", ms=6)
    ax.set_xlabel("$r_1$")
    ax.set_ylabel("$r_2$")
    ax.set_aspect("equal", adjustable="box")
    ax.legend(loc="lower right", fontsize=7)
    ax.set_title(f"(a) Fig. 3 level: {meta['n_found']} relative fixed points (k = 1), "
                 f"{meta['n_failed']} guesses failed (+)", fontsize=8)
    H = arrays["residual_history"]
    for i in range(H.shape[0]):
        bx.semilogy(np.arange(H.shape[1]), H[i], "o-", ms=3, label=meta["types"][i])
    bx.set_xlabel("Newton iterate")
    bx.set_ylabel(r"$\max|\phi_T(x) - S_\theta x|$ and level/section residuals")
    bx.set_title("(b) Newton convergence (float64)", fontsize=8)
    bx.legend(fontsize=7)
    w, tr, T = arrays["branch_omega"], arrays["branch_trace"], arrays["branch_period"]
    if len(w):
        cx.plot(w, tr, "-", color="0.5", lw=0.8)
        for wi, ti, ty in zip(w, tr, meta["branch_types"]):
            m, c = style.get("elliptic" if ty == "elliptic" else "hyperbolic" if "saddle" in ty else "parabolic")
            cx.plot(wi, ti, m, color=c, ms=5, mfc="none")
        for y in (-2.0, 2.0):
            cx.axhline(y, color="k", lw=0.6, ls=":")
        tx = cx.twinx()
        tx.plot(w, T, "--", color="tab:blue", lw=0.8)
        tx.set_ylabel("period (flow time)", color="tab:blue")
    cx.set_xlabel(r"$\Omega$")
    cx.set_ylabel(r"tr $A$ (multiplier matrix)")
    cx.set_title(f"(c) first orbit continued in $\\Omega$ ({len(w)} solutions; "
                 f"{'every value reached' if meta['branch_stopped'] == 'reached' else 'stopped early'})\n"
                 "tr A checked by real128 finite differences; it turns fast (docs/skeleton.md)", fontsize=8)
    def wrap(l_):
        return (l_ + np.pi) % (2 * np.pi) - np.pi

    bg = arrays["fig1_background"]
    for i in range(bg.shape[0]):
        dx.plot(wrap(bg[i, :, 0]), bg[i, :, 1], ".", ms=0.8, color="0.6")
    man = arrays["fig1_manifold"]
    dx.plot(wrap(man[:, 0]), man[:, 1], ".", ms=1.2, color="tab:red", label="unstable manifold")
    for p_, hyp, mu in zip(arrays["fig1_orbit_points"], arrays["fig1_orbit_hyperbolic"], arrays["fig1_orbit_mu"]):
        m, c = style["hyperbolic" if hyp else "elliptic"]
        dx.plot(wrap(p_[0]), p_[1], m, color=c, ms=9, mfc="none", mew=1.8)
        dx.annotate(f"|mu| = {mu:.4g}", (wrap(p_[0]), p_[1]), fontsize=7, xytext=(4, -10), textcoords="offset points")
    dx.set_xlabel("$l$")
    dx.set_ylabel("$L/G$")
    dx.legend(loc="lower right", fontsize=7)
    dx.set_title("(d) M||gamma map, Fig. 1 level ($\\lambda = 2$, $h = 100$): fixed points and the "
                 "saddle's unstable manifold", fontsize=8)
    fig.suptitle("Skeleton of the Fig. 3 map (dynamically symmetric ball, $G = 10$, $H = 6$, $h = 5$, "
                 r"$\Omega = 2$)", fontsize=9)
    return C.save_figure(fig, outdir, "skeleton", meta) + _plot_manifolds(arrays, meta, outdir) + \
        _plot_fig4(arrays, meta, outdir)


def _plot_fig4(arrays, meta, outdir):
    """Figure skeleton_fig4: the Fig. 4a and 4b levels at Omega = 2, the catalogued periodic
    orbits' points marked by type over the MEGNO map of the slice through an orbit's point."""
    from . import _common as C
    from .megno_map import plot_megno_map

    if "fig4" not in meta:
        return []
    plt = C.pyplot()
    fam = meta["fig4"].get("family")
    fig, axes = plt.subplots(1, 3 if fam else 2, figsize=(19 if fam else 13, 6.2), layout="constrained")
    marker = {"saddle": ("X", "tab:red"), "reflection-saddle": ("P", "tab:orange"), "saddle-focus": ("D", "tab:purple"),
              "elliptic": ("o", "tab:green"), "parabolic": ("s", "tab:olive")}
    f4 = meta["fig4"]
    for ax, tag in zip(axes, "ab"):
        lv = f4["levels"][tag]
        plot_megno_map(ax, arrays[f"fig4{tag}_map_values"], arrays[f"fig4{tag}_map_r1"], arrays[f"fig4{tag}_map_r2"],
                       vmax=C.MEGNO_STOP)
        seen = set()
        for o in f4["orbits"]:
            if o["level"] != tag:
                continue
            pts = arrays[f"fig4{tag}_orbit{o['index']}_points"]
            sh = arrays[f"fig4{tag}_orbit{o['index']}_sheets"]
            dl = (pts[:, 0] - lv["l0"] + np.pi) % (2 * np.pi) - np.pi
            inside = (np.abs(dl) <= FIG4_SLAB) & (sh == lv["root"])
            m, c = marker.get(o["type"], ("*", "k"))
            lab = f"{o['type']}, k = {o['k']}, T = {o['period']:.4f}"
            ax.plot(pts[inside, 1], pts[inside, 2], m, color=c, ms=10, mec="w", mew=0.8,
                    label=lab if o["type"] not in seen else None)
            ax.plot(pts[~inside, 1], pts[~inside, 2], m, color=c, ms=8, mfc="none", mew=1.4,
                    label=None if o["type"] in seen or inside.all() else "(other l or sheet)")
            seen.add(o["type"])
        n = lv["n_orbits"]
        ax.set_title(f"Fig. 4{tag} level ({lv['caption']}), $\\Omega = 2$: "
                     f"{n if n else 'no'} periodic orbit{'' if n == 1 else 's'} found\n"
                     f"MEGNO map of the slice $l = {lv['l0']:.3f}$, root {lv['root']} ($t$ = {lv['megno_t']:g}); "
                     f"filled: points within {FIG4_SLAB} of it", fontsize=8)
        if seen:
            ax.legend(loc="lower left", fontsize=7)
    if fam:
        _plot_family(axes[2], arrays, fam, marker)
    fig.suptitle("The Fig. 4 ball ($I = (2, 3, 4)$, $\\Omega = 2$): periodic orbits by multiple shooting",
                 fontsize=9)
    return C.save_figure(fig, outdir, "skeleton_fig4", meta)


def _plot_family(ax, arrays, fam, marker):
    """The family's ``ln |mu|`` against the level value, each stretch coloured by its type."""
    w = arrays["fig4_family_values"]
    y = arrays["fig4_family_logmu"]
    types = fam["types"]
    seen = set()
    for i in range(len(w)):
        c = marker.get(types[i], ("*", "k"))[1]
        j = min(i + 1, len(w) - 1)
        for col in range(y.shape[1]):
            ax.plot(w[i:j + 1], y[i:j + 1, col], "-", color=c, lw=1.6,
                    label=types[i] if col == 0 and types[i] not in seen else None)
            seen.add(types[i])
    ax.axhline(0.0, color="0.6", lw=0.6)
    for ev in fam["events"]:
        ax.axvline(ev["omega"], color="0.4", lw=0.6, ls=":")
    par = {"M_gamma": "H", "C": "G", "h": "h"}.get(fam["parameter"], fam["parameter"])
    ks = sorted(set(fam["k"]))
    ax.set_xlabel(f"${par}$ (the level's {fam['parameter']}; $G = 10$, $h = 5$ kept)")
    ax.set_ylabel(r"$\ln |\mu|$ of the multipliers")
    if fam["stopped"] == "reached":
        end = f"to ${par}$ = {w[-1]:.4g}: reached"
    elif fam["stopped"].startswith("max_steps"):  # a closed family, followed once round
        end = f"{len(w)} orbits, the step limit (${par}$ = {w[-1]:.4g} at the end)"
    else:
        end = f"to ${par}$ = {w[-1]:.4g}: stopped (target {fam['target']:g})"
    ax.set_title(f"the family of {fam['name']} in ${par}$ (multiple shooting, k = "
                 f"{', '.join(str(k) for k in ks)} on $g = 0$)\n${par}$ from {w.min():.4g} to {w.max():.4g}; "
                 f"{end}", fontsize=8)
    ax.legend(loc="upper right", fontsize=7)


def _plot_manifolds(arrays, meta, outdir):
    """Figure skeleton_manifolds: the Fig. 3 section (r1, r2) with the period-4 saddle, its
    manifolds and the symmetric homoclinic points; (b) a zoom on the points."""
    from . import _common as C

    if "saddle_points" not in arrays:
        return []
    plt = C.pyplot()
    fig, (ax, bx, zx) = plt.subplots(1, 3, figsize=(17, 6.2), layout="constrained")
    pts = arrays["points"]
    colors = {"unstable": ("tab:red", "#f4a582"), "stable": ("tab:blue", "#92c5de")}
    hp = arrays["homoclinic_points"]
    for a in (ax, bx, zx):
        for i in range(pts.shape[0]):
            a.plot(pts[i, :, 1], pts[i, :, 2], ".", ms=0.8, color="0.75", zorder=0)
        seen = set()
        for info in meta["manifolds"]:
            arr = arrays[info["key"]]
            c = colors[info["which"]][0 if info["branch"] > 0 else 1]
            for i in range(arr.shape[0]):
                lab = None if (info["which"], info["branch"]) in seen else \
                    f"$W^{{{info['which'][0]}}}$, branch {info['branch']:+d} (arc {info['arc_length']:.2g}, {info['jumps']} jumps)"
                seen.add((info["which"], info["branch"]))
                a.plot(arr[i, :, 0], arr[i, :, 1], "-", lw=1.6 if a is ax else 1.0, color=c, label=lab)
        sp = arrays["saddle_points"]
        a.plot(sp[:, 0], sp[:, 1], "x", color="k", ms=9, mew=2, label="period-4 saddle", zorder=5)
        if len(hp):
            a.plot(hp[:, 0], hp[:, 1], "o", mfc="none", mec="k", ms=10, mew=1.5, label="symmetric homoclinic point",
                   zorder=6)
        a.axhline(0.0, color="k", lw=0.5, ls=":", zorder=1)
        a.set_xlabel("$r_1$")
        a.set_ylabel("$r_2$")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="lower left", fontsize=7)
    mu = meta["saddle"]["multipliers"]
    ax.set_title(f"(a) Fig. 3 section: the period-4 saddle (multipliers {mu[0]:.4f}, {mu[1]:.4f}, period "
                 f"{meta['saddle']['period']:.4f})\nand its manifolds; dotted: $r_2 = 0$, the reversor's fixed line",
                 fontsize=8)
    sp = arrays["saddle_points"]

    def box(a, pts_, pad):
        a.set_xlim(float(np.min(pts_[:, 0])) - pad, float(np.max(pts_[:, 0])) + pad)
        a.set_ylim(float(np.min(pts_[:, 1])) - pad, float(np.max(pts_[:, 1])) + pad)

    mid = float(np.median(sp[:, 0]))
    for a, side, pad in ((bx, sp[:, 0] >= mid, 0.15), (zx, sp[:, 0] < mid, 0.25)):
        group = sp[side]
        near = np.array([p_ for p_ in hp if abs(p_[0] - float(np.mean(group[:, 0]))) < 1.0]).reshape(-1, 2)
        box(a, np.vstack([group, near]), pad)
        n = 0
        for p_, ang in zip(hp, arrays["homoclinic_angle_deg"]):
            if abs(p_[0] - float(np.mean(group[:, 0]))) < 1.0:
                a.annotate(f"$r_1$ = {p_[0]:.8f}: {ang:.4f} deg", (p_[0], p_[1]), fontsize=7,
                           xytext=(12, 40 - 14 * n), textcoords="offset points",
                           arrowprops={"arrowstyle": "-", "lw": 0.5, "color": "0.4"})
                n += 1
    zx.set_title("(c) zoom on the saddle's points at $r_1 = -7.076$", fontsize=8)
    bx.set_title("(b) zoom on the points at $r_1 = -0.177$: $W^u$ crosses $r_2 = 0$ where it meets $W^s$\n"
                 "(its mirror image under the reversor) at a small angle", fontsize=8)
    return C.save_figure(fig, outdir, "skeleton_manifolds", meta)


if __name__ == "__main__":
    from .runner import main

    sys.exit(main(sys.modules[__name__]))
