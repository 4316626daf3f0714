"""solve_static on a punch that starts above the block: the first load steps load nothing.

While the punch moves through the gap the whole model is unloaded (no external force, no
reaction: a rigid motion of the punch), so Newton's residual is round-off of the internal forces
from the first iteration; it must count as converged, not as stagnation. The known answer: the
model is hyperelastic and frictionless, so the end state depends on the punch's final position
only. A punch starting ``gap`` above the block and moving down by ``depth`` ends where a punch
resting on the block ends after moving down by ``depth - gap``. The model is in mm and MPa (a rubber
block, a steel punch), so that round-off of the internal forces is far above any fixed absolute
tolerance: the residual test must scale with the stiffness.
"""

import numpy as np
import pytest

from contopt.assembly.model import Body, Dirichlet, Model
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import law_named
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import box
from contopt.solve.linear import LinearSolverOptions, available_backends
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System

DEPTH = 0.6  # mm


def _punch(gap: float, depth: float, law: str) -> Model:
    block = box((10.0, 10.0, 5.0), (4, 4, 2))
    punch = box((6.0, 6.0, 4.0), (3, 3, 1), origin=(2.0, 2.0, 5.0 + gap))
    return Model(
        bodies=(Body("block", block, neo_hookean(10.0, 0.45)), Body("punch", punch, neo_hookean(210e3, 0.3))),
        dirichlet=(Dirichlet("block", "zmin", "xyz", 0.0), Dirichlet("punch", "zmax", "xyz", (0.0, 0.0, -depth))),
        interfaces=(ContactInterface(nonmortar=("punch", "zmin"), mortar=("block", "zmax"), law=law_named(law)),),
    )


def _block_energy(gap: float, depth: float, law: str, n_steps: int) -> float:
    system = System.of(_punch(gap, depth, law))
    state = solve_static(system, newton=NewtonOptions(n_steps=n_steps))
    disc = system.disc
    return float(disc.strain_energy(state.u, per_cell=True)[disc.cell_slice("block")].sum())


@pytest.mark.parametrize("law", ["alm", "penalty"])
def test_a_punch_moving_through_a_gap_ends_as_one_resting_on_the_block(law):
    gap = 0.5 * DEPTH
    # 4 steps of depth / 4: the first two only close the gap (the second ends at first touch), the
    # last two indent
    moved = _block_energy(gap, DEPTH, law, n_steps=4)
    resting = _block_energy(0.0, DEPTH - gap, law, n_steps=2)
    assert moved > 0.0
    # both solves stop at Newton's rtol 1e-9 of the reactions: energies agree far below 1e-6
    np.testing.assert_allclose(moved, resting, rtol=1e-6)


def test_a_contact_response_of_a_state_without_contact_is_a_clear_error():
    """The punch stops short of the block: the relative pressure variance (var / mean^2) is 0 / 0."""
    from contopt.errors import ConfigError
    from contopt.responses import Fields, PressureVariance

    system = System.of(_punch(2 * DEPTH, DEPTH, "alm"))
    state = solve_static(system, newton=NewtonOptions(n_steps=1))
    assert state.contact[0].n_active == 0
    with pytest.raises(ConfigError, match="'pressure_relative_variance' is undefined .* no node is in contact"):
        PressureVariance(normalized=True).evaluate(Fields.from_state(system, state))


@pytest.mark.skipif("petsc" not in available_backends(), reason="PETSc is not installed (the petsc extra)")
def test_an_iterative_solver_moves_the_punch_through_the_gap_in_one_iteration_a_step():
    # each step's first Krylov solve starts from the last step's increment, which for the rigid
    # motion through the gap is the answer: no Krylov iteration, one Newton iteration, as with a
    # direct solver (from zero, an inexact first solve left 1e-4 of the step's forces and cost
    # two or more further Newton iterations a step)
    system = System.of(_punch(2 * DEPTH, DEPTH, "alm"))
    # each step taken (no leap over the free flight, contopt.solve.freeflight): the steps are what is tested
    newton = NewtonOptions(n_steps=4, leap=False)
    direct = solve_static(system, newton=newton)
    state = solve_static(system, newton=newton, linear=LinearSolverOptions(backend="petsc"))
    assert state.contact[0].n_active == 0 and len(state.logs) == 4
    assert [lg.iterations for lg in direct.logs] == [1, 1, 1, 1]
    assert [lg.iterations for lg in state.logs[1:]] == [1, 1, 1]
    assert [lg.krylov for lg in state.logs[1:]] == [(0,), (0,), (0,)]
    # the later steps repeat the first step's increment, a Krylov solve to a relative residual of
    # 1e-10 (krylov_rtol): its displacement error is that times the tangent's condition number
    # (measured 1e-9..2e-9 of |u|, depending on GAMG's aggregation), whatever the solver did before
    np.testing.assert_allclose(state.u, direct.u, atol=1e-6 * np.abs(direct.u).max())


def _failing_after_update(monkeypatch, after: int):
    """solve_static whose Newton solves after the ``after``-th multiplier update of the final load step
    fail (as one stagnating at round-off would); returns the number of Newton solves tried."""
    import contopt.solve.static as static
    from contopt.solve.newton import StepFailure
    from contopt.solve.newton import newton_step as real

    calls: list[float] = []

    def newton_step(evaluate, u0, free, constrained, target, t, *args, **kwargs):
        u, lg, ev = real(evaluate, u0, free, constrained, target, t, *args, **kwargs)
        calls.append(t)
        if t == 1.0 and calls.count(1.0) > after:
            raise StepFailure("Newton stagnated (|r| = 1e-8 after 10 iterations)", lg)
        return u, lg, ev

    monkeypatch.setattr(static, "newton_step", newton_step)
    return calls


def test_a_newton_failure_after_the_updates_is_settled_not_cut_back(monkeypatch, caplog):
    from contopt.cases.two_blocks import two_blocks
    from contopt.contact.laws import AugmentationOptions
    from contopt.errors import ConvergenceError

    calls = _failing_after_update(monkeypatch, after=3)
    with pytest.raises(ConvergenceError) as info:
        solve_static(two_blocks(), augmentation=AugmentationOptions(pressure_rtol=1e-10, gap_rtol=1e-10))
    message = str(info.value)
    assert "Newton failed after multiplier update 3" in message and "a shorter load step" in message
    assert "newton.n_steps" not in message and "\n" not in message
    # three converged solves, the failing one and its retry at the penalty before it grew; no cutback
    assert calls == [1.0] * len(calls) and len(calls) <= 5
    # near its targets the last converged solve is the state (a warning says so)
    calls = _failing_after_update(monkeypatch, after=3)
    with caplog.at_level("WARNING", logger="contopt.contact.laws"):
        state = solve_static(two_blocks(), augmentation=AugmentationOptions(pressure_rtol=1e-2, gap_rtol=1e-2))
    assert state.t == 1.0 and calls == [1.0] * len(calls) and len(calls) <= 5
    assert any("the last converged solve" in r.getMessage() for r in caplog.records)
    assert state.evaluation is not None and state.contact[0].n_active > 0


@pytest.mark.parametrize("law", ["alm", "penalty"])
def test_no_earlier_tangent_is_alive_while_a_contact_solve_factors_one(monkeypatch, law):
    """While Newton factors a tangent, no earlier evaluation's tangent is alive: neither the load step's
    starting one (the contact-aware predictor's) nor the last one of the solve before a multiplier
    update (both were, 20 MB of the Hertz line's peak at Kratos' size: docs/performance.md)."""
    import gc
    import weakref

    import contopt.solve.newton as newton

    tangents: list = []
    real_evaluate, real_factorize = System.evaluate, newton.factorize

    def evaluate(self, *args, **kwargs):
        ev = real_evaluate(self, *args, **kwargs)
        if ev.K_free is not None:
            tangents.append(weakref.ref(ev.K_free))
        return ev

    alive: list[int] = []

    def factorize(K, *args, **kwargs):
        gc.collect()
        alive.append(sum(1 for ref in tangents if ref() is not None and ref() is not K))
        return real_factorize(K, *args, **kwargs)

    monkeypatch.setattr(System, "evaluate", evaluate)
    monkeypatch.setattr(newton, "factorize", factorize)
    state = solve_static(System.of(_punch(0.0, DEPTH, law)), newton=NewtonOptions(n_steps=2))
    assert state.t == 1.0 and len(alive) >= 4
    if law == "alm":
        assert state.alm_updates > 0  # the solves after an update are covered
    assert alive == [0] * len(alive)
