"""The warm start's penalty stages (contopt.optimize.warm): how much softer the contact cells are, and that the
staged solve ends at the plain solve's equilibrium."""

import math

import numpy as np
import pytest

from contopt.cases.two_blocks import two_blocks
from contopt.contact.interface import plane_strain_modulus
from contopt.errors import ConvergenceError
from contopt.optimize.warm import (
    FIRST,
    MIN_STAGE,
    SOFTER,
    STAGE,
    STAGE_RTOL,
    STAGE_UTOL,
    cold_solve,
    softening,
    staged_solve,
    warm_solve,
)
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import State, solve_static
from contopt.solve.system import System


def _system(law="penalty"):
    return System.of(two_blocks(divisions=4, law=law))


def _rho(system, block_rho):
    rho = np.ones(system.disc.n_cells)
    rho[system.disc.cell_slice("block")] = block_rho
    return rho


def test_softening_is_the_ratio_of_the_contact_moduli():
    system = _system()
    e_block, e_punch = (plane_strain_modulus(b.material) for b in system.model.bodies)
    (ratio,) = softening(system, _rho(system, 0.1), np.ones(system.disc.n_cells))
    expected = (1 / (0.1 * e_block) + 1 / e_punch) / (1 / e_block + 1 / e_punch)
    assert ratio == pytest.approx(expected, rel=1e-12)
    # stiffer now than at the start: no stages (1), nor without the start's design or for an augmented Lagrangian
    assert softening(system, np.ones(system.disc.n_cells), _rho(system, 0.1)) == (1.0,)
    assert softening(system, _rho(system, 0.1), None) == ()
    alm = _system("alm")
    assert softening(alm, _rho(alm, 0.1), np.ones(alm.disc.n_cells)) == (1.0,)


ONE_STEP = NewtonOptions(n_steps=1, min_step=1.0, max_step=1.0)


def test_staged_solve_reaches_the_plain_equilibrium():
    system = _system()
    full = solve_static(system, newton=NewtonOptions(n_steps=2))
    soft = _rho(system, 0.02)
    ratios = softening(system, soft, full.rho)
    staged = staged_solve(system, soft, full, ratios, ONE_STEP, newton=ONE_STEP)
    cold = solve_static(system, soft, newton=NewtonOptions(n_steps=2))
    # one converged solve per stage: the start's penalty over the ratio, then at most STAGE times stiffer up to eps
    assert sum(lg.converged for lg in staged.logs) == math.ceil(math.log(ratios[0]) / math.log(STAGE)) + 1
    assert staged.eps == cold.eps  # ends at the interface's own penalty
    # the same equilibrium: both solves stop at |r| <= rtol r_ref (1e-9); u agrees far inside 1e-6 |u|
    assert np.linalg.norm(staged.u - cold.u) <= 1e-6 * np.linalg.norm(cold.u)
    assert np.linalg.norm(staged.reactions[system.disc.constrained] - cold.reactions[system.disc.constrained]) <= (
        1e-6 * np.linalg.norm(cold.reactions[system.disc.constrained])
    )


def _failing_first(calls):
    """solve_static, but the first call fails (a warm start that does not converge); ``calls`` gets each
    call's starting penalties."""

    def solve(*args, **kw):
        calls.append(kw["start"].eps if kw.get("start") is not None and kw["start"].laws else None)
        if len(calls) == 1:
            raise ConvergenceError("forced", ["the failed solve's log"])
        return solve_static(*args, **kw)

    return solve


def test_a_failed_warm_start_far_softer_goes_on_in_stages_a_near_one_fails():
    system = _system()
    full = solve_static(system, newton=NewtonOptions(n_steps=2))
    eps = system.contact.blocks[0].eps
    calls = []
    state = warm_solve(system, _rho(system, 0.02), full, _failing_first(calls), newton=ONE_STEP)
    (ratio,) = softening(system, _rho(system, 0.02), full.rho)
    assert ratio > SOFTER and state.eps == (eps,)
    assert calls[1] == pytest.approx((eps / ratio,), rel=1e-12)  # the first stage at the start's relative stiffness
    assert len(calls) == math.ceil(math.log(ratio) / math.log(STAGE)) + 2  # the failed solve, then the stages
    assert state.logs[0] == "the failed solve's log"  # kept before the stages'
    # within the bound: no stages, the failure goes on to the caller (the cold solve)
    calls.clear()
    with pytest.raises(ConvergenceError):
        warm_solve(system, _rho(system, 0.5), full, _failing_first(calls), newton=ONE_STEP)
    assert len(calls) == 1


def test_a_warm_start_that_converges_is_that_one_solve():
    system = _system()
    full = solve_static(system, newton=NewtonOptions(n_steps=2))
    rho = _rho(system, 0.5)
    (ratio,) = softening(system, rho, full.rho)
    assert 1.0 < ratio <= SOFTER
    warm = warm_solve(system, rho, full, newton=ONE_STEP)
    plain = solve_static(system, rho, newton=ONE_STEP, start=full)
    assert len(warm.logs) == len(plain.logs) == 1
    # the same solve (equal but for the round-off of the summation order, far below Newton's tolerance)
    np.testing.assert_allclose(warm.u, plain.u, rtol=0, atol=1e-12 * np.linalg.norm(plain.u))


def test_a_cold_solve_whose_stages_fail_is_the_plain_solve_from_zero():
    system = _system()
    soft = _rho(system, 0.02)
    assert softening(system, soft, np.ones(system.disc.n_cells))[0] > SOFTER  # the cold solve stages
    calls = []

    def solve(*args, **kw):
        """solve_static, but every solve from a start (the stages) fails."""
        calls.append(kw.get("start") is not None)
        if kw.get("start") is not None:
            raise ConvergenceError("forced", ["the failed stage's log"])
        return solve_static(*args, **kw)

    newton = NewtonOptions(n_steps=2)
    state = cold_solve(system, soft, solve, newton=newton)
    assert calls == [True, False]  # the first stage failed, then the plain solve from zero
    plain = solve_static(system, soft, newton=newton)
    assert state.logs[0] == "the failed stage's log"  # kept before the plain solve's
    assert len(state.logs) == len(plain.logs) + 1
    np.testing.assert_allclose(state.u, plain.u, rtol=0, atol=1e-12 * np.linalg.norm(plain.u))


def test_a_staged_solve_that_fails_late_raises_with_every_stage_log():
    system = _system()
    soft = _rho(system, 0.02)
    calls = []

    def solve(*args, **kw):
        """solve_static for the first stage, a failure for every later one."""
        calls.append(kw["start"].eps)
        if len(calls) > 1:
            raise ConvergenceError("forced", [f"failed stage {len(calls)}"])
        return solve_static(*args, **kw)

    ratios = softening(system, soft, np.ones(system.disc.n_cells))
    start = State(u=np.zeros(system.disc.n_dofs), laws=system.start_states())
    with pytest.raises(ConvergenceError) as err:
        staged_solve(system, soft, start, ratios, NewtonOptions(n_steps=2), solve, newton=ONE_STEP)
    # the factor STAGE retried at its square root, and again, until it would fall below MIN_STAGE
    failures = 1 + sum(STAGE ** (0.5**k) >= MIN_STAGE for k in range(1, 10))
    assert len(calls) == 1 + failures
    first = err.value.logs[:-failures]
    assert first and all(lg.converged for lg in first)  # the first stage's converged solve is kept
    assert err.value.logs[-failures:] == [f"failed stage {k}" for k in range(2, 2 + failures)]


def test_the_stages_short_of_the_last_are_solved_loosely_the_last_to_the_tolerances():
    system = _system()
    soft = _rho(system, 0.02)
    seen = []

    def solve(*args, **kw):
        seen.append((kw["start"].eps, kw["newton"].rtol, kw["newton"].utol))
        return solve_static(*args, **kw)

    newton = NewtonOptions(n_steps=2)
    state = cold_solve(system, soft, solve, newton=newton)
    (ratio,) = softening(system, soft, np.ones(system.disc.n_cells))
    eps = system.contact.blocks[0].eps
    # from zero, the first stage FIRST times softer than the full design's relative penalty
    assert seen[0][0] == pytest.approx((eps / (FIRST * ratio),), rel=1e-12)
    assert len(seen) == math.ceil(math.log(FIRST * ratio) / math.log(STAGE)) + 1
    assert all(s[1:] == (STAGE_RTOL, STAGE_UTOL) for s in seen[:-1])
    assert seen[-1] == ((eps,), newton.rtol, newton.utol)
    # the last stage converged to the tolerances: the plain solve's equilibrium (both to rtol 1e-9 of r_ref)
    plain = solve_static(system, soft, newton=newton)
    assert state.eps == plain.eps
    assert np.linalg.norm(state.u - plain.u) <= 1e-6 * np.linalg.norm(plain.u)
