r"""The return maps of a periodic orbit's section, forward and backward: the tools the
invariant manifolds are grown with (:mod:`taylorball.periodic_manifolds`) and homoclinic
points are shot with (:mod:`taylorball.periodic_homoclinic`).

:func:`inverse_map` is ``P^-1`` (the flow backwards to the previous crossing of the same
half-line ``g = g0``, Newton in time on the event function); ``_SaddleMap`` is the return
map ``F = S_theta^-1 P^k`` of a ``k``-periodic saddle of a 2D section map and its inverse, in
the orbit's number type, with the eigen-directions of ``DF`` at the saddle and the map's
chart.
"""

from __future__ import annotations

from typing import List, Optional, Tuple

from numpy.typing import ArrayLike

import numpy as np

from .errors import IntegrationError, StateError, UsageError
from .periodic import PeriodicOrbit, _eval_geo, _f64, _has_axial_symmetry, _Ctx, _to_level
from ._propagate import public_state

__all__ = ["inverse_map"]

#: A crossing followed by time (:meth:`_SaddleMap.track`) may move at most this far (flow
#: time) from its guess, the neighbour's crossing time; farther, the neighbours are split.
TAU_JUMP = 0.5


# ---------------------------------------------------------------------------------------
# The inverse map: the flow backwards to the previous crossing.
# ---------------------------------------------------------------------------------------
def _previous_crossing(ctx: _Ctx, x: np.ndarray, t_max: float = 100.0, with_time: bool = False):
    """``P^{-1}(x)``: the internal state at the previous crossing of the section (same
    direction, same half-line ``g = g0``), by stepping the problem's integrator backwards
    and Newton in time on the event function."""
    import copy

    from ._propagate import integrator
    from ._section_run import _on_branch
    from .periodic import T_MIN

    prob, spec = ctx.prob, ctx.prob.spec
    ta = copy.copy(integrator(prob))
    ta.state[:] = x
    ta.pars[:] = prob.pars
    ta.time = spec.scalar(0.0)
    e_prev = None
    t_prev = 0.0
    while float(ta.time) > -t_max:
        oc = ta.step_backward()[0]
        if "success" not in str(oc):
            raise IntegrationError(f"the backward integration stopped at t = {float(ta.time)!r} ({oc})")
        t_now = float(ta.time)
        geo = _eval_geo(prob, ctx.g0, ta.state)
        e_now = float(geo.e)
        if e_prev is not None and t_now < -T_MIN:
            up = e_prev > 0.0 >= e_now if ctx.direction == 1 else e_prev < 0.0 <= e_now
            if up:
                T = t_prev + (t_now - t_prev) * e_prev / (e_prev - e_now)  # interpolated crossing
                for _ in range(20):
                    ta.propagate_until(spec.scalar(T))
                    g = _eval_geo(prob, ctx.g0, ta.state)
                    dT = float(g.e) / float(g.de)
                    T -= dT
                    if abs(dT) <= 4 * float(spec.eps) * (1 + abs(T)):
                        break
                ta.propagate_until(spec.scalar(T))
                if _on_branch(ta.state, ctx.g0) and T < -T_MIN:
                    return (np.asarray(ta.state).copy(), T) if with_time else np.asarray(ta.state).copy()
                ta.propagate_until(spec.scalar(t_now))
        e_prev, t_prev = e_now, t_now
    raise IntegrationError(f"no previous crossing of the section within t = -{t_max!r}")


def inverse_map(orbit: PeriodicOrbit, state: ArrayLike, n: int = 1) -> np.ndarray:
    r"""``P^{-n}`` of a public state on the orbit's section and level (``n >= 1``): the public
    states of the ``n`` previous crossings, most recent first, shape ``(n, dim)``.

    The flow is run backwards (the integrator's backward steps) to each previous crossing of
    the section in the section's direction; the crossing time is refined by Newton on the
    event function. ``P(P^{-1}(x)) = x`` to rounding (tests/test_periodic.py)."""
    from ._propagate import start_state

    if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 1:
        raise UsageError(f"n (backward iterations) must be an integer >= 1, got {n!r}")
    prob = orbit.problem
    ctx = _Ctx(prob, orbit.g0, orbit.direction, 1, _eval_geo(prob, orbit.g0, orbit.internal).c.copy(), False, 1e4)
    x = start_state(prob, state)
    out = []
    for _ in range(n):
        x = _previous_crossing(ctx, x)
        out.append(public_state(prob.system, prob.pars, x, prob.spec))
    return np.array(out)


# ---------------------------------------------------------------------------------------
# Manifolds of k-periodic saddles of a 2D map, grown with refinement.
# ---------------------------------------------------------------------------------------
class _SaddleMap:
    """The return map ``F`` of a saddle of a 2D section map (or, with ``which``, of the 3D map
    of an asymmetric ball whose ``which`` manifold is 1D) and its inverse, in the
    orbit's number type: ``F = S_theta^{-1} P^k`` (``P`` one crossing, ``S_theta`` the rotation
    about the body axis 3 of a symmetric ball's relative orbit; the identity else), the
    eigen-directions of ``DF`` at the saddle, the chart of the 2D map (``(r1, r2)`` for the
    symmetric ball: invariant under ``S_theta``, so the quotient map's chart; ``(l, L/G)``
    for the M||gamma map)."""

    def __init__(self, orbit: PeriodicOrbit, what: str = "the invariant manifolds", which: Optional[str] = None) -> None:
        if not isinstance(orbit, PeriodicOrbit):
            raise UsageError(f"orbit must be a taylorball.PeriodicOrbit (from periodic_orbit), got {type(orbit).__name__}")
        prob = orbit.problem
        if orbit.multipliers.shape != (2,):
            mu = np.abs(orbit.multipliers)
            dims = (int(np.sum(mu > 1.0)), int(np.sum(mu < 1.0)))
            one_d = which is not None and orbit.multipliers.shape == (3,) and not _has_axial_symmetry(prob) and \
                dims[0 if which == "unstable" else 1] == 1
            if not one_d:
                raise UsageError(f"{what} are grown for saddles of a 2D map (the M||gamma map, or the symmetric ball's "
                                 f"map of (r1, r2)) and for the 1D manifold of a saddle of the 3D map; this orbit is of "
                                 f"the 3D map of kind {orbit.kind!r} with multipliers "
                                 f"{np.round(orbit.multipliers, 6).tolist()}: its unstable / stable manifolds are "
                                 f"{dims[0]}D / {dims[1]}D, and 2D manifolds are not grown here (the 2D unstable "
                                 f"manifold: taylorball.periodic_manifolds_3d.grow_surface)")
        if orbit.stability != "hyperbolic":
            raise UsageError(f"{what} need a saddle (stability 'hyperbolic', |tr A| > 2), got a {orbit.stability} orbit "
                             f"with multipliers {np.round(orbit.multipliers, 6).tolist()}")
        self.orbit, self.prob, self.k = orbit, prob, int(orbit.k)
        self.symmetric = _has_axial_symmetry(prob)
        spec = prob.spec
        self.spec = spec
        self.x = np.asarray(orbit.internal).copy()
        geo = _eval_geo(prob, orbit.g0, self.x)
        self.ctx = _Ctx(prob, orbit.g0, orbit.direction, 1, geo.c.copy(), False, 1e4)
        self.scale = max(1.0, float(np.max(np.abs(_f64(self.x)))))
        self.theta = float(orbit.shift) if self.symmetric else 0.0
        # DF at the saddle: the k crossings with the variational equations, rotated back
        from .periodic import _flow, _jacobian

        ctxk = _Ctx(prob, orbit.g0, orbit.direction, self.k, geo.c.copy(), self.symmetric, 1e4)
        xT, Phi, _ = _flow(ctxk, self.x, spec.scalar(orbit.period))
        _, PP = _jacobian(ctxk, self.x, spec.scalar(self.theta), xT, Phi, geo)
        if self.symmetric:
            c, s = np.cos(-self.theta), np.sin(-self.theta)
            PP = np.array([_rotate3_f(col, c, s) for col in PP.T]).T  # S_theta^-1 Pi Phi
        G = np.vstack([_f64(geo.grad_e)[None, :], _f64(geo.grad_c)])
        B = np.linalg.svd(G)[2][G.shape[0]:].T
        A = B.T @ PP @ B
        lam, V = np.linalg.eig(A)
        order = np.argsort(np.abs(lam))
        lam, V = lam[order], V[:, order]
        # a 2D map: both eigen-directions; a 3D map: the 1D manifold's (the others may be complex)
        used = [0, -1] if len(lam) == 2 else ([0] if which == "stable" else [-1])
        if np.max(np.abs(lam[used].imag)) > 0:
            raise StateError(f"the saddle's Jacobian has complex multipliers {lam.tolist()}: not a saddle")
        mu_s, mu_u = float(lam[0].real), float(lam[-1].real)
        ref = np.sort(np.abs(orbit.multipliers))
        if (-1 in used and abs(abs(mu_u) - ref[-1]) > 1e-6 * ref[-1]) or (0 in used and abs(abs(mu_s) - ref[0]) > 1e-6):
            raise StateError(f"the multipliers of F = S^-1 P^{self.k} at the saddle ({mu_s!r}, {mu_u!r}) are not the "
                             f"orbit's {orbit.multipliers.tolist()}")
        vu, vs = B @ V[:, -1].real, B @ V[:, 0].real
        self.mu_u, self.mu_s = mu_u, mu_s
        self.v_u, self.v_s = vu / np.linalg.norm(vu), vs / np.linalg.norm(vs)

    # -- the maps ----------------------------------------------------------------------
    def chart(self, X: np.ndarray) -> np.ndarray:
        from .sections import chart_points

        pts = chart_points(self.prob.kind, np.asarray(_f64(np.asarray(X)), dtype=float).reshape(-1, len(self.x)))
        return pts[:, 1:] if self.symmetric else pts

    def rotate(self, x: np.ndarray, theta: float) -> np.ndarray:
        """``S_theta x`` in the working type (cosine and sine of the float ``theta`` to 60 digits,
        so the rotation is orthogonal to the type's rounding)."""
        if not self.symmetric or theta == 0.0:
            return x
        import heyoka as hy
        import mpmath

        from .periodic import _rotate3

        with mpmath.workdps(60):
            c, s = (self.spec.scalar(hy.real(mpmath.nstr(f(mpmath.mpf(theta)), 60), 256)) for f in (mpmath.cos, mpmath.sin))
        return _rotate3(np.asarray(x), c, s)

    def forward(self, x: np.ndarray) -> List[np.ndarray]:
        """``[P x, P^2 x, ..., P^{k-1} x, F x]`` (internal, working type)."""
        from .periodic import T_MIN

        prob = self.prob
        r = self.ctx.section.run(public_state(prob.system, prob.pars, x, prob.spec), n_points=self.k + 1,
                                 t_end=10.0 * max(1.0, self.orbit.period))
        keep = [i for i, t in enumerate(r.times) if float(t) > T_MIN][: self.k]
        if len(keep) < self.k:
            raise IntegrationError(f"no {self.k} crossings of the section ({r.message})")
        from ._propagate import start_state

        out = [start_state(prob, r.states[i]) for i in keep]
        out[-1] = self.rotate(out[-1], -self.theta)
        return out

    def backward(self, x: np.ndarray) -> List[np.ndarray]:
        """``[P^-1 x, ..., P^-(k-1) x, F^-1 x]`` (the flow backwards)."""
        out = []
        y = x
        for _ in range(self.k):
            y = _previous_crossing(self.ctx, y, t_max=4.0 * max(1.0, self.orbit.period))
            out.append(y)
        out[-1] = self.rotate(out[-1], self.theta)
        return out

    def orbit_times(self, which: str) -> np.ndarray:
        """The orbit's crossing times from ``x*``: ``t_1 < ... < t_k = T`` forward,
        ``-(T - t_{k-1}) > ... > -T`` backward (the guesses of the first level)."""
        from .periodic import T_MIN

        prob = self.prob
        r = self.ctx.section.run(public_state(prob.system, prob.pars, self.x, prob.spec), n_points=self.k + 1,
                                 t_end=10.0 * max(1.0, self.orbit.period))
        t = np.array([float(v) for v in r.times if float(v) > T_MIN][: self.k])
        if which != "unstable":
            t = np.array([tj - t[-1] for tj in ([0.0] + list(t[:-1]))[::-1]])
        self.t_orbit = t
        return t

    def counted_times(self, x: np.ndarray, which: str) -> np.ndarray:
        """The times of the first ``k`` crossings of ``x``'s orbit, counted (forward by the
        section integrator, backward by the integrator's backward steps)."""
        from .periodic import T_MIN

        prob = self.prob
        if which == "unstable":
            r = self.ctx.section.run(public_state(prob.system, prob.pars, x, prob.spec), n_points=self.k + 1,
                                     t_end=10.0 * max(1.0, self.orbit.period))
            t = [float(v) for v in r.times if float(v) > T_MIN][: self.k]
        else:
            t, y, t0 = [], x, 0.0
            for _ in range(self.k):
                y, dt = _previous_crossing(self.ctx, y, t_max=4.0 * max(1.0, self.orbit.period), with_time=True)
                t0 += float(dt)
                t.append(t0)
        if len(t) < self.k:
            raise IntegrationError(f"fewer than {self.k} crossings of the section")
        return np.array(t)

    def track(self, x: np.ndarray, taus: np.ndarray, which: str) -> Tuple[List[Optional[np.ndarray]], np.ndarray]:
        """The crossings of the orbit of ``x`` nearest the times ``taus`` (Newton in time on the
        event, from the integrator's state at each guess): ``[P x, ..., F x]`` (``F`` the last,
        rotated back) and their times; a crossing not found within :data:`TAU_JUMP` of its
        guess, or in the wrong direction, is ``None`` (time NaN). Following crossings by time
        makes ``F`` smooth along the manifold where counting crossings jumps (an intermediate
        crossing that grazes the section adds or removes crossings)."""
        import copy

        from ._propagate import integrator

        prob, spec = self.prob, self.spec
        ta = copy.copy(integrator(prob))
        ta.state[:] = x
        ta.pars[:] = prob.pars
        ta.time = spec.scalar(0.0)
        out: List[Optional[np.ndarray]] = []
        times = np.full(len(taus), np.nan)
        taus = np.where(np.isfinite(taus), taus, self.t_orbit)  # a crossing lost everywhere near: the orbit's
        for j, tau in enumerate(taus):
            T = spec.scalar(float(tau))
            ok = False
            for _ in range(12):
                oc = ta.propagate_until(T)[0]
                if "time_limit" not in str(oc):
                    raise IntegrationError(f"the integration stopped at t = {float(ta.time)!r} ({oc})")
                geo = _eval_geo(prob, self.ctx.g0, ta.state)
                if float(geo.de) == 0.0:
                    break
                dT = geo.e / geo.de
                T = T - dT
                if not abs(float(T) - float(tau)) <= TAU_JUMP:  # also NaN
                    break
                if abs(float(dT)) <= 4 * spec.eps * (1 + abs(float(T))):
                    ok = True
                    break
            if ok:
                ta.propagate_until(T)
                geo = _eval_geo(prob, self.ctx.g0, ta.state)
                from ._section_run import _on_branch

                ok = float(geo.de) * self.ctx.direction > 0 and _on_branch(ta.state, self.ctx.g0)
            if ok:
                out.append(np.asarray(ta.state).copy())
                times[j] = float(T)
            else:
                out.append(None)
                ta.propagate_until(spec.scalar(float(tau)))
        if out[-1] is not None:
            out[-1] = self.rotate(out[-1], -self.theta if which == "unstable" else self.theta)
        return out, times

    def start(self, which: str, branch: int, s0: float, sigma: float, q: int) -> np.ndarray:
        """The fundamental domain's point ``x* + branch s0 |mu|^(q sigma) v``, on section and level."""
        mu, v = (self.mu_u, self.v_u) if which == "unstable" else (1.0 / self.mu_s, self.v_s)
        d = branch * s0 * abs(mu) ** (q * sigma) * v
        return _to_level(self.ctx, self.x + self.spec.array(d), self.scale)

    def orbit_point_index(self, which: str, j: int) -> int:
        """The orbit point whose manifold the ``j``-th intermediate image lies on."""
        return j % self.k if which == "unstable" else (-j) % self.k


def _rotate3_f(x: np.ndarray, c: float, s: float) -> np.ndarray:
    y = np.array(x, dtype=float, copy=True)
    for b in range(0, len(y), 3):
        y[b], y[b + 1] = c * x[b] - s * x[b + 1], s * x[b] + c * x[b + 1]
    return y
