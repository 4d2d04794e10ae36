"""Indicator maps on a section level (tb.megno_map): each value is megno_many of the state
that states_on_section gives at that chart point (bit-identical), NaN exactly where it gives
none; bad grids and arguments are refused before any work."""

import math

import numpy as np
import pytest

import taylorball as tb
from taylorball.paper import FIG3_BALL, FIG3_LEVELS, FIG4_BALL, FIG4B_LEVELS

GRID = dict(l=1.0, r1=(-5.0, 5.0, 6), r2=(-8.0, 8.0, 6))


def _states(params, levels, l, r1, r2, root=0, direction=1):
    """The reference: states_on_section point by point (None where there is no state of index root)."""
    out = {}
    for i, b in enumerate(np.linspace(*r2)):
        for j, a in enumerate(np.linspace(*r1)):
            try:
                xs = tb.states_on_section(params, **levels.as_kwargs(), point=(l, a, b), direction=direction)
            except tb.EmptyLevelError:
                xs = []
            out[i, j] = (xs[root] if -len(xs) <= root < len(xs) else None, len(xs))
    return out


@pytest.fixture(scope="module")
def small_map():
    return tb.megno_map(FIG4_BALL, FIG4B_LEVELS, t_end=200.0, workers=2, **GRID)


def test_map_values_are_megno_many_of_the_section_states(small_map):
    m = small_map
    ref = _states(FIG4_BALL, FIG4B_LEVELS, GRID["l"], GRID["r1"], GRID["r2"])
    keys = [k for k, (x, _) in ref.items() if x is not None]
    # a meaningful test: the grid has admissible and inadmissible points
    assert 5 <= len(keys) <= 31, len(keys)
    many = tb.megno_many("reduced", FIG4_BALL, [ref[k][0] for k in keys], 200.0, workers=1)
    got = {k: float(m.values[k]) for k in keys}
    # bit-identical: the same states through the same lanes (an orbit's bits depend on its state only)
    assert got == {k: r.mean_megno for k, r in zip(keys, many)}
    assert {k: float(m.t.values[k]) for k in keys} == {k: r.t for k, r in zip(keys, many)}
    # NaN exactly where states_on_section finds no state; n_roots as it counts them
    nan = {k for k in ref if math.isnan(m.values[k])}
    assert nan == {k for k, (x, _) in ref.items() if x is None}
    assert {k: int(m.n_roots.values[k]) for k in ref} == {k: n for k, (_, n) in ref.items()}
    # the coordinates and what the map is of
    assert m.dims == ("r2", "r1") and m.shape == (6, 6)
    assert np.array_equal(m.r1.values, np.linspace(-5, 5, 6)) and np.array_equal(m.r2.values, np.linspace(-8, 8, 6))
    assert (m.attrs["C"], m.attrs["M_gamma"], m.attrs["h"]) == (10.0, 6.0, 5.0)
    assert (m.attrs["t_end"], m.attrs["l"], m.attrs["indicator"]) == (200.0, 1.0, "mean_megno")
    assert list(m.attrs["inertia"]) == [2.0, 3.0, 4.0] and "heyoka" in m.attrs["provenance"]
    # the root K taken is that of the state (K = M3 = C cos(theta) on the level)
    for k in keys:
        assert abs(float(tb.reduced_chart(FIG4_BALL, ref[k][0])["K"]) - float(m.K.values[k])) <= 1e-12 * 10


def test_map_other_sheet_and_indicator(small_map):
    """root=1 maps the second sheet (NaN where a point has one state); indicator='fli' is the
    FLI of the very same runs."""
    m1 = tb.megno_map(FIG4_BALL, FIG4B_LEVELS, t_end=200.0, root=1, indicator="fli", **GRID)
    ref = _states(FIG4_BALL, FIG4B_LEVELS, GRID["l"], GRID["r1"], GRID["r2"], root=1)
    keys = [k for k, (x, _) in ref.items() if x is not None]
    assert keys and {k for k in ref if math.isnan(m1.values[k])} == {k for k in ref if ref[k][0] is None}
    many = tb.megno_many("reduced", FIG4_BALL, [ref[k][0] for k in keys], 200.0)
    assert [float(m1.values[k]) for k in keys] == [r.fli for r in many]
    # the second sheet exists only where there are two states
    assert np.all(np.isnan(m1.values[small_map.n_roots.values < 2]))


def test_map_of_a_sheet_label(small_map):
    """sheet=k maps the state of sheet label k (states_on_section's info["sheet"]) at each
    point, bit-identical to megno_many of it; coordinate root is its index in ascending K."""
    m = tb.megno_map(FIG4_BALL, FIG4B_LEVELS, t_end=200.0, sheet=1, **GRID)
    ref = {}
    for i, b in enumerate(np.linspace(*GRID["r2"])):
        for j, a in enumerate(np.linspace(*GRID["r1"])):
            try:
                xs, info = tb.states_on_section(FIG4_BALL, **FIG4B_LEVELS.as_kwargs(), point=(GRID["l"], a, b),
                                                direction=1, return_info=True)
            except tb.EmptyLevelError:
                continue
            hit = np.flatnonzero(info["sheet"] == 1)
            if hit.size:
                ref[i, j] = (xs[hit[0]], int(hit[0]))
    keys = sorted(ref)
    assert keys and {k for k in np.ndindex(m.shape) if not math.isnan(m.values[k])} == set(keys)
    many = tb.megno_many("reduced", FIG4_BALL, [ref[k][0] for k in keys], 200.0)
    assert [float(m.values[k]) for k in keys] == [r.mean_megno for r in many]
    assert [int(m.root.values[k]) for k in keys] == [ref[k][1] for k in keys]
    assert m.attrs["sheet"] == 1 and "root" not in m.attrs and "root" not in small_map.coords
    # where sheet 1 is root 0 the values are those of the root-0 map (the same state, the same run)
    same = [k for k in keys if ref[k][1] == 0]
    assert same and all(float(m.values[k]) == float(small_map.values[k]) for k in same)


def test_symmetric_ball_map_is_the_2d_section():
    """I1 = I2 (Fig. 3 ball): l is cyclic (a rotation about e3 shifts l and leaves the
    equations and integrals unchanged), so two slices carry the same points and roots K.
    K is a bisected root of the energy equation in float64, E ~ C^2 / I ~ 10^2 with
    dE/dK ~ 1..10: the two slices' roots agree to ~ulp(E) / |dE/dK| ~ 1e-14 (measured 2.6e-14);
    bound 100 eps C (2.2e-13). (The indicator values themselves differ: the random initial tangent vector
    is not rotated with the state, and MEGNO at finite T depends on it.)"""
    kw = dict(r1=(-4.0, 4.0, 5), r2=(-4.0, 4.0, 5), t_end=20.0)
    a = tb.megno_map(FIG3_BALL, FIG3_LEVELS, l=0.3, **kw)
    b = tb.megno_map(FIG3_BALL, FIG3_LEVELS, l=2.0, **kw)
    assert np.array_equal(a.n_roots.values, b.n_roots.values) and (a.n_roots.values > 0).any()
    assert np.array_equal(np.isnan(a.values), np.isnan(b.values))
    ok = np.isfinite(a.values)
    eps = np.finfo(float).eps
    assert np.max(np.abs(a.K.values[ok] - b.K.values[ok])) <= 100 * eps * FIG3_LEVELS.C


@pytest.mark.parametrize("kw, match", [
    (dict(r1=(-5.0, 5.0, 0)), "r1 number of points"),
    (dict(r1=(-5.0, 5.0, 1)), "r1 number of points"),
    (dict(r1=(-5.0, 5.0, 2.5)), "r1 number of points"),
    (dict(r2=(-8.0, 8.0, 10**6)), "r2 number of points"),
    (dict(r1=(-5.0, 5.0, 1000), r2=(-8.0, 8.0, 1000)), "MAX_MAP_POINTS"),
    (dict(r1=(float("nan"), 5.0, 6)), "r1 lower bound"),
    (dict(r2=(-8.0, float("inf"), 6)), "r2 upper bound"),
    (dict(r1=(5.0, -5.0, 6)), "lo < hi"),
    (dict(r1=(5.0, 6)), r"r1 must be \(lo, hi, n\)"),
    (dict(r1="abc"), r"r1 must be \(lo, hi, n\)"),
    (dict(l=7.0), "l "),
    (dict(l=-0.1), "l "),
    (dict(l=float("nan")), "l "),
    (dict(t_end=float("nan")), "t_end"),
    (dict(t_end=0.5), "t0 < t_end"),
    (dict(t_end=-1.0), "t0 < t_end"),
    (dict(options=tb.MegnoMapOptions(direction=None)), "direction"),
    (dict(options=tb.MegnoMapOptions(direction=0)), "direction"),
    (dict(root=1.5), "root"),
    (dict(root=True), "root"),
    (dict(sheet=-1), "sheet must be"),
    (dict(sheet=2.0), "sheet must be"),
    (dict(sheet=np.bool_(True)), "sheet must be"),
    (dict(sheet=0, root=0), "not both"),
    (dict(indicator="megnoo"), "indicator"),
    (dict(workers=0), "workers"),
    (dict(options=tb.MegnoMapOptions(stop_above=float("nan"))), "stop_above"),
    (dict(options=tb.MegnoMapOptions(norm="Full")), "norm must be one of"),
    (dict(options=dict(t0=1.0)), "options must be a taylorball.MegnoMapOptions"),
])
def test_bad_arguments_are_refused_before_any_work(kw, match, monkeypatch):
    import taylorball.charts as charts

    def no_work(*a, **k):
        raise AssertionError("work started before the arguments were checked")

    monkeypatch.setattr(charts, "states_on_section", no_work)
    monkeypatch.setattr(charts, "_section_states", no_work)  # what megno_map's root search calls
    args = dict(t_end=200.0, **GRID)
    args.update(kw)
    with pytest.raises(tb.UsageError, match=match):
        tb.megno_map(FIG4_BALL, FIG4B_LEVELS, **args)


def test_an_unknown_keyword_is_named():
    with pytest.raises(TypeError, match="unexpected keyword argument 'tmax'"):
        tb.megno_map(FIG4_BALL, FIG4B_LEVELS, tmax=5.0, **GRID)


def test_bad_levels_params_and_empty_grids():
    with pytest.raises(tb.UsageError, match="levels must be a taylorball.Levels"):
        tb.megno_map(FIG4_BALL, (10.0, 6.0, 5.0), t_end=20.0, **GRID)
    with pytest.raises(tb.ChartError, match="M_gamma"):
        tb.megno_map(FIG4_BALL, tb.Levels(C=10.0, M_gamma=10.0, h=5.0), t_end=20.0, **GRID)
    with pytest.raises(tb.TaylorballError):
        tb.megno_map("ball", FIG4B_LEVELS, t_end=20.0, **GRID)
    # far outside the admissible region (the energy falls like -|R|^2): no state anywhere
    with pytest.raises(tb.EmptyLevelError, match="misses the admissible region"):
        tb.megno_map(FIG4_BALL, FIG4B_LEVELS, l=1.0, r1=(40.0, 50.0, 2), r2=(40.0, 50.0, 2), t_end=20.0)


def test_options_object_and_keywords_are_the_same_run():
    """The run options of a map come in a MegnoMapOptions; the keywords of the same names
    (their deprecated old form, which overrides the object's fields) give the same bits."""
    kw = dict(t_end=30.0, workers=1, **GRID)
    a = tb.megno_map(FIG4_BALL, FIG4B_LEVELS, options=tb.MegnoMapOptions(stop_above=5.0, seed=3), **kw)
    with pytest.warns(DeprecationWarning, match=r"megno_map\(stop_above=\.\.\.\) is deprecated: use "
                                                r"options=tb\.MegnoMapOptions\(stop_above="):
        b = tb.megno_map(FIG4_BALL, FIG4B_LEVELS, options=tb.MegnoMapOptions(seed=3), stop_above=5.0, **kw)
    with pytest.warns(DeprecationWarning, match=r"megno_map\(stop_above=\.\.\.\)"):
        c = tb.megno_map(FIG4_BALL, FIG4B_LEVELS, options=tb.MegnoMapOptions(stop_above=9.0, seed=3), stop_above=5.0,
                         **kw)
    for m in (b, c):
        assert np.array_equal(a.values, m.values, equal_nan=True) and np.array_equal(a.t, m.t, equal_nan=True)
    assert a.attrs["stop_above"] == 5.0 and a.attrs["seed"] == 3 and a.attrs["norm"] == "compact"
