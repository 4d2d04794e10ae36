"""Saving results with their evidence: atomic writes, JSON sidecars, provenance.

Every data file ``name.npz`` gets a sidecar ``name.json`` with the configuration that made
it and its provenance (package versions, git revision, host, time). Files are written to a
temporary name in the same folder and renamed into place, so a crash never leaves a
half-written result behind.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import os
import platform
import subprocess
import tempfile
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Tuple

import numpy as np

from ._typing import PathLike
from .errors import UsageError

__all__ = ["provenance", "atomic_write_bytes", "save_result", "load_result", "jsonable"]


def _git_revision(path: Path) -> Optional[str]:
    try:
        out = subprocess.run(
            ["git", "-C", str(path), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(path), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True, text=True, timeout=5, check=True,
        ).stdout.strip()
        return out + ("-dirty" if dirty else "")
    except Exception:  # not a checkout, git missing: provenance says so
        return None


def provenance() -> Dict[str, Any]:
    """Versions of the numerical stack, git revision of this checkout, host and time."""
    import heyoka as hy
    import mpmath

    from ._version import __version__

    return {
        "taylorball": __version__,
        "git_revision": _git_revision(Path(__file__).resolve().parent),
        "heyoka": hy.__version__,
        "numpy": np.__version__,
        "mpmath": mpmath.__version__,
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }


def jsonable(obj: object) -> Any:
    """Convert dataclasses, numpy and heyoka scalars/arrays to JSON-compatible values."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist()) if obj.dtype.kind in "fiub" else [str(v) for v in obj.reshape(-1)]
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.floating,)):
        return float(obj)
    if isinstance(obj, (str, int, float, bool)) or obj is None:
        return obj
    if isinstance(obj, type):
        return obj.__name__
    return str(obj)


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temporary file in the same folder + rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        # mkstemp creates 0600; results are for sharing: the usual 0666 less the umask
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.filename is None:  # a full disk's write names no file: name it
            raise type(exc)(exc.errno, exc.strerror, str(path)) from exc
        raise


_SAVEZ_ARGUMENTS = ("file", "allow_pickle")


def save_result(path: PathLike, arrays: Mapping[str, np.ndarray], meta: Mapping[str, Any]) -> Path:
    """Save arrays to ``path`` (``.npz``) and ``meta`` plus provenance to the sidecar
    ``.json``, both atomically. Arrays of heyoka's real128 / real are stored as float64
    plus a string copy (``<name>__str``) that keeps every digit."""
    import io

    # numpy.savez_compressed(file, allow_pickle=..., **arrays) would take these names as its own
    # arguments (an array named allow_pickle was dropped without a word)
    bad = [k for k in arrays if not isinstance(k, str) or k in _SAVEZ_ARGUMENTS]
    if bad:
        raise UsageError(f"arrays: the array names must be strings other than {_SAVEZ_ARGUMENTS} (numpy's "
                         f"savez arguments), got {bad!r}")
    path = Path(path).with_suffix(".npz")
    store: dict[str, np.ndarray] = {}
    for k, v in arrays.items():
        a = np.asarray(v)
        if a.dtype.kind not in "fiub":
            store[k] = a.astype(float)
            store[f"{k}__str"] = np.array([str(x) for x in a.reshape(-1)]).reshape(a.shape)
        else:
            store[k] = a
    buf = io.BytesIO()
    # mypy reads **store as possibly filling the bool allow_pickle; that name is refused above
    np.savez_compressed(buf, **store)  # type: ignore[arg-type]
    atomic_write_bytes(path, buf.getvalue())
    side = {"meta": jsonable(meta), "provenance": provenance(), "arrays": sorted(store)}
    atomic_write_bytes(path.with_suffix(".json"), json.dumps(side, indent=2, sort_keys=True).encode())
    return path


def load_result(path: PathLike) -> Tuple[Dict[str, np.ndarray], Dict[str, Any]]:
    """Load ``(arrays: dict, sidecar: dict)`` saved by :func:`save_result`."""
    path = Path(path).with_suffix(".npz")
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    side = json.loads(path.with_suffix(".json").read_text())
    return arrays, side
