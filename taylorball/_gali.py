r"""GALI_k, the generalised alignment index (Skokos, Bountis & Antonopoulos 2007):
:func:`gali` of one orbit, :func:`gali_many` of many in the SIMD lanes. Public from
:mod:`taylorball.chaos` (and ``taylorball``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, Optional, Union

import numpy as np
from numpy.typing import ArrayLike

from ._deprecation import renamed
from ._problem import Problem, at_boundary, lane_problem
from ._typing import FpTypeLike, KindName, ParamsLike, ProgressLike, StatesLike
from ._variational import _check_sample, _check_spectrum_args, _fundamental_lanes, _householder_qr, _run_chunks
from .numbers import count
from .tangent import TangentSystem


@dataclass(frozen=True, eq=False)
class GALI:
    r"""The generalised alignment index of one orbit (:func:`gali`).

    Attributes
    ----------
    k : int
        Number of deviation vectors.
    times : ndarray, shape (m,)
        Times of the series (the renormalisation times, or ``sample``), read-only float64.
    values : ndarray, shape (m,)
        ``GALI_k`` at ``times``: the volume of the parallelepiped of the ``k`` deviation
        vectors normalised to unit length (``prod |R_ii|`` of their QR), in ``[0, 1]``;
        read-only float64.
    value : float
        ``GALI_k`` at ``t``.
    kind : str
    problem : taylorball.Problem
    t0, t, renorm : float
    initial_state, final_state : ndarray
        Public states at ``t0`` (as projected in the working type) and ``t``.
    n_steps : int
        Taylor steps.
    nested_values : ndarray, shape (m, k - 1)
        ``GALI_j`` of the first ``j`` deviation vectors ``w_1 .. w_j``, ``j = 2 .. k``
        (column ``j - 2``), at ``times``, read-only float64: from the same QR (the leading
        ``j x j`` block of ``R`` is the ``R`` of the first ``j`` columns), so one run gives
        ``GALI_2 .. GALI_k``; the last column equals ``values`` to rounding (a cumulative
        product, ``values`` the product of the whole diagonal).
    """

    k: int
    times: np.ndarray = field(repr=False)
    values: np.ndarray = field(repr=False)
    value: float
    kind: str
    problem: object = field(repr=False)
    t0: float
    t: float
    renorm: float
    initial_state: np.ndarray = field(repr=False)
    final_state: np.ndarray = field(repr=False)
    n_steps: int = 0
    nested_values: Optional[np.ndarray] = field(default=None, repr=False)


class _Gali:
    """The ``k`` deviation vectors of one orbit, carried in the first ``k`` columns of the
    fundamental-matrix system's tangent block (the others zero; each column obeys ``d' = J d``
    on its own): at each chunk end they are normalised to unit length (the equation is linear,
    so this only rescales) and ``GALI_k`` recorded."""

    def __init__(self, prob, k: int):
        self.spec, self.k, self.n = prob.spec, k, prob.system.dim
        self.times: list = []
        self.values: list = []
        self.nested: list = []  # GALI_2 .. GALI_k of the first j vectors
        self.n_steps = 0

    def _unit(self, phi):
        W = np.array(phi[:, : self.k], dtype=self.spec.dtype)
        return W / np.sqrt(np.sum(W * W, axis=0))

    def _record(self, t: float, W):
        # the k-volume of the columns is prod |R_ii| of their QR (W = Q R, Q orthonormal);
        # the first j columns' is the product of the first j (R's leading block is their R)
        R = np.linalg.qr(W, mode="r") if self.spec.name == "float" else _householder_qr(W)[1]
        r = np.abs(np.diagonal(R))
        self.times.append(t)
        self.values.append(float(np.prod(r)))
        self.nested.append(np.cumprod(r)[1:].astype(float))

    def sample(self, phi, t: float):
        self._record(t, self._unit(phi))

    def chunk(self, phi, t: float, steps: int, *, record: bool) -> np.ndarray:
        self.n_steps += steps
        W = self._unit(phi)
        if record:
            self._record(t, W)
        out = np.zeros((self.n, self.n), dtype=self.spec.dtype)
        out[:, : self.k] = W
        return out.reshape(-1)


@renamed(t="t_end")
def gali(kind: Union[KindName, Problem], params: Union[ParamsLike, ArrayLike, None] = None,
         state: Optional[ArrayLike] = None, t_end: Optional[float] = None, *, k: int = 2, t0: float = 0.0,
         renorm: float = 1.0, fp_type: FpTypeLike = float, prec: Optional[int] = None, tol: Optional[float] = None,
         seed: int = 0, sample: Optional[ArrayLike] = None) -> GALI:
    r"""The generalised alignment index ``GALI_k(t)`` of an orbit (Skokos, Bountis &
    Antonopoulos 2007).

    ``k`` deviation vectors ``w_1 .. w_k``, random unit vectors tangent to the constraint
    manifold (each drawn like :func:`megno`'s seed, from one generator seeded with ``seed``),
    follow ``w' = J w`` (the first ``k`` columns of the fundamental-matrix system,
    :class:`taylorball.tangent.TangentSystem` ``vectors="all"``, compact mode); every
    ``renorm`` time units they are normalised to unit length. ``GALI_k`` is the volume of the
    parallelepiped of the normalised vectors, ``|w_1/|w_1| ^ ... ^ w_k/|w_k||`` = the product
    of their singular values = ``prod R_ii`` of their QR factorisation (LAPACK in float64, a
    Householder QR in long double).

    Known behaviour (``docs/chaos.md``, "GALI"): on a chaotic orbit
    ``GALI_k ~ exp(-sum_{i=2..k} (lambda_1 - lambda_i) t)`` with the Lyapunov exponents of
    :func:`lyapunov_spectrum` (all vectors align with the most unstable direction), down to
    the rounding floor ``~ eps``; on a regular orbit on a ``d``-torus it stays of order one for
    ``k <= d`` (generic shear) and decays like a power of ``t`` for ``k > d``.

    Parameters
    ----------
    kind : {"reduced", "full", "mparallel"} or Problem
        A system, or a :class:`taylorball.Problem` with ``params`` left out
        (``gali(prob, state, t_end)``; it then fixes ``fp_type``, ``prec`` and ``tol``).
    params : BallParams or MParallelParams
    state : array_like
        Initial public state on the constraint manifold.
    t_end : float
        End of the run (finite, > t0; ``t=`` is its deprecated old name).
    k : int
        Number of deviation vectors, ``2 <= k <= d``, ``d`` the dimension of the constraint
        manifold (reduced 7, full 8, M||gamma 5): more tangent vectors than that are linearly
        dependent.
    t0 : float
        Start of the clock.
    renorm : float
        Time between normalisations (> 0, at most :data:`MAX_CHUNKS` of them); without
        ``sample`` the series is recorded there.
    fp_type : float or numpy.longdouble
    prec, tol
        As for :func:`taylorball.propagate`.
    seed : int
        Seed of the random deviation vectors.
    sample : sequence of float, optional
        Increasing times in ``(t0, t]`` at which to record ``GALI_k`` instead (continuous
        output: the run is unchanged).

    Returns
    -------
    GALI

    Raises
    ------
    UsageError
        Bad kind, k, times, renorm, seed, sample or number type.
    StateError, ConstraintError
        A state of the wrong shape or off the constraint manifold.
    IntegrationError
        If the integrator stops early.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> g = tb.gali("reduced", FIG4_BALL, demo_reduced_state(), 20.0, k=2, renorm=5.0)
    >>> g.times, g.k                                # one value per normalisation
    (array([ 5., 10., 15., 20.]), 2)
    >>> bool(0.0 < g.value <= 1.0)                  # a volume of unit vectors
    True
    """
    from ._propagate import start_state

    prob, (state, t_end) = at_boundary("gali", kind, params, (state, t_end), ("state", "t_end"), fp_type=fp_type,
                                       prec=prec, tol=tol)
    t0f, tf, rf, samples, k = _check_gali_args(prob, t0, t_end, renorm, k, seed, sample, "gali")
    internal = start_state(prob, state)
    acc, tangents = _gali_start(prob, k, seed, internal)
    x_end = _run_chunks(prob, internal, prob.spec.array(tangents), t0f, tf, rf, samples, acc)
    return _gali_result(prob, acc, t0f, tf, rf, internal, x_end)


def _check_gali_args(prob, t0, t, renorm, k, seed, sample, func):
    """``(t0, t, renorm, samples, k)`` checked for :func:`gali` / :func:`gali_many`."""
    t0f, tf, rf, _ = _check_spectrum_args(t0, t, renorm, prob.spec, func)
    k_max = prob.system.dim - len(prob.system.info.geometric_names)  # the constraint manifold's dimension
    k = count("k", k, lo=2, hi=k_max)
    count("seed", seed, lo=0)
    return t0f, tf, rf, _check_sample(sample, t0f, tf), k


def _gali_start(prob, k: int, seed: int, internal):
    """A job's accumulator and initial tangent block (flattened row-major, float64): ``k``
    random unit vectors tangent to the constraint manifold at ``internal`` in the first
    ``k`` columns (drawn in order from one generator seeded with ``seed``), zeros elsewhere."""
    ts = TangentSystem.of(prob, "all")
    rng = np.random.default_rng(seed)
    W = np.zeros((ts.n, ts.n))
    for j in range(k):
        W[:, j] = ts.seed(internal, rng)
    return _Gali(prob, k), W.reshape(-1)


def _gali_result(prob, acc, t0: float, t: float, renorm: float, internal, x_end) -> GALI:
    from ._propagate import public_state

    spec = prob.spec
    times, values = np.asarray(acc.times, dtype=float), np.asarray(acc.values, dtype=float)
    nested = np.asarray(acc.nested, dtype=float).reshape(len(acc.times), acc.k - 1)
    times.flags.writeable = values.flags.writeable = nested.flags.writeable = False
    return GALI(k=acc.k, times=times, values=values, value=float(values[-1]), kind=prob.kind, problem=prob, t0=t0,
                t=t, renorm=renorm, initial_state=public_state(prob.system, prob.pars, internal, spec),
                final_state=public_state(prob.system, prob.pars, x_end, spec), n_steps=acc.n_steps,
                nested_values=nested)


@renamed(t="t_end", threads="workers")
def gali_many(kind: Union[KindName, Problem], params: Union[ParamsLike, StatesLike, None] = None,
              states: Optional[StatesLike] = None, t_end: Optional[float] = None, *, k: int = 2, t0: float = 0.0,
              renorm: float = 1.0, seed: int = 0, sample: Optional[ArrayLike] = None, workers: Optional[int] = None,
              progress: ProgressLike = False) -> List[GALI]:
    """:func:`gali` of many float64 orbits, in the SIMD lanes of heyoka batch integrators (one
    per thread; :mod:`taylorball.ensemble`, ``backend="lanes"``), each lane refilled with the
    next orbit as soon as its orbit ends: the engine of :func:`lyapunov_spectra`, with
    :func:`gali`'s deviation vectors, normalisations and QR.

    Each orbit runs on its own clock through the chunk boundaries ``t0 + j renorm`` of
    :func:`gali`, with the same seed for its deviation vectors, so its result depends only
    on its own state (bit-identical whatever the threads and companions); it agrees with
    :func:`gali` of the same state to rounding, not bitwise (heyoka's vectorised code rounds
    differently; on a chaotic orbit the two then separate as two float64 runs do).

    Parameters
    ----------
    kind : {"reduced", "full", "mparallel"} or Problem
        As for :func:`gali` (``gali_many(prob, states, t_end)``); a Problem must be
        float64 at the default tolerance (the lanes' integrators).
    sample : sequence of float, optional
        As for :func:`gali`, the same times for every orbit (the lane engine's continuous
        output, ``LaneLoad.samples``): the run is unchanged, bit for bit.
    workers : int, optional
        Worker threads (default ``os.cpu_count()``; ``threads=`` is its deprecated old name).
    progress : bool
        A progress bar over orbits.

    Other parameters as for :func:`gali` (float64 only; the batch variational system
    compiles in compact mode).

    Returns
    -------
    list of GALI
        In the order of ``states``. An orbit whose integration fails is rerun alone by
        :func:`gali`, which raises the error.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> x0 = demo_reduced_state()
    >>> gs = tb.gali_many("reduced", FIG4_BALL, [x0, x0], 20.0, k=3, renorm=5.0, workers=2)
    >>> len(gs), bool((gs[0].values == gs[1].values).all())   # an orbit depends only on its own state
    (2, True)
    >>> one = tb.gali("reduced", FIG4_BALL, x0, 20.0, k=3, renorm=5.0)
    >>> bool(abs(gs[0].value - one.value) <= 1e-9 * one.value)   # equal to rounding, not bitwise
    True
    """
    prob, (states, t_end) = at_boundary("gali_many", kind, params, (states, t_end), ("states", "t_end"))
    prob = lane_problem("gali_many", prob)
    t0f, tf, rf, samples, k = _check_gali_args(prob, t0, t_end, renorm, k, seed, sample, "gali_many")

    def rerun(state):  # gali raises the integration error (named by run_many)
        return gali(prob, state, t_end, k=k, t0=t0, renorm=renorm, seed=seed, sample=sample)

    return _fundamental_lanes(prob, states, t0f, tf, rf, samples, start=lambda x: _gali_start(prob, k, seed, x),
                              finish=lambda acc, x, x_end: _gali_result(prob, acc, t0f, tf, rf, x, x_end),
                              rerun=rerun, workers=workers, func="gali_many", one="gali",
                              progress=f"GALI_{k} to t={tf:g}" if progress is True else progress)
