r"""Sheets of the section-4 chart (public from :mod:`taylorball.charts`):
:func:`section_sheet` labels the states over a chart point by sheet.
"""

from __future__ import annotations

import math as _math
from typing import Literal

import numpy as _np
from numpy.typing import ArrayLike

from ._chart_reduced import (_ball, _check_g0, _check_grid, _check_h, _check_levels, _orientation, _pole_windows,
                             _reduced_energy_theta, _sheet_poles, _side, _wrap, angles_to_vectors, reduced_chart)
from .errors import ChartError, UsageError
from .numbers import count
from .params import BallParams


_SHEET_LEVEL_TOL = 1e-6


def section_sheet(params: BallParams, states: ArrayLike, *, C: float, M_gamma: float, h: float, g0: float = 0.0,
                  direction: int = 1, n_grid: int = 801, chunk: int = 128,
                  label: Literal["root", "sheet"] = "root") -> _np.ndarray:
    r"""The sheet of the section-4 map each state lies on: the index of its ``K = M3`` among
    the roots ``K`` of the energy equation at its chart point, in increasing ``K``
    (``label="root"``), or the sheet label that follows a sheet across ``gamma3 = 0``
    (``label="sheet"``).

    Over one chart point ``(l, r1, r2)`` the section ``g = g0`` of the level set can carry
    several states (the roots ``K`` of ``E(K; l, r1, r2, g0) = h``, paper sec. 4, section
    chart; :func:`states_on_section`), so a picture in ``(r1, r2)`` overlays several sheets.
    The index here is the position of the state in the list :func:`states_on_section` returns
    for its chart point and ``direction``: within one index the chart is one-to-one, so
    points of one sheet never stand for two different states. Sheets meet at folds (double
    roots), where the index of an orbit's crossings changes.

    The root index is not a sheet label across ``gamma3 = 0``: there (``r1 = -R3 gamma3 =
    0``, at the one value ``K*`` of :func:`_degenerate_K`, ``sqrt(C^2 - M_gamma^2)`` on
    ``g0 = 0``) the energy equation has a pole, and two roots pass through each other at
    ``K*`` as ``r1`` changes sign, so their order in ``K`` is exchanged while each state
    moves smoothly (docs/chaos.md, "Sheets of the section"). ``label="sheet"`` numbers the
    states by quantities continuous on a sheet instead: the orientation ``o = sign(gamma3
    dE/dK)`` of the chart map (constant on a sheet, opposite on the two sheets of a fold),
    the side of the second pole ``K** = -M_gamma cos g0`` (``gamma1 = gamma2 = 0``; on
    ``g0 = 0, pi`` only), which no sheet crosses, and the distance ``|K - K*|``; a state's
    label is ``4 rank + 2 side + (o < 0)``, ``rank`` its position among the states of its
    side and orientation at its chart point in increasing ``|K - K*|``.
    :func:`taylorball.megno_map` with ``sheet=`` maps them. Where a sheet nearer ``K*`` of
    the same side and orientation appears or ends, the rank of the others shifts (as the
    root index does where a root appears below).

    Parameters
    ----------
    params : BallParams
    states : array_like, shape (n, 9) or (9,)
        Public reduced states on the section ``g = g0`` of the level set (e.g. the
        ``states`` of a :class:`~taylorball.sections.SectionResult`).
    C, M_gamma, h : float
        The levels ``|M|``, ``(M, gamma)``, ``E`` the states lie on.
    g0 : float
        The section angle.
    direction : {+1, -1}
        The branch the crossings are on (``dg/dt`` of this sign; the figures use +1).
    n_grid : int
        Grid in ``theta`` (``K = C cos(theta)``) on which roots are bracketed, as in
        :func:`states_on_section`; next to the poles ``K*`` and ``K**``, where the roots
        crowd as ``r1 -> 0``, they are bracketed again on points approaching the pole
        geometrically. Two roots closer than a grid step next to a fold (a double root) can
        be counted as one: the index of such a crossing is then off by one. A root the
        chart refuses (``|gamma3| < 1e-4``) is counted, so it never shifts the others.
    chunk : int
        States evaluated at once (memory: ``chunk * n_grid`` numbers per temporary array;
        fewer states when that would pass ~4 million). The labels do not depend on it; the
        default keeps the temporaries in cache. For ``label="root"`` the states are taken in
        order of ``K`` and each chunk evaluates the grid only beyond its states' ``K`` (the
        roots below them), which is all a root index depends on.
    label : {"root", "sheet"}
        The root index in increasing ``K`` (the index of :func:`states_on_section` and of
        ``megno_map(root=...)``), or the sheet label (``megno_map(sheet=...)``; the
        ``"sheet"`` entry of :func:`states_on_section`'s info).

    Returns
    -------
    ndarray of int, shape (n,)
        ``label="root"``: ``0`` for the smallest root ``K`` with ``dg/dt`` of sign
        ``direction``, ``1`` for the next, ... ``label="sheet"``: the sheet label.

    Raises
    ------
    ChartError
        Bad levels, or a state not on them or not on the section ``g = g0`` (relative
        distance above 1e-6).
    UsageError
        Bad ``direction``, ``n_grid``, ``chunk`` or ``label``.

    Examples
    --------
    >>> import taylorball as tb
    >>> from taylorball.paper import FIG4_BALL, FIG4A_LEVELS
    >>> xs = tb.states_on_section(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), point=(2.0, 2.5, 1.0), direction=1)
    >>> tb.section_sheet(FIG4_BALL, xs, **FIG4A_LEVELS.as_kwargs())
    array([0, 1])
    >>> tb.section_sheet(FIG4_BALL, xs, **FIG4A_LEVELS.as_kwargs(), label="sheet")   # orientation -1 and +1
    array([1, 0])
    """
    params = _ball(params)
    C, M_gamma = _check_levels(C, M_gamma)
    g0 = _check_g0(g0)
    h = _check_h(h)
    n_grid = _check_grid(n_grid)
    if direction not in (1, -1) or isinstance(direction, bool):
        raise UsageError(f"direction must be +1 or -1 (the branch of the crossings), got {direction!r}")
    chunk = count("chunk", chunk, lo=1, hi=10_000_000)
    if not (isinstance(label, str) and label in ("root", "sheet")):
        raise UsageError(f"label must be 'root' (the index of K among the roots) or 'sheet' (the sheet label), "
                         f"got {label!r}")
    try:
        x = _np.asarray(states, dtype=float)
    except (TypeError, ValueError):
        raise ChartError(f"states must be reduced states of shape (n, 9) or (9,), got {states!r}") from None
    if x.ndim not in (1, 2) or x.shape[-1] != 9:
        raise ChartError(f"states must be reduced states of shape (n, 9) or (9,), got shape {x.shape}")
    x = x.reshape(-1, 9)
    if x.shape[0] == 0:
        return _np.zeros(0, dtype=int)
    ch = reduced_chart(params, x)
    off_g = _np.abs(_wrap(ch["g"] - g0 + _math.pi) - _math.pi)
    bad = ((_np.abs(ch["C"] - C) > _SHEET_LEVEL_TOL * C) | (_np.abs(ch["M_gamma"] - M_gamma) > _SHEET_LEVEL_TOL * C)
           | (off_g > _SHEET_LEVEL_TOL))
    if _np.any(bad):
        i = int(_np.flatnonzero(bad)[0])
        raise ChartError(
            f"states must lie on the section g = {g0!r} of the level set C = {C!r}, M_gamma = {M_gamma!r}; "
            f"state {i} has C = {ch['C'][i]!r}, M_gamma = {ch['M_gamma'][i]!r}, g = {ch['g'][i]!r}"
        )
    theta_state = _np.arccos(_np.clip(ch["K"] / C, -1.0, 1.0))
    K_star, K_far = _sheet_poles(C, M_gamma, g0)
    theta_poles = [_math.acos(k / C) for k in (K_star, K_far) if k is not None]
    if label == "sheet":
        side_state = _side(ch["K"], K_star, K_far)
        orient_state = _orientation(params, C, M_gamma, ch["l"], ch["r1"], ch["r2"], g0, theta_state)
    grid = _np.linspace(0.0, _math.pi, n_grid)
    wins = _pole_windows(grid, theta_poles)
    if label == "root":
        # only the brackets beyond the state's own theta count (smaller K, below): the
        # states go in order of theta, so that each chunk evaluates the grid from its
        # smallest theta on; every value is the same elementwise evaluation as on the whole
        # grid, so the brackets (and the labels) are those of the whole grid
        order = _np.argsort(theta_state, kind="stable")
        j_first = _np.searchsorted(grid, theta_state, side="right")  # grid[j] > theta_state from here
    else:
        order = _np.arange(x.shape[0])
        j_first = _np.zeros(x.shape[0], dtype=int)
    # temporaries of at most ~4 M numbers (32 MB) each, whatever chunk and n_grid ask for
    chunk = max(1, min(chunk, (1 << 22) // n_grid))
    out = _np.empty(x.shape[0], dtype=int)
    for s in range(0, x.shape[0], chunk):
        sl = order[s:s + chunk]
        l, r1, r2 = (ch[k][sl] for k in ("l", "r1", "r2"))
        ts_all = theta_state[sl]
        j0 = min(int(j_first[sl].min()), n_grid - 1)

        def f(rows, th, refuse=True):
            return _reduced_energy_theta(params, C, M_gamma, l[rows], r1[rows], r2[rows], g0, th,
                                         with_gdot=False, refuse=refuse)[0] - h

        def energy_gdot(rows, th):
            return _reduced_energy_theta(params, C, M_gamma, l[rows], r1[rows], r2[rows], g0, th, refuse=False)[1]

        # the energy on the grid from column j0 on, the chunk's states broadcast against it
        col = (slice(None), None)
        E = _reduced_energy_theta(params, C, M_gamma, l[col], r1[col], r2[col], g0, grid[None, j0:],
                                  with_gdot=False)[0] - h
        finite = _np.isfinite(E)
        exact = finite & (E == 0)
        sc = finite[:, :-1] & finite[:, 1:] & (E[:, :-1] * E[:, 1:] < 0)
        # a root in (a, b] where E changes sign: the grid's brackets, except next to a pole of
        # the energy equation, where the roots crowd closer than a grid step as r1 -> 0 and
        # the sub-grid's brackets replace them (counting the roots the chart refuses too)
        change = sc | (exact[:, 1:] & ~exact[:, :-1])
        rows, j = _np.nonzero(change)
        a, b, e0, e1 = grid[j0 + j], grid[j0 + j + 1], E[rows, j], E[rows, j + 1]
        if label == "root":
            keep = a > ts_all[rows]
            rows, a, b, e0, e1 = rows[keep], a[keep], b[keep], e0[keep], e1[keep]
        if wins:
            drop = _np.zeros(a.size, dtype=bool)
            for (w0, _, _), (_, w1, _) in zip(wins[::2], wins[1::2]):  # a pole's two windows
                drop |= (a >= w0) & (b <= w1)
            keep = ~drop
            p_rows, p_a, p_b, p_e0, p_e1 = _pole_sub_brackets(lambda w, th: f(w, th, refuse=False), wins,
                                                              ts_all if label == "root" else None)
            rows, a, b = _np.concatenate([rows[keep], p_rows]), _np.concatenate([a[keep], p_a]), \
                _np.concatenate([b[keep], p_b])
            e0, e1 = _np.concatenate([e0[keep], p_e0]), _np.concatenate([e1[keep], p_e1])
        # located by linear interpolation for the sign of dg/dt there (the branch)
        th = a + (b - a) * e0 / (e0 - e1)
        branch = _np.sign(energy_gdot(rows, th)) == direction
        ts = ts_all[rows]
        if label == "root":
            # K = C cos(theta) decreases with theta: the roots with smaller K than the state's
            # own are those in brackets entirely beyond the state's theta (its own root lies
            # in the bracket that contains theta_state); only those were kept
            out[sl] = _np.bincount(rows[branch], minlength=sl.size)
            continue
        # the sheet label (_sheet_labels): the other roots of the branch on the state's side
        # of K** with the state's orientation (dE/dtheta has the sign of e1 - e0 across a
        # bracket; dK/dtheta < 0) nearer K* than the state's own root (ties: smaller K) come
        # before it. A bracket can hold a pole (K* or K**: E -> -inf) besides the root: the
        # root then lies between the pole and the end where E > h, and gamma3 has its sign
        # (and K its side of K**) at that end; elsewhere they are one over the bracket
        pos = _np.where(e0 > 0, a, b)
        for tp in theta_poles:
            pole = (a < tp) & (tp < b)
            if _np.any(pole):
                th = _np.where(pole, 0.5 * (tp + pos), th)
                branch = _np.sign(energy_gdot(rows, th)) == direction
        _, gam = angles_to_vectors(C, M_gamma, C * _np.cos(pos), l[rows], g0)
        orient = _np.where(_np.sign(e1 - e0) * gam[2] > 0, -1, 1)
        own = (a <= ts) & (ts <= b)
        K_b, K_s = C * _np.cos(th), C * _np.cos(ts)
        d_b, d_s = _np.abs(K_b - K_star), _np.abs(K_s - K_star)
        before = (branch & ~own & (orient == orient_state[sl][rows])
                  & (_side(C * _np.cos(pos), K_star, K_far) == side_state[sl][rows])
                  & ((d_b < d_s) | ((d_b == d_s) & (K_b < K_s))))
        rank = _np.bincount(rows[before], minlength=sl.size)
        out[sl] = 4 * rank + 2 * side_state[sl] + (orient_state[sl] < 0)
    return out


def _pole_sub_brackets(f, wins, ts):
    """The sign changes of the chunk's functions ``f(rows, theta)`` on the sub-grids of the
    pole windows ``wins`` (:func:`_pole_windows`), as :func:`_pole_brackets` finds them:
    ``(rows, a, b, ya, yb)``. Given ``ts`` (each function's own theta), only the brackets
    with ``a > ts`` (the sub-grid from the smallest ``ts`` on is evaluated)."""
    parts = []
    for _, _, sub in wins:
        if ts is not None:
            sub = sub[_np.searchsorted(sub, ts.min(), side="right"):]
            if sub.size < 2:
                continue
        y = f((slice(None), None), sub[None, :])
        sc = _np.isfinite(y[:, :-1]) & _np.isfinite(y[:, 1:]) & (y[:, :-1] * y[:, 1:] < 0)
        rows, j = _np.nonzero(sc)
        a = sub[j]
        keep = slice(None) if ts is None else a > ts[rows]
        parts.append((rows[keep], a[keep], sub[j + 1][keep], y[rows, j][keep], y[rows, j + 1][keep]))
    if not parts:
        e = _np.empty(0)
        return e.astype(int), e, e, e, e
    return tuple(_np.concatenate(c) for c in zip(*parts))
