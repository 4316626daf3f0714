"""CAD in as tetrahedra (``element = "tet"``): tet4 and tet10 meshes of CAD solids written by Gmsh here.

References: a cylinder's volume (the tet4 mesh is inscribed; tet10's edge nodes lie on the curved
face, so its volume error is far smaller), the faces' node sets on their planes, straight tet10s
whose volume is that of their corners (Gmsh's node order turned into VTK's), and the uniaxial
stress of a compressed block (a linear field: reproduced by any tet mesh).
"""

import math

import numpy as np
import pytest

from contopt.fem.cells import cell_geometry
from contopt.mesh.cad import mesh_cad
from contopt.mesh.core import tet_volumes

gmsh = pytest.importorskip("gmsh")
from test_cad import H, R, cylinder_step, write_cad  # noqa: E402,F401  (the fixture and the writer)


@pytest.mark.parametrize("order", [1, 2])
def test_a_step_cylinder_meshes_into_tets_of_its_volume_and_faces(cylinder_step, order):  # noqa: F811
    mesh = mesh_cad(cylinder_step, 0.3, order=order, element="tet")
    assert mesh.element == ("tet4" if order == 1 else "tet10")
    volume = cell_geometry(mesh.points, mesh.cells).volume  # raises for a non-positive Jacobian
    exact = math.pi * R**2 * H
    error = abs(exact - volume.sum()) / exact
    assert error < (0.03 if order == 1 else 1e-3)  # measured 1.2e-2 (inscribed) and 2e-5 (curved edges)
    assert sorted(mesh.facet_sets) == ["surface_1", "surface_2", "surface_3"]
    assert sum(len(mesh.facet_set(n)) for n in mesh.facet_sets) == len(mesh.boundary_facets())
    for end_face in ("surface_2", "surface_3"):
        z = mesh.points[mesh.node_set(end_face), 2]
        assert np.ptp(z) == 0 and z[0] in (0.0, H)
    r = np.hypot(*mesh.points[mesh.node_set("surface_1"), :2].T)
    np.testing.assert_allclose(r, R, rtol=1e-6)  # tet10's edge nodes too lie on the mantle
    if order == 2:
        assert mesh.facet_nodes("surface_1").shape[1] == 6


def test_straight_tet10_from_gmsh_are_in_vtk_order(tmp_path):
    mesh = mesh_cad(
        write_cad(tmp_path / "box.step", lambda occ: occ.addBox(0, 0, 0, 1, 1, 2)), 0.5, order=2, element="tet"
    )
    # a box: every tet straight-sided, so its volume is its corners' (8 and 9 swapped would move two edge nodes)
    np.testing.assert_allclose(
        cell_geometry(mesh.points, mesh.cells).volume, tet_volumes(mesh.points, mesh.cells), rtol=1e-10
    )
    x = mesh.points[mesh.cells]
    edges = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]
    for k, (a, b) in enumerate(edges):
        np.testing.assert_allclose(x[:, 4 + k], (x[:, a] + x[:, b]) / 2, atol=1e-12)


@pytest.mark.parametrize("order", [1, 2])
def test_a_compressed_cad_tet_block_has_the_uniaxial_stress_answer(tmp_path, order):
    from _analytic import principal_cauchy, uniaxial_lateral_stretch

    from contopt.assembly.model import Body, Dirichlet, Model
    from contopt.assembly.system import discretize
    from contopt.material.hyperelastic import neo_hookean
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static

    L = (1.0, 1.0, 2.0)
    mesh = mesh_cad(
        write_cad(tmp_path / "block.step", lambda occ: occ.addBox(0, 0, 0, *L)), 0.5, order=order, element="tet"
    )
    plane = {}
    for name in mesh.facet_sets:
        x = mesh.points[mesh.node_set(name)]
        axis = int(np.argmin(np.ptp(x, axis=0)))
        plane[("xyz"[axis], "min" if x[0, axis] == 0 else "max")] = name
    mat, l3 = neo_hookean(1.0, 0.3), 0.99
    bcs = [Dirichlet("b", plane[(a, "min")], a, 0.0) for a in "xyz"]
    bcs.append(Dirichlet("b", plane[("z", "max")], "z", (l3 - 1.0) * L[2]))
    newton = NewtonOptions(rtol=1e-12, atol=1e-15, utol=1e-12, n_steps=1, max_iter=30)
    disc = discretize(Model(bodies=[Body("b", mesh, mat)], dirichlet=bcs))
    state = solve_static(disc, newton=newton)
    u = disc.body_displacement(state.u, "b")
    l1 = uniaxial_lateral_stretch(mat, l3)
    np.testing.assert_allclose(u, mesh.points * (np.array([l1, l1, l3]) - 1.0), rtol=0, atol=1e-8 * L[2])
    fz = state.reactions.reshape(-1, 3)[mesh.node_set(plane[("z", "max")]), 2].sum()
    assert fz == pytest.approx(principal_cauchy(mat, [l3, l1, l1])[0] * l1**2 * L[0] * L[1], rel=1e-8)
