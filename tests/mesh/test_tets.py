"""Tet4 / tet10 meshes: the Mesh's element type, boundary facets, tetrahedralize, file round trips."""

import meshio
import numpy as np
import pytest

from contopt.errors import MeshError
from contopt.io.vtk import read_vtu, write_vtu
from contopt.mesh import Mesh, box, read_mesh, tetrahedralize, write_mesh


@pytest.fixture(params=[1, 2], ids=["tet4", "tet10"])
def order(request):
    return request.param


def test_element_type_from_the_cells_width(order):
    hexes = box((2.0, 1.0, 1.0), (2, 2, 1))
    tets = tetrahedralize(hexes, order)
    assert hexes.element == "hex8" and tets.element == ("tet4" if order == 1 else "tet10")
    assert tets.n_cells == 6 * hexes.n_cells
    assert "element='tet" in repr(tets) and "element" not in repr(hexes)


def test_tetrahedralize_is_conforming_and_keeps_the_sets(order):
    hexes = box((2.0, 1.0, 1.0), (3, 2, 2))
    tets = tetrahedralize(hexes, order)
    # conforming: every hex boundary face is 2 tet boundary faces and no interior face is on the boundary
    assert len(tets.boundary_facets()) == 2 * len(hexes.boundary_facets())
    for name, facets in hexes.facet_sets.items():
        assert len(tets.facet_set(name)) == 2 * len(facets)
        x = tets.points[tets.facet_nodes(name)]
        axis, side = "xyz".index(name[0]), name[1:]
        np.testing.assert_allclose(x[..., axis], hexes.points[hexes.facet_nodes(name)][..., axis].max())
        assert side in ("min", "max")
    assert tets.facet_nodes("xmin").shape[1] == (3 if order == 1 else 6)
    if order == 2:  # edge nodes of a face are in its node set
        assert len(tets.node_set("zmax")) == (7 * 5)


def test_boundary_facets_of_a_single_tet():
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    mesh = Mesh(X, [[0, 1, 2, 3]], facet_sets={"all": [[0, 0], [0, 1], [0, 2], [0, 3]]})
    assert mesh.boundary_facets().tolist() == [[0, 0], [0, 1], [0, 2], [0, 3]]
    with pytest.raises(MeshError, match="local faces 0..3"):
        Mesh(X, [[0, 1, 2, 3]], facet_sets={"bad": [[0, 4]]})


@pytest.mark.parametrize("name", ["m.msh", "m22.msh", "m.vtu", "m.exo"])
def test_file_round_trip_keeps_cells_and_sets(tmp_path, order, name):
    if name.endswith(".exo"):
        pytest.importorskip("netCDF4")
    mesh = tetrahedralize(box((2.0, 1.0, 1.0), (2, 1, 1)), order)
    path = tmp_path / name
    write_mesh(path, mesh, **({"file_format": "gmsh22"} if "22" in name else {}))
    back = read_mesh(path)
    assert back.element == mesh.element
    np.testing.assert_array_equal(back.points, mesh.points)
    np.testing.assert_array_equal(back.cells, mesh.cells)
    assert sorted(back.facet_sets) == sorted(mesh.facet_sets)
    for k in mesh.facet_sets:
        np.testing.assert_array_equal(np.unique(back.facet_set(k), axis=0), np.unique(mesh.facet_set(k), axis=0))
    if path.suffix == ".msh":  # Gmsh facet groups give node sets, with tet10's edge nodes
        for k in mesh.facet_sets:
            np.testing.assert_array_equal(back.node_set(k), np.unique(mesh.facet_nodes(k)))


def test_gmsh_tetra10_file_has_gmsh_node_order(tmp_path):
    """Gmsh numbers tet10 edge nodes 8 and 9 the other way round from VTK: the file must hold Gmsh's order."""
    mesh = tetrahedralize(box((1.0, 1.0, 1.0), (1, 1, 1)), 2)
    path = tmp_path / "t22.msh"
    write_mesh(path, mesh, file_format="gmsh22", binary=False)
    lines = path.read_text().splitlines()
    start = lines.index("$Elements") + 2
    first_tet10 = next(ln for ln in lines[start:] if ln.split()[1] == "11").split()  # Gmsh type 11: tet10
    assert [int(v) - 1 for v in first_tet10[-10:]] == mesh.cells[0][[0, 1, 2, 3, 4, 5, 6, 7, 9, 8]].tolist()


def test_mixed_element_file_is_refused(tmp_path):
    pts = np.vstack([box().points, [[0.5, 0.5, 2.0]]])
    path = tmp_path / "mixed.vtu"
    meshio.write(path, meshio.Mesh(pts, [("hexahedron", box().cells), ("tetra", np.array([[4, 5, 6, 8]]))]))
    with pytest.raises(MeshError, match="holds hexahedron and tetra cells; a mesh holds one element type"):
        read_mesh(path)


def test_state_vtu_of_tet_bodies(tmp_path, order):
    mesh = tetrahedralize(box((1.0, 1.0, 1.0), (1, 1, 1)), order)
    u = 0.1 * mesh.points
    path = write_vtu(tmp_path / "b.vtu", mesh.points, mesh.cells, {"displacement": u}, {"nu": np.ones(mesh.n_cells)})
    points, cells, point_data, cell_data = read_vtu(path)
    np.testing.assert_array_equal(cells, mesh.cells)
    np.testing.assert_array_equal(point_data["displacement"], u)
    assert meshio.read(path).cells[0].type == ("tetra" if order == 1 else "tetra10")


def test_tetrahedralize_conforms_on_the_structured_generators_and_refuses_the_o_grid():
    from contopt.mesh.generators import annulus, cylinder, cylinder_shell_sector

    for hexes in (cylinder_shell_sector(3.0, 1.7, 4.6, 0.3, (12, 8, 1)), annulus(1.0, 2.0, 1.0, (12, 2, 2))):
        assert len(tetrahedralize(hexes).boundary_facets()) == 2 * len(hexes.boundary_facets())
    # the o-grid's core and ring number their cells differently: shared faces cut two ways
    with pytest.raises(MeshError, match="interior faces would be cut along different diagonals"):
        tetrahedralize(cylinder(1.0, 2.0, (4, 2, 2)))
