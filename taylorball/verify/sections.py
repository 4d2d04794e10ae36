"""Checks of the paper: the Poincaré map of section 4 preserves a volume form (see
:mod:`taylorball.verify`)."""

from __future__ import annotations

#: check functions ``f(full: bool) -> CheckResult | list[CheckResult]``
CHECKS: list = []
