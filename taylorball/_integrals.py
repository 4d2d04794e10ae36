r"""First integrals, geometric integrals and invariant-measure densities.

Each quantity is written once (backend-neutral, see :mod:`taylorball._vec`) and is
available

* as plain numbers from a public state: :func:`integrals`, :func:`geometric_integrals`,
  :func:`density` (numpy, any dtype heyoka supports);
* in mpmath at any precision: :func:`integrals_mp`;
* as heyoka expressions of a system's internal variables, for compiled evaluation and for
  event functions: :func:`integral_expressions`.

The integrals (paper sections 2, 3 and 5)
-----------------------------------------
``full`` (paper eqs. (12) [eq7], (13) [eq8]):
    ``F1 = (M, alpha)``, ``F2 = (M, beta)``, ``F3 = (M, gamma)``,
    ``E = 1/2 (omega, Itilde omega) - m Omega^2 (x^2 + y^2) / 2``.
``reduced`` (section 3):
    ``C2 = (M, M)``, ``M_gamma = (M, gamma)``, ``E = 1/2 (omega, Itilde omega) -
    m Omega^2 (R, R) / 2``, and the geometric ``gamma2 = (gamma, gamma)``,
    ``R_gamma = (R, gamma)``.
``mparallel`` (section 5):
    ``gamma2``, ``lambda = (K, gamma)``,
    ``E = (K, A K)/2 - K^2/(2 d) + d (A K, gamma)^2 / (2 (1 - d (gamma, A gamma)))``.

The paper writes the reduced energy as ``(M, omega)/2 + m a Omega (omega, R)/2 -
m Omega^2 (R, R)/2``; since ``M + m a Omega R = Itilde omega`` that is the same function.
The ``mparallel`` energy equals the reduced ``E`` on ``M = lambda gamma`` minus the
constant ``lambda^2 / (2 d)`` (checked in ``tests/test_integrals.py``).

Densities (checked by ``div(rho f) = 0`` in ``tests/test_integrals.py``)
------------------------------------------------------------------------
With ``D(gamma) = 1 - d (gamma, A gamma)``:

* in the variables ``(M, ...)`` of the full and reduced systems and ``(K, gamma)`` of the
  M||gamma system: ``rho = |D|^{-1/2}``;
* in the paper's variables ``(omega, ...)``: ``rho = det(Itilde) |D|^{-1/2} =
  det(J) D^{1/2}``, the paper's formula of section 2 (the Jacobian of
  ``omega -> M`` is ``det Itilde = det(J) D``).

The absolute value matters only for unphysical parameters such as the paper's Fig. 1
(``D < 0`` everywhere), where the paper's ``D^{-1/2}`` is imaginary; any constant multiple
of a density is a density, so ``|D|^{-1/2}`` is the real one.
"""

from __future__ import annotations

from typing import Any, Callable, Dict, Literal, Optional, Union

import numpy as np
from numpy.typing import ArrayLike

from ._problem import Problem, at_boundary
from ._typing import FpTypeLike, KindName, ParamsLike, Scalar, VecLike
from .model import KIND_TABLE, BallConstants, MParallelConstants, System, get_system, public_system
from .model import _internal_density as internal_density

__all__ = [
    "INTEGRAL_NAMES",
    "GEOMETRIC_NAMES",
    "integrals",
    "integral_scales",
    "geometric_integrals",
    "integrals_mp",
    "integral_expressions",
    "density",
    "state_vectors",
]

#: Keys returned by :func:`integrals`, per system kind.
INTEGRAL_NAMES = {k: info.integral_names for k, info in KIND_TABLE.items()}

#: Keys returned by :func:`geometric_integrals` (``full``): the Gram matrix of
#: (alpha, beta, gamma), whose values are fixed at 1 (diagonal) and 0 (off-diagonal).
GEOMETRIC_NAMES = {k: info.geometric_names for k, info in KIND_TABLE.items()}


def state_vectors(system: System, c: BallConstants | MParallelConstants, internal: Any) -> Dict[str, Any]:
    """Named vectors of an internal state of ``system`` with constants ``c`` (see
    :meth:`taylorball.model.System.vectors`)."""
    return system.vectors(c, internal)


def _density(system, c, v, coords):
    """The invariant density w.r.t. the internal variables ``(M, ...)`` / ``(K, gamma)``
    (``coords="internal"``) or the paper's variables (``"public"``)."""
    return internal_density(c, v) if coords == "internal" else system.info.public_density(c, v)


# ---------------------------------------------------------------------------------------
# Public evaluators.
# ---------------------------------------------------------------------------------------
def _boundary(func, kind, params, state):
    """``(kind, params, state)`` of a public evaluator called with a kind and parameters,
    or with a :class:`Problem` in their place (see :func:`taylorball._problem.at_boundary`)."""
    if not isinstance(kind, Problem):  # as before: the evaluators check kind and params themselves
        if state is None:
            from .errors import UsageError

            raise UsageError(f"{func} needs a state: {func}(kind, params, state) or {func}(problem, state)")
        return kind, params, state
    prob, (state,) = at_boundary(func, kind, params, (state,), ("state",))
    return prob.kind, prob.params, state


def _prepare(kind, params, state, check):
    from .manifold import as_state, params_for

    params = params_for(kind, params)
    system = public_system(kind)
    x = as_state(kind, state, params=params, check=check)
    pars = _pars_like(params, x)
    c = system.constants(tuple(pars))
    cols = tuple(x[..., i] for i in range(x.shape[-1]))
    return system, c, system.vectors(c, cols)


def _pars_like(params, x):
    """The parameter vector in the number type of ``x``; for ``heyoka.real`` in the
    precision of ``x`` (``np.asarray(..., dtype=real)`` would give 53-bit reals, and the
    ``a_i = 1/(I_i + m a^2)`` formed from them would be only that accurate)."""
    import heyoka as hy

    if x.dtype == np.dtype(hy.real):
        from .numbers import resolve_fp_type

        prec = max(v.prec for v in x.reshape(-1))
        return resolve_fp_type(hy.real, prec).array(np.asarray(params.pars, dtype=float))
    return np.asarray(params.pars, dtype=x.dtype)


def _out(d):
    return {k: (v.item() if isinstance(v, np.ndarray) and v.ndim == 0 else v) for k, v in d.items()}


def integrals(kind: Union[KindName, Problem], params: Union[ParamsLike, ArrayLike, None] = None,
              state: Optional[ArrayLike] = None, *, check: bool = True) -> Dict[str, Any]:
    """Values of the first integrals at a state in the public layout.

    Parameters
    ----------
    kind : {"full", "reduced", "mparallel"} or Problem
        A system, or a :class:`taylorball.Problem` with ``params`` left out
        (``integrals(prob, state)``; so for :func:`integral_scales`,
        :func:`geometric_integrals`, :func:`density` and :func:`integrals_mp`).
    params : BallParams or MParallelParams
        ``MParallelParams`` only for ``"mparallel"`` (a ``BallParams`` is converted).
    state : array_like, shape (d,) or (n, d)
        Public layout of ``kind`` (see :data:`taylorball.model.PUBLIC_NAMES`); a stack of
        states gives arrays of values. Any dtype heyoka supports is kept.
    check : bool
        Reject states off the constraint manifold (default). ``False`` evaluates anyway.

    Returns
    -------
    dict
        full: ``F1, F2, F3, E``; reduced: ``C2, M_gamma, E, gamma2, R_gamma``;
        mparallel: ``gamma2, lambda, E``.

    Raises
    ------
    StateError, ConstraintError, ParameterError
        Bad shape, off the manifold, or parameters of the wrong kind.

    Examples
    --------
    >>> import numpy as np
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> x0 = demo_reduced_state()
    >>> d0 = tb.integrals("reduced", FIG4_BALL, x0)
    >>> {k: round(float(v), 6) for k, v in d0.items()}
    {'C2': 152.528693, 'M_gamma': 1.33923, 'E': -2.236138, 'gamma2': 1.0, 'R_gamma': 0.0}
    >>> d1 = tb.integrals("reduced", FIG4_BALL, tb.propagate("reduced", FIG4_BALL, x0, 10.0))
    >>> all(abs(d1[k] - d0[k]) < 1e-11 for k in d0)   # conserved (drift ~1e-12 at t = 10)
    True
    >>> tb.integrals("reduced", FIG4_BALL, np.stack([x0, x0]))["E"].shape   # a stack of states
    (2,)
    """
    kind, params, state = _boundary("integrals", kind, params, state)
    system, c, v = _prepare(kind, params, state, check)
    return _out(system.info.integrals(c, v))


def integral_scales(kind: Union[KindName, Problem], params: Union[ParamsLike, ArrayLike, None] = None,
                    state: Optional[ArrayLike] = None, *,
                    check: bool = True) -> Dict[str, Any]:
    """Natural magnitude of each integral of :func:`integrals` (same keys): a bound on the
    sum of magnitudes of its terms. Drift is judged relative to it.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> x0 = demo_reduced_state()
    >>> scales = tb.integral_scales("reduced", FIG4_BALL, x0)
    >>> list(scales) == list(tb.integrals("reduced", FIG4_BALL, x0))
    True
    >>> round(float(scales["E"]), 4)               # E = -2.236 is a sum of terms of this size
    2.9056
    >>> d0 = tb.integrals("reduced", FIG4_BALL, x0)
    >>> d1 = tb.integrals("reduced", FIG4_BALL, tb.propagate("reduced", FIG4_BALL, x0, 10.0))
    >>> bool(abs(d1["E"] - d0["E"]) / scales["E"] < 1e-12)   # relative drift
    True
    """
    kind, params, state = _boundary("integral_scales", kind, params, state)
    system, c, v = _prepare(kind, params, state, check)
    return _out(system.info.scales(c, v))


def geometric_integrals(kind: Union[KindName, Problem], params: Union[ParamsLike, ArrayLike, None] = None,
                        state: Optional[ArrayLike] = None) -> Dict[str, Any]:
    """The geometric integrals (Gram matrix of the frame for ``full``; ``gamma2``,
    ``R_gamma`` for ``reduced``; ``gamma2`` for ``mparallel``) at a public state,
    without checking them."""
    kind, params, state = _boundary("geometric_integrals", kind, params, state)
    system, c, v = _prepare(kind, params, state, False)
    return _out(system.info.geometric(v))


def density(kind: Union[KindName, Problem], params: Union[ParamsLike, ArrayLike, None] = None,
            state: Optional[ArrayLike] = None, *,
            coords: Literal["public", "internal"] = "public", check: bool = True) -> Scalar:
    """Invariant-measure density at a state in the public layout.

    Parameters
    ----------
    coords : {"public", "internal"}
        ``"public"``: w.r.t. the paper's variables (``d^3 omega ...``);
        ``"internal"``: w.r.t. ``(M, ...)`` (``(K, gamma)`` for mparallel).
    """
    if not isinstance(coords, str) or coords not in ("public", "internal"):
        from .errors import UsageError

        raise UsageError(f"coords must be 'public' or 'internal', got {coords!r}")
    kind, params, state = _boundary("density", kind, params, state)
    system, c, v = _prepare(kind, params, state, check)
    r = _density(system, c, v, coords)
    return r.item() if isinstance(r, np.ndarray) and r.ndim == 0 else r


def integrals_mp(kind: Union[KindName, Problem], params: Union[ParamsLike, VecLike, None] = None,
                 state: Optional[VecLike] = None, *, dps: int = 50) -> Dict[str, Any]:
    """The integrals of :func:`integrals`, evaluated in mpmath with ``dps`` digits.

    The state entries are converted exactly (``mpmath.mpf`` of each float), so this is an
    independent high-precision evaluation of the same formulas."""
    import mpmath

    from .manifold import params_for

    name, given, state = _boundary("integrals_mp", kind, params, state)
    ball = params_for(name, given)
    system = public_system(name)
    with mpmath.workdps(dps):
        pars = tuple(mpmath.mpf(p) for p in ball.pars)
        s = tuple(mpmath.mpf(str(x)) if not isinstance(x, float) else mpmath.mpf(x) for x in state)
        c = system.constants(pars)
        vals = system.info.integrals(c, system.vectors(c, s))
        return {k: +v for k, v in vals.items()}


def integral_expressions(kind: KindName, formulation: str | None = None, *,
                         which: Literal["integrals", "scales", "geometric", "density"] = "integrals",
                         ) -> Dict[str, Any]:
    """Heyoka expressions of the integrals in the internal variables of a system.

    Parameters
    ----------
    which : {"integrals", "scales", "geometric", "density"}
        ``"density"`` gives ``{"rho": ...}`` w.r.t. the internal variables.

    Returns
    -------
    dict of str -> heyoka.expression
        Keyed as :func:`integrals` (or its scales / geometric counterparts), using
        ``hy.par[i]`` in the layout of ``params.pars``.
    """
    import heyoka as hy

    system = get_system(kind, formulation)
    xs = hy.make_vars(*system.internal_names)
    c = system.constants([hy.par[i] for i in range(system.n_pars)])
    v = system.vectors(c, xs)
    if which == "integrals":
        return system.info.integrals(c, v)
    if which == "scales":
        return system.info.scales(c, v)
    if which == "geometric":
        return system.info.geometric(v)
    if which == "density":
        coords = "public" if system.formulation == system.info.public_formulation else "internal"
        return {"rho": _density(system, c, v, coords)}
    from .errors import UsageError

    raise UsageError(f"which must be 'integrals', 'scales', 'geometric' or 'density', got {which!r}")


def integrals_cfunc(kind: KindName, formulation: str | None = None, *, fp_type: FpTypeLike = float,
                    prec: Optional[int] = None,
                    which: Literal["integrals", "scales", "geometric", "density"] = "integrals",
                    ) -> Callable[[ArrayLike, ArrayLike], Dict[str, np.ndarray]]:
    """A compiled heyoka function evaluating :func:`integral_expressions` on internal
    states.

    Returns
    -------
    callable
        ``f(states, pars) -> dict[str, ndarray]`` with ``states`` of shape ``(n, dim)`` in
        the internal variables of the system and ``pars`` the parameter vector.
    """
    from ._cfunc_columns import cfunc_columns
    from .numbers import resolve_fp_type

    spec = resolve_fp_type(fp_type, prec)
    system = get_system(kind, formulation)

    def graph():
        import heyoka as hy

        return integral_expressions(kind, system.formulation, which=which), hy.make_vars(*system.internal_names)

    kw = dict(fp_type=spec.fp_type, compact_mode=spec.compact_mode)
    if spec.prec is not None:
        kw["prec"] = spec.prec
    cf = cfunc_columns(("cfunc", "integrals", kind, system.formulation, str(spec), which), graph, **kw)
    names = cf.names or ()

    def as_type(a):
        # an array of the number type already (float64 from a section's run, say) is used as
        # it is: the columns below are a fresh contiguous copy anyway
        a = np.asarray(a)
        return a if a.dtype == spec.dtype and spec.name != "real" else spec.array(a)

    def evaluate(states, pars):
        out = cf(as_type(states).reshape(-1, system.dim), as_type(pars))
        return {k: out[i] for i, k in enumerate(names)}

    return evaluate
