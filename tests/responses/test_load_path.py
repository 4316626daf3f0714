"""Load-path responses (contopt.responses.path; not named test_path.py, which tests/adjoint has): the
contact force read at t_k = k/steps (or at listed load factors) and combined, their values from the
contact force of every step, their gradients through the path adjoint against central differences
of the whole load-stepped solve.

The punch on the block (two_blocks, 2 cells across, penalty law), a random stiffness field on the
block, solved to rtol = utol = 1e-12 in load steps that end on t = 1/4, 1/2, 3/4, 1. With
h = 1e-5 the central differences are accurate to O(h^2) plus the solver's tolerance over h
(~1e-7 relative): the gradients must agree to 1e-6. The frictional case (the sliding block with
stick and slip) and the augmented Lagrangian are the slow tests.
"""

from dataclasses import replace

import numpy as np
import pytest

from contopt.adjoint.sensitivity import sensitivities
from contopt.cases.sliding_block import sliding_block
from contopt.cases.two_blocks import two_blocks
from contopt.contact.laws import AugmentationOptions, AugmentedLagrangian
from contopt.errors import ConfigError
from contopt.material import neo_hookean
from contopt.responses import ContactForce
from contopt.responses.base import Fields
from contopt.responses.path import ForceMax, ForceMin, ForceTarget
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System

NEWTON = NewtonOptions(rtol=1e-12, utol=1e-12, n_steps=2)
TARGET = ForceTarget([[0.0, 0.0], [0.5, 0.1], [1.0, 0.5]], steps=4)
#: the last two list their load factors: the smallest force after the first step, the force at t = 3/4 alone
LISTED = (ForceMin([0.5, 0.75, 1.0], sharpness=20.0), ForceMax([0.75], sharpness=20.0))
RESPONSES = (
    TARGET,
    ForceMax(4, sharpness=20.0),
    ForceMin(4, sharpness=20.0),
    -2.0 * TARGET + ContactForce(),
    *LISTED,
)


def _random(system, seed=1):
    rho = np.ones(system.disc.n_cells)
    n = system.model.bodies[0].mesh.n_cells
    rho[:n] = np.random.default_rng(seed).uniform(0.6, 1.0, n)
    return rho


def _solve(system, rho):
    return solve_static(system, rho, NEWTON, stops=TARGET.stops, record_path=True)


def _values(system, rho):
    fields = Fields.from_state(system, _solve(system, rho))
    return np.array([r.value(fields) for r in RESPONSES])


def _check_central_differences(system, rho, cells, rel, h=1e-5):
    sens = sensitivities(system, _solve(system, rho), RESPONSES)
    assert sens.method == "path"
    for cell in cells:
        e = np.zeros_like(rho)
        e[cell] = h
        fd = (_values(system, rho + e) - _values(system, rho - e)) / (2 * h)
        for s, d in zip(sens, fd):
            assert s.gradient[cell] == pytest.approx(d, rel=rel), (s.name, cell)


@pytest.fixture(scope="module")
def punch():
    system = System.of(two_blocks(divisions=2, law="penalty"))
    rho = _random(system)
    return system, rho, _solve(system, rho)


def test_the_solve_ends_a_step_on_every_load_factor_read(punch):
    _, _, state = punch
    assert [s.t for s in state.path] == pytest.approx([0.25, 0.5, 0.75, 1.0])  # 2 steps asked, 4 stops


def test_the_values_come_from_the_contact_force_of_every_step(punch):
    system, _, state = punch
    forces = np.array([ContactForce().value(Fields.from_state(system, s)) for s in state.path])
    assert np.all(np.diff(forces) > 0)  # pressed further, the punch pushes back harder
    fields = Fields.from_state(system, state)
    np.testing.assert_allclose(TARGET.values(fields), forces, rtol=1e-14)
    wanted = np.interp([0.25, 0.5, 0.75, 1.0], [0.0, 0.5, 1.0], [0.0, 0.1, 0.5])
    assert TARGET.value(fields) == pytest.approx(np.mean((forces - wanted) ** 2), rel=1e-12)
    s = 20.0
    assert RESPONSES[1].value(fields) == pytest.approx(np.log(np.mean(np.exp(s * forces))) / s, rel=1e-12)
    assert RESPONSES[2].value(fields) == pytest.approx(-np.log(np.mean(np.exp(-s * forces))) / s, rel=1e-12)
    # the smooth max and min lie within log(n)/s of the largest and smallest force
    assert forces.max() - np.log(4) / s <= RESPONSES[1].value(fields) <= forces.max()
    assert forces.min() <= RESPONSES[2].value(fields) <= forces.min() + np.log(4) / s


def test_listed_load_factors_read_those_steps_alone(punch):
    system, _, state = punch
    forces = np.array([ContactForce().value(Fields.from_state(system, s)) for s in state.path])  # t = 1/4 .. 1
    fields = Fields.from_state(system, state)
    s = 20.0
    assert LISTED[0].stops == (0.5, 0.75, 1.0) and LISTED[0].steps == (0.5, 0.75, 1.0)
    np.testing.assert_allclose(LISTED[0].values(fields), forces[1:], rtol=1e-14)
    assert LISTED[0].value(fields) == pytest.approx(-np.log(np.mean(np.exp(-s * forces[1:]))) / s, rel=1e-12)
    assert LISTED[1].value(fields) == pytest.approx(forces[2], rel=1e-12)  # the smooth max of one value is it


def test_listed_load_factors_off_the_steps_cut_the_solve_there(punch):
    system, rho, _ = punch
    response = ForceMax([0.3, 1.0], sharpness=20.0)
    state = solve_static(system, rho, NEWTON, stops=response.stops, record_path=True)
    times = [s.t for s in state.path]
    assert 0.3 in times and times[-1] == 1.0
    at = Fields.from_state(system, state.path[times.index(0.3)])
    assert response.values(Fields.from_state(system, state))[0] == ContactForce().value(at)


def test_frictionless_path_gradients_match_central_differences(punch):
    system, rho, _ = punch
    _check_central_differences(system, rho, (0, 5), rel=1e-6)


def test_the_earlier_steps_matter(punch, monkeypatch):
    # the target's gradient from the last step's partials alone is wrong by far more than the check's 1e-6
    import contopt.adjoint.sensitivity as sensitivity_module

    system, _, state = punch
    full = sensitivities(system, state, TARGET)[0].gradient
    original = sensitivity_module.path_partials

    def last_only(system, steps, evaluated):
        last = len(steps) - 1
        return [
            (n, (v, {k: p for k, p in parts.items() if k == last}))
            for n, (v, parts) in original(system, steps, evaluated)
        ]

    monkeypatch.setattr(sensitivity_module, "path_partials", last_only)
    cut = sensitivities(system, state, TARGET)[0].gradient
    assert np.abs(cut - full).max() > 0.1 * np.abs(full).max()


@pytest.mark.slow
def test_augmented_lagrangian_path_gradients_match_central_differences():
    # every step converged (intermediate = "converge"): the multipliers to 1e-12 relative
    options = AugmentationOptions(pressure_rtol=1e-12, gap_rtol=1e-12, inexact=0.0, intermediate="converge")
    model = two_blocks(divisions=2)
    model = replace(model, interfaces=(replace(model.interfaces[0], law=AugmentedLagrangian(options=options)),))
    system = System.of(model)
    _check_central_differences(system, _random(system), (0, 5), rel=1e-6)


@pytest.mark.slow
def test_frictional_path_gradients_match_central_differences():
    # the sliding block pressed, then dragged: 11 of its contact nodes stick at the end, the others
    # slide; h = 1e-5 flips none of them (tests/adjoint/test_path.py), and the check is theirs (1e-5)
    model = sliding_block(mu=0.3, pull=0.004)
    model = replace(model, bodies=(replace(model.bodies[0], material=neo_hookean(1.0, 0.3)), model.bodies[1]))
    system = System.of(model)
    rho = _random(system)
    stick = _solve(system, rho).contact[0].friction.stick
    assert 0 < stick.sum() < stick.size
    _check_central_differences(system, rho, (0, 17), rel=1e-5)


def test_an_augmented_lagrangian_that_converges_only_the_last_step_is_refused():
    system = System.of(two_blocks(divisions=2))
    state = _solve(system, None)
    with pytest.raises(ConfigError, match='augmentation.intermediate = "converge"'):
        sensitivities(system, state, TARGET)


def test_a_solve_that_did_not_stop_on_the_load_factors_is_refused(punch):
    system, _, _ = punch
    state = solve_static(system, newton=NewtonOptions(n_steps=3), record_path=True)
    with pytest.raises(ConfigError, match=r"reads the load step at t = 0.25.*stops=response.stops"):
        TARGET.value(Fields.from_state(system, state))
    with pytest.raises(ConfigError, match="step= is for responses of one state"):
        sensitivities(system, state, TARGET, step=-1)


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: ForceTarget([[0, 0], [1, 4]], steps=0), "steps must be a whole number of load steps >= 1"),
        (lambda: ForceTarget([[0, 0], [1, 4]], steps=2.5), "steps must be a whole number"),
        (lambda: ForceTarget([0, 1, 4], steps=4), r"target must be a list of \[load factor, force\] points"),
        (lambda: ForceTarget([[0.5, 1], [0.2, 4]], steps=4), "must have load factors that increase within"),
        (lambda: ForceTarget([[0, 1], [1.5, 4]], steps=4), "must have load factors that increase within"),
        (lambda: ForceMax([0.5, 0.25], sharpness=1.0), r"steps must be load factors that increase"),
        (lambda: ForceMax([0.0, 1.0], sharpness=1.0), r"increase within \(0, 1\]"),
        (lambda: ForceMax([0.5, 1.5], sharpness=1.0), r"increase within \(0, 1\]"),
        (lambda: ForceMin([], sharpness=1.0), r"steps must be load factors that increase"),
        (lambda: ForceMin([0.5, "one"], sharpness=1.0), r"steps must be load factors that increase"),
        (lambda: ForceMax(4, sharpness=0.0), "sharpness must be a positive number"),
        (lambda: ForceMin(4, sharpness="high"), "sharpness must be a positive number"),
    ],
)
def test_options_are_checked_at_construction(make, message):
    with pytest.raises(ConfigError, match=message):
        make()
