"""Design-dependent volume loads: body forces and accelerations follow the material (mass = nu)."""

from dataclasses import replace

import numpy as np
import pytest

from contopt.adjoint.check import TIGHT_AUGMENTATION, TIGHT_NEWTON
from contopt.adjoint.sensitivity import sensitivities
from contopt.assembly.model import Acceleration, Body, Dirichlet, Model
from contopt.assembly.system import discretize
from contopt.cases.two_blocks import two_blocks
from contopt.design import BSplineGrid, Design, DesignedBody
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import box
from contopt.optimize.problem import DesignNLP, DesignProblem
from contopt.responses import Compliance, StrainEnergy
from contopt.solve.static import solve_static
from contopt.solve.system import System


def test_volume_loads_scale_with_the_mass_of_each_cell(rng):
    """Total inertia force = -a * density * sum_e mass_e V_e; tractions do not scale."""
    mesh = box((2.0, 1.0, 1.0), (4, 2, 2))
    mat = replace(neo_hookean(1.0, 0.3), mass_density=3.0)
    model = Model(
        bodies=(Body("b", mesh, mat),),
        dirichlet=(Dirichlet("b", "xmin", "xyz", 0.0),),
        loads=(Acceleration("b", (0.5, 0.0, -2.0)),),
    )
    disc = discretize(model)
    assert np.allclose(disc.f_ext(np.ones(disc.n_cells)), disc.f_ext_unit, rtol=0, atol=1e-15)
    mass = rng.uniform(0.0, 1.0, disc.n_cells)
    total = disc.f_ext(mass).reshape(-1, 3).sum(axis=0)
    volume = disc.blocks[0].volume
    assert np.allclose(total, -3.0 * np.array([0.5, 0.0, -2.0]) * (mass @ volume), rtol=1e-13)
    w = rng.normal(size=disc.n_dofs)  # the vjp is the transpose of d r/d mass = -f_volume
    dm = rng.uniform(0.0, 1.0, disc.n_cells)
    assert disc.residual_mass_vjp(w, 0.7) @ dm == pytest.approx(
        -0.7 * w @ (disc.f_ext(mass + dm) - disc.f_ext(mass)), rel=1e-12
    )


@pytest.mark.parametrize("law, tol", [("penalty", 1e-6), ("alm", 1e-5)])
def test_mass_gradient_through_contact_matches_central_differences(law, tol, rng):
    """d theta/d mass of compliance (explicit + adjoint part) and strain energy (adjoint only)."""
    prob = System.of(two_blocks(law=law, body_force=(0.0, 0.05, -0.2)))
    n = prob.disc.n_cells
    rho = rng.uniform(0.5, 1.0, n)
    mass = rng.uniform(0.3, 1.0, n)
    responses = (Compliance(), StrainEnergy())

    def solve(m):
        return solve_static(prob, rho, mass=m, newton=TIGHT_NEWTON, augmentation=TIGHT_AUGMENTATION)

    adj = sensitivities(prob, solve(mass), responses)
    v, h = rng.normal(size=n), 1e-4
    plus, minus = solve(mass + h * v), solve(mass - h * v)
    from contopt.responses.base import Fields

    for r, s in zip(responses, adj.sensitivities):
        fd = (r.value(Fields.from_state(prob, plus)) - r.value(Fields.from_state(prob, minus))) / (2 * h)
        assert abs(s.mass_gradient @ v - fd) <= tol * np.abs(s.mass_gradient * v).sum()
        assert np.abs(s.mass_gradient).max() > 0


def test_design_gradient_with_self_weight_matches_central_differences(rng):
    """Compliance under a body force on the designed block: the load follows nu, df/dx through it."""
    design = Design(DesignedBody("block", BSplineGrid((2, 2, 1)), volume_fraction=0.5))
    pb = DesignProblem(
        model=two_blocks(law="penalty", body_force=(0.0, 0.0, -0.02)),
        design=design,
        objective=Compliance(),
        newton=TIGHT_NEWTON,
        augmentation=TIGHT_AUGMENTATION,
    )
    nlp = DesignNLP(pb)
    x = nlp.space.initial() + rng.uniform(-0.05, 0.05, nlp.n)
    rec = nlp.record(x)
    fields = nlp.space.forward(x)
    assert np.allclose(nlp.last_state.mass, fields.nu)  # the solve saw the design's mass
    v, h = rng.normal(size=nlp.n), 1e-4
    fd = (nlp.record(x + h * v).f - nlp.record(x - h * v).f) / (2 * h)
    assert abs(rec.df @ v - fd) <= 1e-6 * np.abs(rec.df * v).sum()
    # the loads really depend on the design: freezing mass at ones changes the gradient
    frozen = DesignNLP(pb)
    frozen._mass = lambda fields: None
    assert not np.allclose(frozen.record(x).df, rec.df, rtol=1e-3)
