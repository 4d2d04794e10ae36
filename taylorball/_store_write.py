"""The run store's hot path: appending one chunk's records to an orbit's zarr arrays
without zarr's per-write machinery (:class:`ChunkWriter`).

zarr's synchronous API costs 1.7-2.3 ms of CPU per array write here (its event loop, the
codec pipeline, a read of the chunk it rewrites), against ~0.3 ms to compress a 1 MB chunk
with zstd. A run commits ~10-16 arrays per orbit per chunk, so the commits cost more than a
5000-time-unit chunk of batch integration. :class:`ChunkWriter` writes the same zarr chunk
files itself: it keeps the chunk being filled in memory (read once through zarr), encodes
it with the array's own codecs (the ``bytes`` codec, then ``zstd`` at the array's level,
through numcodecs as zarr does) and writes the file as zarr's LocalStore does (a temporary
``*.partial`` file in the same folder, then a rename), so a reader sees the old chunk or
the new one, never a torn one. Arrays of another codec chain or chunk grid go through
zarr's API as before. The values read back are the ones zarr would have written
(``tests/test_store_format.py``, ``tests/test_study_extend_bits.py``).
"""

from __future__ import annotations

import uuid
from pathlib import Path
from typing import Any, Dict, Optional, Tuple

import numpy as np


def _plan(arr: Any) -> Optional[Tuple[Any, str, Any]]:
    """``(zstd codec, dtype string, fill value)`` if the array is one this writer handles:
    a regular chunk grid with one chunk across every dimension but the first, the default
    chunk key encoding with ``/``, codecs ``bytes`` (little-endian) then ``zstd``; else None."""
    try:
        from numcodecs import Zstd  # type: ignore[import-untyped]
        from zarr.codecs import BytesCodec, ZstdCodec

        meta = arr.metadata
        codecs = tuple(meta.codecs)
        if len(codecs) != 2 or not isinstance(codecs[0], BytesCodec) or not isinstance(codecs[1], ZstdCodec):
            return None
        if getattr(codecs[0].endian, "value", codecs[0].endian) != "little":
            return None
        enc = meta.chunk_key_encoding
        if type(enc).__name__ != "DefaultChunkKeyEncoding" or enc.separator != "/":
            return None
        if tuple(arr.chunks[1:]) != tuple(arr.shape[1:]):
            return None
        dtype = np.dtype(arr.dtype).newbyteorder("<")
        return Zstd(level=int(codecs[1].level), checksum=bool(codecs[1].checksum)), dtype.str, arr.fill_value
    except Exception:  # another zarr version or layout: zarr's own API
        return None


class ChunkWriter:
    """Writes rows of an orbit's arrays as zarr chunk files (module docstring). One per
    :class:`taylorball.store.OrbitStore`; :meth:`forget` drops what it keeps of an array
    (after zarr itself rewrote or resized it: a trim, a cleanup)."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self._plans: Dict[str, Optional[Tuple[Any, str, Any]]] = {}
        self._chunks: Dict[str, Tuple[int, np.ndarray]] = {}
        self._dirs: set = set()

    def forget(self, key: Optional[str] = None) -> None:
        if key is None:
            self._chunks.clear()
        else:
            self._chunks.pop(key, None)

    def write(self, key: str, arr: Any, n0: int, a: np.ndarray) -> bool:
        """Write ``a`` into rows ``n0 .. n0 + len(a)`` of ``arr`` (array ``key`` of the
        orbit, already long enough); False if the array is not one this writer handles
        (the caller then writes through zarr)."""
        if key not in self._plans:
            self._plans[key] = _plan(arr)
        plan = self._plans[key]
        if plan is None:
            return False
        codec, dtype, fill = plan
        C = int(arr.chunks[0])
        need = n0 + len(a)
        for c in range(n0 // C, (need - 1) // C + 1):
            buf = self._chunk(key, arr, c, C, fill)
            lo, hi = max(n0, c * C), min(need, (c + 1) * C)
            buf[lo - c * C: hi - c * C] = a[lo - n0: hi - n0]
            data = codec.encode(np.ascontiguousarray(buf, dtype=dtype))
            self._put(self.root / key / "c" / "/".join([str(c)] + ["0"] * (buf.ndim - 1)), data)
        return True

    def _chunk(self, key: str, arr: Any, c: int, C: int, fill: Any) -> np.ndarray:
        """Chunk ``c`` of the array as it is stored: the rows inside the array's shape
        read through zarr once, the rows past it the fill value (as zarr writes an edge
        chunk)."""
        got = self._chunks.get(key)
        if got is not None and got[0] == c:
            return got[1]
        buf = np.full((C, *arr.shape[1:]), fill, dtype=arr.dtype)
        m = min(int(arr.shape[0]), (c + 1) * C) - c * C
        if m > 0:
            buf[:m] = arr[c * C: c * C + m]
        self._chunks[key] = (c, buf)
        return buf

    def _put(self, path: Path, data: Any) -> None:
        """As zarr's LocalStore writes a key: a temporary file beside it, then a rename."""
        parent = path.parent
        if parent not in self._dirs:
            parent.mkdir(parents=True, exist_ok=True)
            self._dirs.add(parent)
        tmp = path.with_suffix(f".{uuid.uuid4().hex}.partial")
        try:
            with open(tmp, "wb") as f:
                f.write(memoryview(data))
            tmp.replace(path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
