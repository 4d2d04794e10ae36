"""A lanes store written by the code before the observables' fast path, extended by the
current code, equals a one-go run bit for bit, and both equal what that earlier code wrote.

The study is the cluster files' observables (``studies/diffusion_h2_1e8.toml``: drift,
extremes and histogram of |R|, sections every Nth crossing, the lifted angle and heading)
at a small scale: 6 orbits of the Fig. 4a level, ``checkpoint_every = 25``, run to 50 and
extended to 100. Every orbit's committed records and checkpoint (without wall-clock
fields) are hashed as in ``tests/test_lane_bits.py``.

The pins were made by this file's hashes on the code of 2026-11-28 before the fast path
(commit a0d3432; heyoka 7.13.2, numpy 2.4.6, 4 float64 lanes, Intel Xeon): the store at
50 (what that code wrote and the 1e6 stores are made of) and at 100 (what that code's
extension wrote). On a machine with another lane count the pins are not comparable and
the extension is checked against the one-go run alone.
"""

import pytest

import taylorball as tb

from tests.test_lane_bits import STUDY_STATES, _pins_apply, _study_digest
from tests.test_study import assert_same_store, store_content, write_study

CLUSTER = {"extremes": True, "angles_every": 2.5, "sections": 3, "histogram": {"bins": 20}}

PINNED = {
    50.0: ["3ab119d54257e393", "66fe6494adcdacba", "2e4317dd314b5118", "425880c7504515e4", "15165cdd1704cf61",
           "e978be3197f3be33"],
    100.0: ["dbf3a58103b7ae24", "3c9de7b0fa75cab1", "c25f0187bc848c6c", "8cea3ad93ab17f01", "eb1c0b8d382eb743",
            "ea90c6d7ba69d081"],
}


def _study(folder, t_end, workers=1):
    level = {"G": None, "H": None, "h": None}
    return write_study(folder, run={"backend": "lanes", "workers": workers, "t_end": t_end},
                       observables=CLUSTER, level=level,
                       orbits={"n": None, "seed": None, "states": STUDY_STATES})


def _digests(store):
    return [_study_digest(ck, arrays) for _, (ck, arrays) in sorted(store_content(store).items())]


def test_extend_a_store_of_the_earlier_code_is_bit_identical(tmp_path):
    f = _study(tmp_path / "ext", 50.0)
    tb.run_study(f)
    short = _digests(tmp_path / "ext" / "store")
    tb.run_study(f, extend=100.0)
    g = _study(tmp_path / "one", 100.0)
    tb.run_study(g)
    assert_same_store(tmp_path / "ext" / "store", tmp_path / "one" / "store")
    if _pins_apply():
        assert short == PINNED[50.0], short
        assert _digests(tmp_path / "one" / "store") == PINNED[100.0]
