r"""The 2D unstable or stable manifold of a saddle of the 3D section map of the reduced system.

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
manifold of such a saddle: ``grow_manifold(orbit, "stable", ...)``.

A saddle with two multipliers *inside* the unit circle has a 2D stable manifold: the same
leaves for ``F^-1`` (``grow_surface(orbit, "stable", ...)``; the flow backwards to the
counted crossings, as for the 1D stable manifolds), ``W`` the stable eigenvectors and ``A``
the restriction of ``DF^-1`` (multipliers ``1 / mu``). docs/skeleton.md, "The 2D manifolds
of the 3D map" and "The 2D stable manifold".
"""


from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np

from .errors import IntegrationError, StateError, UsageError
from .periodic import PeriodicOrbit, _eval_geo, _f64, _has_axial_symmetry, _Ctx, _to_level
from ._propagate import public_state
from .periodic_manifolds import _check_pos, _check_refinement, _wrap_l

__all__ = ["ManifoldSurface", "grow_surface", "surface_trace"]
#: A leaf segment still too long when its ``phi`` interval is this short is a jump of the
#: map (a crossing appears or vanishes between its ends): it is marked broken.
PHI_GAP = 1e-9


@dataclass(frozen=True)
class ManifoldSurface:
    r"""The 2D unstable (or stable) manifold of a saddle of the 3D section map, as leaves.

    Leaf ``j`` is the closed curve ``F^{iterate[j]}(C_{tau[j]})`` (``F^{-iterate[j]}`` for
    the stable manifold; see the module docstring), its points ordered by ``phi`` (the first
    point is not repeated at the end).

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
        The two multipliers of ``DF`` of the manifold (from the variational equations;
        inside the unit circle for the stable one).
    directions : ndarray, shape (2, 9)
        An orthonormal basis of the manifold's tangent plane at the saddle (internal variables).
    eigenvectors : ndarray, shape (2, 9)
        ``W`` transposed: the unit eigenvectors of a node (``Re w, Im w`` of a focus).
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
    which : {"unstable", "stable"}
        The manifold: grown by ``F`` or by ``F^-1``.
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
    which: str = "unstable"

    @property
    def n_points(self) -> int:
        """Points on all leaves."""
        return int(sum(len(p) for p in self.leaves))

    def __repr__(self) -> str:
        return (f"ManifoldSurface({self.which}, {len(self.leaves)} leaves, {self.n_points} points, iterates <= "
                f"{int(self.iterate.max()) if len(self.iterate) else -1}, extent {float(np.max(self.extent)):.3g}, "
                f"{self.stopped}, {self.map_calls} map calls)")


class _Plane:
    """The saddle, its level and section, ``DF`` on the section and level (variational
    equations) and the tangent plane of its 2D ``which`` manifold, with the growth map's
    restriction to it (``DF``, or ``DF^-1`` for the stable manifold)."""

    def __init__(self, orbit: PeriodicOrbit, which: str = "unstable") -> None:
        from .periodic import _flow, _jacobian

        if not isinstance(orbit, PeriodicOrbit):
            raise UsageError(f"orbit must be a taylorball.PeriodicOrbit (from periodic_orbit), got {type(orbit).__name__}")
        prob = orbit.problem
        mu = np.asarray(orbit.multipliers)
        if orbit.kind != "reduced" or _has_axial_symmetry(prob) or mu.shape != (3,):
            raise UsageError(f"grow_surface grows the 2D {which} manifold of a saddle of the 3D map of the reduced "
                             f"system (an asymmetric ball, 3 multipliers); got kind {orbit.kind!r} with multipliers "
                             f"{np.round(mu, 6).tolist()} (for 2D maps: periodic_manifolds.grow_manifold)")
        unstable = which == "unstable"
        n_out, n_in = int(np.sum(np.abs(mu) > 1.0)), int(np.sum(np.abs(mu) < 1.0))
        n_side = n_out if unstable else n_in
        if n_side != 2 or n_out + n_in != 3:
            side = "outside" if unstable else "inside"
            raise UsageError(f"the {which} manifold is 2D only with two multipliers {side} the unit circle and one "
                             f"{'inside' if unstable else 'outside'}; this orbit has {np.round(mu, 6).tolist()} "
                             f"({n_side} {side})"
                             + (": its 1D manifolds: periodic_manifolds.grow_manifold" if n_side == 1 else "")
                             + (f"; its 2D {'stable' if unstable else 'unstable'} manifold: grow_surface(orbit, "
                                f"{'stable' if unstable else 'unstable'!r}, ...)" if n_side == 1 else ""))
        self.which = which
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
        pair = [1, 2] if unstable else [0, 1]  # the manifold's multipliers, |mu| ascending
        self.focus = bool(abs(lam[pair[0]].imag) > 0)
        if self.focus:
            # A (Re w, Im w) = (Re w, Im w) M with M = rho [[c, s], [-s, c]] for the growth map
            # (theta > 0): for DF, w the eigenvector of the multiplier with positive angle; for
            # DF^-1 (M^-1 = rho^-1 [[c, -s], [s, c]]) the same form with Im w negated
            w = B @ V[:, pair[1]]
            W = np.column_stack([w.real, w.imag])
            self.mu = np.array([lam[pair[1]], np.conj(lam[pair[1]])])
            self.rho = float(abs(lam[pair[1]])) if unstable else 1.0 / float(abs(lam[pair[1]]))
            self.theta = float(abs(np.angle(lam[pair[1]])))
            if (np.angle(lam[pair[1]]) < 0) == unstable:
                W[:, 1] = -W[:, 1]
        else:
            if float(lam[pair[0]].real) < 0 or float(lam[pair[1]].real) < 0:
                raise UsageError(f"the {which} multipliers {lam[pair].real.tolist()} include a negative one (a "
                                 f"reflection): grow the surface of F^2, from periodic_manifolds.iterate(orbit, 2)")
            W = np.column_stack([B @ V[:, pair[0]].real, B @ V[:, pair[1]].real])
            self.mu = lam[pair].astype(complex)
        #: the growth map's multipliers on the plane: those of DF, or of DF^-1
        self.growth = self.mu if unstable else 1.0 / self.mu
        self.W = W / np.linalg.norm(W, axis=0)
        self.v = np.linalg.qr(self.W)[0].T.copy()  # an orthonormal basis of the plane
        self.p0 = self.chart(np.array([_f64(self.x)]))[0]

    def linear(self, tau: float) -> np.ndarray:
        """``(DF restricted to the plane)^tau`` in the basis ``W`` (``DF^-1`` for the stable
        manifold)."""
        if self.focus:
            c, s = math.cos(tau * self.theta), math.sin(tau * self.theta)
            return self.rho ** tau * np.array([[c, s], [-s, c]])
        return np.diag(np.abs(self.growth.real) ** tau)

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
        ``T_MIN``; the section integrator, one run per state, in threads), or ``F^-n`` for
        the stable manifold (the ``k n``-th previous crossing, counted: the integrator's
        backward steps, one state after the other)."""
        from ._propagate import start_state
        from .periodic import T_MIN
        from .periodic_return_maps import _previous_crossing
        from .sections import poincare_sections

        if n == 0 or not X:
            return [np.asarray(x).copy() for x in X]
        if self.which == "stable":
            out = []
            for y in X:
                for _ in range(self.k * n):
                    y = _previous_crossing(self.ctx, y, t_max=4.0 * max(1.0, self.orbit.period))
                out.append(y)
            return out
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


def grow_surface(orbit: PeriodicOrbit, which: str = "unstable", *, n_iter: int, extent: Optional[float] = None,
                 s0: float = 1e-4, n_rings: int = 4, n_phi: int = 24, delta: float = 0.05, alpha: float = 0.3,
                 delta_min: float = 1e-3, max_points: int = 20000, workers: Optional[int] = None) -> ManifoldSurface:
    r"""The 2D unstable or stable manifold of a saddle of the 3D section map, as leaves
    (closed curves).

    The leaves ``F^n(C_tau)`` (module docstring; ``F^-n(C_tau)`` for the stable manifold, the
    flow backwards) for ``n_rings`` values ``tau = j / n_rings``
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
        outside the unit circle and one inside (float64); for ``which = "stable"``, two
        inside and one outside.
    which : {"unstable", "stable"}
        The manifold: grown by ``F`` (the section integrator) or by ``F^-1`` (the
        integrator's backward steps).
    n_iter : int
        Iterates of ``F`` or ``F^-1`` (``>= 0``; ``0`` gives the fundamental domain).
    extent : float, optional
        Chart distance from ``orbit.points[0]`` (``l`` wrapped) beyond which no leaf is
        grown (``> 0``).
    s0 : float
        Offset of ``C_0`` from the saddle, in ``(0, 0.1)`` (relative to ``max(1, |x*|)``):
        the linear plane is off the manifold by ``O(s0^2)``, contracted by the multiplier
        off the manifold (``mu_s``, or ``1 / mu_u`` for the stable one) at each iterate.
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
        Threads of the section runs (default: all cores; the backward runs of the stable
        manifold are one after the other).

    Returns
    -------
    ManifoldSurface

    Raises
    ------
    UsageError
        ``which`` not ``"unstable"`` or ``"stable"``, not a saddle of the 3D map whose
        ``which`` manifold is 2D, or bad options (before any work).
    """
    if which not in ("unstable", "stable"):
        raise UsageError(f"which must be 'unstable' or 'stable' (the manifold grown by F or by F^-1), got {which!r}")
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
    pl = _Plane(orbit, which)
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
                           complete=done, stopped=stopped, map_calls=calls, cpu_seconds=time.process_time() - cpu0,
                           which=which)


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
