"""Force against displacement along the load path (contopt.solve.curves): the recorded numbers are
the solver's reactions and contact forces, and they grow as the bodies are pushed together."""

import numpy as np
import pytest

from contopt.cases.forward import block_compression
from contopt.cases.two_blocks import two_blocks
from contopt.solve.curves import LoadPathRecorder
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System

STEPS = 4


def _solve(model):
    system = System.of(model)
    recorder, states = LoadPathRecorder(system), []

    def on_step(state):
        recorder(state)
        states.append(state)

    newton = NewtonOptions(n_steps=STEPS, max_step=1.0 / STEPS)
    final = solve_static(system, newton=newton, on_step=on_step)
    return system, recorder.curves(), states, final


@pytest.fixture(scope="module")
def punch():
    return _solve(two_blocks(divisions=2))


def _reaction(system, body: str, node_set: str, reactions) -> np.ndarray:
    """Sum of the reactions over a node set's dofs, found from the mesh independently of the recorder."""
    model = system.disc.model
    i = model.body_index(body)
    nodes = model.bodies[i].mesh.node_set(node_set) + system.disc.blocks[i].node_offset
    return np.asarray(reactions).reshape(-1, 3)[nodes].sum(axis=0)


def test_every_converged_step_from_the_unloaded_bodies(punch):
    _, curves, states, final = punch
    t = curves["load_factor"]
    assert t[0] == 0.0 and t[1:] == [s.t for s in states] and t[-1] == pytest.approx(final.t) == 1.0
    assert len(t) == STEPS + 1
    for m in curves["motions"]:
        assert len(m["force"]) == len(m["travel"]) == len(t) and m["force"][0] == [0.0, 0.0, 0.0]
    assert [m["kind"] for m in curves["motions"]] == ["support", "motion"]


def test_the_curves_end_at_the_reactions_the_solver_reports(punch):
    system, curves, states, final = punch
    support, motion = curves["motions"]
    for step, state in enumerate(states, start=1):  # at every step, not only the last
        np.testing.assert_allclose(support["force"][step], _reaction(system, "block", "zmin", state.reactions))
        np.testing.assert_allclose(motion["force"][step], _reaction(system, "punch", "zmax", state.reactions))
    np.testing.assert_allclose(motion["force"][-1], _reaction(system, "punch", "zmax", final.reactions))
    # the punch's top is prescribed (shift, 0, -depth) * t
    np.testing.assert_allclose(motion["displacement"][-1], [0.02, 0.0, -0.06])
    assert motion["travel"][-1] == pytest.approx(np.hypot(0.02, 0.06))
    # no load but the motion: what the motion pushes in, the clamp takes out
    total = np.add(support["force"][-1], motion["force"][-1])
    assert np.abs(total).max() <= 1e-6 * np.linalg.norm(motion["force"][-1])


def test_the_contact_force_is_the_pressure_integral(punch):
    system, curves, _, final = punch
    (interface,) = curves["interfaces"]
    lam = tuple(r.lam for r in final.contact)
    assert interface["normal_force"][-1] == pytest.approx(float(system.contact.total_force(final.u, lam)[0]), rel=1e-9)
    assert "friction_force" not in interface  # frictionless
    # on this flat interface the normal force is the push the motion transmits (to the solver's tolerance)
    assert interface["normal_force"][-1] == pytest.approx(-curves["motions"][1]["force"][-1][2], rel=0.02)


def test_pushed_further_the_bodies_push_back_harder(punch):
    _, curves, _, _ = punch
    motion = curves["motions"][1]
    for values in (motion["travel"], motion["force_along"], curves["interfaces"][0]["normal_force"]):
        assert np.all(np.diff(values) > 0), values


def test_a_compressed_block_resists_its_motion():
    system, curves, states, _ = _solve(block_compression(divisions=2, strain=0.2))
    bottom, top = curves["motions"]
    assert (bottom["kind"], top["kind"]) == ("support", "motion") and curves["interfaces"] == []
    assert np.all(np.diff(top["force_along"]) > 0) and np.all(np.diff(top["travel"]) > 0)
    np.testing.assert_allclose(top["force"][-1], _reaction(system, "block", "zmax", states[-1].reactions))
    # hyperelastic compression stiffens: the secant stiffness grows along the path
    secant = np.array(top["force_along"][1:]) / np.array(top["travel"][1:])
    assert np.all(np.diff(secant) > 0), secant
