"""The package's three layers and its import graph (docs/design.md, "Layers").

* the core (``taylorball/*.py``) never imports the checks (``taylorball.verify``), the
  figures (``taylorball.figures``), the command line or the ``studies/`` scripts, at module
  level or inside a function;
* the checks never import the figures;
* no import circle between taylorball's modules, counting imports inside functions too
  (a function-level import that closes a circle is a circle all the same);
* ``import taylorball`` loads neither the checks, the figures, matplotlib nor sympy.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parent.parent / "taylorball"


def _module_name(path: Path) -> str:
    rel = path.relative_to(PKG.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: Path):
    """The taylorball modules ``path`` imports (resolved, with the line), anywhere in it."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] in ("taylorball", "studies"):
                    yield a.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] not in ("taylorball", "studies"):
                continue
            yield mod, node.lineno
            for a in node.names:  # "from . import x" / "from .verify import y" may name submodules
                sub = f"{mod}.{a.name}"
                if (PKG.parent / Path(*sub.split("."))).with_suffix(".py").exists() or \
                        (PKG.parent / Path(*sub.split("."))).is_dir():
                    yield sub, node.lineno


def _graph():
    modules = {_module_name(p): p for p in PKG.rglob("*.py")}
    edges = {m: set() for m in modules}
    where = {}
    for m, p in modules.items():
        for target, line in _imports(p):
            # an import of a.b.c also runs a and a.b: count the deepest module that exists
            t = target
            while t and t not in modules:
                t = t.rsplit(".", 1)[0] if "." in t else ""
            if t and t != m:
                edges[m].add(t)
                where[(m, t)] = f"{p.relative_to(PKG.parent)}:{line}"
    return modules, edges, where


def _layer(m: str) -> str:
    if m.startswith("taylorball.verify"):
        return "checks"
    if m.startswith("taylorball.figures") or m.startswith("studies"):
        return "figures"
    if m in ("taylorball.cli", "taylorball.__main__"):
        return "cli"
    return "core"


def test_the_core_imports_neither_the_checks_nor_the_figures():
    modules, edges, where = _graph()
    bad = [f"{where[(m, t)]}: {m} imports {t}" for m in modules for t in edges[m]
           if _layer(m) == "core" and m != "taylorball" and _layer(t) != "core"]
    assert not bad, "the core reaches up a layer:\n" + "\n".join(sorted(bad))


def test_the_checks_do_not_import_the_figures():
    modules, edges, where = _graph()
    bad = [f"{where[(m, t)]}: {m} imports {t}" for m in modules for t in edges[m]
           if _layer(m) == "checks" and _layer(t) in ("figures", "cli")]
    assert not bad, "\n".join(sorted(bad))


def test_no_import_circle():
    modules, edges, where = _graph()
    # the package itself is the public face: it imports everything and nothing imports it
    # for its names (an `from . import x` of a submodule is counted as that submodule)
    cycles = []
    state = {}

    def visit(m, stack):
        state[m] = 1
        stack.append(m)
        for t in sorted(edges[m]):
            if t == "taylorball":
                continue
            if state.get(t) == 1:
                cyc = stack[stack.index(t):] + [t]
                cycles.append(" -> ".join(f"{a} ({where[(a, b)]})" for a, b in zip(cyc, cyc[1:])))
            elif t not in state:
                visit(t, stack)
        stack.pop()
        state[m] = 2

    for m in sorted(modules):
        if m not in state:
            visit(m, [])
    assert not cycles, "import circles:\n" + "\n".join(cycles)


def test_nothing_imports_the_package_root_for_its_names():
    """A module that imports ``taylorball`` itself (``from . import x`` of a name defined in
    __init__) climbs to the public face: every such import must name a submodule."""
    modules, edges, where = _graph()
    bad = [where[(m, t)] for m in modules for t in edges[m] if t == "taylorball" and m != "taylorball"
           and _layer(m) == "core"]
    assert not bad, "\n".join(sorted(bad))


def test_import_taylorball_loads_only_the_core():
    code = ("import sys, taylorball; "
            "bad = [m for m in sys.modules if m.startswith(('taylorball.verify', 'taylorball.figures', "
            "'matplotlib', 'sympy', 'studies'))]; print(bad); sys.exit(1 if bad else 0)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.mark.parametrize("name", ["integrals", "propagate", "problem", "megno", "poincare_section"])
def test_public_functions_are_not_shadowed_by_modules(name):
    import taylorball as tb

    assert callable(getattr(tb, name)) and not (PKG / f"{name}.py").exists()


def test_design_doc_names_every_module():
    """docs/design.md covers every module of the package: each module's name (``_lanes``,
    ``periodic_search``, a subpackage's ``enclosure``) stands in it as a word, so a reader
    who meets a module finds what it is for (a new module without a line there fails)."""
    import re

    text = (PKG.parent / "docs" / "design.md").read_text()
    words = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", text))
    missing = sorted(str(p.relative_to(PKG)) for p in PKG.rglob("*.py")
                     if p.stem not in ("__init__", "__main__") and p.stem not in words)
    assert not missing, f"docs/design.md does not name these modules: {missing}"
