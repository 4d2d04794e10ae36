"""The README's first session runs as written (so it cannot rot)."""

import re
from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"


def test_first_session_runs():
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
    assert blocks, "README.md has no python block"
    ns: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), ns)  # noqa: S102 - the README's own example
    assert ns["sec"].ok and len(ns["sec"].points) == 500
    assert all(r.ok for r in ns["secs"]) and len(ns["mg"]) == 4
