"""Your own long runs: a study file, its run store, and the runner (issue 10).

A *study file* (TOML) names the ball, the level, the orbits, the run (end time, chunks,
number type, backend), the observables reduced on the fly (:mod:`taylorball.observables`)
and the store (:mod:`taylorball.store`)::

    [ball]
    inertia = [2.0, 3.0, 4.0]
    mass = 1.0
    radius = 5.0
    plane_rate = 2.0

    [level]            # caption form G, H, h; or C, M_gamma, h
    G = 10.0
    H = 2.0
    h = 5.0

    [orbits]
    n = 4              # drawn on the level's admissible region
    seed = 1

    [run]
    t_end = 2000.0
    checkpoint_every = 500.0

    [observables]
    extremes = true
    angles_every = 10.0
    sections = "all"

    [output]
    store = "runs/h2"

:func:`run_study` runs (or resumes, or extends) every orbit; :func:`study_status` reports
progress; :func:`open_run` reads the store as an ``xarray.Dataset``. The reference of every
key is in ``docs/longruns.md``.

Bits. An orbit's records depend on the problem (ball, number type, tolerance), its initial
state, ``checkpoint_every`` and ``sample_dt`` (each chunk is one ``propagate_grid`` on the
sample grid ``t_m = m * sample_dt`` whose last point is the chunk's end), never on which
observables are on (their events are non-terminal), the scalar backend, interruptions,
or ``t_end``: extending a run from ``T1`` to ``T2`` runs exactly the chunks a direct run to
``T2`` runs after ``T1``.

``backend = "lanes"`` (float64 only) runs the orbits in the SIMD lanes of heyoka batch
integrators (:func:`taylorball.ensemble.run_many` with ``backend="lanes"``), one per worker
thread, a lane refilled with the next orbit when its orbit is done; each chunk is one
batch ``propagate_grid`` on every lane's own grid, reduced and committed per orbit exactly
as above. A lane's bits depend only on its own orbit (not on the lane, the thread or the
other orbits), but they are not the scalar integrator's: the integrator family enters the
fingerprint, and a store is resumed only by the family that wrote it.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Any, Dict, List, Literal, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from .errors import ParameterError, StateError, StoreError, TaylorballError, UsageError
from ._problem import Problem

__all__ = ["StudyConfig", "load_study", "run_study", "study_status", "open_run", "StudyStatus"]

FP_TYPES = ("float", "longdouble", "real128")
BACKENDS = ("threads", "processes", "serial", "dask", "lanes")
#: Limits keeping a study's work and memory proportionate: orbits, samples held per chunk,
#: chunks per orbit.
MAX_ORBITS = 100_000
MAX_SAMPLES_PER_CHUNK = 1_000_000
MAX_CHUNKS = 10_000_000
_TABLES = {
    "ball": ("inertia", "mass", "radius", "plane_rate"),
    "level": ("G", "H", "h", "C", "M_gamma"),
    "orbits": ("n", "seed", "states"),
    "run": ("t_end", "checkpoint_every", "sample_dt", "fp_type", "tol", "backend", "scheduler", "workers"),
    "output": ("store",),
}


def _is_real(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


class _Where:
    """Error messages naming the study file and ``table.key``."""

    def __init__(self, source: str):
        self.source = source

    def error(self, key: str, value, form: str, cls=UsageError) -> TaylorballError:
        shown = "missing" if value is _MISSING else f"= {value!r}"
        return cls(f"{self.source}: {key} {shown}: must be {form}")


_MISSING = object()


def _real(w: _Where, table: Mapping, tname: str, key: str, *, default=_MISSING, lo=None, lo_open=False,
          form: Optional[str] = None) -> float:
    v = table.get(key, default)
    rng = "" if lo is None else f" {'>' if lo_open else '>='} {lo:g}"
    form = form or f"a finite number{rng}"
    if v is _MISSING or not _is_real(v) or not math.isfinite(v) or (
            lo is not None and (v <= lo if lo_open else v < lo)):
        raise w.error(f"[{tname}] {key}", v, form)
    return float(v)


def _multiple(a: float, b: float) -> Optional[int]:
    """``a / b`` if it is a positive integer (to 1e-9 relative), else None."""
    r = a / b
    n = round(r)
    return int(n) if n >= 1 and abs(r - n) <= 1e-9 * r else None


@dataclass(frozen=True)
class StudyConfig:
    """A validated study (see the module docstring and ``docs/longruns.md``).

    Build it with :func:`load_study` (a TOML file) or :meth:`from_dict`; every key is
    checked on construction, with an error naming the file, ``[table] key``, the bad value
    and the valid form; unknown tables and keys are refused.

    Attributes
    ----------
    source : str
        The study file (or ``"<dict>"``), for messages.
    kind : str
        ``"reduced"`` (a ``[ball]`` study).
    params : BallParams
    levels : Levels or None
        The level the orbits are drawn on (``[level]``), None with explicit states.
    n_orbits, seed, states
        ``[orbits]``: ``n`` drawn with ``seed``, or explicit public ``states``.
    t_end, checkpoint_every, sample_dt : float
    fp_type : str
    tol : float or None
    backend : str
        ``"threads"``, ``"processes"``, ``"serial"``, ``"dask"`` (scalar integrators) or
        ``"lanes"`` (float64 batch integrators).
    scheduler : str or None
    workers : int or None
    observables : dict
        The ``[observables]`` table with every default filled in.
    store : Path
        Absolute path of the store (``[output] store``, relative to the study file's folder).
    """

    source: str
    kind: Literal["full", "reduced", "mparallel"]
    params: Any
    levels: Any
    n_orbits: int
    seed: int
    states: Optional[Tuple[Tuple[float, ...], ...]]
    t_end: float
    checkpoint_every: float
    sample_dt: float
    fp_type: str
    tol: Optional[float]
    backend: str
    scheduler: Optional[str]
    workers: Optional[int]
    observables: Mapping[str, Any]
    store: Path

    # -- construction ---------------------------------------------------------------------
    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, source: str = "<dict>", base: Optional[Path] = None) -> "StudyConfig":
        """A study from its parsed TOML tables; ``base`` is the folder ``[output] store`` is
        relative to (default: the current folder)."""
        from .levels import Levels
        from .numbers import resolve_fp_type
        from .observables import build_observables, observable_keys
        from .params import BallParams
        from ._problem import _check_tol

        w = _Where(source)
        if not isinstance(d, Mapping):
            raise UsageError(f"{source}: a study must be a table of tables, got {type(d).__name__}")
        known = set(_TABLES) | {"observables", "mparallel"}
        for t in d:
            if t not in known:
                raise UsageError(f"{source}: unknown table [{t}]; valid tables: "
                                 f"{', '.join('[' + k + ']' for k in sorted(known - {'mparallel'}))}")
            if not isinstance(d[t], Mapping):
                raise UsageError(f"{source}: [{t}] must be a table, got {d[t]!r}")
        if "mparallel" in d:
            raise UsageError(f"{source}: [mparallel] studies (the M||gamma system) are not supported by study files "
                             "yet; use [ball] (the reduced system), or the Python API (tb.long_run)")
        for t, keys in _TABLES.items():
            for k in d.get(t, {}):
                if k not in keys:
                    raise UsageError(f"{source}: unknown key [{t}] {k}; valid keys of [{t}]: {', '.join(keys)}")
        okeys = observable_keys()
        for k in d.get("observables", {}):
            if k not in okeys:
                raise UsageError(f"{source}: unknown key [observables] {k}; valid keys: {', '.join(okeys)}")

        # [ball]
        if "ball" not in d:
            raise UsageError(f"{source}: missing table [ball] (inertia = [I1, I2, I3], mass, radius, plane_rate)")
        b = d["ball"]
        inertia = b.get("inertia", _MISSING)
        if not (isinstance(inertia, list) and len(inertia) == 3 and all(_is_real(v) for v in inertia)):
            raise w.error("[ball] inertia", inertia, "a list of 3 numbers [I1, I2, I3]")
        mass = _real(w, b, "ball", "mass", lo=0.0, lo_open=True)
        radius = _real(w, b, "ball", "radius", lo=0.0, lo_open=True)
        rate = _real(w, b, "ball", "plane_rate")
        try:
            params = BallParams(inertia=(float(inertia[0]), float(inertia[1]), float(inertia[2])), mass=mass,
                                radius=radius, plane_rate=rate)
        except ParameterError as exc:
            raise ParameterError(f"{source}: [ball]: {exc}") from None

        # [orbits] and [level]
        o = d.get("orbits", {})
        lv = d.get("level", {})
        states = None
        n_orbits, seed = 0, 0
        levels = None
        if "states" in o:
            if "n" in o or "seed" in o:
                raise UsageError(f"{source}: [orbits] takes either n (and seed) or states, not both")
            st = o["states"]
            if not (isinstance(st, list) and 1 <= len(st) <= MAX_ORBITS and all(
                    isinstance(s, list) and len(s) == 9 and all(_is_real(v) for v in s) for s in st)):
                raise w.error("[orbits] states", st, f"a list of 1 to {MAX_ORBITS} states, each a list of 9 numbers "
                                                    "(omega1..3, gamma1..3, R1..3: the reduced public layout)")
            if lv:
                raise UsageError(f"{source}: [level] is not used with explicit [orbits] states; remove one of them")
            from .manifold import as_state

            for i, s in enumerate(st):
                try:
                    as_state("reduced", np.array(s, dtype=float))
                except StateError as exc:
                    raise StateError(f"{source}: [orbits] states[{i}]: {exc}") from None
            states = tuple(tuple(float(v) for v in s) for s in st)
            n_orbits = len(states)
        else:
            n = o.get("n", _MISSING)
            if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_ORBITS:
                raise w.error("[orbits] n", n, f"an integer in [1, {MAX_ORBITS}] (orbits drawn on the level), "
                                             "or give [orbits] states")
            seed = o.get("seed", 0)
            if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
                raise w.error("[orbits] seed", seed, "a non-negative integer")
            n_orbits = n
            caption = [k for k in ("G", "H") if k in lv]
            direct = [k for k in ("C", "M_gamma") if k in lv]
            if caption and direct:
                raise UsageError(f"{source}: [level] takes either G, H, h (the captions) or C, M_gamma, h, not a mix "
                                 f"(got {', '.join(sorted(lv))})")
            names = ("G", "H", "h") if caption or not direct else ("C", "M_gamma", "h")
            vals = [_real(w, lv, "level", k) for k in names]
            try:
                levels = Levels.from_caption(*vals) if names[0] == "G" else Levels(*vals)
            except ParameterError as exc:
                raise ParameterError(f"{source}: [level]: {exc}") from None

        # [run]
        r = d.get("run", {})
        sample_dt = _real(w, r, "run", "sample_dt", default=0.25, lo=0.0, lo_open=True)
        ce = _real(w, r, "run", "checkpoint_every", lo=0.0, lo_open=True)
        per = _multiple(ce, sample_dt)
        if per is None:
            raise w.error("[run] checkpoint_every", r["checkpoint_every"],
                          f"a positive multiple of [run] sample_dt = {sample_dt!r}")
        if per > MAX_SAMPLES_PER_CHUNK:
            raise w.error("[run] checkpoint_every", r["checkpoint_every"],
                          f"at most {MAX_SAMPLES_PER_CHUNK} samples per chunk (sample_dt = {sample_dt!r}; a chunk's "
                          "states are held in memory): a smaller checkpoint_every or a larger sample_dt")
        t_end = _real(w, r, "run", "t_end", lo=0.0, lo_open=True)
        _check_t_end(w, "[run] t_end", r["t_end"], ce)
        fp_type = r.get("fp_type", "float")
        if not (isinstance(fp_type, str) and fp_type in FP_TYPES):
            raise w.error("[run] fp_type", fp_type, f"one of {', '.join(map(repr, FP_TYPES))}")
        tol = r.get("tol", None)
        if tol is not None:
            try:
                tol = _check_tol(tol, resolve_fp_type(fp_type))
            except UsageError as exc:
                raise UsageError(f"{source}: [run] tol: {exc}") from None
        backend = r.get("backend", "threads")
        if not (isinstance(backend, str) and backend in BACKENDS):
            raise w.error("[run] backend", backend, f"one of {', '.join(map(repr, BACKENDS))}")
        _check_lanes_fp(w, backend, fp_type)
        scheduler = r.get("scheduler", None)
        if backend == "dask":
            if not (isinstance(scheduler, str) and "://" in scheduler):
                raise w.error("[run] scheduler", scheduler if "scheduler" in r else _MISSING,
                              "a dask scheduler address such as \"tcp://10.0.0.1:8786\" (backend = \"dask\")")
        elif scheduler is not None:
            raise UsageError(f"{source}: [run] scheduler = {scheduler!r} is only used with backend = \"dask\" "
                             f"(backend is {backend!r})")
        workers = r.get("workers", None)
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                    or not 1 <= workers <= 4096):
            raise w.error("[run] workers", workers, "an integer in [1, 4096] (threads or processes)")

        # [observables]
        table = dict(d.get("observables", {}))
        try:
            objs = build_observables(table, sample_dt)
        except UsageError as exc:
            raise UsageError(f"{source}: {exc}") from None
        full = {}
        from .observables import builders

        for bl in builders():
            for k in bl.keys:
                full[k] = table.get(k, bl.defaults[k])
        del objs

        # [output]
        out = d.get("output", {})
        st_path = out.get("store", _MISSING)
        if not (isinstance(st_path, str) and st_path.strip()):
            raise w.error("[output] store", st_path, "a folder path (relative to the study file's folder)")
        p = Path(st_path).expanduser()
        if not p.is_absolute():
            p = (base or Path.cwd()) / p
        p = Path(os.path.abspath(p))
        if p.exists() and not p.is_dir():
            raise w.error("[output] store", st_path, "a folder path (it is a file)")
        return cls(source=source, kind="reduced", params=params, levels=levels, n_orbits=n_orbits, seed=seed,
                   states=states, t_end=t_end, checkpoint_every=ce, sample_dt=sample_dt, fp_type=fp_type, tol=tol,
                   backend=backend, scheduler=scheduler, workers=workers, observables=full, store=p)

    # -- derived --------------------------------------------------------------------------
    @property
    def samples_per_chunk(self) -> int:
        return int(round(self.checkpoint_every / self.sample_dt))

    def n_chunks(self, t_end: Optional[float] = None) -> int:
        """Chunks of a run to ``t_end`` (default: the study's)."""
        return int(round((self.t_end if t_end is None else t_end) / self.checkpoint_every))

    def problem(self) -> Problem:
        from ._problem import problem

        return problem(self.kind, self.params, fp_type=self.fp_type, tol=self.tol)

    def observable_objects(self) -> list:
        from .observables import build_observables

        return build_observables(self.observables, self.sample_dt)

    @cached_property
    def initial_states(self) -> np.ndarray:
        """The orbits' initial public states (n, 9): the explicit ones, or ``n`` drawn
        uniformly on the admissible region of the level's section ``g = 0`` (first root
        ``K`` of each chart point, ``direction = +1``)."""
        if self.states is not None:
            return np.array(self.states, dtype=float)
        X = _draw(self.params, self.levels, self.n_orbits, self.seed)
        if len(X) < self.n_orbits:
            raise UsageError(f"{self.source}: only {len(X)} of [orbits] n = {self.n_orbits} admissible "
                             "points were found on the level; use a smaller n or another level")
        return X.copy()

    def as_dict(self) -> Dict[str, Any]:
        """The normalised study (JSON-able)."""
        from .io import jsonable

        d = jsonable(self)
        d["store"] = str(self.store)
        return d

    def fingerprint(self) -> str:
        """sha256 of everything an orbit's bits depend on: problem, orbits, chunking, the
        observables' options and the integrator family (scalar or lanes; not t_end, the
        scalar backend, workers or the store)."""
        from .io import jsonable

        blob = {
            "format": 1, "kind": self.kind, "params": jsonable(self.params), "fp_type": self.fp_type, "tol": self.tol,
            "formulation": self.problem().formulation, "checkpoint_every": self.checkpoint_every,
            "sample_dt": self.sample_dt,
            "orbits": {"states": [list(s) for s in self.states]} if self.states is not None else
            {"n": self.n_orbits, "seed": self.seed, "levels": jsonable(self.levels)},
            "observables": [[o.name, o.options()] for o in self.observable_objects()],
        }
        if self.backend == "lanes":  # other bits than the scalar integrator's (absent: scalar)
            blob["integrator"] = "lanes"
        return hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()[:32]

    @property
    def integrator_family(self) -> str:
        """``"lanes"`` (float64 SIMD batch integrators) or ``"scalar"`` (every other
        backend): the two give different bits, so a store is resumed by its own family."""
        return "lanes" if self.backend == "lanes" else "scalar"

    def orbit_fingerprint(self, i: int) -> str:
        x0 = self.initial_states[i]
        blob = json.dumps([self.fingerprint(), i, [float(v) for v in x0]])
        return hashlib.sha256(blob.encode()).hexdigest()[:32]


@lru_cache(maxsize=16)
def _draw(params, levels, n: int, seed: int) -> np.ndarray:
    """``n`` states drawn on the level (a pure function of its arguments, remembered: a
    study is loaded again by every command)."""
    from .charts import section_admissible_sample

    region = section_admissible_sample(params, **levels.as_kwargs(), n=n, seed=seed, direction=1)
    X = np.array([roots[0] for roots in region["states"]], dtype=float)
    X.setflags(write=False)
    return X


def _check_lanes_fp(w: _Where, backend, fp_type) -> None:
    if backend == "lanes" and fp_type != "float":
        raise UsageError(f"{w.source}: [run] backend = \"lanes\" runs float64 only (heyoka's SIMD batch mode), "
                         f"got [run] fp_type = {fp_type!r}: use fp_type = \"float\" with backend = \"lanes\", or a "
                         "scalar backend (\"threads\", \"processes\", \"serial\", \"dask\") for "
                         f"{fp_type!r}")


def _check_t_end(w: _Where, key: str, t_end, ce: float) -> int:
    n = _multiple(float(t_end), ce)
    if n is None:
        lo = max(1, math.floor(t_end / ce)) * ce
        hi = max(1, math.ceil(t_end / ce)) * ce
        near = f"{lo:g}" if lo == hi else f"{lo:g} or {hi:g}"
        raise w.error(key, t_end, f"a positive multiple of [run] checkpoint_every = {ce!r} (nearest valid: {near}), "
                                  "so that extending a run continues exactly where it stopped")
    if n > MAX_CHUNKS:
        raise w.error(key, t_end, f"at most {MAX_CHUNKS} chunks of checkpoint_every = {ce!r}: a larger "
                                  "checkpoint_every")
    return n


def load_study(path: Union[str, "os.PathLike[str]"]) -> StudyConfig:
    """Read and validate a study file (TOML).

    Raises
    ------
    UsageError, ParameterError, StateError
        A missing or unreadable file, bad TOML, or a bad key (named with the file and
        ``[table] key``).
    """
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # Python 3.10: the same parser as a package
        import tomli as tomllib

    try:
        p = Path(path)
    except TypeError:
        raise UsageError(f"study must be a path to a TOML study file or a StudyConfig, got {path!r}") from None
    if not p.is_file():
        raise UsageError(f"study file {str(p)!r} {'is a folder' if p.is_dir() else 'does not exist'}: give a TOML "
                         "study file (see docs/longruns.md)")
    try:
        d = tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"{p}: not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"{p}: cannot be read: {exc}") from None
    return StudyConfig.from_dict(d, source=str(p), base=p.resolve().parent)


def _as_config(study: Any) -> StudyConfig:
    if isinstance(study, StudyConfig):
        return study
    if isinstance(study, (str, os.PathLike)):
        return load_study(study)
    raise UsageError(f"study must be a path to a TOML study file or a StudyConfig, got {study!r}")


# ---------------------------------------------------------------------------------------
# The store of a study.
# ---------------------------------------------------------------------------------------
def _layouts(cfg: StudyConfig, prob, objs) -> Dict[str, Dict[str, Any]]:
    return {o.name: o.layout(prob) for o in objs}


def _create_store(cfg: StudyConfig, path: Path, t_end: float) -> None:
    from .io import provenance
    from .store import FORMAT_VERSION, RunStore

    X = cfg.initial_states
    orbits = [{"fingerprint": cfg.orbit_fingerprint(i), "index": i, "initial_state": [float(v) for v in X[i]]}
              for i in range(len(X))]
    RunStore(path).create({"format": FORMAT_VERSION, "study": cfg.as_dict(), "fingerprint": cfg.fingerprint(),
                           "provenance": provenance(), "t_end": t_end}, orbits)


def _open_checked(cfg: StudyConfig):
    """The study's store after the start-up check (root fingerprint and every orbit);
    returns ``(store, checkpoints)``."""
    from .store import FORMAT_VERSION, RunStore

    store = RunStore(cfg.store)
    attrs = store.attrs()
    if attrs.get("format") != FORMAT_VERSION:
        raise StoreError(f"{store.path}: not a taylorball run store of format {FORMAT_VERSION} (format "
                         f"{attrs.get('format')!r})")
    if attrs.get("fingerprint") != cfg.fingerprint():
        other = dataclasses.replace(cfg, backend="threads" if cfg.backend == "lanes" else "lanes")
        if attrs.get("fingerprint") == other.fingerprint():
            was = attrs.get("study", {}).get("backend", other.backend)
            raise StoreError(f"{store.path} was written by backend {was!r} ({other.integrator_family} integrators) "
                             f"and cannot be resumed or extended by backend {cfg.backend!r} ({cfg.integrator_family} "
                             "integrators): the two give different bits; set [run] backend back to "
                             f"{was!r} (any scalar backend resumes a scalar store), use another [output] store, "
                             "or --restart to replace it")
        raise StoreError(f"{store.path} was made by another study (fingerprint {attrs.get('fingerprint')} != "
                         f"{cfg.fingerprint()} of {cfg.source}): its ball, level, orbits, number type, chunking or "
                         "observables differ; use another [output] store, or --restart to replace it")
    prob = cfg.problem()
    layouts = _layouts(cfg, prob, cfg.observable_objects())
    cks = [store.orbit(i).verify(cfg.orbit_fingerprint(i), layouts) for i in range(cfg.n_orbits)]
    return store, cks


# ---------------------------------------------------------------------------------------
# One orbit.
# ---------------------------------------------------------------------------------------
def _exact_list(a: np.ndarray) -> list:
    from .longrun import _save_state

    s = _save_state(a)
    return [float(v) for v in s] if s.dtype == np.float64 else [str(v) for v in s]


def _from_list(values: list, spec) -> np.ndarray:
    from .longrun import _load_state

    return _load_state(np.array(values, dtype=float if all(isinstance(v, float) for v in values) else str), spec)


class _OrbitJob:
    """One orbit's job in the store, whatever integrates it: its lock, the checks of its
    fingerprint and checkpoint, the state to start from, and per chunk the observables'
    reduction of a :class:`~taylorball.observables.ChunkData` and the commit (shared by the
    scalar runner :func:`_run_orbit` and the lanes, :func:`_run_lanes`)."""

    def __init__(self, cfg: StudyConfig, i: int, t_end: float, prob, objs, layouts) -> None:
        from .store import RunStore

        self.cfg, self.i, self.prob, self.objs, self.layouts = cfg, i, prob, objs, layouts
        self.orb = RunStore(cfg.store).orbit(i)
        self.fp = cfg.orbit_fingerprint(i)
        self.n_total = cfg.n_chunks(t_end)
        self.lock: Any = None
        self.ck: Optional[Dict[str, Any]] = None
        self.cleaned = False  # the arrays were cut to the checkpoint: close() may trim

    def open(self) -> int:
        """Take the orbit's lock, check it, clean a killed writer's leftovers; returns the
        chunks already committed."""
        from .store import _seal

        orb, fp = self.orb, self.fp
        self.lock = orb.lock().acquire()
        self.attrs = attrs = orb.attrs()
        if attrs.get("fingerprint") != fp:
            raise StoreError(f"{orb.what()} belongs to another run (fingerprint {attrs.get('fingerprint')!r})")
        ck = attrs.get("checkpoint")
        if ck is not None and ck.get("seal") != _seal(fp, ck):
            raise StoreError(f"{orb.what()}: its checkpoint was altered (does not match its seal); use --restart")
        self.ck = ck
        # leftovers of a killed writer (uncommitted rows, temporaries) go first, also when
        # nothing is left to run: a kill after the last commit and before the trim at the
        # end of the job left arrays longer than committed (found by the slow kill -9 test)
        orb.clean(self.layouts, ck)
        self.cleaned = True
        return int(ck["chunks"]) if ck else 0

    def start(self) -> Tuple[np.ndarray, Optional[Tuple[Any, Any]]]:
        """The internal state to go on from and its double-length time ``(hi, lo)`` (None
        at the orbit's start, time 0); sets the carries and counters."""
        from ._propagate import start_state
        from .store import genesis, unpack_carry

        prob, spec, ck = self.prob, self.prob.spec, self.ck
        x0 = start_state(prob, np.array(self.attrs["initial_state"], dtype=float))
        if ck:
            self.carries = {o.name: unpack_carry(ck["carries"][o.name]) for o in self.objs}
            self.n_steps, self.h = int(ck["n_steps"]), bytes.fromhex(ck["digest"])
            self.lengths = dict(ck["lengths"])
            self.wall_total, self.wall_chunks = float(ck["wall_total"]), int(ck["wall_chunks"])
            hi, lo = _from_list(ck["dtime"], spec)
            return _from_list(ck["state"], spec), (hi, lo)
        self.carries = {o.name: o.init(prob, x0, 0.0) for o in self.objs}
        self.n_steps, self.h, self.lengths = 0, genesis(self.fp), {}
        self.wall_total, self.wall_chunks = 0.0, 0
        return x0, None

    def grid(self, k: int) -> Tuple[np.ndarray, np.ndarray]:
        """Chunk ``k``'s sample indices ``m`` and times ``t = m * sample_dt`` (both ends)."""
        per = self.cfg.samples_per_chunk
        m = np.arange(k * per, (k + 1) * per + 1, dtype=np.int64)
        return m, m * self.cfg.sample_dt

    def commit(self, k: int, m: np.ndarray, t: np.ndarray, X: np.ndarray, events: Sequence[Mapping[int, list]],
               steps: int, state: np.ndarray, dtime: Tuple[Any, Any], w0: float,
               share: float = 1.0) -> Dict[str, Any]:
        """Reduce chunk ``k`` (grid ``m``, ``t``, internal states ``X`` there, each
        observable's event records) by the observables and commit it with the checkpoint
        (end ``state``, double-length time ``dtime``; the chunk's wall time is ``share`` of
        the time since ``time.perf_counter()`` was ``w0``)."""
        from ._propagate import public_states
        from .observables import ChunkData
        from .store import pack_carry

        prob, spec = self.prob, self.prob.spec
        self.n_steps += steps
        public = public_states(prob, X).astype(float)
        records = {}
        for o, own in zip(self.objs, events):
            data = ChunkData(k=k, t0=float(t[0]), t1=float(t[-1]), t=t, i=m, x=X, public=public, events=own,
                             problem=prob, n_steps=steps, sample_dt=self.cfg.sample_dt)
            self.carries[o.name], records[o.name] = o.chunk(self.carries[o.name], data)
        wall = (time.perf_counter() - w0) * share
        hi, lo = dtime
        ck_new = {"t": float(t[-1]), "state": _exact_list(np.array(state)),
                  "dtime": _exact_list(np.array([hi, lo], dtype=spec.dtype)), "n_steps": self.n_steps,
                  "carries": {name: pack_carry(c) for name, c in self.carries.items()},
                  "lengths_before": self.lengths, "wall_total": self.wall_total + wall,
                  "wall_chunks": self.wall_chunks + 1, "wall_last": wall}
        ck, self.h = self.orb.append(self.fp, k, self.layouts, records, ck_new, self.h)
        self.ck = ck
        self.lengths = dict(ck["lengths"])
        self.wall_total, self.wall_chunks = self.wall_total + wall, self.wall_chunks + 1
        self.lock.touch()
        return ck

    def close(self) -> None:
        """Cut the arrays to the committed lengths and release the lock. The lengths are
        the stored checkpoint's: an interrupt (Ctrl-C) may land after a commit and before
        :meth:`commit` returns."""
        if self.lock is None:
            return
        try:
            if self.cleaned:
                self.orb.trim(self.layouts, self.orb.checkpoint())
        finally:
            self.lock.release()
            self.lock = None


def _run_orbit(cfg: StudyConfig, i: int, t_end: float) -> Optional[Dict[str, Any]]:
    """Run (or resume) orbit ``i`` to ``t_end``, chunk by chunk, committing each; returns
    its checkpoint. A member of :func:`taylorball.ensemble.run_many` (Ctrl-C and progress
    through :func:`taylorball.ensemble.current`)."""
    from .ensemble import current
    from .observables import events_key
    from ._propagate import _check_outcome, integrator

    prob = cfg.problem()
    spec = prob.spec
    objs = cfg.observable_objects()
    job = _OrbitJob(cfg, i, t_end, prob, objs, _layouts(cfg, prob, objs))
    ctx = current()
    n_total = job.n_total
    try:
        k0 = job.open()
        ctx.advance(min(k0, n_total) / n_total)
        if k0 >= n_total:
            return job.ck
        evs = [o.events(prob) for o in objs]
        flat = [e for lst in evs for e in lst]
        if flat:
            key = ("observables",) + tuple(events_key(o) for o, lst in zip(objs, evs) if lst)
            template = integrator(prob, events_key=key, events=lambda: {"nt_events": list(flat)})
        else:
            template = integrator(prob)
        ta = copy.copy(template)
        ta.pars[:] = prob.pars
        x, dtime = job.start()
        ta.state[:] = x
        if dtime is not None:
            ta.dtime = dtime
        else:
            ta.time = spec.scalar(0.0)
        callbacks = [ev.callback for ev in ta.nt_events] if flat else []
        for k in range(k0, n_total):
            w0 = time.perf_counter()
            m, t = job.grid(k)
            res = ta.propagate_grid(spec.array(t))
            _check_outcome(ta, res, float(t[-1]))
            events, j = [], 0
            for lst in evs:
                own = {}
                for e in range(len(lst)):
                    cb = callbacks[j]
                    own[e] = list(zip(cb.times, cb.states))
                    cb.times.clear()
                    cb.states.clear()
                    j += 1
                events.append(own)
            job.commit(k, m, t, np.asarray(res[-1]), events, int(res[3]), ta.state, ta.dtime, w0)
            ctx.advance(1 / n_total)
            if k + 1 < n_total and ctx.stopping:
                job.orb.trim(job.layouts, job.ck)
            ctx.check()  # Ctrl-C stops here, the chunk committed
        return job.ck
    finally:
        job.close()


# ---------------------------------------------------------------------------------------
# Many orbits in the SIMD lanes of batch integrators (backend = "lanes", float64).
# ---------------------------------------------------------------------------------------
class _LaneView:
    """What a scalar event callback reads of its integrator (``dtime``, ``pars``,
    ``last_h``, ``update_d_output(rel, rel_time=True)``), for one lane of a batch
    integrator: so the observables' own callbacks (:class:`taylorball.sections._Collector`,
    the lifted angle's cut collector) run unchanged in lanes."""

    __slots__ = ("ta", "lane", "rel")

    def __init__(self, ta: Any, lane: int, rel: np.ndarray) -> None:
        self.ta, self.lane, self.rel = ta, lane, rel

    @property
    def dtime(self) -> Tuple[float, float]:
        hi, lo = self.ta.dtime
        return float(hi[self.lane]), float(lo[self.lane])

    @property
    def pars(self) -> np.ndarray:
        return np.ascontiguousarray(self.ta.pars[:, self.lane])

    @property
    def last_h(self) -> float:
        return float(self.ta.last_h[self.lane])

    def update_d_output(self, t: float, rel_time: bool = False) -> np.ndarray:
        if not rel_time:
            raise UsageError("an event callback in lanes must ask for the dense output with rel_time=True")
        self.rel[self.lane] = t  # the other lanes' entries are stale and their outputs unused
        return np.array(self.ta.update_d_output(self.rel, rel_time=True)[:, self.lane], copy=True)


class _LaneCallback:
    """A batch event's callback (``nt_event_batch``: heyoka passes the lane index): one
    copy of the observable's scalar callback per lane, called with a :class:`_LaneView` of
    its lane; the lane's records are read from ``lanes[lane].times`` / ``.states``."""

    def __init__(self, proto: Any, size: int) -> None:
        self.proto, self.size = proto, size
        self.lanes = [copy.deepcopy(proto) for _ in range(size)]
        self.rel = np.zeros(size)

    def __deepcopy__(self, memo: Any) -> "_LaneCallback":
        return _LaneCallback(self.proto, self.size)

    def __call__(self, ta: Any, t: float, d_sgn: Any, idx: int) -> None:
        self.lanes[idx](_LaneView(ta, idx, self.rel), t, d_sgn)


def _lane_template(prob, objs, size: int):
    """The cached float64 batch integrator of ``size`` lanes with the observables' events
    in batch form; returns it and the observables' scalar events (per observable)."""
    import heyoka as hy

    from ._cache import compiled
    from .observables import events_key

    evs = [o.events(prob) for o in objs]
    flat = [e for lst in evs for e in lst]
    key = ("batch", *prob.compile_key, size, "observables") + tuple(
        events_key(o) for o, lst in zip(objs, evs) if lst)

    def build():
        system = prob.system
        kw: Dict[str, Any] = dict(pars=np.zeros((system.n_pars, size)))
        if flat:
            kw["nt_events"] = [hy.nt_event_batch(ev.expression, _LaneCallback(ev.callback, size),
                                                 direction=ev.direction) for ev in flat]
        if prob.tol is not None:
            kw["tol"] = float(prob.tol)
        return hy.taylor_adaptive_batch(system.equations(), np.full((system.dim, size), 0.1), **kw)

    return compiled(key, build), evs


def _uses_grid(obs) -> bool:
    """Whether an observable reads the chunk's sample grid (``ChunkData.t``, ``x``,
    ``public``); an observable says it does not by ``uses_grid() -> False``."""
    own = getattr(obs, "uses_grid", None)
    return True if own is None else bool(own())


def _run_lanes(cfg: StudyConfig, todo: Sequence[int], t_end: float, workers: Optional[int], progress: Any) -> None:
    """Run (or resume) the orbits ``todo`` to ``t_end`` in the lanes of float64 batch
    integrators (:func:`taylorball.ensemble.run_many` with ``backend="lanes"``), chunk by
    chunk, each chunk reduced and committed per orbit exactly as :func:`_run_orbit` does.

    Each orbit goes through the chunk ends ``(k + 1) checkpoint_every`` of its own clock
    (resumed: from its checkpoint's state and double-length time), each chunk one batch
    ``propagate_grid`` on the orbit's own sample grid ``m * sample_dt`` as in the scalar
    runner (``LaneTask.grid``), so its records depend on its own orbit only, whatever
    lane, thread or companions it has. When no observable uses the sample grid (drift and
    sections only) the grid is the chunk's two ends: the same steps (a grid's density does
    not change them; ``propagate_until`` would), and the observables get those two ends."""
    from .errors import IntegrationError
    from .ensemble import LaneLoad, LaneTask, run_many
    from .sections import batch_size

    prob = cfg.problem()
    objs = cfg.observable_objects()
    layouts = _layouts(cfg, prob, objs)
    size = batch_size()
    template, evs = _lane_template(prob, objs, size)
    grid = any(_uses_grid(o) for o in objs)
    jobs = [_OrbitJob(cfg, i, t_end, prob, objs, layouts) for i in todo]
    n = len(jobs)
    pars = np.asarray(prob.pars, dtype=float)
    per, dt = cfg.samples_per_chunk, cfg.sample_dt
    k_next = [0] * n  # the next chunk of each orbit
    w0 = [0.0] * n
    errors: List[Optional[BaseException]] = [None] * n
    callbacks: Dict[int, list] = {}  # id(ta) -> the batch events' callbacks of that copy

    def cbs(ta):
        got = callbacks.get(id(ta))
        if got is None:
            got = callbacks[id(ta)] = [ev.callback for ev in ta.nt_events]
        return got

    def load(j):
        job = jobs[j]
        k0 = job.open()  # in the lane's worker thread, as every callback of this job
        x, dtime = job.start()
        hi, lo = (0.0, 0.0) if dtime is None else (float(dtime[0]), float(dtime[1]))
        k_next[j], w0[j] = k0, time.perf_counter()
        if k0 >= job.n_total:  # the start-up check (under the store's lock) said otherwise
            raise StoreError(f"{job.orb.what()} was completed by another writer during this run")

        def ends(k, k0=k0):  # the same numbers as the scalar grid's last point, m * sample_dt
            return float(np.int64((k0 + k + 1) * per) * dt)

        def samples(k, k0=k0):  # the grid t_m = m * sample_dt of chunk k0 + k, without its start
            return ((k0 + k) * per + np.arange(1, per + 1, dtype=np.int64)) * dt

        def end_only(k):  # no observable reads the grid: the same steps on the chunk's two ends
            return np.array([ends(k)])

        return LaneLoad(x, pars, hi, ends(job.n_total - 1 - k0), cfg.checkpoint_every, t0_lo=lo, ends=ends,
                        chunk_samples=samples if grid else end_only)

    def after_chunk(ta, chunks):
        his, los = ta.dtime
        own_cbs = cbs(ta) if any(evs) else []
        done = []
        for c in chunks:
            j = c.job
            job = jobs[j]
            k = k_next[j]
            if k >= job.n_total:
                done.append(True)
                continue
            m, t = job.grid(k)
            state = np.array(ta.state[:, c.lane], copy=True)
            X = c.sample_x  # the chunk's propagate_grid: its grid t (or its two ends), the start first
            if not grid:
                m, t = m[[0, -1]], t[[0, -1]]
            events, e = [], 0
            for lst in evs:
                own = {}
                for q in range(len(lst)):
                    cb = own_cbs[e].lanes[c.lane]
                    own[q] = list(zip(cb.times, cb.states))
                    cb.times.clear()
                    cb.states.clear()
                    e += 1
                events.append(own)
            # the orbit's share of its worker's time: the lanes of one integrator share it
            job.commit(k, m, t, X, events, c.steps, state, (his[c.lane], los[c.lane]), w0[j], share=1.0 / size)
            w0[j] = time.perf_counter()
            k_next[j] = k + 1
            done.append(k + 1 >= job.n_total)
        return done

    def failed(j, outcome, t):
        errors[j] = IntegrationError(
            f"{jobs[j].orb.what()}: integration stopped at t={t} (in a lane of a batch integrator) with outcome "
            f"{outcome}; a non-finite state usually means a singular configuration (e.g. 1 - d(gamma, A gamma) = 0) "
            "or an orbit escaping to infinity")

    def on_reset(ta, lane):
        for cb in (cbs(ta) if any(evs) else []):  # what a failed orbit's events left
            cb.lanes[lane].times.clear()
            cb.lanes[lane].states.clear()

    def result(j):
        if errors[j] is not None:
            raise errors[j]
        return jobs[j].ck

    task = LaneTask(template, n, load=load, after_chunk=after_chunk, failed=failed,
                    fraction=lambda c: k_next[c.job] / jobs[c.job].n_total,
                    on_done=lambda j: jobs[j].close(), result=result, on_reset=on_reset, grid=True)
    try:
        run_many(task, backend="lanes", workers=workers, progress=progress)
    finally:
        for job in jobs:  # a stopped or failed run: trim and unlock what is still open
            job.close()


# ---------------------------------------------------------------------------------------
# Public entry points.
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StudyStatus:
    """Progress of a study: one row per orbit (``orbits``: dicts with ``index``, ``t_done``,
    ``chunks``, ``n_steps``, ``max_drift`` (largest relative integral drift so far, None
    without the drift observable), ``wall_per_chunk`` (s), ``eta`` (s, this orbit alone)),
    the requested ``t_end`` and its ``n_chunks``, the store, and the study's ``eta`` with
    ``workers``, each running ``per_worker`` orbits at once (the lanes of a batch
    integrator with ``backend = "lanes"``, whose orbits' wall times per chunk are their
    shares of their worker's time)."""

    store: Path
    t_end: float
    fingerprint: str
    orbits: Tuple[Dict[str, Any], ...]
    workers: int = 1
    n_chunks: int = 0
    per_worker: int = 1

    @property
    def complete(self) -> bool:
        return all(o["t_done"] >= self.t_end for o in self.orbits)

    @property
    def eta(self) -> Optional[float]:
        """Estimated seconds left for the whole study: each orbit's estimate (an orbit with
        no timed chunk yet at the mean wall time per chunk of the others), shared by
        ``workers`` (at most one per ``per_worker`` orbits with work left); None if no
        chunk was timed."""
        timed = [o["wall_per_chunk"] for o in self.orbits if o["wall_per_chunk"] is not None]
        if not timed:
            return None
        mean = float(np.mean(timed))
        left = [o["eta"] if o["eta"] is not None else max(self.n_chunks - o["chunks"], 0) * mean
                for o in self.orbits]
        busy = sum(1 for v in left if v > 0)
        return sum(left) / max(1, min(self.workers, -(-busy // max(1, self.per_worker))))

    def table(self) -> str:
        """A plain-text table, one line per orbit."""
        lines = [f"store {self.store}  t_end {self.t_end:g}  fingerprint {self.fingerprint}",
                 f"{'orbit':>5} {'t done':>12} {'chunks':>7} {'steps':>12} {'max drift':>10} {'s/chunk':>8} "
                 f"{'eta (s)':>9}"]
        for o in self.orbits:
            drift = "-" if o["max_drift"] is None else f"{o['max_drift']:.2e}"
            wpc = "-" if o["wall_per_chunk"] is None else f"{o['wall_per_chunk']:.3f}"
            eta = "-" if o["eta"] is None else f"{o['eta']:.0f}"
            lines.append(f"{o['index']:>5} {o['t_done']:>12g} {o['chunks']:>7} {o['n_steps']:>12} {drift:>10} "
                         f"{wpc:>8} {eta:>9}")
        total = self.eta
        lines.append("estimated time left: " + ("unknown (no chunk timed yet)" if total is None else
                                                f"{total:.0f} s with {self.workers} worker(s)"))
        return "\n".join(lines)


StudyLike = Union[str, "os.PathLike[str]", StudyConfig]


def _lanes_per_worker(cfg: StudyConfig) -> int:
    """Orbits a worker runs at once: the batch size with lanes, else 1."""
    if cfg.backend != "lanes":
        return 1
    from .sections import batch_size

    return batch_size()


def _with_backend(cfg: StudyConfig, backend: Any, client: Any) -> StudyConfig:
    """The study with ``[run] backend`` replaced (``run_study(backend=...)``), checked as in
    the file."""
    if backend is None:
        return cfg
    w = _Where(cfg.source)
    if not (isinstance(backend, str) and backend in BACKENDS):
        raise UsageError(f"backend must be one of {', '.join(map(repr, BACKENDS))} (overrides [run] backend), "
                         f"got {backend!r}")
    _check_lanes_fp(w, backend, cfg.fp_type)
    if backend == "dask" and cfg.scheduler is None and client is None:
        raise UsageError(f"{cfg.source}: backend='dask' needs [run] scheduler in the study file or client=")
    return dataclasses.replace(cfg, backend=backend, scheduler=cfg.scheduler if backend == "dask" else None)


def study_status(study: StudyLike) -> StudyStatus:
    """Per-orbit progress of a study's store (nothing is computed or written).

    Parameters
    ----------
    study : str, os.PathLike or StudyConfig
        The study file (or a loaded study).

    Raises
    ------
    UsageError
        A bad study file, or no store yet.
    StoreError
        A store made by another study (fingerprint), or a corrupt orbit (named).
    """
    cfg = _as_config(study)
    from .store import RunStore

    store = RunStore(cfg.store)
    if not store.exists():
        raise UsageError(f"{cfg.source}: no store at {cfg.store} yet: run `taylorball run {cfg.source}` first")
    store_, cks = _open_checked(cfg)
    t_end = max(float(store.attrs().get("t_end", cfg.t_end)), cfg.t_end)
    n_total = cfg.n_chunks(t_end)
    rows = []
    for i, ck in enumerate(cks):
        ck = ck or {}
        chunks = int(ck.get("chunks", 0))
        drift = None
        carry = ck.get("carries", {}).get("drift")
        if carry is not None:
            drift = max(carry["max"]["data"])
        wpc = ck["wall_total"] / ck["wall_chunks"] if ck.get("wall_chunks") else None
        rows.append({"index": i, "t_done": chunks * cfg.checkpoint_every if chunks else 0.0, "chunks": chunks,
                     "n_steps": int(ck.get("n_steps", 0)), "max_drift": drift, "wall_per_chunk": wpc,
                     "eta": None if wpc is None else max(n_total - chunks, 0) * wpc})
    workers = cfg.workers or (1 if cfg.backend == "serial" else (os.cpu_count() or 1))
    return StudyStatus(store=cfg.store, t_end=t_end, fingerprint=cfg.fingerprint(), orbits=tuple(rows),
                       workers=workers, n_chunks=n_total, per_worker=_lanes_per_worker(cfg))


def run_study(study: StudyLike, *, extend: Optional[float] = None, restart: bool = False,
              workers: Optional[int] = None, client: Any = None, progress: Any = False,
              backend: Optional[str] = None) -> StudyStatus:
    """Run, resume or extend every orbit of a study into its store.

    Parameters
    ----------
    study : str, os.PathLike or StudyConfig
        The study file (TOML) or a loaded study.
    extend : float, optional
        Run every orbit to this end time instead of the file's ``t_end`` (a multiple of
        ``checkpoint_every``); bit-identical to a direct run to it.
    restart : bool
        Replace the store by a new one (atomically: the old store is deleted last).
    workers : int, optional
        Threads or processes (overrides ``[run] workers``).
    client : distributed.Client, optional
        For ``backend = "dask"``: use this client instead of connecting to ``[run]
        scheduler``.
    progress : bool, str or callable
        The engine's progress bar, advanced per chunk.
    backend : str, optional
        Overrides ``[run] backend``: ``"threads"``, ``"processes"``, ``"serial"``,
        ``"dask"`` (with ``[run] scheduler`` or ``client``) or ``"lanes"`` (float64 only:
        the orbits in the SIMD lanes of heyoka batch integrators; other bits than the
        scalar backends', so a store is resumed by the family that wrote it).

    Returns
    -------
    StudyStatus

    Raises
    ------
    UsageError
        A bad study file or argument (before any work).
    StoreError
        A store of another study, a corrupt orbit (named), or a store being written by
        another live process (named: host, pid), all found before any work.
    IntegrationError
        An orbit's integrator stopped; its committed chunks are kept.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import taylorball as tb
    >>> study = '''
    ... [ball]
    ... inertia = [2.0, 3.0, 4.0]
    ... mass = 1.0
    ... radius = 5.0
    ... plane_rate = 2.0
    ... [level]
    ... G = 10.0
    ... H = 2.0
    ... h = 5.0
    ... [orbits]
    ... n = 2
    ... [run]
    ... t_end = 20.0
    ... checkpoint_every = 10.0
    ... backend = "serial"
    ... [observables]
    ... angles_every = 10.0
    ... [output]
    ... store = "store"
    ... '''
    >>> with tempfile.TemporaryDirectory() as d:
    ...     f = pathlib.Path(d) / "study.toml"
    ...     _ = f.write_text(study)
    ...     status = tb.run_study(f)
    ...     ds = tb.open_run(pathlib.Path(d) / "store", observable="angles")
    ...     print(status.complete, dict(ds.sizes))
    True {'orbit': 2, 'time': 3}
    """
    from .ensemble import call, run_many
    from .store import Lock, RunStore

    cfg = _with_backend(_as_config(study), backend, client)
    if not isinstance(restart, bool):
        raise UsageError(f"restart must be True or False, got {restart!r}")
    t_end = cfg.t_end
    if extend is not None:
        _real(_Where(cfg.source), {"extend": extend}, "run", "extend", lo=0.0, lo_open=True,
              form="an end time > 0 (--extend T)")
        _check_t_end(_Where(cfg.source), "--extend", extend, cfg.checkpoint_every)
        t_end = float(extend)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, (int, np.integer))
                                or not 1 <= workers <= 4096):
        raise UsageError(f"workers must be an integer in [1, 4096] (threads or processes), got {workers!r}")
    workers = cfg.workers if workers is None else int(workers)
    store = RunStore(cfg.store)
    if store.path.exists() and not store.exists() and any(store.path.iterdir()):
        raise UsageError(f"{cfg.source}: [output] store {str(store.path)!r} is a folder that is not a taylorball "
                         "run store (no zarr.json); give an empty or new folder")
    store.path.parent.mkdir(parents=True, exist_ok=True)
    with Lock(store.path.with_name(store.path.name + ".lock"), f"the store {store.path}"):
        store.clean_leftovers()
        if restart:
            store.restart(lambda p: _create_store(cfg, p, t_end))
        elif not store.exists():
            if store.path.exists():
                store.path.rmdir()  # empty (checked above)
            store.restart(lambda p: _create_store(cfg, p, t_end))
        _, cks = _open_checked(cfg)  # the start-up check: before any work
        store.set_attrs(t_end=t_end)
        todo = [i for i, ck in enumerate(cks) if (ck or {}).get("chunks", 0) < cfg.n_chunks(t_end)]
        jobs = [call(_run_orbit, cfg, i, t_end) for i in todo]
        label = f"study {Path(cfg.source).stem}" if progress is True else progress
        if jobs and cfg.backend == "lanes":
            _run_lanes(cfg, todo, t_end, workers, label)
        elif jobs:
            mode: Any = cfg.backend  # one of BACKENDS, checked by StudyConfig
            own_client = None
            if mode == "dask" and client is None:
                from distributed import Client

                own_client = client = Client(cfg.scheduler)
            try:
                run_many(jobs, backend=mode, workers=workers, client=client, progress=label)
            finally:
                if own_client is not None:
                    own_client.close()
    return study_status(cfg)


def open_run(store: Union[str, "os.PathLike[str]"], *, observable: Optional[str] = None) -> Any:
    """A study's store as an ``xarray.Dataset``, loaded lazily (dask arrays).

    Parameters
    ----------
    store : str or os.PathLike
        The store folder (``[output] store`` of the study).
    observable : str, optional
        One observable's group (``"drift"``, ``"angles"``, ``"samples"``, ...): its
        arrays under their own names, with dims ``orbit`` and the observable's own
        (``time``, ``chunk``, ``crossing``, ...). By default every observable, named
        ``<observable>_<array>`` with dims ``<observable>_<dim>``.

    Returns
    -------
    xarray.Dataset
        Dim ``orbit`` first; each orbit's committed records, ragged lengths padded with NaN
        (integer arrays become float64 then). Attributes: ``study``, ``fingerprint``,
        ``provenance``, ``t_end`` and per-orbit ``progress`` (chunks done).

    Raises
    ------
    UsageError
        Not a store, or an unknown observable.
    """
    import dask.array as da
    import xarray as xr

    from .store import RunStore, _INDEX

    try:
        rs = RunStore(Path(store))
    except TypeError:
        raise UsageError(f"store must be a folder path, got {store!r}") from None
    if not rs.exists():
        raise UsageError(f"store={str(store)!r} is not a taylorball run store (no zarr.json)")
    attrs = rs.attrs()
    study = attrs.get("study", {})
    n = sum(1 for p in rs.path.iterdir() if p.name.startswith("orbit_") and (p / "zarr.json").is_file())
    cks = [rs.orbit(i).checkpoint() or {} for i in range(n)]
    groups: Dict[str, List[str]] = {}
    for i in range(n):
        od = rs.orbit(i).path
        for g in sorted(p.name for p in od.iterdir() if p.is_dir() and p.name != _INDEX):
            groups.setdefault(g, sorted(q.name for q in (od / g).iterdir() if (q / "zarr.json").is_file()))
    if observable is not None and observable not in groups:
        raise UsageError(f"observable={observable!r} is not in the store; it holds {sorted(groups)}")
    data_vars: Dict[str, Any] = {}
    coords: Dict[str, Any] = {"orbit": np.arange(n)}
    for g in ([observable] if observable else sorted(groups)):
        for v in groups[g]:
            arrays, lens = [], []
            for i in range(n):
                p = rs.orbit(i).path / g / v
                # an orbit whose job never started has no arrays yet: no records
                arrays.append(rs.orbit(i)._array(f"{g}/{v}") if (p / "zarr.json").is_file() else None)
                lens.append(int(cks[i].get("lengths", {}).get(g, 0)) if arrays[-1] is not None else 0)
            first = next(a for a in arrays if a is not None)
            longest = max(lens)
            cols = []
            for arr, m in zip(arrays, lens):
                a = da.from_zarr(arr)[:m] if arr is not None else da.empty((0, *first.shape[1:]), dtype=first.dtype)
                if a.dtype.kind != "f":
                    a = a.astype(np.float64)
                if m < longest:
                    pad = da.full((longest - m, *a.shape[1:]), np.nan, dtype=a.dtype)
                    a = da.concatenate([a, pad], axis=0)
                cols.append(a)
            stacked = da.stack(cols, axis=0)
            meta = first.attrs.asdict()
            names = meta.get("dims") or ["time"] + [f"dim_{j}" for j in range(1, stacked.ndim - 1)]
            dims = ["orbit"] + [d if observable else f"{g}_{d}" for d in names]
            data_vars[v if observable else f"{g}_{v}"] = (dims, stacked, {"doc": meta.get("doc", "")})
            if meta.get("step"):  # records on a regular grid: record j at t = j * step
                coords[dims[1]] = (dims[1], np.arange(longest) * float(meta["step"]))
    ds = xr.Dataset(data_vars, coords=coords)
    ds.attrs.update({"study": json.dumps(study), "fingerprint": attrs.get("fingerprint", ""),
                     "provenance": json.dumps(attrs.get("provenance", {})), "t_end": attrs.get("t_end", 0.0),
                     "progress": [int(ck.get("chunks", 0)) for ck in cks]})
    return ds
