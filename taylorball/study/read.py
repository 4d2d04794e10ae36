"""Reading a study's store: :func:`open_run` (an ``xarray.Dataset``)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Dict, List, Optional, Union

import numpy as np

from ..errors import UsageError


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

    from ..store import RunStore, _INDEX

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
