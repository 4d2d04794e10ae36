"""One engine for many orbits: :func:`run_many`.

Sections of many orbits, MEGNO of many orbits, ensembles of long runs and the figures of
``taylorball reproduce`` are all "many independent members" workloads. This module runs
them, in one of five modes, and implements once what every such run needs:

* **Ctrl-C.** Every running member stops at its next chunk boundary (a member calls
  ``ctx.check()`` there; the lane pool checks between chunks), queued members are
  dropped, and ``KeyboardInterrupt`` is re-raised once the workers have left heyoka,
  i.e. within a chunk's time (a member that never checks runs to its end first; code deep
  in a member can check through :func:`current`, and a run started inside a member stops
  with it). Processes are terminated; dask futures are cancelled.
  The caller's thread waits on per-worker :class:`threading.Event` objects, never in an
  interruptible ``Thread.join``: a join interrupted by Ctrl-C marks a thread that is still
  running as stopped (CPython 3.11's bpo-45274 handling) and the interpreter then exits
  under a worker that is inside heyoka (``std::terminate``, exit status 134).
* **Progress** in members: ``progress=True`` (or a label) shows one tqdm bar over the
  members, advanced by fractions of a member as members report them (``ctx.advance``, the
  lane pool after every chunk); ``progress=callable`` receives those fractions instead
  (never concurrently: callers can aggregate several runs in one bar). Every member
  contributes 1 in total (its remainder when it ends), so the fractions add up to the
  number of members that ended, to the rounding of the additions.
* **Failure of one member.** ``on_error="raise"`` (default) stops the others (as for
  Ctrl-C) and re-raises the member's exception, its type unchanged, with a note naming
  the member (``member 3 of 8 failed (backend 'threads')``); ``on_error="keep"`` lets the
  others finish and puts a :class:`MemberFailure` (index and exception) in the failed
  member's place.
* **Determinism.** Each member gets its own context and nothing mutable is shared between
  members by the engine, so member ``i``'s result is whatever its job computes from its own
  input, whatever the backend, the number of workers and the other members (the jobs must
  keep their part of the bargain: their own integrator copies and chunk boundaries fixed
  in time).

Modes
-----
``"serial"``
    In the caller's thread, in order (Ctrl-C raises ``KeyboardInterrupt`` where it lands).
``"threads"``
    ``workers`` threads (default ``os.cpu_count()``) pulling members from one queue;
    heyoka releases the GIL while it integrates.
``"lanes"``
    float64 orbits in the SIMD lanes of heyoka batch integrators, one copy per thread, a
    lane refilled as soon as its orbit is done (see :class:`LaneTask` and below).
``"processes"``
    A ``spawn`` process pool (scripts need an ``if __name__ == "__main__":`` guard; jobs
    must be picklable: top-level functions, :func:`call`); progress bars inside workers
    are switched off (``TQDM_DISABLE``), the engine counts whole members.
``"dask"``
    ``client.submit`` on a dask.distributed ``client`` (``pip install
    taylorball[cluster]``), collected with ``distributed.as_completed`` so progress moves
    as members finish.

Jobs
----
For every backend but ``"lanes"`` a job is a callable taking a :class:`Context`; :func:`call`
turns ``fn(*args)`` into such a job (picklable when ``fn`` and ``args`` are). In processes
and dask backends the job receives a context whose ``check`` never stops and whose ``advance``
does nothing (the engine counts whole members there).

The lane pool
-------------
heyoka's batch mode integrates ``size`` orbits at once, one per SIMD lane, each lane with
its own time and step sizes (measured here: a lane's bits do not depend on its companions,
nor on when it was loaded). Running orbits in fixed groups of ``size`` wastes lanes: a
group lasts as long as its slowest orbit (section runs to ``n`` crossings differ several
times in length; MEGNO runs stop early on chaotic orbits). The lane pool instead refills a
lane with the next orbit as soon as its orbit is done, and runs one batch integrator per
thread, all pulling from one queue of jobs.

Every job advances on its own clock through the chunk boundaries ``t0 + k chunk`` (the
last one ``t_end``), exactly as a run of that orbit alone would, so its result depends only
on its own initial state: it is bit-identical whatever the number of threads, the lane it
lands in and the jobs around it. A lane without a job is given its own time as target, a
step of length zero that leaves it untouched; it holds a finite "spare" state (a failed
lane's state and time are NaN, a lane never loaded has the template's zero parameters, and
a time-dependent field may be singular at ``t = 0``, e.g. MEGNO's ``2 y / t``). A lane that
stops short of its target because another lane failed goes on, its steps counted
(``steps_short``) into its next chunk.
"""

from __future__ import annotations

import copy
import os
import threading
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, List, Literal, Optional, Sequence, Tuple, Union

import numpy as np

from ._typing import ProgressLike
from ._deprecation import renamed
from .errors import UsageError

__all__ = ["run_many", "call", "Context", "MemberFailure", "LaneTask", "LaneLoad", "LaneChunk", "current"]

BACKENDS = ("serial", "threads", "lanes", "processes", "dask")
MODES = BACKENDS  # the old name
ON_ERROR = ("raise", "keep")


class _Stopped(BaseException):
    """Raised by :meth:`Context.check` in a member after Ctrl-C (or after another member
    failed with ``on_error="raise"``): the member is abandoned at a chunk boundary. A
    ``BaseException``, so that a member's ``except Exception`` cannot swallow it."""


@dataclass(frozen=True)
class MemberFailure:
    """In the result list of ``run_many(..., on_error="keep")``: member ``index`` raised
    ``error`` (its traceback is on ``error.__traceback__``, or ``error.__cause__`` for a
    process or dask member)."""

    index: int
    error: BaseException

    def __str__(self) -> str:
        return f"member {self.index} failed: {type(self.error).__name__}: {self.error}"


# ---------------------------------------------------------------------------------------
# Progress: the one implementation.
# ---------------------------------------------------------------------------------------
class _Progress:
    """Fractions of members: per member a running total clipped to ``[0, 1]``; each
    increase goes to the bar or the callable, under one lock (never concurrently)."""

    def __init__(self, progress, n):
        self.bar = None
        self.sink = None
        self.done = [0.0] * n
        self.lock = threading.Lock()
        self.whole, self.partial = 0, {}  # for the bar: members done, fractions of those under way
        if progress is None or progress is False:
            pass
        elif callable(progress):
            self.sink = progress
        elif progress is True or isinstance(progress, str):
            from tqdm.auto import tqdm

            label = progress if isinstance(progress, str) else "members"
            self.bar = tqdm(total=n, desc=label,
                            bar_format="{l_bar}{bar}| {n:.1f}/{total} [{elapsed}<{remaining}]")
        else:
            raise UsageError(f"progress must be True, False, a label (str) or a callable taking fractions, "
                             f"got {progress!r}")
        self.enabled = self.bar is not None or self.sink is not None

    def reach(self, i, fraction):
        """Member ``i`` is ``fraction`` done (cumulative)."""
        if not self.enabled:
            return
        f = min(max(float(fraction), 0.0), 1.0)
        with self.lock:
            if f > self.done[i]:
                delta = (1.0 - self.done[i]) if f == 1.0 else f - self.done[i]
                self.done[i] = f
                if self.sink is not None:
                    self.sink(delta)
                else:
                    self._show(i, f)

    def _show(self, i, f):
        """The bar shows whole members plus the fractions under way (not a running sum of
        increments, whose rounding would leave a finished bar at 3.9999 of 4)."""
        if f == 1.0:
            self.partial.pop(i, None)
            self.whole += 1
        else:
            self.partial[i] = f
        self.bar.n = self.whole + sum(self.partial.values())
        self.bar.update(0)

    def add(self, i, fraction):
        if self.enabled:
            self.reach(i, self.done[i] + float(fraction))

    def close(self):
        if self.bar is not None:
            self.bar.close()


# ---------------------------------------------------------------------------------------
# The member's context.
# ---------------------------------------------------------------------------------------
class Context:
    """What a member sees of the engine: its ``index``, :meth:`check` (call it at every
    chunk boundary: after Ctrl-C it abandons the member) and :meth:`advance` (report
    progress in fractions of the member)."""

    __slots__ = ("index", "_stop", "_progress", "_parent")

    def __init__(self, index: int, stop: Optional[threading.Event] = None,
                 progress: Optional[_Progress] = None, parent: Optional[Context] = None) -> None:
        self.index = index
        self._stop = stop
        self._progress = progress
        self._parent = parent  # the member this run was started from (a run inside a member)

    @property
    def stopping(self) -> bool:
        """True once the run is being stopped (Ctrl-C, another member failed, or the member
        this run was started from is being stopped)."""
        if self._stop is not None and self._stop.is_set():
            return True
        return self._parent is not None and self._parent.stopping

    def check(self) -> None:
        """Leave the member here if the run is being stopped (raises a private exception
        that the engine catches)."""
        if self.stopping:
            raise _Stopped

    def advance(self, fraction: float) -> None:
        """``fraction`` more of this member is done (the total is clipped to 1; whatever is
        left is added when the member ends)."""
        if self._progress is not None:
            self._progress.add(self.index, fraction)


_NULL = Context(-1)
_local = threading.local()


def current() -> Context:
    """The context of the member running in this thread (a context that never stops and
    reports nowhere outside a member, or in processes and dask modes): lets code deep in a
    member call ``current().check()`` at its chunk boundaries without passing ``ctx`` down."""
    return getattr(_local, "ctx", None) or _NULL


class _Call:
    """A job calling ``fn(*args, **kwargs)`` (the context ignored); picklable when its parts are."""

    __slots__ = ("fn", "args", "kwargs")

    def __init__(self, fn, args, kwargs):
        self.fn, self.args, self.kwargs = fn, args, kwargs

    def __call__(self, ctx):
        return self.fn(*self.args, **self.kwargs)

    def __getstate__(self):
        return (self.fn, self.args, self.kwargs)

    def __setstate__(self, state):
        self.fn, self.args, self.kwargs = state

    def __repr__(self):
        return f"call({getattr(self.fn, '__qualname__', self.fn)!r}, ...)"


def call(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Callable[[Context], Any]:
    """A job for :func:`run_many` that computes ``fn(*args, **kwargs)`` and ignores its
    context (picklable when ``fn`` is a top-level function and ``args`` are picklable)."""
    return _Call(fn, args, kwargs)


def _note(error, i, n, mode):
    msg = f"taylorball.ensemble: member {i} of {n} failed (backend {mode!r})"
    msg += "; the other members were dropped" if n > 1 else ""
    if hasattr(error, "add_note"):
        error.add_note(msg)
    else:  # Python 3.10: kept on the exception, not printed
        error.__notes__ = list(getattr(error, "__notes__", [])) + [msg]
    try:
        error.ensemble_member = i
    except Exception:  # pragma: no cover - exceptions with __slots__
        pass
    return error


class _Run:
    """The state of one :func:`run_many` call shared by its workers: the stop event, the
    progress, the results and the first failure (for ``on_error="raise"``)."""

    def __init__(self, n: int, mode: str, progress: ProgressLike, on_error: str,
                 on_result: Optional[Callable[[int, Any], None]]) -> None:
        self.n, self.mode, self.on_error = n, mode, on_error
        self.stop = threading.Event()
        self.parent = current()  # a run started inside a member stops with that member
        self.progress = _Progress(progress, n)
        self.out: List[Any] = [None] * n
        self.failure = None  # (index, exception): the one re-raised with on_error="raise"
        self.lock = threading.Lock()
        self.on_result = on_result

    def finished(self, i, result):
        """Member ``i`` ended with ``result``."""
        self.out[i] = result
        self.progress.reach(i, 1.0)
        if self.on_result is not None:
            with self.lock:
                self.on_result(i, result)

    def failed(self, i, error):
        """Member ``i`` raised ``error``: recorded (keep), or the run is stopped (raise)."""
        if self.on_error == "keep":
            self.finished(i, MemberFailure(i, error))
            return
        with self.lock:
            if self.failure is None or i < self.failure[0]:
                self.failure = (i, error)
        self.stop.set()

    def stopping(self):
        return self.stop.is_set() or self.parent.stopping

    def run_member(self, i, job):
        """Run job ``i`` in this thread; False if the run is being stopped."""
        if self.stopping():
            return False
        ctx = Context(i, self.stop, self.progress, self.parent)
        outer = getattr(_local, "ctx", None)
        _local.ctx = ctx
        try:
            r = job(ctx)
        except _Stopped:
            return False
        except Exception as e:
            self.failed(i, e)
            return not self.stopping()
        finally:
            _local.ctx = outer
        self.finished(i, r)
        return True

    def result(self):
        if self.failure is not None:
            i, e = self.failure
            raise _note(e, i, self.n, self.mode)
        if self.parent.stopping:
            raise _Stopped  # this run was inside a member being stopped: so is the member
        return self.out


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
    started and then raised, so that the caller's handler (which sets ``stop`` and waits for
    every worker) never misses a thread that was already running: a worker started just
    before an interrupt would otherwise run on unstopped and keep the process alive."""
    import signal

    if threading.current_thread() is not threading.main_thread():
        for t in threads:
            t.start()
        return
    held = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: held.append(signum))
    try:
        for t in threads:
            t.start()
    finally:
        signal.signal(signal.SIGINT, previous)
    if held and callable(previous):  # as the handler in force would have done (SIG_IGN: nothing)
        previous(signal.SIGINT, None)


def _run_threads(jobs, run, workers):
    queue = iter(range(len(jobs)))
    lock = threading.Lock()

    def worker():
        while True:
            with lock:
                i = next(queue, None)
            if i is None or not run.run_member(i, jobs[i]):
                return

    _on_threads(max(1, min(workers or os.cpu_count() or 1, len(jobs))), worker, run.stop)


def _run_serial(jobs, run):
    for i, job in enumerate(jobs):
        if not run.run_member(i, job):
            return


# ---------------------------------------------------------------------------------------
# Processes and dask: whole members.
# ---------------------------------------------------------------------------------------
def _remote(job, i):
    """Run job ``i`` in a worker process or on a dask worker (a context that never stops and
    reports nowhere: the engine counts whole members there)."""
    ctx = Context(i)
    outer = getattr(_local, "ctx", None)
    _local.ctx = ctx
    try:
        return job(ctx)
    finally:
        _local.ctx = outer


def _quiet_worker():
    os.environ["TQDM_DISABLE"] = "1"  # bars in workers would interleave; the engine counts members


def _terminate_pool(ex):
    """Drop queued members and end the pool's worker processes (only this pool's). A second
    Ctrl-C (a terminal's reaches the whole process group) must not cut this short."""
    import signal

    main = threading.current_thread() is threading.main_thread()
    old = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
    try:
        procs = list((getattr(ex, "_processes", None) or {}).values())
        ex.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            p.terminate()
        for p in procs:
            p.join()
        ex.shutdown(wait=True)  # the workers are gone: this only releases the pool's resources
    finally:
        if main:
            signal.signal(signal.SIGINT, old)


def _collect(i, future, run):
    """Result or failure of a finished process/dask member; False to stop the run."""
    try:
        r = future.result()
    except Exception as e:
        run.failed(i, e)
        return run.on_error == "keep"
    run.finished(i, r)
    return True


def _as_completed_polling(futures, poll: float = 0.2):
    """``concurrent.futures.as_completed`` with waits of at most ``poll`` seconds: a signal
    the kernel delivers to another thread (a timer's ``os.kill``, or any thread a terminal's
    SIGINT lands on) does not wake a main thread blocked on a lock, but Python runs its
    handler at the main thread's next bytecode, so waiting in slices keeps Ctrl-C prompt
    (an untimed as_completed sat for the members' whole 600 s in a test)."""
    import concurrent.futures as cf

    pending = set(futures)
    while pending:
        done, pending = cf.wait(pending, timeout=poll, return_when=cf.FIRST_COMPLETED)
        for f in done:
            yield f


def _check_picklable(jobs):
    """Refuse, before any pool starts, a job that cannot be sent to a worker process."""
    import pickle

    for i, job in enumerate(jobs):
        try:
            pickle.dumps(job)
        except Exception as exc:
            fn = job.fn if isinstance(job, _Call) else job
            raise UsageError(
                f"job {i} ({getattr(fn, '__qualname__', None) or repr(fn)}) cannot be sent to a worker process "
                f"for backend='processes' ({type(exc).__name__}: {exc}): the function must be a top-level function "
                "of an importable module (not a lambda, a local function or a bound method of an unpicklable "
                "object) and its arguments picklable; or use backend='threads'"
            ) from exc


def _run_processes(jobs, run, workers):
    import concurrent.futures as cf
    import multiprocessing as mp

    n_workers = max(1, min(workers or os.cpu_count() or 1, len(jobs)))
    ex = cf.ProcessPoolExecutor(max_workers=n_workers, mp_context=mp.get_context("spawn"),
                                initializer=_quiet_worker)
    try:
        futures = {ex.submit(_remote, job, i): i for i, job in enumerate(jobs)}
        for f in _as_completed_polling(futures):
            if not _collect(futures[f], f, run):
                break
    except BaseException:  # Ctrl-C (here or as a worker's result)
        _terminate_pool(ex)
        raise
    if run.failure is not None:
        _terminate_pool(ex)  # on_error="raise": the other members are dropped
    else:
        ex.shutdown(wait=True)


def _run_dask(jobs, run, client):
    from distributed import as_completed

    futures = [client.submit(_remote, job, i, pure=False) for i, job in enumerate(jobs)]
    index = {f.key: i for i, f in enumerate(futures)}
    try:
        for f in as_completed(futures):
            if not _collect(index[f.key], f, run):
                break
    except BaseException:
        client.cancel(futures)
        raise
    if run.failure is not None:
        client.cancel(futures)


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


# ---------------------------------------------------------------------------------------
# The engine.
# ---------------------------------------------------------------------------------------
@renamed(mode="backend")
def run_many(jobs: Union[Iterable[Callable[[Context], Any]], LaneTask], *,
             backend: Literal["serial", "threads", "lanes", "processes", "dask"] = "serial",
             workers: Optional[int] = None, client: Any = None, progress: ProgressLike = False,
             on_error: Literal["raise", "keep"] = "raise",
             on_result: Optional[Callable[[int, Any], None]] = None) -> List[Any]:
    """Run independent members; returns their results in job order.

    Parameters
    ----------
    jobs : sequence of callables, or LaneTask
        For ``backend="lanes"`` a :class:`LaneTask`; otherwise callables taking a
        :class:`Context` (``ctx.check()`` at each chunk boundary, ``ctx.advance(f)`` for
        progress), picklable for ``"processes"`` and ``"dask"``; :func:`call` wraps a plain
        ``fn(*args)``.
    backend : {"serial", "threads", "lanes", "processes", "dask"}
        Where the members run (module docstring). Member ``i``'s result does not depend on it.
        (``mode=`` is its deprecated old name.)
    workers : int, optional
        Threads (``"threads"``, ``"lanes"``) or processes (``"processes"``); default
        ``os.cpu_count()``, never more than there is work for. Ignored by ``"serial"`` and
        ``"dask"``.
    client : distributed.Client
        For ``backend="dask"`` (required there).
    progress : bool, str or callable
        ``False`` (default): none; ``True`` or a label: a tqdm bar over members; a callable:
        called with each increase, in fractions of a member (never concurrently).
    on_error : {"raise", "keep"}
        A member's exception stops the run and is re-raised, with a note naming the
        member (``"raise"``); or it is returned in the member's place as a
        :class:`MemberFailure` while the others finish (``"keep"``).
    on_result : callable, optional
        ``on_result(i, result)`` as each member ends (a :class:`MemberFailure` for a
        failed one with ``"keep"``), in any order, never concurrently.

    Raises
    ------
    KeyboardInterrupt
        On Ctrl-C, once the running members have stopped at their next chunk boundary
        (threads, lanes), the worker processes have ended or the dask futures are cancelled;
        queued members never start.
    UsageError
        Bad ``backend``, ``on_error``, ``progress``, ``jobs`` or a missing ``client``.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.ensemble import call
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> x0 = demo_reduced_state()
    >>> jobs = [call(tb.propagate, "reduced", FIG4_BALL, x0, t) for t in (0.5, 1.0)]
    >>> out = tb.run_many(jobs, backend="threads", workers=2)
    >>> [x.shape for x in out]
    [(9,), (9,)]
    >>> bool((out[1] == tb.propagate("reduced", FIG4_BALL, x0, 1.0)).all())
    True
    >>> tb.run_many([call(int, "x"), call(abs, -2)], on_error="keep")
    [MemberFailure(index=0, error=ValueError("invalid literal for int() with base 10: 'x'")), 2]
    """
    mode = backend
    if not isinstance(mode, str) or mode not in MODES:
        raise UsageError(f"backend must be one of {MODES}, got {mode!r}")
    if not isinstance(on_error, str) or on_error not in ON_ERROR:
        raise UsageError(f"on_error must be 'raise' (stop and re-raise) or 'keep' (record and go on), "
                         f"got {on_error!r}")
    if workers is not None and not (isinstance(workers, (int, np.integer)) and not isinstance(workers, bool)
                                    and workers >= 1):
        raise UsageError(f"workers must be a positive integer or None, got {workers!r}")
    if mode == "lanes":
        if not isinstance(jobs, LaneTask):
            raise UsageError(f"backend='lanes' takes a LaneTask, got {type(jobs).__name__}")
        n = int(jobs.n_jobs)
    else:
        if isinstance(jobs, LaneTask):
            raise UsageError(f"a LaneTask runs with backend='lanes', got backend={mode!r}")
        try:
            jobs = list(jobs)
        except TypeError:
            raise UsageError(f"jobs must be a sequence of callables taking a Context (see "
                             f"taylorball.ensemble.call), got {jobs!r}") from None
        bad = [i for i, j in enumerate(jobs) if not callable(j)]
        if bad:
            raise UsageError(f"jobs must be callables taking a Context (see taylorball.ensemble.call); "
                             f"job {bad[0]} is {jobs[bad[0]]!r}")
        n = len(jobs)
    if mode == "dask" and client is None:
        raise UsageError("backend='dask' needs client=<dask.distributed.Client>")
    if mode == "processes":
        _check_picklable(jobs)
    run = _Run(n, mode, progress, on_error, on_result)
    try:
        if mode == "serial":
            _run_serial(jobs, run)
        elif mode == "threads":
            _run_threads(jobs, run, workers)
        elif mode == "lanes":
            _run_lanes(jobs, run, workers)
        elif mode == "processes":
            _run_processes(jobs, run, workers)
        else:
            _run_dask(jobs, run, client)
    finally:
        run.progress.close()
    return run.result()
