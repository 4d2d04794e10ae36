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

import os
import threading
from dataclasses import dataclass
from typing import Any, Callable, Dict, Iterable, List, Literal, Optional, Tuple, Union

import numpy as np

from ._typing import ProgressLike
from ._deprecation import renamed
from ._lanes import LaneChunk, LaneLoad, LaneTask, _on_threads, _run_lanes  # the lane pool (its own module)
from .errors import UsageError

__all__ = ["run_many", "call", "Context", "MemberFailure", "LaneTask", "LaneLoad", "LaneChunk", "current",
           "orbit_lanes"]

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
_worker_stop = threading.Event()  # in a worker process: set by SIGTERM (see _on_sigterm)
_member_running = False  # in a worker process: whether a member is running in it
_member_checks = False  # ... and whether it has called ctx.check() (it stops at chunk boundaries)


class _WorkerContext(Context):
    """A member's context in a worker process: notes that the member checks (see
    :func:`_on_sigterm`)."""

    __slots__ = ()

    def check(self) -> None:
        global _member_checks
        _member_checks = True
        super().check()


def _on_sigterm(signum: int, frame: Any) -> None:
    """A worker process's SIGTERM (its pool being ended: Ctrl-C or SIGTERM of the parent).
    A member that calls ``ctx.check()`` is stopped at its next chunk boundary, as Ctrl-C
    stops a thread's member (a long run's orbit keeps its last commit and releases its
    lock), and the worker then exits (:func:`_remote`); an idle worker, or one whose member
    has not checked yet (which may never check), exits at once. No exception is raised
    here: one raised inside heyoka (an event callback) could end the process without its
    clean-up. The pool may send SIGTERM more than once; SIGKILL ends a worker at once."""
    if not (_member_running and _member_checks):
        os._exit(128 + signum)
    _worker_stop.set()


def _remote(job, i):
    """Run job ``i`` in a worker process or on a dask worker (a context that reports nowhere:
    the engine counts whole members there; it stops only in a worker process told to end,
    :func:`_on_sigterm`)."""
    global _member_running, _member_checks
    ctx = _WorkerContext(i, _worker_stop)
    outer = getattr(_local, "ctx", None)
    _local.ctx = ctx
    _member_running, _member_checks = True, False
    try:
        out = job(ctx)
    except _Stopped:
        os._exit(143)  # the member left at a chunk boundary after its own clean-up: the pool is ending
    except BaseException:
        # a terminal's Ctrl-C reaches the worker too: its KeyboardInterrupt can leave the member
        # after the pool's SIGTERM was handled (which, a member running, only set the flag);
        # back in the pool's loop the worker would wait for work on the call queue for ever,
        # and the parent joining it with it
        if _worker_stop.is_set():
            os._exit(143)
        raise
    finally:
        _member_running = _member_checks = False
        _local.ctx = outer
    if _worker_stop.is_set():
        os._exit(143)
    return out


def _quiet_worker(parent: Optional[int] = None) -> None:
    """A worker process's start: no progress bars (they would interleave; the engine counts
    members), SIGTERM ends the worker after the running member's clean-up
    (:func:`_on_sigterm`; also when the parent was started with SIGTERM ignored), and the
    worker dies with its parent ``parent`` (a kill -9 or SIGTERM of
    the parent must not leave workers integrating on, holding orbit locks): on Linux the
    kernel sends SIGKILL when the parent ends (``prctl(PR_SET_PDEATHSIG)``), elsewhere (and
    if that call fails) a daemon thread sees the parent gone within a second."""
    import signal

    os.environ["TQDM_DISABLE"] = "1"
    signal.signal(signal.SIGTERM, _on_sigterm)
    if parent is None:
        return
    if _die_with_parent_linux() and os.getppid() == parent:
        return  # (checked after the call: the parent may have ended before it)
    if os.getppid() != parent:
        os._exit(1)

    def watch() -> None:
        import time

        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="taylorball-parent-watch", daemon=True).start()


def _die_with_parent_linux() -> bool:
    """``prctl(PR_SET_PDEATHSIG, SIGKILL)``: True if it took effect (Linux only)."""
    import sys

    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes
        import signal

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(1, int(signal.SIGKILL), 0, 0, 0) == 0  # 1: PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return False


def _terminate_pool(ex):
    """Drop queued members and end the pool's worker processes (only this pool's): SIGTERM,
    on which a worker stops its running member at the member's next chunk boundary (a long
    run's orbit keeps its last commit and is unlocked; a member that never checks runs to
    its end) and exits (:func:`_on_sigterm`). A second Ctrl-C (a terminal's reaches the
    whole process group) must not cut this short."""
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
                                initializer=_quiet_worker, initargs=(os.getpid(),))
    # (the "spawn" pool starts its workers from this thread, in submit(), and this thread
    # outlives the pool: PR_SET_PDEATHSIG, which follows the creating thread, fires only
    # when the process ends)
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


def orbit_lanes(template: Any, n_jobs: int, *, load: Callable[[int], LaneLoad],
                on_chunk: Callable[[Any, LaneChunk], Tuple[bool, Any]],
                rerun: Callable[[int, Any, float], Any],
                workers: Optional[int] = None, progress: ProgressLike = False,
                on_chunks: Optional[Callable[[Any, List[LaneChunk]], None]] = None,
                **lane_options: Any) -> List[Any]:
    """Many orbits in the SIMD lanes of ``template`` (``backend="lanes"``): the adapter every
    lane user shares (sections, chaos indicators, studies), so none writes the bookkeeping
    again. ``load(j)`` gives job ``j``'s :class:`LaneLoad` (its start, chunk ends and sample
    times: a resumed job starts at its checkpoint). After each integrator call,
    ``on_chunks(ta, chunks)``, optional, sees every lane that ended a chunk in it at once
    (what the batch events recorded for all lanes is read there), then for each of them
    ``on_chunk(ta, chunk)`` returns ``(stop, result)``: it may change the lane's column of
    ``ta.state``, ``stop`` ends the orbit at this chunk (before its ``t_end``), and a
    ``result`` that is not ``None`` is kept as the job's result. A job whose integration
    fails is ``rerun(j, outcome, t)`` in the caller's thread once the run is over (heyoka's
    outcome and the lane's time when it stopped): its return value is the job's result, an
    exception it raises the job's failure (named by :func:`run_many`). ``lane_options`` go
    to :class:`LaneTask` as they are (``fraction``, ``on_done``, ``on_reset``, ``grid``).
    Returns the results in job order."""
    out: List[Any] = [None] * n_jobs
    failed: Dict[int, Tuple[Any, float]] = {}

    def after_chunk(ta: Any, chunks: List[LaneChunk]) -> List[bool]:
        if on_chunks is not None:
            on_chunks(ta, chunks)
        done = []
        for c in chunks:
            stop, res = on_chunk(ta, c)
            if res is not None:
                out[c.job] = res
            done.append(bool(stop))
        return done

    def on_fail(j: int, outcome: Any, t: float) -> None:
        failed[j] = (outcome, t)

    def result(j: int) -> Any:
        return rerun(j, *failed[j]) if j in failed else out[j]

    task = LaneTask(template, n_jobs, load=load, after_chunk=after_chunk, failed=on_fail, result=result,
                    **lane_options)
    return run_many(task, backend="lanes", workers=workers, progress=progress)
