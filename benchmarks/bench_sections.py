"""Section points per second and their accuracy: taylorball vs scipy DOP853 with events.

System: the Fig. 4a ball (I = (2, 3, 4), m = 1, a = 5, Omega = 2) on the levels of Fig. 4a
(C = G = 10, M_gamma = H = 2, h = 5), initial states at admissible chart points of the
section built by ``taylorball.charts`` (the demo state and perturbations if the chart
inverse is unavailable). Section g = 0, direction +1. ``batch_size() x cores`` orbits.

Printed, all measured in this run (the machine is shared: ratios are what to compare):
* throughput (section points per second of wall time) of taylorball serial (one orbit),
  on all cores with threads (one scalar integrator per orbit), and in heyoka's batch mode
  (``poincare_sections(..., batch=True)``: one orbit per SIMD lane) on 1 thread and on
  all cores; taylorball timings are medians of ``--repeats``;
* scipy ``solve_ivp(method="DOP853")`` with an event function at its tightest tolerance
  (rtol = 100 eps, the smallest scipy accepts without clipping, atol = 1e-300 so that
  only rtol matters), scipy imported and warmed up before the clock starts;
* accuracy of the first N points of orbit 0 against a real128 taylorball reference (the
  chart coordinates (l, r1, r2), max abs error), the event-function residuals, and
  whether batch runs on 1 and on all threads are bit-identical;
* the ratios: taylorball throughput / scipy throughput and scipy error / taylorball error.

Run: ``python benchmarks/bench_sections.py [--quick]`` (exit status 1 if a bit-identity
check fails).
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time

import numpy as np

from taylorball.sections import START_TOL


def demo_states(n):
    """The demo state of ``taylorball demo`` and ``n - 1`` perturbations of its omega."""
    from taylorball.paper import demo_reduced_state

    s = demo_reduced_state()
    rng = np.random.default_rng(5)
    out = [s]
    while len(out) < n:
        x = s.copy()
        x[0:3] += 0.05 * rng.normal(size=3)
        out.append(x)
    return out


def fig4a_states(params, n):
    """States on the Fig. 4a levels (C = G = 10, M_gamma = H = 2, h = 5), at admissible
    chart points of the section g = 0 with g increasing, if the chart inverse exists."""
    try:
        from taylorball.charts import section_admissible_sample, states_on_section
    except ImportError:
        return None
    lev = dict(C=10.0, M_gamma=2.0, h=5.0)
    pts = section_admissible_sample(params, n=n, direction=1, seed=0, **lev)["points"]
    out = [states_on_section(params, point=tuple(p), direction=1, **lev)[0] for p in pts]
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
            # the half-line g = 0, not g = pi; and not the start itself (built on the section,
            # e = 0 to rounding: scipy may report it at t = 0), as taylorball.sections.START_TOL
            if den > 0 and te > START_TOL:
                R = xe[6:9]
                pts.append([math.atan2(M[0], M[1]) % (2 * math.pi), R[0] * g[0] + R[1] * g[1], R[0] * g[1] - R[1] * g[0]])
                times.append(te)
        t0, x = sol.t[-1], sol.y[:, -1]
    return np.array(pts[:n_points]), np.array(times[:n_points])


def _median(fn, repeats):
    walls, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - t)
    return statistics.median(walls), out


def _same(a, b):
    return all(np.array_equal(x, y) for x, y in ((a.points, b.points), (a.times, b.times), (a.states, b.states)))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer points (smoke test)")
    ap.add_argument("--repeats", type=int, default=3, help="repeats of each taylorball timing (median)")
    args = ap.parse_args(argv)

    import heyoka as hy
    import scipy.integrate  # noqa: F401  (imported here: ~1 s that must not count as DOP853 time)

    import taylorball as tb
    from taylorball.paper import FIG4_BALL
    from taylorball.sections import batch_size

    params = FIG4_BALL
    n_acc = 20 if args.quick else 50
    n_tp = 200 if args.quick else 2000
    cores = os.cpu_count() or 2
    B = batch_size()
    n_orbits = B * cores  # one batch per core
    states = fig4a_states(params, n_orbits)
    label = "Fig. 4a levels (C=10, M_gamma=2, h=5), admissible chart points, g increasing"
    if states is None:
        states = demo_states(n_orbits)
        label = "demo state and perturbations (chart inverse unavailable)"
    s0 = states[0]
    print(f"system: reduced, I=(2,3,4), m=1, a=5, Omega=2; section g = 0, direction +1; {n_orbits} initial states "
          f"from {label}")
    print(f"heyoka {hy.__version__}, scipy {scipy.__version__}, {cores} cores, batch size {B}, "
          f"load average {os.getloadavg()[0]:.2f} (shared machine: compare the ratios, measured in one run)")

    # warm-up: compile and cache everything outside the timings
    tb.poincare_section("reduced", params, s0, n_points=2)
    tb.poincare_sections("reduced", params, states[:2], n_points=2, batch=True)
    tb.poincare_section("reduced", params, s0, n_points=2, fp_type=hy.real128)
    scipy_section(params, s0, 1, t_max=50.0)

    w_serial, r = _median(lambda: tb.poincare_section("reduced", params, s0, n_points=n_tp), args.repeats)
    tp_serial = n_tp / w_serial
    w_thr, rs = _median(lambda: tb.poincare_sections("reduced", params, states, n_points=n_tp), args.repeats)
    tp_thr = sum(len(x) for x in rs) / w_thr
    w_b1, rb1 = _median(lambda: tb.poincare_sections("reduced", params, states, n_points=n_tp, batch=True,
                                                     workers=1), args.repeats)
    tp_b1 = sum(len(x) for x in rb1) / w_b1
    w_bt, rbt = _median(lambda: tb.poincare_sections("reduced", params, states, n_points=n_tp, batch=True),
                        args.repeats)
    tp_bt = sum(len(x) for x in rbt) / w_bt
    batch_threads_identical = all(_same(a, b) for a, b in zip(rb1, rbt))
    scalar_identical = _same(r, rs[0])
    steps_serial = r.n_steps

    n_sp = max(n_acc, n_tp // 20)
    t = time.perf_counter()
    sp_pts, sp_times = scipy_section(params, s0, n_sp, t_max=r.times[min(n_sp, n_tp) - 1] * 2 + 100)
    w_sp = time.perf_counter() - t
    tp_sp = len(sp_pts) / w_sp

    ref = tb.poincare_section("reduced", params, s0, n_points=n_acc, fp_type=hy.real128)
    err_tb = np.max(np.abs(r.points[:n_acc] - ref.points))
    err_b = np.max(np.abs(rbt[0].points[:n_acc] - ref.points))
    err_sp = np.max(np.abs(sp_pts[:n_acc] - ref.points)) if len(sp_pts) >= n_acc else float("nan")
    res_tb = max(float(np.max(np.abs(x.residuals))) for x in rs + rbt)

    print("\nthroughput (section points / s of wall time; taylorball: median of "
          f"{args.repeats}):")
    print(f"  taylorball serial, 1 orbit      {tp_serial:12.1f}   ({n_tp} points in {w_serial:.3f} s, {steps_serial} steps)")
    print(f"  taylorball {cores} threads, scalar    {tp_thr:12.1f}   ({n_orbits} orbits x {n_tp} points in {w_thr:.3f} s)")
    print(f"  taylorball batch, 1 thread      {tp_b1:12.1f}   ({n_orbits} orbits x {n_tp} points in {w_b1:.3f} s)")
    print(f"  taylorball batch, {cores} threads     {tp_bt:12.1f}   ({n_orbits} orbits x {n_tp} points in {w_bt:.3f} s)")
    print(f"  scipy DOP853 rtol=100eps        {tp_sp:12.1f}   ({len(sp_pts)} points in {w_sp:.2f} s)")
    print(f"accuracy of the first {n_acc} points of orbit 0 vs real128 (max abs error in (l, r1, r2)):")
    print(f"  taylorball float64 scalar       {err_tb:12.3e}")
    print(f"  taylorball float64 batch        {err_b:12.3e}")
    print(f"  scipy DOP853                    {err_sp:12.3e}")
    print(f"max |event function| at taylorball points (Newton-refined): {res_tb:.1e}")
    print(f"bit-identical: batch 1 thread vs {cores} threads: {batch_threads_identical}; "
          f"poincare_sections vs poincare_section (scalar): {scalar_identical}")
    print("ratios:")
    print(f"  throughput taylorball(batch, threads) / scipy  = {tp_bt / tp_sp:8.1f}   (target >= 300)")
    print(f"  throughput taylorball(scalar, threads) / scipy = {tp_thr / tp_sp:8.1f}")
    print(f"  throughput taylorball(serial) / scipy          = {tp_serial / tp_sp:8.1f}")
    print(f"  error scipy / taylorball(scalar)               = {err_sp / err_tb:8.1f}   (target >= 30)")
    print(f"  error scipy / taylorball(batch)                = {err_sp / err_b:8.1f}")
    return 0 if batch_threads_identical and scalar_identical else 1


if __name__ == "__main__":
    raise SystemExit(main())
