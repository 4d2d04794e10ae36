"""A study's progress: :class:`StudyStatus` and :func:`study_status` (read only)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Optional, Tuple

import numpy as np

from ..errors import UsageError
from ..sections import batch_size
from .config import StudyConfig, StudyLike, _as_config
from .job import _open_checked, study_store


@dataclass(frozen=True)
class StudyStatus:
    """Progress of a study: one row per orbit (``orbits``: dicts with ``index``, ``t_done``,
    ``chunks``, ``n_steps``, ``max_drift`` (largest relative integral drift so far, None
    without the drift observable), ``wall_per_chunk`` (s), ``eta`` (s, this orbit alone)),
    the requested ``t_end`` and its ``n_chunks``, the store, and the study's ``eta`` with
    ``workers``, each running ``per_worker`` orbits at once (the lanes of a batch
    integrator with ``backend = "lanes"``, whose orbits' wall times per chunk are their
    shares of their worker's time)."""

    store: Path
    t_end: float
    fingerprint: str
    orbits: Tuple[Dict[str, Any], ...]
    workers: int = 1
    n_chunks: int = 0
    per_worker: int = 1

    @property
    def complete(self) -> bool:
        """Every orbit has run its ``n_chunks`` chunks (counted, not compared as times: a
        ``t_end`` within rounding of ``n_chunks * checkpoint_every`` is that end)."""
        return all(o["chunks"] >= self.n_chunks for o in self.orbits)

    @property
    def eta(self) -> Optional[float]:
        """Estimated seconds left for the whole study: each orbit's estimate (an orbit with
        no timed chunk yet at the mean wall time per chunk of the others), shared by
        ``workers`` (at most one per ``per_worker`` orbits with work left); None if no
        chunk was timed."""
        timed = [o["wall_per_chunk"] for o in self.orbits if o["wall_per_chunk"] is not None]
        if not timed:
            return None
        mean = float(np.mean(timed))
        left = [o["eta"] if o["eta"] is not None else max(self.n_chunks - o["chunks"], 0) * mean
                for o in self.orbits]
        busy = sum(1 for v in left if v > 0)
        return sum(left) / max(1, min(self.workers, -(-busy // max(1, self.per_worker))))

    def table(self) -> str:
        """A plain-text table, one line per orbit."""
        lines = [f"store {self.store}  t_end {self.t_end:g}  fingerprint {self.fingerprint}",
                 f"{'orbit':>5} {'t done':>12} {'chunks':>7} {'steps':>12} {'max drift':>10} {'s/chunk':>8} "
                 f"{'eta (s)':>9}"]
        for o in self.orbits:
            drift = "-" if o["max_drift"] is None else f"{o['max_drift']:.2e}"
            wpc = "-" if o["wall_per_chunk"] is None else f"{o['wall_per_chunk']:.3f}"
            eta = "-" if o["eta"] is None else f"{o['eta']:.0f}"
            lines.append(f"{o['index']:>5} {o['t_done']:>12g} {o['chunks']:>7} {o['n_steps']:>12} {drift:>10} "
                         f"{wpc:>8} {eta:>9}")
        total = self.eta
        lines.append("estimated time left: " + ("unknown (no chunk timed yet)" if total is None else
                                                f"{total:.0f} s with {self.workers} worker(s)"))
        return "\n".join(lines)


def _lanes_per_worker(cfg: StudyConfig) -> int:
    """Orbits a worker runs at once: the batch size with lanes, else 1."""
    if cfg.backend != "lanes":
        return 1
    return batch_size()


def study_status(study: StudyLike) -> StudyStatus:
    """Per-orbit progress of a study's store (nothing is computed or written).

    Parameters
    ----------
    study : str, os.PathLike or StudyConfig
        The study file (or a loaded study).

    Raises
    ------
    UsageError
        A bad study file, or no store yet.
    StoreError
        A store made by another study (fingerprint), or a corrupt orbit (named).
    """
    cfg = _as_config(study)
    store = study_store(cfg)
    if not store.exists():
        raise UsageError(f"{cfg.source}: no store at {cfg.store} yet: run `taylorball run {cfg.source}` first")
    store_, cks = _open_checked(cfg)
    t_end = max(float(store.attrs().get("t_end", cfg.t_end)), cfg.t_end)
    n_total = cfg.n_chunks(t_end)
    rows = []
    for i, ck in enumerate(cks):
        ck = ck or {}
        chunks = int(ck.get("chunks", 0))
        drift = None
        carry = ck.get("carries", {}).get("drift")
        if carry is not None:
            drift = max(carry["max"]["data"])
        wpc = ck["wall_total"] / ck["wall_chunks"] if ck.get("wall_chunks") else None
        rows.append({"index": i, "t_done": chunks * cfg.checkpoint_every if chunks else 0.0, "chunks": chunks,
                     "n_steps": int(ck.get("n_steps", 0)), "max_drift": drift, "wall_per_chunk": wpc,
                     "eta": None if wpc is None else max(n_total - chunks, 0) * wpc})
    workers = cfg.workers or (1 if cfg.backend == "serial" else (os.cpu_count() or 1))
    return StudyStatus(store=cfg.store, t_end=t_end, fingerprint=cfg.fingerprint(), orbits=tuple(rows),
                       workers=workers, n_chunks=n_total, per_worker=_lanes_per_worker(cfg))
