"""The search for periodic orbits up to period 3 on the Fig. 4a level (docs/skeleton.md,
"Segments chosen automatically"; the target "all periodic orbits up to period 3 on the Fig. 4a
level in <= 5 min on 2 cores", docs/benchmarks.md).

``tb.periodic_orbits("reduced", FIG4_BALL, FIG4A_LEVELS, k_max=3, report=True,
options=SearchOptions(slow_factor=...))``: seeds from the chart grid, near-recurrences and the
reversors' fixed sets; seeds with a slow return (or a section point near the chart's singular
point) by multiple shooting with automatic segments, the others by single shooting. Prints
one line per seed (``k``, how it was solved, its seed residual, CPU s, the outcome and the
best residual), every orbit found with an independent check (a float64 ``poincare_section``
from the reported state must return to it after ``k`` crossings to <= 1e-12 relative), the
seeds' counts and the CPU and wall time. The machine is shared: quote CPU seconds and the load.

Run: ``python benchmarks/bench_search.py [--k-max 3] [--slow-factor 3] [--single] [--n-grid 300]
[--n-seeds 48] [--n-points 200] [--per-k 12] [--max-dist 0.5]`` (defaults: the search's;
``--single``: the search without the slow-seed shooting, as before ``slow_factor``).
"""

from __future__ import annotations

import argparse
import os
import resource
import time

import numpy as np

EPS = float(np.finfo(float).eps)
#: The independent return's tolerance: 1e-12 relative is ~4500 eps (2^12 ~ 4096 eps is
#: what the Fig. 4a orbits of period 25 need; their catalogue checks measured 6e-14 .. 7e-13).
CHECK_EPS = 4500


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--k-max", type=int, default=3)
    ap.add_argument("--slow-factor", type=float, default=3.0)
    ap.add_argument("--single", action="store_true", help="no shooting of slow seeds (slow_factor=None)")
    ap.add_argument("--n-grid", type=int, default=300)
    ap.add_argument("--n-seeds", type=int, default=48)
    ap.add_argument("--n-points", type=int, default=200)
    ap.add_argument("--per-k", type=int, default=12)
    ap.add_argument("--max-dist", type=float, default=0.5)
    args = ap.parse_args()

    import taylorball as tb
    import taylorball.periodic_search as ps
    import taylorball.periodic_shooting as pshoot
    from taylorball.paper import FIG4_BALL, FIG4A_LEVELS

    log = []

    def timed(fn, how):
        def wrapper(*a, **kw):
            t0 = _cpu()
            k = a[3] if how == "single" else sum(a[3] or [1] * len(a[2]))
            try:
                o = fn(*a, **kw)
            except Exception as exc:
                res = getattr(exc, "residual", float("nan"))
                log.append((how, k, _cpu() - t0, "fail", res))
                print(f"  {how:8s} k={k} {_cpu() - t0:6.1f} CPU s  failed  best residual {res:.2e}", flush=True)
                raise
            log.append((how, k, _cpu() - t0, "ok", o.residual))
            print(f"  {how:8s} k={k} {_cpu() - t0:6.1f} CPU s  CONVERGED k={o.k} T={o.period:.6f} {o.type}",
                  flush=True)
            return o
        return wrapper

    ps.periodic_orbit = timed(ps.periodic_orbit, "single")  # type: ignore[assignment]
    pshoot.shoot_periodic_orbit = timed(pshoot.shoot_periodic_orbit, "shooting")  # type: ignore[assignment]

    opts = tb.SearchOptions(slow_factor=None if args.single else args.slow_factor, n_grid=args.n_grid,
                            n_seeds=args.n_seeds, per_k=args.per_k, max_dist=args.max_dist)
    print(f"Fig. 4a level, k_max = {args.k_max}, n_points = {args.n_points}, {opts}; load average "
          f"{os.getloadavg()}", flush=True)
    c0, w0 = _cpu(), time.time()
    rep = tb.periodic_orbits("reduced", FIG4_BALL, FIG4A_LEVELS, k_max=args.k_max, n_points=args.n_points,
                             report=True, options=opts)
    cpu, wall = _cpu() - c0, time.time() - w0
    print(f"seeds {rep.seeds}, by shooting {rep.shooting}, slow return > {rep.slow_time}, failures "
          f"{rep.failures}, duplicates {rep.duplicates}")
    for o in rep.orbits:
        sec = tb.poincare_section("reduced", FIG4_BALL, o.state, n_points=o.k)
        scale = max(1.0, float(np.max(np.abs(o.state))))
        err = float(np.max(np.abs(np.asarray(sec.states[-1]) - np.asarray(o.state)))) / scale
        ok = err <= CHECK_EPS * EPS
        print(f"ORBIT k={o.k} T={o.period:.10f} {o.type} multipliers {np.round(o.multipliers, 6)} residual "
              f"{o.residual:.1e}; independent return {err:.1e} relative ({'ok' if ok else 'FAILED'} <= "
              f"{CHECK_EPS} eps)")
    for k in range(1, args.k_max + 1):
        f = [x for x in rep.failed if x[0] == k]
        if f:
            best = sorted(f, key=lambda x: (np.isnan(x[2]), x[2]))[:3]
            print(f"k={k}: {len(f)} failed; seed residuals {min(x[1] for x in f):.2e} .. "
                  f"{max(x[1] for x in f):.2e}; best Newton residuals "
                  f"{', '.join(f'{x[2]:.2e} ({x[3]})' for x in best)}")
    by = {}
    for how, k, c, out, _ in log:
        by.setdefault(how, [0, 0.0])
        by[how][0] += 1
        by[how][1] += c
    print(f"Newton CPU s by method: {by}")
    print(f"CPU {cpu:.1f} s, wall {wall:.1f} s, load average at the end {os.getloadavg()}")


if __name__ == "__main__":
    main()
