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
from typing import Optional

import numpy as np

from .errors import UsageError

__all__ = ["ChaosIndicators", "megno"]

_CACHE: dict = {}


#: Compact mode per system for the tangent-vector system (measured here): the M||gamma
#: system compiles in ~10 s in default mode and then runs 4.5x faster than in compact mode;
#: the reduced system takes ~26 s to compile in default mode for a 1.5x gain, so it stays
#: compact. Non-float types always use compact mode (see taylorball.numbers).
_DEFAULT_COMPACT = {"reduced": True, "mparallel": False}


def _template(kind, spec):
    import heyoka as hy

    from .model import get_system

    compact = spec.compact_mode or _DEFAULT_COMPACT[kind]
    key = (kind, str(spec), compact)
    if key in _CACHE:
        return _CACHE[key]
    system = get_system(kind)
    n = system.dim
    xs = hy.make_vars(*system.internal_names)
    ds = hy.make_vars(*[f"d_{v}" for v in system.internal_names])
    y, w, ell = hy.make_vars("megno_y", "megno_w", "fli")
    f = system.rhs([hy.par[i] for i in range(system.n_pars)], xs)
    Jd = [hy.sum([hy.diff(fi, xj) * dj for xj, dj in zip(xs, ds)]) for fi in f]
    lam = hy.sum([d * jd for d, jd in zip(ds, Jd)]) / hy.sum([d * d for d in ds])
    t = hy.time
    sys = list(zip(xs, f)) + list(zip(ds, Jd)) + [(y, t * lam), (w, 2.0 * y / t), (ell, lam)]
    kw = dict(fp_type=spec.fp_type, compact_mode=compact)
    if spec.prec is not None:
        kw["prec"] = spec.prec
    zero = spec.scalar(0.0)
    ta = hy.taylor_adaptive(sys, [spec.scalar(0.1)] * (2 * n + 3), pars=[zero] * system.n_pars, **kw)
    _CACHE[key] = (system, ta)
    return system, ta


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


def _tangent_seed(kind, x, rng):
    """A random unit tangent vector to the constraint manifold at internal state x."""
    d = rng.normal(size=len(x))
    g = np.asarray(x[3:6], dtype=float)
    g = g / np.linalg.norm(g)
    d[3:6] -= (d[3:6] @ g) * g  # keep |gamma| = 1 to first order
    if kind == "reduced":
        R = np.asarray(x[6:9], dtype=float)
        # (R, gamma) = 0 to first order: (dR, gamma) + (R, dgamma) = 0
        d[6:9] -= ((d[6:9] @ g) + (R @ d[3:6])) * g
    return d / np.linalg.norm(d)


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
    from .numbers import resolve_fp_type
    from .propagate import _check_outcome, working_state

    if kind not in ("reduced", "mparallel"):
        raise UsageError(f"kind must be 'reduced' or 'mparallel' for chaos indicators, got {kind!r}")
    if not (t0 > 0 and t_end > t0):
        raise UsageError(f"need 0 < t0 < t_end, got t0={t0!r}, t_end={t_end!r}")
    spec = resolve_fp_type(fp_type, prec)
    system, tmpl = _template(kind, spec)
    _, pars, internal = working_state(kind, params, state, spec)
    n = system.dim
    d0 = spec.array(_tangent_seed(kind, internal, np.random.default_rng(seed)))
    ta = copy.copy(tmpl)
    ta.state[:n] = internal
    ta.state[n : 2 * n] = d0
    ta.state[2 * n :] = spec.array(np.zeros(3))
    ta.pars[:] = pars
    ta.time = spec.scalar(t0)
    t = float(t0)
    while t < t_end:
        t = min(t + chunk, float(t_end))
        _check_outcome(ta, ta.propagate_until(spec.scalar(t)), t)
        dn = np.sqrt(sum(v * v for v in ta.state[n : 2 * n]))
        ta.state[n : 2 * n] = ta.state[n : 2 * n] / dn  # linear equation: rescaling is exact
        if stop_above is not None and float(ta.state[2 * n + 1]) / (t - t0) > stop_above:
            break
    yv, wv, fli = (float(v) for v in ta.state[2 * n :])
    T = t
    return ChaosIndicators(t=T, megno=2 * yv / T, mean_megno=wv / (T - t0), fli=fli, lyapunov=fli / (T - t0))
