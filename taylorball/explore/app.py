"""The web page of ``taylorball explore``: a Bokeh document per browser tab.

The page's widgets set a :class:`~taylorball.explore.engine.View`; a tap on the section
chart becomes initial states (:func:`~taylorball.explore.engine.start_states`), whose
orbits an :class:`~taylorball.explore.engine.OrbitPool` integrates in worker threads. A
periodic callback of the document (every :data:`POLL_MS`) takes what the workers found
and streams it to the plots: Bokeh models are only ever touched from the document's own
thread. A field's bad value shows the package's error message next to the field; the
page keeps working.
"""

from __future__ import annotations

import math
import os
import time
from typing import Any, Dict, List, Tuple

import numpy as np

from ..errors import TaylorballError
from ..levels import Levels, MParallelLevels
from ..model import PUBLIC_NAMES
from ..palette import COLORS, STABILITY_COLORS, megno_class
from .engine import PRESETS, OrbitPool, View, admissible_grid, axis_names, level_is_empty, level_ranges, \
    parse_event, parse_number, python_code, start_states
from .skeleton import SEARCH_OPTIONS, SkeletonRunner, point_rows

__all__ = ["make_document", "POLL_MS"]

#: How often the page takes new crossings from the workers (ms).
POLL_MS = 40

#: A level slider applies its value this long after it stopped moving (ms).
DEBOUNCE_MS = 300

_CSV_JS = """
const d = source.data;
const cols = Object.keys(d).filter(k => k !== 'color' && k !== 'state');
let rows = [cols.join(',')];
for (let i = 0; i < d['x'].length; i++) rows.push(cols.map(c => d[c][i]).join(','));
const blob = new Blob([rows.join('\\n') + '\\n'], {type: 'text/csv'});
const a = document.createElement('a');
a.href = URL.createObjectURL(blob); a.download = 'taylorball_points.csv';
document.body.appendChild(a); a.click(); a.remove();
"""

_COLUMNS = ("x", "y", "l", "c1", "c2", "t", "orbit", "color", "cls", "mean_Y", "I1", "I2", "I3", "state")


def _empty() -> Dict[str, list]:
    return {k: [] for k in _COLUMNS}


def make_document(doc: Any) -> None:
    """Build the explorer in the Bokeh document ``doc`` (one per browser tab)."""
    from bokeh.layouts import column, row
    from bokeh.models import (Button, ColumnDataSource, CustomJS, Div, HoverTool, Select, Slider, TapTool,
                              TextAreaInput, TextInput)
    from bokeh.plotting import figure

    runner = SkeletonRunner()
    pool = OrbitPool(workers=max(2, min(4, os.cpu_count() or 1)), megno_workers=max(1, (os.cpu_count() or 2) // 2),
                     notify=lambda: doc.add_next_tick_callback(poll))  # thread-safe: Bokeh's way from threads
    state: Dict[str, Any] = {"view": View(), "rows": _empty(), "user_rows": _empty(), "l0": 2.0, "dl": 0.4,
                             "clicked": None, "timers": {}, "skeleton": None, "found": []}

    # ---- widgets ------------------------------------------------------------------
    preset = Select(title="System and ball (the paper's figures)", value="fig4a",
                    options=[(k, p.label) for k, p in PRESETS.items()], width=330, name="preset")

    def field(name: str, title: str, value: str) -> tuple:
        w = TextInput(title=title, value=value, width=120, name=f"field-{name}")
        err = Div(text="", width=210, styles={"color": "#b00020"}, name=f"error-{name}")
        return w, err

    omega, omega_err = field("omega", "Omega (plane rate)", "")
    lv1, lv1_err = field("lv1", "G = |M|", "")
    lv2, lv2_err = field("lv2", "H = (M, gamma)", "")
    lv3, lv3_err = field("lv3", "h = E", "")
    npts, npts_err = field("npts", "crossings per orbit", "300")
    megno_t, megno_err = field("megno", "MEGNO time", "200")
    omega_slider = Slider(title="Omega", start=0.0, end=4.0, step=0.05, value=2.0, width=330, name="omega-slider")
    slab = Slider(title="l slab centre", start=0.0, end=round(2 * math.pi, 3), step=0.05, value=2.0, width=330,
                  name="slab")
    slab_w = Slider(title="l slab width", start=0.02, end=round(2 * math.pi, 3), step=0.02, value=0.4, width=330,
                    name="slab-width")
    lv_sliders = [Slider(title=t, start=0.0, end=1.0, step=0.01, value=0.5, width=330, name=f"slider-{n}")
                  for n, t in (("lv1", "G"), ("lv2", "H"), ("lv3", "h"))]
    po_k, po_k_err = field("po-k", "periodic orbits: k max", "1")
    po_find = Button(label="Find periodic orbits", width=160, name="po-find")
    po_cancel = Button(label="Cancel search", width=120, name="po-cancel")
    click_mode = Select(title="a click starts", value="orbit", width=330, name="click-mode",
                        options=[("orbit", "an orbit (its crossings)"),
                                 ("newton", "Newton: a periodic orbit (k = k max) from the point")])
    po_status = Div(text="", width=330, name="po-status")
    sheet = Select(title="sheet: root K of the energy equation a click takes", value="0",
                   options=["0", "1", "2", "3"], width=330, name="sheet")
    event, event_err = field("event", "your section: f = 0 (empty: none)", "gamma3")
    event.width = 200
    chart_in, chart_err = field("chart", "its chart (two names)", "R1, R2")
    direction = Select(title="direction", value="+1", options=["+1", "-1", "0"], width=80, name="direction")
    status = Div(text="Click on the section to start an orbit.", width=700, name="status")
    readout = Div(text="", width=700, name="readout")
    stop = Button(label="Stop all", width=100, name="stop")
    clear = Button(label="Clear", width=100, name="clear")
    csv = Button(label="CSV of points", width=120, name="csv")
    code_btn = Button(label="Copy as Python", width=130, name="code-button")
    code = TextAreaInput(title="taylorball code of this view", value="", rows=14, cols=90, width=700,
                         name="code")

    # ---- plots ---------------------------------------------------------------------
    src = ColumnDataSource(_empty(), name="points")
    usrc = ColumnDataSource(_empty(), name="user-points")
    region = ColumnDataSource({"image": [], "x": [], "y": [], "dw": [], "dh": []})
    psrc = ColumnDataSource(point_rows([], "reduced"), name="periodic-points")
    tips = [("orbit", "@orbit"), ("t", "@t{0.000000}"), ("l", "@l{0.000000}"), ("chart", "(@c1{0.000000}, @c2{0.000000})"),
            ("integrals", "@I1{0.0000000000}, @I2{0.0000000000}, @I3{0.0000000000}"), ("<Y>", "@mean_Y{0.00} (@cls)"),
            ("state", "@state")]
    main = figure(width=560, height=520, tools="pan,wheel_zoom,box_zoom,reset,save,tap",
                  name="tb-main", title="the paper's section g = 0", output_backend="canvas")
    main.image(image="image", x="x", y="y", dw="dw", dh="dh", source=region, palette=["#ffffff", "#e6eef7"],
               level="image")
    pts = main.scatter("x", "y", source=src, size=3, color="color", line_color=None)
    main.add_tools(HoverTool(renderers=[pts], tooltips=tips))
    from bokeh.core.properties import field as column_of

    porb = main.scatter("x", "y", source=psrc, marker=column_of("marker"), size=13, line_width=2.5,
                        line_color="color", fill_color="color", fill_alpha=0.25)
    main.add_tools(HoverTool(renderers=[porb], tooltips=[
        ("periodic orbit", "@orbit: k = @k, @stability (@type)"), ("period", "@period{0.000000000000}"),
        ("multipliers", "@multipliers"), ("residual", "@residual{%.1e}"), ("l", "@l{0.000000}")],
        formatters={"@residual": "printf"}))
    main.select_one(TapTool).renderers = []
    user = figure(width=420, height=420, tools="pan,wheel_zoom,box_zoom,reset,save", name="tb-user",
                  title="your section")
    upts = user.scatter("x", "y", source=usrc, size=3, color="color", line_color=None)
    user.add_tools(HoverTool(renderers=[upts], tooltips=tips))
    csv.js_on_click(CustomJS(args={"source": src}, code=_CSV_JS))

    # ---- reading the fields ---------------------------------------------------------
    def read_view() -> View:
        """The view from the fields; each bad field shows its error and raises."""
        v: View = state["view"]
        kind = PRESETS[preset.value].kind
        errors = []

        def take(widget, err, fn) -> Any:
            try:
                out = fn(widget.value)
                err.text = ""
                return out
            except TaylorballError as e:
                err.text = str(e)
                errors.append(e)
                return None

        om = take(omega, omega_err, lambda s: parse_number("Omega", s))
        a = take(lv1, lv1_err, lambda s: parse_number(lv1.title.split(" ")[0], s))
        b = take(lv2, lv2_err, lambda s: parse_number(lv2.title.split(" ")[0], s))
        c = take(lv3, lv3_err, lambda s: parse_number("h", s)) if kind == "reduced" else None
        n = take(npts, npts_err, lambda s: parse_number("crossings per orbit", s, lo=1, integer=True))
        T = take(megno_t, megno_err, lambda s: parse_number("MEGNO time", s, lo=2.0))
        ev = take(event, event_err, lambda s: (parse_event(kind, s), s.strip())[1] if s.strip() else None)
        ch = take(chart_in, chart_err, lambda s: _chart(kind, s))
        if errors:
            raise errors[0]
        try:
            # a, b, c are floats here (a bad field raised above)
            levels: Any = (Levels.from_caption(G=float(a), H=float(b), h=float(c)) if kind == "reduced"  # type: ignore[arg-type]
                           else MParallelLevels(lam=float(a), h=float(b)))
        except TaylorballError as e:
            lv2_err.text = str(e)
            raise
        nv = v.with_(preset=preset.value, omega=om, levels=levels, n_points=int(n), megno_t_end=float(T),
                     event=ev, chart=ch, direction=int(direction.value), sheet=int(sheet.value))
        try:
            nv.params  # a bad Omega for this system
            if ev:
                nv.sections()
        except TaylorballError as e:
            (event_err if ev else omega_err).text = str(e)
            raise
        return nv

    def _chart(kind, s):
        names = tuple(x.strip() for x in s.replace(";", ",").split(",") if x.strip())
        valid = PUBLIC_NAMES[kind]
        if len(names) != 2 or any(n not in valid for n in names):
            from ..errors import UsageError

            raise UsageError(f"chart must be two names among {', '.join(valid)}, got {s!r}")
        return names

    # ---- drawing --------------------------------------------------------------------
    def fill_fields(key: str) -> None:
        state["filling"] = True
        try:
            _fill(key)
        finally:
            state["filling"] = False

    def _fill(key: str) -> None:
        p = PRESETS[key]
        lv = p.levels
        om = p.params.plane_rate
        omega.value = repr(float(om))
        omega_slider.value = float(om)
        if p.kind == "reduced":
            lv1.title, lv2.title, lv3.title = "G = |M|", "H = (M, gamma)", "h = E"
            lv1.value, lv2.value, lv3.value = repr(lv.C), repr(lv.M_gamma), repr(lv.h)
            lv3.visible = slab.visible = slab_w.visible = sheet.visible = True
            event.value, chart_in.value = "gamma3", "R1, R2"
        else:
            lv1.title, lv2.title = "lam = (K, gamma)", "h = Etilde"
            lv1.value, lv2.value = repr(lv.lam), repr(lv.h)
            lv3.visible = slab.visible = slab_w.visible = False
            sheet.visible = True
            event.value, chart_in.value = "gamma3", "K1, K2"
        x, y = axis_names(p.kind)
        main.xaxis.axis_label, main.yaxis.axis_label = x, y
        set_sliders(View(preset=key), (lv.C, lv.M_gamma, lv.h) if p.kind == "reduced" else (lv.lam, lv.h))

    def set_sliders(v: View, values) -> None:
        """The level sliders' ranges for ``v`` and their values (a value outside widens the range)."""
        lv3_s = lv_sliders[2]
        lv3_s.visible = v.kind == "reduced"
        for s_, (name, lo, hi, step), x in zip(lv_sliders, level_ranges(v), values):
            x = float(x)
            s_.title = name
            s_.start, s_.end, s_.step = min(lo, x), max(hi, x), step
            s_.value = x

    def draw_region() -> Any:
        """Draw the admissible region; the message of an empty level (or slab), else None."""
        v: View = state["view"]
        try:
            g = admissible_grid(v, state["l0"])
        except TaylorballError as e:
            status.text = f"admissible region: {e}"
            return str(e)
        m = g["mask"].astype(float)
        region.data = {"image": [m], "x": [g["x"][0]], "y": [g["y"][0]], "dw": [g["x"][1] - g["x"][0]],
                       "dh": [g["y"][1] - g["y"][0]]}
        return level_is_empty(v, g)

    def draw_found() -> None:
        """The periodic orbits found, in the l slab on screen (reduced) or all (M||gamma)."""
        v: View = state["view"]
        rows = point_rows(state["found"], v.kind)
        if v.kind == "reduced":
            l = np.asarray(rows["l"], dtype=float)
            d = np.abs((l - state["l0"] + math.pi) % (2 * math.pi) - math.pi)
            keep = np.flatnonzero(d <= state["dl"] / 2)
            rows = {k: [c[i] for i in keep] for k, c in rows.items()}
        psrc.data = rows

    def start_skeleton(job: tuple, what: str) -> None:
        state["skeleton"] = runner.start(job)
        state["skeleton_t0"] = time.perf_counter()
        po_status.text = f"{what}: running in a separate process (Cancel search stops it)..."

    def on_find() -> None:
        try:
            v = read_view()
            kmax = int(parse_number("k max", po_k.value, lo=1, integer=True))
            po_k_err.text = ""
        except TaylorballError as e:
            if "k max" in str(e):
                po_k_err.text = str(e)
            po_status.text = "Fix the field marked in red."
            return
        if kmax > 6:
            po_k_err.text = f"k max must be <= 6 here (a search costs ~k max times more), got {kmax}"
            return
        state["found"] = []
        draw_found()
        start_skeleton(("search", (v.kind, v.params, v.level, kmax, dict(SEARCH_OPTIONS))),
                       f"searching the level for periodic orbits with k <= {kmax}")

    def on_cancel() -> None:
        if runner.cancel():
            state["skeleton"] = None
            po_status.text = "search cancelled (its process was stopped)"

    def skeleton_done(token: int, res: Any) -> None:
        if token != state["skeleton"]:
            return  # an older (cancelled) job
        state["skeleton"] = None
        dt = time.perf_counter() - state.get("skeleton_t0", time.perf_counter())
        if res is None:
            po_status.text = "search cancelled"
            return
        if res.error:
            po_status.text = f"no periodic orbit: {res.error}"
            return
        state["found"] = list(state["found"]) + list(res.orbits) if res.what == "newton" else list(res.orbits)
        draw_found()
        v: View = state["view"]
        if not res.orbits:
            po_status.text = (f"<b>No periodic orbit found</b> on this level: {res.seeds} seeds, {res.failures} "
                              f"Newton failures ({dt:.1f} s). None found is not none there: a larger k max or "
                              "a click in Newton mode near an island's centre may find one.")
            return
        n_shown = len(psrc.data["x"])
        kinds = ", ".join(f"k = {o.k} {o.stability} (period {o.period:.6g})" for o in res.orbits[:6])
        more = "" if len(res.orbits) <= 6 else f" and {len(res.orbits) - 6} more"
        where = ("" if v.kind != "reduced" or n_shown else
                 f"; none of their points is in this l slab (l = " +
                 ", ".join(f"{float(p[0]):.3f}" for o in res.orbits for p in o.points[:2]) + ")")
        po_status.text = (f"{len(res.orbits)} periodic orbit(s) found ({dt:.1f} s): {kinds}{more}{where}. "
                          "Hover a marker for its multipliers and residual.")

    def shown(rows: Dict[str, list]) -> Dict[str, list]:
        """The rows in the current l slab (reduced); all rows (M||gamma)."""
        v: View = state["view"]
        if v.kind != "reduced":
            return {k: list(c) for k, c in rows.items()}
        l = np.asarray(rows["l"], dtype=float)
        d = np.abs((l - state["l0"] + math.pi) % (2 * math.pi) - math.pi)
        keep = np.flatnonzero(d <= state["dl"] / 2)
        return {k: [c[i] for i in keep] for k, c in rows.items()}

    def restart(relaunch: bool) -> None:
        """Apply the fields; with ``relaunch``, run the clicked points again at the new values."""
        try:
            v = read_view()
        except TaylorballError:
            status.text = "Fix the field marked in red; the orbits on screen are unchanged."
            return
        old = list(pool.orbits)
        pool.clear()
        state["view"] = v
        state["rows"], state["user_rows"] = _empty(), _empty()
        src.data, usrc.data = _empty(), _empty()
        user.title.text = f"your section: {v.event} = 0" if v.event else "your section: none"
        if v.chart:
            user.xaxis.axis_label, user.yaxis.axis_label = v.chart
        empty = draw_region()
        (lv3_err if v.kind == "reduced" else lv2_err).text = empty or ""
        lv = v.level
        state["filling"] = True
        try:
            set_sliders(v, (lv.C, lv.M_gamma, lv.h) if v.kind == "reduced" else (lv.lam, lv.h))
        finally:
            state["filling"] = False
        runner.cancel()
        state["skeleton"], state["found"] = None, []
        psrc.data = point_rows([], v.kind)
        po_status.text = ""
        if empty and empty.startswith("empty level"):
            status.text = "The level is empty: no orbit can start on it; see the message beside the level."
        if relaunch:
            for o in old:
                launch(o.point, quiet=True)
        if v.omega is not None:  # the slider follows the field (its callback waits for a drag)
            omega_slider.end = max(omega_slider.end, float(v.omega))
            omega_slider.start = min(omega_slider.start, float(v.omega))
            omega_slider.value = float(v.omega)
        code.value = python_code(v, pool.orbits)
        update_readout()

    def launch(point, quiet: bool = False) -> None:
        v: View = state["view"]
        try:
            xs = start_states(v, point)
        except TaylorballError as e:
            if not quiet:
                status.text = f"No orbit there: {e}"
            return
        k = min(v.sheet, len(xs) - 1)
        o = pool.submit(v, point, xs[k])
        state["clicked"] = (o.id, time.perf_counter())
        status.text = (f"orbit {o.id} from {tuple(round(float(c), 4) for c in point)} (root {k} of {len(xs)}): "
                       "integrating...")

    def newton_from(point) -> None:
        v: View = state["view"]
        try:
            k = int(parse_number("k max", po_k.value, lo=1, integer=True))
            po_k_err.text = ""
            xs = start_states(v, point)
        except TaylorballError as e:
            (po_k_err if "k max" in str(e) else po_status).text = str(e)
            return
        x = xs[min(v.sheet, len(xs) - 1)]
        start_skeleton(("newton", (v.kind, v.params, v.level, x, k)),
                       f"Newton for a periodic orbit with k = {k} from {tuple(round(float(c), 4) for c in point)}")

    def on_tap(event_) -> None:
        v: View = state["view"]
        point: Tuple[float, ...] = ((float(state["l0"]), float(event_.x), float(event_.y)) if v.kind == "reduced"
                                    else (float(event_.x) % (2 * math.pi), float(event_.y)))
        if click_mode.value == "newton":
            newton_from(point)
            return
        launch(point)
        code.value = python_code(v, pool.orbits)

    def poll() -> None:
        while True:
            try:
                _, token, res = runner.events.get_nowait()
            except Exception:
                break
            skeleton_done(token, res)
        new = {0: _empty(), 1: _empty()}
        recolor = False
        classified: set = set()
        for _ in range(2000):
            try:
                ev = pool.events.get_nowait()
            except Exception:
                break
            kind_ = ev[0]
            o = ev[1]
            if o not in pool.orbits:
                continue  # cleared
            if kind_ == "points":
                _, o, k, times, points, states_, ints = ev
                rows = new[k]
                v = o.view
                names = list(ints)
                for i in range(len(times)):
                    p = points[i]
                    if k == 0 and v.kind == "reduced":
                        x, y, l, c1, c2 = (float(c) for c in (p[1], p[2], p[0], p[1], p[2]))
                    else:
                        x, y, l, c1, c2 = (float(c) for c in (p[0], p[1], p[0] if v.kind != "reduced" else math.nan,
                                                              p[0], p[1]))
                    I: List[float] = [float(ints[n][i]) for n in names[:3]]
                    if v.kind == "reduced":
                        I = [math.sqrt(float(ints["C2"][i])), float(ints["M_gamma"][i]), float(ints["E"][i])]
                    for col, val in zip(_COLUMNS, (float(x), float(y), float(l), float(c1), float(c2),
                                                   float(times[i]), o.id, COLORS[o.cls], o.cls,
                                                   float("nan") if o.mean_Y is None else o.mean_Y, *I,
                                                   np.array2string(np.asarray(states_[i], dtype=float),
                                                                   precision=6, separator=", "))):
                        rows[col].append(val)
                if state["clicked"] and state["clicked"][0] == o.id and k == 0:
                    dt = time.perf_counter() - state["clicked"][1]
                    state["clicked"] = None
                    status.text = f"orbit {o.id}: first crossings on screen {dt * 1000:.0f} ms after the click"
                    state["latency"] = dt
            elif kind_ == "class":
                classified.add(o.id)
            elif kind_ == "end":
                if o.status == "error":
                    status.text = f"orbit {o.id} stopped: {o.message}"
                recolor = True
        for k, rows in new.items():
            if not rows["x"]:
                continue
            store = state["rows"] if k == 0 else state["user_rows"]
            for col in _COLUMNS:
                store[col].extend(rows[col])
            part = shown(rows) if k == 0 else rows
            (src if k == 0 else usrc).stream(part)
        if classified:
            # the orbits' new colours: patch three columns of their rows (not the whole source)
            by_id = {o.id: o for o in pool.orbits}
            for store, s in ((state["rows"], src), (state["user_rows"], usrc)):
                for i, oid in enumerate(store["orbit"]):
                    if oid in classified:
                        o = by_id[oid]
                        store["color"][i], store["cls"][i], store["mean_Y"][i] = COLORS[o.cls], o.cls, o.mean_Y
                patch: Dict[str, list] = {"color": [], "cls": [], "mean_Y": []}
                for i, oid in enumerate(s.data["orbit"]):
                    if oid in classified:
                        o = by_id[oid]
                        patch["color"].append((i, COLORS[o.cls]))
                        patch["cls"].append((i, o.cls))
                        patch["mean_Y"].append((i, o.mean_Y))
                if patch["color"]:
                    s.patch(patch)
        if classified or recolor:
            update_readout()

    def update_readout() -> None:
        done = [o for o in pool.orbits if o.mean_Y is not None]
        counts = {c: sum(1 for o in done if o.cls == c) for c in ("regular", "chaotic")}
        last = pool.orbits[-1] if pool.orbits else None
        txt = (f"<b>{len(pool.orbits)}</b> orbits: <span style='color:{COLORS['regular']}'>regular "
               f"{counts['regular']}</span>, <span style='color:{COLORS['chaotic']}'>chaotic {counts['chaotic']}</span>"
               f" (&lt;Y&gt; &gt; 4), <span style='color:{COLORS['pending']}'>pending "
               f"{len(pool.orbits) - len(done)}</span>.")
        if last is not None:
            rows = state["rows"]
            idx = [i for i, oid in enumerate(rows["orbit"]) if oid == last.id][:3]
            first = "; ".join(f"t={rows['t'][i]:.12g}: ({rows['l'][i]:.12g}, {rows['c1'][i]:.12g}, "
                              f"{rows['c2'][i]:.12g})" for i in idx)
            y = "?" if last.mean_Y is None else f"{last.mean_Y:.3f}"
            txt += f"<br>orbit {last.id}: &lt;Y&gt; = {y} ({megno_class(last.mean_Y)}); first crossings {first}"
        readout.text = txt

    # ---- wiring ---------------------------------------------------------------------
    def on_preset(attr, old, new) -> None:
        fill_fields(new)
        restart(relaunch=False)

    def on_field(attr, old, new) -> None:
        if not state.get("filling"):
            restart(relaunch=True)

    def on_slider(attr, old, new) -> None:
        omega.value = repr(float(new))  # runs on_field

    def debounced(key: str, fn) -> None:
        """Run ``fn`` DEBOUNCE_MS after the last call with this key (a slider being dragged)."""
        old = state["timers"].pop(key, None)
        if old is not None:
            try:
                doc.remove_timeout_callback(old)
            except ValueError:  # already run
                pass
        state["timers"][key] = doc.add_timeout_callback(fn, DEBOUNCE_MS)

    def on_level_slider(i: int):
        target = (lv1, lv2, lv3)[i]

        def apply() -> None:
            state["timers"].pop(f"lv{i}", None)
            # the field takes the slider's value (and runs on_field: the one path for a new level)
            target.value = repr(float(lv_sliders[i].value))

        def cb(attr, old, new) -> None:
            if not state.get("filling"):
                debounced(f"lv{i}", apply)
        return cb

    def on_slab(attr, old, new) -> None:
        state["l0"], state["dl"] = float(slab.value), float(slab_w.value)
        src.data = shown(state["rows"])
        draw_region()
        draw_found()

    def on_code() -> None:
        code.value = python_code(state["view"], pool.orbits)

    preset.on_change("value", on_preset)
    for w in (omega, lv1, lv2, lv3, npts, megno_t, event, chart_in):
        w.on_change("value", on_field)
    direction.on_change("value", on_field)
    sheet.on_change("value", lambda a, o, n: restart(relaunch=False))
    omega_slider.on_change("value_throttled", on_slider)
    slab.on_change("value_throttled", on_slab)
    slab_w.on_change("value_throttled", on_slab)
    from bokeh.events import Tap

    main.on_event(Tap, on_tap)
    def on_stop() -> None:
        pool.cancel_all()
        status.text = "stopped: the orbits on screen stay"

    stop.on_click(on_stop)
    clear.on_click(lambda: restart(relaunch=False))
    code_btn.on_click(on_code)
    for i, s_ in enumerate(lv_sliders):
        s_.on_change("value", on_level_slider(i))
    po_find.on_click(on_find)
    po_cancel.on_click(on_cancel)

    fill_fields(preset.value)
    restart(relaunch=False)
    doc.add_periodic_callback(poll, POLL_MS)
    def on_destroyed(ctx) -> None:
        pool.shutdown()
        runner.shutdown()

    doc.on_session_destroyed(on_destroyed)
    legend = Div(text=(f"<span style='color:{COLORS['regular']}'>&#9679; regular</span> &nbsp; "
                       f"<span style='color:{COLORS['chaotic']}'>&#9679; chaotic (&lt;Y&gt; &gt; 4)</span> &nbsp; "
                       f"<span style='color:{COLORS['pending']}'>&#9679; &lt;Y&gt; pending</span> &nbsp; "
                       "<span style='background:#e6eef7'>&nbsp;admissible&nbsp;</span> &nbsp; periodic: "
                       f"<span style='color:{STABILITY_COLORS['elliptic']}'>&#9711; elliptic</span> "
                       f"<span style='color:{STABILITY_COLORS['hyperbolic']}'>&#10005; hyperbolic</span> "
                       f"<span style='color:{STABILITY_COLORS['parabolic']}'>&#9634; parabolic</span>"), width=560)
    controls = column(preset, row(omega, omega_err), omega_slider, row(lv1, lv1_err), lv_sliders[0],
                      row(lv2, lv2_err), lv_sliders[1], row(lv3, lv3_err), lv_sliders[2], slab, slab_w, sheet,
                      row(npts, npts_err), row(megno_t, megno_err), row(event, direction), event_err,
                      row(chart_in, chart_err), row(stop, clear), row(csv, code_btn), row(po_k, po_k_err),
                      row(po_find, po_cancel), click_mode, po_status, width=350)
    doc.add_root(column(row(controls, column(main, legend), user), status, readout, code, name="tb-root"))
    doc.title = "taylorball explore"
    state["pool"] = pool
    state["runner"] = runner
    # the page's actions, callable without a browser (tests/test_explore.py)
    state["actions"] = {"poll": poll, "find": on_find, "cancel": on_cancel, "newton": newton_from, "launch": launch}
    state["widgets"] = {"po_status": po_status, "po_k": po_k, "sliders": lv_sliders, "lv3_err": lv3_err,
                        "lv2_err": lv2_err, "periodic": psrc, "click_mode": click_mode}
    doc.taylorball_explore = state  # for tests and measurements in the same process
