r"""The 2D unstable manifold of a saddle of the 3D section map of the reduced system.

A ``k``-periodic saddle ``x*`` of the asymmetric ball's map of ``(l, r1, r2)`` on a level
with two multipliers outside the unit circle (a node: ``1 < mu_1 <= mu_2``, or a focus:
``rho e^{+-i theta}``) has a 2D unstable manifold. :func:`grow_surface` grows it by the
``k``-th return map ``F = P^k`` (crossings counted, the section integrator in the engine's
threads) as *leaves*: closed curves, the images ``F^n(C_tau)`` of the closed curves

.. math:: C_\tau(\phi) = x^* + s_0\, W A^\tau (\cos\phi, \sin\phi)^T,
   \qquad \tau \in [0, 1),\ \phi \in [0, 2\pi)

of the linearised unstable plane: ``W = (w_1, w_2)`` the unit unstable eigenvectors of
``DF`` (from the variational equations; internal variables) of a node, ``(Re w, Im w)`` of a
focus, and ``A`` the restriction of ``DF`` to the plane in that basis: ``diag(mu_1, mu_2)``,
or ``rho`` times a rotation by ``theta`` (``A^tau`` its real power). ``DF`` maps ``C_tau``
onto ``C_{tau + 1}``, so the ring ``0 <= tau < 1`` is a fundamental domain, and
the leaves of ``n_rings`` values of ``tau`` and ``n = 0, 1, ...`` iterates foliate the
surface. Each leaf is refined along ``phi`` by the distance and angle criteria of the 1D
manifolds (:func:`taylorball.periodic_manifolds.grow_manifold`): a new point is mapped
``n`` times from the fundamental domain, so no interpolation error enters. The 1D stable
manifold of such a saddle: ``grow_manifold(orbit, "stable", ...)``. docs/skeleton.md,
"The 2D manifolds of the 3D map".
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple, Union

import numpy as np

from .errors import IntegrationError, StateError, UsageError
from .periodic import PeriodicOrbit, _eval_geo, _f64, _has_axial_symmetry, _Ctx, _to_level
from ._propagate import public_state
from .periodic_manifolds import Manifold, _check_pos, _check_refinement, _wrap_l

_log = logging.getLogger(__name__)

__all__ = ["ManifoldSurface", "grow_surface", "surface_trace", "HomoclinicPoint3D", "homoclinic_points_3d",
           "homoclinic_point_3d"]

#: A leaf segment still too long when its ``phi`` interval is this short is a jump of the
#: map (a crossing appears or vanishes between its ends): it is marked broken.
PHI_GAP = 1e-9


@dataclass(frozen=True)
class ManifoldSurface:
    r"""The 2D unstable manifold of a saddle of the 3D section map, as leaves.

    Leaf ``j`` is the closed curve ``F^{iterate[j]}(C_{tau[j]})`` (see the module
    docstring), its points ordered by ``phi`` (the first point is not repeated at the end).

    Attributes
    ----------
    leaves : list of ndarray, each (n_j, 3)
        Chart points ``(l, r1, r2)`` of each leaf, in the order of ``phi``.
    states : list of ndarray, each (n_j, 9)
        The public states of the leaf points (on the section and the level).
    phi : list of ndarray
        The leaf parameter of each point.
    broken : list of ndarray of bool
        ``broken[j][i]``: the segment from point ``i`` to point ``i + 1`` (cyclically) was
        still too long at ``phi`` intervals of :data:`PHI_GAP` (a jump: draw the leaf broken
        there).
    tau, iterate : ndarray
        Per leaf: the ring parameter in ``[0, 1)`` and the number of iterates of ``F``.
    extent : ndarray
        Per leaf: the largest chart distance of its points from ``orbit.points[0]``.
    mu : ndarray (complex)
        The two unstable multipliers of ``DF`` (from the variational equations).
    directions : ndarray, shape (2, 9)
        An orthonormal basis of the unstable plane (internal variables).
    eigenvectors : ndarray, shape (2, 9)
        ``W`` transposed: the unit unstable eigenvectors of a node (``Re w, Im w`` of a focus).
    focus : bool
        The multipliers are a complex pair.
    s0, delta, alpha, delta_min : float
        The fundamental domain's offset (relative to ``max(1, |x*|)``) and the refinement.
    complete : bool
        Every ring was grown to ``n_iter`` iterates or to ``extent``.
    stopped : str
        Why the growth ended (``"n_iter reached"``, ``"extent reached"``, a limit, a failed map).
    map_calls : int
        Evaluations of ``F`` (one per point and iterate).
    cpu_seconds : float
        Process CPU time of the growth (all threads).
    """

    leaves: List[np.ndarray]
    states: List[np.ndarray]
    phi: List[np.ndarray]
    broken: List[np.ndarray]
    tau: np.ndarray
    iterate: np.ndarray
    extent: np.ndarray
    mu: np.ndarray
    directions: np.ndarray
    eigenvectors: np.ndarray
    focus: bool
    s0: float
    delta: float
    alpha: float
    delta_min: float
    complete: bool
    stopped: str
    map_calls: int
    cpu_seconds: float

    @property
    def n_points(self) -> int:
        """Points on all leaves."""
        return int(sum(len(p) for p in self.leaves))

    def __repr__(self) -> str:
        return (f"ManifoldSurface({len(self.leaves)} leaves, {self.n_points} points, iterates <= "
                f"{int(self.iterate.max()) if len(self.iterate) else -1}, extent {float(np.max(self.extent)):.3g}, "
                f"{self.stopped}, {self.map_calls} map calls)")


class _Plane:
    """The saddle, its level and section, ``DF`` on the section and level (variational
    equations) and its unstable plane."""

    def __init__(self, orbit: PeriodicOrbit) -> None:
        from .periodic import _flow, _jacobian

        if not isinstance(orbit, PeriodicOrbit):
            raise UsageError(f"orbit must be a taylorball.PeriodicOrbit (from periodic_orbit), got {type(orbit).__name__}")
        prob = orbit.problem
        mu = np.asarray(orbit.multipliers)
        if orbit.kind != "reduced" or _has_axial_symmetry(prob) or mu.shape != (3,):
            raise UsageError(f"grow_surface grows the 2D unstable manifold of a saddle of the 3D map of the reduced "
                             f"system (an asymmetric ball, 3 multipliers); got kind {orbit.kind!r} with multipliers "
                             f"{np.round(mu, 6).tolist()} (for 2D maps: periodic_manifolds.grow_manifold)")
        n_out = int(np.sum(np.abs(mu) > 1.0))
        if n_out != 2 or float(np.min(np.abs(mu))) >= 1.0:
            raise UsageError(f"the unstable manifold is 2D only with two multipliers outside the unit circle and one "
                             f"inside; this orbit has {np.round(mu, 6).tolist()} ({n_out} outside)"
                             + (": its 1D manifolds: periodic_manifolds.grow_manifold" if n_out == 1 else ""))
        self.orbit, self.prob, self.k, self.spec = orbit, prob, int(orbit.k), prob.spec
        self.x = np.asarray(orbit.internal).copy()
        geo = _eval_geo(prob, orbit.g0, self.x)
        self.ctx = _Ctx(prob, orbit.g0, orbit.direction, 1, geo.c.copy(), False, 1e4)
        self.scale = max(1.0, float(np.max(np.abs(_f64(self.x)))))
        ctxk = _Ctx(prob, orbit.g0, orbit.direction, self.k, geo.c.copy(), False, 1e4)
        xT, Phi, _ = _flow(ctxk, self.x, self.spec.scalar(orbit.period))
        _, PP = _jacobian(ctxk, self.x, self.spec.scalar(0.0), xT, Phi, geo)
        G = np.vstack([_f64(geo.grad_e)[None, :], _f64(geo.grad_c)])
        B = np.linalg.svd(G)[2][G.shape[0]:].T
        lam, V = np.linalg.eig(B.T @ PP @ B)
        order = np.argsort(np.abs(lam))
        lam, V = lam[order], V[:, order]
        ref = np.sort(np.abs(mu))
        if np.max(np.abs(np.abs(lam) - ref) / ref) > 1e-6:
            raise StateError(f"the multipliers of F = P^{self.k} at the saddle ({lam.tolist()}) are not the orbit's "
                             f"{mu.tolist()}")
        self.focus = bool(abs(lam[1].imag) > 0)
        if self.focus:  # A (Re w, Im w) = (Re w, Im w) M with M = rho [[c, s], [-s, c]]
            w = B @ V[:, 2]
            W = np.column_stack([w.real, w.imag])
            self.mu = np.array([lam[2], np.conj(lam[2])])
            self.rho, self.theta = float(abs(lam[2])), float(abs(np.angle(lam[2])))
            if np.angle(lam[2]) < 0:
                W[:, 1] = -W[:, 1]  # the conjugate eigenvector: theta > 0
        else:
            if float(lam[1].real) < 0 or float(lam[2].real) < 0:
                raise UsageError(f"the unstable multipliers {lam[1:].real.tolist()} include a negative one (a "
                                 f"reflection): grow the surface of F^2, from periodic_manifolds.iterate(orbit, 2)")
            W = np.column_stack([B @ V[:, 1].real, B @ V[:, 2].real])
            self.mu = lam[1:].astype(complex)
        self.W = W / np.linalg.norm(W, axis=0)
        self.v = np.linalg.qr(self.W)[0].T.copy()  # an orthonormal basis of the plane
        self.p0 = self.chart(np.array([_f64(self.x)]))[0]

    def linear(self, tau: float) -> np.ndarray:
        """``(DF restricted to the plane)^tau`` in the basis ``W``."""
        if self.focus:
            c, s = math.cos(tau * self.theta), math.sin(tau * self.theta)
            return self.rho ** tau * np.array([[c, s], [-s, c]])
        return np.diag(np.abs(self.mu.real) ** tau)

    def offsets(self, tau: float, phi: np.ndarray) -> np.ndarray:
        """``C_tau(phi) - x*`` for unit ``s0`` (rows, internal variables)."""
        return (self.W @ self.linear(tau) @ np.vstack([np.cos(phi), np.sin(phi)])).T

    def chart(self, X: np.ndarray) -> np.ndarray:
        from .sections import chart_points

        return chart_points("reduced", np.asarray(X, dtype=float).reshape(-1, len(self.x)))

    def start(self, s0: float, tau: float, phi: np.ndarray) -> List[np.ndarray]:
        """The points of ``C_tau`` at ``phi``, moved onto section and level (internal)."""
        d = s0 * self.scale * self.offsets(tau, np.asarray(phi, dtype=float))
        return [_to_level(self.ctx, self.x + self.spec.array(r), self.scale) for r in d]

    def maps(self, X: List[np.ndarray], n: int, workers: Optional[int]) -> List[np.ndarray]:
        """``F^n`` of the internal states ``X`` (the ``k n``-th crossing counted after
        ``T_MIN``; the section integrator, one run per state, in threads)."""
        from ._propagate import start_state
        from .periodic import T_MIN
        from .sections import poincare_sections

        if n == 0 or not X:
            return [np.asarray(x).copy() for x in X]
        prob = self.prob
        pubs = [public_state(prob.system, prob.pars, x, prob.spec) for x in X]
        runs = poincare_sections(prob, pubs, n_points=self.k * n + 1, g0=self.orbit.g0,
                                 direction=1 if self.orbit.direction == 1 else -1,
                                 t_end=4.0 * n * max(1.0, self.orbit.period), workers=workers)
        out = []
        for r in runs:
            keep = [i for i, t in enumerate(r.times) if float(t) > T_MIN]
            if len(keep) < self.k * n:
                raise IntegrationError(f"a leaf point crossed the section only {len(keep)} times, not {self.k * n}, "
                                       f"within t = {4.0 * n * max(1.0, self.orbit.period)!r} ({r.message})")
            out.append(start_state(prob, r.states[keep[self.k * n - 1]]))
        return out


def _closed_bad(C: np.ndarray, delta: float, alpha: float, delta_min: float) -> np.ndarray:
    """The segments ``i -> i + 1`` (cyclically) of a closed chart curve to split."""
    from .periodic_manifolds import _bad_segments  # the 1D manifolds' criteria

    ext = np.vstack([C[-1:], C, C[:1]])
    bad = _bad_segments([ext], True, delta, alpha, delta_min)  # segments (-1 -> 0), (0 -> 1), ..., (n-1 -> 0)
    out = bad[1:].copy()
    out[-1] |= bad[0]
    return out


def grow_surface(orbit: PeriodicOrbit, *, n_iter: int, extent: Optional[float] = None, s0: float = 1e-4,
                 n_rings: int = 4, n_phi: int = 24, delta: float = 0.05, alpha: float = 0.3,
                 delta_min: float = 1e-3, max_points: int = 20000, workers: Optional[int] = None) -> ManifoldSurface:
    r"""The 2D unstable manifold of a saddle of the 3D section map, as leaves (closed curves).

    The leaves ``F^n(C_tau)`` (module docstring) for ``n_rings`` values ``tau = j / n_rings``
    and ``n = 0, ..., n_iter``; a ring stops growing before its first leaf with a point
    (before refinement) farther than ``extent`` from ``orbit.points[0]`` in the chart. Each leaf starts as the images of
    the previous leaf's points (``n_phi`` on the fundamental domain); a segment longer than
    ``delta`` in the chart, or longer than ``delta_min`` next to a turn above ``alpha``
    radians, gets the point of the middle ``phi``, mapped ``n`` times from ``C_tau``; a
    segment still too long at a ``phi`` interval below :data:`PHI_GAP` is marked broken.

    Parameters
    ----------
    orbit : PeriodicOrbit
        A saddle of the reduced system's 3D map (asymmetric ball) with two multipliers
        outside the unit circle and one inside (float64).
    n_iter : int
        Iterates of ``F`` (``>= 0``; ``0`` gives the fundamental domain).
    extent : float, optional
        Chart distance from ``orbit.points[0]`` (``l`` wrapped) beyond which no leaf is
        grown (``> 0``).
    s0 : float
        Offset of ``C_0`` from the saddle, in ``(0, 0.1)`` (relative to ``max(1, |x*|)``):
        the linear plane is off the manifold by ``O(s0^2)``, contracted by the stable
        multiplier at each iterate.
    n_rings : int
        Leaves per fundamental domain (``>= 1``).
    n_phi : int
        Initial points per leaf (``>= 4``).
    delta, alpha, delta_min : float
        Refinement: largest chart distance between neighbours, largest turn (radians, in
        ``(0, pi)``), the distance below which turns are no longer refined.
    max_points : int
        Limit on the points of all leaves (the growth stops with ``complete = False``).
    workers : int, optional
        Threads of the section runs (default: all cores).

    Returns
    -------
    ManifoldSurface

    Raises
    ------
    UsageError
        Not a saddle of the 3D map with a 2D unstable manifold, or bad options (before any
        work).
    """
    if not isinstance(n_iter, (int, np.integer)) or isinstance(n_iter, bool) or n_iter < 0:
        raise UsageError(f"n_iter must be an integer >= 0 (iterates of the return map), got {n_iter!r}")
    if extent is not None:
        _check_pos("extent", extent)
    _check_refinement(s0, delta, alpha, delta_min, max_points)
    _check_pos("n_rings", n_rings, integer=True)
    _check_pos("n_phi", n_phi, integer=True, low=3)
    if workers is not None:
        _check_pos("workers", workers, integer=True)
    if isinstance(orbit, PeriodicOrbit) and orbit.fp_type != "float":
        raise UsageError(f"grow_surface runs in float64: pass the float64 orbit, got fp_type {orbit.fp_type!r}")
    cpu0 = time.process_time()
    pl = _Plane(orbit)
    calls = 0

    def mapped(X: List[np.ndarray], n: int) -> List[np.ndarray]:
        nonlocal calls
        calls += n * len(X)
        return pl.maps(X, n, workers)

    leaves, states, phis, broken, taus, iters, extents = [], [], [], [], [], [], []
    total = reached = 0
    stopped = ""
    done = True
    for j in range(int(n_rings)):
        tau = j / int(n_rings)
        phi = list(np.linspace(0.0, 2 * np.pi, int(n_phi), endpoint=False))
        X = pl.start(float(s0), tau, np.array(phi))
        n = 0
        while True:
            # refine leaf n of ring tau
            brk = np.zeros(len(X), dtype=bool)
            try:
                for _ in range(60):
                    C = pl.chart(np.array([_f64(x) for x in X]))
                    bad = _closed_bad(C, delta, alpha, delta_min)
                    gaps = np.diff(np.append(phi, phi[0] + 2 * np.pi))
                    brk = bad & (gaps <= PHI_GAP)
                    idx = np.flatnonzero(bad & ~brk)
                    if not len(idx) or total + len(X) + len(idx) > max_points:
                        break
                    mids = [phi[i] + gaps[i] / 2 for i in idx]
                    new = mapped(pl.start(float(s0), tau, np.array(mids)), n)
                    for i, p, x in sorted(zip(idx, mids, new), key=lambda t: -t[0]):
                        phi.insert(int(i) + 1, p)
                        X.insert(int(i) + 1, x)
            except (IntegrationError, StateError) as exc:
                stopped, done = f"the map failed on ring {j}, iterate {n}: {exc}", False
                break
            C = pl.chart(np.array([_f64(x) for x in X]))
            ext = float(np.max(np.linalg.norm(_wrap_l(C - pl.p0), axis=1)))
            leaves.append(C)
            states.append(np.array([public_state(pl.prob.system, pl.prob.pars, x, pl.spec) for x in X], dtype=float))
            phis.append(np.array(phi))
            broken.append(brk)
            taus.append(tau)
            iters.append(n)
            extents.append(ext)
            total += len(X)
            if total >= max_points:
                stopped, done = f"max_points = {max_points} reached", False
                break
            if n >= n_iter:
                break
            try:
                X = mapped(X, 1)
            except (IntegrationError, StateError) as exc:
                stopped, done = f"the map failed on ring {j}, iterate {n + 1}: {exc}", False
                break
            if extent is not None and float(np.max(np.linalg.norm(
                    _wrap_l(pl.chart(np.array([_f64(x) for x in X])) - pl.p0), axis=1))) > extent:
                reached += 1  # the next leaf leaves the ball of radius extent: not refined, not kept
                break
            n += 1
        if not done:
            break
    if not stopped:
        stopped = "extent reached" if reached == n_rings else "n_iter reached"
    order = sorted(range(len(leaves)), key=lambda i: (iters[i], taus[i]))
    return ManifoldSurface(leaves=[leaves[i] for i in order], states=[states[i] for i in order],
                           phi=[phis[i] for i in order], broken=[broken[i] for i in order],
                           tau=np.array([taus[i] for i in order]), iterate=np.array([iters[i] for i in order]),
                           extent=np.array([extents[i] for i in order]), mu=pl.mu, directions=pl.v,
                           eigenvectors=pl.W.T.copy(), focus=pl.focus,
                           s0=float(s0), delta=float(delta), alpha=float(alpha), delta_min=float(delta_min),
                           complete=done, stopped=stopped, map_calls=calls, cpu_seconds=time.process_time() - cpu0)


def surface_trace(surface: ManifoldSurface, axis: int, value: float) -> List[Tuple[np.ndarray, float, int]]:
    r"""Where the surface's leaves cross the chart plane ``chart[axis] = value``: per crossing
    the chart point (linear interpolation on the leaf's segment), the leaf's ``tau`` and its
    iterate. Joined by ``(iterate, tau)``, the crossings trace the surface's 1D curve on
    that plane.

    Raises
    ------
    UsageError
        ``axis`` not 0, 1 or 2, or ``value`` not finite.
    """
    if not isinstance(surface, ManifoldSurface):
        raise UsageError(f"surface must be a ManifoldSurface (from grow_surface), got {type(surface).__name__}")
    if axis not in (0, 1, 2) or isinstance(axis, bool):
        raise UsageError(f"axis must be 0, 1 or 2 (the chart coordinate l, r1 or r2), got {axis!r}")
    if not isinstance(value, (int, float, np.floating, np.integer)) or not math.isfinite(float(value)):
        raise UsageError(f"value must be a finite number, got {value!r}")
    out = []
    for C, brk, tau, it in zip(surface.leaves, surface.broken, surface.tau, surface.iterate):
        D = np.roll(C, -1, axis=0)
        a, b = C[:, axis] - value, D[:, axis] - value
        for i in np.flatnonzero((np.sign(a) != np.sign(b)) & ~brk):
            t = a[i] / (a[i] - b[i])
            out.append((C[i] + t * (D[i] - C[i]), float(tau), int(it)))
    return out


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
    if float(np.max(np.abs(_wrap_l(surface.leaves[0][0] - p0)))) > 1e-2 or surface.mu.shape != (2,) or \
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
