"""The one cache of compiled heyoka objects (integrators, batch integrators, cfuncs,
variational systems) for the whole package.

Compiling is the expensive part of a heyoka object (seconds; a step costs microseconds),
so every build goes through :func:`compiled`: the first caller of a key builds the object
while holding that key's lock (other keys compile concurrently), later callers get the
same object. Callers never mutate a cached integrator: they take ``copy.copy`` of it
(heyoka copies the compiled state and deep-copies event callbacks). A cached cfunc has
scratch buffers, so whoever caches one also caches a lock to call it under.

Keys are tuples whose first item names what is built (``"integrator"``, ``"batch"``,
``"cfunc"``, ``"tangent"``, ...), followed by everything the compiled code depends on:
the system and formulation, the number type, the tolerance, compact mode, events. The
parameters are never part of a key: they are runtime ``hy.par[i]``, so one compiled
object serves every ball.

heyoka keeps its own caches below this one: compiled LLVM modules in memory and on disk
(``heyoka.llvm_state.get_diskcache_path()``, ``~/.cache/heyoka`` by default), so a
second process compiling the same graph takes a fraction of the first compile.

Logging (logger ``taylorball.compile``; the library installs no handler, the
``taylorball`` command shows INFO): one INFO line before each build, the first of a
process naming heyoka's disk cache folder, and a DEBUG line after it with its wall time.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Callable, Dict, Hashable, Tuple, TypeVar

__all__ = ["compiled", "cached_keys", "clear"]

T = TypeVar("T")

_log = logging.getLogger("taylorball.compile")
_DESCRIBE_MAX = 80  # characters of a key shown in the compile notice

_ENTRIES: Dict[Hashable, object] = {}
_LOCKS: Dict[Hashable, threading.Lock] = {}
_GUARD = threading.Lock()
_NOTICED = False  # whether this process has logged a compile notice (the first names the disk cache)


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
        if _log.isEnabledFor(logging.INFO):
            _log.info("compiling %s (first use in this process%s)", _describe(key, brief=True),
                      _disk_cache_note())
        t0 = time.perf_counter()
        obj = build()
        _log.debug("built %s in %.2f s", _describe(key), time.perf_counter() - t0)
        with _GUARD:
            _ENTRIES[key] = obj
        return obj


def _describe(key, brief: bool = False) -> str:
    """The key as words; ``brief``: without the flags (bare booleans, e.g. compact mode),
    cut to ``_DESCRIBE_MAX`` characters."""
    text = " ".join(str(k) for k in key if k is not None and not (brief and isinstance(k, bool)))
    return text if not brief or len(text) <= _DESCRIBE_MAX else text[: _DESCRIBE_MAX - 3] + "..."


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


def cached_keys() -> list:
    """The keys built so far in this process (for tests and diagnostics)."""
    with _GUARD:
        return list(_ENTRIES)


def clear() -> None:
    """Forget every compiled object of this process (heyoka's own caches stay)."""
    with _GUARD:
        _ENTRIES.clear()
        _LOCKS.clear()
