"""``taylorball explore`` in a real browser: headless Chromium from the operating system's
packages (``/usr/bin/chromium``, ``/usr/bin/chromedriver``) driven by Selenium.

The test starts the app on a free port, loads the page, clicks on the section chart,
waits for the orbit's crossings, checks them against ``tb.poincare_section`` of the same
state, changes Omega and checks the redrawn orbit the same way, waits for the MEGNO class,
keeps a screenshot, and types bad values into fields: the error appears next to the field
and the page keeps working.

Without Chromium (a developer's machine) the test is skipped; with
``TAYLORBALL_BROWSER_TEST=require`` (set by ``.ci/run``) a missing browser is a failure.
"""

from __future__ import annotations

import ast
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import taylorball as tb
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS

CHROMIUM, DRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"
REQUIRED = os.environ.get("TAYLORBALL_BROWSER_TEST", "") == "require"
EPS = np.finfo(float).eps

pytestmark = pytest.mark.long  # a browser


def _missing() -> str:
    missing = [p for p in (CHROMIUM, DRIVER) if not os.path.exists(p)]
    for mod in ("selenium", "bokeh"):
        try:
            __import__(mod)
        except ImportError:
            missing.append(f"the Python package {mod} (pip install -e '.[test,explore]')")
    return ", ".join(missing)


def _need_browser():
    why = _missing()
    if why:
        if REQUIRED:
            pytest.fail(f"TAYLORBALL_BROWSER_TEST=require but missing: {why}")
        pytest.skip(f"no browser test here: missing {why} (apt-get install chromium chromium-driver)")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def app():
    _need_browser()
    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "taylorball", "explore", "--no-browser", "--port", str(port)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    url = f"http://127.0.0.1:{port}/"
    import urllib.request

    deadline = time.monotonic() + 90
    while True:
        try:
            # a static file: cheap (a page view builds a document)
            with urllib.request.urlopen(url + "static/js/bokeh.min.js", timeout=30) as r:
                if r.status == 200:
                    break
        except OSError:
            pass
        if proc.poll() is not None or time.monotonic() > deadline:
            out = proc.stdout.read() if proc.poll() is not None else ""
            proc.kill()
            pytest.fail(f"taylorball explore did not serve {url}: {out}")
        time.sleep(0.3)
    yield url
    proc.terminate()
    try:
        proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()


@pytest.fixture(scope="module")
def browser():
    _need_browser()
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

    opts = Options()
    opts.binary_location = CHROMIUM
    for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1300"):
        opts.add_argument(a)
    # the driver's path is given, so Selenium Manager downloads nothing
    d = webdriver.Chrome(service=Service(DRIVER), options=opts)
    d.set_script_timeout(30)
    yield d
    d.quit()


JS_MODEL = "return Bokeh.documents[0].get_model_by_name(arguments[0])"


def _wait(browser, js, *args, timeout=60.0, what=""):
    deadline = time.monotonic() + timeout
    while True:
        try:
            v = browser.execute_script(js, *args)
        except Exception:
            v = None
        if v:
            return v
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting for {what or js}")
        time.sleep(0.1)


def _source(browser, name):
    return browser.execute_script(
        "const d = Bokeh.documents[0].get_model_by_name(arguments[0]).data;"
        "const o = {}; for (const k of ['x', 'y', 'l', 'c1', 'c2', 't', 'orbit', 'cls']) o[k] = Array.from(d[k]);"
        "return o;", name)


def _click_data(browser, x, y):
    """A real mouse click where the main chart shows the data point ``(x, y)``."""
    from selenium.webdriver.common.actions.action_builder import ActionBuilder

    pos = browser.execute_script(
        "const plot = Bokeh.documents[0].get_model_by_name('tb-main');"
        "const view = Bokeh.index.find_one(plot);"
        "const r = view.canvas_view.el.getBoundingClientRect();"
        "return [r.left + view.frame.x_scale.compute(arguments[0]), r.top + view.frame.y_scale.compute(arguments[1])];",
        x, y)
    ab = ActionBuilder(browser)
    ab.pointer_action.move_to_location(int(round(pos[0])), int(round(pos[1]))).click()
    ab.perform()


def _field(browser, name):
    """The <input> of a named TextInput (inside Bokeh's shadow DOM)."""
    return _wait(browser, """
        const m = Bokeh.documents[0].get_model_by_name(arguments[0]);
        const v = Bokeh.index.find_one(m);
        return v ? v.shadow_el.querySelector('input') : null;""", name, what=f"the field {name}")


def _type(browser, name, text):
    from selenium.webdriver.common.keys import Keys

    el = _field(browser, name)
    browser.execute_script("arguments[0].value = '';", el)  # then typed as a user types
    el.send_keys(text + Keys.ENTER)
    assert el.get_attribute("value") == text


def _text(browser, name):
    return browser.execute_script(JS_MODEL + ".text", name)


def _clicks(browser):
    """The chart points clicked, as the page's "copy as Python" box gives them."""
    browser.execute_script("""
        const m = Bokeh.documents[0].get_model_by_name('code-button');
        Bokeh.index.find_one(m).shadow_el.querySelector('button').click();""")
    code = _wait(browser, "const c = Bokeh.documents[0].get_model_by_name('code').value;"
                          "return c.includes('clicks = [(') ? c : null", what="the code box")
    line = next(ln for ln in code.splitlines() if ln.startswith("clicks = "))
    return ast.literal_eval(line.split("=", 1)[1].split("#")[0].strip()), code


def _check_against_package(src, point, params, n_check=5):
    """The orbit's points on screen (the l slab's) are ``tb.poincare_section``'s crossings."""
    x0 = tb.states_on_section(params, **FIG4A_LEVELS.as_kwargs(), point=point, direction=1)[0]
    ref = tb.poincare_section("reduced", params, x0, n_points=300)
    mine = [i for i, o in enumerate(src["orbit"]) if o == max(src["orbit"])]
    assert mine, "no points of the orbit on screen"
    for i in mine[:n_check]:
        k = int(np.argmin(np.abs(ref.times - src["t"][i])))
        # the same code path and chunks: equal to the last bit, up to the JSON transport (exact)
        assert abs(ref.times[k] - src["t"][i]) <= 4 * EPS * ref.times[k]
        assert np.allclose(ref.points[k], [src["l"][i], src["c1"][i], src["c2"][i]], rtol=4 * EPS, atol=4 * EPS)
    return len(mine)


def test_click_orbit_slider_screenshot_and_bad_fields(app, browser, tmp_path):
    browser.get(app)
    _wait(browser, "return !!(window.Bokeh && Bokeh.documents.length && "
                   "Bokeh.documents[0].get_model_by_name('tb-main') && Bokeh.index.find_one("
                   "Bokeh.documents[0].get_model_by_name('tb-main')))", what="the page")
    # the admissible region is drawn
    assert _wait(browser, "return Bokeh.documents[0].get_model_by_name('tb-main').renderers[0]"
                          ".data_source.data.image.length", what="the admissible region") == 1

    # a click in the admissible region (the Fig. 4a preset's point (l, r1, r2) = (2, 2.5, 1), slab l = 2)
    _click_data(browser, 2.5, 1.0)
    _wait(browser, JS_MODEL + ".data.x.length > 0", "points", timeout=120, what="the first crossings")
    status = _text(browser, "status")
    assert "first crossings on screen" in status or "integrating" in status, status
    clicks, code = _clicks(browser)
    click = clicks[0][0]
    assert click[0] == 2.0 and abs(click[1] - 2.5) < 0.2 and abs(click[2] - 1.0) < 0.2
    _wait(browser, JS_MODEL + ".data.x.length >= 5", "points", timeout=120, what="five crossings in the slab")
    n = _check_against_package(_source(browser, "points"), click, FIG4_BALL)
    assert n >= 5
    # the user's section (gamma3 = 0) is drawn too
    _wait(browser, JS_MODEL + ".data.x.length > 0", "user-points", timeout=120, what="the user section's points")
    # its MEGNO class arrives and colours the orbit
    _wait(browser, "return Bokeh.documents[0].get_model_by_name('points').data.cls.some(c => c !== 'pending')",
          timeout=180, what="the MEGNO class")
    assert "tb.poincare_sections(prob, states" in code

    # a field: Omega 2 -> 1.9 redraws the same click at the new plane rate
    first = max(_source(browser, "points")["orbit"])
    _type(browser, "field-omega", "1.9")
    _wait(browser, "const d = Bokeh.documents[0].get_model_by_name('points').data;"
                   "return d.x.length >= 3 && Array.from(d.orbit).every(o => o > arguments[0])", first,
          timeout=120, what="the redrawn orbit")
    ball19 = tb.BallParams(inertia=FIG4_BALL.inertia, mass=FIG4_BALL.mass, radius=FIG4_BALL.radius, plane_rate=1.9)
    _check_against_package(_source(browser, "points"), click, ball19)
    shot = tmp_path / "explore.png"
    browser.save_screenshot(str(shot))
    keep = os.environ.get("TAYLORBALL_TEST_ARTEFACTS")
    if keep:
        Path(keep).mkdir(parents=True, exist_ok=True)
        shutil.copy(shot, Path(keep) / "explore.png")
    assert shot.stat().st_size > 10_000

    # bad values: the package's message beside the field, the page alive
    _type(browser, "field-lv1", "ten")
    assert "must be a number" in _wait(browser, JS_MODEL + ".text", "error-lv1", what="the error of G")
    _type(browser, "field-lv1", "10.0")
    _wait(browser, "return " + JS_MODEL.replace("return ", "") + ".text === ''", "error-lv1", what="the error cleared")
    _type(browser, "field-lv2", "20")  # |H| > G: no such level
    assert "|M_gamma| <= C" in _wait(browser, JS_MODEL + ".text", "error-lv2", what="the error of H")
    _type(browser, "field-event", "gamma3 +* 2")
    assert "does not parse" in _wait(browser, JS_MODEL + ".text", "error-event", what="the error of the event")
    _type(browser, "field-event", "gamma3")
    _type(browser, "field-lv2", "2.0")
    _wait(browser, "return " + JS_MODEL.replace("return ", "") + ".text === ''", "error-lv2", what="H accepted")
    # still alive: a new click gives a new orbit
    before = browser.execute_script(JS_MODEL + ".data.x.length", "points")
    _click_data(browser, 2.0, 0.5)
    _wait(browser, JS_MODEL + ".data.x.length > arguments[1]", "points", before, timeout=120,
          what="an orbit after the bad values")
    # a level slider (debounced): H to 3, the field follows and the orbits are redrawn on the new level
    shown = _source(browser, "points")["orbit"]
    last = max(shown) if shown else -1
    browser.execute_script("const s = Bokeh.documents[0].get_model_by_name('slider-lv2');"
                           "s.value = 2.5; s.value = 3.0;")  # two moves within the debounce: one redraw
    _wait(browser, "return Bokeh.documents[0].get_model_by_name('field-lv2').value === '3.0'", timeout=60,
          what="H set by its slider")
    _wait(browser, "const d = Bokeh.documents[0].get_model_by_name('points').data;"
                   "return d.x.length > 0 && Array.from(d.orbit).every(o => o > arguments[0])", last,
          timeout=120, what="the orbits on the slider's level")
    assert _text(browser, "error-lv2") == ""
