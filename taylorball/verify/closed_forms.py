r"""Checks of the paper: the closed-form integral ``F3`` / ``Psi(gamma3)`` of section 5, item 3.

Method
------
1. **Derivation** (sympy, :func:`derive_required_psi_prime`). Paper eq. (22) [Mpn2] and
   eqs. (19)-(21) [sved] are transcribed here from the paper (not taken from :mod:`taylorball.model`), with
   ``a1 = a2``. For ``F3 = D^{-1/2} L + Omega Psi(gamma3)`` (``L`` the printed bracket,
   ``D = 1 - d (gamma, A gamma)``) the time derivative is formed symbolically with the
   unknown ``Psi'(gamma3) = p D^{-1/2}``, the numerator is reduced modulo
   ``gamma1^2 + gamma2^2 + gamma3^2 - 1`` and solved for ``p``. Result: the remainder at
   ``Omega = 0`` is identically 0 (the printed ``K``-linear part is right), and
   ``p = -(1 - a1 d)^2 / (a1^2 d)``, a constant, with zero remainder once substituted, i.e.

   .. math:: \Psi'(\gamma_3) = -\,d\,(1 - 1/(a_1 d))^2\,D(\gamma_3)^{-1/2},\qquad
             D(\gamma_3) = 1 - a_1 d - d (a_3 - a_1)\gamma_3^2 .

   Replacing ``D`` by ``|D|`` in both places changes nothing (``d|D|/|D| = dD/D``): that
   real form is taylorball's ``F3`` (the paper's is imaginary when ``D < 0``).
2. **Closed forms** in mpmath at 50 digits: the derivative of each printed ``Psi``
   (:func:`taylorball.closed_forms.psi_printed`, by ``mpmath.diff`` with the function
   evaluated at 120 digits) and of the corrected one
   (:func:`taylorball.closed_forms.psi_mp`) against the derived ``Psi'`` (lambdified from
   the sympy result, not the package's :func:`~taylorball.closed_forms.psi_prime`) at
   ``gamma3`` of both signs, near 0 and near ``+-1``; ``Psi(b) - Psi(a)`` against
   ``mpmath.quad`` of ``Psi'``; and the jump at ``gamma3 = 0``.
3. **Lie derivative** of ``F3`` along the package's paper eq. (22) [Mpn2] in mpmath at random states.
4. **Trajectories**: ``F3`` along heyoka solutions in float64 and real128, drift in units
   of ``eps sqrt(steps)`` times the scale of ``F3``
   (:func:`taylorball.closed_forms.symmetric_integral_scale`), next to the drift of the
   energy ``E`` and ``lambda``. Orbits crossing ``gamma3 = 0`` are included.

Parameter sets: two physical balls ``I = (2, 2, 3)`` (``a3 < a1``) and ``(3, 3, 2)``
(``a3 > a1``), ``m = 1``, ``a = 5``, ``Omega = 2``; the homogeneous ``(3, 3, 3)``
(``a3 = a1``); and values of the paper's kind (``d a_i > 1``, ``D < 0``):
``a = (1, 1, 3)``, ``(3, 3, 1.5)``, ``(1, 1, 1)``, ``d = 4``, ``Omega = 0.5``.
"""

from __future__ import annotations

import functools
import math
import warnings

import numpy as np

from . import CheckResult

__all__ = [
    "PARAM_SETS",
    "GAMMA3_POINTS",
    "derive_required_psi_prime",
    "required_psi_prime_mp",
    "printed_jump_at_zero",
    "lie_derivative_mp",
    "drift_ratios",
    "orbit_state",
    "K_EVAL",
    "ORBIT_STATES",
    "CHECKS",
]

REF = "sec. 5 item 3"
DPS = 50
#: relative tolerance of 50-digit identities (mpmath.diff of a 120-digit function loses
#: ~ a few digits; 1e-40 leaves 10 digits of room and is 1e39 below an O(1) failure)
TOL_MP = 1e-40
#: drift bound in units of eps * sqrt(steps) * scale (random walk of per-step rounding,
#: see tests/test_propagate.py: measured 0.01 .. 1.1 for the other integrals)
K_DRIFT = 8.0


def _param_sets():
    import taylorball as tb

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {
            "ball I=(2,2,3)": tb.BallParams(
                inertia=(2.0, 2.0, 3.0), mass=1.0, radius=5.0, plane_rate=2.0
            ).to_mparallel(),
            "ball I=(3,3,2)": tb.BallParams(
                inertia=(3.0, 3.0, 2.0), mass=1.0, radius=5.0, plane_rate=2.0
            ).to_mparallel(),
            "ball I=(3,3,3)": tb.BallParams(
                inertia=(3.0, 3.0, 3.0), mass=1.0, radius=5.0, plane_rate=2.0
            ).to_mparallel(),
            "a=(1,1,3),d=4": tb.MParallelParams(a=(1.0, 1.0, 3.0), d=4.0, plane_rate=0.5),
            "a=(3,3,1.5),d=4": tb.MParallelParams(a=(3.0, 3.0, 1.5), d=4.0, plane_rate=0.5),
            "a=(1,1,1),d=4": tb.MParallelParams(a=(1.0, 1.0, 1.0), d=4.0, plane_rate=0.5),
        }


#: name -> MParallelParams (see the module docstring)
PARAM_SETS = _param_sets()

#: gamma3 sample points: both signs, near 0 and near +-1
GAMMA3_POINTS = tuple(
    sign + x
    for x in ("1e-12", "1e-6", "0.001", "0.1", "0.3", "0.5", "0.7", "0.9", "0.999", "0.999999999")
    for sign in ("", "-")
)

#: initial states (K1, K2, K3, gamma1, gamma2, gamma3): one starts on gamma3 = 0
ORBIT_STATES = (
    (1.0, -2.0, 0.5, 0.6, 0.0, 0.8),
    (0.3, 1.0, -0.4, 1.0, 0.0, 0.0),
    (2.0, 0.7, 1.5, 0.0, 0.6, -0.8),
)


# ---------------------------------------------------------------------------------------
# 1. Symbolic derivation.
# ---------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=1)
def derive_required_psi_prime():
    """Derive ``Psi'`` from ``dF3/dt = 0`` along paper eq. (22) [Mpn2] with sympy (see module docstring).

    Returns
    -------
    dict
        ``p``: sympy expression in ``a1, a3, d`` with ``Psi' = p D^{-1/2}``;
        ``remainder_omega0``: the numerator of ``d(D^{-1/2} L)/dt`` at ``Omega = 0``
        reduced on the sphere (0 if the printed linear part is an integral of the fixed-plane
        case); ``remainder``: the full numerator with ``p`` substituted, reduced (0 if ``p``
        makes ``F3`` an integral); ``symbols``: ``(a1, a3, d)``.
    """
    import sympy as sp

    K1, K2, K3, g1, g2, g3, a1, a3, d, Om, p = sp.symbols("K1 K2 K3 g1 g2 g3 a1 a3 d Omega p", real=True)
    A = (a1, a1, a3)
    K = sp.Matrix([K1, K2, K3])
    g = sp.Matrix([g1, g2, g3])
    AK = sp.Matrix([A[i] * K[i] for i in range(3)])
    Ag = sp.Matrix([A[i] * g[i] for i in range(3)])
    D = 1 - d * g.dot(Ag)
    omega = AK + g.dot(AK) / (1 / d - g.dot(Ag)) * Ag  # paper eq. (19) [sved] as printed
    K_dot = Om * g.cross(K) + (K - d * Om * g).cross(omega)  # paper eq. (22) [Mpn2]
    g_dot = g.cross(omega)
    L = g3 * (K1 * g1 + K2 * g2) - (1 - g3**2 - 1 / (a1 * d)) * K3
    X = (K1, K2, K3, g1, g2, g3)
    f = list(K_dot) + list(g_dot)
    L_dot = sum(sp.diff(L, x) * fx for x, fx in zip(X, f))
    D_dot = sum(sp.diff(D, x) * fx for x, fx in zip(X, f))
    # D^{1/2} dF3/dt = L_dot - L D_dot / (2 D) + Omega p gamma3_dot   (Psi' = p D^{-1/2})
    expr = sp.together(L_dot - L * D_dot / (2 * D) + Om * p * g_dot[2])
    sphere = sp.Poly(g1**2 + g2**2 + g3**2 - 1, g1)

    def on_sphere(e):
        return sp.expand(sp.rem(sp.Poly(sp.expand(e), g1), sphere).as_expr())

    num = on_sphere(sp.numer(expr))
    rem0 = on_sphere(num.subs(Om, 0))
    sols = sp.solve(num, p)
    if len(sols) != 1:
        raise RuntimeError(f"expected one solution for Psi' coefficient, got {sols}")
    p_sol = sp.factor(sols[0])
    rem = on_sphere(num.subs(p, p_sol))
    return {"p": p_sol, "remainder_omega0": rem0, "remainder": sp.simplify(rem), "symbols": (a1, a3, d)}


@functools.lru_cache(maxsize=1)
def _p_function():
    import sympy as sp

    der = derive_required_psi_prime()
    return sp.lambdify(der["symbols"], der["p"], "mpmath")


def required_psi_prime_mp(params, gamma3, *, absolute: bool = True):
    """The derived ``Psi'(gamma3) = p |D|^{-1/2}`` (or ``p D^{-1/2}``, principal branch, with
    ``absolute=False``) in mpmath at the current precision, from the sympy result."""
    import mpmath

    a1, a3, d = mpmath.mpf(params.a[0]), mpmath.mpf(params.a[2]), mpmath.mpf(params.d)
    g = mpmath.mpf(gamma3)
    D = 1 - a1 * d - d * (a3 - a1) * g * g
    return _p_function()(a1, a3, d) / mpmath.sqrt(abs(D) if absolute else D)


def _rel(x, y):
    import mpmath

    return float(abs(x - y) / max(abs(x), abs(y), mpmath.mpf(10) ** (-DPS)))


def _deriv_residual(fn, params, points, *, absolute=True):
    """max relative |d fn/d gamma3 - required| over points, at DPS digits."""
    import mpmath

    worst = 0.0
    with mpmath.workdps(DPS):
        for x in points:
            x = mpmath.mpf(x)
            num = mpmath.diff(fn, x)
            worst = max(worst, _rel(num, required_psi_prime_mp(params, x, absolute=absolute)))
    return worst


def _quad_residual(fn, params, intervals):
    import mpmath

    worst = 0.0
    with mpmath.workdps(DPS):
        for a, b in intervals:
            a, b = mpmath.mpf(a), mpmath.mpf(b)
            lhs = fn(mpmath.mpf(b)) - fn(mpmath.mpf(a))
            rhs = mpmath.quad(lambda t: required_psi_prime_mp(params, t), [a, 0, b] if a < 0 < b else [a, b])
            worst = max(worst, _rel(lhs, rhs))
    return worst


def printed_jump_at_zero(params, delta="1e-45"):
    """``Psi_printed(+delta) - Psi_printed(-delta)`` (mpmath, 50 digits)."""
    import mpmath

    from ..closed_forms import psi_printed

    with mpmath.workdps(DPS):
        return psi_printed(params, mpmath.mpf(delta), 2 * DPS) - psi_printed(
            params, -mpmath.mpf(delta), 2 * DPS
        )


def _sets(pred):
    from ..closed_forms import psi_branch

    return {k: p for k, p in PARAM_SETS.items() if pred(p, psi_branch(p))}


def _printed_fn(p, corrected=False, factor=1):
    from ..closed_forms import psi_printed

    return lambda t: factor * psi_printed(p, t, 120, corrected=corrected)


# ---------------------------------------------------------------------------------------
# 2. Checks of the derivation and of the closed forms.
# ---------------------------------------------------------------------------------------
def check_derivation(full: bool):
    """sympy: the K-linear part at Omega = 0, and the Psi' that F3 needs."""
    der = derive_required_psi_prime()
    import sympy as sp

    a1, a3, d = der["symbols"]
    expected = -((1 - a1 * d) ** 2) / (a1**2 * d)
    same = sp.simplify(der["p"] - expected) == 0
    r0 = der["remainder_omega0"] == 0
    r1 = der["remainder"] == 0
    return [
        CheckResult(
            "F3 linear part rho*(g3(K1g1+K2g2)-(1-g3^2-1/(a1d))K3) conserved at Omega=0",
            REF,
            "verified" if r0 else "failed",
            0.0 if r0 else math.inf,
            0.0,
            "sympy: numerator of d(D^(-1/2) L)/dt along eq. (22) [Mpn2] with Omega = 0, reduced mod "
            "|gamma|^2 - 1, "
            f"is {der['remainder_omega0']}",
        ),
        CheckResult(
            "F3 conserved iff dPsi/dg3 = -d(1-1/(a1d))^2 D^(-1/2) (derived)",
            REF,
            "verified" if (r1 and same) else "failed",
            0.0 if (r1 and same) else math.inf,
            0.0,
            f"sympy: solving D^(1/2) dF3/dt = 0 for Psi' = p D^(-1/2) gives p = {der['p']} (a constant); "
            f"remainder with p substituted: {der['remainder']}; the same with |D| for D < 0",
        ),
    ]


def check_arctan_form(full: bool):
    """Printed arctan form (a3 > a1, physical balls): derivative, and continuity at 0."""
    import mpmath

    from ..closed_forms import psi_mp

    sets = _sets(lambda p, br: p.a[2] > p.a[0] and br.s > 0)
    pts = [x for x in GAMMA3_POINTS if float(x) != 0.0]
    res_d = max(_deriv_residual(_printed_fn(p), p, pts) for p in sets.values())
    jumps, corr = [], []
    for name, p in sets.items():
        with mpmath.workdps(DPS):
            a1, a3, d = (mpmath.mpf(v) for v in (p.a[0], p.a[2], p.d))
            coef = mpmath.sqrt(d) * (1 - 1 / (a1 * d)) ** 2 / mpmath.sqrt(a3 - a1)
            jump = printed_jump_at_zero(p)
            jumps.append(_rel(jump, coef * mpmath.pi / 2))  # the predicted jump
            # a continuous Psi has |Psi(+delta) - Psi(-delta)| ~ 2 delta |Psi'(0)| ~ 1e-45 here
            corr.append(float(abs(psi_mp(p, "1e-45") - psi_mp(p, "-1e-45")) / abs(psi_mp(p, 1))))
    rows = [
        CheckResult(
            "Psi arctan form (a3 > a1): dPsi/dgamma3",
            REF,
            "verified" if res_d <= TOL_MP else "failed",
            res_d,
            TOL_MP,
            f"mpmath.diff of the printed Psi vs the derived Psi' at {len(pts)} gamma3 in (-1, 1) \\ {{0}}, "
            f"sets {list(sets)}",
        )
    ]
    traj = _printed_f3_along_crossing_orbit(sets["ball I=(3,3,2)"])
    ok = max(jumps) <= TOL_MP and max(corr) <= TOL_MP
    rows.append(
        CheckResult(
            "Psi arctan form continuous at gamma3 = 0",
            REF,
            "erratum corrected" if ok else "failed",
            max(corr),
            TOL_MP,
            f"E-Psi1: printed Psi jumps by {float(printed_jump_at_zero(sets['ball I=(3,3,2)'])):.3g} at gamma3 = 0 "
            "(ball I=(3,3,2)); the printed arctan argument has gamma3 in the denominator; Psi jumps by "
            f"pi sqrt(d) c^2 / (2 sqrt(a3 - a1)) at gamma3 = 0 (relative deviation from that value {max(jumps):.1e}); "
            f"the corrected arctan(gamma3 sqrt(d(a3-a1)) rho) form is continuous (|Psi(+1e-45) - Psi(-1e-45)| / |Psi(1)| "
            f"<= {max(corr):.1e}). Along a float64 orbit crossing gamma3 = 0 {traj}",
        )
    )
    return rows


def _printed_f3_along_crossing_orbit(p):
    """Printed F3 along an orbit crossing gamma3 = 0: its spread vs the predicted jump."""
    import mpmath

    from ..closed_forms import psi_printed, symmetric_integral
    from .._propagate import propagate

    x = propagate("mparallel", p, orbit_state(p, ORBIT_STATES[1]), np.linspace(0.0, 20.0, 401))
    ncross = int(np.sum(np.diff(np.sign(x[:, 5])) != 0))
    F = symmetric_integral(p, x)
    with mpmath.workdps(30):
        a1, d = p.a[0], p.d
        vals = []
        for row in x:
            if row[5] == 0.0:
                continue
            D = 1 - d * (a1 * (row[3] ** 2 + row[4] ** 2) + p.a[2] * row[5] ** 2)
            L = row[5] * (row[0] * row[3] + row[1] * row[4]) - (1 - row[5] ** 2 - 1 / (a1 * d)) * row[2]
            vals.append(float(L / math.sqrt(D) + p.plane_rate * psi_printed(p, float(row[5]), 30)))
        coef = math.sqrt(d) * (1 - 1 / (a1 * d)) ** 2 / math.sqrt(p.a[2] - a1)
    return (
        f"({ncross} crossings, t <= 20): printed F3 spread {max(vals) - min(vals):.6g} vs predicted "
        f"Omega pi sqrt(d) c^2/(2 sqrt(a3-a1)) = {p.plane_rate * coef * math.pi / 2:.6g}; corrected F3 spread "
        f"{float(np.max(F) - np.min(F)):.1e}"
    )


def check_log_form(full: bool):
    """Printed log form (a3 < a1, physical balls): derivative fails; corrected holds."""
    sets = _sets(lambda p, br: p.a[2] < p.a[0] and br.s > 0)
    pts = [x for x in GAMMA3_POINTS if float(x) != 0.0]
    res_p = max(_deriv_residual(_printed_fn(p), p, pts) for p in sets.values())
    res_c = max(_deriv_residual(_printed_fn(p, corrected=True), p, pts) for p in sets.values())
    verdict = "verified" if res_p <= TOL_MP else ("erratum corrected" if res_c <= TOL_MP else "failed")
    return CheckResult(
        "Psi log form (a3 < a1): dPsi/dgamma3",
        REF,
        verdict,
        res_p if verdict == "verified" else res_c,
        TOL_MP,
        f"E-Psi2: mpmath.diff of the printed Psi vs the derived Psi' at {len(pts)} gamma3, sets {list(sets)}: "
        f"printed residual {res_p:.2e}; with xi = rho(1 - a1 d - 2d(a3-a1)g3^2)/(2 g3 sqrt(d(a1-a3))) and "
        f"ln(xi - 1) - ln(xi + 1) the residual is {res_c:.1e}",
    )


def check_negative_D(full: bool):
    """Paper-kind values d a_i > 1 (D < 0): printed F3 is imaginary; real form with |D|."""
    sets = _sets(lambda p, br: br.s < 0 and p.a[2] != p.a[0])
    pts = [x for x in GAMMA3_POINTS if float(x) != 0.0]
    # printed read literally: is it a real Psi with the real derivative? (no: it is complex)
    import mpmath

    from ..closed_forms import psi_mp, psi_printed

    imag = 0.0
    with mpmath.workdps(DPS):
        for p in sets.values():
            for x in pts:
                v = psi_printed(p, x, DPS)
                imag = max(imag, float(abs(mpmath.im(v)) / abs(v)))
    # complex reading: rho = D^(-1/2) principal branch; with E-Psi2 fixed, printed Psi' = p D^(-1/2)
    res_cplx = max(
        _deriv_residual(_printed_fn(p, corrected=True), p, pts, absolute=False) for p in sets.values()
    )
    res_real = max(_deriv_residual(lambda t, p=p: psi_mp(p, t, 120), p, pts) for p in sets.values())
    ok = res_cplx <= TOL_MP and res_real <= TOL_MP
    return CheckResult(
        "F3 real for d a_i > 1 (D < 0, paper's kind of values)",
        REF,
        "erratum corrected" if ok else "failed",
        res_real,
        TOL_MP,
        f"E-Psi3: sets {list(sets)}: printed Psi (with rho = D^(-1/2) imaginary) has |Im Psi|/|Psi| up to {imag:.2f}; "
        f"read as complex functions the printed forms (log form with E-Psi2) satisfy Psi' = p D^(-1/2) "
        f"(residual {res_cplx:.1e}), so i*F3_printed is real up to piecewise constants (principal branches); the real F3 with rho = |D|^(-1/2) "
        f"uses arsinh for a3 > a1 and arctan for a3 < a1 (branches swapped), residual {res_real:.1e}",
    )


def check_corrected_psi(full: bool):
    """taylorball's Psi (all branches): derivative and integral against the derived Psi'."""
    from ..closed_forms import psi_branch, psi_mp

    pts = list(GAMMA3_POINTS) + ["0"]
    res_d = max(_deriv_residual(lambda t, p=p: psi_mp(p, t, 120), p, pts) for p in PARAM_SETS.values())
    intervals = (
        [(-1, 1), ("0.1", "0.2"), ("-0.999", "-0.5"), ("-0.3", "0.9")] if full else [(-1, 1), ("-0.3", "0.9")]
    )
    res_q = max(
        _quad_residual(lambda t, p=p: psi_mp(p, t, DPS + 10), p, intervals) for p in PARAM_SETS.values()
    )
    res = max(res_d, res_q)
    forms = sorted({f"{psi_branch(p).form}(s={psi_branch(p).s:+d})" for p in PARAM_SETS.values()})
    return CheckResult(
        "Psi corrected closed form (taylorball.closed_forms.psi)",
        REF,
        "verified" if res <= TOL_MP else "failed",
        res,
        TOL_MP,
        f"derivative at {len(pts)} gamma3 (residual {res_d:.1e}) and Psi(b)-Psi(a) vs quad on {intervals} "
        f"(residual {res_q:.1e}), branches {forms}, sets {list(PARAM_SETS)}",
    )


# ---------------------------------------------------------------------------------------
# 3. Lie derivative along the package's paper eq. (22) [Mpn2].
# ---------------------------------------------------------------------------------------
def lie_derivative_mp(params, state, dps=DPS, F=None):
    """``(dF/dt, sum_i |dF/dx_i f_i|)`` at ``state`` along taylorball's paper eq. (22) [Mpn2], mpmath.

    ``F(params, state, dps)`` defaults to :func:`taylorball.closed_forms.symmetric_integral_mp`;
    it is evaluated at ``2 dps`` digits and differentiated by ``mpmath.diff``; the vector
    field is :func:`taylorball.model.mparallel_rhs` on mpmath numbers."""
    import mpmath

    from ..closed_forms import symmetric_integral_mp
    from ..model import get_system

    F = symmetric_integral_mp if F is None else F
    system = get_system("mparallel")
    with mpmath.workdps(dps):
        x = [mpmath.mpf(v) for v in state]
        f = system.rhs([mpmath.mpf(v) for v in params.pars], x)
        terms = []
        for i in range(6):

            def Fi(t, i=i):
                y = list(x)
                y[i] = t
                return F(params, y, 2 * dps)

            terms.append(mpmath.diff(Fi, x[i]) * f[i])
        return mpmath.fsum(terms), mpmath.fsum(abs(t) for t in terms)


def _random_states(n, seed=1):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        g = rng.normal(size=3)
        g /= np.linalg.norm(g)
        out.append(np.concatenate([rng.normal(size=3) * 2, g]))
    return out


def check_lie_derivative(full: bool):
    """dF3/dt = 0 along paper eq. (22) [Mpn2] in mpmath at random states (all parameter sets)."""
    import mpmath

    states = _random_states(6 if full else 2)
    worst = 0.0
    for p in PARAM_SETS.values():
        for s in states:
            # project gamma to |gamma| = 1 at 50 digits (F3 conservation is a statement on the sphere)
            with mpmath.workdps(DPS):
                g = [mpmath.mpf(v) for v in s[3:]]
                n = mpmath.sqrt(mpmath.fsum(v * v for v in g))
                x = [mpmath.mpf(v) for v in s[:3]] + [v / n for v in g]
                lie, mag = lie_derivative_mp(p, x)
                worst = max(worst, float(abs(lie) / mag))
    return CheckResult(
        "F3 Lie derivative along eq. (22) [Mpn2] vanishes",
        REF,
        "verified" if worst <= TOL_MP else "failed",
        worst,
        TOL_MP,
        f"|sum_i dF3/dx_i f_i| / sum_i |dF3/dx_i f_i| at {len(states)} random states x {len(PARAM_SETS)} sets, "
        "mpmath 50 digits, vector field taylorball.model.mparallel_rhs",
    )


# ---------------------------------------------------------------------------------------
# 4. Trajectories.
# ---------------------------------------------------------------------------------------
#: evaluation error of F3 at one state, in units of eps * scale: measured <= 9 for float64,
#: long double and real128 at 1200 random states of the six parameter sets; a drift
#: F3(t) - F3(0) contains two such errors, K_EVAL = 32 allows ~2x the measured worst case
K_EVAL = 32.0


def orbit_state(params, state):
    """``state`` with ``K`` scaled by ``1/a1`` so that ``|A K| ~ |K_given|`` (physical balls
    have ``a_i ~ 0.04``: unscaled orbits would barely move)."""
    x = np.array(state, dtype=float)
    x[:3] /= params.a[0]
    return x


def drift_ratios(params, state, T, *, fp_type=float, n=101):
    """Drift of ``F3``, ``E`` and ``lambda`` along a heyoka solution of paper eq. (22) [Mpn2].

    Returns
    -------
    steps : int
    drifts : dict
        ``max_t |I(t) - I(0)| / (eps max_t scale_I(t))`` for ``F3``, ``E``, ``lambda``;
        ``F3`` is evaluated in the integration's number type.
    crossings : int
        Sign changes of ``gamma3`` on the output grid.

    The bound applied by the checks is ``drift <= K_EVAL + K_DRIFT sqrt(steps)``: two
    evaluation errors plus a random walk of per-step rounding.
    """
    from ..closed_forms import symmetric_integral, symmetric_integral_scale
    from .._integrals import integral_scales, integrals
    from .._propagate import make_integrator

    ta, system, spec = make_integrator("mparallel", params, np.asarray(state, dtype=float), fp_type=fp_type)
    res = ta.propagate_grid(spec.array(np.linspace(0.0, T, n)))
    steps = int(res[3])
    X = res[-1]  # mparallel: internal layout == public layout
    vals = {"F3": symmetric_integral(params, X)}
    scales = {"F3": symmetric_integral_scale(params, X)}
    iv, isc = integrals("mparallel", params, X), integral_scales("mparallel", params, X)
    for k in ("E", "lambda"):
        vals[k], scales[k] = iv[k], isc[k]
    drifts = {
        k: float(np.max(np.abs(vals[k] - vals[k][0]))) / (spec.eps * float(np.max(np.abs(scales[k]))))
        for k in vals
    }
    crossings = int(np.sum(np.diff(np.sign(X[:, 5].astype(float))) != 0))
    return steps, drifts, crossings


def _traj_check(full, fp_type, label, T):
    worst, worst_other, tot_cross, steps_all, worst_abs = 0.0, 0.0, 0, [], 0.0
    for p in PARAM_SETS.values():
        for s in ORBIT_STATES:
            steps, r, c = drift_ratios(p, orbit_state(p, s), T, fp_type=fp_type)
            bound = K_EVAL + K_DRIFT * math.sqrt(steps)
            worst = max(worst, r["F3"] / bound)
            worst_other = max(worst_other, r["E"] / bound, r["lambda"] / bound)
            worst_abs = max(worst_abs, r["F3"])
            tot_cross += c
            steps_all.append(steps)
    return CheckResult(
        f"F3 conserved along eq. (22) [Mpn2] {label}",
        REF,
        "verified" if worst <= 1.0 else "failed",
        worst,
        1.0,
        f"max over {len(PARAM_SETS)} sets x {len(ORBIT_STATES)} orbits to t = {T} ({min(steps_all)}..{max(steps_all)} "
        f"steps, {tot_cross} crossings of gamma3 = 0) of drift(F3) / (eps scale (K_EVAL + K_DRIFT sqrt(steps))), "
        f"K_EVAL = {K_EVAL:g}, K_DRIFT = {K_DRIFT:g}; largest drift {worst_abs:.1f} eps scale; the same ratio for "
        f"E and lambda on the same orbits: {worst_other:.2f}",
    )


def check_float64(full: bool):
    """F3 drift along float64 solutions."""
    return _traj_check(full, float, "float64", 2000.0 if full else 100.0)


def check_real128(full: bool):
    """F3 drift along real128 solutions."""
    import heyoka as hy

    return _traj_check(full, hy.real128, "real128", 20.0 if full else 2.0)


#: check functions f(full: bool) -> CheckResult | list[CheckResult]
CHECKS: list = [
    check_derivation,
    check_arctan_form,
    check_log_form,
    check_negative_D,
    check_corrected_psi,
    check_lie_derivative,
    check_float64,
    check_real128,
]
