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
