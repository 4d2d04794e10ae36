"""Shared fixtures and hypothesis strategies.

Admissible states are built on the constraint manifold in float64 and, where a test needs
the manifold exactly, projected in the working precision (see ``taylorball.manifold``).
"""

from __future__ import annotations

import math
import os

# One OpenBLAS thread per test process (and per child process a test starts), read when numpy
# first loads OpenBLAS, just below: the two xdist workers already take the two cores, and
# OpenBLAS's own threads on top of them wait by spinning. On the shared 2-core Xeon
# (2026-11-29, load ~7) tests/test_periodic_shooting_arclength.py::test_past_the_fold took
# 21.8 CPU s with OpenBLAS's default threads and 9.2 with one (its least-squares solves and
# SVDs: 12.5 -> ~0.5 CPU s). A value set in the environment is kept.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

import taylorball as tb
from taylorball.paper import FIG2_BALL, FIG3_BALL, FIG5_BALL
from taylorball.paper import demo_reduced_state  # noqa: F401  (the tests import it from here)

# Property tests compile nothing per example, but the first example of a session may
# trigger a compile (seconds); keep deadlines off and examples modest for the 2-core CI.
settings.register_profile("ci", deadline=None, max_examples=40, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("thorough", deadline=None, max_examples=500)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

FIG5 = FIG5_BALL  # the paper's balls (taylorball.paper): Fig. 4/5, Fig. 3, Fig. 2
SYMMETRIC = FIG3_BALL
HOMOGENEOUS = FIG2_BALL


@pytest.fixture(scope="session")
def fig5():
    return FIG5


@pytest.fixture(scope="session")
def study_result(tmp_path_factory):
    """``study_result(module, cfg) -> (arrays, meta)``: ``module.compute(cfg)`` of a figure
    study, computed once per test session and handed out as a copy (a study's compute is
    pure and deterministic; the runner's ``workdir`` of a study with long runs is a session
    folder). Tests that need the same configuration's data (a study run end to end, the
    paper's pinned numbers of its QUICK configuration, plots of older data) share one run,
    also across the xdist workers of one test run (``tests/test_studies.py`` and
    ``tests/test_paper.py`` may run on different workers): the first worker to ask computes
    it under a file lock in the run's temporary folder, the other loads it."""
    import copy
    import fcntl
    import hashlib
    import inspect
    import pickle

    cache = {}
    # the run's folder, shared by its xdist workers (each has its own basetemp inside it);
    # a serial run keeps its results in memory only
    shared = tmp_path_factory.getbasetemp().parent if os.environ.get("PYTEST_XDIST_WORKER") else None

    def compute(module, cfg):
        kw = ({"workdir": tmp_path_factory.mktemp("longruns")}
              if "workdir" in inspect.signature(module.compute).parameters else {})
        return module.compute(cfg, **kw)

    def get(module, cfg):
        key = (module.__name__, cfg)
        if key not in cache:
            if shared is None:
                cache[key] = compute(module, cfg)
            else:
                name = "study_result_" + hashlib.sha256(repr(key).encode()).hexdigest()[:16]
                with open(shared / f"{name}.lock", "w") as lock:
                    fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
                    path = shared / f"{name}.pkl"
                    if path.exists():
                        cache[key] = pickle.loads(path.read_bytes())
                    else:
                        cache[key] = compute(module, cfg)
                        tmp = path.with_suffix(".tmp")
                        tmp.write_bytes(pickle.dumps(cache[key]))
                        tmp.replace(path)
        arrays, meta = cache[key]
        return {k: np.array(v, copy=True) for k, v in arrays.items()}, copy.deepcopy(meta)

    return get


def unit_vector(u, v):
    """A unit vector from two numbers in [0, 1) (uniform on the sphere)."""
    z = 2.0 * u - 1.0
    phi = 2.0 * math.pi * v
    s = math.sqrt(max(0.0, 1.0 - z * z))
    return np.array([s * math.cos(phi), s * math.sin(phi), z])


def orthonormal_frame(a, b, c):
    """A right-handed orthonormal frame (alpha, beta, gamma) from three numbers in [0, 1)."""
    g = unit_vector(a, b)
    t = np.array([1.0, 0.0, 0.0]) if abs(g[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(g, t)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(g, e1)
    psi = 2.0 * math.pi * c
    al = math.cos(psi) * e1 + math.sin(psi) * e2
    be = np.cross(g, al)
    return al, be, g


_u = st.floats(0.0, 1.0, exclude_max=True)
_coord = st.floats(-3.0, 3.0)


@st.composite
def reduced_states(draw, omega_scale=1.0, r_scale=3.0):
    """Admissible reduced states (omega, gamma, R): |gamma| = 1, (R, gamma) = 0."""
    g = unit_vector(draw(_u), draw(_u))
    w = np.array([draw(_coord) for _ in range(3)]) * omega_scale
    r = np.array([draw(_coord) for _ in range(3)]) * (r_scale / 3.0)
    r = r - np.dot(r, g) * g
    return np.concatenate([w, g, r])


@st.composite
def full_states(draw):
    """Admissible full states (omega, alpha, beta, gamma, x, y)."""
    al, be, g = orthonormal_frame(draw(_u), draw(_u), draw(_u))
    w = np.array([draw(_coord) for _ in range(3)])
    return np.concatenate([w, al, be, g, [draw(_coord), draw(_coord)]])


@st.composite
def mparallel_states(draw):
    """States (K, gamma) with |gamma| = 1."""
    g = unit_vector(draw(_u), draw(_u))
    K = np.array([draw(_coord) for _ in range(3)])
    return np.concatenate([K, g])


STATES = {"full": full_states, "reduced": reduced_states, "mparallel": mparallel_states}


@st.composite
def ball_params(draw):
    """Physical balls: moments obeying the triangle inequalities, I1+I2+I3 <= 2 m a^2."""
    i1 = draw(st.floats(0.5, 5.0))
    i2 = draw(st.floats(0.5, 5.0))
    # keep 1e-9 away from the triangle and trace bounds so rounding cannot cross them
    lo, hi = abs(i1 - i2) * (1 + 1e-9), (i1 + i2) * (1 - 1e-9)
    i3 = draw(st.floats(max(lo, 0.1), hi))
    m = draw(st.floats(0.5, 3.0))
    a_min = math.sqrt((i1 + i2 + i3) / (2.0 * m)) * (1 + 1e-9)
    a = draw(st.floats(a_min, a_min + 5.0))
    om = draw(st.floats(-3.0, 3.0))
    return tb.BallParams(inertia=(i1, i2, i3), mass=m, radius=a, plane_rate=om)




def nearby_reduced_states(n, seed):
    """``n`` copies of :func:`demo_reduced_state` with omega perturbed by N(0, 0.05^2)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        s = demo_reduced_state()
        s[0:3] += 0.05 * rng.normal(size=3)
        out.append(s)
    return out


def sigint_default():
    """Give a child process SIGINT's default disposition: a test suite started in the
    background by a non-interactive shell (``cmd &``) inherits SIGINT *ignored*, Python then
    installs no KeyboardInterrupt handler, and a Ctrl-C test's signal is silently dropped
    (its run went on to the end, or hung on members that never stop)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


def run_script(args, timeout=120.0, **kw):
    """``subprocess.run(args, capture_output=True, text=True)`` for the Ctrl-C tests: in a new
    session whose whole process group is killed on timeout (a plain run's timeout kills only
    the child, and then waits for the pipes that its spawned workers still hold), and with
    SIGINT at its default disposition, as in a terminal (see :func:`sigint_default`).
    Raises ``subprocess.TimeoutExpired`` after the kill."""
    import os
    import signal
    import subprocess

    p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                         preexec_fn=sigint_default, **kw)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        raise
    return subprocess.CompletedProcess(args, p.returncode, out, err)


#: The smoke subset (``pytest -m smoke``): modules that touch every layer of the package
#: quickly (parameters and levels, the model's integrals and manifold, propagation, the
#: Problem at the boundary, sections of the paper's and the user's choosing, periodic
#: orbits, the run store's format, transport, the import layers and module sizes, the one
#: vocabulary). Measured 2026-11-28 on an idle 2-core machine with a warm compile cache:
#: ~40 s. Their slow and long tests stay out (``-m smoke`` replaces the default
#: ``not slow and not long``, so the marker is given only to tests marked neither).
SMOKE_MODULES = {
    "test_params", "test_levels", "test_transport", "test_occupation", "test_io", "test_layers",
    "test_module_size", "test_integrals", "test_propagate", "test_manifold", "test_problem_boundary",
    "test_user_sections", "test_store_format", "test_sections", "test_periodic", "test_vocabulary",
}


#: The test modules that take longest in the default run, longest first: every module of
#: 4 CPU s or more in the sums of its tests' CPU (each test's ``getrusage`` of its worker and
#: the child processes it waited for) in a cold default run on the 2-core Xeon, 2026-11-28,
#: shared (load ~14; 805 CPU s of tests, these 45 modules 767 s): test_study 64 s (a few s
#: less since its kill -9 test runs 3 kills), test_study_lanes 46, test_studies 36, test_chaos 36,
#: test_verify 33, test_periodic 31, test_paper 30, test_skeleton_bifurcation 30,
#: test_rigorous 37 (29 with its tampered certificate slow), ... They are collected first,
#: and ``--no-loadscope-reorder`` (pyproject's addopts) makes ``--dist loadfile`` hand the
#: modules to the two workers in that order, so that each worker takes the next longest
#: module when it is free and the short ones fill the end (list scheduling, longest first; a
#: long module taken last leaves the other worker idle while it runs: in that run
#: test_skeleton_bifurcation, 30 CPU s and then not in this list, was the last module of
#: one worker). Without the option pytest-xdist >= 3.8 orders the modules by their number
#: of tests. The other modules keep their order.
LONG_MODULES = ("test_study", "test_study_lanes", "test_studies", "test_chaos", "test_verify",
                "test_periodic", "test_paper", "test_skeleton_bifurcation", "test_rigorous", "test_tutorials",
                "test_rigorous_shooting", "test_rigorous_horseshoe", "test_chart_sheet_labels",
                "test_periodic_skeleton", "test_charts", "test_lyapunov", "test_angles_samples",
                "test_explore", "test_explore_browser", "test_periodic_manifolds",
                "test_periodic_continuation", "test_typing", "test_maps", "test_user_sections",
                "test_contact", "test_lane_bits", "test_cli", "test_readme", "test_sections",
                "test_occupation", "test_observables_orbit", "test_ensemble", "test_atlas",
                "test_periodic_reflection_saddle", "test_chaos_jacobian", "test_store_format",
                "test_study_extend_bits", "test_periodic_shooting", "test_options", "test_measures",
                "test_study_full", "test_rigorous_step", "test_sheets", "test_rigorous_homoclinic",
                "test_layers")


#: The compile warm-up (``tests/_compile_warmup.py``) started by the controller of this run, if any.
_WARMUP: list = []


def pytest_configure(config):
    """In the controller of a default xdist run (``pytest`` with no paths, the default
    markers), start the compile warm-up: a process at nice 19 that fills heyoka's disk cache
    with the systems the workers will need, in their idle time (see the module's docstring).
    Not for a run of chosen files, ``-m smoke`` or ``-n 0``; ``TAYLORBALL_TEST_WARMUP=0``
    turns it off."""
    import subprocess
    import sys

    if (os.environ.get("PYTEST_XDIST_WORKER") or hasattr(config, "workerinput")
            or os.environ.get("TAYLORBALL_TEST_WARMUP", "1") == "0" or not getattr(config.option, "numprocesses", 0)
            or getattr(config, "args_source", None) is not pytest.Config.ArgsSource.TESTPATHS
            or "smoke" in (config.option.markexpr or "") or config.option.collectonly):
        return
    script = os.path.join(os.path.dirname(__file__), "_compile_warmup.py")
    _WARMUP.append(subprocess.Popen([sys.executable, script], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                    stderr=subprocess.DEVNULL, preexec_fn=_lowest_priority))


def _lowest_priority() -> None:
    os.nice(19)


def pytest_unconfigure(config):
    """End the compile warm-up if it is still running (the run needed no more of it)."""
    import subprocess

    while _WARMUP:
        p = _WARMUP.pop()
        if p.poll() is None:
            p.terminate()
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def _module_name(item) -> str:
    module = getattr(item, "module", None)
    return module.__name__.rsplit(".", 1)[-1] if module is not None else ""


def pytest_collection_modifyitems(config, items):
    for item in items:
        if (_module_name(item) in SMOKE_MODULES and item.get_closest_marker("slow") is None
                and item.get_closest_marker("long") is None):
            item.add_marker(pytest.mark.smoke)
    rank = {name: i for i, name in enumerate(LONG_MODULES)}
    items.sort(key=lambda item: rank.get(_module_name(item), len(rank)))  # stable: each module's order kept
