"""The engine for many orbits (taylorball.ensemble.run_many).

Every mode gives every member the same result, in job order; a failing member is named
(``on_error="raise"``) or recorded while the others finish (``"keep"``); progress adds up
to one per member; Ctrl-C stops the running members at their next chunk.

The lane pool (``backend="lanes"``): jobs refilled into the SIMD lanes of heyoka batch
integrators give each job the bits of a run of that job alone, on any number of threads;
a failing lane is reported and freed without disturbing the others; a time-dependent
field singular at t = 0 does not trouble idle lanes."""

import sys
import time
from pathlib import Path

import numpy as np
import pytest

from .conftest import run_script

hy = pytest.importorskip("heyoka")

import taylorball as tb  # noqa: E402
from taylorball.ensemble import (  # noqa: E402
    Context, LaneLoad, LaneTask, MemberFailure, call, current, run_many,
)
from tests.conftest import FIG5, demo_reduced_state  # noqa: E402

EPS = np.finfo(float).eps
ROOT = Path(__file__).resolve().parent.parent

SIZE = 4


@pytest.fixture(scope="module")
def template():
    # x' = p x^2 (blows up at t0 + 1/(p x0) for p x0 > 0), y' = x / t (singular at t = 0)
    x, y = hy.make_vars("x", "y")
    return hy.taylor_adaptive_batch([(x, hy.par[0] * x * x), (y, x / hy.time)], np.ones((2, SIZE)),
                                    pars=np.zeros((1, SIZE)))


# (x0, p, t_end, stop after this many chunks or None); job 3 blows up at t = 1 + 1/0.5 = 3
JOBS = [(1.0, -1.0, 7.0, None), (2.0, 0.0, 3.0, None), (0.5, -0.3, 11.0, 2), (0.5, 1.0, 9.0, None),
        (1.5, -2.0, 5.0, None), (0.7, 0.1, 6.5, 1), (1.1, -0.5, 2.2, None)]


def _run(template, jobs, threads):
    seen = {j: [] for j in range(len(jobs))}
    failures, finished = {}, []

    def load(j):
        x0, p, t_end, _ = jobs[j]
        return LaneLoad(np.array([x0, 0.0]), np.array([p]), 1.0, t_end, 1.0)

    def after_chunk(ta, chunks):
        done = []
        for c in chunks:
            seen[c.job].append((c.t, c.last, ta.state[:, c.lane].copy()))
            stop = jobs[c.job][3]
            done.append(stop is not None and len(seen[c.job]) >= stop)
        return done

    task = LaneTask(template, len(jobs), load=load, after_chunk=after_chunk,
                    failed=lambda j, outcome, t: failures.setdefault(j, (outcome, t)),
                    on_done=finished.append)
    run_many(task, backend="lanes", workers=threads)
    return seen, failures, sorted(finished)


def _same(a, b):
    return len(a) == len(b) and all(s == t and l == m and np.array_equal(x, y) for (s, l, x), (t, m, y) in zip(a, b))


def test_each_job_has_the_bits_of_a_run_alone(template):
    alone = [_run(template, [job], 1)[0][0] for job in JOBS]
    for threads in (1, 2):
        seen, failures, finished = _run(template, JOBS, threads)
        assert finished == list(range(len(JOBS)))  # on_done once per job, failed ones included
        for j in range(len(JOBS)):
            assert _same(seen[j], alone[j]), (threads, j)


def test_chunks_stops_and_failures(template):
    seen, failures, _ = _run(template, JOBS, 2)
    assert set(failures) == {3}
    outcome, t = failures[3]
    assert outcome != hy.taylor_outcome.time_limit
    assert [c[0] for c in seen[3]] == [2.0]  # the chunk before the blow-up at t = 3
    for j, (x0, p, t_end, stop) in enumerate(JOBS):
        if j == 3:
            continue
        ts = [c[0] for c in seen[j]]
        if stop is None:
            # chunk boundaries t0 + k chunk on the job's own clock, the last one t_end
            assert ts == [min(1.0 + k, t_end) for k in range(1, len(ts) + 1)] and ts[-1] == t_end
            assert [c[1] for c in seen[j]] == [False] * (len(ts) - 1) + [True]
            # and the integration is right: x = x0 / (1 - p x0 (t - 1))
            x_exact = x0 / (1 - p * x0 * (t_end - 1.0))
            # tol = eps per step, a few dozen steps: 64 eps
            assert abs(seen[j][-1][2][0] - x_exact) <= 64 * np.finfo(float).eps * max(1.0, abs(x_exact))
        else:
            assert len(ts) == stop  # freed as soon as after_chunk said so


def _run_sampled(template, jobs, threads, every=0.37):
    """Like _run, with sample times every ``every`` from t0 on (and t_end) in each job's LaneLoad."""
    got = {j: [] for j in range(len(jobs))}
    ends = {j: [] for j in range(len(jobs))}

    def load(j):
        x0, p, t_end, _ = jobs[j]
        ts = np.append(np.arange(1.0 + every, t_end, every), t_end)
        return LaneLoad(np.array([x0, 0.0]), np.array([p]), 1.0, t_end, 1.0, samples=ts)

    def after_chunk(ta, chunks):
        for c in chunks:
            got[c.job] += [(t, col) for t, col in c.samples]
            ends[c.job].append(ta.state[:, c.lane].copy())
        return [False] * len(chunks)

    run_many(LaneTask(template, len(jobs), load=load, after_chunk=after_chunk, failed=lambda *a: None),
             backend="lanes", workers=threads)
    return got, ends


def test_lane_samples_are_the_continuous_output_and_leave_the_runs_unchanged(template):
    """LaneLoad.samples: each job's state at its sample times, read off the continuous output
    of the calls that reach them, equal bit for bit to the job's run alone (whatever its
    companions, among them job 3, which blows up at t = 3: its samples end with its last
    whole chunk), and the chunk-end states equal to those of the run without samples."""
    got, ends = _run_sampled(template, JOBS, 2)
    plain, _, _ = _run(template, [(x0, p, t_end, None) for x0, p, t_end, _ in JOBS], 2)
    for j, (x0, p, t_end, _) in enumerate(JOBS):
        alone, _ = _run_sampled(template, [JOBS[j]], 1)
        assert [t for t, _ in got[j]] == [t for t, _ in alone[0]]
        assert all(np.array_equal(a, b) for (_, a), (_, b) in zip(got[j], alone[0])), j
        if j == 3:  # failed in its chunk (2, 3]: samples up to t = 2
            assert got[j] and [t for t, _ in got[j]] == [t for t in np.arange(1.0 + 0.37, t_end, 0.37) if t <= 2.0]
            continue
        assert all(np.array_equal(e, c[2]) for e, c in zip(ends[j], plain[j])), j  # the run is unchanged
        assert got[j][-1][0] == t_end and np.array_equal(got[j][-1][1], ends[j][-1])  # at t_end: the state
        # x = x0 / (1 - p x0 (t - 1)): one Taylor polynomial evaluation per sample, tol = eps
        # per step over a few dozen steps: 64 eps (as the chunk-end check above)
        for t, col in got[j]:
            x_exact = x0 / (1 - p * x0 * (t - 1.0))
            assert abs(col[0] - x_exact) <= 64 * EPS * max(1.0, abs(x_exact)), (j, t, col[0], x_exact)


def _run_grid(template, jobs, threads, n=5):
    """Like _run, in grid mode (LaneTask.grid): each chunk one propagate_grid on ``n``
    equally spaced times of the chunk (its end last); returns per job the chunks' grids,
    states and ``last`` flags, the failures, and how often a lane's chunk was reset."""
    got = {j: [] for j in range(len(jobs))}
    failures, resets = {}, []

    def load(j):
        x0, p, t_end, _ = jobs[j]

        def ends(k):
            return min(1.0 + (k + 1) * 1.0, t_end)

        def samples(k):
            a = 1.0 + k * 1.0
            return a + (ends(k) - a) * np.arange(1, n + 1) / n

        return LaneLoad(np.array([x0, 0.0]), np.array([p]), 1.0, t_end, 1.0, ends=ends, chunk_samples=samples)

    def after_chunk(ta, chunks):
        for c in chunks:
            got[c.job].append((c.sample_t, c.sample_x, c.last, c.t))
        return [jobs[c.job][3] is not None and len(got[c.job]) >= jobs[c.job][3] for c in chunks]

    run_many(LaneTask(template, len(jobs), load=load, after_chunk=after_chunk,
                      failed=lambda j, outcome, t: failures.setdefault(j, t),
                      on_reset=lambda ta, lane: resets.append(lane), grid=True), backend="lanes", workers=threads)
    return got, failures, resets


def test_grid_mode_chunks_are_the_runs_alone_and_exact(template):
    """LaneTask.grid: every chunk one propagate_grid on the job's own grid; each job's grids
    and states equal its run alone bit for bit whatever its companions and threads (among
    them job 3, which blows up at t = 3: a companion stopped short by it runs its chunk
    again from the start), its chunks start at its chunk's start with the state itself, and
    the states are the exact solution to the integration's tolerance."""
    alone = [_run_grid(template, [job], 1)[0][0] for job in JOBS]
    for threads in (1, 2):
        got, failures, resets = _run_grid(template, JOBS, threads)
        assert set(failures) == {3} and 2.0 < failures[3] <= 3.0 + 1e-9 or not np.isfinite(failures[3])
        assert resets  # lanes freed (and, if the failure stopped a companion, put back)
        for j, (x0, p, t_end, stop) in enumerate(JOBS):
            assert len(got[j]) == len(alone[j])
            for (ta_, xa, la, ca), (tb_, xb, lb, cb) in zip(got[j], alone[j]):
                assert np.array_equal(ta_, tb_) and np.array_equal(xa, xb) and la == lb and ca == cb, (threads, j)
            if j == 3:
                assert [c[3] for c in got[j]] == [2.0]  # the chunk before the blow-up
                continue
            for k, (ts, xs, last, t) in enumerate(got[j]):
                assert ts[0] == 1.0 + k and ts[-1] == t and xs.shape == (6, 2)
                # x = x0 / (1 - p x0 (t - 1)); tol = eps per step, a few dozen steps: 64 eps
                x_exact = x0 / (1 - p * x0 * (ts - 1.0))
                assert np.all(np.abs(xs[:, 0] - x_exact) <= 64 * EPS * np.maximum(1.0, np.abs(x_exact))), (j, k)
            if stop is None:
                assert got[j][-1][2] and got[j][-1][3] == t_end
    with pytest.raises(tb.UsageError, match=r"chunk_samples must be 3 times in \(1.0, 2.0\], the chunk.s end last"):
        run_many(LaneTask(template, 1, load=lambda j: LaneLoad(np.array([1.0, 0.0]), np.array([0.0]), 1.0, 3.0, 1.0,
                                                               chunk_samples=lambda k: np.array([1.5, 2.0, 7.0])),
                          after_chunk=lambda ta, chunks: [False] * len(chunks), failed=lambda *a: None, grid=True),
                 backend="lanes")


INTERRUPT_SCRIPT = r"""
import threading, time, _thread
import numpy as np, heyoka as hy
from taylorball.ensemble import LaneLoad, LaneTask, run_many
x, v = hy.make_vars("x", "v")
ta = hy.taylor_adaptive_batch([(x, v), (v, -hy.sin(x))], np.full((2, 4), 0.5), pars=np.zeros((0, 4)))
threading.Timer(1.0, _thread.interrupt_main).start()
t0 = time.perf_counter()
try:
    run_many(LaneTask(ta, 16, load=lambda j: LaneLoad(np.array([0.5, 0.5]), np.zeros(0), 0.0, 1e12, 2e5),
                      after_chunk=lambda ta, chunks: [False] * len(chunks), failed=lambda *a: None),
             backend="lanes", workers=2)
except KeyboardInterrupt:
    print(f"interrupted after {time.perf_counter() - t0:.1f} s", flush=True)
"""


@pytest.mark.long
def test_ctrl_c_stops_the_lane_workers_and_the_process_exits_cleanly():
    """Ctrl-C (KeyboardInterrupt in the main thread) stops every worker at its next chunk and
    is re-raised; the process then exits normally (a Thread.join interrupted by Ctrl-C marks
    a running thread as stopped in CPython 3.11, and exiting under a worker still inside
    heyoka aborted with std::terminate: status 134)."""
    for _ in range(3):  # the abort was intermittent (3 runs in 5)
        r = run_script([sys.executable, "-c", INTERRUPT_SCRIPT], timeout=120)
        assert r.returncode == 0 and "interrupted after" in r.stdout, (r.returncode, r.stdout, r.stderr)
        assert "terminate" not in r.stderr


def test_lanes_progress_and_results(template):
    """Lane progress adds up to one per job (time fractions by default, the task's own
    fractions otherwise); ``result(j)`` fills the list in job order; an exception there is
    job j's failure, named."""
    def load(j):
        return LaneLoad(np.array([JOBS[j][0], 0.0]), np.array([JOBS[j][1]]), 1.0, JOBS[j][2], 1.0)

    def task(**kw):
        return LaneTask(template, len(JOBS), load=load, after_chunk=lambda ta, chunks: [False] * len(chunks),
                        failed=lambda *a: None, **kw)

    for kw in ({}, {"fraction": lambda c: 0.5}):
        got = []
        assert run_many(task(**kw), backend="lanes", workers=2, progress=got.append) == [None] * len(JOBS)
        # 7 jobs, a dozen increments each, every one rounded once: 8 eps per job
        assert abs(sum(got) - len(JOBS)) <= 8 * len(JOBS) * EPS and min(got) > 0
    assert run_many(task(result=lambda j: 10 * j), backend="lanes") == [10 * j for j in range(len(JOBS))]

    def result(j):
        if j == 4:
            raise ValueError("no result for job 4")
        return j

    with pytest.raises(ValueError, match="no result for job 4") as ei:
        run_many(task(result=result), backend="lanes")
    assert any("member 4 of 7" in n for n in ei.value.__notes__)
    out = run_many(task(result=result), backend="lanes", on_error="keep")
    assert isinstance(out[4], MemberFailure) and out[4].index == 4 and "no result for job 4" in str(out[4])
    assert [r for j, r in enumerate(out) if j != 4] == [0, 1, 2, 3, 5, 6]


# --- members that are callables: serial, threads, processes, dask ---------------------------


def _orbit(i):
    """A member: a short orbit of the reduced system (top level: picklable)."""
    s = demo_reduced_state()
    s[0] += 0.01 * i
    return tb.propagate("reduced", FIG5, s, 5.0)


def _fails(i):
    raise ValueError(f"member input {i} is bad")


class _Chunks:
    """A member in chunks: ``n`` chunks of ``dt`` seconds, checking and reporting at each."""

    def __init__(self, i, n=4, dt=0.0, fail=False):
        self.i, self.n, self.dt, self.fail = i, n, dt, fail

    def __call__(self, ctx):
        assert current() is ctx and ctx.index == self.i
        for _ in range(self.n):
            ctx.check()
            time.sleep(self.dt)
            ctx.advance(0.3)  # reports more than the whole member: clipped at 1
        if self.fail:
            raise RuntimeError(f"chunked member {self.i} failed")
        return self.i * self.i


@pytest.mark.parametrize("mode", ["serial", "threads"])
def test_in_process_modes_results_order_progress(mode):
    ref = [_orbit(i) for i in range(4)]
    out = run_many([call(_orbit, i) for i in range(4)], backend=mode, workers=2)
    assert len(out) == 4 and all(np.array_equal(a, b) for a, b in zip(out, ref))
    got = []
    out = run_many([_Chunks(i) for i in range(5)], backend=mode, workers=3, progress=got.append)
    assert out == [0, 1, 4, 9, 16]
    # 5 members of 4 increments each (0.3 0.3 0.3 0.1), each one rounding: 4 eps per member
    assert abs(sum(got) - 5) <= 4 * 5 * EPS and max(got) <= 0.3 + EPS
    assert current().check() is None and not current().stopping  # outside a member: never stops


@pytest.mark.parametrize("mode", ["serial", "threads"])
def test_a_failing_member_is_named_or_kept(mode):
    jobs = [_Chunks(0), call(_fails, 1), _Chunks(2), _Chunks(3, fail=True), _Chunks(4)]
    with pytest.raises(ValueError, match="member input 1 is bad") as ei:
        run_many(jobs, backend=mode, workers=2)
    assert any(f"member 1 of 5 failed (backend '{mode}')" in n for n in ei.value.__notes__)
    assert ei.value.ensemble_member == 1
    seen = {}
    got = []
    out = run_many(jobs, backend=mode, workers=2, on_error="keep", progress=got.append,
                   on_result=lambda i, r: seen.setdefault(i, r))
    assert [out[0], out[2], out[4]] == [0, 4, 16]
    assert isinstance(out[1], MemberFailure) and out[1].index == 1 and isinstance(out[1].error, ValueError)
    assert isinstance(out[3], MemberFailure) and "chunked member 3 failed" in str(out[3])
    assert seen == dict(enumerate(out))  # on_result once per member, failed ones included
    assert abs(sum(got) - 5) <= 4 * 5 * EPS  # failed members count as done (4 eps per member, as above)


def test_a_failure_stops_the_other_threads_at_their_next_chunk():
    """``on_error="raise"``: the running members leave at their next ``ctx.check()``, the
    queued ones never start, also through a run started inside a member (it stops with it)."""
    started = []

    def endless(ctx):
        started.append(ctx.index)
        while True:
            ctx.check()
            time.sleep(0.01)

    def nested(ctx):  # a serial run inside a member stops with that member
        return run_many([endless], backend="serial")

    def fail_later(ctx):
        time.sleep(0.3)
        raise ValueError("late failure")

    t0 = time.perf_counter()
    with pytest.raises(ValueError, match="late failure") as ei:
        run_many([endless, nested, fail_later, endless, endless], backend="threads", workers=3)
    assert time.perf_counter() - t0 < 5.0  # 0.3 s, then a chunk of 0.01 s: 5 s is slack
    assert any("member 2 of 5" in n for n in ei.value.__notes__)
    assert sorted(started) == [0, 0]  # members 3 and 4 never started (the nested one is index 0 of its run)


def test_bad_arguments():
    with pytest.raises(tb.UsageError, match="backend must be one of"):
        run_many([], backend="gpu")
    with pytest.raises(tb.UsageError, match="on_error must be"):
        run_many([], on_error="ignore")
    with pytest.raises(tb.UsageError, match="progress must be"):
        run_many([call(int)], progress=3)
    with pytest.raises(tb.UsageError, match="job 1 is"):
        run_many([call(int), 5])
    with pytest.raises(tb.UsageError, match="takes a LaneTask"):
        run_many([call(int)], backend="lanes")
    with pytest.raises(tb.UsageError, match="needs client"):
        run_many([call(int)], backend="dask")
    with pytest.raises(tb.UsageError, match="workers must be"):
        run_many([call(int)], backend="threads", workers=0)
    assert run_many([], backend="threads") == [] and run_many([call(int)]) == [0]
    assert isinstance(current(), Context)


def test_processes_mode_with_a_top_level_function():
    """Spawned worker processes: the same bits as in process, in job order; a failure kept
    in its place (the traceback of the worker on its cause); progress in whole members."""
    ref = [_orbit(i) for i in range(3)]
    got = []
    jobs = [call(_orbit, 0), call(_orbit, 1), call(_fails, 2), call(_orbit, 2)]
    out = run_many(jobs, backend="processes", workers=2, on_error="keep", progress=got.append)
    assert all(np.array_equal(a, b) for a, b in zip([out[0], out[1], out[3]], ref))
    assert isinstance(out[2], MemberFailure) and "member input 2 is bad" in str(out[2])
    assert sorted(got) == [1.0] * 4  # whole members


PROCESSES_INTERRUPT = r"""
import os, signal, threading, time
from taylorball.ensemble import call, run_many
if __name__ == "__main__":
    threading.Timer(3.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
    t0 = time.perf_counter()
    try:
        run_many([call(time.sleep, 600)] * 4, backend="processes", workers=2)
    except KeyboardInterrupt:
        print(f"interrupted after {time.perf_counter() - t0:.1f} s", flush=True)
"""


@pytest.mark.long
def test_ctrl_c_ends_the_worker_processes(tmp_path):
    """Ctrl-C in processes mode: the pool's workers are terminated (members cannot stop at a
    chunk from the outside), queued members dropped, KeyboardInterrupt re-raised."""
    script = tmp_path / "interrupt_processes.py"
    script.write_text(PROCESSES_INTERRUPT)
    t0 = time.perf_counter()
    r = run_script([sys.executable, str(script)], timeout=120, cwd=ROOT)
    assert r.returncode == 0 and "interrupted after" in r.stdout, (r.returncode, r.stdout, r.stderr)
    # without the termination the members sleep 600 s each; 3 s to the signal, 60 s is slack
    assert time.perf_counter() - t0 < 60.0


def test_a_worker_told_to_end_exits_whatever_ends_its_member():
    """The race behind a hang seen once in a Ctrl-C of `taylorball run` with 2 worker processes:
    the pool's SIGTERM is handled while the member runs and checks (it only sets the stop
    flag), then the terminal's SIGINT ends the member with KeyboardInterrupt. The worker must
    exit (status 143), not return to the pool's loop and wait there for work that never comes
    while the parent joins it."""
    code = ("import signal\n"
            "from taylorball import ensemble as e\n"
            "def member(ctx):\n"
            "    ctx.check()\n"
            "    e._on_sigterm(signal.SIGTERM, None)\n"
            "    raise KeyboardInterrupt\n"
            "try:\n"
            "    e._remote(member, 0)\n"
            "except KeyboardInterrupt:\n"
            "    print('returned to the pool loop')\n")
    r = run_script([sys.executable, "-c", code], timeout=120, cwd=ROOT)
    assert r.returncode == 143 and "returned" not in r.stdout, (r.returncode, r.stdout, r.stderr)
    # a member ended by KeyboardInterrupt with no stop asked for still reports it (the parent's
    # Ctrl-C handling sees it as the worker's result)
    code2 = code.replace("    e._on_sigterm(signal.SIGTERM, None)\n", "")
    r2 = run_script([sys.executable, "-c", code2], timeout=120, cwd=ROOT)
    assert r2.returncode == 0 and "returned to the pool loop" in r2.stdout, (r2.returncode, r2.stdout, r2.stderr)


THREADS_INTERRUPT = r"""
import os, signal, threading, time
from taylorball.ensemble import run_many

def member(ctx):
    while True:
        ctx.check()
        time.sleep(0.05)

threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
t0 = time.perf_counter()
try:
    run_many([member] * 6, backend="threads", workers=2)
except KeyboardInterrupt:
    print(f"interrupted after {time.perf_counter() - t0:.1f} s", flush=True)
"""


def test_ctrl_c_stops_the_threads_at_their_next_chunk():
    """Ctrl-C (SIGINT) in threads mode: running members leave at their next ``ctx.check()``,
    queued ones are dropped, KeyboardInterrupt is re-raised and the process exits normally.
    (tests/test_sections.py does the same through ``poincare_sections`` with heyoka.)"""
    r = run_script([sys.executable, "-c", THREADS_INTERRUPT], timeout=120,
                       cwd=ROOT)
    assert r.returncode == 0 and "interrupted after" in r.stdout, (r.returncode, r.stdout, r.stderr)
    # the members never end by themselves; a chunk is 0.05 s: 30 s is slack for a loaded machine
    assert float(r.stdout.split("interrupted after")[1].split()[0]) < 30.0


def test_dask_mode_on_a_local_cluster():
    """dask.distributed futures (optional extra ``cluster``): the same bits, in job order,
    failures named or kept, progress as members finish."""
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(processes=False, n_workers=1, threads_per_worker=2,
                                       dashboard_address=None)
    with cluster, distributed.Client(cluster) as client:
        ref = [_orbit(i) for i in range(3)]
        got = []
        out = run_many([call(_orbit, i) for i in range(3)], backend="dask", client=client, progress=got.append)
        assert all(np.array_equal(a, b) for a, b in zip(out, ref)) and got == [1.0] * 3
        with pytest.raises(ValueError, match="member input 1 is bad") as ei:
            run_many([call(_orbit, 0), call(_fails, 1)], backend="dask", client=client)
        assert any("member 1 of 2 failed (backend 'dask')" in n for n in ei.value.__notes__)
        out = run_many([call(_fails, 0), call(_orbit, 1)], backend="dask", client=client, on_error="keep")
        assert isinstance(out[0], MemberFailure) and np.array_equal(out[1], _orbit(1))
