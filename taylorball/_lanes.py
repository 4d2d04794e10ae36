"""The lane pool of :func:`taylorball.ensemble.run_many` (``backend="lanes"``): jobs
refilled into the SIMD lanes of heyoka batch integrators, one per worker thread (the
design in :mod:`taylorball.ensemble`'s docstring), and the thread functions with waiting
that survives Ctrl-C, which the ``"threads"`` backend shares. Public names
(:class:`LaneLoad`, :class:`LaneChunk`, :class:`LaneTask`) are documented and imported
from :mod:`taylorball.ensemble`.
"""

from __future__ import annotations

import copy
import os
import threading
from dataclasses import dataclass, field
from typing import Any, Callable, List, Optional, Sequence, Tuple

import numpy as np

from .errors import UsageError

__all__ = ["LaneLoad", "LaneChunk", "LaneTask"]


# ---------------------------------------------------------------------------------------
# Threads, with waiting that survives Ctrl-C.
# ---------------------------------------------------------------------------------------
def _on_threads(n_threads, worker, stop):
    """Run ``worker()`` on ``n_threads`` threads and wait for them on events (never an
    interrupted ``Thread.join``, see the module docstring). Ctrl-C sets ``stop`` (workers
    leave at their next chunk), waits for every worker to leave and re-raises. An exception
    escaping a worker stops the others and is re-raised."""
    errors = []
    finished = [threading.Event() for _ in range(n_threads)]

    def guarded(k):
        try:
            worker()
        except BaseException as e:  # re-raised in the caller's thread
            errors.append(e)
            stop.set()
        finally:
            finished[k].set()

    ts = [threading.Thread(target=guarded, args=(k,), name=f"taylorball-ensemble-{k}")
          for k in range(n_threads)]
    try:
        _start_all(ts)
        for ev in finished:
            while not ev.wait(0.2):
                pass
    except KeyboardInterrupt:
        stop.set()  # every worker leaves at its next chunk boundary
        for ev in finished:
            while not ev.is_set():
                try:
                    ev.wait(0.2)
                except KeyboardInterrupt:  # heyoka may raise the interrupt once more
                    pass
        raise
    for t in ts:
        t.join()  # the workers have ended: nothing left to interrupt
    if errors:
        raise errors[0]


def _start_all(threads):
    """Start every thread; a Ctrl-C that arrives meanwhile is held back until all have
    started and then raised (:func:`taylorball._signals.held_signals`), so that the caller's
    handler (which sets ``stop`` and waits for every worker) never misses a thread that was
    already running: a worker started just before an interrupt would otherwise run on
    unstopped and keep the process alive."""
    import signal

    from ._signals import held_signals

    with held_signals((signal.SIGINT,)):
        for t in threads:
            t.start()


# ---------------------------------------------------------------------------------------
# The lane pool.
# ---------------------------------------------------------------------------------------
@dataclass
class LaneLoad:
    """What a job puts in its lane: the state column, the parameter column, its start time
    ``t0``, end time ``t_end`` and chunk length (the task sees the lane after every chunk),
    and optionally ``samples``: strictly increasing times in ``(t0, t_end]`` at which the
    task wants the lane's state (handed over in :attr:`LaneChunk.samples`).

    For a job resumed from a checkpoint (a long run's orbit): ``t0_lo`` is the low part of
    its double-length start time (heyoka's ``dtime``), ``ends(k)`` the end of the job's
    ``k``-th chunk (``k = 0, 1, ...`` from the load; default ``t0 + (k + 1) chunk``, capped
    at ``t_end``), so that chunk ends are the same numbers whatever chunk a run resumed
    at, and ``chunk_samples(k)`` the sample times of chunk ``k`` (strictly increasing, in
    its ``(start, end]``; instead of ``samples``, so that a job of millions of chunks never
    holds all its sample times)."""

    state: np.ndarray
    pars: np.ndarray
    t0: float
    t_end: float
    chunk: float
    samples: Optional[np.ndarray] = None
    t0_lo: float = 0.0
    ends: Optional[Callable[[int], float]] = None
    chunk_samples: Optional[Callable[[int], np.ndarray]] = None


@dataclass
class LaneChunk:
    """One lane at the end of a chunk: the lane, its job, the lane's time ``t``, the steps
    taken in this chunk, and whether ``t`` is the job's ``t_end``; ``sample_t`` are the
    job's sample times that fell in this chunk and the rows of ``sample_x`` (shape
    ``(n, dim)``, a copy) the lane's states there (read off the chunk's continuous output,
    at ``t_i = t`` the state itself); :attr:`samples` gives them as pairs."""

    lane: int
    job: int
    t: float
    steps: int
    last: bool
    sample_t: np.ndarray = field(default_factory=lambda: np.empty(0))
    sample_x: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))

    @property
    def samples(self) -> List[Tuple[float, np.ndarray]]:
        """The samples as ``(t_i, state column)`` pairs (``sample_t``, rows of ``sample_x``)."""
        return [(float(t), self.sample_x[r].copy()) for r, t in enumerate(self.sample_t)]


@dataclass
class LaneTask:
    """Jobs ``range(n_jobs)`` for ``run_many(task, backend="lanes")``, run through the lanes
    of copies of the batch integrator ``template`` (one copy per thread).

    ``load(j)`` returns the job's :class:`LaneLoad`. After every ``propagate_until``,
    ``after_chunk(ta, chunks)`` sees the lanes that advanced (one :class:`LaneChunk` each)
    and returns, per chunk, whether that job is done (it also is at ``last``). A lane whose
    integration ends otherwise than at its target calls ``failed(j, outcome, t)`` and is
    freed. ``fraction(chunk)``, optional, says how much of ``chunk.job`` is done after that
    chunk (cumulative; default: the fraction of its time span ``t0 .. t_end``); the rest is
    counted when the job ends. ``on_done(j)`` is called once per finished or failed job.
    The callbacks of one job are always called from one thread (``on_done`` and
    ``fraction`` from the worker threads too); jobs must not share mutable state. After
    the run, ``result(j)`` (default ``None``) gives job ``j``'s entry of the returned list,
    in the caller's thread, in job order; an exception there is job ``j``'s failure
    (``on_error``). ``on_reset(ta, lane)``, optional, is called when what the lane's event
    callbacks recorded since its chunk's start is void: its job ended (done or failed;
    before the lane is refilled) or, with ``grid``, its chunk is run again.

    ``grid=True``: every chunk is one ``propagate_grid`` on the chunk's sample times (each
    job's ``LaneLoad.chunk_samples(k)``, the chunk's end last, the same number of times in
    every chunk of every job), as a scalar run's ``propagate_grid``, instead of
    ``propagate_until`` with the continuous output (which holds every step's Taylor
    coefficients: measured 6x the integration's cost, and ~10 kB per step of a 9-variable
    float64 system). ``LaneChunk.sample_t`` is then the whole grid, the chunk's start
    first, ``sample_x`` the states there (at the start the state itself). An idle lane
    gets a grid of tiny steps forward from its own time on its spare state (a grid must
    increase strictly). A lane stopped short by another lane's failure is put back to its
    chunk's start (``on_reset``) and runs the chunk again: the same steps."""

    template: Any
    n_jobs: int
    load: Callable[[int], LaneLoad]
    after_chunk: Callable[[Any, List[LaneChunk]], Sequence[bool]]
    failed: Callable[[int, Any, float], None]
    fraction: Optional[Callable[[LaneChunk], float]] = None
    on_done: Optional[Callable[[int], None]] = None
    result: Optional[Callable[[int], Any]] = None
    on_reset: Optional[Callable[[Any, int], None]] = None
    grid: bool = False


#: Sample times evaluated on a batch continuous output per call (rows of ``(times, state, lanes)``).
_SAMPLE_BLOCK = 1024


def _read_samples(ta, c_out, reads, hi, target, got):
    """Append ``(times, states)`` to ``got[lane]`` for the sample times ``reads[lane]`` of
    this call (``states`` of shape ``(n, dim)``): at the lane's target the state itself (as
    a scalar run's end of chunk), elsewhere heyoka's batch continuous output, evaluated for
    all lanes at once (a lane without a time there is evaluated at its own time, and that
    value dropped)."""
    dim = ta.state.shape[0]
    m = max(len(ts) for ts in reads.values())
    own = np.where(np.isfinite(hi), hi, target)  # a failed lane's time is NaN
    out = {lane: np.empty((len(ts), dim)) for lane, ts in reads.items()}
    for start in range(0, m, _SAMPLE_BLOCK):
        rows = min(_SAMPLE_BLOCK, m - start)
        times = np.tile(own, (rows, 1))
        for lane, ts in reads.items():
            part = ts[start : start + rows]
            times[: len(part), lane] = part
        vals = c_out(times)  # (rows, dim, size)
        for lane, ts in reads.items():
            n = len(ts[start : start + rows])
            if n:
                out[lane][start : start + n] = vals[:n, :, lane]
    for lane, ts in reads.items():
        ts = np.asarray(ts, dtype=float)
        at_end = (ts == target[lane]) & (hi[lane] == target[lane])
        if at_end.any():
            out[lane][at_end] = ta.state[:, lane]
        got[lane].append((ts, out[lane]))


def _lane_grid(job, wanted, hi, target) -> np.ndarray:
    """The grid of one ``propagate_grid`` of the lane pool (``LaneTask.grid``): per lane
    with a job its time, then its chunk's sample times (the chunk's end last); an idle
    lane's grid steps forward from its time by 64 ulp (at least 1e-9) per point."""
    n = next(wanted[lane].size for lane in range(len(job)) if job[lane] is not None)
    G = np.empty((n + 1, len(job)))
    for lane in range(len(job)):
        if job[lane] is None:
            G[:, lane] = hi[lane] + np.arange(n + 1) * max(1e-9, 64 * float(np.spacing(abs(hi[lane]))))
            continue
        w = wanted[lane]
        if w.size != n or w[-1] != target[lane] or not w[0] > hi[lane]:
            raise UsageError(f"LaneTask(grid=True): job {job[lane]}'s chunk_samples must be {n} times in "
                             f"({float(hi[lane])!r}, {float(target[lane])!r}], the chunk's end last; got {w.size} "
                             f"times from {float(w[0]) if w.size else None!r} to {float(w[-1]) if w.size else None!r}")
        G[0, lane] = hi[lane]
        G[1:, lane] = w
    return G


class _TimeViews:
    """heyoka's ``dtime`` of one batch integrator (views of its own time, kept current by
    every step and by ``set_dtime`` / ``set_time``), lent to those of its event callbacks
    that read it per crossing (a ``time_views`` attribute; reading ``ta.dtime`` afresh
    adds ~1 microsecond to a 2-3 microsecond callback) for as long as one worker of the
    lane pool uses the integrator. The views hold the integrator, and a callback belongs
    to it (heyoka deep-copies callbacks with the integrator): a cycle through heyoka's C++
    side that Python's collector cannot see, so :meth:`release` drops them when the worker
    is done with its integrator, whatever ends it. A callback without lent views reads
    ``ta.dtime`` afresh at each crossing (the same numbers)."""

    __slots__ = ("takers",)

    def __init__(self, ta: Any) -> None:
        events = ta.nt_events if ta.with_events else ()  # nt_events raises without events
        self.takers = [ev.callback for ev in events if hasattr(ev.callback, "time_views")]
        if self.takers:
            views = ta.dtime
            for cb in self.takers:
                cb.time_views = views

    def release(self) -> None:
        """Drop the lent views (so the integrator can be freed)."""
        for cb in self.takers:
            cb.time_views = None
        self.takers = []


def _run_lanes(task, run, workers):
    """The lane pool (module docstring): every job on its own clock through its own chunk
    boundaries, idle lanes stepping by zero on a finite spare state."""
    import heyoka as hy

    n_jobs = int(task.n_jobs)
    if n_jobs <= 0:
        return
    template = task.template
    size = int(template.batch_size)
    n_threads = max(1, min(workers or os.cpu_count() or 1, -(-n_jobs // size)))
    lock = threading.Lock()
    queue = iter(range(n_jobs))
    stop = run.stop  # set on KeyboardInterrupt: workers leave at their next chunk
    progress = run.progress

    def next_job():
        with lock:
            return next(queue, None)

    def job_done(j):
        progress.reach(j, 1.0)
        if task.on_done is not None:
            task.on_done(j)

    def worker():
        ta = copy.copy(template)
        views = _TimeViews(ta)  # owned by this worker, with its integrator
        try:
            work(ta)
        finally:
            views.release()

    def work(ta):
        job = [None] * size
        target = np.zeros(size)
        steps_short = np.zeros(size, dtype=np.int64)  # steps of calls that stopped short
        plan = [None] * size  # (t0, t_end, chunk, k)
        loads: List[Optional[LaneLoad]] = [None] * size
        wanted = [None] * size  # the job's sample times, the next one's index, samples read so far
        k_sample = [0] * size
        got: List[list] = [[] for _ in range(size)]
        hi, lo = (np.array(v, dtype=float) for v in ta.dtime)
        spare = []  # a finite state, its parameters and start time for idle lanes (a failed
        # lane's state and time are NaN; a lane never loaded has the template's zero parameters;
        # a time-dependent field may be singular at t = 0, e.g. MEGNO's 2 y / t)

        def fill(lane):
            j = next_job()
            job[lane] = j
            if j is None:
                plan[lane] = None
                if spare:
                    ta.state[:, lane], ta.pars[:, lane], hi[lane] = spare[0]
                    lo[lane] = 0.0
                return
            steps_short[lane] = 0
            ld = task.load(j)
            loads[lane] = ld
            if not spare:
                spare.append((np.array(ld.state, copy=True), np.array(ld.pars, copy=True), float(ld.t0)))
            ta.state[:, lane] = ld.state
            ta.pars[:, lane] = ld.pars
            hi[lane], lo[lane] = float(ld.t0), float(ld.t0_lo)
            plan[lane] = [float(ld.t0), float(ld.t_end), float(ld.chunk), 0]
            k_sample[lane], got[lane] = 0, []
            set_wanted(lane)

        def set_wanted(lane):
            """The sample times of the lane's job (its current chunk's, with chunk_samples)."""
            ld = loads[lane]
            if ld.chunk_samples is not None:
                k_sample[lane] = 0
                wanted[lane] = np.asarray(ld.chunk_samples(plan[lane][3]), dtype=float).reshape(-1)
            elif plan[lane][3] == 0:
                wanted[lane] = None if ld.samples is None else np.asarray(ld.samples, dtype=float).reshape(-1)

        def chunk_end(lane):
            t0, t_end, chunk, k = plan[lane]
            ends = loads[lane].ends
            return float(ends(k)) if ends is not None else min(t0 + (k + 1) * chunk, t_end)

        for lane in range(size):
            fill(lane)
        ta.set_dtime(hi, lo)
        while any(j is not None for j in job):
            if run.stopping():
                return
            hi, lo = (np.array(v, dtype=float) for v in ta.dtime)
            for lane in range(size):
                if job[lane] is None:
                    target[lane] = hi[lane]  # idle: a zero-length step leaves the lane as is
                else:
                    target[lane] = chunk_end(lane)
            if task.grid:
                saved = (np.array(ta.state, copy=True), hi.copy(), lo.copy())
                G = _lane_grid(job, wanted, hi, target)
                grid_x = ta.propagate_grid(G)[-1]  # (points, dim, size)
                c_output = False
            else:
                c_output = any(job[lane] is not None and wanted[lane] is not None
                               and k_sample[lane] < wanted[lane].size and wanted[lane][k_sample[lane]] <= target[lane]
                               for lane in range(size))
                c_out = ta.propagate_until(target, c_output=c_output)[0]
            res = ta.propagate_res
            hi, lo = (np.array(v, dtype=float) for v in ta.dtime)
            chunks, freed, redo = [], [], []
            reads = {}  # lane -> sample times reached in this call
            for lane in range(size):
                j = job[lane]
                if j is None or not c_output:
                    continue
                outcome = res[lane][0]
                done_chunk = outcome == hy.taylor_outcome.time_limit
                short = outcome == hy.taylor_outcome.success and np.isfinite(hi[lane])
                if c_output and wanted[lane] is not None and (done_chunk or short):
                    reached = target[lane] if done_chunk else hi[lane]
                    k0 = k_sample[lane]
                    k_sample[lane] = int(np.searchsorted(wanted[lane], reached, side="right"))
                    if k_sample[lane] > k0:
                        reads[lane] = wanted[lane][k0 : k_sample[lane]]
            if reads:
                _read_samples(ta, c_out, reads, hi, target, got)
            for lane in range(size):
                j = job[lane]
                if j is None:
                    continue
                outcome = res[lane][0]
                if outcome == hy.taylor_outcome.time_limit:
                    plan[lane][3] += 1
                    last = bool(target[lane] >= plan[lane][1])
                    c = LaneChunk(lane, j, float(target[lane]), int(res[lane][3] + steps_short[lane]), last)
                    if task.grid:
                        c.sample_t = np.array(G[:, lane], copy=True)
                        c.sample_x = np.array(grid_x[:, :, lane], copy=True)
                    elif got[lane]:
                        c.sample_t = np.concatenate([b[0] for b in got[lane]])
                        c.sample_x = np.concatenate([b[1] for b in got[lane]])
                    chunks.append(c)
                    got[lane] = []
                    steps_short[lane] = 0
                    if not last:
                        set_wanted(lane)
                elif outcome == hy.taylor_outcome.success and np.isfinite(hi[lane]):
                    # stopped short of its target because another lane failed: go on (on a
                    # grid: from the chunk's start again, the same steps)
                    steps_short[lane] += int(res[lane][3])
                    if task.grid:
                        redo.append(lane)
                else:
                    task.failed(j, outcome, float(hi[lane]))
                    freed.append(lane)
            done = task.after_chunk(ta, chunks) if chunks else []
            for c in chunks if progress.enabled else ():
                if task.fraction is not None:
                    progress.reach(c.job, task.fraction(c))
                else:
                    t0, t_end = plan[c.lane][0], plan[c.lane][1]
                    progress.reach(c.job, (c.t - t0) / (t_end - t0) if t_end > t0 else 1.0)
            for c, d in zip(chunks, done):
                if d or c.last:
                    freed.append(c.lane)
            for lane in redo:
                ta.state[:, lane] = saved[0][:, lane]
                hi[lane], lo[lane] = saved[1][lane], saved[2][lane]
                if task.on_reset is not None:
                    task.on_reset(ta, lane)
            if freed:
                for lane in freed:
                    job_done(job[lane])
                    if task.on_reset is not None:
                        task.on_reset(ta, lane)
                    fill(lane)
            if freed or redo:
                ta.set_dtime(hi, lo)

    if n_threads == 1:
        worker()
    else:
        _on_threads(n_threads, worker, stop)
    if run.stopping():  # the member this run is in is being stopped (run.result raises)
        return
    for j in range(n_jobs):
        if task.result is None:
            run.finished(j, None)
            continue
        try:
            r = task.result(j)
        except Exception as e:
            run.failed(j, e)
            if run.on_error == "raise":
                return
            continue
        run.finished(j, r)
