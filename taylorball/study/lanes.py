"""Many orbits of a study in the SIMD lanes of float64 batch integrators (``backend =
"lanes"``) on the engine's one lane adapter (:func:`taylorball.ensemble.orbit_lanes`): the
event views (:class:`_LaneView`, :class:`_LaneCallback`: an observable's scalar event
callback run unchanged on one lane of a batch integrator), the cached batch template and
:func:`_run_lanes`."""

from __future__ import annotations

import copy
import math
import time
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np

from .._cache import compiled
from ..ensemble import LaneLoad, orbit_lanes
from ..errors import IntegrationError, StoreError, UsageError
from ..observables import events_key
from ..sections import START_TOL, batch_size
from .._section_run import _branch_mask
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


class _SectionLane:
    """One lane's crossings of :class:`_SectionLanes`: ``times``, ``states`` and, once the
    runner has set them after a chunk, the orbit's running count of kept crossings
    (``count``, the ``sections`` carry) and its thinning ``every``."""

    __slots__ = ("times", "states", "count", "every")

    def __init__(self) -> None:
        self.times: list = []
        self.states: list = []
        self.count: Optional[int] = None  # unknown: every crossing is refined
        self.every = 1


class _SectionLanes:
    """The ``sections`` observable's batch event callback: the records of the scalar
    :class:`taylorball.sections._Collector` for every crossing the observable keeps, at
    the cost of one dense-output evaluation for those it drops.

    ``Sections.chunk`` keeps every ``every``-th crossing on the section's branch after
    ``START_TOL`` by the orbit's running count. A crossing that will be kept gets the
    collector's exact arithmetic (dense output at heyoka's root relative to the step's end,
    one Newton step in time with the compiled ``(e, de/dt)`` when it is of rounding size, the
    dense output there): the same bits. A crossing that will be dropped is recorded
    unrefined (the dense output at heyoka's root), which decides the same: its branch value
    ``num sin g0 + den cos g0`` is farther than ``1e-8 C^2`` from 0 (the Newton step moves
    the state by ~1e-16 relative; nearer, the crossing is refined) and its time farther
    than 1e-9 from ``START_TOL``. Until the runner has told a lane its orbit's running
    count (the first chunk after a load, a chunk run again), every crossing is refined."""

    def __init__(self, proto: Any, size: int) -> None:
        self.proto, self.size = proto, size
        self.lanes = [_SectionLane() for _ in range(size)]
        self.rel = np.zeros(size)
        self.event = proto.event
        self.eps = proto.eps
        g0 = float(proto.event_def.g0)
        self.g0, self.sin_g0, self.cos_g0 = g0, math.sin(g0), math.cos(g0)
        from ..numbers import resolve_fp_type

        self.spec = resolve_fp_type(*proto.spec_key)
        #: the integrator's time views, lent by the lane pool's worker (taylorball._lanes._TimeViews)
        self.time_views: Optional[Tuple[np.ndarray, np.ndarray]] = None

    def __deepcopy__(self, memo: Any) -> "_SectionLanes":
        return _SectionLanes(self.proto, self.size)

    def __getstate__(self) -> Dict[str, Any]:
        return {**self.__dict__, "time_views": None}  # views of one integrator's time: never copied

    def _decided(self, x: list, t: float) -> Optional[bool]:
        """Whether the crossing at ``t``, state ``x`` (a list of floats), is kept (on the branch, after
        ``START_TOL``); None if a refinement could change either."""
        if abs(t - START_TOL) <= 1e-9:
            return None
        M0, M1, M2, g0_, g1_, g2_ = x[:6]  # Python floats (a state's tolist())
        C2 = M0 * M0 + M1 * M1 + M2 * M2
        num = math.sqrt(C2) * (M1 * g0_ - M0 * g1_)
        den = (M0 * g0_ + M1 * g1_ + M2 * g2_) * M2 - C2 * g2_
        b = num * self.sin_g0 + den * self.cos_g0
        if not abs(b) > 1e-8 * C2:
            return None
        return b > 0.0 and t > START_TOL

    def __call__(self, ta: Any, t: Any, d_sgn: Any, idx: int) -> None:
        dt = self.time_views
        his, los = dt if dt is not None else ta.dtime
        hi, lo = float(his[idx]), float(los[idx])
        rel = (t - hi) - lo  # exact: t and the step's end are within one step (Sterbenz)
        R = self.rel
        R[idx] = rel  # the other lanes' entries are stale and their outputs unused
        v = ta.update_d_output(R, rel_time=True)[:, idx]  # a view of the dense output: read before the next
        own = self.lanes[idx]
        if own.count is not None and own.every > 1:
            xl = v.tolist()
            kept = self._decided(xl, hi + (lo + rel))
            if kept is False or (kept and own.count % own.every):
                own.count += int(kept)
                own.times.append(hi + (lo + rel))  # dropped by Sections.chunk: unrefined
                own.states.append(xl)  # its floats as a list (Sections.chunk reads lists and arrays alike)
                return
        x = np.array(v, copy=True)
        # the scalar collector's arithmetic (sections._Collector.__call__ through a lane view)
        e, de = self.event(x, np.ascontiguousarray(ta.pars[:, idx]))
        if de != 0:
            delta = e / de
            if abs(delta) <= 64 * self.eps * (abs(hi) + abs(float(ta.last_h[idx]))):
                rel = rel - delta
                R[idx] = rel
                x = np.array(ta.update_d_output(R, rel_time=True)[:, idx], copy=True)
        t_c = hi + (lo + rel)
        own.times.append(t_c)
        own.states.append(x.copy())
        if own.count is not None:
            own.count += int(bool(_branch_mask([x], self.g0, self.spec)[0]) and float(t_c) > START_TOL)


def _lane_callback(proto: Any, size: int, obs: Any = None) -> Any:
    """A batch event's callback from an observable's scalar one: :class:`_SectionLanes`
    for the ``sections`` observable, the callback's own lanes form
    (``proto.for_lanes(size)``, the same records without a view per call) where it has one,
    else :class:`_LaneCallback` around it."""
    from ..observables import Sections

    if isinstance(obs, Sections):
        return _SectionLanes(proto, size)
    own = getattr(proto, "for_lanes", None)
    return own(size) if own is not None else _LaneCallback(proto, size)


def _lane_template(prob, objs, size: int):
    """The cached float64 batch integrator of ``size`` lanes with the observables' events
    in batch form; returns it and the observables' scalar events (per observable)."""
    import heyoka as hy

    evs = [o.events(prob) for o in objs]
    flat = [e for lst in evs for e in lst]
    owner = [o for o, lst in zip(objs, evs) for _ in lst]
    key = ("batch", *prob.compile_key, size, "observables") + tuple(
        events_key(o) for o, lst in zip(objs, evs) if lst)

    def build():
        system = prob.system
        kw: Dict[str, Any] = dict(pars=np.zeros((system.n_pars, size)))
        if flat:
            kw["nt_events"] = [hy.nt_event_batch(ev.expression, _lane_callback(ev.callback, size, o),
                                                 direction=ev.direction) for ev, o in zip(flat, owner)]
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
        e = 0
        for o, lst in zip(objs, evs):  # the sections' collector learns the orbit's running count
            for _ in lst:
                own = own_cbs[e].lanes[c.lane]
                if isinstance(own, _SectionLane):
                    own.count, own.every = int(job.carries[o.name]["n"][0]), int(o.every)
                e += 1
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
            if isinstance(cb.lanes[lane], _SectionLane):
                cb.lanes[lane].count = None  # another orbit, or the chunk again: refine until told

    try:
        orbit_lanes(template, n, load=load, on_chunk=on_chunk, rerun=failed, workers=workers,
                    progress=progress, fraction=lambda c: k_next[c.job] / jobs[c.job].n_total,
                    on_done=lambda j: jobs[j].close(), on_reset=on_reset, grid=True)
    finally:
        for job in jobs:  # a stopped or failed run: trim and unlock what is still open
            job.close()
