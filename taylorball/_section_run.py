"""One section run: its results (:class:`Outcome`, :class:`SectionResult`), its checks and
the chunk loop of one orbit (:func:`_chunks`), shared by the scalar runs of
:mod:`taylorball.sections` and the lanes of :mod:`taylorball._section_batch`."""

from __future__ import annotations

import enum
import math
import time as _time
from dataclasses import dataclass, field
from typing import Callable, Dict, Optional

import numpy as np

from .charts import g_angle_parts
from .errors import UsageError
from .numbers import real_number

__all__ = ["Outcome", "SectionResult", "START_TOL", "MAX_POINTS"]


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
            "t_max": "increase t_end (or check that the orbit crosses the section at all: the section may miss "
                     "its level set, or the event function may never vanish on the orbit)",
            "error": "check the initial state and parameters for a singular configuration "
                     "(1 - d (gamma, A gamma) = 0) or an escaping orbit; the crossings found before are kept",
        }[self.value]


@dataclass(frozen=True)
class SectionResult:
    """Crossings of one orbit with the section ``g = g0``.

    Attributes
    ----------
    points : ndarray, shape (n, k)
        The section's chart at each crossing: ``(l, r1, r2)`` (reduced) or ``(l, L/G)``
        (mparallel) by default, the columns named by ``meta["chart"]`` otherwise.
    times : ndarray, shape (n,)
    states : ndarray, shape (n, d)
        Public-layout states at the crossings (dtype of the integration).
    residuals : ndarray, shape (n,)
        Event function at the recorded states (0 exactly on the section; of the size of the
        state, ``|e| <= 1`` for the paper's section).
    integrals : dict of str -> ndarray (n,)
        The first integrals at each crossing.
    drift : dict of str -> float
        ``max |I - I(0)|`` over the crossings, relative to the integral's scale, with
        ``I(0)`` at the initial state.
    levels : dict of str -> float
        The integrals at the initial state (``C = sqrt(C2)``, ``M_gamma``, ``h = E``, or
        ``lambda``, ``h``; the full system's ``F1, F2, F3, E``).
    outcome : Outcome
        :attr:`Outcome.COMPLETED` (``"n_points"``: all requested crossings found),
        :attr:`Outcome.T_MAX` (``"t_max"``: the end time ``t_end`` reached first) or
        :attr:`Outcome.STOPPED` (``"error"``: the integrator stopped); ``outcome.remedy``
        says what to do.
    message : str
        Human-readable account of how the run ended and what to do about it.
    t_end : float
        Time where the integration stopped: for a completed scalar run the end of the
        Taylor step that found the last crossing (``times[-1] <= t_end``, within one step;
        a batch-mode run, ``poincare_sections(batch=True)``, ends at the chunk boundary
        after it), else the run's end time or where the integrator stopped.
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
        "section": section.describe(),
        "chart": list(section.chart_names),
        "taylorball": __version__,
        "heyoka": hy.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }


#: At most this many crossings per orbit (each is kept in memory: ~100 bytes).
MAX_POINTS = 10_000_000
#: At most ``max(MAX_CHUNKS, CHUNKS_PER_POINT * n_points)`` chunks (Python round trips)
#: per orbit, so the work a call implies stays proportional to what it asks for.
MAX_CHUNKS, CHUNKS_PER_POINT = 1_000_000, 1000


def _check_run(n_points, t_end, chunk):
    if not (isinstance(n_points, (int, np.integer)) and not isinstance(n_points, bool)
            and 1 <= n_points <= MAX_POINTS):
        raise UsageError(f"n_points must be a positive integer (at most {MAX_POINTS}), got {n_points!r}")
    if t_end is not None and not (isinstance(t_end, (int, float, np.integer, np.floating))
                                  and not isinstance(t_end, bool) and math.isfinite(t_end) and t_end > 0):
        raise UsageError(f"t_end must be > 0 and finite (a time), got {t_end!r}")
    chunk = real_number("chunk", chunk, lo=0.0, lo_open=True)
    limit = float(t_end) if t_end is not None else 1e4 * n_points
    cap = max(MAX_CHUNKS, CHUNKS_PER_POINT * n_points)
    if limit / chunk > cap:
        raise UsageError(f"chunk={chunk!r} cuts the run to t_end={limit:g} into {limit / chunk:.3g} chunks, more than "
                         f"{cap}: use chunk >= {limit / cap:.3g} (or a smaller t_end)")


@dataclass(frozen=True)
class _Run:
    """How long a section run goes: ``n_points`` crossings, at most to ``t_end`` (default
    ``1e4 * n_points``), in chunks of ``chunk`` time units (boundaries at ``k * chunk``)."""

    n_points: int
    t_end: Optional[float]
    chunk: float
    #: called after every chunk with the new crossings' times and internal states (lists);
    #: it may raise to abandon the run (its exception propagates)
    watch: Optional[Callable[[list, list], None]] = field(default=None, compare=False)

    @property
    def limit(self) -> float:
        return float(self.t_end) if self.t_end is not None else 1e4 * self.n_points

    def completed(self, times) -> str:
        return f"collected {self.n_points} crossings by t={float(times[self.n_points - 1]):.6g}"

    def ran_out(self, n_found) -> str:
        return (f"reached t_end={self.limit:.6g} with {n_found} of {self.n_points} crossings; "
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

    masks: dict = {}  # first root's index -> the branch test of the roots classified by the stop callback

    def kept(ts, xs):
        # a root at the start itself (t <= START_TOL) is never kept: no branch test for it
        mask = (np.zeros(len(ts), dtype=bool) if all(t <= START_TOL for t in ts)
                else section.on_branch(xs))
        masks[len(cb.times) - len(ts)] = (len(ts), mask)
        return sum(1 for t, keep in zip(ts, mask) if keep and t > START_TOL)

    def on_branch(states):
        """The branch test of this chunk's roots, reusing what the stop callback classified
        (one test or several in a row covering all of them)."""
        done, parts = 0, []
        while done in masks:
            n, mask = masks[done]
            parts.append(mask)
            done += n
        if parts and done == len(states):
            return parts[0] if len(parts) == 1 else np.concatenate(parts)
        return section.on_branch(states)

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
        cb.refine(ta.pars)  # a deferred collector's Newton steps (float64); nothing otherwise
        if res[0] not in ends:
            outcome = Outcome.STOPPED
            message = (
                f"the integrator stopped at t={float(ta.time):.6g} with outcome {res[0]}: a non-finite state "
                "(singular configuration or escape); the crossings found before are kept"
            )
            break
        for t, s, keep in zip(cb.times, cb.states, on_branch(cb.states)):
            if keep and t > START_TOL:
                times.append(t)
                states.append(s)
        cb.clear()
        masks.clear()
        if run.watch is not None and len(times) > reported:
            run.watch(times[reported:n_points], states[reported:n_points])
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
