"""``auto``'s trial of the AMG against the direct factor on contact tangents (contopt.solve.linear.choice):
the record's verdicts. The trial inside factorize, with PETSc: tests/solve/test_petsc.py."""

from __future__ import annotations

import numpy as np
import pytest

from contopt.solve.linear.choice import DIRECT_MATRICES, TRIAL_MATRICES, Choice


def _after_first_factor(seconds: float = 1.0) -> Choice:
    record = Choice(free=np.arange(6))
    assert record.verdict == "untried" and not record.wants_amg
    record.record_direct(5.0 * seconds)  # the first factorization also pays the symbolic analysis
    assert record.verdict == "untried"
    record.record_direct(seconds)
    assert record.verdict == "trial" and record.wants_amg and record.direct_seconds == seconds
    return record


@pytest.mark.parametrize(("amg", "verdict"), [(0.9, "amg"), (1.1, "direct")])
def test_the_trial_keeps_the_amg_when_its_mean_cost_a_matrix_beats_the_factorization(amg, verdict):
    record = _after_first_factor(1.0)
    for _ in range(TRIAL_MATRICES - 1):
        record.record_amg(amg, failed=False)
        assert record.verdict == "trial"  # not judged on fewer matrices
    record.record_amg(amg, failed=False)
    assert record.verdict == verdict


def test_a_failed_or_late_solve_ends_the_trial_at_once():
    record = _after_first_factor(1.0)
    assert record.budget == pytest.approx(2.0)  # TRIAL_SLACK factorizations a solve
    record.record_amg(0.1, failed=True)
    assert record.verdict == "direct" and not record.wants_amg
    record.record_amg(0.1, failed=False)  # nothing brings the AMG back
    assert record.verdict == "direct"


def test_the_kept_amg_is_judged_on_its_last_matrices():
    record = _after_first_factor(1.0)
    for _ in range(TRIAL_MATRICES):
        record.record_amg(0.5, failed=False)
    assert record.verdict == "amg" and record.budget == pytest.approx(3.0)  # AMG_SLACK once kept
    record.record_amg(1.5, failed=False)  # last three: 0.5, 0.5, 1.5 -> mean 0.83
    assert record.verdict == "amg"
    record.record_amg(1.5, failed=False)  # 0.5, 1.5, 1.5 -> mean 1.17: slower than a factorization
    assert record.verdict == "direct"


def test_the_yardstick_is_the_faster_of_the_first_factorizations():
    record = Choice(free=np.arange(6))
    for seconds in [2.0, 1.0, 3.0][:DIRECT_MATRICES]:
        record.record_direct(seconds)
    assert record.verdict == "trial" and record.direct_seconds == 1.0


def test_a_later_factorization_is_the_new_yardstick():
    record = _after_first_factor(1.0)
    for _ in range(TRIAL_MATRICES):
        record.record_amg(0.8, failed=False)
    record.record_direct(0.5)  # contact closed: the factor (and the AMG) cost otherwise now
    assert record.verdict == "amg" and record.direct_seconds == 0.5
    record.record_amg(0.8, failed=False)  # 0.8 a matrix against 0.5
    assert record.verdict == "direct"
