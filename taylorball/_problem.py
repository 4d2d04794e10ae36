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
from typing import Any, Optional, Tuple, Union

import numpy as np

from ._typing import FpTypeLike, KindName, ParamsLike
from .errors import UsageError
from .model import System, get_system
from .numbers import FpSpec, resolve_fp_type
from .params import BallParams, MParallelParams

__all__ = ["Problem", "problem", "at_boundary", "params_problem", "lane_problem"]


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
    params: ParamsLike
    spec: FpSpec
    tol: Optional[float] = None

    @property
    def kind(self) -> KindName:
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

    def replace(self, **changes: Any) -> "Problem":
        """A copy with some fields changed (e.g. ``spec=`` for a higher-precision rerun)."""
        return replace(self, **changes)

    def __str__(self) -> str:
        tol = "eps" if self.tol is None else f"{self.tol:g}"
        return f"{self.kind}/{self.formulation} {self.spec} tol={tol} {self.params}"

    def __repr__(self) -> str:  # the generated one printed the whole System with its functions
        return (f"Problem(kind={self.kind!r}, formulation={self.formulation!r}, fp_type={str(self.spec)!r}, "
                f"tol={self.tol!r}, params={self.params!r})")


#: The loosest tolerance accepted. heyoka chooses the Taylor order (``~ -ln(tol)/2 + 1``)
#: and the step (from the last Taylor coefficients) so that the local error of every step
#: stays below ``tol``, relative to the state for large components and absolute for small
#: ones; the global error then grows with time (linearly on regular orbits, exponentially
#: on chaotic ones). Measured on the demo orbit (``paper.demo_reduced_state``, Fig. 5 ball),
#: relative error after 100 time units against tol = eps: 1.4e-5 at tol = 1e-8, 2.5e-2 at
#: 1e-6, O(1) at 1e-4, 1e-2 and 10. Above 1e-6 the orbit is no longer the system's, and
#: nothing in this package (a machine-precision tool) uses more than 2e-13.
TOL_MAX = 1e-6


def _check_tol(tol: object, spec: FpSpec) -> Optional[float]:
    """``tol`` as a float in ``[eps of spec, TOL_MAX]``, or None (the type's epsilon)."""
    if tol is None:
        return None
    lo = spec.eps
    rng = f"[{lo:.3g} (the epsilon of {spec}), {TOL_MAX:g}]"
    what = ("tol is the Taylor integrator's local error bound per step (relative and absolute; heyoka "
            f"picks the order and the step from it; the global error grows with time): it must be a real number in {rng}, "
            "or None for the type's epsilon")
    if not isinstance(tol, (int, float, np.integer, np.floating)) or isinstance(tol, (bool, np.bool_)):
        raise UsageError(f"{what}; got tol={tol!r}")
    t = float(tol)
    if not (math.isfinite(t) and t > 0):
        raise UsageError(f"{what}; got tol={tol!r}")
    if t > TOL_MAX:
        raise UsageError(f"{what}; got tol={tol!r}, too loose: the orbit would not be the system's "
                         f"(O(1) errors after 100 time units at tol >= 1e-4)")
    if t < lo:
        raise UsageError(f"{what}; got tol={tol!r}, below the rounding of {spec}, which only raises the "
                         "Taylor order (and the compile time) without making the orbit more accurate; use a "
                         "wider number type (fp_type=) for more digits")
    return t


def problem(kind: Union[KindName, Problem], params: Optional[ParamsLike] = None, *, fp_type: FpTypeLike = float,
            prec: Optional[int] = None, tol: Optional[float] = None,
            formulation: Optional[str] = None) -> Problem:
    """A checked :class:`Problem`.

    Parameters
    ----------
    kind : {"full", "reduced", "mparallel"} or Problem
        Paper eqs. (8)-(10) [eq6] on SO(3) x R^5, eqs. (15)-(16) [eq10], or eq. (22) [Mpn2] of sec. 5. A :class:`Problem` is
        returned as it is (then no other argument may be given).
    params : BallParams or MParallelParams
        ``BallParams`` for every kind (converted to its M||gamma parameters for
        ``"mparallel"``); ``MParallelParams`` for ``"mparallel"`` only.
    fp_type, prec
        Number type (see :func:`taylorball.numbers.resolve_fp_type`).
    tol : float, optional
        Tolerance of the Taylor integrator (default: epsilon of ``fp_type``): heyoka's
        bound on the local error of each step, relative to the state for large components
        and absolute for small ones, from which it picks the Taylor order (``~ -ln(tol)/2``)
        and the step size. The global error grows with time (linearly on regular orbits,
        exponentially on chaotic ones), so ``tol`` is not the error of the result. Accepted:
        ``[eps of fp_type, 1e-6]`` (see :data:`TOL_MAX`).
    formulation : str, optional
        Internal formulation (see :mod:`taylorball.model`).

    Raises
    ------
    UsageError
        Unknown kind, formulation or number type; a bad tolerance.
    ParameterError
        Parameters that do not fit ``kind``.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL
    >>> prob = tb.problem("reduced", FIG4_BALL)
    >>> print(prob)
    reduced/momentum float tol=eps BallParams(inertia=(2.0, 3.0, 4.0), mass=1.0, radius=5.0, plane_rate=2.0)
    >>> prob.kind, prob.pars.tolist()          # the parameters are runtime values
    ('reduced', [2.0, 3.0, 4.0, 1.0, 5.0, 2.0])
    >>> tb.problem(prob) is prob
    True
    >>> prob == tb.problem("reduced", FIG4_BALL)   # frozen and hashable
    True
    >>> tb.problem("reduced", FIG4_BALL, tol=1e-3)
    Traceback (most recent call last):
    ...
    taylorball.errors.UsageError: tol is the Taylor integrator's local error bound ... got tol=0.001, ...
    """
    if isinstance(kind, Problem):
        _no_conflict("problem", kind, params=params, fp_type=fp_type, prec=prec, tol=tol, formulation=formulation)
        return kind
    system = get_system(kind, formulation)
    checked = system.check_params(params)
    spec = resolve_fp_type(fp_type, prec)
    return Problem(system, checked, spec, _check_tol(tol, spec))


# ---------------------------------------------------------------------------------------
# The boundary: one rule for every public function that takes a system
# ---------------------------------------------------------------------------------------
#: The defaults of the options a :class:`Problem` fixes: an option given with another value
#: next to a Problem is a conflict.
_FIXED_BY_PROBLEM = {"params": None, "fp_type": float, "prec": None, "tol": None, "formulation": None}


def _no_conflict(func: str, prob: Problem, **given: Any) -> None:
    """Raise :class:`UsageError` if any option that ``prob`` fixes was also given."""
    clash = [f"{k}={v!r}" for k, v in given.items()
             if k in _FIXED_BY_PROBLEM and v is not _FIXED_BY_PROBLEM[k] and v is not None and v != ""]
    if clash:
        raise UsageError(
            f"{func} got a Problem ({prob.kind}/{prob.formulation} {prob.spec} tol="
            f"{'eps' if prob.tol is None else format(prob.tol, 'g')}) and also {', '.join(clash)}: a Problem fixes "
            "the parameters, number type, tolerance and formulation; pass the Problem alone (change it with "
            "prob.replace(...) or build another with taylorball.problem(...)), or a kind string with its options")


def at_boundary(func: str, kind: Union[KindName, Problem], params: Any, rest: Tuple[Any, ...],
                names: Tuple[str, ...], **options: Any) -> Tuple[Problem, Tuple[Any, ...]]:
    """The problem and the positional arguments of a public function ``func(kind, params,
    *rest, ...)``, which also reads ``func(prob, *rest, ...)``.

    The one rule of the package: every public function that takes ``(kind, params, ...)``
    takes a :class:`Problem` in the place of ``kind``, with ``params`` left out, so the
    positional arguments after it move one place to the left (``propagate(prob, x, t)``
    is ``propagate("reduced", ball, x, t)``); given by keyword they stay where they are
    (``propagate(prob, state=x, t=t)``). The options a Problem fixes (``params``,
    ``fp_type``, ``prec``, ``tol``, ``formulation``, those of ``options``) must then not be
    given: a conflict raises :class:`UsageError` naming them. A string ``kind`` goes through
    :func:`problem` with ``options``, exactly as before.

    Parameters
    ----------
    func : str
        The public function's name, for messages.
    kind, params
        The first two arguments as given.
    rest : tuple
        The positional arguments after ``params`` as given (``None`` where left out: the
        public signatures give them the default ``None``).
    names : tuple of str
        Their names, for the message when one is missing.
    **options
        The keyword options of :func:`problem` the function takes (``fp_type``, ``prec``,
        ``tol``, ``formulation``).

    Returns
    -------
    (Problem, tuple)
        The problem and ``rest`` resolved (every entry given).
    """
    if isinstance(kind, Problem):
        if rest and params is not None and not isinstance(params, (BallParams, MParallelParams)):
            # func(prob, a, b) or func(prob, a, b=...): the positional arguments move one place
            shifted = [params, *rest[:-1]]
            if rest[-1] is not None:  # the last one given by keyword
                if shifted[-1] is not None:
                    raise UsageError(f"{func} got too many arguments: with a Problem the form is "
                                     f"{func}(problem, {', '.join(names)}, ...)")
                shifted[-1] = rest[-1]
            params, rest = None, tuple(shifted)
        _no_conflict(func, kind, params=params, **options)
        prob = kind
    else:
        prob = problem(kind, params, **options)
    missing = [n for n, v in zip(names, rest) if v is None]
    if missing:
        form = ", ".join(names)
        raise UsageError(f"{func} needs {', '.join(missing)}: call it as {func}(kind, params, {form}, ...) or "
                         f"{func}(problem, {form}, ...)")
    return prob, tuple(rest)


def params_problem(func: str, kind: KindName, params: Any, **options: Any) -> Problem:
    """The problem of a function of one system ``kind`` that takes ``params`` first
    (``contact_trajectory``, ``megno_map``, ``chaotic_fraction``): a :class:`Problem` of
    that system may stand in for ``params`` (then it fixes ``options`` too, see
    :func:`at_boundary`)."""
    if isinstance(params, Problem):
        if params.kind != kind:
            raise UsageError(f"{func} works on the {kind!r} system; got a Problem of the {params.kind!r} system "
                             f"(build one with taylorball.problem({kind!r}, params))")
        _no_conflict(func, params, **options)
        return params
    return problem(kind, params, **options)


def lane_problem(func: str, prob: Problem) -> Problem:
    """``prob`` if it runs in the SIMD lanes of float64 batch integrators (float64, the
    default tolerance); otherwise a :class:`UsageError` naming the one-orbit function."""
    if prob.spec.name != "float" or prob.tol is not None:
        raise UsageError(f"{func} runs float64 batch integrators at the default tolerance; got a Problem with "
                         f"fp_type={prob.spec}, tol={prob.tol!r}: use the one-orbit function for other number "
                         "types or tolerances, or prob.replace(spec=..., tol=None)")
    return prob
