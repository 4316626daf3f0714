"""Voxel meshes of closed surfaces (contopt.mesh.voxel): the inside test against the exact shape, the
volume's first-order convergence, the sets, and the refusals."""

import numpy as np
import pytest
from _envelope import DEPTH, bracket, profile_area, write_bracket  # tests/_envelope.py

from contopt.errors import MeshError
from contopt.io.surface import TriangleSurface, write_surface
from contopt.mesh.generators import box
from contopt.mesh.voxel import inside_surface, mesh_envelope, read_envelope, voxelize


def _in_profile(x, z):
    """Exact membership of the bracket's profile: the L and its gusset x + z <= 1.4."""
    foot = (x <= 2.0) & (z <= 0.4)
    wall = (x <= 0.4) & (z <= 2.0)
    gusset = (x + z <= 1.4) & (x <= 1.0) & (z <= 1.0)
    return (x >= 0) & (z >= 0) & (foot | wall | gusset)


def test_inside_agrees_with_the_exact_shape(rng):
    X = rng.uniform([-0.2, -0.2, -0.2], [2.2, 1.0, 2.2], (20000, 3))
    x, y, z = X.T
    exact = _in_profile(x, z) & (y >= 0) & (y <= DEPTH)
    # the distance to the nearest face plane is at least 1e-6 (the test's ties are none)
    planes = np.abs(np.stack([x, z, x - 2, z - 0.4, x - 0.4, z - 2, y, y - DEPTH, (x + z - 1.4) / np.sqrt(2)]))
    clear = planes.min(axis=0) > 1e-6
    got = inside_surface(bracket(), X)
    np.testing.assert_array_equal(got[clear], exact[clear])
    assert exact.sum() > 2000  # both sides well sampled
    # orientation does not matter (parity), nor does a shift of the whole shape
    flipped = TriangleSurface(bracket().vertices, bracket().faces[:, ::-1])
    np.testing.assert_array_equal(inside_surface(flipped, X)[clear], exact[clear])


def test_a_box_envelope_gives_the_box_mesh():
    """Sizes dividing the box: the voxels are the box generator's cells, the sets its sides."""
    lengths, origin = (1.2, 0.8, 0.4), (0.3, -0.1, 0.5)
    surface = bracket(np.array([(0.0, 0.0), (1.2, 0.0), (1.2, 0.4), (0.0, 0.4)]), 0.8, origin)
    mesh = voxelize(surface, 0.2)
    ref = box(lengths, (6, 4, 2), origin)
    assert mesh.n_cells == ref.n_cells and mesh.n_nodes == ref.n_nodes
    key = lambda p: np.round(p, 9)[np.lexsort(np.round(p, 9).T)]  # noqa: E731
    np.testing.assert_allclose(key(mesh.points), key(ref.points), atol=1e-12)
    for side in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax"):
        np.testing.assert_allclose(
            key(mesh.points[mesh.node_set(side)]), key(ref.points[ref.node_set(side)]), atol=1e-12
        )
        assert len(mesh.facet_set(side)) == len(ref.facet_set(side))
    assert len(mesh.facet_set("boundary")) == len(ref.boundary_facets())


def test_the_volume_converges_at_first_order_in_the_size():
    """|V_h - V| is bounded by the surface's area times half a voxel's diagonal, and halves with h
    (the gusset's face runs through voxel centres at every size: their half cubes go one way)."""
    surface = bracket()
    exact = profile_area() * DEPTH
    sizes = (0.2, 0.1, 0.05)
    errors = np.array([abs(voxelize(surface, h).n_cells * h**3 - exact) for h in sizes])
    assert np.all(errors <= np.sqrt(3) / 2 * surface.area * np.array(sizes))
    rate = np.polyfit(np.log(sizes), np.log(errors), 1)[0]
    assert 0.7 <= rate <= 1.5, errors


def test_bracket_sets_lie_on_the_bounding_box_sides(tmp_path):
    path = write_bracket(tmp_path / "bracket.stl")
    mesh = mesh_envelope(path, 0.1, scale=2.0)  # the file in units of 2
    lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)
    np.testing.assert_allclose(hi - lo, [4.0, 1.6, 4.0], atol=1e-6)
    for axis, name in enumerate("xyz"):
        np.testing.assert_allclose(mesh.points[mesh.node_set(f"{name}min"), axis], lo[axis], atol=1e-9)
        np.testing.assert_allclose(mesh.points[mesh.node_set(f"{name}max"), axis], hi[axis], atol=1e-9)
    # the foot's end (x max) is 0.4 x 0.8 at scale 2: 8 x 16 faces of 0.1
    assert len(mesh.facet_set("xmax")) == 8 * 16
    np.testing.assert_array_equal(mesh.facet_set("boundary"), mesh.boundary_facets())


def test_open_surfaces_and_sizes_without_cells_are_refused(tmp_path):
    s = bracket()
    write_surface(TriangleSurface(s.vertices, s.faces[1:]), tmp_path / "open.stl")
    with pytest.raises(MeshError, match=r"open\.stl: the surface is not closed \(3 open edges") as err:
        mesh_envelope(tmp_path / "open.stl", 0.1)
    assert "\n" not in str(err.value)
    path = write_bracket(tmp_path / "bracket.stl")
    with pytest.raises(MeshError, match="no voxel of size 5 has its centre inside; use a smaller size"):
        mesh_envelope(path, 5.0)
    with pytest.raises(MeshError, match="not found"):
        mesh_envelope(tmp_path / "nope.stl", 0.1)
    with pytest.raises(MeshError, match="not a surface or CAD file"):
        read_envelope(tmp_path / "bracket.txt")


def test_a_step_envelope_is_triangulated_by_gmsh(tmp_path):
    gmsh = pytest.importorskip("gmsh")
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, 1.0, 0.5)
    gmsh.model.occ.synchronize()
    gmsh.write(str(tmp_path / "post.step"))
    gmsh.finalize()
    mesh = mesh_envelope(tmp_path / "post.step", 0.05)
    volume = mesh.n_cells * 0.05**3
    assert volume == pytest.approx(np.pi * 0.25, rel=0.05)


def test_a_loose_piece_is_dropped_with_a_warning(caplog):
    from contopt.io.surface import merge

    square = np.array([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)])
    big = bracket(square, 1.0)
    small = bracket(square * 0.4, 0.4, origin=(2.0, 0.0, 0.0))  # 0.6 away: its own piece
    with caplog.at_level("WARNING", logger="contopt.mesh.voxel"):
        mesh = voxelize(merge([big, small]), 0.2)
    assert mesh.n_cells == 125 and mesh.points[:, 0].max() <= 1.0 + 1e-12
    assert "8 of 133 voxels are loose pieces" in caplog.text


def test_the_grid_columns_agree_with_the_pointwise_test():
    """voxelize counts each grid column's crossings once; the pointwise test casts a ray per point: the
    same cells, also where the gusset's face runs through a row of centres (ties broken alike)."""
    from contopt.design import cell_centroids

    surface = bracket()
    for h in (0.2, 0.1):
        mesh = voxelize(surface, h)
        assert inside_surface(surface, cell_centroids(mesh)).all()
        lo = mesh.points.min(axis=0)
        n = np.round(np.ptp(mesh.points, axis=0) / h).astype(int)
        grid = np.stack(np.meshgrid(*[lo[a] + h * (np.arange(n[a]) + 0.5) for a in range(3)], indexing="ij"), -1)
        assert inside_surface(surface, grid.reshape(-1, 3)).sum() == mesh.n_cells
