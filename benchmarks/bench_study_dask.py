"""The per-task overhead of the study runner's ``backend = "dask"`` (one scalar orbit per
task), for the scaling law of N workers on a cluster.

A LocalCluster of ``--workers`` single-threaded worker processes runs a study of ``n``
orbits of ``studies/h2.toml``'s level with a tiny integration (``t_end = checkpoint_every =
--t-end``, one chunk, default 1 time unit), for ``n = --tasks`` and ``2 * --tasks`` orbits,
into fresh stores, after a warm-up run (imports and compiled integrators in every worker).
The marginal cost of ``--tasks`` more tasks, minus their integration (the same study run
with ``backend = "serial"`` in this process), is the overhead per task: wall seconds (the
cluster's), and CPU seconds of the workers (``time.process_time`` on each worker through
``client.run``) and of this process (the scheduler runs in it).

Run: ``python benchmarks/bench_study_dask.py [--tasks 32] [--workers 2] [--rounds 3]``.
The machine is shared: give the load average with the figures (printed).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_lanes import study  # noqa: E402


def worker_cpu(client):
    return sum(client.run(time.process_time).values())


def timed(fn):
    w0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w0, time.process_time() - c0


def main():
    import taylorball as tb
    from distributed import Client, LocalCluster

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tasks", type=int, default=32)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--t-end", type=float, default=1.0)
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench_dask_"))
    T, n = args.t_end, args.tasks
    print(f"load average at start: {os.getloadavg()}; {args.workers} workers, tasks {n} and {2 * n}, t_end {T:g}")
    with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=None) as cl, \
            Client(cl) as client:
        cfgs = {k: study(work, f"d{k}", t_end=T, ce=T, n=k, backend="serial", observables={}) for k in (n, 2 * n)}
        tb.run_study(study(work, "warm", t_end=T, ce=T, n=2 * args.workers, backend="serial", observables={}),
                     client=client, restart=True, backend="dask")
        rows = []
        for _ in range(args.rounds):
            got = {}
            for k, cfg in cfgs.items():
                c0 = worker_cpu(client)
                wall, cpu_here = timed(lambda: tb.run_study(cfg, client=client, restart=True, backend="dask"))
                got[k] = (wall, cpu_here, worker_cpu(client) - c0)
            serial = study(work, "serial", t_end=T, ce=T, n=n, backend="serial", observables={})
            integ = timed(lambda: tb.run_study(serial, restart=True))[1]  # n orbits' integration and commits
            d = [(got[2 * n][j] - got[n][j]) for j in range(3)]
            rows.append((d[0] / n, d[1] / n, d[2] / n, integ / n))
    print("per task (marginal over", n, "tasks): wall s x workers, scheduler-side cpu s, worker cpu s; "
          "serial cpu s of the same orbit (store and commit included)")
    for r in rows:
        print(f"  wall {r[0] * args.workers:.4f}  scheduler cpu {r[1]:.4f}  worker cpu {r[2]:.4f}  serial {r[3]:.4f}")
    med = [statistics.median(r[j] for r in rows) for j in range(4)]
    print(f"median: wall x workers {med[0] * args.workers:.4f} s, scheduler cpu {med[1]:.4f} s, worker cpu "
          f"{med[2]:.4f} s, serial {med[3]:.4f} s per task; overhead per task (worker cpu - serial) "
          f"{med[2] - med[3]:.4f} s; load average {os.getloadavg()}")


if __name__ == "__main__":
    main()
