"""``taylorball explore``: click-to-first-points latency and the memory of the app with
100 orbits, measured in headless Chromium (the browser test's set-up).

The app is started as ``taylorball explore --no-browser --port P`` (its own process, whose
resident memory is read from ``/proc/PID/status``), on the Fig. 4a preset (reduced system,
300 crossings of g = 0 and 300 of gamma3 = 0 per orbit, MEGNO to t = 200); after a
warm-up click, ``--clicks`` (default 100) real mouse clicks land on admissible points of
the l = 2 slab (cells of the admissible region drawn on the page). Latency of a click =
from the click's return in Selenium (clicks 0.5 s apart: closer ones are a double tap) to the page showing "orbit k: first crossings on
screen" (the status line the page updates when the orbit's first chunk of crossings has
been streamed to it), polled every 5 ms in the browser; the app's own part is the time that
status line reports (from the server's tap handler to the first chunk streamed). Memory: the app's VmRSS before
the first page view, after the page is built, and once all orbits are done (with their
crossings on the page).

``--cold`` measures the first click instead (on the ``--preset`` chosen in the page, after
``--wait`` seconds): the time to its first crossings and to its MEGNO colour; run it with
an empty compile cache (``HOME=$(mktemp -d)``) to see what a first session sees.

Run: ``python benchmarks/bench_explore.py [--clicks 100] [--preset fig4a] [--cold] [--wait 20]``
(needs /usr/bin/chromium, /usr/bin/chromedriver, the explore extra and selenium).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def cold(b, view, pid: int) -> None:
    """The first click of the session on ``view``'s preset point: crossings, then colour."""
    import test_explore_browser as T

    from taylorball.explore.engine import PRESETS

    p = PRESETS[view.preset].point
    x, y = (p[1], p[2]) if view.kind == "reduced" else (p[0], p[1])
    cpu0 = _cpu(pid)
    T._click_data(b, float(x), float(y))
    t0 = time.perf_counter()
    T._wait(b, "return Bokeh.documents[0].get_model_by_name('points').data.x.length > 0", timeout=600,
            what="the first crossings")
    t1 = time.perf_counter()
    T._wait(b, "return Bokeh.documents[0].get_model_by_name('points').data.cls.some(c => c !== 'pending')",
            timeout=600, what="the MEGNO colour")
    t2 = time.perf_counter()
    code = T._clicks(b)[1]
    print(f"{view.preset}, first click: first crossings after {t1 - t0:.2f} s, MEGNO colour after {t2 - t0:.2f} s "
          f"(compact mode: {'compact = [True' in code}); app CPU {_cpu(pid) - cpu0:.1f} s meanwhile (children "
          f"not counted); load average {os.getloadavg()}")


def _cpu(pid: int) -> float:
    f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


def main() -> None:
    import test_explore_browser as T
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

    from taylorball.explore.engine import View, admissible_grid

    ap = argparse.ArgumentParser()
    ap.add_argument("--clicks", type=int, default=100)
    ap.add_argument("--preset", default="fig4a", help="the preset chosen in the page before clicking")
    ap.add_argument("--cold", action="store_true", help="time the first click (crossings and colour) only")
    ap.add_argument("--wait", type=float, default=20.0, help="seconds between the server's start and the page view")
    ap.add_argument("--server-python", default=sys.executable,
                    help="the Python that runs the app (another checkout's, to compare two versions in one run)")
    args = ap.parse_args()
    port = T._free_port()
    proc = subprocess.Popen([args.server_python, "-m", "taylorball", "explore", "--no-browser", "--port", str(port), "-q"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        import urllib.request

        for _ in range(300):
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{port}/static/js/bokeh.min.js", timeout=30)
                break
            except OSError:
                time.sleep(0.3)
        time.sleep(args.wait)  # the warm-up compile (section integrators, MEGNO's tangent system)
        rss0 = rss_mb(proc.pid)
        opts = Options()
        opts.binary_location = T.CHROMIUM
        for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1300"):
            opts.add_argument(a)
        b = webdriver.Chrome(service=Service(T.DRIVER), options=opts)
        b.get(f"http://127.0.0.1:{port}/")
        T._wait(b, "return !!(window.Bokeh && Bokeh.documents.length && Bokeh.index.find_one("
                   "Bokeh.documents[0].get_model_by_name('tb-main')))", what="the page")
        rss1 = rss_mb(proc.pid)
        if args.preset != "fig4a":
            b.execute_script("Bokeh.documents[0].get_model_by_name('preset').value = arguments[0]", args.preset)
            T._wait(b, "return Bokeh.documents[0].get_model_by_name('tb-main').renderers[0].data_source.data"
                       ".image.length === 1 && Bokeh.documents[0].get_model_by_name('field-lv1').value === "
                       "arguments[0]", repr(float(View(preset=args.preset).level.as_kwargs()["lam" if args.preset ==
                                                                                              "fig1" else "C"])),
                    timeout=300, what="the preset")
        if args.cold:
            cold(b, View(preset=args.preset), proc.pid)
            b.quit()
            return
        g = admissible_grid(View(), 2.0, n=64)
        xs = np.linspace(g["x"][0], g["x"][1], 64)
        ys = np.linspace(g["y"][0], g["y"][1], 64)
        cells = [(xs[j], ys[i]) for i, j in zip(*np.nonzero(g["mask"]))]
        # inner cells only (a click lands within half a cell of its target)
        rng = np.random.default_rng(0)
        pick = [cells[k] for k in rng.choice(len(cells), size=args.clicks + 1, replace=len(cells) <= args.clicks)]
        lat: list = []
        server: list = []
        status_js = "return Bokeh.documents[0].get_model_by_name('status').text"
        last = -1
        for k, (x, y) in enumerate(pick):
            time.sleep(0.5)  # clicks closer than ~0.3 s are a double tap to the browser, not two taps
            T._click_data(b, float(x), float(y))
            t0 = time.perf_counter()
            while True:
                text = b.execute_script(status_js)
                if text.startswith("orbit ") and "first crossings" in text and int(text.split()[1][:-1]) > last:
                    last = int(text.split()[1][:-1])
                    if k:  # the first click is the warm-up
                        lat.append(time.perf_counter() - t0)
                        # the app's own part: from its tap handler to its first streamed chunk
                        server.append(float(text.split("on screen ")[1].split(" ms")[0]) / 1e3)
                    break
                if text.startswith("No orbit") or time.perf_counter() - t0 > 60:
                    print(f"click {k}: no orbit ({text})")
                    break
                time.sleep(0.005)
        cpu0 = time.time()
        T._wait(b, "return Bokeh.documents[0].get_model_by_name('readout').text.includes('pending 0')",
                timeout=3600, what="all orbits classified")
        rss2 = rss_mb(proc.pid)
        n_pts = b.execute_script("return Bokeh.documents[0].get_model_by_name('user-points').data.x.length")
        b.quit()
        print(f"clicks: {len(lat)} warm (+1 warm-up), load average {os.getloadavg()}")
        print(f"click-to-first-points latency: median {statistics.median(lat) * 1e3:.0f} ms, "
              f"90th percentile {np.percentile(lat, 90) * 1e3:.0f} ms, max {max(lat) * 1e3:.0f} ms; the app's part "
              f"(tap handler to first chunk streamed): median {statistics.median(server) * 1e3:.0f} ms, 90th "
              f"percentile {np.percentile(server, 90) * 1e3:.0f} ms")
        print(f"app memory (VmRSS): {rss0:.0f} MB idle, {rss1:.0f} MB with the page, {rss2:.0f} MB with "
              f"{len(pick)} orbits done ({n_pts} crossings of gamma3 = 0 on the page); waited "
              f"{time.time() - cpu0:.0f} s after the last click")
    finally:
        proc.terminate()
        proc.wait(timeout=30)


if __name__ == "__main__":
    main()
