"""The path adjoint through Coulomb friction against central finite differences of the whole
load-stepped solve (contopt.adjoint.path, reached through the one entry ``sensitivities``).

The sliding block (nu = 0.3: pressing spreads its base, friction holds it, the edges slip) dragged a
little: at the end 11 of its 25 contact nodes stick and 14 slide. The design is a random stiffness
field on the block. The perturbation h = 1e-5 flips no node between stick and slip (checked: the
flags are compared), so the solve is smooth in rho there; central differences are then accurate to
O(h^2) plus the solver's tolerance over h (~1e-9 relative).
"""

import numpy as np
import pytest

from contopt.adjoint.sensitivity import sensitivities
from contopt.cases.sliding_block import sliding_block
from contopt.contact.laws import AugmentationOptions, AugmentedLagrangian
from contopt.errors import ConfigError
from contopt.material import neo_hookean
from contopt.responses import ContactForce, FrictionForce, StrainEnergy
from contopt.responses.base import Fields
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import State, solve_static
from contopt.solve.system import System

NEWTON = NewtonOptions(rtol=1e-12, utol=1e-12, n_steps=4)
RESPONSES = (StrainEnergy(bodies="block"), ContactForce(), FrictionForce((1.0, 0.0, 0.0)))


def _model(law="penalty"):
    from dataclasses import replace

    model = sliding_block(mu=0.3, pull=0.004, law=law)
    return replace(model, bodies=(replace(model.bodies[0], material=neo_hookean(1.0, 0.3)), model.bodies[1]))


def _alm_model():
    # multipliers converged to 1e-12 relative (or accepted where round-off stalls them within 100x):
    # over h = 1e-4 that leaves the differences of the pressure-borne responses ~1e-7 relative
    from dataclasses import replace

    model = _model()
    law = AugmentedLagrangian(options=AugmentationOptions(pressure_rtol=1e-12, gap_rtol=1e-12, inexact=0.0))
    return replace(model, interfaces=(replace(model.interfaces[0], law=law),))


@pytest.fixture(scope="module")
def path():
    system = System.of(_model())
    rho = _random_block(system, 1)
    state = solve_static(system, rho, NEWTON)
    return system, rho, state


def _random_block(system, seed):
    rho = np.ones(system.disc.n_cells)
    n_block = system.model.bodies[0].mesh.n_cells
    rho[:n_block] = np.random.default_rng(seed).uniform(0.6, 1.0, n_block)
    return rho


def _values(system, rho, step=-1):
    state = solve_static(system, rho, NEWTON).path[step]
    fields = Fields.from_state(system, state)
    return np.array([r.evaluate(fields, gradient=True)[0] for r in RESPONSES]), state.contact[0].friction.stick


def _check_central_differences(system, rho, state, cells, stick, h=1e-5, step=None):
    """The path adjoint's gradients of RESPONSES (at load ``step``, default the last) in ``cells``
    against central differences (1e-5), where neither perturbation flips a node between stick and
    slip (``stick``: the flags at rho)."""
    sens = sensitivities(system, state, RESPONSES, step=step)
    for cell in cells:
        e = np.zeros_like(rho)
        e[cell] = h
        at = -1 if step is None else step
        (plus, stick_p), (minus, stick_m) = _values(system, rho + e, at), _values(system, rho - e, at)
        assert np.array_equal(stick_p, stick) and np.array_equal(stick_m, stick)
        fd = (plus - minus) / (2 * h)
        for s, d in zip(sens, fd):
            assert s.gradient[cell] == pytest.approx(d, rel=1e-5), (s.name, cell)


def test_the_path_adjoint_through_stick_and_slip_matches_central_differences(path):
    system, rho, state = path
    res = state.contact[0]
    active = res.lam > 0
    assert 5 <= res.friction.stick[active].sum() <= active.sum() - 5  # both stick and slip
    assert len(state.path) == NEWTON.n_steps and state.path[-1].t == 1.0  # recorded by the solve itself
    assert sensitivities(system, state, RESPONSES).method == "path"
    _check_central_differences(system, rho, state, (0, 17), res.friction.stick)


def test_a_response_at_an_earlier_load_step_matches_central_differences(path):
    # the responses at the third of four load steps: the adjoint runs back from there, and the last
    # step (which changes the final state) does not enter. h = 3e-5: at the second step the friction
    # force is small, and its differences measure the solves' round-off over h (1e-4 at h = 1e-5)
    system, rho, state = path
    step = state.path[2]
    assert step.t == pytest.approx(0.75) and np.abs(step.u - state.u).max() > 0.1 * np.abs(state.u).max()
    _check_central_differences(system, rho, state, (0, 17), step.contact[0].friction.stick, h=3e-5, step=2)


def test_a_path_that_starts_out_of_contact_matches_central_differences():
    # the block starts 0.012 above the base and is pressed 0.02: the first load step (0.01) closes
    # no contact, so that step has no friction terms while the later ones do
    from dataclasses import replace

    model = sliding_block(mu=0.3, pull=0.004, press=0.02)
    block = model.bodies[0]
    lifted = replace(block.mesh, points=block.mesh.points + np.array([0.0, 0.0, 0.012]))
    model = replace(model, bodies=(replace(block, mesh=lifted, material=neo_hookean(1.0, 0.3)), model.bodies[1]))
    system = System.of(model)
    rho = np.ones(system.disc.n_cells)
    n_block = block.mesh.n_cells
    rho[:n_block] = np.random.default_rng(2).uniform(0.6, 1.0, n_block)
    state = solve_static(system, rho, NEWTON)
    assert state.path[0].contact[0].friction is None and state.contact[0].friction is not None
    _check_central_differences(system, rho, state, (3, 20), state.contact[0].friction.stick)


def test_the_history_terms_matter_here(path, monkeypatch):
    # without the coupling through the last step's positions and tractions the gradients move by
    # 0.06-0.7 %: the check above would fail at 1e-5
    import contopt.adjoint.path as path_module

    system, _, state = path
    full = sensitivities(system, state, RESPONSES[0])[0].gradient
    monkeypatch.setattr(path_module, "_per_node", lambda M, v: np.zeros(M.shape[0] * M.shape[2]))
    cut = sensitivities(system, state, RESPONSES[0])[0].gradient
    block = slice(0, system.model.bodies[0].mesh.n_cells)
    assert np.abs(cut[block] - full[block]).max() > 1e-4 * np.abs(full[block]).max()


@pytest.fixture(scope="module")
def alm_path():
    system = System.of(_alm_model())
    rho = _random_block(system, 1)
    return system, rho, solve_static(system, rho, NEWTON)


def test_the_path_adjoint_with_the_augmented_lagrangian_matches_central_differences(alm_path):
    # the same press and drag with the augmented Lagrangian: every load step converges its
    # multipliers, and the adjoint holds the active gaps at zero step by step, the tractions'
    # dependence on the pressures included (contopt.adjoint.path)
    system, rho, state = alm_path
    res = state.contact[0]
    active = res.lam > 0
    assert 5 <= res.friction.stick[active].sum() <= active.sum() - 5  # both stick and slip
    assert state.alm_updates > len(state.path)  # multipliers updated within the steps
    # the penetration the multipliers leave is round-off: the constraint, not a penalty, carries the pressure
    assert np.max(np.maximum(-res.g[active] / res.a[active], 0.0)) < 1e-10 * 0.125
    _check_central_differences(system, rho, state, (17,), res.friction.stick, h=1e-4)


def test_without_the_pressure_terms_the_augmented_lagrangian_gradients_are_wrong(alm_path, monkeypatch):
    # the tractions' dependence on the multipliers (P = dt/dlam in the constraint rows and their
    # right-hand side) moves the gradients by far more than the check above allows
    import contopt.adjoint.path as path_module

    system, _, state = alm_path
    full = sensitivities(system, state, RESPONSES)
    given = path_module.pressure_derivative
    monkeypatch.setattr(path_module, "pressure_derivative", lambda *args: given(*args) * 0.0)
    cut = sensitivities(system, state, RESPONSES)
    block = slice(0, system.model.bodies[0].mesh.n_cells)
    moved = max(
        np.abs(c.gradient[block] - f.gradient[block]).max() / np.abs(f.gradient[block]).max() for c, f in zip(cut, full)
    )
    assert moved > 1e-3


def test_the_adjoint_needs_the_recorded_path(path):
    system, _, state = path
    with pytest.raises(ConfigError, match="needs the load steps of the solve"):
        sensitivities(system, State(u=state.u), RESPONSES[0])
    with pytest.raises(ConfigError, match="recorded load steps, got 4"):
        sensitivities(system, state, RESPONSES[0], step=4)


@pytest.mark.slow
def test_the_friction_clamp_design_gradient_matches_central_differences():
    # the whole chain from the design variables through the filter, the Heaviside projection, SIMP and
    # the path adjoint (what `contopt check-gradient friction-clamp` prints)
    from contopt.cases.checks import check_design_case

    check = check_design_case("friction-clamp", n_random=1)
    assert check.passed, check.table()


def test_a_check_row_at_a_stick_slip_flip_is_a_kink_not_a_pass_of_a_wrong_derivative(path):
    from contopt.adjoint.check import CheckRow, GradientCheck, stick_flags

    _, _, state = path
    codes = stick_flags(state)
    res = state.contact[0]
    last = codes[-len(res.lam) :]
    np.testing.assert_array_equal(last == 1, res.friction.stick)
    np.testing.assert_array_equal(last == 2, (np.abs(res.traction).sum(axis=1) > 0) & ~res.friction.stick)
    assert len(codes) == len(state.path) * len(res.lam)

    def check(*rows):
        return GradientCheck(rows=rows, tol=1e-5, h=1e-3, h_cell=1e-2, stencil=4, adjoint=None, state=state)

    good = CheckRow("f", "cell 1", 1.0, 1.0, 1e-9, True)
    wrong = CheckRow("f", "cell 2", 1.0, 1.1, 0.1, False)
    kink = CheckRow("f", "cell 3", 1.0, 1.1, 0.1, False, kink=True)
    assert check(good, kink).passed and check(good, kink).max_rel_error == 1e-9
    assert "(kink: a stick/slip flip along the path)" in check(good, kink).table()
    assert not check(good, wrong, kink).passed and check(good, wrong).max_rel_error == 0.1
