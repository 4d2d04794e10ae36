"""Where the validated step's cost and its short length come from (taylorball.rigorous).

On the Fig. 3 level's saddle (``taylorball.periodic_catalog.FIG3_SADDLE``, the symmetric ball at
``Omega = 2``), at 53 bits unless said otherwise:

1. heyoka's float64 steps over one period (the float step the validated one is compared with);
2. the wrapping of the vector field's formula on balls: the interval Lipschitz constant
   (Perron root of ``|Df|``) against the largest ``|eigenvalue of Df|``, and how fast the
   Taylor coefficients' radii grow with the order (ball recursion from a box of radius 1e-12)
   against the point coefficients themselves;
3. the remainder ``x_{N+1}(B) h^{N+1}`` over the a priori box ``B`` against the point
   coefficient's ``x_{N+1}(c) h^{N+1}`` (the overestimate that shortens the step), and the
   largest ``h`` for which the a priori enclosure is found;
4. steps per time unit and CPU per time unit of ``integrate_set`` (C^0 and C^1) against the
   Taylor order and the remainder's time slices, as ratios against order 18 without slices (the
   former code at 53 bits) measured in the same run;
5. (``--segment``) the point box carried along the orbit's longest segment (13.64 time
   units): its radius against time, at 53 and (``--prec128``) 128 bits.

Run: ``python benchmarks/bench_rigorous_step.py [--segment] [--prec128]`` (about 30 CPU s
without the options; quote CPU seconds and the machine's load).
"""

from __future__ import annotations

import argparse
import time
from fractions import Fraction

import numpy as np


def _setup(prec):
    from taylorball.periodic_catalog import FIG3_SADDLE
    from taylorball.rigorous._balls import exact_arb
    from taylorball.rigorous.enclosure import ball_pars, ball_rhs, internal_system

    pars = ball_pars("reduced", FIG3_SADDLE.ball)
    X0 = list(internal_system("reduced").to_internal(pars, [exact_arb(v) for v in FIG3_SADDLE.state]))
    return ball_rhs("reduced", pars), X0


def float_steps() -> None:
    import heyoka as hy

    from taylorball.model import get_system
    from taylorball.periodic_catalog import FIG3_SADDLE
    from taylorball.rigorous._balls import exact_arb, working_precision

    system = get_system("reduced")
    with working_precision(53):
        from taylorball.rigorous.enclosure import ball_pars

        x0 = [float(x.mid()) for x in system.to_internal(ball_pars("reduced", FIG3_SADDLE.ball),
                                                          [exact_arb(v) for v in FIG3_SADDLE.state])]
    ta = hy.taylor_adaptive(system.equations(), x0, pars=list(FIG3_SADDLE.ball.pars), compact_mode=True)
    res = ta.propagate_until(FIG3_SADDLE.period)
    n = res[3]
    print(f"1. heyoka float64 (tol eps, order {ta.order}): {n} steps over the period {FIG3_SADDLE.period:.4f}: "
          f"{n / FIG3_SADDLE.period:.1f} steps per time unit, mean h {FIG3_SADDLE.period / n:.3g}")


def wrapping() -> None:
    from taylorball.rigorous._balls import Dual, arb, exact_arb, working_precision
    from taylorball.rigorous._taylor import LohnerSet, default_order, lohner_step, taylor_coeffs

    with working_precision(53):
        rhs, X0 = _setup(53)
        n = len(X0)
        c = [exact_arb(x.mid()) for x in X0]
        f = rhs([Dual(c[i], tuple(exact_arb(1 if j == i else 0) for j in range(n))) for i in range(n)])
        D = np.array([[float(f[i].g[j].mid()) for j in range(n)] for i in range(n)])
        print(f"2. Df at the saddle's start: largest |entry| {np.abs(D).max():.0f}, largest |eigenvalue| "
              f"{np.abs(np.linalg.eigvals(D)).max():.1f}, Perron root of |Df| (the interval Lipschitz constant) "
              f"{max(abs(np.linalg.eigvals(np.abs(D)))):.1f}")
        K = 14
        pc = taylor_coeffs(rhs, c, K)
        bc = taylor_coeffs(rhs, [x + arb(0, 1e-12) for x in c], K)
        norm = [max(abs(float(pc[i][k].mid())) for i in range(n)) for k in range(K + 1)]
        rad = [max(float(bc[i][k].rad()) for i in range(n)) for k in range(K + 1)]
        gp = (norm[K] / norm[4]) ** (1 / (K - 4))
        gr = (rad[K] / rad[4]) ** (1 / (K - 4))
        print(f"   growth per order (k = 4..{K}): point coefficients x{gp:.1f}, radii of the ball recursion from a "
              f"box of radius 1e-12 x{gr:.1f}; radius of x_1 / 1e-12 = {rad[1] / 1e-12:.0f}; relative radius of "
              f"x_{K} {rad[K] / norm[K]:.1e}")
        N = default_order(53)
        pc = taylor_coeffs(rhs, c, N + 1)
        pn = max(abs(float(pc[i][N + 1].mid())) for i in range(n))
        S = LohnerSet.from_box(X0)
        print(f"3. remainder at order {N} (accepted if <= {16 * 2.0 ** -53 * 12:.1e}):")
        for h in (0.001, 0.002, 0.004, 0.008, 0.016, 0.032):
            res = lohner_step(rhs, S, exact_arb(Fraction(h)), N)
            if res is None:
                print(f"   h = {h}: no a priori enclosure")
                continue
            rem = max(float(abs(r).upper()) for r in res.rem)
            print(f"   h = {h}: x_N+1(B) h^N+1 = {rem:.2e}, point x_N+1(c) h^N+1 = {pn * h ** (N + 1):.2e} "
                  f"(overestimate {rem / (pn * h ** (N + 1)):.1e}); a priori box radius {max(float(b.rad()) for b in res.B):.2e}")


def orders() -> None:
    from taylorball.rigorous._balls import working_precision
    from taylorball.rigorous._taylor import LohnerSet
    from taylorball.rigorous.enclosure import integrate_set

    T = Fraction(1, 10)
    print("4. integrate_set from the saddle's start state to t = 0.1 (point box), against the order and the "
          "remainder's time slices (0: over the one a priori box, the former code):")
    runs = [(False, 18, 0), (False, 18, 4), (False, 12, 0), (False, 12, 4), (False, 10, 4), (False, 24, 4),
            (True, 18, 0), (True, 12, 0)]
    base = {}
    for jac, N, sl in runs:
        with working_precision(53):
            rhs, X0 = _setup(53)
            t0 = time.process_time()
            S, V, steps, box = integrate_set(rhs, LohnerSet.from_box(X0), T, prec=53, order=N, tol=2.0 ** -53, jac=jac,
                                             slices=sl)
            cpu = time.process_time() - t0
        per_unit = cpu / float(T)
        base.setdefault(jac, per_unit)
        print(f"   {'C^1' if jac else 'C^0'} order {N:2d}, slices {sl}: {steps:4d} steps ({steps / float(T):.0f} per time "
              f"unit), {cpu / steps:.3f} CPU s per step, {per_unit:.0f} CPU s per time unit (x{base[jac] / per_unit:.2f} "
              f"against order 18 without slices), largest radius {max(float(b.rad()) for b in box):.1e}")


def segment(prec: int, order: int, t_end: float) -> None:
    from taylorball.paper import FIG3_BALL, FIG3_LEVELS
    from taylorball.rigorous._balls import exact_arb, working_precision
    from taylorball.rigorous._taylor import LohnerSet
    from taylorball.rigorous.enclosure import ball_pars, ball_rhs, integrate_set, max_rad
    from taylorball.rigorous.search import float_map
    from taylorball.rigorous.section import _newton_root, chart_start_state, energy_residual
    from taylorball.model import get_system
    import taylorball as tb

    p = (-7.075896990683475, -0.5831278211157831)  # the saddle's 2nd section point (float64 Newton)
    q, tau, x0 = float_map(FIG3_BALL, FIG3_LEVELS, p, K_near=-10.0)
    Kf = float(tb.reduced_chart(FIG3_BALL, x0[None])["K"][0])
    with working_precision(prec):
        pars = ball_pars("reduced", FIG3_BALL)
        c = get_system("reduced").constants(pars)
        rhs = ball_rhs("reduced", pars)
        C, Mg, h = (exact_arb(v) for v in (FIG3_LEVELS.C, FIG3_LEVELS.M_gamma, FIG3_LEVELS.h))
        r1, r2 = exact_arb(p[0]), exact_arb(p[1])
        F = energy_residual(c, C, Mg, h, r1, r2)
        X0 = list(chart_start_state(C, Mg, _newton_root(F, Kf, (1e-6, 1e-4), "K", refine=8), r1, r2))
        t0 = time.process_time()
        marks = {"n": 0}

        def on_step(t, res):
            marks["n"] += 1
            if marks["n"] % 250 == 0:
                print(f"   {prec} bits, order {order}: step {marks['n']}, t = {float(t):.3f}, radius "
                      f"{max_rad(res.box):.2e}, {time.process_time() - t0:.0f} CPU s", flush=True)

        print(f"5. the point box along the segment of return time {tau:.3f} (to t = {t_end}):")
        try:
            _, _, steps, box = integrate_set(rhs, LohnerSet.from_box(X0), Fraction(t_end), prec=prec, order=order,
                                             tol=2.0 ** -prec, on_step=on_step)
            print(f"   reached t = {t_end}: {steps} steps, radius {max_rad(box):.2e}, "
                  f"{time.process_time() - t0:.0f} CPU s")
        except Exception as exc:  # an IntegrationError: the set has grown too wide
            print(f"   failed: {exc} ({time.process_time() - t0:.0f} CPU s)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--segment", action="store_true", help="carry the point box along the longest segment (53 bits)")
    ap.add_argument("--prec128", action="store_true", help="the same at 128 bits (order 28; many CPU minutes)")
    args = ap.parse_args()
    t0 = time.process_time()
    float_steps()
    wrapping()
    orders()
    if args.segment:
        segment(53, 12, 3.0)
    if args.prec128:
        segment(128, 28, 3.0)
    print(f"total {time.process_time() - t0:.0f} CPU s")


if __name__ == "__main__":
    main()
