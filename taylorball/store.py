"""The store of a study's long runs: a standard zarr v3 hierarchy, one group per orbit.

Layout (format 2)::

    STORE/zarr.json              group; attrs: format, study (normalised), fingerprint, t_end,
                                 layout, provenance, segments, seal
    STORE/.lock                  the coordinating run's lock (host, pid, start)
    STORE/orbit_0003/zarr.json   group; attrs: fingerprint, index, initial_state, checkpoint
    STORE/orbit_0003/<obs>/      group: one observable
    STORE/orbit_0003/<obs>/<var> array, append dimension first; ``dimension_names``, attrs
                                 ``long_name``, ``units`` (CF style) and ``step`` on a grid
    STORE/orbit_0003/_index      (index_chunk, index_column) int64: records per chunk and
                                 observable, then 8 bytes of the sha256 of each array's records
    STORE/orbit_0003/.lock       the orbit's writer (host, pid, start; mtime = heartbeat)

Every folder is a zarr group and every array names its dimensions, so
``xarray.open_datatree(STORE, engine="zarr")`` and ``zarr.open_group(STORE)`` read every
orbit without taylorball. A store of format 1 (observable folders without a group,
dimension names in an attribute) is read by :func:`taylorball.open_run` and refused by a
run (:func:`upgrade` rewrites its metadata, the data untouched).

Crash safety. Per chunk the writer appends every array's records (resize, then write the
new region), then the index rows, then the orbit's ``checkpoint`` attribute: the commit
point. Readers and resumes use the checkpoint's lengths; anything beyond them is an
uncommitted tail, cut off (the last zarr chunk rewritten so no stale value survives in it)
before the orbit's writer continues. zarr's LocalStore writes every key through a temporary
file and a rename; leftover temporaries (``*.partial``) are removed on resume.

Integrity. Each array's records of chunk ``k`` have the digest ``d = sha256(fingerprint,
k, name, dtype, shape, bytes)``; the chunk's digest is chained, ``h_k = sha256(h_{k-1} +
d_1 + ... + d_n)`` (``h_{-1} = sha256(fingerprint)``), and the checkpoint keeps ``h_K`` and
a seal (sha256 of the fingerprint and the checkpoint itself). An orbit's fingerprint is
the sha256 of the study's fingerprint, its index and its initial state, so an edited
``initial_state`` or an orbit moved to another index no longer matches it; the root
attributes are sealed (``seal``: sha256 of the others). :meth:`OrbitStore.verify`
recomputes all of it from the data and names the orbit, the array and the chunk that
differs (a corrupt file, a chunk copied from another run, a checkpoint changed by one ulp).
Every zarr chunk of a format-2 array is written (also one holding only the fill value), so
a deleted chunk file is found without reading the data (:meth:`OrbitStore.check`).

Provenance. Every run appends a *segment* to the root attribute ``segments``: versions
(taylorball, heyoka, numpy, zarr, python), CPU model and heyoka's SIMD width, host,
command line, start and end time and what it did. A run that would add chunks with
another heyoka version, CPU model or SIMD width than the segments that wrote the store is
refused unless forced (and the forced mix is recorded in its segment).

Locks. One writer per orbit: ``.lock`` is created with ``O_CREAT | O_EXCL``. A live holder
on this host is refused (naming host and pid), a dead one (no such pid, a zombie, or a pid
reused by a younger process) is stale and taken over; a holder on another host is refused
unless its lock has not been touched for :data:`HEARTBEAT_TIMEOUT` seconds (the writer
touches it after every chunk). A lock file that is not a lock (not the JSON a writer
writes) is refused, naming it.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import shutil
import socket
import sys
import uuid
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Dict, Iterator, List, Literal, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from ._store_lock import HEARTBEAT_TIMEOUT, Lock
from ._store_write import ChunkWriter
from .errors import StoreError, UsageError

__all__ = ["FORMAT_VERSION", "HEARTBEAT_TIMEOUT", "RunStore", "OrbitStore", "Lock", "orbit_name", "orbit_fingerprint",
           "environment", "upgrade"]

#: Version of the store layout (root attribute ``format``).
FORMAT_VERSION = 2
#: Layouts a reader (:func:`taylorball.open_run`) understands; a run writes only
#: :data:`FORMAT_VERSION`.
FORMATS_READ = (1, 2)
#: Version of the digest chain (unchanged since format 1: a format-1 store's digests and
#: checkpoints stay valid in format 2).
_CHAIN = 1
#: Uncompressed bytes per zarr chunk of an appended array (rows of one record).
_ZARR_CHUNK_BYTES = 1 << 20
_INDEX = "_index"
#: Bytes of each array's per-chunk sha256 kept in the index, to name the array and chunk
#: that differ (8 bytes: 2^-64 chance that a changed chunk goes unnamed; it is still caught
#: by the chain, which the check recomputes from the full digests against the checkpoint).
_TAG = 8
#: Root attributes covered by the root seal.
_SEALED = ("format", "study", "fingerprint", "t_end", "layout", "provenance", "segments")
#: The marker file inside a folder a run creates beside the store (restart): its content
#: names the run, so only that folder is ever deleted.
_MARKER = ".taylorball-temporary"
#: What the store says about units (root attribute ``units``).
UNITS_NOTE = ("times, lengths and momenta in the units of the study's ball parameters (inertia, mass, radius, "
              "plane_rate), so dimensionless: units '1'; angles in radians: units 'rad'")


#: An orbit's layouts: observable name -> array name -> :class:`taylorball.observables.Var`.
Layouts = Mapping[str, Mapping[str, Any]]


def orbit_name(i: int) -> str:
    return f"orbit_{i:04d}"


def orbit_fingerprint(study_fingerprint: str, i: int, initial_state: Sequence[float]) -> str:
    """The fingerprint of orbit ``i``: the study's, its index and its initial state (so the
    orbit's ``initial_state`` attribute and its place are sealed by it)."""
    blob = json.dumps([study_fingerprint, i, [float(v) for v in initial_state]])
    return hashlib.sha256(blob.encode()).hexdigest()[:32]


@contextmanager
def _quiet() -> Iterator[None]:
    """zarr warns about the lock files when it lists a group: they are ours."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r".*is not recognized as a component of a Zarr hierarchy")
        yield


def layout_json(layouts: Layouts) -> List[Dict[str, Any]]:
    """The layouts as JSON (root attribute ``layout``), the observables in their order (the
    order of the index's columns): per array its dims, dtype, the sizes of its further
    dims, ``step``, ``units`` and ``long_name``."""
    return [{"name": o, "arrays": {v: _array_meta(var) for v, var in sorted(layouts[o].items())}} for o in layouts]


def _array_meta(var: Any) -> Dict[str, Any]:
    return {"dims": list(var.dims), "dtype": np.dtype(var.dtype).str, "shape": list(var.shape), "step": var.step,
            "units": getattr(var, "units", "1"), "long_name": var.doc}


def layouts_from_json(layout: Sequence[Mapping[str, Any]]) -> Dict[str, Dict[str, Dict[str, Any]]]:
    """The root attribute ``layout`` as layouts (observable -> array -> its JSON meta)."""
    return {e["name"]: dict(e["arrays"]) for e in layout}


def _root_seal(attrs: Mapping[str, Any]) -> str:
    body = {k: attrs.get(k) for k in _SEALED}
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()


# ---------------------------------------------------------------------------------------
# Provenance.
# ---------------------------------------------------------------------------------------
def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.lower().startswith(("model name", "cpu model", "hardware")):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform

    return platform.processor() or platform.machine() or "unknown"


def environment() -> Dict[str, Any]:
    """What a run's bits may depend on beyond the study: heyoka's version, the CPU model
    and heyoka's SIMD width (:func:`heyoka.recommended_simd_size`)."""
    import heyoka as hy

    return {"heyoka": hy.__version__, "cpu": _cpu_model(), "simd_size": int(hy.recommended_simd_size())}


def segment(action: str, t_end: float) -> Dict[str, Any]:
    """A new provenance segment (see the module docstring); ``ended`` and ``chunks`` are
    filled in when the run ends."""
    import platform

    import zarr

    from .io import provenance

    prov = provenance()
    return {**environment(), "taylorball": prov["taylorball"], "git_revision": prov["git_revision"],
            "numpy": np.__version__, "zarr": zarr.__version__, "python": platform.python_version(),
            "machine": platform.machine(), "host": socket.gethostname(), "pid": os.getpid(),
            "command": [str(a) for a in sys.argv], "action": action, "t_end": t_end,
            "started": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "ended": None, "chunks": None, "forced": None}


def _env_of(seg: Mapping[str, Any]) -> Tuple[Any, Any, Any]:
    return seg.get("heyoka"), seg.get("cpu"), seg.get("simd_size")


# ---------------------------------------------------------------------------------------
# Digests and exact values.
# ---------------------------------------------------------------------------------------
def genesis(fingerprint: str) -> bytes:
    return hashlib.sha256(f"taylorball-store/{_CHAIN}/{fingerprint}".encode()).digest()


def var_digest(fingerprint: str, k: int, name: str, a: np.ndarray) -> bytes:
    """sha256 of one array's records of chunk ``k`` (with everything that identifies them)."""
    a = np.ascontiguousarray(a)
    h = hashlib.sha256(f"{fingerprint}/{k}/{name}/{a.dtype.str}/{a.shape}/".encode())
    h.update(a.tobytes())
    return h.digest()


def chain(prev: bytes, digests: Sequence[bytes]) -> bytes:
    return hashlib.sha256(prev + b"".join(digests)).digest()


def _seal(fingerprint: str, checkpoint: Mapping[str, Any]) -> str:
    body = {k: v for k, v in checkpoint.items() if k != "seal"}
    return hashlib.sha256((fingerprint + json.dumps(body, sort_keys=True)).encode()).hexdigest()


def pack_carry(carry: Mapping[str, np.ndarray]) -> Dict[str, Any]:
    """A carry as exact JSON: float64 values round-trip through ``repr``."""
    out = {}
    for name, v in carry.items():
        a = np.asarray(v)
        if a.dtype.kind not in "fiub":
            raise UsageError(f"carry {name!r} must be a float64/int64 array, got dtype {a.dtype}")
        out[name] = {"dtype": a.dtype.str, "shape": list(a.shape), "data": a.reshape(-1).tolist()}
    return out


def unpack_carry(packed: Mapping[str, Any]) -> Dict[str, np.ndarray]:
    return {name: np.array(d["data"], dtype=np.dtype(d["dtype"])).reshape(d["shape"]) for name, d in packed.items()}


# ---------------------------------------------------------------------------------------
# The store.
# ---------------------------------------------------------------------------------------
def _open_group(path: Path, mode: Literal["r", "r+", "a", "w", "w-"] = "r+") -> Any:
    import zarr

    with _quiet():
        return zarr.open_group(str(path), mode=mode, zarr_format=3)


def _enclosing_store(path: Path) -> Optional[Path]:
    """The nearest folder above ``path`` that is a zarr node (holds ``zarr.json``), if any."""
    for parent in Path(os.path.abspath(path)).parents:
        if (parent / "zarr.json").is_file():
            return parent
    return None


class RunStore:
    """The zarr group of one study (see the module docstring)."""

    def __init__(self, path: Union[str, "os.PathLike[str]"]) -> None:
        self.path = Path(path)

    def exists(self) -> bool:
        return (self.path / "zarr.json").is_file()

    def attrs(self) -> Dict[str, Any]:
        try:
            return dict(_open_group(self.path, "r").attrs)
        except Exception as exc:
            raise StoreError(f"{self.path}: cannot read the store's root attributes (zarr.json): {exc}") from exc

    def check_root(self, attrs: Optional[Mapping[str, Any]] = None, *,
                   formats: Sequence[int] = (FORMAT_VERSION,), seal: bool = True) -> Dict[str, Any]:
        """The root attributes after their check: a taylorball store of one of ``formats``
        whose seal matches (format 2: ``study``, ``t_end``, ``layout``, ``segments`` ... as
        written by taylorball; not checked without ``seal``)."""
        attrs = dict(self.attrs() if attrs is None else attrs)
        fmt = attrs.get("format")
        if fmt not in FORMATS_READ or "fingerprint" not in attrs:
            parent = self.path.parent
            if self.path.name.startswith("orbit_") and (parent / "zarr.json").is_file():
                raise UsageError(f"{self.path} is one orbit's group of the store {parent}: open the store {parent}")
            raise StoreError(f"{self.path} is a zarr group but not a taylorball run store (root attributes format "
                             f"{fmt!r}, fingerprint {attrs.get('fingerprint')!r})")
        if fmt not in formats:
            raise StoreError(f"{self.path} is a taylorball run store of format {fmt}; this version writes format "
                             f"{FORMAT_VERSION} and only reads format {fmt} (tb.open_run): convert it with "
                             f"`python -c \"import taylorball.store as s; s.upgrade('{self.path}')\"` (rewrites its "
                             "metadata, the data untouched) to run, resume or extend it")
        if seal and fmt >= 2 and attrs.get("seal") != _root_seal(attrs):
            changed = "t_end, study, layout, provenance or segments"
            raise StoreError(f"{self.path}: its root attributes (zarr.json: {changed}) were altered: they do not "
                             "match their seal; restore the store or use --restart")
        return attrs

    def lock(self) -> Lock:
        return Lock(self.path / ".lock", f"the store {self.path}")

    def refuse_nested(self) -> None:
        """Raise UsageError if the store's folder is inside a zarr store (a store inside
        another breaks the outer one)."""
        outer = _enclosing_store(self.path)
        if outer is not None:
            raise UsageError(f"store {str(self.path)!r} is inside the zarr store {str(outer)!r}: a store inside "
                             "another breaks the outer one; give a folder outside it")

    def create(self, attrs: Mapping[str, Any], orbits: Sequence[Mapping[str, Any]],
               layouts: Optional[Layouts] = None) -> None:
        """A new store at ``self.path`` (which must not exist) with its root attributes
        (sealed; ``format``, ``layout`` and an empty ``segments`` added) and one group per
        orbit (``orbits``: their attributes)."""
        self.refuse_nested()
        if self.exists():
            raise StoreError(f"{self.path}: a store exists there already")
        g = _open_group(self.path, "a")  # the folder may hold the marker of the run building it
        for i, o in enumerate(orbits):
            og = g.create_group(orbit_name(i))
            og.attrs.update(dict(o, checkpoint=None))
        full = dict(attrs, format=FORMAT_VERSION, units=UNITS_NOTE, segments=list(attrs.get("segments", [])))
        full["layout"] = layout_json(layouts) if layouts is not None else attrs.get("layout", {})
        full["seal"] = _root_seal(full)
        g.attrs.update(full)  # written last: a store without root attrs is incomplete

    def set_attrs(self, **changes: Any) -> None:
        """Change root attributes (and renew the seal)."""
        g = _open_group(self.path)
        attrs = dict(g.attrs)
        attrs.update(changes)
        if attrs.get("format", 0) >= 2:
            changes = dict(changes, seal=_root_seal(attrs))
        g.attrs.update(changes)

    def begin_segment(self, seg: Dict[str, Any], *, work: bool, force: bool = False) -> int:
        """Append the provenance segment ``seg`` (:func:`segment`); returns its index.

        With ``work`` (chunks are to be added), a store whose earlier segments ran
        another heyoka version, CPU model or SIMD width is refused unless ``force`` (then
        the mix is recorded in the segment's ``forced``).

        Raises
        ------
        StoreError
            The other environment, naming both.
        """
        attrs = self.attrs()
        segs = list(attrs.get("segments", []))
        mine = _env_of(seg)
        others = []
        for s in segs:  # a segment that added no chunk (chunks == 0) wrote no bits
            if s.get("chunks") != 0 and _env_of(s) != mine and _env_of(s) not in others:
                others.append(_env_of(s))
        if work and others:
            names = ("heyoka", "cpu", "simd_size")
            theirs = "; ".join(", ".join(f"{k} {v!r}" for k, v in zip(names, o)) for o in others)
            if not force:
                raise StoreError(f"{self.path} was written with {theirs}; this run has "
                                 f"{', '.join(f'{k} {v!r}' for k, v in zip(names, mine))}: its chunks could differ "
                                 "in the last bits from a run on the first, and the store would mix them; run it "
                                 "where it was written, use --force (force=True) to mix them (recorded in the "
                                 "store's segments), or --restart")
            seg = dict(seg, forced=[dict(zip(names, o)) for o in others])
        segs.append(seg)
        self.set_attrs(segments=segs)
        return len(segs) - 1

    def end_segment(self, index: int, chunks: int) -> None:
        """Record the end of segment ``index``: its end time and the chunks it added."""
        attrs = self.attrs()
        segs = list(attrs.get("segments", []))
        if 0 <= index < len(segs):
            segs[index] = dict(segs[index], ended=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
                               chunks=int(chunks))
            self.set_attrs(segments=segs)

    def orbit(self, i: int) -> "OrbitStore":
        return OrbitStore(self.path, i)

    def _temporary(self, kind: str, run_id: str) -> Path:
        return self.path.with_name(f"{self.path.name}.{kind}-{run_id}")

    @staticmethod
    def _mark(folder: Path, run_id: str) -> None:
        (folder / _MARKER).write_text(json.dumps({"run": run_id, "host": socket.gethostname(), "pid": os.getpid()}))

    def restart(self, build: Callable[[Path], None]) -> None:
        """Replace the store atomically by a new one: ``build(tmp_path)`` builds it in a
        sibling folder ``STORE.new-<run id>`` (marked as this run's), then the old store
        is marked and renamed aside to ``STORE.old-<run id>``, the new one renamed into
        place (its mark removed), and the old one deleted last. A crash at any point leaves
        either the old store, the new one, or no store (which a run rebuilds); leftovers
        are removed by :meth:`clean_leftovers`, which deletes only folders so marked."""
        run_id = uuid.uuid4().hex
        tmp, trash = self._temporary("new", run_id), self._temporary("old", run_id)
        self.clean_leftovers()
        tmp.mkdir()
        self._mark(tmp, run_id)
        build(tmp)
        if self.path.exists():
            self._mark(self.path, run_id)
            os.rename(self.path, trash)
        os.rename(tmp, self.path)
        (self.path / _MARKER).unlink()
        if trash.exists():
            self._remove_marked(trash)

    def _remove_marked(self, folder: Path) -> bool:
        """Delete ``folder`` if its marker names the run in its name; True if deleted."""
        run_id = folder.name.rsplit("-", 1)[-1]
        try:
            mark = json.loads((folder / _MARKER).read_text())
        except (OSError, ValueError):
            return False
        if not isinstance(mark, dict) or mark.get("run") != run_id:
            return False
        shutil.rmtree(folder)
        return True

    def clean_leftovers(self) -> None:
        """Remove what an interrupted :meth:`restart` left next to the store: only
        ``STORE.new-<id>`` / ``STORE.old-<id>`` folders holding the marker of that run; a
        store itself left marked (a crash between marking and renaming it) is unmarked."""
        if self.path.is_dir() and (self.path / _MARKER).is_file():
            (self.path / _MARKER).unlink()
        parent = self.path.parent
        if not parent.is_dir():
            return
        for p in parent.iterdir():
            for kind in ("new", "old"):
                if p.name.startswith(f"{self.path.name}.{kind}-") and p.is_dir():
                    self._remove_marked(p)


class OrbitStore:
    """One orbit's group: its arrays, index, checkpoint and lock."""

    def __init__(self, root: Path, index: int) -> None:
        self.root = Path(root)
        self.index = index
        self.name = orbit_name(index)
        self.path = self.root / self.name
        self._arrays: Dict[str, Any] = {}
        self._writer = ChunkWriter(self.path)

    def what(self) -> str:
        return f"orbit {self.index} ({self.path})"

    def lock(self) -> Lock:
        return Lock(self.path / ".lock", f"orbit {self.index} of the store {self.root}")

    def group(self) -> Any:
        if "" in self._arrays:
            return self._arrays[""]
        try:
            self._arrays[""] = _open_group(self.path)
            return self._arrays[""]
        except Exception as exc:
            raise StoreError(f"{self.what()}: missing or unreadable group ({exc})") from exc

    def attrs(self) -> Dict[str, Any]:
        return dict(self.group().attrs)

    def checkpoint(self) -> Optional[Dict[str, Any]]:
        return self.attrs().get("checkpoint")

    # -- arrays ---------------------------------------------------------------------------
    @staticmethod
    def names(layouts: Mapping[str, Mapping[str, Any]]) -> List[Tuple[str, str]]:
        """The ``(observable, var)`` pairs of the layouts, in digest order."""
        return [(o, v) for o in layouts for v in sorted(layouts[o])]

    def _array(self, key: str, mode: Literal["r", "r+"] = "r+"):
        """Array ``key`` of the orbit (opened once; for writing every chunk is written, also
        one holding only the fill value, so a missing chunk file is a deleted one)."""
        if key not in self._arrays:
            import zarr

            with _quiet(), zarr.config.set({"array.write_empty_chunks": True}):
                self._arrays[key] = zarr.open_array(str(self.path / key), mode=mode, zarr_format=3)
        return self._arrays[key]

    def ensure_arrays(self, layouts: Layouts) -> None:
        """Create the observables' groups, their arrays and the index that do not exist yet."""
        import zarr

        def make(key, shape, dtype, dims, attrs):
            p = self.path / key
            if (p / "zarr.json").is_file():
                return
            row = int(np.prod(shape[1:], dtype=np.int64)) * np.dtype(dtype).itemsize
            n = max(1, min(1 << 17, _ZARR_CHUNK_BYTES // max(row, 1)))
            fill = np.nan if np.dtype(dtype).kind == "f" else 0
            with _quiet():
                zarr.create_array(str(p), shape=(0, *shape[1:]), chunks=(n, *shape[1:]), dtype=dtype,
                                  fill_value=fill, zarr_format=3, dimension_names=list(dims),
                                  attributes={k: v for k, v in attrs.items() if v is not None}, overwrite=True)

        for o in layouts:
            if not (self.path / o / "zarr.json").is_file():
                with _quiet():
                    zarr.open_group(str(self.path / o), mode="a", zarr_format=3)
        for o, v in self.names(layouts):
            var = layouts[o][v]
            make(f"{o}/{v}", (0, *var.shape), var.dtype, var.dims,
                 {"long_name": var.doc, "units": getattr(var, "units", "1"), "step": var.step})
        make(_INDEX, (0, len(layouts) + len(self.names(layouts))), "int64", ("index_chunk", "index_column"),
             {"long_name": "per chunk: records of each observable, then the first 8 bytes of each array's sha256",
              "units": "1"})

    def _truncate(self, key: str, n: int) -> None:
        """Cut the array to ``n`` rows. The rows past ``n`` in the last zarr chunk are first
        overwritten with the fill value (one atomic rewrite of that chunk file, the committed
        rows in it unchanged, so a concurrent reader never sees them missing), then the
        array is resized (zarr deletes the chunks wholly past the end)."""
        a = self._array(key)
        self._writer.forget(key)  # zarr rewrites the array's last chunk and resizes it
        if a.shape[0] == n:
            return
        c = a.chunks[0]
        stop = min(a.shape[0], (n // c + 1) * c)
        if stop > n:
            a[n:stop] = np.full((stop - n, *a.shape[1:]), a.fill_value, dtype=a.dtype)
        a.resize((n, *a.shape[1:]))

    def untidy(self, layouts: Layouts, checkpoint: Optional[Mapping[str, Any]]) -> bool:
        """True if a killed writer left something behind: an array longer than committed
        (read from its ``zarr.json``, no data) or a temporary ``*.partial`` file. A kill
        after an orbit's last commit and before the trim at the end of its job leaves a
        finished orbit so; :meth:`clean` tidies it."""
        lengths = (checkpoint or {}).get("lengths", {})
        want = {f"{o}/{v}": int(lengths.get(o, 0)) for o, v in self.names(layouts)}
        want[_INDEX] = int((checkpoint or {}).get("chunks", 0))
        for key, n in want.items():
            try:
                shape = json.loads((self.path / key / "zarr.json").read_text())["shape"]
            except (OSError, ValueError, KeyError):
                return True
            if int(shape[0]) != n:
                return True
        return any(True for _ in self.path.rglob("*.partial"))

    def clean(self, layouts: Layouts, checkpoint: Optional[Mapping[str, Any]]) -> None:
        """Remove an interrupted chunk: every array cut to the committed length, zarr's
        leftover temporaries deleted."""
        for p in self.path.rglob("*.partial"):
            p.unlink(missing_ok=True)
        self.ensure_arrays(layouts)
        self.trim(layouts, checkpoint)

    def append(self, fingerprint: str, k: int, layouts: Layouts, records: Mapping[str, Mapping[str, np.ndarray]],
               checkpoint: Dict[str, Any], prev_digest: bytes) -> Tuple[Dict[str, Any], bytes]:
        """Append chunk ``k``'s records and commit ``checkpoint`` (given with
        ``lengths_before``; the lengths, digest and seal are filled in here); returns the
        committed checkpoint and the chain's new digest.

        Arrays grow by doubling (zarr's resize rewrites metadata), so they may be longer
        than committed while a run goes on; :meth:`trim` cuts them to the committed length
        when the orbit's job ends, :meth:`clean` when a killed run resumes. The writes of
        all arrays go through zarr's public (synchronous) API."""
        lengths = dict(checkpoint.get("lengths_before", {}))
        digests, counts, writes = [], [], []
        for o in layouts:
            n_o = None
            for v in sorted(layouts[o]):
                var = layouts[o][v]
                a = np.ascontiguousarray(records[o][v], dtype=var.dtype)
                if a.shape[1:] != tuple(var.shape) or (n_o is not None and len(a) != n_o):
                    raise UsageError(f"observable {o!r}: records of {v!r} have shape {a.shape}, expected "
                                     f"(n, {', '.join(map(str, var.shape))}) with one n for all its arrays")
                n_o = len(a)
                digests.append(var_digest(fingerprint, k, f"{o}/{v}", a))
                if len(a):
                    n0 = int(lengths.get(o, 0))
                    writes.append((f"{o}/{v}", n0, a))
            counts.append(n_o or 0)
            lengths[o] = int(lengths.get(o, 0)) + (n_o or 0)
        row = np.concatenate([np.array(counts, dtype=np.int64),
                              np.frombuffer(b"".join(d[:_TAG] for d in digests), dtype="<i8")])
        writes.append((_INDEX, k, row[None, :]))
        self._write(writes)
        h = chain(prev_digest, digests)
        ck = {key: val for key, val in checkpoint.items() if key != "lengths_before"}
        ck.update(chunks=k + 1, lengths=lengths, digest=h.hex())
        ck["seal"] = _seal(fingerprint, ck)
        self.group().attrs["checkpoint"] = ck  # the commit point
        return ck, h

    def _write(self, writes) -> None:
        """Write ``(key, row, values)`` items: grow the arrays that are too short, then
        write every region (the chunk files directly, :mod:`taylorball._store_write`, or
        zarr's public API for arrays that writer does not handle)."""
        for key, n0, a in writes:
            arr = self._array(key)
            need = n0 + len(a)
            if arr.shape[0] < need:
                arr.resize((max(need, 2 * arr.shape[0], arr.chunks[0]), *arr.shape[1:]))
            if not self._writer.write(key, arr, n0, a):
                arr[n0:need] = a

    def trim(self, layouts: Layouts, checkpoint: Optional[Mapping[str, Any]]) -> None:
        """Cut every array to its committed length (at the end of an orbit's job)."""
        lengths = (checkpoint or {}).get("lengths", {})
        K = (checkpoint or {}).get("chunks", 0)
        for o, v in self.names(layouts):
            self._truncate(f"{o}/{v}", int(lengths.get(o, 0)))
        self._truncate(_INDEX, K)

    # -- checks ---------------------------------------------------------------------------
    def check_attrs(self, fingerprint: Optional[str], study_fingerprint: Optional[str] = None,
                    attrs: Optional[Mapping[str, Any]] = None) -> Optional[Dict[str, Any]]:
        """Check the orbit's attributes; returns its checkpoint.

        Its ``fingerprint`` must be this orbit's (``fingerprint``; None: whatever follows
        from ``study_fingerprint``) and follow from the study's fingerprint, its index and
        its ``initial_state`` (the study's fingerprint is read from the root when not
        given); its checkpoint must match its seal.

        Raises
        ------
        StoreError
            Naming the orbit: another run's orbit, an orbit in another's place, an edited
            ``initial_state``, an altered checkpoint.
        """
        what = self.what()
        attrs = self.attrs() if attrs is None else attrs
        if study_fingerprint is None:
            study_fingerprint = RunStore(self.root).attrs().get("fingerprint")
        have = attrs.get("fingerprint")
        x0 = attrs.get("initial_state")
        try:
            own = orbit_fingerprint(str(study_fingerprint), self.index, x0)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            own = None
        if own != have:
            idx = attrs.get("index")
            if isinstance(idx, int) and idx != self.index:
                raise StoreError(f"{what} holds the group of orbit {idx} (its 'index' attribute): orbits were moved "
                                 "or swapped; restore the store or use --restart")
            if fingerprint is not None and have == fingerprint:
                raise StoreError(f"{what}: its 'initial_state' attribute (zarr.json) was altered: it does not match "
                                 "the orbit's fingerprint; restore the store or use --restart")
            if fingerprint is None:
                raise StoreError(f"{what} does not belong to this store: its fingerprint {have!r} does not follow from "
                                 "the store's fingerprint, its index and its 'initial_state' (copied from another "
                                 "store, or its 'initial_state' or 'fingerprint' attribute was altered); restore the "
                                 "store or use --restart")
        if fingerprint is not None and have != fingerprint:
            raise StoreError(f"{what} belongs to another run (fingerprint {have!r}, this study's orbit has "
                             f"{fingerprint!r}): it was copied from another store or the study changed; use "
                             "--restart (or another [output] store)")
        ck = attrs.get("checkpoint")
        if ck is None:
            return None
        if not isinstance(ck, dict) or ck.get("seal") != _seal(str(have), ck):
            raise StoreError(f"{what}: its checkpoint (zarr.json attribute 'checkpoint') was altered: it does not "
                             "match its seal; the orbit cannot be resumed from it (use --restart)")
        return ck

    def _committed_rows(self, key: str, ck: Mapping[str, Any]) -> int:
        o = key.split("/")[0]
        return int(ck["chunks"]) if o == _INDEX else int(ck["lengths"].get(o, 0))

    def check(self, fingerprint: Optional[str], layouts: Mapping[str, Mapping[str, Any]], *,
              study_fingerprint: Optional[str] = None, chunks_written: bool = True,
              attrs: Optional[Mapping[str, Any]] = None) -> Optional[Dict[str, Any]]:
        """The cheap check (no data read): :meth:`check_attrs`, then every array of the
        layouts (and the index) present with its dims, dtype, shape and ``step`` as in the
        layouts, at least as long as committed, and (``chunks_written``: format 2, where
        every zarr chunk is written) every zarr chunk file of its committed rows present.
        Returns the checkpoint.

        Raises
        ------
        StoreError
            Naming the orbit and the array.
        """
        what = self.what()
        ck = self.check_attrs(fingerprint, study_fingerprint, attrs)
        if not ck:
            return ck
        names = self.names(layouts)
        for key in [f"{o}/{v}" for o, v in names] + [_INDEX]:
            try:
                arr = self._array(key, "r")
            except Exception as exc:
                raise StoreError(f"{what}: array {key} is missing or its metadata is unreadable ({exc})") from exc
            n = self._committed_rows(key, ck)
            if arr.shape[0] < n:
                raise StoreError(f"{what}: array {key} has {arr.shape[0]} rows, its checkpoint commits {n}")
            if key != _INDEX:
                o, v = key.split("/")
                meta = layouts[o][v]
                meta = meta if isinstance(meta, Mapping) else _array_meta(meta)
                dims = tuple(arr.metadata.dimension_names or arr.attrs.get("dims") or ())
                got = (dims, arr.dtype.str, list(arr.shape[1:]), arr.attrs.get("step"))
                want = (tuple(meta["dims"]), meta["dtype"], list(meta["shape"]), meta["step"])
                if got != want:
                    raise StoreError(f"{what}: array {key} has (dims, dtype, shape, step) {got}, its layout says "
                                     f"{want}: its metadata (zarr.json) was altered; restore the store")
            if chunks_written and n:
                c = arr.chunks[0]
                for q in range(-(-n // c)):
                    f = self.path / key / "/".join(["c", str(q)] + ["0"] * (arr.ndim - 1))
                    if not f.is_file():
                        raise StoreError(f"{what}: array {key}: its zarr chunk file {f} (rows {q * c}.."
                                         f"{min(n, (q + 1) * c) - 1}) is missing; restore the store or use --restart")
        return ck

    def verify(self, fingerprint: Optional[str], layouts: Mapping[str, Mapping[str, Any]], *,
               study_fingerprint: Optional[str] = None, chunks_written: Optional[bool] = None,
               attrs: Optional[Mapping[str, Any]] = None) -> Optional[Dict[str, Any]]:
        """The full check: :meth:`check`, then every chunk's records against their digests
        and the chain against the checkpoint; returns the checkpoint.

        Raises
        ------
        StoreError
            Naming the orbit and the piece: a foreign fingerprint, an altered checkpoint, a
            missing or unreadable array, or the first chunk whose records do not match
            their digest.
        """
        what = self.what()
        if chunks_written is None:
            chunks_written = RunStore(self.root).attrs().get("format", 1) >= 2
        ck = self.check(fingerprint, layouts, study_fingerprint=study_fingerprint, chunks_written=chunks_written,
                        attrs=attrs)
        if ck is None:
            return None
        fingerprint = self.attrs()["fingerprint"] if attrs is None else attrs["fingerprint"]
        K = int(ck["chunks"])
        names = self.names(layouts)
        data = {}
        for key in [f"{o}/{v}" for o, v in names] + [_INDEX]:
            arr = self._array(key, "r")
            try:
                data[key] = arr[:self._committed_rows(key, ck)]
            except Exception as exc:
                raise StoreError(f"{what}: array {key} cannot be read (a corrupt zarr chunk file under "
                                 f"{self.path / key / 'c'}): {exc}") from exc
        n_obs = len(layouts)
        order = list(layouts)
        counts_all = data[_INDEX][:, :n_obs]
        if K and (counts_all.sum(axis=0) != [int(ck["lengths"].get(o, 0)) for o in order]).any():
            raise StoreError(f"{what}: array {_INDEX}: its record counts do not add up to the committed lengths "
                             f"{ck['lengths']}: the index was altered; restore the store or use --restart")
        stored = np.ascontiguousarray(data[_INDEX][:, n_obs:]).astype("<i8").view(np.uint8).reshape(K, len(names), _TAG)
        h = genesis(fingerprint)
        starts = {o: 0 for o in layouts}
        for k in range(K):
            digests = []
            for j, (o, v) in enumerate(names):
                n = int(counts_all[k, order.index(o)])
                part = data[f"{o}/{v}"][starts[o]:starts[o] + n]
                d = var_digest(fingerprint, k, f"{o}/{v}", part)
                if d[:_TAG] != stored[k, j].tobytes():
                    raise StoreError(f"{what}: array {o}/{v}, chunk {k} (rows {starts[o]}..{starts[o] + n - 1}) does "
                                     "not match its digest: corrupt, or copied from another run; use --restart or "
                                     "restore the store")
                digests.append(d)
            for o in layouts:
                starts[o] += int(counts_all[k, order.index(o)])
            h = chain(h, digests)
        if h.hex() != ck.get("digest") or any(starts[o] != int(ck["lengths"].get(o, 0)) for o in layouts):
            raise StoreError(f"{what}: the digest chain of its {K} chunks does not end at its checkpoint's digest "
                             f"(the index {_INDEX} or the checkpoint was altered); use --restart")
        return ck

    def committed(self, key: str, n: int) -> Any:
        """A lazy (dask) view of the first ``n`` rows of array ``key``."""
        import dask.array as da

        return da.from_zarr(self._array(key))[:n]


# ---------------------------------------------------------------------------------------
# Format 1 -> 2.
# ---------------------------------------------------------------------------------------
#: Arrays of format 1 holding angles (their long_name said "(rad)" or nothing).
_RAD_V1 = {("angles", "l"), ("sections", "l"), ("heading", "heading")}


def _write_json(path: Path, meta: Mapping[str, Any]) -> None:
    tmp = path.with_name(path.name + f".{uuid.uuid4().hex}.partial")
    tmp.write_text(json.dumps(meta, indent=2))
    os.replace(tmp, path)


def layouts_v1(path: Union[str, "os.PathLike[str]"]) -> Dict[str, Dict[str, Dict[str, Any]]]:
    """The layouts of a format-1 store, read from its first orbit with arrays (the
    observables in the study's order, which is the order of the index's columns)."""
    from .observables import build_observables

    rs = RunStore(path)
    attrs = rs.attrs()
    study = attrs.get("study", {})
    order = [o.name for o in build_observables(study.get("observables", {}), float(study.get("sample_dt", 1.0)))]
    n = int(study.get("n_orbits", 0))
    out: Dict[str, Dict[str, Dict[str, Any]]] = {}
    for i in range(n):
        od = rs.orbit(i).path
        if not (od / _INDEX / "zarr.json").is_file():
            continue
        for o in order:
            out[o] = {}
            for q in sorted(p for p in (od / o).iterdir() if (p / "zarr.json").is_file()):
                meta = json.loads((q / "zarr.json").read_text())
                a = meta.get("attributes", {})
                out[o][q.name] = {"dims": list(a.get("dims", [])), "dtype": np.dtype(meta["data_type"]).str,
                                  "shape": list(meta["shape"][1:]), "step": a.get("step"),
                                  "units": "rad" if (o, q.name) in _RAD_V1 else "1",
                                  "long_name": str(a.get("doc", "")).replace(" (rad)", "")}
        break
    return out


def upgrade(path: Union[str, "os.PathLike[str]"]) -> None:
    """Rewrite a format-1 store as format 2 in place: every observable folder a group,
    every array with ``dimension_names``, ``long_name`` and ``units``, the root
    attributes ``layout``, ``segments`` (the format-1 run as one segment, its CPU
    unknown, so extending it needs ``force``) and ``seal``. Every orbit is verified in
    full first (nothing is changed if one fails); the data are not rewritten, except
    that zarr chunk files format 1 left out (chunks holding only the fill value) are
    written.

    Raises
    ------
    StoreError
        Not a format-1 store, a store in use, or an orbit that fails verification.
    """
    import zarr

    rs = RunStore(path)
    attrs = rs.check_root(formats=(1,))
    study = attrs.get("study", {})
    n = int(study.get("n_orbits", 0))
    layouts = layouts_v1(rs.path)
    with Lock(rs.path.with_name(rs.path.name + ".lock"), f"the store {rs.path}"):
        cks = []
        for i in range(n):
            orb = rs.orbit(i)
            orb.lock().check()
            cks.append(orb.verify(None, layouts, study_fingerprint=attrs["fingerprint"], chunks_written=False,
                                  attrs=orb.attrs()))
        for i, ck in enumerate(cks):
            orb = rs.orbit(i)
            if not (orb.path / _INDEX / "zarr.json").is_file():
                continue
            for o in layouts:
                if not (orb.path / o / "zarr.json").is_file():
                    with _quiet():
                        zarr.open_group(str(orb.path / o), mode="a", zarr_format=3)
            keys = {f"{o}/{v}": layouts[o][v] for o, v in orb.names(layouts)}
            keys[_INDEX] = {"dims": ["index_chunk", "index_column"], "units": "1", "step": None,
                            "long_name": "per chunk: records of each observable, then the first 8 bytes of each "
                                         "array's sha256"}
            for key, m in keys.items():
                zj = orb.path / key / "zarr.json"
                meta = json.loads(zj.read_text())
                meta["dimension_names"] = list(m["dims"])
                meta["attributes"] = {k: m[k] for k in ("long_name", "units", "step") if m[k] is not None}
                _write_json(zj, meta)
                orb._arrays.pop(key, None)
                n_rows = orb._committed_rows(key, ck) if ck else 0
                arr = orb._array(key)
                c = arr.chunks[0]
                for q in range(-(-n_rows // c)):
                    if not (orb.path / key / "/".join(["c", str(q)] + ["0"] * (arr.ndim - 1))).is_file():
                        sl = slice(q * c, min(arr.shape[0], (q + 1) * c))
                        arr[sl] = arr[sl]  # only the fill value: written now
        prov = attrs.get("provenance", {})
        first = {"heyoka": prov.get("heyoka"), "cpu": "unknown (format 1)", "simd_size": None,
                 "taylorball": prov.get("taylorball"), "git_revision": prov.get("git_revision"),
                 "numpy": prov.get("numpy"), "action": "run (format 1)", "started": prov.get("created"),
                 "ended": None, "chunks": sum(int((ck or {}).get("chunks", 0)) for ck in cks), "forced": None}
        up = dict(segment("upgrade from format 1", float(attrs.get("t_end", 0.0))), chunks=0,
                  ended=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))
        new = dict(attrs, format=FORMAT_VERSION, units=UNITS_NOTE, layout=[{"name": o, "arrays": layouts[o]}
                                                                           for o in layouts], segments=[first, up])
        new["seal"] = _root_seal(new)
        g = _open_group(rs.path)
        g.attrs.update(new)
