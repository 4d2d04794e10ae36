"""Observables reduced on the fly during a long run (issue 10), and their interface.

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
  (default: name and options). Non-terminal
  events do not change the orbit's bits, so observables can be switched on and off
  without changing the others' records;
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

__all__ = ["Var", "ChunkData", "Observable", "register", "builders", "build_observables", "observable_keys",
           "Drift", "Samples", "LiftedAngle", "grid_ratio"]

Carry = Dict[str, np.ndarray]
Records = Dict[str, np.ndarray]


@dataclass(frozen=True)
class Var:
    """One array of an observable: ``dims`` (the first is the append dimension), ``dtype``
    (a numpy dtype name: ``"float64"``, ``"int64"``, ``"int8"``, ...), ``shape`` (the sizes
    of ``dims[1:]``), a one-line ``doc`` (stored as the array's description) and, for
    records on a regular time grid, ``step``: record ``j`` is at ``t = j * step``, so no
    time array is stored (:func:`taylorball.open_run` adds the coordinate)."""

    dims: Tuple[str, ...]
    dtype: str = "float64"
    shape: Tuple[int, ...] = ()
    doc: str = ""
    step: Optional[float] = None

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

    def options(self) -> dict: ...

    def events(self, prob) -> list: ...

    def layout(self, prob) -> Dict[str, Var]: ...

    def init(self, prob, x0: np.ndarray, t0: float) -> Carry: ...

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


_BUILDERS: List[_Builder] = []


def register(keys: Sequence[str], defaults: Mapping[str, Any], order: int = 100):
    """Decorator registering ``build(values, sample_dt) -> list of observables`` for the
    ``[observables]`` keys ``keys`` (``values`` has every key, defaults filled in).
    ``build`` raises :class:`~taylorball.errors.UsageError` for a bad value, naming it as
    ``observables.KEY``, the value and the valid form (the study adds the file's name)."""
    def deco(fn):
        _BUILDERS.append(_Builder(tuple(keys), dict(defaults), fn, order))
        _BUILDERS.sort(key=lambda b: b.order)
        return fn

    return deco


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


def grid_ratio(key: str, every, sample_dt: float, *, allow_zero: bool = False) -> int:
    """``every / sample_dt`` as a positive integer (0 if ``every == 0`` and
    ``allow_zero``); a clear error naming ``observables.KEY`` otherwise."""
    form = f"a positive multiple of sample_dt = {sample_dt!r}" + (" or 0 (off)" if allow_zero else "")
    if isinstance(every, bool) or not isinstance(every, (int, float)) or not math.isfinite(every):
        raise UsageError(f"observables.{key} must be {form}, got {every!r}")
    if every == 0 and allow_zero:
        return 0
    r = every / sample_dt
    n = round(r) if math.isfinite(r) else 0
    if every <= 0 or n < 1 or abs(r - n) > 1e-9 * r:
        raise UsageError(f"observables.{key} must be {form}, got {every!r}")
    if n > 10**12:
        raise UsageError(f"observables.{key} = {every!r} is {r:.3g} sample steps: must be {form}, at most 1e12 steps")
    return int(n)


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
    """Relative drift of each first integral: per chunk, ``max |I - I0| / scale`` over the
    chunk's sample grid, ``I0`` at the orbit's start and ``scale`` from
    :func:`taylorball.integral_scales` there (the sum of the magnitudes of the integral's
    terms), computed in the working number type.

    Arrays (dim ``chunk``): ``t`` (the chunk's end) and ``drift`` (``(chunk, integral)``,
    the integrals of the kind in order: ``C2, M_gamma, E, gamma2, R_gamma`` for reduced);
    the running maximum is in the carry (``max``)."""

    name: str = "drift"

    def options(self) -> dict:
        return {}

    def events(self, prob) -> list:
        return []

    def layout(self, prob) -> Dict[str, Var]:
        names = prob.system.info.integral_names
        return {"t": Var(("chunk",), "float64", doc="end time of the chunk"),
                "drift": Var(("chunk", "integral"), "float64", (len(names),),
                             doc="max |I - I(0)| / scale over the chunk's samples, for I in " + ",".join(names))}

    def init(self, prob, x0, t0) -> Carry:
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
        vals = integrals_cfunc(prob.kind, prob.formulation, fp_type=spec.fp_type, prec=spec.prec)(data.x, prob.pars)
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

    def events(self, prob) -> list:
        return []

    def layout(self, prob) -> Dict[str, Var]:
        d = len(prob.system.public_names)
        return {"t": Var(("time",), "float64", doc="time"),
                "state": Var(("time", "var"), "float64", (d,), doc="public state " + ",".join(prob.system.public_names))}

    def init(self, prob, x0, t0) -> Carry:
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
class _CutCollector:
    """Non-terminal event callback on ``x1 = 0`` (``M1`` or ``K1``): records the crossing
    time, heyoka's sign of ``dx1/dt`` there and the sign of ``x2`` (which cut of the angle
    ``atan2(x1, x2)`` was crossed: ``l = 0`` if ``x2 > 0``, ``l = pi`` if ``x2 < 0``), as
    ``(t, [d_sgn, sign(x2)])`` records. ``x2`` is read from the dense output at the
    crossing, relative to the end of the step (full precision, as sections._Collector)."""

    def __init__(self):
        self.times: list = []
        self.states: list = []

    def __deepcopy__(self, memo):
        return _CutCollector()

    def __call__(self, ta, t, d_sgn):
        hi, lo = ta.dtime
        rel = (t - hi) - lo
        x = ta.update_d_output(rel, rel_time=True)
        self.times.append(float(t))
        self.states.append(np.array([float(int(d_sgn)), float(np.sign(float(x[1])))]))


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

    Arrays (dim ``time``, record ``j`` at ``t = j * every``): ``l`` (float64)."""

    every: float
    ratio: int
    name: str = "angles"

    def options(self) -> dict:
        return {"every": self.every}

    def events_key(self) -> Tuple:
        return ("angles", "x1 = 0")

    def events(self, prob) -> list:
        import heyoka as hy

        if prob.system.info.chart is None:
            raise UsageError(f"observables.angles_every: kind {prob.kind!r} has no section chart (angle l)")
        x1 = hy.make_vars(*prob.system.internal_names)[0]
        kw = {} if prob.spec.name == "float" else {"fp_type": prob.spec.fp_type}
        return [hy.nt_event(x1, _CutCollector(), **kw)]

    def layout(self, prob) -> Dict[str, Var]:
        return {"l": Var(("time",), "float64", doc="lifted section angle l (rad)", step=self.every)}

    @staticmethod
    def _raw(prob, x) -> np.ndarray:
        """``l`` in ``[0, 2 pi)`` of internal states (the section chart's first coordinate)."""
        return prob.system.info.chart(np.asarray(x).astype(float).reshape(-1, prob.system.dim))[:, 0]

    def init(self, prob, x0, t0) -> Carry:
        a = self._raw(prob, x0[None, :])[0]
        b = a - 2 * math.pi if a >= math.pi else a
        # winding counts at the cuts l = 0 and l = pi, and the offset of the second lift
        return {"n": np.array([0, 0], dtype=np.int64), "c": np.array([a - b])}

    def chunk(self, carry: Carry, data: ChunkData) -> Tuple[Carry, Records]:
        fresh = data.fresh()
        keep = fresh & (data.i % self.ratio == 0)
        recs = data.events.get(0, [])
        tc = np.array([r[0] for r in recs], dtype=float)
        info = np.array([r[1] for r in recs], dtype=float).reshape(-1, 2)
        # a crossing of x1 = 0 upwards (d_sgn > 0) at x2 > 0 takes l from 2 pi- to 0+: n0 + 1;
        # at x2 < 0 it takes l' = atan2(x1, x2) from -pi+ to pi-: npi - 1
        d0 = np.where(info[:, 1] > 0, info[:, 0], 0.0).astype(np.int64)
        dpi = np.where(info[:, 1] < 0, -info[:, 0], 0.0).astype(np.int64)
        ts = data.t[keep]
        # crossings up to each recorded time (sorted: heyoka reports them in time order)
        upto = np.searchsorted(tc, ts, side="right")
        c0 = np.concatenate([[0], np.cumsum(d0)])[upto] + carry["n"][0]
        cpi = np.concatenate([[0], np.cumsum(dpi)])[upto] + carry["n"][1]
        a = self._raw(data.problem, data.x[keep])
        b = np.where(a >= math.pi, a - 2 * math.pi, a)
        far0 = (a >= 0.5 * math.pi) & (a < 1.5 * math.pi)
        lifted = np.where(far0, a + 2 * math.pi * c0, b + 2 * math.pi * cpi + carry["c"][0])
        new = {"n": np.array([carry["n"][0] + int(d0.sum()), carry["n"][1] + int(dpi.sum())], dtype=np.int64),
               "c": carry["c"]}
        return new, {"l": lifted}


#: Default spacing of the lifted angles: 1e8 / 50 = 2e6 records of 8 bytes per angle per
#: 1e8 time units (16 MB); at 10 the angle l alone takes 80 MB (measured: 100-130 MB per
#: orbit with the drift, benchmarks/bench_store.py), over the 100 MB default budget.
@register(("angles_every",), {"angles_every": 50.0}, order=30)
def _build_angles(values, sample_dt):
    every = values["angles_every"]
    ratio = grid_ratio("angles_every", every, sample_dt, allow_zero=True)
    return [LiftedAngle(float(every), ratio)] if ratio else []
