r"""The variational chunk loop shared by the chaos indicators (:mod:`taylorball.chaos`):
a tangent system integrated in chunks, the tangent block handed to an accumulator at each
chunk end (and at sample times, off the chunk's continuous output), in one scalar
integrator (:func:`_run_chunks`) or in the SIMD lanes of the engine
(:func:`_fundamental_lanes`, on :func:`taylorball.ensemble.orbit_lanes`); the QR
factorisations, the argument checks and the many-orbit states list they share.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from ._problem import Problem
from .errors import StateError, UsageError
from .numbers import count
from .tangent import TangentSystem

#: At most this many chunks (renormalisations, Python round trips) per orbit: with the
#: default chunk of 50 time units, runs up to 5e7 time units.
MAX_CHUNKS = 1_000_000

#: Number types the spectrum supports: numpy's QR is float64-only, so the long double
#: QR is a Householder factorisation written here in the working dtype (see _qr).
_QR_TYPES = ("float", "longdouble")


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
    from .ensemble import LaneLoad, orbit_lanes

    if workers is not None:
        count("workers", workers)
    states = _states_list(prob, states, func, one)
    work = [start_state(prob, s) for s in states]
    ts = TangentSystem.of(prob, "all")
    template = ts.batch_template(compact_mode=True)
    n = ts.n
    accs: list = [None] * len(states)
    pars = np.asarray(prob.pars, dtype=float)

    def load(j):
        accs[j], tangents = start(work[j])
        x = np.asarray(work[j], dtype=float)
        return LaneLoad(np.concatenate([x, np.asarray(tangents, dtype=float)]), pars, t0, t, renorm, samples=samples)

    def on_chunk(ta, c):
        acc = accs[c.job]
        for ti, row in c.samples:
            acc.sample(row[n:].reshape(n, n), ti)
        col = ta.state[:, c.lane]
        ta.state[n:, c.lane] = acc.chunk(col[n:].reshape(n, n), c.t, c.steps, record=samples is None)
        if c.last:
            accs[c.job] = None
            return False, finish(acc, work[c.job], np.array(col[:n]))
        return False, None

    return orbit_lanes(template, len(states), load=load, on_chunk=on_chunk,
                       rerun=lambda j, outcome, t: rerun(states[j]),
                       workers=workers, progress=progress)
