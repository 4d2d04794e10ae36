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


def test_class_members_are_not_hidden():
    """``autodoc_default_options = {"members": False}`` overrode the class template's
    ``:members:`` and hid every method and property (``Section.run``,
    ``Levels.from_caption``, ...); the template asks for them and no default takes them
    back. Maths is rendered by MathJax, also ``$...$`` in the pages."""
    import ast

    tree = ast.parse((DOCS / "conf.py").read_text())
    values = {t.id: node.value for node in tree.body if isinstance(node, ast.Assign)
              for t in node.targets if isinstance(t, ast.Name)}
    if "autodoc_default_options" in values:
        opts = ast.literal_eval(values["autodoc_default_options"])
        assert opts.get("members", True) not in (False, None), opts
    assert ":members:" in (DOCS / "_templates" / "autosummary" / "class.rst").read_text()
    assert "sphinx.ext.mathjax" in ast.literal_eval(values["extensions"])
    assert "dollarmath" in ast.literal_eval(values["myst_enable_extensions"])


def test_api_summaries_are_not_cut_after_an_abbreviation():
    """The API tables' first sentences were cut after "(paper eq." (autosummary ends a
    sentence at ". " unless it ends with a known abbreviation); conf.py adds the paper's."""
    pytest.importorskip("sphinx")
    from sphinx.ext import autosummary

    runpy = importlib.import_module("runpy")
    runpy.run_path(str(DOCS / "conf.py"))
    assert "Parameters of the M||gamma system (paper eq.".endswith(autosummary.WELL_KNOWN_ABBREVIATIONS)


@pytest.mark.slow
def test_docs_build_with_warnings_as_errors(tmp_path):
    """The README's build command, into a temporary folder, from scratch (no cached notebook
    outputs): it executes the tutorials in a Jupyter kernel. Measured on 2 shared cores
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
    # class members are documented, summaries are whole sentences, maths goes to MathJax
    gen = tmp_path / "html" / "generated"
    assert 'id="taylorball.Section.run"' in (gen / "taylorball.Section.html").read_text()
    assert 'id="taylorball.Levels.from_caption"' in (gen / "taylorball.Levels.html").read_text()
    api = (tmp_path / "html" / "api.html").read_text()
    assert "(paper eq.</p>" not in api
    assert "window.MathJax" in (gen / "taylorball.psi.html").read_text()  # psi's docstring has :math:
    # every tutorial downloadable as its notebook, executed in this build (outputs in it)
    import json

    for md in sorted((DOCS / "tutorials").glob("*.md")):
        page = (tmp_path / "html" / "tutorials" / f"{md.stem}.html").read_text()
        assert f'href="{md.stem}.ipynb" download' in page, md.name
        nb = json.loads((tmp_path / "html" / "tutorials" / f"{md.stem}.ipynb").read_text())
        code = [c for c in nb["cells"] if c["cell_type"] == "code"]
        assert nb["nbformat"] == 4 and code and any(c.get("outputs") for c in code), md.name


def _notebooks_ext():
    spec = importlib.util.spec_from_file_location("_docs_notebooks", DOCS / "_ext" / "notebooks.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_tutorial_is_a_notebook_with_a_download(tmp_path):
    """Each tutorial is a MyST notebook (myst-nb executes it and writes the executed .ipynb),
    the build copies every one next to its page and refuses to finish without one, and the
    page links to it under its title. (The real build: test_docs_build_with_warnings_as_errors.)"""
    nb = _notebooks_ext()
    pages = sorted((DOCS / "tutorials").glob("*.md"))
    assert len(pages) >= 6
    for md in pages:
        head = md.read_text().split("---")[1]
        assert "file_format: mystnb" in head and "kernelspec:" in head, md.name
        assert nb.tutorial_notebook_name(f"tutorials/{md.stem}") == f"{md.stem}.ipynb"
    assert nb.tutorial_notebook_name("figures") is None and nb.tutorial_notebook_name("generated/x") is None
    body = nb.add_notebook_link('<section><h1>1. A first orbit</h1><p>text</p>', "01-first-orbit.ipynb")
    assert body.index("</h1>") < body.index('href="01-first-orbit.ipynb" download') < body.index("<p>text")
    src, out, executed = tmp_path / "src", tmp_path / "html", tmp_path / "jupyter_execute"
    (src / "tutorials").mkdir(parents=True)
    (executed / "tutorials").mkdir(parents=True)
    for stem in ("01-a", "02-b"):
        (src / "tutorials" / f"{stem}.md").write_text("x")
    (executed / "tutorials" / "01-a.ipynb").write_text("{}")
    with pytest.raises(Exception, match=r"02-b\.md"):
        nb.copy_tutorial_notebooks(src, out, executed)
    (executed / "tutorials" / "02-b.ipynb").write_text("{}")
    copies = nb.copy_tutorial_notebooks(src, out, executed)
    assert [p.name for p in copies] == ["01-a.ipynb", "02-b.ipynb"] and all(p.is_file() for p in copies)
