"""One vocabulary: the old argument names keep working for one release, each with a
DeprecationWarning naming the new one; giving both names is refused."""

import warnings

import numpy as np
import pytest

import taylorball as tb
from taylorball._deprecation import renamed
from taylorball.ensemble import call, run_many
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS, FIG4B_LEVELS, demo_reduced_state

X0 = demo_reduced_state()
GRID = dict(l=0.0, r1=(-4, 4, 2), r2=(-6, 6, 2))


def test_the_alias_helper():
    @renamed(threads="workers")
    def f(*, workers=None):
        return workers

    with pytest.warns(DeprecationWarning, match=r"f\(threads=\.\.\.\) is deprecated: use workers="):
        assert f(threads=3) == 3
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert f(workers=3) == 3  # the new name: no warning
    with pytest.raises(tb.UsageError, match="both threads= .* and workers="):
        f(threads=1, workers=2)


# (function, old keyword, new keyword, call with the old name, call with the new name)
CASES = [
    ("run_many", "mode", "backend", lambda: run_many([call(abs, -1)], mode="serial"),
     lambda: run_many([call(abs, -1)], backend="serial")),
    ("megno_many", "threads", "workers", lambda: tb.megno_many("reduced", FIG4_BALL, [X0], 5.0, threads=1)[0].mean_megno,
     lambda: tb.megno_many("reduced", FIG4_BALL, [X0], 5.0, workers=1)[0].mean_megno),
    ("lyapunov_spectrum", "t", "t_end", lambda: tb.lyapunov_spectrum("reduced", FIG4_BALL, X0, t=2.0).exponents,
     lambda: tb.lyapunov_spectrum("reduced", FIG4_BALL, X0, t_end=2.0).exponents),
    ("lyapunov_spectra", "t", "t_end", lambda: tb.lyapunov_spectra("reduced", FIG4_BALL, [X0], t=2.0)[0].exponents,
     lambda: tb.lyapunov_spectra("reduced", FIG4_BALL, [X0], t_end=2.0)[0].exponents),
    ("lyapunov_spectra", "threads", "workers",
     lambda: tb.lyapunov_spectra("reduced", FIG4_BALL, [X0], 2.0, threads=1)[0].exponents,
     lambda: tb.lyapunov_spectra("reduced", FIG4_BALL, [X0], 2.0, workers=1)[0].exponents),
    ("gali", "t", "t_end", lambda: tb.gali("reduced", FIG4_BALL, X0, t=2.0).values,
     lambda: tb.gali("reduced", FIG4_BALL, X0, t_end=2.0).values),
    ("gali_many", "t", "t_end", lambda: tb.gali_many("reduced", FIG4_BALL, [X0], t=2.0)[0].values,
     lambda: tb.gali_many("reduced", FIG4_BALL, [X0], t_end=2.0)[0].values),
    ("gali_many", "threads", "workers", lambda: tb.gali_many("reduced", FIG4_BALL, [X0], 2.0, threads=1)[0].values,
     lambda: tb.gali_many("reduced", FIG4_BALL, [X0], 2.0, workers=1)[0].values),
    ("megno_map", "T", "t_end", lambda: tb.megno_map(FIG4_BALL, FIG4B_LEVELS, T=5.0, **GRID).values,
     lambda: tb.megno_map(FIG4_BALL, FIG4B_LEVELS, t_end=5.0, **GRID).values),
    ("megno_map", "threads", "workers",
     lambda: tb.megno_map(FIG4_BALL, FIG4B_LEVELS, t_end=5.0, threads=1, **GRID).values,
     lambda: tb.megno_map(FIG4_BALL, FIG4B_LEVELS, t_end=5.0, workers=1, **GRID).values),
    ("chaotic_fraction", "threads", "workers",
     lambda: tb.chaotic_fraction(FIG4_BALL, FIG4A_LEVELS, n=1, t_end=5.0, threads=1).mean_megno,
     lambda: tb.chaotic_fraction(FIG4_BALL, FIG4A_LEVELS, n=1, t_end=5.0, workers=1).mean_megno),
    ("poincare_sections", "threads", "workers",
     lambda: tb.poincare_sections("reduced", FIG4_BALL, [X0], n_points=2, threads=1)[0].points,
     lambda: tb.poincare_sections("reduced", FIG4_BALL, [X0], n_points=2, workers=1)[0].points),
    ("poincare_sections", "t_max", "t_end",
     lambda: tb.poincare_sections("reduced", FIG4_BALL, [X0], n_points=50, t_max=10.0)[0].times,
     lambda: tb.poincare_sections("reduced", FIG4_BALL, [X0], n_points=50, t_end=10.0)[0].times),
    ("poincare_section", "t_max", "t_end",
     lambda: tb.poincare_section("reduced", FIG4_BALL, X0, n_points=50, t_max=10.0).times,
     lambda: tb.poincare_section("reduced", FIG4_BALL, X0, n_points=50, t_end=10.0).times),
]


@pytest.mark.parametrize("func, old, new, with_old, with_new", CASES, ids=[f"{c[0]}-{c[1]}" for c in CASES])
def test_an_old_name_warns_and_gives_the_same_result(func, old, new, with_old, with_new):
    with pytest.warns(DeprecationWarning, match=rf"{func}\({old}=\.\.\.\) is deprecated: use {new}="):
        a = with_old()
    b = with_new()
    assert np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float), equal_nan=True)


def test_one_state_given_to_a_many_orbit_function_is_named():
    for f, one in ((tb.lyapunov_spectra, "lyapunov_spectrum"), (tb.gali_many, "gali"), (tb.megno_many, "megno")):
        with pytest.raises(tb.StateError, match=rf"states must have shape \(n, 9\).*got shape \(9,\).*use {one}"):
            f("reduced", FIG4_BALL, X0, 2.0)
        with pytest.raises(tb.StateError, match=r"shape \(n, 9\)"):
            f("reduced", FIG4_BALL, list(X0), 2.0)
