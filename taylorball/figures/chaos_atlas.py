r"""The chaos atlas: where the plane's rotation breaks integrability.

For the Fig. 4 ball (I = (2, 3, 4), m = 1, a = 5) and the levels G = |M| = 10 with
H = (M, gamma) = 2 (Fig. 4a) and 6 (Fig. 4b), the fraction of the section's admissible
region whose orbits are chaotic (MEGNO <Y> > 4 at T, norm="compact", on a fixed random
sample of the level; Wilson 95 % binomial interval) as a function of the plane's rotation
rate Omega, from 0 (Chaplygin's integrable ball) upward: :func:`taylorball.chaotic_fraction`.

Levels. The energy depends on Omega (E = T(M + m a Omega R, gamma) - m Omega^2 |R|^2 / 2), and
the captions' h = 5 is not admissible at Omega = 0 (there E ranges over [2.155, 2.778] for
H = 2 and [5.603, 10.185] for H = 6). At R = 0 the energy is T(M, gamma) for every Omega, so
the levels are fixed by G, H and ``h = E_lo + h_frac (E_hi - E_lo)``, with ``[E_lo, E_hi]``
the range of T(M, gamma) on |M| = G, (M, gamma) = H (grid extrema over (l, g, K) on a 96^3
grid, :func:`rest_energy_range`): the same (G, H, h) level at every Omega, non-empty (it
contains the R = 0 states), at Omega = 0 the integrable ball's level. The region's extent in
R grows like 1/Omega as Omega -> 0 (unbounded at 0, where the sampler's box stops growing at
its cap, r_box = 4096). The Fig. 4a level itself (Omega = 2, h = 5) is run too as an anchor.

Fraction against T. Each orbit's ``<Y>`` is also read at the fractions ``megno_times`` of T
(the same runs, :func:`taylorball.megno_many` with ``sample=``; a run stopped once ``<Y>``
passed 10 counts as chaotic from then on), so the figure shows whether the fraction at a
rate has converged in T. At small Omega it has not: chaos there is slow (``<Y>`` passes 4
only after thousands of time units), and the fraction at a fixed T undercounts it.

Power law. Near Omega = 0, ``f = min(1, A Omega^p)`` is fitted by binomial maximum likelihood
to the counts with 0 < Omega <= ``fit_max_omega`` (zero counts included: they bound A Omega^p
from above), with a 95 % profile-likelihood interval for p (``2 (l_max - l(p)) <= 3.84``);
an interval reaching the search range's edge is reported as unbounded on that side. The fit
is drawn only where it fits (goodness-of-fit p-value ``gof_p >= FIT_MIN_GOF``); otherwise the
figure says it was rejected, with its deviance.

Run: ``python studies/chaos_atlas.py [--full]``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from ..paper import FIG4_BALL, FIG4A_LEVELS
from . import _common as C


@dataclass(frozen=True)
class Config:
    inertia: tuple = FIG4_BALL.inertia
    mass: float = FIG4_BALL.mass
    radius: float = FIG4_BALL.radius
    G: float = FIG4A_LEVELS.C
    H: tuple = (2.0, 6.0)
    h_frac: float = 0.5
    omegas: tuple = (0.0, 0.5, 2.0)
    n_orbits: int = 12
    megno_t: float = 300.0
    seed: int = 0
    fit_max_omega: float = 0.5
    megno_times: tuple = (0.25, 0.5, 1.0)  # fractions of megno_t at which the fraction is also read
    threads: Optional[int] = None
    megno_compact: Optional[bool] = None
    megno_jacobian: str = C.QUICK_MEGNO_JACOBIAN


QUICK = Config(H=(2.0,))
FULL = Config(omegas=(0.0, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 1.0, 2.0), n_orbits=100, megno_t=1000.0,
              threads=2, megno_compact=False, megno_jacobian=C.FULL_MEGNO_JACOBIAN)

#: A power-law fit is drawn only when its goodness-of-fit p-value is at least this.
FIT_MIN_GOF = 0.05

#: Exponents searched by the profile likelihood.
P_RANGE = (0.05, 30.0)


def ball(cfg, omega: float):
    from ..params import BallParams

    return BallParams(inertia=cfg.inertia, mass=cfg.mass, radius=cfg.radius, plane_rate=float(omega))


def rest_energy_range(params, G: float, H: float, n: int = 96) -> Tuple[float, float]:
    """Min and max of the energy at R = 0 (``T(M, gamma)``, independent of Omega) on
    ``|M| = G``, ``(M, gamma) = H``: extrema over an ``n^3`` grid of the chart angles
    ``(l, g)`` and ``K = G cos(theta)`` (within ~1e-4 relative of the true extrema at n = 96:
    the energy is smooth and the grid step 2 pi / 96)."""
    from ..charts import _reduced_energy_theta

    ang = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    l, g, th = np.meshgrid(ang, ang, np.linspace(0.0, np.pi, n), indexing="ij")
    E, _ = _reduced_energy_theta(params, G, H, l.ravel(), 0.0, 0.0, g.ravel(), th.ravel(), with_gdot=False)
    return float(np.nanmin(E)), float(np.nanmax(E))


def level_h(cfg, H: float) -> float:
    lo, hi = rest_energy_range(ball(cfg, 0.0), cfg.G, H)
    return lo + cfg.h_frac * (hi - lo)


def power_law_fit(omega, k, n, *, level: float = 0.95, n_grid: int = 1501) -> dict:
    """Binomial maximum-likelihood fit of ``f = min(1, A omega^p)`` to ``k`` chaotic of ``n``
    orbits at each ``omega > 0``, with the profile-likelihood interval of ``p`` at ``level``.

    Returns a dict: ``p``, ``p_ci`` (``None`` on a side where the interval reaches
    :data:`P_RANGE`), ``A``, ``omega_range``, ``n_points``, ``loglik``, and the goodness of
    fit: ``deviance`` against the saturated binomial model, ``dof`` (points - 2) and
    ``gof_p = P(chi^2_dof > deviance)`` (small: the counts are not a power law). ``p`` is ``None``
    when no orbit in the range is chaotic or the range holds fewer than two rates (no power
    law can be fitted)."""
    from statistics import NormalDist

    omega, k, n = (np.asarray(v, dtype=float) for v in (omega, k, n))
    out = {"omega_range": [float(omega.min()), float(omega.max())], "n_points": int(omega.size)}
    if not np.any(k > 0) or np.unique(omega).size < 2:
        return {**out, "p": None, "p_ci": None, "A": None, "loglik": None, "deviance": None, "dof": None,
                "gof_p": None}
    ps = np.linspace(*P_RANGE, n_grid)
    # f = B (omega / pivot)^p with the pivot the rates' geometric mean, so that ln B (f at the
    # pivot, up to the cap at 1) lies in a fixed window whatever p: a 2D grid, refined in ln B
    x = np.log(omega) - np.log(omega).mean()

    def loglik(c, pp):  # c: (P, C) values of ln B for each of the P exponents pp
        f = np.clip(np.exp(c[:, :, None] + pp[:, None, None] * x), 1e-300, 1.0 - 1e-12)
        return (k * np.log(f) + (n - k) * np.log1p(-f)).sum(axis=2)

    coarse = np.linspace(-15.0, 15.0, 601)
    step = coarse[1] - coarse[0]
    prof, best_c = np.empty(ps.size), np.empty(ps.size)
    for s in range(0, ps.size, 100):
        pp = ps[s : s + 100]
        c0 = coarse[np.argmax(loglik(np.broadcast_to(coarse, (pp.size, coarse.size)), pp), axis=1)]
        fine = c0[:, None] + np.linspace(-step, step, 101)[None, :]  # the maximum is within a step
        ll = loglik(fine, pp)
        j = np.argmax(ll, axis=1)
        prof[s : s + 100] = ll[np.arange(pp.size), j]
        best_c[s : s + 100] = fine[np.arange(pp.size), j] - pp * np.log(omega).mean()  # ln A
    i = int(np.argmax(prof))
    crit = NormalDist().inv_cdf((1 + level) / 2) ** 2 / 2  # chi2_1 quantile / 2 (1.92 at 95 %)
    inside = np.flatnonzero(prof >= prof[i] - crit)
    lo = None if inside[0] == 0 else float(ps[inside[0]])
    hi = None if inside[-1] == ps.size - 1 else float(ps[inside[-1]])
    # goodness of fit: the deviance against the saturated model (f_i = k_i / n_i), chi^2 with
    # (points - 2) degrees of freedom; a small gof_p means the data are not a power law
    f = np.minimum(1.0, np.exp(best_c[i]) * omega ** ps[i])
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = np.where(k > 0, k * np.log(k / (n * f)), 0.0)
        t2 = np.where(n > k, (n - k) * np.log((n - k) / (n * (1.0 - f))), 0.0)
    dev, dof = float(2.0 * np.sum(t1 + t2)), int(omega.size - 2)
    gof = None
    if dof > 0:
        import mpmath

        # P(chi^2_dof > deviance): the upper incomplete gamma directly (1 - lower loses it below 1e-16)
        gof = float(mpmath.gammainc(dof / 2.0, dev / 2.0, mpmath.inf, regularized=True)) if np.isfinite(dev) else 0.0
    return {**out, "p": float(ps[i]), "p_ci": [lo, hi], "A": float(np.exp(best_c[i])), "loglik": float(prof[i]),
            "deviance": dev, "dof": dof, "gof_p": gof}


def omega_half(omega, fraction) -> Optional[float]:
    """Where the fraction first reaches 1/2, by linear interpolation between the two rates
    around it (``None`` if it never does)."""
    i = np.flatnonzero(np.asarray(fraction) >= 0.5)
    if not i.size:
        return None
    j = int(i[0])
    if j == 0:
        return float(omega[0])
    f0, f1, o0, o1 = fraction[j - 1], fraction[j], omega[j - 1], omega[j]
    return float(o0 + (0.5 - f0) * (o1 - o0) / (f1 - f0))


def fractions_over_time(params, levels, cfg, progress=False):
    """:func:`taylorball.chaotic_fraction`'s sample and runs (``cfg.n_orbits`` points, seed
    ``cfg.seed``, ``norm="compact"``, runs stopped once ``<Y> > 10``), read at the times
    ``cfg.megno_times * cfg.megno_t`` as well. Returns ``(times (k,), n_chaotic (k,), n,
    mean_Y at megno_t (n,), points (n, 3), r_box)``; the last count is chaotic_fraction's."""
    from ..chaos import MegnoOptions, megno_many
    from ..charts import section_admissible_sample

    times = np.array([f * cfg.megno_t for f in cfg.megno_times], dtype=float)
    region = section_admissible_sample(params, **levels.as_kwargs(), n=cfg.n_orbits, seed=cfg.seed, direction=1)
    states = [roots[i % len(roots)] for i, roots in enumerate(region["states"])]
    res = megno_many("reduced", params, states, cfg.megno_t, stop_above=C.MEGNO_STOP, norm="compact",
                     workers=cfg.threads, progress=progress, sample=times,
                     options=MegnoOptions(t0=1.0, compact_mode=cfg.megno_compact,
                                          jacobian=cfg.megno_jacobian))
    k = np.zeros(times.size, dtype=int)
    for r in res:
        series = np.full(times.size, np.nan)  # a stopped run's series ends at its stop
        got = np.asarray(r.mean_Y, dtype=float).ravel()[: times.size]
        series[: got.size] = got
        stopped = r.t < times  # passed MEGNO_STOP before that time: chaotic from then on
        with np.errstate(invalid="ignore"):
            k += stopped | (np.isfinite(series) & (series > C.CHAOTIC_MEGNO))
    Y = np.array([r.mean_megno for r in res])
    k[-1] = int(np.count_nonzero(Y > C.CHAOTIC_MEGNO))  # at megno_t: the final value, as chaotic_fraction
    return times, k, len(res), Y, np.asarray(region["points"], dtype=float), float(region["r_box"])


def compute(cfg):
    import time

    from ..levels import Levels
    from .._atlas import chaotic_fraction, wilson_interval
    from ..chaos import MegnoOptions

    rows, times = [], []
    meta: dict = {"levels": {}, "fits": {}}
    Y = np.full((len(cfg.H), len(cfg.omegas), cfg.n_orbits), np.nan)
    KT = np.zeros((len(cfg.H), len(cfg.omegas), len(cfg.megno_times)))
    R = np.full((len(cfg.H), len(cfg.omegas), cfg.n_orbits), np.nan)
    for a, H in enumerate(cfg.H):
        lo, hi = rest_energy_range(ball(cfg, 0.0), cfg.G, H)
        h = lo + cfg.h_frac * (hi - lo)
        meta["levels"][str(H)] = {"G": cfg.G, "H": H, "h": h, "E_rest_range": [lo, hi]}
        for b, om in enumerate(cfg.omegas):
            t = time.perf_counter()
            tt, k, n, y, pts, r_box = fractions_over_time(ball(cfg, om), Levels.from_caption(G=cfg.G, H=H, h=h), cfg,
                                                          progress=C.bar(f"H={H:g}, Omega={om:g}"))
            times.append(time.perf_counter() - t)
            Y[a, b, :n] = y
            R[a, b, :n] = np.hypot(pts[:, 1], pts[:, 2])
            KT[a, b] = k / n
            rows.append([H, om, k[-1], n, k[-1] / n, *wilson_interval(int(k[-1]), n), r_box])
    table = np.array(rows, dtype=float).reshape(len(cfg.H), len(cfg.omegas), 8)
    for a, H in enumerate(cfg.H):
        m = (table[a, :, 1] > 0) & (table[a, :, 1] <= cfg.fit_max_omega)
        fit = power_law_fit(table[a, m, 1], table[a, m, 2], table[a, m, 3]) if m.any() else None
        if fit is not None:
            fit["fits"] = fit["gof_p"] is not None and fit["gof_p"] >= FIT_MIN_GOF
        meta["fits"][str(H)] = fit
        meta.setdefault("omega_half", {})[str(H)] = omega_half(table[a, :, 1], table[a, :, 4])
    # the anchor: the paper's Fig. 4a level itself
    anchor = chaotic_fraction(FIG4_BALL, FIG4A_LEVELS, n=cfg.n_orbits, t_end=cfg.megno_t, seed=cfg.seed,
                              workers=cfg.threads, progress=C.bar("Fig. 4a level"),
                              options=MegnoOptions(compact_mode=cfg.megno_compact, jacobian=cfg.megno_jacobian))
    meta["fig4a_anchor"] = {"omega": FIG4_BALL.plane_rate, **FIG4A_LEVELS.caption, "n_chaotic": anchor.n_chaotic,
                            "n": anchor.n, "fraction": anchor.fraction, "ci": list(anchor.ci)}
    meta["seconds_per_cell"] = times
    meta["table_columns"] = ["H", "Omega", "n_chaotic", "n", "fraction", "ci_lo", "ci_hi", "r_box"]
    meta["table"] = table.reshape(-1, 8).tolist()
    meta["megno_times"] = [f * cfg.megno_t for f in cfg.megno_times]
    return {"table": table, "mean_megno": Y, "radius": R, "fraction_t": KT}, meta


def _fit_text(fit) -> str:
    ci = fit["p_ci"]
    return (f"$p = {fit['p']:.2f}$ [{'-' if ci[0] is None else f'{ci[0]:.2f}'}, "
            f"{'-' if ci[1] is None else f'{ci[1]:.2f}'}]")


def plot(arrays, meta, outdir):
    """(a) the chaotic fraction against Omega (Wilson intervals at the longest T; grey: the
    same orbits at shorter T; a power law only where it fits), (b) the fraction against T,
    one curve per rate (colour: Omega, by the colour bar; line style: the level H). The
    legends sit under the panels, off the data."""
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.lines import Line2D
    from matplotlib.ticker import NullFormatter

    plt = C.pyplot()
    table = np.asarray(arrays["table"])
    cfg = meta["config"]
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 6.2), layout="constrained")
    markers, styles = "os^D", ("-", "--", ":", "-.")
    ft = np.asarray(arrays["fraction_t"]) if "fraction_t" in arrays else None
    Ts = meta.get("megno_times", [cfg["megno_t"]])
    multi = len(cfg["H"]) > 1
    om_all = table[0, :, 1]
    cmap = ListedColormap(plt.get_cmap("viridis")(np.linspace(0.0, 0.9, max(len(om_all), 1))))
    norm = BoundaryNorm(np.arange(len(om_all) + 1) - 0.5, cmap.N)
    notes = []
    for i, H in enumerate(cfg["H"]):
        om, f, lo, hi = table[i, :, 1], table[i, :, 4], table[i, :, 5], table[i, :, 6]
        lev = meta["levels"][str(float(H))]
        lab = f"$H = {H:g}$ ($h = {lev['h']:.3f}$) at $T = {cfg['megno_t']:g}$"
        a.errorbar(om, f, yerr=[f - lo, hi - f], marker=markers[i % 4], ms=4, lw=1.2, capsize=2,
                   color=C.CHAOTIC_COLOR, ls=styles[i % 4], label=lab, zorder=3)
        if ft is not None:
            for j, T in enumerate(Ts[:-1]):
                a.plot(om, ft[i, :, j], marker=markers[i % 4], ms=3, lw=0.8, ls=styles[i % 4], mfc="none",
                       color=str(0.75 - 0.35 * j / max(len(Ts) - 2, 1)), label=f"$H = {H:g}$ at $T = {T:g}$")
        fit = meta["fits"].get(str(float(H)))
        if fit and fit.get("p") is not None:
            good = fit.get("fits", fit.get("gof_p") is not None and fit["gof_p"] >= FIT_MIN_GOF)
            verdict = (f"$H = {H:g}$: power law $A\\Omega^p$ over $0 < \\Omega \\leq {cfg['fit_max_omega']:g}$: "
                       f"{_fit_text(fit)}, deviance {fit['deviance']:.3g} on {fit['dof']} d.o.f.")
            if good:
                x = np.linspace(fit["omega_range"][0], fit["omega_range"][1], 50)
                a.plot(x, np.minimum(1.0, fit["A"] * x ** fit["p"]), color=C.REGULAR_COLORS[0], lw=1.2,
                       label=f"fit $H = {H:g}$: {_fit_text(fit)}")
                notes.append(verdict + " (drawn)")
            else:
                notes.append(verdict + ": rejected, not drawn")
        elif fit is not None:
            notes.append(f"$H = {H:g}$: no power law fitted (no chaotic orbit or fewer than two rates in "
                         f"$0 < \\Omega \\leq {cfg['fit_max_omega']:g}$)")
        if ft is not None:
            for b_, o in enumerate(om):
                b.plot(Ts, ft[i, b_], marker=markers[i % 4], ms=4, ls=styles[i % 4], lw=1.1,
                       color=cmap(norm(int(np.flatnonzero(om_all == o)[0]) if np.any(om_all == o) else b_)))
    an = meta["fig4a_anchor"]
    a.errorbar([an["omega"]], [an["fraction"]], yerr=[[an["fraction"] - an["ci"][0]], [an["ci"][1] - an["fraction"]]],
               marker="*", ms=11, mfc="none", color=C.CHAOTIC_COLOR, ls="none", label="Fig. 4a level ($H = 2$, $h = 5$)")
    a.set_xlabel(r"$\Omega$")
    a.set_ylabel(r"chaotic fraction ($\langle Y\rangle > 4$ at $T$)")
    a.set_ylim(-0.03, 1.03)
    a.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2)
    a.set_title("(a) chaotic fraction against $\\Omega$ (Wilson 95 % intervals at the longest $T$;\n"
                "grey: the same orbits at shorter $T$)", fontsize=9)
    b.set_xscale("log")
    b.set_xticks(Ts, [f"{T:g}" for T in Ts])  # the times read, not log-axis minor labels
    b.xaxis.set_minor_formatter(NullFormatter())
    b.set_xlim(Ts[0] / 1.15, Ts[-1] * 1.15)
    b.set_xlabel("MEGNO time $T$")
    b.set_ylabel("chaotic fraction")
    b.set_ylim(-0.03, 1.03)
    b.set_title("(b) the fraction against $T$ per $\\Omega$ (the same orbits):\n"
                "a curve still rising has not converged in $T$", fontsize=9)
    if ft is not None:
        sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
        cb = fig.colorbar(sm, ax=b, ticks=np.arange(len(om_all)), pad=0.02)
        cb.ax.set_yticklabels([f"{o:g}" for o in om_all])
        cb.set_label(r"$\Omega$")
        if multi:
            b.legend([Line2D([], [], color="0.3", ls=styles[i % 4], marker=markers[i % 4], ms=4)
                      for i in range(len(cfg["H"]))], [f"$H = {H:g}$" for H in cfg["H"]], fontsize=7,
                     loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=len(cfg["H"]))
    fig.suptitle(f"Chaos atlas: ball I=(2,3,4), m=1, a=5, G={cfg['G']:g}, h at {cfg['h_frac']:g} of the "
                 f"R = 0 energy range; {cfg['n_orbits']} orbits per point, MEGNO " + r"$\langle Y\rangle > 4$"
                 " (norm='compact')\n" + "\n".join(notes), fontsize=9)
    return C.save_figure(fig, outdir, "chaos_atlas", meta)


if __name__ == "__main__":
    from .runner import main

    sys.exit(main(sys.modules[__name__]))
