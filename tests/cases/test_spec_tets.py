"""A problem file whose body is a tet10 mesh file: read, summarized, solved and designed like hex8."""

import numpy as np
import pytest

from contopt.cases.problem_summary import model_summary
from contopt.cases.spec import load_spec
from contopt.mesh import box, tetrahedralize, write_mesh
from contopt.solve.static import solve_static

PROBLEM = """
name = "tet-beam"

[[bodies]]
name = "beam"
mesh = { file = "beam.msh" }
material = { model = "neo-hookean", E = 1.0, nu = 0.3 }

[[bodies.sets]]
name = "tip"
from = "xmax"
y = [0.0, 0.5]

[[supports]]
body = "beam"
set = "xmin"
components = "xyz"

[[loads]]
type = "traction"
body = "beam"
set = "tip"
traction = [0.0, -1e-3, 0.0]

[[design.bodies]]
body = "beam"
volume_fraction = 0.4
density = { radius = 0.6 }

[objective]
response = "compliance"
"""


def test_a_tet10_mesh_file_in_a_problem_file(tmp_path):
    mesh = tetrahedralize(box((3.0, 1.0, 0.5), (6, 2, 1)), 2)
    write_mesh(tmp_path / "beam.msh", mesh)
    (tmp_path / "case.toml").write_text(PROBLEM)
    spec = load_spec(tmp_path / "case.toml")
    body = spec.model.body("beam").mesh
    assert body.element == "tet10" and body.n_cells == mesh.n_cells
    # the tip set: the facets of xmax whose centres lie in y <= 0.5, with their edge nodes
    tip = body.facet_set("tip")
    assert len(tip) == 2 and body.facet_nodes(tip).shape == (2, 6)
    said = " ".join(s.text for s in model_summary(spec.model))
    assert "beam (tet10, 72 cells" in said and "F-bar" not in said
    from contopt.assembly.system import discretize

    disc = discretize(spec.model)
    u = disc.body_displacement(solve_static(disc).u, "beam")
    assert u[body.node_set("tip"), 1].mean() < 0
    np.testing.assert_allclose(disc.f_ext_unit.reshape(-1, 3).sum(axis=0), [0.0, -1e-3 * 0.5 * 0.5, 0.0], rtol=1e-12)
    space = spec.problem.design.build(disc)
    assert space.volume_fractions(space.forward(space.initial()))[0] == pytest.approx(0.4, rel=1e-10)
