"""The path adjoint through Coulomb friction on tet10 faces against central finite differences of the
whole load-stepped solve: the sliding block of ``test_path.py`` coarsened to 2 x 2 x 1 cells and cut
into tet10s (its contact face tri6 on the hex8 base: the quadratic slip kernels), with a random
stiffness field on it. The responses: strain energy, the pressure integral and the friction force;
a perturbation flips no node between stick and slip (the flags are compared)."""

from dataclasses import replace

import numpy as np
import pytest

from contopt.adjoint.sensitivity import sensitivities
from contopt.cases.sliding_block import sliding_block
from contopt.material import neo_hookean
from contopt.mesh.tets import tetrahedralize
from contopt.responses import ContactForce, FrictionForce, StrainEnergy
from contopt.responses.base import Fields
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System

NEWTON = NewtonOptions(rtol=1e-12, utol=1e-12, n_steps=3)
RESPONSES = (StrainEnergy(bodies="block"), ContactForce(), FrictionForce((1.0, 0.0, 0.0)))


def _values(system, rho):
    state = solve_static(system, rho, NEWTON)
    fields = Fields.from_state(system, state)
    return np.array([r.evaluate(fields, gradient=True)[0] for r in RESPONSES]), state.contact[0].friction.stick


@pytest.mark.slow  # 60-100 s on an idle 2-core machine
def test_the_path_adjoint_through_friction_on_tet10_faces_matches_central_differences():
    model = sliding_block(divisions=2, mu=0.3, pull=0.004)
    block = model.bodies[0]
    block = replace(block, mesh=tetrahedralize(block.mesh, 2), material=neo_hookean(1.0, 0.3))
    system = System.of(replace(model, bodies=(block, model.bodies[1])))
    assert system.contact.blocks[0].parents.kinds == ("tri6", "quad")
    rho = np.ones(system.disc.n_cells)
    n_block = block.mesh.n_cells
    rho[:n_block] = np.random.default_rng(1).uniform(0.6, 1.0, n_block)
    state = solve_static(system, rho, NEWTON)
    res = state.contact[0]
    active = res.lam > 0
    assert active.sum() >= 9 and res.friction.stick[active].any() and not res.friction.stick[active].all()
    sens = sensitivities(system, state, RESPONSES)
    assert sens.method == "path"
    h = 1e-5
    for cell in (0, 7):
        e = np.zeros_like(rho)
        e[cell] = h
        (plus, stick_p), (minus, stick_m) = _values(system, rho + e), _values(system, rho - e)
        assert np.array_equal(stick_p, res.friction.stick) and np.array_equal(stick_m, res.friction.stick)
        fd = (plus - minus) / (2 * h)
        for s, d in zip(sens, fd):
            assert s.gradient[cell] == pytest.approx(d, rel=1e-5), (s.name, cell)
