"""Observables reduced on the fly during a long run, and their interface.

A long run (:mod:`taylorball.study`) integrates each orbit in *chunks* of
``checkpoint_every`` time units, each with one ``propagate_grid`` on the run's sample grid
``t_m = m * sample_dt``. After every chunk each observable receives a :class:`ChunkData`
(the chunk's grid, internal and public states, its event records) together with its
*carry* (small arrays it keeps from chunk to chunk: a running maximum, histogram counts,
a winding number), and returns its new carry and the *records* to append to its arrays
in the store. The carry is saved in the orbit's checkpoint, so a resumed run continues
exactly; everything an observable writes is a pure function of its options and the
orbit's states, so an interrupted and resumed run writes the same bytes.

Writing an observable
---------------------
An observable is a frozen dataclass satisfying :class:`Observable`:

* ``name``: its group in the store (``orbit_0003/<name>/<var>``);
* ``options()``: a JSON-able dict, part of the run's fingerprint;
* ``events(prob)``: heyoka ``nt_event`` objects it needs, ``[]`` if none. Each callback
  must keep ``times`` and ``states`` lists (as :class:`taylorball.sections._Collector`
  does); the runner reads them from the integrator after each chunk, hands them over in
  ``ChunkData.events`` (keyed by the event's index *in this observable's own list*) and
  clears them. An optional ``events_key()`` identifies the events in the compile cache
  (default: name and options). A non-terminal event leaves the orbit's bits alone only
  if its expression is built from state variables alone and shares no sub-expression with
  the vector field (heyoka decomposes field and events together; shared nodes change the
  rounding of the field's Taylor coefficients: docs/longruns.md). Events that obey this
  (the section's, the cuts of the lifted angle) let observables be switched on and off
  without changing the others' records;
* ``uses_grid()``, optional (default: true): whether ``chunk`` reads the chunk's sample
  grid (``t``, ``x``, ``public`` beyond their two ends). The lanes backend reads no samples
  when no observable does (an observable saying false gets the chunk's two ends only);
* ``layout(prob)``: its arrays, ``name -> Var(dims, dtype, shape)``; ``dims[0]`` is the
  append dimension (``"time"``, ``"crossing"``, ``"chunk"``, ...), the other dims are fixed
  with sizes ``shape``;
* ``init(prob, x0, t0)``: the first carry (``dict`` of small float64/int64 arrays);
* ``chunk(carry, data)``: ``(new carry, records)``, records a ``dict`` with one array per
  variable of the layout, all with the same first length (possibly 0).

It is built from its keys of the study file's ``[observables]`` table by a function
registered with :func:`register` (the study refuses keys that no builder reads).

The grid convention: chunk ``k`` covers ``[t0, t1]`` with both ends on the sample grid;
records on the sample grid are taken on ``(t0, t1]``, plus ``t0`` itself in the first
chunk, so that every grid time is recorded once. ``ChunkData.i`` holds the global sample
index ``m`` of each grid point, so thinning ("every 10 time units") is exact integer
arithmetic (``m % ratio == 0``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Mapping, Optional, Protocol, Sequence, Tuple, runtime_checkable

import numpy as np

from .errors import UsageError
from ._angle_lift import _CutCollector
from ._problem import Problem

__all__ = ["Var", "ChunkData", "Observable", "register", "builders", "build_observables", "observable_keys",
           "Drift", "Samples", "LiftedAngle", "grid_ratio", "Extremes", "Histogram", "Sections", "Heading"]

Carry = Dict[str, np.ndarray]
Records = Dict[str, np.ndarray]


@dataclass(frozen=True)
class Var:
    """One array of an observable: ``dims`` (the first is the append dimension), ``dtype``
    (a numpy dtype name: ``"float64"``, ``"int64"``, ``"int8"``, ...), ``shape`` (the sizes
    of ``dims[1:]``), a one-line ``doc`` (stored as the array's ``long_name``), its CF-style
    ``units`` (``"1"``: dimensionless, in the units of the ball's parameters; ``"rad"``)
    and, for records on a regular time grid, ``step``: record ``j`` is at ``t = j *
    step``, so no time array is stored (:func:`taylorball.open_run` adds the coordinate)."""

    dims: Tuple[str, ...]
    dtype: str = "float64"
    shape: Tuple[int, ...] = ()
    doc: str = ""
    step: Optional[float] = None
    units: str = "1"

    def __post_init__(self):
        if not self.dims or len(self.shape) != len(self.dims) - 1:
            raise UsageError(f"Var needs dims (append dim first) and one size per further dim, got dims={self.dims!r}, "
                             f"shape={self.shape!r}")
        np.dtype(self.dtype)

    def empty(self) -> np.ndarray:
        """A zero-length array of this variable."""
        return np.empty((0, *self.shape), dtype=self.dtype)


@dataclass(frozen=True)
class ChunkData:
    """What an observable sees of chunk ``k`` of one orbit.

    Attributes
    ----------
    k : int
        Chunk index; the chunk covers ``[t0, t1]``.
    t0, t1 : float
    t : ndarray, shape (n,)
        The chunk's sample grid (float64), both ends included.
    i : ndarray of int64, shape (n,)
        Global sample index ``m`` of each grid time (``t = m * sample_dt``).
    x : ndarray, shape (n, dim)
        Internal states at ``t`` (working number type).
    public : ndarray, shape (n, d)
        Public states at ``t`` (float64).
    events : dict of int -> list of (t, internal state)
        Records of this observable's own events found in the chunk, in time order, keyed by
        the event's index in the list :meth:`Observable.events` returned.
    problem : Problem
    n_steps : int
        Taylor steps of the chunk.
    sample_dt : float
    """

    k: int
    t0: float
    t1: float
    t: np.ndarray
    i: np.ndarray
    x: np.ndarray
    public: np.ndarray
    events: Mapping[int, List[Tuple[Any, np.ndarray]]]
    problem: Any
    n_steps: int
    sample_dt: float
    shared: Dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    def jets(self) -> np.ndarray:
        """``|R|^2``, ``(omega, gamma)`` and their first two time derivatives at the
        grid (:func:`taylorball._orbit_reductions._jets`, shape ``(6, n)``), computed once
        per chunk for every observable that shares ``shared`` (the runner gives one dict
        to all observables of a chunk)."""
        J = self.shared.get("jets")
        if J is None:
            J = self.shared["jets"] = _jets(self.problem.kind)(self.public, self.problem.params.pars)
        return J

    def fresh(self) -> np.ndarray:
        """Mask of the grid points this chunk records: ``(t0, t1]``, and ``t0`` too in the
        first chunk (every grid time is recorded exactly once over the run)."""
        mask = np.ones(len(self.t), dtype=bool)
        if self.k > 0:
            mask[0] = False
        return mask


@runtime_checkable
class Observable(Protocol):
    """The interface of an observable (see the module docstring)."""

    name: str

    def __init__(self, *args: Any, **kwargs: Any) -> None: ...

    def options(self) -> dict: ...

    def events(self, prob: Problem) -> list: ...

    def layout(self, prob: Problem) -> Dict[str, Var]: ...

    def init(self, prob: Problem, x0: np.ndarray, t0: float) -> Carry: ...

    def chunk(self, carry: Carry, data: ChunkData) -> Tuple[Carry, Records]: ...


def events_key(obs) -> Tuple:
    """Compile-cache key of an observable's events: its own ``events_key()`` if it has one
    (events that do not depend on all its options, e.g. a recording interval), else its
    name and options."""
    import json

    own = getattr(obs, "events_key", None)
    if own is not None:
        return tuple(own())
    return (obs.name, json.dumps(obs.options(), sort_keys=True))


# ---------------------------------------------------------------------------------------
# Registry of builders: [observables] keys -> observables.
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Builder:
    keys: Tuple[str, ...]
    defaults: Mapping[str, Any]
    build: Callable[[Dict[str, Any], float], Sequence[Any]]
    order: int
    needs: Tuple[str, ...] = ()
    off: Mapping[str, Any] = field(default_factory=dict)


_BUILDERS: List[_Builder] = []

#: What an observable may need of a system (attributes of its :class:`taylorball.model.Kind`),
#: in words for the error that refuses it.
NEEDS = {"contact": "the contact point R (a ball: kind 'reduced' or 'full')",
         "chart": "the section chart (kind 'reduced')",
         "levels": "the section's levels C, M_gamma, h (kind 'reduced')"}


def register(keys: Sequence[str], defaults: Mapping[str, Any], order: int = 100, *,
             needs: Sequence[str] = (),
             off: Optional[Mapping[str, Any]] = None) -> Callable[[Callable[..., Sequence[Any]]],
                                                                  Callable[..., Sequence[Any]]]:
    """Decorator registering ``build(values, sample_dt) -> list of observables`` for the
    ``[observables]`` keys ``keys`` (``values`` has every key, defaults filled in).
    ``build`` raises :class:`~taylorball.errors.UsageError` for a bad value, naming it as
    ``observables.KEY``, the value and the valid form (the study adds the file's name).

    ``needs`` names what the observables need of the system (keys of :data:`NEEDS`: the
    :class:`taylorball.model.Kind` attributes ``"contact"``, ``"chart"``, ``"levels"``);
    on a system without one of them the keys take their ``off`` values (each key's value
    that builds nothing) and any other value is refused by :func:`unavailable`'s user
    before any work."""
    unknown = set(needs) - set(NEEDS)
    if unknown or (needs and set(off or {}) != set(keys)):
        raise UsageError(f"register: needs must be among {sorted(NEEDS)} with an off value for every key, got "
                         f"needs={needs!r}, off={off!r}")

    def deco(fn):
        _BUILDERS.append(_Builder(tuple(keys), dict(defaults), fn, order, tuple(needs), dict(off or {})))
        _BUILDERS.sort(key=lambda b: b.order)
        return fn

    return deco


def unavailable(info: Any) -> Dict[str, Tuple[Any, str]]:
    """The ``[observables]`` keys a system cannot observe, ``key -> (off value, what it
    needs, in words)``, for the system's :class:`taylorball.model.Kind` ``info``."""
    out: Dict[str, Tuple[Any, str]] = {}
    for b in _BUILDERS:
        missing = [n for n in b.needs if getattr(info, n) is None]
        if missing:
            why = " and ".join(NEEDS[n] for n in missing)
            out.update({k: (b.off[k], why) for k in b.keys})
    return out


def builders() -> List[_Builder]:
    return list(_BUILDERS)


def observable_keys() -> Tuple[str, ...]:
    """Every key the ``[observables]`` table may hold."""
    return tuple(k for b in _BUILDERS for k in b.keys)


def build_observables(table: Mapping[str, Any], sample_dt: float) -> List[Any]:
    """The observables of a study's ``[observables]`` table (keys checked by the caller),
    in a fixed order; their names are unique."""
    out: List[Any] = []
    for b in _BUILDERS:
        values = {k: table.get(k, b.defaults[k]) for k in b.keys}
        out.extend(b.build(values, sample_dt))
    names = [o.name for o in out]
    if len(set(names)) != len(names):
        raise UsageError(f"two observables share a group name: {names}")
    return out


def _bool(key: str, v) -> bool:
    if not isinstance(v, bool):
        raise UsageError(f"observables.{key} must be true or false, got {v!r}")
    return v


def grid_ratio(key: str, every: Any, sample_dt: float, *, allow_zero: bool = False) -> int:
    """``every / sample_dt`` as a positive integer (0 if ``every == 0`` and
    ``allow_zero``); a clear error naming ``observables.KEY`` otherwise. A multiple is
    what :func:`taylorball.numbers.multiple_of` says it is (the check of
    ``checkpoint_every`` and ``t_end`` too): decimal multiples such as ``0.3`` of ``0.1``
    are, ``0.30000000001`` is not."""
    form = f"a positive multiple of sample_dt = {sample_dt!r}" + (" or 0 (off)" if allow_zero else "")
    if isinstance(every, bool) or not isinstance(every, (int, float)) or not math.isfinite(every):
        raise UsageError(f"observables.{key} must be {form}, got {every!r}")
    if every == 0 and allow_zero:
        return 0
    n = multiple_of(every, sample_dt) if every > 0 else None
    if n is None:
        raise UsageError(f"observables.{key} must be {form}, got {every!r}")
    if n > 10**12:
        raise UsageError(f"observables.{key} = {every!r} is {every / sample_dt:.3g} sample steps: must be "
                         f"{form}, at most 1e12 steps")
    return n


# ---------------------------------------------------------------------------------------
# drift: relative drift of the first integrals.
# ---------------------------------------------------------------------------------------
_PARTS = 3  # float64 parts of a reference value: 3 x 53 bits hold a real128 (113) exactly


def _split_parts(v) -> np.ndarray:
    """A working-precision number as ``_PARTS`` float64 whose exact sum is it (to 159 bits)."""
    out = np.zeros(_PARTS)
    r = v
    for j in range(_PARTS):
        out[j] = float(r)
        r = r - type(r)(out[j])
    return out


@dataclass(frozen=True)
class Drift:
    """Relative drift of each first integral at each chunk's end: ``|I - I0| / scale``, ``I0``
    at the orbit's start and ``scale`` from
    :func:`taylorball.integral_scales` there (the sum of the magnitudes of the integral's
    terms), computed in the working number type.

    Arrays (dim ``chunk``): ``t`` (the chunk's end) and ``drift`` (``(chunk, integral)``,
    the integrals of the kind in order: ``C2, M_gamma, E, gamma2, R_gamma`` for reduced);
    the running maximum is in the carry (``max``)."""

    name: str = "drift"

    def options(self) -> dict:
        return {}

    def uses_grid(self) -> bool:
        """The chunk's end state only."""
        return False

    def events(self, prob: Problem) -> list:
        return []

    def layout(self, prob: Problem) -> Dict[str, Var]:
        names = prob.system.info.integral_names
        return {"t": Var(("chunk",), "float64", doc="end time of the chunk"),
                "drift": Var(("chunk", "integral"), "float64", (len(names),),
                             doc="|I - I(0)| / scale at the chunk's end, for I in " + ",".join(names))}

    def init(self, prob: Problem, x0: np.ndarray, t0: float) -> Carry:
        from ._integrals import integrals_cfunc

        spec = prob.spec
        I0 = integrals_cfunc(prob.kind, prob.formulation, fp_type=spec.fp_type, prec=spec.prec)(x0[None, :], prob.pars)
        S0 = integrals_cfunc(prob.kind, prob.formulation, fp_type=spec.fp_type, prec=spec.prec,
                             which="scales")(x0[None, :], prob.pars)
        names = prob.system.info.integral_names
        # I(0) of each integral as float64 parts (exact), its scale, the running maximum
        return {"I0": np.array([_split_parts(I0[k][0]) for k in names]),
                "scale": np.array([abs(float(S0[k][0])) for k in names]),
                "max": np.zeros(len(names))}

    def chunk(self, carry: Carry, data: ChunkData) -> Tuple[Carry, Records]:
        from ._integrals import integrals_cfunc

        prob = data.problem
        spec = prob.spec
        # at the chunk's end only: one evaluation per chunk (over every sample it cost ~10 %
        # of a run; the drift of a Taylor integration grows slowly, chunk ends resolve it)
        vals = integrals_cfunc(prob.kind, prob.formulation, fp_type=spec.fp_type, prec=spec.prec)(data.x[-1:],
                                                                                                   prob.pars)
        errs = np.zeros(len(carry["scale"]))
        for j, k in enumerate(prob.system.info.integral_names):
            d = vals[k]
            for part in carry["I0"][j]:  # subtract I0 part by part, in the working type
                d = d - spec.array(np.array([part]))[0]
            scale = float(carry["scale"][j])
            errs[j] = float(np.max(np.abs(np.asarray(d).astype(float)))) / scale if scale > 0 else 0.0
        new = dict(carry, max=np.maximum(carry["max"], errs))
        return new, {"t": np.array([data.t1], dtype=float), "drift": errs[None, :]}


@register(("drift",), {"drift": True}, order=10)
def _build_drift(values, sample_dt):
    return [Drift()] if _bool("drift", values["drift"]) else []


# ---------------------------------------------------------------------------------------
# samples: thinned raw public states.
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Samples:
    """The public state every ``every`` time units (a multiple of the sample grid).

    Arrays (dim ``time``): ``t`` and ``state`` (``(time, var)``, float64 public layout)."""

    every: float
    ratio: int
    name: str = "samples"

    def options(self) -> dict:
        return {"every": self.every}

    def events(self, prob: Problem) -> list:
        return []

    def layout(self, prob: Problem) -> Dict[str, Var]:
        d = len(prob.system.public_names)
        return {"t": Var(("time",), "float64", doc="time"),
                "state": Var(("time", "var"), "float64", (d,), doc="public state " + ",".join(prob.system.public_names))}

    def init(self, prob: Problem, x0: np.ndarray, t0: float) -> Carry:
        return {}

    def chunk(self, carry: Carry, data: ChunkData) -> Tuple[Carry, Records]:
        keep = data.fresh() & (data.i % self.ratio == 0)
        return carry, {"t": data.t[keep].astype(float), "state": np.ascontiguousarray(data.public[keep], dtype=float)}


@register(("samples_every",), {"samples_every": 0.0}, order=20)
def _build_samples(values, sample_dt):
    every = values["samples_every"]
    ratio = grid_ratio("samples_every", every, sample_dt, allow_zero=True)
    return [Samples(float(every), ratio)] if ratio else []


# ---------------------------------------------------------------------------------------
# angles: the lifted section angle l.
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LiftedAngle:
    """The section chart's angle ``l = atan2(M1, M2)`` (paper sec. 4; ``atan2(K1, K2)``
    for mparallel) lifted to the real line, recorded every ``every`` time units.

    The lift does not unwrap samples (near ``M || e3`` the angle turns by more than pi
    between samples of 0.25, and unwrapping is then wrong): heyoka's event detection
    finds every crossing of ``M1 = 0`` inside the steps, and the signed crossings of the
    cut ``l = 0`` (``M2 > 0``) and of ``l = pi`` (``M2 < 0``) are counted exactly
    (``n0``, ``npi``, integers in the carry). At a sample the lift is taken from the cut
    the angle is far from: ``l + 2 pi n0`` with ``l in [0, 2 pi)`` if ``l`` is in
    ``[pi/2, 3 pi/2)``, else ``l' + 2 pi npi + c`` with ``l' in [-pi, pi)`` (``c`` fixed
    at the start), so a crossing within rounding of a sample time cannot miscount.

    ``method = "samples"`` (``angles_method``) counts the same turns without an event, on
    the quintic Hermite interpolant of ``(x1, x2)`` between samples, the rare intervals
    near the origin integrated again with the cut event (:mod:`taylorball._angle_lift`:
    what is exact, what rests on a margin); same counts and states give the same numbers.
    Its options name the method; the events method's are those of stores made before.

    Arrays (dim ``time``, record ``j`` at ``t = j * every``): ``l`` (float64); with
    ``"samples"`` also ``fallback`` (int64): the sample intervals integrated again since
    the previous record."""

    every: float
    ratio: int
    name: str = "angles"
    method: str = "events"

    def __post_init__(self) -> None:
        one_of("observables.angles_method", self.method, ANGLE_METHODS)

    def options(self) -> dict:
        if self.method == "events":
            return {"every": self.every}  # as before the choice existed: old stores' fingerprints
        return {"every": self.every, "method": self.method}

    def events_key(self) -> Tuple:
        return ("angles", "x1 = 0")

    def _event(self, prob: Problem) -> Any:
        import heyoka as hy

        x1 = hy.make_vars(*prob.system.internal_names)[0]
        kw = {} if prob.spec.name == "float" else {"fp_type": prob.spec.fp_type}
        return hy.nt_event(x1, _CutCollector(), **kw)

    def events(self, prob: Problem) -> list:
        if prob.system.info.chart is None:
            raise UsageError(f"observables.angles_every: kind {prob.kind!r} has no section chart (angle l)")
        return [] if self.method == "samples" else [self._event(prob)]

    def layout(self, prob: Problem) -> Dict[str, Var]:
        out = {"l": Var(("time",), "float64", doc="lifted section angle l", step=self.every, units="rad")}
        if self.method == "samples":
            out["fallback"] = Var(("time",), "int64", doc="sample intervals integrated again with the cut event "
                                  "(the interpolant near x1 = x2 = 0) since the previous record", step=self.every)
        return out

    @staticmethod
    def _raw(prob, x) -> np.ndarray:
        """``l`` in ``[0, 2 pi)`` of internal states (the section chart's first coordinate)."""
        return prob.system.info.chart(np.asarray(x).astype(float).reshape(-1, prob.system.dim))[:, 0]

    def init(self, prob: Problem, x0: np.ndarray, t0: float) -> Carry:
        a = self._raw(prob, x0[None, :])[0]
        b = a - 2 * math.pi if a >= math.pi else a
        # winding counts at the cuts l = 0 and l = pi, and the offset of the second lift
        out = {"n": np.array([0, 0], dtype=np.int64), "c": np.array([a - b])}
        if self.method == "samples":
            out["pending"] = np.zeros(1, dtype=np.int64)  # intervals integrated again, not yet recorded
        return out

    def chunk(self, carry: Carry, data: ChunkData) -> Tuple[Carry, Records]:
        fresh = data.fresh()
        keep = fresh & (data.i % self.ratio == 0)
        extra: Records = {}
        if self.method == "samples":
            from ._angle_lift import lift_counts, tally

            a_all = self._raw(data.problem, data.x)
            d0, dpi, again = lift_counts(data.problem, lambda: self._event(data.problem), data.t, data.x, a_all)
            upto = np.flatnonzero(keep)  # crossings up to each grid point: the intervals before it
            a = a_all[keep]
            extra["fallback"], pending = tally(again, upto, int(carry["pending"][0]))
        else:
            recs = data.events.get(0, [])
            tc = np.array([r[0] for r in recs], dtype=float)
            info = np.array([r[1] for r in recs], dtype=float).reshape(-1, 2)
            # a crossing of x1 = 0 upwards (d_sgn > 0) at x2 > 0 takes l from 2 pi- to 0+: n0 + 1;
            # at x2 < 0 it takes l' = atan2(x1, x2) from -pi+ to pi-: npi - 1
            d0 = np.where(info[:, 1] > 0, info[:, 0], 0.0).astype(np.int64)
            dpi = np.where(info[:, 1] < 0, -info[:, 0], 0.0).astype(np.int64)
            # crossings up to each recorded time (sorted: heyoka reports them in time order)
            upto = np.searchsorted(tc, data.t[keep], side="right")
            a = self._raw(data.problem, data.x[keep])
        c0 = np.concatenate([[0], np.cumsum(d0)])[upto] + carry["n"][0]
        cpi = np.concatenate([[0], np.cumsum(dpi)])[upto] + carry["n"][1]
        b = np.where(a >= math.pi, a - 2 * math.pi, a)
        far0 = (a >= 0.5 * math.pi) & (a < 1.5 * math.pi)
        lifted = np.where(far0, a + 2 * math.pi * c0, b + 2 * math.pi * cpi + carry["c"][0])
        new = {"n": np.array([carry["n"][0] + int(d0.sum()), carry["n"][1] + int(dpi.sum())], dtype=np.int64),
               "c": carry["c"]}
        if self.method == "samples":
            new["pending"] = np.array([pending], dtype=np.int64)
        return new, {"l": lifted, **extra}


#: Default spacing of the lifted angles: 1e8 / 50 = 2e6 records of 8 bytes per angle per
#: 1e8 time units (16 MB); at 10 the angle l alone takes 80 MB (measured: 100-130 MB per
#: orbit with the drift, benchmarks/bench_store.py), over the 100 MB default budget.
#: How the lifted angle counts its crossings (``angles_method``): heyoka's event on the cut,
#: or the sample grid's interpolant (no event; :mod:`taylorball._angle_lift`).
ANGLE_METHODS = ("events", "samples")


@register(("angles_every", "angles_method"), {"angles_every": 50.0, "angles_method": "events"}, order=30,
          needs=("chart", "contact"), off={"angles_every": 0.0, "angles_method": "events"})
def _build_angles(values, sample_dt):
    every = values["angles_every"]
    method = one_of("observables.angles_method", values["angles_method"], ANGLE_METHODS)
    ratio = grid_ratio("angles_every", every, sample_dt, allow_zero=True)
    return [LiftedAngle(float(every), ratio, method=method), Heading(float(every), ratio)] if ratio else []


# =======================================================================================
# Observables of the orbit's geometry: extremes and histogram of |R|, section crossings with
# K's sheet, the lifted heading. Their numerics (derivatives along the flow, Hermite
# interpolation and quadrature, time in bins, K's sheet) are in taylorball/_orbit_reductions.py,
# whose docstring says what R is (the contact point's distance from the axis, fixed and
# rotating frame alike) and why these use the sample grid, not events of their own.
# =======================================================================================
from ._orbit_reductions import (HIST_SUBSTEPS, _hermite5, _jets, _stationary_points,  # noqa: E402
                                hermite_quadrature, level_radius_bound, sheet_signs, time_in_bins)
from .numbers import count, multiple_of, one_of, real_number  # noqa: E402
def _f64(a) -> np.ndarray:
    return np.asarray(a, dtype=np.float64).reshape(1)


def _need(prob, who: str, *needs: str):
    """A clear error if the problem's system lacks what the observable ``who`` needs
    (:data:`NEEDS`); a study refuses it earlier, from :func:`unavailable`."""
    missing = [n for n in needs if getattr(prob.system.info, n) is None]
    if missing:
        raise UsageError(f"the observable {who!r} needs {' and '.join(NEEDS[n] for n in missing)}; "
                         f"got kind {prob.kind!r}")


@dataclass(frozen=True)
class Extremes:
    r"""Running minimum and maximum of ``|R|``, the contact point's distance from the
    rotation axis (fixed frame and rotating frame alike, see the module docstring; paper
    eq. (1) [eq1]).

    Per chunk the records are the chunk's ``r_min``, ``r_max`` and their times
    ``t_r_min``, ``t_r_max`` (append dimension ``chunk``); the carry holds the running
    values (the running extremes are also the cumulative min/max of the records).

    Accuracy: candidates are the samples and, in every sample interval where ``d|R|^2/dt`` changes sign, the
    stationary point of the quintic Hermite interpolant of ``|R|^2`` (value, first and second time derivative
    at both samples, from :func:`_jets`): error ``<= h^6 max|d^6 |R|^2/dt^6| / 46080`` per interval (``h =
    sample_dt``). Measured on the Fig. 4a orbit (``sample_dt = 0.25``) against a 1/256 grid of the same orbit:
    in ``tests/test_observables_orbit.py``. A pair of extremes inside one sample interval (a local max and min
    closer than ``sample_dt``) is missed; it cannot hold the running extreme unless ``|R|`` turns twice within
    ``sample_dt``. At a pass of the axis with ``|R|^2`` below that error the interpolant's minimum can be
    negative: ``r_min`` then reads 0.0.
    Storage: 4 float64 per chunk (6.4 MB per 1e8 time units at ``checkpoint_every = 500``).
    """

    name: str = "extremes"

    def options(self) -> Dict[str, Any]:
        return {}

    def events(self, prob: Problem) -> list:
        return []

    def layout(self, prob: Problem) -> Dict[str, Var]:
        doc = {"r_min": "min |R| over the chunk", "r_max": "max |R| over the chunk",
               "t_r_min": "time of r_min", "t_r_max": "time of r_max"}
        return {k: Var(("chunk",), "float64", doc=d) for k, d in doc.items()}

    def init(self, prob: Problem, x0: np.ndarray, t0: float) -> Dict[str, np.ndarray]:
        _need(prob, self.name, "contact")
        return {"n": np.zeros(1, dtype=np.int64), "r_min": _f64(0.0), "r_max": _f64(0.0),
                "t_r_min": _f64(t0), "t_r_max": _f64(t0)}

    def chunk(self, carry: Carry, data: ChunkData) -> Tuple[Carry, Records]:
        J = data.jets()
        t = np.asarray(data.t, dtype=float)
        # only the intervals whose interpolant can reach the samples' extremes: the same records
        ts, ys = _stationary_points(t, J[0], J[1], J[2], within=(float(np.min(J[0])), float(np.max(J[0]))))
        tt = np.concatenate([t, ts])
        yy = np.concatenate([J[0], ys])
        i, j = int(np.argmin(yy)), int(np.argmax(yy))
        rec = {"r_min": _f64(math.sqrt(max(yy[i], 0.0))), "r_max": _f64(math.sqrt(max(yy[j], 0.0))),
               "t_r_min": _f64(tt[i]), "t_r_max": _f64(tt[j])}
        first = int(carry["n"][0]) == 0
        new = {"n": carry["n"] + 1}
        lo = first or rec["r_min"][0] < carry["r_min"][0]
        hi = first or rec["r_max"][0] > carry["r_max"][0]
        new["r_min"], new["t_r_min"] = (rec["r_min"], rec["t_r_min"]) if lo else (carry["r_min"], carry["t_r_min"])
        new["r_max"], new["t_r_max"] = (rec["r_max"], rec["t_r_max"]) if hi else (carry["r_max"], carry["t_r_max"])
        return new, rec


@dataclass(frozen=True)
class Histogram:
    r"""Time spent by ``|R|`` in ``bins`` equal bins of ``[0, r_max)`` (plus the time at or
    above ``r_max``, which the default ``r_max`` makes zero).

    ``r_max`` defaults to the rigorous bound :func:`taylorball.contact.radius_bound` of
    the orbit's own level ``(C, h)`` (``C = |M|``, ``h = E`` at its start, for the reduced and
    the full system alike; so no time can fall above it); it is then per orbit
    and kept in the carry. The carry holds the running histogram (``time``, ``bins + 1``
    float64: the last entry is the time at or above ``r_max``); it is recorded (append
    dimension ``snapshot``, with ``t_snapshot``) after chunks ``k`` with ``k + 1`` a power
    of two, so the records show the convergence over time in log-spaced snapshots
    (``log2`` of the number of chunks of them) and the carry has the latest.

    Accuracy: ``|R|(t)`` is followed as a broken line through ``HIST_SUBSTEPS`` (8) points
    per sample interval of the quintic Hermite interpolant of ``|R|^2`` (see
    :class:`Extremes`), and the time in each bin is exact for that broken line
    (:func:`time_in_bins`); the counts sum to the elapsed time to rounding. The broken line
    is off by at most ``(h/8)^2 max|d^2|R|/dt^2| / 8``; measured against a 1/512 grid of
    the same orbit: ``tests/test_observables_orbit.py``.
    Storage: ``(bins + 2)`` float64 per snapshot (~60 kB per 1e8 time units for 200 bins).
    """

    bins: int = 200
    r_max: Optional[float] = None
    name: str = "histogram"

    def __post_init__(self):
        object.__setattr__(self, "bins", count("histogram bins", self.bins, lo=1, hi=100_000))
        if self.r_max is not None:
            object.__setattr__(self, "r_max", real_number("histogram r_max", self.r_max, lo=0.0, lo_open=True))

    def options(self) -> Dict[str, Any]:
        return {"bins": self.bins, "r_max": self.r_max, "substeps": HIST_SUBSTEPS}

    def events(self, prob: Problem) -> list:
        return []

    def layout(self, prob: Problem) -> Dict[str, Var]:
        return {"time": Var(("snapshot", "bin"), "float64", (self.bins + 1,),
                            doc="time spent by |R| in each bin of [0, r_max) so far; last: at or above r_max"),
                "t_snapshot": Var(("snapshot",), "float64", doc="time of the snapshot")}

    def init(self, prob: Problem, x0: np.ndarray, t0: float) -> Dict[str, np.ndarray]:
        _need(prob, self.name, "contact")
        return {"time": np.zeros(self.bins + 1), "r_max": _f64(0.0 if self.r_max is None else self.r_max)}

    def _r_max(self, carry, data) -> float:
        if carry["r_max"][0] > 0:
            return float(carry["r_max"][0])
        return level_radius_bound(data.problem, data.public[0])

    def chunk(self, carry: Carry, data: ChunkData) -> Tuple[Carry, Records]:
        r_max = self._r_max(carry, data)
        J = data.jets()
        t = np.asarray(data.t, dtype=float)
        h = np.diff(t)[:, None]
        s = np.arange(HIST_SUBSTEPS)[None, :] / HIST_SUBSTEPS
        y = _hermite5(J[0][:-1, None], J[1][:-1, None], J[2][:-1, None], J[0][1:, None], J[1][1:, None],
                      J[2][1:, None], h, s)
        tt = np.append((t[:-1, None] + h * s).ravel(), t[-1])
        rr = np.sqrt(np.maximum(np.append(y.ravel(), J[0][-1]), 0.0))
        occ = time_in_bins(tt, rr, np.linspace(0.0, r_max, self.bins + 1))
        # occ[0] is below 0 (never); the bins, then the time at or above r_max
        new = {"time": carry["time"] + occ[1:], "r_max": _f64(r_max)}
        k = int(data.k) + 1
        if k & (k - 1) == 0:
            rec = {"time": new["time"][None, :].copy(), "t_snapshot": _f64(data.t1)}
        else:
            rec = {"time": np.empty((0, self.bins + 1)), "t_snapshot": np.empty(0)}
        return new, rec


@dataclass(frozen=True)
class Sections:
    r"""Crossings of the section ``g = g0`` (direction +1: ``g`` increasing), found by the
    :class:`taylorball.Section` event (heyoka's roots of the event polynomial, Newton-refined
    in time; paper section 4), every ``every``-th kept (``every = 1``: ``"all"``), thinned
    by the running crossing count in the carry, so the kept crossings do not depend on the
    chunking.

    ``method = "samples"`` (``sections_method``) finds the crossings without the event
    during the run, on the quintic Hermite interpolant of the event function between
    samples; the intervals it cannot decide and those of the recorded crossings are
    integrated again with the event (:mod:`taylorball._section_samples`). Its options name
    the method; the events method's are those of stores made before.

    Records (append dimension ``crossing``): ``t``, the chart point ``l``, ``r1``, ``r2``,
    ``K = M3`` and ``dEdK_sign`` (int8, :func:`sheet_signs`). Storage: 41 bytes per kept
    crossing; the Fig. 4a orbit crosses ~0.63 times per time unit: 2.6 GB per 1e8 time
    units with ``"all"``, 86 MB with ``every = 30``.
    """

    every: int = 1
    g0: float = 0.0
    name: str = "sections"
    method: str = "events"

    def __post_init__(self):
        object.__setattr__(self, "every", count("sections (every Nth crossing)", self.every, lo=1, hi=10**12))
        g0 = real_number("sections g0", self.g0, lo=0.0, hi=2 * math.pi)
        if g0 >= 2 * math.pi:
            raise UsageError(f"sections g0 must be in [0, 2 pi), got {self.g0!r}")
        object.__setattr__(self, "g0", g0)
        one_of("observables.sections_method", self.method, SECTION_METHODS)

    def options(self) -> Dict[str, Any]:
        if self.method == "events":  # as before the choice existed: old stores' fingerprints
            return {"every": self.every, "g0": self.g0, "direction": 1}
        return {"every": self.every, "g0": self.g0, "direction": 1, "method": self.method}

    def events_key(self) -> Tuple:
        """The event depends on ``g0`` (and the direction), not on ``every``."""
        return ("sections", self.g0, 1)

    def uses_grid(self) -> bool:
        """Its event records only (``"events"``); the grid (``"samples"``)."""
        return self.method == "samples"

    def section(self, prob: Problem) -> Any:
        from .sections import Section

        return Section(prob, self.g0, 1)

    def events(self, prob: Problem) -> list:
        _need(prob, self.name, "chart", "contact", "levels")
        if prob.formulation != prob.system.info.default_formulation:
            raise UsageError(f"the observable 'sections' needs the {prob.system.info.default_formulation!r} "
                             f"formulation (the section event is written in M), got {prob.formulation!r}")
        return [] if self.method == "samples" else [self.section(prob).event()]

    def layout(self, prob: Problem) -> Dict[str, Var]:
        doc = {"t": "crossing time", "l": "chart angle l = atan2(M1, M2) in [0, 2 pi)",
               "r1": "R1 gamma1 + R2 gamma2", "r2": "R1 gamma2 - R2 gamma1", "K": "K = M3"}
        out = {k: Var(("crossing",), "float64", doc=d, units="rad" if k == "l" else "1") for k, d in doc.items()}
        out["dEdK_sign"] = Var(("crossing",), "int8", doc="sign of dE/dK at fixed (l, r1, r2, g0), 0 at a fold: "
                               "which side of a fold (the root index among all roots, the figures' sheet, is "
                               "tb.section_sheet of the states)")
        return out

    def init(self, prob: Problem, x0: np.ndarray, t0: float) -> Dict[str, np.ndarray]:
        out = {"n": np.zeros(1, dtype=np.int64)}
        if self.method == "samples":
            out["again"] = np.zeros(1, dtype=np.int64)  # sample intervals integrated again so far
        return out

    def chunk(self, carry: Carry, data: ChunkData) -> Tuple[Carry, Records]:
        from .sections import START_TOL

        prob = data.problem
        sec = self.section(prob)
        n0 = int(carry["n"][0])
        if self.method == "samples":
            from ._section_samples import crossings

            got, n_new, again = crossings(prob, sec, data.t, data.x, n0, self.every)
            times, states, mine = [t for t, _ in got], [x for _, x in got], np.arange(len(got))
            new = {"n": np.array([n0 + n_new], dtype=np.int64), "again": carry["again"] + again}
        else:
            recs = list(data.events.get(0, []))
            times, states = [t for t, _ in recs], [x for _, x in recs]
            keep = sec.on_branch(states) if recs else np.zeros(0, dtype=bool)
            keep &= np.array([float(t) > START_TOL for t in times], dtype=bool)
            idx = np.flatnonzero(keep)
            mine = idx[(n0 + np.arange(idx.size)) % self.every == 0]
            new = {"n": np.array([n0 + idx.size], dtype=np.int64)}
        X = np.array([np.asarray(states[i], dtype=float) for i in mine]).reshape(-1, prob.system.dim)
        pts = sec.chart(X) if len(X) else np.empty((0, 3))
        rec = {"t": np.array([float(times[i]) for i in mine], dtype=float), "l": pts[:, 0], "r1": pts[:, 1],
               "r2": pts[:, 2], "K": X[:, 2].copy(), "dEdK_sign": sheet_signs(prob.params, X)}
        return new, rec


@dataclass(frozen=True)
class Heading:
    r"""The ball's heading about the vertical, lifted (unbounded):
    ``psi(t) = int_0^t (omega, gamma) dt'``, the angle the ball has turned about the
    vertical (``(omega, gamma)`` is the vertical component of its angular velocity,
    ``gamma`` being the upward normal in body axes; paper section 1), recorded every
    ``every`` time units (``angles_every``; append dimension ``time``, record ``j`` at
    ``t = j * every``, as the angle ``l``).

    ``psi`` is the lifted angle for transport because its rate ``(omega, gamma)`` is a
    function of the state: its mean rate and diffusion coefficient are time averages of a
    state function, with no reference direction. Angles about the vertical that are
    functions of the state exist too (e.g. the azimuth of a body axis measured from the
    fixed horizontal part of ``M``), but each follows one body axis against a moving
    direction and turns at its own mean rate, not the ball's. Relative to the rotating
    plane the heading is ``psi - Omega t``.

    Quadrature: on every sample interval, the integral of the quintic Hermite interpolant
    of ``(omega, gamma)`` from its value and first two time derivatives at the samples
    (:func:`hermite_quadrature`, order 6, local error ``h^7 |g^(6)| / 100800``); the running
    value is carried as a double-double (``psi_hi``, ``psi_lo``) with the chunk's sum by
    ``math.fsum``, so rounding does not accumulate over chunks. Measured against an
    independent long-double integration of ``psi' = (omega, gamma)`` appended to the
    reduced system (Fig. 4a orbit): 2.6e-3 rad per 10 time units at ``sample_dt = 0.25``,
    2.2e-5 at 0.125, 1.4e-8 at 0.0625 (``tests/test_observables_orbit.py``).
    Storage: 1 float64 per ``every`` (16 MB per 1e8 time units at the default 50).
    """

    every: float
    ratio: int
    name: str = "heading"

    def options(self) -> Dict[str, Any]:
        return {"every": self.every, "quadrature": "hermite5"}

    def events(self, prob: Problem) -> list:
        return []

    def layout(self, prob: Problem) -> Dict[str, Var]:
        return {"heading": Var(("time",), "float64", doc="lifted heading int (omega, gamma) dt", units="rad",
                               step=self.every)}

    def init(self, prob: Problem, x0: np.ndarray, t0: float) -> Dict[str, np.ndarray]:
        _need(prob, self.name, "contact")
        return {"psi_hi": _f64(0.0), "psi_lo": _f64(0.0)}

    def chunk(self, carry: Carry, data: ChunkData) -> Tuple[Carry, Records]:
        J = data.jets()
        t = np.asarray(data.t, dtype=float)
        q = hermite_quadrature(t, J[3], J[4], J[5])
        hi, lo = float(carry["psi_hi"][0]), float(carry["psi_lo"][0])
        partial = np.concatenate([[0.0], np.cumsum(q)])
        at = data.fresh() & (np.asarray(data.i) % self.ratio == 0)
        rec = {"heading": hi + (lo + partial[at])}
        S = math.fsum(q)
        s = hi + S
        bp = s - hi
        err = (hi - (s - bp)) + (S - bp)  # two-sum: s + err = hi + S exactly
        return {"psi_hi": _f64(s), "psi_lo": _f64(lo + err)}, rec


# ---------------------------------------------------------------------------------------
# [observables] keys of the geometric observables
# ---------------------------------------------------------------------------------------
@register(("extremes",), {"extremes": True}, order=40, needs=("contact",), off={"extremes": False})
def _build_extremes(values, sample_dt):
    return [Extremes()] if _bool("extremes", values["extremes"]) else []


@register(("histogram",), {"histogram": False}, order=50, needs=("contact",), off={"histogram": False})
def _build_histogram(values, sample_dt):
    v = values["histogram"]
    form = "false, true, or a table {bins = 200, r_max = <a radius>} (r_max defaults to contact.radius_bound)"
    if isinstance(v, bool):
        return [Histogram()] if v else []
    if not isinstance(v, dict) or set(v) - {"bins", "r_max"}:
        raise UsageError(f"observables.histogram must be {form}, got {v!r}")
    try:
        return [Histogram(**v)]
    except UsageError as exc:
        raise UsageError(f"observables.{exc}; observables.histogram must be {form}") from None


#: How the section observable finds its crossings (``sections_method``): heyoka's event,
#: or the sample grid's interpolant (no event during the run; :mod:`taylorball._section_samples`).
SECTION_METHODS = ("events", "samples")


@register(("sections", "sections_method"), {"sections": False, "sections_method": "events"}, order=60,
          needs=("chart", "contact", "levels"), off={"sections": False, "sections_method": "events"})
def _build_sections(values, sample_dt):
    v = values["sections"]
    method = one_of("observables.sections_method", values["sections_method"], SECTION_METHODS)
    form = '"all", a positive integer N (every Nth crossing) or false'
    if v is False:
        return []
    if isinstance(v, str) and v == "all":
        return [Sections(1, method=method)]
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise UsageError(f"observables.sections must be {form}, got {v!r}")
    return [Sections(int(v), method=method)]


