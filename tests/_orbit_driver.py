"""A minimal chunk loop for the observables' tests, mirroring the runner's contract
(taylorball/observables.py ChunkData): one ``propagate_grid`` per chunk over the run's
sample grid (both ends included), the observables' events collected per chunk."""
from __future__ import annotations

import copy

import numpy as np

from taylorball._propagate import integrator, public_states, start_state
from taylorball.observables import ChunkData, events_key


def run_chunks(prob, x0, observables, *, t_end, checkpoint_every, sample_dt, events=True, k_start=0,
               resume=None):
    """Returns (carries, records per observable as lists of per-chunk dicts, final ta)."""
    evs, owners = [], []
    if events:
        for i, ob in enumerate(observables):
            for j, e in enumerate(ob.events(prob)):
                evs.append(e)
                owners.append((i, j))
    key = ("observables",) + tuple(events_key(o) for o in observables if o.events(prob)) if evs else None
    tmpl = integrator(prob, events_key=key, events=(lambda: {"nt_events": evs}) if evs else None)
    ta = copy.copy(tmpl)
    if resume is None:
        ta.state[:] = start_state(prob, x0)
        ta.time = prob.spec.scalar(0.0)
        carries = [ob.init(prob, start_state(prob, x0), 0.0) for ob in observables]
    else:
        state, time, carries = resume
        ta.state[:] = state
        ta.time = time
    ta.pars[:] = prob.pars
    records = [[] for _ in observables]
    n_chunks = int(round(t_end / checkpoint_every))
    per = int(round(checkpoint_every / sample_dt))
    for k in range(k_start, n_chunks):
        m = np.arange(k * per, (k + 1) * per + 1, dtype=np.int64)  # as the runner (taylorball.study)
        grid = m * sample_dt
        t0 = float(grid[0])
        out = ta.propagate_grid(grid)
        assert str(out[0]) == "taylor_outcome.time_limit", out[0]
        X = np.asarray(out[-1])
        ev = {}
        for n, (i, j) in enumerate(owners):
            cb = ta.nt_events[n].callback
            ev.setdefault(i, {})[j] = list(zip(cb.times, cb.states))
            cb.times.clear()
            cb.states.clear()
        for i, ob in enumerate(observables):
            data = ChunkData(k=k, t0=t0, t1=float(grid[-1]), t=grid, i=m, x=X,
                             public=public_states(prob, X).astype(float), events=ev.get(i, {}), problem=prob,
                             n_steps=int(out[3]), sample_dt=sample_dt)
            carries[i], rec = ob.chunk(carries[i], data)
            records[i].append(rec)
    return carries, records, ta


def concat(records, key):
    return np.concatenate([r[key] for r in records])
