r"""Chaos indicators from the variational equations: MEGNO and the fast Lyapunov indicator.

For an orbit ``x(t)`` and a tangent vector ``delta`` with ``d delta/dt = J(x) delta``, let
``lambda(t) = (delta, J delta)/(delta, delta)`` (the instantaneous stretching rate). Then

* ``FLI(t) = ln |delta(t)| / |delta(0)| = int_0^t lambda``;
* MEGNO (Cincotta & Simó 2000): ``Y(t) = (2/t) int_0^t s lambda(s) ds`` and its running
  mean ``<Y>(t) = (1/t) int_0^t Y``. ``<Y> -> 2`` on quasi-periodic orbits (sheared tori),
  ``-> 0`` on stable periodic ones, and grows like ``lambda_max t / 2`` on chaotic ones.

The quantities are integrated as extra state variables (``y' = t lambda``,
``w' = 2 y / t``, ``ell' = lambda``) together with the system and one tangent vector
(one tangent vector, not the full variational matrix, so default-mode compilation stays
affordable: see ``_DEFAULT_COMPACT`` for the per-system choice, measured). The
tangent vector is renormalised between chunks (its equation is linear and ``lambda`` is
scale invariant), so it never overflows. The clock starts at ``t = t0 > 0`` to keep
``2 y / t`` regular; the indicators are then over ``[t0, t]``.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any, List, Literal, Optional, Union

import numpy as np
from numpy.typing import ArrayLike

from ._problem import Problem, at_boundary, lane_problem
from ._typing import FpTypeLike, KindName, ParamsLike, ProgressLike, StatesLike
from .errors import StateError, UsageError
from .numbers import count, real_number
from ._deprecation import renamed
from .tangent import NORMS, SEED_KINDS, TangentSystem

__all__ = ["ChaosIndicators", "megno", "megno_many", "LyapunovSpectrum", "lyapunov_spectrum", "lyapunov_spectra",
           "GALI", "gali", "gali_many"]

#: Compact mode per system of the scalar tangent-vector system in :func:`megno` (measured
#: here; :func:`megno_many` chooses by the amount of work, :data:`DEFAULT_MODE_WORK`): the M||gamma
#: system compiles in ~10 s in default mode and then runs 4.5x faster than in compact mode;
#: the reduced system takes ~26 s to compile in default mode for a 1.5x gain, so it stays
#: compact; so does the full system (its default-mode compile time not measured: a larger
#: graph than the reduced one's, 31 equations against 21).
#: Non-float types always use compact mode (see taylorball.numbers).
_DEFAULT_COMPACT = {"reduced": True, "full": True, "mparallel": False}


def _tangents(prob: Problem, norm: str = "full") -> TangentSystem:
    """The problem's system with one tangent vector and the MEGNO/FLI integrands."""
    return TangentSystem.of(prob, "one", indicators=True, norm=norm)


def _states_list(prob: Problem, states: Any, func: str, one: str) -> list:
    """The initial states of a many-orbit function as a non-empty list, one state each:
    a single state (shape ``(d,)``) is refused with a message naming the one-orbit
    function (iterating it would hand out its numbers as states)."""
    d = len(prob.system.info.public_names)
    if isinstance(states, np.ndarray) or (isinstance(states, (list, tuple)) and states
                                          and all(np.ndim(x) == 0 for x in states)):
        arr = np.asarray(states, dtype=object if not isinstance(states, np.ndarray) else None)
        if arr.ndim != 2:
            raise StateError(f"{func}: states must have shape (n, {d}), one initial {prob.kind} state per row; got "
                             f"shape {arr.shape}" + (f" (one state: use {one}, or pass [state])" if arr.ndim == 1
                                                      else ""))
    try:
        states = list(states)
    except TypeError:
        raise StateError(f"{func}: states must be a sequence of initial states (shape (n, {d})), got "
                         f"{states!r}") from None
    if not states:
        raise UsageError(f"{func}: states must contain at least one initial state")
    return states


#: At most this many chunks (renormalisations, Python round trips) per orbit: with the
#: default chunk of 50 time units, runs up to 5e7 time units.
MAX_CHUNKS = 1_000_000


def _check_args(kind, t0, t_end, chunk=50.0, stop_above=None, norm="compact"):
    if not isinstance(kind, str) or kind not in SEED_KINDS:
        raise UsageError(f"kind must be one of {SEED_KINDS} for chaos indicators, got {kind!r}")
    if not isinstance(norm, str) or norm not in NORMS:
        raise UsageError(f"norm must be one of {NORMS} ('compact': the indicators measure the tangent vector "
                         f"without the contact point's unbounded directions; docs/chaos.md), got {norm!r}")
    t0 = real_number("t0", t0, lo=0.0, lo_open=True)
    t_end = real_number("t_end", t_end)
    if not t_end > t0:
        raise UsageError(f"need 0 < t0 < t_end, got t0={t0!r}, t_end={t_end!r}")
    chunk = real_number("chunk", chunk, lo=0.0, lo_open=True)
    if (t_end - t0) / chunk > MAX_CHUNKS:
        raise UsageError(f"chunk={chunk!r} cuts [t0, t_end] = [{t0!r}, {t_end!r}] into {(t_end - t0) / chunk:.3g} "
                         f"chunks, more than {MAX_CHUNKS}: use chunk >= {(t_end - t0) / MAX_CHUNKS:.3g} "
                         "(the chunk only sets how often the tangent vector is renormalised)")
    if stop_above is not None:
        real_number("stop_above", stop_above)


@dataclass(frozen=True, eq=False)
class ChaosIndicators:
    """Indicators of one orbit at ``t``: ``megno`` (``Y(t)``), ``mean_megno``
    (``<Y>(t)``), ``fli`` (``ln |delta(t)|/|delta(0)|``), and the estimate of the largest
    Lyapunov exponent ``fli / (t - t0)``.

    With ``megno(..., sample=times)`` also the series at those times (read-only float64
    arrays, otherwise ``None``; left out of the repr): ``times``, ``Y`` (``Y(t) = 2 y / t``),
    ``mean_Y`` (``<Y>(t) = w / (t - t0)``) and ``fli_series`` (``ln |delta(t)|/|delta(0)|``).
    ``norm`` says what the indicators measured the tangent vector on (``"compact"`` or
    ``"full"``, see :func:`megno`).

    Equality compares everything (arrays elementwise); the hash uses the final values."""

    t: float
    megno: float
    mean_megno: float
    fli: float
    lyapunov: float
    times: Optional[np.ndarray] = field(default=None, repr=False)
    Y: Optional[np.ndarray] = field(default=None, repr=False)
    mean_Y: Optional[np.ndarray] = field(default=None, repr=False)
    fli_series: Optional[np.ndarray] = field(default=None, repr=False)
    norm: str = "compact"

    def _finals(self):
        return (self.t, self.megno, self.mean_megno, self.fli, self.lyapunov, self.norm)

    def _series(self):
        return (self.times, self.Y, self.mean_Y, self.fli_series)

    def __eq__(self, other):
        if other.__class__ is not self.__class__:
            return NotImplemented
        return self._finals() == other._finals() and all(
            (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))
            for a, b in zip(self._series(), other._series()))

    def __hash__(self):
        return hash(self._finals())


def megno(kind: Union[KindName, Problem], params: Union[ParamsLike, ArrayLike, None] = None,
          state: Optional[ArrayLike] = None, t_end: Optional[float] = None, *,
          t0: float = 1.0, chunk: float = 50.0, fp_type: FpTypeLike = float,
          prec: Optional[int] = None, seed: int = 0, stop_above: Optional[float] = None,
          sample: Optional[ArrayLike] = None, norm: str = "compact") -> ChaosIndicators:
    """MEGNO and FLI of an orbit of the reduced, full or M||gamma system.

    Parameters
    ----------
    kind : {"reduced", "full", "mparallel"} or Problem
        A system, or a :class:`taylorball.Problem` with ``params`` left out
        (``megno(prob, state, t_end)``; it then fixes ``fp_type`` and ``prec``, and its
        tolerance and formulation are used).
    params : BallParams or MParallelParams
    state : array_like
        Initial public state.
    t_end : float
        Length of the run (> t0).
    t0 : float
        Start of the clock (> 0).
    seed : int
        Seed of the random initial tangent vector (tangent to the constraints).
    stop_above : float, optional
        Stop at the first chunk boundary where ``<Y>`` exceeds this (the orbit is then
        classified chaotic; quasi-periodic orbits stay near 2): the result's ``t`` is that
        time, not ``t_end``. ``None`` (default) always runs to ``t_end``.
    sample : sequence of float, optional
        Strictly increasing finite times in ``(t0, t_end]`` (at most :data:`MAX_SAMPLES`) at
        which to record the series ``Y(t)``, ``<Y>(t)`` and ``FLI(t)`` (the result's
        ``times``, ``Y``, ``mean_Y``, ``fli_series``). They are read off each chunk's
        continuous output (heyoka's Taylor polynomials of the chunk's steps): the chunk
        boundaries and steps are those of the run without ``sample``, so the final values are
        bit-identical. The indicators are state variables and scale-free in the tangent
        vector, so its renormalisation at chunk ends does not affect them. With
        ``stop_above`` the series ends where the run stops.
    norm : {"compact", "full"}
        What the indicators measure the tangent vector ``d`` on (the result's ``norm`` says
        which). ``"compact"`` (default): its components ``P d`` on the compact part of the
        phase space (reduced: ``(M, gamma)`` without the contact point ``R``; full:
        ``(M, alpha, beta, gamma)`` without ``(x, y)``; M||gamma: everything, so the same as
        ``"full"``), i.e. the stretching rate ``(P d, P J d) / (P d, P d)``; the tangent
        equation is unchanged. ``"full"``: all of it. At Omega = 0 the contact point rolls
        away and nearby orbits shear apart quadratically in ``R``, so with ``"full"`` an
        integrable orbit's ``<Y>`` tends to 4 (the package's chaos threshold) instead of 2:
        a regular orbit would read as chaotic, which is why ``"compact"`` is the default.
        The ``(M, gamma)`` equations do not involve ``R`` there, so ``"compact"`` gives
        ``<Y> -> 2`` on those tori, while a chaotic orbit (Omega != 0) still has
        ``<Y> ~ lambda_max t / 2`` (``docs/chaos.md``, "MEGNO on the compact part"). The
        default was ``"full"`` before this release; pass ``norm="full"`` for the old values.

    Raises
    ------
    UsageError
        Bad kind, times, sample or norm.
    IntegrationError
        If the integrator stops early.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> ind = tb.megno("reduced", FIG4_BALL, demo_reduced_state(), 50.0)
    >>> ind                                        # doctest: +ELLIPSIS
    ChaosIndicators(t=50.0, megno=..., mean_megno=..., fli=..., lyapunov=..., norm='compact')
    >>> round(ind.mean_megno, 1)                   # <Y> well above 2 (where quasi-periodic orbits go)
    4.0
    >>> ser = tb.megno("reduced", FIG4_BALL, demo_reduced_state(), 50.0, sample=[10.0, 25.0, 50.0])
    >>> ser.times, ser.mean_Y.round(2)              # <Y>(t) at the sample times
    (array([10., 25., 50.]), array([2.39, 2.56, 4.  ]))
    >>> bool(ser.mean_Y[-1] == ind.mean_megno), ser.fli == ind.fli   # the run is unchanged
    (True, True)
    """
    from ._propagate import start_state

    prob, (state, t_end) = at_boundary("megno", kind, params, (state, t_end), ("state", "t_end"), fp_type=fp_type,
                                       prec=prec)
    kind = prob.kind
    _check_args(kind, t0, t_end, chunk, stop_above, norm)
    count("seed", seed, lo=0)
    samples = _check_sample(sample, float(t0), float(t_end), end="t_end")
    spec = prob.spec
    ts = TangentSystem.of(prob, "one", indicators=True, norm=norm)
    tmpl = ts.template(prob, compact_mode=spec.compact_mode or _DEFAULT_COMPACT[kind])
    pars, internal = prob.pars, start_state(prob, state)
    d0 = spec.array(ts.seed(internal, np.random.default_rng(seed)))
    ta = copy.copy(tmpl)
    ta.state[ts.x] = internal
    ta.state[ts.tangents] = d0
    ta.state[ts.indicators_slice] = spec.array(np.zeros(3))
    ta.pars[:] = pars
    ta.time = spec.scalar(t0)
    t = float(t0)
    series, k_sample = [], 0  # (time, y, w, ell) at the sample times
    while t < t_end:
        t = min(t + chunk, float(t_end))
        _, rows, k_sample = _sampled_chunk(ta, spec, t, samples, k_sample)
        series += [(ti, *(float(v) for v in row[ts.indicators_slice])) for ti, row in rows]
        dn = np.sqrt(sum(v * v for v in ta.state[ts.tangents]))
        ta.state[ts.tangents] = ta.state[ts.tangents] / dn  # linear equation: rescaling is exact
        if stop_above is not None and float(ta.state[ts.megno_w]) / (t - t0) > stop_above:
            break
    yv, wv, fli = (float(v) for v in ta.state[ts.indicators_slice])
    return _indicators(t, float(t0), yv, wv, fli, series if samples is not None else None, norm)


def _indicators(t: float, t0: float, yv: float, wv: float, fli: float, series, norm: str) -> ChaosIndicators:
    """The indicators at ``t`` from the integrated ``y, w, ell``; ``series`` a list of
    ``(t_i, y_i, w_i, ell_i)`` at the sample times (``None``: no series). The series and
    the final values use the same formulas, so at ``t_end`` they are equal."""
    extra = {}
    if series is not None:
        tt, ys, ws, ells = (np.array(c, dtype=float).reshape(-1) for c in (zip(*series) if series else [[]] * 4))
        extra = dict(times=tt, Y=2 * ys / tt, mean_Y=ws / (tt - t0), fli_series=ells)
        for a in extra.values():
            a.flags.writeable = False
    return ChaosIndicators(t=t, megno=2 * yv / t, mean_megno=wv / (t - t0), fli=fli, lyapunov=fli / (t - t0),
                           norm=norm, **extra)


#: Compact mode of the batch tangent system when ``megno_many(compact_mode=None)``, per
#: system: compact (compiles in < 1 s) below this much work (orbits x time units), default
#: mode above. Each threshold is where default mode's faster run has paid for its compilation
#: on a cold cache (heyoka keeps compiled code in its disk cache: with a warm cache default
#: mode always pays; callers who run often pass ``compact_mode=False``). Measured (CPU time,
#: 8 lanes): reduced system, per orbit and 1000 time units, compact 0.37 s, default mode
#: 0.20 s, ~28 s of compilation: ~150 000 orbit time units (the full system, a larger graph,
#: takes the same threshold). M||gamma system (Fig. 1's quick 19 orbits x 199 time units,
#: MEGNO stopped at 10, AMD EPYC Zen 5): compact 0.4 s compile + 2.9 s run, default mode
#: 9.3 s compile + 1.8 s run: ~30 000.
DEFAULT_MODE_WORK = {"reduced": 150_000.0, "full": 150_000.0, "mparallel": 30_000.0}


@renamed(threads="workers")
def megno_many(kind: Union[KindName, Problem], params: Union[ParamsLike, StatesLike, None] = None,
               states: Optional[StatesLike] = None, t_end: Optional[float] = None, *, t0: float = 1.0, chunk: float = 50.0,
               seed: int = 0, stop_above: Optional[float] = None, workers: Optional[int] = None,
               compact_mode: Optional[bool] = None, progress: ProgressLike = False,
               sample: Optional[ArrayLike] = None, norm: str = "compact") -> List[ChaosIndicators]:
    """:func:`megno` for many float64 orbits at once, in the SIMD lanes of heyoka batch
    integrators (one per thread), a lane refilled with the next orbit as soon as one ends
    (at ``t_end`` or, with ``stop_above``, once ``<Y>`` passes it): see
    :mod:`taylorball.ensemble` (``backend="lanes"``).

    Each orbit runs on its own clock through the same chunk boundaries as :func:`megno`,
    with the same seed for its tangent vector, so its result depends only on its own state:
    bit-identical whatever the number of threads and the orbits around it. It agrees with
    :func:`megno` of the same state to rounding, not bitwise (heyoka's vectorised code rounds
    differently; on a chaotic orbit the two then separate as any two float64 runs do).

    Parameters
    ----------
    kind : {"reduced", "full", "mparallel"} or Problem
        As for :func:`megno` (``megno_many(prob, states, t_end)``); a Problem must be
        float64 at the default tolerance (the lanes' integrators).
    compact_mode : bool, optional
        heyoka's compact mode for the batch tangent system; ``None`` picks default mode
        (faster, long to compile once) when ``len(states) * (t_end - t0)`` is at least
        :data:`DEFAULT_MODE_WORK` of the system, compact mode otherwise.
    workers : int, optional
        Worker threads (default ``os.cpu_count()``; ``threads=`` is its deprecated old name).
    progress : bool
        A progress bar over orbits.
    sample : sequence of float, optional
        As for :func:`megno`, the same times for every orbit: the series ``Y(t)``,
        ``<Y>(t)``, ``FLI(t)`` read off the continuous output of each lane's chunks
        (``LaneLoad.samples`` of :mod:`taylorball.ensemble`); the steps are those of the run
        without ``sample``, so the final values are bit-identical.
    norm : {"compact", "full"}
        As for :func:`megno` (default ``"compact"``: the tangent vector without the contact
        point, so that integrable Omega = 0 orbits come out at ``<Y> -> 2``).

    Other parameters as for :func:`megno`.

    Returns
    -------
    list of ChaosIndicators
        In the order of ``states``. An orbit whose integration fails is rerun alone by
        :func:`megno`, which raises the error.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> x0 = demo_reduced_state()
    >>> res = tb.megno_many("reduced", FIG4_BALL, [x0, x0], 50.0, workers=2)
    >>> len(res), res[0] == res[1]                 # an orbit depends only on its own state
    (2, True)
    >>> one = tb.megno("reduced", FIG4_BALL, x0, 50.0)
    >>> bool(abs(res[0].mean_megno - one.mean_megno) < 1e-6)   # equal to rounding, not bitwise
    True
    """
    from .ensemble import LaneLoad, LaneTask, run_many
    from ._propagate import start_state

    prob, (states, t_end) = at_boundary("megno_many", kind, params, (states, t_end), ("states", "t_end"))
    prob = lane_problem("megno_many", prob)
    kind = prob.kind
    _check_args(kind, t0, t_end, chunk, stop_above, norm)
    count("seed", seed, lo=0)
    if workers is not None:
        count("workers", workers)
    states = _states_list(prob, states, "megno_many", "megno")
    samples = _check_sample(sample, float(t0), float(t_end), end="t_end")
    work = [start_state(prob, s) for s in states]
    pars = np.asarray(prob.pars, dtype=float)
    if compact_mode is None:
        compact_mode = len(states) * (t_end - t0) < DEFAULT_MODE_WORK[kind]
    ts = _tangents(prob, norm)
    template = ts.batch_template(compact_mode=compact_mode)
    n = ts.system.dim
    out: list = [None] * len(states)
    failed = [False] * len(states)
    series: list = [None if samples is None else [] for _ in states]  # (t, y, w, ell) per orbit

    def load(j):
        x = np.asarray(work[j], dtype=float)
        d0 = ts.seed(x, np.random.default_rng(seed))
        return LaneLoad(np.concatenate([x, d0, np.zeros(3)]), pars,
                        float(t0), float(t_end), float(chunk), samples=samples)

    def after_chunk(ta, chunks):
        done = []
        for c in chunks:
            if series[c.job] is not None:
                series[c.job] += [(ti, *(float(v) for v in row[2 * n :])) for ti, row in c.samples]
            col = ta.state[:, c.lane]
            d = col[n : 2 * n]
            ta.state[n : 2 * n, c.lane] = d / np.sqrt(np.sum(d * d))  # linear equation: exact rescaling
            stop = stop_above is not None and float(col[2 * n + 1]) / (c.t - t0) > stop_above
            if stop or c.last:
                yv, wv, fli = (float(v) for v in col[2 * n :])
                out[c.job] = _indicators(c.t, float(t0), yv, wv, fli, series[c.job], norm)
            done.append(stop)
        return done

    def result(j):
        if failed[j]:  # rerun alone: megno raises the integration error (named by run_many)
            return megno(prob, states[j], t_end, t0=t0, chunk=chunk, seed=seed, stop_above=stop_above,
                         sample=sample, norm=norm)
        return out[j]

    def on_fail(j, outcome, t):
        failed[j] = True

    # progress in orbits, advanced by each chunk (the fraction of [t0, t_end]; a run stopped
    # early counts as whole)
    task = LaneTask(template, len(states), load=load, after_chunk=after_chunk, failed=on_fail, result=result)
    return run_many(task, backend="lanes", workers=workers,
                    progress=f"MEGNO to t={t_end:g}" if progress is True else progress)


# ---------------------------------------------------------------------------------------
# The Lyapunov spectrum (Benettin et al. 1980, QR re-orthonormalisation)
# ---------------------------------------------------------------------------------------
#: Largest number of re-orthonormalisation chunks ``(t - t0) / renorm`` one call accepts
#: (each chunk costs a QR factorisation in Python, ~0.1 ms, on top of the integration).
MAX_CHUNKS = 1_000_000

#: Number types the spectrum supports: numpy's QR is float64-only, so the long double
#: QR is a Householder factorisation written here in the working dtype (see _qr).
_QR_TYPES = ("float", "longdouble")


@dataclass(frozen=True)
class LyapunovSpectrum:
    r"""The Lyapunov spectrum of one orbit (:func:`lyapunov_spectrum`).

    Attributes
    ----------
    exponents : ndarray, shape (n,)
        Finite-time exponents ``(1/(t - t0)) sum_k ln |R_k,ii|``, sorted descending, in the
        working number type (``n`` = dimension of the integrated system, constraint
        directions included: see :func:`lyapunov_spectrum`).
    times : ndarray, shape (m,)
        Times of the running estimates (the re-orthonormalisation times, or ``sample``).
    partial : ndarray, shape (m, n)
        Running estimates at ``times``, each row sorted descending.
    sum : scalar
        Sum of the exponents, ``ln |det Phi(t)| / (t - t0)``, in the working type.
    sum_error_bound : float
        Bound on the rounding and truncation error of ``sum`` (see :func:`lyapunov_spectrum`).
    liouville_residual : float
        ``sum + (ln rho(x(t)) - ln rho(x(t0))) / (t - t0)``: zero for exact arithmetic,
        ``rho`` the invariant density in the integrated variables.
    kind : str
    problem : taylorball.Problem
        System, formulation, parameters, number type and tolerance of the run.
    t0, t, renorm : float
    initial_state, final_state : ndarray
        Public states at ``t0`` (as projected in the working type) and ``t``.
    n_chunks, n_steps : int
        Re-orthonormalisations and Taylor steps.
    cond_sum : float
        ``sum_k c_k (1 + sqrt(steps_k))``, ``c_k = max_i |Phi_k e_i| / R_ii`` of chunk ``k``
        (float64): the condition factor of :attr:`sum_error_bound`.
    """

    exponents: np.ndarray
    times: np.ndarray
    partial: np.ndarray
    sum: object
    sum_error_bound: float
    liouville_residual: float
    kind: str
    problem: object
    t0: float
    t: float
    renorm: float
    initial_state: np.ndarray
    final_state: np.ndarray
    n_chunks: int
    n_steps: int
    cond_sum: float

    @property
    def maximal(self) -> float:
        """The largest exponent (float)."""
        return float(self.exponents[0])


def _householder_qr(A):
    """``A = Q R`` by Householder reflections in ``A``'s own dtype (numpy's QR is
    float64-only). Backward stable like LAPACK's: ``Q`` is orthogonal to ``O(n eps)``
    whatever the condition of ``A`` (modified Gram--Schmidt loses orthogonality like
    ``eps cond(A)``, hence not used)."""
    R = np.array(A, copy=True)
    m, n = R.shape
    Q = np.eye(m, dtype=R.dtype)
    for j in range(min(m - 1, n)):
        x = R[j:, j]
        nx = np.sqrt(x @ x)
        if nx == 0:
            continue
        alpha = -nx if x[0] >= 0 else nx
        v = x.copy()
        v[0] -= alpha
        beta = 2 / (v @ v)
        R[j:, :] -= beta * np.outer(v, v @ R[j:, :])
        Q[:, j:] -= beta * np.outer(Q[:, j:] @ v, v)
        R[j + 1 :, j] = 0
    return Q, R


def _qr(A, spec):
    """``(Q, R)`` with ``diag(R) >= 0`` (signs moved into ``Q``, so the tangent vectors keep
    their orientation from chunk to chunk): numpy's Householder QR (LAPACK) for float64,
    :func:`_householder_qr` in the working dtype otherwise."""
    if spec.name == "float":
        Q, R = np.linalg.qr(np.asarray(A, dtype=float))
    else:
        Q, R = _householder_qr(np.asarray(A, dtype=spec.dtype))
    s = np.where(np.diagonal(R) < 0, -1, 1).astype(R.dtype)
    return Q * s, R * s[:, None]


def _check_spectrum_args(t0, t, renorm, spec, func="lyapunov_spectrum"):
    try:
        t0f, tf, rf = float(t0), float(t), float(renorm)
    except (TypeError, ValueError):
        raise UsageError(f"t0, t_end and renorm must be numbers, got t0={t0!r}, t_end={t!r}, renorm={renorm!r}") \
            from None
    if not (np.isfinite(t0f) and np.isfinite(tf) and tf > t0f):
        raise UsageError(f"t_end must be finite and > t0 (finite), got t0={t0!r}, t_end={t!r}")
    if not (np.isfinite(rf) and rf > 0):
        raise UsageError(f"renorm (time between re-orthonormalisations) must be finite and > 0, got {renorm!r}")
    n_chunks = int(np.ceil((tf - t0f) / rf))
    if n_chunks > MAX_CHUNKS:
        raise UsageError(f"(t_end - t0) / renorm = {(tf - t0f) / rf:.3g} re-orthonormalisations exceed "
                         f"MAX_CHUNKS = {MAX_CHUNKS}; use a larger renorm (the exponents do not depend on it)")
    if spec.name not in _QR_TYPES:
        raise UsageError(f"fp_type for {func} must be float or numpy.longdouble (its QR runs in the "
                         f"working type), got {spec}")
    return t0f, tf, rf, n_chunks


#: Most sample times one call accepts (each is a continuous-output evaluation and a row kept).
MAX_SAMPLES = 1_000_000


def _check_sample(sample, t0, t, end="t"):
    """``sample`` as a float64 array: finite, strictly increasing, in ``(t0, t]``, at most
    :data:`MAX_SAMPLES` long (``None`` passes through); ``end`` names ``t`` in the message."""
    if sample is None:
        return None
    try:
        s = np.atleast_1d(np.asarray(sample, dtype=float))
    except (TypeError, ValueError):
        s = np.array([np.nan])
    if s.ndim == 1 and s.size > MAX_SAMPLES:
        raise UsageError(f"sample has {s.size} times, more than MAX_SAMPLES = {MAX_SAMPLES}: sample more sparsely")
    if s.ndim != 1 or s.size == 0 or not np.all(np.isfinite(s)) or np.any(np.diff(s) <= 0) \
            or s[0] <= t0 or s[-1] > t:
        shown = repr(sample) if s.size <= 20 else f"{s.size} times from {s[0]!r} to {s[-1]!r}"
        raise UsageError(f"sample must be a non-empty increasing sequence of finite times in (t0, {end}] = "
                         f"({t0:g}, {t:g}], got {shown}")
    return s


def _sampled_chunk(ta, spec, t_end: float, samples, k: int):
    """Propagate ``ta`` to ``t_end`` (one chunk) and read its state at the sample times
    ``samples[k:] <= t_end`` off the chunk's continuous output (the Taylor polynomials of its
    steps: the same steps with or without samples, so the run is unchanged). Returns
    ``(res, [(t_i, state row)], k_next)`` with ``res`` heyoka's outcome tuple."""
    from ._propagate import _check_outcome

    inner = []
    if samples is not None:
        while k < len(samples) and samples[k] <= t_end:
            inner.append(float(samples[k]))
            k += 1
    res = ta.propagate_until(spec.scalar(t_end), c_output=bool(inner))
    _check_outcome(ta, res, t_end)
    # (copies: heyoka reuses the continuous output's buffer; at t_end the state itself)
    rows = [(ti, np.array(ta.state if ti == t_end else res[4](spec.scalar(ti)), copy=True)) for ti in inner]
    return res, rows, k


def _log_density(prob, public):
    """``ln rho`` of the invariant density in the problem's integrated variables."""
    from ._integrals import density

    info = prob.system.info
    coords = "public" if prob.formulation == info.public_formulation else "internal"
    return np.log(prob.spec.array([density(prob.kind, prob.params, public, coords=coords, check=False)])[0])


@renamed(t="t_end")
def lyapunov_spectrum(kind: Union[KindName, Problem], params: Union[ParamsLike, ArrayLike, None] = None,
                      state: Optional[ArrayLike] = None, t_end: Optional[float] = None, *, t0: float = 0.0,
                      renorm: float = 1.0, fp_type: FpTypeLike = float, prec: Optional[int] = None,
                      tol: Optional[float] = None, sample: Optional[ArrayLike] = None) -> LyapunovSpectrum:
    r"""The full Lyapunov spectrum of an orbit by Benettin's method.

    The system is integrated with its fundamental matrix ``Phi' = J Phi``
    (:class:`taylorball.tangent.TangentSystem`, ``vectors="all"``, compact mode) from
    ``Phi(t0) = E``; every ``renorm`` time units ``Phi`` is replaced by ``Q`` of its QR
    factorisation (``diag R > 0``) and ``ln R_ii`` is added to the running sums. The
    exponents are the sums over ``t - t0``. QR: numpy's Householder (LAPACK) in float64; in
    long double a Householder QR written in the working dtype (not modified Gram--Schmidt:
    Householder keeps ``Q`` orthogonal to ``O(n eps)`` whatever the conditioning).

    **What the spectrum contains.** The tangent vectors span all of the integrated ``R^n``
    (9 for reduced, 14 for full, 6 for M||gamma), including directions off the constraint
    manifold. The constraint functions (``gamma^2`` and ``(R, gamma)`` for reduced; the six
    entries of the frame's Gram matrix for full; ``gamma^2`` for M||gamma) are conserved by
    the equations *everywhere*, not only on the manifold (``v' = v x omega`` for
    ``v = gamma, alpha, beta``, and ``(R, gamma)' = (R x omega, gamma) + (R, gamma x omega)
    = 0`` identically), so ``dg Phi(t) = dg`` for each: the transverse exponents of the
    invariant sets ``|gamma| = 1``, ``(R, gamma) = 0`` are **zero**, one per constraint.
    On the manifold each independent first integral ``F`` (``dF Phi(t) = dF``; reduced:
    ``C2, M_gamma, E``; full: ``F1, F2, F3, E``; M||gamma: ``lambda, E``) gives one zero
    exponent and the flow direction (``Phi(t) X(x0) = X(x(t))``, bounded) one more. Zeros
    imposed by the structure: reduced ``2 + 3 + 1 = 6`` of 9, full ``6 + 4 + 1 = 11`` of 14
    (its symmetry field, rotation of the plane (paper eq. (14) [eq9]), is transverse to the level of
    ``F1, F2`` and so is not an extra one), M||gamma ``1 + 2 + 1 = 4`` of 6. The others are
    the exponents of the Poincaré map on an integral level: ``(lambda, -lambda)`` for the
    area-preserving map of M||gamma, ``(lambda1, lambda2, lambda3)`` with sum 0 for the
    volume-preserving 3D map of reduced and full. The reduced equations are reversible
    (``t -> -t`` with ``(omega, gamma, R) -> (S omega, S gamma, S R)`` for ``S = -E`` or a
    reflection in a principal plane of inertia: any improper ``S`` commuting with ``I``,
    since ``S(u x v) = -(Su x Sv)``; it preserves ``C2, M_gamma, E``), so on a chaotic
    component that the reversal maps to itself the spectrum is symmetric,
    ``lambda3 = -lambda1`` and ``lambda2 = 0``: then 7 of 9 (12 of 14) exponents vanish,
    as measured on the Fig. 4a level (``docs/chaos.md``). At finite ``t`` the zero
    exponents are ``O(ln(t)/t)``.

    **Their sum.** The flow preserves the measure ``rho dx`` (``rho`` =
    :func:`taylorball.density` in the integrated variables), so ``rho(x(t)) det Phi(t) =
    rho(x(t0))`` (Liouville) and, exactly for every finite ``t``,
    ``sum = ln det Phi / (t - t0) = -(ln rho(x(t)) - ln rho(x(t0))) / (t - t0)``:
    :attr:`LyapunovSpectrum.liouville_residual` is the difference, and
    :attr:`~LyapunovSpectrum.sum_error_bound` is the first-order bound
    ``n eps sum_k c_k (1 + sqrt(steps_k)) / (t - t0)`` on it: over chunk ``k`` each of the
    ``n`` tangent vectors carries a relative error ``~ eps`` from each Taylor step (random
    walk over ``steps_k`` steps) and from the QR, and ``R_ii`` is the part of vector ``i``
    orthogonal to the vectors before it, a fraction ``1/c_k`` of it at worst
    (``c_k = max_i |Phi_k e_i| / R_ii``), so ``ln R_ii`` is off by ``~ eps c_k`` per
    error. It is a worst case: measured residuals are ``10^-5 .. 10^-3`` of it.

    Parameters
    ----------
    kind : {"reduced", "full", "mparallel"} or Problem
        A system, or a :class:`taylorball.Problem` with ``params`` left out
        (``lyapunov_spectrum(prob, state, t_end)``; it then fixes ``fp_type``, ``prec``
        and ``tol``).
    params : BallParams or MParallelParams
    state : array_like
        Initial public state on the constraint manifold (within the default
        ``constraint_tol``; it is then projected in the working type).
    t_end : float
        End of the run (finite, > t0; ``t=`` is its deprecated old name).
    t0 : float
        Start of the clock.
    renorm : float
        Time between re-orthonormalisations (> 0; at most :data:`MAX_CHUNKS` of them). The
        last chunk ends at ``t_end``.
    fp_type : float or numpy.longdouble
    prec, tol
        As for :func:`taylorball.propagate`.
    sample : sequence of float, optional
        Increasing times in ``(t0, t]`` at which to record the running estimates (from a QR of
        ``Phi`` on the chunk's continuous output, which leaves the run itself unchanged); default: at
        every re-orthonormalisation.

    Returns
    -------
    LyapunovSpectrum

    Raises
    ------
    UsageError
        Bad kind, times, renorm, sample or number type.
    StateError, ConstraintError
        A state of the wrong shape or off the constraint manifold.
    IntegrationError
        If the integrator stops early.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, demo_reduced_state
    >>> spec = tb.lyapunov_spectrum("reduced", FIG4_BALL, demo_reduced_state(), 20.0)
    >>> spec.exponents.shape, spec.n_chunks        # 9 exponents, one QR per unit of time
    ((9,), 20)
    >>> bool(spec.maximal == spec.exponents.max())
    True
    >>> bool(abs(spec.liouville_residual) <= spec.sum_error_bound)   # the sum obeys Liouville
    True
    """
    from ._propagate import start_state

    prob, (state, t_end) = at_boundary("lyapunov_spectrum", kind, params, (state, t_end), ("state", "t_end"),
                                       fp_type=fp_type, prec=prec, tol=tol)
    spec = prob.spec
    t0f, tf, rf, _ = _check_spectrum_args(t0, t_end, renorm, spec)
    samples = _check_sample(sample, t0f, tf)
    internal = start_state(prob, state)
    acc = _Benettin(prob, t0f, rf, internal)
    x_end = _run_chunks(prob, internal, TangentSystem.of(prob, "all").identity(spec), t0f, tf, rf, samples, acc)
    return acc.result(x_end, tf)


def _run_chunks(prob, internal, tangents, t0: float, t: float, renorm: float, samples, acc) -> np.ndarray:
    """Integrate ``internal`` with the fundamental-matrix system (``vectors="all"``, compact
    mode) from ``t0`` to ``t`` in chunks ending at ``min(t0 + k renorm, t)`` (the lane engine's
    boundaries), the tangent block starting as ``tangents`` (flattened row-major). At each
    sample time ``acc.sample(Phi, t_i)`` (continuous output, the run unchanged); at each chunk
    end the tangent block is replaced by ``acc.chunk(Phi, t_k, steps, record=samples is None)``.
    Returns the internal state at ``t``."""
    spec = prob.spec
    ts = TangentSystem.of(prob, "all")
    ta = copy.copy(ts.template(prob, compact_mode=True))  # var_ode_sys: ~2 s compact, minutes otherwise
    ta.state[ts.x] = internal
    ta.state[ts.tangents] = tangents
    ta.pars[:] = prob.pars
    ta.time = spec.scalar(t0)
    k_sample = 0
    t_end, k = t0, 0
    while t_end < t:
        k += 1
        t_end = min(t0 + k * renorm, t)
        res, rows, k_sample = _sampled_chunk(ta, spec, t_end, samples, k_sample)
        for ts_i, row in rows:
            acc.sample(ts.tangent_matrix(row), ts_i)
        ta.state[ts.tangents] = acc.chunk(ts.tangent_matrix(ta.state), t_end, int(res[3]), record=samples is None)
    return np.array(ta.state[ts.x])


class _Benettin:
    """The running sums of one orbit's spectrum: after each chunk :meth:`chunk` takes the
    tangent matrix ``Phi`` and returns ``Q`` to put back (scalar and lane runs share it, so
    their arithmetic is the same)."""

    def __init__(self, prob, t0: float, renorm: float, internal):
        self.prob, self.spec, self.t0, self.renorm, self.internal = prob, prob.spec, t0, renorm, internal
        self.logs = np.zeros(prob.system.dim, dtype=prob.spec.dtype)
        self.times: List[float] = []
        self.partial: List[np.ndarray] = []
        self.cond_sum, self.n_steps, self.n_chunks = 0.0, 0, 0

    def _elapsed(self, t: float):
        """``t - t0`` in the working type: the integrator ran from ``t0`` to ``t`` (float64
        values) and their difference is exact in long double, not always in float64 (there
        a rounded ``t - t0`` would put a relative error ``eps64`` on the long double sum and
        ``~eps64 |Delta ln rho|`` on its Liouville residual); the same operation in float64."""
        return self.spec.scalar(t) - self.spec.scalar(self.t0)

    def sample(self, phi, t: float):
        """Record the running estimate at ``t`` from ``Phi(t)`` without changing the run."""
        _, Rs = _qr(phi, self.spec)
        self.times.append(t)
        self.partial.append(np.sort((self.logs + np.log(np.diagonal(Rs))) / self._elapsed(t))[::-1])

    def chunk(self, phi, t: float, steps: int, *, record: bool) -> np.ndarray:
        """Add ``ln R_ii`` of the chunk ending at ``t``; ``Q`` flattened (row-major)."""
        self.n_steps += steps
        self.n_chunks += 1
        Q, R = _qr(phi, self.spec)
        self.logs = self.logs + np.log(np.diagonal(R))
        Rf = np.asarray(R, dtype=float)
        kappa = float(np.max(np.linalg.norm(Rf, axis=0) / np.diagonal(Rf)))  # max_i |Phi_k e_i| / R_ii >= 1
        self.cond_sum += kappa * (1.0 + float(np.sqrt(max(steps, 0))))
        if record:
            self.times.append(t)
            self.partial.append(np.sort(self.logs / self._elapsed(t))[::-1])
        return Q.reshape(-1)

    def result(self, internal_end, t: float) -> LyapunovSpectrum:
        from ._propagate import public_state

        prob, spec, n = self.prob, self.spec, self.prob.system.dim
        T = self._elapsed(t)
        total = self.logs.sum() / T
        x0 = public_state(prob.system, prob.pars, self.internal, spec)
        x1 = public_state(prob.system, prob.pars, internal_end, spec)
        resid = total + (_log_density(prob, x1) - _log_density(prob, x0)) / T
        bound = n * spec.eps * self.cond_sum / (t - self.t0)
        return LyapunovSpectrum(
            exponents=np.sort(self.logs / T)[::-1], times=np.asarray(self.times, dtype=float),
            partial=np.asarray(self.partial, dtype=spec.dtype).reshape(len(self.times), n), sum=total,
            sum_error_bound=float(bound), liouville_residual=float(resid), kind=prob.kind, problem=prob,
            t0=self.t0, t=t, renorm=self.renorm, initial_state=x0, final_state=x1, n_chunks=self.n_chunks,
            n_steps=self.n_steps, cond_sum=float(self.cond_sum))


@renamed(t="t_end", threads="workers")
def lyapunov_spectra(kind: Union[KindName, Problem], params: Union[ParamsLike, StatesLike, None] = None,
                     states: Optional[StatesLike] = None, t_end: Optional[float] = None, *,
                     t0: float = 0.0, renorm: float = 1.0, workers: Optional[int] = None,
                     progress: ProgressLike = False, sample: Optional[ArrayLike] = None) -> List[LyapunovSpectrum]:
    """:func:`lyapunov_spectrum` of many float64 orbits, in the SIMD lanes of heyoka batch
    integrators (one per thread; :mod:`taylorball.ensemble`, ``backend="lanes"``), each lane
    refilled with the next orbit as soon as its orbit ends.

    Each orbit runs on its own clock through the same chunk boundaries ``t0 + k renorm`` as
    :func:`lyapunov_spectrum`, with the same QR, so its result depends only on its own state
    (bit-identical whatever the threads and companions); it agrees with
    :func:`lyapunov_spectrum` of the same state to rounding, not bitwise (heyoka's vectorised
    code rounds differently; on a chaotic orbit the two then separate as two float64 runs
    do). The batch variational system compiles in compact mode.

    Parameters
    ----------
    kind : {"reduced", "full", "mparallel"} or Problem
        As for :func:`lyapunov_spectrum` (``lyapunov_spectra(prob, states, t_end)``); a
        Problem must be float64 at the default tolerance (the lanes' integrators).
    states : array_like, shape (n, d), or sequence of states
        The initial public states, one per row.
    sample : sequence of float, optional
        As for :func:`lyapunov_spectrum`, the same times for every orbit: the running
        estimates at those times instead of at the re-orthonormalisation times, from a QR of
        ``Phi`` read off the continuous output of each lane's chunks (``LaneLoad.samples`` of
        :mod:`taylorball.ensemble`, as :func:`megno_many`); the steps and re-orthonormalisations
        are those of the run without ``sample``, so the exponents are bit-identical.
    workers : int, optional
        Worker threads (default ``os.cpu_count()``; ``threads=`` is its deprecated old name).
    progress : bool
        A progress bar over orbits.

    Other parameters as for :func:`lyapunov_spectrum` (float64 only).

    Returns
    -------
    list of LyapunovSpectrum
        In the order of ``states``. An orbit whose integration fails is rerun alone by
        :func:`lyapunov_spectrum`, which raises the error.
    """
    prob, (states, t_end) = at_boundary("lyapunov_spectra", kind, params, (states, t_end), ("states", "t_end"))
    prob = lane_problem("lyapunov_spectra", prob)
    t0f, tf, rf, _ = _check_spectrum_args(t0, t_end, renorm, prob.spec)
    samples = _check_sample(sample, t0f, tf)
    n = prob.system.dim

    def start(internal):
        return _Benettin(prob, t0f, rf, internal), np.eye(n).reshape(-1)

    def rerun(state):  # lyapunov_spectrum raises the integration error (named by run_many)
        return lyapunov_spectrum(prob, state, t_end, t0=t0, renorm=renorm, sample=sample)

    return _fundamental_lanes(prob, states, t0f, tf, rf, samples, start=start,
                              finish=lambda acc, internal, x_end: acc.result(x_end, tf), rerun=rerun,
                              workers=workers, progress=f"Lyapunov spectra to t={tf:g}" if progress is True else progress,
                              func="lyapunov_spectra", one="lyapunov_spectrum")


def _fundamental_lanes(prob, states, t0: float, t: float, renorm: float, samples, *, start, finish, rerun,
                       workers, progress, func, one) -> list:
    """Many float64 orbits with the fundamental-matrix system (``vectors="all"``, batch,
    compact mode) in the lane pool (:mod:`taylorball.ensemble`, ``backend="lanes"``): the lane
    counterpart of :func:`_run_chunks`, the same chunk boundaries ``min(t0 + k renorm, t)``
    and the same accumulator protocol. ``start(internal)`` gives a job's ``(acc, tangents)``
    (the tangent block flattened row-major); at each sample time ``acc.sample(Phi, t_i)``
    (the engine's continuous output, ``LaneLoad.samples``), at each chunk end the block is
    replaced by ``acc.chunk(Phi, t_k, steps, record=samples is None)``, and at ``t`` the
    job's result is ``finish(acc, internal, x_end)``. A job whose integration fails is
    ``rerun(state)`` alone in the caller's thread (which raises the error)."""
    from ._propagate import start_state
    from .ensemble import LaneLoad, LaneTask, run_many

    if workers is not None:
        count("workers", workers)
    states = _states_list(prob, states, func, one)
    work = [start_state(prob, s) for s in states]
    ts = TangentSystem.of(prob, "all")
    template = ts.batch_template(compact_mode=True)
    n = ts.n
    accs: list = [None] * len(states)
    out: list = [None] * len(states)
    failed = [False] * len(states)
    pars = np.asarray(prob.pars, dtype=float)

    def load(j):
        accs[j], tangents = start(work[j])
        x = np.asarray(work[j], dtype=float)
        return LaneLoad(np.concatenate([x, np.asarray(tangents, dtype=float)]), pars, t0, t, renorm, samples=samples)

    def after_chunk(ta, chunks):
        for c in chunks:
            acc = accs[c.job]
            for ti, row in c.samples:
                acc.sample(row[n:].reshape(n, n), ti)
            col = ta.state[:, c.lane]
            ta.state[n:, c.lane] = acc.chunk(col[n:].reshape(n, n), c.t, c.steps, record=samples is None)
            if c.last:
                out[c.job] = finish(acc, work[c.job], np.array(col[:n]))
                accs[c.job] = None
        return [False] * len(chunks)

    def on_fail(j, outcome, t_fail):
        failed[j] = True

    def result(j):
        return rerun(states[j]) if failed[j] else out[j]

    task = LaneTask(template, len(states), load=load, after_chunk=after_chunk, failed=on_fail, result=result)
    return run_many(task, backend="lanes", workers=workers, progress=progress)


# ---------------------------------------------------------------------------------------
# GALI_k, the generalised alignment index (Skokos, Bountis & Antonopoulos 2007)
# ---------------------------------------------------------------------------------------
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
