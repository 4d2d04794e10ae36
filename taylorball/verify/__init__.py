"""``taylorball verify``: every checkable claim of the paper as an executable check.

Each topic module of this package (:data:`CHECK_MODULES`) defines ``CHECKS``, a list of
functions ``check(full: bool) -> CheckResult | list[CheckResult]``. A check computes its
residual independently of the code it checks (sympy identities, mpmath at high precision,
heyoka in quadruple precision, ...). :func:`run_checks` runs them all;
:func:`format_table` renders the table of claim, paper reference, verdict and residual
(100 columns, claims wrapped), :func:`records` the same as JSON-ready dicts and
:func:`format_markdown` as a markdown table. The command line is ``taylorball verify``
(:mod:`taylorball.cli`), which calls :func:`run_verify`.

Verdicts:

* ``"verified"`` -- the paper's claim holds to the stated tolerance;
* ``"erratum corrected"`` -- the printed formula fails, a corrected one (documented in
  ``docs/errata.md``) holds and is the one taylorball uses;
* ``"failed"`` -- neither holds (or the check raised): a defect to investigate. The
  command exits with status 1.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import json
import logging
import math
import re
import sys
import textwrap
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Dict, Iterable, List, Optional, Tuple

from .invariant_measures import liouville, liouville_residual

__all__ = ["CheckResult", "CHECK_MODULES", "VERDICTS", "collect", "run_checks", "format_table", "records",
           "format_markdown", "run_verify", "liouville", "liouville_residual"]

#: Topic modules of this package, each with a ``CHECKS`` list.
CHECK_MODULES = ("formulas", "closed_forms", "measures", "charts", "sections", "chaos")

VERDICTS = ("verified", "erratum corrected", "failed")

#: Width of :func:`format_table`'s lines (claims and paper references are wrapped to fit).
TABLE_WIDTH = 100

_log = logging.getLogger("taylorball.verify")


@dataclass(frozen=True)
class CheckResult:
    """Outcome of one check.

    Attributes
    ----------
    claim : str
        What the paper claims, in a few words.
    reference : str
        Where: equation or section of the paper (e.g. ``"eq. (17) [eq11]"``, ``"sec. 5 item 3"``; the
        form of docs/equations.md, "Citation form", without the word "paper").
    verdict : str
        One of :data:`VERDICTS`.
    residual : float
        The measured residual (NaN when not applicable): of the paper's claim for
        ``"verified"``, of the corrected formula (the one taylorball uses) for
        ``"erratum corrected"``, whose ``detail`` gives how far the printed one is off.
    tolerance : float
        The bound the residual was held to (NaN when not applicable).
    detail : str
        How it was measured, and for an erratum its id in ``docs/errata.md``.
    topic, name : str
        The topic module (one of :data:`CHECK_MODULES`) and the check function that
        produced the result; filled in by :func:`run_checks`.
    """

    claim: str
    reference: str
    verdict: str
    residual: float = math.nan
    tolerance: float = math.nan
    detail: str = ""
    topic: str = ""
    name: str = ""

    def __post_init__(self):
        if self.verdict not in VERDICTS:
            raise ValueError(f"verdict must be one of {VERDICTS}, got {self.verdict!r}")

    @property
    def ok(self) -> bool:
        return self.verdict != "failed"


def _checks_by_topic(modules: Iterable[str]) -> List[Tuple[str, Callable]]:
    out: List[Tuple[str, Callable]] = []
    for name in modules:
        mod = importlib.import_module(f"{__name__}.{name}")
        out.extend((name, check) for check in getattr(mod, "CHECKS", ()))
    return out


def collect(modules: Iterable[str] = CHECK_MODULES) -> List[Callable]:
    """All check functions of the given topic modules, in order."""
    return [check for _, check in _checks_by_topic(modules)]


def run_checks(full: bool = False, modules: Iterable[str] = CHECK_MODULES, log: Optional[Callable] = None):
    """Run the checks; an exception in a check becomes a ``"failed"`` result.

    ``log``, if given, receives one progress line per check function: its topic and name,
    the verdicts and the wall time (not the claims: those are in the table)."""
    results: List[CheckResult] = []
    for topic, check in _checks_by_topic(modules):
        name = getattr(check, "__name__", "check")
        t0 = time.perf_counter()
        try:
            out = check(full)
            out = [out] if isinstance(out, CheckResult) else list(out)
        except Exception as exc:  # a crashing check is a failed check, reported, not hidden
            tb_last = traceback.format_exception(exc)[-1].strip()
            out = [CheckResult(claim=check.__doc__.strip().splitlines()[0] if check.__doc__ else name,
                               reference="-", verdict="failed", detail=f"raised {tb_last}")]
        out = [dataclasses.replace(r, topic=r.topic or topic, name=r.name or name) for r in out]
        if log is not None:
            counts = ", ".join(f"{sum(r.verdict == v for r in out)} {v}" for v in VERDICTS
                               if any(r.verdict == v for r in out))
            log(f"[{time.perf_counter() - t0:6.1f} s] {topic}.{name}: {counts}")
        results.extend(out)
    return results


def _fmt(x: float) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.2e}"


def _summary(results: List[CheckResult]) -> str:
    n_fail = sum(not r.ok for r in results)
    n_err = sum(r.verdict == "erratum corrected" for r in results)
    return (f"{len(results)} checks: {len(results) - n_fail - n_err} verified, {n_err} errata corrected, "
            f"{n_fail} failed")


_PAPER_MAX = 14  # paper references longer than this wrap inside their column


def _wrap(text: str, width: int) -> List[str]:
    """``text`` in lines of at most ``width``; continuation lines indented by two spaces."""
    return textwrap.wrap(text, width, subsequent_indent="  ", break_on_hyphens=False) or [""]


_CITATION = re.compile(r"\(\d+\)(?:-\(\d+\))? \[\w+\]")  # "(15) [eq10]": printed number, label
_NBSP = "\u00a0"  # textwrap breaks only at ASCII whitespace


def _wrap_reference(text: str, width: int) -> List[str]:
    """:func:`_wrap` for a paper reference: a printed number stays on one line with its label
    ("(15) [eq10]", docs/equations.md, "Citation form") where the pair, a comma after it
    and the continuation indent fit in ``width``."""
    def glue(m):
        return m.group(0).replace(" ", _NBSP) if len(m.group(0)) + 3 <= width else m.group(0)

    glued = _CITATION.sub(glue, text)
    return [line.replace(_NBSP, " ") for line in _wrap(glued, width)]


def format_table(results: List[CheckResult], width: int = TABLE_WIDTH, details: bool = False) -> str:
    """A plain-text table: claim, paper reference, verdict, residual, tolerance.

    One row per result, grouped under a ``[topic]`` line when the results carry their
    topic; the claim (and a long paper reference) wraps so that every line fits in
    ``width`` columns, continuation lines indented. With ``details``, how each residual
    was measured follows its row, indented further. The last line counts the verdicts."""
    head = ("claim", "paper", "verdict", "residual", "tolerance")
    cells = [(r.claim, r.reference, r.verdict, _fmt(r.residual), _fmt(r.tolerance)) for r in results]
    fixed = [min(_PAPER_MAX, max(len(c[1]) for c in [head, *cells]))]
    fixed += [max(len(c[i]) for c in [head, *cells]) for i in (2, 3, 4)]
    claim_w = max(20, width - sum(fixed) - 2 * len(fixed))
    w = [claim_w, *fixed]

    def line(row) -> str:
        return "  ".join(c.ljust(w[i]) for i, c in enumerate(row)).rstrip()

    lines = [line(head), line(["-" * n for n in w])]
    topic = None
    for r, c in zip(results, cells):
        if r.topic and r.topic != topic:
            topic = r.topic
            lines.append(f"[{topic}]")
        claim, paper = _wrap(c[0], claim_w), _wrap_reference(c[1], fixed[0])
        for k in range(max(len(claim), len(paper))):
            first = k == 0
            lines.append(line([claim[k] if k < len(claim) else "", paper[k] if k < len(paper) else "",
                               c[2] if first else "", c[3] if first else "", c[4] if first else ""]))
        if details and r.detail:
            lines += textwrap.wrap(r.detail, width, initial_indent="    ", subsequent_indent="    ") or []
    lines.append(_summary(results))
    return "\n".join(lines)


def _finite_or_none(x) -> Optional[float]:
    return float(x) if x is not None and math.isfinite(x) else None


def records(results: List[CheckResult]) -> List[Dict[str, object]]:
    """The results as JSON-ready dicts: ``topic``, ``name`` (the check function),
    ``claim``, ``reference`` (where in the paper), ``verdict``, ``residual``,
    ``tolerance`` (``None`` when not applicable or not finite) and ``detail``."""
    return [{"topic": r.topic, "name": r.name, "claim": r.claim, "reference": r.reference,
             "verdict": r.verdict, "residual": _finite_or_none(r.residual),
             "tolerance": _finite_or_none(r.tolerance), "detail": r.detail} for r in results]


def format_markdown(results: List[CheckResult]) -> str:
    """The results as a markdown table (topic, claim, paper, verdict, residual, tolerance)."""

    def cell(text: str) -> str:
        return text.replace("|", "\\|").replace("\n", " ")

    lines = ["| topic | claim | paper | verdict | residual | tolerance |", "|---|---|---|---|---:|---:|"]
    lines += [f"| {cell(r.topic)} | {cell(r.claim)} | {cell(r.reference)} | {r.verdict} | "
              f"{_fmt(r.residual)} | {_fmt(r.tolerance)} |" for r in results]
    lines += ["", _summary(results) + "."]
    return "\n".join(lines)


def run_verify(full: bool = False, modules: Iterable[str] = CHECK_MODULES, *, details: bool = False,
               json_out: Optional[str] = None, markdown_out: Optional[str] = None) -> int:
    """What ``taylorball verify`` does: run the checks, print the table on stdout (or, with
    ``json_out="-"``, only the JSON list of :func:`records`), write ``json_out`` /
    ``markdown_out`` files atomically when they are paths. Progress goes to the
    ``taylorball.verify`` logger. Returns the exit status: 1 if a check failed, else 0.
    The paths are not checked here: the command line checks them before any work."""
    from ..io import atomic_write_bytes

    modules = tuple(modules)
    json_stdout = json_out == "-"
    heading = f"taylorball verify ({'full' if full else 'quick'}): {', '.join(modules)}"
    # with JSON on stdout, nothing else may reach stdout: a check's stray print goes to stderr
    with contextlib.redirect_stdout(sys.stderr) if json_stdout else contextlib.nullcontext():
        if json_stdout:
            _log.info(heading.removeprefix("taylorball "))
        else:
            print(heading, flush=True)
        results = run_checks(full, modules, log=_log.info)
    if json_stdout:
        json.dump(records(results), sys.stdout, indent=1, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print()
        print(format_table(results, details=details))
    if json_out and not json_stdout:
        text = json.dumps(records(results), indent=1, allow_nan=False) + "\n"
        atomic_write_bytes(Path(json_out), text.encode())
    if markdown_out:
        atomic_write_bytes(Path(markdown_out), (format_markdown(results) + "\n").encode())
    return 0 if all(r.ok for r in results) else 1
