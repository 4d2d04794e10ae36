"""Signals held back while a piece of work must not be cut: :func:`held_signals`.

Python runs a signal's handler in the main thread, between two bytecodes: Ctrl-C's
``KeyboardInterrupt`` (or the study runner's ``Terminated`` on SIGTERM) can land anywhere
in code that runs there. Where that code is a commit (a store's rows, then its checkpoint,
whose write zarr finishes in its own I/O thread while the main thread waits for it), an
interrupt in the middle leaves the in-memory state behind the files: the clean-up that
follows then acts on a stale checkpoint. Holding the signals over the commit
(:meth:`taylorball.study.job.Job.commit`) moves the interrupt to its end; holding Ctrl-C
while the lane pool starts its threads (:func:`taylorball._lanes._start_all`) lets the
pool's handler stop every thread that was started."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from typing import Any, Iterator, List, Sequence

__all__ = ["held_signals"]


@contextlib.contextmanager
def held_signals(signums: Sequence[int] = (signal.SIGINT, signal.SIGTERM)) -> Iterator[None]:
    """In the main thread, hold the signals ``signums`` back for the ``with`` block and then
    deliver them as the handlers in force would have (a Python handler is called, so Ctrl-C
    raises ``KeyboardInterrupt`` after the block; ``SIG_DFL`` is re-sent to the process;
    ``SIG_IGN``: nothing). In another thread it does nothing (signals are handled in the
    main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: List[int] = []
    previous: dict = {}
    try:
        for s in signums:
            previous[s] = signal.signal(s, lambda signum, frame: held.append(signum))
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        for s in dict.fromkeys(held):  # each signal once, in the order it came
            h2: Any = previous[s]
            if callable(h2):
                h2(s, None)
            elif h2 == signal.SIG_DFL:
                os.kill(os.getpid(), s)
