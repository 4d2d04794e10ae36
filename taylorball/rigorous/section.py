r"""Rigorous section maps and their C^1 enclosures: the dynamically symmetric ball's 2D map
(:func:`section_map`), the asymmetric ball's 3D map of ``(l, r1, r2)``
(:func:`section_map3`, the same steps with ``l`` a chart coordinate) and the M||gamma
system's map of the Andoyer--Deprit chart (:func:`mparallel_section_map`).

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

The variational matrix is carried by the C^1 Lohner algorithm
(:func:`taylorball.rigorous._taylor.c1_lohner_update`).

The map so defined is the local return map near the candidate's return time; a fixed point
of it is a periodic orbit of the reduced flow modulo the symmetry (a relative periodic orbit),
whatever happens between ``0`` and ``t_a``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, Callable, List, Sequence, Tuple

from ..charts import section_event_function
from ..errors import IntegrationError, UsageError
from ..model import REDUCED, get_system
from ._balls import Dual, arb, arb_mat, exact_arb, interval
from ._taylor import LohnerSet, c1_lohner_update, default_order, lohner_step
from .enclosure import ball_pars, ball_rhs, integrate_set

__all__ = ["SectionEnclosure", "section_map", "section_map3", "mparallel_section_map", "NotProved", "energy_residual",
           "level_start_states", "chart_lr", "quarter_turns"]


class NotProved(Exception):
    """A validated step did not close (an inclusion failed); the message says which."""


def _sqrt(x: Any) -> Any:
    return x.sqrt()


def chart_start_state(C: Any, Mg: Any, K: Any, r1: Any, r2: Any, l: Any = None) -> Tuple[Any, ...]:
    """Internal reduced state ``(M, gamma, R)`` on ``g = 0`` at the chart point ``(l, r1, r2)``
    (balls or duals): :func:`taylorball.charts.angles_to_vectors` and
    :func:`taylorball.charts.R_from_r`. ``l=None``: ``l = 0`` exactly (the symmetric ball's
    chart, where ``l`` is cyclic)."""
    k = K / C
    q = _sqrt(1 - k * k)
    mu = Mg / C
    s = _sqrt(1 - mu * mu)
    if l is None:
        zero = K * 0
        M = (zero, C * q, C * k)
        g2, g3 = mu * q + s * k, mu * k - s * q
        gamma = (zero, g2, g3)
        R = (r2 / g2, r1 / g2, -r1 / g3)  # R_from_r with gamma1 = 0
        return (*M, *gamma, *R)
    sl, cl = l.sin(), l.cos()
    a = mu * q + s * k  # |(gamma1, gamma2)| on g = 0
    g3 = mu * k - s * q
    M = (C * q * sl, C * q * cl, C * k)
    gamma = (a * sl, a * cl, g3)
    R = ((sl * r1 + cl * r2) / a, (cl * r1 - sl * r2) / a, -r1 / g3)  # R_from_r
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


def _unit(n: int, j: int) -> Tuple[Any, ...]:
    one, zero = exact_arb(1), exact_arb(0)
    return tuple(one if i == j else zero for i in range(n))


def _cross_section(rhs: Any, X0: Sequence[Any], tau_guess: float, *, prec: int, order: int, delta: float,
                   jac: bool, c1: str, refine: int = 0, S0: Any = None) -> Tuple[List[Any], Any, Any, Any, int]:
    r"""Flow the box ``X0`` (internal ``(M, gamma, ...)`` or ``(K, gamma)``: the event reads
    the first six components) to the section ``g = 0`` near ``tau_guess``.

    Returns the box of the crossing points, the variational set ``V`` (C^1 Lohner, or None),
    the projection-and-field data ``(Pi)`` as an interval matrix (or None), the crossing time
    (a ball) and the number of steps. Raises :class:`NotProved` when the crossing is not
    isolated, not on ``g = 0`` or not with ``g`` increasing. ``S0``: the start set (a
    :class:`LohnerSet` containing ``X0``'s states) in place of the box ``X0``."""
    t_a = Fraction(tau_guess) - Fraction(delta)
    S_a, V_a, steps, _ = integrate_set(rhs, LohnerSet.from_box(X0) if S0 is None else S0, t_a, prec=prec, order=order,
                                       tol=2.0 ** (-prec), jac=jac, c1=c1)
    Ns, _ = isolate_crossing(rhs, S_a, delta, order, refine=refine)
    cross = lohner_step(rhs, S_a, Ns, order, jac=jac)
    if cross is None:
        raise NotProved("no validated step to the crossing")
    Xc = cross.box
    tau = exact_arb(t_a) + Ns
    V = Pi = None
    if jac:
        assert cross.jac is not None and V_a is not None
        V = c1_lohner_update(V_a, cross, c1)
        Pi = section_projection(rhs, Xc)
    return Xc, V, Pi, tau, steps + 1


def _event(x: Sequence[Any]) -> Any:
    return section_event_function(x[0:3], x[3:6], 0.0)


def isolate_crossing(rhs: Any, S_a: Any, delta: float, order: int, refine: int = 0) -> Tuple[Any, Any]:
    r"""The crossing of ``g = 0`` after the set ``S_a``: interval Newton on
    ``G(s) = e(x(s))``, ``s`` in ``[0, 2 delta]`` (``e`` the section's event function). Returns
    the Newton image (a ball in ``[0, 2 delta]`` containing each state's unique crossing time)
    and ``dG/ds`` enclosed over the step's a priori box.

    ``refine``: at most this many further Newton steps from the midpoint of the current image
    ``N``, with ``dG/ds`` enclosed over the states at the times ``N`` (not over the a priori
    box of the whole window), kept while the radius at least halves: the root lies in each
    image by the mean value theorem. The crossing state's box is as wide as the crossing time's
    interval times the speed, so one step (its width ~ ``delta`` times the relative variation of
    ``dG/ds`` over the window) can dominate the section point's enclosure.

    Raises
    ------
    NotProved
        When ``dg/dt > 0`` is not proved, the crossing is not isolated, or it is not proved
        to be on ``g = 0`` (rather than ``g = pi``)."""
    from ..charts import g_angle_parts

    n = len(S_a.c)
    Sint = interval(0, 2 * delta)
    s_m = exact_arb(delta)
    full = lohner_step(rhs, S_a, exact_arb(2 * delta), order)
    mid = lohner_step(rhs, S_a, s_m, order)
    if full is None or mid is None:
        raise NotProved("no validated step across the section")
    B = full.B
    eB = _event([Dual(B[i], _unit(n, i)) for i in range(n)])
    fB = rhs(B)
    dG = sum((eB.g[i] * fB[i] for i in range(n)), exact_arb(0))
    if not dG > 0:
        raise NotProved(f"dg/dt is not proved > 0 on the crossing step (d e/dt in {dG.str(5)})")
    Ns = s_m - _event(mid.box) / dG
    if not Sint.contains_interior(Ns):
        raise NotProved(f"the crossing time is not isolated in [t_a, t_a + 2 delta] (Newton image {Ns.str(5)})")
    _, den = g_angle_parts(B[0:3], B[3:6])
    if not den > 0:
        raise NotProved("the crossing is not proved to be on g = 0 (rather than g = pi)")
    for _ in range(refine):
        over = lohner_step(rhs, S_a, Ns, order)  # the states at every time of Ns
        s2 = exact_arb(Ns.mid())
        at = lohner_step(rhs, S_a, s2, order)
        if over is None or at is None:
            break
        Xo = over.box
        eo = _event([Dual(Xo[i], _unit(n, i)) for i in range(n)])
        fo = rhs(Xo)
        dG2 = sum((eo.g[i] * fo[i] for i in range(n)), exact_arb(0))
        if not dG2 > 0:
            break
        N2 = s2 - _event(at.box) / dG2
        if not float(N2.rad()) <= 0.5 * float(Ns.rad()):
            break
        Ns = N2
    return Ns, dG


def section_projection(rhs: Any, Xc: Sequence[Any]) -> Any:
    r"""``I - f \nabla e^T / (\nabla e, f)`` enclosed over the crossing states ``Xc``."""
    n = len(Xc)
    one, zero = exact_arb(1), exact_arb(0)
    ec = _event([Dual(Xc[i], _unit(n, i)) for i in range(n)])
    fc = rhs(Xc)
    de_f = sum((ec.g[i] * fc[i] for i in range(n)), zero)
    return arb_mat([[(one if i == j else zero) - fc[i] * ec.g[j] / de_f for j in range(n)] for i in range(n)])


def _section_jacobian(chart: Any, Xc: Sequence[Any], V: Any, Pi: Any, Dx0: Any) -> List[List[Any]]:
    """``Dchart (I - f grad(e)^T/(grad(e), f)) Dphi Dx0`` with ``Dphi`` in Lohner form (as
    many rows as the chart has coordinates, columns as ``Dx0``)."""
    n = len(Xc)
    rd = chart([Dual(Xc[i], _unit(n, i)) for i in range(n)])
    Dch = arb_mat([[rd[a].g[j] for j in range(n)] for a in range(len(rd))])
    D = V.left(Dch * Pi) * Dx0
    return [[D[a, b] for b in range(Dx0.ncols())] for a in range(len(rd))]


def _newton_root(F: Any, guess: float, widths: Sequence[float], what: str, refine: int = 0) -> Any:
    """Interval Newton for a scalar root: ``F(x, grad)`` evaluates the function on a ball or a
    dual. Returns the Newton image (a ball proved to contain the unique root in the box).

    ``refine``: at most this many further Newton steps, each from the midpoint of the current
    image ``N`` over ``N`` itself (the root ``r`` in ``N`` lies in ``m - F(m)/F'(N)`` by the mean
    value theorem), kept while the radius at least halves. The first image is as wide as
    ``|F(guess)|`` times the relative width of ``F'`` over the first box (on the Fig. 3 level
    near ``K = -C``, a float64 guess 2e-8 off the root gave a radius 3e-13 at 53 bits and 5e-15
    at 128 bits, and the start states ~100 times that); refined, it is down to the rounding."""
    m = exact_arb(guess)
    F_m = F(m)
    NK = None
    for w in widths:  # the root moves with the chart point over its box: widen if needed
        Kb = m + arb(0, w)
        Fd = F(Dual(Kb, (exact_arb(1),)))
        NK = m - F_m / Fd.g[0]
        if Kb.contains_interior(NK):
            for _ in range(refine):
                m2 = exact_arb(NK.mid())
                N2 = m2 - F(m2) / F(Dual(NK, (exact_arb(1),))).g[0]
                if not float(N2.rad()) <= 0.5 * float(NK.rad()):
                    break
                NK = N2
            return NK
    raise NotProved(f"the energy equation's root {what} is not isolated in [{guess!r} +- {widths[-1]:g}] "
                    f"(Newton image {NK.str(5) if NK is not None else '?'})")


def energy_residual(c: Any, C: Any, Mg: Any, h: Any, r1: Any, r2: Any) -> Callable[[Any], Any]:
    """``K -> E(x(K, r1, r2)) - h``: the energy equation for ``K = M3`` at the chart point
    ``(r1, r2)`` (balls) on the level ``|M| = C``, ``(M, gamma) = Mg``; ``K`` a ball, or a
    :class:`Dual` (then ``r1, r2`` are constants), as :func:`_newton_root` needs."""
    return _level_residual(lambda x: _energy(c, x), h, lambda K, r1, r2: chart_start_state(C, Mg, K, r1, r2),
                           (r1, r2))


def _level_residual(energy: Callable[[Any], Any], h: Any, start: Callable[..., Tuple[Any, ...]],
                    pbox: Sequence[Any]) -> Callable[[Any], Any]:
    """``K -> E(start(K, *pbox)) - h`` for a ball or a :class:`Dual` ``K`` (then the chart
    values are constants of the dual)."""
    zero = exact_arb(0)

    def F(K: Any) -> Any:
        if isinstance(K, Dual):
            return energy(start(K, *(Dual(p, (zero,)) for p in pbox))) - h
        return energy(start(K, *pbox)) - h

    return F


def level_start_states(energy: Callable[[Any], Any], h: Any, start: Callable[..., Tuple[Any, ...]],
                       pbox: Sequence[Any], K_guess: float, dK: float, newton_refine: int = 0,
                       what: str = "K") -> Tuple[Any, Tuple[Any, ...], List[Any], Any]:
    r"""The start states over the chart box ``pbox`` on the energy level ``energy = h``: the
    root ``K`` (``M3``; ``G = |K|`` for M||gamma) of the energy equation by the interval
    Newton operator (unique in ``K_guess +- dK``, widened up to ``1e4 dK``),
    ``dK/dp = -E_p / E_K`` and the states ``start(K, *p)`` as duals in ``p``. Returns
    ``(K, x0 as duals, x0 as balls, D x0)`` (``D x0`` an interval matrix, one column per chart
    coordinate)."""
    n = len(pbox)
    one, zero = exact_arb(1), exact_arb(0)

    def e(j: int, m: int) -> Tuple[Any, ...]:
        return tuple(one if i == j else zero for i in range(m))

    NK = _newton_root(_level_residual(energy, h, start, pbox), K_guess, (dK, dK * 1e2, dK * 1e4), what,
                      refine=newton_refine)
    Fg = energy(start(Dual(NK, e(n, n + 1)), *(Dual(p, e(j, n + 1)) for j, p in enumerate(pbox)))) - h
    dKdp = tuple(-Fg.g[j] / Fg.g[n] for j in range(n))
    x0d = start(Dual(NK, dKdp), *(Dual(p, e(j, n)) for j, p in enumerate(pbox)))
    X0 = [x.v for x in x0d]
    if not all(x.is_finite() for x in X0):
        raise NotProved("the start states are not finite: the chart is singular on the box (gamma3 or "
                        "|(gamma1, gamma2)| not proved nonzero, or |K| = C)")
    return NK, x0d, X0, arb_mat([[x.g[j] for j in range(n)] for x in x0d])


def section_map(params: Any, levels: Any, pbox: Sequence[Any], K_guess: float, tau_guess: float, *,
                prec: int = 128, order: int | None = None, delta: float = 1e-3, dK: float = 1e-6,
                jac: bool = True, c1: str = "lohner", newton_refine: int = 8,
                crossing_refine: int = 4, start: str = "box") -> SectionEnclosure:
    """Enclose the symmetric 2D section map and (``jac=True``) its Jacobian on ``pbox``
    (two arbs ``r1, r2``), near the float candidate's root ``K_guess`` and return time
    ``tau_guess``. Must run inside :class:`~taylorball.rigorous._balls.working_precision`.
    ``c1``: how the flow's Jacobian is carried (``"lohner"``, the C^1 Lohner algorithm, or
    ``"product"``, the plain product of the steps' interval Jacobians, for comparison).
    ``newton_refine``: further interval Newton steps on the energy root ``K`` once it is
    isolated (0: the single step of the former code; a wide root widens every start state);
    ``crossing_refine``: the same for the crossing time (:func:`isolate_crossing`).
    ``start``: the start states as a box of the 9 internal variables (``"box"``, the former
    code) or as a doubleton set ``x0(c) + P q + r`` (``"doubleton"``: ``c`` the box's centre,
    ``P = mid [D x0]``, ``q`` the chart box minus ``c``, ``r`` the rest of the mean value form;
    the chart box's two parameters are carried by ``P`` and never wrapped into 9 dimensions:
    on the Tzenoff saddle's box of radius 1e-13 the set's hull after one time unit is 1.4e-12
    against 1.1e-10 from the box, docs/rigorous.md).

    Raises
    ------
    NotProved
        When an inclusion of an interval Newton operator fails (no uniqueness proved), or the
        crossing is not on ``g = 0`` with ``g`` increasing.
    """
    if start not in ("box", "doubleton"):
        raise UsageError(f"start must be 'box' or 'doubleton', got {start!r}")
    order = default_order(prec) if order is None else order
    pars = ball_pars("reduced", params)
    system = get_system("reduced")
    c = system.constants(pars)
    rhs = ball_rhs("reduced", pars)
    C, Mg, h = (exact_arb(v) for v in (levels.C, levels.M_gamma, levels.h))
    energy = lambda x: _energy(c, x)  # noqa: E731
    start_at = lambda K, r1, r2: chart_start_state(C, Mg, K, r1, r2)  # noqa: E731
    NK, x0d, X0, Dx0 = level_start_states(energy, h, start_at, pbox, K_guess, dK, newton_refine)
    S0 = _doubleton_start(energy, h, start_at, pbox, K_guess, dK, newton_refine, x0d) if start == "doubleton" else None
    # 2.-3. the flow to the section, the crossing time
    Xc, V, Pi, tau, steps = _cross_section(rhs, X0, tau_guess, prec=prec, order=order, delta=delta, jac=jac, c1=c1,
                                           refine=crossing_refine, S0=S0)
    P = list(chart_r(Xc))
    DP = _section_jacobian(chart_r, Xc, V, Pi, Dx0) if jac else []
    return SectionEnclosure(P, DP, tau, steps)


def _doubleton_start(energy: Callable[[Any], Any], h: Any, start: Callable[..., Tuple[Any, ...]],
                     pbox: Sequence[Any], K_guess: float, dK: float, newton_refine: int,
                     x0d: Sequence[Any]) -> LohnerSet:
    r"""The start states over the chart box ``pbox`` as ``x0(p_c) + P q + r``: by the mean
    value theorem ``x0(p) \in x0(p_c) + [D x0](pbox) (p - p_c)``; ``P = mid [D x0]`` (exact),
    ``q = pbox - p_c`` and ``r = (x0(p_c) - mid) + ([D x0] - P) q`` (``x0d``: the start states
    over ``pbox`` as duals in the chart coordinates, :func:`level_start_states`)."""
    pc = [exact_arb(x.mid()) for x in pbox]
    NKc = _newton_root(_level_residual(energy, h, start, pc), K_guess, (dK, dK * 1e2, dK * 1e4), "K at the centre",
                       refine=newton_refine)
    xc = start(NKc, *pc)
    n, m = len(xc), len(pbox)
    cc = [exact_arb(x.mid()) for x in xc]
    P = arb_mat([[exact_arb(x0d[i].g[j].mid()) for j in range(m)] for i in range(n)])
    q = [b - p for b, p in zip(pbox, pc)]
    r = []
    for i in range(n):
        ri = xc[i] - cc[i]
        for j in range(m):
            ri = ri + (x0d[i].g[j] - P[i, j]) * q[j]
        r.append(ri)
    return LohnerSet(cc, _eye(n), r, P, q)


# ---------------------------------------------------------------------------------------
# The M||gamma system (paper section 5): the map of the Andoyer--Deprit chart (l, L/G).
# ---------------------------------------------------------------------------------------
def mparallel_start_state(lam: Any, G: Any, l: Any, rho: Any) -> Tuple[Any, ...]:
    """``(K, gamma)`` on ``g = 0`` from ``G = |K|``, ``l`` and ``rho = L/G`` (balls or duals):
    :func:`taylorball.charts.angles_to_vectors` at ``g = 0``."""
    q = _sqrt(1 - rho * rho)
    mu = lam / G
    s = _sqrt(1 - mu * mu)
    sl, cl = l.sin(), l.cos()
    K = (G * q * sl, G * q * cl, G * rho)
    a = mu * q + s * rho
    gamma = (a * sl, a * cl, mu * rho - s * q)
    return (*K, *gamma)


#: The branches of ``l'``: ``l_branch -> k`` with ``l_branch = k pi/2``.
L_BRANCHES = {0.0: 0, math.pi / 2: 1, math.pi: 2, 3 * math.pi / 2: 3}


def _branch_uv(K: Sequence[Any], k: int) -> Tuple[Any, Any]:
    """``(u, v)`` with ``l = k pi/2 + atan(u/v)`` where ``v > 0``: ``(K1, K2)`` turned by
    ``-k pi/2``."""
    return ((K[0], K[1]), (-K[1], K[0]), (-K[0], -K[1]), (K[1], -K[0]))[k]


def mparallel_chart_lr(x: Sequence[Any], l_branch: float = 0.0) -> Tuple[Any, Any]:
    """``(l, L/G)`` of ``(K, gamma)``: ``l = l_branch + atan(u/v)`` with ``(u, v)`` the pair
    ``(K1, K2)`` turned by ``-l_branch`` (valid where ``v > 0``: the caller proves it),
    ``L/G = K3/|K|``; ``l_branch`` one of :data:`L_BRANCHES`."""
    K = x[0:3]
    G = _sqrt(K[0] * K[0] + K[1] * K[1] + K[2] * K[2])
    u, v = _branch_uv(K, L_BRANCHES[l_branch])
    return (u / v).atan() + l_branch, K[2] / G


def _mparallel_energy(c: Any, x: Sequence[Any]) -> Any:
    system = get_system("mparallel")
    return system.info.integrals(c, system.vectors(c, tuple(x)))["E"]


def mparallel_section_map(params: Any, levels: Any, pbox: Sequence[Any], G_guess: float, tau_guess: float, *,
                          prec: int = 128, order: int | None = None, delta: float = 1e-3, dG: float = 1e-6,
                          l_branch: float = 0.0, jac: bool = True, c1: str = "lohner") -> SectionEnclosure:
    r"""Enclose the M||gamma section map ``(l, L/G) -> (l', L'/G')`` (paper section 5,
    section ``g = 0`` with ``g`` increasing) and (``jac=True``) its Jacobian on ``pbox``
    (two arbs), on the level ``lambda = levels.lam``, ``Etilde = levels.h``, near the float
    candidate's ``G = |K|`` root ``G_guess`` and return time ``tau_guess``. ``l'`` is taken on
    the branch ``l_branch + (-pi/2, pi/2)`` (``l_branch`` a multiple of ``pi/2`` in
    ``[0, 2 pi)``, a key of :data:`L_BRANCHES`; proved, else NotProved). Must run
    inside :class:`~taylorball.rigorous._balls.working_precision`.

    Steps: ``G`` by the interval Newton operator on the energy equation (unique in
    ``G_guess +- dG``), ``dG/dp = -E_p / E_G``; ``(K, gamma)`` from the inverse chart; the
    flow, the crossing and ``DP`` as in :func:`section_map`.

    Raises
    ------
    NotProved
        When an inclusion fails (the message says which).
    """
    order = default_order(prec) if order is None else order
    if l_branch not in L_BRANCHES:
        raise UsageError(f"l_branch must be one of 0, pi/2, pi, 3 pi/2 (math.pi multiples), got {l_branch!r}")
    pars = ball_pars("mparallel", params)
    system = get_system("mparallel")
    c = system.constants(pars)
    rhs = ball_rhs("mparallel", pars)
    lam, h = exact_arb(levels.lam), exact_arb(levels.h)
    _, _, X0, Dx0 = level_start_states(lambda x: _mparallel_energy(c, x), h,
                                       lambda G, l, rho: mparallel_start_state(lam, G, l, rho), pbox, G_guess, dG,
                                       what="G")
    Xc, V, Pi, tau, steps = _cross_section(rhs, X0, tau_guess, prec=prec, order=order, delta=delta, jac=jac, c1=c1)
    kq = L_BRANCHES[l_branch]
    u, v = _branch_uv(Xc[0:3], kq)
    if not v > 0:
        raise NotProved(f"the return point's l is not proved to lie in {l_branch!r} + (-pi/2, pi/2) "
                        f"(the turned K component in {v.str(5)})")
    chart = lambda x: mparallel_chart_lr(x, l_branch)  # noqa: E731
    pb = arb.pi() * kq / 2
    P = [(u / v).atan() + pb, Xc[2] / _sqrt(Xc[0] * Xc[0] + Xc[1] * Xc[1] + Xc[2] * Xc[2])]
    DP = _section_jacobian(chart, Xc, V, Pi, Dx0) if jac else []
    return SectionEnclosure(P, DP, tau, steps)


def check_finite(xs: Sequence[Any]) -> None:
    if not all(x.is_finite() for x in xs):
        raise IntegrationError("non-finite enclosure")


# ---------------------------------------------------------------------------------------
# The asymmetric ball: the 3D map of the chart (l, r1, r2).
# ---------------------------------------------------------------------------------------
def chart_lr(x: Sequence[Any], l_turns: int = 0) -> Tuple[Any, Any, Any]:
    r"""``(l, r1, r2)`` of an internal reduced state, ``l = atan2(M1, M2)`` taken as
    ``l_turns pi/2 + atan(u/v)`` with ``(u, v)`` the pair ``(M1, M2)`` turned by
    ``-l_turns pi/2`` (valid where ``v > 0``: the caller proves it); any integer ``l_turns``
    (``4`` gives ``l`` near ``2 pi``)."""
    u, v = _branch_uv(x[0:3], l_turns % 4)
    r1, r2 = chart_r(x)
    return (u / v).atan() + arb.pi() * l_turns / 2, r1, r2


def quarter_turns(l: float) -> int:
    """The integer ``k`` with ``k pi/2`` nearest ``l``: the branch of :func:`chart_lr` for a
    value of ``l`` near ``l``."""
    return int(round(float(l) / (math.pi / 2)))


def section_map3(params: Any, levels: Any, pbox: Sequence[Any], K_guess: float, tau_guess: float, *,
                 l_turns: int, prec: int = 128, order: int | None = None, delta: float = 1e-3, dK: float = 1e-6,
                 jac: bool = True, c1: str = "lohner", newton_refine: int = 8,
                 crossing_refine: int = 4, start: str = "doubleton") -> SectionEnclosure:
    r"""Enclose the asymmetric ball's 3D section map ``(l, r1, r2) -> (l', r1', r2')`` of the
    section ``g = 0`` (``g`` increasing) on a level ``|M| = C``, ``(M, gamma) = M_gamma``,
    ``E = h``, and (``jac=True``) its 3 x 3 Jacobian, on the box ``pbox`` (three arbs), near
    the float candidate's energy root ``K_guess`` (``M3``) and return time ``tau_guess``.
    ``l'`` is taken near ``l_turns pi/2`` (:func:`chart_lr`; the branch is proved, else
    NotProved). Must run inside :class:`~taylorball.rigorous._balls.working_precision`.

    The chart is the float64 code's (:func:`taylorball.sections.chart_points`,
    :func:`taylorball.charts.reduced_state_from_chart` at ``g = 0``); the steps are those of
    :func:`section_map` (the energy root, the flow with the C^1 Lohner algorithm, the
    crossing proved unique in ``[tau_guess - delta, tau_guess + delta]`` and on ``g = 0``
    with ``g`` increasing), with ``l`` a third chart coordinate instead of ``0``.

    Raises
    ------
    NotProved
        When an inclusion fails (the message says which): no unique energy root near
        ``K_guess`` (e.g. a box off the level), no unique crossing in the time window,
        ``l'`` not on its branch.
    """
    if start not in ("box", "doubleton"):
        raise UsageError(f"start must be 'box' or 'doubleton', got {start!r}")
    if isinstance(l_turns, bool) or not isinstance(l_turns, int):
        raise UsageError(f"l_turns must be an integer (l' near l_turns pi/2), got {l_turns!r}")
    if len(pbox) != 3:
        raise UsageError(f"pbox must be three balls (l, r1, r2), got {len(pbox)}")
    order = default_order(prec) if order is None else order
    pars = ball_pars("reduced", params)
    c = get_system("reduced").constants(pars)
    rhs = ball_rhs("reduced", pars)
    C, Mg, h = (exact_arb(v) for v in (levels.C, levels.M_gamma, levels.h))
    energy = lambda x: _energy(c, x)  # noqa: E731
    start_at = lambda K, l, r1, r2: chart_start_state(C, Mg, K, r1, r2, l)  # noqa: E731
    _, x0d, X0, Dx0 = level_start_states(energy, h, start_at, pbox, K_guess, dK, newton_refine)
    S0 = _doubleton_start(energy, h, start_at, pbox, K_guess, dK, newton_refine, x0d) if start == "doubleton" else None
    Xc, V, Pi, tau, steps = _cross_section(rhs, X0, tau_guess, prec=prec, order=order, delta=delta, jac=jac, c1=c1,
                                           refine=crossing_refine, S0=S0)
    u, v = _branch_uv(Xc[0:3], l_turns % 4)
    if not v > 0:
        raise NotProved(f"the return point's l is not proved to lie in {l_turns} pi/2 + (-pi/2, pi/2) "
                        f"(the turned M component in {v.str(5)})")
    chart = lambda x: chart_lr(x, l_turns)  # noqa: E731
    P = list(chart(Xc))
    DP = _section_jacobian(chart, Xc, V, Pi, Dx0) if jac else []
    return SectionEnclosure(P, DP, tau, steps)
