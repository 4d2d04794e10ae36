"""Bad inputs get a clear taylorball error up front.

One table row per case: the call, the expected error class and a fragment of the message
that names the argument. The rows cover the kinds of bad input and those
already tested elsewhere (test_params, test_propagate, test_manifold, test_sections,
test_chaos, test_longrun, test_ensemble), so the table is the one list to grow with the
API. A second table lists borderline inputs that must be *accepted* (numpy scalars).
Then a hypothesis test throws random non-finite, huge, tiny, negative, wrong-type and
wrong-shape values at the main entry points and requires a result or a
``TaylorballError`` within a time limit, never a foreign exception or a hang.
"""

from __future__ import annotations

import functools
import math
import re
import signal
import warnings
from contextlib import contextmanager
from pathlib import Path

import heyoka as hy
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import taylorball as tb
from taylorball.ensemble import call, run_many
from taylorball.manifold import as_state

from .conftest import FIG5, demo_reduced_state

X = demo_reduced_state()
MPAR_STATE = np.array([1.0, 2.0, 3.0, 0.0, 0.0, 1.0])
LEVELS = dict(C=10.0, M_gamma=2.0, h=5.0)  # Fig. 4a caption (taylorball.paper.FIG4A_LEVELS)
POINT = (0.0, 0.1, 0.1)
NAN, INF = math.nan, math.inf


def _study(p, kind="reduced", **kw):
    """A long run: the study of one orbit (``StudyConfig.from_problem``), store under ``p``."""
    base = dict(states=[X] if kind == "reduced" else [tb.reduced_to_full(FIG5, X)], t_end=10.0, sample_dt=1.0,
                checkpoint_every=10.0, store=p / "run")
    base.update(kw)
    return tb.StudyConfig.from_problem(tb.problem(kind, FIG5), **base)


def _ball(**kw):
    base = dict(inertia=(2, 3, 4), mass=1, radius=5)
    base.update(kw)
    return tb.BallParams(**base)


def _file(tmp_path):
    f = tmp_path / "a_file"
    f.write_text("not a folder")
    return f


def _top_level(x):
    return x


# (id, call taking tmp_path, error class, message fragment naming the argument)
CASES = [
    # --- tolerance (the worst case: tol=10 was accepted silently) ---------
    ("tol=10", lambda p: tb.problem("reduced", FIG5, tol=10), tb.UsageError, "tol=10"),
    ("tol=1e-5", lambda p: tb.problem("reduced", FIG5, tol=1e-5), tb.UsageError, "too loose"),
    ("tol=nan", lambda p: tb.problem("reduced", FIG5, tol=NAN), tb.UsageError, "tol=nan"),
    ("tol=-1", lambda p: tb.problem("reduced", FIG5, tol=-1.0), tb.UsageError, "tol=-1"),
    ("tol=str", lambda p: tb.problem("reduced", FIG5, tol="1e-10"), tb.UsageError, "tol='1e-10'"),
    ("tol<eps", lambda p: tb.problem("reduced", FIG5, tol=1e-300), tb.UsageError, "below the rounding"),
    ("propagate tol=10", lambda p: tb.propagate("reduced", FIG5, X, 1.0, tol=10), tb.UsageError, "tol=10"),
    ("long run tol=10", lambda p: tb.StudyConfig.from_dict({
        "ball": {"inertia": [2.0, 3.0, 4.0], "mass": 1.0, "radius": 5.0, "plane_rate": 2.0},
        "orbits": {"states": [list(X)]}, "run": {"t_end": 10.0, "checkpoint_every": 5.0, "tol": 10.0},
        "output": {"store": str(p / "run")}}), tb.UsageError, "[run] tol"),
    # --- number types ---------------------------------------------------------------
    ("fp_type unknown", lambda p: tb.propagate("reduced", FIG5, X, 1.0, fp_type=np.float32), tb.UsageError,
     "fp_type must be one of"),
    ("real needs prec", lambda p: tb.propagate("reduced", FIG5, X, 1.0, fp_type=hy.real), tb.UsageError,
     "needs prec"),
    ("prec for float", lambda p: tb.propagate("reduced", FIG5, X, 1.0, prec=100), tb.UsageError, "prec is only for"),
    ("prec=32", lambda p: tb.propagate("reduced", FIG5, X, 1.0, fp_type="real", prec=32), tb.UsageError, "prec"),
    ("prec=2.5", lambda p: tb.problem("reduced", FIG5, fp_type="real", prec=2.5), tb.UsageError, "prec"),
    ("prec=1e6", lambda p: tb.problem("reduced", FIG5, fp_type="real", prec=10**6), tb.UsageError, "prec"),
    ("prec=str", lambda p: tb.problem("reduced", FIG5, fp_type="real", prec="256"), tb.UsageError, "prec"),
    # --- kinds, formulations, params type -------------------------------------------
    ("kind unknown", lambda p: tb.propagate("reduce", FIG5, X, 1.0), tb.UsageError, "kind must be one of"),
    ("formulation", lambda p: tb.propagate("reduced", FIG5, X, 1.0, formulation="lagrange"), tb.UsageError,
     "formulation must be one of"),
    ("params type", lambda p: tb.propagate("reduced", "ball", X, 1.0), tb.ParameterError, "must be BallParams"),
    # --- times ----------------------------------------------------------------------
    ("t=nan", lambda p: tb.propagate("reduced", FIG5, X, NAN), tb.UsageError, "t must be finite"),
    ("t=inf", lambda p: tb.propagate("reduced", FIG5, X, INF), tb.UsageError, "t must be finite"),
    ("t=-inf", lambda p: tb.propagate("reduced", FIG5, X, -INF), tb.UsageError, "t must be finite"),
    ("grid with nan", lambda p: tb.propagate("reduced", FIG5, X, [0.0, NAN, 2.0]), tb.UsageError,
     "t must be finite"),
    ("t=str", lambda p: tb.propagate("reduced", FIG5, X, "1"), tb.UsageError, "t must be a finite time"),
    ("t=complex", lambda p: tb.propagate("reduced", FIG5, X, 1j), tb.UsageError, "t must be a finite time"),
    ("grid decreasing", lambda p: tb.propagate("reduced", FIG5, X, [0.0, 2.0, 1.0]), tb.UsageError,
     "strictly increasing"),
    ("grid repeated time", lambda p: tb.propagate("reduced", FIG5, X, [0.0, 1.0, 1.0]), tb.UsageError,
     "strictly increasing"),  # heyoka refused it with its own ValueError (found by the thorough profile)
    ("grid 2-D", lambda p: tb.propagate("reduced", FIG5, X, np.zeros((2, 2))), tb.UsageError, "1-D grid"),
    ("contact grid nan", lambda p: tb.contact_trajectory(FIG5, X, [0.0, NAN]), tb.UsageError, "t must be finite"),
    # --- states and constraint_tol --------------------------------------------------
    ("state length", lambda p: as_state("reduced", np.zeros(10)), tb.StateError, "must have 9 entries"),
    ("state strings", lambda p: as_state("reduced", ["a"] * 9), tb.StateError, "real numbers"),
    ("state nan", lambda p: tb.propagate("reduced", FIG5, np.where(np.arange(9) == 0, NAN, X), 1.0),
     tb.StateError, "non-finite"),
    ("state off manifold", lambda p: tb.propagate("reduced", FIG5, X * 1.01, 1.0), tb.ConstraintError,
     "constraint manifold"),
    ("constraint_tol=nan", lambda p: tb.propagate("reduced", FIG5, X, 1.0, constraint_tol=NAN), tb.UsageError,
     "constraint_tol"),
    ("constraint_tol=-1", lambda p: tb.propagate("reduced", FIG5, X, 1.0, constraint_tol=-1.0), tb.UsageError,
     "constraint_tol"),
    # --- parameters -----------------------------------------------------------------
    ("inertia '234'", lambda p: _ball(inertia="234"), tb.ParameterError, "inertia"),
    ("inertia negative", lambda p: _ball(inertia=(2, 3, -4)), tb.ParameterError, "inertia[2] must be > 0"),
    ("inertia 2 items", lambda p: _ball(inertia=(2, 3)), tb.ParameterError, "exactly three components"),
    ("inertia scalar", lambda p: _ball(inertia=5.0), tb.ParameterError, "sequence of three numbers"),
    ("inertia triangle", lambda p: _ball(inertia=(1, 1, 3)), tb.ParameterError, "triangle inequality"),
    ("mass=0", lambda p: _ball(mass=0), tb.ParameterError, "mass must be > 0"),
    ("mass=nan", lambda p: _ball(mass=NAN), tb.ParameterError, "mass must be finite"),
    ("mass=True", lambda p: _ball(mass=True), tb.ParameterError, "mass must be a real number"),
    ("mass='1'", lambda p: _ball(mass="1"), tb.ParameterError, "mass must be a real number"),
    ("radius=-1", lambda p: _ball(radius=-1), tb.ParameterError, "radius must be > 0"),
    ("m a^2 overflows", lambda p: _ball(mass=1e300, radius=1e10), tb.ParameterError, "mass=1e+300"),
    ("radius^2 overflows", lambda p: _ball(radius=1e200), tb.ParameterError, "radius=1e+200"),
    ("m a^2 underflows", lambda p: _ball(mass=1e-200, radius=1e-100), tb.ParameterError, "mass=1e-200"),
    ("plane_rate=inf", lambda p: _ball(plane_rate=INF), tb.ParameterError, "plane_rate must be finite"),
    ("mparallel d=0", lambda p: tb.MParallelParams(a=(1, 2, 3), d=0), tb.ParameterError, "d must be > 0"),
    # --- chaos indicators -----------------------------------------------------------
    ("megno kind", lambda p: tb.megno("fulll", FIG5, X, 2.0), tb.UsageError, "kind must be"),
    ("megno full with a reduced state", lambda p: tb.megno("full", FIG5, X, 2.0), tb.StateError, "14 entries"),
    ("gali k=0", lambda p: tb.gali("reduced", FIG5, X, 2.0, k=0), tb.UsageError, "k must be"),
    ("gali t_end=nan", lambda p: tb.gali("reduced", FIG5, X, NAN), tb.UsageError, "t_end must be finite"),
    ("megno t_end=inf", lambda p: tb.megno("reduced", FIG5, X, INF), tb.UsageError, "t_end"),
    ("megno t_end=nan", lambda p: tb.megno("reduced", FIG5, X, NAN), tb.UsageError, "t_end"),
    ("megno t0>t_end", lambda p: tb.megno("reduced", FIG5, X, 2.0, t0=3.0), tb.UsageError, "t0 < t_end"),
    ("megno t0=0", lambda p: tb.megno("reduced", FIG5, X, 2.0, t0=0.0), tb.UsageError, "t0"),
    ("megno chunk=0", lambda p: tb.megno("reduced", FIG5, X, 2.0, chunk=0.0), tb.UsageError, "chunk"),
    ("megno chunk tiny", lambda p: tb.megno("reduced", FIG5, X, 100.0, chunk=1e-9), tb.UsageError, "chunk=1e-09"),
    ("megno seed=-1", lambda p: tb.megno("reduced", FIG5, X, 2.0, seed=-1), tb.UsageError, "seed"),
    ("megno stop_above=nan", lambda p: tb.megno("reduced", FIG5, X, 2.0, stop_above=NAN), tb.UsageError,
     "stop_above"),
    ("megno_many t_end=inf", lambda p: tb.megno_many("reduced", FIG5, [X], INF), tb.UsageError, "t_end"),
    ("megno_many workers=-1", lambda p: tb.megno_many("reduced", FIG5, [X], 2.0, workers=-1), tb.UsageError,
     "workers"),
    ("megno_many workers=0", lambda p: tb.megno_many("reduced", FIG5, [X], 2.0, workers=0), tb.UsageError,
     "workers"),
    ("megno_many no states", lambda p: tb.megno_many("reduced", FIG5, [], 2.0), tb.UsageError,
     "at least one initial state"),
    ("megno_many states=5", lambda p: tb.megno_many("reduced", FIG5, 5, 2.0), tb.StateError, "states"),
    ("lyapunov_spectra sample past t", lambda p: tb.lyapunov_spectra("reduced", FIG5, [X], 2.0, sample=[1.0, 3.0]),
     tb.UsageError, "sample must be"),
    ("lyapunov_spectra sample=nan", lambda p: tb.lyapunov_spectra("reduced", FIG5, [X], 2.0, sample=NAN),
     tb.UsageError, "sample must be"),
    ("lyapunov_spectra states=5", lambda p: tb.lyapunov_spectra("reduced", FIG5, 5, 2.0), tb.StateError, "states"),
    ("gali_many k=1", lambda p: tb.gali_many("reduced", FIG5, [X], 2.0, k=1), tb.UsageError, "k must be"),
    ("gali_many states=5", lambda p: tb.gali_many("reduced", FIG5, 5, 2.0), tb.StateError, "states"),
    ("gali_many sample past t", lambda p: tb.gali_many("reduced", FIG5, [X], 2.0, sample=[3.0]), tb.UsageError,
     "sample must be"),
    ("lyapunov_spectra workers=0", lambda p: tb.lyapunov_spectra("reduced", FIG5, [X], 2.0, workers=0),
     tb.UsageError, "workers"),
    # --- sections -------------------------------------------------------------------
    ("section kind", lambda p: tb.poincare_section("full", FIG5, X, n_points=2), tb.UsageError, "kind must be one of"),
    ("n_points=0", lambda p: tb.poincare_section("reduced", FIG5, X, n_points=0), tb.UsageError,
     "n_points must be a positive integer"),
    ("n_points=2.5", lambda p: tb.poincare_section("reduced", FIG5, X, n_points=2.5), tb.UsageError, "n_points"),
    ("n_points=1e8", lambda p: tb.poincare_section("reduced", FIG5, X, n_points=10**8), tb.UsageError, "n_points"),
    ("g0=7", lambda p: tb.poincare_section("reduced", FIG5, X, n_points=2, g0=7.0), tb.UsageError,
     "g0 must be a float in"),
    ("direction=2", lambda p: tb.poincare_section("reduced", FIG5, X, n_points=2, direction=2), tb.UsageError,
     "direction must be"),
    ("direction=list", lambda p: tb.poincare_section("reduced", FIG5, X, n_points=2, direction=[1]), tb.UsageError,
     "direction must be"),
    ("t_end=-1", lambda p: tb.poincare_section("reduced", FIG5, X, n_points=2, t_end=-1.0), tb.UsageError,
     "t_end must be > 0"),
    ("t_end=inf", lambda p: tb.poincare_section("reduced", FIG5, X, n_points=2, t_end=INF), tb.UsageError, "t_end"),
    ("section chunk tiny", lambda p: tb.poincare_section("reduced", FIG5, X, n_points=2, options=tb.SectionOptions(chunk=1e-9)), tb.UsageError,
     "chunk=1e-09"),
    ("section chunk=nan", lambda p: tb.poincare_section("reduced", FIG5, X, n_points=2, options=tb.SectionOptions(chunk=NAN)), tb.UsageError,
     "chunk"),
    ("sections workers=-1", lambda p: tb.poincare_sections("reduced", FIG5, [X], n_points=2, workers=-1),
     tb.UsageError, "workers"),
    ("sections states=5", lambda p: tb.poincare_sections("reduced", FIG5, 5, n_points=2), tb.StateError, "states"),
    ("sections batch real128", lambda p: tb.poincare_sections("reduced", FIG5, [X], n_points=2, batch=True,
                                                              fp_type=hy.real128), tb.UsageError, "batch=True"),
    # --- charts: bad levels and grids are not "empty level sets" --------------------
    ("h=nan", lambda p: tb.states_on_section(FIG5, C=10, M_gamma=2, h=NAN, point=POINT), tb.ChartError, "h (the"),
    ("h=inf", lambda p: tb.states_on_section(FIG5, C=10, M_gamma=2, h=INF, point=POINT), tb.ChartError, "h (the"),
    ("n_grid=1", lambda p: tb.states_on_section(FIG5, **LEVELS, point=POINT, n_grid=1), tb.UsageError, "n_grid"),
    ("n_grid=2.5", lambda p: tb.states_on_section(FIG5, **LEVELS, point=POINT, n_grid=2.5), tb.UsageError, "n_grid"),
    ("C=0", lambda p: tb.states_on_section(FIG5, C=0, M_gamma=0, h=5, point=POINT), tb.ChartError, "C = |M|"),
    ("point nan", lambda p: tb.states_on_section(FIG5, **LEVELS, point=(0, NAN, 0)), tb.ChartError, "point"),
    ("chart g0=nan", lambda p: tb.states_on_section(FIG5, **LEVELS, point=POINT, g0=NAN), tb.UsageError, "g0"),
    ("sample n=0", lambda p: tb.section_admissible_sample(FIG5, **LEVELS, n=0), tb.UsageError, "n must"),
    ("sample n=-1", lambda p: tb.section_admissible_sample(FIG5, **LEVELS, n=-1), tb.UsageError, "n must"),
    ("sample h=nan", lambda p: tb.section_admissible_sample(FIG5, C=10, M_gamma=2, h=NAN), tb.ChartError, "h (the"),
    ("sample n_grid=1", lambda p: tb.section_admissible_sample(FIG5, **LEVELS, n_grid=1), tb.UsageError, "n_grid"),
    ("sample seed=nan", lambda p: tb.section_admissible_sample(FIG5, **LEVELS, seed=NAN), tb.UsageError, "seed"),
    ("psi=inf", lambda p: tb.reduced_to_full(FIG5, X, psi=INF), tb.UsageError, "psi"),
    ("psi=str", lambda p: tb.reduced_to_full(FIG5, X, psi="1"), tb.UsageError, "psi"),
    ("contact t=''", lambda p: tb.contact_trajectory(FIG5, X, ""), tb.UsageError, "t must be a finite time"),
    ("sample r_box=-1", lambda p: tb.section_admissible_sample(FIG5, **LEVELS, r_box=-1.0), tb.UsageError, "r_box"),
    ("megno_map sheet=-1", lambda p: tb.megno_map(FIG5, tb.Levels(C=10.0, M_gamma=6.0, h=5.0), r1=(-2, 2, 2),
                                                  r2=(-2, 2, 2), t_end=2.0, sheet=-1), tb.UsageError, "sheet must be"),
    ("megno_map sheet=1.5", lambda p: tb.megno_map(FIG5, tb.Levels(C=10.0, M_gamma=6.0, h=5.0), r1=(-2, 2, 2),
                                                   r2=(-2, 2, 2), t_end=2.0, sheet=1.5), tb.UsageError, "sheet must be"),
    ("megno_map sheet=True", lambda p: tb.megno_map(FIG5, tb.Levels(C=10.0, M_gamma=6.0, h=5.0), r1=(-2, 2, 2),
                                                    r2=(-2, 2, 2), t_end=2.0, sheet=True), tb.UsageError,
     "sheet must be"),
    ("megno_map root and sheet", lambda p: tb.megno_map(FIG5, tb.Levels(C=10.0, M_gamma=6.0, h=5.0), r1=(-2, 2, 2),
                                                        r2=(-2, 2, 2), t_end=2.0, root=0, sheet=0), tb.UsageError,
     "root (the index of K among the roots) or sheet"),
    ("section_sheet label='K'", lambda p: tb.section_sheet(FIG5, tb.states_on_section(FIG5, **LEVELS, point=POINT),
                                                           **LEVELS, label="K"), tb.UsageError, "label must be"),
    ("section_sheet label=1", lambda p: tb.section_sheet(FIG5, tb.states_on_section(FIG5, **LEVELS, point=POINT),
                                                         **LEVELS, label=1), tb.UsageError, "label must be"),
    ("mparallel h=inf", lambda p: tb.mparallel_states_on_section(FIG5, lam=1.0, h=INF, point=(0.0, 0.5)),
     tb.ChartError, "h (the"),
    ("mparallel n_grid=1", lambda p: tb.mparallel_states_on_section(FIG5, lam=1.0, h=1.0, point=(0.0, 0.5), n_grid=1),
     tb.UsageError, "n_grid"),
    # --- long runs ------------------------------------------------------------------
    ("t_end=-1", lambda p: _study(p, t_end=-1.0), tb.UsageError, "[run] t_end = -1.0: must be"),
    ("not a multiple", lambda p: _study(p, sample_dt=3.0), tb.UsageError, "multiple of [run] sample_dt = 3.0"),
    ("sample_dt=1e-9", lambda p: _study(p, sample_dt=1e-9), tb.UsageError, "at most 1000000 samples per chunk"),
    ("sample_dt=5e-324 (ratio overflows)", lambda p: _study(p, sample_dt=5e-324), tb.UsageError,
     "[run] checkpoint_every = 10.0: must be at most 1000000 samples per chunk"),
    ("t_end / checkpoint_every overflows", lambda p: _study(p, t_end=1e300, sample_dt=1e-300, checkpoint_every=1e-300),
     tb.UsageError, "[run] t_end = 1e+300: must be at most 10000000 chunks"),
    ("extend overflows", lambda p: tb.run_study(_study(p, sample_dt=1e-300, checkpoint_every=1e-300, t_end=1e-300,
                                                       observables={"angles_every": 0.0}),
                                                extend=1e300), tb.UsageError, "--extend = 1e+300: must be at most"),
    ("1e12 chunks", lambda p: _study(p, t_end=1e12, sample_dt=1.0, checkpoint_every=1.0), tb.UsageError,
     "at most 10000000 chunks"),
    ("sample_dt=nan", lambda p: _study(p, sample_dt=NAN), tb.UsageError, "[run] sample_dt = nan"),
    ("long run state strings", lambda p: _study(p, states=[("a",) * 9]), tb.UsageError, "states must be an (n, d)"),
    ("full run state of 9", lambda p: _study(p, "full", states=[X]), tb.UsageError, "each a list of 14 numbers"),
    ("full run angles", lambda p: _study(p, "full", observables={"angles_every": 10.0}), tb.UsageError,
     "[observables] angles_every = 10.0: needs the section chart"),
    ("store is a file", lambda p: _study(p, store=_file(p)), tb.UsageError, "[output] store"),
    ("observables not a table", lambda p: _study(p, observables=[1]), tb.UsageError, "[observables] must be a table"),
    # --- ensembles ------------------------------------------------------------------
    ("backend unknown", lambda p: run_many([], backend="gpu"), tb.UsageError, "backend must be one of"),
    ("workers=-1", lambda p: run_many([call(_top_level, 1)], backend="threads", workers=-1), tb.UsageError, "workers"),
    ("workers=0", lambda p: run_many([call(_top_level, 1)], backend="threads", workers=0), tb.UsageError, "workers"),
    ("workers=True", lambda p: run_many([call(_top_level, 1)], backend="threads", workers=True), tb.UsageError,
     "workers"),
    ("job not callable", lambda p: run_many([1]), tb.UsageError, "job 0 is"),
    ("lambda for processes", lambda p: run_many([call(lambda: 1)], backend="processes"), tb.UsageError,
     "top-level function"),
]


@pytest.mark.parametrize("name, fn, error, fragment", CASES, ids=[c[0] for c in CASES])
def test_bad_input_is_refused_with_a_clear_error(name, fn, error, fragment, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # unphysical-parameter warnings of some rows
        with pytest.raises(error, match=re.escape(fragment)) as info:
            fn(tmp_path)
    assert isinstance(info.value, tb.TaylorballError)


def test_nothing_is_written_for_a_refused_long_run(tmp_path):
    with pytest.raises(tb.UsageError):
        tb.run_study(_study(tmp_path, t_end=10.0), extend=15.0)  # not a multiple of checkpoint_every
    assert not (tmp_path / "run").exists()


# Borderline inputs that are valid: numpy scalars wherever a number is taken.
ACCEPTED = [
    ("t=np.float32", lambda p: tb.propagate("reduced", FIG5, X, np.float32(1.0))),
    ("t=np.int64", lambda p: tb.propagate("reduced", FIG5, X, np.int64(1))),
    ("tol=np.float64", lambda p: tb.problem("reduced", FIG5, tol=np.float64(1e-10))),
    ("prec=np.int64", lambda p: tb.problem("reduced", FIG5, fp_type="real", prec=np.int64(128))),
    ("mass=np.float32", lambda p: _ball(mass=np.float32(1.0))),
    ("inertia numpy", lambda p: _ball(inertia=np.array([2.0, 3.0, 4.0]))),
    ("n_points=np.int64", lambda p: tb.poincare_section("reduced", FIG5, X, n_points=np.int64(1),
                                                        t_end=np.float64(50.0),
                                                        options=tb.SectionOptions(chunk=np.float32(10)))),
    ("g0=np.float64", lambda p: tb.poincare_section("reduced", FIG5, X, n_points=1, g0=np.float64(0.0))),
    ("megno np scalars", lambda p: tb.megno("reduced", FIG5, X, np.float32(3.0), t0=np.int64(1), chunk=np.float64(1))),
    ("megno_many workers=np.int64", lambda p: tb.megno_many("reduced", FIG5, [X], 3.0, workers=np.int64(1))),
    ("long run np scalars", lambda p: _study(p, t_end=np.float32(10.0), sample_dt=np.int64(1),
                                             checkpoint_every=np.float64(10), workers=np.int64(1),
                                             observables={"samples_every": np.float32(2.0), "extremes": np.bool_(0)})),
    ("long run drawn np scalars", lambda p: tb.StudyConfig.from_problem(
        tb.problem("reduced", FIG5), store=p / "run", levels=tb.Levels(**LEVELS), n=np.int64(2), seed=np.int64(1),
        t_end=np.float64(10.0), checkpoint_every=np.int32(5))),
    ("chart np scalars", lambda p: tb.states_on_section(FIG5, C=np.float64(10), M_gamma=np.int64(2), h=np.float32(5),
                                                        point=POINT, g0=np.float32(0.0), n_grid=np.int64(201))),
    ("sample n=np.int64", lambda p: tb.section_admissible_sample(FIG5, **LEVELS, n=np.int64(1), n_grid=np.int64(201))),
    ("long run 0.1/0.3", lambda p: _study(p, t_end=1.5, sample_dt=0.1, checkpoint_every=0.3)),
    ("long run 0.1/0.7", lambda p: _study(p, t_end=2.1, sample_dt=0.1, checkpoint_every=0.7)),
]


@pytest.mark.parametrize("name, fn", ACCEPTED, ids=[c[0] for c in ACCEPTED])
def test_borderline_input_is_accepted(name, fn, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert fn(tmp_path) is not None


def test_a_chunk_grid_that_rounds_runs_to_the_end_and_resumes(tmp_path):
    """sample_dt=0.1, checkpoint_every=0.3: the grid is ``m * sample_dt`` (0.3 + 3 * 0.1 is
    0.6000000000000001, past the next chunk's start 0.6, on a grid of sums); a run to 0.6
    extended to 1.5 is the direct run to 1.5, every time once and increasing."""
    part = _study(tmp_path / "a", t_end=0.6, sample_dt=0.1, checkpoint_every=0.3, observables={"samples_every": 0.1})
    tb.run_study(part)
    tb.run_study(part, extend=1.5)
    once = _study(tmp_path / "b", t_end=1.5, sample_dt=0.1, checkpoint_every=0.3, observables={"samples_every": 0.1})
    assert tb.run_study(once).complete
    a = tb.open_run(tmp_path / "a" / "run", observable="samples")
    b = tb.open_run(tmp_path / "b" / "run", observable="samples")
    t = a.t.values[0]
    assert len(t) == 16 and t[-1] == 1.5 and np.all(np.diff(t) > 0)
    assert np.array_equal(t, b.t.values[0]) and np.array_equal(a.state.values, b.state.values)


# ---------------------------------------------------------------------------------------
# Hypothesis: random bad values at the main entry points.
# ---------------------------------------------------------------------------------------
class _Hang(Exception):
    pass


@contextmanager
def _time_limit(seconds):
    def on_alarm(signum, frame):
        raise _Hang(f"no answer within {seconds} s")

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


_WEIRD = [NAN, INF, -INF, 0, 0.0, -0.0, -1, -1.0, 1e-300, -1e-300, 5e-324, 1e308, -1e308, 10**30, True, False,
          None, "1", "", b"x", "nan", [], [1.0], [NAN], (1, 2, 3), {}, object(), 1j, 2.5, np.float32(2), np.int64(2),
          np.nan, np.array([]), np.zeros((2, 2)), np.array(["a"]), np.zeros(9), np.ones(3), np.array(1.0),
          np.float64(INF), np.bool_(True), hy.real128(NAN), slice(1)]
BAD = st.one_of(
    st.sampled_from(_WEIRD),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**20), max_value=10**20),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=10),
    st.text(max_size=3),
)


def _real(v):
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def _costly(limit):
    """A valid number whose work is legitimately large (a long time, many points): such
    draws are skipped, the time limit is for answers to bad input and small requests."""
    return lambda v: _real(v) and math.isfinite(float(v)) and abs(float(v)) > limit


def _tiny_step(v):
    return _real(v) and math.isfinite(float(v)) and 0 < float(v) < 0.05


def _valid_tol(v):
    # a valid tolerance compiles a new integrator (seconds each): not what this test is about
    return _real(v) and 2.0**-52 <= float(v) <= 1e-6


_STUDY_KEYS = {("ball", "inertia"): [2.0, 3.0, 4.0], ("ball", "mass"): 1.0, ("ball", "radius"): 5.0,
               ("ball", "plane_rate"): 2.0, ("level", "G"): 10.0, ("level", "H"): 2.0, ("level", "h"): 5.0,
               ("orbits", "n"): 2, ("orbits", "seed"): 1, ("run", "t_end"): 100.0, ("run", "checkpoint_every"): 25.0,
               ("run", "sample_dt"): 0.25, ("run", "fp_type"): "float", ("run", "tol"): 1e-15,
               ("run", "backend"): "serial", ("run", "workers"): 2, ("observables", "drift"): True,
               ("observables", "samples_every"): 5.0, ("observables", "angles_every"): 10.0,
               ("observables", "extremes"): True, ("observables", "histogram"): False,
               ("observables", "sections"): "all", ("output", "store"): "store"}


def _study_tables(a):
    """The study's tables from ``{(table, key): value}`` (a value None leaves the key out)."""
    d = {}
    for (t, k), v in a.items():
        if v is not None:
            d.setdefault(t, {})[k] = v
    return d


# entry point: (call with overrides, {argument: skip-predicate or None})
ENTRY = {
    "propagate": (lambda a: tb.propagate(a["kind"], a["params"], a["state"], a["t"], tol=a["tol"],
                                         constraint_tol=a["constraint_tol"], fp_type=a["fp_type"], prec=a["prec"]),
                  dict(kind="reduced", params=FIG5, state=X, t=0.5, tol=None, constraint_tol=None, fp_type=float,
                       prec=None),
                  dict(t=_costly(5), tol=_valid_tol, prec=lambda v: True)),
    "integrals": (lambda a: tb.integrals(a["kind"], a["params"], a["state"]),
                  dict(kind="reduced", params=FIG5, state=X), {}),
    "poincare_section": (lambda a: tb.poincare_section("reduced", a["params"], a["state"], n_points=a["n_points"],
                                                       g0=a["g0"], direction=a["direction"], t_end=a["t_end"],
                                                       options=tb.SectionOptions(chunk=a["chunk"], tol=a["tol"])),
                         dict(params=FIG5, state=X, n_points=1, g0=0.0, direction=1, t_end=50.0, chunk=10.0, tol=None),
                         dict(n_points=_costly(2), t_end=_costly(60), chunk=_tiny_step, tol=_valid_tol)),
    "megno": (lambda a: tb.megno("reduced", a["params"], a["state"], a["t_end"], t0=a["t0"], chunk=a["chunk"],
                                 seed=a["seed"], stop_above=a["stop_above"]),
              dict(params=FIG5, state=X, t_end=2.0, t0=1.0, chunk=1.0, seed=0, stop_above=None),
              dict(t_end=_costly(5), t0=_costly(5), chunk=_tiny_step)),
    "BallParams": (lambda a: tb.BallParams(inertia=a["inertia"], mass=a["mass"], radius=a["radius"],
                                           plane_rate=a["plane_rate"]),
                   dict(inertia=(2, 3, 4), mass=1.0, radius=5.0, plane_rate=2.0), {}),
    "states_on_section": (lambda a: tb.states_on_section(a["params"], C=a["C"], M_gamma=a["M_gamma"], h=a["h"],
                                                         point=a["point"], g0=a["g0"], direction=a["direction"],
                                                         n_grid=a["n_grid"]),
                          dict(params=FIG5, C=10.0, M_gamma=2.0, h=5.0, point=POINT, g0=0.0, direction=None,
                               n_grid=201),
                          dict(n_grid=_costly(10**5))),
    "StudyConfig.from_problem": (lambda a: tb.StudyConfig.from_problem(
        tb.problem(a["kind"], FIG5), store=a["store"], states=a["states"], t_end=a["t_end"],
        sample_dt=a["sample_dt"], checkpoint_every=a["checkpoint_every"], observables=a["observables"]),
        dict(kind="reduced", store="/nonexistent/run", states=[X], t_end=10.0, sample_dt=1.0, checkpoint_every=10.0,
             observables={}), {}),
    # the rest of the public API ("every public entry point")
    "problem": (lambda a: tb.problem(a["kind"], a["params"], fp_type=a["fp_type"], prec=a["prec"], tol=a["tol"],
                                     formulation=a["formulation"]),
                dict(kind="reduced", params=FIG5, fp_type=float, prec=None, tol=None, formulation=None),
                dict(tol=_valid_tol, prec=lambda v: True)),
    "make_integrator": (lambda a: tb.make_integrator(a["kind"], a["params"], a["state"], t0=a["t0"],
                                                     project=a["project"]),
                        dict(kind="reduced", params=FIG5, state=X, t0=0.0, project=False), {}),
    "integral_scales": (lambda a: tb.integral_scales(a["kind"], a["params"], a["state"], check=a["check"]),
                        dict(kind="reduced", params=FIG5, state=X, check=True), {}),
    "density": (lambda a: tb.density(a["kind"], a["params"], a["state"], coords=a["coords"]),
                dict(kind="reduced", params=FIG5, state=X, coords="public"), {}),
    "project": (lambda a: tb.project(a["kind"], a["state"]), dict(kind="reduced", state=X), {}),
    "reduced_to_full": (lambda a: tb.reduced_to_full(a["params"], a["state"], psi=a["psi"]),
                        dict(params=FIG5, state=X, psi=0.0), {}),
    "reduced_chart": (lambda a: tb.reduced_chart(a["params"], a["state"]), dict(params=FIG5, state=X), {}),
    "section_sheet": (lambda a: tb.section_sheet(a["params"], a["states"], C=a["C"], M_gamma=a["M_gamma"], h=a["h"],
                                                 g0=a["g0"], direction=a["direction"], n_grid=a["n_grid"],
                                                 chunk=a["chunk"], label=a["label"]),
                      dict(params=FIG5, states=tb.states_on_section(FIG5, **LEVELS, point=POINT, direction=1),
                           **LEVELS, g0=0.0, direction=1, n_grid=201, chunk=64, label="root"),
                      dict(n_grid=_costly(10**5))),
    "section_admissible_sample": (lambda a: tb.section_admissible_sample(a["params"], C=a["C"], M_gamma=a["M_gamma"],
                                                                         h=a["h"], n=a["n"], seed=a["seed"]),
                                  dict(params=FIG5, C=10.0, M_gamma=2.0, h=5.0, n=2, seed=0),
                                  dict(n=_costly(50))),
    "poincare_sections": (lambda a: tb.poincare_sections("reduced", a["params"], a["states"], n_points=a["n_points"],
                                                         t_end=a["t_end"], workers=a["workers"], batch=a["batch"]),
                          dict(params=FIG5, states=[X], n_points=1, t_end=50.0, workers=1, batch=False),
                          dict(n_points=_costly(2), t_end=_costly(60))),
    "megno_many": (lambda a: tb.megno_many("reduced", a["params"], a["states"], a["t_end"], workers=a["workers"],
                                           options=tb.MegnoOptions(t0=a["t0"])),
                   dict(params=FIG5, states=[X], t_end=2.0, t0=1.0, workers=1),
                   dict(t_end=_costly(5), t0=_costly(5))),
    "megno_map": (lambda a: tb.megno_map(a["params"], a["levels"], l=a["l"], r1=a["r1"], r2=a["r2"], t_end=a["t_end"],
                                         root=a["root"], sheet=a["sheet"], indicator=a["indicator"], workers=1),
                  dict(params=FIG5, levels=tb.Levels(C=10.0, M_gamma=6.0, h=5.0), l=1.0, r1=(-2.0, 2.0, 2),
                       r2=(-2.0, 2.0, 2), t_end=2.0, root=None, sheet=0, indicator="mean_megno"),
                  dict(t_end=_costly(5))),
    "lyapunov_spectrum": (lambda a: tb.lyapunov_spectrum("reduced", a["params"], a["state"], a["t_end"], t0=a["t0"],
                                                         renorm=a["renorm"]),
                          dict(params=FIG5, state=X, t_end=1.0, t0=0.0, renorm=0.5),
                          dict(t_end=_costly(3), t0=_costly(3), renorm=_tiny_step)),
    "lyapunov_spectra": (lambda a: tb.lyapunov_spectra("reduced", a["params"], a["states"], a["t_end"], t0=a["t0"],
                                                       renorm=a["renorm"], sample=a["sample"], workers=1),
                         dict(params=FIG5, states=[X], t_end=1.0, t0=0.0, renorm=0.5, sample=[0.25, 1.0]),
                         dict(t_end=_costly(3), t0=_costly(3), renorm=_tiny_step)),
    "gali": (lambda a: tb.gali("reduced", a["params"], a["state"], a["t_end"], k=a["k"], t0=a["t0"],
                               renorm=a["renorm"], seed=a["seed"]),
             dict(params=FIG5, state=X, t_end=1.0, k=2, t0=0.0, renorm=0.5, seed=0),
             dict(t_end=_costly(3), t0=_costly(3), renorm=_tiny_step)),
    "gali_many": (lambda a: tb.gali_many("reduced", a["params"], a["states"], a["t_end"], k=a["k"], t0=a["t0"],
                                         renorm=a["renorm"], seed=a["seed"], sample=a["sample"], workers=1),
                  dict(params=FIG5, states=[X], t_end=1.0, k=2, t0=0.0, renorm=0.5, seed=0, sample=None),
                  dict(t_end=_costly(3), t0=_costly(3), renorm=_tiny_step)),
    "MParallelParams": (lambda a: tb.MParallelParams(a=a["a"], d=a["d"], plane_rate=a["plane_rate"]),
                        dict(a=(0.037, 0.036, 0.034), d=25.0, plane_rate=2.0), {}),
    "Levels.from_caption": (lambda a: tb.Levels.from_caption(a["G"], a["H"], a["h"]),
                            dict(G=10.0, H=2.0, h=5.0), {}),
    "contact_trajectory": (lambda a: tb.contact_trajectory(a["params"], a["state"], a["t"]),
                           dict(params=FIG5, state=X, t=[0.0, 0.5]), dict(t=_costly(5))),
    "transport.msd": (lambda a: tb.transport.msd(a["t"], a["x"]),
                      dict(t=np.arange(8.0), x=np.cumsum(np.ones((3, 8)), axis=1)), {}),
    "transport.msd_per_orbit": (lambda a: tb.transport.msd_per_orbit(a["t"], a["x"], lags=a["lags"]),
                                dict(t=np.arange(8.0), x=np.cumsum(np.ones((1, 8)), axis=1), lags=None), {}),
    "section_sigma": (lambda a: tb.section_sigma(a["params"], C=a["C"], M_gamma=a["M_gamma"], h=a["h"],
                                                 points=a["points"], g0=a["g0"], direction=a["direction"],
                                                 n_grid=a["n_grid"]),
                      dict(params=FIG5, C=10.0, M_gamma=2.0, h=5.0, points=[POINT], g0=0.0, direction=1, n_grid=201),
                      dict(n_grid=_costly(10**5))),
    "section_sigma_sample": (lambda a: tb.section_sigma_sample(a["params"], C=a["C"], M_gamma=a["M_gamma"], h=a["h"],
                                                               n=a["n"], g0=a["g0"], direction=a["direction"],
                                                               seed=a["seed"]),
                             dict(params=FIG5, C=10.0, M_gamma=2.0, h=5.0, n=100, g0=0.0, direction=1, seed=0),
                             dict(n=_costly(10**7))),
    "transport.occupation": (lambda a: tb.transport.occupation(a["points"], a["times"], a["density"], a["bins"],
                                                               at=a["at"], metric=a["metric"], quad=a["quad"]),
                             dict(points=np.full((3, 2), 0.5), times=[0.0, 1.0, 2.0], density=np.ones((2, 2)),
                                  bins=[[0.0, 0.5, 1.0]] * 2, at=None, metric="tv", quad=2), {}),
    "run_many": (lambda a: run_many(a["jobs"], backend=a["backend"], workers=a["workers"], on_error=a["on_error"]),
                 dict(jobs=[call(abs, -1.0)], backend="serial", workers=None, on_error="raise"), {}),
    # run_study's arguments (a valid value of each is skipped: it would run or extend the study)
    "run_study": (lambda a: tb.run_study(_small_study() if a["study"] is None else a["study"], backend=a["backend"], workers=a["workers"], extend=a["extend"],
                                         restart=a["restart"]),
                  dict(study=None, backend="lanes", workers=None, extend=None, restart=False),
                  dict(backend=lambda v: isinstance(v, str) and v in ("threads", "processes", "serial", "lanes"),
                       workers=lambda v: isinstance(v, (int, np.integer)) and not isinstance(v, bool) and 1 <= v <= 4096,
                       extend=lambda v: _real(v) and math.isfinite(float(v)) and float(v) > 0,
                       restart=lambda v: isinstance(v, bool), study=lambda v: v is None)),
    # a study file's every key (validation only: nothing is drawn, run or written)
    "StudyConfig.from_dict": (lambda a: tb.StudyConfig.from_dict(_study_tables(a), base=Path("/nonexistent")),
                              dict(_STUDY_KEYS), {}),
}


@functools.lru_cache(maxsize=None)
def _small_study():
    """A small lanes study (2 orbits to t = 25) in a temporary folder (removed at exit), for
    run_study."""
    import atexit
    import shutil
    import tempfile

    keys = {**_STUDY_KEYS, ("run", "t_end"): 25.0, ("run", "backend"): "lanes", ("run", "tol"): None,
            ("observables", "sections"): False}
    folder = tempfile.mkdtemp(prefix="tb_bad_inputs_")
    atexit.register(shutil.rmtree, folder, True)
    return tb.StudyConfig.from_dict(_study_tables(keys), base=Path(folder))


@functools.lru_cache(maxsize=None)
def _warm(name):
    """One valid call per entry point outside the time limit: compiling on a cold heyoka
    cache takes seconds (not an answer to bad input)."""
    call_, base, _ = ENTRY[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        call_(dict(base))


def _throw(name, data):
    call_, base, skip = ENTRY[name]
    _warm(name)
    args = dict(base)
    for key in data.draw(st.lists(st.sampled_from(sorted(base)), min_size=1, max_size=2, unique=True), label="args"):
        value = data.draw(BAD, label=key)
        assume(not (skip.get(key) or (lambda v: False))(value))
        args[key] = value
    peak0 = _peak_rss_mib()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            with _time_limit(20.0):
                call_(args)
        except tb.TaylorballError:
            pass
    # no memory blow-up: the process's peak resident size may not jump by a GiB in one call
    # (a refused long-run configuration with sample_dt=1e-9 once reached 3.9 GB in 25 s; every valid draw
    # here is small, a few MiB)
    grown = _peak_rss_mib() - peak0
    assert grown < 1024, f"{name}({args!r}) raised the peak memory by {grown:.0f} MiB"


def _peak_rss_mib() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux: KiB


_FAST = settings(max_examples=12, deadline=None, derandomize=True,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


@pytest.mark.parametrize("name", sorted(ENTRY))
@_FAST
@given(data=st.data())
def test_random_bad_values_give_a_result_or_a_taylorball_error(name, data):
    _throw(name, data)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(ENTRY))
@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(data=st.data())
def test_random_bad_values_thorough(name, data):
    _throw(name, data)


def test_how_many_random_examples_ran():
    """The random test above must not be all skipped draws (guard against a filter that
    rejects everything): count the examples that reached the call."""
    reached = []

    @settings(max_examples=30, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
    @given(data=st.data())
    def run(data):
        _throw("BallParams", data)
        reached.append(1)

    run()
    assert len(reached) >= 20
