"""The validated step's remainder over time slices (taylorball.rigorous._taylor.sliced_remainder):
tighter than over the one a priori box, still an enclosure of the truth."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

flint = pytest.importorskip("flint", reason="python-flint is not installed (optional extra 'rigorous')")

import taylorball as tb  # noqa: E402
from taylorball.periodic_catalog import FIG3_SADDLE  # noqa: E402
from taylorball.rigorous._balls import exact_arb, working_precision  # noqa: E402
from taylorball.rigorous._taylor import LohnerSet, apriori_high_order, horner, sliced_remainder, taylor_coeffs  # noqa: E402
from taylorball.rigorous._balls import interval  # noqa: E402
from taylorball.rigorous.enclosure import _to_ball, ball_pars, ball_rhs, integrate_set, internal_system  # noqa: E402


def _saddle_start():
    pars = ball_pars("reduced", FIG3_SADDLE.ball)
    X0 = list(internal_system("reduced").to_internal(pars, [exact_arb(v) for v in FIG3_SADDLE.state]))
    return ball_rhs("reduced", pars), X0


def test_sliced_remainder_is_tighter_and_contains_the_start_coefficient():
    """Fig. 3 saddle's start, order 18, h = 4e-3: over the a priori box the remainder is
    ~1e-7 (the ball recursion's radii grow with the box's width), over 16 slices below 1e-15;
    the slices' hull contains x_19 at the start point (x(0) lies in the first slice)."""
    N, hf = 18, Fraction(1, 250)
    with working_precision(53):
        rhs, X0 = _saddle_start()
        h = exact_arb(hf)
        cX = taylor_coeffs(rhs, X0, N)
        found = apriori_high_order(rhs, [horner(c[:-1], interval(0, h)) for c in cX], h, N)
        assert found is not None
        B, cB = found
        over_B = max(float(abs(cB[i][N + 1]).upper()) for i in range(9)) * float(hf) ** (N + 1)
        xs = sliced_remainder(rhs, cX, cB, h, N, 16)
        sliced = max(float(abs(x).upper()) for x in xs) * float(hf) ** (N + 1)
        assert over_B > 1e-9 and sliced < 1e-15
        c0 = taylor_coeffs(rhs, X0, N + 1)
        assert all(x.contains(c0[i][N + 1]) for i, x in enumerate(xs))


def test_sliced_steps_contain_heyoka_mpfr_and_are_longer():
    """From the saddle's start to t = 0.1 at 53 bits: with the sliced remainder (4 slices)
    the box contains heyoka's 256-bit MPFR solution (an independent integration), and it
    takes fewer steps than with the remainder over the a priori box (slices=0, the default)."""
    hy = pytest.importorskip("heyoka")
    t = Fraction(1, 10)
    x = np.array(FIG3_SADDLE.state)
    ref = tb.propagate("reduced", FIG3_SADDLE.ball, x, float(t), fp_type=hy.real, prec=256, project=True)
    with working_precision(53):
        rhs, X0 = _saddle_start()
        X0 = [b + exact_arb(0) for b in X0]
        _, _, steps4, box = integrate_set(rhs, LohnerSet.from_box(X0), t, prec=53, order=18, tol=2.0 ** -53, slices=4)
        _, _, steps0, _ = integrate_set(rhs, LohnerSet.from_box(X0), t, prec=53, order=18, tol=2.0 ** -53)
        pars = ball_pars("reduced", FIG3_SADDLE.ball)
        pub = internal_system("reduced").to_public(pars, box)
        # heyoka projects the float state onto the constraints at 256 bits (a shift of ~1e-16,
        # far inside the box's radius ~1e-11)
        assert all(b.contains(_to_ball(v)) for b, v in zip(pub, ref))
        assert max(float(b.rad()) for b in pub) < 1e-9
        assert steps4 < 0.8 * steps0


@pytest.mark.slow
def test_refined_crossing_time_tightens_the_section_point():
    """The Fig. 3 saddle's third segment (return time 2.01) at 128 bits, order 28, from the
    point: with the crossing time refined (the default) the section point is enclosed to
    radius < 1e-30, without (``crossing_refine=0``) only to ~4e-17; the refined box lies in the
    unrefined one and within 1e-12 of heyoka's float64 section point (its own error).
    About 90 CPU s."""
    from taylorball.paper import FIG3_BALL, FIG3_LEVELS
    from taylorball.rigorous.search import float_map
    from taylorball.rigorous.section import section_map

    p = (-0.17666812593679765, 0.44585521709215525)  # float64 Newton (periodic_catalog.fig3_saddle)
    q, tau, x0 = float_map(FIG3_BALL, FIG3_LEVELS, p, K_near=-3.5)
    K = float(tb.reduced_chart(FIG3_BALL, x0[None])["K"][0])
    with working_precision(128):
        pb = [exact_arb(p[0]), exact_arb(p[1])]
        ref = section_map(FIG3_BALL, FIG3_LEVELS, pb, K, tau, prec=128, order=28, jac=False)
        one = section_map(FIG3_BALL, FIG3_LEVELS, pb, K, tau, prec=128, order=28, jac=False, crossing_refine=0)
        assert max(float(b.rad()) for b in ref.P) < 1e-30 < 1e-20 < max(float(b.rad()) for b in one.P)
        assert all(o.contains(r) for o, r in zip(one.P, ref.P))
        assert all(abs(float(r.mid()) - v) < 1e-12 for r, v in zip(ref.P, q))
