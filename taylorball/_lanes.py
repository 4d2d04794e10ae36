"""Many independent orbits through the SIMD lanes of heyoka batch integrators.

heyoka's batch mode integrates ``size`` orbits at once, one per SIMD lane, each lane with
its own time and step sizes (measured here: a lane's bits do not depend on its companions,
nor on when it was loaded). Running orbits in fixed groups of ``size`` wastes lanes: a
group lasts as long as its slowest orbit (section runs to ``n`` crossings differ several
times in length; MEGNO runs stop early on chaotic orbits). :func:`run_lanes` instead
refills a lane with the next orbit as soon as its orbit is done, and runs one batch
integrator per thread, all pulling from one queue of jobs.

Every job advances on its own clock through the chunk boundaries ``t0 + k chunk`` (the
last one ``t_end``), exactly as a run of that orbit alone would, so its result depends only
on its own initial state: it is bit-identical whatever the number of threads, the lane it
lands in and the jobs around it. A lane without a job is given its own time as target, a
step of length zero that leaves it untouched.
"""

from __future__ import annotations

import copy
import os
import threading
from dataclasses import dataclass
from typing import Callable, List, Optional, Sequence

import numpy as np

__all__ = ["LaneLoad", "run_lanes"]


@dataclass
class LaneLoad:
    """What a job puts in its lane: the state column, the parameter column, its start time
    ``t0``, end time ``t_end`` and chunk length (the task sees the lane after every chunk)."""

    state: np.ndarray
    pars: np.ndarray
    t0: float
    t_end: float
    chunk: float


@dataclass
class LaneChunk:
    """One lane at the end of a chunk: the lane, its job, the lane's time ``t``, the steps
    taken in this chunk, and whether ``t`` is the job's ``t_end``."""

    lane: int
    job: int
    t: float
    steps: int
    last: bool


def run_lanes(template, n_jobs: int, *, load: Callable[[int], LaneLoad],
              after_chunk: Callable[[object, List[LaneChunk]], Sequence[bool]],
              failed: Callable[[int, object, float], None], threads: Optional[int] = None,
              on_done: Optional[Callable[[int], None]] = None) -> None:
    """Run jobs ``0 .. n_jobs - 1`` through the lanes of copies of the batch integrator
    ``template``, one copy per thread.

    ``load(j)`` returns the job's :class:`LaneLoad`. After every ``propagate_until``,
    ``after_chunk(ta, chunks)`` sees the lanes that advanced (one :class:`LaneChunk`
    each) and returns, per chunk, whether that job is done (it also is at ``last``). A
    lane whose integration ends otherwise than at its target calls
    ``failed(j, outcome, t)`` and is freed. ``on_done(j)`` is called once per finished or
    failed job (from the worker threads: it must be thread safe). The callbacks of one
    job are always called from one thread; jobs must not share mutable state.
    """
    import heyoka as hy

    if n_jobs <= 0:
        return
    size = int(template.batch_size)
    n_threads = max(1, min(threads or os.cpu_count() or 1, -(-n_jobs // size)))
    lock = threading.Lock()
    queue = iter(range(n_jobs))
    stop = threading.Event()  # set on KeyboardInterrupt: workers leave at their next chunk

    def next_job():
        with lock:
            return next(queue, None)

    def worker():
        ta = copy.copy(template)
        job = [None] * size
        target = np.zeros(size)
        steps_short = np.zeros(size, dtype=np.int64)  # steps of calls that stopped short
        plan = [None] * size  # (t0, t_end, chunk, k)
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
            ld = load(j)
            if not spare:
                spare.append((np.array(ld.state, copy=True), np.array(ld.pars, copy=True), float(ld.t0)))
            ta.state[:, lane] = ld.state
            ta.pars[:, lane] = ld.pars
            hi[lane], lo[lane] = float(ld.t0), 0.0
            plan[lane] = [float(ld.t0), float(ld.t_end), float(ld.chunk), 0]

        for lane in range(size):
            fill(lane)
        ta.set_dtime(hi, lo)
        while any(j is not None for j in job):
            if stop.is_set():
                return
            hi, lo = (np.array(v, dtype=float) for v in ta.dtime)
            for lane in range(size):
                if job[lane] is None:
                    target[lane] = hi[lane]  # idle: a zero-length step leaves the lane as is
                else:
                    t0, t_end, chunk, k = plan[lane]
                    target[lane] = min(t0 + (k + 1) * chunk, t_end)
            ta.propagate_until(target)
            res = ta.propagate_res
            hi, lo = (np.array(v, dtype=float) for v in ta.dtime)
            chunks, freed = [], []
            for lane in range(size):
                j = job[lane]
                if j is None:
                    continue
                outcome = res[lane][0]
                if outcome == hy.taylor_outcome.time_limit:
                    plan[lane][3] += 1
                    chunks.append(LaneChunk(lane, j, float(target[lane]), int(res[lane][3] + steps_short[lane]),
                                            target[lane] >= plan[lane][1]))
                    steps_short[lane] = 0
                elif outcome == hy.taylor_outcome.success and np.isfinite(hi[lane]):
                    # stopped short of its target because another lane failed: go on
                    steps_short[lane] += int(res[lane][3])
                else:
                    failed(j, outcome, float(hi[lane]))
                    freed.append(lane)
            done = after_chunk(ta, chunks) if chunks else []
            for c, d in zip(chunks, done):
                if d or c.last:
                    freed.append(c.lane)
            if freed:
                for lane in freed:
                    if on_done is not None:
                        on_done(job[lane])
                    fill(lane)
                ta.set_dtime(hi, lo)

    if n_threads == 1:
        worker()
        return
    errors = []
    finished = [threading.Event() for _ in range(n_threads)]

    def guarded(k):
        try:
            worker()
        except BaseException as e:  # re-raised in the caller's thread
            errors.append(e)
        finally:
            finished[k].set()

    ts = [threading.Thread(target=guarded, args=(k,)) for k in range(n_threads)]
    for t in ts:
        t.start()
    # wait on our own events, not Thread.join: a join interrupted by Ctrl-C marks a thread
    # that is still running as stopped (CPython 3.11's bpo-45274 handling), and the
    # interpreter then exits under a worker that is inside heyoka (std::terminate)
    try:
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
        t.join()
    if errors:
        raise errors[0]
