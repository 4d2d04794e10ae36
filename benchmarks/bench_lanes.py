"""Throughput of the study runner's ``backend = "lanes"`` against raw heyoka batch mode
("orbit-time-units per second per core against raw heyoka batch-mode on the same
system, target at least 90 %, and the scaling from 1 to 2 workers").

The study: ``studies/h2.toml``'s ball and level (Fig. 4a: G = 10, H = 2, h = 5), ``--orbits``
(8: one batch of 8 lanes with AVX-512, two of 4 with AVX2) orbits drawn with seed 1, float64 at
the default tolerance, to ``--t-end``.

Each ``checkpoint_every`` ``ce`` runs to ``min(--t-end, --chunks * ce)`` (default 40 chunks,
at most 200 000 time units: 4 chunks at 50 000), so that the fixed costs of a run (the
store's creation, the start-up check, the final status) weigh little.

* **raw**: ``hy.taylor_adaptive_batch`` of the same system (``tb.problem(...)``'s
  equations, parameters and tolerance), compiled before the clock, one per
  ``batch_size()`` orbits with their internal initial states in its lanes, ``propagate_until``
  over the same chunk ends
  ``k * checkpoint_every`` (one call per chunk, all lanes); a copy of the compiled
  integrator per round.
* **lanes**: ``tb.run_study(cfg, restart=True, workers=1)`` with ``backend = "lanes"`` into
  a fresh store each round (the store's creation, the start-up check, the observables and
  every commit included; the batch integrator compiled before the clock by a warm-up run).

For (a) no observable (``off``), (b) the default observables (``default``: drift, lifted
angle and heading every 50, extremes of |R|), (c) the same with the lifted angle counted
on the sample grid without its event (``samples``: ``angles_method = "samples"``), (d) the
cluster files' observables (``cluster``, ``studies/diffusion_h2_1e8.toml``: the defaults,
sections every 30th crossing, the |R| histogram), (e) those with ``"samples"``
(``cl-samp``), (f) those with the section's crossings found on the sample grid's
interpolant without the section's event (``cl-sec``: ``sections_method = "samples"``) and
(g) with both (``cl-both``), at each ``--checkpoint-every``; raw and lanes alternate
within each round; CPU time (all threads, and worker processes once ended) and wall time;
the ratio raw/lanes of CPU time is the runner's share of raw batch throughput per core (1 =
as fast as raw); ``grid ratio`` is the same against raw ``propagate_grid`` on the study's
sample grid (what the runner integrates, for its observables' samples).

Then, on the default observables at ``checkpoint_every = 5000`` to ``--other-t-end``
(default 50 000):

* the runner's scaling from 1 to 2 workers on ``2 * --orbits`` orbits (2 workers: two
  worker processes, each its share in its own lanes): wall and CPU time, orbit-time-units
  per wall second, CPU seconds per orbit-time-unit, and whether the stores of 1 and 2
  workers are bit-identical;
* lanes against the threads backend (scalar integrators, one orbit per member) on the
  same 8-orbit study with 1 worker each: CPU time per orbit-time-unit.

Run: ``python benchmarks/bench_lanes.py [--t-end 200000] [--chunks 40]
[--checkpoint-every 500,5000,50000] [--rounds 3]
[--skip off,default,samples,cluster,cl-samp,cl-sec,cl-both,ratio,scaling,threads]``. The machine is shared: compare the ratios measured in the same run, and give
the load average with them (printed).
"""

from __future__ import annotations

import argparse
import copy
import os
import shutil
import statistics
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OFF = {"drift": False, "angles_every": 0.0, "extremes": False}
#: The cluster files' observables (studies/diffusion_h2_1e8.toml): drift, extremes, lifted
#: angle and heading every 50 (the defaults), sections every 30th crossing, |R| histogram.
CLUSTER = {"sections": 30, "histogram": {"bins": 200}}
#: The lifted angle without its event (counted on the sample grid's interpolant).
SAMPLES = {"angles_method": "samples"}
#: The section's crossings without its event (found on the sample grid's interpolant).
SEC_SAMPLES = {"sections_method": "samples"}


def study(work: Path, store: str, *, t_end, ce, n, backend, observables):
    from taylorball.study import StudyConfig

    d = tomllib.loads((ROOT / "studies" / "h2.toml").read_text())
    d["orbits"] = {"n": n, "seed": 1}
    d["run"] = {"t_end": t_end, "checkpoint_every": ce, "backend": backend}
    d["observables"] = dict(observables)
    d["output"] = {"store": store}
    return StudyConfig.from_dict(d, source=f"h2.toml ({store})", base=work)


def raw_template(cfg):
    """The raw batch integrators of the study's system, compiled (not timed): one per
    ``batch_size()`` orbits (the last batch filled up with the first orbits' states)."""
    import heyoka as hy

    from taylorball._propagate import start_state
    from taylorball.sections import batch_size

    prob = cfg.problem()
    size = batch_size()
    states = [start_state(prob, x) for x in cfg.initial_states]
    kw = {} if prob.tol is None else {"tol": float(prob.tol)}
    out = []
    for b in range(0, len(states), size):
        cols = (states[b:b + size] + states)[:size]
        out.append(hy.taylor_adaptive_batch(prob.system.equations(), np.stack(cols, axis=1),
                                            pars=np.repeat(np.asarray(prob.pars, float)[:, None], size, axis=1), **kw))
    return out


def raw_run(templates, cfg, grid=False):
    """Raw batch mode over the chunk ends (``propagate_until``), or with ``grid`` one
    ``propagate_grid`` per chunk on the study's sample grid (what the runner integrates),
    for every batch of orbits."""
    per, dt = cfg.samples_per_chunk, cfg.sample_dt
    ends = [float(np.int64((k + 1) * per) * dt) for k in range(cfg.n_chunks())]
    wall = cpu = 0.0
    for template in templates:
        ta = copy.copy(template)
        size = ta.batch_size
        w0, c0 = time.perf_counter(), time.process_time()
        for k, t in enumerate(ends):
            if grid:
                g = np.arange(k * per, (k + 1) * per + 1, dtype=np.int64) * dt
                ta.propagate_grid(np.repeat(g[:, None], size, axis=1))
            else:
                ta.propagate_until(t)
        wall, cpu = wall + time.perf_counter() - w0, cpu + time.process_time() - c0
    return wall, cpu


def store_digest(store):
    """sha256 of every orbit's committed records and checkpoint (wall-clock fields left out)."""
    import hashlib
    import sys

    sys.path.insert(0, str(ROOT))
    from tests.test_study import store_content

    h = hashlib.sha256()
    for i, (ck, arrays) in sorted(store_content(store).items()):
        h.update(repr(sorted(ck.items())).encode())
        for k in sorted(arrays):
            h.update(k.encode() + arrays[k][2])
    return h.hexdigest()


def _cpu():
    """CPU seconds of this process and of its ended children (worker processes)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def runner(cfg, workers=1):
    import taylorball as tb

    w0, c0 = time.perf_counter(), _cpu()
    tb.run_study(cfg, restart=True, workers=workers)
    return time.perf_counter() - w0, _cpu() - c0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--t-end", type=float, default=200000.0,
                    help="the longest run; a checkpoint_every ce runs to min(t_end, --chunks * ce)")
    ap.add_argument("--chunks", type=int, default=40)
    ap.add_argument("--other-t-end", type=float, default=50000.0,
                    help="t_end of the scaling and lanes-vs-threads runs (checkpoint_every 5000)")
    ap.add_argument("--checkpoint-every", default="500,5000,50000")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--orbits", type=int, default=8)
    ap.add_argument("--skip", default="", help="comma list of parts to skip: off,default,samples,cluster,cl-samp,cl-sec,cl-both "
                    "(rows), "
                    "ratio,scaling,threads")
    args = ap.parse_args()
    skip = set(filter(None, args.skip.split(",")))
    ces = [float(v) for v in args.checkpoint_every.split(",")]
    n, T = args.orbits, args.t_end
    work = Path(tempfile.mkdtemp(prefix="bench_lanes_"))
    print(f"load average at start: {os.getloadavg()}; t_end {T:g}, {n} orbits, rounds {args.rounds}")
    try:
        if "ratio" not in skip:
            print("\nlanes runner vs raw heyoka batch (CPU ratio = raw CPU / runner CPU; 1 = raw's throughput)")
            print(f"{'obs':>8} {'ckpt':>7} {'t_end':>8} {'raw cpu s':>10} {'run cpu s':>10} {'cpu ratio':>10} {'wall ratio':>10} "
                  f"{'raw t.u./cpu-s':>15} {'run t.u./cpu-s':>15} {'grid ratio':>10}  rounds")
            parts = [("off", OFF), ("default", {}), ("samples", SAMPLES), ("cluster", CLUSTER),
                     ("cl-samp", {**CLUSTER, **SAMPLES}), ("cl-sec", {**CLUSTER, **SEC_SAMPLES}),
                     ("cl-both", {**CLUSTER, **SAMPLES, **SEC_SAMPLES})]
            for label, obs in [p for p in parts if p[0] not in skip]:
                for ce in ces:
                    t_end = min(T, args.chunks * ce)
                    cfg = study(work, f"s_{label}_{ce:g}", t_end=t_end, ce=ce, n=n, backend="lanes", observables=obs)
                    template = raw_template(cfg)
                    short = study(work, f"w_{label}_{ce:g}", t_end=ce, ce=ce, n=n, backend="lanes", observables=obs)
                    runner(short)  # warm-up: compiles the lanes' integrator and its events
                    rr, cr, wr, gr = [], [], [], []
                    for _ in range(args.rounds):
                        raw = raw_run(template, cfg)
                        run = runner(cfg)
                        grid = raw_run(template, cfg, grid=True)
                        rr.append(raw)
                        cr.append(raw[1] / run[1])
                        wr.append(raw[0] / run[0])
                        gr.append(grid[1] / run[1])
                    raw_cpu = statistics.median(r[1] for r in rr)
                    tu = n * t_end
                    print(f"{label:>8} {ce:>7g} {t_end:>8g} {raw_cpu:>10.2f} {raw_cpu / statistics.median(cr):>10.2f} "
                          f"{statistics.median(cr):>10.3f} {statistics.median(wr):>10.3f} {tu / raw_cpu:>15.0f} "
                          f"{tu * statistics.median(cr) / raw_cpu:>15.0f} {statistics.median(gr):>10.3f}  "
                          f"{' '.join(f'{c:.3f}' for c in cr)}",
                          flush=True)
            print(f"load average: {os.getloadavg()}")
        ce, T = 5000.0, args.other_t_end
        if "scaling" not in skip:
            cfg = study(work, "scaling", t_end=T, ce=ce, n=2 * n, backend="lanes", observables={})
            runner(study(work, "w_scaling", t_end=ce, ce=ce, n=2 * n, backend="lanes", observables={}), workers=2)
            rows = {1: [], 2: []}
            digests = {1: set(), 2: set()}
            for _ in range(args.rounds):
                for w in (1, 2):
                    rows[w].append(runner(cfg, workers=w))
                    digests[w].add(store_digest(work / "scaling"))
            print(f"\nscaling, {2 * n} orbits, default observables, checkpoint_every {ce:g} (wall s, cpu s per round; "
                  "cpu: this process and its worker processes)")
            for w in (1, 2):
                wall = statistics.median(r[0] for r in rows[w])
                cpu = statistics.median(r[1] for r in rows[w])
                print(f"  workers {w}: wall {wall:.2f} s, cpu {cpu:.2f} s, {2 * n * T / wall:.0f} orbit-t.u. per wall-s, "
                      f"{cpu / (2 * n * T):.3g} cpu-s per orbit-t.u.  "
                      f"rounds {' '.join(f'{r[0]:.2f}/{r[1]:.2f}' for r in rows[w])}")
            speed = [a[0] / b[0] for a, b in zip(rows[1], rows[2])]
            print(f"  speed-up 1 -> 2 workers (wall, paired rounds): median {statistics.median(speed):.2f} "
                  f"({' '.join(f'{s:.2f}' for s in speed)}); load average {os.getloadavg()}")
            same = len(digests[1] | digests[2]) == 1
            print(f"  stores of 1 and 2 workers bit-identical (every committed record and checkpoint): {same}")
        if "threads" not in skip:
            lanes = study(work, "vs_lanes", t_end=T, ce=ce, n=n, backend="lanes", observables={})
            threads = study(work, "vs_threads", t_end=T, ce=ce, n=n, backend="threads", observables={})
            runner(study(work, "w_threads", t_end=ce, ce=ce, n=n, backend="threads", observables={}))
            ratio, cpu = [], {"lanes": [], "threads": []}
            for _ in range(args.rounds):
                a = runner(lanes)
                b = runner(threads)
                cpu["lanes"].append(a[1])
                cpu["threads"].append(b[1])
                ratio.append(b[1] / a[1])
            tu = n * T
            print(f"\nlanes vs threads (scalar) runner, {n} orbits, default observables, checkpoint_every {ce:g}, "
                  "1 worker each")
            for k in ("lanes", "threads"):
                c = statistics.median(cpu[k])
                print(f"  {k:>8}: cpu {c:.2f} s, {tu / c:.0f} orbit-t.u. per cpu-s")
            print(f"  threads cpu / lanes cpu: median {statistics.median(ratio):.2f} "
                  f"({' '.join(f'{r:.2f}' for r in ratio)}); load average {os.getloadavg()}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
