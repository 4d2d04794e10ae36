"""The default run's schedule (tests/conftest.py, ``LONG_MODULES``; pyproject's addopts):
the longest modules are collected first and handed to the workers in that order."""

from pathlib import Path

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
