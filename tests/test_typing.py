"""Static typing of the package: mypy is clean, the public API is annotated.

* ``python -m mypy`` with the ``[tool.mypy]`` configuration of ``pyproject.toml`` reports no
  error on ``taylorball`` (its core, checks and figures);
* every public callable (see :func:`public_callables`) annotates each of its parameters and
  its return, so a new public function without hints fails here rather than rotting mypy's
  view of the API (mypy does not check calls into an unannotated function);
* the docstring examples, the documented usage, type-check against those annotations (an
  annotation narrower than what the API takes shows up as an error in user code).
"""

from __future__ import annotations

import doctest
import enum
import functools
import importlib
import inspect
import os
import re
import subprocess
import sys
import textwrap
import time
import typing
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "taylorball"

# the core's public modules (each one's ``__all__`` is public) and the command line's entry
# point; private modules (``_x.py``) reach the API through ``taylorball.__all__``
PUBLIC_MODULES = sorted(
    f"taylorball.{p.stem}" for p in PKG.glob("*.py") if not p.stem.startswith("_")
) + ["taylorball"]


def _own_callables(cls: type) -> Iterator[tuple[str, Callable[..., object]]]:
    """The callables a public class defines itself: public methods, properties,
    class/static methods, ``__init__``, ``__new__`` and ``__call__`` (inherited ones belong to
    the base; an enum's ``__new__`` is the one ``enum`` installs)."""
    for name, member in vars(cls).items():
        if name.startswith("_") and name not in ("__init__", "__call__", "__new__"):
            continue
        if name == "__new__" and issubclass(cls, enum.Enum):
            continue
        if isinstance(member, (staticmethod, classmethod)):
            yield name, member.__func__
        elif isinstance(member, property):
            for part, f in (("fget", member.fget), ("fset", member.fset)):
                if f is not None:
                    yield f"{name}.{part}", f
        elif isinstance(member, functools.cached_property):
            yield name, member.func
        elif inspect.isfunction(member):
            yield name, member
        # enum members, constants and nested classes are not callables of the API


def public_callables() -> dict[str, Callable[..., object]]:
    """Qualified name -> callable for every public function, method and property of the
    package's public modules (their ``__all__``, lazily loaded names included)."""
    found: dict[str, Callable[..., object]] = {}
    for modname in PUBLIC_MODULES:
        mod = importlib.import_module(modname)
        for name in getattr(mod, "__all__", ()):
            obj = getattr(mod, name)
            if inspect.isclass(obj):
                if issubclass(obj, enum.Enum) and not any(True for _ in _own_callables(obj)):
                    continue
                for mname, f in _own_callables(obj):
                    # a dataclass's generated __init__ is annotated from its fields
                    found[f"{obj.__module__}.{obj.__qualname__}.{mname}"] = f
            elif inspect.isfunction(obj):
                found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return found


def missing_annotations(f: Callable[..., object]) -> list[str]:
    """What ``f`` leaves unannotated: parameter names (``self``/``cls`` exempt) and
    ``"return"``."""
    sig = inspect.signature(f)
    missing = []
    for i, p in enumerate(sig.parameters.values()):
        if i == 0 and p.name in ("self", "cls"):
            continue
        if p.annotation is inspect.Parameter.empty:
            missing.append(p.name)
    if sig.return_annotation is inspect.Signature.empty:
        missing.append("return")
    return missing


def test_public_api_fully_annotated():
    """Every public callable annotates every parameter and its return (``inspect``), with
    annotations that resolve at run time (``typing.get_type_hints``, as documentation tools
    and runtime checkers read them)."""
    found = public_callables()
    # a floor, so that a broken discovery (nothing or little found) cannot pass: 174 were
    # found when this test was written
    assert len(found) >= 150, sorted(found)
    bad = {name: m for name, f in sorted(found.items()) if (m := missing_annotations(f))}
    assert not bad, f"{len(bad)} of {len(found)} public callables lack annotations:\n" + "\n".join(
        f"  {name}: {', '.join(m)}" for name, m in bad.items()
    )
    unresolved = {}
    for name, f in sorted(found.items()):
        try:
            typing.get_type_hints(f)
        except Exception as exc:  # NameError for a name imported only under TYPE_CHECKING, ...
            unresolved[name] = f"{type(exc).__name__}: {exc}"
    assert not unresolved, unresolved


def test_coverage_probe_sees_a_missing_annotation():
    """The probe itself flags an unannotated parameter and return (so the test above can fail)."""

    def f(self, a: int, b, *args, c=1, **kw) -> None: ...

    def g(a: int):
        return a

    assert missing_annotations(f) == ["b", "args", "c", "kw"]
    assert missing_annotations(g) == ["return"]


@pytest.mark.long
def test_mypy_clean():
    """``python -m mypy`` (configuration: ``[tool.mypy]`` in pyproject.toml) finds no error in
    the package. Its cache is the default ``.mypy_cache`` of the checkout (git-ignored): a
    cold run (fresh clone) took 13 s alone and 26 s under load on 2 cores, a warm one ~2 s."""
    t0 = time.perf_counter()
    proc = _mypy("taylorball")
    took = time.perf_counter() - t0
    assert proc.returncode == 0, f"mypy ({took:.0f} s):\n{proc.stdout}\n{proc.stderr}"


def _mypy(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, MYPY_FORCE_COLOR="0")
    return subprocess.run([sys.executable, "-m", "mypy", *args], cwd=ROOT, capture_output=True, text=True,
                          env=env, timeout=600)


def test_docstring_examples_type_check(tmp_path):
    """Every docstring example of the public modules and the README's Python block, as a
    user's script, passes mypy.

    Each docstring becomes one function of its examples' source; examples that show an error
    on purpose (their output is a traceback) are left out. Strict Optional is off for this
    script only: the examples read fields that are ``None`` only without the option they
    pass (``megno(..., sample=...).mean_Y``), which a user's own code would narrow. Warm
    cache: ~3 s."""
    finder = doctest.DocTestFinder(recurse=True)
    funcs, seen = [], set()
    for modname in PUBLIC_MODULES:
        for test in finder.find(importlib.import_module(modname)):
            if test.name in seen:
                continue
            seen.add(test.name)
            body = [ex.source for ex in test.examples if "Traceback (most recent call last)" not in ex.want]
            if body:
                funcs.append(f"def example_{len(funcs)}() -> None:  # {test.name}\n"
                             + textwrap.indent("".join(body), "    "))
    assert len(funcs) >= 15, funcs  # 20 docstrings with examples when this was written
    readme = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
    assert readme
    funcs += [f"def readme_{i}() -> None:\n" + textwrap.indent(block, "    ") for i, block in enumerate(readme)]
    script = tmp_path / "examples.py"
    script.write_text("# mypy: no-strict-optional\n" + "\n\n".join(funcs) + "\n")
    proc = _mypy(str(script))
    assert proc.returncode == 0, f"{proc.stdout}\n{proc.stderr}\n--- {script.name}:\n{script.read_text()}"
