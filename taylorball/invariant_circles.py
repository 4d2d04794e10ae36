r"""Invariant circles of the section maps: the cores of nested invariant tori.

In the 3D volume-preserving map of the reduced system (paper section 4, Fig. 4b) regular
orbits fill 2-tori, and nested 2-tori surround a closed curve on which the map is a rotation:
an invariant circle ``K(theta)`` with

.. math:: P(K(\theta)) = K(\theta + \rho),

``P`` the first return map of the section ``g = g0`` on a level, ``rho`` the rotation angle
(``rho / 2 pi`` the rotation number). In the 2D map of the M||gamma system the same equation
describes an invariant curve. :func:`invariant_circle` finds one by Newton's method from an
orbit that lies on or near it; :class:`InvariantCircle` is the result.

Method (docs/skeleton.md, "The tori of Fig. 4b and their cores")
-----------------------------------------------------------------
*Unknowns.* ``N`` (odd) internal states ``x_j = K(theta_j)``, ``theta_j = 2 pi j / N`` (the
nodes, each on the section and the level; not chart points, so no energy root is followed),
and ``rho``. ``K`` between the nodes is their trigonometric interpolant (harmonics
``|k| <= (N - 1)/2``, component by component).

*Equations.* ``P(x_j) - K(theta_j + rho) = 0`` for every node (``9 N`` equations for the
reduced system; ``K(theta + rho)`` at the nodes is the matrix ``T_rho`` applied to the nodes),
and the phase condition ``sum_j (K'(theta_j), dx_j) = 0`` (the circle's parametrisation is
fixed up to a shift of ``theta``). Each node moves in the tangent space of section and level
(``dx_j = B_j w_j``) and is put back onto both after every step (the retraction of
:func:`taylorball.periodic_orbit`). The Jacobian has the blocks ``Pi_j Phi_j B_j`` (the
return map's derivative, as for periodic orbits: ``Phi_j`` from the variational equations to
the crossing, ``Pi_j`` the projection along the flow), ``-T_rho B`` and ``-K'(theta_j +
rho)`` for ``rho``. Gauss-Newton (least squares) with halving of the step on ``max |F|``.

*The guess.* From an orbit ``y_0, y_1, ...`` of the map on or near the circle: ``rho`` is
the frequency of the largest peak of the complex signal ``u_n + i v_n`` (the orbit's two
leading principal components, a closed curve around its mean), refined to the maximum of
the windowed ``|sum_n w_n z_n e^{-i omega n}|`` (:func:`rotation_from_orbit`); the
harmonics of ``K`` are then the least-squares fit ``y_n ~ K(n rho)`` (a linear problem once
``rho`` is known), evaluated at the nodes.

*What the result says.* ``residual`` is ``max_j |P(x_j) - K(theta_j + rho)|`` (internal
variables, max norm): at the nodes the equations hold to it. Between the nodes the circle is
the interpolant; ``fourier_tail`` (the largest harmonic amplitude among the top third of
``|k|``, relative to the circle's size) says how well ``N`` nodes resolve it. An independent
check, that an orbit of :func:`taylorball.poincare_section` from a node stays on the curve,
is :meth:`InvariantCircle.distance` of its states.

*A guess from a fat torus.* :func:`shrink_torus` starts orbits on the least-squares circle of
an orbit on a torus (the harmonics of the rotation angle along the core only: the torus
averaged around its tube) and keeps the one on the thinnest torus, round after round; its last
orbit is Newton's input.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from ._problem import Problem
from ._propagate import internal_f64, public_state
from ._typing import Direction, KindName, ParamsLike
from .errors import IntegrationError, StateError, UsageError
from .numbers import count, real_number
from .periodic import (LevelsLike, _Ctx, _crossing_time, _eval_geo, _f64, _flow, _jacobian, _level_targets,
                       _on_branch, _tangent_basis, _to_level, orbit_problem)
from .sections import Section, SectionResult, chart_points, poincare_sections

_EPS = float(np.finfo(float).eps)

__all__ = ["InvariantCircle", "InvariantCircleFailure", "invariant_circle", "rotation_from_orbit", "FIG4B_CORE_SEED",
           "FIG4B_ISLAND_SEED", "TorusShrink", "shrink_torus"]

#: A state near the core of the Fig. 4b tori around ``l = pi/2`` (``FIG4_BALL``,
#: ``FIG4B_LEVELS``, section ``g = 0``, direction +1): the chart point ``(l, r1, r2)`` and
#: the root index of :func:`taylorball.states_on_section` there. Found by minimising the
#: thickness of the tori's cut by the slab ``|l - pi/2| < 0.08`` (docs/skeleton.md, "The
#: tori of Fig. 4b and their cores"); the state is 2.6e-4 from the circle
#: :func:`invariant_circle` finds from its orbit.
FIG4B_CORE_SEED = ((math.pi / 2, 6.68793713, 9.44173083e-05), 0)

#: A state on the core of a narrow island inside the Fig. 4b tori around circle A (same ball,
#: level and section as :data:`FIG4B_CORE_SEED`): the chart point ``(l, r1, r2)`` on the
#: fixed line of the reversor sigma2 and the root index of
#: :func:`taylorball.states_on_section`. Found from a dip of the least-squares circle's
#: residual along ``l = pi/2, r2 = 0`` and put where the 201-node circle that
#: :func:`invariant_circle` finds from its orbit crosses that line (9e-8 from it);
#: rotation number 0.0246824, against circle A's 0.0233050 (docs/skeleton.md, "The tori of
#: Fig. 4b and their cores").
FIG4B_ISLAND_SEED = ((math.pi / 2, 1.79707710, 0.0), 0)


class InvariantCircleFailure(IntegrationError):
    """Newton did not reach an invariant circle; ``residual`` and ``residual_history`` say
    how far it got, ``states`` are its last nodes (public layout)."""

    def __init__(self, message: str, residual: float, history: List[float], states: np.ndarray) -> None:
        super().__init__(message)
        self.residual = residual
        self.residual_history = tuple(history)
        self.states = states


@dataclass(frozen=True, eq=False)
class InvariantCircle:
    r"""An invariant circle ``K`` of the first return map, ``P(K(theta)) = K(theta + rho)``.

    Attributes
    ----------
    kind : str
    states : ndarray, shape (N, d)
        The nodes ``K(2 pi j / N)`` (public layout, float64).
    points : ndarray, shape (N, 3) or (N, 2)
        The nodes in the section's chart, ``(l, r1, r2)`` or ``(l, L/G)``.
    rho : float
        The rotation angle in ``[0, 2 pi)`` (in the orientation of ``theta``; the opposite
        orientation has ``2 pi - rho``).
    rotation_number : float
        ``rho / (2 pi)``.
    residual : float
        ``max_j |P(K(theta_j)) - K(theta_j + rho)|`` over the nodes (internal variables).
    residual_history : tuple of float
        The residual at each Newton iterate.
    fourier_tail : float
        The largest harmonic amplitude with ``|k| > (N - 1)/3``, relative to the largest
        non-constant one: the resolution of the interpolant between the nodes.
    return_times : ndarray, shape (N,)
        The flow time from each node to its image.
    levels : dict of str -> float
        The values of the level's constraints the nodes lie on (``C2, M_gamma, E, gamma2,
        R_gamma``; ``gamma2, lambda, E``).
    g0, direction : the section.
    internal : ndarray, shape (N, d)
        The nodes in the internal variables (the unknowns of Newton; :meth:`evaluate`
        interpolates them).
    problem : Problem
        The problem the map was integrated in.
    """

    kind: str
    states: np.ndarray
    points: np.ndarray
    rho: float
    rotation_number: float
    residual: float
    residual_history: Tuple[float, ...]
    fourier_tail: float
    return_times: np.ndarray
    levels: Dict[str, float]
    g0: float
    direction: int
    internal: np.ndarray = field(repr=False)
    problem: Problem = field(repr=False, default=None)  # type: ignore[assignment]

    @property
    def n_nodes(self) -> int:
        return len(self.internal)

    def __repr__(self) -> str:
        return (f"InvariantCircle(kind={self.kind!r}, n_nodes={self.n_nodes}, rotation_number="
                f"{self.rotation_number:.10f}, residual={self.residual:.1e}, fourier_tail={self.fourier_tail:.1e})")

    def evaluate(self, theta: ArrayLike, *, public: bool = False) -> np.ndarray:
        """``K(theta)``, shape ``(len(theta), d)``: the trigonometric interpolant of the nodes
        (on the section and level to the interpolation error only), in the internal variables,
        or with ``public=True`` converted to the public layout (as ``states``)."""
        th = np.atleast_1d(np.asarray(theta, dtype=float))
        X = _basis(th, self.n_nodes) @ _coefficients(self.internal)
        if not public:
            return X
        prob = self.problem
        return np.array([_f64(public_state(prob.system, prob.pars, prob.spec.array(x), prob.spec)) for x in X])

    def distance(self, states: ArrayLike, *, oversample: int = 16) -> np.ndarray:
        """Distance (max norm over the internal variables) from each of ``states`` (public
        layout, shape ``(m, d)``) to the curve ``K``: the nearest of ``oversample * N``
        points of the interpolant, then Newton in ``theta`` on the squared distance."""
        X = internal_f64(self.problem, np.atleast_2d(states))
        n = self.n_nodes
        grid = np.linspace(0.0, 2 * np.pi, oversample * n, endpoint=False)
        c = _coefficients(self.internal)
        Kg = _basis(grid, n) @ c
        out = np.empty(len(X))
        for i, x in enumerate(X):
            th = grid[int(np.argmin(np.sum((Kg - x) ** 2, axis=1)))]
            for _ in range(8):
                B0, B1, B2 = _basis(np.array([th]), n, 2)
                r = (B0 @ c)[0] - x
                d1, d2 = (B1 @ c)[0], (B2 @ c)[0]
                g, h = float(r @ d1), float(d1 @ d1 + r @ d2)
                if h <= 0:
                    break
                th -= g / h
            out[i] = float(np.max(np.abs((_basis(np.array([th]), n) @ c)[0] - x)))
        return out


# ---------------------------------------------------------------------------------------
# Trigonometric interpolation on N (odd) equispaced nodes.
# ---------------------------------------------------------------------------------------
def _basis(theta: np.ndarray, n: int, derivs: int = 0):
    """Real Fourier basis ``[1, cos k t, sin k t (k = 1..(n-1)/2)]`` at ``theta`` (rows), and
    with ``derivs`` its first ``derivs`` derivatives (a tuple then)."""
    h = (n - 1) // 2
    k = np.arange(1, h + 1)
    a = np.outer(theta, k)
    out = []
    for d in range(derivs + 1):
        # d-th derivative of cos, sin: k^d cos(a + d pi/2), k^d sin(a + d pi/2)
        kd = k.astype(float) ** d
        cols = [np.full((len(theta), 1), 1.0 if d == 0 else 0.0), kd * np.cos(a + d * np.pi / 2),
                kd * np.sin(a + d * np.pi / 2)]
        out.append(np.hstack(cols))
    return out[0] if derivs == 0 else tuple(out)


def _nodes(n: int) -> np.ndarray:
    return 2 * np.pi * np.arange(n) / n


def _coefficients(X: np.ndarray) -> np.ndarray:
    """Coefficients (rows as in :func:`_basis`) of the interpolant of the nodes ``X``."""
    n = len(X)
    return np.linalg.solve(_basis(_nodes(n), n), X)


def _shift_matrices(n: int, rho: float) -> Tuple[np.ndarray, np.ndarray]:
    """``(T, D)``: ``T @ X`` is the interpolant at ``theta_j + rho``, ``D = dT/drho``."""
    th = _nodes(n)
    inv = np.linalg.inv(_basis(th, n))
    B0, B1 = _basis(th + rho, n, 1)
    return B0 @ inv, B1 @ inv


def _tail(X: np.ndarray) -> float:
    c = _coefficients(X)
    h = (len(X) - 1) // 2
    amp = np.hypot(c[1:h + 1], c[h + 1:]).max(axis=1)  # per harmonic k = 1..h, max over components
    top = amp.max()
    return float(amp[np.arange(1, h + 1) > 2 * h / 3].max() / top) if top > 0 else 0.0


# ---------------------------------------------------------------------------------------
# The guess: rotation angle and harmonics of an orbit on the circle.
# ---------------------------------------------------------------------------------------
def _check_window(window) -> None:
    if not (isinstance(window, (int, float)) and not isinstance(window, bool) and 0 < window < math.pi):
        raise UsageError(f"window must be an angle in (0, pi) (radians), got {window!r}")


def _angle(name: str, value: object) -> float:
    """``value`` as a finite angle in radians (a real number, not a bool), or UsageError."""
    return real_number(f"{name} (an angle in radians)", value)


def _n_nodes(n_nodes: object) -> int:
    """The number of nodes: an odd integer >= 5 (the interpolant's harmonics ``|k| <= (N-1)/2``)."""
    n = count("n_nodes", n_nodes, lo=5)
    if n % 2 == 0:
        raise UsageError(f"n_nodes must be odd (an integer in [5, inf]), got {n_nodes!r}")
    return n


def rotation_from_orbit(points: ArrayLike, *, near: Optional[float] = None, window: float = 0.05) -> float:
    """The rotation angle ``rho`` in ``[0, 2 pi)`` of an orbit ``points`` (shape ``(m, d)``,
    ``m >= 16``, successive iterates of a map) on or near an invariant circle: the frequency
    of the largest peak (with ``near``: the largest within ``window`` of ``near`` or of ``2 pi
    - near``, the other orientation; for an orbit on a torus, whose largest peak may be the
    other frequency or a combination) of ``z_n = u_n + i v_n``, ``(u, v)`` the two leading principal
    components (the circle must wind once around the mean in that plane; each axis's sign is
    fixed so that its largest entry is positive, and ``theta`` turns with ``(u, v)``),
    refined to the maximum of ``|sum_n w_n z_n e^{-i omega n}|`` (a zero of its derivative,
    by regula falsi) with the window ``w_n`` the square of a Hann window (its leakage from
    the other harmonics falls fast: on orbits of 1500 and 3000 crossings 2.6e-4 off the Fig.
    4b core this agrees with Newton's ``rho`` to 2e-10 and 2e-11; with a Hann window to 4e-8
    and 2e-9, without a window to 2e-5 and 5e-6). The other peaks' leakage (the mean's too)
    sets the accuracy: for a rigid rotation by 0.3 rad on a circle, 7e-6 from 100 points,
    2e-10 from 400, 1e-14 from 1500."""
    Y = np.asarray(points, dtype=float)
    if Y.ndim != 2 or len(Y) < 16 or not np.all(np.isfinite(Y)):
        raise UsageError(f"points must be an array of shape (m, d) with m >= 16 finite rows, got shape "
                         f"{Y.shape}")
    if near is not None:
        _angle("near", near)
    _check_window(window)
    Y = Y - Y.mean(axis=0)
    _, _, Vt = np.linalg.svd(Y, full_matrices=False)
    axes = [v * (1.0 if v[int(np.argmax(np.abs(v)))] > 0 else -1.0) for v in Vt[:2]]
    m = len(Y)
    zw = (Y @ axes[0] + 1j * (Y @ axes[1])) * np.hanning(m) ** 2
    nfft = 1 << int(math.ceil(math.log2(16 * m)))
    F = np.abs(np.fft.fft(zw, nfft))
    if near is not None:  # only the bins within window of near, in either orientation
        f = 2 * np.pi * np.arange(nfft) / nfft
        gap = np.minimum(np.abs(np.mod(f - near + np.pi, 2 * np.pi) - np.pi),
                         np.abs(np.mod(f + near + np.pi, 2 * np.pi) - np.pi))
        F = np.where(gap <= window, F, -1.0)
    w = 2 * np.pi * int(np.argmax(F)) / nfft
    n = np.arange(m)

    def slope(om):  # d/d omega of |S(omega)|^2 / 2, S the windowed transform: zero at the peak
        e = zw * np.exp(-1j * om * n)
        return float(np.real(np.conj(np.sum(e)) * np.sum(-1j * n * e)))

    # the peak's maximum lies within one bin of the FFT's largest: the slope changes sign
    # there; regula falsi (Illinois) on it reaches the rounding of the slope
    a, b = w - 2 * np.pi / nfft, w + 2 * np.pi / nfft
    fa, fb = slope(a), slope(b)
    if fa * fb > 0:  # pragma: no cover  (a peak at the edge of its bins: keep the FFT's)
        return float(w % (2 * np.pi))
    side, c = 0, w
    for _ in range(100):
        c = (a * fb - b * fa) / (fb - fa)
        fc = slope(c)
        if fc == 0:
            break
        if fc * fb > 0:  # c replaces b; Illinois: halve the kept end's value if b moved twice
            b, fb = c, fc
            if side == -1:
                fa *= 0.5
            side = -1
        else:
            a, fa = c, fc
            if side == 1:
                fb *= 0.5
            side = 1
        if abs(b - a) <= 4 * _EPS * max(1.0, abs(c)):
            break
    return float(c % (2 * np.pi))


def _fit(Y: np.ndarray, rho: float, n: int) -> Tuple[np.ndarray, float]:
    """Nodes of the least-squares circle through the orbit ``Y`` (``Y_m ~ K(m rho)``) and the
    fit's RMS residual."""
    Bm = _basis(rho * np.arange(len(Y)), n)
    c, *_ = np.linalg.lstsq(Bm, Y, rcond=None)
    res = float(np.sqrt(np.mean((Bm @ c - Y) ** 2)))
    return _basis(_nodes(n), n) @ c, res


# ---------------------------------------------------------------------------------------
# Newton.
# ---------------------------------------------------------------------------------------
def _images(ctx: _Ctx, X: List[np.ndarray]):
    """``P(x_j)``, ``Pi_j Phi_j`` and return times of the nodes."""
    PX, DP, T = [], [], []
    for x in X:
        xT, Phi, Tj = _flow(ctx, x, _crossing_time(ctx, x))
        DP.append(_jacobian(ctx, x, 0.0, xT, Phi, _eval_geo(ctx.prob, ctx.g0, x))[1])  # Pi Phi
        PX.append(_f64(xT))
        T.append(float(Tj))
    return np.array(PX), DP, np.array(T)


def _residual(ctx: _Ctx, X: List[np.ndarray], rho: float):
    PX, DP, T = _images(ctx, X)
    Tm, Dm = _shift_matrices(len(X), rho)
    Xf = np.array([_f64(x) for x in X])
    F = PX - Tm @ Xf
    return float(np.max(np.abs(F))), F, DP, T, Tm, Dm, Xf


def _newton(ctx: _Ctx, X: List[np.ndarray], rho: float, *, max_iter: int, rtol: float, scale: float):
    spec = ctx.prob.spec
    N = len(X)

    def evaluate(X, rho):
        try:
            return _residual(ctx, X, rho)
        except (IntegrationError, StateError):
            return None

    cur = evaluate(X, rho)
    if cur is None:
        raise IntegrationError("a node of the guess does not return to the section")
    hist = [cur[0]]
    for _ in range(max_iter):
        res, F, DP, T, Tm, Dm, Xf = cur
        if res <= rtol * scale:
            break
        if len(hist) >= 3 and hist[-1] > 0.5 * hist[-3]:
            break  # stagnation (at the interpolation's or the map's floor): two iterates without a 2x gain
        Bs = [_tangent_basis(ctx.prob, ctx.g0, x) for x in X]
        d, m = Xf.shape[1], Bs[0].shape[1]
        J = np.zeros((N * d + 1, N * m + 1))
        K1 = _shift_matrices(N, 0.0)[1] @ Xf  # K'(theta_j): the phase condition
        for j in range(N):
            J[j * d:(j + 1) * d, j * m:(j + 1) * m] += DP[j] @ Bs[j]
            for i in range(N):
                J[j * d:(j + 1) * d, i * m:(i + 1) * m] -= Tm[j, i] * Bs[i]
            J[N * d, j * m:(j + 1) * m] = K1[j] @ Bs[j]
        J[:N * d, -1] = -(Dm @ Xf).ravel()
        rhs = np.concatenate([F.ravel(), [0.0]])
        step = np.linalg.lstsq(J, -rhs, rcond=None)[0]
        smax = float(np.max(np.abs(step[:-1])))
        if smax > 0.2 * scale:
            step *= 0.2 * scale / smax
        lam, nxt = 1.0, None
        for _ in range(12):
            try:
                Xn = [_to_level(ctx, X[j] + spec.array(lam * (Bs[j] @ step[j * m:(j + 1) * m])), scale)
                      for j in range(N)]
            except StateError:
                lam *= 0.5
                continue
            trial = evaluate(Xn, rho + lam * float(step[-1]))
            if trial is not None and trial[0] < res * (1 - 1e-4 * lam) + 64 * spec.eps * scale:
                nxt = (Xn, rho + lam * float(step[-1]), trial)
                break
            lam *= 0.5
        if nxt is None:
            break
        X, rho, cur = nxt
        hist.append(cur[0])
    return X, rho % (2 * np.pi), cur, hist


def _orbit_on_level(prob: Problem, orbit, n_nodes: int, levels: LevelsLike, g0: float, direction, section_tol):
    """The checked orbit of :func:`invariant_circle` and :func:`shrink_torus`: its internal
    states, the geometry at its first state and the level's targets (working type)."""
    real_number("section_tol", section_tol, lo=0.0)
    if orbit is None:
        raise UsageError("orbit (successive crossings of one orbit, public layout, shape (m, d)) is required")
    Y = np.asarray(orbit, dtype=float)
    d = prob.system.dim
    if Y.ndim != 2 or Y.shape[1] != d or len(Y) < 4 * n_nodes or not np.all(np.isfinite(Y)):
        raise UsageError(f"orbit must be finite crossings of shape (m, {d}) with m >= 4 * n_nodes = {4 * n_nodes}, "
                         f"got shape {Y.shape}")
    Section(prob, g0, direction)  # checks g0, direction
    Xo = internal_f64(prob, Y)
    geo = _eval_geo(prob, g0, prob.spec.array(Xo[0]))
    targets_d = _level_targets(prob, geo.names, levels)
    targets = prob.spec.array([targets_d[k] for k in geo.names]) if targets_d else geo.c.copy()
    for i, x in enumerate(Xo):
        gx = _eval_geo(prob, g0, prob.spec.array(x))
        off = np.abs(_f64(gx.c) - _f64(targets)) / np.maximum(1.0, np.abs(_f64(targets)))
        if abs(float(gx.e)) > section_tol or float(off.max()) > section_tol or not _on_branch(prob, g0, x):
            raise StateError(f"orbit state {i} is off the section g = {g0!r} (event {float(gx.e):.1e}) or off the "
                             f"level (relative {float(off.max()):.1e}); section_tol = {section_tol!r}")
    return Xo, geo, targets


def invariant_circle(kind: Union[KindName, Problem], params: Optional[ParamsLike] = None,
                     orbit: Optional[ArrayLike] = None, *, n_nodes: int = 41, levels: LevelsLike = None,
                     g0: float = 0.0, direction: Direction = 1, rho: Optional[float] = None,
                     max_iter: int = 12, rtol: float = 1e-11, section_tol: float = 1e-8) -> InvariantCircle:
    r"""An invariant circle of the first return map, by Newton from an orbit on or near it.

    Parameters
    ----------
    kind : {"reduced", "mparallel"} or Problem
    params : BallParams or MParallelParams (None with a Problem)
    orbit : array_like, shape (m, d)
        Successive crossings of one orbit (public layout; e.g. ``poincare_section(...).states``)
        that lie on or close to the circle, ``m >= 4 * n_nodes``.
    n_nodes : int
        Number of nodes ``N`` (odd, >= 5): harmonics up to ``(N - 1)/2``.
    levels : Levels, MParallelLevels or dict, optional
        The level (default: the first state's integrals).
    g0, direction
        The section (as :func:`taylorball.poincare_section`).
    rho : float, optional
        The rotation angle's guess (default: :func:`rotation_from_orbit` of the orbit).
    max_iter : int
        Newton iterations (>= 1).
    rtol : float
        Accept when ``residual <= rtol * max(1, max |x|)`` (> 0).
    section_tol : float
        How far (event function, relative level) the orbit's states may be off the section
        and the level.

    Returns
    -------
    InvariantCircle

    Raises
    ------
    UsageError
        Bad ``n_nodes``, ``orbit``, ``max_iter``, ``rtol``, ``section_tol``, ``rho``; a kind
        without a section.
    StateError
        An orbit state off the section or off ``levels``.
    InvariantCircleFailure
        Newton did not reach ``1e3 * rtol`` (relative); the best nodes are attached.
    """
    prob = orbit_problem(kind, params)
    _n_nodes(n_nodes)
    count("max_iter", max_iter)
    real_number("rtol", rtol, lo=0.0, lo_open=True)
    if rho is not None:
        _angle("rho", rho)
    Xo, geo, targets = _orbit_on_level(prob, orbit, n_nodes, levels, g0, direction, section_tol)
    ctx = _Ctx(prob, float(g0), int(direction), 1, targets, False, 1e4)
    r0 = rotation_from_orbit(Xo) if rho is None else float(rho) % (2 * np.pi)
    nodes, _ = _fit(Xo, r0, n_nodes)
    scale = max(1.0, float(np.max(np.abs(Xo))))
    X0 = [_to_level(ctx, prob.spec.array(x), scale) for x in nodes]
    X, r, cur, hist = _newton(ctx, X0, r0, max_iter=max_iter, rtol=rtol, scale=scale)
    res, F, DP, T, Tm, Dm, Xf = cur
    pub = np.array([_f64(public_state(prob.system, prob.pars, x, prob.spec)) for x in X])
    if not res <= 1e3 * rtol * scale:
        raise InvariantCircleFailure(f"Newton did not reach an invariant circle: best residual {res:.3e} (needed "
                                     f"<= {1e3 * rtol * scale:.1e}); history "
                                     f"{', '.join(f'{h:.1e}' for h in hist)}", res, hist, pub)
    lv = {k: float(v) for k, v in zip(geo.names, _f64(targets))}
    return InvariantCircle(kind=prob.kind, states=pub, points=chart_points(prob.kind, Xf), rho=float(r),
                           rotation_number=float(r / (2 * np.pi)), residual=res, residual_history=tuple(hist),
                           fourier_tail=_tail(Xf), return_times=T, levels=lv, g0=float(g0),
                           direction=int(direction), internal=Xf, problem=prob)


# ---------------------------------------------------------------------------------------
# Shrinking tori onto their core: a guess for Newton from an orbit on a fat torus.
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class TorusShrink:
    """The result of :func:`shrink_torus`.

    Attributes
    ----------
    states : ndarray, shape (n_points, d)
        The crossings of the thinnest orbit found (public layout): Newton's input for
        :func:`invariant_circle` (with ``rho=rho``).
    rho : float
        Its rotation angle (the peak near the given one, either orientation).
    residuals : tuple of float
        The RMS residual of the least-squares circle of the input orbit, then of the orbit
        kept in each round (decreasing).
    starts : int
        The orbits run in all (the refused ones included).
    """

    states: np.ndarray
    rho: float
    residuals: Tuple[float, ...]
    starts: int


def shrink_torus(kind: Union[KindName, Problem], params: Optional[ParamsLike] = None,
                 orbit: Optional[ArrayLike] = None, *, rho: float, window: float = 0.05, n_nodes: int = 41,
                 n_starts: int = 16, n_points: int = 1000, max_rounds: int = 8, levels: LevelsLike = None,
                 keep: Optional[Callable[[SectionResult], bool]] = None, g0: float = 0.0,
                 direction: Direction = 1, section_tol: float = 1e-8) -> TorusShrink:
    r"""Orbits on ever thinner tori around an invariant circle, from an orbit on a fat one.

    An orbit ``y_n`` on an invariant 2-torus ``T(phi, psi)`` of the map around a circle
    (``phi -> phi + rho`` along the circle, ``psi`` around it) is fitted by ``y_n ~ K(n rho)``
    (least squares, harmonics up to ``(n_nodes - 1)/2``): the fit keeps the harmonics of
    ``rho`` only, so ``K`` is the torus averaged over ``psi``, close to the core (to second
    order in the torus's width for a circle that is elliptic in the normal direction). Each
    round starts ``n_starts`` orbits on ``K`` (equally spaced in ``theta``, moved onto the
    section and level), runs ``n_points`` crossings of each (:func:`taylorball.poincare_sections`,
    float64, batch mode), and keeps the one whose own least-squares circle has the smallest RMS
    residual (its ``rho`` refound near the previous one); it stops when no start improves
    on the orbit kept. The residual measures the torus's width; it does not tend to zero if
    there is no circle (in a chaotic layer, a resonance) and says nothing about that by
    itself: :func:`invariant_circle` from ``states`` decides.

    Parameters
    ----------
    kind, params
        As for :func:`invariant_circle`.
    orbit : array_like, shape (m, d)
        Successive crossings of one orbit on the torus (public layout), ``m >= 4 * n_nodes``.
    rho : float
        The rotation angle along the core to follow: the torus's frequency that tends to it
        (e.g. from a spectrum of the orbit); each round takes the largest peak within
        ``window`` of the previous ``rho`` (:func:`rotation_from_orbit` with ``near``).
    window : float
        In ``(0, pi)``.
    n_nodes : int
        Odd, >= 5: the harmonics of the fit.
    n_starts : int
        Orbits per round (>= 1; at most ``n_nodes``, the fit's nodes).
    n_points : int
        Crossings of each (>= 4 * n_nodes).
    max_rounds : int
        >= 1.
    levels : optional
        The level (default: the orbit's first state's integrals).
    keep : callable, optional
        ``keep(section_result) -> bool``: which orbits may be kept (e.g. those in the region of
        the family followed; without it, a start that falls onto another family's thinner
        torus wins).
    g0, direction, section_tol
        The section, and how far the orbit's states may be off it and the level (as for
        :func:`invariant_circle`).

    Returns
    -------
    TorusShrink

    Raises
    ------
    UsageError
        Bad ``rho``, ``window``, ``n_nodes``, ``n_starts``, ``n_points``, ``max_rounds``,
        ``orbit``, ``keep``, ``section_tol``.
    StateError
        An orbit state off the section or off ``levels`` (as for :func:`invariant_circle`).
    """
    prob = orbit_problem(kind, params)
    _n_nodes(n_nodes)
    count("n_starts", n_starts)
    count("max_rounds", max_rounds)
    count("n_points (at least 4 * n_nodes)", n_points, lo=4 * n_nodes)
    _angle("rho", rho)
    _check_window(window)
    if keep is not None and not callable(keep):
        raise UsageError(f"keep must be a callable (SectionResult -> bool) or None, got {keep!r}")
    X, _, targets = _orbit_on_level(prob, orbit, n_nodes, levels, g0, direction, section_tol)
    r = rotation_from_orbit(X, near=float(rho), window=window)
    ctx = _Ctx(prob, float(g0), int(direction), 1, targets, False, 1e4)
    scale = max(1.0, float(np.max(np.abs(X))))
    nodes, res = _fit(X, r, n_nodes)
    residuals, states, starts = [res], np.asarray(orbit, dtype=float), 0
    pick = np.unique(np.linspace(0, n_nodes, n_starts, endpoint=False).astype(int))
    for _ in range(max_rounds):
        trial = []
        for x in nodes[pick]:
            try:
                trial.append(_f64(public_state(prob.system, prob.pars, _to_level(ctx, prob.spec.array(x), scale),
                                               prob.spec)))
            except StateError:  # a point of the averaged circle off the level's reach
                continue
        starts += len(trial)
        best = None
        for sec in (poincare_sections(prob, trial, n_points=n_points, g0=g0, direction=direction, batch=True)
                    if trial else []):
            if not sec.ok or (keep is not None and not keep(sec)):
                continue
            Xs = internal_f64(prob, sec.states)
            rs = rotation_from_orbit(Xs, near=r, window=window)
            ns, fr = _fit(Xs, rs, n_nodes)
            if best is None or fr < best[0]:
                best = (fr, rs, ns, sec.states)
        if best is None or not best[0] < residuals[-1]:
            break
        res, r, nodes, states = best
        residuals.append(res)
    return TorusShrink(states=np.asarray(states, dtype=float), rho=float(r), residuals=tuple(residuals),
                       starts=starts)
