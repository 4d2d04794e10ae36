"""Small rooms: no module of the core (``taylorball/*.py``; the checks in ``verify/`` and
the figures are not counted here) is longer than MAX_LINES lines.

Lines are counted as the file has them (``len(text.splitlines())``, blank lines and
comments included: what a reader scrolls through). A module that grows past the limit is
split by job, with its public names re-exported where they are documented.
"""

from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "taylorball"
MAX_LINES = 900

MODULES = sorted(PACKAGE.glob("*.py"))


@pytest.mark.parametrize("path", MODULES, ids=[str(p.relative_to(PACKAGE)) for p in MODULES])
def test_no_module_is_over_the_limit(path):
    rel = str(path.relative_to(PACKAGE))
    n = len(path.read_text(encoding="utf-8").splitlines())
    assert n <= MAX_LINES, f"taylorball/{rel} has {n} lines, more than {MAX_LINES}: split it by job"
