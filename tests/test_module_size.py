"""Small rooms: no module of the package (every ``.py`` file under ``taylorball/``: the core,
the checks in ``verify/``, the figures and every other subpackage) is longer than MAX_LINES
lines.

Lines are counted as the file has them (``len(text.splitlines())``, blank lines and
comments included: what a reader scrolls through). A module that grows past the limit is
split by job, with its public names re-exported where they are documented.
"""

from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "taylorball"
MAX_LINES = 900

MODULES = sorted(PACKAGE.rglob("*.py"))


def test_the_subpackages_are_counted():
    rels = {p.relative_to(PACKAGE).as_posix() for p in MODULES}
    assert "verify/formulas.py" in rels and "figures/runner.py" in rels, sorted(rels)[:10]


@pytest.mark.parametrize("path", MODULES, ids=[p.relative_to(PACKAGE).as_posix() for p in MODULES])
def test_no_module_is_over_the_limit(path):
    rel = path.relative_to(PACKAGE).as_posix()
    n = len(path.read_text(encoding="utf-8").splitlines())
    assert n <= MAX_LINES, f"taylorball/{rel} has {n} lines, more than {MAX_LINES}: split it by job"
