"""``taylorball verify`` (quick form): every check of the paper passes, the table and the
exit status say so, and a failing check is reported as failed (not hidden)."""

import math

import numpy as np
import pytest

from taylorball import cli
from taylorball.verify import CHECK_MODULES, CheckResult, collect, format_table, run_checks


@pytest.mark.long
def test_quick_verify_passes_and_prints_a_table(capsys):
    status = cli.main(["verify"])
    out = capsys.readouterr().out
    assert status == 0, out
    assert " failed" in out.splitlines()[-1] and out.splitlines()[-1].endswith("0 failed"), out.splitlines()[-1]
    for topic in CHECK_MODULES:
        assert topic in out.splitlines()[0]
    # every topic contributes rows, and the errata found so far appear as corrected
    assert "erratum corrected" in out
    assert "[chaos]" in out and "Lyapunov" in out  # the Lyapunov spectrum's rows


def test_each_topic_has_checks():
    for topic in CHECK_MODULES:
        assert collect([topic]), f"verify topic {topic!r} has no checks"


def test_a_crashing_check_is_a_failure(monkeypatch):
    from taylorball.verify import charts

    def boom(full):
        """A check that raises."""
        raise RuntimeError("deliberate")

    monkeypatch.setattr(charts, "CHECKS", [boom])
    res = run_checks(modules=["charts"])
    assert len(res) == 1 and res[0].verdict == "failed" and "deliberate" in res[0].detail
    assert format_table(res).endswith("1 failed")
    monkeypatch.setattr(charts, "CHECKS", [lambda full: CheckResult("x", "-", "failed", 1.0, 0.5)])
    assert cli.main(["verify", "--only", "charts"]) == 1


def test_verdicts_are_validated():
    with pytest.raises(ValueError, match="verdict"):
        CheckResult("x", "-", "probably fine")
    assert math.isnan(CheckResult("x", "-", "verified").residual)


def test_chaos_sum_row_fails_without_the_density(monkeypatch):
    """The Lyapunov sum row can fail: with the Lebesgue measure (no density term) it must."""
    from taylorball.chaos import lyapunov_spectrum
    from taylorball.paper import FIG4_BALL
    from taylorball.verify import chaos

    r = lyapunov_spectrum("reduced", FIG4_BALL, chaos._fig4a_states(1)[0], 50.0)
    assert chaos._sum_row(r).verdict == "verified"
    monkeypatch.setattr(chaos, "_density_change", lambda r: 0)
    assert chaos._sum_row(r).verdict == "failed"


def test_chaos_zero_row_counts(monkeypatch):
    """The zero-count row fails when the count it is held to is not the measured one."""
    from taylorball.chaos import lyapunov_spectrum
    from taylorball.verify import chaos

    p, x = chaos._fig1()
    r = lyapunov_spectrum("mparallel", p, x, 100.0)
    assert chaos._zero_row(r, 10.0).verdict == "verified"
    n, why, middle = chaos._ZEROS["mparallel"]
    for wrong in (n - 1, n + 1):
        monkeypatch.setitem(chaos._ZEROS, "mparallel", (wrong, why, middle))
        assert chaos._zero_row(r, 10.0).verdict == "failed"


def test_megno_limit_rows_hold_and_a_wrong_limit_fails():
    """The integrable-case MEGNO rows: <Y> of Chaplygin's Omega = 0 ball tends to 2 with
    norm="compact" and to 4 with norm="full" (the quadratic shear); claiming the other limit
    fails (the fitted growth law then mispredicts the second time, or has no solution)."""
    import dataclasses

    from taylorball.chaos import megno
    from taylorball.paper import FIG4_BALL, demo_reduced_state
    from taylorball.verify import chaos

    p = dataclasses.replace(FIG4_BALL, plane_rate=0.0)
    c, f = (megno("reduced", p, demo_reduced_state(), 2000.0, sample=[500.0, 2000.0], norm=n)
            for n in ("compact", "full"))
    assert chaos._megno_limit_row(c, 1, "compact", "-").verdict == "verified"
    assert chaos._megno_limit_row(f, 2, "full", "-").verdict == "verified"
    assert chaos._megno_limit_row(c, 2, "compact, wrong limit 4", "-").verdict == "failed"
    assert chaos._megno_limit_row(f, 1, "full, wrong limit 2", "-").verdict == "failed"


def test_megno_deficit_law_against_a_direct_quadrature():
    """The growth law's deficit 2p - <Y> (closed form with the dilogarithm) against a direct
    mpmath quadrature of <Y> = (1/T) int_0^T (2/s) int_0^s u p/(tau + u) du ds (tolerance
    1e-10 relative: quadrature error, far below the rows' 35 % margin)."""
    import mpmath

    from taylorball.verify import chaos

    for p, tau, T in ((1, 0.8, 1000.0), (2, 3.2, 2000.0), (1, 50.0, 1000.0)):
        inner = lambda s: 2 / s * mpmath.quad(lambda u: u * p / (tau + u), [0, s])  # noqa: E731
        direct = 2 * p - mpmath.quad(inner, [0, 1, T]) / T
        assert abs(chaos._megno_deficit(p, tau, T) - float(direct)) <= 1e-10 * float(direct), (p, tau, T)
        assert abs(chaos._megno_deficit(p, chaos._fit_tau(p, float(direct), T), T) - float(direct)) <= 1e-9


def test_gali_rows_hold_and_a_wrong_claim_fails():
    """GALI_2 of a Fig. 4a orbit falls at lambda_1 - lambda_2; the claim that it falls at
    lambda_1 - lambda_3 (= 2 lambda_1: the GALI_3 rate) fails; a chaotic orbit's GALI_2 fails the
    regular-torus row."""
    from taylorball.chaos import gali, lyapunov_spectrum
    from taylorball.paper import FIG4_BALL
    from taylorball.verify import chaos

    x = chaos._fig4a_states(1)[0]
    g = gali("reduced", FIG4_BALL, x, 300.0, k=2, sample=np.arange(10.0, 301.0, 10.0))
    lam = np.sort(np.asarray(lyapunov_spectrum("reduced", FIG4_BALL, x, 300.0).exponents, dtype=float))[::-1]
    assert chaos._gali_rate_row(g, lam[0] - lam[1], "l1 - l2").verdict == "verified"
    assert chaos._gali_rate_row(g, lam[0] - lam[-1], "wrong: l1 - l9").verdict == "failed"
    assert chaos._gali_regular_row(g).verdict == "failed"
