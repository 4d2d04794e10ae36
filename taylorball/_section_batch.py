"""Batch mode of sections: several orbits in the SIMD lanes of one integrator (float64
only), through the one lane adapter, :func:`taylorball.ensemble.orbit_lanes`."""

from __future__ import annotations

import time as _time
from typing import Any, List

import numpy as np

from ._cache import compiled
from .model import get_system
from ._propagate import start_state
from ._section_events import PaperEvent, _BatchCollector, _direction, _refine_batch_records
from ._section_run import START_TOL, Outcome, _Crossings, _Run

__all__ = ["batch_size"]


def batch_size() -> int:
    """Lanes of heyoka's batch mode used for float64 sections (``hy.recommended_simd_size()``,
    4 with AVX2/AVX-512 doubles)."""
    import heyoka as hy

    return max(1, int(hy.recommended_simd_size()))


def _batch_template(event, tol, direction, size):
    """Compiled float64 batch integrator with the section's event (cached; copy it)."""
    system = get_system(event.kind, getattr(event, "formulation", None))

    def build():
        import heyoka as hy

        event.field_cfunc()
        ev = hy.nt_event_batch(event.expression(), _BatchCollector(size), direction=_direction(direction))
        kw = dict(pars=np.zeros((system.n_pars + event.n_extra, size)), nt_events=[ev])
        if tol is not None:
            kw["tol"] = float(tol)
        return hy.taylor_adaptive_batch(system.equations(), np.full((system.dim, size), 0.1), **kw)

    where = (float(event.g0),) if isinstance(event, PaperEvent) else event.key
    return compiled(("batch", event.kind, system.formulation, "float", None if tol is None else float(tol), size,
                     "section", *where, int(direction)), build)


def _run_batch(sec: Any, states, run: _Run, threads=None, progress=False):
    """Sections of many orbits in the SIMD lanes of batch integrators (float64), one per
    thread, a lane refilled with the next orbit as soon as its orbit has ``n_points``
    crossings (:func:`taylorball.ensemble.orbit_lanes`).

    Each orbit runs on its own clock through the chunk boundaries ``k chunk``, as a scalar
    run does, and its result is cut at the chunk boundary where it has ``n_points``
    crossings (``t_end``, ``n_steps`` from there; a scalar run stops earlier, after the
    step of its last crossing). So a result
    depends only on its own initial state (lanes are independent in heyoka's batch mode).
    Returns one :class:`SectionResult` per state, ``None`` for an orbit whose integration
    stopped with an error (the caller reruns those in scalar mode, which reports the
    error). ``progress`` as for :func:`taylorball.ensemble.run_many`, in orbits' worth of
    crossings (after every chunk)."""
    from .ensemble import LaneLoad, orbit_lanes

    prob, event = sec.problem, sec.event_def
    n_points, t_max = run.n_points, run.limit
    size = batch_size()
    n = len(states)
    internal = [start_state(prob, s) for s in states]
    pars = np.asarray(prob.pars, dtype=float)
    # a user event's weight is a parameter of its own orbit (its lane)
    lane_pars = [np.concatenate([pars, sec.extra_pars(x)]) for x in internal] if event.n_extra else None
    times: List[List[float]] = [[] for _ in range(n)]
    states_out: List[List[np.ndarray]] = [[] for _ in range(n)]
    steps = np.zeros(n, dtype=np.int64)
    wall0 = [0.0] * n

    def load(j):
        wall0[j] = _time.perf_counter()
        return LaneLoad(internal[j], pars if lane_pars is None else lane_pars[j], 0.0, t_max, float(run.chunk))

    def crossings(ta, chunks):
        """The crossings the batch event recorded in this call, for the lanes that ended a chunk."""
        cb = ta.nt_events[0].callback
        recs, cb.records = cb.records, []
        job_of = {c.lane: c.job for c in chunks}
        recs = [r for r in recs if r[0] in job_of]
        rec_pars = pars if lane_pars is None or not recs else np.array([lane_pars[job_of[r[0]]] for r in recs])
        lanes, ts, xs = _refine_batch_records(event, recs, rec_pars)
        keep = sec.on_branch(xs)
        for lane, t, x, k in zip(lanes, ts, xs, keep):
            if k and t > START_TOL:
                j = job_of[lane]
                times[j].append(t)
                states_out[j].append(x)

    def on_chunk(ta, c):
        j = c.job
        steps[j] += c.steps
        done = len(times[j]) >= n_points
        if not (done or c.last):
            return False, None
        if done:
            outcome, message = Outcome.COMPLETED, run.completed(times[j])
        else:
            outcome, message = Outcome.T_MAX, run.ran_out(len(times[j]))
        wall = _time.perf_counter() - wall0[j]
        r = sec._finish(internal[j], _Crossings(times[j][:n_points], states_out[j][:n_points], outcome, message,
                                               float(c.t), int(steps[j]), wall))
        r.meta["batch"] = {"size": size, "note": "orbits share SIMD lanes; wall_time is the orbit's time in a lane"}
        return done, r

    # an orbit whose lane failed gives None: the caller reruns it in scalar mode
    return orbit_lanes(sec.batch_integrator(size), n, load=load, on_chunk=on_chunk,
                       rerun=lambda j, outcome, t: None, workers=threads, progress=progress, on_chunks=crossings,
                       fraction=lambda c: min(len(times[c.job]), n_points) / n_points)
