"""Rigid tools' surfaces (contopt.mesh.tool): areas and outward normals against the analytic shapes,
STL files split into conforming quads, and the hex8 layer under a surface."""

import numpy as np
import pytest

from contopt.errors import MeshError
from contopt.mesh import cylinder_shell_sector, scaled_jacobian
from contopt.mesh.tool import (
    QuadSurface,
    cylinder_surface,
    plane_surface,
    read_surface,
    sphere_surface,
    surface_from_cells,
    tool_layer,
)


def edge_uses(surface):
    """(k,) how many facets use each undirected edge."""
    q = surface.quads
    e = np.sort(np.stack([q, np.roll(q, -1, axis=1)], axis=-1).reshape(-1, 2), axis=1)
    return np.unique(e, axis=0, return_counts=True)[1]


def test_a_plane_patch_has_its_area_and_normal():
    n = np.array([1.0, 2.0, -2.0]) / 3.0
    s = plane_surface(center=[1.0, 0.0, 2.0], normal=n, size=(2.0, 0.5), divisions=(4, 3))
    assert s.areas().sum() == pytest.approx(1.0, rel=1e-13)
    np.testing.assert_allclose(s.normals(), np.tile(n, (12, 1)), atol=1e-14)
    np.testing.assert_allclose(s.points.mean(axis=0), [1.0, 0.0, 2.0], atol=1e-14)
    # a patch facing z has its sides along x and y
    z = plane_surface([0, 0, 0], [0, 0, 1], 1.0, (1, 1))
    np.testing.assert_allclose(np.sort(np.abs(z.points[:, :2]).ravel()), 0.5)


@pytest.mark.parametrize("n", [8, 33])
def test_a_cylinder_has_the_polygon_s_area_and_radial_outward_normals(n):
    R, L = 0.7, 2.0
    s = cylinder_surface(R, L, center=[0.0, 1.0, 0.0], axis=[1.0, 1.0, 0.0], divisions=(n, 3))
    polygon = n * 2 * R * np.sin(np.pi / n) * L  # the inscribed prism, exactly
    assert s.areas().sum() == pytest.approx(polygon, rel=1e-12)
    assert abs(polygon / (2 * np.pi * R * L) - 1) < (np.pi / n) ** 2 / 6 * 1.01  # the polygon's error
    w = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    r = s.points[s.quads].mean(axis=1) - [0.0, 1.0, 0.0]
    radial = r - np.outer(r @ w, w)
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    np.testing.assert_allclose(np.einsum("ij,ij->i", s.normals(), radial), 1.0, atol=1e-12)
    assert (edge_uses(s) <= 2).all() and len(s.points) == n * 4  # closed around: the seam is shared


def test_a_cylinder_arc_has_the_nodes_of_the_shell_sector_s_outer_surface():
    arc = np.deg2rad(100.0)
    s = cylinder_surface(3.0, 4.6, [4.5, 2.0, 6.4], "y", (12, 8), arc=arc, normal=[0, 0, -1])
    die = cylinder_shell_sector(3.0, arc, 4.6, 0.3, (12, 8, 1), center=(4.5, 2.0, 6.4), axis="y")
    outer = die.points[die.node_set("outer")]
    a, b = np.lexsort(s.points.T.round(9)), np.lexsort(outer.T.round(9))
    np.testing.assert_allclose(s.points[a], outer[b], atol=1e-12)
    assert (s.normals()[:, 2] < 0).all()  # the middle faces down


@pytest.mark.parametrize("n", [6, 12])
def test_a_cube_sphere_is_closed_outward_and_its_area_converges_to_4_pi_r2(n):
    R = 1.5
    s = sphere_surface(R, center=[1.0, 2.0, 3.0], divisions=n)
    assert len(s.quads) == 6 * n * n and len(s.points) == 6 * n * n + 2
    assert (edge_uses(s) == 2).all()
    np.testing.assert_allclose(np.linalg.norm(s.points - [1, 2, 3], axis=1), R, rtol=1e-14)
    r = s.points[s.quads].mean(axis=1) - [1.0, 2.0, 3.0]
    assert (np.einsum("ij,ij->i", s.normals(), r / np.linalg.norm(r, axis=1, keepdims=True)) > 0.99).all()
    # inscribed bilinear facets: the area error is second order in the facet angle (pi/2n)
    err = 1 - s.areas().sum() / (4 * np.pi * R**2)
    assert 0 < err < 0.5 * (np.pi / (2 * n)) ** 2


def test_a_sphere_cap_lies_on_the_sphere_around_its_normal():
    d = np.array([1.0, 0.0, -1.0]) / np.sqrt(2)
    s = sphere_surface(2.0, [0.0, 0.0, 0.0], divisions=4, normal=d, angle=0.3)
    np.testing.assert_allclose(np.linalg.norm(s.points, axis=1), 2.0, rtol=1e-14)
    middle = s.points[12]  # node (2, 2) of the 5 x 5 grid
    np.testing.assert_allclose(middle, 2.0 * d, atol=1e-14)
    assert (s.normals() @ d > np.cos(0.3 * np.sqrt(2))).all()
    with pytest.raises(MeshError, match="angle"):
        sphere_surface(2.0, [0, 0, 0], angle=1.2)


CUBE_POINTS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
#: the unit cube's faces, counter-clockwise seen from outside
CUBE_QUADS = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])
CUBE_TRIANGLES = np.concatenate([CUBE_QUADS[:, [0, 1, 2]], CUBE_QUADS[:, [0, 2, 3]]])


def write_stl(path, triangles, points=CUBE_POINTS):
    """An ASCII STL, every triangle with its own three vertices (as STL files store them)."""
    lines = ["solid cube"]
    for t in triangles:
        a, b, c = points[t]
        n = np.cross(b - a, c - a)
        lines += [f"facet normal {n[0]} {n[1]} {n[2]}", "outer loop"]
        lines += [f"vertex {p[0]} {p[1]} {p[2]}" for p in (a, b, c)]
        lines += ["endloop", "endfacet"]
    path.write_text("\n".join([*lines, "endsolid cube", ""]))
    return path


def test_an_stl_cube_becomes_36_conforming_outward_quads_of_area_6(tmp_path):
    s = read_surface(write_stl(tmp_path / "cube.stl", CUBE_TRIANGLES), scale=2.0)
    assert len(s.quads) == 36 and (edge_uses(s) == 2).all()  # conforming and closed
    assert s.areas().sum() == pytest.approx(24.0, rel=1e-12)
    c = s.points[s.quads].mean(axis=1) - 1.0
    assert (np.einsum("ij,ij->i", s.normals(), c) > 0).all()
    # the same file ordered inward is turned outward; flip turns it inward
    inward = read_surface(write_stl(tmp_path / "in.stl", CUBE_TRIANGLES[:, ::-1]), scale=2.0)
    assert (np.einsum("ij,ij->i", inward.normals(), inward.points[inward.quads].mean(axis=1) - 1.0) > 0).all()
    flipped = read_surface(tmp_path / "cube.stl", scale=2.0, flip=True)
    assert (np.einsum("ij,ij->i", flipped.normals(), flipped.points[flipped.quads].mean(axis=1) - 1.0) < 0).all()


def test_an_inconsistently_ordered_file_and_a_missing_one_are_one_line_errors(tmp_path):
    bad = CUBE_TRIANGLES.copy()
    bad[0] = bad[0, ::-1]
    with pytest.raises(MeshError, match="ordered inconsistently"):
        read_surface(write_stl(tmp_path / "bad.stl", bad))
    with pytest.raises(MeshError, match="no such surface file"):
        read_surface(tmp_path / "none.stl")


def test_triangles_beside_quads_split_both_so_that_the_surface_conforms():
    # the cube's bottom as two triangles, the rest as quads
    s = surface_from_cells(CUBE_POINTS, CUBE_TRIANGLES[[0, 6]], CUBE_QUADS[1:])
    assert len(s.quads) == 2 * 3 + 5 * 4 and (edge_uses(s) == 2).all()
    assert s.areas().sum() == pytest.approx(6.0, rel=1e-13)
    # quads alone are kept as they are
    assert len(surface_from_cells(CUBE_POINTS, quads=CUBE_QUADS).quads) == 6


def test_the_layer_is_valid_and_its_face_is_the_surface():
    s = sphere_surface(1.0, [0.0, 0.0, 0.0], divisions=4)
    mesh = tool_layer(s)
    assert mesh.n_cells == len(s.quads) and scaled_jacobian(mesh).min() > 0.3
    face = mesh.points[mesh.facet_nodes("surface")]
    np.testing.assert_array_equal(face, s.points[s.quads])
    va = 0.5 * np.cross(face[:, 2] - face[:, 0], face[:, 3] - face[:, 1])
    np.testing.assert_allclose(va, s.vector_areas(), atol=1e-15)  # the facet's outward normal
    assert sorted(mesh.node_sets) == ["all", "surface"] and len(mesh.node_set("all")) == mesh.n_nodes
    # the inner nodes lie inside the sphere, under their surface node
    inner = mesh.points[len(s.points) :]
    assert (np.linalg.norm(inner, axis=1) < 1.0 - 0.1 * 0.45).all()


def test_a_layer_that_would_invert_is_refused_with_the_remedy():
    # a ridge folded back over itself: a square and a second facet turned by about 174 degrees
    points = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.02, 0, 0.1], [0.02, 1, 0.1]], float)
    folded = QuadSurface(points, np.array([[0, 1, 2, 3], [1, 4, 5, 2]]))
    with pytest.raises(MeshError, match="smaller thickness"):
        tool_layer(folded, thickness=1.0)
