"""Cost of a MEGNO map (tb.megno_map) and how it scales with threads.

System: the Fig. 4b level (the asymmetric ball I = (2, 3, 4), m = 1, a = 5, Omega = 2;
H = 6, h = 5, G = 10), slice l = 0 of the section g = 0, the grid of the figure study
(r1 in [-5.5, 7], r2 in [-8, 8]) at ``--n`` x ``--n`` points, MEGNO to ``--T``, runs stopped
at <Y> > 10 as in the figures (and once without stopping), the batch tangent system in
default mode (compiled once, then from heyoka's disk cache: the first call is excluded
from the timings).

Printed, all measured in this run (the machine is shared: compare the ratios):
* the root search alone (states_on_section at every grid point, one thread: numpy);
* the whole map on 1 and 2 threads (and ``--threads`` more if given), wall seconds, per
  admissible point, speed-up over 1 thread, and whether the maps are bit-identical (they
  must be: an orbit's bits depend on its own state only);
* the map on all threads without ``stop_above`` (every run to T);
* the extrapolation to 100 x 100 at the same T: (root search + MEGNO per point) x points.

Run: ``python benchmarks/bench_maps.py [--n 24] [--T 1000]`` (exit status 1 if the maps on
different thread counts differ).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np


def main(argv=None) -> int:
    import taylorball as tb
    from taylorball.manifold import params_for
    from taylorball.maps import _row_states
    from taylorball.paper import FIG4_BALL, FIG4B_LEVELS

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=24, help="grid points per axis (default 24)")
    ap.add_argument("--T", type=float, default=1000.0, help="MEGNO horizon (default 1000)")
    ap.add_argument("--threads", type=int, nargs="*", default=[1, 2], help="thread counts (default 1 2)")
    args = ap.parse_args(argv)
    grid = dict(l=0.0, r1=(-5.5, 7.0, args.n), r2=(-8.0, 8.0, args.n))
    kw = dict(t_end=args.T, options=tb.MegnoMapOptions(stop_above=10.0, compact_mode=False, norm="full"))
    print(f"MEGNO map, Fig. 4b level, {args.n} x {args.n} grid at l = 0, T = {args.T:g}; "
          f"os.cpu_count() = {os.cpu_count()}, load average {os.getloadavg()[0]:.1f}")
    tb.megno_map(FIG4_BALL, FIG4B_LEVELS, l=0.0, r1=(-1, 1, 2), r2=(-1, 1, 2), t_end=2.0,
                 options=tb.MegnoMapOptions(compact_mode=False))  # compile

    p = params_for("reduced", FIG4_BALL)
    r1s = np.linspace(*grid["r1"][:2], args.n)
    t0 = time.perf_counter()
    n_adm = sum(int(np.isfinite(_row_states(p, FIG4B_LEVELS, 0.0, r1s, float(b), 0.0, 1, 0, 2001)[1]).sum())
                for b in np.linspace(*grid["r2"][:2], args.n))
    t_roots = time.perf_counter() - t0
    print(f"root search: {t_roots:.1f} s for {args.n ** 2} points ({1e3 * t_roots / args.n ** 2:.1f} ms per point), "
          f"{n_adm} admissible")

    maps, walls, cpus = {}, {}, {}
    for th in args.threads:
        t0, c0 = time.perf_counter(), time.process_time()
        maps[th] = tb.megno_map(FIG4_BALL, FIG4B_LEVELS, workers=th, **grid, **kw)
        walls[th], cpus[th] = time.perf_counter() - t0, time.process_time() - c0
        m = maps[th]
        ok = np.isfinite(m.values)
        print(f"map, {th} thread(s), stop_above=10: {walls[th]:.1f} s wall, {cpus[th]:.1f} s CPU "
              f"({walls[th] / ok.sum():.3f} s wall, {cpus[th] / ok.sum():.3f} s CPU per admissible "
              f"point; speed-up over 1 thread {walls[args.threads[0]] / walls[th]:.2f}); "
              f"{int((m.values[ok] > 4).sum())} of {int(ok.sum())} with <Y> > 4, "
              f"{int((m.t.values[ok] < args.T).sum())} stopped early")
    ref = maps[args.threads[0]]
    same = all(np.array_equal(m.values, ref.values, equal_nan=True) for m in maps.values())
    print(f"maps bit-identical across thread counts: {same}")

    th = max(args.threads)
    t0 = time.perf_counter()
    full = tb.megno_map(FIG4_BALL, FIG4B_LEVELS, workers=th, **grid, t_end=args.T,
                        options=tb.MegnoMapOptions(compact_mode=False, norm="full"))
    w_full = time.perf_counter() - t0
    ok = np.isfinite(full.values)
    print(f"map, {th} thread(s), every run to T: {w_full:.1f} s ({w_full / walls[th]:.2f}x the stopped runs); "
          f"<Y> from {np.nanmin(full.values):.2f} to {np.nanmax(full.values):.1f}")
    scale = 100 * 100 / args.n ** 2
    print(f"extrapolated to 100 x 100 at T = {args.T:g} on {th} thread(s): {walls[th] * scale / 60:.1f} min "
          f"(stopped at <Y> > 10), {w_full * scale / 60:.1f} min (every run to T); from the CPU time, on "
          f"{os.cpu_count()} otherwise idle cores: {cpus[th] * scale / os.cpu_count() / 60:.1f} min (stopped)")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
