"""Many orbits of a study in the SIMD lanes of float64 batch integrators (``backend =
"lanes"``) on the engine's one lane adapter (:func:`taylorball.ensemble.orbit_lanes`): the
event views (:class:`_LaneView`, :class:`_LaneCallback`: an observable's scalar event
callback run unchanged on one lane of a batch integrator), the cached batch template and
:func:`_run_lanes`."""

from __future__ import annotations

import copy
import time
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np

from .._cache import compiled
from ..ensemble import LaneLoad, orbit_lanes
from ..errors import IntegrationError, StoreError, UsageError
from ..observables import events_key
from ..sections import batch_size
from .config import StudyConfig
from .job import _layouts, _OrbitJob


class _LaneView:
    """What a scalar event callback reads of its integrator (``dtime``, ``pars``,
    ``last_h``, ``update_d_output(rel, rel_time=True)``), for one lane of a batch
    integrator: so the observables' own callbacks (:class:`taylorball.sections._Collector`,
    the lifted angle's cut collector) run unchanged in lanes."""

    __slots__ = ("ta", "lane", "rel")

    def __init__(self, ta: Any, lane: int, rel: np.ndarray) -> None:
        self.ta, self.lane, self.rel = ta, lane, rel

    @property
    def dtime(self) -> Tuple[float, float]:
        hi, lo = self.ta.dtime
        return float(hi[self.lane]), float(lo[self.lane])

    @property
    def pars(self) -> np.ndarray:
        return np.ascontiguousarray(self.ta.pars[:, self.lane])

    @property
    def last_h(self) -> float:
        return float(self.ta.last_h[self.lane])

    def update_d_output(self, t: float, rel_time: bool = False) -> np.ndarray:
        if not rel_time:
            raise UsageError("an event callback in lanes must ask for the dense output with rel_time=True")
        self.rel[self.lane] = t  # the other lanes' entries are stale and their outputs unused
        return np.array(self.ta.update_d_output(self.rel, rel_time=True)[:, self.lane], copy=True)


class _LaneCallback:
    """A batch event's callback (``nt_event_batch``: heyoka passes the lane index): one
    copy of the observable's scalar callback per lane, called with a :class:`_LaneView` of
    its lane; the lane's records are read from ``lanes[lane].times`` / ``.states``."""

    def __init__(self, proto: Any, size: int) -> None:
        self.proto, self.size = proto, size
        self.lanes = [copy.deepcopy(proto) for _ in range(size)]
        self.rel = np.zeros(size)

    def __deepcopy__(self, memo: Any) -> "_LaneCallback":
        return _LaneCallback(self.proto, self.size)

    def __call__(self, ta: Any, t: float, d_sgn: Any, idx: int) -> None:
        self.lanes[idx](_LaneView(ta, idx, self.rel), t, d_sgn)


def _lane_callback(proto: Any, size: int) -> Any:
    """A batch event's callback from an observable's scalar one: its own lanes form
    (``proto.for_lanes(size)``, the same records without a view per call) where it has one,
    else :class:`_LaneCallback` around it."""
    own = getattr(proto, "for_lanes", None)
    return own(size) if own is not None else _LaneCallback(proto, size)


def _lane_template(prob, objs, size: int):
    """The cached float64 batch integrator of ``size`` lanes with the observables' events
    in batch form; returns it and the observables' scalar events (per observable)."""
    import heyoka as hy

    evs = [o.events(prob) for o in objs]
    flat = [e for lst in evs for e in lst]
    key = ("batch", *prob.compile_key, size, "observables") + tuple(
        events_key(o) for o, lst in zip(objs, evs) if lst)

    def build():
        system = prob.system
        kw: Dict[str, Any] = dict(pars=np.zeros((system.n_pars, size)))
        if flat:
            kw["nt_events"] = [hy.nt_event_batch(ev.expression, _lane_callback(ev.callback, size),
                                                 direction=ev.direction) for ev in flat]
        if prob.tol is not None:
            kw["tol"] = float(prob.tol)
        return hy.taylor_adaptive_batch(system.equations(), np.full((system.dim, size), 0.1), **kw)

    return compiled(key, build), evs


def _uses_grid(obs) -> bool:
    """Whether an observable reads the chunk's sample grid (``ChunkData.t``, ``x``,
    ``public``); an observable says it does not by ``uses_grid() -> False``."""
    own = getattr(obs, "uses_grid", None)
    return True if own is None else bool(own())


def _run_lanes(cfg: StudyConfig, todo: Sequence[int], t_end: float, workers: Optional[int], progress: Any) -> None:
    """Run (or resume) the orbits ``todo`` to ``t_end`` in the lanes of float64 batch
    integrators (:func:`taylorball.ensemble.orbit_lanes`), chunk by
    chunk, each chunk reduced and committed per orbit exactly as :func:`_run_orbit` does.

    Each orbit goes through the chunk ends ``(k + 1) checkpoint_every`` of its own clock
    (resumed: from its checkpoint's state and double-length time), each chunk one batch
    ``propagate_grid`` on the orbit's own sample grid ``m * sample_dt`` as in the scalar
    runner (``LaneTask.grid``), so its records depend on its own orbit only, whatever
    lane, thread or companions it has. When no observable uses the sample grid (drift and
    sections only) the grid is the chunk's two ends: the same steps (a grid's density does
    not change them; ``propagate_until`` would), and the observables get those two ends."""
    prob = cfg.problem()
    objs = cfg.observable_objects()
    layouts = _layouts(cfg, prob, objs)
    size = batch_size()
    template, evs = _lane_template(prob, objs, size)
    grid = any(_uses_grid(o) for o in objs)
    jobs = [_OrbitJob(cfg, i, t_end, prob, objs, layouts) for i in todo]
    n = len(jobs)
    pars = np.asarray(prob.pars, dtype=float)
    per, dt = cfg.samples_per_chunk, cfg.sample_dt
    k_next = [0] * n  # the next chunk of each orbit
    w0 = [0.0] * n
    callbacks: Dict[int, list] = {}  # id(ta) -> the batch events' callbacks of that copy

    def cbs(ta):
        got = callbacks.get(id(ta))
        if got is None:
            got = callbacks[id(ta)] = [ev.callback for ev in ta.nt_events]
        return got

    def load(j):
        job = jobs[j]
        k0 = job.open()  # in the lane's worker thread, as every callback of this job
        x, dtime = job.start()
        hi, lo = (0.0, 0.0) if dtime is None else (float(dtime[0]), float(dtime[1]))
        k_next[j], w0[j] = k0, time.perf_counter()
        if k0 >= job.n_total:  # the start-up check (under the store's lock) said otherwise
            raise StoreError(f"{job.orb.what()} was completed by another writer during this run")

        def ends(k, k0=k0):  # the same numbers as the scalar grid's last point, m * sample_dt
            return float(np.int64((k0 + k + 1) * per) * dt)

        def samples(k, k0=k0):  # the grid t_m = m * sample_dt of chunk k0 + k, without its start
            return ((k0 + k) * per + np.arange(1, per + 1, dtype=np.int64)) * dt

        def end_only(k):  # no observable reads the grid: the same steps on the chunk's two ends
            return np.array([ends(k)])

        return LaneLoad(x, pars, hi, ends(job.n_total - 1 - k0), cfg.checkpoint_every, t0_lo=lo, ends=ends,
                        chunk_samples=samples if grid else end_only)

    def on_chunk(ta, c):
        j = c.job
        job = jobs[j]
        k = k_next[j]
        if k >= job.n_total:
            return True, None
        m, t = job.grid(k)
        state = np.array(ta.state[:, c.lane], copy=True)
        his, los = ta.dtime
        X = c.sample_x  # the chunk's propagate_grid: its grid t (or its two ends), the start first
        if not grid:
            m, t = m[[0, -1]], t[[0, -1]]
        own_cbs = cbs(ta) if any(evs) else []
        events, e = [], 0
        for lst in evs:
            own = {}
            for q in range(len(lst)):
                cb = own_cbs[e].lanes[c.lane]
                own[q] = list(zip(cb.times, cb.states))
                cb.times.clear()
                cb.states.clear()
                e += 1
            events.append(own)
        # the orbit's share of its worker's time: the lanes of one integrator share it
        job.commit(k, m, t, X, events, c.steps, state, (his[c.lane], los[c.lane]), w0[j], share=1.0 / size)
        w0[j] = time.perf_counter()
        k_next[j] = k + 1
        return k + 1 >= job.n_total, None

    def failed(j, outcome, t):
        raise IntegrationError(
            f"{jobs[j].orb.what()}: integration stopped at t={t} (in a lane of a batch integrator) with outcome "
            f"{outcome}; a non-finite state usually means a singular configuration (e.g. 1 - d(gamma, A gamma) = 0) "
            "or an orbit escaping to infinity")

    def on_reset(ta, lane):
        for cb in (cbs(ta) if any(evs) else []):  # what a failed orbit's events left
            cb.lanes[lane].times.clear()
            cb.lanes[lane].states.clear()

    try:
        orbit_lanes(template, n, load=load, on_chunk=on_chunk, rerun=failed, workers=workers,
                    progress=progress, fraction=lambda c: k_next[c.job] / jobs[c.job].n_total,
                    on_done=lambda j: jobs[j].close(), on_reset=on_reset, grid=True)
    finally:
        for job in jobs:  # a stopped or failed run: trim and unlock what is still open
            job.close()
