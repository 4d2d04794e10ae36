r"""Poincaré sections by heyoka's event detection.

The section ``g = g0`` (paper section 4; section 5 for the M||gamma system) is the zero
set of the event function of :func:`taylorball.charts.section_event_function`,

.. math:: e = \frac{\mathrm{num}\cos g_0 - \mathrm{den}\sin g_0}{C^2}
          = \frac{\rho}{C^2}\sin(g - g_0),\qquad |e| \le 1,

built from the state's own ``M`` (reduced) or ``K`` (mparallel). heyoka finds its roots
inside each Taylor step from the step's polynomial (no sampling, no Python loop over
steps); the root on the other half-line ``g = g0 + pi`` is discarded in the callback.
``direction=+1`` keeps crossings with ``g`` increasing through ``g0`` (``e`` increasing
there), ``-1`` decreasing, ``0`` both.

A run is cut into chunks of time (a Python loop over chunks, each thousands of steps) so
that it can be interrupted and report progress. The chunk boundaries are the fixed times
``k * chunk``: heyoka truncates the last step of a chunk to land on its boundary, so
boundaries that depend only on time (not on ``n_points`` or on how fast crossings come)
make the first ``k`` crossings of an orbit bit-identical whatever ``n_points`` and
``t_max`` are. The run stops after the step that brings the ``n_points``-th crossing (a
step callback, :meth:`_Collector.arm`): stopping after a whole step, unlike a time limit or
a terminal event, changes no step before it.
"""

from __future__ import annotations

import enum
import math
import time as _time
from dataclasses import dataclass, field
from typing import Any, Dict, List, Literal, Optional

import numpy as np
from numpy.typing import ArrayLike

from ._typing import Direction, FpTypeLike, KindName, ParamsLike, ProgressLike, StatesLike
from .charts import g_angle_parts, section_event_function
from .errors import StateError, UsageError
from ._cache import compiled, working_copy
from ._integrals import integrals_cfunc
from .model import KIND_TABLE, get_system
from .numbers import count, real_number, resolve_fp_type
from ._problem import Problem, problem
from ._propagate import integrator, public_state, start_state

__all__ = ["Section", "SectionResult", "Outcome", "poincare_section", "poincare_sections", "chart_points",
           "batch_size"]

#: The systems with a section chart (section 4: reduced; section 5: mparallel).
SECTION_KINDS = tuple(k for k, info in KIND_TABLE.items() if info.chart is not None)


class _Collector:
    """Non-terminal event callback: records the crossing time and the state there.

    heyoka hands the callback the crossing time rounded to the number type, i.e. to
    ``ulp(t)`` (5.7e-14 at t = 500 in float64); evaluated there, the event function is off
    by ``|de/dt| ulp(t)`` (measured: 1e-13, growing with t). So the crossing is refined by
    one Newton step in time *relative to the end of the step* (``rel_time=True``, where the
    offset carries full precision), using the compiled ``(e, de/dt)``; the residual then is
    rounding of the event function itself (~eps). heyoka deep-copies this object into the
    integrator; read it back from ``ta.nt_events[0].callback``.
    """

    def __init__(self, key):
        self.key = key
        self.eps = resolve_fp_type(*key[1]).eps
        self.times = []
        self.states = []
        self.event = _event_cfunc(*key)  # looked up once per integrator copy, not per crossing
        self.disarm()

    def __deepcopy__(self, memo):
        return _Collector(self.key)

    def arm(self, ta, kept, need, t0, t1):
        """A step callback for ``ta.propagate_until`` over the chunk ``t0 .. t1``: it stops
        the propagation after the step that brings ``need`` more crossings accepted by
        ``kept(times, states)`` (a count), or, once the crossings so far say the chunk will
        not bring them, after the step of that check (:attr:`paused`; the caller then
        propagates on without a callback). Stopping after a step leaves the state at the
        end of a whole step, and steps depend only on the state, so the run goes on with
        the same steps and crossings whatever the callback does.

        The step callback runs after every step (once the step's crossings are recorded
        here), so it is a C-level ``set.__contains__`` on a set holding ``ta`` (~0.14 us per
        step against ~2 us for a Taylor step here; a Python callable ~0.2 us); this callback
        empties the set to stop. A recorded root is at most one accepted crossing, so
        roots are classified only once there are ``need`` new ones. Call :meth:`disarm`
        after the propagation (the set refers to ``ta``, which refers to this object)."""
        self.kept, self.need, self.t0, self.span = kept, need, float(t0), float(t1) - float(t0)
        self.first = self.counted = len(self.times)  # roots before the chunk; roots classified
        self.paused = False
        self.go = {ta}
        self._plan()
        return self.go.__contains__

    def disarm(self):
        self.go = set()
        self.kept = None
        self.next_check = math.inf

    def _plan(self):
        self.next_check = min(self.counted + self.need, len(self.times) + RATE_CHECK)

    def _check(self):
        n = len(self.times)
        if n >= self.counted + self.need:
            self.need -= self.kept(self.times[self.counted:], self.states[self.counted:])
            self.counted = n
            if self.need <= 0:
                self.go.clear()
                self.next_check = math.inf
                return
        elapsed = float(self.times[-1]) - self.t0
        roots = n - self.first
        if elapsed > 0 and roots >= RATE_CHECK:
            # crossings the chunk may still bring: the unclassified roots and, at the rate so
            # far, the roots of the rest of the chunk
            likely = (n - self.counted) + roots * (self.span - elapsed) / elapsed
            if self.need > STOP_MARGIN * likely:
                self.paused = True
                self.go.clear()
                self.next_check = math.inf
                return
        self._plan()

    def __call__(self, ta, t, d_sgn):
        hi, lo = ta.dtime
        rel = (t - hi) - lo  # exact: t and the step's end are within one step (Sterbenz)
        x = ta.update_d_output(rel, rel_time=True)
        e, de = self.event(x, ta.pars)
        if de != 0:
            delta = e / de
            # apply only a rounding-size correction (a few ulp of t): anything larger would
            # mean a grazing crossing where one Newton step is not to be trusted
            if abs(delta) <= 64 * self.eps * (abs(hi) + abs(ta.last_h)):
                rel = rel - delta
                x = ta.update_d_output(rel, rel_time=True)
        self.times.append(hi + (lo + rel))
        self.states.append(x.copy())
        if len(self.times) >= self.next_check:
            self._check()


class _BatchCollector:
    """The batch-mode counterpart of :class:`_Collector`: heyoka calls it with the lane
    index. To keep the Python work per crossing small (it holds the GIL, and sections
    produce ~10^5 crossings per figure), it only records ``(lane, hi, lo, rel, x)``: the
    lane's step end ``hi + lo``, heyoka's crossing time relative to it, and the dense
    output there. :func:`_refine_batch_records` then applies the same Newton step in time
    as :class:`_Collector`, on whole columns."""

    def __init__(self, batch_size):
        self.batch_size = batch_size
        self.records = []
        self._rel = np.zeros(batch_size)

    def __deepcopy__(self, memo):
        return _BatchCollector(self.batch_size)

    def __call__(self, ta, t, d_sgn, idx):
        his, los = ta.dtime
        hi, lo = float(his[idx]), float(los[idx])
        rel = (t - hi) - lo  # exact: t and the step's end are within one step (Sterbenz)
        self._rel[idx] = rel  # the other lanes' entries are stale and their outputs unused
        self.records.append((idx, hi, lo, rel, ta.update_d_output(self._rel, rel_time=True)[:, idx].copy()))


def _refine_batch_records(kind, g0, records, pars):
    """Newton-refined crossings ``(lanes, times, states)`` from :class:`_BatchCollector`
    records (float64). With ``delta = e/(de/dt)`` at the recorded point, the crossing is
    ``t - delta`` and the state ``x - delta f(x)`` (``f`` the vector field): the dense
    output there to ``O(delta^2)``, i.e. ~1e-26 for the rounding-size ``delta`` accepted
    (at most 64 ulp of ``|t| + 1``; larger ones mean a grazing crossing, left as is)."""
    if not records:
        return [], [], []
    lanes = np.array([r[0] for r in records])
    hi = np.array([r[1] for r in records])
    lo = np.array([r[2] for r in records])
    rel = np.array([r[3] for r in records])
    X = np.array([r[4] for r in records])
    out = _event_field_cfunc(kind, g0)(np.ascontiguousarray(X.T),
                                       pars=np.repeat(np.asarray(pars, dtype=float)[:, None], len(X), axis=1))
    e, de, f = out[0], out[1], out[2:]
    eps = np.finfo(float).eps
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(de != 0, e / de, 0.0)
    ok = np.isfinite(delta) & (np.abs(delta) <= 64 * eps * (np.abs(hi) + 1.0))
    delta = np.where(ok, delta, 0.0)
    X = X - delta[:, None] * f.T
    return list(lanes), list(hi + (lo + (rel - delta))), list(X)


def _event_field_cfunc(kind, g0):
    """Compiled float64 ``x -> (e, de/dt, f(x))`` (section event, its time derivative, the
    vector field), evaluated on columns of states (cached)."""

    def build():
        import heyoka as hy

        xs, e, de, rhs = _event_parts(kind, g0)
        return hy.cfunc([e, de] + list(rhs), xs, compact_mode=True)

    return compiled(("cfunc", "section event+field", kind, float(g0)), build)


def _event_cfunc(kind, spec_key, g0):
    """Compiled ``x -> (e(x), de/dt(x))`` for the section event (cached)."""

    def build():
        import heyoka as hy

        spec = resolve_fp_type(*spec_key)
        xs, e, de, _ = _event_parts(kind, g0)
        kw = dict(fp_type=spec.fp_type, compact_mode=True)
        if spec.prec is not None:
            kw["prec"] = spec.prec
        cf = hy.cfunc([e, de], xs, **kw)
        n_par = cf.nparams

        def f(x, pars, _cf=cf, _n=n_par):
            out = _cf(x, pars=pars[:_n])
            return out[0], out[1]

        return f

    return compiled(("cfunc", "section event", kind, str(resolve_fp_type(*spec_key)), g0), build)


def _event_parts(kind, g0):
    """heyoka expressions of the section event: ``(xs, e, de/dt, f)`` with ``xs`` the
    internal variables, ``e`` the event function and ``f`` the vector field."""
    import heyoka as hy

    system = get_system(kind)
    xs = hy.make_vars(*system.internal_names)
    e = section_event_function(xs[0:3], xs[3:6], g0)
    rhs = system.rhs([hy.par[i] for i in range(system.n_pars)], xs)
    de = hy.sum([hy.diff(e, x) * fx for x, fx in zip(xs, rhs)])
    return xs, e, de, rhs


def _event_expression(kind, g0):
    return _event_parts(kind, g0)[1]


def _direction(direction):
    import heyoka as hy

    table = {1: hy.event_direction.positive, -1: hy.event_direction.negative, 0: hy.event_direction.any}
    if not isinstance(direction, (int, np.integer)) or isinstance(direction, bool) or direction not in table:
        raise UsageError(f"direction must be +1 (g increasing through g0), -1 (decreasing) or 0 (both), got {direction!r}")
    return table[direction]


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


# ---------------------------------------------------------------------------------------
# Results.
# ---------------------------------------------------------------------------------------
class Outcome(str, enum.Enum):
    """How a section run ended; compares equal to its value (``"n_points"``, ...)."""

    #: every requested crossing was found
    COMPLETED = "n_points"
    #: the time limit came first
    T_MAX = "t_max"
    #: the integrator stopped (a non-finite state): singular configuration or escape
    STOPPED = "error"

    __str__ = str.__str__
    # mypy types str.__format__ read off the class as bound (Callable[[str], str]); it is the
    # plain function Enum's slot takes
    __format__ = str.__format__  # type: ignore[assignment]

    @property
    def remedy(self) -> str:
        """What to do about it."""
        return {
            "n_points": "nothing: the run is complete",
            "t_max": "increase t_max (or check that the orbit crosses g = g0 at all: the section may miss its "
                     "level set)",
            "error": "check the initial state and parameters for a singular configuration "
                     "(1 - d (gamma, A gamma) = 0) or an escaping orbit; the crossings found before are kept",
        }[self.value]


@dataclass(frozen=True)
class SectionResult:
    """Crossings of one orbit with the section ``g = g0``.

    Attributes
    ----------
    points : ndarray, shape (n, 3) or (n, 2)
        ``(l, r1, r2)`` (reduced) or ``(l, L/G)`` (mparallel).
    times : ndarray, shape (n,)
    states : ndarray, shape (n, d)
        Public-layout states at the crossings (dtype of the integration).
    residuals : ndarray, shape (n,)
        Event function at the recorded states (0 exactly on the section; ``|e| <= 1``).
    integrals : dict of str -> ndarray (n,)
        The first integrals at each crossing.
    drift : dict of str -> float
        ``max |I - I(0)|`` over the crossings, relative to the integral's scale, with
        ``I(0)`` at the initial state.
    levels : dict of str -> float
        The integrals at the initial state (``C = sqrt(C2)``, ``M_gamma``, ``h = E``, or
        ``lambda``, ``h``).
    outcome : Outcome
        :attr:`Outcome.COMPLETED` (``"n_points"``: all requested crossings found),
        :attr:`Outcome.T_MAX` (``"t_max"``: time limit reached first) or
        :attr:`Outcome.STOPPED` (``"error"``: the integrator stopped); ``outcome.remedy``
        says what to do.
    message : str
        Human-readable account of how the run ended and what to do about it.
    t_end : float
        Time where the integration stopped: for a completed scalar run the end of the
        Taylor step that found the last crossing (``times[-1] <= t_end``, within one step;
        a batch-mode run, ``poincare_sections(batch=True)``, ends at the chunk boundary
        after it), else ``t_max`` or where the integrator stopped.
    n_steps : int
        Taylor steps taken up to ``t_end``.
    wall_time : float
        Seconds of wall time of the integration and collection (not of the checks before
        nor of this result's evaluation).
    meta : dict
        Provenance: kind, parameters, number type, tolerance, section, package versions.
    """

    kind: str
    points: np.ndarray
    times: np.ndarray
    states: np.ndarray
    residuals: np.ndarray
    integrals: Dict[str, np.ndarray]
    drift: Dict[str, float]
    levels: Dict[str, float]
    outcome: Outcome
    message: str
    t_end: float
    n_steps: int
    wall_time: float
    meta: Dict[str, object] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.outcome is Outcome.COMPLETED

    def __len__(self):
        return len(self.times)

    def __repr__(self):
        d = ", ".join(f"{k}={v:.1e}" for k, v in self.drift.items())
        return (
            f"SectionResult(kind={self.kind!r}, n={len(self)}, outcome={self.outcome.value!r}, t_end={self.t_end:.6g}, "
            f"max|residual|={float(np.max(np.abs(self.residuals))) if len(self) else 0.0:.1e}, drift: {d})"
        )


def _provenance(section):
    import platform

    import heyoka as hy

    from ._version import __version__

    prob = section.problem
    return {
        "kind": prob.kind,
        "params": {k: getattr(prob.params, k) for k in prob.params.__dataclass_fields__},
        "params_type": type(prob.params).__name__,
        "fp_type": str(prob.spec),
        "tol": prob.tol,
        "g0": float(section.g0),
        "direction": int(section.direction),
        "taylorball": __version__,
        "heyoka": hy.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }


# ---------------------------------------------------------------------------------------
# One orbit.
# ---------------------------------------------------------------------------------------
def _check_kind(kind):
    if not isinstance(kind, str) or kind not in SECTION_KINDS:
        raise UsageError(f"kind must be one of {SECTION_KINDS} for a Poincaré section, got {kind!r}")


#: At most this many crossings per orbit (each is kept in memory: ~100 bytes).
MAX_POINTS = 10_000_000
#: At most ``max(MAX_CHUNKS, CHUNKS_PER_POINT * n_points)`` chunks (Python round trips)
#: per orbit, so the work a call implies stays proportional to what it asks for.
MAX_CHUNKS, CHUNKS_PER_POINT = 1_000_000, 1000


def _check_run(n_points, t_max, chunk):
    if not (isinstance(n_points, (int, np.integer)) and not isinstance(n_points, bool)
            and 1 <= n_points <= MAX_POINTS):
        raise UsageError(f"n_points must be a positive integer (at most {MAX_POINTS}), got {n_points!r}")
    if t_max is not None and not (isinstance(t_max, (int, float, np.integer, np.floating))
                                  and not isinstance(t_max, bool) and math.isfinite(t_max) and t_max > 0):
        raise UsageError(f"t_max must be > 0 and finite (a time), got {t_max!r}")
    chunk = real_number("chunk", chunk, lo=0.0, lo_open=True)
    limit = float(t_max) if t_max is not None else 1e4 * n_points
    cap = max(MAX_CHUNKS, CHUNKS_PER_POINT * n_points)
    if limit / chunk > cap:
        raise UsageError(f"chunk={chunk!r} cuts the run to t_max={limit:g} into {limit / chunk:.3g} chunks, more than "
                         f"{cap}: use chunk >= {limit / cap:.3g} (or a smaller t_max)")


@dataclass(frozen=True)
class Section:
    """The Poincaré section ``g = g0`` of a problem (paper section 4; section 5 for the
    M||gamma system): its event, branch test and chart, and runs of orbits through it.

    Parameters
    ----------
    problem : Problem
        A system with a section chart (``"reduced"`` or ``"mparallel"``), its parameters,
        number type and tolerance (:func:`taylorball._problem.problem`).
    g0 : float
        Section angle, in ``[0, 2 pi)``.
    direction : {1, -1, 0}
        ``+1``: ``g`` increasing through ``g0``; ``-1``: decreasing; ``0``: both.

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
    """

    problem: Problem
    g0: float = 0.0
    direction: Direction = 1

    def __post_init__(self) -> None:
        _check_kind(self.problem.kind)
        g0 = self.g0
        if not (isinstance(g0, (int, float, np.integer, np.floating)) and not isinstance(g0, bool)
                and 0.0 <= g0 < 2 * math.pi):
            raise UsageError(f"g0 must be a float in [0, 2 pi), got {g0!r}")
        _direction(self.direction)
        object.__setattr__(self, "g0", float(g0))

    @property
    def kind(self) -> KindName:
        return self.problem.kind

    def integrator(self) -> Any:
        """The cached scalar integrator with the section event (copy it)."""

        def events():
            return {"nt_events": [self.event()]}

        return integrator(self.problem, events_key=("section", self.g0, int(self.direction)), events=events)

    def event(self) -> Any:
        """The section's non-terminal heyoka event with its :class:`_Collector` callback
        (crossing times and internal states, Newton-refined): what :meth:`integrator`
        compiles in, and what the long-run observable ``sections`` adds to a run's
        integrator. Its expression uses only the state variables ``M``, ``gamma`` (no
        sub-expression of the vector field), so adding it leaves the orbit's bits unchanged
        (``tests/test_observables_orbit.py``)."""
        import heyoka as hy

        prob, g0 = self.problem, self.g0
        kind, spec = prob.kind, prob.spec
        kw = dict(direction=_direction(self.direction))
        if spec.name != "float":
            kw["fp_type"] = spec.fp_type
        key = (kind, (spec.fp_type, spec.prec), g0)
        _event_cfunc(*key)  # compile before the first crossing
        return hy.nt_event(_event_expression(kind, g0), _Collector(key), **kw)

    def batch_integrator(self, size: int) -> Any:
        """The cached float64 batch integrator with ``size`` lanes and the section event."""
        return _batch_template(self.kind, self.problem.tol, self.g0, self.direction, size)

    def on_branch(self, states: ArrayLike) -> np.ndarray:
        """Which internal states lie on the half-line ``g = g0`` (not ``g0 + pi``)."""
        return _branch_mask(states, self.g0, self.problem.spec)

    def chart(self, internal: ArrayLike) -> np.ndarray:
        """Chart coordinates of internal states (see :func:`chart_points`)."""
        return chart_points(self.kind, internal)

    def run(self, state: ArrayLike, *, n_points: int, t_max: Optional[float] = None, chunk: float = 100.0,
            progress: ProgressLike = False) -> "SectionResult":
        """Crossings of the orbit of ``state`` (public layout): see :func:`poincare_section`."""
        from .ensemble import run_many

        _check_run(n_points, t_max, chunk)
        job = _SectionJob(self, state, _Run(n_points, t_max, chunk))
        return run_many([job], backend="serial", progress=f"section {self.kind}" if progress is True else progress)[0]

    def _run(self, internal, run: "_Run", ctx) -> "SectionResult":
        """One orbit from the internal state ``internal``, as a member with context ``ctx``."""
        prob = self.problem
        with working_copy(self.integrator()) as ta:
            ta.state[:] = internal
            ta.pars[:] = prob.pars
            ta.time = prob.spec.scalar(0.0)
            cb = ta.nt_events[0].callback
            cb.times.clear()
            cb.states.clear()
            crossings = _chunks(self, ta, run, ctx)
        return self._finish(internal, crossings)

    def _finish(self, internal, c: "_Crossings") -> "SectionResult":
        """The result of a run from the internal start ``internal`` and its crossings."""
        prob = self.problem
        system, spec, pars = prob.system, prob.spec, prob.pars
        d = system.dim
        X = np.array(c.states, dtype=spec.dtype).reshape(-1, d) if c.states else np.empty((0, d), dtype=spec.dtype)
        ints_fn = integrals_cfunc(prob.kind, fp_type=spec.fp_type, prec=spec.prec)
        scales_fn = integrals_cfunc(prob.kind, fp_type=spec.fp_type, prec=spec.prec, which="scales")
        I0 = ints_fn(internal[None, :], pars)
        S0 = scales_fn(internal[None, :], pars)
        if len(X):
            I = ints_fn(X, pars)
            S = scales_fn(X, pars)
        else:
            I = {k: np.empty(0, dtype=spec.dtype) for k in I0}
            S = I
        drift = {}
        for k in system.info.integral_names:
            if len(X):
                scale = max(float(np.max(np.abs(S[k].astype(float)))), abs(float(S0[k][0])))
                drift[k] = float(np.max(np.abs((I[k] - I0[k][0]).astype(float)))) / scale if scale > 0 else 0.0
            else:
                drift[k] = 0.0
        g0 = self.g0
        if spec.name in _VECTOR_TYPES and len(X):
            # whole columns: the same IEEE operations as row by row, hence the same bits
            cols = tuple(X[:, i] for i in range(d))
            residuals = np.asarray(section_event_function(cols[0:3], cols[3:6], g0)).astype(float)
            public = np.empty_like(X)
            for i, v in enumerate(system.to_public(tuple(pars), cols)):
                public[:, i] = v
        else:
            ev = [section_event_function(tuple(x[0:3]), tuple(x[3:6]), g0) for x in X]
            residuals = np.array([float(e) for e in ev], dtype=float)
            public = np.array([public_state(system, pars, x, spec) for x in X], dtype=spec.dtype).reshape(-1, d)
        return SectionResult(
            kind=prob.kind,
            points=self.chart(X),
            times=np.array([float(t) for t in c.times], dtype=float),
            states=public,
            residuals=residuals,
            integrals={k: v for k, v in I.items()},
            drift=drift,
            # every kind with a section (SECTION_KINDS) has levels, which mypy cannot know
            levels=system.info.levels({k: v[0] for k, v in I0.items()}),  # type: ignore[misc]
            outcome=c.outcome,
            message=c.message,
            t_end=c.t_end,
            n_steps=c.n_steps,
            wall_time=c.wall,
            meta=_provenance(self),
        )


@dataclass(frozen=True)
class _Run:
    """How long a section run goes: ``n_points`` crossings, at most to ``t_max`` (default
    ``1e4 * n_points``), in chunks of ``chunk`` time units (boundaries at ``k * chunk``)."""

    n_points: int
    t_max: Optional[float]
    chunk: float

    @property
    def limit(self) -> float:
        return float(self.t_max) if self.t_max is not None else 1e4 * self.n_points

    def completed(self, times) -> str:
        return f"collected {self.n_points} crossings by t={float(times[self.n_points - 1]):.6g}"

    def ran_out(self, n_found) -> str:
        return (f"reached t_max={self.limit:.6g} with {n_found} of {self.n_points} crossings; "
                + Outcome.T_MAX.remedy)


@dataclass
class _Crossings:
    """What a run found: crossing times and internal states (at most ``n_points``), how it
    ended, the time and step count where it stopped and its wall time."""

    times: list
    states: list
    outcome: Outcome
    message: str
    t_end: float
    n_steps: int
    wall: float


def poincare_section(
    kind: Literal["reduced", "mparallel"],
    params: ParamsLike,
    state: ArrayLike,
    *,
    n_points: int,
    g0: float = 0.0,
    direction: Direction = 1,
    t_max: Optional[float] = None,
    fp_type: FpTypeLike = float,
    prec: Optional[int] = None,
    tol: Optional[float] = None,
    chunk: float = 100.0,
    progress: ProgressLike = False,
) -> SectionResult:
    """Crossings of an orbit with the section ``g = g0``.

    A thin wrapper: ``Section(problem(kind, params, fp_type=..., prec=..., tol=...), g0,
    direction).run(state, n_points=..., ...)``.

    Parameters
    ----------
    kind : {"reduced", "mparallel"}
        The reduced system (3D map in ``(l, r1, r2)``) or the M||gamma system (2D map in
        ``(l, L/G)``).
    params : BallParams or MParallelParams
    state : array_like
        Initial state in the public layout of ``kind``.
    n_points : int
        Number of crossings to collect (> 0).
    g0 : float
        Section angle, in ``[0, 2 pi)``.
    direction : {1, -1, 0}
        ``+1``: ``g`` increasing through ``g0``; ``-1``: decreasing; ``0``: both.
    t_max : float, optional
        Give up at this time (default: ``1e4 * n_points`` time units, a guard against
        orbits that never cross; the result then says so).
    fp_type, prec, tol
        Number type and tolerance, as for :func:`taylorball.propagate`.
    chunk : float
        Time per integration chunk (default 100); boundaries at multiples of it.
    progress : bool
        Show a progress bar (tqdm), in fractions of the orbit (collected crossings over
        ``n_points``).

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
    _check_kind(kind)
    _check_run(n_points, t_max, chunk)
    sec = Section(problem(kind, params, fp_type=fp_type, prec=prec, tol=tol), g0, direction)
    return sec.run(state, n_points=n_points, t_max=t_max, chunk=chunk, progress=progress)


@dataclass(frozen=True, eq=False)
class _SectionJob:
    """One orbit's section as a member of :func:`taylorball.ensemble.run_many` (called with
    the member's context): what :func:`poincare_section` computes, for it and for every
    orbit of :func:`poincare_sections` (scalar mode), hence the same bits."""

    section: "Section"
    state: object
    run: "_Run"

    def __call__(self, ctx) -> SectionResult:
        return self.section._run(start_state(self.section.problem, self.state), self.run, ctx)


def _on_branch(internal_row, g0):
    """True on the half-line g = g0 (not g0 + pi): num sin g0 + den cos g0 > 0."""
    num, den = g_angle_parts(tuple(internal_row[0:3]), tuple(internal_row[3:6]))
    return float(num) * math.sin(g0) + float(den) * math.cos(g0) > 0.0


_VECTOR_TYPES = ("float", "longdouble")  # numpy arithmetic on whole columns is exact IEEE


def _branch_mask(states, g0, spec):
    """:func:`_on_branch` for a list of internal states, on whole columns for float64 and
    long double (the same operations, hence the same bits, as row by row)."""
    if not states:
        return np.zeros(0, dtype=bool)
    if spec.name not in _VECTOR_TYPES:
        return np.array([_on_branch(x, g0) for x in states], dtype=bool)
    X = np.asarray(states)
    num, den = g_angle_parts(tuple(X[:, i] for i in range(3)), tuple(X[:, i] for i in range(3, 6)))
    return np.asarray(num, dtype=float) * math.sin(g0) + np.asarray(den, dtype=float) * math.cos(g0) > 0.0


#: Crossings within this time of the start are the start itself (an initial state built on
#: the section, e.g. by :func:`taylorball.states_on_section`, has ``e = 0`` to rounding and
#: heyoka may or may not report a root at ``t ~ 1e-17``): never reported, so the points are
#: always the returns ``P(x0), P^2(x0), ...`` whatever the rounding.
START_TOL = 1e-12


#: The step callback that stops a run at its last crossing costs ~7 % of a Taylor step, so a
#: chunk drops it (:meth:`_Collector.arm`) once its first roots show that it will not bring
#: the crossings still needed: after every ``RATE_CHECK`` roots, if more than ``STOP_MARGIN``
#: times what the rate so far predicts for the rest of the chunk are needed.
RATE_CHECK, STOP_MARGIN = 4, 1.25


def _chunks(section, ta, run, ctx) -> _Crossings:
    """The chunk loop of one orbit: integrate ``ta`` until ``run.n_points`` crossings (or
    the limit); ``ctx`` (:class:`taylorball.ensemble.Context`) is checked at every chunk
    boundary (Ctrl-C) and told the fraction of crossings collected.

    The chunk that brings the ``n_points``-th crossing stops after the step where heyoka
    found it (a step callback; the steps before are those of the whole chunk, so the
    crossings keep their bits); ``t_end`` and ``n_steps`` are then those of that step's
    end, inside the chunk."""
    import heyoka as hy

    wall0 = _time.perf_counter()
    n_points, t_max, spec = run.n_points, run.limit, section.problem.spec
    cb = ta.nt_events[0].callback
    times: list = []
    states: list = []
    n_steps = 0
    outcome, message = Outcome.T_MAX, ""
    k_chunk = 0
    reported = 0
    ends = (hy.taylor_outcome.time_limit, hy.taylor_outcome.cb_stop)

    def kept(ts, xs):
        return sum(1 for t, keep in zip(ts, section.on_branch(xs)) if keep and t > START_TOL)

    while True:
        ctx.check()
        k_chunk += 1
        t_now = float(ta.time)
        t_next = min(k_chunk * float(run.chunk), t_max)
        try:
            stop = cb.arm(ta, kept, n_points - len(times), t_now, t_next)
            res = ta.propagate_until(spec.scalar(t_next), callback=stop)
            if res[0] == hy.taylor_outcome.cb_stop and cb.paused:
                n_steps += int(res[3])
                cb.disarm()
                res = ta.propagate_until(spec.scalar(t_next))
        finally:
            cb.disarm()
        n_steps += int(res[3])
        if res[0] not in ends:
            outcome = Outcome.STOPPED
            message = (
                f"the integrator stopped at t={float(ta.time):.6g} with outcome {res[0]}: a non-finite state "
                "(singular configuration or escape); the crossings found before are kept"
            )
            break
        for t, s, keep in zip(cb.times, cb.states, section.on_branch(cb.states)):
            if keep and t > START_TOL:
                times.append(t)
                states.append(s)
        cb.times.clear()
        cb.states.clear()
        if min(len(times), n_points) > reported:
            ctx.advance((min(len(times), n_points) - reported) / n_points)
            reported = min(len(times), n_points)
        if len(times) >= n_points:
            outcome = Outcome.COMPLETED
            message = run.completed(times)
            break
        if t_next >= t_max:
            message = run.ran_out(len(times))
            break
    return _Crossings(times[:n_points], states[:n_points], outcome, message, float(ta.time), n_steps,
                      _time.perf_counter() - wall0)


# ---------------------------------------------------------------------------------------
# Batch mode: several orbits in the SIMD lanes of one integrator (float64 only).
# ---------------------------------------------------------------------------------------
def batch_size() -> int:
    """Lanes of heyoka's batch mode used for float64 sections (``hy.recommended_simd_size()``,
    4 with AVX2/AVX-512 doubles)."""
    import heyoka as hy

    return max(1, int(hy.recommended_simd_size()))


def _batch_template(kind, tol, g0, direction, size):
    """Compiled float64 batch integrator with the section event (cached; copy it)."""

    def build():
        import heyoka as hy

        system = get_system(kind)
        _event_field_cfunc(kind, g0)
        ev = hy.nt_event_batch(_event_expression(kind, g0), _BatchCollector(size),
                               direction=_direction(direction))
        kw = dict(pars=np.zeros((system.n_pars, size)), nt_events=[ev])
        if tol is not None:
            kw["tol"] = float(tol)
        return hy.taylor_adaptive_batch(system.equations(), np.full((system.dim, size), 0.1), **kw)

    return compiled(("batch", kind, get_system(kind).formulation, "float", None if tol is None else float(tol), size,
                     "section", float(g0), int(direction)), build)


def _run_batch(sec: "Section", states, run: "_Run", threads=None, progress=False):
    """Sections of many orbits in the SIMD lanes of batch integrators (float64), one per
    thread, a lane refilled with the next orbit as soon as its orbit has ``n_points``
    crossings (``taylorball.ensemble.run_many(..., backend="lanes")``).

    Each orbit runs on its own clock through the chunk boundaries ``k chunk``, as a scalar
    run does, and its result is cut at the chunk boundary where it has ``n_points``
    crossings (``t_end``, ``n_steps`` from there; a scalar run stops earlier, after the
    step of its last crossing). So a result
    depends only on its own initial state (lanes are independent in heyoka's batch mode).
    Returns one :class:`SectionResult` per state, ``None`` for an orbit whose integration
    stopped with an error (the caller reruns those in scalar mode, which reports the
    error). ``progress`` as for :func:`taylorball.ensemble.run_many`, in orbits' worth of
    crossings (after every chunk)."""
    from .ensemble import LaneLoad, LaneTask, run_many

    prob, kind, g0 = sec.problem, sec.kind, sec.g0
    n_points, t_max = run.n_points, run.limit
    size = batch_size()
    n = len(states)
    internal = [start_state(prob, s) for s in states]
    pars = np.asarray(prob.pars, dtype=float)
    times: List[List[float]] = [[] for _ in range(n)]
    states_out: List[List[np.ndarray]] = [[] for _ in range(n)]
    steps = np.zeros(n, dtype=np.int64)
    done_at = [None] * n  # (t_end, n_steps) when the orbit got n_points crossings
    end_t = [0.0] * n
    failed = [False] * n
    wall0 = [0.0] * n
    walls = [0.0] * n

    def load(j):
        wall0[j] = _time.perf_counter()
        return LaneLoad(internal[j], pars, 0.0, t_max, float(run.chunk))

    def after_chunk(ta, chunks):
        cb = ta.nt_events[0].callback
        recs, cb.records = cb.records, []
        job_of = {c.lane: c.job for c in chunks}
        lanes, ts, xs = _refine_batch_records(kind, g0, [r for r in recs if r[0] in job_of], pars)
        keep = sec.on_branch(xs)
        for lane, t, x, k in zip(lanes, ts, xs, keep):
            if k and t > START_TOL:
                j = job_of[lane]
                times[j].append(t)
                states_out[j].append(x)
        done = []
        for c in chunks:
            steps[c.job] += c.steps
            end_t[c.job] = c.t
            d = len(times[c.job]) >= n_points
            if d:
                done_at[c.job] = (c.t, int(steps[c.job]))
            if d or c.last:
                walls[c.job] = _time.perf_counter() - wall0[c.job]
            done.append(d)
        return done

    def on_fail(j, outcome, t):
        failed[j] = True

    def result(j):
        if failed[j]:
            return None
        if done_at[j] is not None:
            t_end, n_steps = done_at[j]
            outcome, message = Outcome.COMPLETED, run.completed(times[j])
        else:
            t_end, n_steps = end_t[j], int(steps[j])
            outcome, message = Outcome.T_MAX, run.ran_out(len(times[j]))
        r = sec._finish(internal[j], _Crossings(times[j][:n_points], states_out[j][:n_points], outcome, message,
                                               float(t_end), n_steps, walls[j]))
        r.meta["batch"] = {"size": size, "note": "orbits share SIMD lanes; wall_time is the orbit's time in a lane"}
        return r

    task = LaneTask(sec.batch_integrator(size), n, load=load, after_chunk=after_chunk,
                    failed=on_fail, fraction=lambda c: min(len(times[c.job]), n_points) / n_points,
                    result=result)
    return run_many(task, backend="lanes", workers=threads, progress=progress)


# ---------------------------------------------------------------------------------------
# Many orbits.
# ---------------------------------------------------------------------------------------
def poincare_sections(
    kind: Literal["reduced", "mparallel"],
    params: ParamsLike,
    states: StatesLike,
    *,
    n_points: int,
    g0: float = 0.0,
    direction: Direction = 1,
    t_max: Optional[float] = None,
    fp_type: FpTypeLike = float,
    prec: Optional[int] = None,
    tol: Optional[float] = None,
    threads: Optional[int] = None,
    progress: ProgressLike = False,
    batch: bool = False,
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
    states : sequence of array_like
        Initial states (public layout).
    threads : int, optional
        Worker threads (default: ``os.cpu_count()``); ``1`` runs serially.
    batch : bool
        Use batch mode (default ``False``): ~2.3x the throughput per core for many
        float64 orbits (``benchmarks/bench_sections.py``), at the price of bit-identity with
        :func:`poincare_section`. Only float64 has a batch mode (``UsageError``
        otherwise). An orbit whose lane stops with an error is rerun alone in scalar
        mode, which reports the error.

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
    >>> secs = tb.poincare_sections("reduced", FIG4_BALL, xs, n_points=5, threads=2)
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

    try:
        states = list(states)
    except TypeError:
        raise StateError(f"states must be a sequence of initial states, got {states!r}") from None
    if not states:
        raise UsageError("states must contain at least one initial state")
    _check_kind(kind)
    _check_run(n_points, t_max, 100.0)
    if threads is not None:
        count("threads", threads)
    sec = Section(problem(kind, params, fp_type=fp_type, prec=prec, tol=tol), g0, direction)
    if batch and sec.problem.spec.name != "float":
        raise UsageError(f"batch=True needs fp_type=float (heyoka's batch mode is float64 only), "
                         f"got {sec.problem.spec}")
    # validate every state before starting threads
    for s in states:
        start_state(sec.problem, s)
    n = threads or os.cpu_count() or 1
    jobs = [_SectionJob(sec, s, _Run(n_points, t_max, 100.0)) for s in states]
    label = f"sections {kind}" if progress is True else progress
    if batch:
        out = _run_batch(sec, states, _Run(n_points, t_max, 100.0), threads=n, progress=label)
        # an orbit whose lane stopped with an error: rerun alone, which reports the error
        again = [i for i, r in enumerate(out) if r is None]
        for i, r in zip(again, run_many([jobs[i] for i in again], backend="serial")):
            out[i] = r
        return out
    sec.integrator()  # compile before starting threads
    # Ctrl-C: the running orbits stop at their next chunk, the queued ones are dropped
    return run_many(jobs, backend="threads", workers=n, progress=label)
