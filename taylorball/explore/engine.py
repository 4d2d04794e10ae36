"""What ``taylorball explore`` computes, without the web page: the paper's presets, the
view the user has chosen (system, ball, Omega, level, section), initial states from a
click, orbits integrated by a pool of worker threads that stream their crossings and
MEGNO class, the admissible region, event expressions typed as text, and the
``taylorball`` code that reproduces a view.

Everything here is plain Python on the package's public API (no Bokeh), so it is tested
without a browser. Compiled integrators come from the package's cache
(:mod:`taylorball._cache`): one compile per section and system while the app runs,
never one per click.
"""

from __future__ import annotations

import ast
import math
import queue
import threading
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from ..paper import (FIG1_LEVELS, FIG2_BALL, FIG2_LEVELS, FIG3_BALL, FIG3_LEVELS, FIG4_BALL, FIG4A_LEVELS,
                     FIG4B_LEVELS, FIG5_BALL, FIG5A_LEVELS, FIG5B_LEVELS, fig1_params)
from .._integrals import integrals
from .._problem import problem
from .._typing import KindName
from ..chaos import MegnoOptions, megno, megno_many
from ..charts import mparallel_states_on_section, states_on_section
from ..errors import TaylorballError, UsageError
from ..sections import Section
from ..levels import Levels, MParallelLevels
from ..palette import megno_class
from ..params import BallParams, MParallelParams

__all__ = ["PRESETS", "Preset", "View", "Orbit", "OrbitPool", "parse_number", "parse_event", "start_states",
           "admissible_grid", "python_code", "axis_names", "level_ranges", "level_is_empty"]


@dataclass(frozen=True)
class Preset:
    """A figure of the paper: its system, parameters (plane rate included) and level."""

    label: str
    kind: KindName
    params: Any
    levels: Any
    point: Tuple[float, ...]  #: a chart point in the admissible region (for a first orbit)


def _fig1_params() -> MParallelParams:
    with warnings.catch_warnings():  # Fig. 1 describes no real ball: said once in the docs, not per redraw
        warnings.simplefilter("ignore")
        return fig1_params()


PRESETS: Dict[str, Preset] = {
    "fig1": Preset("Fig. 1: M||gamma map, a = (1, 2, 3), d = 4", "mparallel", _fig1_params(), FIG1_LEVELS,
                   (1.0, 0.3)),
    "fig2": Preset("Fig. 2: homogeneous ball", "reduced", FIG2_BALL, FIG2_LEVELS, (2.0, 2.5, 1.0)),
    "fig3": Preset("Fig. 3: dynamically symmetric ball", "reduced", FIG3_BALL, FIG3_LEVELS,
                   (2.0, 2.5, 1.0)),
    "fig4a": Preset("Fig. 4a: asymmetric ball, H = 2 (chaotic)", "reduced", FIG4_BALL, FIG4A_LEVELS,
                    (2.0, 2.5, 1.0)),
    "fig4b": Preset("Fig. 4b: asymmetric ball, H = 6 (tori)", "reduced", FIG4_BALL, FIG4B_LEVELS,
                    (2.0, 2.5, 1.0)),
    "fig5a": Preset("Fig. 5a: the ball and level of Fig. 4a", "reduced", FIG5_BALL, FIG5A_LEVELS,
                    (2.0, 2.5, 1.0)),
    "fig5b": Preset("Fig. 5b: the ball and level of Fig. 4b", "reduced", FIG5_BALL, FIG5B_LEVELS,
                    (2.0, 2.5, 1.0)),
}


def parse_number(name: str, text: str, *, lo: Optional[float] = None, integer: bool = False) -> float:
    """A field's text as a finite number, or a :class:`UsageError` naming the field."""
    s = str(text).strip()
    try:
        x = float(s)
    except ValueError:
        raise UsageError(f"{name} must be a number, got {s!r}") from None
    if not math.isfinite(x):
        raise UsageError(f"{name} must be a finite number, got {s!r}")
    if integer and x != int(x):
        raise UsageError(f"{name} must be a whole number, got {s!r}")
    if lo is not None and x < lo:
        raise UsageError(f"{name} must be >= {lo:g}, got {s!r}")
    return int(x) if integer else x


_FUNCS = ("sin", "cos", "exp", "log", "sqrt", "tanh")


def parse_event(kind: str, text: str) -> Any:
    """A heyoka expression from text in the public variables of ``kind`` (``"gamma3"``,
    ``"R1 - 0.5*omega2"``, ``"sin(gamma1) + K3/10"``): numbers, names, ``+ - * / **``
    and the functions ``sin, cos, exp, log, sqrt, tanh``; anything else is a
    :class:`UsageError` naming what is allowed. Parsed by :mod:`ast`, never evaluated."""
    import heyoka as hy

    from ..model import PUBLIC_NAMES

    names = PUBLIC_NAMES[kind]
    allowed = (f"an expression in {', '.join(names)} with numbers, + - * / ** and "
               f"{', '.join(_FUNCS)}")
    s = str(text).strip()
    if not s:
        raise UsageError(f"event must be {allowed}; got an empty field")
    try:
        tree = ast.parse(s, mode="eval")
    except SyntaxError as e:
        raise UsageError(f"event must be {allowed}; {s!r} does not parse ({e.msg})") from None
    ops = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b, ast.Mult: lambda a, b: a * b,
           ast.Div: lambda a, b: a / b, ast.Pow: lambda a, b: a ** b}

    def conv(node):
        if isinstance(node, ast.Expression):
            return conv(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
            return hy.expression(float(node.value))
        if isinstance(node, ast.Name):
            if node.id not in names:
                raise UsageError(f"event must be {allowed}; {node.id!r} is not a variable of kind={kind!r}")
            return hy.make_vars(node.id)
        if isinstance(node, ast.BinOp) and type(node.op) in ops:
            return ops[type(node.op)](conv(node.left), conv(node.right))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            v = conv(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in _FUNCS
                and len(node.args) == 1 and not node.keywords):
            return getattr(hy, node.func.id)(conv(node.args[0]))
        raise UsageError(f"event must be {allowed}; {ast.unparse(node)!r} is not allowed")

    return conv(tree)


def axis_names(kind: str) -> Tuple[str, str]:
    """The two coordinates of the paper's section drawn on the screen: ``(r1, r2)`` of an
    ``l`` slab (reduced, Fig. 4's panels), ``(l, L/G)`` (M||gamma, Fig. 1)."""
    return ("r1", "r2") if kind == "reduced" else ("l", "L/G")


@dataclass(frozen=True)
class View:
    """What is on screen: a preset's system with the user's Omega and level, the section
    (the paper's, or ``event`` with its ``direction`` and ``chart``), how long orbits run
    and which root (sheet) a click takes."""

    preset: str = "fig4a"
    omega: Optional[float] = None  #: None: the preset's
    levels: Any = None  #: None: the preset's
    event: Optional[str] = None  #: text of a user's section (None: the paper's g = 0 only)
    chart: Tuple[str, ...] = ()
    direction: int = 1
    n_points: int = 300
    megno_t_end: float = 200.0
    sheet: int = 0

    @property
    def kind(self) -> KindName:
        return PRESETS[self.preset].kind

    @property
    def params(self) -> Any:
        p = PRESETS[self.preset].params
        if self.omega is None:
            return p
        if isinstance(p, BallParams):
            return BallParams(inertia=p.inertia, mass=p.mass, radius=p.radius, plane_rate=self.omega)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return MParallelParams(a=p.a, d=p.d, plane_rate=self.omega)

    @property
    def level(self) -> Any:
        return PRESETS[self.preset].levels if self.levels is None else self.levels

    def with_(self, **changes: Any) -> "View":
        return replace(self, **changes)

    def sections(self) -> List[Any]:
        """The sections computed for each orbit: the paper's, then the user's if any."""

        prob = problem(self.kind, self.params)
        out = [Section(prob)]
        if self.event:
            out.append(Section(prob, event=parse_event(self.kind, self.event),
                                  direction=self.direction,  # type: ignore[arg-type]  # checked by Section
                                  chart=self.chart or None))
        return out


def start_states(view: View, point: Sequence[float]) -> np.ndarray:
    """The initial states on the paper's section at chart ``point`` of the view's level
    (``states_on_section`` / ``mparallel_states_on_section``), crossing upwards."""

    lv = view.level
    if view.kind == "reduced":
        return states_on_section(view.params, **lv.as_kwargs(), point=tuple(point), direction=1)
    return mparallel_states_on_section(view.params, **lv.as_kwargs(), point=tuple(point))


def admissible_grid(view: View, l0: float, n: int = 64) -> Dict[str, Any]:
    """Where the view's level meets the paper's section: a boolean image on the screen's
    axes (``(r1, r2)`` at ``l = l0`` for the reduced map, ``(l, L/G)`` for M||gamma) and its
    extent."""
    from ..charts import _section_states

    lv = view.level
    if view.kind == "reduced":
        def ok(r1, r2):
            found = _section_states(view.params, lv.C, lv.M_gamma, lv.h, np.full(len(r1), float(l0)), list(r1),
                                    list(r2), 0.0, 1, 161)
            return np.array([not isinstance(f, Exception) and len(f[0]) > 0 for f in found])

        box = 1.0
        ring = np.linspace(0, 2 * math.pi, 48, endpoint=False)
        for _ in range(10):
            if not ok(box * np.cos(ring), box * np.sin(ring)).any() and box >= 4.0:
                break
            box *= 2.0
        r = np.linspace(-box, box, n)
        R1, R2 = np.meshgrid(r, r)
        mask = ok(R1.ravel(), R2.ravel()).reshape(n, n)
        return {"mask": mask, "x": (-box, box), "y": (-box, box)}

    ls = np.linspace(0.0, 2 * math.pi, n)
    gs = np.linspace(-1.0, 1.0, n // 2)
    mask = np.zeros((len(gs), len(ls)), dtype=bool)
    for i, g in enumerate(gs):
        for j, l in enumerate(ls):
            try:
                mparallel_states_on_section(view.params, **lv.as_kwargs(), point=(l, g), n_grid=161)
                mask[i, j] = True
            except TaylorballError:
                pass
    return {"mask": mask, "x": (0.0, 2 * math.pi), "y": (-1.0, 1.0)}


def level_ranges(view: View) -> List[Tuple[str, float, float, float]]:
    """The level sliders of the view: ``(name, start, end, step)`` per level field.

    ``G = |M| > 0`` and ``|H| <= G`` are the valid ranges of the ball's first two levels (H's
    slider spans ``[-G, G]``); ``h`` has an upper bound for each ``G, H`` (the energy falls
    like ``-|R|^2``) that is not known in closed form here, nor are M||gamma's ranges of
    ``lam``, ``h``: those sliders span the current value +- twice its size, and a level
    that misses the section is reported by :func:`level_is_empty`."""
    lv = view.level

    def around(x: float) -> Tuple[float, float, float]:
        w = 2.0 * max(abs(x), 1.0)
        return (x - w, x + w, w / 200)

    if view.kind == "reduced":
        G = float(lv.C)
        g_end = max(4.0 * G, 1.0)
        return [("G", g_end / 400, g_end, g_end / 400), ("H", -G, G, G / 200), ("h", *around(float(lv.h)))]
    return [("lam", *around(float(lv.lam))), ("h", *around(float(lv.h)))]


def level_is_empty(view: View, grid: Dict[str, Any]) -> Optional[str]:
    """``None`` if the view's level meets the paper's section, else the message to show.
    ``grid`` is :func:`admissible_grid`'s answer for the slab on screen; when it is empty
    for a reduced level the other ``l`` are sampled
    (:func:`taylorball.charts.section_admissible_sample`) before the level is called empty."""
    from ..charts import section_admissible_sample
    from ..errors import EmptyLevelError

    if np.asarray(grid["mask"]).any():
        return None
    lv = view.level
    if view.kind == "reduced":
        try:
            found = section_admissible_sample(view.params, **lv.as_kwargs(), n=1, max_candidates=4000)
        except EmptyLevelError as e:
            return (f"empty level: G = {lv.C!r}, H = {lv.M_gamma!r}, h = {lv.h!r} meets no state of the section "
                    f"g = 0 ({e}); lower h (the energy falls like -|R|^2: each G, H has a largest h)")
        l0 = float(found["points"][0][0])
        return f"no admissible point in this l slab; the level meets the section elsewhere (l = {l0:.3f})"
    return (f"empty level: lam = {lv.lam!r}, h = {lv.h!r} meets no state of the section g = 0 on a "
            f"{grid['mask'].shape[1]} x {grid['mask'].shape[0]} grid of (l, L/G); change h or lam")


class _Cancelled(Exception):
    pass


@dataclass(eq=False)
class Orbit:
    """One clicked orbit: its start, status and (once known) ``<Y>``."""

    id: int
    point: Tuple[float, ...]
    state: np.ndarray
    view: View
    status: str = "running"  #: running, done, cancelled, error
    message: str = ""
    mean_Y: Optional[float] = None
    compact: bool = False  #: <Y> from the compact-mode integrator (before the default one was compiled)
    n: int = 0
    cancel: threading.Event = field(default_factory=threading.Event)

    @property
    def cls(self) -> str:
        return megno_class(self.mean_Y)


class OrbitPool:
    """Orbits integrated in worker threads; what they find is put on :attr:`events` as
    ``("points", orbit, section_index, times, points, states, integrals)``,
    ``("class", orbit)`` and ``("end", orbit)`` tuples, for the page to take in its own
    thread.

    Crossings and MEGNO run in two pools: an orbit's crossings (milliseconds to a tenth of
    a second) never wait behind other orbits' MEGNO runs (most of a second each), so a new
    click is answered at once however many orbits are being classified."""

    def __init__(self, workers: int = 2, megno_workers: int = 1, notify: Optional[Callable[[], None]] = None) -> None:
        self.events: "queue.Queue[tuple]" = queue.Queue()
        #: called (from the worker thread) when an orbit's first crossings are on :attr:`events`,
        #: so that the page takes them at once instead of at its next periodic poll
        self.notify = notify
        self._pool = ThreadPoolExecutor(max_workers=max(1, workers), thread_name_prefix="taylorball-explore")
        self._megno = ThreadPoolExecutor(max_workers=max(1, megno_workers), thread_name_prefix="taylorball-megno")
        self._next = 0
        self._lock = threading.Lock()
        self.orbits: List[Orbit] = []

    def submit(self, view: View, point: Sequence[float], state: np.ndarray) -> Orbit:
        with self._lock:
            orbit = Orbit(self._next, tuple(float(p) for p in point), np.asarray(state), view)
            self._next += 1
            self.orbits.append(orbit)
        self._pool.submit(self._work, orbit)
        return orbit

    def cancel_all(self) -> None:
        for o in list(self.orbits):
            o.cancel.set()

    def clear(self) -> None:
        self.cancel_all()
        with self._lock:
            self.orbits = []

    def shutdown(self) -> None:
        self.cancel_all()
        self._pool.shutdown(wait=False, cancel_futures=True)
        self._megno.shutdown(wait=False, cancel_futures=True)

    def _work(self, orbit: Orbit) -> None:
        view = orbit.view
        try:
            sections = view.sections()
            for k, sec in enumerate(sections):
                def push(times, points, states, _k=k):
                    if orbit.cancel.is_set():
                        raise _Cancelled
                    ints = integrals(view.kind, view.params, states)
                    first = _k == 0 and orbit.n == 0
                    if _k == 0:
                        orbit.n += len(times)
                    self.events.put(("points", orbit, _k, times, points, states, ints))
                    if first and self.notify is not None:
                        self.notify()

                if orbit.cancel.is_set():
                    raise _Cancelled
                # the default chunks (100 time units): the same bits as poincare_section(s) and the
                # code of python_code; a chunk takes milliseconds, so the first crossings come at once
                sec.run(orbit.state, n_points=view.n_points, on_chunk=push)
            if orbit.cancel.is_set():
                raise _Cancelled
        except _Cancelled:
            orbit.status = "cancelled"
        except Exception as e:  # shown on the page next to the orbit, never a dead page
            orbit.status, orbit.message = "error", f"{type(e).__name__}: {e}"
        if orbit.status != "running":
            self.events.put(("end", orbit))
            return
        self._megno.submit(self._classify, orbit)

    def _classify(self, orbit: Orbit) -> None:
        view = orbit.view
        try:
            if orbit.cancel.is_set():
                raise _Cancelled
            if view.kind in MEGNO_READY:
                ind = megno(view.kind, view.params, orbit.state, view.megno_t_end)
            else:
                # heyoka's compile of the default-mode tangent system (M||gamma: ~20-60 s on an
                # empty cache) is under way in the background: compact mode compiles in a second
                orbit.compact = True
                ind = megno_many(view.kind, view.params, [orbit.state], view.megno_t_end, workers=1,
                                 options=MegnoOptions(compact_mode=True))[0]
            orbit.mean_Y = float(ind.mean_megno)
            self.events.put(("class", orbit))
            orbit.status = "done"
        except _Cancelled:
            orbit.status = "cancelled"
        except Exception as e:
            orbit.status, orbit.message = "error", f"{type(e).__name__}: {e}"
        self.events.put(("end", orbit))


#: The systems whose MEGNO (:func:`taylorball.megno`) answers without a long compile: the
#: reduced and full systems (compact mode by default) and, once :func:`warm_megno` has
#: compiled it into heyoka's disk cache, M||gamma. Until then the pool classifies M||gamma
#: orbits with ``megno_many(..., options=MegnoOptions(compact_mode=True))`` (the orbit's ``compact`` is set, and
#: "copy as Python" writes that call).
MEGNO_READY = {"reduced", "full"}


def _compile_megno(view: View, x: np.ndarray) -> None:
    # in the order a click needs them: the sections, compact MEGNO, default-mode MEGNO
    for sec in view.sections():
        sec.run(x, n_points=1)
    megno_many(view.kind, view.params, [x], 2.0, workers=1, options=MegnoOptions(compact_mode=True))
    megno(view.kind, view.params, x, 2.0)


def warm_megno(view: View) -> Optional[threading.Thread]:
    """Compile what a click on the view needs (its sections, MEGNO in compact and default
    mode) into heyoka's disk cache in a child process (so that the compile never holds
    this process's interpreter; this process then loads them from the disk cache), then
    mark the system ready (:data:`MEGNO_READY`). Returns the thread that waits for it
    (None: nothing to do)."""
    import multiprocessing as mp

    if view.kind in MEGNO_READY:
        return None
    x = start_states(view, PRESETS[view.preset].point)[0]
    proc = mp.get_context("spawn").Process(target=_compile_megno, args=(view, x), daemon=True,
                                           name="taylorball-megno-compile")
    proc.start()

    def wait() -> None:
        proc.join()
        if proc.exitcode == 0:
            MEGNO_READY.add(view.kind)

    th = threading.Thread(target=wait, daemon=True, name="taylorball-megno-compile-wait")
    th.start()
    return th


def warm_up(view: View) -> None:
    """Compile what a click needs (section integrators, MEGNO's tangent system) before
    the first click: they stay in the package's cache while the app runs."""

    x = start_states(view, PRESETS[view.preset].point)[0]
    for sec in view.sections():
        sec.run(x, n_points=1)
    megno(view.kind, view.params, x, 2.0)


def python_code(view: View, orbits: Sequence[Orbit]) -> str:
    """The ``taylorball`` code that reproduces the orbits on screen: the same presets'
    numbers, chart points, roots (sheets) and sections."""
    p = view.params
    lv = view.level
    if isinstance(p, BallParams):
        ball = (f"tb.BallParams(inertia={tuple(p.inertia)!r}, mass={p.mass!r}, radius={p.radius!r}, "
                f"plane_rate={p.plane_rate!r})")
        roots = "tb.states_on_section(params, **levels, point=p, direction=1)"
        lvl = f"dict(C={lv.C!r}, M_gamma={lv.M_gamma!r}, h={lv.h!r})"
    else:
        ball = f"tb.MParallelParams(a={tuple(p.a)!r}, d={p.d!r}, plane_rate={p.plane_rate!r})"
        roots = "tb.mparallel_states_on_section(params, **levels, point=p)"
        lvl = f"dict(lam={lv.lam!r}, h={lv.h!r})"
    clicks = [(tuple(float(c) for c in o.point), int(o.view.sheet)) for o in orbits]
    lines = [
        "import heyoka as hy",
        "import taylorball as tb",
        "",
        f"params = {ball}",
        f"levels = {lvl}",
        f"prob = tb.problem({view.kind!r}, params)",
        f"clicks = {clicks!r}   # (chart point, root index: the sheet)",
        "states = []",
        "for p, s in clicks:",
        f"    roots = {roots}",
        "    states.append(roots[min(s, len(roots) - 1)])",
        f"paper = tb.poincare_sections(prob, states, n_points={view.n_points})   # the section g = 0",
    ]
    if view.event:
        chart = f", chart={tuple(view.chart)!r}" if view.chart else ""
        lines += _event_code(view.kind, view.event)
        lines.append(f"user = tb.poincare_sections(prob, states, n_points={view.n_points}, "
                     f"direction={view.direction}, options=tb.SectionOptions(event=event{chart}))")
    T = repr(view.megno_t_end)
    if any(o.compact for o in orbits):
        lines.append(f"compact = {[bool(o.compact) for o in orbits]!r}   # compact-mode MEGNO (see docs/explore.md)")
        lines.append(f"mean_Y = [(tb.megno_many({view.kind!r}, params, [x], {T}, workers=1, "
                     f"options=tb.MegnoOptions(compact_mode=True))[0] "
                     f"if c else tb.megno({view.kind!r}, params, x, {T})).mean_megno for x, c in zip(states, compact)]")
    else:
        lines.append(f"mean_Y = [tb.megno({view.kind!r}, params, x, {T}).mean_megno for x in states]")
    lines.append("chaotic = [y > 4.0 for y in mean_Y]   # taylorball.palette.CHAOTIC_MEGNO")
    return "\n".join(lines) + "\n"


def _event_code(kind: str, text: str) -> List[str]:
    """Lines defining ``event`` as the heyoka expression of ``text`` (checked by
    :func:`parse_event`)."""
    parse_event(kind, text)
    tree = ast.parse(str(text).strip(), mode="eval")
    used = sorted({n.id for n in ast.walk(tree) if isinstance(n, ast.Name) and n.id not in _FUNCS})
    if isinstance(tree.body, ast.Name):
        return [f"event = {tree.body.id!r}"]

    class _Hy(ast.NodeTransformer):
        def visit_Call(self, node):
            self.generic_visit(node)
            node.func = ast.Attribute(value=ast.Name("hy", ast.Load()), attr=node.func.id, ctx=ast.Load())
            return node

    body = ast.unparse(_Hy().visit(tree))
    names = ", ".join(used)
    make = f"hy.make_vars({', '.join(repr(u) for u in used)})"
    return [f"{names}{',' if len(used) == 1 else ''} = {make}" if len(used) > 1 else f"{names} = {make}",
            f"event = {body}"]
