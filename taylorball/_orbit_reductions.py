r"""Observables of a long run reduced on the fly from the orbit (issue 10): running extremes
of ``|R|``, a histogram of ``|R|`` over time, the section crossings, the ball's lifted
heading. Each is a frozen dataclass following the observable interface of
:mod:`taylorball.observables` (``options``, ``events``, ``layout``, ``init``, ``chunk``).

What ``R`` is (paper section 1, eq. (1) [eq1]): ``R = x alpha + y beta`` is the radius
vector of the ball's centre measured from the rotation axis, written in body axes;
``(x, y)`` are the centre's (= the contact point's) coordinates in the *fixed* frame
``Oxyz`` whose ``z`` axis is the axis of rotation (paper eq. (10) [eq6]: ``dx/dt = -Omega
y + a (omega, beta)``: the ``-Omega y`` is the plane's velocity under the contact point, seen
from the fixed frame). Since ``(R, gamma) = 0``, ``|R|^2 = x^2 + y^2``: ``|R|`` *is* the
contact point's distance from the rotation axis in the fixed frame, and, the plane turning
about that same axis, also in the plane's rotating frame (the rotating-frame position is
``(x, y)`` turned by ``-Omega t``: same distance). :func:`taylorball.contact_trajectory`
gives ``(x, y)`` in the fixed frame with ``F1 = 0`` (section 3); the tests check
``x^2 + y^2 = |R|^2`` there. So one pair of extremes serves both frames.

Why no event for the extremes. An extra non-terminal event whose expression shares a
sub-expression with the vector field (``omega``, or even a product of parameters like
``m a Omega``) changes heyoka's decomposition of the whole system and with it the rounding
of the Taylor coefficients of the *orbit*: measured here on the Fig. 4a orbit, an event on
``d|R|^2/dt = 0`` (written with ``omega``) changed the step count over 2000 time units from
33307 to 33253 and the final state completely (a chaotic orbit); an event ``R1 gamma1``
changed it too. The orbit's bits must not depend on which observables are on, so the
extremes, the histogram and the heading are computed from the states on the run's sample
grid (``ChunkData.public``), with the time derivatives of the observed quantity from a
separate compiled function (:func:`_jets`): a quintic Hermite interpolant between samples.
The section event is the exception: its expression uses only the state variables ``M``,
``gamma`` and leaves the orbit's bits unchanged (checked in the tests).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from ._cache import compiled
from ._vec import dot, norm2
from .errors import UsageError
from .numbers import count, real_number
from .observables import ChunkData, Var, grid_ratio, register

__all__ = ["Extremes", "Histogram", "Sections", "Heading"]

#: Sub-intervals per sample interval on which the histogram follows the interpolated
#: ``|R|(t)`` as a broken line (see :class:`Histogram`).
HIST_SUBSTEPS = 8


# ---------------------------------------------------------------------------------------
# derivatives along the flow, and the quintic Hermite interpolant
# ---------------------------------------------------------------------------------------
def _jets(kind: str):
    """Compiled float64 ``public states -> (|R|^2, d/dt, d^2/dt^2, (omega, gamma), d/dt,
    d^2/dt^2)`` (time derivatives along the vector field of the public formulation, paper
    eqs. (15)-(16) [eq10], by heyoka's symbolic differentiation); cached. Returns
    ``f(public (n, dim), pars) -> (6, n)``."""
    from .model import public_system

    def build():
        import heyoka as hy

        system = public_system(kind)
        xs = hy.make_vars(*system.internal_names)
        pars = [hy.par[i] for i in range(system.n_pars)]
        v = system.vectors(system.constants(pars), xs)
        rhs = system.rhs(pars, xs)

        def ddt(e):
            return hy.sum([hy.diff(e, x) * f for x, f in zip(xs, rhs)])

        f0 = norm2(v["R"])
        g0 = dot(v["omega"], v["gamma"])
        f1, g1 = ddt(f0), ddt(g0)
        cf = hy.cfunc([f0, f1, ddt(f1), g0, g1, ddt(g1)], xs, compact_mode=True)
        return cf, threading.Lock()

    cf, lock = compiled(("cfunc", "orbit jets", kind), build)

    def evaluate(public, pars):
        X = np.ascontiguousarray(np.asarray(public, dtype=float).T)
        p = np.asarray(pars, dtype=float).reshape(-1)[: cf.nparams]
        with lock:  # a cfunc holds scratch buffers: one call at a time
            return cf(X, pars=np.ascontiguousarray(np.repeat(p[:, None], X.shape[1], axis=1)))

    return evaluate


def _hermite5(y0, d0, s0, y1, d1, s1, h, s):
    """Quintic Hermite interpolant on ``[t, t + h]`` matching value, first and second
    derivative at both ends, at the fractions ``s`` (broadcast); its error is
    ``h^6 |y^(6)| / 46080`` at most (``max |s^3 (1-s)^3| / 6! = 1/(64 * 720)``)."""
    s2 = s * s
    s3 = s2 * s
    s4 = s3 * s
    s5 = s4 * s
    return (y0 * (1 - 10 * s3 + 15 * s4 - 6 * s5) + h * d0 * (s - 6 * s3 + 8 * s4 - 3 * s5)
            + h * h * s0 * 0.5 * (s2 - 3 * s3 + 3 * s4 - s5) + y1 * (10 * s3 - 15 * s4 + 6 * s5)
            + h * d1 * (-4 * s3 + 7 * s4 - 3 * s5) + h * h * s1 * 0.5 * (s3 - 2 * s4 + s5))


def _hermite5_slope(y0, d0, s0, y1, d1, s1, h, s):
    """Time derivative of :func:`_hermite5` at the fractions ``s``."""
    s2 = s * s
    s3 = s2 * s
    s4 = s3 * s
    return ((y0 - y1) * (-30 * s2 + 60 * s3 - 30 * s4) + h * d0 * (1 - 18 * s2 + 32 * s3 - 15 * s4)
            + h * h * s0 * 0.5 * (2 * s - 9 * s2 + 12 * s3 - 5 * s4) + h * d1 * (-12 * s2 + 28 * s3 - 15 * s4)
            + h * h * s1 * 0.5 * (3 * s2 - 8 * s3 + 5 * s4)) / h


def _stationary_points(t, y, d, dd):
    """Times and interpolated values of the interior stationary points of the quintic
    Hermite interpolant in the sample intervals where ``d`` changes sign (bisection on the
    interpolant's slope to the last bit of ``s``)."""
    idx = np.flatnonzero(d[:-1] * d[1:] < 0)
    if idx.size == 0:
        return np.empty(0), np.empty(0)
    h = t[idx + 1] - t[idx]
    args = (y[idx], d[idx], dd[idx], y[idx + 1], d[idx + 1], dd[idx + 1], h)
    lo, hi = np.zeros(idx.size), np.ones(idx.size)
    sign_lo = np.sign(d[idx])
    for _ in range(60):  # 2^-60 of an interval: below the rounding of t
        mid = 0.5 * (lo + hi)
        same = np.sign(_hermite5_slope(*args, mid)) == sign_lo
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    s = 0.5 * (lo + hi)
    return t[idx] + s * h, _hermite5(*args, s)


def _need_levels(prob, who: str):
    if prob.system.info.levels is None or prob.system.info.contact is None:
        raise UsageError(f"the observable {who!r} needs a ball's reduced system (kind 'reduced'); "
                         f"got kind {prob.kind!r}")


def _f64(a) -> np.ndarray:
    return np.asarray(a, dtype=np.float64).reshape(1)


# ---------------------------------------------------------------------------------------
# extremes
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Extremes:
    r"""Running minimum and maximum of ``|R|``, the contact point's distance from the
    rotation axis (fixed frame and rotating frame alike, see the module docstring; paper
    eq. (1) [eq1]).

    Per chunk the records are the chunk's ``r_min``, ``r_max`` and their times
    ``t_r_min``, ``t_r_max`` (append dimension ``chunk``); the carry holds the running
    values (the running extremes are also the cumulative min/max of the records).

    Accuracy: candidates are the samples and, in every sample interval where ``d|R|^2/dt``
    changes sign, the stationary point of the quintic Hermite interpolant of ``|R|^2``
    (value, first and second time derivative at both samples, from :func:`_jets`): error
    ``<= h^6 max|d^6 |R|^2/dt^6| / 46080`` per interval (``h = sample_dt``). Measured on
    the Fig. 4a orbit (``sample_dt = 0.25``) against a 1/256 grid of the same orbit: in
    ``tests/test_observables_orbit.py``. A pair of extremes inside one sample interval (a
    local max and min closer than ``sample_dt``) is missed; it cannot hold the running
    extreme unless ``|R|`` turns twice within ``sample_dt``.
    Storage: 4 float64 per chunk (6.4 MB per 1e8 time units at ``checkpoint_every = 500``).
    """

    name: str = "extremes"

    def options(self) -> Dict[str, Any]:
        return {}

    def events(self, prob) -> list:
        return []

    def layout(self, prob) -> Dict[str, Var]:
        doc = {"r_min": "min |R| over the chunk", "r_max": "max |R| over the chunk",
               "t_r_min": "time of r_min", "t_r_max": "time of r_max"}
        return {k: Var(("chunk",), "float64", doc=d) for k, d in doc.items()}

    def init(self, prob, x0, t0) -> Dict[str, np.ndarray]:
        _need_levels(prob, self.name)
        return {"n": np.zeros(1, dtype=np.int64), "r_min": _f64(0.0), "r_max": _f64(0.0),
                "t_r_min": _f64(t0), "t_r_max": _f64(t0)}

    def chunk(self, carry, data: ChunkData):
        J = _jets(data.problem.kind)(data.public, data.problem.params.pars)
        t = np.asarray(data.t, dtype=float)
        ts, ys = _stationary_points(t, J[0], J[1], J[2])
        tt = np.concatenate([t, ts])
        yy = np.concatenate([J[0], ys])
        i, j = int(np.argmin(yy)), int(np.argmax(yy))
        rec = {"r_min": _f64(math.sqrt(max(yy[i], 0.0))), "r_max": _f64(math.sqrt(max(yy[j], 0.0))),
               "t_r_min": _f64(tt[i]), "t_r_max": _f64(tt[j])}
        first = int(carry["n"][0]) == 0
        new = {"n": carry["n"] + 1}
        lo = first or rec["r_min"][0] < carry["r_min"][0]
        hi = first or rec["r_max"][0] > carry["r_max"][0]
        new["r_min"], new["t_r_min"] = (rec["r_min"], rec["t_r_min"]) if lo else (carry["r_min"], carry["t_r_min"])
        new["r_max"], new["t_r_max"] = (rec["r_max"], rec["t_r_max"]) if hi else (carry["r_max"], carry["t_r_max"])
        return new, rec


# ---------------------------------------------------------------------------------------
# histogram
# ---------------------------------------------------------------------------------------
def time_in_bins(t, r, edges) -> np.ndarray:
    """Time a broken line ``r(t)`` (through the points ``(t_i, r_i)``) spends in each bin.

    Returns ``len(edges) + 1`` times: below ``edges[0]``, in ``[edges[j-1], edges[j])`` for
    ``j = 1 .. len(edges) - 1``, at or above ``edges[-1]``. Exact for the broken line (each
    segment is split at the edges it crosses), so the times sum to ``t[-1] - t[0]`` up to
    rounding.
    """
    t = np.asarray(t, dtype=float)
    r = np.asarray(r, dtype=float)
    edges = np.asarray(edges, dtype=float)
    nb = edges.size + 1
    dt = np.diff(t)
    lo = np.minimum(r[:-1], r[1:])
    hi = np.maximum(r[:-1], r[1:])
    i0 = np.searchsorted(edges, lo, side="right")
    i1 = np.searchsorted(edges, hi, side="right")
    same = i0 == i1
    out = np.bincount(i0[same], weights=dt[same], minlength=nb).astype(float)
    cr = np.flatnonzero(~same)
    if cr.size:
        L, H, D, a, b = lo[cr], hi[cr], dt[cr], i0[cr], i1[cr]
        w = D / (H - L)  # H > L: the segment straddles an edge
        out += np.bincount(a, weights=w * (edges[a] - L), minlength=nb)
        out += np.bincount(b, weights=w * (H - edges[b - 1]), minlength=nb)
        n_mid = b - a - 1
        if n_mid.sum():
            seg = np.repeat(np.arange(cr.size), n_mid)
            start = np.repeat(np.cumsum(n_mid) - n_mid, n_mid)
            j = a[seg] + 1 + (np.arange(seg.size) - start)
            out += np.bincount(j, weights=w[seg] * (edges[j] - edges[j - 1]), minlength=nb)
    return out


@dataclass(frozen=True)
class Histogram:
    r"""Time spent by ``|R|`` in ``bins`` equal bins of ``[0, r_max)`` (plus the time at or
    above ``r_max``, which the default ``r_max`` makes zero).

    ``r_max`` defaults to the rigorous bound :func:`taylorball.contact.radius_bound` of
    the orbit's own level ``(C, h)`` (so no time can fall above it); it is then per orbit
    and kept in the carry. The carry holds the running histogram (``time``, ``bins + 1``
    float64: the last entry is the time at or above ``r_max``); it is recorded (append
    dimension ``snapshot``, with ``t_snapshot``) after chunks ``k`` with ``k + 1`` a power
    of two, so the records show the convergence over time in log-spaced snapshots
    (``log2`` of the number of chunks of them) and the carry has the latest.

    Accuracy: ``|R|(t)`` is followed as a broken line through ``HIST_SUBSTEPS`` (8) points
    per sample interval of the quintic Hermite interpolant of ``|R|^2`` (see
    :class:`Extremes`), and the time in each bin is exact for that broken line
    (:func:`time_in_bins`); the counts sum to the elapsed time to rounding. The broken line
    is off by at most ``(h/8)^2 max|d^2|R|/dt^2| / 8``; measured against a 1/512 grid of
    the same orbit: ``tests/test_observables_orbit.py``.
    Storage: ``(bins + 2)`` float64 per snapshot (~60 kB per 1e8 time units for 200 bins).
    """

    bins: int = 200
    r_max: Optional[float] = None
    name: str = "histogram"

    def __post_init__(self):
        object.__setattr__(self, "bins", count("histogram bins", self.bins, lo=1, hi=100_000))
        if self.r_max is not None:
            object.__setattr__(self, "r_max", real_number("histogram r_max", self.r_max, lo=0.0, lo_open=True))

    def options(self) -> Dict[str, Any]:
        return {"bins": self.bins, "r_max": self.r_max, "substeps": HIST_SUBSTEPS}

    def events(self, prob) -> list:
        return []

    def layout(self, prob) -> Dict[str, Var]:
        return {"time": Var(("snapshot", "bin"), "float64", (self.bins + 1,),
                            doc="time spent by |R| in each bin of [0, r_max) so far; last: at or above r_max"),
                "t_snapshot": Var(("snapshot",), "float64", doc="time of the snapshot")}

    def init(self, prob, x0, t0) -> Dict[str, np.ndarray]:
        _need_levels(prob, self.name)
        return {"time": np.zeros(self.bins + 1), "r_max": _f64(0.0 if self.r_max is None else self.r_max)}

    def _r_max(self, carry, data) -> float:
        if carry["r_max"][0] > 0:
            return float(carry["r_max"][0])
        from ._integrals import integrals
        from .contact import radius_bound

        ints = integrals(data.problem.kind, data.problem.params, data.public[0])
        lev = data.problem.system.info.levels(ints)
        return float(radius_bound(data.problem.params, lev["C"], lev["h"]))

    def chunk(self, carry, data: ChunkData):
        r_max = self._r_max(carry, data)
        J = _jets(data.problem.kind)(data.public, data.problem.params.pars)
        t = np.asarray(data.t, dtype=float)
        h = np.diff(t)[:, None]
        s = np.arange(HIST_SUBSTEPS)[None, :] / HIST_SUBSTEPS
        y = _hermite5(J[0][:-1, None], J[1][:-1, None], J[2][:-1, None], J[0][1:, None], J[1][1:, None],
                      J[2][1:, None], h, s)
        tt = np.append((t[:-1, None] + h * s).ravel(), t[-1])
        rr = np.sqrt(np.maximum(np.append(y.ravel(), J[0][-1]), 0.0))
        occ = time_in_bins(tt, rr, np.linspace(0.0, r_max, self.bins + 1))
        # occ[0] is below 0 (never); the bins, then the time at or above r_max
        new = {"time": carry["time"] + occ[1:], "r_max": _f64(r_max)}
        k = int(data.k) + 1
        if k & (k - 1) == 0:
            rec = {"time": new["time"][None, :].copy(), "t_snapshot": _f64(data.t1)}
        else:
            rec = {"time": np.empty((0, self.bins + 1)), "t_snapshot": np.empty(0)}
        return new, rec


# ---------------------------------------------------------------------------------------
# section crossings
# ---------------------------------------------------------------------------------------
#: ``|dE/dtheta|`` below this fraction of the energy scale leaves K's sheet undecided (0):
#: the central difference's error (truncation ~delta^2, rounding ~eps/delta relative) is
#: ~1e-10 of the scale.
SHEET_TOL = 1e-8
_SHEET_STEP = 1e-5


def sheet_signs(params, internal) -> np.ndarray:
    r"""K's sheet of reduced states on the section: the sign of ``dE/dK`` at fixed chart
    point ``(l, r1, r2)``, section angle ``g`` and levels ``(C, M_gamma)`` of each state.

    On the section the chart point ``(l, r1, r2)`` fixes the state up to ``K = M3``, a
    root of the energy equation ``E(K; l, r1, r2, g0) = h`` (paper section 4; the inverse
    chart, :func:`taylorball.states_on_section`, returns all roots ordered by ``K``).
    Between consecutive simple roots ``E - h`` changes sign, so the roots alternate in the
    sign of ``dE/dK``: ``K`` together with this sign tells the sheets apart, the sign alone
    tells the two sheets of a fold apart (where two roots meet, ``dE/dK = 0``, the section
    map's density ``sigma = rho5 |g'| / |dE/dK|`` is singular). Computed by a central
    difference in ``theta`` (``K = C cos theta``) of the energy on the chart
    (``charts._reduced_energy_theta``); ``0`` where ``|dE/dtheta|`` is below
    ``SHEET_TOL`` times the energy scale (undecided: at a fold).

    Parameters
    ----------
    params : BallParams
    internal : ndarray (n, 9)
        Internal (momentum form) reduced states on the section.

    Returns
    -------
    ndarray (n,) of int8 in {-1, 0, 1}
    """
    from .charts import _reduced_energy_theta, g_angle_parts

    X = np.asarray(internal, dtype=float).reshape(-1, 9)
    if X.shape[0] == 0:
        return np.zeros(0, dtype=np.int8)
    M, g, R = X[:, 0:3].T, X[:, 3:6].T, X[:, 6:9].T
    C = np.sqrt(np.sum(X[:, 0:3] ** 2, axis=1))
    Mg = np.sum(X[:, 0:3] * X[:, 3:6], axis=1)
    l = np.arctan2(M[0], M[1])
    r1 = R[0] * g[0] + R[1] * g[1]
    r2 = R[0] * g[1] - R[1] * g[0]
    num, den = g_angle_parts(tuple(M), tuple(g))
    gg = np.arctan2(num, den)
    th = np.arccos(np.clip(M[2] / C, -1.0, 1.0))
    # each state at its own levels (C, M_gamma): they differ from the orbit's by the drift
    e = [_reduced_energy_theta(params, C, Mg, l, r1, r2, gg, th + sg * _SHEET_STEP, with_gdot=False)[0]
         for sg in (1.0, -1.0)]
    dE = (e[0] - e[1]) / (2 * _SHEET_STEP)  # dE/dtheta; dK/dtheta = -C sin(theta) < 0
    scale = np.maximum(np.maximum(np.abs(e[0]), np.abs(e[1])), C * C / max(params.inertia))
    out = np.where(np.abs(dE) > SHEET_TOL * scale, np.where(dE > 0, -1, 1), 0).astype(np.int8)
    return out


@dataclass(frozen=True)
class Sections:
    r"""Crossings of the section ``g = g0`` (direction +1: ``g`` increasing), found by the
    :class:`taylorball.Section` event (heyoka's roots of the event polynomial, Newton-refined
    in time; paper section 4), every ``every``-th kept (``every = 1``: ``"all"``), thinned
    by the running crossing count in the carry, so the kept crossings do not depend on the
    chunking.

    Records (append dimension ``crossing``): ``t``, the chart point ``l``, ``r1``, ``r2``,
    ``K = M3`` and ``sheet`` (int8, :func:`sheet_signs`). Storage: 41 bytes per kept
    crossing; the Fig. 4a orbit crosses ~0.63 times per time unit: 2.6 GB per 1e8 time
    units with ``"all"``, 86 MB with ``every = 30``.
    """

    every: int = 1
    g0: float = 0.0
    name: str = "sections"

    def __post_init__(self):
        object.__setattr__(self, "every", count("sections (every Nth crossing)", self.every, lo=1, hi=10**12))
        g0 = real_number("sections g0", self.g0, lo=0.0, hi=2 * math.pi)
        if g0 >= 2 * math.pi:
            raise UsageError(f"sections g0 must be in [0, 2 pi), got {self.g0!r}")
        object.__setattr__(self, "g0", g0)

    def options(self) -> Dict[str, Any]:
        return {"every": self.every, "g0": self.g0, "direction": 1}

    def section(self, prob):
        from .sections import Section

        return Section(prob, self.g0, 1)

    def events(self, prob) -> list:
        _need_levels(prob, self.name)
        if prob.formulation != prob.system.info.default_formulation:
            raise UsageError(f"the observable 'sections' needs the {prob.system.info.default_formulation!r} "
                             f"formulation (the section event is written in M), got {prob.formulation!r}")
        return [self.section(prob).event()]

    def layout(self, prob) -> Dict[str, Var]:
        doc = {"t": "crossing time", "l": "chart angle l = atan2(M1, M2) in [0, 2 pi)",
               "r1": "R1 gamma1 + R2 gamma2", "r2": "R1 gamma2 - R2 gamma1", "K": "K = M3"}
        out = {k: Var(("crossing",), "float64", doc=d) for k, d in doc.items()}
        out["sheet"] = Var(("crossing",), "int8", doc="K's sheet: sign of dE/dK at fixed (l, r1, r2, g0); 0 at a fold")
        return out

    def init(self, prob, x0, t0) -> Dict[str, np.ndarray]:
        return {"n": np.zeros(1, dtype=np.int64)}

    def chunk(self, carry, data: ChunkData):
        from .sections import START_TOL

        prob = data.problem
        recs = list(data.events.get(0, []))
        sec = self.section(prob)
        times = [t for t, _ in recs]
        states = [x for _, x in recs]
        keep = sec.on_branch(states) if recs else np.zeros(0, dtype=bool)
        keep &= np.array([float(t) > START_TOL for t in times], dtype=bool)
        idx = np.flatnonzero(keep)
        n0 = int(carry["n"][0])
        mine = idx[(n0 + np.arange(idx.size)) % self.every == 0]
        X = np.array([np.asarray(states[i], dtype=float) for i in mine]).reshape(-1, prob.system.dim)
        pts = sec.chart(X) if len(X) else np.empty((0, 3))
        rec = {"t": np.array([float(times[i]) for i in mine], dtype=float), "l": pts[:, 0], "r1": pts[:, 1],
               "r2": pts[:, 2], "K": X[:, 2].copy(), "sheet": sheet_signs(prob.params, X)}
        return {"n": np.array([n0 + idx.size], dtype=np.int64)}, rec


# ---------------------------------------------------------------------------------------
# heading
# ---------------------------------------------------------------------------------------
def hermite_quadrature(t, g, g1, g2) -> np.ndarray:
    r"""Integrals of ``g`` over the intervals ``[t_j, t_{j+1}]`` from its value, first and
    second derivative at both ends (the integral of the quintic Hermite interpolant):

    .. math:: \int_{t_j}^{t_j + h} g = \frac h2 (g_j + g_{j+1}) + \frac{h^2}{10} (g'_j - g'_{j+1})
              + \frac{h^3}{120} (g''_j + g''_{j+1}) + \frac{h^7}{100800} g^{(6)}(\xi).

    Order 6 (local error ``O(h^7)``)."""
    h = np.diff(np.asarray(t, dtype=float))
    return h * (0.5 * (g[:-1] + g[1:]) + h * (g1[:-1] - g1[1:]) / 10.0 + h * h * (g2[:-1] + g2[1:]) / 120.0)


@dataclass(frozen=True)
class Heading:
    r"""The ball's heading about the vertical, lifted (unbounded):
    ``psi(t) = int_0^t (omega, gamma) dt'``, the angle the ball has turned about the
    vertical (``(omega, gamma)`` is the vertical component of its angular velocity,
    ``gamma`` being the upward normal in body axes; paper section 1), recorded every
    ``every`` time units (``angles_every``; append dimension ``time``, with ``t``).

    There is no orientation angle about the vertical that is a function of the state alone
    (the spin about the vertical of a rolling ball is not integrable: ``psi`` depends on
    the path), so the heading is this integral, accumulated from the orbit's start.
    Relative to the rotating plane it is ``psi - Omega t``.

    Quadrature: on every sample interval, the integral of the quintic Hermite interpolant
    of ``(omega, gamma)`` from its value and first two time derivatives at the samples
    (:func:`hermite_quadrature`, order 6, local error ``h^7 |g^(6)| / 100800``); the running
    value is carried as a double-double (``psi_hi``, ``psi_lo``) with the chunk's sum by
    ``math.fsum``, so rounding does not accumulate over chunks. Measured against an
    independent long-double integration of ``psi' = (omega, gamma)`` appended to the
    reduced system (Fig. 4a orbit): 2.6e-3 rad per 10 time units at ``sample_dt = 0.25``,
    2.2e-5 at 0.125, 1.4e-8 at 0.0625 (``tests/test_observables_orbit.py``).
    Storage: 2 float64 per ``every`` (16 MB per 1e8 time units at 10).
    """

    every: float
    ratio: int
    name: str = "heading"

    def options(self) -> Dict[str, Any]:
        return {"every": self.every, "quadrature": "hermite5"}

    def events(self, prob) -> list:
        return []

    def layout(self, prob) -> Dict[str, Var]:
        return {"t": Var(("time",), "float64", doc="time"),
                "heading": Var(("time",), "float64", doc="lifted heading int (omega, gamma) dt (rad)")}

    def init(self, prob, x0, t0) -> Dict[str, np.ndarray]:
        _need_levels(prob, self.name)
        return {"psi_hi": _f64(0.0), "psi_lo": _f64(0.0)}

    def chunk(self, carry, data: ChunkData):
        J = _jets(data.problem.kind)(data.public, data.problem.params.pars)
        t = np.asarray(data.t, dtype=float)
        q = hermite_quadrature(t, J[3], J[4], J[5])
        hi, lo = float(carry["psi_hi"][0]), float(carry["psi_lo"][0])
        partial = np.concatenate([[0.0], np.cumsum(q)])
        at = data.fresh() & (np.asarray(data.i) % self.ratio == 0)
        rec = {"t": t[at].copy(), "heading": hi + (lo + partial[at])}
        S = math.fsum(q)
        s = hi + S
        bp = s - hi
        err = (hi - (s - bp)) + (S - bp)  # two-sum: s + err = hi + S exactly
        return {"psi_hi": _f64(s), "psi_lo": _f64(lo + err)}, rec


# ---------------------------------------------------------------------------------------
# [observables] keys
# ---------------------------------------------------------------------------------------
def _flag(key: str, v) -> bool:
    if not isinstance(v, bool):
        raise UsageError(f"observables.{key} must be true or false, got {v!r}")
    return v


@register(("extremes",), {"extremes": True}, order=40)
def _build_extremes(values, sample_dt):
    return [Extremes()] if _flag("extremes", values["extremes"]) else []


@register(("histogram",), {"histogram": False}, order=50)
def _build_histogram(values, sample_dt):
    v = values["histogram"]
    form = "false, true, or a table {bins = 200, r_max = <a radius>} (r_max defaults to contact.radius_bound)"
    if isinstance(v, bool):
        return [Histogram()] if v else []
    if not isinstance(v, dict) or set(v) - {"bins", "r_max"}:
        raise UsageError(f"observables.histogram must be {form}, got {v!r}")
    try:
        return [Histogram(**v)]
    except UsageError as exc:
        raise UsageError(f"observables.{exc}; observables.histogram must be {form}") from None


@register(("sections",), {"sections": False}, order=60)
def _build_sections(values, sample_dt):
    v = values["sections"]
    form = '"all", a positive integer N (every Nth crossing) or false'
    if v is False:
        return []
    if v == "all" and isinstance(v, str):
        return [Sections(1)]
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise UsageError(f"observables.sections must be {form}, got {v!r}")
    return [Sections(int(v))]


@register(("angles_every",), {"angles_every": 10.0}, order=70)
def _build_heading(values, sample_dt):
    every = values["angles_every"]
    ratio = grid_ratio("angles_every", every, sample_dt, allow_zero=True)
    return [Heading(float(every), ratio)] if ratio else []
