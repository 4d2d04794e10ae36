"""The 2D unstable and 1D stable manifolds of the Fig. 4a saddle (k = 10) of the 3D section
map. Checks against computations the code under test does not make: a finite-difference
Jacobian of the section map in the chart (states from the chart by states_on_section, the
map by poincare_section, crossings counted), fresh section runs, and the reversor sigma1
applied to the mirror orbit's unstable curve."""

import dataclasses

import numpy as np
import pytest

import taylorball as tb
from taylorball.errors import UsageError
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS

from ._periodic_checks import polyline_distance


@pytest.fixture(scope="module")
def saddle():
    from taylorball.periodic_catalog import FIG4A_SADDLE_K10, catalog_orbit

    return catalog_orbit(FIG4A_SADDLE_K10)


@pytest.fixture(scope="module")
def surface(saddle):
    """Leaves of 4 rings to iterate 3 within chart distance 0.3 (~1 CPU s, 14 leaves)."""
    from taylorball.periodic_manifolds_3d import grow_surface

    return grow_surface(saddle, n_iter=4, extent=0.3, s0=1e-4, workers=1)


def _state_at(saddle, point):
    """The state of the section (increasing g) and level at a chart point, nearest the saddle."""
    xs = tb.states_on_section(FIG4_BALL, **FIG4A_LEVELS.as_kwargs(), point=tuple(point), direction=1)
    return xs[int(np.argmin(np.linalg.norm(np.asarray(xs) - saddle.state, axis=1)))]


def _F(saddle, state, n=1):
    """Chart point of F^n = P^(10 n): the section integrator, crossings counted."""
    return tb.poincare_section("reduced", FIG4_BALL, state, n_points=10 * n).points[-1]


@pytest.fixture(scope="module")
def chart_jacobian(saddle):
    """DF in the chart (l, r1, r2) at the saddle's first point by central differences,
    h = 1e-5 (truncation ~h^2 |F'''| ~ 1e-8)."""
    p0 = saddle.points[0]
    h = 1e-5
    J = np.empty((3, 3))
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        J[:, i] = (_F(saddle, _state_at(saddle, p0 + e)) - _F(saddle, _state_at(saddle, p0 - e))) / (2 * h)
    return J


def test_chart_jacobian_has_the_orbits_multipliers(saddle, chart_jacobian):
    """The reference is right: its eigenvalues are the orbit's multipliers (variational
    equations) to 1e-6 (the states from the chart carry ~1e-12, over h = 1e-5: ~1e-7 in DF;
    measured 1.2e-7 relative on mu_u, 5e-8 absolute on mu_s)."""
    lam = np.sort(np.abs(np.linalg.eigvals(chart_jacobian)))
    assert np.allclose(lam, np.sort(np.abs(saddle.multipliers)), rtol=1e-6, atol=1e-6)


def test_surface_leaves_the_saddle_in_the_unstable_plane_to_second_order(saddle, surface, chart_jacobian):
    """Chart distance d of leaf points from the unstable eigenplane of the finite-difference
    Jacobian against their distance r from the saddle: d / r^2 is the same (within a factor
    3) on leaves from r ~ 2e-3 to 0.1 (a second-order contact), and d / r falls with r (a
    first-order error, e.g. a wrong plane, would keep d / r constant)."""
    lam, V = np.linalg.eig(chart_jacobian)
    u = V[:, np.argsort(np.abs(lam))[1:]].real
    n = np.cross(u[:, 0], u[:, 1])
    n /= np.linalg.norm(n)
    p0 = saddle.points[0]
    rows = []
    for C, it in zip(surface.leaves, surface.iterate):
        if it < 1:
            continue
        D = C - p0
        r = np.linalg.norm(D, axis=1)
        d = np.abs(D @ n)
        rows.append((float(np.median(r)), float(np.median(d / r ** 2)), float(np.median(d / r))))
    rows = np.array(sorted(rows))
    sel = (rows[:, 0] > 2e-3) & (rows[:, 0] < 0.1)
    assert sel.sum() >= 6 and rows[sel, 0].max() / rows[sel, 0].min() > 20
    q = rows[sel, 1]
    assert q.max() <= 3 * q.min(), rows
    assert rows[sel, 2][-1] >= 10 * rows[sel, 2][0], rows  # d / r grows with r: d = O(r^2), not O(r)


def test_surface_is_invariant(saddle, surface, chart_jacobian):
    """Points of the linear unstable plane of the finite-difference Jacobian (chart, not the
    code's eigenvectors; states by states_on_section), off the leaves' rings (tau = 1/8 and
    5/8, 3/8), mapped by fresh section runs (crossings counted) to the last iterate inside
    the grown surface, land on it: their distance to a local quadratic fit of the nearest
    24 leaf points of iterates 2..4 is below 2e-3 of the refinement distance delta
    (the off-plane start error, ~1e-6, contracts by mu_s = 0.0155 per iterate; what is
    left is the fit's own error on a mesh of spacing ~delta)."""
    lam, V = np.linalg.eig(chart_jacobian)
    order = np.argsort(np.abs(lam))
    w = V[:, order[1:]].real
    w /= np.linalg.norm(w, axis=0)
    mu = np.abs(lam[order[1:]])
    p0 = saddle.points[0]
    mesh = np.vstack([C for C, it in zip(surface.leaves, surface.iterate) if it >= 2])
    r0 = 1e-3  # chart radius of the start
    worst, used = 0.0, 0
    for tau, phi in ((0.125, 0.4), (0.625, 2.0), (0.625, 4.1), (0.375, 5.5)):
        p = p0 + r0 * (mu[0] ** tau * np.cos(phi) * w[:, 0] + mu[1] ** tau * np.sin(phi) * w[:, 1])
        imgs = tb.poincare_section("reduced", FIG4_BALL, _state_at(saddle, p), n_points=40).points[9::10]
        inside = [q for q in imgs if 0.02 < np.linalg.norm(q - p0) < 0.8 * surface.extent.max()]
        if not inside:  # this start leaves the grown part of the surface within one iterate
            continue
        q = inside[-1]
        near = mesh[np.argsort(np.linalg.norm(mesh - q, axis=1))[:24]]
        c = near.mean(axis=0)
        _, _, Vt = np.linalg.svd(near - c)
        a, b, nrm = Vt[0], Vt[1], Vt[2]
        X = np.column_stack([(near - c) @ a, (near - c) @ b])
        A = np.column_stack([np.ones(len(X)), X, X[:, 0] ** 2, X[:, 0] * X[:, 1], X[:, 1] ** 2])
        coef = np.linalg.lstsq(A, (near - c) @ nrm, rcond=None)[0]
        x, y = (q - c) @ a, (q - c) @ b
        off = abs((q - c) @ nrm - coef @ np.array([1, x, y, x * x, x * y, y * y]))
        worst, used = max(worst, off), used + 1
    assert used >= 2
    assert worst <= 2e-3 * surface.delta, worst


def test_surface_bad_input_is_refused_before_work(saddle):
    from taylorball.periodic_manifolds_3d import grow_surface, surface_trace

    for kw, word in ((dict(n_iter=-1), "n_iter"), (dict(n_iter=1.5), "n_iter"), (dict(n_iter=2, extent=0.0), "extent"),
                     (dict(n_iter=2, s0=0.5), "s0"), (dict(n_iter=2, n_rings=0), "n_rings"),
                     (dict(n_iter=2, n_phi=3), "n_phi"), (dict(n_iter=2, delta=float("nan")), "delta"),
                     (dict(n_iter=2, alpha=4.0), "alpha"), (dict(n_iter=2, delta=0.01, delta_min=0.02), "delta_min"),
                     (dict(n_iter=2, max_points=0), "max_points"), (dict(n_iter=2, workers=0), "workers")):
        with pytest.raises(UsageError, match=word):
            grow_surface(saddle, **kw)
    with pytest.raises(UsageError, match="PeriodicOrbit"):
        grow_surface(np.zeros(9), n_iter=1)
    one_out = dataclasses.replace(saddle, multipliers=np.array([0.1, 0.2, 50.0]))
    with pytest.raises(UsageError, match="grow_manifold"):
        grow_surface(one_out, n_iter=1)
    with pytest.raises(UsageError, match="ManifoldSurface"):
        surface_trace(None, 0, 0.0)  # type: ignore[arg-type]


def test_surface_trace_on_a_plane_through_the_saddle(saddle, surface):
    """The leaves cross the plane r2 = r2* through the saddle's point twice each (closed
    curves around the saddle), on both sides of it."""
    from taylorball.periodic_manifolds_3d import surface_trace

    with pytest.raises(UsageError, match="axis"):
        surface_trace(surface, 3, 0.0)
    p0 = saddle.points[0]
    tr = surface_trace(surface, 2, float(p0[2]))
    per_leaf = {}
    for p, tau, it in tr:
        assert abs(p[2] - p0[2]) <= 1e-12
        per_leaf.setdefault((it, tau), []).append(p)
    assert len(per_leaf) == len(surface.leaves)
    for pts in per_leaf.values():
        assert len(pts) == 2
        assert np.dot(pts[0] - p0, pts[1] - p0) < 0  # on opposite sides of the saddle


# ---------------------------------------------------------------------------------------
# The 1D stable manifold (grow_manifold on the 3D map).
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def stable_curve(saddle):
    from taylorball.periodic_manifolds import grow_manifold

    return grow_manifold(saddle, "stable", length=0.05, branch=1, refine_all=False)


def test_stable_curve_approaches_the_saddle_at_the_stable_multiplier(saddle, stable_curve):
    """Points of the stable curve at chart distance ~1e-2 from the saddle, mapped by fresh
    section runs (crossings counted): the distance shrinks by mu_s = 0.01554 per iterate of
    F, within 2 % (nonlinear terms O(d), d ~ 1e-2; the amplified rounding is far below)."""
    p0 = saddle.points[0]
    mu_s = float(np.min(np.abs(saddle.multipliers)))
    P, S = stable_curve.points, stable_curve.states
    d0 = np.linalg.norm(P - p0, axis=1)
    for i in (int(np.argmin(np.abs(d0 - 1e-2))), int(np.argmin(np.abs(d0 - 3e-2)))):
        pts = tb.poincare_section("reduced", FIG4_BALL, S[i], n_points=20).points[[9, 19]]
        d = np.linalg.norm(pts - p0, axis=1)
        r = np.array([d[0] / d0[i], d[1] / d[0]])
        assert np.all(np.abs(r - mu_s) <= 0.02 * mu_s), (d0[i], d, r)  # measured: within 1.0 %


def test_stable_curve_is_the_mirror_of_the_mirror_orbits_unstable_curve(saddle, stable_curve):
    """The reversor sigma1 maps the chart (l, r1, r2) to (2 pi - l, r1, -r2) and the unstable
    manifold of FIG4A_SADDLE_K10_R onto the stable manifold of FIG4A_SADDLE_K10: the stable
    curve (flow backwards) lies on the mirrored unstable curve (flow forwards) of the mirror
    orbit started at the mirrored point (Newton from sigma1 of the saddle's state)."""
    from taylorball.periodic import periodic_orbit, reversors
    from taylorball.periodic_manifolds import grow_manifold

    sigma1 = reversors()["sigma1"]  # on (M, gamma, R); the public (omega, gamma, R) flips the same components
    mirror = periodic_orbit("reduced", FIG4_BALL, sigma1 * np.asarray(saddle.state, dtype=float), 10,
                            levels=FIG4A_LEVELS)
    assert np.allclose(np.sort(np.abs(mirror.multipliers)), np.sort(1 / np.abs(saddle.multipliers)), rtol=1e-6)
    x0 = saddle.points[0]
    assert np.linalg.norm(mirror.points[0] - np.array([2 * np.pi - x0[0], x0[1], -x0[2]])) <= 1e-9
    best = None
    for branch in (1, -1):
        wu = grow_manifold(mirror, "unstable", length=0.05, branch=branch, refine_all=False)
        C = wu.curves[0].copy()
        C[:, 0], C[:, 2] = 2 * np.pi - C[:, 0], -C[:, 2]
        d = np.array([polyline_distance(p, C) for p in stable_curve.points])
        if best is None or np.median(d) < np.median(best):
            best = d
    assert abs(stable_curve.mu * wu.mu - 1.0) <= 1e-6
    # the two fundamental domains are mirror images (same s0, sigma and |mu|^sigma), so the
    # points nearly coincide: measured 1.2e-10 at most (amplified float64 rounding), far
    # below the polylines' chord error delta * alpha / 4 = 3.8e-3
    assert np.max(best) <= 1e-8, np.max(best)
