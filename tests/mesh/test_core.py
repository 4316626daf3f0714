"""The Mesh dataclass: face tables, validation errors, named sets, quality."""

import numpy as np
import pytest

from contopt.errors import MeshError
from contopt.mesh import HEX_FACES, Mesh, boundary_facets, box, scaled_jacobian
from contopt.mesh.core import HEX_FACE_AXIS, HEX_FACE_SIDE, cell_jacobian_dets

UNIT_CUBE = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=float,
)


def two_cells():
    """Two unit cubes side by side along x (cell 1 is x in [1, 2])."""
    return box((2.0, 1.0, 1.0), (2, 1, 1))


def test_hex_faces_have_outward_normals_on_unit_cube():
    centre = UNIT_CUBE.mean(axis=0)
    for k, face in enumerate(HEX_FACES):
        p = UNIT_CUBE[face]
        normal = np.cross(p[2] - p[0], p[3] - p[1])
        normal /= np.linalg.norm(normal)
        expected = np.zeros(3)
        expected[HEX_FACE_AXIS[k]] = HEX_FACE_SIDE[k]
        assert np.allclose(normal, expected), k
        assert np.dot(p.mean(axis=0) - centre, normal) > 0
        # the face is the plane X_axis = 0 or 1 given by the side
        coord = (HEX_FACE_SIDE[k] + 1) / 2
        assert np.all(p[:, HEX_FACE_AXIS[k]] == coord)


def test_unit_cube_is_valid_with_positive_corner_jacobians():
    mesh = Mesh(UNIT_CUBE, [np.arange(8)])
    assert mesh.n_nodes == 8 and mesh.n_cells == 1
    assert np.allclose(cell_jacobian_dets(mesh.points, mesh.cells), 1.0)
    assert len(mesh.boundary_facets()) == 6
    assert not mesh.points.flags.writeable and not mesh.cells.flags.writeable


def test_inverted_cell_is_rejected_naming_it():
    mesh = two_cells()
    cells = mesh.cells.copy()
    cells[1] = cells[1][[4, 5, 6, 7, 0, 1, 2, 3]]  # mirror: swap bottom and top
    with pytest.raises(MeshError, match=r"cell 1 is inverted"):
        Mesh(mesh.points, cells)


def test_mirrored_in_plane_order_is_also_inverted():
    mesh = two_cells()
    cells = mesh.cells.copy()
    cells[0] = cells[0][[0, 3, 2, 1, 4, 7, 6, 5]]  # clockwise bottom face
    with pytest.raises(MeshError, match=r"cell 0 is inverted"):
        Mesh(mesh.points, cells)


def test_repeated_node_is_degenerate():
    mesh = two_cells()
    cells = mesh.cells.copy()
    cells[1, 6] = cells[1, 5]
    with pytest.raises(MeshError, match=r"cell 1 is degenerate: repeated nodes"):
        Mesh(mesh.points, cells)


def test_flattened_cell_without_repeated_nodes_is_degenerate():
    pts = UNIT_CUBE.copy()
    pts[4:, 2] = 0.0  # top face collapsed onto the bottom one
    with pytest.raises(MeshError, match=r"cell 0 is inverted or degenerate"):
        Mesh(pts, [np.arange(8)])


def test_tiny_but_well_shaped_cells_are_valid():
    # a 1e-5 cube in a unit box: its Jacobian is 1e-15, far below 1e-12 * size^3,
    # yet it is a perfect cube (the check is relative to each corner's edges)
    x = np.array([0.0, 1e-5, 1.0])
    mesh = box(grading=(x, x, x))
    assert mesh.n_cells == 8
    assert np.allclose(scaled_jacobian(mesh), 1.0)


def test_bad_shapes_and_indices():
    with pytest.raises(MeshError, match=r"points must have shape \(n, 3\)"):
        Mesh(UNIT_CUBE[:, :2], [np.arange(8)])
    with pytest.raises(MeshError, match=r"\(m, 8\) \(hex8\), \(m, 4\) \(tet4\) or \(m, 10\) \(tet10\)"):
        Mesh(UNIT_CUBE, [np.arange(5)])
    with pytest.raises(MeshError, match=r"cell 0 refers to a node outside 0..7"):
        Mesh(UNIT_CUBE, [np.arange(1, 9)])
    pts = UNIT_CUBE.copy()
    pts[3, 1] = np.nan
    with pytest.raises(MeshError, match=r"node 3 has a non-finite coordinate"):
        Mesh(pts, [np.arange(8)])
    with pytest.raises(MeshError, match=r"node set 'far' refers to nodes outside"):
        Mesh(UNIT_CUBE, [np.arange(8)], node_sets={"far": [8]})
    with pytest.raises(MeshError, match=r"facet set 'f' must have shape \(k, 2\)"):
        Mesh(UNIT_CUBE, [np.arange(8)], facet_sets={"f": [0, 1]})
    with pytest.raises(MeshError, match=r"facet set 'f' has a row outside"):
        Mesh(UNIT_CUBE, [np.arange(8)], facet_sets={"f": [[0, 6]]})


@pytest.mark.parametrize(
    "cells, node_sets, facet_sets, match",
    [
        ([np.arange(8) + 0.4], {}, {}, r"cells must be integer indices, got float64 values \(first 0.4\)"),
        ([np.arange(8.0)], {}, {}, r"cells must be integer indices, got float64"),  # whole numbers too: explicit
        ([np.arange(8)], {"a": [0.5, 1.2]}, {}, r"node set 'a' must be integer indices"),
        ([np.arange(8)], {}, {"f": [[0.0, 0.7]]}, r"facet set 'f' must be integer indices"),
        ([np.arange(8)], {"a": np.ones(8, bool)}, {}, r"node set 'a' must be integer indices, got a boolean array"),
    ],
)
def test_float_or_boolean_indices_are_refused_never_truncated(cells, node_sets, facet_sets, match):
    with pytest.raises(MeshError, match=match):
        Mesh(UNIT_CUBE, cells, node_sets, facet_sets)


def test_float32_points_are_converted_and_empty_sets_accepted():
    mesh = Mesh(UNIT_CUBE.astype(np.float32), np.arange(8)[None].astype(np.int32), {"none": []}, {"nothing": []})
    assert mesh.points.dtype == np.float64 and mesh.cells.dtype == np.int64
    assert mesh.node_sets["none"].size == 0 and mesh.facet_sets["nothing"].shape == (0, 2)


def test_unknown_set_names_list_the_available_ones():
    mesh = two_cells()
    with pytest.raises(MeshError) as err:
        mesh.node_set("nope")
    msg = str(err.value)
    assert "'nope'" in msg and "'xmin'" in msg and "'all'" in msg
    with pytest.raises(MeshError) as err:
        mesh.facet_set("nope")
    msg = str(err.value)
    assert "'nope'" in msg and "'zmax'" in msg and "'all'" not in msg


def test_node_set_falls_back_to_facet_nodes():
    mesh = two_cells()
    only_facets = Mesh(mesh.points, mesh.cells, facet_sets={"right": mesh.facet_set("xmax")})
    nodes = only_facets.node_set("right")
    assert np.array_equal(nodes, mesh.node_set("xmax"))
    assert np.allclose(only_facets.points[nodes, 0], 2.0)
    assert len(nodes) == 4


def test_interior_face_in_a_facet_set_is_rejected():
    mesh = two_cells()
    # cell 0's face xi=+1 (local face 3) is shared with cell 1
    with pytest.raises(MeshError, match=r"facet set 'mid' is not on the boundary.*cell 0, local face 3"):
        mesh.with_sets(facet_sets={"mid": [[0, 3]]})


def test_boundary_facets_of_a_box():
    nx, ny, nz = 3, 2, 4
    mesh = box((1, 1, 1), (nx, ny, nz))
    bnd = boundary_facets(mesh.cells)
    assert len(bnd) == 2 * (nx * ny + ny * nz + nx * nz)
    assert np.array_equal(bnd, np.unique(bnd, axis=0))  # sorted, unique
    all_sets = np.concatenate([mesh.facet_set(k) for k in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")])
    assert np.array_equal(np.unique(all_sets, axis=0), bnd)


def test_scaled_jacobian_of_a_sheared_cube():
    s = 0.75
    pts = UNIT_CUBE.copy()
    pts[4:, 0] += s  # top face shifted along x
    sj = scaled_jacobian(pts, np.arange(8)[None])
    assert sj.shape == (1,)
    assert sj[0] == pytest.approx(1.0 / np.sqrt(1 + s**2), rel=1e-12)
    assert scaled_jacobian(Mesh(UNIT_CUBE, [np.arange(8)]))[0] == pytest.approx(1.0)


def test_transformed_and_with_sets_keep_sets():
    mesh = two_cells()
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    moved = mesh.transformed(R, [1.0, 2.0, 3.0])
    assert np.allclose(moved.points, mesh.points @ R.T + [1, 2, 3])
    assert np.array_equal(moved.facet_set("xmin"), mesh.facet_set("xmin"))
    extra = mesh.with_sets(node_sets={"corner": [0]})
    assert sorted(extra.node_sets) == sorted([*mesh.node_sets, "corner"])
    with pytest.raises(TypeError):
        extra.node_sets["x"] = np.zeros(1)  # read-only mapping


def test_a_mesh_pickles_with_its_sets_and_read_only_arrays():
    """A process pool sends models to its workers (contopt.optimize.case_pool)."""
    import pickle

    mesh = box(divisions=(2, 1, 1))
    back = pickle.loads(pickle.dumps(mesh))
    np.testing.assert_array_equal(back.points, mesh.points)
    np.testing.assert_array_equal(back.cells, mesh.cells)
    assert sorted(back.node_sets) == sorted(mesh.node_sets) and sorted(back.facet_sets) == sorted(mesh.facet_sets)
    np.testing.assert_array_equal(back.facet_set("xmax"), mesh.facet_set("xmax"))
    assert not back.points.flags.writeable
    with pytest.raises(TypeError):
        back.node_sets["x"] = np.zeros(0, dtype=np.int64)
