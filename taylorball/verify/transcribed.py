r"""The paper's formulas transcribed literally, and the full field derived from Newton--Euler.

Used by the checks of :mod:`taylorball.verify.formulas`, which compare them with each other
and with the package's fields. The functions ``paper_*`` are transcribed *from the paper*,
independently of :mod:`taylorball.model`, on tuples of exact rationals (or :class:`Dual`
numbers); :func:`newton_euler_full_field` *derives* the full system from the Newton--Euler
equations (paper eq. (6) [eq2]) and the no-slip constraint (eq. (1) [eq1]). A parameter set
``p`` is ``(I1, I2, I3, m, a, Omega)``.
"""

from __future__ import annotations

from .._vec import add, cross, dot, scale, sub
from .exact import _matrix_of, _split_full, directional_derivative, solve3

__all__ = [
    "paper_full_field",
    "paper_itilde",
    "paper_R_dot",
    "paper_reduced_field",
    "mparallel_pars",
    "paper_sved",
    "paper_mparallel_field",
    "paper_M",
    "paper_E_full",
    "paper_E_reduced",
    "paper_E_tilde",
    "newton_euler_full_field",
]


# ---------------------------------------------------------------------------------------
# The paper's formulas, transcribed literally.
# ---------------------------------------------------------------------------------------
def _itilde_op(p, g):
    """Paper eq. (8) [eq6], left-hand side operator ``W -> I W + m a^2 gamma x (W x gamma)``."""
    I, m, a = p[0:3], p[3], p[4]
    return lambda W: add(tuple(I[k] * W[k] for k in range(3)), scale(m * a * a, cross(g, cross(W, g))))


def _eq6_rhs(p, w, g, R, Rd):
    """Right-hand side of the omega equation, paper eqs. (8) [eq6] / (15) [eq10]."""
    I, m, a, Om = p[0:3], p[3], p[4], p[5]
    Iw = tuple(I[k] * w[k] for k in range(3))
    return sub(
        sub(cross(Iw, w), scale(m * a * Om * dot(w, g), cross(R, g))),
        scale(m * a * Om, cross(cross(Rd, g), g)),
    )


def paper_full_field(p, s):
    """Paper eqs. (8)-(10) [eq6] literally: ``(omega', alpha', beta', gamma', x', y')``; ``Rdot`` is the time
    derivative of ``R = x alpha + y beta`` (product rule with ``alpha' = alpha x omega``)."""
    w, al, be, g, x, y = _split_full(s)
    a, Om = p[4], p[5]
    xd = -Om * y + a * dot(w, be)
    yd = Om * x - a * dot(w, al)
    ald, bed, gd = cross(al, w), cross(be, w), cross(g, w)
    R = add(scale(x, al), scale(y, be))
    Rd = add(scale(xd, al), scale(yd, be), scale(x, ald), scale(y, bed))
    wd = solve3(_matrix_of(_itilde_op(p, g)), _eq6_rhs(p, w, g, R, Rd))
    return (*wd, *ald, *bed, *gd, xd, yd)


def paper_itilde(p, g):
    """``Itilde = I + m a^2 (gamma^2 E - gamma (x) gamma)`` of paper sec. 3 (Itilde, defined under
    eqs. (15)-(16) [eq10]), as rows."""
    I, d = p[0:3], p[3] * p[4] * p[4]
    g2 = dot(g, g)
    return [[(I[i] + d * g2 if i == j else 0) - d * g[i] * g[j] for j in range(3)] for i in range(3)]


def paper_R_dot(p, w, g, R):
    """Paper eq. (16) [eq10]: ``R' = R x (omega - Omega gamma) - a gamma x omega``."""
    a, Om = p[4], p[5]
    return sub(cross(R, sub(w, scale(Om, g))), scale(a, cross(g, w)))


def paper_reduced_field(p, s):
    """Paper eqs. (15)-(16) [eq10] literally: ``(omega', gamma', R')``."""
    s = list(s)
    w, g, R = tuple(s[0:3]), tuple(s[3:6]), tuple(s[6:9])
    Rd = paper_R_dot(p, w, g, R)
    wd = solve3(paper_itilde(p, g), _eq6_rhs(p, w, g, R, Rd))
    return (*wd, *cross(g, w), *Rd)


def mparallel_pars(p):
    """``(a1, a2, a3, d, Omega)`` of section 5 from ``(I1, I2, I3, m, a, Omega)``."""
    d = p[3] * p[4] * p[4]
    return (1 / (p[0] + d), 1 / (p[1] + d), 1 / (p[2] + d), d, p[5])


def paper_sved(q, K, g):
    """Paper eq. (19) [sved]: ``omega = A K + (gamma, A K)/(d^-1 - (gamma, A gamma)) A gamma``."""
    A, d = q[0:3], q[3]
    AK = tuple(A[k] * K[k] for k in range(3))
    Ag = tuple(A[k] * g[k] for k in range(3))
    return add(AK, scale(dot(g, AK) / (1 / d - dot(g, Ag)), Ag))


def paper_mparallel_field(q, s):
    """Paper eq. (22) [Mpn2] literally: ``K' = Omega gamma x K + (K - d Omega gamma) x omega``,
    ``gamma' = gamma x omega`` with ``omega`` of eq. (19) [sved]; ``q = (a1, a2, a3, d, Omega)``."""
    s = list(s)
    K, g = tuple(s[0:3]), tuple(s[3:6])
    d, Om = q[3], q[4]
    w = paper_sved(q, K, g)
    Kd = add(scale(Om, cross(g, K)), cross(sub(K, scale(d * Om, g)), w))
    return (*Kd, *cross(g, w))


def paper_M(p, w, g, R):
    """Paper eq. (11) [eq13]: ``M = I omega + m a^2 gamma x (omega x gamma) - m a Omega R``."""
    I, m, a, Om = p[0:3], p[3], p[4], p[5]
    return sub(add(tuple(I[k] * w[k] for k in range(3)), scale(m * a * a, cross(g, cross(w, g)))), scale(m * a * Om, R))


def paper_E_full(p, s):
    """Paper eq. (13) [eq8]: ``E = (omega, I omega + m a^2 gamma x (omega x gamma))/2
    - m Omega^2 (x^2 + y^2)/2``."""
    w, al, be, g, x, y = _split_full(s)
    I, m, a, Om = p[0:3], p[3], p[4], p[5]
    return dot(w, add(tuple(I[k] * w[k] for k in range(3)), scale(m * a * a, cross(g, cross(w, g))))) / 2 - m * Om * Om * (x * x + y * y) / 2


def paper_E_reduced(p, s):
    """Section 3: ``E = (M, omega)/2 + m a Omega (omega, R)/2 - m Omega^2 (R, R)/2``."""
    s = list(s)
    w, g, R = tuple(s[0:3]), tuple(s[3:6]), tuple(s[6:9])
    m, a, Om = p[3], p[4], p[5]
    M = paper_M(p, w, g, R)
    return dot(M, w) / 2 + m * a * Om * dot(w, R) / 2 - m * Om * Om * dot(R, R) / 2


def paper_E_tilde(q, s):
    """Section 5: ``E~ = (K, A K)/2 - K^2/(2 d) + d (A K, gamma)^2 / (2 (1 - d (gamma, A gamma)))``."""
    s = list(s)
    K, g = tuple(s[0:3]), tuple(s[3:6])
    A, d = q[0:3], q[3]
    AK = tuple(A[k] * K[k] for k in range(3))
    Ag = tuple(A[k] * g[k] for k in range(3))
    return dot(K, AK) / 2 - dot(K, K) / (2 * d) + d * dot(AK, g) ** 2 / (2 * (1 - d * dot(g, Ag)))


# ---------------------------------------------------------------------------------------
# The equations of motion derived from Newton--Euler (paper eq. (6) [eq2]) and the constraint (eq. (1) [eq1]).
# ---------------------------------------------------------------------------------------
def _v_constraint(p, w, g, R):
    """Paper eq. (1) [eq1], ``f = 0``: ``v = a omega x gamma + Omega gamma x R`` (the contact point of
    the ball moves with the plane, whose velocity there is ``Omega e_z x R``)."""
    a, Om = p[4], p[5]
    return add(scale(a, cross(w, g)), scale(Om, cross(g, R)))


def newton_euler_full_field(p, s):
    """The full system derived, not transcribed.

    Kinematics (paper eq. (2) [eq4]): a fixed axis ``e`` has body coordinates with ``e' = e x omega``;
    ``x' = (alpha, v)``, ``y' = (beta, v)``. Dynamics (paper eq. (6) [eq2]): ``m v' + m omega x v = N``,
    ``I omega' + omega x I omega = a N x gamma``, with ``v`` from the constraint. ``v'`` is
    the exact time derivative of ``v(omega, gamma, alpha, beta, x, y)`` along the
    kinematics for an unknown ``omega' = W`` (dual numbers); ``N`` is eliminated and the
    resulting linear equation ``A W = b`` is solved exactly."""
    w, al, be, g, x, y = _split_full(s)
    I, m, a = p[0:3], p[3], p[4]
    R = add(scale(x, al), scale(y, be))
    v = _v_constraint(p, w, g, R)
    xd, yd = dot(al, v), dot(be, v)
    ald, bed, gd = cross(al, w), cross(be, w), cross(g, w)

    def v_of(z):
        w_, al_, be_, g_, x_, y_ = _split_full(z)
        return _v_constraint(p, w_, g_, add(scale(x_, al_), scale(y_, be_)))

    def residual(W):
        vd, _ = directional_derivative(v_of, s, (*W, *ald, *bed, *gd, xd, yd))
        N = add(scale(m, tuple(vd)), scale(m, cross(w, v)))
        IW = tuple(I[k] * W[k] for k in range(3))
        Iw = tuple(I[k] * w[k] for k in range(3))
        return sub(add(IW, cross(w, Iw)), scale(a, cross(N, g)))

    r0 = residual((0, 0, 0))
    cols = [sub(residual(tuple(1 if i == j else 0 for i in range(3))), r0) for j in range(3)]
    A = [[cols[j][i] for j in range(3)] for i in range(3)]
    wd = solve3(A, tuple(-c for c in r0))
    return (*wd, *ald, *bed, *gd, xd, yd)
