"""The tutorials (docs/tutorials/*.md, MyST notebooks) run as written, so they cannot rot.

Each tutorial's ``{code-cell}`` blocks are executed in order in one fresh namespace, in a
temporary working directory, without a Jupyter kernel (the documentation build executes
them with one: ``sphinx-build -W``, see ``test_docs.py``). A failure names the tutorial and
the cell.
"""

import re
import time
from pathlib import Path

import matplotlib
import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"
TUTORIALS = sorted((DOCS / "tutorials").glob("*.md"))

_CELL = re.compile(r"^```\{code-cell\}[^\n]*\n(.*?)^```[ \t]*$", re.S | re.M)


def code_cells(text: str) -> list:
    """The source of each ``{code-cell}`` block of a MyST notebook, in order, without the
    cell's options (``:key: value`` lines, or a ``---`` YAML block, at its top)."""
    cells = []
    for body in _CELL.findall(text):
        lines = body.splitlines()
        if lines and lines[0].strip() == "---":
            end = lines.index("---", 1)
            lines = lines[end + 1:]
        while lines and re.match(r"^:[\w-]+:", lines[0]):
            lines = lines[1:]
        cells.append("\n".join(lines) + "\n")
    return cells


def test_cell_parser_reads_options_and_order():
    text = ("# t\n\n```{code-cell} ipython3\n:tags: [hide-input]\nx = 1\n```\n\ntext\n\n"
            "```python\nnot = a cell\n```\n\n```{code-cell} ipython3\n---\ntags: [x]\n---\ny = x + 1\n```\n")
    assert code_cells(text) == ["x = 1\n", "y = x + 1\n"]


def test_the_tutorials_are_there_each_with_cells():
    assert len(TUTORIALS) >= 5, [t.name for t in TUTORIALS]
    for t in TUTORIALS:
        assert "file_format: mystnb" in t.read_text(), f"{t.name}: no mystnb front matter"
        assert len(code_cells(t.read_text())) >= 3, t.name


@pytest.mark.parametrize("path", TUTORIALS, ids=[t.stem for t in TUTORIALS])
@pytest.mark.long
def test_tutorial_runs(path, tmp_path, monkeypatch):
    """Each tutorial runs in well under 30 s with a warm compile cache (times in the docs'
    index of tutorials and the report; the first run on a fresh machine compiles more)."""
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)
    ns: dict = {"__name__": "__tutorial__"}
    start = time.perf_counter()
    try:
        for i, src in enumerate(code_cells(path.read_text()), 1):
            try:
                # the tutorial's own code, as a reader runs it
                exec(compile(src, f"{path.name} [cell {i}]", "exec"), ns)  # noqa: S102
            except Exception as err:
                raise AssertionError(f"{path.name}, cell {i} failed: {type(err).__name__}: {err}\n"
                                     f"--- cell {i} ---\n{src}") from err
    finally:
        plt.close("all")
    print(f"{path.name}: {time.perf_counter() - start:.1f} s")
