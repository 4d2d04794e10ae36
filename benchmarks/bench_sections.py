"""Section points per second and their accuracy: taylorball vs scipy DOP853 with events.

System: the Fig. 4a ball (I = (2, 3, 4), m = 1, a = 5, Omega = 2) on the levels of Fig. 4a
(C = 10, M_gamma = 2, h = 5) when the chart module can build such a state, else the demo
state. Section g = 0, direction +1.

Printed, all measured in this run:
* throughput (section points per second of wall time) of taylorball serial, taylorball on
  all cores (threads, several orbits), and scipy ``solve_ivp(method="DOP853")`` with an
  event function at its tightest tolerance (rtol = 100 eps, the smallest scipy accepts
  without clipping, atol = 1e-300 so that only rtol matters);
* accuracy of the first N points of both against a real128 taylorball reference (the
  chart coordinates (l, r1, r2), max abs error);
* the ratios: taylorball throughput / scipy throughput and scipy error / taylorball error.

Run: ``python benchmarks/bench_sections.py [--quick]``.
"""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np


def demo_state():
    g = np.array([0.3, 0.4, math.sqrt(0.75)])
    R = np.array([1.0, -0.5, 0.0])
    R[2] = -(R[0] * g[0] + R[1] * g[1]) / g[2]
    return np.array([0.1, 0.2, 0.3, *g, *R])


def fig4a_states(params, n):
    """States on the Fig. 4a levels, if the chart inverse is available."""
    try:
        from taylorball.charts import states_on_section
    except ImportError:
        return None
    out = []
    rng = np.random.default_rng(0)
    tries = 0
    while len(out) < n and tries < 200 * n:
        tries += 1
        point = (rng.uniform(0, 2 * math.pi), rng.uniform(-3, 3), rng.uniform(-3, 3))
        try:
            res = states_on_section(params, C=10.0, M_gamma=2.0, h=5.0, point=point)
        except Exception:
            continue
        st = np.asarray(getattr(res, "states", res))
        if st.size:
            out.append(st[0])
    return out if len(out) == n else None


def scipy_section(params, state, n_points, t_max):
    """Section points with scipy DOP853 + events, on the reduced system in the momentum
    variables (the same equations taylorball integrates). The right-hand side is the
    package's own formula evaluated on Python floats (9 us per call here; an np.cross
    version took 110 us, which would flatter taylorball 10x)."""
    from scipy.integrate import solve_ivp

    import taylorball as tb
    from taylorball.model import get_system

    system = get_system("reduced")
    pars = tuple(float(p) for p in params.pars)
    x0 = np.array(system.to_internal(pars, tuple(tb.project("reduced", np.asarray(state)))), dtype=float)

    def rhs(t, x):
        return system.rhs(pars, tuple(x.tolist()))

    def event(t, x):
        M, g = x[0:3], x[3:6]
        C2 = M @ M
        return math.sqrt(C2) * (M[1] * g[0] - M[0] * g[1]) / C2

    event.direction = 1.0
    pts, times = [], []
    t0, x = 0.0, x0
    eps = np.finfo(float).eps
    while len(pts) < n_points and t0 < t_max:
        sol = solve_ivp(rhs, (t0, min(t0 + 100.0, t_max)), x, method="DOP853", rtol=100 * eps, atol=1e-300,
                        events=event, dense_output=False)
        for te, xe in zip(sol.t_events[0], sol.y_events[0]):
            M, g = xe[0:3], xe[3:6]
            den = (M @ g) * M[2] - (M @ M) * g[2]
            if den > 0:  # the half-line g = 0, not g = pi
                R = xe[6:9]
                pts.append([math.atan2(M[0], M[1]) % (2 * math.pi), R[0] * g[0] + R[1] * g[1], R[0] * g[1] - R[1] * g[0]])
                times.append(te)
        t0, x = sol.t[-1], sol.y[:, -1]
    return np.array(pts[:n_points]), np.array(times[:n_points])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer points (smoke test)")
    args = ap.parse_args(argv)

    import heyoka as hy

    import taylorball as tb

    params = tb.BallParams(inertia=(2.0, 3.0, 4.0), mass=1.0, radius=5.0, plane_rate=2.0)
    n_acc = 20 if args.quick else 50
    n_tp = 200 if args.quick else 2000
    n_orbits = os.cpu_count() or 2
    states = fig4a_states(params, n_orbits)
    label = "Fig. 4a levels (C=10, M_gamma=2, h=5)"
    if states is None:
        states = [demo_state()] * n_orbits
        label = "demo state (chart inverse unavailable)"
    s0 = states[0]
    print(f"system: reduced, I=(2,3,4), m=1, a=5, Omega=2; initial state from {label}")
    print(f"heyoka {hy.__version__}, {os.cpu_count()} cores")

    # warm-up: compile and cache
    tb.poincare_section("reduced", params, s0, n_points=2)
    tb.poincare_section("reduced", params, s0, n_points=2, fp_type=hy.real128)

    t = time.perf_counter()
    r = tb.poincare_section("reduced", params, s0, n_points=n_tp)
    w_serial = time.perf_counter() - t
    tp_serial = n_tp / w_serial

    t = time.perf_counter()
    rs = tb.poincare_sections("reduced", params, states, n_points=n_tp)
    w_thr = time.perf_counter() - t
    tp_thr = sum(len(x) for x in rs) / w_thr

    n_sp = max(n_acc, n_tp // 20)
    t = time.perf_counter()
    sp_pts, sp_times = scipy_section(params, s0, n_sp, t_max=r.times[min(n_sp, n_tp) - 1] * 2 + 100)
    w_sp = time.perf_counter() - t
    tp_sp = len(sp_pts) / w_sp

    ref = tb.poincare_section("reduced", params, s0, n_points=n_acc, fp_type=hy.real128)
    err_tb = np.max(np.abs(r.points[:n_acc] - ref.points))
    err_sp = np.max(np.abs(sp_pts[:n_acc] - ref.points)) if len(sp_pts) >= n_acc else float("nan")

    print(f"\nthroughput (section points / s):")
    print(f"  taylorball serial           {tp_serial:12.1f}   ({n_tp} points in {w_serial:.2f} s, {r.n_steps} steps)")
    print(f"  taylorball {n_orbits} threads        {tp_thr:12.1f}   ({n_orbits} orbits x {n_tp} points in {w_thr:.2f} s)")
    print(f"  scipy DOP853 rtol=100eps    {tp_sp:12.1f}   ({len(sp_pts)} points in {w_sp:.2f} s)")
    print(f"accuracy of the first {n_acc} points vs real128 (max abs error in (l, r1, r2)):")
    print(f"  taylorball float64          {err_tb:12.3e}")
    print(f"  scipy DOP853                {err_sp:12.3e}")
    print("ratios:")
    print(f"  throughput taylorball(threads) / scipy = {tp_thr / tp_sp:8.1f}   (target >= 300)")
    print(f"  throughput taylorball(serial) / scipy  = {tp_serial / tp_sp:8.1f}")
    print(f"  error scipy / taylorball               = {err_sp / err_tb:8.1f}   (target >= 30)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
