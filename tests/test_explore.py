"""``taylorball explore`` without a browser: event text, the code of "copy as Python"
(run here: it reproduces the orbits the page computed, bit for bit), the worker pool
(streaming, cancelling, errors) and the colour scheme."""

import heyoka as hy
import numpy as np
import pytest

import taylorball as tb
from taylorball.palette import CHAOTIC_MEGNO, COLORS, color_of, megno_class

engine = pytest.importorskip("taylorball.explore.engine")


def test_event_text_is_parsed_never_evaluated():
    e = engine.parse_event("reduced", "R1 - 0.5*omega2 + sin(gamma3)**2")
    R1, w2, g3 = hy.make_vars("R1", "omega2", "gamma3")
    assert str(e) == str(R1 - hy.expression(0.5) * w2 + hy.sin(g3) ** hy.expression(2.0))
    for bad, needle in [("gamma9", "'gamma9' is not a variable"), ("__import__('os')", "is not allowed"),
                        ("R1 +* 2", "does not parse"), ("", "empty field"), ("R1.real", "is not allowed")]:
        with pytest.raises(tb.UsageError, match="event must be an expression in omega1") as err:
            engine.parse_event("reduced", bad)
        assert needle in str(err.value)
    with pytest.raises(tb.UsageError, match="Omega must be a number, got 'x'"):
        engine.parse_number("Omega", "x")


def _run(pool):
    """Everything the pool reports until every orbit has ended."""
    out, ended = [], 0
    while ended < len(pool.orbits):
        ev = pool.events.get(timeout=120)
        out.append(ev)
        ended += ev[0] == "end"
    return out


def test_copy_as_python_reproduces_the_orbits_on_screen():
    view = engine.View(preset="fig4a", n_points=20, megno_t_end=20.0, event="R1 - 0.5*omega2", chart=("R1", "omega2"),
                       direction=0)
    pool = engine.OrbitPool(workers=2)
    points = [(2.0, 2.5, 1.0), (2.0, 1.0, -2.0)]
    for p in points:
        pool.submit(view, p, engine.start_states(view, p)[0])
    events = _run(pool)
    assert all(o.status == "done" for o in pool.orbits), [o.message for o in pool.orbits]
    shown = {(o.id, k): [] for o in pool.orbits for k in (0, 1)}
    for ev in events:
        if ev[0] == "points":
            shown[(ev[1].id, ev[2])].append(ev[4])
    code = engine.python_code(view, pool.orbits)
    ns: dict = {}
    exec(compile(code, "<copy as Python>", "exec"), ns)
    for o in pool.orbits:
        assert np.array_equal(np.concatenate(shown[(o.id, 0)]), ns["paper"][o.id].points)
        assert np.array_equal(np.concatenate(shown[(o.id, 1)]), ns["user"][o.id].points)
        assert ns["mean_Y"][o.id] == o.mean_Y and o.cls == megno_class(o.mean_Y)
    pool.shutdown()


def test_the_pool_cancels_and_reports_errors():
    view = engine.View(preset="fig4b", n_points=200_000, megno_t_end=20.0, event=None)
    pool = engine.OrbitPool(workers=1)
    p = engine.PRESETS["fig4b"].point
    o = pool.submit(view, p, engine.start_states(view, p)[0])
    ev = pool.events.get(timeout=120)  # the first chunk's crossings
    assert ev[0] == "points" and ev[1] is o
    pool.cancel_all()
    while ev[0] != "end":
        ev = pool.events.get(timeout=120)
    assert o.status == "cancelled"
    bad = pool.submit(view, p, np.full(9, np.nan))
    while True:
        ev = pool.events.get(timeout=120)
        if ev[0] == "end" and ev[1] is bad:
            break
    assert bad.status == "error" and "StateError" in bad.message
    pool.shutdown()


def test_start_states_and_the_admissible_region_of_each_system():
    for key in ("fig1", "fig2"):
        view = engine.View(preset=key)
        xs = engine.start_states(view, engine.PRESETS[key].point)
        assert len(xs) >= 1
        g = engine.admissible_grid(view, 2.0, n=16)
        # Fig. 1's level meets every (l, L/G) of the section; Fig. 2's a bounded part of (r1, r2)
        assert g["mask"].all() if key == "fig1" else (g["mask"].any() and not g["mask"].all())
    with pytest.raises(tb.EmptyLevelError):
        engine.start_states(engine.View(preset="fig4a"), (2.0, 500.0, 500.0))


def test_one_colour_scheme():
    assert megno_class(None) == "pending" and megno_class(float("nan")) == "pending"
    assert megno_class(CHAOTIC_MEGNO) == "regular" and megno_class(CHAOTIC_MEGNO + 1e-9) == "chaotic"
    assert color_of(2.0) == COLORS["regular"] and color_of(20.0) == COLORS["chaotic"]
