"""The default run's schedule (tests/conftest.py, ``LONG_MODULES``; pyproject's addopts):
the longest modules are collected first and handed to the workers in that order."""

from pathlib import Path

import pytest

from .conftest import LONG_MODULES

HERE = Path(__file__).resolve().parent


def test_long_modules_name_existing_modules_once():
    """A renamed or removed module would silently lose its place in the schedule."""
    assert len(set(LONG_MODULES)) == len(LONG_MODULES)
    missing = [m for m in LONG_MODULES if not (HERE / f"{m}.py").is_file()]
    assert not missing, missing


def test_workers_take_the_modules_in_collection_order(request):
    """``--no-loadscope-reorder`` is in force (pytest-xdist >= 3.8 reorders the modules by
    their number of tests otherwise, which undoes the longest-first collection order)."""
    assert request.config.getoption("loadscopereorder") is False


def test_long_modules_are_collected_first(request):
    """In this run's collection the modules of ``LONG_MODULES`` come first, in its order."""
    names = []
    for item in request.session.items:
        name = item.module.__name__.rsplit(".", 1)[-1]
        if not names or names[-1] != name:
            names.append(name)
    long_seen = [n for n in names if n in LONG_MODULES]
    assert names[: len(long_seen)] == long_seen  # no other module before the last long one
    assert long_seen == [m for m in LONG_MODULES if m in long_seen]


def _readme_test_command() -> str:
    """The test command of README.md's "Run the tests" (the line that installs the test extra)."""
    import re

    text = (HERE.parent / "README.md").read_text()
    lines = re.findall(r"^pip install -e \"\.\[test\]\" && pytest.*$", text, re.M)
    assert len(lines) == 1, lines
    return lines[0]


def test_ci_runs_the_readme_test_command():
    """``.ci/run`` calls the test command README.md gives, exactly, and that command asks for
    every test but the ``slow`` ones (``long`` included, which a plain ``pytest`` leaves out)."""
    command = _readme_test_command()
    assert command.endswith("&& pytest -m 'not slow'"), command
    ci = (HERE.parent / ".ci" / "run").read_text().splitlines()
    assert command in ci, command


@pytest.mark.long  # two fresh interpreters collecting a module (5.1 CPU s)
def test_a_marker_expression_on_the_command_line_replaces_the_default_one():
    """pytest's ``-m`` on the command line comes after pyproject's ``addopts`` and replaces its
    ``-m 'not slow and not long'``: README's ``pytest -m 'not slow'`` collects the ``long``
    tests and not the ``slow`` ones, a plain ``pytest`` neither (collected, not run, in a
    module that has all three kinds: ``tests/test_study.py``)."""
    import shlex
    import subprocess
    import sys

    argv = shlex.split(_readme_test_command().split("&&")[1])
    assert argv[0] == "pytest"
    base = [sys.executable, "-m", "pytest", "--collect-only", "-q", "-n", "0", "-p", "no:cacheprovider", "--rootdir", str(HERE.parent), str(HERE / "test_study.py")]
    long_test, slow_test, plain_test = ("test_kill_9_then_rerun_is_bit_identical", "test_kill_9_many_times",
                                        "test_run_then_rerun_does_no_work")
    ci = subprocess.run(base + argv[1:], capture_output=True, text=True, cwd=HERE.parent, timeout=300)
    default = subprocess.run(base, capture_output=True, text=True, cwd=HERE.parent, timeout=300)
    for out in (ci, default):
        assert out.returncode == 0, out.stdout + out.stderr
        assert f"::{plain_test}\n" in out.stdout and f"::{slow_test}\n" not in out.stdout, out.stdout
    assert f"::{long_test}\n" in ci.stdout, ci.stdout
    assert f"::{long_test}\n" not in default.stdout, default.stdout
