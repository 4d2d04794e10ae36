"""The problem object: one system of the paper, its parameters, a number type, a
tolerance and a formulation, resolved and checked once at the public boundary.

The public functions take a string ``kind`` and keyword options (``tb.propagate("reduced",
ball, x, 100.0, fp_type=hy.real128)``, in heyoka's style); each turns them into a
:class:`Problem` with :func:`problem` before any work, and everything below takes the
problem. A problem is frozen and hashable. Its :attr:`Problem.compile_key` (everything
but the parameters, which are runtime ``hy.par[i]``) keys the compiled objects in
:mod:`taylorball._cache`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Optional, Tuple, Union

import numpy as np

from .errors import UsageError
from .model import System, get_system
from .numbers import FpSpec, resolve_fp_type
from .params import BallParams, MParallelParams

__all__ = ["Problem", "problem"]

Params = Union[BallParams, MParallelParams]


@dataclass(frozen=True)
class Problem:
    """A system x parameters x number type x tolerance x formulation.

    Build it with :func:`problem`, which checks every part.

    Attributes
    ----------
    system : System
        The system in its formulation (:func:`taylorball.model.get_system`).
    params : BallParams or MParallelParams
        The parameters, of the type the system takes (a ball's M||gamma parameters for
        ``"mparallel"``).
    spec : FpSpec
        The number type.
    tol : float or None
        The Taylor integrator's tolerance (``None``: the type's epsilon).
    """

    system: System
    params: Params
    spec: FpSpec
    tol: Optional[float] = None

    @property
    def kind(self) -> str:
        return self.system.kind

    @property
    def formulation(self) -> str:
        return self.system.formulation

    @property
    def pars(self) -> np.ndarray:
        """The runtime parameter vector in the working number type."""
        return self.spec.array(np.asarray(self.params.pars, dtype=np.float64))

    @property
    def compile_key(self) -> Tuple:
        """What compiled code depends on: everything but the parameters."""
        return (self.system.kind, self.system.formulation, str(self.spec), self.tol)

    def replace(self, **changes) -> "Problem":
        """A copy with some fields changed (e.g. ``spec=`` for a higher-precision rerun)."""
        return replace(self, **changes)

    def __str__(self):
        tol = "eps" if self.tol is None else f"{self.tol:g}"
        return f"{self.kind}/{self.formulation} {self.spec} tol={tol} {self.params}"


def _check_tol(tol) -> Optional[float]:
    if tol is None:
        return None
    try:
        t = float(tol)
    except (TypeError, ValueError):
        raise UsageError(f"tol must be a finite number > 0 (the Taylor integrator's relative and "
                         f"absolute tolerance), or None for the type's epsilon; got {tol!r}") from None
    if not (math.isfinite(t) and t > 0):
        raise UsageError(f"tol must be a finite number > 0 (the Taylor integrator's relative and "
                         f"absolute tolerance), or None for the type's epsilon; got {tol!r}")
    return t


def problem(kind: Union[str, Problem], params=None, *, fp_type=float, prec: Optional[int] = None, tol=None,
            formulation: Optional[str] = None) -> Problem:
    """A checked :class:`Problem`.

    Parameters
    ----------
    kind : {"full", "reduced", "mparallel"} or Problem
        Eq. (6) on SO(3) x R^5, eq. (10), or (Mpn2) of section 5. A :class:`Problem` is
        returned as it is (then no other argument may be given).
    params : BallParams or MParallelParams
        ``BallParams`` for every kind (converted to its M||gamma parameters for
        ``"mparallel"``); ``MParallelParams`` for ``"mparallel"`` only.
    fp_type, prec
        Number type (see :func:`taylorball.numbers.resolve_fp_type`).
    tol : float, optional
        Tolerance of the Taylor integrator (default: epsilon of ``fp_type``).
    formulation : str, optional
        Internal formulation (see :mod:`taylorball.model`).

    Raises
    ------
    UsageError
        Unknown kind, formulation or number type; a bad tolerance.
    ParameterError
        Parameters that do not fit ``kind``.
    """
    if isinstance(kind, Problem):
        if params is not None or fp_type is not float or prec is not None or tol is not None or formulation:
            raise UsageError("a Problem already fixes params, fp_type, prec, tol and formulation; pass none of them")
        return kind
    system = get_system(kind, formulation)
    return Problem(system, system.check_params(params), resolve_fp_type(fp_type, prec), _check_tol(tol))
