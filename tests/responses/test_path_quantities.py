"""Load-path responses on other quantities than the contact force (``on``: a support's or a motion's
reaction, a node set's mean displacement, the strain energy): their values from the solve's own
reactions, displacements and energies at every step, and their gradients through the path adjoint
against central differences of the whole load-stepped solve (tests/responses/test_load_path.py's
setting: solved to rtol = utol = 1e-12, h = 1e-5, the gradients to 1e-6; with friction 1e-5)."""

from dataclasses import replace

import numpy as np
import pytest

from contopt.adjoint.sensitivity import sensitivities
from contopt.assembly.model import Body, Dirichlet, Model, RigidMotion
from contopt.cases.sliding_block import sliding_block
from contopt.cases.two_blocks import two_blocks
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import law_named
from contopt.errors import ConfigError
from contopt.material import neo_hookean
from contopt.mesh.generators import box
from contopt.mesh.tool import plane_surface, tool_layer
from contopt.responses import ContactForce, MeanDisplacement, Reaction
from contopt.responses.base import Fields
from contopt.responses.path import ForceMax, ForceMin, ForceTarget
from contopt.solve.curves import conditions
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System

NEWTON = NewtonOptions(rtol=1e-12, utol=1e-12, n_steps=2)
RESPONSES = (
    ForceTarget([[0.0, 0.0], [1.0, 0.3]], steps=4, on="reaction", bodies="punch"),  # along the punch's motion
    ForceMax(4, sharpness=20.0, on="reaction", bodies="block", direction=[0.0, 0.0, 1.0], name="support"),
    ForceMin(4, sharpness=200.0, on="displacement", bodies="block", set="zmax", direction=[0.0, 0.0, -1.0]),
    ForceTarget([[0.0, 0.0], [1.0, 0.01]], steps=4, on="energy", bodies="block", name="energy"),
)
STOPS = RESPONSES[0].stops


def _random(system, seed=1):
    rho = np.ones(system.disc.n_cells)
    n = system.model.bodies[0].mesh.n_cells
    rho[:n] = np.random.default_rng(seed).uniform(0.6, 1.0, n)
    return rho


def _solve(system, rho):
    return solve_static(system, rho, NEWTON, stops=STOPS, record_path=True)


def _values(system, rho, responses):
    fields = Fields.from_state(system, _solve(system, rho))
    return np.array([r.value(fields) for r in responses])


def _check_central_differences(system, rho, cells, responses, rel, h=1e-5):
    sens = sensitivities(system, _solve(system, rho), responses)
    assert sens.method == "path"
    for cell in cells:
        e = np.zeros_like(rho)
        e[cell] = h
        fd = (_values(system, rho + e, responses) - _values(system, rho - e, responses)) / (2 * h)
        for s, d in zip(sens, fd):
            assert s.gradient[cell] == pytest.approx(d, rel=rel), (s.name, cell)


@pytest.fixture(scope="module")
def punch():
    system = System.of(two_blocks(divisions=2, law="penalty"))
    rho = _random(system)
    return system, rho, _solve(system, rho)


def test_the_values_are_the_solves_reactions_displacements_and_energies(punch):
    system, rho, state = punch
    fields = Fields.from_state(system, state)
    held = {c.bc.body: c for c in conditions(system)}  # one condition a body here
    motion = np.array([0.02, 0.0, -0.06]) / np.hypot(0.02, 0.06)
    disc = system.disc
    top = disc.blocks[0].node_offset + system.model.bodies[0].mesh.node_set("zmax")
    expected = {
        "punch": [held["punch"].force(s.reactions) @ motion for s in state.path],
        "block": [held["block"].force(s.reactions)[2] for s in state.path],
        "down": [-s.u.reshape(-1, 3)[top, 2].mean() for s in state.path],
        "energy": [disc.strain_energy(s.u, rho, per_cell=True)[disc.cell_slice("block")].sum() for s in state.path],
    }
    # the reactions of the solve's own residual (State.reactions), evaluated again: to round-off
    for r, key in zip(RESPONSES, expected):
        np.testing.assert_allclose(r.values(fields), expected[key], rtol=1e-10, err_msg=key)
    assert np.all(np.diff(expected["punch"]) > 0) and expected["punch"][0] > 0  # pressed harder, pushing back
    # the punch's support carries what the contact carries, the block's support too (no other load)
    contact = [ContactForce(direction=[0.0, 0.0, 1.0]).value(Fields.from_state(system, s)) for s in state.path]
    np.testing.assert_allclose(expected["block"], contact, rtol=1e-6)  # Newton's tolerance, with margin


def test_frictionless_path_gradients_match_central_differences(punch):
    system, rho, _ = punch
    _check_central_differences(system, rho, (0, 5), RESPONSES, rel=1e-6)


def _plate(law="penalty"):
    """The block under a rigid plate moved down 0.06: the plate's support holds contact nodes only."""
    plate = tool_layer(plane_surface((0.5, 0.5, 0.5), (0.0, 0.0, -1.0), 0.6, (3, 3)))
    return Model(
        bodies=(
            Body("block", box((1.0, 1.0, 0.5), (2, 2, 1)), neo_hookean(1.0, 0.3)),
            Body("plate", plate, rigid=RigidMotion(translation=(0.01, 0.0, -0.06))),
        ),
        dirichlet=(Dirichlet("block", "zmin", "xyz", 0.0),),
        interfaces=(ContactInterface(("block", "zmax"), ("plate", "surface"), law=law_named(law)),),
    )


def test_a_rigid_tools_reaction_is_the_contact_force_and_its_gradient_passes():
    """The rigid plate's reaction is its contact terms alone (the layer stores no energy): the force
    the block exerts on it, along the motion; its partials by u and lam from the interface's tangent."""
    system = System.of(_plate())
    rho = _random(system)
    responses = (
        ForceTarget([[0.0, 0.0], [1.0, 0.2]], steps=4, on="reaction", bodies="plate"),
        ForceMax(4, sharpness=50.0, on="reaction", bodies="plate", direction=[0.0, 0.0, -1.0], name="down"),
    )
    state = _solve(system, rho)
    fields = Fields.from_state(system, state)
    exchanged = [ContactForce(direction=[0.0, 0.0, 1.0]).value(Fields.from_state(system, s)) for s in state.path]
    assert np.all(np.asarray(exchanged) > 0)
    np.testing.assert_allclose(responses[1].values(fields), exchanged, rtol=1e-12)
    _check_central_differences(system, rho, (0, 3), responses, rel=1e-6)


@pytest.mark.slow
def test_frictional_path_gradients_match_central_differences():
    # the sliding block pressed, then dragged (test_load_path's frictional case): the drag's reaction
    # on the block's top (along the motion at the end, and along x), its displacement and its energy
    model = sliding_block(mu=0.3, pull=0.004)
    model = replace(model, bodies=(replace(model.bodies[0], material=neo_hookean(1.0, 0.3)), model.bodies[1]))
    system = System.of(model)
    rho = _random(system)
    responses = (
        ForceTarget([[0.0, 0.0], [1.0, 0.01]], steps=4, on="reaction", bodies="block"),
        ForceMax(4, sharpness=500.0, on="reaction", bodies="block", direction=[1.0, 0.0, 0.0], name="drag"),
        ForceMin(4, sharpness=500.0, on="displacement", bodies="block", set="zmin", direction=[1.0, 0.0, 0.0]),
        ForceTarget([[0.0, 0.0], [1.0, 1e-4]], steps=4, on="energy", name="energy"),
    )
    stick = _solve(system, rho).contact[0].friction.stick
    assert 0 < stick.sum() < stick.size
    _check_central_differences(system, rho, (0, 17), responses, rel=1e-5)


def test_a_reaction_on_nodes_of_a_frictional_contact_is_refused():
    model = sliding_block(mu=0.3)
    model = replace(model, dirichlet=(*model.dirichlet, Dirichlet("base", "zmax", "z", 0.0)))
    system = System.of(model)
    with pytest.raises(ConfigError, match="holds nodes of the frictional contact .*away from it"):
        Reaction("base", set="zmax", direction=[0.0, 0.0, 1.0]).check(system)
    Reaction("base", set="zmin", direction=[0.0, 0.0, 1.0]).check(system)  # away from it: fine


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: ForceMax(4, 1.0, on="stress"), r"ForceMax.on must be one of \('contact', 'reaction'"),
        (lambda: ForceMax(4, 1.0, on="reaction"), 'ForceMax.bodies must name one body with on = "reaction"'),
        (lambda: ForceMax(4, 1.0, on="reaction", bodies=["a", "b"]), "must name one body"),
        (lambda: ForceMax(4, 1.0, on="energy", set="top"), 'ForceMax.set is not read with on = "energy"'),
        (lambda: ForceMax(4, 1.0, bodies="block"), 'ForceMax.bodies is not read with on = "contact"'),
        (lambda: ForceMax(4, 1.0, on="reaction", bodies="b", quadrature="gauss"), "quadrature is not read"),
        (lambda: ForceTarget([[0, 0]], 4, on="displacement", bodies="b", set="s"), "direction is needed"),
        (lambda: ForceTarget([[0, 0]], 4, on="displacement", bodies="b", direction=[0, 0, 1]), "set is needed"),
        (lambda: Reaction("b", direction=[0, 0, 0]), r"Reaction.direction must be a nonzero vector"),
        (lambda: MeanDisplacement("b", "s", "norm"), r"MeanDisplacement.direction must be a nonzero vector"),
    ],
)
def test_options_are_checked_at_construction(make, message):
    with pytest.raises(ConfigError, match=message):
        make()


def test_the_body_and_its_support_are_checked_against_the_model(punch):
    system = punch[0]
    for response, message in (
        (Reaction("nope"), "body 'nope' is not a body of the model"),
        (
            Reaction("punch", set="zmin"),
            r"no support or prescribed motion on set 'zmin'; its sets with one: \['zmax'\]",
        ),
        (Reaction("block"), "the support of body 'block' does not move; give direction"),
        (MeanDisplacement("block", "top", [0, 0, 1]), "body 'block': unknown node set 'top'"),
    ):
        with pytest.raises(ConfigError, match=message):
            response.check(system)
