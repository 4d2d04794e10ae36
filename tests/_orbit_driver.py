"""A minimal chunk loop for the observables' tests, mirroring the runner's contract
(taylorball/observables.py ChunkData): one ``propagate_grid`` per chunk over the run's
sample grid (both ends included), the observables' events collected per chunk."""
from __future__ import annotations

import copy

import numpy as np

from taylorball._propagate import integrator, public_states, start_state
from taylorball.observables import ChunkData


def run_chunks(prob, x0, observables, *, t_end, checkpoint_every, sample_dt, events=True, k_start=0,
               resume=None):
    """Returns (carries, records per observable as lists of per-chunk dicts, final ta)."""
    evs, owners = [], []
    if events:
        for i, ob in enumerate(observables):
            for j, e in enumerate(ob.events(prob)):
                evs.append(e)
                owners.append((i, j))
    key = ("test-driver", tuple((type(o).__name__, str(sorted(o.options().items()))) for o in observables)) if evs else None
    tmpl = integrator(prob, events_key=key, events=(lambda: {"nt_events": evs}) if evs else None)
    ta = copy.copy(tmpl)
    if resume is None:
        ta.state[:] = start_state(prob, x0)
        ta.time = prob.spec.scalar(0.0)
        carries = [ob.init(prob, x0, 0.0) for ob in observables]
    else:
        state, time, carries = resume
        ta.state[:] = state
        ta.time = time
    ta.pars[:] = prob.pars
    records = [[] for _ in observables]
    n_chunks = int(round(t_end / checkpoint_every))
    per = int(round(checkpoint_every / sample_dt))
    for k in range(k_start, n_chunks):
        t0 = k * checkpoint_every
        grid = t0 + np.arange(per + 1) * sample_dt
        grid[-1] = (k + 1) * checkpoint_every
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
            data = ChunkData(k=k, t0=t0, t1=float(grid[-1]), t=grid, x=X, public=public_states(prob, X).astype(float),
                             events=ev.get(i, {}), problem=prob, n_steps=int(out[3]))
            carries[i], rec = ob.chunk(carries[i], data)
            records[i].append(rec)
    return carries, records, ta


def concat(records, key):
    return np.concatenate([r[key] for r in records])
