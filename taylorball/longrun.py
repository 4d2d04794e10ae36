"""Long integrations with atomic checkpoints and bit-exact resume, and ensembles of them.

**Deprecated.** :func:`long_run`, :func:`load_long_run` and :func:`run_ensemble` (and with them the npz
run folder and :class:`LongRunConfig`) are replaced by studies, one long-run path for
every system: :meth:`taylorball.StudyConfig.from_problem` (or a study file) with
:func:`taylorball.run_study`, read by :func:`taylorball.open_run`; many independent jobs
by :func:`taylorball.ensemble.run_many`. They warn (``DeprecationWarning``) and go in the
next release; ``CHANGELOG.md`` says how to move an npz run.

A long run (e.g. 1e8 time units for a diffusion study of the contact point) is cut into
*chunks* of ``checkpoint_dt`` time units. Each chunk samples the orbit every
``sample_dt`` on heyoka's dense output (``propagate_grid``), then writes

1. ``chunk_<k>.npz`` -- the chunk's samples (public state, contact point for the
   reduced/full systems, integrals), atomically;
2. ``checkpoint.npz`` -- the integrator's internal state, its double-length time
   ``dtime`` and counters, atomically, *after* the chunk file.

A crash loses at most the chunk in progress. Resuming rebuilds the integrator from the
checkpoint (the compiled code is recompiled or taken from heyoka's cache: a pickled
integrator holds machine code tied to versions and CPU, so it is no archive) and
continues; the state, the double-length time and the parameters are all a Taylor
integrator carries from step to step, so the resumed run is bit-identical to an
uninterrupted one (tested).

Ensembles (:func:`run_ensemble`, on :func:`taylorball.ensemble.run_many`) run members on
threads, processes (``spawn``) or a dask.distributed cluster; member ``i`` depends only on
its own config, so every backend gives the same bits.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
import warnings
from typing import Any, Callable, Dict, Iterable, List, Literal, Optional

import numpy as np

from ._typing import KindName, ParamsLike, PathLike, ProgressLike
from .errors import StateError, UsageError
from .io import atomic_write_bytes, jsonable, provenance
from .numbers import resolve_fp_type

__all__ = ["LongRunConfig", "LongRunResult", "long_run", "load_long_run", "run_ensemble"]


#: Limits of a long run, so that a config's work and memory stay finite and proportional:
#: samples per chunk (a chunk's grid and states are held in memory), chunks (one file
#: each), and samples in all (:func:`load_long_run` returns them all in memory).
MAX_SAMPLES_PER_CHUNK = 1_000_000
MAX_CHUNKS = 1_000_000
MAX_SAMPLES = 100_000_000


def _is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def _n_chunks(t_end, checkpoint_dt) -> int:
    """Chunks of a run: ``ceil(t_end / checkpoint_dt)`` (a relative 1e-12 of the last chunk
    forgiven), and never a last chunk that would start at or after ``t_end``."""
    n = int(math.ceil(t_end / checkpoint_dt - 1e-12))
    while n > 1 and (n - 1) * checkpoint_dt >= t_end:
        n -= 1
    return max(n, 1)


@dataclass(frozen=True)
class LongRunConfig:
    """A long integration, frozen and checked on construction.

    Parameters
    ----------
    kind : {"full", "reduced", "mparallel"}
    params : BallParams or MParallelParams
    state : tuple of float
        Initial public state.
    t_end : float
        Final time (> 0).
    sample_dt : float
        Sampling interval of the output (> 0).
    checkpoint_dt : float
        Time between checkpoints; a multiple of ``sample_dt``.
    fp_type : str
        ``"float"``, ``"longdouble"``, ``"real128"`` or ``"real"`` (with ``prec``).
    prec : int, optional
    tol : float, optional

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> cfg = tb.LongRunConfig("reduced", FIG4_BALL, tuple(demo_reduced_state()), t_end=2.0,
    ...                        sample_dt=0.5, checkpoint_dt=1.0)
    >>> cfg.n_chunks, cfg.samples_per_chunk
    (2, 2)
    >>> tb.LongRunConfig("reduced", FIG4_BALL, tuple(demo_reduced_state()), t_end=2.0,
    ...                  sample_dt=0.5, checkpoint_dt=0.7)
    Traceback (most recent call last):
    ...
    taylorball.errors.UsageError: checkpoint_dt=0.7 must be a positive multiple of sample_dt=0.5
    """

    kind: KindName
    params: ParamsLike
    state: tuple
    t_end: float
    sample_dt: float
    checkpoint_dt: float
    fp_type: str = "float"
    prec: Optional[int] = None
    tol: Optional[float] = None

    def __post_init__(self):
        from .manifold import as_state, params_for
        from ._problem import _check_tol

        params_for(self.kind, self.params)
        try:
            state = tuple(float(v) for v in np.asarray(self.state, dtype=float))
        except (TypeError, ValueError):
            raise StateError(f"state must be a sequence of real numbers (the public layout of kind={self.kind!r}), "
                             f"got {self.state!r}") from None
        object.__setattr__(self, "state", state)
        as_state(self.kind, np.array(self.state))
        spec = resolve_fp_type(self.fp_type, self.prec)
        _check_tol(self.tol, spec)
        for name in ("t_end", "sample_dt", "checkpoint_dt"):
            v = getattr(self, name)
            if not (_is_number(v) and math.isfinite(v) and v > 0):
                raise UsageError(f"{name} must be a finite number > 0, got {v!r}")
            if not isinstance(v, (int, float)):  # a numpy scalar: as a float (Python numbers are kept
                object.__setattr__(self, name, float(v))  # as given: they are in the fingerprint)
        ratio = self.checkpoint_dt / self.sample_dt
        if ratio > MAX_SAMPLES_PER_CHUNK:  # also an overflow to inf (sample_dt = 5e-324), before round()
            raise UsageError(
                f"checkpoint_dt={self.checkpoint_dt!r} / sample_dt={self.sample_dt!r} = {ratio:.3g} samples per chunk, "
                f"more than {MAX_SAMPLES_PER_CHUNK} (a chunk is held in memory): use a smaller checkpoint_dt or a "
                "larger sample_dt")
        if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
            raise UsageError(
                f"checkpoint_dt={self.checkpoint_dt!r} must be a positive multiple of sample_dt={self.sample_dt!r}"
            )
        if self.samples_per_chunk > MAX_SAMPLES_PER_CHUNK:
            raise UsageError(
                f"checkpoint_dt={self.checkpoint_dt!r} / sample_dt={self.sample_dt!r} = {self.samples_per_chunk} "
                f"samples per chunk, more than {MAX_SAMPLES_PER_CHUNK} (a chunk is held in memory): use a smaller "
                "checkpoint_dt or a larger sample_dt")
        n_chunks = self.t_end / self.checkpoint_dt
        if n_chunks > MAX_CHUNKS:
            raise UsageError(
                f"t_end={self.t_end!r} / checkpoint_dt={self.checkpoint_dt!r} = {n_chunks:.3g} chunks, more than "
                f"{MAX_CHUNKS} (one file each): use a larger checkpoint_dt, or split the run into several")
        if n_chunks * self.samples_per_chunk > MAX_SAMPLES:
            raise UsageError(
                f"t_end={self.t_end!r} / sample_dt={self.sample_dt!r} = {self.t_end / self.sample_dt:.3g} samples, "
                f"more than {MAX_SAMPLES} (load_long_run holds them all in memory, ~100 bytes each): use a "
                "larger sample_dt, or split the run into several")

    @property
    def samples_per_chunk(self) -> int:
        return int(round(self.checkpoint_dt / self.sample_dt))

    @property
    def n_chunks(self) -> int:
        return _n_chunks(self.t_end, self.checkpoint_dt)

    def fingerprint(self) -> str:
        """Hash identifying the run; a checkpoint of another config is never resumed."""
        blob = json.dumps(jsonable(self), sort_keys=True).encode()
        return hashlib.sha256(blob).hexdigest()[:16]


@dataclass
class LongRunResult:
    """Samples of a long run: ``t`` (n,), ``states`` (n, d) public layout (float64 copy),
    ``xy`` (n, 2) contact point (reduced/full) or None, ``integrals`` dict of (n,) arrays,
    ``n_steps``, ``complete`` (reached t_end) and the folder it lives in."""

    t: np.ndarray
    states: np.ndarray
    xy: Optional[np.ndarray]
    integrals: dict
    n_steps: int
    complete: bool
    path: Path


def _chunk_grid(cfg, k, spec):
    """The sample times of chunk ``k``: ``k * checkpoint_dt + j * sample_dt`` for the
    ``j < samples_per_chunk`` before the chunk's end, then its end, ``(k + 1) *
    checkpoint_dt`` (``t_end`` for the last chunk). Both ends are products of integer
    counts, never sums of rounded steps, so a chunk starts exactly where the previous one
    ended (with ``sample_dt=0.1, checkpoint_dt=0.3``, ``0.3 + 3 * 0.1`` is
    0.6000000000000001, past the next chunk's start 0.6)."""
    n = cfg.samples_per_chunk
    t0 = k * cfg.checkpoint_dt
    t1 = cfg.t_end if k >= cfg.n_chunks - 1 else (k + 1) * cfg.checkpoint_dt
    ts = [t for t in (t0 + j * cfg.sample_dt for j in range(n)) if t < t1]
    ts.append(t1)
    return spec.array(np.array(ts, dtype=float))


def _save_state(arr):
    """Exact serialisation of a state array of any supported dtype."""
    a = np.asarray(arr)
    if a.dtype == np.float64:
        return a.copy()
    return np.array([str(v) for v in a.reshape(-1)])  # shortest round-trip digits


def _load_state(saved, spec):
    saved = np.asarray(saved)
    if saved.dtype.kind == "f":
        return spec.array(saved)
    out = np.empty(len(saved), dtype=spec.dtype)
    for i, s in enumerate(saved):
        out[i] = np.longdouble(str(s)) if spec.name == "longdouble" else _from_str(str(s), spec)
    return out


def _from_str(s, spec):
    import heyoka as hy

    if spec.name == "real128":
        return hy.real128(s)
    if spec.name == "real":
        return hy.real(s, spec.prec)
    return float(s)


def _deprecated(name: str, instead: str) -> None:
    warnings.warn(f"taylorball.{name} is deprecated and goes in the next release: {instead} (CHANGELOG.md says "
                  "how to move an npz run)", DeprecationWarning, stacklevel=3)


_STUDY_INSTEAD = ("use a study, the one long-run path: tb.StudyConfig.from_problem(problem, states=..., t_end=..., "
                  "checkpoint_every=..., store=...) and tb.run_study (or a study file and `taylorball run`), read by "
                  "tb.open_run")


def long_run(cfg: LongRunConfig, path: PathLike, *, resume: bool = True,
             max_chunks: Optional[int] = None, progress: bool = False,
             on_chunk: Optional[Callable[[int, int], None]] = None) -> LongRunResult:
    """Run (or resume) a long integration, checkpointing into the folder ``path``.

    **Deprecated.** Use a study: :meth:`taylorball.StudyConfig.from_problem` and
    :func:`taylorball.run_study` (tutorial 4). Warns ``DeprecationWarning``.

    Parameters
    ----------
    resume : bool
        Continue from ``path/checkpoint.npz`` if it exists and belongs to ``cfg``
        (default). ``False`` starts afresh, discarding what is there.
    max_chunks : int, optional
        Stop after this many chunks in this call (the run stays resumable); for splitting
        a run across job-queue slots.
    progress : bool
        tqdm progress bar over chunks.
    on_chunk : callable, optional
        Called as ``on_chunk(k_done, n_chunks)`` once the run's position is known (``k_done``
        chunks already on disk when resuming) and after every chunk written, e.g. to show
        the progress of an ensemble of long runs in one bar.

    Raises
    ------
    UsageError
        If ``path`` holds a checkpoint of a different config.
    IntegrationError
        If the integrator stops early; everything before is kept on disk.

    Examples
    --------
    >>> import tempfile, warnings
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> cfg = tb.LongRunConfig("reduced", FIG4_BALL, tuple(demo_reduced_state()), t_end=2.0,
    ...                        sample_dt=0.5, checkpoint_dt=1.0)
    >>> with tempfile.TemporaryDirectory() as folder, warnings.catch_warnings():
    ...     warnings.simplefilter("ignore", DeprecationWarning)
    ...     part = tb.long_run(cfg, folder, max_chunks=1)   # stops after one chunk
    ...     done = tb.long_run(cfg, folder)                 # resumes from the checkpoint
    >>> part.t, part.complete
    (array([0. , 0.5, 1. ]), False)
    >>> done.t, done.complete
    (array([0. , 0.5, 1. , 1.5, 2. ]), True)
    >>> done.states.shape, done.xy.shape, sorted(done.integrals)
    ((5, 9), (5, 2), ['C2', 'E', 'M_gamma', 'R_gamma', 'gamma2'])
    """
    _deprecated("long_run", _STUDY_INSTEAD)
    return _long_run(cfg, path, resume=resume, max_chunks=max_chunks, progress=progress, on_chunk=on_chunk)


def _long_run(cfg: LongRunConfig, path: PathLike, *, resume: bool = True,
              max_chunks: Optional[int] = None, progress: bool = False,
              on_chunk: Optional[Callable[[int, int], None]] = None) -> LongRunResult:
    """:func:`long_run` without the deprecation warning (the contact-diffusion figure's
    runs, kept bit for bit until it moves onto the study runner)."""
    from .ensemble import current
    from ._integrals import integrals_cfunc
    from ._propagate import _check_outcome, make_integrator, public_state

    if not isinstance(cfg, LongRunConfig):
        raise UsageError(f"cfg must be a LongRunConfig, got {type(cfg).__name__}")
    if max_chunks is not None and not (isinstance(max_chunks, (int, np.integer)) and not isinstance(max_chunks, bool)
                                       and max_chunks >= 1):
        raise UsageError(f"max_chunks must be a positive integer (chunks to run in this call) or None, "
                         f"got {max_chunks!r}")
    if progress:  # the engine's bar, advanced per chunk
        from .ensemble import call, run_many

        return run_many([call(_long_run, cfg, path, resume=resume, max_chunks=max_chunks, on_chunk=on_chunk)],
                        progress=f"long run {cfg.kind}")[0]
    path = _run_folder(path)
    spec = resolve_fp_type(cfg.fp_type, cfg.prec)
    fp = cfg.fingerprint()
    ck = path / "checkpoint.npz"
    ta, system, _ = make_integrator(cfg.kind, cfg.params, np.array(cfg.state), fp_type=spec.fp_type,
                                    prec=spec.prec, tol=cfg.tol)
    k_next, n_steps = 0, 0
    if resume and ck.exists():
        with np.load(ck, allow_pickle=False) as z:
            if str(z["fingerprint"]) != fp:
                raise UsageError(
                    f"{path} holds a checkpoint of another run (fingerprint {z['fingerprint']} != {fp}); "
                    "use another folder or resume=False"
                )
            ta.state[:] = _load_state(z["state"], spec)
            hi, lo = _load_state(z["dtime"], spec)
            ta.dtime = (hi, lo)
            k_next, n_steps = int(z["next_chunk"]), int(z["n_steps"])
    else:
        for f in path.glob("chunk_*.npz"):
            f.unlink()
        if ck.exists():
            ck.unlink()
        atomic_write_bytes(path / "config.json", json.dumps(
            {"config": jsonable(cfg), "fingerprint": fp, "provenance": provenance()}, indent=2).encode())
    ints = integrals_cfunc(cfg.kind, fp_type=spec.fp_type, prec=spec.prec)
    ctx = current()  # a member of run_many (the bar of progress=True, or an ensemble's)
    ctx.advance(k_next / cfg.n_chunks)  # chunks already on disk count as done
    done_here = 0
    if on_chunk is not None:
        on_chunk(k_next, cfg.n_chunks)
    while k_next < cfg.n_chunks and (max_chunks is None or done_here < max_chunks):
        grid = _chunk_grid(cfg, k_next, spec)
        res = ta.propagate_grid(grid)
        _check_outcome(ta, res, float(grid[-1]))
        n_steps += int(res[3])
        X = res[-1]
        pars = np.array(ta.pars)
        pub = np.array([public_state(system, pars, x, spec) for x in X])
        vals = ints(X, pars)
        arrays = {"t": grid.astype(float), "states": pub.astype(float)}
        if system.info.contact is not None:
            arrays["xy"] = np.asarray(system.info.contact(cfg.params, pub)).astype(float)
        for name, v in vals.items():
            arrays[f"I_{name}"] = np.asarray(v).astype(float)
        _save_npz(path / f"chunk_{k_next:06d}.npz", arrays)
        k_next += 1
        done_here += 1
        hi, lo = ta.dtime
        _save_npz(ck, {"state": _save_state(ta.state), "dtime": _save_state(np.array([hi, lo], dtype=spec.dtype)),
                       "next_chunk": np.array(k_next), "n_steps": np.array(n_steps),
                       "fingerprint": np.array(fp)})
        ctx.advance(1 / cfg.n_chunks)
        if on_chunk is not None:
            on_chunk(k_next, cfg.n_chunks)
        ctx.check()  # Ctrl-C stops here, the chunk and its checkpoint on disk
    return _load_long_run(path)


def _run_folder(path) -> Path:
    """The folder of a long run, created if missing; a clear error if it cannot be."""
    try:
        path = Path(path)
    except TypeError:
        raise UsageError(f"path must be a folder path (str or os.PathLike), got {path!r}") from None
    if path.exists() and not path.is_dir():
        raise UsageError(f"path={str(path)!r} is a file, not a folder: a long run writes its chunks and "
                         "checkpoint into a folder; give a folder path")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"cannot create the long-run folder path={str(path)!r}: {exc.strerror or exc}") from exc
    return path


def _save_npz(path, arrays):
    import io

    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def load_long_run(path: PathLike) -> LongRunResult:
    """Read the samples written so far by :func:`long_run` (overlapping chunk ends are
    merged: each chunk's first sample is the previous chunk's last).

    **Deprecated.** Studies are read by :func:`taylorball.open_run`. Warns ``DeprecationWarning``."""
    _deprecated("load_long_run", "a study's store is read by tb.open_run")
    return _load_long_run(path)


def _load_long_run(path: PathLike) -> LongRunResult:
    path = Path(path)
    if not (path / "config.json").is_file():
        what = "does not exist" if not path.exists() else ("is a file" if not path.is_dir()
                                                           else "holds no long run (no config.json)")
        raise UsageError(f"cannot load a long run from path={str(path)!r}: it {what}; give the folder "
                         "passed to long_run")
    ck = path / "checkpoint.npz"
    n_done, n_steps = 0, 0
    if ck.exists():
        with np.load(ck, allow_pickle=False) as z:
            n_done, n_steps = int(z["next_chunk"]), int(z["n_steps"])
    cfg = json.loads((path / "config.json").read_text())["config"]
    t, st, xy = [], [], []
    ints: Dict[str, List[np.ndarray]] = {}
    for k in range(n_done):
        with np.load(path / f"chunk_{k:06d}.npz", allow_pickle=False) as z:
            sl = slice(1, None) if k > 0 else slice(None)
            t.append(z["t"][sl])
            st.append(z["states"][sl])
            if "xy" in z.files:
                xy.append(z["xy"][sl])
            for name in z.files:
                if name.startswith("I_"):
                    ints.setdefault(name[2:], []).append(z[name][sl])
    cat = lambda a: np.concatenate(a) if a else np.empty(0)  # noqa: E731
    n_chunks = _n_chunks(cfg["t_end"], cfg["checkpoint_dt"])
    return LongRunResult(
        t=cat(t), states=cat(st), xy=cat(xy) if xy else None, integrals={k: cat(v) for k, v in ints.items()},
        n_steps=n_steps, complete=n_done >= n_chunks, path=path,
    )


# ---------------------------------------------------------------------------------------
# Ensembles.
# ---------------------------------------------------------------------------------------
def run_ensemble(fn: Callable[[Any], Any], items: Iterable[Any], *,
                 backend: Literal["serial", "threads", "processes", "dask"] = "threads",
                 max_workers: Optional[int] = None, client: Any = None,
                 progress: ProgressLike = False) -> List[Any]:
    """Apply ``fn`` to every item on a pool; results in the order of ``items``.

    **Deprecated.** Use :func:`taylorball.ensemble.run_many` (``run_many([call(fn, x) for x in
    items], mode=backend, workers=...)``), or a study for long runs. Warns
    ``DeprecationWarning``.

    Parameters
    ----------
    fn : callable
        A top-level (picklable) function for ``"processes"`` and ``"dask"``.
    backend : {"serial", "threads", "processes", "dask"}
        ``"threads"``: heyoka releases the GIL while integrating; ``"processes"``: a
        ``spawn`` pool (scripts need an ``if __name__ == "__main__":`` guard);
        ``"dask"``: futures on a dask.distributed ``client`` (``pip install
        taylorball[cluster]``). The ensemble runs on :func:`taylorball.ensemble.run_many`
        (that mode): a failing member is re-raised with a note naming it and the members
        not yet started are dropped; so are they on Ctrl-C (worker processes are ended).
    progress : bool or callable
        A tqdm bar over members (or a callable receiving fractions of members).
    """
    from .ensemble import call, run_many

    _deprecated("run_ensemble", "use taylorball.ensemble.run_many([call(fn, x) for x in items], backend=backend, "
                "workers=...), or a study (tb.run_study) for long runs")
    if backend not in ("serial", "threads", "processes", "dask"):
        raise UsageError(f"backend must be 'serial', 'threads', 'processes' or 'dask', got {backend!r}")
    if backend == "dask" and client is None:
        raise UsageError("backend='dask' needs client=<dask.distributed.Client>")
    if max_workers is not None and not (isinstance(max_workers, (int, np.integer))
                                        and not isinstance(max_workers, bool) and max_workers >= 1):
        raise UsageError(f"max_workers must be a positive integer or None (default: the number of cores), "
                         f"got {max_workers!r}")
    if not callable(fn):
        raise UsageError(f"fn must be a callable applied to every item, got {fn!r}")
    try:
        items = list(items)
    except TypeError:
        raise UsageError(f"items must be a sequence (one ensemble member each), got {items!r}") from None
    # Ctrl-C or a failed member: the members not started are dropped; processes are
    # terminated; running threads finish their member unless it checks
    # taylorball.ensemble.current() (long runs checkpoint: rerun to resume them)
    return run_many([call(fn, it) for it in items], backend=backend, workers=max_workers, client=client,
                    progress="ensemble" if progress is True else progress)
