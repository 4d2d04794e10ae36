"""Checks of the paper: closed forms (see :mod:`taylorball.verify`)."""

from __future__ import annotations

#: check functions f(full: bool) -> CheckResult | list[CheckResult]
CHECKS: list = []
