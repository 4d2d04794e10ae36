"""Long runs: atomic checkpoints, bit-exact resume, ensembles identical on every backend.

``long_run``, ``load_long_run`` and ``run_ensemble`` are deprecated (studies replace them):
their behaviour is tested here until they go, with the warning silenced, and the warning
itself in ``test_the_npz_long_run_is_deprecated``."""

import numpy as np
import pytest

import taylorball as tb
from taylorball.longrun import LongRunConfig, long_run, run_ensemble

from .conftest import FIG5, demo_reduced_state

pytestmark = pytest.mark.filterwarnings("ignore:taylorball.(long_run|load_long_run|run_ensemble) is deprecated")


def _cfg(fp_type="float", t_end=40.0, **kw):
    return LongRunConfig(kind="reduced", params=FIG5, state=tuple(demo_reduced_state()), t_end=t_end,
                         sample_dt=1.0, checkpoint_dt=10.0, fp_type=fp_type, **kw)


def _checkpoint(path):
    with np.load(path / "checkpoint.npz", allow_pickle=False) as z:
        return z["state"].copy(), z["dtime"].copy(), int(z["n_steps"])


@pytest.mark.parametrize("fp_type", ["float", "real128"])
def test_resume_is_bit_identical(tmp_path, fp_type):
    cfg = _cfg(fp_type, t_end=40.0 if fp_type == "float" else 20.0)
    a = long_run(cfg, tmp_path / "a")
    part = long_run(cfg, tmp_path / "b", max_chunks=1)
    assert not part.complete and len(part.t) == 11
    b = long_run(cfg, tmp_path / "b")  # a new integrator, rebuilt from the checkpoint
    assert a.complete and b.complete
    sa, ta, na = _checkpoint(tmp_path / "a")
    sb, tb_, nb = _checkpoint(tmp_path / "b")
    assert np.array_equal(sa, sb) and np.array_equal(ta, tb_) and na == nb  # every bit (strings for real128)
    assert np.array_equal(a.states, b.states) and np.array_equal(a.xy, b.xy)


def test_long_run_samples_and_contact_point(tmp_path):
    r = long_run(_cfg(), tmp_path)
    assert r.t.shape == (41,) and np.allclose(r.t, np.arange(41.0))
    ref = tb.propagate("reduced", FIG5, demo_reduced_state(), np.arange(41.0))
    # same integrator, same grid chunks: equal to rounding x growth over t = 40
    assert np.max(np.abs(r.states - ref)) <= 1e-9
    ct = tb.contact_trajectory(FIG5, demo_reduced_state(), np.arange(41.0))
    assert np.max(np.abs(r.xy - ct.xy)) <= 1e-9


def test_checkpoint_of_another_run_is_refused(tmp_path):
    long_run(_cfg(), tmp_path, max_chunks=1)
    with pytest.raises(tb.UsageError, match="another run"):
        long_run(_cfg(t_end=50.0), tmp_path)


@pytest.mark.parametrize(
    "kw, needle",
    [(dict(t_end=-1.0), "t_end must be"), (dict(sample_dt=3.0), "multiple of sample_dt")],
)
def test_config_validation(kw, needle):
    base = dict(kind="reduced", params=FIG5, state=tuple(demo_reduced_state()), t_end=10.0, sample_dt=1.0,
                checkpoint_dt=10.0)
    base.update(kw)
    with pytest.raises(tb.UsageError, match=needle):
        LongRunConfig(**base)


def _member(i):
    s = demo_reduced_state()
    s[0] += 0.01 * i
    return tb.propagate("reduced", FIG5, s, 5.0)


def test_ensemble_backends_agree():
    serial = run_ensemble(_member, range(4), backend="serial")
    threads = run_ensemble(_member, range(4), backend="threads", max_workers=2)
    procs = run_ensemble(_member, range(4), backend="processes", max_workers=2)
    for a, b, c in zip(serial, threads, procs):
        assert np.array_equal(a, b) and np.array_equal(a, c)
    with pytest.raises(tb.UsageError, match="needs client"):
        run_ensemble(_member, range(2), backend="dask")


def test_on_chunk_reports_the_position_including_resumed_chunks(tmp_path):
    seen = []
    cb = lambda k, n: seen.append((k, n))  # noqa: E731
    long_run(_cfg(), tmp_path / "r", max_chunks=1, on_chunk=cb)
    assert seen == [(0, 4), (1, 4)]
    seen.clear()
    long_run(_cfg(), tmp_path / "r", on_chunk=cb)  # resumes: 1 chunk already on disk
    assert seen == [(1, 4), (2, 4), (3, 4), (4, 4)]


def test_progress_advances_chunk_by_chunk_and_counts_resumed_chunks(tmp_path):
    """A long run inside run_many reports its progress per chunk (4 chunks: quarters); on
    resume the chunks already on disk count at once; every member ends at exactly 1."""
    seen = []
    run_ensemble(lambda item: long_run(*item), [(_cfg(), tmp_path / "a")], backend="serial", progress=seen.append)
    assert seen == [0.25] * 4
    long_run(_cfg(t_end=40.0), tmp_path / "b", max_chunks=1)
    seen.clear()
    run_ensemble(lambda item: long_run(*item), [(_cfg(), tmp_path / "b")], backend="serial", progress=seen.append)
    assert seen[0] == 0.25 and sum(seen) == 1.0


@pytest.mark.filterwarnings("default")
def test_the_npz_long_run_is_deprecated(tmp_path):
    """Each deprecated door warns once per call, naming its replacement."""
    with pytest.warns(DeprecationWarning, match=r"taylorball.long_run is deprecated.*tb.run_study"):
        long_run(_cfg(t_end=10.0), tmp_path / "a")
    with pytest.warns(DeprecationWarning, match=r"taylorball.load_long_run is deprecated.*tb.open_run"):
        tb.load_long_run(tmp_path / "a")
    with pytest.warns(DeprecationWarning, match=r"taylorball.run_ensemble is deprecated.*run_many"):
        assert run_ensemble(abs, [-1, 2], backend="serial") == [1, 2]
