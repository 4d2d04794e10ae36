"""Homoclinic points of the Fig. 4a saddle (k = 10) of the 3D section map: the 1D stable curve
piercing the 2D unstable surface (periodic_manifolds_3d.homoclinic_points_3d).

The geometric search is checked on a surface with a known answer (planar rings); the bad
input is refused before any work."""

import dataclasses
import math

import numpy as np
import pytest

from taylorball.errors import UsageError


def _planar_surface(n_rings=4, n_iter=2, mu=(2.0, 3.0), n_phi=40):
    """A ManifoldSurface whose leaves are the ellipses (mu_1^u cos phi, mu_2^u sin phi, 0),
    u = n + tau, in the plane r2 = 0 around (l, r1) = (1, 0): the surface of a linear node."""
    from taylorball.periodic_manifolds_3d import ManifoldSurface

    leaves, phis, taus, its = [], [], [], []
    for n in range(n_iter + 1):
        for j in range(n_rings):
            u = n + j / n_rings
            phi = np.linspace(0.0, 2 * np.pi, n_phi, endpoint=False) + 0.01 * (j % 2)  # not aligned across rings
            leaves.append(np.column_stack([1.0 + 0.1 * mu[0] ** u * np.cos(phi), 0.1 * mu[1] ** u * np.sin(phi),
                                           np.zeros(n_phi)]))
            phis.append(phi)
            taus.append(j / n_rings)
            its.append(n)
    m = len(leaves)
    return ManifoldSurface(leaves=leaves, states=[np.zeros((n_phi, 9))] * m, phi=phis,
                           broken=[np.zeros(n_phi, dtype=bool)] * m, tau=np.array(taus), iterate=np.array(its),
                           extent=np.ones(m), mu=np.array(mu, dtype=complex), directions=np.eye(2, 9),
                           eigenvectors=np.eye(2, 9), focus=False, s0=1e-4, delta=0.05, alpha=0.3, delta_min=1e-3,
                           complete=True, stopped="n_iter reached", map_calls=0, cpu_seconds=0.0)


def test_geometric_search_finds_the_piercing_point_and_its_parameters():
    """A segment through the plane of a linear node's surface at a point with known (u, phi):
    exactly one triangle is pierced, at that point, and the interpolated parameters are the
    point's to the mesh's interpolation error (u: the rings are 1/4 apart and the radius
    grows by 2..3 per unit of u, so linear interpolation in the chart is off by ~1e-2 in u;
    phi: ~2 pi / 40 / 4 at most)."""
    from taylorball.periodic_manifolds_3d import _band_triangles, _pierce

    S = _planar_surface()
    tris, par = _band_triangles(S, 4)
    # 2 iterates x 4 rings of bands (the last leaf has no successor), ~2 x 40 triangles each
    assert len(tris) == (len(S.leaves) - 1) * 80
    for u, phi in ((0.6, 0.3), (1.37, 2.0), (2.1, 5.9)):
        target = np.array([1.0 + 0.1 * 2.0 ** u * math.cos(phi), 0.1 * 3.0 ** u * math.sin(phi), 0.0])
        d = np.array([0.01, 0.02, 1.0])
        p, q = target - 0.3 * d, target + 0.5 * d  # crosses the plane at the target
        hits = _pierce(tris, p, q)
        assert len(hits) == 1, hits
        i, b1, b2, t = hits[0]
        x = tris[i, 0] + b1 * (tris[i, 1] - tris[i, 0]) + b2 * (tris[i, 2] - tris[i, 0])
        # the triangle's point is the segment's and the target, to rounding (64 eps: a few
        # operations on numbers of order 1)
        assert np.allclose(x, p + t * (q - p), rtol=0, atol=64 * np.finfo(float).eps)
        assert np.allclose(x, target, rtol=0, atol=64 * np.finfo(float).eps)
        uv = par[i, 0] + b1 * (par[i, 1] - par[i, 0]) + b2 * (par[i, 2] - par[i, 0])
        assert abs(uv[0] - u) <= 0.03 and abs((uv[1] - phi + np.pi) % (2 * np.pi) - np.pi) <= 0.05, (u, phi, uv)
    # a segment that stays off the plane, and one across the l wrap, pierce nothing
    assert _pierce(tris, np.array([1.0, 0.0, 0.1]), np.array([1.2, 0.1, 0.4])) == []
    assert _pierce(tris, np.array([6.2, 0.0, -0.1]), np.array([0.1, 0.0, 0.1])) == []


@pytest.fixture(scope="module")
def saddle():
    from taylorball.periodic_catalog import FIG4A_SADDLE_K10, catalog_orbit

    return catalog_orbit(FIG4A_SADDLE_K10)


@pytest.fixture(scope="module")
def small(saddle):
    """A small surface (iterates 0..1) and a short stable curve: only for the refusals."""
    from taylorball.periodic_manifolds import grow_manifold
    from taylorball.periodic_manifolds_3d import grow_surface

    return (grow_surface(saddle, n_iter=1, extent=0.05, workers=1),
            grow_manifold(saddle, "stable", length=0.005, branch=1, refine_all=False))


def test_bad_input_is_refused_before_work(saddle, small):
    from taylorball.periodic_manifolds_3d import homoclinic_points_3d

    S, ws = small
    for kw, word in ((dict(max_points=0), "max_points"), (dict(max_points=1.5), "max_points"),
                     (dict(max_iter=0), "max_iter"), (dict(tol_factor=0.5), "tol_factor"),
                     (dict(tol_factor=float("nan")), "tol_factor"), (dict(max_edge=0.0), "max_edge")):
        with pytest.raises(UsageError, match=word):
            homoclinic_points_3d(saddle, S, ws, **kw)
    with pytest.raises(UsageError, match="ManifoldSurface"):
        homoclinic_points_3d(saddle, ws, ws)
    with pytest.raises(UsageError, match="stable must be"):
        homoclinic_points_3d(saddle, S, S)
    with pytest.raises(UsageError, match="stable must be"):
        homoclinic_points_3d(saddle, S, [])
    with pytest.raises(UsageError, match="stable must be"):
        homoclinic_points_3d(saddle, S, dataclasses.replace(ws, which="unstable"))
    # a saddle with a 2D stable manifold (one multiplier outside), a non-saddle, not an orbit
    for mu in ([0.1, 0.2, 50.0], [0.5, 1.0, 2.0 + 0j]):
        with pytest.raises(UsageError, match="unstable manifold is 2D"):
            homoclinic_points_3d(dataclasses.replace(saddle, multipliers=np.array(mu)), S, ws)
    with pytest.raises(UsageError, match="PeriodicOrbit"):
        homoclinic_points_3d(np.zeros(9), S, ws)
    # a surface of another orbit
    with pytest.raises(UsageError, match="not the unstable surface of this orbit"):
        homoclinic_points_3d(saddle, _planar_surface(), ws)


def test_tangents_of_the_two_manifolds_agree_with_finite_differences_of_fresh_runs(saddle):
    """The tangents the Newton and the angle use (variational equations along F^n; the stable
    side forwards from its preimage) against central differences in the parameters of fresh
    runs: the unstable side by poincare_section (10 n crossings, counted), the stable side by
    inverse_map (10 n crossings backwards), each from the same fundamental-domain starts.
    Away from any intersection, at (tau, phi) = (0.3, 1.1), n_u = 2 and sigma = 0.4, n_s = 1.
    The surface's tangent plane (its chart normal) and the stable curve's chart tangent agree
    to 1e-6 rad, and so does the angle between the two (which is not a homoclinic angle here:
    the points differ). Measured 2026-11-29: 3.4e-8 (plane), 2.5e-8 (tangent), 2.5e-8
    (angle 0.6236 rad); the bound is 30 times that, room for the differences' own error
    (step 1e-4: truncation ~1e-8 |ln mu|^3 relative, rounding amplified by the maps ~1e-13 /
    (1e-4 |D|))."""
    import taylorball as tb
    from taylorball._propagate import public_state, start_state
    from taylorball.paper import FIG4_BALL
    from taylorball.periodic_manifolds import inverse_map
    from taylorball.periodic_manifolds_3d import _chart_dir, _plane_angle, _Shooter
    from taylorball.sections import chart_points

    sh = _Shooter(saddle, 1e-4, 1e-6, 1)
    prob = saddle.problem

    def pub(x):
        return public_state(prob.system, prob.pars, x, prob.spec)

    tau, phi, n_u, sigma, n_s, h = 0.3, 1.1, 2, 0.4, 1, 1e-4
    z_u, Du = sh.unstable(tau, phi, n_u)
    z_s, ds = sh.stable(sigma, n_s)
    Cu = np.column_stack([_chart_dir(sh.pl, z_u, Du[:, 0]), _chart_dir(sh.pl, z_u, Du[:, 1])])
    cs = _chart_dir(sh.pl, z_s, ds)

    def fwd(x):
        return tb.poincare_section("reduced", FIG4_BALL, pub(x), n_points=10 * n_u).points[-1]

    def bwd(x):
        return chart_points("reduced", start_state(prob, inverse_map(saddle, pub(x), 10 * n_s)[-1])[None, :])[0]

    # the fresh runs land on the code's points
    assert np.max(np.abs(fwd(sh.start_u(tau, phi)) - sh.pl.chart(z_u[None, :])[0])) <= 1e-9
    assert np.max(np.abs(bwd(sh.start_s(sigma)) - sh.pl.chart(z_s[None, :])[0])) <= 1e-9
    fd_u = np.column_stack([(fwd(sh.start_u(tau + h, phi)) - fwd(sh.start_u(tau - h, phi))) / (2 * h),
                            (fwd(sh.start_u(tau, phi + h)) - fwd(sh.start_u(tau, phi - h))) / (2 * h)])
    fd_s = (bwd(sh.start_s(sigma + h)) - bwd(sh.start_s(sigma - h))) / (2 * h)
    n_code = np.cross(Cu[:, 0], Cu[:, 1])
    n_fd = np.cross(fd_u[:, 0], fd_u[:, 1])
    plane_err = float(np.arcsin(min(1.0, np.linalg.norm(np.cross(n_code, n_fd)) /
                                     (np.linalg.norm(n_code) * np.linalg.norm(n_fd)))))
    tangent_err = float(np.arcsin(min(1.0, np.linalg.norm(np.cross(cs, fd_s)) / (np.linalg.norm(cs) * np.linalg.norm(fd_s)))))
    a_code, a_fd = _plane_angle(Cu, cs)[0], _plane_angle(fd_u, fd_s)[0]
    assert plane_err <= 1e-6 and tangent_err <= 1e-6, (plane_err, tangent_err)
    assert abs(a_code - a_fd) <= 1e-6, (a_code, a_fd)
    assert sh.calls > 0


def test_newton_from_a_point_off_both_manifolds_fails_with_its_history(saddle):
    """homoclinic_point_3d from parameters whose two points are far apart (no homoclinic
    point near: the unstable ring's point after one iterate and the stable domain's point
    after none) raises StateError with the residual reached, and refuses bad guesses first."""
    from taylorball.errors import StateError
    from taylorball.periodic_manifolds_3d import homoclinic_point_3d

    for g in ((1, 0.0, 0.0, 0), (-1, 0.0, 0.0, 0, 0.0), (1, float("nan"), 0.0, 0, 0.0), (1.5, 0.0, 0.0, 0, 0.0)):
        with pytest.raises(UsageError, match="guess"):
            homoclinic_point_3d(saddle, g, branch=1)  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="branch"):
        homoclinic_point_3d(saddle, (1, 0.0, 0.0, 0, 0.0), branch=0)
    with pytest.raises(UsageError, match="s0_u"):
        homoclinic_point_3d(saddle, (1, 0.0, 0.0, 0, 0.0), branch=1, s0_u=0.5)
    with pytest.raises(StateError, match="rounding floor"):
        homoclinic_point_3d(saddle, (1, 0.0, 0.0, 0, 0.5), branch=1, max_iter=2)


def test_near_the_saddle_the_manifolds_meet_only_at_it(saddle, small):
    """Near the saddle W^s is transverse to W^u's plane, so the search over the small
    surface (iterates 0..1, chart distance < 0.05) and the short stable curve (arc 0.005)
    finds no crossing and reports no point: the triangulation of a real surface does not
    invent one."""
    from taylorball.periodic_manifolds_3d import _band_triangles, _pierce, homoclinic_points_3d

    S, ws = small
    tris, _ = _band_triangles(S, 4)
    assert len(tris) >= 4 * 24  # the bands of the grown leaves were triangulated
    P = ws.points
    assert sum(len(_pierce(tris, P[i], P[i + 1])) for i in range(len(P) - 1)) == 0
    assert homoclinic_points_3d(saddle, S, ws) == []
