"""The npz long-run path is gone: its names raise an ``AttributeError`` naming the
replacement, and the CHANGELOG's recipes move an old npz run folder to a study (rerun, bit for
bit where the grids are the same numbers) or read it without taylorball.

``tests/data/npz_long_run`` is an npz run folder written by the removed ``tb.long_run`` (the
reduced system, ``paper.demo_reduced_state()`` of the Fig. 4 ball, ``t_end = 100``,
``sample_dt = 0.5``, ``checkpoint_dt = 50``; 2026-11-28, heyoka 7.13.2, x86_64), kept as the
reference the recipes are checked against."""

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

import taylorball as tb

ROOT = Path(__file__).resolve().parents[1]
NPZ_RUN = Path(__file__).resolve().parent / "data" / "npz_long_run"


@pytest.mark.parametrize("name, replacement", [
    ("long_run", r"tb.StudyConfig.from_problem\(problem.*tb.run_study.*tb.open_run"),
    ("load_long_run", r"read by tb.open_run"),
    ("LongRunConfig", r"use tb.StudyConfig"),
    ("LongRunResult", r"tb.open_run\(store\) returns an xarray.Dataset"),
    ("run_ensemble", r"use tb.run_many\(\[taylorball.ensemble.call\(fn, x\) for x in items\]"),
    ("longrun", r"long runs are studies \(taylorball.study\)"),
])
def test_a_removed_name_raises_naming_its_replacement(name, replacement):
    with pytest.raises(AttributeError, match=rf"taylorball.{name} was removed in 0.1.0 .*{replacement}"):
        getattr(tb, name)
    assert name not in tb.__all__
    assert hasattr(tb, "no_such_name") is False  # other names: the plain AttributeError


def _recipes():
    text = (ROOT / "CHANGELOG.md").read_text()
    sec = text[text.index("#### Moving an npz long run to a study"):]
    sec = sec[:sec.index("\n### ")]
    blocks = re.findall(r"```python\n(.*?)```", sec, re.S)
    assert len(blocks) == 2
    return blocks


def _npz_samples(folder):
    """The npz run's samples, read here with numpy (chunk ends shared with the next chunk)."""
    n = int(np.load(folder / "checkpoint.npz")["next_chunk"])
    t, X = [], []
    for k in range(n):
        with np.load(folder / f"chunk_{k:06d}.npz") as z:
            t.append(z["t"] if k == 0 else z["t"][1:])
            X.append(z["states"] if k == 0 else z["states"][1:])
    return np.concatenate(t), np.concatenate(X)


def test_the_changelog_reruns_an_npz_run_as_a_study_bit_for_bit(tmp_path, monkeypatch):
    """The first recipe, as written (in a folder holding ``old-run``): the study's samples
    are the npz run's, bit for bit (sample_dt = 0.5, checkpoint_dt = 50: the two grids are
    the same numbers)."""
    shutil.copytree(NPZ_RUN, tmp_path / "old-run")
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    exec(compile(_recipes()[0], "CHANGELOG.md", "exec"), ns)  # noqa: S102 - the changelog's own recipe
    ds = ns["ds"]
    t, X = _npz_samples(tmp_path / "old-run")
    assert X.shape == (201, 9)
    np.testing.assert_array_equal(ds["t"].values[0], t)
    np.testing.assert_array_equal(ds["state"].values[0], X)
    assert ns["cfg"].store == tmp_path / "runs" / "converted"


def test_the_changelog_reads_an_npz_folder_without_taylorball(tmp_path, monkeypatch):
    shutil.copytree(NPZ_RUN, tmp_path / "old-run")
    monkeypatch.chdir(tmp_path)
    code = _recipes()[1]
    assert "taylorball" not in code.replace("(no taylorball needed)", "")
    ns: dict = {}
    exec(compile(code, "CHANGELOG.md", "exec"), ns)  # noqa: S102 - the changelog's own recipe
    t, X = _npz_samples(tmp_path / "old-run")
    np.testing.assert_array_equal(ns["ds"]["time"].values, t)
    np.testing.assert_array_equal(ns["ds"]["state"].values, X)
    assert '"checkpoint_dt": 50.0' in ns["ds"].attrs["config"]
