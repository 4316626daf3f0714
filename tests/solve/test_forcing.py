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
