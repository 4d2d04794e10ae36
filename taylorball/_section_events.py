r"""The events of Poincaré sections: the paper's section ``g = g0`` and sections of the
user's choosing, their compiled functions and the callbacks that record crossings.

An event here is an object with what a run needs of it (:class:`PaperEvent`,
:class:`UserEvent`): its heyoka expression in the internal variables, the compiled
``x -> (e, de/dt)`` used to refine crossings, the float64 ``x -> (e, de/dt, f(x))`` of
batch mode, the extra runtime parameters it takes and a key naming it in the cache.

**Order 1.** heyoka's step-size control takes the event functions' Taylor coefficients
into account with the state's (measured on the Fig. 4a orbit over 200 time units: an event
``gamma3`` or ``R1`` leaves the 3366 steps bit-identical to a run without events; ``10
gamma3`` changes them to 3365, ``1e10 gamma3`` to 2994). So an event function larger than
the state changes the orbit's steps, and a function of the user's would make the orbit
depend on how the section is written. The paper's event is ``|e| <= 1`` by construction
(:func:`taylorball.charts.section_event_function`); a user's function ``f`` is scaled by a
runtime weight ``w``, the event being ``e = w f`` with

.. math:: w = \min\Bigl(1, \frac{N}{F}\Bigr),\qquad N = \max_i |x_i(0)|,\qquad
          F = \max\bigl(|f(x(0))|,\ N \textstyle\sum_i |\partial f/\partial x_i(x(0))|\bigr),

``x`` the internal variables at the start of the orbit: ``F`` bounds the size of ``f`` on
the level of the orbit's start, so ``|e|`` stays at the size of the state and the steps are
those of the orbit without the section (a component of the state, e.g. ``gamma3`` or
``R1``, keeps ``w = 1``; ``1e10 gamma3`` gets ``w = 1e-10``). ``w`` is ``par[n]`` after the
system's ``n`` parameters, set per orbit from its own start, so an orbit's crossings depend
only on its initial state (and one compiled integrator serves every orbit and level).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Dict, Tuple

import numpy as np

from .charts import section_event_function
from .errors import UsageError
from ._cache import compiled
from .model import get_system
from .numbers import resolve_fp_type
from ._problem import Problem

__all__ = ["PaperEvent", "UserEvent", "user_event", "RATE_CHECK", "STOP_MARGIN"]

#: A deferred collector refines up to this many roots one by one, more on whole columns
#: (:meth:`_Collector.refine`; the two give the same bits).
_FEW_ROOTS = 8

#: The step callback that stops a run at its last crossing costs ~7 % of a Taylor step, so a
#: chunk drops it (:meth:`_Collector.arm`) once its first roots show that it will not bring
#: the crossings still needed: after every ``RATE_CHECK`` roots, if more than ``STOP_MARGIN``
#: times what the rate so far predicts for the rest of the chunk are needed.
RATE_CHECK, STOP_MARGIN = 4, 1.25


def _newton_delta(e, de, hi, h, eps):
    """One crossing's Newton step in time, ``e / (de/dt)``, or None where it is not to be
    trusted: ``de/dt = 0`` (or NaN), or a step larger than a rounding-size correction
    (``64 eps (|t| + |h|)``, a few ulp of the time; anything larger means a grazing crossing
    where one Newton step is no refinement). :meth:`_Collector.refine` applies the same
    test on columns."""
    if de != 0:
        delta = e / de
        if abs(delta) <= 64 * eps * (abs(hi) + abs(h)):
            return delta
    return None


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

    def __init__(self, event, spec_key, deferred=False):
        self.event_def, self.spec_key = event, spec_key
        spec = resolve_fp_type(*spec_key)
        self.eps = spec.eps
        self.times = []
        self.states = []
        # deferred (float64 only): the callback records, :meth:`refine` applies the Newton step
        # to all roots of a propagation at once
        self.deferred = bool(deferred) and spec.name == "float"
        self._steps: list = []  # deferred: (hi, lo, rel, last_h) of each root not yet refined
        # looked up once per integrator copy, not per crossing
        self.event = event.field_cfunc() if self.deferred else event.cfunc(spec_key)
        self.disarm()

    def __deepcopy__(self, memo):
        return _Collector(self.event_def, self.spec_key, self.deferred)

    def clear(self):
        """Forget every recorded root."""
        self.times.clear()
        self.states.clear()
        self._steps.clear()

    def refine(self, pars):
        """Deferred mode: the Newton step of :meth:`__call__` for every root recorded since the
        last call, on whole columns (one compiled ``(e, de/dt, f)`` evaluation; ~8 us per
        root less than in the callback). The crossing time is the callback's, bit for bit
        (``rel - delta`` from the same ``e``, ``de/dt`` and the same test); the state is the
        dense output's first-order Taylor step there, ``x - delta f(x)`` (as in batch mode),
        instead of the dense output evaluated again: it differs from it by rounding (an ulp
        or two of each component) plus ``O(delta^2)`` (~1e-26 for the rounding-size
        ``delta`` accepted). Parameters ``pars``: the integrator's."""
        n = len(self._steps)
        if not n:
            return
        if n <= _FEW_ROOTS:
            self._refine_each(pars, n)
            return
        hi, lo, rel, h = np.array(self._steps, dtype=float).T
        X = np.array(self.states[-n:], dtype=float)
        cols = np.repeat(np.asarray(pars, dtype=float)[:, None], n, axis=1)
        e, de, *f = self.event(X.T.copy(), pars=cols)
        nz = de != 0
        delta = np.divide(e, de, out=np.zeros(n), where=nz)
        ok = nz & (np.abs(delta) <= 64 * self.eps * (np.abs(hi) + np.abs(h)))  # NaN: not ok
        delta[~ok] = 0.0  # the time and the state as recorded
        X[ok] -= delta[ok, None] * np.array(f).T[ok]
        self.times[-n:] = (hi + (lo + (rel - delta))).tolist()
        self.states[-n:] = list(X)
        self._steps.clear()

    def _refine_each(self, pars, n):
        """:meth:`refine` root by root (a call's fixed cost is ~25 us of NumPy on columns,
        ~5 us per root here): the same operations on each root, hence the same bits
        (``tests/test_sections_refine.py``)."""
        pars = np.asarray(pars, dtype=float)
        base = len(self.times) - n
        for k, (hi, lo, rel, h) in enumerate(self._steps):
            x = self.states[base + k]
            out = self.event(x, pars=pars)
            delta = _newton_delta(float(out[0]), float(out[1]), hi, h, self.eps)
            if delta is not None:
                rel = rel - delta
                self.states[base + k] = x - delta * out[2:]
            self.times[base + k] = hi + (lo + rel)
        self._steps.clear()

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
        if self.deferred:
            self._steps.append((hi, lo, rel, ta.last_h))
            self.times.append(hi + (lo + rel))
            self.states.append(x.copy())
            if len(self.times) >= self.next_check:
                self._check()
            return
        e, de = self.event(x, ta.pars)
        delta = _newton_delta(e, de, hi, ta.last_h, self.eps)
        if delta is not None:
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


def _refine_batch_records(event, records, pars):
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
    pars = np.asarray(pars, dtype=float)
    # one parameter vector for every record, or one row per record (a user event's weight
    # differs between orbits)
    cols = np.repeat(pars[:, None], len(X), axis=1) if pars.ndim == 1 else np.ascontiguousarray(pars.T)
    out = event.field_cfunc()(np.ascontiguousarray(X.T), pars=cols)
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
    """Compiled ``x -> (e(x), de/dt(x))`` for the paper's section event (cached)."""
    return _cfunc_pair(("paper", kind, float(g0)), lambda: _event_parts(kind, g0), spec_key)


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
        raise UsageError(f"direction must be +1 (the event function increasing through 0; g increasing through g0 "
                         f"for the paper's section), -1 (decreasing) or 0 (both), got {direction!r}")
    return table[direction]


def _cfunc_pair(key, parts, spec_key):
    """Compiled ``(x, pars) -> (e(x), de/dt(x))`` of an event's ``parts()`` (cached)."""

    def build():
        import heyoka as hy

        spec = resolve_fp_type(*spec_key)
        xs, e, de, _ = parts()
        kw = dict(fp_type=spec.fp_type, compact_mode=True)
        if spec.prec is not None:
            kw["prec"] = spec.prec
        cf = hy.cfunc([e, de], xs, **kw)
        n_par = cf.nparams

        def f(x, pars, _cf=cf, _n=n_par):
            out = _cf(x, pars=pars[:_n])
            return out[0], out[1]

        return f

    return compiled(("cfunc", "section event", *key, str(resolve_fp_type(*spec_key))), build)


@dataclass(frozen=True)
class PaperEvent:
    """The paper's section ``g = g0`` (section 4; section 5 for M||gamma): the event of
    :func:`taylorball.charts.section_event_function` in the kind's default formulation,
    with the branch test that drops the half-line ``g = g0 + pi``."""

    kind: str
    g0: float
    n_extra = 0
    branch = True

    @property
    def key(self) -> Tuple:
        return ("paper", self.kind, float(self.g0))

    def expression(self) -> Any:
        return _event_expression(self.kind, self.g0)

    def cfunc(self, spec_key) -> Any:
        return _event_cfunc(self.kind, spec_key, self.g0)

    def field_cfunc(self) -> Any:
        return _event_field_cfunc(self.kind, self.g0)

    def residuals_cols(self, cols) -> Any:
        """The event function on columns (or a row) of internal states."""
        return section_event_function(cols[0:3], cols[3:6], self.g0)

    def extra_pars(self, internal) -> Tuple[float, ...]:
        return ()

    def describe(self) -> str:
        return f"g = {self.g0:g}"


@dataclass(frozen=True)
class UserEvent:
    """A section ``f = 0`` of the user's choosing: ``f`` a smooth scalar function of the
    public variables (a heyoka expression), rewritten in the internal variables of the
    problem's formulation through its public <-> internal maps and weighted by the runtime
    parameter ``w = par[n]`` (see the module's notes on order 1)."""

    kind: str
    formulation: str
    text: str  #: ``str(f)``: names the event in keys and messages
    public: Any = field(compare=False, hash=False, repr=False)  #: ``f`` in the public variables
    n_extra = 1
    branch = False

    @property
    def key(self) -> Tuple:
        return ("user", self.kind, self.formulation, self.text)

    def _internal(self):
        import heyoka as hy

        system = get_system(self.kind, self.formulation)
        xs = hy.make_vars(*system.internal_names)
        pub = system.to_public([hy.par[i] for i in range(system.n_pars)], xs)
        f = hy.subs(self.public, {n: p for n, p in zip(system.public_names, pub)})
        return system, xs, f

    def parts(self):
        """``(xs, e, de/dt, rhs)`` with ``e = w f`` (``w = par[n]``)."""
        import heyoka as hy

        system, xs, f = self._internal()
        e = f * hy.par[system.n_pars]
        rhs = system.rhs([hy.par[i] for i in range(system.n_pars)], xs)
        de = hy.sum([hy.diff(e, x) * fx for x, fx in zip(xs, rhs)])
        return xs, e, de, rhs

    def expression(self) -> Any:
        return self.parts()[1]

    def cfunc(self, spec_key) -> Any:
        return _cfunc_pair(self.key, self.parts, spec_key)

    def field_cfunc(self) -> Any:
        def build():
            import heyoka as hy

            xs, e, de, rhs = self.parts()
            return hy.cfunc([e, de] + list(rhs), xs, compact_mode=True)

        return compiled(("cfunc", "section event+field", *self.key), build)

    def _grad_cfunc(self, spec_key) -> Any:
        """``x -> (f, df/dx_1, ..., df/dx_n)`` (unweighted; cached)."""

        def build():
            import heyoka as hy

            system, xs, f = self._internal()
            spec = resolve_fp_type(*spec_key)
            kw = dict(fp_type=spec.fp_type, compact_mode=True)
            if spec.prec is not None:
                kw["prec"] = spec.prec
            return hy.cfunc([f] + [hy.diff(f, x) for x in xs], xs, **kw)

        return compiled(("cfunc", "section event gradient", *self.key, str(resolve_fp_type(*spec_key))), build)

    def weight(self, internal, pars, spec_key) -> float:
        """``w = min(1, N / F)`` at the internal start state (module notes)."""
        cf = self._grad_cfunc(spec_key)
        out = np.asarray(cf(np.asarray(internal), pars=np.asarray(pars)[: cf.nparams]), dtype=float)
        x = np.abs(np.asarray(internal, dtype=float))
        N = float(np.max(x)) if x.size else 1.0
        F = max(abs(float(out[0])), N * float(np.sum(np.abs(out[1:]))))
        if not (math.isfinite(F) and math.isfinite(N)):
            raise UsageError(f"the section's event {self.text} is not finite at the initial state "
                             f"(f = {float(out[0])!r}): choose a function that is smooth on the orbit")
        return 1.0 if F <= N or F == 0.0 else N / F

    def residuals_cols(self, cols) -> Any:
        raise NotImplementedError  # evaluated through cfunc (it needs the weight)

    def describe(self) -> str:
        return f"{self.text} = 0"


def user_event(prob: Problem, event: Any) -> UserEvent:
    """The :class:`UserEvent` of ``event`` (a public variable's name or a heyoka expression
    in the public variables) for ``prob``, or a :class:`UsageError` listing the valid names."""
    import heyoka as hy

    names = prob.system.public_names
    valid = (f"a name among the public variables of kind={prob.kind!r} ({', '.join(names)}) or a heyoka "
             f"expression in them (e.g. hy.make_vars('{names[-1]}') - 0.5)")
    if isinstance(event, str):
        if event not in names:
            raise UsageError(f"event must be {valid}; got {event!r}")
        f = hy.make_vars(event)
    elif isinstance(event, hy.expression):
        used = list(hy.get_variables(event))
        bad = [v for v in used if v not in names]
        if bad:
            raise UsageError(f"event must be {valid}; got the expression {event} with unknown variable(s) "
                             f"{', '.join(bad)}")
        if not used:
            raise UsageError(f"event must be {valid}; got the constant expression {event}, which never crosses 0 "
                             "or is 0 everywhere")
        if list(hy.get_params(event)):
            raise UsageError(f"event must be {valid}, without runtime parameters (par[i] are the system's "
                             f"parameters); got {event}")
        f = event
    else:
        raise UsageError(f"event must be {valid}; got {event!r} of type {type(event).__name__}")
    return UserEvent(prob.kind, prob.formulation, str(f), f)
