"""taylorball.io: results saved as .npz plus a JSON sidecar."""

from __future__ import annotations

import numpy as np
import pytest

import taylorball as tb
from taylorball.io import load_result, save_result


def test_save_and_load_round_trip(tmp_path):
    arrays = {"t": np.linspace(0.0, 1.0, 5), "n": np.arange(3)}
    path = save_result(tmp_path / "r", arrays, {"what": "test"})
    loaded, side = load_result(path)
    assert sorted(loaded) == ["n", "t"]
    assert all(np.array_equal(loaded[k], arrays[k]) for k in arrays)
    assert side["meta"] == {"what": "test"} and side["arrays"] == ["n", "t"]


@pytest.mark.parametrize("name", ["allow_pickle", "file", 3])
def test_array_names_that_numpy_takes_as_arguments_are_refused(tmp_path, name):
    """``allow_pickle`` was silently not saved and ``file`` a TypeError inside numpy (found by
    mypy's check of ``savez_compressed(buf, **store)``); now a UsageError before any write."""
    with pytest.raises(tb.UsageError, match=r"arrays: the array names must be strings other than"):
        save_result(tmp_path / "r", {name: np.arange(3.0)}, {})
    assert list(tmp_path.iterdir()) == []
