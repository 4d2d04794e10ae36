"""The run store as a standard zarr v3 hierarchy (readable without taylorball), the
format-1 compatibility path, provenance segments, the checks of tb.open_run and the
store defects (restart leftovers, sealed attributes, nested stores, locks)."""

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import taylorball as tb
import taylorball.store as st
from taylorball.errors import StoreError, UsageError
from taylorball.store import RunStore

from tests.test_study import store_content, write_study

ROOT = Path(__file__).resolve().parents[1]
V1 = ROOT / "tests" / "data" / "store_format1"  # written by format 1 (study.toml beside it)
SHORT = {"run": {"t_end": 50.0}}


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    """A finished 2-orbit store (samples, angles, drift, extremes, histogram, sections)."""
    d = tmp_path_factory.mktemp("done")
    f = write_study(d, run={"t_end": 50.0}, observables={"histogram": True, "sections": "all"})
    tb.run_study(f)
    return f, d / "store"


@pytest.fixture
def copy(done, tmp_path):
    """A private copy of the finished store (and its study file)."""
    f, store = done
    shutil.copytree(store, tmp_path / "store")
    shutil.copy(f, tmp_path / "study.toml")
    return tmp_path / "study.toml", tmp_path / "store"


# ---------------------------------------------------------------------------------------
# A store anyone can read.
# ---------------------------------------------------------------------------------------
def _read_without_taylorball(store: Path) -> dict:
    """Every array of every orbit by xarray.open_datatree in a process where importing
    taylorball fails, checked there against zarr.open_group's dimension names and for units
    and long_name: ``"orbit/observable/variable" -> [dims, flat values]``."""
    code = textwrap.dedent(f"""
        import sys, json, warnings
        sys.modules["taylorball"] = None  # any import of taylorball fails
        import numpy as np, xarray as xr, zarr
        warnings.simplefilter("ignore")
        dt = xr.open_datatree({str(store)!r}, engine="zarr", consolidated=False)
        g = zarr.open_group({str(store)!r}, mode="r")
        out = {{}}
        for orbit in sorted(dt.children):
            for obs in sorted(dt[orbit].children):
                ds = dt[orbit][obs].to_dataset()
                for v in ds.data_vars:
                    a = g[f"{{orbit}}/{{obs}}/{{v}}"]
                    assert a.metadata.dimension_names == ds[v].dims, (orbit, obs, v)
                    assert ds[v].attrs["units"] in ("1", "rad") and ds[v].attrs["long_name"], (orbit, obs, v)
                    out[f"{{orbit}}/{{obs}}/{{v}}"] = [list(ds[v].dims), np.asarray(ds[v].values, float).ravel().tolist()]
        print(json.dumps(out))
    """)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd="/", timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def _assert_same_as_open_run(store: Path, got: dict) -> None:
    ds = tb.open_run(store, verify="full")
    seen = 0
    for i in range(2):
        for name in ds.data_vars:
            obs, v = name.split("_", 1) if not name.startswith("extremes") else ("extremes", name[len("extremes_"):])
            key = f"orbit_{i:04d}/{obs}/{v}"
            dims, values = got[key]
            mine = ds[name].isel(orbit=i).values
            n = len(values) // max(1, int(np.prod(mine.shape[1:])))
            np.testing.assert_array_equal(np.asarray(values).reshape(n, *mine.shape[1:]), mine[:n])
            assert not np.isnan(mine[n:]).any() or np.isnan(mine[n:]).all()
            seen += 1
    assert seen == 2 * len(ds.data_vars) and len(got) == seen


def test_every_orbit_reads_without_taylorball(done):
    """xarray.open_datatree and zarr.open_group in a process where importing taylorball
    fails: every orbit's every array, with dims, units and long_name, equal to open_run's."""
    _, store = done
    _assert_same_as_open_run(store, _read_without_taylorball(store))


def test_a_store_of_the_samples_methods_reads_without_taylorball(tmp_path):
    """The same for a store whose section crossings and lifted angles came from the sample
    grid (``sections_method = angles_method = "samples"``): the same plain hierarchy."""
    f = write_study(tmp_path, run={"t_end": 50.0},
                    observables={"histogram": True, "sections": "all", "sections_method": "samples",
                                 "angles_method": "samples"})
    tb.run_study(f)
    store = tmp_path / "store"
    got = _read_without_taylorball(store)
    assert any("/sections/" in k for k in got) and any("/angles/" in k for k in got)
    _assert_same_as_open_run(store, got)


def test_read_arrays_are_open_runs_values_bit_for_bit(done, copy):
    """taylorball._store_read.read_arrays (numpy, without xarray and dask: the diffusion
    study's reading) gives open_run's arrays: the same names, shapes, dtypes and bits, ragged
    sections padded with NaN alike (the two orbits cross the section a different number of
    times), for the whole store and for one observable; and the same refusal of a damaged
    store, before any array is read."""
    from taylorball._store_read import read_arrays

    _, store = done
    for observable in (None, "sections"):
        ds = tb.open_run(store, observable=observable)
        got = read_arrays(store, observable=observable)
        assert sorted(got) == sorted([*ds.data_vars, *ds.coords])
        assert "angles_time" in got or observable  # the coordinate the diffusion study reads
        for name, a in got.items():
            ref = ds[name].values
            assert a.dtype == ref.dtype and a.shape == ref.shape, name
            # bit for bit, NaN padding included (assert_array_equal counts NaN == NaN)
            assert a.tobytes() == ref.tobytes(), name
    sec = read_arrays(store, observable="sections")["t"]
    assert np.isnan(sec).any() and (np.isfinite(sec).sum(axis=1) > 0).all()  # ragged: padded
    _, broken = copy
    shutil.rmtree(broken / "orbit_0001")
    with pytest.raises(StoreError, match="missing: orbit_0001"):
        read_arrays(broken)


def test_format_1_is_read_and_refused_for_runs_until_upgraded(tmp_path):
    """A store written by format 1: open_run reads it (compatibility path, checks
    included); a run, status or extend refuses it naming the upgrade; upgrade() rewrites
    its metadata (data untouched) and an extend then needs force (its CPU is unknown)."""
    shutil.copytree(V1, tmp_path / "v1")
    f, store = tmp_path / "v1" / "study.toml", tmp_path / "v1" / "store"
    before = store_content(store)
    ds = tb.open_run(store, verify="full")
    assert ds.sizes["orbit"] == 2 and ds.attrs["progress"] == [2, 2]
    assert ds.angles_l.shape == (2, 11) and ds.angles_l.attrs["units"] == "rad"
    with pytest.raises(StoreError, match=r"format 1.*upgrade"):
        tb.run_study(f)
    with pytest.raises(StoreError, match=r"format 1.*upgrade"):
        tb.study_status(f)
    st.upgrade(store)
    assert store_content(store) == before  # the data and checkpoints as they were
    assert RunStore(store).attrs()["format"] == 2
    ds2 = tb.open_run(store, verify="full")
    for v in ds.data_vars:
        np.testing.assert_array_equal(ds[v].values, ds2[v].values)
    assert ds2.angles_l.attrs["units"] == "rad"
    assert tb.study_status(f).complete
    with pytest.raises(StoreError, match="unknown .format 1."):
        tb.run_study(f, extend=75.0)
    tb.run_study(f, extend=75.0, force=True)
    segs = RunStore(store).attrs()["segments"]
    assert segs[-1]["action"] == "extend" and segs[-1]["chunks"] == 2 and segs[-1]["forced"]
    # and the same study run now gives the same values (bits unchanged by the format)
    g = tmp_path / "new"
    shutil.copy(f, tmp_path / "study_new.toml")
    text = (tmp_path / "study_new.toml").read_text().replace('store = "store"', f'store = "{g}"')
    (tmp_path / "study_new.toml").write_text(text)
    tb.run_study(tmp_path / "study_new.toml")
    new = store_content(g)
    for i in before:
        assert new[i][0] == before[i][0]
        assert {k: v[:3] for k, v in new[i][1].items()} == {k: v[:3] for k, v in before[i][1].items()}


# ---------------------------------------------------------------------------------------
# Provenance per segment.
# ---------------------------------------------------------------------------------------
def test_segments_and_the_refused_mix(tmp_path, monkeypatch):
    f = write_study(tmp_path, run={"t_end": 50.0})
    tb.run_study(f, extend=25.0)
    tb.run_study(f)  # resume to 50
    tb.run_study(f)  # nothing to do
    segs = RunStore(tmp_path / "store").attrs()["segments"]
    assert [s["action"] for s in segs] == ["create", "extend", "resume"]
    assert [s["chunks"] for s in segs] == [2, 2, 0]
    import heyoka as hy

    for s in segs:
        assert s["heyoka"] == hy.__version__ and s["simd_size"] == hy.recommended_simd_size() and s["cpu"]
        assert s["host"] and s["started"] and s["ended"] and s["command"] and s["zarr"] and s["numpy"]
    real = st.environment
    monkeypatch.setattr(st, "environment", lambda: dict(real(), heyoka="0.0.1-other", simd_size=16))
    with pytest.raises(StoreError, match=r"heyoka '.*'.*simd_size \d+.*this run has heyoka '0.0.1-other'"):
        tb.run_study(f, extend=75.0)
    assert RunStore(tmp_path / "store").orbit(0).checkpoint()["chunks"] == 2  # no work done
    tb.run_study(f)  # nothing to add: not refused
    from taylorball.cli import main

    assert main(["-q", "run", str(f), "--extend", "75"]) == 2  # the CLI: one line, exit 2
    assert main(["-q", "run", str(f), "--extend", "75", "--force"]) == 0
    assert tb.study_status(f).orbits[0]["chunks"] == 3
    last = RunStore(tmp_path / "store").attrs()["segments"][-1]
    assert last["action"] == "extend" and last["heyoka"] == "0.0.1-other" and last["chunks"] == 2
    assert last["forced"] == [{"heyoka": hy.__version__, "cpu": real()["cpu"], "simd_size": real()["simd_size"]}]
    with pytest.raises(UsageError, match="force must be True or False"):
        tb.run_study(f, force="yes")


# ---------------------------------------------------------------------------------------
# open_run's checks.
# ---------------------------------------------------------------------------------------
def _chunk(store, orbit, key):
    return store / f"orbit_{orbit:04d}" / key / "c" / "0"


def test_open_run_cheap_check_names_the_piece(copy):
    f, store = copy
    tb.open_run(store)
    # a deleted chunk (would read as NaN)
    p = _chunk(store, 1, "angles/l")
    saved = p.read_bytes()
    p.unlink()
    with pytest.raises(StoreError, match=r"orbit 1 .*array angles/l: its zarr chunk file .* is missing"):
        tb.open_run(store)
    p.write_bytes(saved)
    # an edited step (the time coordinate)
    zj = store / "orbit_0000" / "angles" / "l" / "zarr.json"
    meta = json.loads(zj.read_text())
    meta["attributes"]["step"] = 5.0
    zj.write_text(json.dumps(meta))
    with pytest.raises(StoreError, match=r"orbit 0 .*array angles/l has .*step"):
        tb.open_run(store)
    meta["attributes"]["step"] = 2.5
    zj.write_text(json.dumps(meta))
    # swapped orbits
    os.rename(store / "orbit_0000", store / "tmp")
    os.rename(store / "orbit_0001", store / "orbit_0000")
    os.rename(store / "tmp", store / "orbit_0001")
    with pytest.raises(StoreError, match=r"orbit 0 .*holds the group of orbit 1"):
        tb.open_run(store)
    with pytest.raises(StoreError, match=r"orbit 0 .*holds the group of orbit 1"):
        tb.run_study(f)
    os.rename(store / "orbit_0000", store / "tmp")
    os.rename(store / "orbit_0001", store / "orbit_0000")
    os.rename(store / "tmp", store / "orbit_0001")
    # a missing orbit
    os.rename(store / "orbit_0001", store.parent / "away")
    with pytest.raises(StoreError, match=r"2 orbits.*1 orbit groups; missing: orbit_0001"):
        tb.open_run(store)
    os.rename(store.parent / "away", store / "orbit_0001")
    tb.open_run(store)
    # a plain zarr group, an orbit's group
    import zarr

    zarr.open_group(str(store.parent / "plain"), mode="w")
    with pytest.raises(StoreError, match="not a taylorball run store"):
        tb.open_run(store.parent / "plain")
    with pytest.raises(UsageError, match=r"one orbit's group of the store"):
        tb.open_run(store / "orbit_0000")
    with pytest.raises(UsageError, match="verify must be"):
        tb.open_run(store, verify="some")


def test_open_run_full_check_and_decode_errors(copy):
    f, store = copy
    # a chunk copied from the other orbit: only the digests see it
    _chunk(store, 0, "angles/l").write_bytes(_chunk(store, 1, "angles/l").read_bytes())
    tb.open_run(store)  # the cheap check reads no data
    with pytest.raises(StoreError, match=r"orbit 0 .*array angles/l, chunk 0"):
        tb.open_run(store, verify=True)
    with pytest.raises(StoreError, match=r"orbit 0 .*array angles/l, chunk 0"):
        tb.open_run(store, verify="full")
    # flipped bytes: a decode error names orbit and array when the data are computed
    p = _chunk(store, 1, "samples/t")
    data = bytearray(p.read_bytes())
    data[len(data) // 2] ^= 0xFF
    p.write_bytes(bytes(data))
    ds = tb.open_run(store, verify=False)
    with pytest.raises(StoreError, match=r"orbit 1 .*array samples/t cannot be read"):
        ds.samples_t.values
    with pytest.raises(StoreError, match=r"orbit 0 .*angles/l|orbit 1 .*samples/t"):
        tb.open_run(store, verify="full")


# ---------------------------------------------------------------------------------------
# Defects of the store.
# ---------------------------------------------------------------------------------------
def test_restart_never_deletes_a_users_old_or_new_folder(tmp_path):
    f = write_study(tmp_path, **SHORT)
    tb.run_study(f, extend=25.0)
    for name in ("store.old", "store.new", "store.old-123", "store.new-abc"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "backup.txt").write_text("mine")
    tb.run_study(f, restart=True)
    tb.run_study(f)
    for name in ("store.old", "store.new", "store.old-123", "store.new-abc"):
        assert (tmp_path / name / "backup.txt").read_text() == "mine"
    assert not (tmp_path / "store" / ".taylorball-temporary").exists()


def test_edited_initial_state_is_refused(tmp_path):
    f = write_study(tmp_path, **SHORT)
    cfg = tb.load_study(f)
    from taylorball.study.job import _create_store

    _create_store(cfg, cfg.store, 50.0)  # orbits not started
    zj = cfg.store / "orbit_0001" / "zarr.json"
    meta = json.loads(zj.read_text())
    meta["attributes"]["initial_state"][0] = float(np.nextafter(meta["attributes"]["initial_state"][0], 0))
    zj.write_text(json.dumps(meta))
    with pytest.raises(StoreError, match=r"orbit 1 .*'initial_state' attribute .*altered"):
        tb.run_study(f)
    with pytest.raises(StoreError, match=r"orbit 1 .*does not belong to this store"):
        tb.open_run(cfg.store)
    assert RunStore(cfg.store).orbit(0).checkpoint() is None  # no work done


@pytest.mark.parametrize("key,value", [("t_end", 25.0), ("study", {"n_orbits": 2})])
def test_edited_root_attributes_are_refused(copy, key, value):
    f, store = copy
    zj = store / "zarr.json"
    meta = json.loads(zj.read_text())
    if key == "study":
        meta["attributes"]["study"]["t_end"] = 1e9
    else:
        meta["attributes"][key] = value
    zj.write_text(json.dumps(meta))
    with pytest.raises(StoreError, match=r"root attributes .*altered"):
        tb.run_study(f)
    with pytest.raises(StoreError, match=r"root attributes .*altered"):
        tb.open_run(store)


def test_a_store_inside_another_is_refused(copy, tmp_path):
    f, store = copy
    for inner in (store / "inner", store / "orbit_0000" / "inner"):
        g = write_study(tmp_path / "x", output={"store": str(inner)}, **SHORT)
        with pytest.raises(UsageError, match="inside the zarr store"):
            tb.run_study(g)
        assert not inner.exists()
    tb.open_run(store, verify="full")


def test_locks_are_checked_before_any_work(tmp_path):
    f = write_study(tmp_path, orbits={"n": 3}, **SHORT)
    cfg = tb.load_study(f)
    from taylorball.study.job import _create_store

    _create_store(cfg, cfg.store, 50.0)
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        import socket

        lock = cfg.store / "orbit_0002" / ".lock"
        lock.write_text(json.dumps({"host": socket.gethostname(), "pid": sleeper.pid, "started": "then"}))
        with pytest.raises(StoreError, match=rf"orbit 2 .*pid {sleeper.pid}"):
            tb.run_study(f, backend="serial")
        assert [RunStore(cfg.store).orbit(i).checkpoint() for i in range(3)] == [None] * 3  # no orbit ran
    finally:
        sleeper.kill()
        sleeper.wait()
    lock.write_text("garbage that is no lock")
    os.utime(lock, (0, 0))
    with pytest.raises(StoreError, match=r"orbit 2 .*lock file .*orbit_0002/.lock is unreadable"):
        tb.run_study(f)
    assert lock.read_text() == "garbage that is no lock"  # not ours: not deleted
    lock.unlink()


def test_a_deleted_index_chunk_is_named(copy):
    f, store = copy
    _chunk(store, 0, "_index").joinpath("0").unlink()
    with pytest.raises(StoreError, match=r"orbit 0 .*array _index: its zarr chunk file"):
        tb.run_study(f)
    with pytest.raises(StoreError, match=r"orbit 0 .*array _index"):
        tb.open_run(store)
