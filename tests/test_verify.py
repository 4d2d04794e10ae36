"""``taylorball verify`` (quick form): every check of the paper passes, the table and the
exit status say so, and a failing check is reported as failed (not hidden)."""

import math

import pytest

from taylorball import cli
from taylorball.verify import CHECK_MODULES, CheckResult, collect, format_table, run_checks


def test_quick_verify_passes_and_prints_a_table(capsys):
    status = cli.main(["verify"])
    out = capsys.readouterr().out
    assert status == 0, out
    assert " failed" in out.splitlines()[-1] and out.splitlines()[-1].endswith("0 failed"), out.splitlines()[-1]
    for topic in CHECK_MODULES:
        assert topic in out.splitlines()[0]
    # every topic contributes rows, and the errata found so far appear as corrected
    assert "erratum corrected" in out
    assert "[chaos]" in out and "Lyapunov" in out  # the Lyapunov spectrum's rows (issue 11)


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
