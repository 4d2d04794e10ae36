"""Reading a study's store: :func:`open_run` (an ``xarray.Dataset``, after a check; the
reading and its checks live with the store, in :mod:`taylorball._store_read`)."""

from __future__ import annotations

import os
from typing import Any, Optional, Union


def open_run(store: Union[str, "os.PathLike[str]"], *, observable: Optional[str] = None,
             verify: Union[bool, str] = "cheap") -> Any:
    """A study's store as an ``xarray.Dataset``, loaded lazily (dask arrays), after a check.

    Parameters
    ----------
    store : str or os.PathLike
        The store folder (``[output] store`` of the study).
    observable : str, optional
        One observable's group (``"drift"``, ``"angles"``, ``"samples"``, ...): its
        arrays under their own names, with dims ``orbit`` and the observable's own
        (``time``, ``chunk``, ``crossing``, ...). By default every observable, named
        ``<observable>_<array>`` with dims ``<observable>_<dim>``.
    verify : bool or str
        ``"cheap"`` (default; no data read): the store's format and sealed root
        attributes, the orbit count, every orbit's fingerprint (which seals its index and
        initial state) and checkpoint seal, every array's metadata and length, every zarr
        chunk file present. ``True`` or ``"full"``: also every chunk's records against
        their digests (reads everything). ``False`` or ``"none"``: no check.

    Returns
    -------
    xarray.Dataset
        Dim ``orbit`` first; each orbit's committed records, ragged lengths padded with NaN
        (integer arrays become float64 then). Variable attributes ``long_name``, ``units``
        (and ``doc``, the same as ``long_name``). Attributes: ``study``, ``fingerprint``,
        ``provenance``, ``t_end`` and per-orbit ``progress`` (chunks done).

    Raises
    ------
    UsageError
        Not a store (or one orbit's group of a store), an unknown observable, a bad
        ``verify``.
    StoreError
        A check failed, naming the orbit and the array; also raised when the data are
        computed and a zarr chunk cannot be decoded.
    """
    from .._store_read import open_run as _open_run  # the reading and its checks

    return _open_run(store, observable=observable, verify=verify)
