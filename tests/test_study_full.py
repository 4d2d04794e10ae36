"""The full system (kind "full": the ball's frame and contact point, paper eqs. (8)-(10) [eq6]) in
the study runner: a short study against an independent long-double propagation, resume and
extend bit-identical, its own fingerprint, and what it cannot observe refused by name before
any work."""

import numpy as np
import pytest

import taylorball as tb
from taylorball.contact import radius_bound
from taylorball.errors import StateError, StoreError, UsageError
from taylorball.manifold import full_to_reduced
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS

EPS = np.finfo(float).eps
OBS = {"samples_every": 0.25, "extremes": True, "histogram": True, "drift": True}


def _cfg(store, t_end=20.0, kind="full", **kw):
    kw.setdefault("observables", OBS)
    kw.setdefault("sample_dt", 0.0625)  # the extremes' Hermite interpolant: error ~ sample_dt^6
    kw.setdefault("backend", "serial")
    return tb.StudyConfig.from_problem(tb.problem(kind, FIG4_BALL), store=store, levels=FIG4A_LEVELS, n=2, seed=3,
                                       t_end=t_end, checkpoint_every=10.0, **kw)


def _arrays(store):
    ds = tb.open_run(store, verify="full").load()
    return {k: ds[k].values for k in ds.data_vars}


@pytest.fixture(scope="module")
def full_store(tmp_path_factory):
    store = tmp_path_factory.mktemp("full") / "store"
    st = tb.run_study(_cfg(store))
    assert st.complete
    return store


def test_a_full_study_follows_an_independent_long_double_propagation(full_store):
    """Samples, drift, extremes and histogram of a float64 full-system study against
    ``tb.propagate`` of the same initial states in long double (64-bit mantissa) on a grid
    64 times finer than the sample grid."""
    ds = tb.open_run(full_store).load()
    assert ds.attrs["study"] and '"kind": "full"' in ds.attrs["study"]
    t = ds.samples_t.values[0]
    np.testing.assert_array_equal(t, np.arange(81) * 0.25)
    fine = np.arange(20 * 1024 + 1) / 1024  # 64 points per sample interval
    for i in range(2):
        X = ds.samples_state.values[i]
        ref = tb.propagate("full", FIG4_BALL, X[0], fine, fp_type=np.longdouble).astype(float)
        # float64 Taylor steps at tol = eps on a chaotic orbit: measured 386 eps of max|x| at
        # t = 20 (error growth); 4096 eps leaves a factor ~10
        np.testing.assert_allclose(X, ref[::256], rtol=0, atol=4096 * EPS * np.abs(ref).max())
        # extremes of |R| = sqrt(x^2 + y^2) per chunk against the fine grid, refined by a
        # parabola through the three fine points around each extreme (error O(h^3), h = 1/1024)
        r = np.hypot(ref[:, 12], ref[:, 13])
        for k in range(2):
            sl = slice(k * 10240, (k + 1) * 10240 + 1)
            for name, sgn in (("r_max", 1.0), ("r_min", -1.0)):
                seg = sgn * r[sl]
                j = int(np.argmax(seg))
                best = seg[j]
                if 0 < j < len(seg) - 1:  # interior: the parabola's vertex
                    a, b, c = seg[j - 1], seg[j], seg[j + 1]
                    best = b + (a - c) ** 2 / (8 * (2 * b - a - c)) if 2 * b - a - c > 0 else b
                got = float(ds[f"extremes_{name}"].values[i, k])
                # not rounding: the quintic Hermite interpolant between samples 1/16 apart
                # (error h^6 max|f^(6)| / 46080; 1.5e-5 at h = 0.25 on these orbits, measured
                # 4.2e-10 relative at 1/16): 1e-8 relative leaves a factor ~24
                assert abs(got - sgn * best) <= 1e-8 * abs(best), (i, k, name, got, sgn * best)
        # the histogram's default r_max is the rigorous bound of the orbit's level (C, h),
        # here from the reduced system's integrals of the reduced state (another code path
        # than the full state's |M| and E the observable uses)
        I = tb.integrals("reduced", FIG4_BALL, full_to_reduced(X[0]))
        bound = float(radius_bound(FIG4_BALL, float(np.sqrt(I["C2"])), float(I["E"])))
        h = ds.histogram_time.values[i]
        np.testing.assert_allclose(h.sum(axis=1), [10.0, 20.0], rtol=64 * EPS)  # time in bins sums to t
        assert h[-1, -1] == 0.0 and r.max() < bound  # nothing at or above the bound
        # drift of F1, F2, F3, E at the chunk ends: rounding, measured 3.2 eps; 64 eps is
        # a factor 20 (a broken drift, e.g. of the wrong integrals, is O(1))
        assert 0 < ds.drift_drift.values[i].max() < 64 * EPS


def test_drawn_full_orbits_are_the_lifted_reduced_ones(full_store, tmp_path):
    """Orbits drawn on a level for the full system are the reduced study's orbits lifted
    (``reduced_to_full``, psi = 0): reduced again, they follow the reduced study."""
    tb.run_study(_cfg(tmp_path / "reduced", kind="reduced", observables={"samples_every": 0.25}))
    red = tb.open_run(tmp_path / "reduced", observable="samples").state.values
    full = tb.open_run(full_store, observable="samples").state.values
    back = full_to_reduced(full)
    # two float64 integrations of one orbit in two systems: measured 1543 eps of max|x| at
    # t = 20 (chaotic growth of the rounding), 16384 eps leaves a factor ~10
    np.testing.assert_allclose(back, red, rtol=0, atol=16384 * EPS * np.abs(red).max())
    # the initial states: the lift and its inverse, measured 0.64 eps; 16 eps a factor 25
    np.testing.assert_allclose(back[:, 0], red[:, 0], rtol=0, atol=16 * EPS * np.abs(red).max())


def test_full_study_resume_and_extend_are_bit_identical(full_store, tmp_path):
    cfg = _cfg(tmp_path / "s", t_end=10.0)
    tb.run_study(cfg)
    assert tb.study_status(cfg).complete
    tb.run_study(cfg, extend=20.0)  # the same chunks a direct run to 20 runs after 10
    st = tb.run_study(_cfg(tmp_path / "s", t_end=20.0))  # t_end raised in the study: the same store, nothing to do
    assert st.complete
    a, b = _arrays(full_store), _arrays(tmp_path / "s")
    assert a.keys() == b.keys() and "samples_state" in a
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_a_full_study_file_is_the_python_study(tmp_path):
    text = """
[ball]
inertia = [2.0, 3.0, 4.0]
mass = 1.0
radius = 5.0
plane_rate = 2.0
system = "full"
[level]
C = 10.0
M_gamma = 2.0
h = 5.0
[orbits]
n = 2
seed = 3
[run]
t_end = 20.0
checkpoint_every = 10.0
backend = "serial"
sample_dt = 0.0625
[observables]
samples_every = 0.25
histogram = true
[output]
store = "store"
"""
    f = tmp_path / "full.toml"
    f.write_text(text)
    file_cfg = tb.load_study(f)
    py = _cfg(tmp_path / "store")
    assert file_cfg.kind == "full" and file_cfg.fingerprint() == py.fingerprint()
    np.testing.assert_array_equal(file_cfg.initial_states, py.initial_states)
    assert file_cfg.initial_states.shape == (2, 14)


def test_the_full_fingerprint_is_not_the_reduced_one(tmp_path):
    """The same ball, level, orbits and observables in the two systems: two studies; a store
    of one is refused by the other, before any work."""
    obs = {"samples_every": 0.25}
    red = _cfg(tmp_path / "s", kind="reduced", observables=obs)
    full = _cfg(tmp_path / "s", observables=obs)
    assert red.fingerprint() != full.fingerprint()
    assert red.orbit_fingerprint(0) != full.orbit_fingerprint(0)
    tb.run_study(_cfg(tmp_path / "s", kind="reduced", observables=obs, t_end=10.0))
    with pytest.raises(StoreError, match="was made by another study"):
        tb.run_study(full)
    assert tb.open_run(tmp_path / "s").attrs["t_end"] == 10.0  # untouched


@pytest.mark.parametrize("tables, error, pattern", [
    ({"observables": {"angles_every": 10.0}}, UsageError,
     r"\[observables\] angles_every = 10.0: needs the section chart \(kind 'reduced'\); a study of kind 'full' "
     r"has drift, samples_every, extremes, histogram"),
    ({"observables": {"sections": "all"}}, UsageError, r"\[observables\] sections = 'all': needs the section chart"),
    ({"ball": {"system": "Full"}}, UsageError, r"\[ball\] system = 'Full': must be \"reduced\" .* or \"full\""),
    ({"orbits": {"states": [[0.0] * 9]}}, UsageError, r"each a list of 14 numbers \(omega1, omega2, omega3, alpha1"),
    ({"orbits": {"states": [[1.0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0]]}}, StateError, r"states\[0\]"),
])
def test_what_the_full_system_does_not_have_is_refused_before_any_work(tmp_path, tables, error, pattern):
    d = {"ball": {"inertia": [2.0, 3.0, 4.0], "mass": 1.0, "radius": 5.0, "plane_rate": 2.0, "system": "full"},
         "level": {"C": 10.0, "M_gamma": 2.0, "h": 5.0}, "orbits": {"n": 1},
         "run": {"t_end": 10.0, "checkpoint_every": 5.0}, "output": {"store": str(tmp_path / "s")}}
    for t, upd in tables.items():
        d[t] = {**d.get(t, {}), **upd}
    if "states" in d["orbits"]:
        d["orbits"].pop("n")
        d.pop("level")
    with pytest.raises(error, match=pattern):
        tb.StudyConfig.from_dict(d)
    assert not (tmp_path / "s").exists()


def test_the_observables_refuse_a_system_without_R_by_name():
    """The observables' own check (for a caller building them by hand) names what is missing."""
    from taylorball.observables import Extremes, Sections

    with pytest.raises(UsageError, match=r"'extremes' needs the contact point R .* got kind 'mparallel'"):
        Extremes().init(tb.problem("mparallel", FIG4_BALL.to_mparallel()), np.zeros(6), 0.0)
    with pytest.raises(UsageError, match=r"'sections' needs the section chart .* and the section's levels"):
        Sections().events(tb.problem("full", FIG4_BALL))


def test_a_full_study_in_simd_lanes(full_store, tmp_path):
    """``backend = "lanes"`` runs the full system too: its own fingerprint (other bits than
    the scalar integrator's), an extension bit-identical to a direct run, and the scalar
    run's orbits to the integration's error."""
    obs = {"samples_every": 0.25}
    lanes = _cfg(tmp_path / "l", t_end=10.0, observables=obs, backend="lanes")
    assert lanes.fingerprint() != _cfg(tmp_path / "l", observables=obs).fingerprint()
    tb.run_study(lanes)
    tb.run_study(lanes, extend=20.0)
    tb.run_study(_cfg(tmp_path / "d", t_end=20.0, observables=obs, backend="lanes"))
    a = tb.open_run(tmp_path / "l", observable="samples").state.values
    np.testing.assert_array_equal(a, tb.open_run(tmp_path / "d", observable="samples").state.values)
    scalar = tb.open_run(full_store, observable="samples").state.values
    # two float64 integrations (scalar and SIMD batch steppers round differently) of a chaotic
    # orbit to t = 20: measured 34 eps of max|x|; 1024 eps leaves a factor ~30 (chaotic
    # growth: 386 eps against long double in the first test)
    np.testing.assert_allclose(a, scalar, rtol=0, atol=1024 * EPS * np.abs(scalar).max())
