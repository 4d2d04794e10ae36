r"""Observables of a long run reduced on the fly from the orbit: running extremes
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
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from ._vec import dot, norm2
from .errors import UsageError
from .numbers import count, real_number

__all__ = ["time_in_bins", "sheet_signs", "hermite_quadrature"]

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
    from ._cfunc_columns import along_flow, cfunc_columns
    from .model import public_system

    def graph():
        import heyoka as hy

        system = public_system(kind)
        xs = hy.make_vars(*system.internal_names)
        pars = [hy.par[i] for i in range(system.n_pars)]
        v = system.vectors(system.constants(pars), xs)
        rhs = system.rhs(pars, xs)
        ddt = along_flow(xs, rhs)

        f0 = norm2(v["R"])
        g0 = dot(v["omega"], v["gamma"])
        f1, g1 = ddt(f0), ddt(g0)
        return [f0, f1, ddt(f1), g0, g1, ddt(g1)], xs

    cf = cfunc_columns(("cfunc", "orbit jets", kind), graph, compact_mode=True)

    def evaluate(public, pars):
        return cf(np.asarray(public, dtype=float), np.asarray(pars, dtype=float))

    return evaluate


def _hermite5(y0, d0, s0, y1, d1, s1, h, s):
    """Quintic Hermite interpolant on ``[t, t + h]`` matching value, first and second
    derivative at both ends, at the fractions ``s`` (broadcast); its error is
    ``h^6 |y^(6)| / 46080`` at most (``max |s^3 (1-s)^3| / 6! = 1/(64 * 720)``)."""
    # Written twice on purpose: _angle_lift.hermite_coefficients gives the monomial
    # coefficients of the same polynomial (the lifted angle's bounds need them); evaluated
    # through those it would round differently (81 % of the values on 1e5 random inputs) and
    # change the stored extremes and histograms, so this keeps the Hermite-basis form.
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


#: Bounds of ``|H_k(s)|`` on ``[0, 1]`` for the quintic Hermite basis of the first and second
#: derivatives (:func:`_hermite5`): ``s (1-s)^3 (1+3s)`` and ``-s^3 (1-s) (4-3s)`` reach
#: ``16/81 = 0.1975...``, ``s^2 (1-s)^3 / 2`` and ``s^3 (1-s)^2 / 2`` reach ``0.01728``; rounded up.
_H_D, _H_DD = 0.2, 0.018
#: The slack of :func:`_reach` in units of the interval's scale: the evaluation of
#: :func:`_hermite5` rounds by a few tens of eps of that scale; 1e-10 is ~5e5 eps.
_REACH_SLACK = 1e-10


def _reach(y0, d0, s0, y1, d1, s1, h):
    """Lower and upper bounds of the quintic Hermite interpolant (:func:`_hermite5`) on
    each interval, as evaluated in float64: ``H_0 + H_3 = 1`` with both in ``[0, 1]`` puts
    the value part between the ends' values; the derivative parts add at most
    ``h (0.2 |d| ...) + h^2 (0.018 |s| ...)``, and the slack covers the evaluation's rounding."""
    w = h * (_H_D * (np.abs(d0) + np.abs(d1))) + h * h * (_H_DD * (np.abs(s0) + np.abs(s1)))
    slack = _REACH_SLACK * (np.abs(y0) + np.abs(y1) + h * (np.abs(d0) + np.abs(d1))
                            + h * h * (np.abs(s0) + np.abs(s1)))
    return np.minimum(y0, y1) - w - slack, np.maximum(y0, y1) + w + slack


def _stationary_points(t, y, d, dd, within=None):
    """Times and interpolated values of the interior stationary points of the quintic
    Hermite interpolant in the sample intervals where ``d`` changes sign (bisection on the
    interpolant's slope to ``2^-36`` of the interval).

    ``within = (lo, hi)``: only the intervals where the interpolant can reach ``<= lo`` or
    ``>= hi`` (:func:`_reach`); the points of the others lie strictly between, so the
    extremes of the samples and points together, and which point or sample attains them
    first, are the same as with every interval (each point's value is computed elementwise,
    the same bits in any subset)."""
    idx = np.flatnonzero(d[:-1] * d[1:] < 0)
    if idx.size and within is not None:
        lo_i, hi_i = _reach(y[idx], d[idx], dd[idx], y[idx + 1], d[idx + 1], dd[idx + 1], t[idx + 1] - t[idx])
        idx = idx[(lo_i <= within[0]) | (hi_i >= within[1])]
    if idx.size == 0:
        return np.empty(0), np.empty(0)
    h = t[idx + 1] - t[idx]
    args = (y[idx], d[idx], dd[idx], y[idx + 1], d[idx + 1], dd[idx + 1], h)
    lo, hi = np.zeros(idx.size), np.ones(idx.size)
    sign_lo = np.sign(d[idx])
    for _ in range(36):  # 2^-36 h ~ 4e-12: the value is off by ~|f''| (4e-12)^2, far below the interpolant's error
        mid = 0.5 * (lo + hi)
        same = np.sign(_hermite5_slope(*args, mid)) == sign_lo
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    s = 0.5 * (lo + hi)
    return t[idx] + s * h, _hermite5(*args, s)


# ---------------------------------------------------------------------------------------
# extremes
# ---------------------------------------------------------------------------------------
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


def level_radius_bound(prob: Any, public: np.ndarray) -> float:
    """The rigorous bound :func:`taylorball.contact.radius_bound` on ``|R|`` of the level
    ``(C, h)`` of the public state ``public`` (``C = |M|``, ``h = E``; for a system without
    section levels, the full one, ``|M|`` and ``E`` of the same state)."""
    from ._integrals import integrals
    from .contact import radius_bound
    from .model import public_system

    ints = integrals(prob.kind, prob.params, public)
    if prob.system.info.levels is not None:
        lev = prob.system.info.levels(ints)
        C, h = lev["C"], lev["h"]
    else:
        system = public_system(prob.kind)
        M = system.vectors(system.constants(tuple(float(v) for v in prob.params.pars)),
                           tuple(float(v) for v in public))["M"]
        C, h = math.sqrt(sum(float(m) ** 2 for m in M)), float(ints["E"])
    return float(radius_bound(prob.params, C, h))
