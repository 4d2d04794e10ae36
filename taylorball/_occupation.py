"""Occupation of a region against an invariant density: :func:`occupation` (TV or
Hellinger distance of the histogram of an orbit's crossings to a density, against time,
with the i.i.d. floor). Public through :mod:`taylorball.transport`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional, Sequence, Union

import numpy as np
from numpy.typing import ArrayLike

from .errors import UsageError


def _readonly(a):
    a = np.array(a, copy=True)
    a.flags.writeable = False
    return a


def _check_int(name, value, minimum):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise UsageError(f"{name} must be an integer >= {minimum}; got {value!r}")
    return int(value)


# ---------------------------------------------------------------------------------------
# occupation of a region vs an invariant density
# ---------------------------------------------------------------------------------------
OCCUPATION_METRICS = ("tv", "hellinger")


@dataclass(frozen=True)
class Occupation:
    """Distance between the histogram of an orbit's points up to each time and a reference
    distribution over the same bins (:func:`occupation`).

    ``at``: the times; ``n``: points counted at each (``times <= at``); ``distance``: the
    distance at each (``nan`` while ``n = 0``); ``metric``; ``reference``: the reference bin
    probabilities (shape of the bins, sum 1); ``floor``: at each time, the large-``n``
    expectation of the total-variation distance of ``n`` *independent* draws from the
    reference, ``0.5 sum_i sqrt(2 q_i (1 - q_i) / (pi n))`` (for ``metric="tv"``; for
    ``"hellinger"`` ``sqrt((B - 1) / (8 n))`` with ``B`` the bins of nonzero ``q``): an orbit's
    points are correlated, so its distance sits above this even when it fills its region
    with the reference density; ``outside``: the fraction of the points at the last time
    outside every bin (counted as mass the reference does not have)."""

    at: np.ndarray
    n: np.ndarray
    distance: np.ndarray
    metric: str
    reference: np.ndarray
    floor: np.ndarray
    outside: float


def _gauss_bin_probabilities(density, edges, quad):
    """Integrals of ``density`` over the bins, by ``quad``-point Gauss-Legendre in each
    dimension of each bin (exact for polynomials of degree ``2 quad - 1`` per coordinate)."""
    x, w = np.polynomial.legendre.leggauss(quad)
    nodes, weights = [], []
    for e in edges:
        mid, half = 0.5 * (e[1:] + e[:-1]), 0.5 * (e[1:] - e[:-1])
        nodes.append((mid[:, None] + half[:, None] * x[None, :]).ravel())
        weights.append((half[:, None] * w[None, :]).ravel())
    grids = np.meshgrid(*nodes, indexing="ij")
    pts = np.column_stack([g.ravel() for g in grids])
    vals = np.asarray(density(pts), dtype=float).reshape(-1)
    if vals.shape[0] != pts.shape[0]:
        raise UsageError(f"density must return one value per point: called with {pts.shape[0]} points of "
                         f"shape {pts.shape}, returned {vals.shape[0]} values")
    if not np.all(np.isfinite(vals)) or np.any(vals < 0):
        bad = int(np.flatnonzero(~(np.isfinite(vals) & (vals >= 0)))[0])
        raise UsageError(f"density must be finite and >= 0; density({pts[bad].tolist()}) = {vals[bad]!r}")
    W = weights[0]
    for wk in weights[1:]:
        W = np.multiply.outer(W, wk)
    cell = vals.reshape(W.shape) * W
    shape = tuple(len(e) - 1 for e in edges)
    for k, nb in enumerate(shape):  # sum the quad nodes of each bin
        cell = cell.reshape(cell.shape[:k] + (nb, quad) + cell.shape[k + 1:]).sum(axis=k + 1)
    return cell


def occupation(points: ArrayLike, times: ArrayLike, density: Union[Callable[[np.ndarray], ArrayLike], ArrayLike],
               bins: Sequence[ArrayLike], *, at: Optional[ArrayLike] = None, metric: str = "tv",
               quad: int = 4) -> Occupation:
    """How an orbit's points fill a region over time, against a reference density.

    For each time ``a`` in ``at``, the points with ``times <= a`` are binned; the distance
    between their normalised histogram and the reference bin probabilities is returned
    (total variation ``0.5 sum |p_i - q_i|``, or Hellinger ``sqrt(1 - sum sqrt(p_i q_i))``;
    both in ``[0, 1]``). Points outside every bin count as probability the reference does
    not have. For the section-4 map: ``points`` the crossings' chart points ``(l, r1, r2)``
    (the ``sections`` observable of a long run), ``density`` the invariant density of the
    map with its sheets merged, :func:`taylorball.section_sigma` (does a chaotic orbit
    fill its region with the invariant density?).

    Parameters
    ----------
    points : array_like (n, d)
        The points, in the order of ``times``.
    times : array_like (n,)
        Non-decreasing times of the points.
    density : callable or array_like
        Either ``density(pts (m, d)) -> (m,)`` values ``>= 0`` (any normalisation),
        integrated over each bin by ``quad``-point Gauss-Legendre per coordinate, or the
        reference bin weights directly, an array of the bins' shape (``>= 0``, any
        normalisation).
    bins : sequence of d array_like
        Strictly increasing bin edges per coordinate (at least 2 each).
    at : array_like, optional
        Times at which to measure (default: 20 times log-spaced between the first and the
        last point's). Sorted internally.
    metric : {"tv", "hellinger"}
    quad : int
        Gauss points per coordinate and bin (1 .. 16) for a callable ``density``.

    Returns
    -------
    Occupation

    Examples
    --------
    >>> import numpy as np
    >>> import taylorball as tb
    >>> rng = np.random.default_rng(0)
    >>> pts = rng.uniform(size=(10000, 2))                  # i.i.d. uniform on the unit square
    >>> occ = tb.transport.occupation(pts, np.arange(10000.0), lambda p: np.ones(len(p)),
    ...                               [np.linspace(0, 1, 11)] * 2, at=[99.0, 9999.0])
    >>> occ.n.tolist(), occ.distance.round(2).tolist()   # falls like n^-1/2 ...
    ([100, 10000], [0.39, 0.05])
    >>> occ.floor.round(2).tolist()                      # ... at the i.i.d. expectation
    [0.4, 0.04]
    """
    try:
        P = np.asarray(points, dtype=float)
        t = np.asarray(times, dtype=float)
    except (TypeError, ValueError) as exc:
        raise UsageError(f"points (n, d) and times (n,) must be real arrays ({exc})") from None
    if P.ndim != 2 or P.shape[0] < 1:
        raise UsageError(f"points must be a 2-D array (n, d) with n >= 1, one point per row; got shape {P.shape}")
    n, d = P.shape
    if t.shape != (n,):
        raise UsageError(f"times must have shape ({n},), one per point; got {t.shape}")
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(t))):
        raise UsageError("points and times must be finite (no nan or inf)")
    if np.any(np.diff(t) < 0):
        bad = int(np.flatnonzero(np.diff(t) < 0)[0])
        raise UsageError(f"times must be non-decreasing; times[{bad}] = {t[bad]!r} > times[{bad + 1}] = {t[bad + 1]!r}")
    if not isinstance(metric, str) or metric not in OCCUPATION_METRICS:
        raise UsageError(f"metric must be one of {OCCUPATION_METRICS}, got {metric!r}")
    quad = _check_int("quad", quad, 1)
    if quad > 16:
        raise UsageError(f"quad must be an integer in 1 .. 16, got {quad!r}")
    try:
        edges = [np.asarray(e, dtype=float) for e in bins]
    except (TypeError, ValueError):
        raise UsageError(f"bins must be a sequence of {d} arrays of bin edges, got {bins!r}") from None
    if len(edges) != d:
        raise UsageError(f"bins must give edges for each of the {d} coordinates of the points, got {len(edges)}")
    for k, e in enumerate(edges):
        if e.ndim != 1 or e.size < 2 or not np.all(np.isfinite(e)) or np.any(np.diff(e) <= 0):
            raise UsageError(f"bins[{k}] must be at least 2 finite, strictly increasing edges; got {e!r}")
    shape = tuple(e.size - 1 for e in edges)
    if int(np.prod(shape, dtype=np.float64)) > 10**7:
        raise UsageError(f"bins make {np.prod(shape, dtype=np.float64):.3g} cells; at most 1e7")
    if callable(density):
        q = _gauss_bin_probabilities(density, edges, quad)
    else:
        try:
            q = np.asarray(density, dtype=float)
        except (TypeError, ValueError):
            raise UsageError(f"density must be a callable or an array of bin weights of shape {shape}") from None
        if q.shape != shape or not np.all(np.isfinite(q)) or np.any(q < 0):
            raise UsageError(f"density as bin weights must be a finite array >= 0 of shape {shape} (the bins); "
                             f"got shape {q.shape}")
    total = q.sum()
    if not total > 0:
        raise UsageError("the reference density has zero mass over the bins")
    q = q / total
    if at is None:
        lo = t[0] if t[0] > 0 else (t[t > 0][0] if np.any(t > 0) else 1.0)
        at = np.geomspace(lo, max(t[-1], lo), 20)
    at = np.sort(np.asarray(at, dtype=float).reshape(-1))
    if at.size == 0 or not np.all(np.isfinite(at)):
        raise UsageError(f"at must be finite times (a non-empty 1-D array), got {at!r}")
    # flat bin index per point; the last index (prod(shape)) is "outside every bin"
    idx = np.zeros(n, dtype=np.int64)
    inside = np.ones(n, dtype=bool)
    for k, e in enumerate(edges):
        j = np.searchsorted(e, P[:, k], side="right") - 1
        j = np.where(P[:, k] == e[-1], e.size - 2, j)  # the last edge closes the last bin
        inside &= (j >= 0) & (j < e.size - 1)
        idx = idx * (e.size - 1) + np.clip(j, 0, e.size - 2)
    m = int(np.prod(shape))
    idx = np.where(inside, idx, m)
    qf = np.append(q.ravel(), 0.0)
    ends = np.searchsorted(t, at, side="right")
    counts = np.zeros(m + 1)
    dist = np.full(at.size, np.nan)
    start = 0
    for a, end in enumerate(ends):
        counts += np.bincount(idx[start:end], minlength=m + 1)
        start = end
        if end == 0:
            continue
        p = counts / end
        dist[a] = 0.5 * np.abs(p - qf).sum() if metric == "tv" else math.sqrt(max(0.0, 1.0 - np.sqrt(p * qf).sum()))
    nn = np.maximum(ends, 1).astype(float)
    if metric == "tv":
        floor = 0.5 * np.sum(np.sqrt(2 * q.ravel() * (1 - q.ravel()) / math.pi)) / np.sqrt(nn)
    else:
        floor = np.sqrt((np.count_nonzero(q) - 1) / (8 * nn))
    floor = np.where(ends > 0, floor, np.nan)
    return Occupation(at=_readonly(at), n=_readonly(ends.astype(np.int64)), distance=_readonly(dist), metric=metric,
                      reference=_readonly(q), floor=_readonly(floor),
                      outside=float(counts[m] / max(start, 1)))
