"""A compiled heyoka function (``cfunc``) evaluated on the columns of an array: compiled
once per key through the package's cache (:func:`taylorball._cache.compiled`), called
under its own lock (a cfunc holds scratch buffers: one call at a time).

Every cfunc the long-run path evaluates on many states at once goes through here: the
first integrals, scales and densities (:func:`taylorball._integrals.integrals_cfunc`), the
jets of ``|R|^2`` and ``(omega, gamma)`` (:func:`taylorball._orbit_reductions._jets`) and
of the lifted angle's ``x1, x2`` (:func:`taylorball._angle_lift.cut_jets`). States come as
rows ``(n, n_vars)`` and are handed to the cfunc as the columns of a contiguous
``(n_vars, n)`` array with the parameter vector repeated per column: heyoka's batch mode
over the ``n`` points, one call.
"""

from __future__ import annotations

import threading
from typing import Any, Callable, Dict, Hashable, Optional, Sequence, Tuple, Union

import numpy as np

from ._cache import compiled

__all__ = ["CfuncColumns", "cfunc_columns", "along_flow"]

#: What a graph builder returns: the outputs (a list, or a dict whose keys name them, in
#: order) and the variables, in the order of the rows' columns.
Graph = Tuple[Union[Sequence[Any], Dict[str, Any]], Sequence[Any]]


class CfuncColumns:
    """A compiled cfunc with its lock; calling it evaluates the cfunc on states as rows.

    Attributes
    ----------
    cf : heyoka cfunc
    names : tuple of str or None
        The outputs' names when the graph gave them as a dict, else None.
    """

    __slots__ = ("cf", "names", "nparams", "_lock")

    def __init__(self, cf: Any, names: Optional[Tuple[str, ...]] = None) -> None:
        self.cf = cf
        self.names = names
        self.nparams = int(cf.nparams)
        self._lock = threading.Lock()

    def __call__(self, rows: np.ndarray, pars: np.ndarray) -> np.ndarray:
        """The outputs ``(n_out, n)`` at the ``n`` states ``rows`` (``(n, n_vars)``, of the
        cfunc's number type) with the parameter vector ``pars`` (of that type; entries past
        the cfunc's ``nparams`` are dropped)."""
        X = np.ascontiguousarray(rows.T)
        p = pars.reshape(-1)[: self.nparams]
        P = np.ascontiguousarray(np.repeat(p[:, None], X.shape[1], axis=1))
        with self._lock:  # a cfunc holds scratch buffers: one call at a time
            return self.cf(X, pars=P)


def cfunc_columns(key: Tuple[Hashable, ...], graph: Callable[[], Graph], **options: Any) -> CfuncColumns:
    """The cached :class:`CfuncColumns` of ``key`` (a :func:`taylorball._cache.compiled`
    key naming everything the compiled code depends on), compiled on first use as
    ``hy.cfunc(outputs, variables, **options)`` of ``graph() -> (outputs, variables)``."""

    def build() -> CfuncColumns:
        import heyoka as hy

        outs, xs = graph()
        names = tuple(outs) if isinstance(outs, dict) else None
        exprs = list(outs.values()) if isinstance(outs, dict) else list(outs)
        return CfuncColumns(hy.cfunc(exprs, list(xs), **options), names)

    return compiled(key, build)


def along_flow(xs: Sequence[Any], rhs: Sequence[Any]) -> Callable[[Any], Any]:
    """``d/dt`` along the vector field ``rhs`` of the variables ``xs`` (heyoka expressions):
    ``e -> sum_i (de/dx_i) rhs_i``, by heyoka's symbolic differentiation."""
    import heyoka as hy

    def ddt(e: Any) -> Any:
        return hy.sum([hy.diff(e, x) * f for x, f in zip(xs, rhs)])

    return ddt
