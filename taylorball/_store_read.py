"""Reading a study's store: :func:`open_run` (checks, then a lazy ``xarray.Dataset``).

What is checked (``verify``):

* ``"cheap"`` (the default; no data read): the root attributes (format, seal over the
  study, ``t_end``, layout and segments), the orbit count against the study's, every
  orbit's fingerprint (it follows from the store's, the orbit's index and its initial
  state: a swapped, moved or foreign orbit, an edited ``initial_state``), its checkpoint's
  seal, every array's dims, dtype, shape and ``step`` against the sealed layout, its
  length against the checkpoint, and (format 2) every zarr chunk file of the committed
  rows present (a deleted chunk would read as NaN);
* ``"full"`` (or True): also every chunk's records against their digests and the digest
  chain against the checkpoint (a flipped byte, a chunk copied from another run);
* ``"none"`` (or False): only that the store is a taylorball store (of a format this
  version reads).

A zarr chunk that cannot be decoded when the data are computed raises
:class:`~taylorball.errors.StoreError` naming the orbit and the array.
"""

from __future__ import annotations

import json
import os
import uuid
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Tuple, Union

import numpy as np

from .errors import StoreError, UsageError
from .store import FORMATS_READ, OrbitStore, RunStore, layouts_from_json, layouts_v1, orbit_name

VERIFY = ("none", "cheap", "full")


class _Guarded:
    """A zarr array for dask whose read errors name the orbit and the array."""

    def __init__(self, arr: Any, what: str, key: str, folder: Path) -> None:
        self.arr, self.what, self.key, self.folder = arr, what, key, folder
        self.shape, self.dtype, self.ndim = arr.shape, arr.dtype, arr.ndim

    def __getitem__(self, sel: Any) -> np.ndarray:
        try:
            return self.arr[sel]
        except Exception as exc:
            raise StoreError(f"{self.what}: array {self.key} cannot be read (a corrupt zarr chunk file under "
                             f"{self.folder / 'c'}): {type(exc).__name__}: {exc}") from exc


def _verify_level(verify: Any) -> str:
    if verify is True:
        return "full"
    if verify is False:
        return "none"
    if isinstance(verify, str) and verify in VERIFY:
        return verify
    raise UsageError(f"verify must be True (every digest), False (no check) or one of {', '.join(map(repr, VERIFY))}, "
                     f"got {verify!r}")


def _open_checked(store: Union[str, "os.PathLike[str]"], observable: Optional[str], verify: Union[bool, str]):
    """The checks of :func:`open_run` (``verify``); returns ``(attrs, study, layouts, orbs,
    cks, n)``: the root attributes, the study, the sealed layouts, the orbit stores, their
    checkpoints and the orbit count."""
    level = _verify_level(verify)
    try:
        rs = RunStore(Path(store))
    except TypeError:
        raise UsageError(f"store must be a folder path, got {store!r}") from None
    if not rs.exists():
        raise UsageError(f"store={str(store)!r} is not a taylorball run store (no zarr.json)")
    attrs = rs.check_root(formats=FORMATS_READ, seal=level != "none")
    fmt = int(attrs["format"])
    study = attrs.get("study", {})
    layouts = layouts_from_json(attrs["layout"]) if fmt >= 2 else layouts_v1(rs.path)
    n = int(study.get("n_orbits", 0))
    present = sorted(p.name for p in rs.path.iterdir() if p.name.startswith("orbit_") and (p / "zarr.json").is_file())
    if level != "none" and present != [orbit_name(i) for i in range(n)]:
        missing = sorted(set(orbit_name(i) for i in range(n)) - set(present))
        extra = sorted(set(present) - set(orbit_name(i) for i in range(n)))
        raise StoreError(f"{rs.path}: the study has {n} orbits, the store holds {len(present)} orbit groups"
                         + (f"; missing: {', '.join(missing)}" if missing else "")
                         + (f"; not of the study: {', '.join(extra)}" if extra else "")
                         + "; restore the store or use --restart")
    if level == "none":
        n = sum(1 for i in range(n) if orbit_name(i) in present)
    orbs = [rs.orbit(i) for i in range(n)]
    cks: List[Dict[str, Any]] = []
    for orb in orbs:
        if level == "none":
            ck = orb.checkpoint()
        elif level == "cheap":
            ck = orb.check(None, layouts, study_fingerprint=attrs["fingerprint"], chunks_written=fmt >= 2)
        else:
            ck = orb.verify(None, layouts, study_fingerprint=attrs["fingerprint"], chunks_written=fmt >= 2)
        cks.append(ck or {})
    if observable is not None and observable not in layouts:
        raise UsageError(f"observable={observable!r} is not in the store; it holds {sorted(layouts)}")
    return attrs, study, layouts, orbs, cks, n


def open_run(store: Union[str, "os.PathLike[str]"], *, observable: Optional[str] = None,
             verify: Union[bool, str] = "cheap") -> Any:
    """See :func:`taylorball.open_run`."""
    import dask.array as da
    import xarray as xr

    attrs, study, layouts, orbs, cks, n = _open_checked(store, observable, verify)
    data_vars: Dict[str, Any] = {}
    coords: Dict[str, Any] = {"orbit": np.arange(n)}
    for g in ([observable] if observable else sorted(layouts)):
        for v in sorted(layouts[g]):
            meta = layouts[g][v]
            cols, lens = _columns(orbs, cks, g, v, meta)
            longest = max(lens, default=0)
            padded = []
            for a, m in zip(cols, lens):
                if a.dtype.kind != "f":
                    a = a.astype(np.float64)
                if m < longest:
                    a = da.concatenate([a, da.full((longest - m, *a.shape[1:]), np.nan, dtype=a.dtype)], axis=0)
                padded.append(a)
            if padded:  # one chunking along time for every orbit (orbits with other numbers of
                # crossings were chunked differently; stacking them unified the chunks with
                # dask's PerformanceWarning on every open)
                c0 = max(max(a.chunks[0], default=1) for a in padded)
                padded = [a.rechunk({0: c0}) for a in padded]
            inner = tuple(meta["shape"])
            stacked = (da.stack(padded, axis=0) if padded else
                       da.empty((0, 0, *inner), dtype=np.float64 if np.dtype(meta["dtype"]).kind != "f"
                                else np.dtype(meta["dtype"])))
            names = meta.get("dims") or ["time"] + [f"dim_{j}" for j in range(1, stacked.ndim - 1)]
            dims = ["orbit"] + [d if observable else f"{g}_{d}" for d in names]
            data_vars[v if observable else f"{g}_{v}"] = (dims, stacked, {"doc": meta.get("long_name", ""),
                                                                         "long_name": meta.get("long_name", ""),
                                                                         "units": meta.get("units", "1")})
            if meta.get("step"):  # records on a regular grid: record j at t = j * step
                coords[dims[1]] = (dims[1], np.arange(longest) * float(meta["step"]))
    ds = xr.Dataset(data_vars, coords=coords)
    ds.attrs.update({"study": json.dumps(study), "fingerprint": attrs.get("fingerprint", ""),
                     "provenance": json.dumps(attrs.get("provenance", {})), "t_end": attrs.get("t_end", 0.0),
                     "progress": [int(ck.get("chunks", 0)) for ck in cks]})
    return ds


def _columns(orbs: List[OrbitStore], cks: List[Dict[str, Any]], g: str, v: str,
             meta: Mapping[str, Any], lazy: bool = True) -> Tuple[List[Any], List[int]]:
    """Each orbit's committed rows of array ``g/v`` (dask, or read at once into numpy with
    ``lazy=False``; empty for an orbit whose job never started) and their lengths."""
    if lazy:
        import dask.array as da

    key = f"{g}/{v}"
    cols, lens = [], []
    for orb, ck in zip(orbs, cks):
        if (orb.path / key / "zarr.json").is_file():
            arr = orb._array(key, "r")
            m = int(ck.get("lengths", {}).get(g, 0))
            guarded = _Guarded(arr, orb.what(), key, orb.path / key)
            if lazy:
                a = da.from_array(guarded, chunks=arr.chunks, asarray=False, fancy=False,
                                  meta=np.empty((0,) * arr.ndim, dtype=arr.dtype),
                                  name=f"taylorball-{uuid.uuid4().hex}")[:m]
            else:
                a = np.asarray(guarded[:m]) if m else np.empty((0, *guarded.shape[1:]), dtype=guarded.dtype)
        else:
            m = 0
            a = (da.empty if lazy else np.empty)((0, *meta["shape"]), dtype=np.dtype(meta["dtype"]))
        cols.append(a)
        lens.append(m)
    return cols, lens


def read_arrays(store: Union[str, "os.PathLike[str]"], *, observable: Optional[str] = None,
                verify: Union[bool, str] = "cheap") -> Dict[str, np.ndarray]:
    """The arrays of :func:`open_run`'s Dataset as numpy arrays, read at once, without
    xarray or dask (their imports alone are ~1.2 CPU s, more than a small study's reading):
    the same checks (``verify``), names (``<observable>_<array>``, or the array's own name
    with ``observable``), values and padding (dim ``orbit`` first, ragged lengths padded
    with NaN, integer arrays as float64) and coordinates (``orbit``, and ``<observable>_time``
    of records on a regular grid), bit for bit; no attributes."""
    _, _, layouts, orbs, cks, n = _open_checked(store, observable, verify)
    out: Dict[str, np.ndarray] = {}
    coords: Dict[str, np.ndarray] = {"orbit": np.arange(n)}
    for g in ([observable] if observable else sorted(layouts)):
        for v in sorted(layouts[g]):
            meta = layouts[g][v]
            cols, _ = _columns(orbs, cks, g, v, meta, lazy=False)
            cols = [a if a.dtype.kind == "f" else a.astype(np.float64) for a in cols]
            longest = max((len(a) for a in cols), default=0)
            cols = [np.concatenate([a, np.full((longest - len(a), *a.shape[1:]), np.nan, dtype=a.dtype)])
                    if len(a) < longest else a for a in cols]
            inner = tuple(meta["shape"])
            stacked = (np.stack(cols, axis=0) if cols else
                       np.empty((0, 0, *inner), dtype=np.float64 if np.dtype(meta["dtype"]).kind != "f"
                                else np.dtype(meta["dtype"])))
            out[v if observable else f"{g}_{v}"] = stacked
            if meta.get("step"):  # open_run's coordinate of records on a regular grid: record j at j * step
                names = meta.get("dims") or ["time"] + [f"dim_{j}" for j in range(1, stacked.ndim - 1)]
                coords[names[0] if observable else f"{g}_{names[0]}"] = np.arange(longest) * float(meta["step"])
    return {**coords, **out}


__all__ = ["open_run", "read_arrays", "VERIFY"]
