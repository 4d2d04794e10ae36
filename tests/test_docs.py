"""The documentation site: every public name is in the API reference, every tutorial in the
index, and (slow) the site builds with warnings as errors."""

import importlib
import importlib.util
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import taylorball as tb

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"


def _autosummary_names(text: str) -> set:
    """``module.name`` of every entry of the page's autosummary blocks."""
    names, module = set(), None
    for line in text.splitlines():
        m = re.match(r"^\.\. currentmodule:: (\S+)", line)
        if m:
            module = m.group(1)
        elif re.match(r"^   [A-Za-z_]\w*$", line) and module:
            names.add(f"{module}.{line.strip()}")
    return names


def test_api_reference_lists_every_public_name():
    listed = _autosummary_names((DOCS / "api.md").read_text())
    missing = {f"taylorball.{n}" for n in tb.__all__ if n != "__version__"} - listed
    assert not missing, f"add to docs/api.md: {sorted(missing)}"
    for name in listed:  # and nothing that does not exist
        module, attr = name.rsplit(".", 1)
        assert hasattr(importlib.import_module(module), attr), name


def test_index_lists_every_tutorial_and_page():
    index = (DOCS / "index.md").read_text()
    for md in sorted((DOCS / "tutorials").glob("*.md")):
        assert f"tutorials/{md.stem}\n" in index, md.name
    for md in sorted(DOCS.glob("*.md")):
        if md.stem != "index":
            assert re.search(rf"^{re.escape(md.stem)}$", index, re.M), f"{md.name} is not in the toctree"


def test_readme_gives_the_build_command():
    assert "sphinx-build -W --keep-going -b html docs docs/_build/html" in (ROOT / "README.md").read_text()


@pytest.mark.slow
def test_docs_build_with_warnings_as_errors(tmp_path):
    """The README's build command, into a temporary folder, from scratch (no cached notebook
    outputs): it executes the five tutorials in a Jupyter kernel. Measured on 2 shared cores
    with a warm heyoka cache: 105 s; with an empty heyoka cache 168 s (load average ~10)."""
    for mod in ("sphinx", "myst_nb", "numpydoc", "furo", "ipykernel"):
        if importlib.util.find_spec(mod) is None:
            pytest.skip(f"{mod} is not installed: pip install -e '.[docs]'")
    if shutil.which("sphinx-build") is None and importlib.util.find_spec("sphinx") is None:
        pytest.skip("sphinx-build is not installed")
    out = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-E", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(DOCS), str(tmp_path / "html")],
        cwd=ROOT, capture_output=True, text=True, timeout=1200)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-5000:]
    for page in ("index", "getting-started", "api", "figures", "tutorials/05-validate-digits"):
        assert (tmp_path / "html" / f"{page}.html").is_file(), page
    # the tutorials' outputs are in the pages: they were executed
    assert "identical:" in (tmp_path / "html" / "tutorials" / "04-long-run.html").read_text()
