r"""Poincaré sections by heyoka's event detection: the paper's section ``g = g0`` and
sections of the user's choosing.

The section ``g = g0`` (paper section 4; section 5 for the M||gamma system) is the zero
set of the event function of :func:`taylorball.charts.section_event_function`,

.. math:: e = \frac{\mathrm{num}\cos g_0 - \mathrm{den}\sin g_0}{C^2}
          = \frac{\rho}{C^2}\sin(g - g_0),\qquad |e| \le 1,

built from the state's own ``M`` (reduced) or ``K`` (mparallel). heyoka finds its roots
inside each Taylor step from the step's polynomial (no sampling, no Python loop over
steps); the root on the other half-line ``g = g0 + pi`` is discarded in the callback.
``direction=+1`` keeps crossings with ``g`` increasing through ``g0`` (``e`` increasing
there), ``-1`` decreasing, ``0`` both.

A section of the user's choosing, ``Section(problem, event="gamma3", direction=+1)``, is
the zero set of a smooth scalar function of the public variables (a name, or a heyoka
expression in them), for any of the three systems; it is rewritten in the internal
variables and kept of the size of the state (:mod:`taylorball._section_events`), its
crossings refined as the paper's are, and ``chart=`` names the coordinates returned as
``points``.

A run is cut into chunks of time (a Python loop over chunks, each thousands of steps) so
that it can be interrupted and report progress. The chunk boundaries are the fixed times
``k * chunk``: heyoka truncates the last step of a chunk to land on its boundary, so
boundaries that depend only on time (not on ``n_points`` or on how fast crossings come)
make the first ``k`` crossings of an orbit bit-identical whatever ``n_points`` and
``t_end`` are. The run stops after the step that brings the ``n_points``-th crossing (a
step callback, :meth:`_Collector.arm`): stopping after a whole step, unlike a time limit or
a terminal event, changes no step before it.

The work is split by job: the events and their callbacks in
:mod:`taylorball._section_events`, one run's results and chunk loop in
:mod:`taylorball._section_run`, the SIMD lanes in :mod:`taylorball._section_batch`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, List, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from ._typing import Direction, FpTypeLike, KindName, ParamsLike, ProgressLike, StatesLike
from .errors import StateError, UsageError
from ._cache import compiled, working_copy
from ._deprecation import moved, options_of, renamed
from ._integrals import integrals_cfunc
from .model import KIND_TABLE, KINDS, get_system
from .numbers import count
from ._problem import Problem, at_boundary, problem
from ._propagate import integrator, public_state, start_state
from ._section_batch import _batch_template, _run_batch, batch_size
from ._section_events import (  # noqa: F401  (private names re-exported for tests and benchmarks)
    RATE_CHECK,
    STOP_MARGIN,
    PaperEvent,
    UserEvent,
    _Collector,
    _direction,
    _event_cfunc,
    _event_expression,
    user_event,
)
from ._section_run import (  # noqa: F401
    MAX_POINTS,
    START_TOL,
    Outcome,
    SectionResult,
    _branch_mask,
    _check_run,
    _on_branch,
    _chunks,
    _Crossings,
    _provenance,
    _Run,
    _VECTOR_TYPES,
)

__all__ = ["Section", "SectionResult", "SectionOptions", "Outcome", "poincare_section", "poincare_sections", "chart_points",
           "batch_size"]

#: The systems with a section chart (section 4: reduced; section 5: mparallel).
SECTION_KINDS = tuple(k for k, info in KIND_TABLE.items() if info.chart is not None)


# ---------------------------------------------------------------------------------------
# Chart coordinates of section points.
# ---------------------------------------------------------------------------------------
def chart_points(kind: KindName, internal: ArrayLike) -> np.ndarray:
    """Chart coordinates of internal states on the section.

    ``reduced``: ``(l, r1, r2)`` with ``l = atan2(M1, M2)`` in ``[0, 2 pi)``,
    ``r1 = R1 gamma1 + R2 gamma2``, ``r2 = R1 gamma2 - R2 gamma1`` (section 4);
    ``mparallel``: ``(l, L/G)`` with ``l = atan2(K1, K2)``, ``L/G = K3/|K|`` (section 5)."""
    system = get_system(kind)
    if system.info.chart is None:
        raise UsageError(f"kind must be one of {SECTION_KINDS} (a system with a section chart), got {kind!r}")
    return system.info.chart(np.asarray(internal, dtype=float).reshape(-1, system.dim))


def _check_kind(kind):
    if not isinstance(kind, str) or kind not in SECTION_KINDS:
        raise UsageError(f"kind must be one of {SECTION_KINDS} for a Poincaré section, got {kind!r} (any of "
                         f"{KINDS} with a section of your choosing, event=...)")


def _chart_names(prob: Problem, chart) -> Tuple[str, ...]:
    """``chart`` (None, a name or a sequence of names) as a tuple of valid column names."""
    info = prob.system.info
    default = info.chart_names if info.chart is not None else info.public_names
    if chart is None:
        return default
    names = (chart,) if isinstance(chart, str) else chart
    valid = (*info.chart_names, *info.public_names)
    try:
        names = tuple(names)
    except TypeError:
        names = (names,)
    bad = [n for n in names if not isinstance(n, str) or n not in valid]
    if not names or bad:
        raise UsageError(f"chart must name one or more coordinates of kind={prob.kind!r} among {', '.join(valid)}; "
                         f"got {chart!r}")
    return names


@dataclass(frozen=True)
class Section:
    """A Poincaré section of a problem, its event, branch test and chart, and runs of
    orbits through it: the paper's section ``g = g0`` (section 4; section 5 for the
    M||gamma system) by default, or the zero set of a function of the user's choosing
    (``event=``).

    Parameters
    ----------
    problem : Problem
        A system, its parameters, number type and tolerance (:func:`taylorball.problem`):
        ``"reduced"`` or ``"mparallel"`` for the paper's section, any kind with ``event=``.
    g0 : float
        The paper's section angle, in ``[0, 2 pi)`` (not with ``event=``).
    direction : {1, -1, 0}
        ``+1``: the event function increasing through 0 (``g`` increasing through ``g0``);
        ``-1``: decreasing; ``0``: both.
    event : str or heyoka expression, optional
        The section ``f = 0`` of a smooth scalar function ``f`` of the public variables of
        the kind (:data:`taylorball.model.PUBLIC_NAMES`): a name (``"gamma3"``, ``"R1"``,
        ...) or a heyoka expression in them (``hy.make_vars("gamma3") - 0.5``). It is
        rewritten in the internal variables of the problem's formulation and weighted to
        the size of the state (so that it leaves the orbit's steps as they are: see
        :mod:`taylorball._section_events`); every root is a crossing (no branch test).
    chart : str or sequence of str, optional
        The coordinates of a crossing returned as ``points``: names among the kind's chart
        (``l, r1, r2``; ``l, L/G``) and public variables. Default: the kind's chart, or the
        public variables for the full system.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> x0 = tb.states_on_section(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), point=(2.0, 2.5, 1.0),
    ...                           direction=1)[0]
    >>> section = tb.Section(tb.problem("reduced", FIG4_BALL), g0=0.0, direction=1)
    >>> sec = section.run(x0, n_points=5)
    >>> sec.points.shape, sec.outcome is tb.Outcome.COMPLETED
    ((5, 3), True)
    >>> same = tb.poincare_section("reduced", FIG4_BALL, x0, n_points=5)
    >>> bool((sec.points == same.points).all())    # what poincare_section runs
    True
    >>> up = tb.Section(tb.problem("reduced", FIG4_BALL), event="gamma3", direction=1,
    ...                 chart=("R1", "R2"))       # gamma3 = 0 crossed upwards
    >>> r = up.run(x0, n_points=3)
    >>> r.points.shape, bool(abs(r.states[:, 5]).max() < 1e-14)
    ((3, 2), True)
    """

    problem: Problem
    g0: float = 0.0
    direction: Direction = 1
    #: The event as given (``None``: the paper's section)
    function: Any = None
    #: The names of the columns of ``points``
    chart_names: Tuple[str, ...] = ()
    event_def: Any = field(default=None, repr=False, compare=False)

    def __init__(self, problem: Problem, g0: float = 0.0, direction: Direction = 1, *, event: Any = None,
                 chart: Union[None, str, Sequence[str]] = None) -> None:
        if not isinstance(problem, Problem):
            raise UsageError(f"problem must be a taylorball Problem (tb.problem(kind, params, ...)), got {problem!r}")
        if not (isinstance(g0, (int, float, np.integer, np.floating)) and not isinstance(g0, bool)
                and 0.0 <= g0 < 2 * math.pi):
            raise UsageError(f"g0 must be a float in [0, 2 pi), got {g0!r}")
        _direction(direction)
        if event is None:
            _check_kind(problem.kind)
            ev: Any = PaperEvent(problem.kind, float(g0))
        else:
            if g0 != 0.0:
                raise UsageError(f"g0 is the angle of the paper's section; a section with event={event!r} has none "
                                 f"(write the angle into the event), got g0={g0!r}")
            ev = user_event(problem, event)
        names = _chart_names(problem, chart)
        for k, v in (("problem", problem), ("g0", float(g0)), ("direction", direction),
                     ("function", None if event is None else ev.text), ("chart_names", names), ("event_def", ev)):
            object.__setattr__(self, k, v)

    @property
    def kind(self) -> KindName:
        return self.problem.kind

    @property
    def _paper_points(self) -> bool:
        """Whether ``points`` are the kind's chart, computed as the paper's section has always done."""
        info = self.problem.system.info
        return info.chart is not None and self.chart_names == info.chart_names

    def describe(self) -> str:
        """The section in words: ``"g = 0"``, ``"gamma3 = 0"``, with its direction."""
        return f"{self.event_def.describe()}, direction {int(self.direction):+d}"

    def integrator(self) -> Any:
        """The cached scalar integrator with the section event (copy it)."""

        def events():
            return {"nt_events": [self.event(deferred=True)]}

        if not self.event_def.n_extra:
            return integrator(self.problem, events_key=("section", self.g0, int(self.direction)), events=events)
        prob = self.problem
        spec, system = prob.spec, prob.system

        def build():
            import heyoka as hy

            zero = spec.scalar(0.0)
            kw = dict(sys=system.equations(), state=[spec.scalar(0.1)] * system.dim,
                      pars=[zero] * (system.n_pars + self.event_def.n_extra), fp_type=spec.fp_type,
                      compact_mode=spec.compact_mode, **events())
            if spec.prec is not None:
                kw.update(prec=spec.prec, time=zero)
            if prob.tol is not None:
                kw["tol"] = spec.scalar(prob.tol)
            return hy.taylor_adaptive(**kw)

        return compiled(("integrator", *prob.compile_key, spec.compact_mode,
                         ("section", *self.event_def.key, int(self.direction))), build)

    def event(self, deferred: bool = False) -> Any:
        """The section's non-terminal heyoka event with its :class:`_Collector` callback
        (crossing times and internal states, Newton-refined): what :meth:`integrator`
        compiles in, and what the long-run observable ``sections`` adds to a run's
        integrator. The paper's expression uses only the state variables ``M``, ``gamma``
        (no sub-expression of the vector field), so adding it leaves the orbit's bits
        unchanged (``tests/test_observables_orbit.py``). ``deferred=True`` (float64, what
        :meth:`integrator` uses): the callback only records and the owner of the integrator
        calls the collector's ``refine(ta.pars)`` after each propagation."""
        import heyoka as hy

        spec = self.problem.spec
        kw = dict(direction=_direction(self.direction))
        if spec.name != "float":
            kw["fp_type"] = spec.fp_type
        spec_key = (spec.fp_type, spec.prec)
        self.event_def.cfunc(spec_key)  # compile before the first crossing
        # the paper's compiled field is in the kind's default formulation, as its event
        deferred = deferred and (bool(self.event_def.n_extra)
                                 or self.problem.formulation == self.problem.system.info.default_formulation)
        return hy.nt_event(self.event_def.expression(), _Collector(self.event_def, spec_key, deferred), **kw)

    def batch_integrator(self, size: int) -> Any:
        """The cached float64 batch integrator with ``size`` lanes and the section event."""
        return _batch_template(self.event_def, self.problem.tol, self.direction, size)

    def on_branch(self, states: ArrayLike) -> np.ndarray:
        """Which internal states are crossings: on the half-line ``g = g0`` (not ``g0 +
        pi``) for the paper's section; every root of a user's event."""
        if not self.event_def.branch:
            return np.ones(np.shape(states)[0] if np.ndim(states) else 0, dtype=bool)
        spec = self.problem.spec
        if spec.name == "float" and isinstance(states, list) and 0 < len(states) <= _FEW_ROWS:
            # a few float64 rows (a chunk's roots): row by row on Python floats, the same IEEE
            # operations as on whole columns, hence the same decisions
            g0 = self.g0
            return np.array([_on_branch(x.tolist() if isinstance(x, np.ndarray) else x, g0) for x in states],
                            dtype=bool)
        return _branch_mask(states, self.g0, spec)

    def extra_pars(self, internal: ArrayLike) -> Tuple[float, ...]:
        """The event's runtime parameters after the system's for the orbit starting at
        ``internal``: none for the paper's section, the weight ``w`` of a user's event."""
        if not self.event_def.n_extra:
            return ()
        spec = self.problem.spec
        return (self.event_def.weight(internal, self.problem.pars, (spec.fp_type, spec.prec)),)

    def chart(self, internal: ArrayLike) -> np.ndarray:
        """Chart coordinates of internal states of the kind's default formulation (see
        :func:`chart_points`)."""
        return chart_points(self.kind, internal)

    @renamed(t_max="t_end")
    def run(self, state: ArrayLike, *, n_points: int, t_end: Optional[float] = None, chunk: float = 100.0,
            progress: ProgressLike = False,
            on_chunk: Optional[Callable[[np.ndarray, np.ndarray, np.ndarray], Any]] = None) -> SectionResult:
        """Crossings of the orbit of ``state`` (public layout): see :func:`poincare_section`
        (``t_max`` is a deprecated alias of ``t_end``).

        ``on_chunk(times, points, states)``, if given, is called after every chunk that
        brought crossings, with those crossings (times, :attr:`chart_names` coordinates,
        public states), e.g. to show an orbit as it comes; an exception it raises abandons
        the run and propagates. It sees the run, it does not change it (same bits)."""
        from .ensemble import run_many

        _check_run(n_points, t_end, chunk)
        if on_chunk is not None and not callable(on_chunk):
            raise UsageError(f"on_chunk must be a callable (times, points, states) or None, got {on_chunk!r}")
        watch = None if on_chunk is None else self._watcher(on_chunk)
        job = _SectionJob(self, state, _Run(n_points, t_end, chunk, watch))
        return run_many([job], backend="serial", progress=f"section {self.kind}" if progress is True else progress)[0]

    def _watcher(self, on_chunk):
        prob = self.problem

        def watch(times, states):
            d = prob.system.dim
            X = np.array(states, dtype=prob.spec.dtype).reshape(-1, d)
            public = np.array([public_state(prob.system, prob.pars, x, prob.spec) for x in X],
                              dtype=prob.spec.dtype).reshape(-1, d)
            pts = self.chart(X) if self._paper_points else self._points(X, public)
            on_chunk(np.array([float(t) for t in times]), pts, public)

        return watch

    def _run(self, internal, run: _Run, ctx) -> SectionResult:
        """One orbit from the internal state ``internal``, as a member with context ``ctx``."""
        prob = self.problem
        extra = self.extra_pars(internal)
        with working_copy(self.integrator()) as ta:
            ta.state[:] = internal
            if extra:
                ta.pars[:] = np.concatenate([prob.pars, prob.spec.array(np.asarray(extra, dtype=float))])
            else:
                ta.pars[:] = prob.pars
            ta.time = prob.spec.scalar(0.0)
            ta.nt_events[0].callback.clear()
            crossings = _chunks(self, ta, run, ctx)
        return self._finish(internal, crossings)

    def _finish(self, internal, c: _Crossings) -> SectionResult:
        """The result of a run from the internal start ``internal`` and its crossings."""
        prob = self.problem
        system, spec, pars = prob.system, prob.spec, prob.pars
        d = system.dim
        X = np.array(c.states, dtype=spec.dtype).reshape(-1, d) if c.states else np.empty((0, d), dtype=spec.dtype)
        ints_fn, scales_fn = _integral_fns(prob.kind, spec.fp_type, spec.prec)
        # the start and the crossings in one evaluation each (a compiled function evaluates
        # every row on its own: the same bits as row by row)
        both = np.concatenate([np.asarray(internal, dtype=spec.dtype).reshape(1, d), X])
        names = system.info.integral_names
        drift = dict.fromkeys(names, 0.0)
        IA, SA = ints_fn(both, pars), scales_fn(both, pars)
        fast = (spec.name == "float" and 0 < len(X) <= _FEW_ROWS
                and _drift_floats({k: v.tolist() for k, v in IA.items()}, {k: v.tolist() for k, v in SA.items()},
                                  names, drift))
        I = {k: v[1:] for k, v in IA.items()}
        if len(X) and not fast:
            # every integral at once (rows): the same elementwise operations and exact maxima
            # as one integral at a time, hence the same values
            A, B = np.stack([IA[k] for k in names]), np.stack([SA[k] for k in names])
            dev = np.abs((A[:, 1:] - A[:, :1]).astype(float)).max(axis=1)
            scales = np.maximum(np.abs(B[:, 1:].astype(float)).max(axis=1), np.abs(B[:, 0].astype(float)))
            for k, dv, sc in zip(names, dev.tolist(), scales.tolist()):
                drift[k] = dv / sc if sc > 0 else 0.0
        ev = self.event_def
        if spec.name == "float" and 0 < len(X) <= _FEW_ROWS:
            # a few float64 rows: row by row on Python floats, the same IEEE operations as on
            # whole columns (+ - * / and a correctly rounded sqrt), hence the same bits,
            # without numpy's fixed cost per operation on short columns
            rows = X.tolist()
            if not ev.n_extra:
                residuals = np.array([float(ev.residuals_cols(r)) for r in rows], dtype=float)
            else:
                residuals = self._user_residuals(internal, X)
            fpars = tuple(pars.tolist())
            public = np.array([system.to_public(fpars, r) for r in rows], dtype=float).reshape(-1, d)
        elif spec.name in _VECTOR_TYPES and len(X):
            # whole columns: the same IEEE operations as row by row, hence the same bits
            cols = tuple(X[:, i] for i in range(d))
            residuals = (np.asarray(ev.residuals_cols(cols)).astype(float) if not ev.n_extra
                         else self._user_residuals(internal, X))
            public = np.empty_like(X)
            for i, v in enumerate(system.to_public(tuple(pars), cols)):
                public[:, i] = v
        else:
            residuals = (np.array([float(ev.residuals_cols(tuple(x))) for x in X], dtype=float) if not ev.n_extra
                         else self._user_residuals(internal, X))
            public = np.array([public_state(system, pars, x, spec) for x in X], dtype=spec.dtype).reshape(-1, d)
        levels_of = system.info.levels
        start = {k: v[0] for k, v in IA.items()}
        if not self._paper_points:
            points = self._points(X, public)
        elif X.dtype == np.float64 and system.info.chart is not None:
            points = system.info.chart(X)  # float64 rows already: what chart_points calls after its checks
        else:
            points = self.chart(X)
        return SectionResult(
            kind=prob.kind,
            points=points,
            times=np.array([float(t) for t in c.times], dtype=float),
            states=public,
            residuals=residuals,
            integrals={k: v for k, v in I.items()},
            drift=drift,
            levels=(levels_of(start) if levels_of is not None
                    else {k: float(start[k]) for k in system.info.integral_names}),
            outcome=c.outcome,
            message=c.message,
            t_end=c.t_end,
            n_steps=c.n_steps,
            wall_time=c.wall,
            meta=_provenance(self),
        )

    def _user_residuals(self, internal, X) -> np.ndarray:
        """A user's event ``e = w f`` at the internal states ``X`` (rows)."""
        spec = self.problem.spec
        f = self.event_def.cfunc((spec.fp_type, spec.prec))
        full = np.concatenate([self.problem.pars, spec.array(np.asarray(self.extra_pars(internal), dtype=float))])
        return np.array([float(f(np.ascontiguousarray(x), full)[0]) for x in X], dtype=float).reshape(-1)

    def _points(self, X, public) -> np.ndarray:
        """The columns :attr:`chart_names` of crossings with internal states ``X`` and
        public states ``public``."""
        info = self.problem.system.info
        out = np.empty((len(X), len(self.chart_names)), dtype=float)
        chart = None
        for j, name in enumerate(self.chart_names):
            if name in info.public_names:
                out[:, j] = np.asarray(public[:, info.public_names.index(name)], dtype=float)
                continue
            if chart is None:
                # the kind's chart reads the variables of its default formulation
                default = get_system(self.kind)
                rows = np.asarray(public, dtype=float)
                pars = np.asarray(self.problem.pars, dtype=float)
                inner = (X if self.problem.formulation == default.formulation
                         else np.array([default.to_internal(tuple(pars), tuple(r)) for r in rows]).reshape(-1, default.dim))
                chart = chart_points(self.kind, inner)
            out[:, j] = chart[:, info.chart_names.index(name)]
        return out


@dataclass(frozen=True)
class SectionOptions:
    """The less common options of :func:`poincare_section` and :func:`poincare_sections`
    (``options=tb.SectionOptions(...)``; their old keywords of the same names are
    deprecated).

    Attributes
    ----------
    prec : int, optional
        Precision in bits for ``fp_type=heyoka.real`` (as for :func:`taylorball.propagate`).
    tol : float, optional
        The integrator's tolerance (default: the number type's epsilon).
    chunk : float
        Time per integration chunk (default 100); boundaries at multiples of it.
    event, chart
        A section of your choosing and the coordinates returned as ``points``: see
        :class:`Section`.
    """

    prec: Optional[int] = None
    tol: Optional[float] = None
    chunk: float = 100.0
    event: Any = None
    chart: Union[None, str, Sequence[str]] = None


_SECTION_OPTIONS = ("prec", "tol", "chunk", "event", "chart")


@moved(SectionOptions, *_SECTION_OPTIONS, renamed={"t_max": "t_end"})
def poincare_section(
    kind: Union[KindName, Problem],
    params: Union[ParamsLike, ArrayLike, None] = None,
    state: Optional[ArrayLike] = None,
    *,
    n_points: int,
    g0: float = 0.0,
    direction: Direction = 1,
    t_end: Optional[float] = None,
    fp_type: FpTypeLike = float,
    progress: ProgressLike = False,
    options: Optional[SectionOptions] = None,
) -> SectionResult:
    """Crossings of an orbit with the section ``g = g0`` (or a section of your choosing,
    ``event=``).

    A thin wrapper: ``Section(problem(kind, params, fp_type=..., prec=..., tol=...), g0,
    direction, event=..., chart=...).run(state, n_points=..., ...)`` (``prec``, ``tol``,
    ``event``, ``chart`` and ``chunk`` from ``options``).

    Parameters
    ----------
    kind : {"reduced", "mparallel"} or Problem
        The reduced system (3D map in ``(l, r1, r2)``) or the M||gamma system (2D map in
        ``(l, L/G)``); any kind (``"full"`` too) with ``event=``. Or a
        :class:`~taylorball.Problem`, which fixes the parameters, number type and
        tolerance: then the state comes second, ``poincare_section(prob, x0, n_points=...)``.
    params : BallParams or MParallelParams
    state : array_like
        Initial state in the public layout of ``kind``.
    n_points : int
        Number of crossings to collect (> 0).
    g0 : float
        Section angle, in ``[0, 2 pi)``.
    direction : {1, -1, 0}
        ``+1``: ``g`` increasing through ``g0``; ``-1``: decreasing; ``0``: both.
    t_end : float, optional
        Give up at this time (default: ``1e4 * n_points`` time units, a guard against
        orbits that never cross; the result then says so). ``t_max`` is its deprecated
        alias.
    fp_type
        Number type, as for :func:`taylorball.propagate`.
    progress : bool
        Show a progress bar (tqdm), in fractions of the orbit (collected crossings over
        ``n_points``).
    options : SectionOptions, optional
        The precision ``prec``, tolerance ``tol``, ``chunk`` length, a section of your
        choosing (``event``, ``chart``); default ``SectionOptions()``. The keywords
        ``prec=``, ``tol=``, ``chunk=``, ``event=``, ``chart=`` are their deprecated old form.

    Returns
    -------
    SectionResult
        The crossings after the start: an initial state on the section itself (as
        :func:`taylorball.states_on_section` builds them) is not reported, so ``points``
        are the returns ``P(x0), P^2(x0), ...`` (see :data:`START_TOL`).

    Raises
    ------
    UsageError
        Unknown ``kind``, bad ``n_points``, ``g0`` or ``direction``.
    StateError, ConstraintError, ParameterError
        As for :func:`taylorball.propagate`.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> x0 = tb.states_on_section(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), point=(2.0, 2.5, 1.0),
    ...                           direction=1)[0]
    >>> sec = tb.poincare_section("reduced", FIG4_BALL, x0, n_points=5)
    >>> sec                                        # doctest: +ELLIPSIS
    SectionResult(kind='reduced', n=5, outcome='n_points', ...)
    >>> sec.points.shape                           # (l, r1, r2) of each return
    (5, 3)
    >>> sec.outcome is tb.Outcome.COMPLETED
    True
    >>> {k: round(v, 9) for k, v in sec.levels.items()}   # the level set of the orbit
    {'C': 10.0, 'M_gamma': 2.0, 'h': 5.0}
    >>> bool(max(sec.drift.values()) < 1e-12)
    True
    """
    o = options_of(options, SectionOptions, "poincare_section")
    prob, state = _problem_and(kind, params, state, "state", o.event,
                               dict(fp_type=fp_type, prec=o.prec, tol=o.tol))
    _check_run(n_points, t_end, o.chunk)
    sec = Section(prob, g0, direction, event=o.event, chart=o.chart)
    return sec.run(state, n_points=n_points, t_end=t_end, chunk=o.chunk, progress=progress)


_INTEGRAL_FNS: dict = {}

#: Up to this many float64 crossings (or roots for the branch test), :meth:`Section._finish`
#: converts them and takes the drift row by row on Python floats (a few us a row); more, on
#: whole numpy columns (a fixed ~50 us). Both give the same bits.
_FEW_ROWS = 8


def _drift_floats(IL, SL, names, drift) -> bool:
    """The drift of float64 integrals (lists ``IL``, start first) relative to their scales
    (``SL``) on Python floats, into ``drift``: the same subtractions, exact absolute values
    and maxima as the numpy reduction, hence the same values. False (``drift`` untouched)
    if a value is not finite: the numpy reduction then decides how NaN propagates."""
    out = {}
    for k in names:
        a, b = IL[k], SL[k]
        if not math.isfinite(sum(a) + sum(b)):  # a NaN or an infinity (or an overflow: numpy then)
            return False
        a0 = a[0]
        dv = max([abs(v - a0) for v in a[1:]])
        sc = max(max([abs(v) for v in b[1:]]), abs(b[0]))
        out[k] = dv / sc if sc > 0 else 0.0
    drift.update(out)
    return True


def _integral_fns(kind, fp_type, prec):
    """The compiled integrals and scales of ``kind`` in a number type, looked up once per
    process (each is a closure over its compiled function, valid as long as it lives)."""
    key = (kind, fp_type, prec)
    fns = _INTEGRAL_FNS.get(key)
    if fns is None:
        fns = _INTEGRAL_FNS[key] = (integrals_cfunc(kind, fp_type=fp_type, prec=prec),
                                    integrals_cfunc(kind, fp_type=fp_type, prec=prec, which="scales"))
    return fns


def _problem_and(kind, params, what, name, event, options) -> Tuple[Problem, Any]:
    """The problem of ``kind`` (a name or a Problem) and the state(s) ``what``, by the
    package's one rule (:func:`taylorball._problem.at_boundary`): with a Problem, the
    state(s) come second (in ``params``' place) or by keyword."""
    if not isinstance(kind, Problem) and event is None:
        _check_kind(kind)  # the paper's section: the kinds with a section chart
    func = "poincare_section" if name == "state" else "poincare_sections"
    prob, (what,) = at_boundary(func, kind, params, (what,), (name,), **options)
    return prob, what


@dataclass(frozen=True, eq=False)
class _SectionJob:
    """One orbit's section as a member of :func:`taylorball.ensemble.run_many` (called with
    the member's context): what :func:`poincare_section` computes, for it and for every
    orbit of :func:`poincare_sections` (scalar mode), hence the same bits."""

    section: Section
    state: object
    run: _Run

    def __call__(self, ctx) -> SectionResult:
        return self.section._run(start_state(self.section.problem, self.state), self.run, ctx)


@moved(SectionOptions, *_SECTION_OPTIONS, renamed={"t_max": "t_end", "threads": "workers"})
def poincare_sections(
    kind: Union[KindName, Problem],
    params: Union[ParamsLike, StatesLike, None] = None,
    states: Optional[StatesLike] = None,
    *,
    n_points: int,
    g0: float = 0.0,
    direction: Direction = 1,
    t_end: Optional[float] = None,
    fp_type: FpTypeLike = float,
    workers: Optional[int] = None,
    progress: ProgressLike = False,
    batch: bool = False,
    options: Optional[SectionOptions] = None,
) -> List[SectionResult]:
    """:func:`poincare_section` for many initial states, on a pool of threads; with
    ``batch=True`` (float64) several orbits per integrator (heyoka's SIMD batch mode).

    heyoka releases the GIL while it integrates, so threads run in parallel. By default
    each orbit is integrated by its own copy of the compiled scalar integrator, exactly as
    :func:`poincare_section` does, so ``poincare_sections(...)[i]`` is bit-identical to
    ``poincare_section(..., states[i], ...)``. In batch mode (float64), consecutive
    orbits run in the SIMD lanes of ``taylor_adaptive_batch`` integrators, one per thread,
    a lane refilled with the next orbit as soon as its orbit is done
    (``taylorball.ensemble.run_many(..., backend="lanes")``; measured here: 4 lanes in 1.3x the
    time of one scalar orbit without events, 1.7x with the section event and its callback). The lanes are
    independent (own clock and step sizes; a lane's bits do not depend on its companions
    nor on when it was loaded), and every orbit depends only on its own initial state, so
    the results are bit-identical whatever the number of threads, and a batched run is
    bit-identical to another batched run of the same state. Batched and scalar (:func:`poincare_section`) runs of the same state agree to
    rounding only: heyoka's vectorised code rounds differently from its scalar code
    (first difference measured at step 24 of the demo orbit: 1 ulp in the step size and
    ~1e-15 in the state), so on chaotic orbits they separate as any two float64 runs do;
    both are equally accurate (``benchmarks/bench_sections.py`` compares both with a
    real128 reference).

    Parameters
    ----------
    kind, params
        As for :func:`poincare_section` (a Problem then the states, or a kind, its
        parameters and the states).
    states : sequence of array_like
        Initial states (public layout).
    workers : int, optional
        Worker threads (default: ``os.cpu_count()``); ``1`` runs serially (``threads=`` is
        its deprecated old name).
    batch : bool
        Use batch mode (default ``False``): ~2.3x the throughput per core for many
        float64 orbits (``benchmarks/bench_sections.py``), at the price of bit-identity with
        :func:`poincare_section`. Only float64 has a batch mode (``UsageError``
        otherwise). An orbit whose lane stops with an error is rerun alone in scalar
        mode, which reports the error.
    options : SectionOptions, optional
        As for :func:`poincare_section`.

    Returns
    -------
    list of SectionResult
        In the order of ``states``.

    Examples
    --------
    >>> import numpy as np
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> xs = tb.states_on_section(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), point=(2.0, 2.5, 1.0))
    >>> secs = tb.poincare_sections("reduced", FIG4_BALL, xs, n_points=5, workers=2)
    >>> [s.points.shape for s in secs]
    [(5, 3), (5, 3)]
    >>> one = tb.poincare_section("reduced", FIG4_BALL, xs[1], n_points=5)
    >>> bool((secs[1].points == one.points).all())    # bit-identical to one orbit alone
    True
    >>> lanes = tb.poincare_sections("reduced", FIG4_BALL, xs, n_points=5, batch=True)
    >>> bool(np.allclose(lanes[1].points, one.points, rtol=0, atol=1e-10))   # equal to rounding
    True
    """
    import os

    from .ensemble import run_many

    o = options_of(options, SectionOptions, "poincare_sections")
    prob, states = _problem_and(kind, params, states, "states", o.event,
                                dict(fp_type=fp_type, prec=o.prec, tol=o.tol))
    try:
        states = list(states)
    except TypeError:
        raise StateError(f"states must be a sequence of initial states, got {states!r}") from None
    if not states:
        raise UsageError("states must contain at least one initial state")
    _check_run(n_points, t_end, o.chunk)
    if workers is not None:
        count("workers", workers)
    sec = Section(prob, g0, direction, event=o.event, chart=o.chart)
    if batch and sec.problem.spec.name != "float":
        raise UsageError(f"batch=True needs fp_type=float (heyoka's batch mode is float64 only), "
                         f"got {sec.problem.spec}")
    # validate every state before starting threads
    for s in states:
        start_state(sec.problem, s)
    n = workers or os.cpu_count() or 1
    jobs = [_SectionJob(sec, s, _Run(n_points, t_end, o.chunk)) for s in states]
    label = f"sections {prob.kind}" if progress is True else progress
    if batch:
        out = _run_batch(sec, states, _Run(n_points, t_end, o.chunk), threads=n, progress=label)
        # an orbit whose lane stopped with an error: rerun alone, which reports the error
        again = [i for i, r in enumerate(out) if r is None]
        for i, r in zip(again, run_many([jobs[i] for i in again], backend="serial")):
            out[i] = r
        return out
    sec.integrator()  # compile before starting threads
    # Ctrl-C: the running orbits stop at their next chunk, the queued ones are dropped
    return run_many(jobs, backend="threads", workers=n, progress=label)
