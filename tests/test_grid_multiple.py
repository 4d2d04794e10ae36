"""One multiple check (``taylorball.numbers.multiple_of``) for the sample grids of the
observables (``observables.grid_ratio``) and a study's ``checkpoint_every`` / ``t_end``.

Every grid a user can write in decimal that is mathematically a multiple is accepted with
its exact ratio (the reference is exact decimal arithmetic, ``decimal.Decimal``), and the
values a looser rule (1e-9 relative, what ``grid_ratio`` allowed before) took for
multiples but are not are refused, in the observables as in the study file."""

from decimal import Decimal

import pytest

import taylorball as tb
from taylorball.errors import UsageError
from taylorball.numbers import multiple_of
from taylorball.observables import grid_ratio

from tests.test_study import write_study

#: decimal steps a study file might hold (sample_dt, angles_every, checkpoint_every)
STEPS = ["0.1", "0.01", "0.05", "0.2", "0.25", "0.3", "0.7", "0.001", "1.1", "2.5", "0.125", "3.3", "0.0625",
         "1e-5", "7", "12.5", "0.15"]
#: ratios: all small ones, and some large (a chunk of many samples, a long run of chunks)
RATIOS = list(range(1, 1001)) + [1234, 4096, 10**4 + 1, 99999, 10**6 - 1, 123456789]


def _exact(k: int, step: str) -> float:
    """The float64 a user gets writing ``k * step`` in decimal (exact product, one rounding)."""
    return float(Decimal(k) * Decimal(step))


@pytest.mark.parametrize("step", STEPS)
def test_every_decimal_multiple_is_accepted(step):
    dt = float(step)
    for k in RATIOS:
        every = _exact(k, step)
        assert multiple_of(every, dt) == k, (every, step, k)
        if k <= 10**12:
            assert grid_ratio("angles_every", every, dt) == k, (every, step, k)


def _old_rule(every: float, dt: float) -> bool:
    """What grid_ratio accepted before: within 1e-9 relative of an integer ratio."""
    r = every / dt
    n = round(r)
    return n >= 1 and abs(r - n) <= 1e-9 * r


#: (every, sample_dt): accepted by the old rule, not multiples, refused now
CHANGED = [(0.30000000001, 0.1), (20.000000001, 10.0), (50.00000001, 0.25), (2.5000000001, 0.25),
           (0.1 + 1e-12, 0.1), (1000.0000001, 0.5)]


@pytest.mark.parametrize("every, dt", CHANGED)
def test_near_multiples_are_refused(every, dt):
    assert _old_rule(every, dt)  # what changes acceptance
    assert multiple_of(every, dt) is None
    with pytest.raises(UsageError, match=r"observables\.angles_every must be a positive multiple of sample_dt"):
        grid_ratio("angles_every", every, dt)


def test_the_rule_is_relative_and_not_an_offset():
    # 0.1 * 3 (a product computed in float64) and 0.3 (written) are both 3 steps of 0.1
    assert multiple_of(0.1 * 3, 0.1) == 3 and multiple_of(0.3, 0.1) == 3
    assert multiple_of(0.05, 0.1) is None and multiple_of(0.15, 0.1) is None  # 0.5 and 1.5 steps
    assert multiple_of(0.0, 0.1) is None and multiple_of(float("inf"), 1.0) is None
    assert multiple_of(1e308, 1e-10) is None  # the ratio overflows: no multiple, no OverflowError


def test_study_file_uses_the_same_rule(tmp_path):
    """A study file's decimal grid is read with the same rule: ``0.3`` checkpoints of
    ``0.1`` samples and ``angles_every = 0.7`` load; ``angles_every = 0.30000000001`` and
    ``t_end = 20.000000001`` with ``checkpoint_every = 10`` are refused."""
    run = {"sample_dt": 0.1, "checkpoint_every": 0.3, "t_end": 0.9}
    cfg = tb.load_study(write_study(tmp_path / "a", run=run, observables={"angles_every": 0.7,
                                                                          "samples_every": 2.1}))
    assert cfg.samples_per_chunk == 3
    with pytest.raises(UsageError, match=r"angles_every must be a positive multiple of sample_dt = 0.1"):
        tb.load_study(write_study(tmp_path / "b", run=run, observables={"angles_every": 0.30000000001}))
    with pytest.raises(UsageError, match=r"t_end.*multiple of \[run\] checkpoint_every = 10.0"):
        tb.load_study(write_study(tmp_path / "c", run={"t_end": 20.000000001, "checkpoint_every": 10.0}))
