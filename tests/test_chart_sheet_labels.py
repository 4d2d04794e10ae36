"""The sheet labels of :func:`taylorball.section_sheet` against the grid search it had before
it evaluated only the part of the grid that decides a label (kept here as the reference,
``_reference_sheet``): identical labels, root index and sheet label, on several thousand
states of the Fig. 4a and 4b levels, including states at folds (double roots) and next to
the pole ``K*`` (``r1 -> 0``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import taylorball as tb
from taylorball._chart_reduced import (_grid_brackets, _orientation, _pole_brackets, _reduced_energy_theta,
                                       _section_states, _sheet_poles, _side, angles_to_vectors, reduced_chart)
from taylorball.charts import section_admissible_sample
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS, FIG4B_LEVELS

LEVELS = {"fig4a": FIG4A_LEVELS, "fig4b": FIG4B_LEVELS}


def _reference_sheet(params, x, *, C, M_gamma, h, g0=0.0, direction=1, n_grid=801, chunk=2048, label="root"):
    """section_sheet as it was before (checked arguments, states on the level): every state
    evaluates the energy on the whole grid and on the sub-grids next to the poles."""
    ch = reduced_chart(params, x)
    theta_state = np.arccos(np.clip(ch["K"] / C, -1.0, 1.0))
    K_star, K_far = _sheet_poles(C, M_gamma, g0)
    theta_poles = [math.acos(k / C) for k in (K_star, K_far) if k is not None]
    if label == "sheet":
        side_state = _side(ch["K"], K_star, K_far)
        orient_state = _orientation(params, C, M_gamma, ch["l"], ch["r1"], ch["r2"], g0, theta_state)
    chunk = max(1, min(chunk, (1 << 22) // n_grid))
    out = np.empty(x.shape[0], dtype=int)
    for s in range(0, x.shape[0], chunk):
        sl = slice(s, s + chunk)
        l, r1, r2 = (ch[k][sl] for k in ("l", "r1", "r2"))

        def f(which, th, refuse=True):
            return _reduced_energy_theta(params, C, M_gamma, l[which], r1[which], r2[which], g0, th,
                                         with_gdot=False, refuse=refuse)[0] - h

        def energy_gdot(rows, th):
            return _reduced_energy_theta(params, C, M_gamma, l[rows], r1[rows], r2[rows], g0, th, refuse=False)[1]

        grid, _, _, E, _, exact, sc = _grid_brackets(f, l.size, 0.0, math.pi, n_grid)
        change = sc | (exact[:, 1:] & ~exact[:, :-1])
        rows, j = np.nonzero(change)
        a, b, e0, e1 = grid[j], grid[j + 1], E[rows, j], E[rows, j + 1]
        wins, (_, p_rows, p_a, p_b, p_e0, p_e1) = _pole_brackets(lambda w, th: f(w, th, refuse=False), l.size,
                                                                 grid, theta_poles)
        if wins:
            drop = np.zeros(a.size, dtype=bool)
            for (w0, _), (_, w1) in zip(wins[::2], wins[1::2]):
                drop |= (a >= w0) & (b <= w1)
            keep = ~drop
            rows, a, b = np.concatenate([rows[keep], p_rows]), np.concatenate([a[keep], p_a]), \
                np.concatenate([b[keep], p_b])
            e0, e1 = np.concatenate([e0[keep], p_e0]), np.concatenate([e1[keep], p_e1])
        th = a + (b - a) * e0 / (e0 - e1)
        branch = np.sign(energy_gdot(rows, th)) == direction
        ts = theta_state[sl][rows]
        if label == "root":
            below = (a > ts) & branch
            out[sl] = np.bincount(rows[below], minlength=E.shape[0])
            continue
        pos = np.where(e0 > 0, a, b)
        for tp in theta_poles:
            pole = (a < tp) & (tp < b)
            if np.any(pole):
                th = np.where(pole, 0.5 * (tp + pos), th)
                branch = np.sign(energy_gdot(rows, th)) == direction
        _, gam = angles_to_vectors(C, M_gamma, C * np.cos(pos), l[rows], g0)
        orient = np.where(np.sign(e1 - e0) * gam[2] > 0, -1, 1)
        own = (a <= ts) & (ts <= b)
        K_b, K_s = C * np.cos(th), C * np.cos(ts)
        d_b, d_s = np.abs(K_b - K_star), np.abs(K_s - K_star)
        before = (branch & ~own & (orient == orient_state[sl][rows])
                  & (_side(C * np.cos(pos), K_star, K_far) == side_state[sl][rows])
                  & ((d_b < d_s) | ((d_b == d_s) & (K_b < K_s))))
        rank = np.bincount(rows[before], minlength=E.shape[0])
        out[sl] = 4 * rank + 2 * side_state[sl] + (orient_state[sl] < 0)
    return out


def _states(params, lev, points, direction=1):
    """All the states (of the branch ``direction``) over the chart points ``(l, r1, r2)``, with
    the number of roots found at each point."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    found = _section_states(params, lev.C, lev.M_gamma, lev.h, pts[:, 0], pts[:, 1], pts[:, 2], 0.0, direction,
                            2001)
    xs = [f[0] for f in found if not isinstance(f, tb.ChartError)]
    counts = np.array([-1 if isinstance(f, tb.ChartError) else len(f[0]) + len(f[1]["refused_K"]) for f in found])
    return (np.concatenate(xs) if xs else np.empty((0, 9))), counts


def _fold_points(params, lev, n_lines=12, n_scan=120, n_bisect=40, seed=5):
    """Chart points next to the folds of the section (where the number of roots changes:
    two roots meet at a double root): along lines in ``r1`` at random ``(l, r2)``, each change
    of the root count between scan points bisected ``n_bisect`` times; both ends of the
    final brackets (the one side carries two roots closer than ~1e-5 in theta)."""
    rng = np.random.default_rng(seed)
    r_max = 10.0
    lines = [(rng.uniform(0, 2 * math.pi), rng.uniform(-r_max, r_max)) for _ in range(n_lines)]
    r1 = np.linspace(-r_max, r_max, n_scan)
    pts = np.array([(l, a, r2) for l, r2 in lines for a in r1])
    _, counts = _states(params, lev, pts)
    counts = counts.reshape(n_lines, n_scan)
    i, j = np.nonzero((counts[:, :-1] != counts[:, 1:]) & (counts[:, :-1] >= 0) & (counts[:, 1:] >= 0))
    base = np.array(lines)[i]
    lo, hi, c_lo = r1[j], r1[j + 1], counts[i, j]
    for _ in range(n_bisect):
        mid = 0.5 * (lo + hi)
        _, c_mid = _states(params, lev, np.column_stack([base[:, 0], mid, base[:, 1]]))
        left = c_mid == c_lo
        lo, hi = np.where(left, mid, lo), np.where(left, hi, mid)
    ends = np.concatenate([lo, hi])
    base = np.concatenate([base, base])
    return np.column_stack([base[:, 0], ends, base[:, 1]])


def _level_states(params, lev, direction=1, n=2500, seed=3):
    """States over random chart points of the box of Fig. 4 (``|r1|, |r2| <= 10.5``), over
    points next to the folds, and over points next to the pole ``K*`` (``r1`` from 1e-2 to
    1e-8 of either sign). Returns ``(states, n_close)``: ``n_close`` of them have another
    root of their chart point within two grid steps (801 points) in theta."""
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(0, 2 * math.pi, n), rng.uniform(-10.5, 10.5, (n, 2))])
    near_pole = np.column_stack([rng.uniform(0, 2 * math.pi, 200),
                                 rng.choice([-1.0, 1.0], 200) * 10.0 ** rng.uniform(-8, -2, 200),
                                 rng.uniform(-10.5, 10.5, 200)])
    pts = np.concatenate([pts, near_pole, _fold_points(params, lev)])
    found = _section_states(params, lev.C, lev.M_gamma, lev.h, pts[:, 0], pts[:, 1], pts[:, 2], 0.0, direction,
                            2001)
    xs, n_close = [], 0
    for f in found:
        if isinstance(f, tb.ChartError) or not len(f[0]):
            continue
        xs.append(f[0])
        th = np.sort(np.arccos(np.concatenate([f[1]["K"], f[1]["refused_K"]]) / lev.C))
        n_close += int(np.sum(np.diff(th) < 2 * math.pi / 800))
    return np.concatenate(xs), n_close



@pytest.mark.parametrize("name", list(LEVELS))
def test_labels_are_those_of_the_whole_grid(name):
    """~2000 states a level, ~50-120 of them with another root within two grid steps (next
    to a fold or to K*), where the grid search can count two roots as none: the labels (root
    index and sheet label) equal the old search's, bit for bit, errors of the grid included
    (the same grid values decide)."""
    lev = LEVELS[name]
    X, n_close = _level_states(FIG4_BALL, lev)
    assert X.shape[0] >= 1800 and n_close >= 30  # the sample reached the folds
    for label in ("root", "sheet"):
        new = tb.section_sheet(FIG4_BALL, X, **lev.as_kwargs(), label=label)
        ref = _reference_sheet(FIG4_BALL, X, **lev.as_kwargs(), label=label)
        assert np.array_equal(new, ref), (label, np.flatnonzero(new != ref)[:20])
        assert np.unique(new).size >= 4  # several sheets / root indices met


def test_labels_do_not_depend_on_chunk_or_order():
    """The other branch (direction -1), any chunk size, and states in any order: the same
    labels as the old search's on its default chunks."""
    lev = FIG4B_LEVELS
    X, _ = _level_states(FIG4_BALL, lev, direction=-1, n=150, seed=11)
    refs = {label: _reference_sheet(FIG4_BALL, X, **lev.as_kwargs(), direction=-1, label=label)
            for label in ("root", "sheet")}
    for chunk in (1, 7, 128, 5000):
        perm = np.random.default_rng(chunk).permutation(X.shape[0])
        for label, ref in refs.items():
            new = tb.section_sheet(FIG4_BALL, X[perm], **lev.as_kwargs(), direction=-1, chunk=chunk, label=label)
            assert np.array_equal(new, ref[perm]), (chunk, label, np.flatnonzero(new != ref[perm])[:20])
