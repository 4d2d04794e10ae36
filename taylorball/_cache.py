"""The one cache of compiled heyoka objects (integrators, batch integrators, cfuncs,
variational systems) for the whole package.

Compiling is the expensive part of a heyoka object (seconds; a step costs microseconds),
so every build goes through :func:`compiled`: the first caller of a key builds the object
while holding that key's lock (other keys compile concurrently), later callers get the
same object. Callers never mutate a cached integrator: they take ``copy.copy`` of it
(heyoka copies the compiled state and deep-copies event callbacks), or borrow a working
copy with :func:`working_copy` where the ~1 ms of a copy matters (a call that integrates
for milliseconds). A cached cfunc has scratch buffers, so whoever caches one also caches a
lock to call it under.

Keys are tuples whose first item names what is built (``"integrator"``, ``"batch"``,
``"cfunc"``, ``"tangent"``, ...), followed by everything the compiled code depends on:
the system and formulation, the number type, the tolerance, compact mode, events. The
parameters are never part of a key: they are runtime ``hy.par[i]``, so one compiled
object serves every ball.

heyoka keeps its own caches below this one: compiled LLVM modules in memory and on disk
(``heyoka.llvm_state.get_diskcache_path()``, ``~/.cache/heyoka`` by default), so a
second process compiling the same graph takes a fraction of the first compile.

Logging (logger ``taylorball.compile``; the library installs no handler, the
``taylorball`` command shows INFO): one INFO line per build, the first of a process naming
heyoka's disk cache folder: "loaded KEY from heyoka's disk cache in S s" when heyoka's disk
cache served the machine code (a warm run), "compiling KEY ...: S s" otherwise; a build
still running after :data:`SLOW_BUILD_NOTICE_S` is announced ("compiling KEY ...") while it
runs. A DEBUG line after each build gives its wall time.

Processes that compile the same keys at the same time (the worker processes of
``taylorball reproduce``) can ask, with :func:`share_builds_between_processes`, that a
build also holds a lock file of its key next to heyoka's disk cache: the second process to
want a key waits until the first has compiled it and then loads it from the disk cache
instead of compiling it again (off by default: a process that does not share a disk cache
with others gains nothing from it).
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import logging
import os
import threading
import time
from typing import Callable, Dict, Hashable, Iterator, List, Tuple, TypeVar

__all__ = ["compiled", "cached_keys", "clear", "working_copy", "share_builds_between_processes"]

T = TypeVar("T")

_log = logging.getLogger("taylorball.compile")
_DESCRIBE_MAX = 80  # characters of a key shown in the compile notice

_ENTRIES: Dict[Hashable, object] = {}
_LOCKS: Dict[Hashable, threading.Lock] = {}
_GUARD = threading.Lock()
_NOTICED = False  # whether this process has logged a compile notice (the first names the disk cache)
#: id(template) -> (template, idle working copies); the template is held so that its id stays its own
_SPARE: Dict[int, Tuple[object, List[object]]] = {}  # spares are copies of their template
#: Idle copies kept per template: enough for every thread of a threaded run on a large machine,
#: few enough to bound the memory (measured: ~110 kB per copy of the float64 section integrator).
MAX_SPARE = 64


def compiled(key: Tuple, build: Callable[[], T]) -> T:
    """The cached object for ``key``, built by ``build()`` on first use.

    Thread safe with one lock per key: two threads asking for the same key compile it
    once; different keys compile concurrently. ``build`` may itself ask for other keys
    (e.g. an integrator whose event needs a compiled cfunc), never for its own key.
    """
    with _GUARD:
        if key in _ENTRIES:
            return _ENTRIES[key]  # type: ignore[return-value]
        lock = _LOCKS.setdefault(key, threading.Lock())
    with lock:
        with _GUARD:
            if key in _ENTRIES:  # built by another thread while we waited
                return _ENTRIES[key]  # type: ignore[return-value]
        notice = _log.isEnabledFor(logging.INFO)
        with _process_lock(key, notice):  # another process's build of the key first, if any
            before = _heyoka_cache_sizes() if notice else None
            # a build that takes a while is announced while it runs (the outcome follows it)
            early = _EarlyNotice(key) if notice else None
            t0 = time.perf_counter()
            try:
                obj = build()
            finally:
                announced = early.cancel() if early is not None else False
            seconds = time.perf_counter() - t0
            if notice and not announced:
                if _served_by_disk_cache(before, _heyoka_cache_sizes()):
                    _log.info("loaded %s from heyoka's disk cache in %.2f s (first use in this process%s)",
                              _describe(key, brief=True), seconds, _disk_cache_note())
                else:
                    _log.info("compiling %s (first use in this process%s): %.2f s", _describe(key, brief=True),
                              _disk_cache_note(), seconds)
        _log.debug("built %s in %.2f s", _describe(key), seconds)
        with _GUARD:
            _ENTRIES[key] = obj
        return obj


_SHARE_BETWEEN_PROCESSES = False
#: The longest a build waits for another process's build of the same key (seconds): a
#: process stopped mid-build must not stall the others; past this, it compiles itself.
PROCESS_LOCK_WAIT_S = 120.0


def share_builds_between_processes(on: bool = True) -> None:
    """Whether this process's builds hold a lock file per key next to heyoka's disk cache
    (module docstring), so that another process wanting the same key at the same time waits
    and then loads it from the disk cache instead of compiling it too. Compiled objects and
    their bits are the same either way (heyoka's disk cache holds the machine code of the
    same graph)."""
    global _SHARE_BETWEEN_PROCESSES
    _SHARE_BETWEEN_PROCESSES = bool(on)


@contextlib.contextmanager
def _process_lock(key, notice: bool = False) -> Iterator[None]:
    """Hold the lock file of ``key`` (:func:`share_builds_between_processes`) for a build; a
    no-op when sharing is off, heyoka's disk cache is off, the key's text is not the same in
    every process (an object's address in it), there is no ``fcntl`` (Windows) or the folder
    cannot be written. After :data:`PROCESS_LOCK_WAIT_S` the build goes ahead unlocked.
    ``notice``: say (INFO) that the build waits for another process's."""
    fd = _lock_file(key) if _SHARE_BETWEEN_PROCESSES else None
    if fd is None:
        yield
        return
    import fcntl

    deadline = time.monotonic() + PROCESS_LOCK_WAIT_S
    locked = False
    try:
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                locked = True
                break
            except BlockingIOError:  # another process holds it
                if notice:
                    _log.info("waiting for another process compiling %s (then heyoka's disk cache has it)",
                              _describe(key, brief=True))
                    notice = False
                if time.monotonic() > deadline:
                    break
                time.sleep(0.02)
            except OSError:  # no locks on this file system: build unlocked
                break
        yield
    finally:
        if locked:
            fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)


def _lock_file(key):
    """An open descriptor of ``key``'s lock file (``taylorball-locks/<sha1 of the key>.lock``
    in heyoka's disk cache folder, created if missing; never removed: one small file per key
    ever built), or ``None`` where locking does not apply (:func:`_process_lock`)."""
    text = repr(key)
    if " at 0x" in text:  # an object's address: not the same key in another process
        return None
    try:
        import fcntl  # noqa: F401  (POSIX only)

        folder = _lock_folder()
        if folder is None:
            return None
        os.makedirs(folder, exist_ok=True)
        name = hashlib.sha1(text.encode()).hexdigest() + ".lock"
        return os.open(os.path.join(folder, name), os.O_RDWR | os.O_CREAT, 0o644)
    except (ImportError, OSError, AttributeError):
        return None


def _lock_folder():
    """``taylorball-locks`` in heyoka's disk cache folder, or ``None`` if that cache is off."""
    import heyoka as hy

    if not hy.llvm_state.get_diskcache_enabled():
        return None
    return os.path.join(str(hy.llvm_state.get_diskcache_path()), "taylorball-locks")


def _describe(key, brief: bool = False) -> str:
    """The key as words; ``brief``: without the flags (bare booleans, e.g. compact mode),
    cut to ``_DESCRIBE_MAX`` characters."""
    text = " ".join(str(k) for k in key if k is not None and not (brief and isinstance(k, bool)))
    return text if not brief or len(text) <= _DESCRIBE_MAX else text[: _DESCRIBE_MAX - 3] + "..."


#: A build still running after this many seconds is announced at once ("compiling ..."):
#: heyoka's disk cache serves a compiled module in well under a second.
SLOW_BUILD_NOTICE_S = 2.0


class _EarlyNotice:
    """Logs "compiling KEY" if a build is still running after :data:`SLOW_BUILD_NOTICE_S`;
    :meth:`cancel` stops it and says whether it was logged."""

    def __init__(self, key):
        self._key = key
        self._lock = threading.Lock()
        self._done = False
        self._logged = False
        self._timer = threading.Timer(SLOW_BUILD_NOTICE_S, self._fire)
        self._timer.daemon = True
        self._timer.start()

    def _fire(self) -> None:
        with self._lock:
            if self._done:
                return
            self._logged = True
        _log.info("compiling %s (first use in this process%s; not in heyoka's disk cache)",
                  _describe(self._key, brief=True), _disk_cache_note())

    def cancel(self) -> bool:
        self._timer.cancel()
        with self._lock:
            self._done = True
            return self._logged


def _heyoka_cache_sizes():
    """``(in-memory, on-disk)`` sizes of heyoka's caches of compiled modules, or ``None``
    (a heyoka without that API, or its disk cache off)."""
    try:
        import heyoka as hy

        if not hy.llvm_state.get_diskcache_enabled():
            return None
        return hy.llvm_state.get_memcache_size(), hy.llvm_state.get_diskcache_size()
    except Exception:  # an older heyoka: no way to tell, the notice says "compiling"
        return None


def _served_by_disk_cache(before, after) -> bool:
    """Whether a build loaded its machine code from heyoka's disk cache: heyoka's in-memory
    cache of compiled modules grew (the build made new machine code available) while the disk
    cache did not (nothing was compiled and stored). A build that compiled stores its module
    on disk; one that took everything from the in-memory cache changes neither (and says
    "compiling", as does a build that cannot be told: another process writing the disk cache
    at the same time makes this say "compiling" too, never "loaded" wrongly)."""
    if before is None or after is None:
        return False
    return after[0] > before[0] and after[1] == before[1]


def _disk_cache_note() -> str:
    """Where heyoka keeps compiled machine code: said once per process (first notice)."""
    global _NOTICED
    with _GUARD:
        if _NOTICED:
            return ""
        _NOTICED = True
    try:
        import heyoka as hy

        if not hy.llvm_state.get_diskcache_enabled():
            return "; heyoka's disk cache is off"
        return f"; heyoka caches machine code in {hy.llvm_state.get_diskcache_path()}"
    except Exception:  # an older heyoka without the disk-cache API: say nothing about it
        return ""


@contextlib.contextmanager
def working_copy(template: T) -> Iterator[T]:
    """A private copy of a cached template (an integrator) for the duration of a ``with``
    block: an idle copy left by an earlier block if there is one, else ``copy.copy(template)``.

    Taking a copy costs ~1 ms (heyoka copies the compiled state); reusing one costs nothing.
    The copy comes back in whatever state its last user left it: the borrower sets
    everything its run depends on (state, time, parameters, what its event callbacks
    collect) before using it. heyoka's step-size control and non-terminal event detection
    depend only on those (no memory of earlier steps), so a run of a reused copy is
    bit-identical to a run of a fresh one (``tests/test_section_stop.py``). A block that
    raises does not give its copy back (it may be half-way through a step). Thread safe:
    each copy is lent to one block at a time.
    """
    key = id(template)
    with _GUARD:
        entry = _SPARE.get(key)
        spare_copy = entry[1].pop() if entry is not None and entry[1] else None
    obj: T = copy.copy(template) if spare_copy is None else spare_copy  # type: ignore[assignment]  # the spares are copies of this template
    yield obj
    with _GUARD:
        spare = _SPARE.setdefault(key, (template, []))[1]
        if len(spare) < MAX_SPARE:
            spare.append(obj)


def cached_keys() -> list:
    """The keys built so far in this process (for tests and diagnostics)."""
    with _GUARD:
        return list(_ENTRIES)


def clear() -> None:
    """Forget every compiled object of this process (heyoka's own caches stay)."""
    with _GUARD:
        _ENTRIES.clear()
        _LOCKS.clear()
        _SPARE.clear()
