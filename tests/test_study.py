"""Study files, the run store and the runner: resume, extend, crash safety,
locks, integrity checks, bad study files, the dask backend."""

import json
import math
import os
import random
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np

import pytest

import taylorball as tb
from taylorball.errors import ParameterError, StateError, StoreError, UsageError
from taylorball.store import OrbitStore, RunStore

ROOT = Path(__file__).resolve().parents[1]

BASE = {
    "ball": {"inertia": [2.0, 3.0, 4.0], "mass": 1.0, "radius": 5.0, "plane_rate": 2.0},
    "level": {"G": 10.0, "H": 2.0, "h": 5.0},
    "orbits": {"n": 2, "seed": 1},
    "run": {"t_end": 100.0, "checkpoint_every": 25.0, "backend": "serial"},
    "observables": {"angles_every": 2.5, "samples_every": 5.0},
    "output": {"store": "store"},
}
# wall-clock fields and the seal over them differ between two runs of the same orbit
_WALL = ("wall_total", "wall_last", "wall_chunks", "seal")


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    return repr(v)


def write_study(folder: Path, name="study.toml", **changes) -> Path:
    """A study file from BASE with tables changed (``run={"t_end": 50.0}`` updates the
    table; a value None removes the key)."""
    d = {t: dict(v) for t, v in BASE.items()}
    for t, upd in changes.items():
        d.setdefault(t, {})
        for k, v in upd.items():
            if v is None:
                d[t].pop(k, None)
            else:
                d[t][k] = v
    text = "\n".join(f"[{t}]\n" + "\n".join(f"{k} = {_toml_value(v)}" for k, v in tab.items()) + "\n"
                     for t, tab in d.items())
    p = Path(folder) / name
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text)
    return p


def store_content(path: Path):
    """Every orbit's committed records (array name -> bytes and dtype) and checkpoint
    without its wall-clock fields."""
    import zarr

    rs = RunStore(path)
    out = {}
    n = len([p for p in path.iterdir() if p.name.startswith("orbit_")])
    for i in range(n):
        orb = rs.orbit(i)
        ck = orb.checkpoint() or {}
        arrays = {}
        for zj in sorted(orb.path.rglob("zarr.json")):
            key = zj.parent.relative_to(orb.path).as_posix()
            meta = json.loads(zj.read_text())
            if meta.get("node_type") != "array":
                continue
            a = zarr.open_array(str(zj.parent), mode="r")
            top = key.split("/")[0]
            m = ck.get("chunks", 0) if top == "_index" else ck.get("lengths", {}).get(top, 0)
            arrays[key] = (a[:m].dtype.str, a[:m].shape, a[:m].tobytes(), a.shape[0])
        out[i] = ({k: v for k, v in ck.items() if k not in _WALL}, arrays)
    return out


def assert_same_store(a: Path, b: Path):
    ca, cb = store_content(a), store_content(b)
    assert ca.keys() == cb.keys()
    for i in ca:
        assert ca[i][0] == cb[i][0], f"orbit {i}: checkpoints differ"
        assert ca[i][1].keys() == cb[i][1].keys()
        for k in ca[i][1]:
            assert ca[i][1][k] == cb[i][1][k], f"orbit {i}: array {k} differs"


def no_leftovers(store: Path):
    """No temporaries, no locks, every array exactly as long as committed."""
    assert not list(store.rglob("*.partial")), list(store.rglob("*.partial"))
    assert not list(store.rglob(".lock"))
    assert not store.with_name(store.name + ".lock").exists()
    assert not list(store.parent.glob(store.name + ".new*")) and not list(store.parent.glob(store.name + ".old*"))
    assert not (store / ".taylorball-temporary").exists()
    for i, (ck, arrays) in store_content(store).items():
        for k, (_, shape, _, full_len) in arrays.items():
            assert shape[0] == full_len, f"orbit {i}: {k} has {full_len} rows, {shape[0]} committed"


# ---------------------------------------------------------------------------------------
# Runs, resume, extension.
# ---------------------------------------------------------------------------------------
def test_the_example_study_file_runs(tmp_path):
    """studies/h2.toml as shipped, with t_end 1000 instead of 2000."""
    text = (ROOT / "studies" / "h2.toml").read_text()
    assert "t_end = 2000.0" in text
    f = tmp_path / "h2.toml"
    f.write_text(text.replace("t_end = 2000.0", "t_end = 1000.0"))
    st = tb.run_study(f)
    assert st.complete and len(st.orbits) == 4 and all(o["chunks"] == 2 for o in st.orbits)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # orbits with different crossing counts: no dask PerformanceWarning
        ds = tb.open_run(tmp_path / "runs" / "h2")
    assert ds.sizes["orbit"] == 4
    assert ds.angles_l.shape == (4, 101) and ds.heading_heading.shape == (4, 101)
    assert ds.extremes_r_max.shape == (4, 2) and ds.drift_drift.shape == (4, 2, 5)
    n_cross = ds.sections_t.sizes["sections_crossing"]
    assert 300 < n_cross < 1000  # ~0.63 crossings per t.u. on 1000 t.u.
    # one chunking along the crossings for every orbit (each orbit padded to the longest):
    # equal chunks but the last, not the union of the orbits' own boundaries (which grows
    # with the orbits and made dask warn on a 64-orbit store)
    ch = ds.sections_t.data.chunks[1]
    assert all(c == ch[0] for c in ch[:-1]) and ch[-1] <= ch[0] and sum(ch) == n_cross
    assert tb.study_status(f).complete


@pytest.mark.parametrize("backend", ["serial", "lanes"])
def test_rerun_trims_a_finished_orbit_killed_before_its_trim(tmp_path, monkeypatch, backend):
    """A kill after an orbit's last commit and before the trim that ends its job leaves
    its arrays longer than committed (they grow by doubling); the orbit is finished, so no
    job of a rerun opens it: the rerun itself cuts it to the committed lengths, the
    committed records unchanged (the kill -9 test of the lanes found this by chance)."""
    f = write_study(tmp_path / "a", run={"backend": backend})
    ref_store = tmp_path / "a" / "store"
    assert tb.run_study(f).complete
    ref = store_content(ref_store)
    g = write_study(tmp_path / "k", run={"backend": backend})
    store = tmp_path / "k" / "store"
    monkeypatch.setattr(OrbitStore, "trim", lambda self, layouts, ck: None)  # the kill before the trim
    assert tb.run_study(g).complete
    monkeypatch.undo()
    index = json.loads((store / "orbit_0000" / "_index" / "zarr.json").read_text())
    assert index["shape"][0] > 4  # grown past the committed 4 chunks: the case under test
    assert tb.run_study(g).complete
    no_leftovers(store)
    assert store_content(store) == ref


def test_run_then_rerun_does_no_work(tmp_path):
    f = write_study(tmp_path)
    st = tb.run_study(f)
    assert st.complete and [o["chunks"] for o in st.orbits] == [4, 4]
    store = tmp_path / "store"
    before = {p: p.stat().st_mtime_ns for p in store.rglob("*") if p.is_file()}
    raw = store_content(store)
    cks = [RunStore(store).orbit(i).checkpoint() for i in range(2)]
    st2 = tb.run_study(f)
    assert st2.complete
    # nothing committed again: the checkpoints keep their wall-clock fields, no data file changed
    assert [RunStore(store).orbit(i).checkpoint() for i in range(2)] == cks
    after = {p: p.stat().st_mtime_ns for p in store.rglob("*") if p.is_file() and p.parent.name.startswith("c")}
    assert all(before[p] == m for p, m in after.items())
    assert store_content(store) == raw
    no_leftovers(store)


def test_extend_is_bit_identical_to_a_direct_run(tmp_path):
    short = write_study(tmp_path / "a", run={"t_end": 50.0})
    tb.run_study(short)
    st = tb.run_study(short, extend=100.0)
    assert st.complete and st.t_end == 100.0
    direct = write_study(tmp_path / "b")
    tb.run_study(direct)
    assert_same_store(tmp_path / "a" / "store", tmp_path / "b" / "store")
    # raising t_end in the file is the same as --extend
    longer = write_study(tmp_path / "a", run={"t_end": 125.0})
    tb.run_study(longer)
    tb.run_study(write_study(tmp_path / "b", run={"t_end": 125.0}))
    assert_same_store(tmp_path / "a" / "store", tmp_path / "b" / "store")


@pytest.mark.parametrize("again", ["plain", "same extend"])
def test_an_interrupted_extension_resumes(tmp_path, monkeypatch, again):
    """An extension stopped part-way (here after 3 of its 4 commits) is resumed by a plain
    rerun and by the same --extend, to the extension's end, bit-identical to a direct run
    (before: the plain rerun stopped at the file's t_end and the same --extend was
    refused, so nothing could finish it)."""
    f = write_study(tmp_path / "a", run={"t_end": 50.0})
    tb.run_study(f)

    class Crash(BaseException):
        pass

    real = OrbitStore.append
    calls = []

    def append_then_die(self, *args, **kw):
        out = real(self, *args, **kw)
        calls.append(1)
        if len(calls) == 3:
            raise Crash
        return out

    monkeypatch.setattr(OrbitStore, "append", append_then_die)
    with pytest.raises(Crash):
        tb.run_study(f, extend=100.0)
    monkeypatch.undo()
    assert not tb.study_status(f).complete
    st = tb.run_study(f) if again == "plain" else tb.run_study(f, extend=100.0)
    assert st.complete and st.t_end == 100.0
    tb.run_study(write_study(tmp_path / "b"))
    assert_same_store(tmp_path / "a" / "store", tmp_path / "b" / "store")
    no_leftovers(tmp_path / "a" / "store")


@pytest.mark.parametrize("fp_type,t_end,ce,eps", [("longdouble", 40.0, 20.0, 2.0**-63), ("real128", 4.0, 2.0, 2.0**-112)])
def test_extend_and_resume_are_exact_in_wider_types(tmp_path, fp_type, t_end, ce, eps):
    """Checkpoints of long double / real128 runs are exact (decimal strings): an extended
    run equals a direct one bit for bit, checkpoint state included."""
    obs = {"angles_every": ce, "samples_every": ce, "sections": "all"}
    half = write_study(tmp_path / "a", run={"fp_type": fp_type, "t_end": t_end / 2, "checkpoint_every": ce},
                       observables=obs)
    tb.run_study(half)
    tb.run_study(half, extend=t_end)
    tb.run_study(write_study(tmp_path / "b", run={"fp_type": fp_type, "t_end": t_end, "checkpoint_every": ce},
                             observables=obs))
    assert_same_store(tmp_path / "a" / "store", tmp_path / "b" / "store")
    ck = RunStore(tmp_path / "a" / "store").orbit(0).checkpoint()
    assert all(isinstance(v, str) for v in ck["state"])  # not rounded to float64
    st = tb.study_status(half)
    # the drift is measured in the working precision (not rounded to float64 first): a few
    # hundred steps at tol = eps, each adding ~eps: below 1e3 eps
    assert all(0 < o["max_drift"] < 1e3 * eps for o in st.orbits)


def test_backends_give_the_same_bits(tmp_path):
    tb.run_study(write_study(tmp_path / "s"))
    tb.run_study(write_study(tmp_path / "t", run={"backend": "threads", "workers": 2}))
    assert_same_store(tmp_path / "s" / "store", tmp_path / "t" / "store")


@pytest.mark.slow
def test_processes_backend_gives_the_same_bits(tmp_path):
    """2 spawned worker processes (~12 s: start-up and compile lookups in each)."""
    tb.run_study(write_study(tmp_path / "s"))
    tb.run_study(write_study(tmp_path / "p", run={"backend": "processes", "workers": 2}))
    assert_same_store(tmp_path / "s" / "store", tmp_path / "p" / "store")


def test_an_observable_switched_off_does_not_change_the_others(tmp_path):
    tb.run_study(write_study(tmp_path / "all", observables={"sections": "all", "histogram": True}))
    tb.run_study(write_study(tmp_path / "some", observables={"samples_every": 0.0, "drift": False,
                                                             "extremes": False}))
    a, b = store_content(tmp_path / "all" / "store"), store_content(tmp_path / "some" / "store")
    for i in a:
        for k in ("angles/l",):
            assert a[i][1][k] == b[i][1][k]
        assert a[i][0]["state"] == b[i][0]["state"] and a[i][0]["dtime"] == b[i][0]["dtime"]
        assert "samples/state" not in b[i][1] and "drift/drift" not in b[i][1] and "extremes/r_max" not in b[i][1]
        assert len(a[i][1]["sections/t"][2]) > 0  # the section event was on in the first run


def test_lifted_angle_against_a_fine_unwrap(tmp_path):
    """The lifted l (event counts of the cuts) equals numpy's unwrap of the chart angle on
    an independent grid 50x finer than the run's samples (fine enough that no step of the
    raw angle exceeds pi/2, checked), at the recorded times. The run's own sample grid
    (0.25) is too coarse to unwrap on this level: such steps occur, checked too."""
    f = write_study(tmp_path, observables={"angles_every": 0.25})
    tb.run_study(f)
    ds = tb.open_run(tmp_path / "store", observable="angles")
    cfg = tb.load_study(f)
    eps = np.finfo(float).eps
    coarse_jumps = 0
    for i in range(2):
        ta, system, spec = tb.make_integrator("reduced", cfg.params, cfg.initial_states[i])
        # per chunk, one propagate_grid to the chunk's end (the same steps as the run: the
        # grid's density does not change them), with the run's times m * 0.25 among 49
        # points between each two of them
        raws, coarse = [], []
        for k in range(4):
            m = np.arange(k * 100, (k + 1) * 100 + 1)
            fine = (m[:-1, None] * 0.25 + np.arange(50)[None, :] * 0.005).ravel()
            fine[::50] = m[:-1] * 0.25
            grid = np.append(fine, m[-1] * 0.25)
            X = ta.propagate_grid(grid)[-1]
            raw = np.mod(np.arctan2(X[:, 0], X[:, 1]), 2 * np.pi)
            raws.append(raw if k == 0 else raw[1:])
        raw = np.concatenate(raws)
        step = np.abs(np.angle(np.exp(1j * np.diff(raw))))
        assert step.max() < np.pi / 2  # the reference lift is unambiguous
        ref = np.unwrap(raw)[::50]
        coarse_jumps += int(np.sum(np.abs(np.angle(np.exp(1j * np.diff(raw[::50])))) > np.pi / 2))
        np.testing.assert_array_equal(ds.time.values, np.arange(401) * 0.25)
        # the same states: only numpy's unwrap arithmetic (sums of 2 pi corrections) and the
        # chart's float64 atan2 differ: a few ulp of |l|
        assert np.max(np.abs(ds.l.values[i] - ref)) <= 8 * eps * (1 + np.max(np.abs(ref)))
    assert coarse_jumps > 0


def test_status_reports_progress_and_drift(tmp_path):
    f = write_study(tmp_path)
    tb.run_study(f, extend=50.0)
    st = tb.study_status(f)
    assert st.t_end == 100.0 and not st.complete  # the file's t_end
    for o in st.orbits:
        assert o["t_done"] == 50.0 and o["chunks"] == 2
        assert 0 < o["max_drift"] < 1e3 * np.finfo(float).eps  # 100 t.u. in float64 at tol = eps
        assert o["wall_per_chunk"] > 0 and o["eta"] == pytest.approx(2 * o["wall_per_chunk"])
    assert st.n_chunks == 4 and st.workers == 1  # serial
    assert st.eta == pytest.approx(sum(o["eta"] for o in st.orbits))
    assert "estimated time left" in st.table()
    ds = tb.open_run(tmp_path / "store", observable="drift")
    assert ds.drift.dims == ("orbit", "chunk", "integral")
    worst = float(ds.drift.max())
    assert worst == max(o["max_drift"] for o in st.orbits)
    # a store made by another study file is refused by fingerprint
    other = write_study(tmp_path, name="other.toml", orbits={"seed": 2})
    with pytest.raises(StoreError, match="another study"):
        tb.study_status(other)
    with pytest.raises(StoreError, match="another study"):
        tb.run_study(other)


def test_open_run_dims_and_attrs(tmp_path):
    tb.run_study(write_study(tmp_path))
    ds = tb.open_run(tmp_path / "store")
    assert ds.sizes["orbit"] == 2
    assert ds.samples_state.dims == ("orbit", "samples_time", "samples_var")
    assert ds.angles_l.shape == (2, 41) and ds.samples_t.shape == (2, 21)
    np.testing.assert_array_equal(ds.angles_time.values, np.arange(41) * 2.5)
    assert hasattr(ds.angles_l.data, "dask")  # lazy
    assert ds.attrs["progress"] == [4, 4] and ds.attrs["fingerprint"]
    one = tb.open_run(tmp_path / "store", observable="angles")
    assert one.l.dims == ("orbit", "time")
    np.testing.assert_array_equal(one.time.values, np.arange(41) * 2.5)
    # ragged: orbit 1 extended further than orbit 0, orbit 2 of another store never started
    from taylorball.study.job import _create_store
    from taylorball.study.runner import _run_orbit

    cfg = tb.load_study(write_study(tmp_path / "r", orbits={"n": 3}))
    _create_store(cfg, cfg.store, 100.0)
    _run_orbit(cfg, 0, 50.0)
    _run_orbit(cfg, 1, 100.0)
    rag = tb.open_run(cfg.store, observable="angles")
    assert rag.l.shape == (3, 41) and rag.attrs["progress"] == [2, 4, 0]
    assert np.isnan(rag.l.values[0, 21:]).all() and not np.isnan(rag.l.values[0, :21]).any()
    assert np.isnan(rag.l.values[2]).all() and not np.isnan(rag.l.values[1]).any()
    with pytest.raises(UsageError, match="not in the store"):
        tb.open_run(tmp_path / "store", observable="nope")
    with pytest.raises(UsageError, match="not a taylorball run store"):
        tb.open_run(tmp_path)


# ---------------------------------------------------------------------------------------
# Crash safety: kill -9 at random moments.
# ---------------------------------------------------------------------------------------
def _kill_and_resume(tmp_path, n_kills, seed, t_end=1000.0, run=None, orbits=None):
    """``n_kills`` kill -9 of `taylorball run` at random moments, then a rerun; the store must
    equal an uninterrupted run's. ``run``, ``orbits``: changes to those tables of BASE (e.g.
    another backend); returns the number of kills that landed before the run ended."""
    run = {"t_end": t_end, **(run or {})}
    ref = write_study(tmp_path / "ref", run=run, orbits=orbits or {})
    tb.run_study(ref)
    f = write_study(tmp_path / "k", run=run, orbits=orbits or {})
    rng = random.Random(seed)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    killed = 0
    for _ in range(n_kills):
        p = subprocess.Popen([sys.executable, "-m", "taylorball", "-q", "run", str(f)], env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        time.sleep(rng.uniform(0.8, 2.5))
        if p.poll() is None:
            p.send_signal(signal.SIGKILL)
            killed += 1
        p.wait()
    r = subprocess.run([sys.executable, "-m", "taylorball", "-q", "run", str(f)], env=env, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert_same_store(tmp_path / "ref" / "store", tmp_path / "k" / "store")
    no_leftovers(tmp_path / "k" / "store")
    return killed


@pytest.mark.long
def test_kill_9_then_rerun_is_bit_identical(tmp_path):
    """3 kill -9 of `taylorball run` at random moments (0.8-2.5 s: start-up, compile, chunk
    writes), then a rerun: the store equals an uninterrupted run's, no leftovers. The run
    (4000 t.u., ~4.5 CPU s of work in one go on the 2-core Xeon) outlasts the first two kills
    with a margin of ~2 (they land 1.77 and 1.53 s after their starts, each after ~0.8 s of
    start-up), as the 6000 t.u. did the first three of 5 kills; 20 kills:
    ``test_kill_9_many_times`` (slow)."""
    assert _kill_and_resume(tmp_path, 3, seed=10, t_end=4000.0) >= 2


@pytest.mark.slow
def test_kill_9_many_times(tmp_path):
    """20 kills (~2 min). The run is long enough (10 000 t.u.) that most kills land before it
    ends on a quiet machine too (at 1000 t.u. a quiet machine finished it after 6 kills)."""
    assert _kill_and_resume(tmp_path, 20, seed=11, t_end=10000.0) >= 15


# ---------------------------------------------------------------------------------------
# Locks.
# ---------------------------------------------------------------------------------------
def test_a_second_run_on_the_same_store_is_refused_naming_the_first(tmp_path):
    f = write_study(tmp_path, run={"t_end": 3000.0})
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen([sys.executable, "-m", "taylorball", "-q", "run", str(f)], env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        lock = tmp_path / "store.lock"
        t0 = time.time()
        while not lock.exists() and time.time() - t0 < 60:
            time.sleep(0.05)
        assert lock.exists() and p.poll() is None
        with pytest.raises(StoreError, match=rf"pid {p.pid}\b"):
            tb.run_study(f)
        r = subprocess.run([sys.executable, "-m", "taylorball", "run", str(f)], env=env, capture_output=True,
                           text=True, timeout=120)
        assert r.returncode == 2 and f"pid {p.pid}" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    finally:
        p.kill()
        p.wait()


def test_orbit_lock_live_dead_and_foreign_holders(tmp_path):
    from taylorball.store import HEARTBEAT_TIMEOUT, Lock

    path = tmp_path / "x.lock"
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        import socket

        path.write_text(json.dumps({"host": socket.gethostname(), "pid": sleeper.pid, "started": "then"}))
        with pytest.raises(StoreError, match=rf"pid {sleeper.pid} on host"):
            Lock(path, "orbit 0").acquire()
    finally:
        sleeper.kill()
        sleeper.wait()
    lk = Lock(path, "orbit 0").acquire()  # the holder is dead: stale, taken over
    assert json.loads(path.read_text())["pid"] == os.getpid()
    lk.release()
    assert not path.exists()
    path.write_text(json.dumps({"host": "elsewhere", "pid": 1, "started": "then"}))
    with pytest.raises(StoreError, match="host elsewhere"):
        Lock(path, "orbit 0").acquire()
    old = time.time() - HEARTBEAT_TIMEOUT - 10
    os.utime(path, (old, old))  # no heartbeat for longer than the timeout: taken over
    Lock(path, "orbit 0").acquire().release()


# ---------------------------------------------------------------------------------------
# Integrity: foreign or corrupt pieces are named at start, before any work.
# ---------------------------------------------------------------------------------------
@pytest.fixture
def half_done(tmp_path):
    f = write_study(tmp_path)
    tb.run_study(f, extend=50.0)
    return f, tmp_path / "store"


def _untouched(store):
    return [RunStore(store).orbit(i).checkpoint() for i in range(2)]


def test_a_chunk_copied_from_another_run_is_named(half_done):
    f, store = half_done
    before = _untouched(store)
    src = store / "orbit_0001" / "angles" / "l" / "c" / "0"
    dst = store / "orbit_0000" / "angles" / "l" / "c" / "0"
    dst.write_bytes(src.read_bytes())
    with pytest.raises(StoreError, match=r"orbit 0 .*array angles/l, chunk 0 "):
        tb.run_study(f)
    assert _untouched(store) == before  # no work was done


def test_a_checkpoint_changed_by_one_ulp_is_named(half_done):
    f, store = half_done
    zj = store / "orbit_0001" / "zarr.json"
    meta = json.loads(zj.read_text())
    x = meta["attributes"]["checkpoint"]["state"][0]
    meta["attributes"]["checkpoint"]["state"][0] = float(np.nextafter(x, np.inf))
    zj.write_text(json.dumps(meta))
    with pytest.raises(StoreError, match=r"orbit 1 .*checkpoint .*altered"):
        tb.run_study(f)


def test_a_corrupt_array_file_is_named(half_done):
    f, store = half_done
    chunk = store / "orbit_0000" / "samples" / "state" / "c" / "0" / "0"
    data = bytearray(chunk.read_bytes())
    data[len(data) // 2] ^= 0xFF
    chunk.write_bytes(bytes(data))
    with pytest.raises(StoreError, match=r"orbit 0 .*samples/state"):
        tb.run_study(f)


def test_an_orbit_copied_from_another_store_is_named(tmp_path):
    tb.run_study(write_study(tmp_path / "a"))
    f = write_study(tmp_path / "b", orbits={"seed": 1})
    tb.run_study(f, extend=50.0)
    other = write_study(tmp_path / "c", orbits={"seed": 5})
    tb.run_study(other, extend=50.0)
    import shutil

    shutil.rmtree(tmp_path / "b" / "store" / "orbit_0001")
    shutil.copytree(tmp_path / "c" / "store" / "orbit_0001", tmp_path / "b" / "store" / "orbit_0001")
    with pytest.raises(StoreError, match=r"orbit 1 .*belongs to another run"):
        tb.run_study(f)


def test_a_crash_during_restart_leaves_a_usable_store(tmp_path, monkeypatch):
    f = write_study(tmp_path)
    tb.run_study(f, extend=50.0)
    store = tmp_path / "store"
    ref = store_content(store)

    class Crash(BaseException):
        pass

    import taylorball.store as st

    # crash while the new store is being built: the old one is untouched and resumes
    real_create = st.RunStore.create

    def dies(self, attrs, orbits, layouts=None):
        real_create(self, attrs, orbits[:1], layouts)
        raise Crash

    monkeypatch.setattr(st.RunStore, "create", dies)
    with pytest.raises(Crash):
        tb.run_study(f, restart=True)
    monkeypatch.setattr(st.RunStore, "create", real_create)
    assert store_content(store) == ref
    assert tb.run_study(f).complete
    # crash right after the old store was renamed aside: a run builds a fresh one
    real_rename = os.rename
    calls = []

    def rename_then_die(a, b):
        real_rename(a, b)
        calls.append(b)
        if len(calls) == 1:
            raise Crash

    monkeypatch.setattr(st.os, "rename", rename_then_die)
    with pytest.raises(Crash):
        tb.run_study(f, restart=True)
    monkeypatch.setattr(st.os, "rename", real_rename)
    assert not store.exists()
    assert tb.run_study(f).complete
    no_leftovers(store)
    # and a restart that completes replaces the store by a fresh run of the same bits
    tb.run_study(f, restart=True)
    assert store_content(store) == store_content(store)
    no_leftovers(store)


# ---------------------------------------------------------------------------------------
# Bad study files: one clear error each, naming file, key, value and the valid form.
# ---------------------------------------------------------------------------------------
BAD = [
    ({"ball": {"inertia": [2.0, 3.0]}}, UsageError, r"\[ball\] inertia = \[2.0, 3.0\]: must be a list of 3"),
    ({"ball": {"mass": -1.0}}, UsageError, r"\[ball\] mass = -1.0: must be a finite number > 0"),
    ({"ball": {"radius": "5"}}, UsageError, r"\[ball\] radius = '5'"),
    ({"ball": {"plane_rate": None}}, UsageError, r"\[ball\] plane_rate missing"),
    ({"ball": {"inertia": [1.0, 1.0, 5.0]}}, ParameterError, r"\[ball\]:.*triangle"),
    ({"ball": {"colour": "red"}}, UsageError, r"unknown key \[ball\] colour"),
    ({"level": {"G": float("nan")}}, UsageError, r"\[level\] G = nan"),
    ({"level": {"C": 10.0}}, UsageError, r"either G, H, h .* or C, M_gamma, h"),
    ({"level": {"H": 20.0}}, ParameterError, r"\[level\]:.*M_gamma"),
    ({"orbits": {"n": 0}}, UsageError, r"\[orbits\] n = 0: must be an integer in \[1, 100000\]"),
    ({"orbits": {"n": True}}, UsageError, r"\[orbits\] n = True"),
    ({"orbits": {"seed": -1}}, UsageError, r"\[orbits\] seed = -1"),
    ({"orbits": {"states": [[1.0, 2.0]]}}, UsageError, r"\[orbits\] takes either n"),
    ({"orbits": {"n": None, "seed": None, "states": [[1.0] * 9]}}, UsageError, r"\[level\] is not used"),
    ({"run": {"t_end": 110.0}}, UsageError, r"\[run\] t_end = 110.0: must be a positive multiple of \[run\] "
                                            r"checkpoint_every = 25.0 \(nearest valid: 100 or 125\)"),
    ({"run": {"t_end": -5.0}}, UsageError, r"\[run\] t_end = -5.0"),
    ({"run": {"t_end": 1e300}}, UsageError, r"\[run\] t_end = 1e\+300: must be at most 10000000 chunks"),
    ({"run": {"checkpoint_every": 0.3}}, UsageError, r"\[run\] checkpoint_every = 0.3: must be a positive multiple "
                                                     r"of \[run\] sample_dt = 0.25"),
    ({"run": {"checkpoint_every": 1e9, "t_end": 1e9}}, UsageError, r"at most 1000000 samples per chunk"),
    ({"run": {"sample_dt": 0.0}}, UsageError, r"\[run\] sample_dt = 0.0"),
    ({"run": {"fp_type": "double"}}, UsageError, r"\[run\] fp_type = 'double': must be one of 'float'"),
    ({"run": {"tol": 1.0}}, UsageError, r"\[run\] tol: tol is the Taylor"),
    ({"run": {"backend": "gpu"}}, UsageError, r"\[run\] backend = 'gpu': must be one of 'threads'"),
    ({"run": {"backend": "dask"}}, UsageError, r"\[run\] scheduler missing: must be a dask scheduler address"),
    ({"run": {"scheduler": "tcp://x:1"}}, UsageError, r"only used with backend = \"dask\""),
    ({"run": {"workers": 0}}, UsageError, r"\[run\] workers = 0"),
    ({"run": {"speed": 2}}, UsageError, r"unknown key \[run\] speed"),
    ({"observables": {"angles_every": 0.3}}, UsageError, r"observables.angles_every must be a positive multiple of "
                                                          r"sample_dt = 0.25 or 0 \(off\), got 0.3"),
    ({"observables": {"samples_every": -1.0}}, UsageError, r"observables.samples_every"),
    ({"observables": {"drift": "yes"}}, UsageError, r"observables.drift must be true or false"),
    ({"observables": {"colour": 1}}, UsageError, r"unknown key \[observables\] colour"),
    ({"output": {"store": ""}}, UsageError, r"\[output\] store = ''"),
    ({"mparallel": {"a": [1.0, 1.0, 1.0]}}, UsageError, r"both tables \[ball\] .* and \[mparallel\] .*: give one"),
    ({"extra": {"a": 1}}, UsageError, r"unknown table \[extra\]"),
]


@pytest.mark.parametrize("changes,error,pattern", BAD, ids=[str(i) for i in range(len(BAD))])
def test_bad_study_files(tmp_path, changes, error, pattern):
    f = write_study(tmp_path, **changes)
    with pytest.raises(error, match=pattern) as info:
        tb.run_study(f)
    assert str(f) in str(info.value)
    assert not (tmp_path / "store").exists()  # refused before any work


def test_every_key_refuses_odd_python_values():
    """StudyConfig.from_dict is public: every key given arrays, bytes, objects, NaN, huge
    or empty values raises a TaylorballError naming it, never another exception."""
    from tests.test_bad_inputs import _STUDY_KEYS, _study_tables

    odd = [np.array(["a"]), np.zeros(2), np.array([]), np.zeros(9), np.bool_(True), float("nan"), float("inf"),
           {}, [], 1j, b"x", object(), 10**30, -1, "", {"bins": np.zeros(2)}]
    for key in _STUDY_KEYS:
        for v in odd:
            a = {**_STUDY_KEYS, key: v}
            try:
                tb.StudyConfig.from_dict(_study_tables(a), base=Path("/nonexistent"))
            except tb.TaylorballError:
                pass


def test_bad_files_and_arguments(tmp_path):
    with pytest.raises(UsageError, match="does not exist"):
        tb.run_study(tmp_path / "none.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[ball\ninertia = ")
    with pytest.raises(UsageError, match="not valid TOML"):
        tb.load_study(bad)
    with pytest.raises(UsageError, match="StudyConfig"):
        tb.run_study(42)
    f = write_study(tmp_path)
    for extend, pat in ((-1.0, "--extend"), (110.0, "nearest valid: 100 or 125"), (float("inf"), "extend")):
        with pytest.raises(UsageError, match=pat):
            tb.run_study(f, extend=extend)
    with pytest.raises(UsageError, match="workers"):
        tb.run_study(f, workers=0)
    with pytest.raises(UsageError, match="restart"):
        tb.run_study(f, restart="yes")
    (tmp_path / "file_store").write_text("x")
    with pytest.raises(UsageError, match="it is a file"):
        tb.run_study(write_study(tmp_path, output={"store": "file_store"}))
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "x").write_text("x")
    with pytest.raises(UsageError, match="not a taylorball run store"):
        tb.run_study(write_study(tmp_path, output={"store": "busy"}))
    assert not (tmp_path / "store").exists()


def test_cli_errors_are_one_line_exit_2(tmp_path, capsys):
    from taylorball.cli import main

    f = write_study(tmp_path, run={"t_end": 110.0})
    assert main(["run", str(f)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "t_end = 110.0" in err[0]
    assert main(["status", str(write_study(tmp_path))]) == 2
    assert "no store" in capsys.readouterr().err
    assert main(["-q", "run", str(write_study(tmp_path)), "--extend", "50"]) == 0
    capsys.readouterr()
    assert main(["status", str(write_study(tmp_path))]) == 0
    out = capsys.readouterr().out
    assert "t_end 100" in out and len(out.strip().splitlines()) == 5


# ---------------------------------------------------------------------------------------
# dask: a worker process killed mid-run.
# ---------------------------------------------------------------------------------------
@pytest.mark.slow
def test_dask_worker_killed_mid_run_equals_threads(tmp_path):
    """A LocalCluster of 2 worker processes; one is killed (SIGKILL) once chunks are
    committed; dask reruns its orbit elsewhere, which resumes from the checkpoint (the
    dead worker's orbit lock is stale). ~40 s."""
    from distributed import Client, LocalCluster

    tb.run_study(write_study(tmp_path / "t", run={"t_end": 2000.0, "backend": "threads"}))
    f = write_study(tmp_path / "d", run={"t_end": 2000.0, "backend": "dask", "scheduler": "tcp://unused:1"})
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        pids = list(client.run(os.getpid).values())
        result = {}
        th = threading.Thread(target=lambda: result.update(st=tb.run_study(f, client=client)))
        th.start()
        store = tmp_path / "d" / "store"
        t0 = time.time()
        while time.time() - t0 < 120:
            cks = [RunStore(store).orbit(i).checkpoint() if store.exists() else None for i in range(2)]
            if any(ck and ck["chunks"] >= 10 for ck in cks):
                break
            time.sleep(0.05)
        assert any(ck and ck["chunks"] >= 10 for ck in cks) and not all(ck and ck["chunks"] == 80 for ck in cks)
        os.kill(pids[0], signal.SIGKILL)  # mid-run: chunks committed, orbits not done
        th.join(300)
        assert result["st"].complete
    assert_same_store(tmp_path / "t" / "store", tmp_path / "d" / "store")
    no_leftovers(tmp_path / "d" / "store")


# ---------------------------------------------------------------------------------------
# Signals: SIGTERM stops a run at a chunk boundary; worker processes die with their parent.
# ---------------------------------------------------------------------------------------
def _signal_defaults():
    """SIGINT and SIGTERM at their default dispositions in the child (see
    ``tests.conftest.sigint_default``)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _descendants(pid):
    """Pids of the live processes below ``pid`` (Linux /proc; zombies not counted)."""
    children = {}
    for p in Path("/proc").iterdir():
        if not p.name.isdigit():
            continue
        try:
            stat = (p / "stat").read_text()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()
        if fields[0] != "Z":
            children.setdefault(int(fields[1]), []).append(int(p.name))
    out, todo = [], [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            out.append(c)
            todo.append(c)
    return out


def _alive(pids):
    alive = []
    for q in pids:
        try:
            if (Path("/proc") / str(q) / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
                alive.append(q)
        except OSError:
            pass
    return alive


def _start_run(f, n_orbits, committed=2, timeout=120.0):
    """`taylorball run f` in its own session; returns it once ``committed`` orbits have a
    committed chunk (and the worker processes, if any, have started)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen([sys.executable, "-m", "taylorball", "-q", "run", str(f)], env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True, preexec_fn=_signal_defaults)
    store = f.parent / "store"
    last = store / f"orbit_{n_orbits - 1:04d}"
    deadline = time.time() + timeout
    while time.time() < deadline and p.poll() is None:
        cks = [RunStore(store).orbit(i).checkpoint() for i in range(n_orbits)] if last.exists() else []
        if sum(1 for ck in cks if ck) >= committed:
            return p
        time.sleep(0.1)
    p.kill()
    raise AssertionError(f"no {committed} committed orbits within {timeout} s: {p.communicate()}")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("backend", [pytest.param("serial", marks=pytest.mark.slow),
                                     pytest.param("threads", marks=pytest.mark.long),
                                     pytest.param("processes", marks=pytest.mark.long),
                                     pytest.param("lanes", marks=pytest.mark.slow)])
def test_sigterm_stops_a_run_at_a_chunk_boundary(tmp_path, backend):
    """SIGTERM to `taylorball run` (a batch scheduler's wall-time limit) once chunks are
    being committed: exit status 143, every worker process gone, no lock or uncommitted row
    left, and a rerun equals an uninterrupted run bit for bit (before: the default SIGTERM
    ended the process at once, exit -15, with the workers of backend "processes" running on)."""
    run = {"t_end": 2000.0, "checkpoint_every": 100.0, "backend": backend, "workers": 2}
    f = write_study(tmp_path / "k", run=run, orbits={"n": 3})
    p = _start_run(f, 3)
    workers = _descendants(p.pid)
    p.send_signal(signal.SIGTERM)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 143, (p.returncode, out, err)
    assert "terminated (SIGTERM)" in err and "rerun" in err
    deadline = time.time() + 10
    while _alive(workers) and time.time() < deadline:
        time.sleep(0.1)
    assert not _alive(workers)
    st = tb.study_status(f)
    assert not st.complete and sum(o["chunks"] for o in st.orbits) > 0
    no_leftovers(tmp_path / "k" / "store")
    tb.run_study(f)
    # the uninterrupted reference in this process (no worker processes to start): the scalar
    # backends write the same bits (test_backends_give_the_same_bits), and a lanes run's do
    # not depend on its workers (tests/test_study_lanes.py); so the rerun with "processes" is
    # also checked against a serial run here
    ref = {"workers": 1} if backend == "lanes" else {"backend": "serial"}
    tb.run_study(write_study(tmp_path / "ref", run=run, orbits={"n": 3}), **ref)
    assert_same_store(tmp_path / "k" / "store", tmp_path / "ref" / "store")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.long
def test_worker_processes_die_with_a_killed_parent(tmp_path):
    """kill -9 of `taylorball run` with backend "processes": its worker processes end within
    a few seconds (before: they integrated on for hours, holding their orbits' locks), and a
    rerun takes the orbits over and completes the store as an uninterrupted run."""
    run = {"t_end": 3000.0, "checkpoint_every": 100.0, "backend": "processes", "workers": 2}
    f = write_study(tmp_path / "k", run=run, orbits={"n": 2})
    p = _start_run(f, 2, committed=1)
    workers = _descendants(p.pid)
    assert workers
    p.send_signal(signal.SIGKILL)
    p.communicate(timeout=60)
    deadline = time.time() + 10
    while _alive(workers) and time.time() < deadline:
        time.sleep(0.1)
    assert not _alive(workers), f"workers {_alive(workers)} outlived their parent"
    tb.run_study(f, backend="serial")
    tb.run_study(write_study(tmp_path / "ref", run=run, orbits={"n": 2}), backend="serial")
    assert_same_store(tmp_path / "k" / "store", tmp_path / "ref" / "store")
    no_leftovers(tmp_path / "k" / "store")


# ---------------------------------------------------------------------------------------
# End times: --extend below the store's end, t_end a hair off a multiple.
# ---------------------------------------------------------------------------------------
def test_extend_below_the_current_end_is_refused(tmp_path, capsys):
    """--extend T with T below the store's end: refused before any work, naming both
    (before: exit 0 and the store's t_end rewritten below its data); T at the end resumes
    (here: nothing left to run); a plain run of a file with a smaller t_end does not lower
    the store's t_end either."""
    f = write_study(tmp_path, run={"t_end": 50.0})
    tb.run_study(f, extend=100.0)
    store = tmp_path / "store"
    raw = store_content(store)
    with pytest.raises(UsageError, match=r"--extend 50.0: is below the store's current end t_end = 100.0"):
        tb.run_study(f, extend=50.0)
    assert RunStore(store).attrs()["t_end"] == 100.0
    from taylorball.cli import main

    assert main(["run", str(f), "--extend", "75"]) == 2
    assert "is below the store's current end t_end = 100.0" in capsys.readouterr().err
    st = tb.run_study(f, extend=100.0)  # the store's end: a resume with nothing left to run
    assert st.complete and store_content(store) == raw
    st = tb.run_study(f)  # the file's t_end = 50: nothing to run, the store keeps its end
    assert RunStore(store).attrs()["t_end"] == 100.0 and st.t_end == 100.0 and st.complete
    assert store_content(store) == raw
    assert tb.run_study(f, extend=125.0).complete  # beyond the end: extends
    # --restart replaces the store: any end is valid again
    assert tb.run_study(f, extend=50.0, restart=True).t_end == 50.0


def test_t_end_a_hair_off_a_multiple_is_refused(tmp_path):
    """t_end = 100.000000001 with checkpoint_every = 25 is not a multiple (before: counted as
    4 chunks, run to 100 and never complete); decimal multiples such as 2.1 of 0.7 (2.1 / 0.7
    = 3.0000000000000004 in float64, and 3 * 0.7 = 2.0999999999999996 < 2.1) are, and their
    runs complete."""
    with pytest.raises(UsageError, match=r"\[run\] t_end = 100.000000001: must be a positive multiple of \[run\] "
                                         r"checkpoint_every = 25.0 \(nearest valid: 100 or 125\)"):
        tb.load_study(write_study(tmp_path, run={"t_end": 100.000000001}))
    with pytest.raises(UsageError, match=r"--extend = 125.00000001: must be a positive multiple"):
        tb.run_study(write_study(tmp_path), extend=125.00000001)
    with pytest.raises(UsageError, match=r"\[run\] checkpoint_every = 25.000001: must be a positive multiple"):
        tb.load_study(write_study(tmp_path, run={"checkpoint_every": 25.000001}))
    assert 2.1 / 0.7 != 3.0 and 3 * 0.7 < 2.1 and 0.7 / 0.1 != 7.0
    f = write_study(tmp_path / "d", run={"t_end": 2.1, "checkpoint_every": 0.7, "sample_dt": 0.1},
                    observables={"angles_every": 0.7, "samples_every": 0.7})
    cfg = tb.load_study(f)
    assert cfg.n_chunks() == 3 and cfg.samples_per_chunk == 7
    st = tb.run_study(f)
    assert st.complete and [o["chunks"] for o in st.orbits] == [3, 3]


# ---------------------------------------------------------------------------------------
# The M||gamma system, and studies built from Python.
# ---------------------------------------------------------------------------------------
def _mp_study(tmp_path, name, t_end, **kw):
    from taylorball.paper import FIG4_BALL

    g = np.array([0.3, 0.4, math.sqrt(1 - 0.3**2 - 0.4**2)])
    X = np.array([[1.0, 2.0, 3.0, *g], [2.0, -1.0, 0.5, *g[::-1]]])
    p = tb.problem("mparallel", FIG4_BALL.to_mparallel())
    kw = {"observables": {"samples_every": 1.0}, "backend": "serial", **kw}
    return tb.StudyConfig.from_problem(p, store=tmp_path / name, states=X, t_end=t_end, checkpoint_every=50.0,
                                       **kw), p, X


def test_an_mparallel_study_built_from_python(tmp_path):
    """The M||gamma system through the study runner: its samples agree with an independent
    long-double integration, the integrals' drift is at rounding level, an extended run is
    bit-identical to a direct one, and the study file of the same values is the same study."""
    cfg, p, X = _mp_study(tmp_path, "a", 200.0)
    st = tb.run_study(cfg)
    assert cfg.kind == "mparallel" and st.complete and [o["chunks"] for o in st.orbits] == [4, 4]
    # drift of |K|^2-type integrals over 200 t.u.: measured 1.1e-14 (48 eps); 1e3 eps bounds it
    assert all(0 < o["max_drift"] < 1e3 * np.finfo(float).eps for o in st.orbits)
    ds = tb.open_run(cfg.store, observable="samples")
    t = np.arange(201) * 1.0
    for i in range(2):
        np.testing.assert_array_equal(ds.t.values[i], t)
        ref = np.asarray(tb.propagate("mparallel", p.params, X[i], t, fp_type=np.longdouble)).astype(float)
        # the float64 integration's own global error, growing along the orbit: measured
        # 5.3e3 and 9.5e3 eps at t <= 200 (~50 eps per time unit); 4e4 eps is a 4x margin
        assert np.max(np.abs(ds.state.values[i] - ref)) < 4e4 * np.finfo(float).eps
    # and in the SIMD lanes of batch integrators (other bits, the same orbits)
    lanes, _, _ = _mp_study(tmp_path, "l", 200.0, backend="lanes")
    assert tb.run_study(lanes).complete
    dl = tb.open_run(lanes.store, observable="samples")
    for i in range(2):
        ref = np.asarray(tb.propagate("mparallel", p.params, X[i], t, fp_type=np.longdouble)).astype(float)
        assert np.max(np.abs(dl.state.values[i] - ref)) < 4e4 * np.finfo(float).eps  # measured 6.9e3, 2.7e3 eps
    half, _, _ = _mp_study(tmp_path, "b", 100.0)
    tb.run_study(half)
    assert tb.run_study(half, extend=200.0).complete
    assert_same_store(tmp_path / "a", tmp_path / "b")
    # the study file with the same values: the same fingerprint (so it resumes that store)
    f = tmp_path / "mp.toml"
    a = p.params
    f.write_text(f"""[mparallel]
a = [{a.a[0]!r}, {a.a[1]!r}, {a.a[2]!r}]
d = {a.d!r}
plane_rate = {a.plane_rate!r}
[orbits]
states = {[list(map(float, x)) for x in X]!r}
[run]
t_end = 200.0
checkpoint_every = 50.0
backend = "serial"
[observables]
samples_every = 1.0
[output]
store = "a"
""")
    assert tb.load_study(f).fingerprint() == cfg.fingerprint()
    assert tb.run_study(f).complete


def test_a_reduced_study_from_python_is_the_study_file(tmp_path):
    """``StudyConfig.from_problem`` with a level and n orbits: the study of the same study file."""
    from taylorball.levels import Levels

    b = BASE["ball"]
    ball = tb.BallParams(inertia=tuple(b["inertia"]), mass=b["mass"], radius=b["radius"], plane_rate=b["plane_rate"])
    cfg = tb.StudyConfig.from_problem(tb.problem("reduced", ball), store=tmp_path / "store", t_end=100.0,
                                      checkpoint_every=25.0, levels=Levels.from_caption(10.0, 2.0, 5.0), n=2, seed=1,
                                      observables=BASE["observables"], backend="serial")
    f = tb.load_study(write_study(tmp_path))
    assert cfg.fingerprint() == f.fingerprint() and cfg.store == f.store
    np.testing.assert_array_equal(cfg.initial_states, f.initial_states)


def test_what_the_mparallel_system_does_not_have_is_refused(tmp_path):
    from taylorball.paper import FIG4_BALL

    mp = {"a": [1 / 27, 1 / 28, 1 / 29], "d": 25.0, "plane_rate": 2.0}
    g = [0.6, 0.0, 0.8]
    cases = [
        ({"orbits": {"states": [[1.0, 2.0, 3.0, *g]]}, "observables": {"extremes": True}},
         r"\[observables\] extremes = True: needs the contact point R \(a ball.*kind 'mparallel' has drift, "
         r"samples_every$"),
        ({"orbits": {"states": [[1.0, 2.0, 3.0, *g]]}, "observables": {"angles_every": 10.0}},
         r"\[observables\] angles_every = 10.0: needs the contact point R"),
        ({"orbits": {"n": 3}}, r"\[mparallel\] studies take explicit \[orbits\] states \(lists of 6 numbers: K1"),
        ({"orbits": {"states": [[1.0] * 9]}}, r"\[orbits\] states = .*each a list of 6 numbers \(K1, K2, K3, gamma1"),
    ]
    for tables, pattern in cases:
        d = {"mparallel": mp, "run": {"t_end": 100.0, "checkpoint_every": 25.0}, "output": {"store": "s"}, **tables}
        with pytest.raises(UsageError, match=pattern):
            tb.StudyConfig.from_dict(d)
    with pytest.raises(UsageError, match=r"\[orbits\] states = .*each a list of 14 numbers"):  # the full system's
        tb.StudyConfig.from_problem(tb.problem("full", FIG4_BALL), store=tmp_path, t_end=10.0, checkpoint_every=5.0,
                                    states=[[0.0] * 12])
    p = tb.problem("mparallel", FIG4_BALL.to_mparallel())
    with pytest.raises(UsageError, match=r"unknown keyword\(s\) fp_type.*come from problem"):
        tb.StudyConfig.from_problem(p, store=tmp_path, t_end=10.0, checkpoint_every=5.0, states=[[1, 2, 3, *g]],
                                    fp_type="float")
    with pytest.raises(UsageError, match=r"problem must be a taylorball Problem"):
        tb.StudyConfig.from_problem("mparallel", store=tmp_path, t_end=10.0, checkpoint_every=5.0)
