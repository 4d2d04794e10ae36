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
  clears them. ``events_key()`` identifies the events in the compile cache. Non-terminal
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
    of ``dims[1:]``) and a one-line ``doc`` (stored as the array's description)."""

    dims: Tuple[str, ...]
    dtype: str = "float64"
    shape: Tuple[int, ...] = ()
    doc: str = ""

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
    """Compile-cache key of an observable's events: its name and options."""
    import json

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

    Arrays (dim ``chunk``): ``t`` (the chunk's end) and one per integral (``E``, ``C2``,
    ... of the kind); the running maximum is in the carry (``max_<name>``)."""

    name: str = "drift"

    def options(self) -> dict:
        return {}

    def events(self, prob) -> list:
        return []

    def layout(self, prob) -> Dict[str, Var]:
        out = {"t": Var(("chunk",), "float64", doc="end time of the chunk")}
        for k in prob.system.info.integral_names:
            out[k] = Var(("chunk",), "float64", doc=f"max |{k} - {k}(0)| / scale over the chunk's samples")
        return out

    def init(self, prob, x0, t0) -> Carry:
        from ._integrals import integrals_cfunc

        spec = prob.spec
        I0 = integrals_cfunc(prob.kind, prob.formulation, fp_type=spec.fp_type, prec=spec.prec)(x0[None, :], prob.pars)
        S0 = integrals_cfunc(prob.kind, prob.formulation, fp_type=spec.fp_type, prec=spec.prec,
                             which="scales")(x0[None, :], prob.pars)
        carry: Carry = {}
        for k in prob.system.info.integral_names:
            carry[f"I0_{k}"] = _split_parts(I0[k][0])
            carry[f"scale_{k}"] = np.array([abs(float(S0[k][0]))])
            carry[f"max_{k}"] = np.array([0.0])
        return carry

    def chunk(self, carry: Carry, data: ChunkData) -> Tuple[Carry, Records]:
        from ._integrals import integrals_cfunc

        prob = data.problem
        spec = prob.spec
        vals = integrals_cfunc(prob.kind, prob.formulation, fp_type=spec.fp_type, prec=spec.prec)(data.x, prob.pars)
        new = dict(carry)
        rec: Records = {"t": np.array([data.t1], dtype=float)}
        for k in prob.system.info.integral_names:
            d = vals[k]
            for part in carry[f"I0_{k}"]:  # subtract I0 part by part, in the working type
                d = d - spec.array(np.array([part]))[0]
            scale = float(carry[f"scale_{k}"][0])
            err = float(np.max(np.abs(np.asarray(d).astype(float)))) / scale if scale > 0 else 0.0
            rec[k] = np.array([err])
            new[f"max_{k}"] = np.array([max(float(carry[f"max_{k}"][0]), err)])
        return new, rec


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
#: Largest change of the chart angle between two consecutive samples for which the lift
#: is unambiguous: beyond pi/2 a turn of +-(2 pi - delta) can no longer be told apart
#: from delta with a margin (at pi it could not at all); such steps are counted.
LIFT_MAX_STEP = math.pi / 2


@dataclass(frozen=True)
class LiftedAngle:
    """The section chart's angle ``l`` (``atan2(M1, M2)``, paper sec. 4; ``atan2(K1, K2)``
    for mparallel), lifted to the real line by unwrapping on the sample grid, recorded
    every ``every`` time units.

    The lift is ``l_raw + 2 pi n`` with the integer winding ``n`` carried from sample to
    sample (no rounding accumulates). A step of the raw angle larger than
    :data:`LIFT_MAX_STEP` between consecutive samples makes the lift ambiguous: such steps
    are counted in ``ambiguous`` (since the previous record); use a smaller ``sample_dt``.

    Arrays (dim ``time``): ``t``, ``l`` (float64), ``ambiguous`` (int64)."""

    every: float
    ratio: int
    name: str = "angles"

    def options(self) -> dict:
        return {"every": self.every}

    def events(self, prob) -> list:
        return []

    def layout(self, prob) -> Dict[str, Var]:
        return {"t": Var(("time",), "float64", doc="time"),
                "l": Var(("time",), "float64", doc="lifted section angle l (rad)"),
                "ambiguous": Var(("time",), "int64", doc=f"sample steps since the previous record with |dl| > pi/2")}

    @staticmethod
    def _raw(prob, x) -> np.ndarray:
        chart = prob.system.info.chart
        if chart is None:
            raise UsageError(f"observables.angles_every: kind {prob.kind!r} has no section chart (angle l)")
        return chart(np.asarray(x).astype(float).reshape(-1, prob.system.dim))[:, 0]

    def init(self, prob, x0, t0) -> Carry:
        zero = np.array([0], dtype=np.int64)
        # last raw angle, winding number, ambiguous steps so far and up to the last record
        return {"last": self._raw(prob, x0[None, :]), "winding": zero, "ambiguous": zero, "since": zero}

    def chunk(self, carry: Carry, data: ChunkData) -> Tuple[Carry, Records]:
        raw = self._raw(data.problem, data.x)
        seq = np.concatenate([carry["last"], raw[1:]]) if data.k > 0 else np.concatenate([carry["last"], raw])
        # seq[0] is the previous sample (the chunk's start, equal to raw[0] after chunk 0)
        step = np.diff(seq)
        turns = -np.round(step / (2 * math.pi)).astype(np.int64)  # +1 when l wraps 2 pi -> 0
        wrapped = step + 2 * math.pi * turns
        bad = (np.abs(wrapped) > LIFT_MAX_STEP).astype(np.int64)
        winding = carry["winding"][0] + np.cumsum(turns)
        n_bad = carry["ambiguous"][0] + np.cumsum(bad)
        vals = seq[1:]
        t = data.t[1:] if data.k > 0 else data.t
        idx = data.i[1:] if data.k > 0 else data.i
        if data.k == 0:  # the start itself is recorded too
            vals, t, idx = np.concatenate([seq[:1], vals]), np.concatenate([data.t[:1], t]), \
                np.concatenate([data.i[:1], idx])
            winding = np.concatenate([carry["winding"], winding])
            n_bad = np.concatenate([carry["ambiguous"], n_bad])
        keep = idx % self.ratio == 0
        lifted = vals + 2 * math.pi * winding
        # ambiguous steps since the previous record: differences of the running count
        counts = n_bad[keep]
        prev = np.concatenate([carry["since"], counts[:-1]])
        rec = {"t": t[keep].astype(float), "l": lifted[keep], "ambiguous": (counts - prev).astype(np.int64)}
        new = {"last": seq[-1:].copy(), "winding": winding[-1:].astype(np.int64),
               "ambiguous": n_bad[-1:].astype(np.int64),
               "since": (counts[-1:] if len(counts) else carry["since"]).astype(np.int64)}
        return new, rec


@register(("angles_every",), {"angles_every": 10.0}, order=30)
def _build_angles(values, sample_dt):
    every = values["angles_every"]
    ratio = grid_ratio("angles_every", every, sample_dt, allow_zero=True)
    return [LiftedAngle(float(every), ratio)] if ratio else []


# extremes, histogram, sections and the heading live in a module of their own; importing it
# registers their [observables] keys
from . import _orbit_reductions  # noqa: E402,F401
