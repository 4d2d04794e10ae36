"""The 2D stable manifold of a saddle of the 3D section map (periodic_surfaces.grow_surface with
which="stable", grown by the flow backwards): FIG4A_SADDLE_K10_R, the sigma1 image of the Fig. 4a
saddle, with multipliers 0.111, 0.140 (a 2D stable node) and 64.4.

Checks against computations the code under test does not make: the reversor sigma1 applied
to the unstable surface of FIG4A_SADDLE_K10 grown forwards (the section integrator), and
fresh forward section runs from the stable surface's points. The unstable surface itself is
checked in tests/test_periodic_manifolds_3d.py."""

import dataclasses

import numpy as np
import pytest

import taylorball as tb
from taylorball.errors import UsageError
from taylorball.paper import FIG4_BALL


@pytest.fixture(scope="module")
def saddle():
    from taylorball.periodic_catalog import FIG4A_SADDLE_K10, catalog_orbit

    return catalog_orbit(FIG4A_SADDLE_K10)


@pytest.fixture(scope="module")
def mirror():
    from taylorball.periodic_catalog import FIG4A_SADDLE_K10_R, catalog_orbit

    return catalog_orbit(FIG4A_SADDLE_K10_R)


@pytest.fixture(scope="module")
def stable(mirror):
    """Leaves of 4 rings to iterate 2 of F^-1, 20 initial points each (~4 CPU s, 12 leaves,
    extents 2.4e-4 to 0.083)."""
    from taylorball.periodic_surfaces import grow_surface

    return grow_surface(mirror, "stable", n_iter=2, n_phi=20, workers=1)


def _sigma1(C):
    """The reversor sigma1 on chart points: (l, r1, r2) -> (2 pi - l, r1, -r2)."""
    D = np.array(C, dtype=float, copy=True)
    D[:, 0] = (2 * np.pi - D[:, 0]) % (2 * np.pi)
    D[:, 2] = -D[:, 2]
    return D


def _closed_polyline_distance(P, C):
    """Distance of each point of P to the closed polyline through the rows of C."""
    A, B = C, np.roll(C, -1, axis=0)
    d = B - A
    out = np.empty(len(P))
    for i, p in enumerate(P):
        t = np.clip(np.einsum("ij,ij->i", p - A, d) / np.einsum("ij,ij->i", d, d), 0.0, 1.0)
        out[i] = np.min(np.linalg.norm(p - (A + t[:, None] * d), axis=1))
    return out


def test_stable_surface_is_the_mirror_image_of_the_unstable_surface(saddle, mirror, stable):
    """The reduced equations are reversible (sigma1 P sigma1 = P^-1), so the stable manifold
    of sigma1 x* is the sigma1 image of the unstable manifold of x*, leaf by leaf: with equal
    s0 and rings, F_R^-n(C'_tau) = sigma1 F^n(C_tau) as sets. The stable leaves (grown
    backwards, 20 points per ring) and the mirrored unstable leaves (grown forwards, 24
    points: different samples of the same curves)
    * lie on each other's polylines within the refinement's resolution max(delta alpha / 4,
      delta_min) = 3.75e-3 (a segment of at most delta turning by at most alpha is off its
      arc by about delta alpha / 8, a factor 2 kept for varying curvature; where a leaf
      turns sharper its segments are shorter than delta_min, which bounds what is resolved
      there); measured 7.7e-4 at most, at the tip of the thin leaf (2, 3/4): 0.3 % to 1.2 %
      of each leaf's extent at the worst point (the chord error at the tips), the median
      point 2e-4 of it;
    * share the four points phi = 0, pi/2, pi, 3 pi/2 of the grids (the stable eigenvectors
      are the mirrored unstable ones, up to order and sign): those coincide to the maps'
      rounding, 1000 eps max(1, |x*|) mu_max^n at iterate n (the starts' rounding and the
      Taylor steps' local errors, hundreds per F, amplified along the leaf by at most
      mu_max = 8.98 per iterate); measured 1.9e-13, 2.8e-12, 3.4e-11 at n = 0, 1, 2."""
    from taylorball.periodic_surfaces import grow_surface

    assert stable.which == "stable" and stable.complete and not any(b.any() for b in stable.broken)
    # the multipliers: the stable ones of the mirror are the inverses of the saddle's unstable ones
    assert np.allclose(np.sort(np.abs(stable.mu)), np.sort(1.0 / np.abs(saddle.multipliers))[:2], rtol=1e-6)
    assert np.max(np.abs(stable.mu)) < 1.0
    p0 = saddle.points[0]
    assert np.linalg.norm(_sigma1(p0[None, :])[0] - mirror.points[0]) <= 1e-9
    unstable = grow_surface(saddle, n_iter=2, n_phi=24, workers=1)
    assert unstable.which == "unstable"
    pairs = {(int(i), float(t)): j for j, (i, t) in enumerate(zip(unstable.iterate, unstable.tau))}
    assert len(pairs) == len(stable.leaves) == 12
    resolution = max(stable.delta * stable.alpha / 4, stable.delta_min)
    scale = max(1.0, float(np.max(np.abs(saddle.internal))))
    mu_max = float(np.max(np.abs(saddle.multipliers)))
    axes = np.arange(4) * np.pi / 2
    worst = 0.0
    for j, (i, t) in enumerate(zip(stable.iterate, stable.tau)):
        u = pairs[(int(i), float(t))]
        M = _sigma1(unstable.leaves[u])
        for P, Q in ((stable.leaves[j], M), (M, stable.leaves[j])):
            d = float(np.max(_closed_polyline_distance(P, Q)))
            assert d <= resolution, (i, t, d)
            worst = max(worst, d)
        A = stable.leaves[j][[int(np.argmin(np.abs(stable.phi[j] - a))) for a in axes]]
        B = M[[int(np.argmin(np.abs(unstable.phi[u] - a))) for a in axes]]
        gap = np.max(np.min(np.linalg.norm(A[:, None, :] - B[None, :, :], axis=2), axis=1))
        assert gap <= 1e3 * np.finfo(float).eps * scale * mu_max ** i, (i, t, gap)
    assert worst > 1e-6  # different samples: most points do not coincide


def test_stable_surface_points_approach_the_saddle_at_the_stable_multipliers(mirror, stable):
    """The points of the leaf (n, tau) = (2, 0) at phi = 0, pi/2, pi, 3 pi/2 (along the
    eigenvectors w_1, w_2 of C_0, at chart distance 0.009..0.014 from the saddle), mapped
    forwards by fresh section runs (crossings counted): the distance shrinks per iterate of F
    by the first stable multiplier (0.11136) along w_1 and by the second (0.13951) along w_2,
    within 1 % (quadratic terms, relative O(d) ~ 1e-2; measured: within 0.35 %); the two
    rates differ by 25 %."""
    p0 = mirror.points[0]
    mu = np.sort(np.abs(mirror.multipliers))[:2]
    assert np.allclose(np.abs(stable.mu), mu, rtol=1e-6)  # ascending: w_1 belongs to the smaller
    j = [j for j, (i, t) in enumerate(zip(stable.iterate, stable.tau)) if i == 2 and t == 0.0][0]
    for phi, m in ((0.0, mu[0]), (np.pi / 2, mu[1]), (np.pi, mu[0]), (1.5 * np.pi, mu[1])):
        k = int(np.argmin(np.abs(stable.phi[j] - phi)))
        assert abs(stable.phi[j][k] - phi) <= 1e-12
        pts = tb.poincare_section("reduced", FIG4_BALL, stable.states[j][k], n_points=30).points[9::10]
        d = np.linalg.norm(np.vstack([stable.leaves[j][k], pts]) - p0, axis=1)
        assert 5e-3 < d[0] < 2e-2, d
        ratio = d[1:] / d[:-1]
        assert np.all(np.abs(ratio / m - 1.0) <= 0.01), (phi, ratio, m)


def test_stable_surface_bad_input_is_refused_before_work(saddle, mirror):
    from taylorball.periodic_manifolds_3d import homoclinic_points_3d
    from taylorball.periodic_manifolds import grow_manifold
    from taylorball.periodic_surfaces import ManifoldSurface, grow_surface

    with pytest.raises(UsageError, match="which"):
        grow_surface(mirror, "backward", n_iter=1)
    for kw, word in ((dict(n_iter=-1), "n_iter"), (dict(n_iter=True), "n_iter"), (dict(n_iter=2, s0=0.0), "s0"),
                     (dict(n_iter=2, extent=-1.0), "extent"), (dict(n_iter=2, n_phi=2), "n_phi")):
        with pytest.raises(UsageError, match=word):
            grow_surface(mirror, "stable", **kw)
    # the saddle has one multiplier inside the unit circle: its stable manifold is 1D
    with pytest.raises(UsageError, match=r"stable manifold is 2D only.*grow_manifold.*'unstable'"):
        grow_surface(saddle, "stable", n_iter=1)
    # and the mirror's unstable manifold is 1D
    with pytest.raises(UsageError, match=r"unstable manifold is 2D only.*grow_manifold.*'stable'"):
        grow_surface(mirror, "unstable", n_iter=1)
    two_out = dataclasses.replace(mirror, multipliers=np.array([0.5, 3.0, 50.0]))
    with pytest.raises(UsageError, match=r"stable manifold is 2D only.*\(1 inside\)"):
        grow_surface(two_out, "stable", n_iter=1)
    # a stable surface is no unstable surface for the homoclinic search
    fake = ManifoldSurface(leaves=[np.tile(saddle.points[0], (4, 1))], states=[np.zeros((4, 9))],
                           phi=[np.linspace(0, 6, 4)], broken=[np.zeros(4, dtype=bool)], tau=np.zeros(1),
                           iterate=np.zeros(1, dtype=int), extent=np.zeros(1), mu=np.array([7.17, 8.98], dtype=complex),
                           directions=np.eye(2, 9), eigenvectors=np.eye(2, 9), focus=False, s0=1e-4, delta=0.05,
                           alpha=0.3, delta_min=1e-3, complete=True, stopped="n_iter reached", map_calls=0,
                           cpu_seconds=0.0, which="stable")
    ws = grow_manifold(saddle, "stable", length=0.002, branch=1, refine_all=False)
    with pytest.raises(UsageError, match="not the unstable surface"):
        homoclinic_points_3d(saddle, fake, ws)
