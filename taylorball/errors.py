"""Exception hierarchy of taylorball: what each error means and what a caller should do.

Every error raised on purpose by the package derives from :class:`TaylorballError`,
and also from the builtin it refines (``ValueError`` for bad input, ``RuntimeError``
for a computation that could not finish), so ``except ValueError`` keeps working.
Messages name the argument, the bad value, the valid form and, where there is one,
a likely fix. Bad input is refused at the public boundary, before any work (no
integration starts, no pool, no file is written); anything else escaping the package
(a foreign ``TypeError``, a heyoka ``ValueError``) is a bug of taylorball.

::

    TaylorballError                  catch-all for the package's own errors
    |-- UsageError (ValueError)      an option or size the call cannot take
    |-- ParameterError (ValueError)  parameters that describe no admissible system
    |-- StateError (ValueError)      a state of the wrong shape, type or content
    |   `-- ConstraintError          a state off the constraint manifold
    |-- ChartError (ValueError)      a point outside a chart's domain / at a singularity
    |   `-- EmptyLevelError          an integral level set (or section) with no point
    |-- IntegrationError (RuntimeError)  the integrator stopped before the requested time
    `-- StoreError (RuntimeError)    a long-run store that is corrupt, foreign or locked

* :class:`UsageError` -- the call itself is wrong: an unknown kind, formulation, number
  type, mode or backend; a non-finite or out-of-range time, step, tolerance, count or
  number of threads; sizes whose work or memory would not be proportionate (a chunk of
  1e-9 time units, 1e9 samples per checkpoint: the message gives the limit and how to
  split the work); a folder that is a file, a run that does not exist, a job that cannot
  be sent to a worker process. *Fix the call*; retrying the same call fails the same way.
* :class:`ParameterError` -- ``BallParams`` / ``MParallelParams`` (or the parameters
  handed to a system) are not those of any admissible system: non-positive or
  non-finite moments, mass or radius, a violated triangle inequality, ``m a^2`` out of
  the float64 range. *Fix the parameters* (or rescale units). Merely unphysical but
  well-posed parameters only warn (:class:`~taylorball.params.UnphysicalParametersWarning`).
* :class:`StateError` -- a state of the wrong length, dtype or with non-finite entries.
  *Fix the state*. Its subclass :class:`ConstraintError`: the state is off the
  constraint manifold (``|gamma| != 1``, ``(R, gamma) != 0``, ``Q`` not in SO(3)) by more
  than ``constraint_tol``: *fix the state, or pass* ``project=True``.
* :class:`ChartError` -- chart coordinates outside the chart's domain or at a singular
  point (``gamma3 = 0``, ``|L/G| > 1``, ``M || gamma``). *Choose another point, chart or
  section angle.* Its subclass :class:`EmptyLevelError`: the requested level set (or its
  intersection with the section) has no point; a valid, informative answer about the
  levels, *not* a failure of the computation: choose other levels.
* :class:`IntegrationError` -- the Taylor integrator stopped early (a non-finite state:
  a singular configuration, an escape to infinity). The input was valid; the orbit is
  not integrable there. *Inspect the orbit* (a shorter ``t``, another formulation or
  number type); what was computed before is kept where the API says so (long runs,
  sections).

``KeyboardInterrupt`` is re-raised as itself by the runners (:mod:`taylorball.ensemble`)
once the workers have stopped; long runs can then be resumed.
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
    "StoreError",
]


class TaylorballError(Exception):
    """Base class of every error raised on purpose by taylorball."""


class ParameterError(TaylorballError, ValueError):
    """Physical or numerical parameters that describe no admissible system."""


class StateError(TaylorballError, ValueError):
    """A state of the wrong shape, type or content for the requested system."""


class ConstraintError(StateError):
    """A state that is off the constraint manifold (``|gamma| = 1``, ``(R, gamma) = 0``, ...)."""


class ChartError(TaylorballError, ValueError):
    """A point outside a chart's domain, or at one of its singular points."""


class EmptyLevelError(ChartError):
    """An integral level set (or section of it) that contains no point."""


class IntegrationError(TaylorballError, RuntimeError):
    """The Taylor integrator stopped before reaching the requested time."""


class UsageError(TaylorballError, ValueError):
    """A call the package cannot take: an unknown option (system kind, formulation,
    number type, chart branch, mode), an out-of-range or non-finite time, step, tolerance
    or count, sizes whose work or memory would be out of proportion, a bad path or an
    unpicklable job."""


class StoreError(TaylorballError, RuntimeError):
    """A long-run store (:mod:`taylorball.store`) that cannot be used as it is: a piece
    that is corrupt or belongs to another run (named: orbit, array, chunk), or an orbit
    locked by another live process (named: host and pid). Found at start, before any work.
    *Fix or remove the named piece* (``taylorball run --restart`` starts the store afresh),
    or wait for the other process."""
