"""The augmented Lagrangian's stall: accepted where the update's force change is the Newton solve's own
residual (the multipliers cannot be known better than the forces they balance), an error otherwise."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from contopt.contact.laws import NOISE_FACTOR, AugmentationOptions, AugmentedLagrangian

A = 0.01  # each node's overlap area
H = 0.1


def _stalled(dp: float):
    """A law one update short of its stall (``patience`` updates without halving, growth stopped) and a
    solve's result whose first node's pressure moves by ``dp`` (relative), all gaps closed: (law, result,
    state). The pressure change ``dp`` is far above 100x the target, so only the noise rule can accept it."""
    law = AugmentedLagrangian(options=AugmentationOptions(pressure_rtol=1e-9, gap_rtol=1e-9, patience=5))
    state = law.start(3, eps=10.0)
    state = replace(
        state, p=np.ones(3), grow=False, since_best=4, best_error=1.0, last_error=1e3, updates=12
    )  # fmt: skip
    lam = np.array([1.0 + dp, 1.0, 1.0])
    result = SimpleNamespace(
        lam=lam, coverage=np.ones(3), a=np.full(3, A), g=np.zeros(3), has_overlap=np.ones(3, bool), n_active=3
    )
    return law, result, state


def test_a_stall_whose_force_change_is_the_solves_residual_is_accepted():
    dp = 1e-6  # 1000x the pressure target: no 100x acceptance
    law, result, state = _stalled(dp)
    force_change = dp * A  # node 0: |lam - p| a, coverage 1
    # the solve ended at a residual whose NOISE_FACTOR-fold covers the force change: accepted, with the
    # state the solve was made with (as at a converged update)
    done = law.advance(result, state, True, H, residual=1.01 * force_change / NOISE_FACTOR)
    assert done.status == "done" and done.state is state
    # the measure is |lam - p| over the largest pressure 1 + dp
    assert abs(done.measures.pressure_change - dp / (1.0 + dp)) < 1e-15


def test_a_stall_above_the_solves_residual_or_after_an_early_stop_is_an_error():
    dp = 1e-6
    law, result, state = _stalled(dp)
    force_change = dp * A
    # a residual NOISE_FACTOR times too small to explain the change, and an early-stopped solve (its
    # residual is passed as 0: a tighter solve would lower it) both end in the one-line stall error
    for residual in (0.99 * force_change / NOISE_FACTOR, 0.0):
        out = law.advance(result, state, True, H, residual=residual)
        assert out.status == "failed"
        assert "stall" in out.message and "loosen augmentation.pressure_rtol" in out.message
        assert "\n" not in out.message


def test_the_noise_rule_waits_for_a_stall():
    # one update short of the patience the same force change is no stall yet: the updates go on
    law, result, state = _stalled(1e-6)
    early = replace(state, since_best=2)
    out = law.advance(result, early, True, H, residual=1.0)
    assert out.status == "continue"
