"""A study's configuration: the study file's keys, their validation (errors naming the file,
``[table] key``, the bad value and the valid form), :class:`StudyConfig`, its fingerprints
and the orbits' initial states, and :func:`load_study`."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import tomllib
from dataclasses import dataclass
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Any, Dict, Literal, Mapping, Optional, Tuple, Union

import numpy as np

from ..charts import section_admissible_sample
from ..errors import ParameterError, StateError, TaylorballError, UsageError
from ..io import jsonable
from ..levels import Levels
from ..manifold import as_state
from ..numbers import multiple_of, resolve_fp_type
from ..observables import build_observables, builders, observable_keys, unavailable
from ..model import KIND_TABLE, PUBLIC_NAMES
from ..params import BallParams, MParallelParams
from ..store import orbit_fingerprint
from .._problem import Problem, _check_tol, problem
from .._problem import problem as problem_of

FP_TYPES = ("float", "longdouble", "real128")
BACKENDS = ("threads", "processes", "serial", "dask", "lanes")
#: Limits keeping a study's work and memory proportionate: orbits, samples held per chunk,
#: chunks per orbit.
MAX_ORBITS = 100_000
MAX_SAMPLES_PER_CHUNK = 1_000_000
MAX_CHUNKS = 10_000_000
_TABLES = {
    "ball": ("inertia", "mass", "radius", "plane_rate", "system"),
    "level": ("G", "H", "h", "C", "M_gamma"),
    "orbits": ("n", "seed", "states"),
    "run": ("t_end", "checkpoint_every", "sample_dt", "fp_type", "tol", "backend", "scheduler", "workers"),
    "output": ("store",),
    "mparallel": ("a", "d", "plane_rate"),
}
#: The systems a study runs, by the table naming its parameters (a ``[ball]`` runs the
#: reduced system, or the full one with ``[ball] system = "full"``).
SYSTEMS = {"ball": "reduced", "mparallel": "mparallel"}
#: The systems of a ``[ball]`` (``[ball] system``).
BALL_SYSTEMS = ("reduced", "full")


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


@dataclass(frozen=True)
class StudyConfig:
    """A validated study (see the module docstring and ``docs/longruns.md``).

    Build it with :func:`load_study` (a TOML file), :meth:`from_problem` (from Python) or
    :meth:`from_dict`; every key is
    checked on construction, with an error naming the file, ``[table] key``, the bad value
    and the valid form; unknown tables and keys are refused.

    Attributes
    ----------
    source : str
        The study file (or ``"<dict>"``), for messages.
    kind : str
        ``"reduced"`` (a ``[ball]`` study), ``"full"`` (``[ball] system = "full"``: the full
        system, explicit or drawn states; the observables ``drift``, ``samples_every``,
        ``extremes`` and ``histogram``) or ``"mparallel"`` (a ``[mparallel]`` study: the
        M||gamma system, explicit states, the observables ``drift`` and ``samples_every``).
    params : BallParams or MParallelParams
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
        w = _Where(source)
        if not isinstance(d, Mapping):
            raise UsageError(f"{source}: a study must be a table of tables, got {type(d).__name__}")
        known = set(_TABLES) | {"observables"}
        for t in d:
            if t not in known:
                raise UsageError(f"{source}: unknown table [{t}]; valid tables: "
                                 f"{', '.join('[' + k + ']' for k in sorted(known))}")
            if not isinstance(d[t], Mapping):
                raise UsageError(f"{source}: [{t}] must be a table, got {d[t]!r}")
        for t, keys in _TABLES.items():
            for k in d.get(t, {}):
                if k not in keys:
                    raise UsageError(f"{source}: unknown key [{t}] {k}; valid keys of [{t}]: {', '.join(keys)}")
        okeys = observable_keys()
        for k in d.get("observables", {}):
            if k not in okeys:
                raise UsageError(f"{source}: unknown key [observables] {k}; valid keys: {', '.join(okeys)}")

        # [ball] (the reduced system) or [mparallel] (the M||gamma system)
        named = [t for t in SYSTEMS if t in d]
        if len(named) != 1:
            raise UsageError(f"{source}: {'missing table' if not named else 'both tables'} [ball] (a ball: inertia = "
                             "[I1, I2, I3], mass, radius, plane_rate; the reduced system) "
                             f"{'or' if not named else 'and'} [mparallel] (a = [a1, a2, a3], d, plane_rate; the "
                             "M||gamma system): give one")
        kind: Literal["full", "reduced", "mparallel"] = "reduced" if named[0] == "ball" else "mparallel"
        params: Any
        if named[0] == "ball":
            b = d["ball"]
            system = b.get("system", "reduced")
            if not (isinstance(system, str) and system in BALL_SYSTEMS):
                raise w.error("[ball] system", system, '"reduced" (default: the reduced system, paper eqs. (15)-(16) [eq10]) '
                              'or "full" (the full system with the ball\'s frame and contact point, paper eqs. (8)-(10) [eq6])')
            kind = "full" if system == "full" else "reduced"
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
        else:
            mp = d["mparallel"]
            a = mp.get("a", _MISSING)
            if not (isinstance(a, list) and len(a) == 3 and all(_is_real(v) for v in a)):
                raise w.error("[mparallel] a", a, "a list of 3 numbers [a1, a2, a3], each > 0")
            dd = _real(w, mp, "mparallel", "d", lo=0.0, lo_open=True)
            rate = _real(w, mp, "mparallel", "plane_rate")
            try:
                params = MParallelParams(a=(float(a[0]), float(a[1]), float(a[2])), d=dd, plane_rate=rate)
            except ParameterError as exc:
                raise ParameterError(f"{source}: [mparallel]: {exc}") from None
        dim = len(PUBLIC_NAMES[kind])
        layout = ", ".join(PUBLIC_NAMES[kind])

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
                    isinstance(s, list) and len(s) == dim and all(_is_real(v) for v in s) for s in st)):
                raise w.error("[orbits] states", st, f"a list of 1 to {MAX_ORBITS} states, each a list of {dim} "
                                                    f"numbers ({layout}: the {kind} public layout)")
            if lv:
                raise UsageError(f"{source}: [level] is not used with explicit [orbits] states; remove one of them")
            for i, s in enumerate(st):
                try:
                    as_state(kind, np.array(s, dtype=float))
                except StateError as exc:
                    raise StateError(f"{source}: [orbits] states[{i}]: {exc}") from None
            states = tuple(tuple(float(v) for v in s) for s in st)
            n_orbits = len(states)
        elif named[0] != "ball":
            raise UsageError(f"{source}: [mparallel] studies take explicit [orbits] states (lists of {dim} numbers: "
                             f"{layout}); orbits drawn on a [level] are for [ball] studies")
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
        if not ce / sample_dt <= MAX_SAMPLES_PER_CHUNK + 0.5:  # also an overflow to inf
            raise w.error("[run] checkpoint_every", r["checkpoint_every"],
                          f"at most {MAX_SAMPLES_PER_CHUNK} samples per chunk (sample_dt = {sample_dt!r}; a chunk's "
                          "states are held in memory): a smaller checkpoint_every or a larger sample_dt")
        per = multiple_of(ce, sample_dt)
        if per is None:
            raise w.error("[run] checkpoint_every", r["checkpoint_every"],
                          f"a positive multiple of [run] sample_dt = {sample_dt!r}")
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
        missing = unavailable(KIND_TABLE[kind])  # refused by name; off by default
        has = ", ".join(k for k in observable_keys() if k not in missing)
        for k, (off, why) in missing.items():
            if table.get(k, off) != off:
                raise UsageError(f"{source}: [observables] {k} = {table[k]!r}: needs {why}; a study of kind "
                                 f"{kind!r} has {has}")
            table[k] = off
        try:
            objs = build_observables(table, sample_dt)
        except UsageError as exc:
            raise UsageError(f"{source}: {exc}") from None
        full = {}
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
        return cls(source=source, kind=kind, params=params, levels=levels, n_orbits=n_orbits, seed=seed,
                   states=states, t_end=t_end, checkpoint_every=ce, sample_dt=sample_dt, fp_type=fp_type, tol=tol,
                   backend=backend, scheduler=scheduler, workers=workers, observables=full, store=p)

    @classmethod
    def from_problem(cls, problem: Problem, *, store: Union[str, "os.PathLike[str]"], t_end: float,
                     checkpoint_every: float, states: Any = None, levels: Optional[Levels] = None,
                     n: Optional[int] = None, seed: int = 0, observables: Optional[Mapping[str, Any]] = None,
                     **run: Any) -> "StudyConfig":
        r"""A study from Python: the same study as the study file with these values, checked
        the same way (errors name the argument as its ``[table] key``).

        Parameters
        ----------
        problem : Problem
            ``tb.problem("reduced", ball, ...)``, ``tb.problem("full", ball, ...)`` (``[ball]
            system = "full"``) or ``tb.problem("mparallel", params, ...)`` (its number type
            and tolerance become ``[run] fp_type`` and ``tol``; the default formulation
            only).
        store : str or os.PathLike
            The store folder (relative to the current folder).
        t_end, checkpoint_every : float
            ``[run] t_end`` and ``checkpoint_every``.
        states : array_like, optional
            ``(n, d)`` initial public states (``[orbits] states``); or, for a ball (reduced
            or full system), ``levels`` (a :class:`~taylorball.Levels`) with ``n`` orbits
            drawn with ``seed``.
        observables : mapping, optional
            The ``[observables]`` table (``{"angles_every": 10.0, "sections": "all"}``).
        **run
            The other ``[run]`` keys: ``sample_dt``, ``backend``, ``scheduler``,
            ``workers``.

        Examples
        --------
        >>> import taylorball as tb
        >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
        >>> cfg = tb.StudyConfig.from_problem(tb.problem("reduced", FIG4_BALL), store="runs/h2",
        ...                                   levels=FIG4A_LEVELS, n=4, t_end=2000.0,
        ...                                   checkpoint_every=500.0)
        >>> cfg.kind, cfg.n_orbits, cfg.n_chunks()
        ('reduced', 4, 4)
        >>> full = tb.StudyConfig.from_problem(tb.problem("full", FIG4_BALL), store="runs/h2-full",
        ...                                    levels=FIG4A_LEVELS, n=4, t_end=2000.0,
        ...                                    checkpoint_every=500.0)
        >>> full.kind, full.initial_states.shape, full.fingerprint() != cfg.fingerprint()
        ('full', (4, 14), True)
        """
        if not isinstance(problem, Problem):
            raise UsageError(f"problem must be a taylorball Problem (tb.problem(kind, params, ...)), got {problem!r}")
        table = {"reduced": "ball", "full": "ball", "mparallel": "mparallel"}[problem.kind]
        if problem.formulation != problem_of(problem.kind, problem.params).formulation:
            raise UsageError(f"problem: formulation {problem.formulation!r} is not the default of kind "
                             f"{problem.kind!r}; a study runs the default formulation")
        pr: Any = problem.params  # BallParams for "reduced", MParallelParams for "mparallel"
        d: Dict[str, Any] = {}
        if table == "ball":
            d["ball"] = {"inertia": [float(v) for v in pr.inertia], "mass": float(pr.mass),
                         "radius": float(pr.radius), "plane_rate": float(pr.plane_rate)}
            if problem.kind == "full":
                d["ball"]["system"] = "full"
        else:
            d["mparallel"] = {"a": [float(v) for v in pr.a], "d": float(pr.d), "plane_rate": float(pr.plane_rate)}
        if states is not None:
            if levels is not None or n is not None:
                raise UsageError("give either states or levels (and n, seed), not both")
            try:
                X = np.asarray(states, dtype=float)
            except (TypeError, ValueError):
                raise UsageError(f"states must be an (n, d) array of initial public states, got {states!r}") from None
            d["orbits"] = {"states": X.tolist() if X.ndim == 2 else states}
        else:
            if levels is not None and not isinstance(levels, Levels):
                raise UsageError(f"levels must be a taylorball Levels (C, M_gamma, h), got {levels!r}")
            d["orbits"] = {k: v for k, v in (("n", n), ("seed", seed)) if v is not None}
            if levels is not None:
                d["level"] = {"C": levels.C, "M_gamma": levels.M_gamma, "h": levels.h}
        unknown = sorted(set(run) - set(_TABLES["run"]) - {"t_end", "checkpoint_every", "fp_type", "tol"})
        if unknown or {"fp_type", "tol"} & set(run):
            raise UsageError(f"unknown keyword(s) {', '.join(unknown or sorted({'fp_type', 'tol'} & set(run)))}: "
                             "the run's keywords are sample_dt, backend, scheduler, workers (the number type and "
                             "tolerance come from problem)")
        spec = problem.spec
        d["run"] = {"t_end": t_end, "checkpoint_every": checkpoint_every, "fp_type": spec.name, **run}
        if problem.tol is not None:
            d["run"]["tol"] = problem.tol
        d["observables"] = dict(observables or {}) if isinstance(observables, Mapping) or not observables \
            else observables
        d = _plain(d)  # numpy scalars as the Python numbers a study file gives
        d["output"] = {"store": os.fspath(store) if isinstance(store, (str, os.PathLike)) else store}
        return cls.from_dict(d, source="<StudyConfig.from_problem>")

    # -- derived --------------------------------------------------------------------------
    @property
    def samples_per_chunk(self) -> int:
        return int(round(self.checkpoint_every / self.sample_dt))

    def n_chunks(self, t_end: Optional[float] = None) -> int:
        """Chunks of a run to ``t_end`` (default: the study's)."""
        return int(round((self.t_end if t_end is None else t_end) / self.checkpoint_every))

    def problem(self) -> Problem:
        return problem(self.kind, self.params, fp_type=self.fp_type, tol=self.tol)

    def observable_objects(self) -> list:
        return build_observables(self.observables, self.sample_dt)

    @cached_property
    def initial_states(self) -> np.ndarray:
        """The orbits' initial public states (n, d): the explicit ones, or ``n`` drawn
        uniformly on the admissible region of the level's section ``g = 0`` (first root
        ``K`` of each chart point, ``direction = +1``); for the full system each drawn
        reduced state is lifted by :func:`taylorball.manifold.reduced_to_full` (``psi = 0``:
        the fixed frame with ``F1 = (M, alpha) = 0``, ``F2 > 0``)."""
        if self.states is not None:
            return np.array(self.states, dtype=float)
        X = _draw(self.params, self.levels, self.n_orbits, self.seed)
        if len(X) < self.n_orbits:
            raise UsageError(f"{self.source}: only {len(X)} of [orbits] n = {self.n_orbits} admissible "
                             "points were found on the level; use a smaller n or another level")
        if self.kind == "full":
            from ..manifold import reduced_to_full

            return np.array(reduced_to_full(self.params, X), dtype=float)
        return X.copy()

    def as_dict(self) -> Dict[str, Any]:
        """The normalised study (JSON-able)."""
        d = jsonable(self)
        d["store"] = str(self.store)
        return d

    def fingerprint(self) -> str:
        """sha256 of everything an orbit's bits depend on: problem, orbits, chunking, the
        observables' options and the integrator family (scalar or lanes; not t_end, the
        scalar backend, workers or the store)."""
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
        return orbit_fingerprint(self.fingerprint(), i, self.initial_states[i])


def _plain(v: Any) -> Any:
    """``v`` with numpy scalars (``np.float32(10.0)``, ``np.int64(2)``, ``np.bool_``) turned
    into the Python numbers a study file holds, inside dicts and lists too; other values as
    they are (the checks then name what is wrong)."""
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.floating):
        return float(v)
    if isinstance(v, Mapping):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_plain(x) for x in v]
    return v


@lru_cache(maxsize=16)
def _draw(params, levels, n: int, seed: int) -> np.ndarray:
    """``n`` states drawn on the level (a pure function of its arguments, remembered: a
    study is loaded again by every command)."""
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
    if not float(t_end) / ce <= MAX_CHUNKS + 0.5:  # also an overflow to inf (1e300 / 1e-300)
        raise w.error(key, t_end, f"at most {MAX_CHUNKS} chunks of checkpoint_every = {ce!r}: a larger "
                                  "checkpoint_every")
    n = multiple_of(float(t_end), ce)
    if n is None:
        lo = max(1, math.floor(t_end / ce)) * ce
        hi = max(1, math.ceil(t_end / ce)) * ce
        near = f"{lo:g}" if lo == hi else f"{lo:g} or {hi:g}"
        raise w.error(key, t_end, f"a positive multiple of [run] checkpoint_every = {ce!r} (nearest valid: {near}), "
                                  "so that extending a run continues exactly where it stopped")
    return n


def load_study(path: Union[str, "os.PathLike[str]"]) -> StudyConfig:
    """Read and validate a study file (TOML).

    Raises
    ------
    UsageError, ParameterError, StateError
        A missing or unreadable file, bad TOML, or a bad key (named with the file and
        ``[table] key``).
    """
    try:
        p = Path(path)
    except TypeError:
        raise UsageError(f"study must be a path to a TOML study file or a StudyConfig, got {path!r}") from None
    if not p.is_file():
        raise UsageError(f"study file {str(p)!r} {'is a folder' if p.is_dir() else 'does not exist'}: give a TOML "
                         "study file (its keys: taylorball docs longruns)")
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




StudyLike = Union[str, os.PathLike, StudyConfig]


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
