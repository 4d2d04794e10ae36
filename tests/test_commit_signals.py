"""An interrupt that lands inside a store commit is held back to the commit's end
(taylorball._signals.held_signals around study.job.Job.commit): a lanes run with one worker
integrates and commits in the main thread, where Python raises Ctrl-C's KeyboardInterrupt
between any two bytecodes; one raised between a commit's rows and its checkpoint (whose
write zarr finishes in its own thread) left the in-memory checkpoint behind the file, and
the clean-up then cut arrays below the stored checkpoint."""

import os
import signal

import pytest

import taylorball as tb
from taylorball._signals import held_signals
from taylorball.store import OrbitStore, RunStore
from tests.test_study import no_leftovers, write_study


def test_held_signals_deliver_after_the_block():
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        done = []
        with pytest.raises(KeyboardInterrupt):
            with held_signals():
                os.kill(os.getpid(), signal.SIGINT)
                done.append("after the signal")  # the block runs to its end
        assert done == ["after the signal"]
        with held_signals():  # nothing held: nothing delivered
            done.append("quiet")
    finally:
        signal.signal(signal.SIGINT, old)


def test_ctrl_c_inside_a_commit_lands_after_it(tmp_path, monkeypatch):
    """SIGINT sent while orbit 0's second chunk is being written (its rows written, its
    checkpoint not yet): the commit completes, KeyboardInterrupt comes after it, and the
    store is consistent (status reads it; no lock or uncommitted row left)."""
    run = {"backend": "lanes", "t_end": 1000.0, "checkpoint_every": 250.0, "workers": 1}
    f = write_study(tmp_path / "k", run=run, orbits={"n": 2})
    original = OrbitStore._write
    calls = {"n": 0}

    def write(self, writes):
        original(self, writes)
        if self.index == 0:
            calls["n"] += 1
            if calls["n"] == 2:  # orbit 0, chunk 2: rows written, checkpoint next
                os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(OrbitStore, "_write", write)
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            tb.run_study(f, progress=False)
    finally:
        signal.signal(signal.SIGINT, old)
    assert calls["n"] == 2
    assert RunStore(tmp_path / "k" / "store").orbit(0).checkpoint()["chunks"] == 2  # the interrupted commit is whole
    st = tb.study_status(f)  # the arrays are at least as long as committed
    assert not st.complete
    no_leftovers(tmp_path / "k" / "store")
