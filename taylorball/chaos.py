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
from dataclasses import dataclass
from typing import List, Optional, Sequence

import numpy as np

from .errors import StateError, UsageError
from .numbers import count, real_number
from .tangent import SEED_KINDS, TangentSystem

__all__ = ["ChaosIndicators", "megno", "megno_many"]

#: Compact mode per system for the tangent-vector system (measured here): the M||gamma
#: system compiles in ~10 s in default mode and then runs 4.5x faster than in compact mode;
#: the reduced system takes ~26 s to compile in default mode for a 1.5x gain, so it stays
#: compact. Non-float types always use compact mode (see taylorball.numbers).
_DEFAULT_COMPACT = {"reduced": True, "mparallel": False}


def _tangents(kind) -> TangentSystem:
    """The system of ``kind`` with one tangent vector and the MEGNO/FLI integrands."""
    from .model import get_system

    return TangentSystem(get_system(kind), "one", indicators=True)


def _batch_template(kind, compact):
    """``(system, template)``: the float64 batch integrator of the tangent system (cached; copy it)."""
    ts = _tangents(kind)
    return ts.system, ts.batch_template(compact_mode=compact)


def _tangent_seed(kind, x, rng):
    """A random unit tangent vector to the constraint manifold at internal state x."""
    return _tangents(kind).seed(x, rng)


#: At most this many chunks (renormalisations, Python round trips) per orbit: with the
#: default chunk of 50 time units, runs up to 5e7 time units.
MAX_CHUNKS = 1_000_000


def _check_args(kind, t0, t_end, chunk=50.0, stop_above=None):
    if not isinstance(kind, str) or kind not in SEED_KINDS:
        raise UsageError(f"kind must be one of {SEED_KINDS} for chaos indicators, got {kind!r}")
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


@dataclass(frozen=True)
class ChaosIndicators:
    """Indicators of one orbit at ``t``: ``megno`` (``Y(t)``), ``mean_megno``
    (``<Y>(t)``), ``fli`` (``ln |delta(t)|/|delta(0)|``), and the estimate of the largest
    Lyapunov exponent ``fli / (t - t0)``."""

    t: float
    megno: float
    mean_megno: float
    fli: float
    lyapunov: float


def megno(kind: str, params, state, t_end: float, *, t0: float = 1.0, chunk: float = 50.0, fp_type=float,
          prec: Optional[int] = None, seed: int = 0, stop_above: Optional[float] = None) -> ChaosIndicators:
    """MEGNO and FLI of an orbit of the reduced or M||gamma system.

    Parameters
    ----------
    kind : {"reduced", "mparallel"}
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

    Raises
    ------
    UsageError
        Bad kind or times.
    IntegrationError
        If the integrator stops early.
    """
    from ._problem import problem
    from ._propagate import _check_outcome, working_state

    _check_args(kind, t0, t_end, chunk, stop_above)
    count("seed", seed, lo=0)
    prob = problem(kind, params, fp_type=fp_type, prec=prec)
    spec = prob.spec
    ts = TangentSystem.of(prob, "one", indicators=True)
    tmpl = ts.template(prob, compact_mode=spec.compact_mode or _DEFAULT_COMPACT[kind])
    _, pars, internal = working_state(kind, params, state, spec)
    d0 = spec.array(ts.seed(internal, np.random.default_rng(seed)))
    ta = copy.copy(tmpl)
    ta.state[ts.x] = internal
    ta.state[ts.tangents] = d0
    ta.state[ts.indicators_slice] = spec.array(np.zeros(3))
    ta.pars[:] = pars
    ta.time = spec.scalar(t0)
    t = float(t0)
    while t < t_end:
        t = min(t + chunk, float(t_end))
        _check_outcome(ta, ta.propagate_until(spec.scalar(t)), t)
        dn = np.sqrt(sum(v * v for v in ta.state[ts.tangents]))
        ta.state[ts.tangents] = ta.state[ts.tangents] / dn  # linear equation: rescaling is exact
        if stop_above is not None and float(ta.state[ts.megno_w]) / (t - t0) > stop_above:
            break
    yv, wv, fli = (float(v) for v in ta.state[ts.indicators_slice])
    T = t
    return ChaosIndicators(t=T, megno=2 * yv / T, mean_megno=wv / (T - t0), fli=fli, lyapunov=fli / (T - t0))


#: Compact mode of the batch tangent system when ``megno_many(compact_mode=None)``: compact
#: (compiles in < 1 s) below this much work (orbits x time units), default mode above. Measured
#: here (reduced system, 4 lanes, one thread, per orbit and 1000 time units): compact 0.37 s,
#: default mode 0.20 s, for ~28 s of compilation once per machine (heyoka keeps compiled code
#: in its disk cache), so default mode pays for itself on a cold cache from ~150 000 orbit time
#: units on; with a warm cache it always does (callers who run often pass ``compact_mode=False``).
DEFAULT_MODE_WORK = 150_000.0


def megno_many(kind: str, params, states: Sequence, t_end: float, *, t0: float = 1.0, chunk: float = 50.0,
               seed: int = 0, stop_above: Optional[float] = None, threads: Optional[int] = None,
               compact_mode: Optional[bool] = None, progress: bool = False) -> List[ChaosIndicators]:
    """:func:`megno` for many float64 orbits at once, in the SIMD lanes of heyoka batch
    integrators (one per thread), a lane refilled with the next orbit as soon as one ends
    (at ``t_end`` or, with ``stop_above``, once ``<Y>`` passes it): see
    :mod:`taylorball.ensemble` (``mode="lanes"``).

    Each orbit runs on its own clock through the same chunk boundaries as :func:`megno`,
    with the same seed for its tangent vector, so its result depends only on its own state:
    bit-identical whatever the number of threads and the orbits around it. It agrees with
    :func:`megno` of the same state to rounding, not bitwise (heyoka's vectorised code rounds
    differently; on a chaotic orbit the two then separate as any two float64 runs do).

    Parameters
    ----------
    compact_mode : bool, optional
        heyoka's compact mode for the batch tangent system; ``None`` picks default mode
        (faster, long to compile once) when ``len(states) * (t_end - t0)`` is at least
        :data:`DEFAULT_MODE_WORK`, compact mode otherwise.
    threads : int, optional
        Worker threads (default ``os.cpu_count()``).
    progress : bool
        A progress bar over orbits.

    Other parameters as for :func:`megno`.

    Returns
    -------
    list of ChaosIndicators
        In the order of ``states``. An orbit whose integration fails is rerun alone by
        :func:`megno`, which raises the error.
    """
    from .ensemble import LaneLoad, LaneTask, run_many
    from .numbers import resolve_fp_type
    from ._propagate import working_state

    _check_args(kind, t0, t_end, chunk, stop_above)
    count("seed", seed, lo=0)
    if threads is not None:
        count("threads", threads)
    try:
        states = list(states)
    except TypeError:
        raise StateError(f"states must be a sequence of initial states, got {states!r}") from None
    if not states:
        raise UsageError("states must contain at least one initial state")
    spec = resolve_fp_type(float)
    work = [working_state(kind, params, s, spec) for s in states]
    if compact_mode is None:
        compact_mode = _DEFAULT_COMPACT[kind] and len(states) * (t_end - t0) < DEFAULT_MODE_WORK
    system, template = _batch_template(kind, compact_mode)
    n = system.dim
    out: list = [None] * len(states)
    failed = [False] * len(states)

    def load(j):
        x = np.asarray(work[j][2], dtype=float)
        d0 = _tangent_seed(kind, x, np.random.default_rng(seed))
        return LaneLoad(np.concatenate([x, d0, np.zeros(3)]), np.asarray(work[j][1], dtype=float),
                        float(t0), float(t_end), float(chunk))

    def after_chunk(ta, chunks):
        done = []
        for c in chunks:
            col = ta.state[:, c.lane]
            d = col[n : 2 * n]
            ta.state[n : 2 * n, c.lane] = d / np.sqrt(np.sum(d * d))  # linear equation: exact rescaling
            stop = stop_above is not None and float(col[2 * n + 1]) / (c.t - t0) > stop_above
            if stop or c.last:
                yv, wv, fli = (float(v) for v in col[2 * n :])
                out[c.job] = ChaosIndicators(t=c.t, megno=2 * yv / c.t, mean_megno=wv / (c.t - t0), fli=fli,
                                             lyapunov=fli / (c.t - t0))
            done.append(stop)
        return done

    def result(j):
        if failed[j]:  # rerun alone: megno raises the integration error (named by run_many)
            return megno(kind, params, states[j], t_end, t0=t0, chunk=chunk, seed=seed, stop_above=stop_above)
        return out[j]

    def on_fail(j, outcome, t):
        failed[j] = True

    # progress in orbits, advanced by each chunk (the fraction of [t0, t_end]; a run stopped
    # early counts as whole)
    task = LaneTask(template, len(states), load=load, after_chunk=after_chunk, failed=on_fail, result=result)
    return run_many(task, mode="lanes", workers=threads,
                    progress=f"MEGNO to t={t_end:g}" if progress is True else progress)
