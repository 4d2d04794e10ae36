r"""Homoclinic points of a saddle of the 3D section map of the reduced system, where its 1D
stable curve pierces its 2D unstable surface; and the home of the 3D map's 2D manifolds'
public names.

The surfaces themselves (:func:`grow_surface`, :class:`ManifoldSurface`,
:func:`surface_trace`) are grown in :mod:`taylorball.periodic_surfaces` and importable from
here. :func:`homoclinic_points_3d` intersects the surface with the stable curve of
:func:`taylorball.periodic_manifolds.grow_manifold` and refines each crossing by Newton
(:func:`homoclinic_point_3d`). docs/skeleton.md, "Homoclinic points of the 3D map's saddle".
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple, Union

import numpy as np

from .errors import IntegrationError, StateError, UsageError
from .periodic import PeriodicOrbit, _eval_geo, _f64, _Ctx, _to_level
from ._propagate import public_state
from .periodic_manifolds import Manifold, _check_pos, _wrap_l
# grow_surface and surface_trace are re-exported: their documented home
from .periodic_surfaces import ManifoldSurface, _Plane, grow_surface, surface_trace  # noqa: F401

_log = logging.getLogger(__name__)

__all__ = ["ManifoldSurface", "grow_surface", "surface_trace", "HomoclinicPoint3D", "homoclinic_points_3d",
           "homoclinic_point_3d"]


# ---------------------------------------------------------------------------------------
# Homoclinic points: the 1D stable curve piercing the 2D unstable surface.
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class HomoclinicPoint3D:
    r"""A transverse intersection of the 1D stable and the 2D unstable manifold of a saddle
    of the 3D section map.

    The point is ``F^{n_u}(C_tau(phi))`` on the unstable surface (``C_tau`` the closed curves
    of :func:`grow_surface`, offset ``s0_u``) and ``F^{-n_s}(x* + branch s0_s |mu_s|^-sigma
    v_s)`` on the stable curve (:func:`taylorball.periodic_manifolds.grow_manifold`'s
    fundamental domain, offset ``s0_s``), each start moved onto section and level; Newton on
    ``(tau, phi, sigma)`` makes the two states agree on the tangent space of section and
    level.

    Attributes
    ----------
    point : ndarray, shape (3,)
        Chart point ``(l, r1, r2)`` (of the unstable side).
    state : ndarray
        Public state of the unstable side (float64).
    state_s : ndarray
        Public state of the stable side.
    n_u, n_s : int
        Iterates of ``F`` from the unstable ring, of ``F^-1`` from the stable fundamental domain.
    tau, phi, sigma : float
        The parameters at the solution.
    branch : int
        The stable curve's side of the saddle.
    s0_u, s0_s : float
        The offsets of the two fundamental domains (relative to ``max(1, |x*|)``).
    residual : float
        ``max |x_u - x_s|`` of the internal states of the two sides at the solution.
    residual_chart : float
        Their chart distance (max norm, ``l`` wrapped).
    noise : float
        The rounding floor the residual is judged against: ``eps max(1, |x*|)
        (|mu_u|^{n_u} + |mu_s|^{-n_s})`` (the start's rounding amplified by the maps).
    residual_history : tuple of float
        The tangent-space mismatch at each Newton iterate.
    angle : float
        Between the stable curve's tangent and the unstable surface's tangent plane, in the
        chart ``(l, r1, r2)`` (radians, in ``(0, pi/2]``).
    angle_state : float
        The same in the tangent space of section and level (Euclidean metric of the
        internal variables).
    tangent_s : ndarray, shape (3,)
        Unit chart tangent of the stable curve.
    tangents_u : ndarray, shape (2, 3)
        Chart tangents of the surface along ``tau`` and ``phi`` (not normalised).
    normal_u : ndarray, shape (3,)
        Unit chart normal of the surface.
    newton_iterations : int
    map_calls : int
        Evaluations of ``F^n`` or ``F^-n`` (with or without the variational equations) for
        this point.
    """

    point: np.ndarray
    state: np.ndarray
    state_s: np.ndarray
    n_u: int
    n_s: int
    tau: float
    phi: float
    sigma: float
    branch: int
    s0_u: float
    s0_s: float
    residual: float
    residual_chart: float
    noise: float
    residual_history: Tuple[float, ...]
    angle: float
    angle_state: float
    tangent_s: np.ndarray
    tangents_u: np.ndarray
    normal_u: np.ndarray
    newton_iterations: int
    map_calls: int


def _band_triangles(surface: ManifoldSurface, n_rings: int):
    """Triangles between consecutive leaves in ``u = iterate + tau`` (matched by ``phi``: the
    leaf ``F^n(C_tau)`` and the next ring's share the parametrisation), as chart vertices
    ``(m, 3, 3)`` and their ``(u, phi)`` (``(m, 3, 2)``, ``phi`` unwrapped within a
    triangle); triangles on a broken segment are left out."""
    key = {(int(it), round(float(t) * n_rings)): j for j, (it, t) in enumerate(zip(surface.iterate, surface.tau))}
    tris, pars = [], []
    for (it, r), ja in key.items():
        nxt = (it, r + 1) if r + 1 < n_rings else (it + 1, 0)
        jb = key.get(nxt)
        if jb is None:
            continue
        A, B = surface.leaves[ja], surface.leaves[jb]
        pa, pb = surface.phi[ja], surface.phi[jb]
        ba, bb = surface.broken[ja], surface.broken[jb]
        ua, ub = it + r / n_rings, nxt[0] + nxt[1] / n_rings
        na, nb = len(A), len(B)
        i = j = 0
        while i < na or j < nb:  # the zipper: advance on the leaf whose next phi is smaller
            fa = pa[(i + 1) % na] + 2 * np.pi * ((i + 1) // na) if i < na else np.inf
            fb = pb[(j + 1) % nb] + 2 * np.pi * ((j + 1) // nb) if j < nb else np.inf
            va = (A[i % na], ua, pa[i % na] + 2 * np.pi * (i // na))
            vb = (B[j % nb], ub, pb[j % nb] + 2 * np.pi * (j // nb))
            if fa <= fb:
                vc, brk = (A[(i + 1) % na], ua, fa), ba[i % na]
                i += 1
            else:
                vc, brk = (B[(j + 1) % nb], ub, fb), bb[j % nb]
                j += 1
            if brk:
                continue
            tris.append([va[0], vb[0], vc[0]])
            pars.append([[va[1], va[2]], [vb[1], vb[2]], [vc[1], vc[2]]])
    return np.array(tris, dtype=float).reshape(-1, 3, 3), np.array(pars, dtype=float).reshape(-1, 3, 2)


def _pierce(tris: np.ndarray, p: np.ndarray, q: np.ndarray) -> List[Tuple[int, float, float, float]]:
    """Where the chart segment ``p -> q`` crosses the triangles (Moeller-Trumbore, ``l``
    differences wrapped, triangles and segments spanning more than 1 in ``l`` skipped):
    ``(triangle, b1, b2, t)`` with the point ``v0 + b1 (v1 - v0) + b2 (v2 - v0) = p + t (q - p)``."""
    e1 = _wrap_l(tris[:, 1] - tris[:, 0])
    e2 = _wrap_l(tris[:, 2] - tris[:, 0])
    d = _wrap_l(q - p)
    if abs(d[0]) > 1.0:
        return []
    s = _wrap_l(p[None, :] - tris[:, 0])
    h = np.cross(np.broadcast_to(d, e2.shape), e2)
    a = np.einsum("ij,ij->i", e1, h)
    ok = (np.abs(a) > 1e-300) & (np.abs(e1[:, 0]) < 1.0) & (np.abs(e2[:, 0]) < 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = 1.0 / a
        b1 = f * np.einsum("ij,ij->i", s, h)
        qv = np.cross(s, e1)
        b2 = f * (qv @ d)
        t = f * np.einsum("ij,ij->i", e2, qv)
    hit = ok & (b1 >= 0) & (b2 >= 0) & (b1 + b2 <= 1) & (t >= 0) & (t < 1)
    return [(int(i), float(b1[i]), float(b2[i]), float(t[i])) for i in np.flatnonzero(hit)]


#: Step in ``tau``, ``phi`` and ``sigma`` of the central differences of the fundamental domains'
#: starts (truncation ~h^2 |d^3/dsigma^3| ~ 1e-8 |ln mu_s|^3 relative; rounding ~8 eps / (h s0) ~ 1e-8).
START_STEP = 1e-4

#: The largest Newton step in ``tau``, ``phi`` or ``sigma`` (longer steps are shortened: far
#: from a solution the linearisation of ``F^n`` is poor and a long step leaves the manifold's
#: grown part).
MAX_STEP = 0.25


class _Shooter:
    """The two sides of a homoclinic point and their derivatives in the parameters (the
    variational equations along ``F^n`` and ``F^-n``)."""

    def __init__(self, orbit: PeriodicOrbit, s0_u: float, s0_s: float, branch: int) -> None:
        from .periodic_return_maps import _SaddleMap

        self.pl = _Plane(orbit)
        self.sm = _SaddleMap(orbit, "homoclinic points", "stable")
        self.s0u_rel, self.s0s_rel = s0_u, s0_s
        self.s0u = s0_u * self.pl.scale
        self.s0s = s0_s * self.pl.scale
        self.branch = branch
        self.calls = 0
        self.last = ""

    def tangent(self, z: np.ndarray) -> np.ndarray:
        from .periodic import _tangent_basis

        return _tangent_basis(self.pl.prob, self.pl.orbit.g0, z)

    def forward_var(self, x: np.ndarray, n: int) -> Tuple[np.ndarray, np.ndarray]:
        """``(F^n x, Pi Phi)``: the ``k n``-th crossing (counted) with the projected
        fundamental matrix."""
        from .periodic import _crossing_time, _flow, _jacobian

        if n == 0:
            return x.copy(), np.eye(len(x))
        pl = self.pl
        self.calls += 1
        ctx = _Ctx(pl.prob, pl.orbit.g0, pl.orbit.direction, pl.k * n, pl.ctx.targets, False, 1e4)
        T = _crossing_time(ctx, x)
        xT, Phi, _ = _flow(ctx, x, T)
        _, PP = _jacobian(ctx, x, 0.0, xT, Phi, _eval_geo(pl.prob, pl.orbit.g0, x))
        return xT, PP

    def start_u(self, tau: float, phi: float) -> np.ndarray:
        """``C_tau(phi)`` on section and level (internal)."""
        pl = self.pl
        c = np.array([math.cos(phi), math.sin(phi)])
        return _to_level(pl.ctx, pl.x + pl.spec.array(self.s0u * (pl.W @ pl.linear(tau) @ c)), pl.scale)

    def start_s(self, sigma: float) -> np.ndarray:
        """``x* + branch s0 |mu_s|^-sigma v_s`` on section and level (internal)."""
        d = self.branch * self.s0s * (1.0 / abs(self.sm.mu_s)) ** sigma * self.sm.v_s
        return _to_level(self.pl.ctx, self.pl.x + self.pl.spec.array(d), self.pl.scale)

    def unstable(self, tau: float, phi: float, n: int):
        """``F^n(C_tau(phi))`` and its derivatives along ``tau`` and ``phi`` (internal)."""
        pl = self.pl
        q = self.start_u(tau, phi)
        h = START_STEP  # central differences of the start (no integration): the start's derivative
        D = np.column_stack([_f64(self.start_u(tau + h, phi) - self.start_u(tau - h, phi)) / (2 * h),
                             _f64(self.start_u(tau, phi + h) - self.start_u(tau, phi - h)) / (2 * h)])
        z, PP = self.forward_var(q, n)
        return z, PP @ D

    def stable(self, sigma: float, n: int):
        """``F^-n(x* + branch s0 |mu_s|^-sigma v_s)`` and its derivative along ``sigma``: the
        flow backwards to the crossings (counted), then forwards with the variational
        equations from there."""
        sm, pl = self.sm, self.pl
        p = self.start_s(sigma)
        h = START_STEP
        dp = _f64(self.start_s(sigma + h) - self.start_s(sigma - h)) / (2 * h)
        z = p
        for _ in range(n):
            self.calls += 1
            z = sm.backward(z)[-1]
        back, PP = self.forward_var(z, n)
        if float(np.max(np.abs(_f64(back - p)))) > 1e-6 * pl.scale:
            raise StateError(f"F^{n} of F^-{n} of the stable start is off it by "
                             f"{float(np.max(np.abs(_f64(back - p)))):.1e}: the crossings counted backwards and "
                             f"forwards differ")
        Bz, Bp = self.tangent(z), self.tangent(p)
        y = np.linalg.lstsq(Bp.T @ PP @ Bz, Bp.T @ dp, rcond=None)[0]
        return z, Bz @ y


def _chart_dir(pl: _Plane, z: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The chart's derivative along ``t`` at ``z`` (central differences, ``h = 1e-7`` relative:
    truncation ~h^2, rounding ~eps / h ~ 1e-9)."""
    h = 1e-7 / max(1e-300, float(np.linalg.norm(t)))
    return _wrap_l(pl.chart(np.array([z + h * t]))[0] - pl.chart(np.array([z - h * t]))[0]) / (2 * h)


def _plane_angle(U: np.ndarray, s: np.ndarray) -> Tuple[float, np.ndarray]:
    """The angle between the vector ``s`` and the plane of the columns of ``U`` (3D), and the
    plane's unit normal."""
    nrm = np.cross(U[:, 0], U[:, 1])
    nrm = nrm / np.linalg.norm(nrm)
    c = abs(float(np.dot(nrm, s))) / float(np.linalg.norm(s))
    return float(np.arcsin(min(1.0, c))), nrm


def homoclinic_points_3d(orbit: PeriodicOrbit, surface: ManifoldSurface, stable: Union[Manifold, Sequence[Manifold]],
                         *, max_points: int = 8, max_iter: int = 12, tol_factor: float = 64.0,
                         max_edge: Optional[float] = None) -> List[HomoclinicPoint3D]:
    r"""Homoclinic points of a saddle of the 3D section map: where its 1D stable curve pierces
    its 2D unstable surface, refined by Newton on three parameters.

    Candidates: every crossing of a segment of ``stable``'s curve (``grow_manifold(orbit,
    "stable", ...)``, not across a jump) with a triangle between consecutive leaves of
    ``surface`` (``grow_surface(orbit, ...)``; leaves ``F^n(C_tau)`` of consecutive ``u = n
    + tau``, matched by ``phi``). From the interpolated parameters, Newton on ``(tau, phi,
    sigma)`` solves ``B^T (F^{n_u}(C_tau(phi)) - F^{-n_s}(p_s(sigma))) = 0`` (``B`` an
    orthonormal basis of the tangent space of section and level; ``n_u``, ``n_s`` the
    candidate's iterate and level; every evaluation a fresh run from the fundamental
    domains, crossings counted), with the Jacobian from the variational equations along
    ``F^{n_u}`` and ``F^{n_s}`` (the stable side: forwards from its preimage). The same
    derivatives give the tangents of the two manifolds at the solution and the angle.

    A solution is kept if its residual is below ``tol_factor`` times the rounding floor
    ``eps max(1, |x*|) (|mu_u|^{n_u} + |mu_s|^{-n_s})`` (the starts' rounding amplified by
    the maps); a point found twice (chart distance below 1e-8) is kept once.

    Parameters
    ----------
    orbit : PeriodicOrbit
        The saddle (float64) with a 2D unstable and a 1D stable manifold.
    surface : ManifoldSurface
        Its unstable surface from :func:`grow_surface` (of this orbit).
    stable : Manifold or sequence of Manifold
        Its stable curve(s) from :func:`taylorball.periodic_manifolds.grow_manifold` (of this
        orbit, ``which = "stable"``; one per branch).
    max_points : int
        At most this many points (``>= 1``; candidates in the order of the curve).
    max_iter : int
        Newton iterations per candidate (``>= 1``).
    tol_factor : float
        Acceptance: residual below this times the rounding floor (``>= 1``).
    max_edge : float, optional
        Triangles with an edge longer than this in the chart are left out (default ``10
        surface.delta``): far from the saddle the leaves of neighbouring rings fold
        differently, and points of equal ``phi`` on them can be far apart; such a triangle
        bridges the gap and is no piece of the surface.

    Returns
    -------
    list of HomoclinicPoint3D
        Sorted by chart distance from ``orbit.points[0]``.

    Raises
    ------
    UsageError
        An orbit that is not such a saddle, a surface or stable curve not of this orbit, bad
        counts (before any work).
    """
    if not isinstance(surface, ManifoldSurface):
        raise UsageError(f"surface must be a ManifoldSurface (from grow_surface), got {type(surface).__name__}")
    curves = [stable] if isinstance(stable, Manifold) else list(stable) if isinstance(stable, (list, tuple)) else None
    if not curves or not all(isinstance(m, Manifold) and m.which == "stable" for m in curves):
        raise UsageError(f"stable must be a Manifold from grow_manifold(orbit, 'stable', ...) or a list of them, got "
                         f"{stable!r:.80}")
    if not isinstance(max_points, (int, np.integer)) or isinstance(max_points, bool) or max_points < 1:
        raise UsageError(f"max_points must be an integer >= 1, got {max_points!r}")
    _check_solve(max_iter, tol_factor)
    if max_edge is not None:
        _check_pos("max_edge", max_edge)
    if isinstance(orbit, PeriodicOrbit) and orbit.fp_type != "float":
        raise UsageError(f"homoclinic_points_3d runs in float64: pass the float64 orbit, got fp_type {orbit.fp_type!r}")
    pl = _Plane(orbit)  # refuses what is not a saddle with a 2D unstable manifold
    p0 = pl.p0
    if surface.which != "unstable" or float(np.max(np.abs(_wrap_l(surface.leaves[0][0] - p0)))) > 1e-2 or \
            surface.mu.shape != (2,) or \
            not np.allclose(np.sort(np.abs(surface.mu)), np.sort(np.abs(pl.mu)), rtol=1e-9):
        raise UsageError("surface is not the unstable surface of this orbit (grow_surface(orbit, ...))")
    for m in curves:
        if m.curves.shape[0] != orbit.k or float(np.max(np.abs(_wrap_l(m.points[0] - p0)))) > 1e-2:
            raise UsageError("stable is not the stable curve of this orbit's first point (grow_manifold(orbit, "
                             "'stable', ...))")
    n_rings = int(round(1.0 / float(np.min(np.diff(np.unique(np.append(surface.tau, 1.0))))))) \
        if len(np.unique(surface.tau)) > 1 else 1
    tris, tpar = _band_triangles(surface, n_rings)
    edge = np.max([np.linalg.norm(_wrap_l(tris[:, a] - tris[:, b]), axis=1) for a, b in ((0, 1), (1, 2), (2, 0))],
                  axis=0) if len(tris) else np.zeros(0)
    keep = edge <= (10.0 * surface.delta if max_edge is None else float(max_edge))
    tris, tpar = tris[keep], tpar[keep]
    found: List[HomoclinicPoint3D] = []
    for m in curves:
        P = m.points
        sh = _Shooter(orbit, float(surface.s0), float(m.s0), int(m.branch))
        for i in range(len(P) - 1):
            if m.level[i] != m.level[i + 1] or m.xjumps[i] or not np.all(np.isfinite(P[i:i + 2])):
                continue
            for it, b1, b2, t in _pierce(tris, P[i], P[i + 1]):
                uv = tpar[it, 0] + b1 * (tpar[it, 1] - tpar[it, 0]) + b2 * (tpar[it, 2] - tpar[it, 0])
                n_u = int(math.floor(float(np.max(tpar[it, :, 0]))))
                guess = (n_u, float(uv[0] - n_u), float(uv[1] % (2 * np.pi)), int(m.level[i]),
                         float(m.sigma[i] + t * (m.sigma[i + 1] - m.sigma[i])))
                q = _solve_3d(sh, guess, max_iter, tol_factor)
                if q is None or any(float(np.max(np.abs(_wrap_l(q.point - f.point)))) <= 1e-8 for f in found):
                    continue
                found.append(q)
                if len(found) >= max_points:
                    return sorted(found, key=lambda f: float(np.linalg.norm(_wrap_l(f.point - p0))))
    return sorted(found, key=lambda f: float(np.linalg.norm(_wrap_l(f.point - p0))))


def homoclinic_point_3d(orbit: PeriodicOrbit, guess: Tuple[int, float, float, int, float], *, branch: int,
                        s0_u: float = 1e-4, s0_s: float = 1e-6, max_iter: int = 12,
                        tol_factor: float = 64.0) -> HomoclinicPoint3D:
    r"""One homoclinic point of a saddle of the 3D section map by Newton from a guess of its
    parameters ``(n_u, tau, phi, n_s, sigma)`` (as in :class:`HomoclinicPoint3D`; e.g. one
    found before by :func:`homoclinic_points_3d`): the solve that function applies to each
    candidate.

    Parameters
    ----------
    orbit : PeriodicOrbit
        The saddle (float64) with a 2D unstable and a 1D stable manifold.
    guess : tuple
        ``(n_u, tau, phi, n_s, sigma)``: iterates ``n_u, n_s >= 0`` and finite parameters.
    branch : {1, -1}
        The stable curve's side of the saddle.
    s0_u, s0_s : float
        The offsets of the unstable ring and of the stable fundamental domain, in ``(0, 0.1)``
        (relative to ``max(1, |x*|)``; :func:`grow_surface`'s and ``grow_manifold``'s defaults).
    max_iter, tol_factor
        As for :func:`homoclinic_points_3d`.

    Returns
    -------
    HomoclinicPoint3D

    Raises
    ------
    UsageError
        Bad arguments or an orbit that is not such a saddle (before any work).
    StateError
        Newton did not reach ``tol_factor`` times the rounding floor (with the history), or
        a map failed.
    """
    ok = isinstance(guess, (tuple, list)) and len(guess) == 5 and all(
        isinstance(guess[i], (int, np.integer)) and not isinstance(guess[i], bool) and guess[i] >= 0 for i in (0, 3)) \
        and all(isinstance(guess[i], (int, float, np.floating, np.integer)) and not isinstance(guess[i], bool)
                and math.isfinite(float(guess[i])) for i in (1, 2, 4))
    if not ok:
        raise UsageError(f"guess must be (n_u, tau, phi, n_s, sigma) with integers n_u, n_s >= 0 and finite tau, phi, "
                         f"sigma, got {guess!r}")
    if branch not in (1, -1) or isinstance(branch, bool):
        raise UsageError(f"branch must be 1 or -1 (the stable curve's side of the saddle), got {branch!r}")
    _check_pos("s0_u", s0_u, upper=0.1)
    _check_pos("s0_s", s0_s, upper=0.1)
    _check_solve(max_iter, tol_factor)
    if isinstance(orbit, PeriodicOrbit) and orbit.fp_type != "float":
        raise UsageError(f"homoclinic_point_3d runs in float64: pass the float64 orbit, got fp_type {orbit.fp_type!r}")
    sh = _Shooter(orbit, float(s0_u), float(s0_s), int(branch))
    g = (int(guess[0]), float(guess[1]), float(guess[2]), int(guess[3]), float(guess[4]))
    q = _solve_3d(sh, g, max_iter, tol_factor)
    if q is None:
        raise StateError(f"Newton from {g} did not reach {tol_factor} times the rounding floor: {sh.last}")
    return q


def _check_solve(max_iter, tol_factor) -> None:
    if not isinstance(max_iter, (int, np.integer)) or isinstance(max_iter, bool) or max_iter < 1:
        raise UsageError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    if not isinstance(tol_factor, (int, float)) or isinstance(tol_factor, bool) or not math.isfinite(tol_factor) \
            or not tol_factor >= 1.0:
        raise UsageError(f"tol_factor must be a finite number >= 1, got {tol_factor!r}")


def _solve_3d(sh: "_Shooter", guess: Tuple[int, float, float, int, float], max_iter: int,
              tol_factor: float) -> Optional[HomoclinicPoint3D]:
    """Newton from ``guess``, the acceptance test and the tangents; ``None`` if rejected
    (the reason in ``sh.last``)."""
    pl = sh.pl
    n_u, n_s = guess[0], guess[3]
    calls0 = sh.calls
    hit = _newton_3d(sh, np.array([guess[1], guess[2], guess[4]]), n_u, n_s, max_iter)
    if hit is None:
        return None
    z_u, z_s, Du, ds, x, hist, its = hit
    res = float(np.max(np.abs(_f64(z_u - z_s))))
    noise = float(np.finfo(float).eps) * pl.scale * (float(np.max(np.abs(pl.mu))) ** n_u + abs(sh.sm.mu_s) ** (-n_s))
    if not res <= tol_factor * noise:
        sh.last = f"residual {res:.1e}, rounding floor {noise:.1e}; mismatch history {[f'{h:.1e}' for h in hist]}"
        _log.debug("Newton from a candidate stalled: %s", sh.last)
        return None
    pt = pl.chart(np.array([_f64(z_u)]))[0]
    Bz = sh.tangent(z_u)
    ang_state, _ = _plane_angle(Bz.T @ Du, Bz.T @ ds)
    Cu = np.column_stack([_chart_dir(pl, _f64(z_u), Du[:, 0]), _chart_dir(pl, _f64(z_u), Du[:, 1])])
    cs = _chart_dir(pl, _f64(z_u), ds)
    ang, nrm = _plane_angle(Cu, cs)
    prob = pl.prob
    return HomoclinicPoint3D(
        point=pt, state=public_state(prob.system, prob.pars, z_u, prob.spec),
        state_s=public_state(prob.system, prob.pars, z_s, prob.spec), n_u=int(n_u), n_s=int(n_s),
        tau=float(x[0]), phi=float(x[1]), sigma=float(x[2]), branch=sh.branch, s0_u=sh.s0u_rel, s0_s=sh.s0s_rel,
        residual=res, residual_chart=float(np.max(np.abs(_wrap_l(pt - pl.chart(np.array([_f64(z_s)]))[0])))),
        noise=noise, residual_history=tuple(hist), angle=ang, angle_state=ang_state,
        tangent_s=cs / np.linalg.norm(cs), tangents_u=Cu.T.copy(), normal_u=nrm, newton_iterations=its,
        map_calls=sh.calls - calls0)


def _newton_3d(sh: _Shooter, x: np.ndarray, n_u: int, n_s: int, max_iter: int):
    """Newton on ``(tau, phi, sigma)``; ``None`` where a map fails. Ends when the mismatch
    no longer halves (the rounding floor) or after ``max_iter`` iterations."""
    hist: List[float] = []
    best = None
    for its in range(int(max_iter) + 1):
        try:
            z_u, Du = sh.unstable(float(x[0]), float(x[1]), n_u)
            z_s, ds = sh.stable(float(x[2]), n_s)
        except (IntegrationError, StateError) as exc:
            sh.last = f"a map failed: {exc}"
            _log.debug("a map failed in the homoclinic Newton: %s", exc)
            return best
        B = sh.tangent(z_u)
        Fv = B.T @ _f64(z_u - z_s)
        r = float(np.max(np.abs(_f64(z_u - z_s))))
        hist.append(float(np.max(np.abs(Fv))))
        prev = None if best is None else float(np.max(np.abs(_f64(best[0] - best[1]))))
        if prev is None or r < prev:
            best = (z_u, z_s, Du, ds, x.copy(), hist[:], its)
        if (prev is not None and r > 0.5 * prev) or its == max_iter or r == 0.0:
            return best  # at the rounding floor (or out of iterations)
        J = B.T @ np.column_stack([Du, -ds])
        dx = np.linalg.solve(J, Fv)
        x = x - dx * min(1.0, MAX_STEP / float(np.max(np.abs(dx))))  # a damped step far from the solution
    return best
