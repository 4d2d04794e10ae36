"""docs/equations.md stays honest: every name it gives exists.

The index maps each equation of the paper to the code that implements it, the
``taylorball verify`` check that verifies it and the tests. This test parses its tables and
checks, row by row, that

* every ``module.name`` of the code column imports (``taylorball.<module>`` or the private
  ``taylorball._<module>``, then a ``getattr`` chain: ``model.REDUCED.integrals`` is an
  attribute of the ``REDUCED`` system);
* every ``topic.check_name`` of the check column is a function in the ``CHECKS`` list of
  ``taylorball.verify.<topic>`` (so it runs in ``taylorball verify``);
* every ``tests/test_x.py::test_y`` of the test column names a file with a ``def test_y``;
* every erratum id names a section ``## <id>.`` of docs/errata.md;
* a cell without a name says so: it starts with "—" and a note;
* every label exists in the paper's .tex, the printed numbers are the ones LaTeX gives
  (counted from the .tex as iopart.cls numbers them), and every numbered equation of the
  paper is indexed. These need the .tex at ``../shared/paper/`` from the repository root and
  are skipped, with the reason, where the package is checked out without it.

Fast: no integration, imports only.
"""

from __future__ import annotations

import importlib
import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
INDEX = ROOT / "docs" / "equations.md"
ERRATA = ROOT / "docs" / "errata.md"
#: The paper's LaTeX source (not shipped with the package): $TAYLORBALL_PAPER_TEX, else
#: ../shared/paper/ beside the checkout.
TEX = Path(os.environ.get("TAYLORBALL_PAPER_TEX") or ROOT.parent / "shared" / "paper" /
           "chaplygin-ball-rotating-plane.tex")

COLUMNS = ("printed", "label", "what", "code", "check", "test", "erratum")
DASH = "—"


# ---------------------------------------------------------------------------------------
# Parsing the index.
# ---------------------------------------------------------------------------------------
def _cells(line: str):
    """Cells of a Markdown table row; ``\\|`` is a literal bar inside a cell."""
    parts = re.split(r"(?<!\\)\|", line.strip())
    return [p.strip() for p in parts[1:-1]]


def index_rows():
    """``(where, row)`` for every data row of the equation tables (header ``| printed |
    label | ...``), ``row`` a dict by :data:`COLUMNS`; ``where`` names the row for messages."""
    rows, header, section = [], None, "?"
    for n, line in enumerate(INDEX.read_text(encoding="utf-8").splitlines(), 1):
        if line.startswith("## "):
            section = line[3:].strip()
        if not line.startswith("|"):
            header = None
            continue
        cells = _cells(line)
        if header is None:
            header = [c.lower() for c in cells]
            continue
        if set("".join(cells)) <= set("-: "):
            continue  # the |---|---| line
        if tuple(header[: len(COLUMNS)]) != COLUMNS:
            continue  # another kind of table
        assert len(cells) == len(COLUMNS), f"docs/equations.md:{n}: {len(cells)} cells, expected {len(COLUMNS)}: {line}"
        row = dict(zip(COLUMNS, cells))
        what = re.sub(r"[*`]", "", row["what"])[:50]
        rows.append((f"docs/equations.md:{n} ({section}; {row['printed']} {row['label']} {what!r})", row))
    return rows


def _names(cell: str):
    """The backticked names of a cell."""
    return re.findall(r"`([^`]+)`", cell)


ROWS = index_rows() if INDEX.is_file() else []


def test_the_index_has_rows_in_every_section():
    assert INDEX.is_file(), f"no equation index at {INDEX}"
    sections = {w.split("(", 1)[1].split(";")[0] for w, _ in ROWS}
    assert len(ROWS) >= 30, f"only {len(ROWS)} rows parsed from {INDEX}"
    for sec in ("1.", "2.", "3.", "4.", "5."):
        assert any(s.startswith(f"Sec. {sec}") for s in sections), (sec, sorted(sections))


def test_every_cell_names_something_or_says_why_not():
    for where, row in ROWS:
        for col in ("code", "check", "test"):
            cell = row[col]
            if cell.startswith(DASH):
                assert len(cell) > len(DASH) + 3, f"{where}: {col} cell is a bare '{DASH}'; add a note saying why"
            else:
                assert _names(cell), f"{where}: {col} cell {cell!r} names nothing and does not start with '{DASH}'"


# ---------------------------------------------------------------------------------------
# Code, checks, tests, errata.
# ---------------------------------------------------------------------------------------
def resolve(dotted: str):
    """``model.REDUCED.integrals`` -> the object, trying ``taylorball.model`` and
    ``taylorball._model`` (and ``verify.x`` -> ``taylorball.verify.x``); the longest module
    prefix that imports wins."""
    parts = dotted.split(".")
    errors = []
    for k in range(len(parts) - 1, 0, -1):
        mod_path = ".".join(parts[:k])
        for cand in (f"taylorball.{mod_path}", f"taylorball._{mod_path}"):
            try:
                obj = importlib.import_module(cand)
            except ImportError as exc:
                errors.append(f"{cand}: {exc}")
                continue
            try:
                for attr in parts[k:]:
                    obj = getattr(obj, attr)
            except AttributeError as exc:
                errors.append(f"{cand}: {exc}")
                continue
            return obj
    raise LookupError("; ".join(errors) or f"{dotted!r} is not of the form module.name")


def test_code_names_resolve():
    bad = []
    for where, row in ROWS:
        for name in _names(row["code"]):
            try:
                resolve(name)
            except LookupError as exc:
                bad.append(f"{where}: code `{name}` does not resolve ({exc})")
    assert not bad, "\n".join(bad)


def test_checks_are_run_by_taylorball_verify():
    from taylorball.verify import CHECK_MODULES

    bad = []
    for where, row in ROWS:
        for name in _names(row["check"]):
            topic, _, fn = name.partition(".")
            if topic not in CHECK_MODULES or not fn:
                bad.append(f"{where}: check `{name}` is not topic.check_name with a topic of {CHECK_MODULES}")
                continue
            mod = importlib.import_module(f"taylorball.verify.{topic}")
            if fn not in {c.__name__ for c in getattr(mod, "CHECKS", ())}:
                bad.append(f"{where}: check `{name}`: no function {fn} in taylorball.verify.{topic}.CHECKS")
    assert not bad, "\n".join(bad)


def test_tests_exist():
    bad, defs = [], {}
    for where, row in ROWS:
        for name in _names(row["test"]):
            m = re.fullmatch(r"(tests/[\w/]+\.py)::(\w+)(\[[^\]]+\])?", name)
            if not m:
                bad.append(f"{where}: test `{name}` is not of the form tests/test_x.py::test_y")
                continue
            path = ROOT / m.group(1)
            if not path.is_file():
                bad.append(f"{where}: test `{name}`: no file {m.group(1)}")
                continue
            if path not in defs:
                defs[path] = set(re.findall(r"^\s*def (test_\w+)\(", path.read_text(encoding="utf-8"), re.M))
            if m.group(2) not in defs[path]:
                bad.append(f"{where}: test `{name}`: no def {m.group(2)} in {m.group(1)}")
    assert not bad, "\n".join(bad)


def test_errata_ids_exist():
    ids = set(re.findall(r"^## ([\w-]+)[.\s]", ERRATA.read_text(encoding="utf-8"), re.M))
    bad = []
    for where, row in ROWS:
        if row["erratum"] in ("", DASH):
            continue
        for eid in re.findall(r"\[([\w-]+)\]\(errata\.md\)", row["erratum"]):
            if eid not in ids:
                bad.append(f"{where}: erratum {eid} has no section '## {eid}.' in docs/errata.md")
        rest = re.sub(r"\[([\w-]+)\]\(errata\.md\)", "", row["erratum"]).strip(" ,")
        if rest:
            bad.append(f"{where}: erratum cell {row['erratum']!r}: write ids as [E1](errata.md), comma-separated")
    assert not bad, "\n".join(bad)
    cited = {e for _, row in ROWS for e in re.findall(r"\[([\w-]+)\]\(errata\.md\)", row["erratum"])}
    assert ids <= cited, f"errata not attached to any row of the index: {sorted(ids - cited)}"


# ---------------------------------------------------------------------------------------
# Against the paper's .tex.
# ---------------------------------------------------------------------------------------
def tex_numbers(tex: str):
    """``{label: [numbers of its environment]}`` and the environments' numbers in order,
    as iopart.cls numbers them: one number per ``equation``, one per row of an
    ``eqnarray`` (rows end at ``\\\\``; ``\\nonumber`` rows get none), none for the starred
    forms and ``$$``; a label takes the number of its own row (the first of the list for
    the label's row is recorded first)."""
    tex = re.sub(r"(?<!\\)%.*", "", tex)
    n, out = 0, {}
    for m in re.finditer(r"\\begin\{(equation|eqnarray|align|gather)(\*?)\}(.*?)\\end\{\1\2\}", tex, re.S):
        env, star, body = m.groups()
        if star:
            continue
        rows = [body] if env == "equation" else re.split(r"\\\\", body)
        nums, labels = [], []
        for row in rows:
            own = None
            if not re.search(r"\\(nonumber|notag)\b", row):
                n += 1
                own = n
                nums.append(n)
            labels += [(lab, own) for lab in re.findall(r"\\label\{([^}]+)\}", row)]
        for lab, own in labels:
            out[lab] = ([own] if own else []) + [k for k in nums if k != own]
    return out


def _printed(cell: str):
    """``(15)`` -> [15]; ``(3)–(5)`` -> [3, 4, 5]; anything else -> []."""
    nums = [int(x) for x in re.findall(r"\((\d+)\)", cell)]
    if len(nums) == 2 and re.search(r"\)\s*[–-]\s*\(", cell):
        return list(range(nums[0], nums[1] + 1))
    return nums


@pytest.fixture(scope="module")
def tex():
    if not TEX.is_file():
        pytest.skip(f"needs the paper's LaTeX source, not found at {TEX}: set TAYLORBALL_PAPER_TEX to the path "
                    "of chaplygin-ball-rotating-plane.tex")
    return TEX.read_text(encoding="utf-8")


def test_labels_exist_in_the_paper(tex):
    labels = set(re.findall(r"\\label\{([^}]+)\}", tex))
    bad = [f"{where}: label `{lab}` is not a \\label of {TEX.name}"
           for where, row in ROWS for lab in _names(row["label"]) if lab not in labels]
    assert not bad, "\n".join(bad)


def test_printed_numbers_are_latex_numbers(tex):
    numbers = tex_numbers(tex)
    bad = []
    for where, row in ROWS:
        labs = _names(row["label"])
        printed = _printed(row["printed"])
        if not labs:
            assert not printed, f"{where}: a printed number without a label"
            continue
        lab = labs[0]
        if lab not in numbers:
            bad.append(f"{where}: `{lab}` labels no numbered equation")
        elif not printed or not set(printed) <= set(numbers[lab]):
            bad.append(f"{where}: printed {row['printed']!r}, but `{lab}` numbers {numbers[lab]}")
    assert not bad, "\n".join(bad)


def test_every_numbered_equation_is_indexed(tex):
    numbers = tex_numbers(tex)
    indexed = {k for _, row in ROWS if _names(row["label"]) for k in _printed(row["printed"])}
    missing = sorted(set(range(1, max(k for v in numbers.values() for k in v) + 1)) - indexed)
    assert not missing, f"equations printed as {missing} have no row in docs/equations.md"
    unlabelled = set(numbers) - {lab for _, row in ROWS for lab in _names(row["label"])}
    assert not unlabelled, f"labels of the paper with no row: {sorted(unlabelled)}"


def test_label_table_matches_the_paper(tex):
    """The 'label -> printed' table at the top of the index."""
    numbers = tex_numbers(tex)
    seen, bad = label_numbers(), []
    assert seen, "no '| label | printed |' table in docs/equations.md"
    for lab, nums in numbers.items():
        if seen.get(lab) != sorted(nums):
            bad.append(f"`{lab}`: index says {seen.get(lab)}, the .tex gives {sorted(nums)}")
    assert not bad, "\n".join(bad)


def test_tex_numbering_rules():
    """The counting itself, on a small document: equation 1 number, eqnarray 1 per row, a
    label takes its row's number, starred forms and \\nonumber rows none."""
    doc = r"""
    \begin{equation}\label{a} x \\ y \end{equation}
    \begin{equation*} z \end{equation*}
    % \begin{equation}\label{commented} \end{equation}
    \begin{eqnarray}\label{b} p \\ q \nonumber \\ r \label{c} \end{eqnarray}
    $$ w $$
    \begin{eqnarray*} s \\ t \end{eqnarray*}
    \begin{equation}\label{d} u \end{equation}
    """
    assert tex_numbers(doc) == {"a": [1], "b": [2, 3], "c": [3, 2], "d": [4]}
    assert _printed("(3)–(5)") == [3, 4, 5] and _printed("(15)") == [15] and _printed("—") == []


# ---------------------------------------------------------------------------------------
# One citation form in the code and the docs.
# ---------------------------------------------------------------------------------------
#: Files whose comments, docstrings and strings (.py) or text (.md) must cite the paper's
#: equations in the form of docs/equations.md ("Citation form"): ``paper eq. (15) [eq10]``,
#: ``paper eqs. (15)-(16) [eq10]``, lists as ``eqs. (8)-(10) [eq6], (15) [eq10]``.
CITING = [*sorted((ROOT / "taylorball").rglob("*.py")), *sorted((ROOT / "tests").glob("*.py")),
          *sorted((ROOT / "benchmarks").glob("*.py")), *sorted((ROOT / "docs").glob("*.md")),
          ROOT / "README.md"]

#: Quote the old forms on purpose: the index explains them, this file tests the checker.
QUOTES_OLD_FORMS = {"docs/equations.md", "tests/test_equations_index.py"}

#: Files whose citations are exempt from the form (none: every file is normalised).
NOT_YET_NORMALISED: set = set()

_LABEL = r"(?:eq\d+|sved|Mpn2?)"
_ITEM = r"\((\d+)\)(?:-\((\d+)\))?\s+\[(" + _LABEL + r")\]"  # "(15) [eq10]", "(15)-(16) [eq10]"
_SEP = r"(?:,\s+|\s+/\s+|\s+and\s+|\s+or\s+)"
_ITEMS = re.compile(_ITEM + r"(?:" + _SEP + _ITEM + r")*")
_ORPHAN = re.compile(_SEP + r"\(\d+\)(?!\s+\[)")  # "eqs. (8) [eq6] / (10)": a number without label
_EQ = re.compile(r"\b([Ee]qs?)\b\.?\s+")
_LABEL_IN_PARENS = re.compile(r"\((" + _LABEL + r")\)")
_BARE_LABEL = re.compile(r"(?<![\[\w{`(])(" + _LABEL + r")\b(?!\])")  # not \label{eq10}, check_eq11


def label_numbers():
    """``{label: [printed numbers]}`` from the index's label table."""
    lines = INDEX.read_text(encoding="utf-8").splitlines()
    out = {}
    for i, line in enumerate(lines):
        if line.startswith("| label | printed"):
            for row in lines[i + 2:]:
                if not row.startswith("|"):
                    break
                lab_cell, printed = _cells(row)[:2]
                out[_names(lab_cell)[0]] = _printed(printed)
    return out


def citation_errors(text: str, numbers) -> list:
    """``(offset, message)`` for each bad paper citation in ``text``; ``numbers`` maps a
    label to its printed numbers (:func:`label_numbers`)."""
    bad = []

    def quote(i, j):
        return repr(" ".join(text[i:j].split()))

    for m in _EQ.finditer(text):
        items = _ITEMS.match(text, m.end())
        if not items:
            msg = "cite the printed number and the label, `paper eq. (15) [eq10]`"
            bad.append((m.start(), f"{quote(m.start(), m.end() + 12)}: {msg}"))
            continue
        if _ORPHAN.match(text, items.end()):
            msg = "every number of a list needs its label"
            bad.append((m.start(), f"{quote(m.start(), items.end() + 8)}: {msg}"))
        found = re.findall(_ITEM, items.group(0))
        if m.group(1).lower() == "eq" and (len(found) > 1 or found[0][1]):
            bad.append((m.start(), f"{quote(m.start(), items.end())}: several equations are `eqs.`"))
        for first, last, lab in found:
            nums = [int(first)] + ([int(last)] if last else [])
            if not set(nums) <= set(numbers.get(lab, [])):
                msg = f"[{lab}] is printed as {numbers.get(lab)}, not {nums}"
                bad.append((m.start(), f"{quote(m.start(), items.end())}: {msg}"))
    for m in _LABEL_IN_PARENS.finditer(text):
        msg = f"a label in parentheses reads as a printed number; write `paper eq. (N) [{m.group(1)}]`"
        bad.append((m.start(), f"'({m.group(1)})': {msg}"))
    for m in _BARE_LABEL.finditer(text):
        msg = f"label {m.group(1)} outside a citation `eq. (N) [label]`"
        bad.append((m.start(), f"{quote(max(0, m.start() - 12), m.end())}: {msg}"))
    return bad


def _prose(path: Path):
    """``(line, text)`` of the comments and string literals of a .py file, or the whole text
    of a .md (a citation may wrap)."""
    import io
    import tokenize

    src = path.read_text(encoding="utf-8")
    if path.suffix != ".py":
        return [(1, src)]
    kinds = {tokenize.COMMENT, tokenize.STRING, getattr(tokenize, "FSTRING_MIDDLE", tokenize.STRING)}
    return [(t.start[0], t.string) for t in tokenize.generate_tokens(io.StringIO(src).readline)
            if t.type in kinds]


def test_citations_use_one_form():
    numbers = label_numbers()
    assert numbers, "no label table in docs/equations.md"
    bad = []
    for path in CITING:
        rel = path.relative_to(ROOT).as_posix()
        if rel in QUOTES_OLD_FORMS or rel in NOT_YET_NORMALISED or not path.is_file():
            continue
        for line, text in _prose(path):
            bad += [f"{rel}:{line + text[:i].count(chr(10))}: {msg}"
                    for i, msg in citation_errors(text, numbers)]
    assert not bad, "citations not in the form of docs/equations.md (\"Citation form\"):\n" + "\n".join(bad)


def test_not_yet_normalised_files_exist():
    """The allow-list names real files (a renamed file would silently leave the check)."""
    missing = sorted(f for f in NOT_YET_NORMALISED if not (ROOT / f).is_file())
    assert not missing, f"NOT_YET_NORMALISED names files that do not exist: {missing}"


@pytest.mark.parametrize("text, wrong", [
    ("paper eq. (15) [eq10]", False), ("paper eqs. (15)-(16) [eq10]", False),
    ("paper eq. (16) [eq10]", False), ("eqs. (8)-(10) [eq6], (11) [eq13]", False),
    ("eqs. (8) [eq6] / (15) [eq10]", False), ("paper sec. 4, section chart", False),
    ("check_mpn2_from_eq10 and test_psi_rotates_F1_F2_as_eq_11", False), (r"\label{eq10}", False),
    ("paper eqs. (15)-(16)\n    [eq10]", False),
    ("eq. 10", True), ("eq. (10)", True), ("Eq. (sved)", True), ("the system (Mpn2)", True),
    ("(eq. 13)", True), ("eq 6", True), ("eqs. 6, 10", True), ("eq. (10) [eq10]", True),
    ("eq. (15)-(16) [eq10]", True), ("sec. 5 eq. Mpn", True), ("along Mpn2 here", True),
    ("eqs. (15)-(16) [eq10] / (10)", True),
])
def test_citation_checker(text, wrong):
    """The checker of :func:`test_citations_use_one_form` accepts the form and catches the old ones."""
    numbers = {"eq6": [8, 9, 10], "eq10": [15, 16], "eq13": [11], "sved": [19, 20, 21], "Mpn2": [22],
               "Mpn": [18]}
    assert bool(citation_errors(text, numbers)) == wrong, citation_errors(text, numbers)
