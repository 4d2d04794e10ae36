"""The figure studies run end to end on tiny configurations: data + JSON sidecar with
provenance, PNG and PDF, and ``taylorball reproduce`` (including ``--plot-only``)."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from .conftest import sigint_default

import taylorball as tb
from taylorball import cli
from taylorball.errors import UsageError

from taylorball.figures import runner as C

TINY = {"n_orbits": 2, "n_points": 20, "megno_t": 20.0, "contact_t": 10.0, "n_candidates": 2, "extra_points": (),
        "T": 20.0, "map_n": 3}


def tiny(cfg):
    fields = {f.name for f in dataclasses.fields(cfg)}
    return dataclasses.replace(cfg, **{k: v for k, v in TINY.items() if k in fields})


def _no_plot(arrays, meta, outdir):
    """A study's ``plot`` for runs that only need its data (saved; the figures are drawn by
    another run of the same test)."""
    return []


def _shared_compute(mod, study_result):
    """``mod.compute`` through the session's cache of study results (``study_result``,
    tests/conftest.py): the same function of the configuration, run once per session (the
    runner passes ``workdir`` only to a study whose compute takes it)."""
    import inspect
    import types

    original = types.SimpleNamespace(__name__=mod.__name__, compute=mod.compute)
    if "workdir" in inspect.signature(mod.compute).parameters:
        def compute(cfg, workdir=None):
            return study_result(original, cfg)
    else:
        def compute(cfg):
            return study_result(original, cfg)
    return compute


@pytest.mark.parametrize("name", C.figure_studies())
@pytest.mark.long
def test_study_runs_and_saves(name, tmp_path, monkeypatch, study_result):
    mod = C.load_study(name)
    assert dataclasses.is_dataclass(mod.QUICK) and dataclasses.is_dataclass(mod.FULL)
    monkeypatch.setattr(mod, "QUICK", tiny(mod.QUICK))
    monkeypatch.setattr(mod, "compute", _shared_compute(mod, study_result))
    drawn = []
    plot = mod.plot

    def recording_plot(arrays, meta, outdir):
        drawn.append((arrays, meta))
        return plot(arrays, meta, outdir)

    monkeypatch.setattr(mod, "plot", recording_plot)
    data, figs = C.run(mod, outdir=tmp_path, log=lambda *a: None)
    assert data.exists() and data.with_suffix(".json").exists()
    side = json.loads(data.with_suffix(".json").read_text())
    assert side["meta"]["study"] == name and side["meta"]["quality"] == "quick"
    assert "heyoka" in json.dumps(side)  # provenance: package versions
    assert {f.suffix for f in figs} == {".png"} and all(f.stat().st_size > 1000 for f in figs)
    # re-plot from the saved data without computing: plot() gets exactly the arrays (names,
    # dtypes, values) and the metadata it drew the figures from above (plot is a function
    # of them, so it draws the same figures; drawing them twice cost half of this test)
    monkeypatch.setattr(mod, "plot", lambda arrays, meta, outdir: drawn.append((arrays, meta)) or figs)
    _, figs2 = C.run(mod, outdir=tmp_path, plot_only=True, log=lambda *a: None)
    assert [f.name for f in figs2] == [f.name for f in figs]
    (a1, m1), (a2, m2) = drawn
    assert sorted(a1) == sorted(a2) and m1 == m2
    for k in a1:
        assert a1[k].dtype == a2[k].dtype and a1[k].shape == a2[k].shape, k
        assert np.array_equal(a1[k], a2[k], equal_nan=a1[k].dtype.kind in "fc"), k


def test_figure_list_and_reproduce_cli(tmp_path, capsys):
    assert C.figure_studies() == ["fig1_mparallel_map", "fig2_homogeneous", "fig3_symmetric",
                                  "fig4_asymmetric_map", "fig5_contact_point", "megno_map", "chaos_atlas",
                                  "diffusion"]
    assert C.ON_REQUEST == ("skeleton", "skeleton_bifurcation", "skeleton_surface", "skeleton_tori")  # taylorball reproduce --only skeleton
    assert cli.main(["reproduce", "--only", "fig9", "--out", str(tmp_path)]) == 2
    assert "unknown figure" in capsys.readouterr().err


@pytest.mark.long
def test_reproduce_in_worker_processes(tmp_path, capsys, monkeypatch, study_result):
    """``--workers 2``: figures in spawned worker processes, a line per figure; a figure that
    fails in its worker (here: --plot-only on a corrupt data file; a missing one is refused
    before any work, tests/test_cli.py) is named and makes the exit status 1 while the
    others finish."""
    for name in ("fig2_homogeneous", "fig5_contact_point"):
        mod = C.load_study(name)
        with monkeypatch.context() as m:  # the data only: the workers draw the figures
            m.setattr(mod, "QUICK", tiny(mod.QUICK))
            m.setattr(mod, "plot", _no_plot)
            m.setattr(mod, "compute", _shared_compute(mod, study_result))
            C.run(mod, outdir=tmp_path, log=lambda *a: None)
    argv = ["reproduce", "--plot-only", "--out", str(tmp_path), "--workers", "2"]
    assert cli.main(argv + ["--only", "fig2,fig5"]) == 0
    out = capsys.readouterr().out
    assert "2 at a time" in out and "fig2_homogeneous: data" in out and "fig5_contact_point: data" in out
    (tmp_path / "data" / "fig3_symmetric.npz").write_bytes(b"not an npz file")
    assert cli.main(argv + ["--only", "fig2,fig3"]) == 1
    cap = capsys.readouterr()
    assert "fig2_homogeneous: data" in cap.out and "fig3_symmetric: FAILED" in cap.err
    assert cli.main(argv + ["--only", "fig2", "--workers", "-1"]) == 2
    assert "--workers must be a positive integer" in capsys.readouterr().err


def test_schedule_runs_the_longest_first_and_no_two_shared_compiles_at_once():
    """``reproduce --workers N`` (quick) hands the studies to the workers longest first, but the
    first N include at most one study that compiles the reduced system's shared integrators;
    every quick study has a cost, and the schedule is a permutation of the names given."""
    names = C.figure_studies()
    assert set(names) <= set(C.QUICK_CPU_S), "a quick study without a cost in runner.QUICK_CPU_S"
    for jobs in (1, 2, 3, 8):
        order = C.schedule(names, jobs)
        assert sorted(order) == sorted(names)
        if jobs <= 3:  # (8 jobs: every study starts at once, whatever the order)
            assert sum(n in C.SHARED_COMPILES for n in order[:jobs]) == 1
            rest = [C.QUICK_CPU_S[n] for n in order[jobs:]]
            assert rest == sorted(rest, reverse=True)
    assert C.schedule(names, 2)[0] == max(names, key=C.QUICK_CPU_S.get)
    assert C.schedule(["fig3_symmetric", "fig4_asymmetric_map", "fig1_mparallel_map"], 2) == [
        "fig4_asymmetric_map", "fig1_mparallel_map", "fig3_symmetric"]
    assert C.schedule(["contact_diffusion", "fig2_homogeneous"], 2) == ["fig2_homogeneous", "contact_diffusion"]


@pytest.mark.long
def test_contact_diffusion_study_runs_and_resumes(tmp_path, monkeypatch):
    """The long-run study on the study runner: running extremes of |R| are monotone, below
    the rigorous bound, one store per level under the output folder; a second run resumes
    (no chunk is recomputed: its segment adds none, no data file is rewritten) with the same
    numbers; a file beside the stores is left alone."""
    import numpy as np

    from taylorball.store import RunStore

    mod = C.load_study("contact_diffusion")
    cfg = dataclasses.replace(mod.QUICK, n_orbits=1, t_end=60.0, sample_dt=0.5, checkpoint_dt=20.0, n_log=6)
    monkeypatch.setattr(mod, "QUICK", cfg)
    keep = tmp_path / "longruns" / "contact_diffusion_H2_notes.old"  # a user's file, named like a leftover
    keep.parent.mkdir(parents=True)
    keep.write_text("mine")
    data, figs = C.run(mod, outdir=tmp_path, log=lambda *a: None)
    side = json.loads(data.with_suffix(".json").read_text())["meta"]
    z = np.load(data)
    assert z["r_max"].shape == (2, 6) and z["r_min"].shape == (2, 6)
    assert np.all(np.diff(z["r_max"], axis=1) >= 0) and np.all(np.diff(z["r_min"], axis=1) <= 0)
    assert np.all(z["r_max"] <= side["radius_bound"]) and np.all(z["r_min"] >= 0)
    # float64, tolerance eps, ~1000 steps: integrals to ~1e-14 of their scale
    assert 0 < side["max_relative_integral_drift"] < 1e-12
    # the bits the npz long-run path (removed) gave for this configuration, measured with it
    # on 2026-11-28: the same integrator, tolerance, chunk ends and sample grid, so the same
    # orbits, running extremes, steps and contact points
    hexes = lambda a: [[float(v).hex() for v in row] for row in np.asarray(a)]  # noqa: E731
    assert hexes(z["r_max"]) == [
        ["0x1.02d34ed483429p+4"] * 5 + ["0x1.0f5aedebfd723p+4"],
        ["0x1.d54c416bb747bp+3"] * 3 + ["0x1.f2245cfb8b5b2p+3"] * 2 + ["0x1.f3bc823e43f4ep+3"]]
    assert hexes(z["r_min"]) == [
        ["0x1.fc94fde284ea7p+1"] + ["0x1.db9a95173c338p-1"] * 3 + ["0x1.b8ef3869d901fp-1"] * 2,
        ["0x1.07b5b291a62cfp+2"] + ["0x1.a65b7fd55f9b3p-1"] * 4 + ["0x1.82348cb7258c5p-1"]]
    assert side["n_steps"] == [926, 985]
    assert hexes(z["tail_xy"][:, -1]) == [["-0x1.de6f4b21e33b9p+2", "0x1.80bd6f7a45d34p+2"],
                                          ["0x1.ab97a769ace78p-1", "0x1.f3057231d80fep+3"]]
    stores = [Path(f) for f in side["stores"]]
    assert [f.parent for f in stores] == [tmp_path / "longruns"] * 2
    assert [f.name.split("_")[2] for f in stores] == ["H2", "H6"]
    for f in stores:
        ds = tb.open_run(f, verify="full")
        assert list(ds.attrs["progress"]) == [3] and ds.attrs["t_end"] == 60.0
    files = {p: p.stat().st_mtime_ns for f in stores for p in f.rglob("*") if p.is_file() and "orbit_" in str(p)
             and p.name != "zarr.json"}
    monkeypatch.setattr(mod, "plot", _no_plot)  # the resumed run's data (its figures are drawn above)
    data2, _ = C.run(mod, outdir=tmp_path, log=lambda *a: None)
    z2 = np.load(data2)
    assert np.array_equal(z["r_max"], z2["r_max"]) and np.array_equal(z["r_min"], z2["r_min"])
    assert all(RunStore(f).attrs()["segments"][-1]["chunks"] == 0 for f in stores)
    assert {p: p.stat().st_mtime_ns for p in files} == files
    assert keep.read_text() == "mine"
    assert {f.suffix for f in figs} == {".png"}


@pytest.mark.long
def test_diffusion_large_study_runs_resumes_and_matches_its_study_file(tmp_path, monkeypatch):
    """The lanes study: the h2 store is the one ``studies/diffusion_h2_64_1e6.toml`` makes
    (same fingerprint at the same size), a rerun resumes without recomputing (same numbers),
    the running extremes of |R| are monotone and below the rigorous bound, the fits are
    finite with the point estimate inside its interval, the orbit classes partition the
    orbits."""
    import numpy as np

    import taylorball as tb

    mod = C.load_study("diffusion_large")
    cfg = dataclasses.replace(mod.QUICK, n_orbits=3, t_end=2000.0, checkpoint_every=1000.0, angles_every=2.0,
                              n_boot=100)
    monkeypatch.setattr(mod, "QUICK", cfg)
    data, figs = C.run(mod, outdir=tmp_path, log=lambda *a: None)
    levels = json.loads(data.with_suffix(".json").read_text())["meta"]["levels"]
    z = np.load(data)
    assert sorted(levels) == ["h2", "h6"]
    for label, side in levels.items():
        assert z[f"{label}_r_max"].shape == (3, 2) and np.all(np.diff(z[f"{label}_r_max"], axis=1) >= 0)
        assert np.all(z[f"{label}_r_max"] <= side["radius_bound"]) and np.all(z[f"{label}_r_min"] >= 0)
        for name in ("l", "heading"):
            for f in side[name]["fits"]:
                assert f["ci"][0] <= f["mu"] <= f["ci"][1] and np.isfinite(f["mu"])
            cl = side[name]["classes"]
            assert sorted(cl["chaotic"]["orbits"] + cl["regular"]["orbits"]) == [0, 1, 2]
        # float64, tolerance eps: the integrals to ~1e-14 of their scale
        assert side["max_integral_drift"] < 1e-12
    # the study files of the FULL runs name the same stores (fingerprints) as the module's FULL
    for label in ("h2", "h6"):
        f = Path(__file__).resolve().parent.parent / "studies" / f"diffusion_{label}_64_1e6.toml"
        full_file = tb.load_study(f)
        assert full_file.fingerprint() == mod.study_config(mod.FULL, label, tmp_path).fingerprint()
        assert (full_file.n_orbits, full_file.t_end) == (mod.FULL.n_orbits, mod.FULL.t_end)
    store = Path(levels["h2"]["store"])
    # the orbits' arrays and checkpoints (the store's own attributes record each run's t_end)
    stamp = {f: f.stat().st_mtime_ns for f in store.rglob("*") if f.is_file() and f.parent != store}
    assert len(stamp) > 20
    monkeypatch.setattr(mod, "plot", _no_plot)  # the resumed run's data (its figures are drawn above)
    data2, _ = C.run(mod, outdir=tmp_path, log=lambda *a: None)
    z2 = np.load(data2)
    assert np.array_equal(z["h2_l_msd"], z2["h2_l_msd"]) and np.array_equal(z["h6_r_max"], z2["h6_r_max"])
    assert {f: f.stat().st_mtime_ns for f in stamp} == stamp  # nothing rewritten: resumed, no work
    assert {f.suffix for f in figs} == {".png"}
    # the same stores reduced as a study file's (reduce_stores, nothing run): the same numbers,
    # bit for bit; a store of other orbits, or one that has not reached t_end, is refused
    from taylorball.io import jsonable

    stores = {label: side["store"] for label, side in levels.items()}
    arrays3, meta3 = mod.reduce_stores(cfg, stores)
    assert sorted(arrays3) == sorted(z.files) and all(np.array_equal(arrays3[k], z[k]) for k in z.files)
    for label, side in levels.items():
        got = json.loads(json.dumps(jsonable(meta3["levels"][label])))
        assert got["orbits"] == [0, 1, 2] and got["n_orbits_study"] == 3
        assert {k: v for k, v in got.items() if k not in ("orbits", "n_orbits_study")} == \
            {k: v for k, v in side.items() if k != "n_steps"}
    with pytest.raises(UsageError, match="other orbits or observables"):
        mod.reduce_stores(dataclasses.replace(cfg, levels=("h2",)), {"h2": stores["h6"]})
    with pytest.raises(UsageError, match="0 of 3 orbits .* have reached t_end = 4000"):
        mod.reduce_stores(dataclasses.replace(cfg, levels=("h2",), t_end=4000.0), {"h2": stores["h2"]})


@pytest.mark.long
def test_ctrl_c_stops_a_parallel_reproduce(tmp_path):
    """Ctrl-C at the terminal (SIGINT to the whole process group) during ``reproduce --workers
    2``: workers end, queued figures are dropped, exit status 130, and no partial files
    (figures are written atomically)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    p = subprocess.Popen([sys.executable, "-m", "taylorball.cli", "reproduce", "--only", "fig3,fig4,fig1",
                          "--out", str(tmp_path), "--workers", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, start_new_session=True, preexec_fn=sigint_default)
    time.sleep(4.0)  # the workers are importing or computing (fig3 and fig4 take ~9 s and ~4 s each)
    os.killpg(p.pid, signal.SIGINT)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 130, (p.returncode, out, err)
    assert "interrupted after" in err
    done = [n for n in ("fig3_symmetric", "fig4_asymmetric_map", "fig1_mparallel_map") if f"{n}: data" in out]
    for n in done:  # a figure reported finished has its data and sidecar
        assert (tmp_path / "data" / f"{n}.npz").exists() and (tmp_path / "data" / f"{n}.json").exists()
    import numpy as np

    for f in (tmp_path / "data").glob("*.npz") if (tmp_path / "data").exists() else []:
        np.load(f)  # every visible data file is complete (a killed write leaves at most a hidden .tmp)


def test_every_study_has_its_module_and_its_script():
    """The list of studies matches the package's modules and the checkout's thin scripts
    (``studies/<name>.py``, one per study); no matplotlib import at a module's top level."""
    import ast

    import taylorball.figures as F

    pkg = Path(F.__file__).parent
    assert sorted(p.stem for p in pkg.glob("fig*.py")) == list(C.FIGURES)
    assert sorted(p.stem for p in pkg.glob("[!_]*.py") if p.stem != "runner") == sorted(C.STUDIES)
    scripts = Path(__file__).resolve().parent.parent / "studies"
    assert sorted(p.stem for p in scripts.glob("*.py")) == sorted(C.STUDIES)
    for f in pkg.glob("*.py"):
        top = [n for n in ast.parse(f.read_text()).body if isinstance(n, (ast.Import, ast.ImportFrom))]
        names = [a.name for n in top for a in n.names]
        names += [n.module or "" for n in top if isinstance(n, ast.ImportFrom)]
        assert not any(m.split(".")[0] == "matplotlib" for m in names), f"{f.name}: matplotlib at top level"
    with pytest.raises(UsageError, match="study must be one of"):
        C.load_study("fig9")


@pytest.mark.long
def test_study_script_runs_outside_the_package(tmp_path, monkeypatch, study_result):
    """``python studies/fig2_homogeneous.py --plot-only --out DIR`` re-plots saved data
    through the package's study (the script is a thin launcher)."""
    import subprocess
    import sys

    mod = C.load_study("fig2_homogeneous")
    with monkeypatch.context() as m:  # the data only: the script draws the figures
        m.setattr(mod, "QUICK", tiny(mod.QUICK))
        m.setattr(mod, "plot", _no_plot)
        m.setattr(mod, "compute", _shared_compute(mod, study_result))
        C.run(mod, outdir=tmp_path, log=lambda *a: None)
    png = tmp_path / "figures" / "fig2_homogeneous.png"
    assert not png.exists()
    script = Path(__file__).resolve().parent.parent / "studies" / "fig2_homogeneous.py"
    r = subprocess.run([sys.executable, str(script), "--plot-only", "--out", str(tmp_path)], cwd=tmp_path,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "fig2_homogeneous: data" in r.stdout and png.exists()
    h = subprocess.run([sys.executable, str(script), "--help"], capture_output=True, text=True, timeout=300)
    assert h.returncode == 0 and "Fig. 2: homogeneous ball" in h.stdout and "--plot-only" in h.stdout


@pytest.mark.parametrize("name", ["fig2_homogeneous", "fig4_asymmetric_map"])  # Fig. 3 plots as Fig. 2
def test_maps_plot_data_saved_before_the_sheets_were_recorded(name, tmp_path, study_result):
    """The sheet of each crossing (root index of K) and Fig. 4b's MEGNO map are later arrays:
    data without them still plots, with the sheets overlaid and without the map panel
    (test_study_runs_and_saves plots the data with them)."""
    from taylorball.io import jsonable

    mod = C.load_study(name)
    cfg = tiny(mod.QUICK)
    arrays, meta = study_result(mod, cfg)  # test_study_runs_and_saves computes the same
    sheets = [k for k in arrays if k.endswith("sheet")]
    assert sheets and all(arrays[k].dtype.kind == "i" and len(arrays[k]) == len(arrays[k[:-5] + "orbit"])
                          for k in sheets)
    old = {k: v for k, v in arrays.items() if k not in sheets and "_map_" not in k}
    figs = mod.plot(old, jsonable({"config": dataclasses.asdict(cfg), **meta}), tmp_path)
    assert figs and all(f.stat().st_size > 1000 for f in figs)


def test_pi_ticks_label_angles_in_multiples_of_pi():
    from taylorball.figures._common import pi_ticks, pyplot

    plt = pyplot()
    fig, ax = plt.subplots()
    pi_ticks(ax, "x")
    assert [t.get_text() for t in ax.get_xticklabels()] == ["0", "π/2", "π", "3π/2", "2π"]
    assert ax.get_xticks()[-1] == pytest.approx(2 * 3.141592653589793, rel=4 * 2.0**-52)  # 2 * (pi/2 * 2): 2 roundings
    pi_ticks(ax, "y", lo=-3.2, hi=3.2, denominator=1)
    assert [t.get_text() for t in ax.get_yticklabels()] == ["−π", "0", "π"]
    plt.close(fig)


@pytest.mark.parametrize("label", ["h2", "h6", "weak"])
def test_diffusion_cluster_study_files(label, tmp_path):
    """``studies/diffusion_<label>_1e8.toml`` (the diffusion study at cluster scale) names the
    level of ``taylorball.figures.diffusion.LEVELS`` with the Fig. 4 ball, and runs as
    written once shrunk (2 orbits to t = 20, threads instead of the dask scheduler): its
    observables give the arrays the study's reductions read."""
    import sys

    if sys.version_info >= (3, 11):
        import tomllib
    else:
        import tomli as tomllib

    import numpy as np

    import taylorball as tb
    from taylorball.figures import diffusion as D
    from taylorball.study import StudyConfig

    f = Path(__file__).resolve().parent.parent / "studies" / f"diffusion_{label}_1e8.toml"
    d = tomllib.loads(f.read_text())
    full = tb.load_study(f)
    _, omega, H, h = dict((lv[0], lv) for lv in D.LEVELS)[label]
    assert full.params.plane_rate == omega and tuple(full.params.inertia) == D.FULL.inertia
    assert full.levels == tb.Levels.from_caption(G=D.FULL.G, H=H, h=h)
    assert (full.n_orbits, full.t_end, full.backend) == (64, 1e8, "dask")
    d["orbits"]["n"] = 2
    d["run"] = {"t_end": 20.0, "checkpoint_every": 10.0, "backend": "threads", "workers": 2}
    d["output"]["store"] = "store"
    tb.run_study(StudyConfig.from_dict(d, base=tmp_path))
    ds = tb.open_run(tmp_path / "store")
    for v in ("angles_l", "heading_heading", "extremes_r_max", "extremes_r_min", "sections_t", "histogram_time"):
        assert v in ds and ds[v].sizes["orbit"] == 2
    assert np.all(np.isfinite(ds.angles_l.values)) and ds.angles_l.shape == (2, 1 + 20 // 50)


@pytest.mark.parametrize("label", ["h2", "h6", "weak"])
def test_diffusion_64_orbit_study_files_are_the_large_study(label):
    """``studies/diffusion_<label>_64_1e6.toml`` holds the orbits and observables of the
    diffusion_large study's level ``label`` at 64 orbits (the same fingerprint), so that
    ``studies/diffusion_large.py --stores`` reduces its store, extended or not."""
    import dataclasses

    from taylorball.figures import diffusion_large as DL
    from taylorball.study.config import load_study

    root = Path(__file__).resolve().parent.parent / "studies"
    cfg = dataclasses.replace(DL.FULL, levels=(label,))
    assert DL.study_config(cfg, label, root).fingerprint() == \
        load_study(root / f"diffusion_{label}_64_1e6.toml").fingerprint()
