"""Running a study: :func:`run_study` (run, resume or extend every orbit, under the store's
lock, after the start-up check) and the scalar orbit job :func:`_run_orbit` (one scalar
heyoka integrator per orbit, a member of :func:`taylorball.ensemble.run_many`)."""

from __future__ import annotations

import contextlib
import copy
import json
import signal
import threading
import time
from pathlib import Path
from typing import Any, Dict, Iterator, Optional

import numpy as np

from ..ensemble import call, current, run_many
from ..errors import UsageError
from ..observables import events_key
from .._propagate import _check_outcome, integrator
from ..store import Lock, orbit_name, segment
from .config import StudyConfig, StudyLike, _as_config, _check_t_end, _real, _Where, _with_backend
from .job import _create_store, _layouts, _open_checked, _OrbitJob, study_store
from .lanes import _run_lanes
from .status import StudyStatus, study_status


def _run_orbit(cfg: StudyConfig, i: int, t_end: float) -> Optional[Dict[str, Any]]:
    """Run (or resume) orbit ``i`` to ``t_end``, chunk by chunk, committing each; returns
    its checkpoint. A member of :func:`taylorball.ensemble.run_many` (Ctrl-C and progress
    through :func:`taylorball.ensemble.current`)."""
    prob = cfg.problem()
    spec = prob.spec
    objs = cfg.observable_objects()
    job = _OrbitJob(cfg, i, t_end, prob, objs, _layouts(cfg, prob, objs))
    ctx = current()
    n_total = job.n_total
    try:
        k0 = job.open()
        ctx.advance(min(k0, n_total) / n_total)
        if k0 >= n_total:
            return job.ck
        ctx.check()  # a boundary too (chunk k0): a worker process told to end before the first chunk stops here
        evs = [o.events(prob) for o in objs]
        flat = [e for lst in evs for e in lst]
        if flat:
            key = ("observables",) + tuple(events_key(o) for o, lst in zip(objs, evs) if lst)
            template = integrator(prob, events_key=key, events=lambda: {"nt_events": list(flat)})
        else:
            template = integrator(prob)
        ta = copy.copy(template)
        ta.pars[:] = prob.pars
        x, dtime = job.start()
        ta.state[:] = x
        if dtime is not None:
            ta.dtime = dtime
        else:
            ta.time = spec.scalar(0.0)
        callbacks = [ev.callback for ev in ta.nt_events] if flat else []
        for k in range(k0, n_total):
            w0 = time.perf_counter()
            m, t = job.grid(k)
            res = ta.propagate_grid(spec.array(t))
            _check_outcome(ta, res, float(t[-1]))
            events, j = [], 0
            for lst in evs:
                own = {}
                for e in range(len(lst)):
                    cb = callbacks[j]
                    own[e] = list(zip(cb.times, cb.states))
                    cb.times.clear()
                    cb.states.clear()
                    j += 1
                events.append(own)
            job.commit(k, m, t, np.asarray(res[-1]), events, int(res[3]), ta.state, ta.dtime, w0)
            ctx.advance(1 / n_total)
            if k + 1 < n_total and ctx.stopping:
                job.orb.trim(job.layouts, job.ck)
            ctx.check()  # Ctrl-C stops here, the chunk committed
        return job.ck
    finally:
        job.close()




def _tidy_finished(cfg: StudyConfig, done: list, cks: list, t_end: float) -> None:
    """Cut the finished orbits ``done`` that a kill left longer than committed (a kill
    after an orbit's last commit and before the trim that ends its job) to their committed
    lengths, under each orbit's lock. The orbits left to run are tidied when their jobs
    open (:meth:`_OrbitJob.open`)."""
    if not done:
        return
    prob = cfg.problem()
    objs = cfg.observable_objects()
    layouts = _layouts(cfg, prob, objs)
    store = study_store(cfg)
    for i in done:
        if store.orbit(i).untidy(layouts, cks[i]):
            job = _OrbitJob(cfg, i, t_end, prob, objs, layouts)
            try:
                job.open()
            finally:
                job.close()


@contextlib.contextmanager
def _watched(cfg: StudyConfig, todo: list, t_end: float, progress: Any) -> Iterator[None]:
    """Progress of orbits run in other processes (worker processes, dask): a thread reads
    each orbit's committed chunks from its ``zarr.json`` every second and advances the bar
    (or the callable) ``progress`` in fractions of orbits, as the threads' members do. (The
    engine sees a process's member only when it ends: a lanes worker's share of the orbits
    runs for hours.)"""
    from ..ensemble import _Progress

    bar = _Progress(progress, len(todo))
    if not bar.enabled:
        yield
        return
    root, n_total = study_store(cfg).path, cfg.n_chunks(t_end)
    files = [root / orbit_name(i) / "zarr.json" for i in todo]

    def poll() -> None:
        for j, f in enumerate(files):
            try:
                ck = json.loads(f.read_text()).get("attributes", {}).get("checkpoint") or {}
                bar.reach(j, min(int(ck.get("chunks", 0)), n_total) / n_total)
            except (OSError, ValueError, TypeError, AttributeError):
                pass  # being replaced (zarr writes it atomically): the next poll reads it

    done = threading.Event()

    def watch() -> None:
        while not done.wait(1.0):
            poll()

    poll()
    thread = threading.Thread(target=watch, name="taylorball-study-progress", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        poll()
        bar.close()


def _lane_groups(todo: list, workers: Optional[int]) -> list:
    """The orbits of a lanes run split between ``workers`` worker processes (None: one
    per core; contiguous, sizes differing by at most one), or ``[]`` when one process does
    it: one worker, or no more orbits than one batch integrator's lanes."""
    import os

    from ..sections import batch_size

    n = min(int(workers or os.cpu_count() or 1), -(-len(todo) // batch_size()))
    if n < 2:
        return []
    return [list(map(int, g)) for g in np.array_split(np.asarray(todo, dtype=np.int64), n)]


def _run_lanes_group(cfg: StudyConfig, todo: list, t_end: float) -> None:
    """One worker process's share of a lanes run: its orbits in the lanes of one batch
    integrator, as :func:`_run_lanes` with one worker (each orbit's bits depend on the
    orbit alone, so the split changes none)."""
    current().check()  # a member that checks: SIGTERM stops its orbits at their next chunk boundary
    _run_lanes(cfg, todo, t_end, 1, False)


class Terminated(KeyboardInterrupt):
    """SIGTERM stopped :func:`run_study` (a batch scheduler's wall-time limit, ``kill``): as
    Ctrl-C, every orbit stopped at a chunk boundary (``backend = "processes"``: its worker
    processes were ended, the committed chunks kept) and a rerun resumes bit-identically.
    A ``KeyboardInterrupt``, so code that handles Ctrl-C handles it too; ``taylorball run``
    exits with status 143 (128 + SIGTERM) on it, 130 on Ctrl-C."""


@contextlib.contextmanager
def _sigterm_stops_the_run() -> Iterator[None]:
    """While a run is on, SIGTERM raises :class:`Terminated` in the main thread, which the
    engine handles as Ctrl-C. Only where SIGTERM has its default disposition (a caller's own
    handler, or SIG_IGN, is left alone) and in the main thread (Python runs handlers
    there); the previous disposition is restored after the run. A second SIGTERM while the
    run stops is ignored (kill -9 remains; the store is safe against it)."""
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        raise Terminated("SIGTERM: the run stopped at a chunk boundary; rerun to resume")

    signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def run_study(study: StudyLike, *, extend: Optional[float] = None, restart: bool = False,
              workers: Optional[int] = None, client: Any = None, progress: Any = False,
              backend: Optional[str] = None, force: bool = False) -> StudyStatus:
    """Run, resume or extend every orbit of a study into its store.

    Parameters
    ----------
    study : str, os.PathLike or StudyConfig
        The study file (TOML) or a loaded study.
    extend : float, optional
        Run every orbit to this end time instead of the file's ``t_end`` (a multiple of
        ``checkpoint_every``); bit-identical to a direct run to it. On an existing store it
        must be at least the store's current end (its ``t_end``: the end it was last run or
        extended to); ``extend`` equal to it resumes that end. A run without ``extend`` goes
        to the file's ``t_end`` or the store's, whichever is later: it resumes an interrupted
        extension and never lowers the store's ``t_end``.
    restart : bool
        Replace the store by a new one (atomically: the old store is deleted last).
    workers : int, optional
        Threads or processes (overrides ``[run] workers``).
    client : distributed.Client, optional
        For ``backend = "dask"``: use this client instead of connecting to ``[run]
        scheduler``.
    progress : bool, str or callable
        The engine's progress bar, advanced per chunk.
    backend : str, optional
        Overrides ``[run] backend``: ``"threads"``, ``"processes"``, ``"serial"``,
        ``"dask"`` (with ``[run] scheduler`` or ``client``) or ``"lanes"`` (float64 only:
        the orbits in the SIMD lanes of heyoka batch integrators; other bits than the
        scalar backends', so a store is resumed by the family that wrote it).
    force : bool
        Resume or extend a store written with another heyoka version, CPU model or SIMD
        width (refused otherwise); the mix is recorded in the store's ``segments``.

    Returns
    -------
    StudyStatus

    Raises
    ------
    UsageError
        A bad study file or argument (before any work).
    StoreError
        A store of another study, a corrupt orbit (named), or a store being written by
        another live process (named: host, pid), all found before any work.
    IntegrationError
        An orbit's integrator stopped; its committed chunks are kept.
    KeyboardInterrupt
        Ctrl-C; :class:`Terminated` (a ``KeyboardInterrupt``) on SIGTERM, caught while the
        run is on when SIGTERM has its default disposition and this is the main thread.
        Either way every orbit stopped at a chunk boundary (worker processes are ended) and
        a rerun resumes bit-identically.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import taylorball as tb
    >>> study = '''
    ... [ball]
    ... inertia = [2.0, 3.0, 4.0]
    ... mass = 1.0
    ... radius = 5.0
    ... plane_rate = 2.0
    ... [level]
    ... G = 10.0
    ... H = 2.0
    ... h = 5.0
    ... [orbits]
    ... n = 2
    ... [run]
    ... t_end = 20.0
    ... checkpoint_every = 10.0
    ... backend = "serial"
    ... [observables]
    ... angles_every = 10.0
    ... [output]
    ... store = "store"
    ... '''
    >>> with tempfile.TemporaryDirectory() as d:
    ...     f = pathlib.Path(d) / "study.toml"
    ...     _ = f.write_text(study)
    ...     status = tb.run_study(f)
    ...     ds = tb.open_run(pathlib.Path(d) / "store", observable="angles")
    ...     print(status.complete, dict(ds.sizes))
    True {'orbit': 2, 'time': 3}
    """
    cfg = _with_backend(_as_config(study), backend, client)
    if not isinstance(restart, bool):
        raise UsageError(f"restart must be True or False, got {restart!r}")
    if not isinstance(force, bool):
        raise UsageError(f"force must be True or False, got {force!r}")
    t_end = cfg.t_end
    if extend is not None:
        _real(_Where(cfg.source), {"extend": extend}, "run", "extend", lo=0.0, lo_open=True,
              form="an end time > 0 (--extend T)")
        _check_t_end(_Where(cfg.source), "--extend", extend, cfg.checkpoint_every)
        t_end = float(extend)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, (int, np.integer))
                                or not 1 <= workers <= 4096):
        raise UsageError(f"workers must be an integer in [1, 4096] (threads or processes), got {workers!r}")
    workers = cfg.workers if workers is None else int(workers)
    store = study_store(cfg)
    store.refuse_nested()  # not inside another store
    if store.path.exists() and not store.exists() and any(store.path.iterdir()):
        raise UsageError(f"{cfg.source}: [output] store {str(store.path)!r} is a folder that is not a taylorball "
                         "run store (no zarr.json); give an empty or new folder")
    store.path.parent.mkdir(parents=True, exist_ok=True)
    with _sigterm_stops_the_run(), \
            Lock(store.path.with_name(store.path.name + ".lock"), f"the store {store.path}"):
        store.clean_leftovers()
        created = restart or not store.exists()
        action = "restart" if restart else "create" if created else "resume"
        if restart:
            store.restart(lambda p: _create_store(cfg, p, t_end))
        elif not store.exists():
            if store.path.exists():
                store.path.rmdir()  # empty (checked above)
            store.restart(lambda p: _create_store(cfg, p, t_end))
        _, cks = _open_checked(cfg)  # the start-up check: before any work
        end = float(store.attrs().get("t_end", t_end))  # what the store was last run or extended to
        if extend is not None and not created and t_end < end:
            raise UsageError(f"{cfg.source}: --extend {extend!r}: is below the store's current end t_end = {end!r} "
                             f"({store.path}); give T > {end:g} to extend, or T = {end:g} (or no --extend) to resume "
                             f"to {end:g}")
        if extend is None and not created and end > t_end:
            t_end = end  # an interrupted extension: a plain rerun resumes it (the store's data go to `end`)
        todo = [i for i, ck in enumerate(cks) if (ck or {}).get("chunks", 0) < cfg.n_chunks(t_end)]
        for i in todo:  # every orbit's lock before any work
            store.orbit(i).lock().check()
        left = set(todo)
        _tidy_finished(cfg, [i for i in range(cfg.n_orbits) if i not in left], cks, t_end)
        if action == "resume" and t_end > end:
            action = "extend"
        done0 = sum(int((ck or {}).get("chunks", 0)) for ck in cks)
        seg = store.begin_segment(segment(action, t_end), work=bool(todo), force=force)  # provenance
        store.set_attrs(t_end=max(t_end, end))  # never below the store's data
        jobs = [call(_run_orbit, cfg, i, t_end) for i in todo]
        label = f"study {Path(cfg.source).stem}" if progress is True else progress
        try:
            if jobs and cfg.backend == "lanes" and _lane_groups(todo, workers):
                # worker processes, each its share of the orbits in its own lanes: the Python work
                # of the observables and commits holds the GIL, so threads share one core for it
                with _watched(cfg, todo, t_end, label):
                    run_many([call(_run_lanes_group, cfg, g, t_end) for g in _lane_groups(todo, workers)],
                             backend="processes", workers=workers)
            elif jobs and cfg.backend == "lanes":
                _run_lanes(cfg, todo, t_end, workers, label)
            elif jobs:
                mode: Any = cfg.backend  # one of BACKENDS, checked by StudyConfig
                if mode == "serial":  # in one worker thread, so that Ctrl-C and SIGTERM, which land in this
                    mode, workers = "threads", 1  # thread, stop the orbit at a chunk boundary (same bits)
                own_client = None
                if mode == "dask" and client is None:
                    from distributed import Client

                    own_client = client = Client(cfg.scheduler)
                try:
                    if mode in ("processes", "dask"):  # members report only when they end there
                        with _watched(cfg, todo, t_end, label):
                            run_many(jobs, backend=mode, workers=workers, client=client)
                    else:
                        run_many(jobs, backend=mode, workers=workers, client=client, progress=label)
                finally:
                    if own_client is not None:
                        own_client.close()
        finally:  # the segment's end and the chunks it added
            store.end_segment(seg, sum(int((store.orbit(i).checkpoint() or {}).get("chunks", 0))
                                       for i in range(cfg.n_orbits)) - done0)
    return study_status(cfg)
