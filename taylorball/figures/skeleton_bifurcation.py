"""A bifurcation diagram of periodic orbits in the plane's rate ``Omega``.

Two systems, chosen where a continuation over the whole interval is cheap (short return
times):

* **(a, b) the M||gamma map on the Fig. 1 level** (``a = (1, 2, 3)``, ``d = 4``, ``lambda =
  2``, ``h = 100``; the paper's Fig. 1 has ``Omega = 0.5``), ``Omega`` from 0 (the Chaplygin
  ball on a fixed plane: integrable) to 2: the saddle (``l = 0``) and the elliptic fixed point
  (``l = pi/2``), started at ``Omega = 0.5``, and the period-3 pair born from the ``Omega = 0``
  resonant torus with rotation number ``-1/3`` (Poincare-Birkhoff), started at ``Omega =
  0.005``. At ``Omega = 0`` the period-3 orbit on the torus is solved too (``tr A = 2``: a
  torus of period-3 points; the fixed points are isolated, ``tr A != 2``).
* **(c, d) Tzenoff's case on the level where the validated integrator is cheap**
  (``periodic_catalog.TZENOFF_D35_REFLECTION_SADDLE``: ``I = (2, 2, 3)``, ``m a^2 = 7/2``,
  ``C = 10, M_gamma = 6, h = -20``), the reflection saddle proved in docs/rigorous.md followed
  down from its own ``Omega = 3``.
* **(e, f) the reduced system from Omega ~ 0: the ball held in place** (Fig. 3's symmetric ball
  ``I = (2, 2, 3)``, ``m = 1``, ``a = 5``; :func:`taylorball.periodic_held.held_in_place` over
  Chaplygin's orbit ``|K| = 10``, ``(K, gamma) = 6``, ``E = 7.2`` at chart point ``(0.3, 0,
  0)``; limit level ``C = 6.0599``, ``M_gamma = 6``, ``h = 6.1776``), started at ``Omega =
  0.05`` and followed by :func:`taylorball.periodic_continuation.continue_in_omega` down to
  ``0.001`` and up to 2: ``tr A`` and ``Omega |R|``, which tends to the Chaplygin orbit's
  drift speed ``|D| / T`` as ``Omega -> 0`` (docs/skeleton.md, "Omega -> 0 in the reduced
  system").

Each family is :func:`taylorball.periodic_bifurcation.follow_family` (pseudo-arclength in both
senses, landed on the interval's ends; folds, multipliers through -1 and +1, changes of type,
branch points by the sign of the bordered Jacobian's determinant, ``1:3`` and ``1:4``
resonances). Plotted: ``tr A`` and the period per crossing (``period / k``) against
``Omega``, coloured by type, the lines ``tr = +-2`` and ``tr = -1`` (``1:3``), the events
marked.

Run: ``python studies/skeleton_bifurcation.py [--full]`` or ``taylorball reproduce --only
skeleton_bifurcation``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Dict

import numpy as np

#: Chart points (l, L/G) of the start orbits of the M||gamma map: the fixed points at the
#: Fig. 1 rate Omega = 0.5, and the period-3 pair at Omega = 0.005 (points of the Omega = 0
#: torus with rotation number -1/3 above and below the elliptic fixed point; docs/skeleton.md).
FIXED_POINT_GUESSES = (("saddle l = 0", 0.0, 0.0), ("elliptic l = pi/2", math.pi / 2, 0.0))
PERIOD3_GUESSES = (("period-3 elliptic", math.pi / 2, 0.515142), ("period-3 saddle", math.pi / 2, -0.782140))
#: Omega at which the period-3 pair is started, and the chart point of the Omega = 0 period-3
#: orbit on the resonant torus (a root of the rotation number, docs/skeleton.md).
PERIOD3_OMEGA = 0.005
TORUS3_SEED = (math.pi / 2, 0.51408210)


@dataclass(frozen=True)
class Config:
    #: Arclength step and steps per side for the M||gamma fixed points, the period-3 pair and
    #: the Tzenoff orbit.
    fixed_ds: float = 0.2
    fixed_steps: int = 60
    period3: tuple = ("period-3 elliptic",)
    period3_ds: float = 0.3
    period3_steps: int = 40
    tzenoff: bool = True
    tzenoff_ds: float = 0.5
    tzenoff_steps: int = 90
    #: Section switching for the Tzenoff orbit (``SectionSwitch()``): without it the branch
    #: stalls on ``g = 0`` at ``Omega = 2.7957``, past its fold (measured 2026-11-28).
    tzenoff_switch: bool = False
    #: The elliptic orbit proved on the h = -30 level (``TZENOFF_D35_H30_ELLIPTIC``) followed
    #: down from Omega = 3 with the Tzenoff step and section switching.
    tzenoff_h30: bool = True
    #: Switch onto the family of twice the period at the Tzenoff orbit's period doubling
    #: (:func:`taylorball.periodic_bifurcation.period_doubled_orbit`) and follow it away from
    #: the doubling, at most this many arclength steps (0: not done).
    doubled_steps: int = 0
    #: The held-in-place family of the reduced system (panels e, f): its start ``Omega`` and
    #: the values ``continue_in_omega`` reaches below and above it (it halves and doubles its
    #: step between them, so the values set the coarsest sampling).
    held_omega: float = 0.05
    held_down: tuple = (0.02, 0.01, 0.005, 0.002, 0.001)
    held_up: tuple = (0.5, 1.0, 1.5, 2.0)


QUICK = Config()
FULL = Config(fixed_ds=0.05, fixed_steps=200, period3=("period-3 elliptic", "period-3 saddle"), period3_ds=0.1,
              period3_steps=250, tzenoff_ds=0.2, tzenoff_steps=300, tzenoff_switch=True, doubled_steps=40,
              held_up=tuple(round(0.05 * i, 2) for i in range(2, 41)))

#: The Chaplygin orbit (Omega = 0) over which the held-in-place family starts: Fig. 3's ball
#: on ``|K| = 10``, ``(K, gamma) = 6``, ``E = 7.2``, chart point ``(0.3, 0, 0)``.
HELD_TORUS: Dict[str, Any] = dict(C=10.0, M_gamma=6.0, h=7.2, point=(0.3, 0.0, 0.0))


def _fig1_params(w: float):
    import dataclasses
    import warnings

    import taylorball as tb
    from taylorball.paper import fig1_params

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", tb.UnphysicalParametersWarning)
        return dataclasses.replace(fig1_params(), plane_rate=w)


def _family_arrays(key: str, fam) -> dict:
    return {f"{key}_omega": fam.omega, f"{key}_trace": fam.trace, f"{key}_period": fam.period,
            f"{key}_points": np.array([o.points[0] for o in fam.orbits]),
            f"{key}_states": np.array([np.asarray(o.state, dtype=float) for o in fam.orbits]),
            f"{key}_shift": np.array([float(o.shift) for o in fam.orbits]),
            f"{key}_g0": np.array([float(o.g0) for o in fam.orbits]), f"{key}_k": np.array([o.k for o in fam.orbits])}


def _family_meta(name: str, key: str, fam, system: str) -> dict:
    o = fam.orbits[fam.start]
    return {"name": name, "key": key, "system": system, "k": o.k, "types": fam.types, "events": fam.events,
            "stopped": fam.stopped, "cpu_s": fam.cpu_s, "n_points": len(fam.omega),
            "omega_range": [float(np.min(fam.omega)), float(np.max(fam.omega))],
            "start_omega": float(fam.omega[fam.start])}


def compute(cfg):
    import taylorball as tb
    from taylorball import periodic_catalog as cat
    from taylorball.paper import FIG1_LEVELS
    from taylorball.periodic_bifurcation import follow_family

    lev = FIG1_LEVELS.as_kwargs()
    arrays, fams, fp_orbits = {}, [], []
    p05 = _fig1_params(0.5)
    for j, (name, l0, lg) in enumerate(FIXED_POINT_GUESSES):
        st = tb.mparallel_states_on_section(p05, **lev, point=(l0, lg))[0]
        o = tb.periodic_orbit("mparallel", p05, st, 1, levels=FIG1_LEVELS)
        fp_orbits.append(o)
        fam = follow_family(o, FIG1_LEVELS, bounds=(0.0, 2.0), ds=cfg.fixed_ds, n_steps=cfg.fixed_steps)
        arrays.update(_family_arrays(f"fp{j}", fam))
        fams.append(_family_meta(name, f"fp{j}", fam, "mparallel"))
    p3 = _fig1_params(PERIOD3_OMEGA)
    for j, (name, l0, lg) in enumerate(PERIOD3_GUESSES):
        if name not in cfg.period3:
            continue
        st = tb.mparallel_states_on_section(p3, **lev, point=(l0, lg))[0]
        o = tb.periodic_orbit("mparallel", p3, st, 3, levels=FIG1_LEVELS)
        fam = follow_family(o, FIG1_LEVELS, bounds=(PERIOD3_OMEGA, 2.0), ds=cfg.period3_ds, n_steps=cfg.period3_steps,
                            sides=(1,))
        arrays.update(_family_arrays(f"p3_{j}", fam))
        fams.append({**_family_meta(name, f"p3_{j}", fam, "mparallel"), "end": _period3_end(fam, fp_orbits[1])})
    omega0 = _omega0_checks()
    if cfg.tzenoff:
        e = cat.TZENOFF_D35_REFLECTION_SADDLE
        o = cat.catalog_orbit(e)
        from taylorball.periodic_continuation import SectionSwitch

        fam = follow_family(o, e.levels, bounds=(0.0, 3.0), ds=cfg.tzenoff_ds, n_steps=cfg.tzenoff_steps, sides=(-1,),
                            switch=SectionSwitch() if cfg.tzenoff_switch else None)
        arrays.update(_family_arrays("tz", fam))
        fams.append(_family_meta("Tzenoff d = 7/2 reflection saddle", "tz", fam, "reduced"))
        tz_meta = fams[-1]
        if cfg.tzenoff_h30:
            from taylorball.periodic_continuation import SectionSwitch as _Switch

            e30 = cat.TZENOFF_D35_H30_ELLIPTIC
            f30 = follow_family(cat.catalog_orbit(e30), e30.levels, bounds=(0.0, 3.0), ds=cfg.tzenoff_ds,
                                n_steps=cfg.tzenoff_steps, sides=(-1,), switch=_Switch())
            arrays.update(_family_arrays("tz30", f30))
            fams.append(_family_meta("Tzenoff h = -30 elliptic", "tz30", f30, "reduced"))
        pds = [ev for ev in fam.events if ev["event"] == "period doubling"]
        if cfg.doubled_steps and pds:
            d = _doubled(fam, pds[0], e.levels, cfg)
            if isinstance(d, str):
                tz_meta["doubled"] = d
            else:
                arrays.update(_family_arrays("tz2", d))
                fams.append({**_family_meta("Tzenoff period 2 (from the doubling)", "tz2", d, "reduced"),
                             "from_event": pds[0]})
    held_arrays, held_meta = held_family(cfg)
    arrays.update(held_arrays)
    meta = {"families": fams, "omega0": omega0, "held": held_meta,
            "config": {k: getattr(cfg, k) for k in cfg.__dataclass_fields__},
            "levels": {"mparallel": "lambda = 2, h = 100", "tzenoff": "C = 10, M_gamma = 6, h = -20"}}
    return arrays, meta


def held_family(cfg) -> tuple:
    """The reduced system's held-in-place family (panels e, f): arrays ``held_*`` (as a
    family's, ascending in ``Omega``, plus ``held_omega_R``: ``Omega |R|`` at the section
    state) and its metadata (the limit: level, period and drift speed of the Chaplygin orbit;
    types, events, why each side ended, CPU s)."""
    from taylorball.paper import FIG3_BALL
    from taylorball.periodic_continuation import Branch, continue_in_omega
    from taylorball.periodic_held import held_in_place

    t0 = time.process_time()
    r = held_in_place(FIG3_BALL, **HELD_TORUS, omega=cfg.held_omega)
    down = continue_in_omega(r.orbit, r.levels, list(cfg.held_down))
    up = continue_in_omega(r.orbit, r.levels, list(cfg.held_up))
    orbits = down.orbits[::-1] + up.orbits[1:]
    fam = Branch(omega=np.concatenate([down.omega[::-1], up.omega[1:]]), orbits=orbits)
    arrays = _family_arrays("held", fam)
    arrays["held_omega_R"] = fam.omega * np.linalg.norm(arrays["held_states"][:, 6:9], axis=1)
    lev = r.levels
    meta = {"name": "held in place (reduced, I = (2, 2, 3))", "key": "held", "system": "reduced, held in place",
            "k": 1, "types": [o.type for o in orbits], "events": down.events + up.events,
            "stopped": {"down": down.stopped, "up": up.stopped}, "n_points": len(orbits),
            "omega_range": [float(np.min(fam.omega)), float(np.max(fam.omega))], "start_omega": cfg.held_omega,
            "levels": {"C": lev.C, "M_gamma": lev.M_gamma, "h": lev.h},
            "limit": {"torus": dict(HELD_TORUS), "period": r.period,
                      "drift_speed": r.drift_speed, "drift": r.drift.tolist()},
            "cpu_s": time.process_time() - t0}
    return arrays, meta


def _doubled(fam, event, levels, cfg):
    """The family of twice the period at the period doubling ``event`` of ``fam``: the orbit
    of ``P^2`` found next to the branch's orbits on either side of the event (the side where
    it exists is not known beforehand), followed away from the doubling. A string (why) if
    none was found."""
    from taylorball.periodic_bifurcation import follow_family, period_doubled_orbit
    from taylorball.periodic_continuation import SectionSwitch

    from ..errors import IntegrationError, StateError

    why = []
    for wv in event["between"]:
        i = int(np.argmin(np.abs(fam.omega - wv)))
        try:
            o2 = period_doubled_orbit(fam.orbits[i], levels, eps=(0.02, 0.05, 0.1))
        except (IntegrationError, StateError) as exc:
            why.append(str(exc))
            continue
        side = 1 if float(fam.omega[i]) > event["omega"] else -1
        return follow_family(o2, levels, bounds=(0.0, 3.0), ds=cfg.tzenoff_ds, n_steps=cfg.doubled_steps,
                             sides=(side,), switch=SectionSwitch() if cfg.tzenoff_switch else None)
    return "; ".join(why)


def _period3_end(fam, fixed_point) -> dict:
    """Where a period-3 branch ended: the elliptic fixed point solved at the branch's last
    ``Omega`` (natural continuation from ``Omega = 0.5``), its trace (``-1`` at the ``1:3``
    resonance) and the largest chart distance of the period-3 orbit's points from it."""
    from taylorball.paper import FIG1_LEVELS
    from taylorball.periodic_continuation import continue_in_omega

    w = float(np.max(fam.omega))
    o3 = fam.orbits[int(np.argmax(fam.omega))]
    b = continue_in_omega(fixed_point, FIG1_LEVELS, [w])
    if b.stopped != "reached":
        return {"omega": w, "fixed_point": b.stopped}
    fp = b.orbits[-1]
    d = np.abs(o3.points - fp.points[0])
    d[:, 0] = np.abs((d[:, 0] + np.pi) % (2 * np.pi) - np.pi)
    return {"omega": w, "fixed_point_trace": fp.trace, "fixed_point": fp.points[0].tolist(),
            "max_chart_distance": float(np.max(np.hypot(d[:, 0], d[:, 1]))), "period3_trace": o3.trace}


def _omega0_checks() -> dict:
    """At Omega = 0: the fixed points' traces (isolated: tr A != 2), and the period-3 orbit on
    the resonant torus (tr A = 2; |K|^2, the integrable system's extra integral, the same at
    its three section points)."""
    import taylorball as tb
    from taylorball.paper import FIG1_LEVELS

    t0 = time.process_time()
    lev = FIG1_LEVELS.as_kwargs()
    p0 = _fig1_params(0.0)
    out: dict = {"fixed_points": []}
    for name, l0, lg in FIXED_POINT_GUESSES:
        st = tb.mparallel_states_on_section(p0, **lev, point=(l0, lg))[0]
        o = tb.periodic_orbit("mparallel", p0, st, 1, levels=FIG1_LEVELS)
        out["fixed_points"].append({"name": name, "trace": o.trace, "type": o.type,
                                    "multipliers": [str(complex(m)) for m in o.multipliers]})
    st = tb.mparallel_states_on_section(p0, **lev, point=TORUS3_SEED)[0]
    o = tb.periodic_orbit("mparallel", p0, st, 3, levels=FIG1_LEVELS)
    sec = tb.poincare_section("mparallel", p0, o.state, n_points=3)
    K2 = [float(np.sum(np.asarray(s[:3], dtype=float) ** 2)) for s in [o.state] + list(sec.states)]
    out["torus3"] = {"trace_minus_2": o.trace - 2.0, "type": o.type, "period": o.period,
                     "multipliers": [str(complex(m)) for m in o.multipliers], "K2": K2[0],
                     "K2_spread": float(max(K2) - min(K2)), "points": o.points.tolist()}
    out["cpu_s"] = time.process_time() - t0
    return out


#: Marker and colour per stability type, and per event.
TYPE_STYLE = {"elliptic": "tab:green", "saddle": "tab:red", "reflection-saddle": "tab:orange",
              "parabolic": "k", "saddle-focus": "tab:purple"}
EVENT_STYLE = {"fold": ("s", "k"), "period doubling": ("v", "tab:blue"), "multiplier +1": ("^", "0.4"),
               "stability change": ("d", "0.4"), "branch point": ("*", "tab:purple"),
               "1:3 resonance": ("o", "tab:cyan"), "1:4 resonance": ("h", "tab:olive")}


def _draw(ax, bx, arrays, fam, label_types: set, label_events: set, nth: int = 0) -> None:
    key = fam["key"]
    w, tr, T = arrays[f"{key}_omega"], arrays[f"{key}_trace"], arrays[f"{key}_period"] / fam["k"]
    ax.plot(w, tr, "-", color="0.75", lw=0.7, zorder=1)
    bx.plot(w, T, "-", color="0.75", lw=0.7, zorder=1)
    for ty in sorted(set(fam["types"])):
        sel = np.array([t == ty for t in fam["types"]])
        lab = None if ty in label_types else ty
        ax.plot(w[sel], tr[sel], ".", ms=3, color=TYPE_STYLE.get(ty, "k"), label=lab, zorder=2)
        bx.plot(w[sel], T[sel], ".", ms=3, color=TYPE_STYLE.get(ty, "k"), zorder=2)
        label_types.add(ty)
    for e in fam["events"]:
        m, c = EVENT_STYLE.get(e["event"], ("x", "k"))
        y = float(np.interp(e["omega"], np.sort(w), tr[np.argsort(w)]))
        if e["event"] in ("period doubling",):
            y = -2.0
        elif e["event"] in ("fold", "multiplier +1", "branch point"):
            y = 2.0
        elif e["event"] == "1:3 resonance":
            y = -1.0
        elif e["event"] == "1:4 resonance":
            y = 0.0
        lab = None if e["event"] in label_events else e["event"]
        ax.plot(e["omega"], y, m, ms=8, mfc="none", mew=1.5, color=c, label=lab, zorder=3)
        ax.annotate(f"{e['omega']:.4f}", (e["omega"], y), fontsize=6, xytext=(3, 5), textcoords="offset points")
        label_events.add(e["event"])
    i = int(np.argmax(w))
    # families ending at one point (the period-3 pair) get their names on different lines
    ax.annotate(fam["name"], (w[i], tr[i]), fontsize=7, xytext=(-60, 8 + 10 * (nth % 2)), textcoords="offset points")


def plot(arrays, meta, outdir):
    from . import _common as C

    plt = C.pyplot()
    fig, ((ax, bx), (cx, dx), (ex, fx)) = plt.subplots(3, 2, figsize=(13, 15), layout="constrained")
    mp = [f for f in meta["families"] if f["system"] == "mparallel"]
    tz = [f for f in meta["families"] if f["system"] == "reduced"]
    for axes, fams in (((ax, bx), mp), ((cx, dx), tz)):
        types: set = set()
        evs: set = set()
        for j, f in enumerate(fams):
            _draw(axes[0], axes[1], arrays, f, types, evs, j)
        for y, ls in ((2.0, ":"), (-2.0, ":"), (-1.0, "-.")):
            axes[0].axhline(y, color="k", lw=0.6, ls=ls)
        axes[0].set_ylabel(r"tr $A$ (multiplier matrix of $P^k$ on the level)")
        axes[1].set_ylabel("period / k (flow time per crossing)")
        for a in axes:
            a.set_xlabel(r"$\Omega$")
        axes[0].legend(fontsize=7, loc="best")
    om0 = meta["omega0"]
    cfg = meta["config"]
    # the period-3 pair's traces differ from 2 by < 0.05: drawn again, magnified, in an inset
    ins = ax.inset_axes([0.07, 0.33, 0.4, 0.2])
    for f in mp:
        if f["k"] == 3:
            w3, t3 = arrays[f"{f['key']}_omega"], arrays[f"{f['key']}_trace"] - 2.0
            for ty in sorted(set(f["types"])):
                sel = np.array([t == ty for t in f["types"]])
                ins.plot(w3[sel], t3[sel], ".", ms=2, color=TYPE_STYLE.get(ty, "k"))
    ins.plot([0.0], [om0["torus3"]["trace_minus_2"]], "s", ms=5, mfc="none", color="k")
    ins.annotate(r"$\Omega = 0$: torus of period-3 points", (0.0, 0.0), fontsize=6, xytext=(4, -12),
                 textcoords="offset points")
    ins.axhline(0.0, color="k", lw=0.5, ls=":")
    ins.set_title("period 3: tr A - 2", fontsize=6)
    ins.tick_params(labelsize=6)

    def sampled(fams):
        return "\n".join(f"{f['name']}: {f['n_points']} points on [{f['omega_range'][0]:.4g}, "
                          f"{f['omega_range'][1]:.4g}]" for f in fams)

    ax.set_title("(a) M||gamma map, Fig. 1 level ($a = (1,2,3)$, $d = 4$, $\\lambda = 2$, $h = 100$): tr A;\n"
                 f"arclength ds = {cfg['fixed_ds']} (fixed points), {cfg['period3_ds']} (period 3). At $\\Omega = 0$: "
                 "fixed points isolated (tr = " + ", ".join(f"{f['trace']:.4f}" for f in om0["fixed_points"])
                 + "),\nperiod-3 orbit on a resonant torus "
                 f"(tr - 2 = {om0['torus3']['trace_minus_2']:.1e}, $|K|^2$ spread {om0['torus3']['K2_spread']:.1e})",
                 fontsize=7)
    ends = [f["end"] for f in mp if "end" in f and "max_chart_distance" in f["end"]]
    for e in ends[:1]:
        ax.annotate(f"period 3 ends on the fixed point at $\\Omega$ = {e['omega']:.4f}\n(chart distance "
                    f"{e['max_chart_distance']:.1e}, fixed point tr = {e['fixed_point_trace']:.4f})",
                    (e["omega"], 2.0), fontsize=6, xytext=(8, -40), textcoords="offset points",
                    arrowprops={"arrowstyle": "->", "lw": 0.6})
    bx.set_title("(b) period per crossing; sampled:\n" + sampled(mp), fontsize=7)
    cx.set_title("(c) Tzenoff's case, $I = (2,2,3)$, $m a^2 = 7/2$, $C = 10$, $M_\\gamma = 6$: the proved "
                 "orbits from $\\Omega = 3$ down\n(reflection saddle, $h = -20$; elliptic, $h = -30$; "
                 f"ds = {cfg['tzenoff_ds']})\n"
                 + "\n".join(f"lowest $\\Omega$ {f['omega_range'][0]:.4f}, ended: {f['stopped'].get('down', '')[:40]}"
                             for f in tz if f["key"] in ("tz", "tz30")), fontsize=7)
    dx.set_title("(d) period per crossing; sampled:\n" + sampled(tz), fontsize=7)
    _plot_held(ex, fx, arrays, meta["held"])
    fig.suptitle("Bifurcation diagram in $\\Omega$: families followed by pseudo-arclength, events marked "
                 "(folds, period doublings, branch points, 1:3 / 1:4 resonances)", fontsize=9)
    return C.save_figure(fig, outdir, "skeleton_bifurcation", meta)


def _plot_held(ex, fx, arrays, held) -> None:
    """Panels (e, f): the held-in-place family's ``tr A`` (inset: ``2 - tr A`` on log axes)
    and ``Omega |R|`` with its limit, the drift speed, at ``Omega = 0``."""
    w, tr, wr = arrays["held_omega"], arrays["held_trace"], arrays["held_omega_R"]
    lev, lim = held["levels"], held["limit"]
    for ty in sorted(set(held["types"])):
        sel = np.array([t == ty for t in held["types"]])
        ex.plot(w[sel], tr[sel], ".", ms=4, color=TYPE_STYLE.get(ty, "k"), label=ty)
        fx.plot(w[sel], wr[sel], ".", ms=4, color=TYPE_STYLE.get(ty, "k"))
    ex.plot(w, tr, "-", color="0.75", lw=0.7, zorder=0)
    fx.plot(w, wr, "-", color="0.75", lw=0.7, zorder=0)
    ex.axhline(2.0, color="k", lw=0.6, ls=":")
    ex.set_xlim(0.0, 2.05)
    ex.set_ylabel(r"tr $A$ (multiplier matrix of $P$ on the level)")
    ex.legend(fontsize=7, loc="lower left")
    ins = ex.inset_axes([0.55, 0.5, 0.4, 0.38])
    ins.loglog(w, 2.0 - tr, ".", ms=2, color="tab:green")
    ins.set_title(r"$2 - $ tr $A$ (log-log): $\propto \Omega^2$ as $\Omega \to 0$", fontsize=6)
    ins.tick_params(labelsize=6)
    fx.plot([0.0], [lim["drift_speed"]], "*", ms=10, color="k",
            label=f"$\\Omega = 0$: drift speed $|D|/T$ = {lim['drift_speed']:.6f} of Chaplygin's orbit")
    fx.set_xlim(-0.03, 2.05)
    fx.set_ylabel(r"$\Omega\,|R|$ at the section point")
    fx.legend(fontsize=7, loc="lower left")
    for a in (ex, fx):
        a.set_xlabel(r"$\Omega$")
    ends = ", ".join(f"{k}: {v}" for k, v in held["stopped"].items())
    ev = ", ".join(f"{e['event']} ({e.get('from', '')} -> {e.get('to', '')}) at {e['omega']:.4f}" for e in held["events"])
    ex.set_title("(e) reduced system, Fig. 3's ball $I = (2,2,3)$, $m a^2 = 25$: the ball held in place, on the limit "
                 f"level $C$ = {lev['C']:.6f}, $M_\\gamma$ = {lev['M_gamma']:.6f}, $h$ = {lev['h']:.6f}\n"
                 f"(over Chaplygin's orbit $|K| = 10$, $(K, \\gamma) = 6$, $E = 7.2$); continue_in_omega from "
                 f"$\\Omega$ = {held['start_omega']} ({held['n_points']} orbits on [{held['omega_range'][0]:.4g}, "
                 f"{held['omega_range'][1]:.4g}]; {ends})\nevents: {ev or 'none'} (parabolic: tr A within the "
                 "classification's tolerance of 2; no fold, period doubling, 1:3 or 1:4)", fontsize=7)
    fx.set_title(f"(f) $\\Omega |R|$ tends to the drift speed as $\\Omega \\to 0$ (the plane's velocity at the centre "
                 f"cancels the mean rolling velocity);\nlimit period $T$ = {lim['period']:.8f}; family computed in "
                 f"{held['cpu_s']:.2f} CPU s", fontsize=7)
