"""The paper's formulas, checked exactly (taylorball/verify/formulas.py).

Every check there is exact (sympy, or rational arithmetic with dual numbers at rational
points of the constraint manifold), so true identities give residual 0 exactly and the
tolerance is 0. The tests below also show that each kind of check fails on a wrong
formula (teeth), and that the exact machinery itself is right.
"""

from fractions import Fraction as F

import pytest
import sympy as sp

from taylorball._vec import cross, dot
from taylorball.verify import formulas as fm

#: claims the paper prints wrongly (docs/errata.md): the check must say so
ERRATA = {"check_u_homogeneous": "E-F1", "check_u3_l": "E-F2"}


@pytest.mark.parametrize("check", fm.CHECKS, ids=lambda c: c.__name__)
def test_check_passes(check):
    out = check(False)
    out = out if isinstance(out, list) else [out]
    verdicts = {r.verdict for r in out}
    assert "failed" not in verdicts, [(r.claim, r.detail) for r in out if not r.ok]
    if check.__name__ in ERRATA:
        assert "erratum corrected" in verdicts
        assert any(ERRATA[check.__name__] in r.detail for r in out)
    else:
        assert verdicts == {"verified"}
    for r in out:
        assert r.residual <= r.tolerance


# --- the exact machinery -------------------------------------------------------------
def test_rational_points_are_exactly_on_the_manifold():
    for s in fm.random_full_states(5):
        al, be, g = s[3:6], s[6:9], s[9:12]
        assert [dot(al, al), dot(be, be), dot(g, g), dot(al, be), dot(be, g), dot(g, al)] == [1, 1, 1, 0, 0, 0]
        assert tuple(cross(al, be)) == tuple(g)  # right-handed
    for s in fm.random_reduced_states(5):
        assert dot(s[3:6], s[3:6]) == 1 and dot(s[3:6], s[6:9]) == 0


def test_dual_numbers_match_sympy():
    """Exact forward-mode derivative of a rational function equals sympy's."""
    x, y = sp.symbols("x y")
    f = lambda u, v: (u**3 - 2 * u * v + 5) / (1 + u * u * v)  # noqa: E731
    dfx = sp.diff(f(x, y), x).subs({x: sp.Rational(3, 7), y: sp.Rational(-2, 5)})
    ders, vals = fm.directional_derivative(lambda z: [f(z[0], z[1])], [F(3, 7), F(-2, 5)], [1, 0])
    assert sp.Rational(ders[0].numerator, ders[0].denominator) == dfx


# --- teeth: each kind of check fails on a wrong formula --------------------------------
def test_newton_euler_comparison_detects_a_wrong_sign():
    """Flipping the sign of Omega in paper eqs. (8)-(10) [eq6] (not in the derivation) gives an O(1)
    mismatch."""
    p = fm.FIG5
    s = fm.random_full_states(1)[0]

    def wrong(p_, s_):
        q = (*p_[:5], -p_[5])  # Omega -> -Omega in eqs. (8)-(10) [eq6] only
        return fm.paper_full_field(q, s_)

    assert fm._compare(fm.newton_euler_full_field(p, s), wrong(p, s)) > 1e-3
    assert fm._compare(fm.newton_euler_full_field(p, s), fm.paper_full_field(p, s)) == 0.0


def test_bracket_detects_a_broken_symmetry():
    """u_3 is a symmetry of the symmetric ball but not of the asymmetric one."""
    pts = fm.random_reduced_states(2)
    assert fm.bracket_residual(fm.u3, fm.paper_reduced_field, pts, fm.SYMMETRIC) == 0.0
    assert fm.bracket_residual(fm.u3, fm.paper_reduced_field, pts, fm.FIG5) > 1e-3


def test_printed_u1_is_not_even_tangent():
    """The printed u_1 does not preserve (R, gamma) = 0: u_1((R, gamma)) = R2 gamma3 - R3 gamma2."""
    s = fm.random_reduced_states(1)[0]
    d, _ = fm.directional_derivative(lambda z: [dot(z[3:6], z[6:9])], s, fm.u1_printed(s))
    assert d[0] == s[7] * s[5] - s[8] * s[4] != 0
    d, _ = fm.directional_derivative(lambda z: [dot(z[3:6], z[6:9])], s, fm.u1(s))
    assert d[0] == 0


def test_wrong_density_fails():
    """rho = (1 - d (gamma, A gamma))^(+1/2) (wrong exponent) is not invariant for paper eq. (22) [Mpn2]."""
    q = fm.mparallel_pars(fm.FIG5)
    s = fm.random_mparallel_states(1)[0]
    field = lambda z: fm.paper_mparallel_field(q, z)  # noqa: E731
    assert fm.liouville_defect(field, lambda z: fm.mparallel_rho2(q, z), s) == 0.0
    assert fm.liouville_defect(field, lambda z: 1 / fm.mparallel_rho2(q, z), s) > 1e-3


def test_u3_of_l_is_minus_one():
    """E-F2: u_3(l) = -1 for l = atan2(M1, M2) (u_3 rotates M by e3 x M)."""
    r = fm.check_u3_l(False)
    assert "['-1']" in r.detail


def test_compiled_graph_check_detects_a_wrong_graph():
    """Feeding the omega-form check the M-form graph (same dimension) gives an O(1) residual."""
    import heyoka as hy

    from taylorball.model import get_system

    eqs = get_system("reduced", "momentum").equations()
    wrong = {("reduced", "omega"): hy.cfunc([r for _, r in eqs], [v for v, _ in eqs], fp_type=hy.real128,
                                            compact_mode=True)}
    s = fm.random_reduced_states(1)[0]
    assert fm.compiled_field_residual("reduced", "omega", fm.FIG5, s, cache=wrong) > 1e-3
    assert fm.compiled_field_residual("reduced", "omega", fm.FIG5, s) <= fm.K_GRAPH * 2.0**-112


def test_symbolic_normal_form_has_teeth():
    """A non-conserved quantity does not reduce to 0 modulo the constraints."""
    import sympy as sp

    q = sp.symbols("a1 a2 a3 d Omega")
    K, g = sp.symbols("K1:4"), sp.symbols("g1:4")
    z = [*K, *g]
    X = fm.paper_mparallel_field(q, z)
    lie_K2 = sum(sp.diff(sum(k * k for k in K), z[i]) * X[i] for i in range(6))  # K^2 is not an integral
    assert not fm._normal_form_zero(lie_K2, [sum(v * v for v in g) - 1], [*K, *g, *q])


@pytest.mark.slow
def test_symbolic_full_mode():
    out = fm.check_symbolic(True)
    assert all(r.verdict == "verified" for r in out), [r.detail for r in out]
