"""The rarer options of ``megno_many``, ``chaotic_fraction``, ``megno_map``,
``poincare_section`` and ``poincare_sections`` come in an options object
(``tb.MegnoOptions``, ``tb.MegnoMapOptions``, ``tb.SectionOptions``); each old keyword form
keeps working for one release with a DeprecationWarning naming the new form, and gives the
same bits as the new form."""

import numpy as np
import pytest

import taylorball as tb
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS, FIG4B_LEVELS, demo_reduced_state

X0 = demo_reduced_state()
GRID = dict(l=0.0, r1=(-4, 4, 3), r2=(-6, 6, 3))


def _mm(**kw):
    return [r.mean_megno for r in tb.megno_many("reduced", FIG4_BALL, [X0], 6.0, workers=1, **kw)]


def _cf(**kw):
    return tb.chaotic_fraction(FIG4_BALL, FIG4A_LEVELS, n=1, t_end=6.0, workers=1, **kw).mean_megno


def _map(**kw):
    return tb.megno_map(FIG4_BALL, FIG4B_LEVELS, t_end=6.0, workers=1, **GRID, **kw).values


def _ps(**kw):
    r = tb.poincare_section("reduced", FIG4_BALL, X0, n_points=3, **kw)
    return np.concatenate([r.times, r.points.ravel()])


def _pss(**kw):
    r = tb.poincare_sections("reduced", FIG4_BALL, [X0], n_points=3, workers=1, **kw)[0]
    return np.concatenate([r.times, r.points.ravel()])


def _gamma3(**kw):  # a user section: the event and its chart
    r = tb.poincare_section("reduced", FIG4_BALL, X0, n_points=2, **kw)
    return np.concatenate([r.times, r.points.ravel()])


# (function, its caller, options type, old keyword, a value other than the default)
CASES = [
    ("megno_many", _mm, tb.MegnoOptions, "t0", 0.5),
    ("megno_many", _mm, tb.MegnoOptions, "chunk", 2.0),
    ("megno_many", _mm, tb.MegnoOptions, "seed", 3),
    ("megno_many", _mm, tb.MegnoOptions, "compact_mode", True),
    ("chaotic_fraction", _cf, tb.MegnoOptions, "t0", 0.5),
    ("chaotic_fraction", _cf, tb.MegnoOptions, "compact_mode", True),
    ("megno_map", _map, tb.MegnoMapOptions, "g0", 0.5),
    ("megno_map", _map, tb.MegnoMapOptions, "direction", -1),
    ("megno_map", _map, tb.MegnoMapOptions, "t0", 0.5),
    ("megno_map", _map, tb.MegnoMapOptions, "chunk", 2.0),
    ("megno_map", _map, tb.MegnoMapOptions, "seed", 3),
    ("megno_map", _map, tb.MegnoMapOptions, "stop_above", 3.0),
    ("megno_map", _map, tb.MegnoMapOptions, "compact_mode", True),
    ("megno_map", _map, tb.MegnoMapOptions, "norm", "full"),
    ("megno_map", _map, tb.MegnoMapOptions, "n_grid", 501),
    ("poincare_section", _ps, tb.SectionOptions, "tol", 1e-12),
    ("poincare_section", _ps, tb.SectionOptions, "chunk", 7.0),
    ("poincare_section", _ps, tb.SectionOptions, "prec", None),  # float64 takes no precision: None only
    ("poincare_section", _gamma3, tb.SectionOptions, "event", "gamma3"),
    ("poincare_sections", _pss, tb.SectionOptions, "tol", 1e-12),
    ("poincare_sections", _pss, tb.SectionOptions, "chunk", 7.0),
    ("poincare_sections", _pss, tb.SectionOptions, "prec", None),
]


@pytest.mark.parametrize("func, run, options, old, value", CASES, ids=[f"{c[0]}-{c[3]}" for c in CASES])
def test_an_old_keyword_warns_and_gives_the_same_result(func, run, options, old, value):
    with pytest.warns(DeprecationWarning, match=rf"{func}\({old}=\.\.\.\) is deprecated: use "
                                                rf"options=tb\.{options.__name__}\({old}=\.\.\.\)"):
        a = run(**{old: value})
    b = run(options=options(**{old: value}))
    assert np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float), equal_nan=True)


def test_the_chart_of_a_user_section_moved_too():
    with pytest.warns(DeprecationWarning, match=r"poincare_section\(chart=\.\.\.\) is deprecated"):
        a = _gamma3(chart=("r1", "r2"), options=tb.SectionOptions(event="gamma3"))
    b = _gamma3(options=tb.SectionOptions(event="gamma3", chart=("r1", "r2")))
    assert np.array_equal(a, b)


def test_an_option_changes_the_run():
    """The options object is used, not ignored: a shorter chunk and another seed change the bits."""
    assert _mm() != _mm(options=tb.MegnoOptions(seed=3))
    assert not np.array_equal(_ps(), _ps(options=tb.SectionOptions(tol=1e-10)))


@pytest.mark.parametrize("call, name", [
    (lambda: tb.megno_many("reduced", FIG4_BALL, [X0], 6.0, options={"t0": 0.5}), "MegnoOptions"),
    (lambda: tb.chaotic_fraction(FIG4_BALL, FIG4A_LEVELS, n=1, t_end=6.0, options=tb.SectionOptions()),
     "MegnoOptions"),
    (lambda: tb.poincare_section("reduced", FIG4_BALL, X0, n_points=1, options=tb.MegnoOptions()), "SectionOptions"),
    (lambda: tb.poincare_sections("reduced", FIG4_BALL, [X0], n_points=1, options=1.0), "SectionOptions"),
])
def test_a_wrong_options_object_is_named(call, name):
    with pytest.raises(tb.UsageError, match=rf"options must be a taylorball\.{name}"):
        call()


def test_an_old_keyword_with_a_wrong_options_object_is_named():
    with pytest.warns(DeprecationWarning, match=r"megno_many\(t0=\.\.\.\)"):
        with pytest.raises(tb.UsageError, match=r"megno_many: options must be a taylorball\.MegnoOptions"):
            tb.megno_many("reduced", FIG4_BALL, [X0], 6.0, t0=0.5, options=tb.SectionOptions())


def _po(**kw):
    """A Fig. 3 periodic orbit from the guess of tests/test_periodic.py: its period and
    state, or the residual of a Newton failure (both are outcomes to compare)."""
    from taylorball.paper import FIG3_BALL, FIG3_LEVELS

    st = tb.states_on_section(FIG3_BALL, **FIG3_LEVELS.as_kwargs(), point=(0.0, -0.3, 0.0), direction=1)[1]
    try:
        o = tb.periodic_orbit("reduced", FIG3_BALL, st, 1, levels=FIG3_LEVELS, **kw)
    except tb.NewtonFailure as e:
        return np.array([e.residual])
    return np.concatenate([[o.period], o.state])


PERIODIC = [("max_iter", 2), ("rtol", 1e-9), ("shift", 0.01), ("section_tol", 1e-6)]


@pytest.mark.parametrize("old, value", PERIODIC, ids=[c[0] for c in PERIODIC])
def test_periodic_orbit_old_keyword(old, value):
    with pytest.warns(DeprecationWarning, match=rf"periodic_orbit\({old}=\.\.\.\) is deprecated: use "
                                                rf"options=tb\.NewtonOptions\({old}=\.\.\.\)"):
        a = _po(**{old: value})
    assert np.array_equal(a, _po(options=tb.NewtonOptions(**{old: value})))


SEARCH = ["n_seeds", "per_k", "n_grid", "max_dist", "reversor_seeds", "max_iter"]


@pytest.mark.parametrize("old", SEARCH)
def test_periodic_orbits_old_keyword(old):
    """The warning of each old keyword (the search itself is not run: ``k_max=0`` is refused
    after the keyword was put into the options; the value reaching the run is the shared
    mechanism checked with the real runs above)."""
    from taylorball.paper import FIG3_BALL, FIG3_LEVELS

    value = getattr(tb.SearchOptions(), old)
    with pytest.warns(DeprecationWarning, match=rf"periodic_orbits\({old}=\.\.\.\) is deprecated: use "
                                                rf"options=tb\.SearchOptions\({old}=\.\.\.\)"):
        with pytest.raises(tb.UsageError, match="k_max"):
            tb.periodic_orbits("reduced", FIG3_BALL, FIG3_LEVELS, k_max=0, **{old: value})
