r"""Sampling a section level (public from :mod:`taylorball.charts`): the section's
invariant density :func:`section_sigma`, draws from it (:func:`section_sigma_sample`) and
uniform draws of the admissible region (:func:`section_admissible_sample`).
"""

from __future__ import annotations

import math as _math
from typing import Any, Dict, Literal, Optional, Tuple

import numpy as _np
from numpy.typing import ArrayLike

from ._chart_reduced import (_SIGMA_DTHETA, _ball, _check_direction, _check_g0, _check_grid, _check_h,
                             _check_levels, _reduced_energy_theta, _rng, _roots_1d, _section_states,
                             angles_to_vectors)
from ._typing import SeedLike
from .errors import ChartError, EmptyLevelError
from .numbers import count, real_number
from .params import BallParams


def section_sigma(params: BallParams, *, C: float, M_gamma: float, h: float, points: ArrayLike,
                  g0: float = 0.0, direction: Optional[int] = 1, n_grid: int = 2001) -> _np.ndarray:
    r"""Density of the invariant volume form of the section-4 map, summed over the sheets.

    At a chart point ``(l, r1, r2)`` of the section ``g = g0`` on the level ``(C, M_gamma,
    h)``, every root ``K`` of the energy equation (a sheet; :func:`states_on_section`) with
    ``dg/dt`` of sign ``direction`` carries the density

    .. math:: \sigma = \frac{\rho_5\,|\dot g|}{|\partial E/\partial K|},\qquad
              \rho_5 = \frac{|D|^{-1/2}}{4\,C\,(\gamma_1^2 + \gamma_2^2)\,|\gamma_3|},\quad
              D = 1 - d\,(\gamma, A\gamma)

    (w.r.t. ``dl dr1 dr2``; the return map preserves ``sigma dl dr1 dr2``). This returns the
    sum over those sheets: the density of the section map's invariant measure in ``(l, r1,
    r2)`` with the sheets merged, what a histogram of an orbit's crossings over ``(l, r1,
    r2)`` converges to if the orbit is ergodic on its level (up to normalisation). The
    derivation and its mpmath check (the map preserves it: ``sigma(P x) |det DP| = sigma(x)``)
    are in :mod:`taylorball.verify.section_volume`, which evaluates the same formula
    independently in mpmath; here it is numpy, with ``dg/dt`` in closed form and ``dE/dK``
    by a central difference in ``theta`` (``K = C cos theta``; relative error ~1e-9).
    ``sigma`` is infinite at a fold (a double root, ``dE/dK = 0``); double roots are left
    out (measure zero).

    Parameters
    ----------
    params : BallParams
    C, M_gamma, h : float
        The levels ``|M|``, ``(M, gamma)``, ``E``.
    points : array_like (m, 3)
        Chart points ``(l, r1, r2)``.
    g0 : float
    direction : {1, -1, None}
        Sheets with ``g`` crossing ``g0`` increasing (+1), decreasing (-1), or all.
    n_grid : int
        Grid of the root search in ``theta`` (as :func:`states_on_section`).

    Returns
    -------
    ndarray (m,)
        ``0`` outside the admissible region.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> s = tb.section_sigma(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), points=[(2.0, 2.5, 1.0), (2.0, 50.0, 0.0)])
    >>> bool(s[0] > 0), float(s[1])              # the second point is outside the region
    (True, 0.0)
    """
    from .model import ball_constants

    params = _ball(params)
    C, M_gamma = _check_levels(C, M_gamma)
    h = _check_h(h)
    g0 = _check_g0(g0)
    _check_direction(direction)
    n_grid = _check_grid(n_grid)
    try:
        pts = _np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise ChartError(f"points must be an array of chart points (l, r1, r2), shape (m, 3); got {points!r}") from None
    if pts.ndim != 2 or pts.shape[1] != 3 or not _np.all(_np.isfinite(pts)):
        raise ChartError(f"points must be a finite array of chart points (l, r1, r2), shape (m, 3); got shape "
                         f"{pts.shape}" + ("" if _np.all(_np.isfinite(pts)) else " with non-finite entries"))
    c = ball_constants(params.pars)
    out = _np.zeros(len(pts))
    for j, (l, r1, r2) in enumerate(pts):
        def f(th):
            return _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g0, th, with_gdot=False)[0] - h

        th, mult = _roots_1d(f, 0.0, _math.pi, n_grid)
        th = th[(mult == 1) & (th > 0.0) & (th < _math.pi)]
        if th.size == 0:
            continue
        gdot = _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g0, th)[1]
        if direction is not None:
            th, gdot = th[_np.sign(gdot) == direction], gdot[_np.sign(gdot) == direction]
        if th.size == 0:
            continue
        ep = _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g0, th + _SIGMA_DTHETA, with_gdot=False)[0]
        em = _reduced_energy_theta(params, C, M_gamma, l, r1, r2, g0, th - _SIGMA_DTHETA, with_gdot=False)[0]
        dEdK = (ep - em) / (2 * _SIGMA_DTHETA) / (-C * _np.sin(th))
        rho5 = _sigma_rho5(c, C, M_gamma, th, l, g0)
        out[j] = float(_np.sum(rho5 * _np.abs(gdot) / _np.abs(dEdK)))
    return out


def _sigma_rho5(c, C, M_gamma, theta, l, g0):
    """``rho5 = |D|^(-1/2) / (4 C (gamma_1^2 + gamma_2^2) |gamma_3|)`` of :func:`section_sigma`
    at ``K = C cos(theta)`` (elementwise)."""
    _, gam = angles_to_vectors(C, M_gamma, C * _np.cos(theta), l, g0)
    D = 1 - c.d * (c.A[0] * gam[0] ** 2 + c.A[1] * gam[1] ** 2 + c.A[2] * gam[2] ** 2)
    return 1.0 / _np.sqrt(_np.abs(D)) / (4 * C * (gam[0] ** 2 + gam[1] ** 2) * _np.abs(gam[2]))


_SIGMA_SAMPLE_BLOCK = 1 << 18  # draws per vectorised block (~100 MB of temporaries)


def section_sigma_sample(params: BallParams, *, C: float, M_gamma: float, h: float, n: int, g0: float = 0.0,
                         direction: Optional[int] = 1, seed: SeedLike = 0) -> Dict[str, Any]:
    r"""Monte Carlo sample of the section map's invariant measure ``sigma dl dr1 dr2``
    (:func:`section_sigma`), with weights, free of its fold singularities.

    :func:`section_sigma` is ``sum_K rho5 |dg/dt| / |dE/dK|`` and diverges like
    ``1/sqrt(distance)`` at a fold of the level set over the chart (``dE/dK = 0``: the
    edge of the admissible region and the lines where two sheets meet), so quadrature of it
    over a bin that a fold cuts converges slowly and erratically. The same measure in
    the coordinates ``(l, theta, alpha)`` is smooth: for fixed ``l`` and ``K = C cos
    theta`` the energy is a quadratic form in ``(r1, r2)`` (``R`` is linear in them and the
    energy quadratic in ``R``) with a definite Hessian ``Q`` (``Omega > 0``), so the level
    ``E = h`` is an ellipse, parametrised by ``alpha``, and (coarea formula)

    .. math:: \int f\,\sigma\,dl\,dr_1\,dr_2 = \int dl\int_0^\pi C\sin\theta\,d\theta
              \oint \frac{\rho_5\,|\dot g|}{\sqrt{\det Q}}\,f\,d\alpha ,

    with ``(r1, r2)`` on the ellipse at angle ``alpha`` (``r = r0 + V diag(sqrt(2 Delta /
    lambda)) (cos alpha, sin alpha)``, ``Q = V diag(lambda) V^T``, ``r0`` the centre,
    ``Delta = h - E(r0)``) and only points with ``dg/dt`` of sign ``direction`` counted.
    The integrand is bounded where the chart is regular. This draws ``n`` points uniformly
    in ``(l, theta, alpha) in [0, 2 pi) x (0, pi) x [0, 2 pi)``, keeps those on an ellipse
    with the right sign of ``dg/dt`` and weights each by ``4 pi^3 C sin(theta) rho5 |dg/dt|
    / (sqrt(det Q) n)``: ``sum_i w_i f(p_i)`` is an unbiased estimate of ``int f sigma`` with
    finite variance (e.g. ``np.histogramdd(points, edges, weights=w)`` estimates the
    measure of each bin). ``Q``, the centre and ``Delta`` come from the energy at six
    points ``r = 0, +-e1, +-e2, e1 + e2`` (exact for a quadratic, to rounding).

    Parameters
    ----------
    params : BallParams
        ``plane_rate > 0`` (at ``Omega = 0`` the energy does not depend on ``R``: the region
        is unbounded).
    C, M_gamma, h : float
        The levels ``|M|``, ``(M, gamma)``, ``E``.
    n : int
        Draws (``1 .. 10^9``); about ``2.5 s`` of one core per ``10^6``.
    g0 : float
    direction : {1, -1, None}
        As for :func:`section_sigma`.
    seed : int, None, numpy Generator or SeedSequence
        For ``numpy.random.default_rng``.

    Returns
    -------
    dict
        ``points`` (k, 3) chart points ``(l, r1, r2)`` (``l`` in ``[0, 2 pi)``), ``K`` (k,)
        their sheets (``M3``), ``weights`` (k,), ``n`` the draws (``k <= n``: draws off
        every ellipse, with the other sign of ``dg/dt`` or on the chart's singular set are
        dropped); ``total`` the estimate of ``int sigma`` (the sum of the weights).

    Raises
    ------
    ChartError
        Bad levels or ``h``; ``Omega = 0`` or an indefinite energy form (no ellipse).

    Examples
    --------
    >>> import numpy as np
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> s = tb.section_sigma_sample(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), n=20000, seed=1)
    >>> s["points"].shape[1], bool(np.all(s["weights"] > 0))
    (3, True)
    """
    from .model import ball_constants

    params = _ball(params)
    C, M_gamma = _check_levels(C, M_gamma)
    h = _check_h(h)
    g0 = _check_g0(g0)
    _check_direction(direction)
    n = count("n", n, lo=1, hi=10**9)
    rng = _rng(seed)
    if not params.plane_rate > 0:
        raise ChartError(f"section_sigma_sample needs plane_rate > 0 (at plane_rate = {params.plane_rate!r} the "
                         "energy does not depend on R and the section region is unbounded in (r1, r2))")
    c = ball_constants(params.pars)
    parts: Dict[str, list] = {"points": [], "K": [], "weights": []}
    for lo in range(0, n, _SIGMA_SAMPLE_BLOCK):
        m = min(_SIGMA_SAMPLE_BLOCK, n - lo)
        l = rng.uniform(0.0, 2 * _math.pi, m)
        th = rng.uniform(0.0, _math.pi, m)
        al = rng.uniform(0.0, 2 * _math.pi, m)

        def energy(a, b):
            return _reduced_energy_theta(params, C, M_gamma, l, a, b, g0, th, with_gdot=False)[0]

        zero, one = _np.zeros(m), _np.ones(m)
        e0, e1p, e1m, e2p, e2m, e12 = (energy(zero, zero), energy(one, zero), energy(-one, zero),
                                       energy(zero, one), energy(zero, -one), energy(one, one))
        b = _np.stack([(e1p - e1m) / 2, (e2p - e2m) / 2], axis=-1)
        q11, q22, q12 = e1p + e1m - 2 * e0, e2p + e2m - 2 * e0, e12 - e1p - e2p + e0
        det = q11 * q22 - q12 * q12
        ok = _np.isfinite(det)  # False on the chart's singular set (E is NaN there)
        if _np.any(ok & ~(det > 0)):
            raise ChartError(f"the energy is not a definite quadratic form in (r1, r2) at some (l, K) of the level "
                             f"(C={C!r}, M_gamma={M_gamma!r}); the section region is not bounded")
        Q = _np.stack([_np.stack([q11, q12], -1), _np.stack([q12, q22], -1)], -2)
        Q[~ok] = _np.eye(2)
        b[~ok] = 0.0
        r0 = -_np.linalg.solve(Q, b[..., None])[..., 0]
        delta = h - (e0 + 0.5 * _np.einsum("ni,ni->n", b, r0))
        lam, V = _np.linalg.eigh(Q)
        on = ok & (delta * lam[:, 0] > 0)  # lambda_1, lambda_2 of one sign: delta of that sign
        ax = _np.sqrt(_np.where(on[:, None], 2 * delta[:, None] / lam, 0.0))
        u = _np.stack([_np.cos(al), _np.sin(al)], axis=-1)
        r = r0 + _np.einsum("nij,nj->ni", V, ax * u)
        _, gdot = _reduced_energy_theta(params, C, M_gamma, l, r[:, 0], r[:, 1], g0, th)
        keep = on & _np.isfinite(gdot) & (gdot != 0)
        if direction is not None:
            keep &= _np.sign(gdot) == direction
        rho5 = _sigma_rho5(c, C, M_gamma, th[keep], l[keep], g0)
        w = (4 * _math.pi**3 / n) * C * _np.sin(th[keep]) * rho5 * _np.abs(gdot[keep]) / _np.sqrt(det[keep])
        parts["points"].append(_np.column_stack([l[keep], r[keep]]))
        parts["K"].append(C * _np.cos(th[keep]))
        parts["weights"].append(w)
    out: Dict[str, Any] = {k: _np.concatenate(v) for k, v in parts.items()}
    out["n"] = n
    out["total"] = float(out["weights"].sum())
    return out


#: Candidates :func:`section_admissible_sample` draws ahead and searches at once (one
#: vectorised root search instead of 32: ~10x less time in the figures' samples).
_SAMPLE_BLOCK = 32


def section_admissible_sample(params: BallParams, *, C: float, M_gamma: float, h: float, g0: float = 0.0,
                              n: int = 100, direction: Optional[Literal[-1, 1]] = 1, seed: SeedLike = 0,
                              r_box: Optional[float] = None, n_grid: int = 801,
                              max_candidates: Optional[int] = None) -> Dict[str, Any]:
    """Sample the admissible region of the section-4 map: ``n`` chart points
    ``(l, r1, r2)`` on ``g = g0`` that carry at least one state of the level set (with
    ``dg/dt`` of sign ``direction``, unless ``None``).

    Candidates are drawn uniformly in ``l in [0, 2 pi)`` and ``(r1, r2)`` in the box
    ``[-r_box, r_box]^2`` (at most ``max_candidates``, default ``100 n``); each is kept
    when the energy equation has a root, so the points are uniform in the region. With
    ``r_box=None`` the box is grown from 1 until a ring of candidates at its edge is
    entirely inadmissible (the energy falls like ``-|R|^2`` for large ``R``, so the region
    is bounded).

    Returns
    -------
    dict
        ``points`` (k, 3) admissible points (``k = n`` unless the candidates ran out),
        ``K`` (k,) the first root of each, ``states`` (list of k arrays (n_roots, 9): the
        states of each point, as :func:`states_on_section` gives them), ``fraction`` of candidates admissible (an
        estimate of the region's share of the box), ``r_box`` used, ``n_candidates``.

    Raises
    ------
    EmptyLevelError
        When no candidate is admissible (an empty level set, or one too thin to sample).

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> region = tb.section_admissible_sample(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), n=3)
    >>> region["points"].shape, len(region["states"])   # 3 chart points (l, r1, r2)
    ((3, 3), 3)
    >>> x0 = tb.states_on_section(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), point=region["points"][0],
    ...                           direction=1)[0]
    >>> round(float(tb.integrals("reduced", FIG4_BALL, x0)["E"]), 9)
    5.0
    """
    params = _ball(params)
    C, M_gamma = _check_levels(C, M_gamma)
    g0 = _check_g0(g0)
    _check_h(h)
    _check_grid(n_grid)
    n = count("n", n, lo=1, hi=1_000_000)
    _check_direction(direction)
    if r_box is not None:
        r_box = real_number("r_box", r_box, lo=0.0, lo_open=True)
    if max_candidates is not None:
        count("max_candidates", max_candidates, lo=1, hi=100_000_000)
    # a Generator of the caller's advances exactly as if the candidates were drawn one at a
    # time; a sampler of our own draws candidates ahead and searches a block of them at once
    block = 1 if isinstance(seed, _np.random.Generator) else _SAMPLE_BLOCK
    rng = _rng(seed)

    def admissible(ps):
        """Per candidate ``(l, r1, r2)``: ``(states, info)`` as :func:`states_on_section`
        gives them (bit for bit: :func:`_section_states`), or None where it has none."""
        found = _section_states(params, C, M_gamma, h, _np.array([p[0] for p in ps]), [p[1] for p in ps],
                                [p[2] for p in ps], g0, direction, n_grid)
        return [None if isinstance(f, ChartError) or not len(f[0]) else f for f in found]

    if r_box is None:
        r_box = 1.0
        for _ in range(12):
            edge = [(rng.uniform(0, 2 * _math.pi), r_box * _math.cos(a), r_box * _math.sin(a))
                    for a in rng.uniform(0, 2 * _math.pi, 48)]
            if all(f is None for f in admissible(edge)):
                break
            r_box *= 2.0
    pts: list[Tuple[float, float, float]] = []
    Ks, states = [], []
    n_cand = 0
    max_candidates = 100 * n if max_candidates is None else int(max_candidates)
    while len(pts) < n and n_cand < max_candidates:
        cands = [(rng.uniform(0, 2 * _math.pi), rng.uniform(-r_box, r_box), rng.uniform(-r_box, r_box))
                 for _ in range(min(block, max_candidates - n_cand))]
        for p, found in zip(cands, admissible(cands)):
            n_cand += 1
            if found is not None:
                pts.append(p)
                Ks.append(found[1]["K"][0])
                states.append(found[0])
                if len(pts) == n:
                    break
    if not pts:
        raise EmptyLevelError(
            f"no admissible chart point found among {n_cand} candidates in r1, r2 in [-{r_box:g}, {r_box:g}] for "
            f"C = {C!r}, M_gamma = {M_gamma!r}, h = {h!r}, g0 = {g0!r}, direction = {direction!r}: the level set "
            "is empty or does not meet this section"
        )
    return {"points": _np.array(pts), "K": _np.array(Ks), "states": states, "fraction": len(pts) / n_cand,
            "r_box": r_box, "n_candidates": n_cand}
