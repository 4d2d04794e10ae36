r"""Validated propagation of the paper's systems: :func:`enclose`.

``enclose(kind, params, state, t, radius=0.0)`` returns a box that provably contains the
solution at time ``t`` of every initial state in the box ``state +- radius`` (public layout),
computed with the validated Taylor steps of :mod:`taylorball.rigorous._taylor` in ball
arithmetic at ``prec`` bits. The vector field is :meth:`taylorball.model.System.rhs` (the
one source of the physics), evaluated on balls and series of balls.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from ..errors import IntegrationError, StateError, UsageError
from ..model import KIND_TABLE, KINDS, get_system
from ..params import BallParams, MParallelParams
from ._balls import arb, exact_arb, hull, require_flint, working_precision
from ._taylor import (LohnerSet, StepResult, VarSet, c1_lohner_update, default_order, lohner_step, max_rad,
                      step_size_guess)

__all__ = ["Enclosure", "enclose", "ball_pars", "ball_rhs", "internal_system", "outward_float",
           "integrate_set"]


def outward_float(x: Any, side: int) -> float:
    """The float64 nearest ``x``'s lower (``side = -1``) or upper (``+1``) end, rounded outward:
    ``lo <= every point of x`` exactly."""
    end = x.lower() if side < 0 else x.upper()
    v = float(end.mid())
    if not math.isfinite(v):
        return -math.inf if side < 0 else math.inf
    while True:
        e = exact_arb(v)
        if (side < 0 and e <= x) or (side > 0 and e >= x):
            return v
        v = math.nextafter(v, -math.inf if side < 0 else math.inf)


def ball_pars(kind: str, params: Any) -> Tuple[Any, ...]:
    """The parameter vector of ``kind`` as exact balls (every float64 is exact). For
    ``"mparallel"`` with :class:`BallParams`, ``a_i = 1/(I_i + m a^2)`` and ``d = m a^2`` are
    formed in ball arithmetic (not rounded to float64)."""
    if kind == "mparallel" and isinstance(params, BallParams):
        I1, I2, I3, m, a, om = (exact_arb(p) for p in params.pars)
        d = m * a * a
        return (1 / (I1 + d), 1 / (I2 + d), 1 / (I3 + d), d, om)
    params = get_system(kind).check_params(params)
    return tuple(exact_arb(p) for p in params.pars)


def internal_system(kind: str) -> Any:
    """The formulation integrated rigorously: the default (``momentum`` for the balls)."""
    return get_system(kind)


def ball_rhs(kind: str, pars: Sequence[Any]) -> Callable[[Sequence[Any]], Tuple[Any, ...]]:
    """The vector field of ``kind`` (internal variables) as a function of a list of scalars
    (arbs, arb_series or duals), from :meth:`taylorball.model.System.rhs`."""
    system = internal_system(kind)
    pars = tuple(pars)
    return lambda xs: system.rhs(pars, tuple(xs))


@dataclass
class Enclosure:
    """A validated enclosure of the solution at time :attr:`t`.

    Attributes
    ----------
    lower, upper : ndarray
        float64 bounds in the public layout, rounded outward.
    mid, rad : ndarray
        Midpoint (nearest float) and radius (rounded up) per public component.
    balls : list
        The public components as ``flint.arb`` balls (exact working-precision enclosures).
    internal : list
        The integrated (internal) variables as balls.
    integrals : dict
        For each first integral of the kind, ``(lo, hi)`` enclosing its values on every step's
        box (float64, outward): the integrals enclosed along the way.
    t : float
    prec, order, steps : int
    widths : list of (t, max radius)
        The largest radius of the internal box after each step.
    cpu_seconds : float
    """

    lower: np.ndarray
    upper: np.ndarray
    mid: np.ndarray
    rad: np.ndarray
    balls: List[Any]
    internal: List[Any]
    integrals: Dict[str, Tuple[float, float]]
    t: float
    prec: int
    order: int
    steps: int
    widths: List[Tuple[float, float]] = field(default_factory=list)
    cpu_seconds: float = 0.0

    def contains(self, state: Sequence[Any]) -> bool:
        """True only if every component of ``state`` (floats, mpmath numbers converted exactly
        through their decimal string at the working precision, or arbs) lies in the box."""
        with working_precision(max(self.prec, 53)):
            for b, x in zip(self.balls, state):
                xb = _to_ball(x)
                if not b.contains(xb):
                    return False
        return True


def _to_ball(x: Any) -> Any:
    if isinstance(x, arb):
        return x
    mod = type(x).__module__ or ""
    if mod.startswith("mpmath"):
        import mpmath

        # exact: value = (-1)^sign man 2^exp (x._mpf_, not mpf(x), which rounds to mp.prec)
        sign, man, exp, _ = x._mpf_ if hasattr(x, "_mpf_") else mpmath.mpf(x)._mpf_
        q = Fraction(int(man) * 2 ** exp) if exp >= 0 else Fraction(int(man), 2 ** (-exp))
        b = exact_arb(q)
        return -b if sign else b
    if mod.startswith("heyoka") and type(x).__name__ == "real":
        # heyoka.real (MPFR): through its decimal digits (as many as its bits need, so the
        # ball of the string lies within ~1e-3 ulp of the binary value)
        return arb(str(x))
    return exact_arb(float(x))


def _check_state(kind: str, state: Any) -> np.ndarray:
    n = len(KIND_TABLE[kind].public_names)
    try:
        x = np.asarray(state, dtype=float)
    except (TypeError, ValueError):
        raise StateError(f"state must be {n} real numbers (the public layout of kind={kind!r}), got {state!r}") from None
    if x.shape != (n,) or not np.all(np.isfinite(x)):
        raise StateError(
            f"state must be {n} finite real numbers {KIND_TABLE[kind].public_names} for kind={kind!r}, got {state!r}"
        )
    return x


def _jac_rem_ok(res: StepResult, tol: float) -> bool:
    """The remainder of the variational equation (C^1 steps) is below ``16 tol`` of the step
    Jacobian's size, or below 1e-3 of its own width (the Jacobian of the box dominates)."""
    assert res.rem_jac is not None and res.jac is not None
    J = res.jac
    n = J.nrows()
    jscale = max(1.0, max(float(abs(J[i, j].mid())) for i in range(n) for j in range(n)))
    rj = max(float(abs(x).upper()) for row in res.rem_jac for x in row)
    wj = max(float(J[i, j].rad()) for i in range(n) for j in range(n))
    return rj <= max(16 * tol * jscale, 1e-3 * wj)


def integrate_set(rhs: Callable, S: LohnerSet, t_end: Fraction, *, prec: int, order: int, tol: float,
                  jac: bool = False, wrapping: str = "qr", max_steps: int = 100000,
                  remainder_scale: int = 1, on_step: Optional[Callable[[Fraction, StepResult], None]] = None,
                  h_max: Optional[float] = None, c1: str = "lohner",
                  step_memory: bool = True, slices: int = 0) -> Tuple[LohnerSet, Optional[VarSet], int, List[Any]]:
    """Carry the set ``S`` from time 0 to ``t_end`` (exact) with validated steps. Returns the
    final set, the Jacobian enclosure of the flow over the initial set (``jac=True``; a
    :class:`~taylorball.rigorous._taylor.VarSet`, carried by the C^1 Lohner algorithm, or with
    ``c1="product"`` as the plain product of the steps' interval Jacobians), the number of
    steps and the last step's box.

    Step size: the Jorba--Zou guess from the point coefficients, halved until the step is
    validated and its remainder small enough. With ``step_memory`` (the default) the guess is
    scaled by a factor that remembers those halvings (``2^-k`` after ``k`` of them) and grows
    by ``2^(1/4)`` after a step accepted at once, up to 1: on the Fig. 3 ball the guess was
    halved 2.6 times per accepted step on average (3.6 attempts per step; with the memory 1.3),
    docs/rigorous.md. ``step_memory=False`` is the former behaviour.

    ``slices``: the C^0 steps' remainder is enclosed over that many time slices of the step
    (:func:`~taylorball.rigorous._taylor.sliced_remainder`), which lets the steps grow to the
    a priori enclosure's limit: fewer steps, but each wraps more, so the enclosure can come
    out wider (on the Fig. 3 saddle at 53 bits 1.4 times less CPU per time unit and 1.6
    times fewer steps with 4 slices, and 2 to 10 times wider boxes; docs/rigorous.md).
    ``0`` (the default): over the one a priori box."""
    if c1 not in ("lohner", "product"):
        raise UsageError(f"c1 must be 'lohner' or 'product', got {c1!r}")
    n = len(S.c)
    t = Fraction(0)
    V: Optional[VarSet] = VarSet.identity(n) if jac else None
    steps = 0
    box = S.box()
    fac = 1.0
    while t < t_end:
        if steps >= max_steps:
            raise IntegrationError(f"enclose: more than max_steps = {max_steps} steps before t = {float(t_end)!r}")
        h = step_size_guess(rhs, S.c, order, tol) * fac
        scale = max(1.0, max(abs(float(x.mid())) for x in S.c))
        if h_max is not None:
            h = min(h, h_max)
        # the remainder may be 1e-3 of the set's width: for a doubleton set the width of its
        # error part A r only (its parameter part P q is carried exactly)
        wide = max_rad(box) if S.P is None else max_rad([S.c[i] + sum((S.A[i, j] * S.r[j] for j in range(n)), exact_arb(0))
                                                         for i in range(n)])
        res = None
        halvings, truncated = 0, False
        for _ in range(40):
            hf = Fraction(h)
            truncated = t + hf >= t_end
            if truncated:
                hf = t_end - t
            res = lohner_step(rhs, S, exact_arb(hf), order, jac=jac, wrapping=wrapping,
                              remainder_scale=remainder_scale, slices=slices,
                              rem_limit=max(16 * tol * scale, 1e-3 * wide))
            if res is not None and max(float(abs(r).upper()) for r in res.rem) <= max(16 * tol * scale, 1e-3 * wide) \
                    and (res.rem_jac is None or _jac_rem_ok(res, tol)):
                break
            res = None
            h = float(hf) / 2
            halvings += 1
            if h < 1e-12:
                break
        if step_memory and res is not None and not truncated:
            fac = fac * 0.5 ** halvings if halvings else min(1.0, fac * 2 ** 0.25)
        if res is None:
            raise IntegrationError(
                f"enclose: no validated step at t = {float(t):.6g} (the a priori enclosure failed down to h = {h:.3g}; "
                f"the box has grown to radius {max_rad(box):.3g}, or the field is singular on it)"
            )
        S = res.set
        box = res.box
        if V is not None:
            V = c1_lohner_update(V, res, c1)
        t += hf
        steps += 1
        if on_step is not None:
            on_step(t, res)
        if not all(b.is_finite() for b in box):
            raise IntegrationError(f"enclose: the enclosure became unbounded at t = {float(t):.6g}")
    return S, V, steps, box


def enclose(kind: Any, params: Any = None, state: Any = None, t: float = 0.0, radius: float = 0.0, *,
            prec: int = 53, order: Optional[int] = None, tol: Optional[float] = None,
            wrapping: str = "qr", max_steps: int = 100000) -> Enclosure:
    r"""A validated enclosure of the solution at time ``t``.

    Parameters
    ----------
    kind : {"reduced", "full", "mparallel"} or Problem
        The system (a :class:`taylorball.Problem` gives kind and params).
    params : BallParams or MParallelParams
    state : array_like
        Initial state in the public layout (float64, taken as exact binary numbers).
    t : float
        End time (>= 0).
    radius : float
        Half-width of the initial box around ``state`` in every public component.
    prec : int
        Working precision in bits (53 up to hundreds).
    order : int, optional
        Taylor order (default :func:`~taylorball.rigorous._taylor.default_order`).
    tol : float, optional
        Local remainder target (default ``2^-prec``).
    wrapping : {"qr", "parallelepiped", "box"}
        Lohner's QR method (default), the parallelepiped method, or none (direct interval).

    Returns
    -------
    Enclosure

    Raises
    ------
    UsageError, StateError
        Bad arguments, before any work is done.
    IntegrationError
        When no validated step can be made (the box has grown too large, or the field is
        singular on it); nothing is returned that is not proved.
    """
    require_flint()
    from .._problem import Problem

    if isinstance(kind, Problem):
        if params is not None and state is None:
            params, state, t = None, params, state if state is not None else t
        problem = kind
        kind, params = problem.kind, problem.params
    if kind not in KINDS:
        raise UsageError(f"kind must be one of {KINDS} or a Problem, got {kind!r}")
    if params is None or not isinstance(params, (BallParams, MParallelParams)):
        raise UsageError(f"params must be BallParams or MParallelParams, got {params!r}")
    x = _check_state(kind, state)
    try:
        t_f = float(t)
    except (TypeError, ValueError):
        raise UsageError(f"t must be a finite real number >= 0, got {t!r}") from None
    if not (math.isfinite(t_f) and t_f >= 0):
        raise UsageError(f"t must be a finite real number >= 0, got {t!r}")
    r_f = float(radius)
    if not (math.isfinite(r_f) and r_f >= 0):
        raise UsageError(f"radius must be a finite real number >= 0, got {radius!r}")
    if wrapping not in ("qr", "parallelepiped", "box"):
        raise UsageError(f"wrapping must be 'qr', 'parallelepiped' or 'box', got {wrapping!r}")
    order = default_order(prec) if order is None else order
    if isinstance(order, bool) or not isinstance(order, int) or not 2 <= order <= 200:
        raise UsageError(f"order must be an integer in [2, 200], got {order!r}")
    tol_f = 2.0 ** (-prec) if tol is None else float(tol)
    if not (tol_f > 0 and math.isfinite(tol_f)):
        raise UsageError(f"tol must be a finite number > 0, got {tol!r}")
    system = internal_system(kind)
    info = KIND_TABLE[kind]
    cpu0 = time.process_time()
    with working_precision(prec):
        pars = ball_pars(kind, params)
        pub0 = [exact_arb(v) + (arb(0, r_f) if r_f else 0) for v in x]
        X0 = list(system.to_internal(pars, pub0))
        rhs = ball_rhs(kind, pars)
        c = system.constants(pars)
        ints: Dict[str, Any] = {}
        widths: List[Tuple[float, float]] = []

        def record(tt: Fraction, res: Optional[StepResult], box: Sequence[Any]) -> None:
            vals = info.integrals(c, system.vectors(c, tuple(box)))
            for k, v in vals.items():
                ints[k] = v if k not in ints else hull(ints[k], v)
            widths.append((float(tt), max_rad(box)))

        record(Fraction(0), None, X0)
        S, _, steps, box = integrate_set(
            rhs, LohnerSet.from_box(X0), Fraction(t_f), prec=prec, order=order, tol=tol_f, wrapping=wrapping,
            max_steps=max_steps, on_step=lambda tt, res: record(tt, res, res.box),
        )
        pub = list(system.to_public(pars, box))
        lower = np.array([outward_float(b, -1) for b in pub])
        upper = np.array([outward_float(b, +1) for b in pub])
        mid = np.array([float(b.mid()) for b in pub])
        rad = np.array([float(b.rad()) for b in pub])
        integrals = {k: (outward_float(v, -1), outward_float(v, +1)) for k, v in ints.items()}
    return Enclosure(lower, upper, mid, rad, pub, list(box), integrals, t_f, prec, order, steps, widths,
                     time.process_time() - cpu0)
