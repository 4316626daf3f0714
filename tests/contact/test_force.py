"""The force the bodies exchange, read as the resultant of the interface's residual forces
(``ContactForce(direction=...)``): the block's support reaction where the interface is the only load
path, on a curved, coarse contact where the pressure integral is not; its gradient is exact."""

import numpy as np
import pytest
from _meshing import roller_on_block  # tests/contact/_meshing.py

from contopt.adjoint.check import check_gradient
from contopt.contact.laws import AugmentationOptions, AugmentedLagrangian, Penalty
from contopt.errors import ConfigError
from contopt.responses import ContactForce, Fields
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System

TIGHT = NewtonOptions(rtol=1e-12, n_steps=2)
ALM = AugmentedLagrangian(options=AugmentationOptions(pressure_rtol=1e-10, gap_rtol=1e-10))


@pytest.fixture(scope="module", params=["penalty", "alm"])
def solved(request):
    system = System.of(roller_on_block(Penalty() if request.param == "penalty" else ALM))
    state = solve_static(system, newton=TIGHT)
    assert state.contact[0].n_active >= 2
    return system, state


def test_the_exchanged_force_is_the_support_reaction_where_the_pressure_integral_is_not(solved):
    system, state = solved
    fields = Fields.from_state(system, state)
    # the block is held at its bottom only: what it takes there is what the roller gives it
    reaction = -state.reactions[system.disc.body_slice("block")].reshape(-1, 3).sum(axis=0)
    scale = np.linalg.norm(reaction)
    # Newton's residual (rtol 1e-12 of the reference force) is all that separates the two
    for k in (0, 2):
        e = np.eye(3)[k]
        assert abs(ContactForce(direction=e).value(fields) - abs(reaction[k])) <= 1e-8 * scale
    assert abs(ContactForce(direction="norm").value(fields) - scale) <= 1e-8 * scale
    assert abs(reaction[0]) > 0.05 * scale  # the slide tilts the force: a check of direction, not only size
    # the pressure integral adds nodal forces without their directions over a coarse, curved contact
    assert abs(ContactForce().value(fields) - abs(reaction[2])) > 1e-3 * scale


@pytest.mark.parametrize("law, tol", [(Penalty(), 1e-6), (ALM, 1e-5)], ids=["penalty", "alm"])
@pytest.mark.parametrize("direction", [[0.0, 0.0, 1.0], "norm"], ids=["along", "norm"])
def test_exchanged_force_gradient_matches_finite_differences(law, tol, direction):
    system = System.of(roller_on_block(law))
    cells = np.arange(system.disc.n_cells)[system.disc.cell_slice("block")]
    rho = np.ones(system.disc.n_cells)
    rho[cells] = np.random.default_rng(3).uniform(0.5, 1.0, cells.size)
    report = check_gradient(
        system,
        ContactForce(direction=direction),
        rho=rho,
        cells=cells,
        n_random=1,
        n_cells=3,
        h=1e-4,
        h_cell=1e-3,
        tol=tol,
        stencil=2,
        newton=TIGHT,
    )
    assert report.passed, report.table()


def test_a_direction_is_a_nonzero_vector_or_the_norm():
    for bad in ([0.0, 0.0, 0.0], [1.0, 2.0], "up", [np.nan, 0.0, 1.0]):
        with pytest.raises(ConfigError, match="direction"):
            ContactForce(direction=bad)
    np.testing.assert_allclose(ContactForce(direction=[0.0, 3.0, 4.0]).direction, [0.0, 0.6, 0.8])


def test_the_exchanged_force_needs_the_law_states_and_a_frictionless_interface(solved):
    system, state = solved
    fields = Fields.from_state(system, state)
    bare = Fields(system=system, u=fields.u, rho=fields.rho, lam=fields.lam)
    with pytest.raises(ConfigError, match="Fields.from_state"):
        ContactForce(direction="norm").value(bare)
    rough = System.of(roller_on_block(Penalty(), friction=0.3))
    frictional = Fields(system=rough, u=fields.u, rho=fields.rho, lam=fields.lam, laws=fields.laws)
    with pytest.raises(ConfigError, match="frictionless"):
        ContactForce(direction="norm").value(frictional)


def _tet10_roller_on_block():
    """``roller_on_block`` with the block cut into tet10s: its flat top nonmortar in tri6 faces (the
    quadratic kernels) under the curved hex8 roller."""
    from dataclasses import replace

    from contopt.mesh.tets import tetrahedralize

    model = roller_on_block(Penalty())
    block = model.bodies[0]
    return replace(model, bodies=(replace(block, mesh=tetrahedralize(block.mesh, 2)), model.bodies[1]))


@pytest.mark.slow  # 60-100 s on an idle 2-core machine
def test_the_exchanged_force_through_tet10_faces_is_the_support_reaction_and_its_gradient_is_exact():
    system = System.of(_tet10_roller_on_block())
    assert system.contact.blocks[0].parents.kinds == ("tri6", "quad")
    state = solve_static(system, newton=TIGHT)
    assert state.contact[0].n_active >= 2
    fields = Fields.from_state(system, state)
    reaction = -state.reactions[system.disc.body_slice("block")].reshape(-1, 3).sum(axis=0)
    scale = np.linalg.norm(reaction)
    for k in (0, 2):
        assert abs(ContactForce(direction=np.eye(3)[k]).value(fields) - abs(reaction[k])) <= 1e-8 * scale
    assert abs(reaction[0]) > 0.01 * scale  # measured 3.4 %: a check of the direction too
    cells = np.arange(system.disc.n_cells)[system.disc.cell_slice("block")]
    rho = np.ones(system.disc.n_cells)
    rho[cells] = np.random.default_rng(3).uniform(0.5, 1.0, cells.size)
    for response in (ContactForce(direction=[0.0, 0.0, 1.0]), ContactForce()):
        report = check_gradient(
            system,
            response,
            rho=rho,
            cells=cells,
            n_random=1,
            n_cells=2,
            h=1e-4,
            h_cell=1e-3,
            tol=1e-6,
            stencil=2,
            newton=TIGHT,
        )
        assert report.passed, report.table()
