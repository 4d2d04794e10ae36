"""The state file of a resumable proof run (one JSON file; the chain's and the periodic
orbit's runs): open or start it, refusing another design or a changed one."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable, Dict, Optional

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
