"""Scouting levels of the dynamically symmetric ball (I1 = I2) where validated proofs are cheap.

For each candidate (ball, level) of :data:`CANDIDATES`:

1. float64 search: ``tb.periodic_orbits(..., k_max=1)`` (fixed points of the 2D section map
   of ``(r1, r2)``, i.e. relative periodic orbits with one crossing of ``g = 0``); the most
   hyperbolic one (largest ``|multiplier|``) and, if found, an elliptic one;
2. at the hyperbolic orbit's section state: the Sherman--Morrison denominator
   ``1 - d (gamma, A gamma)`` (``A = diag(1/(I_i + d))``, ``d = m a^2``), the largest entry of
   ``Df`` against its largest ``|eigenvalue|``, and the radius growth of one evaluation of the
   field on balls (radius of the first Taylor coefficient from a box of radius 1e-12, over
   1e-12), all at 53 bits;
3. heyoka's float64 steps over one return (mean step);
4. the validated C^0 steps (``integrate_set``, 53 bits, order 18, point box) to ``t = T_VAL``:
   mean step, CPU s per time unit, and the estimate for one return.

``--grid``: the k = 1 orbits found by ``tb.periodic_orbits`` on the grid of levels of
:data:`GRID` (the first table of docs/rigorous.md, "Tzenoff's case on a tractable level";
4-26 CPU s per level).

Floating-point searches only propose candidates; nothing here proves anything. Run:
``python benchmarks/bench_rigorous_scout.py [--grid] [NAME ...]`` (about 30-60 CPU s per
candidate on the shared 2-core machine; quote CPU seconds and the load).
"""

from __future__ import annotations

import sys
import time
import warnings
from fractions import Fraction

import numpy as np

#: name -> (inertia, mass, radius, Omega, (C, M_gamma, h)). d = m a^2.
CANDIDATES = {
    "fig3": ((2.0, 2.0, 3.0), 1.0, 5.0, 2.0, (10.0, 6.0, 5.0)),
    "d3.5_om2_h5": ((2.0, 2.0, 3.0), 3.5, 1.0, 2.0, (10.0, 6.0, 5.0)),
    "d3.5_om2_h-5": ((2.0, 2.0, 3.0), 3.5, 1.0, 2.0, (10.0, 6.0, -5.0)),
    "d3.5_om2_h-20": ((2.0, 2.0, 3.0), 3.5, 1.0, 2.0, (10.0, 6.0, -20.0)),
    "d3.5_om3_h-20": ((2.0, 2.0, 3.0), 3.5, 1.0, 3.0, (10.0, 6.0, -20.0)),
}
T_VAL = Fraction(1, 5)
#: The grid of levels scanned (ball I = (2, 2, 3), m = 7/2, a = 1, C = 10): (Omega, M_gamma, h).
GRID = ([(om, mg, h) for om in (1.0, 2.0, 3.0) for mg in (0.0, 6.0) for h in (-20.0, -5.0, 5.0, 15.0)]
        + [(3.0, mg, h) for mg in (4.0, 8.0) for h in (-40.0, -30.0, -20.0, -10.0)]
        + [(3.0, 6.0, h) for h in (-40.0, -30.0, -10.0)])


def grid() -> None:
    import taylorball as tb

    for om, mg, h in GRID:
        P = tb.BallParams(inertia=(2.0, 2.0, 3.0), mass=3.5, radius=1.0, plane_rate=om)
        t0 = time.process_time()
        try:
            orbs = tb.periodic_orbits("reduced", P, tb.Levels(C=10.0, M_gamma=mg, h=h), k_max=1, n_points=60)
        except Exception as exc:  # an empty level or a failed search: say so and go on
            print(f"Omega = {om}, M_gamma = {mg}, h = {h}: {type(exc).__name__}: {exc}")
            continue
        found = "; ".join(f"{o.type} (T = {o.period:.3f}, |mu| = {max(abs(o.multipliers)):.3f})" for o in orbs)
        print(f"Omega = {om}, M_gamma = {mg}, h = {h}: {found or 'none'} ({time.process_time() - t0:.0f} CPU s)",
              flush=True)


def scout(name: str) -> None:
    import heyoka as hy

    import taylorball as tb
    from taylorball.model import get_system
    from taylorball.rigorous._balls import Dual, arb, exact_arb, working_precision
    from taylorball.rigorous._taylor import LohnerSet, taylor_coeffs
    from taylorball.rigorous.enclosure import ball_pars, ball_rhs, integrate_set
    from taylorball.rigorous.search import float_map

    inertia, m, a, Om, (C, Mg, h) = CANDIDATES[name]
    P = tb.BallParams(inertia=inertia, mass=m, radius=a, plane_rate=Om)
    L = tb.Levels(C=C, M_gamma=Mg, h=h)
    d = m * a * a
    t0 = time.process_time()
    orbs = tb.periodic_orbits("reduced", P, L, k_max=1, n_points=60)
    t_search = time.process_time() - t0
    hyp = [o for o in orbs if o.stability == "hyperbolic"]
    ell = [o for o in orbs if o.stability == "elliptic"]
    print(f"{name}: I = {inertia}, m = {m}, a = {a} (d = {d}), Omega = {Om}, level C = {C}, M_gamma = {Mg}, h = {h}; "
          f"{len(hyp)} hyperbolic, {len(ell)} elliptic k = 1 orbits ({t_search:.0f} CPU s)", flush=True)
    for o in ell[:1]:
        ch = tb.reduced_chart(P, np.asarray(o.state)[None])
        print(f"   elliptic: T = {o.period:.6f}, trace {o.trace:.4f}, (r1, r2) = ({float(ch['r1'][0]):.6f}, "
              f"{float(ch['r2'][0]):.6f})")
    if not hyp:
        return
    o = max(hyp, key=lambda q: max(abs(q.multipliers)))
    ch = tb.reduced_chart(P, np.asarray(o.state)[None])
    p = (float(ch["r1"][0]), float(ch["r2"][0]))
    K = float(ch["K"][0])
    Pp, tau, x0 = float_map(P, L, p, K_near=K)
    mu = np.sort(np.abs(o.multipliers))
    print(f"   hyperbolic ({o.type}): T = {o.period:.6f}, multipliers {mu[0]:.5f}, {mu[-1]:.5f}; (r1, r2) = "
          f"({p[0]:.9f}, {p[1]:.9f}), K = {K:.9f}; float map residual {np.max(np.abs(Pp - p)):.1e}, tau {tau:.6f}")
    g = np.asarray(x0[3:6], dtype=float)
    den = 1.0 - d * float(np.sum(g * g / (np.asarray(inertia) + d)))
    system = get_system("reduced")
    with working_precision(53):
        pars = ball_pars("reduced", P)
        rhs = ball_rhs("reduced", pars)
        X0 = list(system.to_internal(pars, [exact_arb(float(v)) for v in x0]))
        n = len(X0)
        c = [exact_arb(x.mid()) for x in X0]
        f = rhs([Dual(c[i], tuple(exact_arb(1 if j == i else 0) for j in range(n))) for i in range(n)])
        D = np.array([[float(f[i].g[j].mid()) for j in range(n)] for i in range(n)])
        bc = taylor_coeffs(rhs, [x + arb(0, 1e-12) for x in c], 2)
        growth = max(float(bc[i][1].rad()) for i in range(n)) / 1e-12
        print(f"   denominator 1 - d (gamma, A gamma) = {den:.3f}; Df: largest |entry| {np.abs(D).max():.0f}, largest "
              f"|eigenvalue| {np.abs(np.linalg.eigvals(D)).max():.1f}; one field evaluation multiplies radii by "
              f"{growth:.0f}", flush=True)
        xf = [float(x.mid()) for x in X0]
    ta = hy.taylor_adaptive(system.equations(), xf, pars=list(P.pars), compact_mode=True)
    nfl = ta.propagate_until(tau)[3]
    c0 = time.process_time()
    with working_precision(53):
        _, _, steps, _ = integrate_set(rhs, LohnerSet.from_box(X0), T_VAL, prec=53, order=18, tol=2.0 ** -53)
    cpu = time.process_time() - c0
    hv = float(T_VAL) / steps
    print(f"   heyoka float64: {nfl} steps per return, mean step {tau / nfl:.3g}; validated (53 bits, order 18, C^0) "
          f"to t = {float(T_VAL)}: {steps} steps, mean step {hv:.3g} ({tau / nfl / hv:.1f}x shorter), "
          f"{cpu / float(T_VAL):.0f} CPU s per time unit, ~{cpu / float(T_VAL) * tau:.0f} CPU s per return (C^0)",
          flush=True)


def main() -> None:
    warnings.simplefilter("ignore")
    args = sys.argv[1:]
    t0 = time.process_time()
    if "--grid" in args:
        args.remove("--grid")
        grid()
        if not args:
            print(f"total {time.process_time() - t0:.0f} CPU s")
            return
    names = args or list(CANDIDATES)
    for name in names:
        scout(name)
    print(f"total {time.process_time() - t0:.0f} CPU s")


if __name__ == "__main__":
    main()
