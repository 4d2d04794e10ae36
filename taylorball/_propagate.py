"""Compiled Taylor integrators for the paper's systems, and :func:`propagate`.

Integrators are compiled once per (system, formulation, number type, tolerance, events)
and kept in an in-process cache; heyoka also caches the machine code in memory and on disk
(``HEYOKA_CACHE_DIR``). Parameters are runtime ``hy.par[i]``, so one compiled integrator
serves every parameter set. :func:`propagate` borrows an idle working copy of the cached
template (:func:`taylorball._cache.working_copy`; a fresh ``copy.copy`` costs ~1 ms) and
sets its state, time and parameters, so calls are independent and thread-safe;
:func:`make_integrator` hands the caller a copy of its own. Many states at once run in
the SIMD lanes of a float64 batch integrator (:func:`taylorball.ensemble.orbit_lanes`).
"""

from __future__ import annotations

import copy
from typing import Any, Callable, Hashable, Optional, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from ._cache import compiled, working_copy
from ._typing import FpTypeLike, KindName, ParamsLike
from .errors import IntegrationError, StateError, UsageError
from .manifold import as_state, params_for
from .model import _project_array
from .model import System, get_system
from .numbers import FpSpec, times
from ._problem import Problem, at_boundary

__all__ = ["propagate", "make_integrator", "integrator", "start", "start_state", "internal_f64", "working_state",
           "public_state", "public_states"]

def integrator(prob: Problem, *, events_key: Hashable = None, events: Optional[Callable[[], dict]] = None,
               compact_mode: Optional[bool] = None):
    """The cached, compiled template integrator of a problem (do not mutate: copy it).

    Parameters
    ----------
    events_key, events
        ``events()`` returns keyword arguments for ``hy.taylor_adaptive`` (``nt_events``,
        ``t_events``); ``events_key`` identifies them in the cache.
    compact_mode : bool, optional
        heyoka's compact mode (default: the number type's choice, ``FpSpec.compact_mode``).
    """
    import heyoka as hy

    system, spec, tol = prob.system, prob.spec, prob.tol
    cm = spec.compact_mode if compact_mode is None else compact_mode

    def build():
        zero = spec.scalar(0.0)
        kwargs = dict(
            sys=system.equations(),
            state=[spec.scalar(0.1)] * system.dim,
            pars=[zero] * system.n_pars,
            fp_type=spec.fp_type,
            compact_mode=cm,
        )
        if spec.prec is not None:
            kwargs["prec"] = spec.prec
            kwargs["time"] = zero
        if tol is not None:
            kwargs["tol"] = spec.scalar(tol)
        if events is not None:
            kwargs.update(events())
        return hy.taylor_adaptive(**kwargs)

    return compiled(("integrator", *prob.compile_key, cm, events_key), build)


def start_state(prob: Problem, state, *, project_state: bool = False, constraint_tol=None) -> np.ndarray:
    """Validate a public state, project it onto the constraints in the working precision
    and convert it to the internal variables of the problem's system.

    Returns
    -------
    ndarray
        The internal state in the working number type.
    """
    system, spec = prob.system, prob.spec
    x = as_state(prob.kind, state, check=not project_state, constraint_tol=constraint_tol)
    if x.ndim != 1:
        raise StateError(f"state must be one state of shape ({len(system.public_names)},), got shape {x.shape}")
    if spec.name == "float" and x.dtype == np.float64:
        # one float64 state: the projection and the change of variables on Python floats,
        # the same IEEE operations (+ - * / and a correctly rounded sqrt) as on the array's
        # 0-d columns, hence the same bits, without numpy's per-operation overhead
        c = system.info.project(x.tolist())
        return np.array(system.to_internal(tuple(map(float, prob.params.pars)), tuple(c)), dtype=np.float64)
    x = _project_array(system.info, spec.array(x))  # x was checked above
    return _arr(system.to_internal(tuple(prob.pars), tuple(x)), spec)


def internal_f64(prob: Problem, states) -> np.ndarray:
    """Internal float64 rows of the public ``states`` (rows), each by :func:`start_state`
    with ``project_state=True``."""
    return np.array([np.asarray(start_state(prob, x, project_state=True), dtype=object).astype(float)
                     for x in states])


def working_state(kind, params, state, spec: FpSpec, *, formulation=None, project_state=False, constraint_tol=None):
    """:func:`start_state` from loose arguments: ``(system, pars, internal)`` in the working type."""
    prob = Problem(get_system(kind, formulation), params_for(kind, params), spec)
    return prob.system, prob.pars, start_state(prob, state, project_state=project_state,
                                               constraint_tol=constraint_tol)


def _flag(name, value):
    if not isinstance(value, (bool, np.bool_)):
        raise UsageError(f"{name} must be True or False, got {value!r}")


def _arr(values, spec):
    out = np.empty(len(values), dtype=spec.dtype)
    for i, v in enumerate(values):
        out[i] = v
    return out


def public_state(system, pars, internal, spec: FpSpec) -> np.ndarray:
    """Public layout from internal variables (same number type)."""
    return _arr(system.to_public(tuple(pars), tuple(internal)), spec)


def public_states(prob: Problem, internal) -> np.ndarray:
    """Public layout of the rows of ``internal`` (n, dim), in the working number type:
    whole columns at once for float64 / long double (the same elementwise IEEE operations,
    hence the same bits as row by row, ~100x faster for long grids), row by row otherwise."""
    system, spec, pars = prob.system, prob.spec, prob.pars
    X = np.asarray(internal)
    if spec.name in ("float", "longdouble"):
        cols = tuple(X[:, i] for i in range(X.shape[1]))
        return np.column_stack(system.to_public(tuple(pars), cols)).astype(spec.dtype, copy=False)
    return np.stack([public_state(system, pars, row, spec) for row in X])


def start(prob: Problem, state, *, project_state: bool = False, constraint_tol=None, t0=0.0):
    """A copy of the problem's compiled integrator at ``state`` (public layout), time ``t0``."""
    ta = copy.copy(integrator(prob))
    ta.state[:] = start_state(prob, state, project_state=project_state, constraint_tol=constraint_tol)
    ta.pars[:] = prob.pars
    ta.time = prob.spec.scalar(t0)
    return ta


def make_integrator(
    kind: Union[KindName, Problem],
    params: Union[ParamsLike, ArrayLike, None] = None,
    state: Optional[ArrayLike] = None,
    *,
    fp_type: FpTypeLike = float,
    prec: Optional[int] = None,
    tol: Optional[float] = None,
    formulation: Optional[str] = None,
    project: bool = False,
    constraint_tol: Optional[float] = None,
    t0: float = 0.0,
) -> Tuple[Any, System, FpSpec]:
    """A ready heyoka integrator at ``state`` (public layout) and time ``t0``.

    The integrator's own state ``ta.state`` is in the internal variables of the system
    (``system.internal_names``); ``system.to_public(tuple(ta.pars), tuple(ta.state))``
    converts it back to the public layout (see the example).

    Returns
    -------
    (ta, system, spec) : heyoka integrator, System, FpSpec

    Examples
    --------
    >>> import numpy as np
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> x0 = demo_reduced_state()
    >>> ta, system, spec = tb.make_integrator("reduced", FIG4_BALL, x0)
    >>> system.internal_names                      # the variables of ta.state
    ('M1', 'M2', 'M3', 'gamma1', 'gamma2', 'gamma3', 'R1', 'R2', 'R3')
    >>> print(ta.propagate_until(1.0)[0])
    taylor_outcome.time_limit
    >>> x1 = np.array(system.to_public(tuple(ta.pars), tuple(ta.state)))
    >>> bool((x1 == tb.propagate("reduced", FIG4_BALL, x0, 1.0)).all())   # the same bits
    True
    """
    prob, (state,) = at_boundary("make_integrator", kind, params, (state,), ("state",), fp_type=fp_type, prec=prec,
                                 tol=tol, formulation=formulation)
    _flag("project", project)
    if np.ndim(t0) != 0:
        raise UsageError(f"t0 must be one finite time (the start), got {t0!r}")
    times("t0", t0)
    ta = start(prob, state, project_state=project, constraint_tol=constraint_tol, t0=t0)
    return ta, prob.system, prob.spec


def _check_outcome(ta, res, t_target):
    import heyoka as hy

    outcome = res[0]
    if outcome != hy.taylor_outcome.time_limit:
        raise IntegrationError(
            f"integration stopped at t={ta.time} before t={t_target} with outcome {outcome}; "
            "a non-finite state usually means a singular configuration (e.g. 1 - d(gamma, A gamma) = 0) "
            "or an orbit escaping to infinity"
        )


def propagate(
    kind: Union[KindName, Problem],
    params: Union[ParamsLike, ArrayLike, None] = None,
    state: Optional[ArrayLike] = None,
    t: Optional[ArrayLike] = None,
    *,
    fp_type: FpTypeLike = float,
    prec: Optional[int] = None,
    tol: Optional[float] = None,
    formulation: Optional[str] = None,
    project: bool = False,
    constraint_tol: Optional[float] = None,
    workers: Optional[int] = None,
) -> np.ndarray:
    r"""Integrate one of the paper's systems from time 0 to ``t``, for one state or many.

    Parameters
    ----------
    kind : {"full", "reduced", "mparallel"} or Problem
        Paper eqs. (8)-(10) [eq6] on SO(3) x R^5, eqs. (15)-(16) [eq10], or eq. (22) [Mpn2]
        of sec. 5; or a :class:`taylorball.Problem` (:func:`taylorball.problem`), with
        ``params`` left out: ``propagate(prob, state, t)``. The problem fixes ``fp_type``,
        ``prec``, ``tol`` and ``formulation`` (giving one of them too raises UsageError).
    params : BallParams or MParallelParams
    state : array_like, shape (d,) or (n, d)
        Initial state in the public layout (:data:`taylorball.model.PUBLIC_NAMES`,
        ``d`` = 14, 9 or 6), or ``n >= 1`` initial states as rows (see Notes).
    t : float or array_like of float
        Final time (may be negative), or an increasing grid of times starting at >= 0.
    fp_type : float, numpy.longdouble, heyoka.real128 or heyoka.real
        Number type of the integration; the result has this dtype.
    prec : int, optional
        Bits of precision, for ``heyoka.real`` only.
    tol : float, optional
        Taylor integrator tolerance (default: machine epsilon of ``fp_type``): the bound on
        each step's local error (relative and absolute) from which heyoka picks the order
        and the step; the global error grows with time. In ``[eps, 1e-6]``
        (:func:`taylorball.problem`).
    formulation : str, optional
        Internal formulation (``"momentum"`` or ``"omega"``; see :mod:`taylorball.model`).
    project : bool
        Project a state that is off the constraint manifold instead of rejecting it.
        States within ``constraint_tol`` are always snapped onto the manifold in the
        working precision.
    constraint_tol : float, optional
        See :func:`taylorball.manifold.as_state`.
    workers : int, optional
        Threads for many states (each runs one batch integrator); default ``os.cpu_count()``,
        never more than there are groups of lanes. Ignored for one state.

    Returns
    -------
    numpy.ndarray, shape (d,), (len(t), d), (n, d) or (n, len(t), d)
        The state(s) at ``t`` in the public layout: one state's, or for ``n`` states one
        row (one block of rows for a grid) per initial state, in their order.

    Raises
    ------
    ParameterError, StateError, ConstraintError, UsageError
        Bad parameters, state(s) or options (every row is checked before any integration).
    IntegrationError
        If the integrator stops early (non-finite state); for many states, naming the row.

    Notes
    -----
    **Many states** (``state`` of shape ``(n, d)``), float64 at the default tolerance: the
    rows run in the SIMD lanes of heyoka's batch mode (``hy.taylor_adaptive_batch`` of
    ``heyoka.recommended_simd_size()`` lanes, refilled as rows finish,
    :func:`taylorball.ensemble.orbit_lanes`). Row ``i`` is then bit-identical to raw heyoka
    batch mode on the same compiled system from that state (``propagate_until(t)``, or
    ``propagate_grid`` on the grid with the start time 0 put first if the grid does not
    start there), whatever ``n``, the row's place among the others, its lane and
    ``workers``: heyoka's lanes are independent. It is **not** bit-identical to the
    one-state call ``propagate(..., state[i], t)``: heyoka's vectorised code rounds
    differently from its scalar code, so the two differ by rounding, grown along the orbit
    as any rounding error is (a few hundred eps of the state's size over tens of time
    units on the paper's orbits; more on chaotic ones over long spans). Other number types
    or tolerances run the rows one by one, and row ``i`` then equals the one-state call.

    Examples
    --------
    >>> import heyoka as hy
    >>> import numpy as np
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> x0 = demo_reduced_state()                  # (omega, gamma, R)
    >>> x1 = tb.propagate("reduced", FIG4_BALL, x0, 1.0)
    >>> x1.shape, x1.dtype
    ((9,), dtype('float64'))
    >>> x1[:3].round(6)                            # omega at t = 1
    array([ 0.572145,  0.829357, -0.051085])
    >>> xs = tb.propagate("reduced", FIG4_BALL, x0, [0.0, 0.5, 1.0])   # a grid of times
    >>> xs.shape
    (3, 9)
    >>> q = tb.propagate("reduced", FIG4_BALL, x0, 1.0, fp_type=hy.real128)   # quadruple precision
    >>> q.dtype == hy.real128, bool(abs(float(q[0]) - x1[0]) < 1e-13)
    (True, True)
    >>> prob = tb.problem("reduced", FIG4_BALL)    # or a Problem in the place of kind and params
    >>> bool((tb.propagate(prob, x0, 1.0) == x1).all())
    True
    >>> many = tb.propagate(prob, np.stack([x0, x0]), 1.0)   # many states: the SIMD lanes
    >>> many.shape, bool(np.allclose(many[1], x1, rtol=0, atol=1e-13))
    ((2, 9), True)
    """
    prob, (state, t) = at_boundary("propagate", kind, params, (state, t), ("state", "t"), fp_type=fp_type,
                                   prec=prec, tol=tol, formulation=formulation)
    times("t", t)
    _flag("project", project)
    if workers is not None and not (isinstance(workers, (int, np.integer)) and not isinstance(workers, bool)
                                    and workers >= 1):
        raise UsageError(f"workers must be a positive integer or None (all cores), got {workers!r}")
    grid = None if np.ndim(t) == 0 else _grid(t)
    if np.ndim(state) == 2:
        return _propagate_many(prob, state, t, grid, project, constraint_tol, workers)
    x = start_state(prob, state, project_state=project, constraint_tol=constraint_tol)
    spec, pars = prob.spec, prob.pars
    with working_copy(integrator(prob)) as ta:  # an idle copy: state, time and parameters set here
        ta.state[:] = x
        ta.pars[:] = pars
        ta.time = spec.scalar(0.0)
        if grid is None:
            _check_outcome(ta, ta.propagate_until(spec.scalar(t)), t)
            return public_state(prob.system, pars, ta.state, spec)
        tg = spec.array(grid)
        if float(grid[0]) > 0:  # heyoka's grid must start at the current time
            _check_outcome(ta, ta.propagate_until(tg[0]), grid[0])
        res = ta.propagate_grid(tg)
        _check_outcome(ta, res, grid[-1])
        return public_states(prob, res[-1])


def _grid(t) -> np.ndarray:
    """The output grid ``t`` checked: non-empty, 1-D, strictly increasing, from ``>= 0``."""
    grid = np.asarray(t)
    if grid.ndim != 1 or grid.size == 0:
        raise UsageError(f"t must be a number or a non-empty 1-D grid of times, got shape {grid.shape}")
    # strictly increasing (heyoka refuses a repeated time), compared in the grid's own type
    increasing = bool(np.all(np.diff(grid) > 0)) if grid.dtype.kind == "f" else \
        all(b > a for a, b in zip(grid[:-1], grid[1:]))
    if not increasing or float(grid[0]) < 0:
        raise UsageError(f"a time grid t must be strictly increasing and start at t >= 0 (the initial time is "
                         f"0), got {grid!r}"[:300])
    return grid


def _propagate_many(prob: Problem, states, t, grid, project, constraint_tol, workers) -> np.ndarray:
    """:func:`propagate` of the rows of ``states``: in the SIMD lanes for float64 at the
    default tolerance, else row by row (see its Notes)."""
    system, spec = prob.system, prob.spec
    d = len(system.public_names)
    X = as_state(prob.kind, states, check=False)
    if X.shape[0] == 0:
        raise StateError(f"state must be one state of shape ({d},) or n >= 1 states of shape (n, {d}), "
                         f"got shape {X.shape}")
    # every row checked (and projected) before any integration
    rows = []
    for i in range(X.shape[0]):
        try:
            rows.append(start_state(prob, X[i], project_state=project, constraint_tol=constraint_tol))
        except (StateError, UsageError) as e:
            raise type(e)(f"state[{i}]: {e}") from None
    if spec.name != "float" or prob.tol is not None:
        return np.stack([propagate(prob, X[i], t, project=project, constraint_tol=constraint_tol)
                         for i in range(X.shape[0])])
    from .ensemble import LaneLoad, orbit_lanes

    n = len(rows)
    pars = np.asarray(prob.pars, dtype=float)
    if grid is None:
        t_end = float(t)
        if t_end == 0.0:
            return public_states(prob, np.stack(rows))

        def load(j: int) -> LaneLoad:
            return LaneLoad(rows[j], pars, 0.0, t_end, abs(t_end), ends=lambda k: t_end)

        def on_chunk(ta, c):
            return True, np.array(ta.state[:, c.lane], copy=True)
    else:
        g = np.asarray(grid, dtype=float)
        samples = g[g > 0.0]
        if samples.size == 0:  # the grid is [0]
            return public_states(prob, np.stack(rows))[:, None, :]
        skip = 0 if g[0] == 0.0 else 1  # the grid's rows of the chunk's start time 0 (first)

        def load(j: int) -> LaneLoad:
            return LaneLoad(rows[j], pars, 0.0, float(samples[-1]), float(samples[-1]),
                            chunk_samples=lambda k: samples)

        def on_chunk(ta, c):
            return True, np.array(c.sample_x[skip:], copy=True)

    def rerun(j: int, outcome, t_stop):
        # a lane that stopped early (its outcome, at t_stop): the one-state run of that row raises the error
        try:
            propagate(prob, X[j], t, project=project, constraint_tol=constraint_tol)
        except IntegrationError as e:
            raise IntegrationError(f"state[{j}]: {e}") from None
        raise IntegrationError(f"state[{j}]: the batch integration stopped early ({outcome} at t = {t_stop!r}), "
                               "although the one-state run of this row did not")

    out = orbit_lanes(_batch_template(prob), n, load=load, on_chunk=on_chunk, rerun=rerun, workers=workers,
                      grid=grid is not None)
    internal = np.stack(out)
    if grid is None:
        return public_states(prob, internal)
    flat = public_states(prob, internal.reshape(-1, internal.shape[-1]))
    return flat.reshape(internal.shape)


def _batch_template(prob: Problem):
    """The cached float64 batch integrator of the problem's system, no events, with
    ``heyoka.recommended_simd_size()`` lanes (copy it)."""
    import heyoka as hy

    size = max(1, int(hy.recommended_simd_size()))
    system = prob.system

    def build():
        return hy.taylor_adaptive_batch(system.equations(), np.full((system.dim, size), 0.1),
                                        pars=np.zeros((system.n_pars, size)))

    return compiled(("batch", *prob.compile_key, size), build)
