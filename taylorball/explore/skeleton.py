"""Periodic orbits on the explorer's level: :func:`taylorball.periodic_orbits` (a search of
the level) or :func:`taylorball.periodic_orbit` (Newton from a clicked point), run in a
child process so that the page never waits and *Cancel* really stops the work (the child
is killed; a Python thread could only be abandoned).

The child is started with the ``spawn`` method (no fork of the server's threads); it
imports taylorball and takes the compiled integrators from heyoka's disk cache. What it
returns is plain data (:class:`FoundOrbit`), pickled exactly: the points drawn are the
bits of the package's call.
"""

from __future__ import annotations

import multiprocessing as mp
import queue
import threading
import time
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from ..errors import UsageError

__all__ = ["FoundOrbit", "SearchResult", "SkeletonRunner", "run_job", "search_job", "newton_job"]

#: Options of the level search the page uses (small: seconds on the Fig. 1 level; a reduced
#: level takes tens of CPU seconds, see docs/skeleton.md).
SEARCH_OPTIONS: Dict[str, Any] = {"n_grid": 120, "n_seeds": 12, "n_points": 100, "per_k": 8, "reversor_seeds": 4}


#: Bokeh markers of the stabilities (colours: :data:`taylorball.palette.STABILITY_COLORS`).
MARKERS = {"elliptic": "circle", "hyperbolic": "x", "parabolic": "square"}


@dataclass(frozen=True)
class FoundOrbit:
    """A periodic orbit as the page shows it: the fields of
    :class:`taylorball.PeriodicOrbit` it draws and hovers."""

    k: int
    period: float
    points: np.ndarray  #: (k, 3) ``(l, r1, r2)`` or (k, 2) ``(l, L/G)``
    multipliers: np.ndarray
    residual: float
    stability: str
    type: str
    state: np.ndarray
    symmetric: Optional[str]

    @classmethod
    def of(cls, o: Any) -> "FoundOrbit":
        return cls(int(o.k), float(o.period), np.asarray(o.points, dtype=float), np.asarray(o.multipliers),
                   float(o.residual), str(o.stability), str(o.type), np.asarray(o.state, dtype=float), o.symmetric)

    def multipliers_text(self) -> str:
        return ", ".join(f"{m.real:.6g}" + (f"{m.imag:+.4g}i" if m.imag != 0 else "") for m in self.multipliers)


@dataclass(frozen=True)
class SearchResult:
    """What a job returned: the orbits found (maybe none), or the error that stopped it."""

    what: str  #: "search" or "newton"
    orbits: Tuple[FoundOrbit, ...]
    seeds: int = 0
    failures: int = 0
    error: str = ""
    cpu: float = 0.0


def search_job(kind: str, params: Any, levels: Any, k_max: int, options: Dict[str, Any]) -> SearchResult:
    """:func:`taylorball.periodic_orbits` on the level (what the child runs)."""
    from ..periodic_search import SearchOptions, periodic_orbits

    t0 = time.process_time()
    opts = dict(options)
    n_points = int(opts.pop("n_points", 200))  # a keyword of its own; the rest are SearchOptions
    rep = periodic_orbits(kind, params, levels, k_max=k_max, n_points=n_points,  # type: ignore[arg-type]
                          report=True, options=SearchOptions(**opts))
    return SearchResult("search", tuple(FoundOrbit.of(o) for o in rep.orbits),  # type: ignore[union-attr]
                        seeds=sum(rep.seeds.values()), failures=rep.failures,  # type: ignore[union-attr]
                        cpu=time.process_time() - t0)


def newton_job(kind: str, params: Any, levels: Any, state: np.ndarray, k: int) -> SearchResult:
    """:func:`taylorball.periodic_orbit` from one guess on the level (what the child runs)."""
    from ..periodic import periodic_orbit

    t0 = time.process_time()
    o = periodic_orbit(kind, params, state, k, levels=levels)  # type: ignore[arg-type]
    return SearchResult("newton", (FoundOrbit.of(o),), seeds=1, cpu=time.process_time() - t0)


def run_job(job: Tuple[str, tuple]) -> SearchResult:
    """Run ``("search", args)`` or ``("newton", args)``; a package error becomes the
    result's ``error`` (shown on the page)."""
    from ..errors import TaylorballError

    what, args = job
    try:
        return search_job(*args) if what == "search" else newton_job(*args)
    except TaylorballError as e:
        return SearchResult(what, (), error=f"{type(e).__name__}: {e}")


def _child(conn: Any, job: Tuple[str, tuple]) -> None:
    try:
        out = run_job(job)
    except Exception as e:  # anything else: reported, never a silent child
        out = SearchResult(job[0], (), error=f"{type(e).__name__}: {e}")
    conn.send(out)
    conn.close()


class SkeletonRunner:
    """One periodic-orbit job at a time in a child process; its result (or ``None`` when
    cancelled) is put on :attr:`events` as ``("skeleton", token, result)``."""

    def __init__(self) -> None:
        self.events: "queue.Queue[tuple]" = queue.Queue()
        self._lock = threading.Lock()
        self._proc: Optional[Any] = None
        self._token = 0

    @property
    def running(self) -> bool:
        return self._proc is not None and self._proc.is_alive()

    def start(self, job: Tuple[str, tuple]) -> int:
        """Start ``job`` (cancelling a running one); returns its token."""
        if job[0] not in ("search", "newton"):
            raise UsageError(f"job must be ('search', ...) or ('newton', ...), got {job[0]!r}")
        self.cancel()
        ctx = mp.get_context("spawn")
        recv, send = ctx.Pipe(duplex=False)
        proc = ctx.Process(target=_child, args=(send, job), daemon=True, name="taylorball-skeleton")
        with self._lock:
            self._token += 1
            token = self._token
            proc.start()
            send.close()
            self._proc = proc
        threading.Thread(target=self._wait, args=(proc, recv, token), daemon=True,
                         name="taylorball-skeleton-wait").start()
        return token

    def _wait(self, proc: Any, recv: Any, token: int) -> None:
        try:
            out: Optional[SearchResult] = recv.recv()
        except (EOFError, OSError):  # killed (cancelled) or died
            out = None
            if proc.exitcode not in (None, -9, -15):
                out = SearchResult("search", (), error=f"the search process ended with exit code {proc.exitcode}")
        proc.join(timeout=10)
        self.events.put(("skeleton", token, out))

    def cancel(self) -> bool:
        """Kill the running job (its result will be ``None``); ``True`` if one was running."""
        with self._lock:
            proc, self._proc = self._proc, None
        if proc is not None and proc.is_alive():
            proc.kill()
            return True
        return False

    def shutdown(self) -> None:
        self.cancel()


def point_rows(orbits: List[FoundOrbit], kind: str) -> Dict[str, list]:
    """The rows the page draws: one per section point of each orbit, with its hover text."""
    from ..palette import STABILITY_COLORS

    rows: Dict[str, list] = {k: [] for k in ("x", "y", "l", "orbit", "k", "period", "stability", "type",
                                             "multipliers", "residual", "marker", "color")}
    for i, o in enumerate(orbits):
        stab = o.stability if o.stability in STABILITY_COLORS else "parabolic"
        marker, color = MARKERS[stab], STABILITY_COLORS[stab]
        for p in o.points:
            x, y = (float(p[1]), float(p[2])) if kind == "reduced" else (float(p[0]), float(p[1]))
            for col, val in zip(rows, (x, y, float(p[0]), i, o.k, o.period, o.stability, o.type,
                                       o.multipliers_text(), o.residual, marker, color)):
                rows[col].append(val)
    return rows
