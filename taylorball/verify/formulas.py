r"""Checks of the paper's formulas: equations of motion, conservation laws, symmetry fields,
paper eq. (17) [eq11], section 5 and the densities (see :mod:`taylorball.verify`).

Method
------
Every formula of the paper is transcribed *from the paper* (functions ``paper_*`` of
:mod:`taylorball.verify.transcribed`), independently of :mod:`taylorball.model`, and the
equations of motion are also *derived* from the Newton--Euler equations (paper eq. (6) [eq2])
and the no-slip constraint (eq. (1) [eq1])
(:func:`~taylorball.verify.transcribed.newton_euler_full_field`). Claims are then checked
in one of two exact ways:

* **symbolically** with sympy, where the identity is polynomial and needs no constraint
  (paper eq. (17) [eq11], the tensor ``Itilde`` of sec. 3, the kinematic sign convention);
* **in exact rational arithmetic** (:class:`fractions.Fraction`) at random *rational*
  points of the constraint manifold. Rational points of the sphere come from the
  stereographic parametrisation and rational rotations from unnormalised integer
  quaternions, so ``|gamma| = 1``, ``Q in SO(3)``, ``(R, gamma) = 0`` hold exactly.
  Derivatives (Lie derivatives, Lie brackets, divergences) are exact too: forward-mode
  dual numbers over ``Fraction`` (:class:`~taylorball.verify.exact.Dual`; the exact tools
  are in :mod:`taylorball.verify.exact`). Every quantity checked is a rational
  function of the point, so a residual of exactly ``0`` at several random points is a
  proof up to the (Schwartz--Zippel) probability that a nonzero rational function
  vanishes at all of them by chance; a wrong formula shows an O(1) relative residual.

Densities involve square roots; ``div(rho X) = 0`` is checked in the equivalent rational
form ``div X + X . grad(rho^2) / (2 rho^2) = 0``.

Residuals reported are relative: ``max |lhs - rhs| / max(|lhs|, |rhs|, sum of term sizes)``
over the points, as a float. Exact identities give ``0.0`` and are held to tolerance 0.
"""

from __future__ import annotations

import random
from fractions import Fraction
from typing import Callable

from .._vec import add, cross, dot, scale, sub
from . import CheckResult
from .exact import (
    Dual,
    _flat,
    _rel,
    _rq,
    _split_full,
    det3,
    directional_derivative,
    divergence,
    lie_bracket,
    random_full_states,
    random_mparallel_states,
    random_reduced_states,
    rational_frame,
    rational_unit_vector,
    solve3,
)
from .transcribed import (
    _v_constraint,
    mparallel_pars,
    newton_euler_full_field,
    paper_E_full,
    paper_E_reduced,
    paper_E_tilde,
    paper_full_field,
    paper_itilde,
    paper_M,
    paper_mparallel_field,
    paper_R_dot,
    paper_reduced_field,
    paper_sved,
)

# the exact-arithmetic tools imported above (Dual, random states, ...) are listed where they
# live, in taylorball.verify.exact
__all__ = [
    "paper_full_field",
    "paper_reduced_field",
    "paper_mparallel_field",
    "newton_euler_full_field",
    "paper_M",
    "CHECKS",
]

# Parameter sets (I1, I2, I3, m, a, Omega) as exact rationals: the paper's Fig. 5 ball,
# the Fig. 3 symmetric ball, the Fig. 2 homogeneous ball, and a generic one.
F = Fraction
FIG5 = (F(2), F(3), F(4), F(1), F(5), F(2))
SYMMETRIC = (F(2), F(2), F(3), F(1), F(5), F(2))
HOMOGENEOUS = (F(3), F(3), F(3), F(1), F(5), F(2))
GENERIC = (F(7, 3), F(5, 2), F(11, 4), F(3, 2), F(9, 5), F(-4, 3))


# ---------------------------------------------------------------------------------------
# Helpers for the checks.
# ---------------------------------------------------------------------------------------
def _compare(a_vals, b_vals):
    a_vals, b_vals = _flat(a_vals), _flat(b_vals)
    diffs = [u - v for u, v in zip(a_vals, b_vals)]
    size = max(max(abs(u) for u in a_vals), max(abs(v) for v in b_vals))
    return _rel(diffs, size)


def _result(claim, ref, residual, detail, tol=0.0):
    return CheckResult(claim=claim, reference=ref, verdict="verified" if residual <= tol else "failed",
                       residual=residual, tolerance=tol, detail=detail)


def _npts(full):
    return 12 if full else 4


_EXACT = "exact rational arithmetic at {n} random rational points of the manifold, params {p}"
_PARAM_SETS = {"FIG5": FIG5, "GENERIC": GENERIC}


def _each(full, gen, fn, param_sets=_PARAM_SETS):
    """Max residual of ``fn(p, state)`` over parameter sets and random states."""
    worst = 0.0
    n = _npts(full)
    for p in param_sets.values():
        for s in gen(n):
            worst = max(worst, fn(p, s))
    return worst, _EXACT.format(n=n, p="/".join(param_sets))


def _to_reduced(s):
    w, al, be, g, x, y = _split_full(s)
    return (*w, *g, *add(scale(x, al), scale(y, be)))


# ---------------------------------------------------------------------------------------
# A1: equations of motion and conservation laws.
# ---------------------------------------------------------------------------------------
def check_kinematic_convention(full=False):
    """Kinematics: a fixed axis has body coordinates e' = e x omega (sympy)."""
    import sympy as sp

    w = sp.Matrix(sp.symbols("w1:4"))
    e = sp.Matrix(sp.symbols("e1:4"))
    t = sp.symbols("t")
    W = sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])  # [w]_x
    # body axes in space: B(t) = exp(t [omega]_x) for constant omega; its derivative at t = 0
    # only needs the first-order terms
    B = sp.eye(3) + t * W
    body = B.T * e  # body coordinates of the fixed vector e
    res = sp.simplify(body.diff(t).subs(t, 0) - e.cross(w))
    r = 0.0 if res == sp.zeros(3, 1) else 1.0
    return _result("kinematics alpha' = alpha x omega (fixed axes seen from the body)", "eq. (2) [eq4]", r,
                   "sympy: body coordinates B(t)^T e of a fixed vector, B' = B [omega]_x; d/dt at t=0 is e x omega")


def check_eom_newton_euler(full=False):
    """Paper eqs. (8)-(10) [eq6] follow from Newton-Euler (eq. (6) [eq2]) with the constraint
    (eq. (1) [eq1])."""
    def fn(p, s):
        return _compare(newton_euler_full_field(p, s), paper_full_field(p, s))

    r, how = _each(full, random_full_states, fn)
    return _result("eqs. (8)-(10) [eq6] (omega', x', y', alpha', ...) = Newton-Euler eq. (6) [eq2] "
                   "+ constraint eq. (1) [eq1] with N, v eliminated",
                   "eqs. (1) [eq1], (2) [eq4], (6) [eq2], (8)-(10) [eq6]", r,
                   how + "; derivation: newton_euler_full_field")


def check_v_dot_eq5(full=False):
    """Paper eq. (7) [eq5]: v' = (a omega' - Omega R') x gamma + (a omega - Omega R) x (gamma x omega)."""
    def fn(p, s):
        X = newton_euler_full_field(p, s)
        w, al, be, g, x, y = _split_full(s)

        def v_of(z):
            w_, al_, be_, g_, x_, y_ = _split_full(z)
            return _v_constraint(p, w_, g_, add(scale(x_, al_), scale(y_, be_)))

        vd, _ = directional_derivative(v_of, s, X)
        a, Om = p[4], p[5]
        R = add(scale(x, al), scale(y, be))
        Rd, _ = directional_derivative(lambda z: add(scale(z[12], z[3:6]), scale(z[13], z[6:9])), s, X)
        printed = add(cross(sub(scale(a, X[0:3]), scale(Om, tuple(Rd))), g),
                      cross(sub(scale(a, w), scale(Om, R)), cross(g, w)))
        v5 = cross(sub(scale(a, w), scale(Om, R)), g)
        return max(_compare(vd, printed), _compare(v5, _v_constraint(p, w, g, R)))

    r, how = _each(full, random_full_states, fn)
    return _result("eq. (7) [eq5]: v = (a omega - Omega R) x gamma and its derivative", "eq. (7) [eq5]", r,
                   how)


def check_model_full_omega(full=False):
    """taylorball.model.full_rhs_omega equals paper eqs. (8)-(10) [eq6]."""
    from ..model import ball_constants, full_rhs_omega

    def fn(p, s):
        return _compare(full_rhs_omega(ball_constants(p), *_split_full(s)), paper_full_field(p, s))

    r, how = _each(full, random_full_states, fn)
    return _result("taylorball full_rhs_omega = eqs. (8)-(10) [eq6]", "eqs. (8)-(10) [eq6]", r,
                   how + "; model code evaluated on Fractions")


def check_model_full_momentum(full=False):
    """taylorball's momentum form of the full system is paper eqs. (8)-(10) [eq6] in the variables M."""
    from ..model import ball_constants, full_rhs

    def fn(p, s):
        w, al, be, g, x, y = _split_full(s)
        X = paper_full_field(p, s)
        M_of = lambda z: paper_M(p, tuple(z[0:3]), tuple(z[9:12]), add(scale(z[12], z[3:6]), scale(z[13], z[6:9])))  # noqa: E731
        Md, M = directional_derivative(M_of, s, X)
        model = full_rhs(ball_constants(p), tuple(M), al, be, g, x, y)
        return _compare(model, (*Md, *X[3:]))

    r, how = _each(full, random_full_states, fn)
    return _result("taylorball full_rhs (M form) = eqs. (8)-(10) [eq6] pushed forward by omega -> M "
                   "(eq. (11) [eq13])", "eqs. (8)-(10) [eq6], (11) [eq13]", r, how)


def check_M_dot(full=False):
    """Section 2: M' = M x omega along paper eqs. (8)-(10) [eq6]."""
    def fn(p, s):
        X = paper_full_field(p, s)
        M_of = lambda z: paper_M(p, tuple(z[0:3]), tuple(z[9:12]), add(scale(z[12], z[3:6]), scale(z[13], z[6:9])))  # noqa: E731
        Md, M = directional_derivative(M_of, s, X)
        return _compare(Md, cross(tuple(M), tuple(s[0:3])))

    r, how = _each(full, random_full_states, fn)
    return _result("M' = M x omega along eqs. (8)-(10) [eq6]", "sec. 2", r, how)


def check_L_star_and_M(full=False):
    """Section 2: L* (v eliminated from L) as printed, and M = dL*/domega is paper eq. (11) [eq13]."""
    def L_sub(p, z):  # L = m v^2/2 + (omega, I omega)/2 with v from the constraint
        w_, al_, be_, g_, x_, y_ = _split_full(z)
        v = _v_constraint(p, w_, g_, add(scale(x_, al_), scale(y_, be_)))
        return p[3] * dot(v, v) / 2 + sum(p[k] * w_[k] * w_[k] for k in range(3)) / 2

    def L_printed(p, z):
        w_, al_, be_, g_, x_, y_ = _split_full(z)
        m, a, Om = p[3], p[4], p[5]
        R = add(scale(x_, al_), scale(y_, be_))
        wg = cross(w_, g_)
        return (sum(p[k] * w_[k] * w_[k] for k in range(3)) / 2 + m * a * a * dot(wg, wg) / 2
                - m * a * Om * dot(w_, R) + m * Om * Om * (x_ * x_ + y_ * y_) / 2)

    def fn(p, s):
        r1 = _compare([L_sub(p, s)], [L_printed(p, s)])
        grad = []
        for j in range(3):
            e = [0] * 14
            e[j] = 1
            dj, _ = directional_derivative(lambda z: [L_printed(p, z)], s, e)
            grad.append(dj[0])
        w, al, be, g, x, y = _split_full(s)
        r2 = _compare(grad, paper_M(p, w, g, add(scale(x, al), scale(y, be))))
        return max(r1, r2)

    r, how = _each(full, random_full_states, fn)
    return _result("L* as printed = L on the constraint; M (eq. (11) [eq13]) = dL*/domega",
                   "sec. 2, eq. (11) [eq13]", r, how)


def check_itilde(full=False):
    """Paper sec. 3, Itilde = I + m a^2 (gamma^2 E - gamma (x) gamma) (the left-hand side of
    paper eq. (15) [eq10]) is the operator of paper eq. (8) [eq6]."""
    import sympy as sp

    I = sp.symbols("I1:4")
    d = sp.symbols("d")
    w = sp.Matrix(sp.symbols("W1:4"))
    g = sp.Matrix(sp.symbols("g1:4"))
    lhs = sp.Matrix([I[k] * w[k] for k in range(3)]) + d * g.cross(w.cross(g))
    It = sp.diag(*I) + d * ((g.T * g)[0] * sp.eye(3) - g * g.T)
    res = sp.expand(lhs - It * w)
    r = 0.0 if res == sp.zeros(3, 1) else 1.0
    return _result("Itilde (sec. 3, eq. (15) [eq10]) = operator W -> I W + m a^2 gamma x (W x gamma) "
                   "of eq. (8) [eq6]",
                   "eqs. (8) [eq6], (15) [eq10]", r,
                   "sympy, polynomial identity for all gamma (no constraint used)")


def check_R_dot(full=False):
    """Paper eq. (16) [eq10]: R' = R x (omega - Omega gamma) - a gamma x omega follows from
    R = x alpha + y beta."""
    def fn(p, s):
        X = paper_full_field(p, s)
        Rd, R = directional_derivative(lambda z: add(scale(z[12], z[3:6]), scale(z[13], z[6:9])), s, X)
        return _compare(Rd, paper_R_dot(p, tuple(s[0:3]), tuple(s[9:12]), tuple(R)))

    r, how = _each(full, random_full_states, fn)
    return _result("R' of eq. (16) [eq10] = d/dt (x alpha + y beta) along eqs. (8)-(10) [eq6]",
                   "eqs. (8)-(10) [eq6], (16) [eq10]",
                   r, how)


def check_reduced_is_full(full=False):
    """Paper eqs. (15)-(16) [eq10] are eqs. (8)-(10) [eq6] in (omega, gamma, R)."""
    def fn(p, s):
        X = paper_full_field(p, s)
        Y = paper_reduced_field(p, _to_reduced(s))
        return _compare(X[0:3], Y[0:3])

    r, how = _each(full, random_full_states, fn)
    return _result("omega' of eq. (15) [eq10] = omega' of eq. (8) [eq6] at R = x alpha + y beta",
                   "eqs. (8) [eq6], (15) [eq10]",
                   r, how)


def check_model_reduced(full=False):
    """taylorball reduced_rhs_omega / reduced_rhs equal paper eqs. (15)-(16) [eq10]."""
    from ..model import K_from_omega, ball_constants, reduced_rhs, reduced_rhs_omega

    def fn(p, s):
        s = list(s)
        c = ball_constants(p)
        w, g, R = tuple(s[0:3]), tuple(s[3:6]), tuple(s[6:9])
        Y = paper_reduced_field(p, s)
        r1 = _compare(reduced_rhs_omega(c, w, g, R), Y)
        M_of = lambda z: paper_M(p, tuple(z[0:3]), tuple(z[3:6]), tuple(z[6:9]))  # noqa: E731
        Md, M = directional_derivative(M_of, s, Y)
        r2 = _compare(reduced_rhs(c, tuple(M), g, R), (*Md, *Y[3:]))
        K = K_from_omega(c.I, c.d, g, w)
        r3 = _compare(K, add(tuple(M), scale(p[3] * p[4] * p[5], R)))
        return max(r1, r2, r3)

    r, how = _each(full, random_reduced_states, fn)
    return _result("taylorball reduced_rhs_omega, reduced_rhs (M form), K_from_omega = "
                   "eqs. (15)-(16) [eq10] / eq. (11) [eq13]",
                   "eqs. (11) [eq13], (15)-(16) [eq10]",
                   r, how)


def check_energy(full=False):
    """Paper eq. (13) [eq8] and the reduced E of sec. 3 agree and are conserved; F1, F2, F3
    (paper eq. (12) [eq7]) conserved."""
    def fn(p, s):
        X = paper_full_field(p, s)
        dE, E = directional_derivative(lambda z: [paper_E_full(p, z)], s, X)
        w, al, be, g, x, y = _split_full(s)
        Iw = tuple(p[k] * w[k] for k in range(3))
        scaleE = abs(dot(w, Iw)) + p[3] * p[4] ** 2 * dot(w, w) + abs(p[3] * p[5] ** 2 * (x * x + y * y))
        r1 = _rel(dE, scaleE * (1 + sum(abs(v) for v in X)))
        r2 = _compare([paper_E_reduced(p, _to_reduced(s))], E)
        Y = paper_reduced_field(p, _to_reduced(s))
        dEr, _ = directional_derivative(lambda z: [paper_E_reduced(p, z)], _to_reduced(s), Y)
        r3 = _rel(dEr, scaleE * (1 + sum(abs(v) for v in Y)))
        Fs = lambda z: [dot(paper_M(p, tuple(z[0:3]), tuple(z[9:12]), add(scale(z[12], z[3:6]), scale(z[13], z[6:9]))),  # noqa: E731
                            tuple(z[k:k + 3])) for k in (3, 6, 9)]
        dF, Fv = directional_derivative(Fs, s, X)
        r4 = _rel(dF, 1 + max(abs(v) for v in Fv) * (1 + sum(abs(v) for v in X)))
        return max(r1, r2, r3, r4)

    r, how = _each(full, random_full_states, fn)
    return _result("E (eq. (13) [eq8]) = reduced E (sec. 3); E, F1, F2, F3 conserved along "
                   "eqs. (8)-(10) [eq6] / (15)-(16) [eq10]", "eqs. (12) [eq7], (13) [eq8], sec. 3",
                   r, how)


# ---------------------------------------------------------------------------------------
# A2: symmetry fields.
# ---------------------------------------------------------------------------------------
def u_s(s):
    """Paper eq. (14) [eq9]: ``-y d/dx + x d/dy - beta_i d/dalpha_i + alpha_i d/dbeta_i``."""
    w, al, be, g, x, y = _split_full(s)
    return (0, 0, 0, *(-b for b in be), *al, 0, 0, 0, -y, x)


def _rot_field(i, j):
    """``-v_i d/dv_j + v_j d/dv_i`` on each of omega, gamma, R (0-based i, j): component
    ``j`` of the field is ``-v_i``, component ``i`` is ``v_j``."""
    def u(s):
        out = [0] * 9
        for b in (0, 3, 6):
            out[b + j] -= s[b + i]
            out[b + i] += s[b + j]
        return tuple(out)
    return u


#: Section 4 as printed. u_1's R part "-R2 d/dR3 + R2 d/dR3" cancels.
def u1_printed(s):
    """u_1 as printed: ``-omega2 d/domega3 + omega3 d/domega2 - gamma2 d/dgamma3 +
    gamma3 d/dgamma2 - R2 d/dR3 + R2 d/dR3`` (the R part is zero)."""
    return (0, s[2], -s[1], 0, s[5], -s[4], 0, -s[7] + s[7], 0)


u1 = _rot_field(1, 2)  # corrected: ... - R2 d/dR3 + R3 d/dR2
u2 = _rot_field(2, 0)  # -omega3 d/domega1 + omega1 d/domega3 ...
u3 = _rot_field(1, 0)  # -omega2 d/domega1 + omega1 d/domega2 ...


def bracket_residual(u, X, points, p):
    """Max relative ``|[u, X]|`` over points (exact)."""
    worst = 0.0
    for s in points:
        br, size = lie_bracket(u, lambda z: X(p, z), s)
        worst = max(worst, _rel(br, size))
    return worst


def check_u_s(full=False):
    """Paper eq. (14) [eq9]: u_s commutes with the field of paper eqs. (8)-(10) [eq6]."""
    r = max(bracket_residual(u_s, paper_full_field, random_full_states(_npts(full)), p) for p in _PARAM_SETS.values())
    return _result("[u_s, X] = 0 for eqs. (8)-(10) [eq6] (rotations of the plane)", "eq. (14) [eq9]", r,
                   _EXACT.format(n=_npts(full), p="FIG5/GENERIC") + ", exact Lie bracket")


def check_u_homogeneous(full=False):
    """Section 4: u_1, u_2, u_3 commute with paper eqs. (15)-(16) [eq10] for the homogeneous ball
    (u_1 corrected)."""
    pts = random_reduced_states(_npts(full))
    r_printed = bracket_residual(u1_printed, paper_reduced_field, pts, HOMOGENEOUS)
    rs = [bracket_residual(u, paper_reduced_field, pts, HOMOGENEOUS) for u in (u1, u2, u3)]
    how = _EXACT.format(n=_npts(full), p="HOMOGENEOUS (Fig. 3)") + ", exact Lie brackets"
    out = [
        _result("[u_2, X] = 0, homogeneous ball", "sec. 4", rs[1], how),
        _result("[u_3, X] = 0, homogeneous ball", "sec. 4", rs[2], how),
    ]
    verdict = "erratum corrected" if (r_printed > 1e-3 and rs[0] == 0.0) else ("verified" if r_printed == 0.0 else "failed")
    out.insert(0, CheckResult(
        claim="[u_1, X] = 0, homogeneous ball (printed R part -R2 d/dR3 + R2 d/dR3 cancels)", reference="sec. 4",
        verdict=verdict, residual=rs[0], tolerance=0.0,
        detail=how + f"; printed u_1: relative |[u_1, X]| = {r_printed:.3g} (fails); corrected -R2 d/dR3 + R3 d/dR2: "
                     f"{rs[0]:.3g}. Erratum E-F1"))
    return out


def check_u_symmetric(full=False):
    """Section 4: for I1 = I2 != I3 only u_3 survives."""
    pts = random_reduced_states(_npts(full))
    r1, r2, r3 = (bracket_residual(u, paper_reduced_field, pts, SYMMETRIC) for u in (u1, u2, u3))
    how = _EXACT.format(n=_npts(full), p="SYMMETRIC (Fig. 4, I = (2, 2, 3))")
    ok = r3 == 0.0 and r1 > 1e-3 and r2 > 1e-3
    return CheckResult(claim="I1 = I2: [u_3, X] = 0 while u_1, u_2 are not symmetries", reference="sec. 4",
                       verdict="verified" if ok else "failed", residual=r3, tolerance=0.0,
                       detail=how + f"; |[u_1, X]| = {r1:.3g}, |[u_2, X]| = {r2:.3g} (nonzero as claimed)")


def chart_functions(p, s):
    """Section 4 chart pieces as rational functions: ``K = M3``, ``r1``, ``r2``,
    ``tan g`` numerator and denominator, and ``(M1, M2)`` for ``l = atan2(M1, M2)``."""
    s = list(s)
    w, g, R = tuple(s[0:3]), tuple(s[3:6]), tuple(s[6:9])
    M = paper_M(p, w, g, R)
    C2 = dot(M, M)
    Mg = dot(M, g)
    # tan g = C (M2 g1 - M1 g2) / (M_gamma K - C^2 g3): C = sqrt(C2) is an invariant factor, the
    # rational parts are checked (u(C2) = 0 is checked separately).
    return {"K": M[2], "r1": R[0] * g[0] + R[1] * g[1], "r2": R[0] * g[1] - R[1] * g[0],
            "tan_g_num": M[1] * g[0] - M[0] * g[1], "tan_g_den": Mg * M[2] - C2 * g[2], "C2": C2, "M1": M[0], "M2": M[1]}


def check_u3_l(full=False):
    """Section 4: 'l is cyclic, u_3(l) = 0' for I1 = I2; l = atan2(M1, M2)."""
    p = SYMMETRIC
    worst_other, ul_vals = 0.0, []
    for s in random_reduced_states(_npts(full)):
        names = list(chart_functions(p, s))
        ders, vals = directional_derivative(lambda z: list(chart_functions(p, z).values()), s, u3(list(s)))
        dv = dict(zip(names, ders))
        v = dict(zip(names, vals))
        for k in ("K", "r1", "r2", "C2", "tan_g_num", "tan_g_den"):
            worst_other = max(worst_other, _rel([dv[k]], 1 + abs(v[k])))
        # u(l) for l = atan2(M1, M2): (M2 u(M1) - M1 u(M2)) / (M1^2 + M2^2)
        ul_vals.append((v["M2"] * dv["M1"] - v["M1"] * dv["M2"]) / (v["M1"] ** 2 + v["M2"] ** 2))
    ok_minus1 = all(x == -1 for x in ul_vals)
    printed_res = max(abs(float(x)) for x in ul_vals)
    verdict = "erratum corrected" if (ok_minus1 and worst_other == 0.0) else "failed"
    return CheckResult(
        claim="I1 = I2: l cyclic; printed u_3(l) = 0, true u_3(l) = -1 and u_3(K, r1, r2, g) = 0", reference="sec. 4",
        verdict=verdict, residual=worst_other, tolerance=0.0,
        detail=_EXACT.format(n=_npts(full), p="SYMMETRIC") + f"; u_3(l) = {sorted(set(str(x) for x in ul_vals))} at every point "
               f"(|printed residual| = {printed_res:.3g}); u_3 of K, r1, r2, C^2 and of the numerator and denominator "
               "of tan g: 0 exactly, i.e. u_3 = -d/dl in the chart (K, r1, r2, l, g). Erratum E-F2")


# ---------------------------------------------------------------------------------------
# A3: paper eq. (17) [eq11], symbolically.
# ---------------------------------------------------------------------------------------
def check_eq11(full=False):
    """Paper eq. (17) [eq11]: u_s(F3) = 0, u_s(E) = 0, u_s(F1) = -F2, u_s(F2) = F1 (sympy, no constraints)."""
    import sympy as sp

    I1, I2, I3, m, a, Om, x, y = sp.symbols("I1 I2 I3 m a Omega x y")
    w = sp.Matrix(sp.symbols("omega1:4"))
    al = sp.Matrix(sp.symbols("alpha1:4"))
    be = sp.Matrix(sp.symbols("beta1:4"))
    g = sp.Matrix(sp.symbols("gamma1:4"))
    R = x * al + y * be
    Iw = sp.Matrix([I1 * w[0], I2 * w[1], I3 * w[2]])
    M = Iw + m * a**2 * g.cross(w.cross(g)) - m * a * Om * R
    F1, F2, F3 = M.dot(al), M.dot(be), M.dot(g)
    E = w.dot(Iw + m * a**2 * g.cross(w.cross(g))) / 2 - m * Om**2 * (x**2 + y**2) / 2

    def us(f):
        out = -y * sp.diff(f, x) + x * sp.diff(f, y)
        for k in range(3):
            out += -be[k] * sp.diff(f, al[k]) + al[k] * sp.diff(f, be[k])
        return sp.expand(out)

    res = [us(F3), us(E), us(F1) + sp.expand(F2), us(F2) - sp.expand(F1)]
    r = 0.0 if all(v == 0 for v in res) else 1.0
    return _result("u_s(F3) = 0, u_s(E) = 0, u_s(F1) = -F2, u_s(F2) = F1", "eq. (17) [eq11]", r,
                   "sympy, polynomial identities in all 20 symbols (no constraint needed: u_s(R) = 0 identically)")


# ---------------------------------------------------------------------------------------
# A4: section 5.
# ---------------------------------------------------------------------------------------
def mparallel_point(p, g, R, lam):
    """A reduced state on ``M = lam gamma``: ``K = lam gamma + m a Omega R``,
    ``omega = Itilde^{-1} K`` (exact solve)."""
    K = add(scale(lam, g), scale(p[3] * p[4] * p[5], R))
    w = solve3(paper_itilde(p, g), K)
    return (*w, *g, *R), K


def _mparallel_reduced_points(n, seed=5):
    rng = random.Random(seed)
    out = []
    for s in random_reduced_states(n, seed):
        out.append((tuple(s[3:6]), tuple(s[6:9]), _rq(rng)))
    return out


def check_M_parallel_invariant(full=False):
    """Section 5: M = lambda gamma is an invariant relation of paper eqs. (15)-(16) [eq10]
    (paper eq. (18) [Mpn])."""
    worst, generic = 0.0, 0.0
    for p in _PARAM_SETS.values():
        for g, R, lam in _mparallel_reduced_points(_npts(full)):
            s, K = mparallel_point(p, g, R, lam)
            Y = paper_reduced_field(p, s)
            MxG = lambda z: cross(paper_M(p, tuple(z[0:3]), tuple(z[3:6]), tuple(z[6:9])), tuple(z[3:6]))  # noqa: E731
            d, _ = directional_derivative(MxG, s, Y)
            worst = max(worst, _rel(d, 1 + abs(lam) * sum(abs(v) for v in Y)))
        for s in random_reduced_states(2):  # off the relation the derivative is not zero
            d, _ = directional_derivative(MxG, s, paper_reduced_field(p, s))
            generic = max(generic, float(max(abs(v) for v in d)))
    ok = worst == 0.0 and generic > 0
    return CheckResult(claim="M = lambda gamma is invariant under eqs. (15)-(16) [eq10] "
                             "(d/dt (M x gamma) = 0 there)",
                       reference="sec. 5, eq. (18) [Mpn]", verdict="verified" if ok else "failed",
                       residual=worst, tolerance=0.0,
                       detail=_EXACT.format(n=_npts(full), p="FIG5/GENERIC") +
                       f"; off the relation |d/dt (M x gamma)| up to {generic:.3g} (the check is not vacuous)")


def check_mpn2_from_eq10(full=False):
    """Section 5: paper eq. (22) [Mpn2] and eqs. (19)-(21) [sved] follow from eqs. (15)-(16) [eq10] on
    M = lambda gamma."""
    from ..model import mparallel_constants, mparallel_rhs

    worst = 0.0
    for p in _PARAM_SETS.values():
        q = mparallel_pars(p)
        for g, R, lam in _mparallel_reduced_points(_npts(full)):
            s, K = mparallel_point(p, g, R, lam)
            Y = paper_reduced_field(p, s)
            K_of = lambda z: add(paper_M(p, tuple(z[0:3]), tuple(z[3:6]), tuple(z[6:9])),  # noqa: E731
                                 scale(p[3] * p[4] * p[5], tuple(z[6:9])))
            Kd, _ = directional_derivative(K_of, s, Y)
            Z = paper_mparallel_field(q, (*K, *g))
            r1 = _compare((*Kd, *Y[3:6]), Z)
            r2 = _compare(paper_sved(q, K, g), s[0:3])
            r3 = _compare(mparallel_rhs(mparallel_constants(q), K, g), Z)
            worst = max(worst, r1, r2, r3)
    return _result("eq. (22) [Mpn2] and eqs. (19)-(21) [sved] follow from eqs. (15)-(16) [eq10] with "
                   "K = lambda gamma + m a Omega R; taylorball mparallel_rhs = eq. (22) [Mpn2]",
                   "sec. 5, eqs. (19)-(21) [sved], (22) [Mpn2]", worst,
                   _EXACT.format(n=_npts(full), p="FIG5/GENERIC"))


def check_mpn2_integrals(full=False):
    """Section 5: gamma^2, (K, gamma), E~ are conserved along paper eq. (22) [Mpn2];
    E~ = E - lambda^2/(2d)."""
    worst = 0.0
    for p in _PARAM_SETS.values():
        q = mparallel_pars(p)
        for s in random_mparallel_states(_npts(full)):
            Z = paper_mparallel_field(q, s)
            f = lambda z: [dot(z[3:6], z[3:6]), dot(z[0:3], z[3:6]), paper_E_tilde(q, z)]  # noqa: E731
            d, v = directional_derivative(f, s, Z)
            worst = max(worst, _rel(d, (1 + max(abs(x) for x in v)) * (1 + sum(abs(x) for x in Z))))
        for g, R, lam in _mparallel_reduced_points(_npts(full)):
            s, K = mparallel_point(p, g, R, lam)
            lhs = paper_E_tilde(q, (*K, *g))
            rhs = paper_E_reduced(p, s) - lam * lam / (2 * q[3])
            worst = max(worst, _compare([lhs], [rhs]))
    return _result("gamma^2, (K, gamma) = lambda, E~ conserved along eq. (22) [Mpn2]; "
                   "E~ = E (sec. 3) - lambda^2/(2 d)",
                   "sec. 5", worst, _EXACT.format(n=_npts(full), p="FIG5/GENERIC"))


# ---------------------------------------------------------------------------------------
# A4/A5: densities.
# ---------------------------------------------------------------------------------------
def liouville_defect(field: Callable, rho2: Callable, point):
    """Exact ``div X + X . grad(rho^2) / (2 rho^2)`` (= ``div(rho X)/rho``), relative to
    the sum of the magnitudes of its terms."""
    divX, terms = divergence(field, point)
    X = _flat(field(list(point)))
    dr2, r2 = directional_derivative(lambda z: [rho2(z)], point, X)
    corr = dr2[0] / (2 * r2[0])
    total = divX + corr
    size = sum(abs(t) for t in terms) + abs(corr)
    return _rel([total], size) if size else float(abs(total))


def paper_full_rho2(p, s):
    """Square of the paper's density of section 2:
    ``rho = det(I + m a^2 E - m a^2 gamma (x) gamma) / sqrt(1 - m a^2 (gamma, (I + m a^2 E)^{-1} gamma))``."""
    g = tuple(s[9:12])
    I, d = p[0:3], p[3] * p[4] * p[4]
    mat = [[(I[i] + d if i == j else 0) - d * g[i] * g[j] for j in range(3)] for i in range(3)]
    den = 1 - d * sum(g[k] * g[k] / (I[k] + d) for k in range(3))
    return det3(mat) ** 2 / den


def reduced_rho2(p, s):
    """Square of the density derived for paper eqs. (15)-(16) [eq10] in ``(omega, gamma, R)``:
    ``rho = det(Itilde) |D|^{-1/2}``, ``D = 1 - m a^2 (gamma, (I + m a^2 E)^{-1} gamma)``."""
    g = tuple(s[3:6])
    I, d = p[0:3], p[3] * p[4] * p[4]
    den = 1 - d * sum(g[k] * g[k] / (I[k] + d) for k in range(3))
    return det3(paper_itilde(p, g)) ** 2 / den


def mparallel_rho2(q, s):
    """Square of the section-5 density ``rho = (1 - d (gamma, A gamma))^{-1/2}``."""
    g = tuple(s[3:6])
    return 1 / (1 - q[3] * sum(q[k] * g[k] * g[k] for k in range(3)))


def _density_rows(full, name, ref, field, rho2, gen, pars_sets, pars_text="FIG5/GENERIC"):
    worst, worst_one = 0.0, float("inf")
    for p in pars_sets:
        for s in gen(_npts(full)):
            worst = max(worst, liouville_defect(lambda z: field(p, z), lambda z: rho2(p, z), s))
            worst_one = min(worst_one, liouville_defect(lambda z: field(p, z), lambda z: 1, s))
    ok = worst == 0.0 and worst_one > 1e-6
    return CheckResult(claim=name, reference=ref, verdict="verified" if ok else "failed", residual=worst, tolerance=0.0,
                       detail=_EXACT.format(n=_npts(full), p=pars_text) + ": div(rho X)/rho exact; with rho = 1 "
                       f"the relative defect is >= {worst_one:.3g} (the check has teeth)")


def check_full_density(full=False):
    """Section 2: the paper's density of paper eqs. (8)-(10) [eq6] in (x, y, alpha, beta, gamma, omega)."""
    return _density_rows(full, "rho = det(I + ma^2 E - ma^2 gamma gamma)/sqrt(1 - ma^2 (gamma, J^-1 gamma)) is an "
                         "invariant density of eqs. (8)-(10) [eq6]", "sec. 2", paper_full_field,
                         paper_full_rho2, random_full_states, _PARAM_SETS.values())


def check_reduced_density(full=False):
    """Paper eqs. (15)-(16) [eq10] (no density printed): rho = det(Itilde) |D|^{-1/2} in (omega, gamma, R)."""
    return _density_rows(full, "eqs. (15)-(16) [eq10] (no density printed): rho = det(Itilde)/sqrt(D) "
                         "in (omega, gamma, R)",
                         "sec. 3",
                         paper_reduced_field, reduced_rho2, random_reduced_states, _PARAM_SETS.values())


def check_mparallel_density(full=False):
    """Section 5: rho = (1 - d (gamma, A gamma))^{-1/2} is an invariant density of paper eq. (22) [Mpn2]."""
    return _density_rows(full, "rho = (1 - d (gamma, A gamma))^(-1/2) is an invariant density of "
                         "eq. (22) [Mpn2]", "sec. 5",
                         paper_mparallel_field, mparallel_rho2, random_mparallel_states,
                         [mparallel_pars(p) for p in _PARAM_SETS.values()] + [(F(1), F(2), F(3), F(4), F(1, 2))],
                         "FIG5/GENERIC/paper Fig. 1 (a = (1, 2, 3), d = 4, D < 0: rho = |D|^(-1/2))")


def check_densities_match_package(full=False):
    """taylorball._integrals.density (public coords) equals the paper's densities (float64 vs exact)."""
    import numpy as np

    from .._integrals import density
    from ..params import BallParams

    worst = 0.0
    for p in _PARAM_SETS.values():
        bp = BallParams(inertia=tuple(float(v) for v in p[0:3]), mass=float(p[3]), radius=float(p[4]),
                        plane_rate=float(p[5]))
        for s in random_full_states(_npts(full)):
            rho = density("full", bp, np.array([float(v) for v in s]))
            worst = max(worst, abs(rho * rho / float(paper_full_rho2(p, s)) - 1))
            sr = _to_reduced(s)
            rho = density("reduced", bp, np.array([float(v) for v in sr]))
            worst = max(worst, abs(rho * rho / float(reduced_rho2(p, sr)) - 1))
    # k = 64: the state is rounded to float64 (1/2 eps each), then ~20 operations and a square root;
    # squaring doubles the relative error.
    tol = 64 * 2.0**-52
    return _result("taylorball density() = paper's density (full), det(Itilde)/sqrt(D) (reduced)", "secs. 2, 3",
                   worst, "float64 package value squared vs exact rational value at rational points", tol=tol)


#: check functions f(full: bool) -> CheckResult | list[CheckResult]
CHECKS: list = [
    check_kinematic_convention,
    check_eom_newton_euler,
    check_v_dot_eq5,
    check_model_full_omega,
    check_model_full_momentum,
    check_M_dot,
    check_L_star_and_M,
    check_itilde,
    check_R_dot,
    check_reduced_is_full,
    check_model_reduced,
    check_energy,
    check_u_s,
    check_u_homogeneous,
    check_u_symmetric,
    check_u3_l,
    check_eq11,
    check_M_parallel_invariant,
    check_mpn2_from_eq10,
    check_mpn2_integrals,
    check_full_density,
    check_reduced_density,
    check_mparallel_density,
    check_densities_match_package,
]


# ---------------------------------------------------------------------------------------
# The compiled heyoka graphs against the exact fields.
# ---------------------------------------------------------------------------------------
#: Relative tolerance of the compiled-graph comparison, in units of eps(real128): the
#: rational point is rounded to real128 on input (|dx| <= eps |x|, amplified by the
#: Jacobian, |Df| |x| / |f| ~ 10 at these points) and the graph does ~10^2 roundings that
#: partly cancel; measured worst 22 eps (full, momentum form, whose omega = Itilde^-1 K
#: adds a solve). 2^10 leaves a factor ~50 and is ~30 orders below a formula error.
K_GRAPH = 2**10


def compiled_field_residual(kind: str, formulation, p, state_exact, cache=None) -> float:
    """Norm-wise relative difference between the compiled heyoka right-hand side (real128,
    compact mode) of ``taylorball.model.get_system(kind, formulation)`` and the exact field
    derived here, at one exact rational point given in the paper's variables. ``cache``: a
    dict ``{(kind, formulation): cfunc}`` to use instead of the package's compile cache (the
    tests hand it a wrong function to see the check fail)."""
    import heyoka as hy
    import numpy as np

    from .._cache import compiled
    from ..model import get_system

    system = get_system(kind, formulation)
    key = (kind, system.formulation)

    def build():
        eqs = system.equations()
        return hy.cfunc([r for _, r in eqs], [v for v, _ in eqs], fp_type=hy.real128, compact_mode=True)

    cf = cache[key] if cache is not None and key in cache else compiled(("cfunc", "field", *key, "real128"), build)
    s = list(state_exact)
    if kind == "mparallel":
        q = mparallel_pars(p)
        internal, exact, pars = s, list(paper_mparallel_field(q, s)), q
    elif kind == "reduced":
        Y = paper_reduced_field(p, s)
        if system.formulation == "omega":
            internal, exact = s, list(Y)
        else:
            Md, M = directional_derivative(lambda z: paper_M(p, tuple(z[0:3]), tuple(z[3:6]), tuple(z[6:9])), s, Y)
            internal, exact = [*M, *s[3:]], [*Md, *Y[3:]]
        pars = p
    else:
        X = paper_full_field(p, s)
        if system.formulation == "omega":
            internal, exact = s, list(X)
        else:
            M_of = lambda z: paper_M(p, tuple(z[0:3]), tuple(z[9:12]), add(scale(z[12], z[3:6]), scale(z[13], z[6:9])))  # noqa: E731
            Md, M = directional_derivative(M_of, s, X)
            internal, exact = [*M, *s[3:]], [*Md, *X[3:]]
        pars = p

    def r128(v):
        return hy.real128(v.numerator) / hy.real128(v.denominator) if isinstance(v, Fraction) else hy.real128(v)

    xin = np.array([r128(F(v)) for v in internal], dtype=hy.real128)
    pin = np.array([r128(F(v)) for v in pars], dtype=hy.real128)
    out = cf(xin, pars=pin)
    import mpmath

    with mpmath.workdps(50):
        diff = max(abs(mpmath.mpf(str(o)) - mpmath.mpf(e.numerator) / e.denominator) for o, e in zip(out, map(F, exact)))
        size = max(abs(mpmath.mpf(e.numerator) / e.denominator) for e in map(F, exact))
        return float(diff / size)


def check_compiled_graphs(full=False):
    """The compiled heyoka graphs of all five systems equal the exact fields (real128)."""
    import heyoka as hy

    eps = 2.0**-112
    worst = {}
    for kind, form, gen in [("full", "omega", random_full_states), ("full", "momentum", random_full_states),
                            ("reduced", "omega", random_reduced_states), ("reduced", "momentum", random_reduced_states),
                            ("mparallel", None, random_mparallel_states)]:
        for p in _PARAM_SETS.values():
            for s in gen(_npts(full)):
                key = f"{kind}/{form or 'native'}"
                worst[key] = max(worst.get(key, 0.0), compiled_field_residual(kind, form, p, s))
    r = max(worst.values())
    del hy
    return _result("taylorball's compiled heyoka graphs (5 systems/formulations) = the exact fields of "
                   "eqs. (8)-(10) [eq6], (15)-(16) [eq10], (22) [Mpn2]",
                   "eqs. (8)-(10) [eq6], (11) [eq13], (15)-(16) [eq10], (22) [Mpn2]", r,
                   _EXACT.format(n=_npts(full), p="FIG5/GENERIC") + "; real128 cfunc vs exact, relative (in eps128): "
                   + ", ".join(f"{k} {v / eps:.3g}" for k, v in worst.items()), tol=K_GRAPH * eps)


CHECKS.append(check_compiled_graphs)


# ---------------------------------------------------------------------------------------
# Fully symbolic proofs (sympy, modulo the constraint ideal) where they are affordable.
# ---------------------------------------------------------------------------------------
def _normal_form_zero(expr, constraints, gens) -> bool:
    """True iff the numerator of ``expr`` lies in the ideal of ``constraints`` (normal form
    w.r.t. their Groebner basis is 0). The denominators (powers of ``det Itilde`` or ``D``)
    are nonzero on the phase space."""
    import sympy as sp

    num, _ = sp.fraction(sp.together(expr))
    G = sp.groebner(constraints, *gens, order="grevlex")
    return G.reduce(sp.expand(num))[1] == 0


def check_symbolic(full=False):
    """Symbolic proofs: the integrals and density of paper eq. (22) [Mpn2]; the density of
    eqs. (15)-(16) [eq10] (and, in full mode, its integrals C^2, M_gamma, E), all parameters
    symbolic."""
    import sympy as sp

    out = []
    # paper eq. (22) [Mpn2]: 6 variables, 5 parameters, ideal (gamma^2 - 1).
    q = sp.symbols("a1 a2 a3 d Omega")
    K, g = sp.symbols("K1:4"), sp.symbols("g1:4")
    z = [*K, *g]
    X = list(paper_mparallel_field(q, z))
    ideal, gens = [sum(v * v for v in g) - 1], [*K, *g, *q]
    lie = lambda f: sum(sp.diff(f, z[i]) * X[i] for i in range(6))  # noqa: E731
    rho2 = mparallel_rho2(q, z)
    div = sum(sp.diff(X[i], z[i]) for i in range(6)) + lie(rho2) / (2 * rho2)
    items = {"gamma^2": lie(sum(v * v for v in g)), "(K, gamma)": lie(sum(K[i] * g[i] for i in range(3))),
             "E~": lie(paper_E_tilde(q, z)), "div(rho X)/rho": div}
    bad = [k for k, e in items.items() if not _normal_form_zero(e, ideal, gens)]
    out.append(_result("eq. (22) [Mpn2]: d/dt gamma^2 = d/dt (K, gamma) = d/dt E~ = 0 and div(rho X) = 0, "
                       "symbolically",
                       "sec. 5", 0.0 if not bad else 1.0,
                       "sympy: numerators reduce to 0 modulo gamma^2 - 1, all of a1, a2, a3, d, Omega symbolic"
                       + (f"; NOT zero: {bad}" if bad else "")))
    # paper eqs. (15)-(16) [eq10]: 9 variables, 6 parameters, ideal (gamma^2 - 1, (R, gamma)).
    p = sp.symbols("I1 I2 I3 m a Omega")
    w, g, R = sp.symbols("w1:4"), sp.symbols("g1:4"), sp.symbols("R1:4")
    z = [*w, *g, *R]
    Y = list(paper_reduced_field(p, z))
    ideal = [sum(v * v for v in g) - 1, sum(R[i] * g[i] for i in range(3))]
    gens = [*R, *g, *w, *p]
    lie = lambda f: sum(sp.diff(f, z[i]) * Y[i] for i in range(9))  # noqa: E731
    rho2 = reduced_rho2(p, z)
    items = {"div(rho X)/rho": sum(sp.diff(Y[i], z[i]) for i in range(9)) + lie(rho2) / (2 * rho2)}
    if full:
        M = paper_M(p, tuple(w), tuple(g), tuple(R))
        items.update({"C^2": lie(sum(v * v for v in M)), "M_gamma": lie(sum(M[i] * g[i] for i in range(3))),
                      "E": lie(paper_E_reduced(p, z))})
    bad = [k for k, e in items.items() if not _normal_form_zero(e, ideal, gens)]
    out.append(_result("eqs. (15)-(16) [eq10]: div(rho X) = 0 for rho = det(Itilde)/sqrt(D)"
                       + ("; C^2, M_gamma, E conserved" if full else "") + ", symbolically", "sec. 3", 0.0 if not bad else 1.0,
                       "sympy: numerators reduce to 0 modulo (gamma^2 - 1, (R, gamma)), I1, I2, I3, m, a, Omega symbolic"
                       + ("" if full else " (integrals: --full, ~20 s)") + (f"; NOT zero: {bad}" if bad else "")))
    return out


CHECKS.append(check_symbolic)
