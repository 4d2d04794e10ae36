"""Cost of a MEGNO map (tb.megno_map): the tangent equations' two forms, threads, the
root search, and the 100 x 100 map of the Fig. 4b level.

System: the Fig. 4b level (the asymmetric ball I = (2, 3, 4), m = 1, a = 5, Omega = 2;
H = 6, h = 5, G = 10), slice l = 0 of the section g = 0, the grid of the figure study
(r1 in [-5.5, 7], r2 in [-8, 8]) at ``--n`` x ``--n`` points, MEGNO to ``--T`` (every run
to T), the batch tangent system in default mode (compiled before the clock; heyoka's disk
cache keeps it).

Printed, all measured in this run (the machine is shared: CPU seconds of the process, and
ratios from the same run):
* the root search alone (states_on_section at every grid point, one thread: numpy), CPU
  per grid point;
* for each ``--jacobian`` form ("forward" and "symbolic", the default of ``tb.megno_map``:
  the tangent equations of earlier releases): the map on each of ``--threads``, CPU and wall, CPU per
  admissible orbit (per 1000 time units), and whether the maps on different thread counts
  are bit-identical (they must be: an orbit's bits depend on its own state only);
* how far the two forms' maps are apart: ``<Y>`` in units of float64 eps of ``<Y>``, by
  class, and how many points change class (``<Y> > 4``);
* the extrapolation to 100 x 100 at the same T on ``os.cpu_count()`` otherwise idle cores:
  the root search (serial) + CPU per orbit x 7206 admissible points / cores;
* with ``--full``: the 100 x 100 map itself, once, in the first of the ``--jacobian`` forms,
  all threads.

Run: ``python benchmarks/bench_maps.py [--n 12] [--T 1000] [--full]`` (exit status 1 if a
form's maps on different thread counts differ).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

#: Admissible points of the 100 x 100 grid (root 0), counted by the map itself.
ADMISSIBLE_100 = 7206


def main(argv=None) -> int:
    import taylorball as tb
    from taylorball.manifold import params_for
    from taylorball.maps import _row_states
    from taylorball.paper import FIG4_BALL, FIG4B_LEVELS

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=12, help="grid points per axis (default 12)")
    ap.add_argument("--T", type=float, default=1000.0, help="MEGNO horizon (default 1000)")
    ap.add_argument("--threads", type=int, nargs="*", default=[1, 2], help="thread counts (default 1 2)")
    ap.add_argument("--jacobian", nargs="*", default=["forward", "symbolic"], help="forms (default both)")
    ap.add_argument("--full", action="store_true", help="then the 100 x 100 map once (the first --jacobian form)")
    args = ap.parse_args(argv)
    cores = os.cpu_count() or 1
    grid = dict(l=0.0, r1=(-5.5, 7.0, args.n), r2=(-8.0, 8.0, args.n))
    print(f"MEGNO map, Fig. 4b level, {args.n} x {args.n} grid at l = 0, T = {args.T:g}; "
          f"os.cpu_count() = {cores}, load average {os.getloadavg()[0]:.1f}", flush=True)
    for jac in args.jacobian:  # compile (or load from heyoka's disk cache) before the clock
        tb.megno_map(FIG4_BALL, FIG4B_LEVELS, l=0.0, r1=(-1, 1, 2), r2=(-1, 1, 2), t_end=2.0,
                     options=tb.MegnoMapOptions(compact_mode=False, jacobian=jac))

    p = params_for("reduced", FIG4_BALL)
    r1s = np.linspace(*grid["r1"][:2], args.n)
    c0 = time.process_time()
    n_adm = sum(int(np.isfinite(_row_states(p, FIG4B_LEVELS, 0.0, r1s, float(b), 0.0, 1, 0, 2001)[1]).sum())
                for b in np.linspace(*grid["r2"][:2], args.n))
    c_roots = (time.process_time() - c0) / args.n ** 2
    print(f"root search: {1e3 * c_roots:.2f} ms CPU per grid point, {n_adm} of {args.n ** 2} admissible", flush=True)

    same, per_orbit, maps = True, {}, {}
    for jac in args.jacobian:
        opts = tb.MegnoMapOptions(compact_mode=False, jacobian=jac)
        got = {}
        for th in args.threads:
            c0, w0 = time.process_time(), time.perf_counter()
            got[th] = tb.megno_map(FIG4_BALL, FIG4B_LEVELS, workers=th, t_end=args.T, options=opts, **grid)
            cpu, wall = time.process_time() - c0, time.perf_counter() - w0
            ok = np.isfinite(got[th].values)
            orbit = (cpu - c_roots * args.n ** 2) / ok.sum() * 1000.0 / args.T
            per_orbit.setdefault(jac, []).append(orbit)
            print(f"{jac}, {th} thread(s): {cpu:.1f} s CPU, {wall:.1f} s wall; {orbit:.4f} CPU-s per orbit per "
                  f"1000 t.u.; {int((got[th].values[ok] > 4).sum())} of {int(ok.sum())} with <Y> > 4", flush=True)
        ref = got[args.threads[0]]
        ident = all(np.array_equal(m.values, ref.values, equal_nan=True) for m in got.values())
        same = same and ident
        maps[jac] = ref.values
        print(f"{jac}: maps bit-identical across thread counts {args.threads}: {ident}")
    if len(maps) == 2:
        a, b = maps["symbolic"], maps["forward"]
        ok = np.isfinite(a)
        a, b = a[ok], b[ok]
        d = np.abs(a - b) / np.spacing(a)
        for name, sel in (("<Y> < 3", a < 3), ("3 <= <Y> < 8", (a >= 3) & (a < 8)), ("<Y> >= 8", a >= 8)):
            if sel.any():
                print(f"forward vs symbolic, {name} ({int(sel.sum())} points): |d<Y>| median {np.median(d[sel]):.3g} "
                      f"eps, max {d[sel].max():.3g} eps (relative {np.max(np.abs(a - b)[sel] / a[sel]):.2g})")
        print(f"points that change class (<Y> > 4): {int(np.sum((a > 4) != (b > 4)))} of {a.size}")
        r = np.median(per_orbit["symbolic"]) / np.median(per_orbit["forward"])
        print(f"CPU per orbit, symbolic / forward: {r:.2f}")
    for jac, v in per_orbit.items():
        est = c_roots * 1e4 + min(v) * args.T / 1000.0 * ADMISSIBLE_100 / cores  # the root search is serial
        print(f"extrapolated 100 x 100 at T = {args.T:g}, {jac}, {cores} otherwise idle cores: {est / 60:.1f} min "
              f"(root search {c_roots * 1e4:.0f} CPU s + {ADMISSIBLE_100} orbits x {min(v):.4f} CPU-s / {cores})")

    if args.full:
        c0, w0 = time.process_time(), time.perf_counter()
        load0 = os.getloadavg()[0]
        jac = args.jacobian[0]
        m = tb.megno_map(FIG4_BALL, FIG4B_LEVELS, l=0.0, r1=(-5.5, 7.0, 100), r2=(-8.0, 8.0, 100), t_end=args.T,
                         workers=cores, options=tb.MegnoMapOptions(compact_mode=False, jacobian=jac))
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        ok = np.isfinite(m.values)
        print(f"100 x 100 map, T = {args.T:g}, {jac}, {cores} threads: {wall:.1f} s wall ({wall / 60:.2f} min), "
              f"{cpu:.1f} s CPU, {int(ok.sum())} admissible, {int((m.values[ok] > 4).sum())} with <Y> > 4; "
              f"load average {load0:.1f} at the start, {os.getloadavg()[0]:.1f} at the end", flush=True)
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
