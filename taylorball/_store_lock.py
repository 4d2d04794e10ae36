"""Lock files of the run store: one writer per orbit, one coordinating run per store.

A lock is a file created with ``O_CREAT | O_EXCL`` holding its holder's host, pid and
process start time (the writer touches it after every chunk: a heartbeat). A live holder
on this host is refused (naming host and pid), a dead one (no such pid, a zombie, or a pid
reused by a younger process) is stale and taken over; a holder on another host is refused
unless its lock has not been touched for :data:`HEARTBEAT_TIMEOUT` seconds. A lock file
that is not a lock (not the JSON a writer writes) is refused, naming it, and never deleted.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import socket
import time
from pathlib import Path
from typing import Any, Dict, Mapping, Optional

from .errors import StoreError

__all__ = ["HEARTBEAT_TIMEOUT", "Lock"]

#: A lock held by a process on another host is taken over when its file has not been
#: touched (the writer touches it after every chunk) for this many seconds.
HEARTBEAT_TIMEOUT = 600.0


def _proc_start(pid: int) -> Optional[str]:
    """The start time of process ``pid`` in clock ticks since boot (Linux), to tell a pid
    reused by another process from the original; None where /proc is not available."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
        return fields[19]
    except (OSError, IndexError):
        return None


def _alive(pid: int, start: Optional[str]) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat") as fh:
            state = fh.read().rsplit(")", 1)[1].split()[0]
        if state in ("Z", "X"):  # a zombie: dead, not yet reaped by its parent
            return False
    except (OSError, IndexError):
        pass
    now = _proc_start(pid)
    return start is None or now is None or now == start


def _me() -> Dict[str, Any]:
    return {"host": socket.gethostname(), "pid": os.getpid(), "proc_start": _proc_start(os.getpid()),
            "started": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}


class Lock:
    """An ``O_CREAT | O_EXCL`` lock file naming its holder; see the module docstring.

    ``what`` names the locked thing in messages (``"orbit 3 of STORE"``)."""

    def __init__(self, path: Path, what: str) -> None:
        self.path = Path(path)
        self.what = what
        self.held = False

    def acquire(self) -> "Lock":
        me = _me()
        for _ in range(5):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                self._judge_holder(me)
                continue
            with os.fdopen(fd, "w") as fh:
                json.dump(me, fh)
            self.held = True
            return self
        raise StoreError(f"{self.what}: could not take the lock {self.path} (contended); try again")

    def _judge_holder(self, me) -> None:
        """Raise if the holder is live; remove the lock file if it is stale."""
        if self._holder_is_live(me):
            return  # a lock file being written or released meanwhile: try again
        try:  # stale: its holder is dead
            self.path.unlink()
        except FileNotFoundError:
            pass

    def _holder_is_live(self, me: Mapping[str, Any]) -> bool:
        """Raise StoreError if the lock is held by a live process (or is not a lock);
        True if the file is being written or went away meanwhile (look again), False
        if its holder is dead."""
        try:
            text = self.path.read_text()
            mtime = self.path.stat().st_mtime
        except FileNotFoundError:
            return True  # released meanwhile: try again
        except (OSError, UnicodeDecodeError) as exc:
            raise StoreError(f"{self.what}: the lock file {self.path} cannot be read ({exc}); if no run is writing "
                             "it, delete that file") from None
        age = time.time() - mtime
        try:
            holder = json.loads(text)
            host, pid = holder["host"], int(holder["pid"])
            if not isinstance(host, str):
                raise TypeError(host)
        except (ValueError, KeyError, TypeError):
            if not text.strip() and age < 10.0:  # just created, its content not yet written
                return True
            raise StoreError(f"{self.what}: the lock file {self.path} is unreadable (not a lock written by taylorball: "
                             f"{text[:60]!r}); if no run is writing it, delete that file") from None
        if host == me["host"]:
            if pid == me["pid"] and holder.get("proc_start") == me["proc_start"]:
                raise StoreError(f"{self.what} is already being written by this process (pid {pid})")
            if _alive(pid, holder.get("proc_start")):
                raise StoreError(f"{self.what} is locked by a running process: pid {pid} on host {host} "
                                 f"(started {holder.get('started')}); only one run may write it at a time: wait for "
                                 f"that run to end or stop it ({self.path})")
        elif age < HEARTBEAT_TIMEOUT:  # another host
            raise StoreError(f"{self.what} is locked by pid {pid} on host {host} (lock touched {age:.0f} s ago); "
                             f"a lock of another host is taken over only after {HEARTBEAT_TIMEOUT:.0f} s "
                             f"without a heartbeat; if that process is dead, delete {self.path}")
        return False

    def check(self) -> None:
        """Raise StoreError (naming the holder) if the lock is held by a live process or
        its file is not a lock; nothing is changed (a stale lock is taken over later by
        :meth:`acquire`)."""
        if self.path.exists():
            self._holder_is_live(_me())

    def touch(self) -> None:
        if self.held:
            os.utime(self.path)

    def release(self) -> None:
        if self.held:
            self.held = False
            try:
                self.path.unlink()
            except FileNotFoundError:
                pass

    def __enter__(self) -> "Lock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()
