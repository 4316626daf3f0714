"""The inexact Newton's linear tolerance: Eisenstat-Walker's choice 2 and the linear model's agreement."""

import numpy as np
import pytest

from contopt.solve.forcing import EW_GAMMA, forcing_term, model_agreement
from contopt.solve.linear import LinearSolverOptions

LINEAR = LinearSolverOptions(backend="petsc", krylov_eta_max=1e-4, krylov_rtol=1e-12)


def _inexact_step(residual, u0, A, eta, rng):
    """du with |A du - rhs| = eta |rhs| (rhs = -r(u0)), and that linear residual."""
    rhs = -residual(u0)
    e = rng.standard_normal(u0.size)
    lin = eta * np.linalg.norm(rhs) * e / np.linalg.norm(e)
    du = np.linalg.solve(A, rhs + lin)
    return du, lin, rhs


@pytest.mark.parametrize("alpha", [1.0, 0.25])
def test_a_linear_residual_agrees_with_its_model_to_round_off(alpha):
    rng = np.random.default_rng(0)
    A = rng.standard_normal((30, 30)) + 30 * np.eye(30)
    b = rng.standard_normal(30)

    def residual(u):
        return A @ u - b

    u0 = np.zeros(30)
    du, lin, rhs = _inexact_step(residual, u0, A, 1e-4, rng)
    r_new = residual(u0 + alpha * du)
    assert np.linalg.norm(r_new) > 1e-6 * np.linalg.norm(rhs)  # the solve's error is all that is left
    assert model_agreement(r_new, residual(u0), lin, float(np.linalg.norm(rhs)), alpha) < 1e-13


def test_a_nonlinear_residual_departs_from_its_model_at_second_order():
    rng = np.random.default_rng(1)
    A = rng.standard_normal((30, 30)) + 30 * np.eye(30)
    b = rng.standard_normal(30)

    def residual(u):  # quadratic: the model's remainder is exactly a^2 du^2
        return A @ u + u**2 - b

    u0 = 0.1 * rng.standard_normal(30)
    J = A + np.diag(2 * u0)  # the tangent at u0
    du, lin, rhs = _inexact_step(residual, u0, J, 1e-4, rng)
    r0, scale = residual(u0), float(np.linalg.norm(rhs))
    full, half = (model_agreement(residual(u0 + a * du), r0, lin, scale, a) for a in (1.0, 0.5))
    assert full > 1e-6
    np.testing.assert_allclose(full / half, 4.0, rtol=1e-6)  # the remainder grows as a^2


def test_the_forcing_term_takes_the_tighter_measure_within_its_bounds():
    target = 1e-9
    residuals = [1.0, 1e-2]
    choice2 = EW_GAMMA * 1e-4
    assert forcing_term(LINEAR, residuals, 1e-4, target) == pytest.approx(min(choice2, 1e-4))
    # a step the linear model predicted well: tighter, down to what brings |r| to half the target
    assert forcing_term(LINEAR, residuals, 1e-4, target, agreement=1e-7) == pytest.approx(1e-7)
    assert forcing_term(LINEAR, residuals, 1e-4, target, agreement=0.0) == pytest.approx(0.5 * target / 1e-2)
    # a poor model does not loosen choice 2, and nothing goes past krylov_eta_max
    assert forcing_term(LINEAR, residuals, 1e-4, target, agreement=0.5) == pytest.approx(min(choice2, 1e-4))
    assert forcing_term(LINEAR, [1.0, 0.9], 1e-4, target, agreement=0.5) == 1e-4
    # the first iteration has no model to judge: krylov_eta_max
    assert forcing_term(LINEAR, [1.0], 1e-4, target, agreement=0.0) == 1e-4


def test_forcing_term_follows_eisenstat_walker_and_its_safeguards():
    lin = LinearSolverOptions(krylov_rtol=1e-10, krylov_eta_max=0.1)
    target = 1e-12
    assert forcing_term(lin, [1.0], 0.1, target) == 0.1  # first iteration: the loosest
    # quadratic convergence 1e-2 -> 1e-4: eta = 0.9 (1e-2)^2, and the previous eta's floor is below 0.1
    assert forcing_term(lin, [1e-2, 1e-4], 1e-3, target) == pytest.approx(EW_GAMMA * 1e-4)
    # a sudden drop after slow progress: the floor 0.9 eta_prev^2 keeps the term from collapsing
    assert forcing_term(lin, [1.0, 1e-3], 0.5, target) == pytest.approx(min(0.1, EW_GAMMA * 0.25))
    # near the target: no tighter than what halves the remaining gap, never looser than eta_max
    assert forcing_term(lin, [1e-6, 1e-11], 1e-3, target) == pytest.approx(0.5 * target / 1e-11)
    # never tighter than krylov_rtol, and "fixed" is always krylov_rtol
    assert forcing_term(lin, [1.0, 1e-9], 1e-5, 1e-30) == 1e-10
    fixed = LinearSolverOptions(forcing="fixed", krylov_rtol=1e-7)
    assert forcing_term(fixed, [1.0, 0.5], 0.1, target) == 1e-7
    # the default keeps every solve at 1e-4 or tighter (contact: Newton iterations cost more than Krylov ones)
    assert forcing_term(LinearSolverOptions(), [1.0], 0.1, target) == 1e-4
