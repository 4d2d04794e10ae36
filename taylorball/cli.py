"""The ``taylorball`` command.

* ``taylorball reproduce [--full] [--only fig2,fig4] [--out DIR] [--jobs N]`` -- regenerate
  the paper's figures (quick by default) from the studies in :mod:`taylorball.figures`, ``N``
  figures at a time in worker processes (default: one per core);
* ``taylorball verify [--full] [--precision]`` -- check the paper's claims and print a
  table (exit status 1 if a check fails);
* ``taylorball demo [--t T]`` -- propagate the Fig. 5 ball and print its integrals;
* ``taylorball --version``. ``python -m taylorball`` is the same command.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

__all__ = ["main"]


def cmd_demo(args) -> int:
    """Propagate the Fig. 5 ball and print its integrals and their drift."""
    import taylorball as tb
    from taylorball.paper import FIG5_BALL, demo_reduced_state

    params = FIG5_BALL
    full0 = tb.reduced_to_full(params, demo_reduced_state())
    print(f"Fig. 5 ball: {params}")
    print(f"initial full state (omega, alpha, beta, gamma, x, y):\n  {np.array2string(full0, precision=6)}")
    i0 = tb.integrals("full", params, full0)
    scales = tb.integral_scales("full", params, full0)
    t_end = float(args.t)
    t0 = time.perf_counter()
    full1 = tb.propagate("full", params, full0, t_end)
    wall = time.perf_counter() - t0
    i1 = tb.integrals("full", params, full1, check=False)
    s1 = tb.integral_scales("full", params, full1, check=False)
    scales = {k: max(scales[k], s1[k]) for k in scales}  # the larger of the two ends
    geo = tb.geometric_integrals("full", params, full1)
    print(f"propagated to t = {t_end:g} in {wall:.2f} s (float64, tol = eps)")
    print(f"  {'integral':<12}{'t = 0':>24}{'t = end':>24}{'drift/scale':>14}")
    for k in i0:
        print(f"  {k:<12}{i0[k]:>24.16g}{i1[k]:>24.16g}{(i1[k] - i0[k]) / scales[k]:>14.2e}")
    worst = max(abs(geo[k] - (1.0 if k.endswith("2") else 0.0)) for k in geo)
    print(f"  frame orthonormality error at t = end: {worst:.2e}")
    print(f"  contact point at t = end: x = {full1[12]:.6f}, y = {full1[13]:.6f}")
    return 0


def cmd_reproduce(args) -> int:
    from .figures import runner

    names = runner.figure_studies()
    if args.only:
        wanted = [w.strip() for w in args.only.split(",") if w.strip()]
        unknown = [w for w in wanted if not any(n == w or n.startswith(w + "_") for n in names)]
        if unknown:
            print(f"--only: unknown figure(s) {unknown}; available: {names}", file=sys.stderr)
            return 2
        names = [n for n in names if any(n == w or n.startswith(w + "_") for w in wanted)]
    out = Path(args.out)
    jobs = min(args.jobs or os.cpu_count() or 1, len(names))
    if jobs < 1:
        print(f"--jobs must be a positive integer, got {args.jobs!r}", file=sys.stderr)
        return 2
    print(f"regenerating {len(names)} figure(s) ({'full' if args.full else 'quick'}) into {out.resolve()}"
          + (f", {jobs} at a time" if jobs > 1 else ""))
    t0 = time.perf_counter()
    if jobs == 1:
        for name in names:
            runner.run(runner.load_study(name), full=args.full, outdir=out, plot_only=args.plot_only)
        print(f"done in {time.perf_counter() - t0:.1f} s")
        return 0
    # one process per figure at a time (spawned: heyoka and threads do not survive a fork);
    # progress bars off in the workers (they would interleave), a line per finished figure
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed

    failed, finished = [], []
    ex = ProcessPoolExecutor(max_workers=jobs, mp_context=mp.get_context("spawn"), initializer=_quiet_worker)
    try:
        futures = {ex.submit(_reproduce_one, name, args.full, str(out), args.plot_only): name for name in names}
        for f in as_completed(futures):
            name = futures[f]
            try:
                print(f.result(), flush=True)
                finished.append(name)
            except Exception as e:  # report, finish the other figures, exit 1
                failed.append(name)
                print(f"{name}: FAILED: {type(e).__name__}: {e}", file=sys.stderr, flush=True)
    except KeyboardInterrupt:
        # stop now: drop queued figures and end the workers (a figure's files are written
        # atomically, so the finished ones are complete and the others absent); a second
        # Ctrl-C (or the terminal's, which reaches the whole process group) must not cut
        # the cleanup short
        import signal

        signal.signal(signal.SIGINT, signal.SIG_IGN)
        ex.shutdown(wait=False, cancel_futures=True)
        for p in mp.active_children():
            p.terminate()
        ex.shutdown(wait=True)  # the workers are gone: this only releases the pool's resources
        print(f"interrupted after {time.perf_counter() - t0:.1f} s; finished: {', '.join(finished) or 'none'}",
              file=sys.stderr, flush=True)
        return 130
    ex.shutdown(wait=True)
    print(f"done in {time.perf_counter() - t0:.1f} s" + (f"; failed: {', '.join(failed)}" if failed else ""))
    return 1 if failed else 0


def _quiet_worker():
    os.environ["TQDM_DISABLE"] = "1"


def _reproduce_one(name, full, out, plot_only):
    """One figure in a worker process; returns its log line."""
    from .figures import runner

    lines = []
    runner.run(runner.load_study(name), full=full, outdir=Path(out), plot_only=plot_only, log=lines.append)
    return "\n".join(lines)


def cmd_verify(args) -> int:
    if args.precision:
        from .verify.precision import precision_main

        return precision_main(["--full"] if args.full else [])
    from .verify import cli_main

    argv = ["--full"] if args.full else []
    if args.only:
        argv += ["--only", args.only]
    if args.details:
        argv.append("--details")
    return cli_main(argv)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="taylorball", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    from ._version import __version__

    parser.add_argument("--version", action="version", version=f"taylorball {__version__}")
    sub = parser.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("reproduce", help="regenerate the paper's figures (quick by default)")
    p.add_argument("--full", action="store_true", help="publication density (slow)")
    p.add_argument("--only", default="", help="comma-separated figures, e.g. fig2,fig4")
    p.add_argument("--out", default="output", help="output folder (default ./output)")
    p.add_argument("--plot-only", action="store_true", help="re-plot saved data without computing")
    p.add_argument("--jobs", type=int, default=0,
                   help="figures computed at once, each in its own process (default: the number of cores)")
    p.set_defaults(func=cmd_reproduce)
    p = sub.add_parser("verify", help="check the paper's claims; table of verdicts")
    p.add_argument("--full", action="store_true", help="more samples, longer runs")
    p.add_argument("--precision", action="store_true", help="precision study across number types")
    p.add_argument("--only", default="", help="comma-separated topics: formulas, closed_forms, measures, charts, sections")
    p.add_argument("--details", action="store_true", help="print how each residual was measured")
    p.set_defaults(func=cmd_verify)
    p = sub.add_parser("demo", help="propagate the Fig. 5 ball and print its integrals and drift")
    p.add_argument("--t", default=1000.0, type=float, help="final time (default 1000)")
    p.set_defaults(func=cmd_demo)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
