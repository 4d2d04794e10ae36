r"""The rigorous section map of the dynamically symmetric ball and its C^1 enclosure.

For ``I1 = I2`` the section-4 angle ``l`` is cyclic (paper section 4), so the map of the
section ``g = g0`` (here ``g0 = 0``, crossings with ``g`` increasing) induces a 2D map
``P: (r1, r2) -> (r1', r2')`` on a level ``|M| = C``, ``(M, gamma) = M_gamma``, ``E = h``;
it is evaluated at ``l = 0``. For a box ``Pbox`` of ``(r1, r2)`` this module encloses, in
ball arithmetic:

1. the start states: ``K = M3`` from the energy equation by the interval Newton operator
   (unique in its interval), ``M, gamma, R`` from the inverse chart
   (:func:`taylorball.charts.angles_to_vectors` and :func:`taylorball.charts.R_from_r` at
   ``l = g = 0``), and their derivatives in ``(r1, r2)`` (duals; ``dK/dp = -E_p/E_K``);
2. the flow to ``t_a`` (just before the crossing) with its Jacobian (Lohner steps with the
   variational equations, :mod:`taylorball.rigorous._taylor`);
3. the crossing time: the interval Newton operator on ``s -> e(x(t_a + s))`` with ``e`` the
   section's event function (:func:`taylorball.charts.section_event_function`) proves one
   crossing per start state in ``[0, 2 delta]`` and encloses it; the crossing is checked to be
   on ``g = 0`` (not ``g = pi``) and with ``g`` increasing;
4. ``P(Pbox)`` and ``DP(Pbox) = Dchart (I - f grad(e)^T / (grad(e), f)) Dphi Dx0``.

The map so defined is the local return map near the candidate's return time; a fixed point
of it is a periodic orbit of the reduced flow modulo the symmetry (a relative periodic orbit),
whatever happens between ``0`` and ``t_a``.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Any, List, Sequence, Tuple

from ..charts import section_event_function
from ..errors import IntegrationError
from ..model import REDUCED, get_system
from ._balls import Dual, arb, arb_mat, exact_arb, interval
from ._taylor import LohnerSet, default_order, lohner_step
from .enclosure import ball_pars, ball_rhs, integrate_set

__all__ = ["SectionEnclosure", "section_map", "NotProved"]


class NotProved(Exception):
    """A validated step did not close (an inclusion failed); the message says which."""


def _sqrt(x: Any) -> Any:
    return x.sqrt()


def chart_start_state(C: Any, Mg: Any, K: Any, r1: Any, r2: Any) -> Tuple[Any, ...]:
    """Internal reduced state ``(M, gamma, R)`` at ``l = g = 0`` (balls or duals)."""
    k = K / C
    q = _sqrt(1 - k * k)
    mu = Mg / C
    s = _sqrt(1 - mu * mu)
    zero = K * 0
    M = (zero, C * q, C * k)
    g2, g3 = mu * q + s * k, mu * k - s * q
    gamma = (zero, g2, g3)
    R = (r2 / g2, r1 / g2, -r1 / g3)  # R_from_r with gamma1 = 0
    return (*M, *gamma, *R)


def chart_r(x: Sequence[Any]) -> Tuple[Any, Any]:
    """``r1 = R1 gamma1 + R2 gamma2``, ``r2 = R1 gamma2 - R2 gamma1`` of an internal state."""
    g, R = x[3:6], x[6:9]
    return R[0] * g[0] + R[1] * g[1], R[0] * g[1] - R[1] * g[0]


def _energy(c: Any, x: Sequence[Any]) -> Any:
    system = get_system("reduced")
    return REDUCED.integrals(c, system.vectors(c, tuple(x)))["E"]


@dataclass
class SectionEnclosure:
    """``P(Pbox)`` (two balls), ``DP(Pbox)`` (2 x 2 balls), the crossing time (a ball)."""

    P: List[Any]
    DP: List[List[Any]]
    tau: Any
    steps: int


def _eye(n: int) -> Any:
    return arb_mat([[1 if i == j else 0 for j in range(n)] for i in range(n)])


def section_map(params: Any, levels: Any, pbox: Sequence[Any], K_guess: float, tau_guess: float, *,
                prec: int = 128, order: int | None = None, delta: float = 1e-3, dK: float = 1e-6,
                jac: bool = True) -> SectionEnclosure:
    """Enclose the symmetric 2D section map and (``jac=True``) its Jacobian on ``pbox``
    (two arbs ``r1, r2``), near the float candidate's root ``K_guess`` and return time
    ``tau_guess``. Must run inside :class:`~taylorball.rigorous._balls.working_precision`.

    Raises
    ------
    NotProved
        When an inclusion of an interval Newton operator fails (no uniqueness proved), or the
        crossing is not on ``g = 0`` with ``g`` increasing.
    """
    order = default_order(prec) if order is None else order
    pars = ball_pars("reduced", params)
    system = get_system("reduced")
    c = system.constants(pars)
    rhs = ball_rhs("reduced", pars)
    C, Mg, h = (exact_arb(v) for v in (levels.C, levels.M_gamma, levels.h))
    r1, r2 = pbox
    # 1. K by interval Newton, unique in [K_guess +- dK] for every p in pbox
    Km = exact_arb(K_guess)
    F_m = _energy(c, chart_start_state(C, Mg, Km, r1, r2)) - h
    for dK_try in (dK, dK * 1e2, dK * 1e4):  # the root moves with p over the box: widen if needed
        Kb = exact_arb(K_guess) + arb(0, dK_try)
        Fd = _energy(c, chart_start_state(C, Mg, Dual(Kb, (exact_arb(1),)), Dual(r1, (0,)), Dual(r2, (0,)))) - h
        NK = Km - F_m / Fd.g[0]
        if Kb.contains_interior(NK):
            break
    else:
        raise NotProved(f"the energy equation's root K is not isolated in [{K_guess!r} +- {dK_try:g}] "
                        f"(Newton image {NK.str(5)})")
    one, zero = exact_arb(1), exact_arb(0)
    Fg = _energy(c, chart_start_state(C, Mg, Dual(NK, (zero, zero, one)), Dual(r1, (one, zero, zero)),
                                      Dual(r2, (zero, one, zero)))) - h
    dKdp = (-Fg.g[0] / Fg.g[2], -Fg.g[1] / Fg.g[2])
    x0d = chart_start_state(C, Mg, Dual(NK, dKdp), Dual(r1, (one, zero)), Dual(r2, (zero, one)))
    X0 = [x.v for x in x0d]
    Dx0 = arb_mat([[x.g[j] for j in range(2)] for x in x0d])
    # 2. flow to t_a with its Jacobian
    t_a = Fraction(tau_guess) - Fraction(delta)
    S_a, V_a, steps, _ = integrate_set(rhs, LohnerSet.from_box(X0), t_a, prec=prec, order=order,
                                       tol=2.0 ** (-prec), jac=jac)
    # 3. the crossing: interval Newton on G(s) = e(x(t_a + s)), s in [0, 2 delta]
    Sint = interval(0, 2 * delta)
    s_m = exact_arb(delta)
    full = lohner_step(rhs, S_a, exact_arb(2 * delta), order)
    mid = lohner_step(rhs, S_a, s_m, order)
    if full is None or mid is None:
        raise NotProved("no validated step across the section")
    ev = lambda x: section_event_function(x[0:3], x[3:6], 0.0)  # noqa: E731
    n = 9
    B = full.B
    Bd = [Dual(B[i], tuple(one if j == i else zero for j in range(n))) for i in range(n)]
    eB = ev(Bd)
    fB = rhs(B)
    dG = sum((eB.g[i] * fB[i] for i in range(n)), zero)
    if not dG > 0:
        raise NotProved(f"dg/dt is not proved > 0 on the crossing step (d e/dt in {dG.str(5)})")
    G_m = ev(mid.box)
    Ns = s_m - G_m / dG
    if not Sint.contains_interior(Ns):
        raise NotProved(f"the crossing time is not isolated in [t_a, t_a + 2 delta] (Newton image {Ns.str(5)})")
    from ..charts import g_angle_parts

    _, den = g_angle_parts(B[0:3], B[3:6])
    if not den > 0:
        raise NotProved("the crossing is not proved to be on g = 0 (rather than g = pi)")
    cross = lohner_step(rhs, S_a, Ns, order, jac=jac)
    if cross is None:
        raise NotProved("no validated step to the crossing")
    Xc = cross.box
    P = list(chart_r(Xc))
    tau = exact_arb(t_a) + Ns
    DP: List[List[Any]] = []
    if jac:
        assert cross.jac is not None and V_a is not None
        V = cross.jac * V_a
        Xd = [Dual(Xc[i], tuple(one if j == i else zero for j in range(n))) for i in range(n)]
        ec = ev(Xd)
        fc = rhs(Xc)
        de_f = sum((ec.g[i] * fc[i] for i in range(n)), zero)
        Pi = arb_mat([[(one if i == j else zero) - fc[i] * ec.g[j] / de_f for j in range(n)] for i in range(n)])
        rd = chart_r(Xd)
        Dch = arb_mat([[rd[a].g[j] for j in range(n)] for a in range(2)])
        D = Dch * Pi * V * Dx0
        DP = [[D[a, b] for b in range(2)] for a in range(2)]
    return SectionEnclosure(P, DP, tau, steps + 1)


def check_finite(xs: Sequence[Any]) -> None:
    if not all(x.is_finite() for x in xs):
        raise IntegrationError("non-finite enclosure")
