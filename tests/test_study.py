"""Study files, the run store and the runner (issue 10): resume, extend, crash safety,
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
from pathlib import Path

import numpy as np
import pytest

import taylorball as tb
from taylorball.errors import ParameterError, StateError, StoreError, UsageError
from taylorball.store import RunStore

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
def test_the_issue_example_file_runs(tmp_path):
    """studies/h2.toml as written in issue 10, with t_end 1000 instead of 2000."""
    text = (ROOT / "studies" / "h2.toml").read_text()
    assert "t_end = 2000.0" in text
    f = tmp_path / "h2.toml"
    f.write_text(text.replace("t_end = 2000.0", "t_end = 1000.0"))
    st = tb.run_study(f)
    assert st.complete and len(st.orbits) == 4 and all(o["chunks"] == 2 for o in st.orbits)
    ds = tb.open_run(tmp_path / "runs" / "h2")
    assert ds.sizes["orbit"] == 4
    assert ds.angles_l.shape == (4, 101) and ds.heading_heading.shape == (4, 101)
    assert ds.extremes_r_max.shape == (4, 2) and ds.drift_drift.shape == (4, 2, 5)
    n_cross = ds.sections_t.sizes["sections_crossing"]
    assert 300 < n_cross < 1000  # ~0.63 crossings per t.u. (lead's figure) on 1000 t.u.
    assert tb.study_status(f).complete


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
    from taylorball.study import _create_store, _run_orbit

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


def test_kill_9_then_rerun_is_bit_identical(tmp_path):
    """5 kill -9 of `taylorball run` at random moments (0.8-2.5 s: start-up, compile, chunk
    writes), then a rerun: the store equals an uninterrupted run's, no leftovers (~30 s). The
    run (6000 t.u.) outlasts the kills on a quiet machine too (at 1000 t.u. it could finish
    before the third kill)."""
    assert _kill_and_resume(tmp_path, 5, seed=10, t_end=6000.0) >= 3


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
    ({"mparallel": {"a": [1.0, 1.0, 1.0]}}, UsageError, r"\[mparallel\] studies .* not supported"),
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
