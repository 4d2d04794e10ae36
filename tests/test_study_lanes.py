"""The study runner's ``backend = "lanes"``: float64 orbits in the SIMD
lanes of heyoka batch integrators, with the store, observables and guarantees of the scalar
backends (resume, extend, kill -9), bits independent of the packing, and a fingerprint that
keeps lanes and scalar stores apart."""

import dataclasses

import numpy as np
import pytest

import taylorball as tb
from taylorball.errors import StoreError, UsageError
from taylorball.store import RunStore

from tests.test_study import _kill_and_resume, assert_same_store, no_leftovers, store_content, write_study

EPS = np.finfo(float).eps
LANES = {"backend": "lanes"}
# every observable, the grid ones at every sample
ALL = {"samples_every": 0.25, "angles_every": 0.25, "sections": "all", "histogram": True}


def _records(path, i):
    """Orbit ``i``'s committed records (array -> bytes) and its checkpoint's state, time,
    steps and carries: what must not depend on the other orbits (the digests and index do,
    through the study's fingerprint, which holds every initial state)."""
    ck, arrays = store_content(path)[i]
    return ({k: v for k, v in arrays.items() if not k.startswith("_index")},
            {k: ck[k] for k in ("state", "dtime", "n_steps", "carries", "lengths", "chunks", "t")})


def test_lanes_agree_with_scalar_to_rounding(tmp_path):
    """4 orbits of the H = 2 chaotic sea to t = 200 with every observable, lanes against the
    serial (scalar) runner. heyoka's batch and scalar steppers round differently, so the
    states differ by rounding, which this chaotic level amplifies: over the first 5 time
    units (~80 steps) the sampled states agree to 1000 eps relative (measured 112 eps: one
    rounding per step, grown a few times by the orbit's local stretching; later the
    difference grows at the Lyapunov rate, as between any two roundings). The discrete
    outcomes agree exactly: the same Taylor steps, the same numbers of section crossings
    and signed crossings of the lifted angle's cuts; the integrals drift alike (both a few
    tens of eps over ~3000 steps at tol = eps: below 200 eps)."""
    run = {"t_end": 200.0, "checkpoint_every": 25.0}
    tb.run_study(write_study(tmp_path / "l", run={**run, **LANES}, orbits={"n": 4}, observables=ALL))
    tb.run_study(write_study(tmp_path / "s", run=run, orbits={"n": 4}, observables=ALL))
    a, s = tb.open_run(tmp_path / "l" / "store"), tb.open_run(tmp_path / "s" / "store")
    x, y = a.samples_state.values, s.samples_state.values
    np.testing.assert_array_equal(a.samples_t.values, s.samples_t.values)
    early = a.samples_t.values[0] <= 5.0
    rel = np.abs(x - y)[:, early].max(axis=(1, 2)) / np.abs(y).max(axis=(1, 2))
    assert rel.max() <= 1000 * EPS, rel / EPS
    assert not np.array_equal(x, y)  # the lanes are not a disguised scalar run
    assert a.sections_t.shape == s.sections_t.shape and a.sections_t.shape[1] > 100
    for i in range(4):
        cl, cs = (RunStore(p / "store").orbit(i).checkpoint() for p in (tmp_path / "l", tmp_path / "s"))
        assert cl["n_steps"] == cs["n_steps"]
        assert cl["carries"]["angles"]["n"] == cs["carries"]["angles"]["n"]
        assert cl["carries"]["sections"]["n"] == cs["carries"]["sections"]["n"]
    assert 0 < float(a.drift_drift.max()) < 200 * EPS and 0 < float(s.drift_drift.max()) < 200 * EPS


@pytest.mark.long
def test_lanes_bits_do_not_depend_on_workers_or_packing(tmp_path):
    """9 orbits (a batch of 8 plus a refill) with 1 and with 2 worker threads give the same
    store; the same initial states packed differently (5 of the 9, some reversed, among others:
    other lanes, other companions, other refill times) give every orbit the same records."""
    cfg = tb.load_study(write_study(tmp_path / "draw", orbits={"n": 9}))
    X = [list(map(float, x)) for x in cfg.initial_states]
    obs = {"sections": "all", "samples_every": 2.5}
    run = {"t_end": 50.0}
    one = write_study(tmp_path / "1", run={**run, **LANES, "workers": 1}, orbits={"n": 9}, observables=obs)
    two = write_study(tmp_path / "2", run={**run, **LANES, "workers": 2}, orbits={"n": 9}, observables=obs)
    tb.run_study(one)
    got = []
    tb.run_study(two, progress=got.append)  # 2 worker processes, 5 and 4 orbits
    assert_same_store(tmp_path / "1" / "store", tmp_path / "2" / "store")
    # the progress counts orbits' chunks as they are committed, not the 2 worker shares
    # when they end (read from the store: the orbits' zarr.json)
    assert sum(got) == pytest.approx(9, rel=1e-15) and len(got) >= 9
    # one worker process: the 5 orbits in one batch integrator and a refill (the 2-worker
    # split is the run above's)
    rev = write_study(tmp_path / "r", run={**run, **LANES, "workers": 1}, observables=obs,
                      orbits={"n": None, "seed": None, "states": X[::-1][:3] + X[3:5]}, level={"G": None, "H": None,
                                                                                           "h": None})
    tb.run_study(rev)
    for j, i in enumerate([8, 7, 6, 3, 4]):
        assert _records(tmp_path / "r" / "store", j) == _records(tmp_path / "1" / "store", i), (j, i)


def test_lanes_extend_and_resume_are_bit_identical(tmp_path):
    """Extending a lanes run (chunk by chunk, and by --extend) equals a direct run bit for
    bit; a run stopped after some orbits' chunks (Ctrl-C in the engine) resumes exactly."""
    obs = {"sections": "all", "histogram": True}
    half = write_study(tmp_path / "a", run={**LANES, "t_end": 50.0}, orbits={"n": 3}, observables=obs)
    tb.run_study(half)
    # 3 orbits share one batch integrator: their wall times per chunk are shares of its
    # time, and the study's estimate is their sum (one worker busy, whatever workers)
    st = tb.study_status(write_study(tmp_path / "a", name="full.toml", run={**LANES, "workers": 2},
                                     orbits={"n": 3}, observables=obs))
    assert st.t_end == 100.0 and st.workers == 2 and st.per_worker == tb.sections.batch_size()
    assert all(o["wall_per_chunk"] > 0 and o["eta"] == pytest.approx(2 * o["wall_per_chunk"]) for o in st.orbits)
    assert st.eta == pytest.approx(sum(o["eta"] for o in st.orbits))
    tb.run_study(half, extend=75.0)
    tb.run_study(half, extend=100.0)
    tb.run_study(write_study(tmp_path / "b", run=LANES, orbits={"n": 3}, observables=obs))
    assert_same_store(tmp_path / "a" / "store", tmp_path / "b" / "store")
    no_leftovers(tmp_path / "a" / "store")


def test_lanes_stopped_mid_run_resumes_bit_identically(tmp_path, monkeypatch):
    """The engine stopped (as by Ctrl-C) once some chunks are committed: the run raises
    KeyboardInterrupt, the store holds only whole chunks, and a rerun equals a direct run."""
    import taylorball.store as store_mod

    f = write_study(tmp_path / "a", run=LANES, orbits={"n": 3}, observables={"sections": "all"})
    real = store_mod.OrbitStore.append
    calls = []

    def append(self, *a, **k):
        out = real(self, *a, **k)
        calls.append(1)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return out

    monkeypatch.setattr(store_mod.OrbitStore, "append", append)
    with pytest.raises(KeyboardInterrupt):
        tb.run_study(f)
    monkeypatch.setattr(store_mod.OrbitStore, "append", real)
    assert 0 < sum(o["chunks"] for o in tb.study_status(f).orbits) < 12
    no_leftovers(tmp_path / "a" / "store")
    tb.run_study(f)
    tb.run_study(write_study(tmp_path / "b", run=LANES, orbits={"n": 3}, observables={"sections": "all"}))
    assert_same_store(tmp_path / "a" / "store", tmp_path / "b" / "store")


def test_drift_only_lanes_read_no_samples_and_keep_the_bits(tmp_path):
    """With no observable using the sample grid (drift and sections) the lanes read no
    samples (no continuous output): the drift and the crossings are the same bits as with
    every observable on, so the continuous output does not change the steps."""
    tb.run_study(write_study(tmp_path / "all", run=LANES, observables=ALL))
    tb.run_study(write_study(tmp_path / "few", run=LANES, observables={"angles_every": 0.0, "extremes": False,
                                                                       "samples_every": 0.0, "sections": "all"}))
    a, b = store_content(tmp_path / "all" / "store"), store_content(tmp_path / "few" / "store")
    for i in a:
        for k in ("drift/drift", "sections/t", "sections/l", "sections/K"):
            assert a[i][1][k] == b[i][1][k], k
        assert a[i][0]["state"] == b[i][0]["state"] and a[i][0]["dtime"] == b[i][0]["dtime"]
        assert "angles/l" not in b[i][1]


def test_lanes_and_scalar_stores_refuse_each_other(tmp_path):
    """A store written by lanes is not resumed or extended by a scalar backend and vice
    versa (other bits): the refusal names both backends, before any work."""
    f = write_study(tmp_path, run={**LANES, "t_end": 50.0})
    tb.run_study(f)
    before = store_content(tmp_path / "store")
    for backend in ("threads", "serial"):
        with pytest.raises(StoreError, match=r"written by backend 'lanes'.*by backend '" + backend + "'"):
            tb.run_study(f, backend=backend, extend=100.0)
    g = write_study(tmp_path, name="t.toml", run={"backend": "threads", "t_end": 50.0})
    with pytest.raises(StoreError, match=r"written by backend 'lanes'.*by backend 'threads'"):
        tb.run_study(g)
    with pytest.raises(StoreError, match=r"written by backend 'lanes'"):
        tb.study_status(g)
    assert store_content(tmp_path / "store") == before
    tb.run_study(g, restart=True)  # replaced on request
    with pytest.raises(StoreError, match=r"written by backend 'threads'.*by backend 'lanes'"):
        tb.run_study(f)
    # the scalar backends share one family: a threads store is extended by serial
    tb.run_study(g, backend="serial", extend=100.0)
    # the family is in the fingerprint for lanes only: scalar fingerprints are unchanged
    cfg = tb.load_study(g)
    assert {dataclasses.replace(cfg, backend=b).fingerprint() for b in ("threads", "serial", "processes")} == {
        cfg.fingerprint()}
    assert dataclasses.replace(cfg, backend="lanes").fingerprint() != cfg.fingerprint()


@pytest.mark.parametrize("fp_type", ["longdouble", "real128"])
def test_lanes_refuse_other_number_types(tmp_path, fp_type):
    f = write_study(tmp_path, run={**LANES, "fp_type": fp_type})
    with pytest.raises(UsageError, match=r'\[run\] backend = "lanes" runs float64 only.*\[run\] fp_type = '
                                         f"'{fp_type}'" r'.*fp_type = "float"') as info:
        tb.run_study(f)
    assert str(f) in str(info.value)
    g = write_study(tmp_path, name="g.toml", run={"fp_type": fp_type})
    with pytest.raises(UsageError, match=r"float64 only.*fp_type"):
        tb.run_study(g, backend="lanes")
    for bad in ("gpu", 1, True):
        with pytest.raises(UsageError, match=r"backend must be one of .*'lanes'.*got"):
            tb.run_study(g, backend=bad)
    with pytest.raises(UsageError, match=r"backend='dask' needs \[run\] scheduler"):
        tb.run_study(g, backend="dask")
    assert not (tmp_path / "store").exists()  # refused before any work


@pytest.mark.long
def test_kill_9_lanes_then_rerun_is_bit_identical(tmp_path):
    """3 kill -9 of `taylorball run` (lanes) at random moments, then a rerun: the store
    equals an uninterrupted lanes run's, no leftovers."""
    assert _kill_and_resume(tmp_path, 3, seed=20, t_end=3000.0, run=LANES) >= 2


@pytest.mark.slow
def test_kill_9_lanes_many_times(tmp_path):
    """12 kills of a lanes run of 10 orbits (two batches' worth of refills) with 2 workers."""
    assert _kill_and_resume(tmp_path, 12, seed=21, t_end=6000.0, run={**LANES, "workers": 2},
                            orbits={"n": 10}) >= 8


@pytest.mark.parametrize("workers", [pytest.param(1, marks=pytest.mark.slow), pytest.param(2, marks=pytest.mark.long)])
def test_ctrl_c_stops_a_lanes_run_cleanly(tmp_path, workers):
    """SIGINT to `taylorball run` (lanes, 9 orbits: two integrators with 2 workers) once
    chunks are being committed: exit status 130, no lock or uncommitted row left, and a
    rerun equals an uninterrupted run bit for bit."""
    import os
    import signal
    import subprocess
    import sys
    import time

    from tests.conftest import sigint_default
    from tests.test_study import ROOT

    run = {**LANES, "t_end": 2500.0, "checkpoint_every": 250.0, "workers": workers}
    f = write_study(tmp_path / "k", run=run, orbits={"n": 9})
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen([sys.executable, "-m", "taylorball", "-q", "run", str(f)], env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True, preexec_fn=sigint_default)
    store = tmp_path / "k" / "store"
    deadline = time.time() + 120
    while time.time() < deadline and p.poll() is None:  # wait for the first commits
        cks = [RunStore(store).orbit(i).checkpoint() for i in range(9)] if (store / "orbit_0008").exists() else []
        if sum(1 for ck in cks if ck) >= 2:
            break
        time.sleep(0.2)
    os.killpg(p.pid, signal.SIGINT)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 130, (p.returncode, out, err)
    st = tb.study_status(f)
    assert not st.complete and sum(o["chunks"] for o in st.orbits) > 0
    no_leftovers(store)
    tb.run_study(f)
    # the uninterrupted reference with one worker, in this process (a lanes run's bits do not
    # depend on its workers: test_lanes_bits_do_not_depend_on_workers_or_packing)
    tb.run_study(write_study(tmp_path / "ref", run=run, orbits={"n": 9}), workers=1)
    assert_same_store(store, tmp_path / "ref" / "store")
