"""What the resumable proof runs share (the chain's and the periodic orbit's): the state
file (one JSON file: open or start it, refusing another design or a changed one), the
design's hash, and the pool that runs independent proof jobs in worker processes."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any, Callable, Dict, Optional, Sequence

from ..errors import UsageError


def open_run_state(path: Path, record: Optional[Dict[str, Any]], design_hash: Callable[[Dict[str, Any]], str],
                   **fresh: Any) -> Dict[str, Any]:
    """The record in the state file ``path``, resumed; or, if the file does not exist, a new
    one from ``record`` with its ``design_sha256`` (and the fields ``fresh``). Raises
    :class:`UsageError` if ``record`` is given and is another design than the file's, if
    neither exists, or if the file's design was changed after it was made."""
    if path.exists():
        with open(path) as fh:
            rec = json.load(fh)
        if record is not None and design_hash(record) != rec.get("design_sha256"):
            raise UsageError(f"the state file {str(path)!r} belongs to another design (its sha256 "
                             f"{rec.get('design_sha256')!r}); use a new state file")
    elif record is None:
        raise UsageError(f"the state file {str(path)!r} does not exist and no record was given to start it")
    else:
        rec = dict(record, design_sha256=design_hash(record), **fresh)
    if rec.get("design_sha256") != design_hash(rec):
        raise UsageError(f"the state file {str(path)!r} was changed after it was made (design sha256 mismatch)")
    return rec


def design_hash(rec: Dict[str, Any], keys: Sequence[str], what: str) -> str:
    """The sha256 of the record's design: its fields ``keys`` as sorted JSON. Raises
    :class:`UsageError` naming the missing field (``what``: the kind of state, for the message)."""
    try:
        design = {k: rec[k] for k in keys}
    except KeyError as exc:
        raise UsageError(f"a {what} state needs the fields {tuple(keys)}; {exc!r} is missing") from None
    return hashlib.sha256(json.dumps(design, sort_keys=True).encode()).hexdigest()


def check_workers(workers: Any) -> None:
    """Raise :class:`UsageError` unless ``workers`` (processes for :func:`run_jobs`) is an
    integer in ``[1, 64]``: called before any work by the runs and checks that take it."""
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= 64:
        raise UsageError(f"workers must be an integer in [1, 64], got {workers!r}")


def run_jobs(fn: Callable[[Any], Any], jobs: Sequence[Any], workers: int, keep: Callable[[int, Any], bool]) -> None:
    """``fn(job)`` for each of the independent ``jobs``, handing ``keep(k, result)`` each
    result in this process as it comes (``k``: the job's index). With ``workers > 1`` the jobs
    run in that many worker processes (``fn`` and the jobs must pickle) and every job runs,
    the results coming in the order they finish; with one worker they run here in order and
    stop at the first result that ``keep`` answers false (a failed inclusion decides a proof)."""
    if workers > 1 and len(jobs) > 1:
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(max_workers=workers) as pool:
            futs = {pool.submit(fn, j): k for k, j in enumerate(jobs)}
            for fu in as_completed(futs):
                keep(futs[fu], fu.result())
    else:
        for k, j in enumerate(jobs):
            if not keep(k, fn(j)):
                break
