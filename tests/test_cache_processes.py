"""Builds shared between processes (``taylorball._cache.share_builds_between_processes``):
the lock file of a key makes a second build of the same key wait for the first, so that it
loads the first one's machine code from heyoka's disk cache instead of compiling it again.

``flock`` locks belong to an open file, so two threads that each open the key's lock file
contend like two processes do; the tests use threads and sleeps instead of compiling."""

from __future__ import annotations

import threading
import time

import pytest

from taylorball import _cache

pytest.importorskip("fcntl")


@pytest.fixture
def locks(tmp_path, monkeypatch):
    monkeypatch.setattr(_cache, "_lock_folder", lambda: str(tmp_path / "locks"))
    monkeypatch.setattr(_cache, "_SHARE_BETWEEN_PROCESSES", False)
    return tmp_path / "locks"


def _two_builds(key_a, key_b, hold=1.0, notice=False):
    """Build A holds its lock for ``hold`` s; build B asks for its own lock 0.05 s after A
    took its lock (``notice``: B says so if it waits). Returns (A's end, B's start) in
    perf_counter seconds."""
    times = {}
    taken = threading.Event()

    def a():
        with _cache._process_lock(key_a):
            taken.set()
            time.sleep(hold)
            times["a_end"] = time.perf_counter()

    t = threading.Thread(target=a)
    t.start()
    assert taken.wait(10)
    time.sleep(0.05)
    with _cache._process_lock(key_b, notice):
        times["b_start"] = time.perf_counter()
    t.join()
    return times["a_end"], times["b_start"]


def test_a_second_build_of_the_same_key_waits_for_the_first(locks, caplog):
    _cache.share_builds_between_processes(True)
    with caplog.at_level("INFO", logger="taylorball.compile"):
        a_end, b_start = _two_builds(("test", "same", 1.5), ("test", "same", 1.5), notice=True)
    assert b_start >= a_end
    assert len(list(locks.iterdir())) == 1  # one lock file per key, left in place
    waits = [r.getMessage() for r in caplog.records if r.getMessage().startswith("waiting for another process")]
    assert waits == ["waiting for another process compiling test same 1.5 (then heyoka's disk cache has it)"]


def test_other_keys_and_sharing_off_do_not_wait(locks):
    _cache.share_builds_between_processes(True)
    a_end, b_start = _two_builds(("test", "one"), ("test", "two"))
    assert b_start < a_end  # another key: its own lock file
    _cache.share_builds_between_processes(False)
    a_end, b_start = _two_builds(("test", "same"), ("test", "same"))
    assert b_start < a_end  # off: no lock at all
    assert len(list(locks.iterdir())) == 2  # the two keys of the first half


def test_a_build_waits_at_most_the_limit_and_unportable_keys_are_not_locked(locks, monkeypatch):
    _cache.share_builds_between_processes(True)
    monkeypatch.setattr(_cache, "PROCESS_LOCK_WAIT_S", 0.05)
    a_end, b_start = _two_builds(("test", "stuck"), ("test", "stuck"), hold=1.0)
    assert b_start < a_end  # gave up waiting after ~0.05 s and built unlocked
    obj = object()  # its repr holds an address: not the same key in another process
    assert _cache._lock_file(("test", obj)) is None


def test_a_file_system_without_locks_builds_at_once(locks, monkeypatch):
    import fcntl

    def no_locks(fd, op):
        raise OSError(37, "No locks available")

    _cache.share_builds_between_processes(True)
    monkeypatch.setattr(fcntl, "flock", no_locks)
    t0 = time.perf_counter()
    with _cache._process_lock(("test", "nfs")):
        waited = time.perf_counter() - t0
    assert waited < 1.0  # not the PROCESS_LOCK_WAIT_S of a held lock
