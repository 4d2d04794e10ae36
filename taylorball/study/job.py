"""The store of a study (:func:`study_store`, the one place a study opens it; creation and
the start-up check) and one orbit's job in it, whatever integrates the orbit: its lock,
checks, start state and per-chunk commit (shared by the scalar runner and the lanes)."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Sequence, Tuple

import numpy as np

from ..errors import StoreError
from ..io import provenance
from ..observables import ChunkData
from .._propagate import public_states, start_state
from .._signals import held_signals
from ..store import FORMAT_VERSION, RunStore, genesis, pack_carry, unpack_carry
from .config import StudyConfig


def study_store(cfg: StudyConfig) -> RunStore:
    """The study's run store (``[output] store``): every part of the runner opens it here."""
    return RunStore(cfg.store)


# ---------------------------------------------------------------------------------------
# The store of a study.
# ---------------------------------------------------------------------------------------
def _layouts(cfg: StudyConfig, prob, objs) -> Dict[str, Dict[str, Any]]:
    return {o.name: o.layout(prob) for o in objs}


def _create_store(cfg: StudyConfig, path: Path, t_end: float) -> None:
    X = cfg.initial_states
    orbits = [{"fingerprint": cfg.orbit_fingerprint(i), "index": i, "initial_state": [float(v) for v in X[i]]}
              for i in range(len(X))]
    RunStore(path).create({"format": FORMAT_VERSION, "study": cfg.as_dict(), "fingerprint": cfg.fingerprint(),
                           "provenance": provenance(), "t_end": t_end}, orbits,
                          _layouts(cfg, cfg.problem(), cfg.observable_objects()))  # the layout, sealed


def _open_checked(cfg: StudyConfig):
    """The study's store after the start-up check (root fingerprint and every orbit);
    returns ``(store, checkpoints)``."""
    store = study_store(cfg)
    attrs = store.check_root()  # format and root seal
    if attrs.get("fingerprint") != cfg.fingerprint():
        other = dataclasses.replace(cfg, backend="threads" if cfg.backend == "lanes" else "lanes")
        if attrs.get("fingerprint") == other.fingerprint():
            was = attrs.get("study", {}).get("backend", other.backend)
            raise StoreError(f"{store.path} was written by backend {was!r} ({other.integrator_family} integrators) "
                             f"and cannot be resumed or extended by backend {cfg.backend!r} ({cfg.integrator_family} "
                             "integrators): the two give different bits; set [run] backend back to "
                             f"{was!r} (any scalar backend resumes a scalar store), use another [output] store, "
                             "or --restart to replace it")
        raise StoreError(f"{store.path} was made by another study (fingerprint {attrs.get('fingerprint')} != "
                         f"{cfg.fingerprint()} of {cfg.source}): its ball, level, orbits, number type, chunking or "
                         "observables differ; use another [output] store, or --restart to replace it")
    prob = cfg.problem()
    layouts = _layouts(cfg, prob, cfg.observable_objects())
    cks = [store.orbit(i).verify(cfg.orbit_fingerprint(i), layouts, study_fingerprint=attrs["fingerprint"],
                                 chunks_written=True) for i in range(cfg.n_orbits)]  # also initial states
    return store, cks


# ---------------------------------------------------------------------------------------
# One orbit.
# ---------------------------------------------------------------------------------------
def _save_state(arr: Any) -> np.ndarray:
    """Exact serialisation of a state array of any supported dtype: float64 as it is,
    other types as their shortest round-trip digits."""
    a = np.asarray(arr)
    if a.dtype == np.float64:
        return a.copy()
    return np.array([str(v) for v in a.reshape(-1)])


def _load_state(saved: Any, spec: Any) -> np.ndarray:
    """The state :func:`_save_state` wrote, in the number type ``spec``."""
    saved = np.asarray(saved)
    if saved.dtype.kind == "f":
        return spec.array(saved)
    out = np.empty(len(saved), dtype=spec.dtype)
    for i, s in enumerate(saved):
        out[i] = np.longdouble(str(s)) if spec.name == "longdouble" else _from_str(str(s), spec)
    return out


def _from_str(s: str, spec: Any) -> Any:
    import heyoka as hy

    if spec.name == "real128":
        return hy.real128(s)
    if spec.name == "real":
        return hy.real(s, spec.prec)
    return float(s)


def _exact_list(a: np.ndarray) -> list:
    s = _save_state(a)
    return [float(v) for v in s] if s.dtype == np.float64 else [str(v) for v in s]


def _from_list(values: list, spec) -> np.ndarray:
    return _load_state(np.array(values, dtype=float if all(isinstance(v, float) for v in values) else str), spec)


class _OrbitJob:
    """One orbit's job in the store, whatever integrates it: its lock, the checks of its
    fingerprint and checkpoint, the state to start from, and per chunk the observables'
    reduction of a :class:`~taylorball.observables.ChunkData` and the commit (shared by the
    scalar runner :func:`_run_orbit` and the lanes, :func:`_run_lanes`)."""

    def __init__(self, cfg: StudyConfig, i: int, t_end: float, prob, objs, layouts) -> None:
        self.cfg, self.i, self.prob, self.objs, self.layouts = cfg, i, prob, objs, layouts
        self.orb = study_store(cfg).orbit(i)
        self.fp = cfg.orbit_fingerprint(i)
        self.n_total = cfg.n_chunks(t_end)
        self.lock: Any = None
        self.ck: Optional[Dict[str, Any]] = None
        self.cleaned = False  # the arrays were cut to the checkpoint: close() may trim

    def open(self) -> int:
        """Take the orbit's lock, check it, clean a killed writer's leftovers; returns the
        chunks already committed."""
        orb, fp = self.orb, self.fp
        self.lock = orb.lock().acquire()
        self.attrs = attrs = orb.attrs()
        ck = orb.check_attrs(fp, self.cfg.fingerprint(), attrs)  # fingerprint, initial state, seal
        self.ck = ck
        # leftovers of a killed writer (uncommitted rows, temporaries) go first, also when
        # nothing is left to run: a kill after the last commit and before the trim at the
        # end of the job left arrays longer than committed (found by the slow kill -9 test)
        orb.clean(self.layouts, ck)
        self.cleaned = True
        return int(ck["chunks"]) if ck else 0

    def start(self) -> Tuple[np.ndarray, Optional[Tuple[Any, Any]]]:
        """The internal state to go on from and its double-length time ``(hi, lo)`` (None
        at the orbit's start, time 0); sets the carries and counters."""
        prob, spec, ck = self.prob, self.prob.spec, self.ck
        x0 = start_state(prob, np.array(self.attrs["initial_state"], dtype=float))
        if ck:
            self.carries = {o.name: unpack_carry(ck["carries"][o.name]) for o in self.objs}
            self.n_steps, self.h = int(ck["n_steps"]), bytes.fromhex(ck["digest"])
            self.lengths = dict(ck["lengths"])
            self.wall_total, self.wall_chunks = float(ck["wall_total"]), int(ck["wall_chunks"])
            hi, lo = _from_list(ck["dtime"], spec)
            return _from_list(ck["state"], spec), (hi, lo)
        self.carries = {o.name: o.init(prob, x0, 0.0) for o in self.objs}
        self.n_steps, self.h, self.lengths = 0, genesis(self.fp), {}
        self.wall_total, self.wall_chunks = 0.0, 0
        return x0, None

    def grid(self, k: int) -> Tuple[np.ndarray, np.ndarray]:
        """Chunk ``k``'s sample indices ``m`` and times ``t = m * sample_dt`` (both ends)."""
        per = self.cfg.samples_per_chunk
        m = np.arange(k * per, (k + 1) * per + 1, dtype=np.int64)
        return m, m * self.cfg.sample_dt

    def commit(self, k: int, m: np.ndarray, t: np.ndarray, X: np.ndarray, events: Sequence[Mapping[int, list]],
               steps: int, state: np.ndarray, dtime: Tuple[Any, Any], w0: float,
               share: float = 1.0) -> Dict[str, Any]:
        """Reduce chunk ``k`` (grid ``m``, ``t``, internal states ``X`` there, each
        observable's event records) by the observables and commit it with the checkpoint
        (end ``state``, double-length time ``dtime``; the chunk's wall time is ``share`` of
        the time since ``time.perf_counter()`` was ``w0``)."""
        prob, spec = self.prob, self.prob.spec
        self.n_steps += steps
        public = public_states(prob, X).astype(float)
        records: Dict[str, Any] = {}
        shared: Dict[str, Any] = {}  # what the observables of this chunk compute once (ChunkData.jets)
        for o, own in zip(self.objs, events):
            data = ChunkData(k=k, t0=float(t[0]), t1=float(t[-1]), t=t, i=m, x=X, public=public, events=own,
                             problem=prob, n_steps=steps, sample_dt=self.cfg.sample_dt, shared=shared)
            self.carries[o.name], records[o.name] = o.chunk(self.carries[o.name], data)
        wall = (time.perf_counter() - w0) * share
        hi, lo = dtime
        ck_new = {"t": float(t[-1]), "state": _exact_list(np.array(state)),
                  "dtime": _exact_list(np.array([hi, lo], dtype=spec.dtype)), "n_steps": self.n_steps,
                  "carries": {name: pack_carry(c) for name, c in self.carries.items()},
                  "lengths_before": self.lengths, "wall_total": self.wall_total + wall,
                  "wall_chunks": self.wall_chunks + 1, "wall_last": wall}
        with held_signals():  # an interrupt lands after the commit, not inside it (taylorball._signals)
            ck, self.h = self.orb.append(self.fp, k, self.layouts, records, ck_new, self.h)
            self.ck = ck
            self.lengths = dict(ck["lengths"])
            self.wall_total, self.wall_chunks = self.wall_total + wall, self.wall_chunks + 1
        self.lock.touch()
        return ck

    def close(self) -> None:
        """Cut the arrays to the committed lengths and release the lock. The lengths are
        the stored checkpoint's: an interrupt (Ctrl-C) may land after a commit and before
        :meth:`commit` returns."""
        if self.lock is None:
            return
        try:
            if self.cleaned:
                self.orb.trim(self.layouts, self.orb.checkpoint())
        finally:
            self.lock.release()
            self.lock = None
