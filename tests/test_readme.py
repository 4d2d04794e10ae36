"""The README's first steps and long-run example run as written (so they cannot rot)."""

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"


def _section(title: str) -> str:
    """The README's text from the heading ``## title`` to the next ``## `` heading."""
    text = README.read_text()
    start = text.index(f"## {title}\n")
    end = text.find("\n## ", start + 3)
    return text[start:end if end > 0 else None]


@pytest.mark.long
def test_first_session_runs():
    blocks = re.findall(r"```python\n(.*?)```", _section("First steps"), re.S)
    assert blocks, "README.md has no python block under 'First steps'"
    ns: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), ns)  # noqa: S102 - the README's own example
    assert ns["sec"].ok and len(ns["sec"].points) == 500
    assert all(r.ok for r in ns["secs"]) and len(ns["mg"]) == 4


@pytest.mark.long
def test_long_run_example_runs_as_written(tmp_path, monkeypatch):
    """The README's "Your own long runs": its study file, saved under the name the text
    gives it in a fresh folder, its shell commands run there as written (``taylorball`` is
    this interpreter's ``-m taylorball``), then its python block, in that folder."""
    import shlex
    import subprocess
    import sys

    sec = _section("Your own long runs")
    name = re.search(r"A small one, `([^`]+\.toml)`", sec).group(1)
    (toml,) = re.findall(r"```toml\n(.*?)```", sec, re.S)
    (sh,) = re.findall(r"```sh\n(.*?)```", sec, re.S)
    (py,) = re.findall(r"```python\n(.*?)```", sec, re.S)
    (tmp_path / name).write_text(toml)
    commands = [shlex.split(line, comments=True) for line in sh.splitlines() if line.strip()]
    assert [c[:2] for c in commands] == [["taylorball", "run"], ["taylorball", "status"], ["taylorball", "run"]]
    for c in commands:
        r = subprocess.run([sys.executable, "-m", "taylorball", *c[1:]], cwd=tmp_path, capture_output=True,
                           text=True, timeout=300)
        assert r.returncode == 0, (c, r.stdout, r.stderr)
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    exec(compile(py, "README.md", "exec"), ns)  # noqa: S102 - the README's own example
    ds, fit = ns["ds"], ns["fit"]
    assert float(ds.attrs["t_end"]) == 400.0 and ds.sizes["orbit"] == 2
    assert float(ns["t"][-1]) == 400.0 and ns["psi"].shape == (2, 401)
    assert 0.0 < fit.mu < 3.0  # the heading spreads (ballistic at most)
