"""``taylorball verify``: every checkable claim of the paper as an executable check.

Each topic module of this package (:data:`CHECK_MODULES`) defines ``CHECKS``, a list of
functions ``check(full: bool) -> CheckResult | list[CheckResult]``. A check computes its
residual independently of the code it checks (sympy identities, mpmath at high precision,
heyoka in quadruple precision, ...). :func:`run_checks` runs them all and
:func:`format_table` prints the table of claim, paper reference, verdict and residual.

Verdicts:

* ``"verified"`` -- the paper's claim holds to the stated tolerance;
* ``"erratum corrected"`` -- the printed formula fails, a corrected one (documented in
  ``docs/errata.md``) holds and is the one taylorball uses;
* ``"failed"`` -- neither holds (or the check raised): a defect to investigate. The
  command exits with status 1.
"""

from __future__ import annotations

import importlib
import math
import sys
import time
import traceback
from dataclasses import dataclass
from typing import Callable, Iterable, List, Optional

from .invariant_measures import liouville, liouville_residual

__all__ = ["CheckResult", "CHECK_MODULES", "VERDICTS", "collect", "run_checks", "format_table", "cli_main",
           "liouville", "liouville_residual"]

#: Topic modules of this package, each with a ``CHECKS`` list.
CHECK_MODULES = ("formulas", "closed_forms", "measures", "charts", "sections")

VERDICTS = ("verified", "erratum corrected", "failed")


@dataclass(frozen=True)
class CheckResult:
    """Outcome of one check.

    Attributes
    ----------
    claim : str
        What the paper claims, in a few words.
    reference : str
        Where: equation or section of the paper (e.g. ``"eq. 11"``, ``"sec. 5 item 3"``).
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
    """

    claim: str
    reference: str
    verdict: str
    residual: float = math.nan
    tolerance: float = math.nan
    detail: str = ""

    def __post_init__(self):
        if self.verdict not in VERDICTS:
            raise ValueError(f"verdict must be one of {VERDICTS}, got {self.verdict!r}")

    @property
    def ok(self) -> bool:
        return self.verdict != "failed"


def collect(modules: Iterable[str] = CHECK_MODULES) -> List[Callable]:
    """All check functions of the given topic modules, in order."""
    checks = []
    for name in modules:
        mod = importlib.import_module(f"{__name__}.{name}")
        checks.extend(getattr(mod, "CHECKS", ()))
    return checks


def run_checks(full: bool = False, modules: Iterable[str] = CHECK_MODULES, log: Optional[Callable] = None):
    """Run the checks; an exception in a check becomes a ``"failed"`` result."""
    results: List[CheckResult] = []
    for check in collect(modules):
        t0 = time.perf_counter()
        try:
            out = check(full)
            out = [out] if isinstance(out, CheckResult) else list(out)
        except Exception as exc:  # a crashing check is a failed check, reported, not hidden
            tb_last = traceback.format_exception(exc)[-1].strip()
            out = [CheckResult(claim=check.__doc__.strip().splitlines()[0] if check.__doc__ else check.__name__,
                               reference="-", verdict="failed", detail=f"raised {tb_last}")]
        if log is not None:
            for r in out:
                log(f"  [{time.perf_counter() - t0:6.1f} s] {r.verdict:<18} {r.claim}")
        results.extend(out)
    return results


def _fmt(x: float) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.2e}"


def format_table(results: List[CheckResult]) -> str:
    """A plain-text table: claim, reference, verdict, residual, tolerance."""
    rows = [("claim", "paper", "verdict", "residual", "tolerance")]
    rows += [(r.claim, r.reference, r.verdict, _fmt(r.residual), _fmt(r.tolerance)) for r in results]
    w = [max(len(row[i]) for row in rows) for i in range(5)]
    lines = ["  ".join(c.ljust(w[i]) for i, c in enumerate(row)) for row in rows]
    lines.insert(1, "  ".join("-" * n for n in w))
    n_fail = sum(not r.ok for r in results)
    n_err = sum(r.verdict == "erratum corrected" for r in results)
    lines.append(f"{len(results)} checks: {len(results) - n_fail - n_err} verified, {n_err} errata corrected, "
                 f"{n_fail} failed")
    return "\n".join(lines)


def cli_main(argv=None) -> int:
    """``taylorball verify [--full] [--only topic,...]``; exit status 1 if a check fails."""
    import argparse

    ap = argparse.ArgumentParser(prog="taylorball verify")
    ap.add_argument("--full", action="store_true")
    ap.add_argument("--only", default="", help=f"comma-separated topics from {CHECK_MODULES}")
    ap.add_argument("--details", action="store_true", help="print how each residual was measured")
    args = ap.parse_args(argv)
    modules = CHECK_MODULES
    if args.only:
        modules = tuple(m.strip() for m in args.only.split(",") if m.strip())
        bad = [m for m in modules if m not in CHECK_MODULES]
        if bad:
            print(f"--only: unknown topic(s) {bad}; valid: {CHECK_MODULES}", file=sys.stderr)
            return 2
    print(f"taylorball verify ({'full' if args.full else 'quick'}): {', '.join(modules)}")
    results = run_checks(args.full, modules, log=print)
    print()
    print(format_table(results))
    if args.details:
        for r in results:
            print(f"- {r.claim} [{r.reference}]: {r.detail}")
    return 0 if all(r.ok for r in results) else 1
