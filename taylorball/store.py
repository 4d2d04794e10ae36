"""The store of a study's long runs: one zarr v3 group, one subgroup per orbit.

Layout::

    STORE/zarr.json              attrs: format, study (normalised), fingerprint, provenance, t_end
    STORE/.lock                  the coordinating run's lock (host, pid, start)
    STORE/orbit_0003/zarr.json   attrs: fingerprint, index, initial_state, checkpoint
    STORE/orbit_0003/<obs>/<var> an observable's arrays, append dimension first
    STORE/orbit_0003/_index      (chunk, n_obs + n_vars) int64: records per chunk and
                                 observable, then 8 bytes of the sha256 of each array's records
    STORE/orbit_0003/.lock       the orbit's writer (host, pid, start; mtime = heartbeat)

Crash safety. Per chunk the writer appends every array's records (resize, then write the
new region), then the index rows, then the orbit's ``checkpoint`` attribute: the commit
point. Readers and resumes use the checkpoint's lengths; anything beyond them is an
uncommitted tail, cut off (the last zarr chunk rewritten so no stale value survives in it)
before the orbit's writer continues. zarr's LocalStore writes every key through a temporary
file and a rename; leftover temporaries (``*.partial``) are removed on resume.

Integrity. Each array's records of chunk ``k`` have the digest ``d = sha256(fingerprint,
k, name, dtype, shape, bytes)``; the chunk's digest is chained, ``h_k = sha256(h_{k-1} +
d_1 + ... + d_n)`` (``h_{-1} = sha256(fingerprint)``), and the checkpoint keeps ``h_K`` and
a seal (sha256 of the fingerprint and the checkpoint itself). :meth:`OrbitStore.verify`
recomputes all of it from the data and names the orbit, the array and the chunk that
differs (a corrupt file, a chunk copied from another run, a checkpoint changed by one ulp).

Locks. One writer per orbit: ``.lock`` is created with ``O_CREAT | O_EXCL``. A live holder
on this host is refused (naming host and pid), a dead one (no such pid, a zombie, or a pid
reused by a younger process) is stale and taken over; a holder on another host is refused
unless its lock has not been touched for :data:`HEARTBEAT_TIMEOUT` seconds (the writer
touches it after every chunk).
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import shutil
import socket
import time
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Dict, Iterator, List, Literal, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from .errors import StoreError, UsageError

__all__ = ["FORMAT_VERSION", "HEARTBEAT_TIMEOUT", "RunStore", "OrbitStore", "Lock", "orbit_name"]

#: Version of the store layout (root attribute ``format``).
FORMAT_VERSION = 1
#: A lock held by a process on another host is taken over when its file has not been
#: touched (the writer touches it after every chunk) for this many seconds.
HEARTBEAT_TIMEOUT = 600.0
#: Uncompressed bytes per zarr chunk of an appended array (rows of one record).
_ZARR_CHUNK_BYTES = 1 << 20
_INDEX = "_index"
#: Bytes of each array's per-chunk sha256 kept in the index, to name the array and chunk
#: that differ (8 bytes: 2^-64 chance that a changed chunk goes unnamed; it is still caught
#: by the chain, which the check recomputes from the full digests against the checkpoint).
_TAG = 8


#: An orbit's layouts: observable name -> array name -> :class:`taylorball.observables.Var`.
Layouts = Mapping[str, Mapping[str, Any]]


def orbit_name(i: int) -> str:
    return f"orbit_{i:04d}"


@contextmanager
def _quiet() -> Iterator[None]:
    """zarr warns about the lock files when it lists a group: they are ours."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r".*is not recognized as a component of a Zarr hierarchy")
        yield


# ---------------------------------------------------------------------------------------
# Locks.
# ---------------------------------------------------------------------------------------
def _proc_start(pid: int) -> Optional[str]:
    """The start time of process ``pid`` in clock ticks since boot (Linux), to tell a pid
    reused by another process from the original; None where /proc is not available."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
        return fields[19]
    except (OSError, IndexError):
        return None


def _alive(pid: int, start: Optional[str]) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat") as fh:
            state = fh.read().rsplit(")", 1)[1].split()[0]
        if state in ("Z", "X"):  # a zombie: dead, not yet reaped by its parent
            return False
    except (OSError, IndexError):
        pass
    now = _proc_start(pid)
    return start is None or now is None or now == start


class Lock:
    """An ``O_CREAT | O_EXCL`` lock file naming its holder; see the module docstring.

    ``what`` names the locked thing in messages (``"orbit 3 of STORE"``)."""

    def __init__(self, path: Path, what: str) -> None:
        self.path = Path(path)
        self.what = what
        self.held = False

    def acquire(self) -> "Lock":
        me = {"host": socket.gethostname(), "pid": os.getpid(), "proc_start": _proc_start(os.getpid()),
              "started": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}
        for _ in range(5):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                self._judge_holder(me)
                continue
            with os.fdopen(fd, "w") as fh:
                json.dump(me, fh)
            self.held = True
            return self
        raise StoreError(f"{self.what}: could not take the lock {self.path} (contended); try again")

    def _judge_holder(self, me) -> None:
        """Raise if the holder is live; remove the lock file if it is stale."""
        try:
            text = self.path.read_text()
            mtime = self.path.stat().st_mtime
        except FileNotFoundError:
            return  # released meanwhile: try again
        try:
            holder = json.loads(text)
            host, pid = holder["host"], int(holder["pid"])
        except (ValueError, KeyError, TypeError):
            holder, host, pid = {}, None, None
        age = time.time() - mtime
        if host == me["host"] and pid is not None:
            if pid == me["pid"] and holder.get("proc_start") == me["proc_start"]:
                raise StoreError(f"{self.what} is already being written by this process (pid {pid})")
            if _alive(pid, holder.get("proc_start")):
                raise StoreError(f"{self.what} is locked by a running process: pid {pid} on host {host} "
                                 f"(started {holder.get('started')}); only one run may write it at a time: wait for "
                                 f"that run to end or stop it ({self.path})")
        elif host is not None or age < 10.0:  # another host, or a lock file still being written
            if age < HEARTBEAT_TIMEOUT:
                raise StoreError(f"{self.what} is locked by pid {pid} on host {host} (lock touched {age:.0f} s ago); "
                                 f"a lock of another host is taken over only after {HEARTBEAT_TIMEOUT:.0f} s "
                                 f"without a heartbeat; if that process is dead, delete {self.path}")
        try:  # stale: its holder is dead
            self.path.unlink()
        except FileNotFoundError:
            pass

    def touch(self) -> None:
        if self.held:
            os.utime(self.path)

    def release(self) -> None:
        if self.held:
            self.held = False
            try:
                self.path.unlink()
            except FileNotFoundError:
                pass

    def __enter__(self) -> "Lock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


# ---------------------------------------------------------------------------------------
# Digests and exact values.
# ---------------------------------------------------------------------------------------
def genesis(fingerprint: str) -> bytes:
    return hashlib.sha256(f"taylorball-store/{FORMAT_VERSION}/{fingerprint}".encode()).digest()


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

    def lock(self) -> Lock:
        return Lock(self.path / ".lock", f"the store {self.path}")

    def create(self, attrs: Mapping[str, Any], orbits: Sequence[Mapping[str, Any]]) -> None:
        """A new store at ``self.path`` (which must not exist) with its root attributes and
        one group per orbit (``orbits``: their attributes)."""
        g = _open_group(self.path, "w-")
        for i, o in enumerate(orbits):
            og = g.create_group(orbit_name(i))
            og.attrs.update(dict(o, checkpoint=None))
        g.attrs.update(dict(attrs))  # written last: a store without root attrs is incomplete

    def set_attrs(self, **changes: Any) -> None:
        g = _open_group(self.path)
        g.attrs.update(changes)

    def orbit(self, i: int) -> "OrbitStore":
        return OrbitStore(self.path, i)

    def restart(self, build: Callable[[Path], None]) -> None:
        """Replace the store atomically by a new one: ``build(tmp_path)`` builds it in a
        sibling folder, then the old store is renamed aside, the new one renamed into
        place, and the old one deleted last. A crash at any point leaves either the old
        store, the new one, or no store (which a run rebuilds); leftovers are removed by
        :meth:`clean_leftovers`."""
        tmp = self.path.with_name(self.path.name + ".new")
        trash = self.path.with_name(self.path.name + ".old")
        self.clean_leftovers()
        build(tmp)
        if self.path.exists():
            os.rename(self.path, trash)
        os.rename(tmp, self.path)
        shutil.rmtree(trash, ignore_errors=True)

    def clean_leftovers(self) -> None:
        """Remove what an interrupted :meth:`restart` left next to the store."""
        for suffix in (".new", ".old"):
            p = self.path.with_name(self.path.name + suffix)
            if p.exists():
                shutil.rmtree(p)


class OrbitStore:
    """One orbit's group: its arrays, index, checkpoint and lock."""

    def __init__(self, root: Path, index: int) -> None:
        self.root = Path(root)
        self.index = index
        self.name = orbit_name(index)
        self.path = self.root / self.name
        self._arrays: Dict[str, Any] = {}

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

    def _array(self, key: str):
        if key not in self._arrays:
            import zarr

            with _quiet():
                self._arrays[key] = zarr.open_array(str(self.path / key), mode="r+", zarr_format=3)
        return self._arrays[key]

    def ensure_arrays(self, layouts: Layouts) -> None:
        """Create the arrays of the layouts (and the index) that do not exist yet."""
        import zarr

        def make(key, shape, dtype, dims, doc, step=None):
            p = self.path / key
            if (p / "zarr.json").is_file():
                return
            row = int(np.prod(shape[1:], dtype=np.int64)) * np.dtype(dtype).itemsize
            n = max(1, min(1 << 17, _ZARR_CHUNK_BYTES // max(row, 1)))
            fill = np.nan if np.dtype(dtype).kind == "f" else 0
            with _quiet():
                zarr.create_array(str(p), shape=(0, *shape[1:]), chunks=(n, *shape[1:]), dtype=dtype,
                                  fill_value=fill, zarr_format=3,
                                  attributes={"dims": list(dims), "doc": doc, "step": step},
                                  overwrite=True)

        for o, v in self.names(layouts):
            var = layouts[o][v]
            make(f"{o}/{v}", (0, *var.shape), var.dtype, var.dims, var.doc, var.step)
        make(_INDEX, (0, len(layouts) + len(self.names(layouts))), "int64", ("chunk", "column"),
             "per chunk: records of each observable, then the first 8 bytes of each array's sha256")

    def _truncate(self, key: str, n: int) -> None:
        """Cut the array to ``n`` rows. The rows past ``n`` in the last zarr chunk are first
        overwritten with the fill value (one atomic rewrite of that chunk file, the committed
        rows in it unchanged, so a concurrent reader never sees them missing), then the
        array is resized (zarr deletes the chunks wholly past the end)."""
        a = self._array(key)
        if a.shape[0] == n:
            return
        c = a.chunks[0]
        stop = min(a.shape[0], (n // c + 1) * c)
        if stop > n:
            a[n:stop] = np.full((stop - n, *a.shape[1:]), a.fill_value, dtype=a.dtype)
        a.resize((n, *a.shape[1:]))

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
        all arrays are issued concurrently (zarr's async API)."""
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
        write every region concurrently."""
        import asyncio

        from zarr.core.sync import sync

        grow, puts = [], []
        for key, n0, a in writes:
            arr = self._array(key)
            need = n0 + len(a)
            if arr.shape[0] < need:
                grow.append((arr, (max(need, 2 * arr.shape[0], arr.chunks[0]), *arr.shape[1:])))
            puts.append((arr, slice(n0, need), a))

        async def run():
            await asyncio.gather(*(arr._async_array.resize(shape) for arr, shape in grow))
            await asyncio.gather(*(arr._async_array.setitem(sel, a) for arr, sel, a in puts))

        sync(run())
        for arr, shape in grow:  # the sync wrappers cache their metadata: reopen
            self._arrays.pop(next(k for k, v in self._arrays.items() if v is arr), None)

    def trim(self, layouts: Layouts, checkpoint: Optional[Mapping[str, Any]]) -> None:
        """Cut every array to its committed length (at the end of an orbit's job)."""
        lengths = (checkpoint or {}).get("lengths", {})
        K = (checkpoint or {}).get("chunks", 0)
        for o, v in self.names(layouts):
            self._truncate(f"{o}/{v}", int(lengths.get(o, 0)))
        self._truncate(_INDEX, K)

    # -- checks ---------------------------------------------------------------------------
    def verify(self, fingerprint: str, layouts: Layouts) -> Optional[Dict[str, Any]]:
        """Check the orbit against ``fingerprint`` and the layouts; returns its checkpoint.

        Raises
        ------
        StoreError
            Naming the orbit and the piece: a foreign fingerprint, an altered checkpoint, a
            missing or unreadable array, or the first chunk whose records do not match
            their digest.
        """
        what = self.what()
        attrs = self.attrs()
        if attrs.get("fingerprint") != fingerprint:
            raise StoreError(f"{what} belongs to another run (fingerprint {attrs.get('fingerprint')!r}, this study's "
                             f"orbit has {fingerprint!r}): it was copied from another store or the study changed; "
                             "use --restart (or another [output] store)")
        ck = attrs.get("checkpoint")
        if ck is None:
            return None
        if not isinstance(ck, dict) or ck.get("seal") != _seal(fingerprint, ck):
            raise StoreError(f"{what}: its checkpoint (zarr.json attribute 'checkpoint') was altered: it does not "
                             "match its seal; the orbit cannot be resumed from it (use --restart)")
        K = int(ck["chunks"])
        names = self.names(layouts)
        data, counts_all = {}, None
        for key in [f"{o}/{v}" for o, v in names] + [_INDEX]:
            try:
                arr = self._array(key)
            except Exception as exc:
                raise StoreError(f"{what}: array {key} is missing or its metadata is unreadable ({exc})") from exc
            o = key.split("/")[0]
            n = K if o == _INDEX else int(ck["lengths"].get(o, 0))
            if arr.shape[0] < n:
                raise StoreError(f"{what}: array {key} has {arr.shape[0]} rows, its checkpoint commits {n}")
            try:
                data[key] = arr[:n]
            except Exception as exc:
                raise StoreError(f"{what}: array {key} cannot be read (a corrupt zarr chunk file under "
                                 f"{self.path / key / 'c'}): {exc}") from exc
        n_obs = len(layouts)
        counts_all = data[_INDEX][:, :n_obs]
        stored = np.ascontiguousarray(data[_INDEX][:, n_obs:]).astype("<i8").view(np.uint8).reshape(K, len(names), _TAG)
        h = genesis(fingerprint)
        starts = {o: 0 for o in layouts}
        for k in range(K):
            digests = []
            for j, (o, v) in enumerate(names):
                n = int(counts_all[k, list(layouts).index(o)])
                part = data[f"{o}/{v}"][starts[o]:starts[o] + n]
                d = var_digest(fingerprint, k, f"{o}/{v}", part)
                if d[:_TAG] != stored[k, j].tobytes():
                    raise StoreError(f"{what}: array {o}/{v}, chunk {k} (rows {starts[o]}..{starts[o] + n - 1}) does "
                                     "not match its digest: corrupt, or copied from another run; use --restart or "
                                     "restore the store")
                digests.append(d)
            for o in layouts:
                starts[o] += int(counts_all[k, list(layouts).index(o)])
            h = chain(h, digests)
        if h.hex() != ck.get("digest") or any(starts[o] != int(ck["lengths"].get(o, 0)) for o in layouts):
            raise StoreError(f"{what}: the digest chain of its {K} chunks does not end at its checkpoint's digest "
                             f"(the index {_INDEX} or the checkpoint was altered); use --restart")
        return ck

    def committed(self, key: str, n: int) -> Any:
        """A lazy (dask) view of the first ``n`` rows of array ``key``."""
        import dask.array as da

        return da.from_zarr(self._array(key))[:n]
