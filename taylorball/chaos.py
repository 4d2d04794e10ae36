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
from typing import List, Optional, Union

import numpy as np
from numpy.typing import ArrayLike

from ._problem import Problem, at_boundary, lane_problem
from ._typing import FpTypeLike, KindName, ParamsLike, ProgressLike, StatesLike
from .errors import UsageError
from .numbers import count, real_number
from ._deprecation import moved, options_of
from .tangent import JACOBIANS, NORMS, SEED_KINDS, TangentSystem

__all__ = ["ChaosIndicators", "MegnoOptions", "megno", "megno_many", "LyapunovSpectrum", "lyapunov_spectrum", "lyapunov_spectra",
           "GALI", "gali", "gali_many", "MAX_CHUNKS", "MAX_SAMPLES"]

#: Compact mode per system of the scalar tangent-vector system in :func:`megno` (measured
#: here; :func:`megno_many` chooses by the amount of work, :data:`DEFAULT_MODE_WORK`): the M||gamma
#: system compiles in ~10 s in default mode and then runs 4.5x faster than in compact mode;
#: the reduced system takes ~26 s to compile in default mode for a 1.5x gain, so it stays
#: compact; so does the full system (its default-mode compile time not measured: a larger
#: graph than the reduced one's, 31 equations against 21).
#: Non-float types always use compact mode (see taylorball.numbers).
_DEFAULT_COMPACT = {"reduced": True, "full": True, "mparallel": False}


def _tangents(prob: Problem, norm: str = "full", jacobian: str = "symbolic") -> TangentSystem:
    """The problem's system with one tangent vector and the MEGNO/FLI integrands."""
    return TangentSystem.of(prob, "one", indicators=True, norm=norm, jacobian=jacobian)



#: At most this many chunks (renormalisations, Python round trips) per orbit: with the
#: default chunk of 50 time units, runs up to 5e7 time units.
MAX_CHUNKS = 1_000_000


def _check_args(kind, t0, t_end, chunk=50.0, stop_above=None, norm="compact", jacobian="symbolic"):
    if not isinstance(kind, str) or kind not in SEED_KINDS:
        raise UsageError(f"kind must be one of {SEED_KINDS} for chaos indicators, got {kind!r}")
    if not isinstance(jacobian, str) or jacobian not in JACOBIANS:
        raise UsageError(f"jacobian must be one of {JACOBIANS} (how the tangent equation's J d is formed: "
                         f"'forward' differentiation of the vector field, or 'symbolic' derivatives of each "
                         f"component, the values of earlier releases), got {jacobian!r}")
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
#: 9.3 s compile + 1.8 s run: ~30 000. These were measured with ``jacobian="symbolic"`` (the
#: default); the forward form compiles the reduced system in default mode in ~5 s, so for it
#: the thresholds are conservative (kept: they decide which compiled code, hence which bits,
#: a run of a given size gets).
DEFAULT_MODE_WORK = {"reduced": 150_000.0, "full": 150_000.0, "mparallel": 30_000.0}


@dataclass(frozen=True)
class MegnoOptions:
    """The less common options of :func:`megno_many` and :func:`taylorball.chaotic_fraction`
    (``options=tb.MegnoOptions(...)``; their old keywords of the same names are deprecated).

    Attributes
    ----------
    t0 : float
        Start of the clock (> 0), as for :func:`megno`.
    chunk : float
        Time between the tangent vector's renormalisations, as for :func:`megno`.
    seed : int
        Seed of each orbit's random initial tangent vector, as for :func:`megno`.
    compact_mode : bool, optional
        heyoka's compact mode for the batch tangent system; ``None`` picks default mode
        (faster, long to compile once) when ``len(states) * (t_end - t0)`` is at least
        :data:`DEFAULT_MODE_WORK` of the system, compact mode otherwise.
    jacobian : {"forward", "symbolic"}
        How the tangent equation ``d' = J d`` forms ``J d`` (:mod:`taylorball.tangent`).
        ``"symbolic"`` (default): heyoka's derivative of each component, the equations of
        earlier releases, whose results (and the figures' documented numbers) it reproduces
        bit for bit. ``"forward"``: forward-mode differentiation of the vector field, ~4x
        faster per step on the reduced system (223 elementary operations instead of 599). The two agree to rounding in
        ``J d`` (a few eps); on a regular orbit ``<Y>`` then differs in the last ~10
        digits, on a chaotic one, as any two float64 runs of it, by O(1) after the orbit
        has amplified the rounding (docs/benchmarks.md, "MEGNO maps").
    """

    t0: float = 1.0
    chunk: float = 50.0
    seed: int = 0
    compact_mode: Optional[bool] = None
    jacobian: str = "symbolic"


@moved(MegnoOptions, "t0", "chunk", "seed", "compact_mode", renamed={"threads": "workers"})
def megno_many(kind: Union[KindName, Problem], params: Union[ParamsLike, StatesLike, None] = None,
               states: Optional[StatesLike] = None, t_end: Optional[float] = None, *,
               stop_above: Optional[float] = None, sample: Optional[ArrayLike] = None, norm: str = "compact",
               workers: Optional[int] = None, progress: ProgressLike = False,
               options: Optional[MegnoOptions] = None) -> List[ChaosIndicators]:
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
    options : MegnoOptions, optional
        The start of the clock ``t0``, the renormalisation ``chunk``, the tangent vectors'
        ``seed`` and heyoka's ``compact_mode`` (default ``MegnoOptions()``; the keywords
        ``t0=``, ``chunk=``, ``seed=``, ``compact_mode=`` are their deprecated old form).

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
    from .ensemble import LaneLoad, orbit_lanes
    from ._propagate import start_state

    prob, (states, t_end) = at_boundary("megno_many", kind, params, (states, t_end), ("states", "t_end"))
    prob = lane_problem("megno_many", prob)
    kind = prob.kind
    opts = options_of(options, MegnoOptions, "megno_many")
    t0, chunk, seed, compact_mode = opts.t0, opts.chunk, opts.seed, opts.compact_mode
    _check_args(kind, t0, t_end, chunk, stop_above, norm, opts.jacobian)
    count("seed", seed, lo=0)
    if workers is not None:
        count("workers", workers)
    states = _states_list(prob, states, "megno_many", "megno")
    samples = _check_sample(sample, float(t0), float(t_end), end="t_end")
    work = [start_state(prob, s) for s in states]
    pars = np.asarray(prob.pars, dtype=float)
    if compact_mode is None:
        compact_mode = len(states) * (t_end - t0) < DEFAULT_MODE_WORK[kind]
    ts = _tangents(prob, norm, opts.jacobian)
    template = ts.batch_template(compact_mode=compact_mode)
    n = ts.system.dim
    series: list = [None if samples is None else [] for _ in states]  # (t, y, w, ell) per orbit

    def load(j):
        x = np.asarray(work[j], dtype=float)
        d0 = ts.seed(x, np.random.default_rng(seed))
        return LaneLoad(np.concatenate([x, d0, np.zeros(3)]), pars,
                        float(t0), float(t_end), float(chunk), samples=samples)

    def on_chunk(ta, c):
        if series[c.job] is not None:
            series[c.job] += [(ti, *(float(v) for v in row[2 * n :])) for ti, row in c.samples]
        col = ta.state[:, c.lane]
        d = col[n : 2 * n]
        ta.state[n : 2 * n, c.lane] = d / np.sqrt(np.sum(d * d))  # linear equation: exact rescaling
        stop = stop_above is not None and float(col[2 * n + 1]) / (c.t - t0) > stop_above
        if stop or c.last:
            yv, wv, fli = (float(v) for v in col[2 * n :])
            return stop, _indicators(c.t, float(t0), yv, wv, fli, series[c.job], norm)
        return stop, None

    def rerun(j, outcome, t):  # alone: megno raises the integration error (named by run_many)
        return megno(prob, states[j], t_end, t0=t0, chunk=chunk, seed=seed, stop_above=stop_above, sample=sample,
                     norm=norm)

    # progress in orbits, advanced by each chunk (the fraction of [t0, t_end]; a run stopped
    # early counts as whole)
    return orbit_lanes(template, len(states), load=load, on_chunk=on_chunk, rerun=rerun, workers=workers,
                       progress=f"MEGNO to t={t_end:g}" if progress is True else progress)


# The Lyapunov spectrum and GALI live in their own modules (on the shared variational
# chunk loop of ``_variational``); they are public here, where they are documented.
from ._gali import GALI, gali, gali_many  # noqa: E402
from ._lyapunov import LyapunovSpectrum, lyapunov_spectra, lyapunov_spectrum  # noqa: E402
from ._variational import MAX_SAMPLES, _check_sample, _householder_qr, _sampled_chunk, _states_list  # noqa: E402,F401
