"""``taylorball explore`` without a browser: event text, the code of "copy as Python"
(run here: it reproduces the orbits the page computed, bit for bit), the worker pool
(streaming, cancelling, errors) and the colour scheme."""

import time

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


def _wait_runner(runner, timeout=300):
    _, token, res = runner.events.get(timeout=timeout)
    return token, res


def test_periodic_orbit_from_a_click_is_the_package_call_bit_for_bit():
    """Newton in the page's child process gives the bits of a direct ``tb.periodic_orbit``
    (Fig. 1 level, the saddle near the chart point (0, 0)); the page draws its points with
    the stability's marker and colour."""
    from taylorball.explore.skeleton import MARKERS, SkeletonRunner, point_rows
    from taylorball.palette import STABILITY_COLORS

    view = engine.View(preset="fig1")
    x = engine.start_states(view, (0.0, 0.0))[0]
    runner = SkeletonRunner()
    token = runner.start(("newton", (view.kind, view.params, view.level, x, 1)))
    got_token, res = _wait_runner(runner)
    assert got_token == token and not res.error, res
    direct = tb.periodic_orbit(view.kind, view.params, x, 1, levels=view.level)
    (o,) = res.orbits
    assert np.array_equal(o.points, direct.points) and np.array_equal(o.state, direct.state)
    assert o.period == direct.period and np.array_equal(o.multipliers, direct.multipliers)
    assert o.residual == direct.residual and o.stability == direct.stability == "hyperbolic"
    rows = point_rows([o], "mparallel")
    assert rows["x"] == [float(p[0]) for p in direct.points] and rows["y"] == [float(p[1]) for p in direct.points]
    assert rows["marker"] == [MARKERS["hyperbolic"]] and rows["color"] == [STABILITY_COLORS["hyperbolic"]]
    # a guess off the level: the package's error, reported (no orbit, no dead runner)
    runner.start(("newton", (view.kind, view.params, tb.MParallelLevels(lam=2.0, h=50.0), x, 1)))
    _, bad = _wait_runner(runner)
    assert bad.orbits == () and "StateError" in bad.error and "off the level" in bad.error
    runner.shutdown()


def test_a_search_is_cancelled_by_killing_its_process():
    from taylorball.explore.skeleton import SkeletonRunner

    view = engine.View(preset="fig4b")
    runner = SkeletonRunner()
    token = runner.start(("search", (view.kind, view.params, view.level, 2, {})))  # minutes of work
    assert runner.running
    assert runner.cancel() and not runner.running
    got_token, res = _wait_runner(runner, timeout=60)
    assert got_token == token and res is None
    with pytest.raises(tb.UsageError, match="job must be"):
        runner.start(("shell", ()))


@pytest.mark.long
def test_the_page_without_a_browser_levels_sliders_and_periodic_orbits():
    """The page built server-side: slider ranges, an empty level's message beside h, a
    Newton click drawing the package's periodic orbit, and the plain "none found"."""
    from bokeh.document import Document

    from taylorball.explore.app import make_document
    from taylorball.explore.skeleton import SearchResult

    doc = Document()
    make_document(doc)
    st = doc.taylorball_explore
    w, act = st["widgets"], st["actions"]
    g, h_, e = w["sliders"]
    assert (g.value, h_.value, e.value) == (10.0, 2.0, 5.0) and (h_.start, h_.end) == (-10.0, 10.0)  # |H| <= G
    doc.get_model_by_name("field-lv3").value = "50.0"  # above every energy of G = 10, H = 2 on g = 0
    assert w["lv3_err"].text.startswith("empty level: G = 10.0, H = 2.0, h = 50.0"), w["lv3_err"].text
    assert "lower h" in w["lv3_err"].text and "The level is empty" in doc.get_model_by_name("status").text
    doc.get_model_by_name("field-lv3").value = "5.0"
    assert w["lv3_err"].text == ""
    # the search's answer when it found nothing: said plainly
    st["skeleton"] = 10 ** 6
    st["runner"].events.put(("skeleton", 10 ** 6, SearchResult("search", (), seeds=20, failures=20)))
    act["poll"]()
    assert "No periodic orbit found" in w["po_status"].text and "20 seeds" in w["po_status"].text
    # Fig. 1, Newton from (0, 0): the saddle, the bits of tb.periodic_orbit on the chart
    doc.get_model_by_name("preset").value = "fig1"
    view = st["view"]
    assert view.preset == "fig1"
    act["newton"]((0.0, 0.0))
    deadline = time.monotonic() + 300
    while st["skeleton"] is not None and time.monotonic() < deadline:
        time.sleep(0.2)
        act["poll"]()
    assert "1 periodic orbit(s) found" in w["po_status"].text, w["po_status"].text
    x = engine.start_states(view, (0.0, 0.0))[0]
    direct = tb.periodic_orbit("mparallel", view.params, x, 1, levels=view.level)
    data = w["periodic"].data
    assert list(data["x"]) == [float(p[0]) for p in direct.points]
    assert list(data["y"]) == [float(p[1]) for p in direct.points]
    assert list(data["period"]) == [direct.period] and list(data["stability"]) == ["hyperbolic"]
    st["runner"].shutdown()
    st["pool"].shutdown()


@pytest.mark.filterwarnings("ignore::taylorball.params.UnphysicalParametersWarning")  # Fig. 1's a, d (by design)
def test_megno_in_compact_mode_until_the_default_compile_is_ready():
    """On a cold cache the M||gamma MEGNO integrator (default mode) takes tens of seconds to
    compile: until it is ready the pool classifies with compact mode, and "copy as Python"
    writes that call (the same bits)."""
    assert "mparallel" not in engine.MEGNO_READY  # nothing warmed it in this process
    view = engine.View(preset="fig1", n_points=5, megno_t_end=20.0)
    pool = engine.OrbitPool(workers=1)
    p = engine.PRESETS["fig1"].point
    pool.submit(view, p, engine.start_states(view, p)[0])
    _run(pool)
    (o,) = pool.orbits
    assert o.status == "done" and o.compact, o.message
    ns: dict = {}
    exec(compile(engine.python_code(view, pool.orbits), "<copy as Python>", "exec"), ns)
    assert ns["compact"] == [True] and ns["mean_Y"] == [o.mean_Y]
    pool.shutdown()
