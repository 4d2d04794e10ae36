"""The long-run store: zarr v3 (taylorball.store) vs HDF5 (h5py) vs npz chunk files, and
the runner's throughput vs a bare heyoka loop.

The issue-10 study (``studies/h2.toml``: Fig. 4a ball, level G = 10, H = 2, h = 5, 4 orbits
drawn with seed 1) is run by ``tb.run_study`` to ``--t-end`` with the default observables
(plus ``--observables`` keys and thinned samples every ``--samples-every``). Orbit 0's
records, chunk by chunk, are then replayed into three stores, each written the way a
crash-safe run has to write it (one commit per chunk):

* zarr: :class:`taylorball.store.OrbitStore` (resize, write the new region, commit the
  checkpoint attribute; digest chain);
* HDF5: one file, a resizable chunked dataset per array (gzip level 1), ``flush()`` per
  chunk (HDF5 has no atomic commit: a kill during a write can corrupt the file, the reason
  it is not used);
* npz: one ``chunk_<k>.npz`` per chunk written atomically (temporary file + rename), as
  the npz long runs of earlier versions did.

Printed: write time per chunk, read time of everything, size on disk, and the run's own
storage per 1e8 time units (the zarr chunk files extrapolated linearly, metadata and
checkpoint as they are). Then the throughput in paired rounds: a bare ``propagate_until``
loop over the same chunk ends on orbit 0, then ``run_study`` of a one-orbit study of the
same state into a fresh store (restart, start-up check, every commit included); process
CPU time and wall time, median of the per-round ratios.

Run: ``python benchmarks/bench_store.py [--t-end 20000] [--checkpoint-every 500] [--rounds 5]
[--observables 'sections = 30;extremes = false']``. The machine is shared: compare the
ratios, not the absolute times.
"""

from __future__ import annotations

import argparse
import io
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np


def du(path: Path) -> int:
    return sum(p.stat().st_size for p in Path(path).rglob("*") if p.is_file())


def study(work: Path, t_end, ce, samples_every, store, extra: str = "", states=None):
    """studies/h2.toml (the issue's example) with the run's parameters changed; ``extra``:
    more [observables] lines (``key = value`` separated by ``;``); ``states``: explicit
    initial states instead of the drawn orbits."""
    import tomllib

    from taylorball.study import StudyConfig

    d = tomllib.loads((Path(__file__).resolve().parents[1] / "studies" / "h2.toml").read_text())
    d["run"] = {"t_end": t_end, "checkpoint_every": ce, "backend": "serial"}
    d["observables"] = {"samples_every": samples_every, **tomllib.loads(extra.replace(";", "\n"))}
    d["output"] = {"store": store}
    if states is not None:
        d["orbits"] = {"states": states}
        del d["level"]
    return StudyConfig.from_dict(d, source=f"h2.toml ({store})", base=work)


def chunks_of(store: Path, layouts):
    """Per chunk: {obs: {var: records}} from orbit 0 of a finished store."""
    import zarr

    from taylorball.store import RunStore

    orb = RunStore(store).orbit(0)
    ck = orb.checkpoint()
    counts = zarr.open_array(str(orb.path / "_index"), mode="r")[: ck["chunks"], : len(layouts)]
    data = {o: {v: zarr.open_array(str(orb.path / o / v), mode="r")[: ck["lengths"][o]] for v in layouts[o]}
            for o in layouts}
    out, start = [], {o: 0 for o in layouts}
    for k in range(ck["chunks"]):
        rec = {}
        for j, o in enumerate(layouts):
            n = int(counts[k, j])
            rec[o] = {v: data[o][v][start[o]:start[o] + n] for v in layouts[o]}
            start[o] += n
        out.append(rec)
    return out


def write_zarr(folder: Path, fp, layouts, chunks, state):
    from taylorball.store import OrbitStore, RunStore, genesis

    RunStore(folder).create({"format": 1}, [{"fingerprint": fp, "index": 0, "initial_state": []}])
    orb = OrbitStore(folder, 0)
    orb.ensure_arrays(layouts)
    h, lengths = genesis(fp), {}
    t0 = time.perf_counter()
    for k, rec in enumerate(chunks):
        ck, h = orb.append(fp, k, layouts, rec, {"state": state, "lengths_before": lengths}, h)
        lengths = ck["lengths"]
    orb.trim(layouts, ck)
    return time.perf_counter() - t0


def read_zarr(folder: Path, layouts):
    import taylorball as tb

    t0 = time.perf_counter()
    ds = tb.open_run(folder)
    for v in ds.data_vars:
        ds[v].values
    return time.perf_counter() - t0


def write_h5(path: Path, layouts, chunks, state):
    import h5py

    t0 = time.perf_counter()
    with h5py.File(path, "w") as f:
        dsets = {}
        for o in layouts:
            for v, var in layouts[o].items():
                dsets[o, v] = f.create_dataset(f"{o}/{v}", shape=(0, *var.shape), maxshape=(None, *var.shape),
                                               chunks=(max(1, 65536 // max(1, int(np.prod(var.shape)))), *var.shape),
                                               dtype=var.dtype, compression="gzip", compression_opts=1)
        for rec in chunks:
            for (o, v), d in dsets.items():
                a = rec[o][v]
                if len(a):
                    n0 = d.shape[0]
                    d.resize(n0 + len(a), axis=0)
                    d[n0:] = a
            f.attrs["checkpoint"] = str(state)
            f.flush()
    return time.perf_counter() - t0


def read_h5(path: Path):
    import h5py

    t0 = time.perf_counter()
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: obj[()] if isinstance(obj, h5py.Dataset) else None)
    return time.perf_counter() - t0


def write_npz(folder: Path, chunks, state):
    from taylorball.io import atomic_write_bytes

    folder.mkdir(parents=True)
    t0 = time.perf_counter()
    for k, rec in enumerate(chunks):
        buf = io.BytesIO()
        np.savez_compressed(buf, **{f"{o}__{v}": a for o in rec for v, a in rec[o].items()})
        atomic_write_bytes(folder / f"chunk_{k:06d}.npz", buf.getvalue())
        atomic_write_bytes(folder / "checkpoint.json", str(state).encode())
    return time.perf_counter() - t0


def read_npz(folder: Path):
    t0 = time.perf_counter()
    parts = {}
    for p in sorted(folder.glob("chunk_*.npz")):
        with np.load(p) as z:
            for k in z.files:
                parts.setdefault(k, []).append(z[k])
    {k: np.concatenate(v) for k, v in parts.items()}
    return time.perf_counter() - t0


def bare_loop(cfg, t_end):
    """Wall time of a propagate_until loop over the chunk ends of the same orbit (the
    same compiled integrator without events, nothing recorded)."""
    import copy

    from taylorball._propagate import integrator, start_state

    prob = cfg.problem()
    ta = copy.copy(integrator(prob))
    ta.pars[:] = prob.pars
    ta.state[:] = start_state(prob, cfg.initial_states[0])
    ta.time = 0.0
    n = cfg.n_chunks(t_end)
    t0, c0 = time.perf_counter(), time.process_time()
    for k in range(n):
        ta.propagate_until((k + 1) * cfg.samples_per_chunk * cfg.sample_dt)
    return time.perf_counter() - t0, time.process_time() - c0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--t-end", type=float, default=20000.0)
    ap.add_argument("--checkpoint-every", type=float, default=500.0)
    ap.add_argument("--samples-every", type=float, default=0.0)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--observables", default="", help="extra [observables] keys, e.g. 'sections = 30;extremes = false'")
    args = ap.parse_args()
    import taylorball as tb
    from taylorball.study.job import _layouts

    work = Path(tempfile.mkdtemp(prefix="bench_store_"))
    try:
        cfg = study(work, args.t_end, args.checkpoint_every, args.samples_every, "run", args.observables)
        tb.run_study(cfg, extend=args.checkpoint_every)  # compile, draw the states (not timed)
        from taylorball.store import RunStore

        w0, c0 = time.perf_counter(), time.process_time()
        tb.run_study(cfg)  # all 4 orbits (serial)
        wall_run, cpu_run = time.perf_counter() - w0, time.process_time() - c0
        ck0 = RunStore(cfg.store).orbit(0).checkpoint()
        prob = cfg.problem()
        layouts = _layouts(cfg, prob, cfg.observable_objects())
        chunks = chunks_of(cfg.store, layouts)
        state = ck0["state"]
        print(f"orbit 0 to t = {args.t_end:g}, {len(chunks)} chunks of {args.checkpoint_every:g}, observables "
              f"{[o.name for o in cfg.observable_objects()]}")
        read_zarr(cfg.store, layouts)  # imports xarray and dask (not timed)
        t_zarr = write_zarr(work / "z", cfg.orbit_fingerprint(0), layouts, chunks, state)
        t_h5 = write_h5(work / "o.h5", layouts, chunks, state)
        t_npz = write_npz(work / "npz", chunks, state)
        r_zarr, r_h5, r_npz = read_zarr(work / "z", layouts), read_h5(work / "o.h5"), read_npz(work / "npz")
        s_zarr, s_h5, s_npz = du(work / "z"), (work / "o.h5").stat().st_size, du(work / "npz")
        scale = 1e8 / args.t_end
        print(f"{'store':<6}{'write ms/chunk':>16}{'read all (s)':>14}{'size (kB)':>11}{'MB per 1e8 t.u.':>17}")
        for name, w, r, s in (("zarr", t_zarr, r_zarr, s_zarr), ("hdf5", t_h5, r_h5, s_h5),
                              ("npz", t_npz, r_npz, s_npz)):
            print(f"{name:<6}{1e3 * w / len(chunks):>16.2f}{r:>14.3f}{s / 1e3:>11.1f}{s * scale / 1e6:>17.1f}")
        run_size = du(cfg.store / "orbit_0000")
        data = sum(p.stat().st_size for p in (cfg.store / "orbit_0000").rglob("*")
                   if p.is_file() and "c" in p.relative_to(cfg.store / "orbit_0000").parts[:-1])
        print(f"the run's own orbit_0000 group: {run_size / 1e3:.1f} kB, of which {data / 1e3:.1f} kB zarr chunk "
              f"files (they grow with t; the rest is metadata and the checkpoint) -> "
              f"{(data * scale + run_size - data) / 1e6:.1f} MB per 1e8 t.u.")
        # throughput: the runner (integration + observables, from the checkpoint's wall time,
        # and whole-run wall time including the store) vs a bare loop
        # throughput, paired: in each round the bare loop on orbit 0, then run_study of a
        # one-orbit study of the same state (fresh store); process CPU time and wall time
        one = study(work, args.t_end, args.checkpoint_every, args.samples_every, "one", args.observables,
                    states=[[float(v) for v in cfg.initial_states[0]]])
        ratios_cpu, ratios_wall = [], []
        for r in range(args.rounds):
            w_bare, c_bare = bare_loop(cfg, args.t_end)
            w0, c0 = time.perf_counter(), time.process_time()
            tb.run_study(one, restart=True)
            w_run, c_run = time.perf_counter() - w0, time.process_time() - c0
            ratios_cpu.append(c_bare / c_run)
            ratios_wall.append(w_bare / w_run)
            print(f"  round {r}: bare {args.t_end / w_bare:,.0f} t.u./s, run_study {args.t_end / w_run:,.0f} t.u./s "
                  f"(wall); CPU ratio {ratios_cpu[-1]:.2f}")
        import statistics

        print(f"throughput of run_study (incl. store writes, the start-up check and the restart) / bare "
              f"propagate_until loop, median of {args.rounds} paired rounds: CPU {statistics.median(ratios_cpu):.2f}, "
              f"wall {statistics.median(ratios_wall):.2f}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
