"""Exception hierarchy of taylorball.

Every error raised on purpose by the package derives from :class:`TaylorballError`,
and also from the builtin it refines (``ValueError`` for bad input, ``RuntimeError``
for a computation that could not finish), so ``except ValueError`` keeps working.
Messages name the argument, the bad value, the valid form and, where there is one,
a likely fix.
"""

from __future__ import annotations

__all__ = [
    "TaylorballError",
    "ParameterError",
    "StateError",
    "ConstraintError",
    "ChartError",
    "EmptyLevelError",
    "IntegrationError",
    "UsageError",
]


class TaylorballError(Exception):
    """Base class of every error raised on purpose by taylorball."""


class ParameterError(TaylorballError, ValueError):
    """Physical or numerical parameters that describe no admissible system."""


class StateError(TaylorballError, ValueError):
    """A state of the wrong shape, type or content for the requested system."""


class ConstraintError(StateError):
    """A state that is off the constraint manifold (|gamma| = 1, (R, gamma) = 0, ...)."""


class ChartError(TaylorballError, ValueError):
    """A point outside a chart's domain, or at one of its singular points."""


class EmptyLevelError(ChartError):
    """An integral level set (or section of it) that contains no point."""


class IntegrationError(TaylorballError, RuntimeError):
    """The Taylor integrator stopped before reaching the requested time."""


class UsageError(TaylorballError, ValueError):
    """An unknown option: system kind, formulation, number type, chart branch, ..."""
