"""Closed surfaces from lattice fields, their checks, smoothing and files."""

import struct

import meshio
import numpy as np
import pytest
from _surfaces import closed_manifold_problems, signed_volume  # tests/_surfaces.py (independent surface checks)

from contopt.errors import ConfigError
from contopt.io.surface import (
    TriangleSurface,
    check_surface,
    lattice_surface,
    read_surface,
    taubin_smooth,
    write_surface,
)


def _lattice(lower, upper, h):
    axes = [np.arange(lo, hi + 0.5 * h, h) for lo, hi in zip(lower, upper)]
    X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    return X, np.array([a[0] for a in axes]), np.array([h, h, h])


def _sphere(h, R=1.0):
    X, origin, spacing = _lattice((-1.3 * R,) * 3, (1.3 * R,) * 3, h)
    return lattice_surface(R - np.linalg.norm(X, axis=-1), origin, spacing)


def _cube(lo=0.0, hi=1.0):
    """A hand-made closed unit cube, 12 triangles, outward."""
    v = np.array([[x, y, z] for z in (lo, hi) for y in (lo, hi) for x in (lo, hi)], dtype=float)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return TriangleSurface(v, faces)


@pytest.mark.parametrize("h", [0.2, 0.1])
def test_sphere_is_closed_and_its_volume_converges_at_second_order(h):
    """Marching cubes of the distance field R - |x|: vertices interpolated on lattice edges and flat
    triangles of edges up to sqrt(3) h across a surface of curvature 1/R: the enclosed volume is
    within area * h^2 / (2 R) of 4/3 pi R^3 (the sagitta of a sqrt(3) h chord is 3 h^2 / (8 R))."""
    s = _sphere(h)
    assert closed_manifold_problems(s.vertices, s.faces) == []
    exact = 4.0 / 3.0 * np.pi
    assert abs(s.volume - exact) <= s.area * h * h / 2.0
    assert s.volume == pytest.approx(signed_volume(s.vertices, s.faces), rel=1e-12)
    coarse = abs(_sphere(2 * h).volume - exact)
    assert abs(s.volume - exact) <= coarse / 2.5  # second order: halving h divides the error by ~4


def test_material_reaching_the_lattice_planes_is_capped_exactly_on_them():
    """All material: the box itself, caps on the outer planes, its volume and area exact."""
    s = lattice_surface(np.ones((6, 5, 4)), origin=(1.0, -2.0, 0.5), spacing=(0.5, 0.25, 1.0))
    assert closed_manifold_problems(s.vertices, s.faces) == []
    np.testing.assert_allclose(s.vertices.min(axis=0), [1.0, -2.0, 0.5], atol=1e-15)
    np.testing.assert_allclose(s.vertices.max(axis=0), [3.5, -1.0, 3.5], atol=1e-15)
    assert s.volume == pytest.approx(2.5 * 1.0 * 3.0, rel=1e-13)
    assert s.area == pytest.approx(2 * (2.5 * 1.0 + 2.5 * 3.0 + 1.0 * 3.0), rel=1e-13)


def test_a_linear_field_gives_its_exact_half_space_closed_by_the_lattice():
    """Marching cubes reproduces a linear field's plane exactly: volume below a slanted plane."""
    X, origin, spacing = _lattice((0, 0, 0), (2.0, 1.0, 1.0), 0.1)
    a, b, c = 0.5531, 0.1, 0.05  # F = a - z + b x - c y > 0 below the plane, off the lattice points
    s = lattice_surface(a - X[..., 2] + b * X[..., 0] - c * X[..., 1], origin, spacing)
    assert closed_manifold_problems(s.vertices, s.faces) == []
    exact = 2.0 * 1.0 * (a + b * 1.0 - c * 0.5)  # the mean height of the plane over [0,2]x[0,1]
    assert s.volume == pytest.approx(exact, rel=1e-12)


def test_no_material_gives_an_empty_surface():
    s = lattice_surface(-np.ones((3, 3, 3)), (0, 0, 0), (1, 1, 1))
    assert s.n_faces == 0 and s.volume == 0.0


def test_values_on_the_level_itself_make_no_degenerate_triangles():
    """A 0/1 block whose boundary values are exactly 0: no repeated or zero-area faces."""
    F = -np.ones((8, 8, 8))
    F[2:6, 2:6, 2:6] = 1.0
    F[2:6, 2:6, 6] = 0.0
    s = lattice_surface(F, (0, 0, 0), (1, 1, 1))
    assert closed_manifold_problems(s.vertices, s.faces) == []
    assert check_surface(s).degenerate_faces == 0


def test_check_surface_names_what_is_wrong():
    cube = _cube()
    good = check_surface(cube)
    assert good.ok and good.volume == pytest.approx(1.0) and good.components == 1
    opened = check_surface(TriangleSurface(cube.vertices, cube.faces[1:]))
    assert not opened.watertight and opened.boundary_edges == 3 and not opened.ok
    flipped = cube.faces.copy()
    flipped[0] = flipped[0, ::-1]
    assert check_surface(TriangleSurface(cube.vertices, flipped)).misoriented_edges == 3
    inward = check_surface(TriangleSurface(cube.vertices, cube.faces[:, ::-1]))
    assert inward.oriented and inward.volume == pytest.approx(-1.0) and not inward.ok
    assert "normals point inward" in " ".join(inward.problems())
    # two cubes sharing the corner (1, 1, 1): each closed, but the shared vertex is two fans
    other = _cube(1.0, 2.0)
    v = np.concatenate([cube.vertices, other.vertices[1:]])
    shared = np.where(other.faces == 0, 7, other.faces + 7)
    pair = check_surface(TriangleSurface(v, np.concatenate([cube.faces, shared])))
    assert pair.watertight and pair.nonmanifold_vertices == 1 and not pair.manifold and pair.components == 1
    assert closed_manifold_problems(v, np.concatenate([cube.faces, shared])) != []


def test_taubin_smoothing_keeps_the_volume_and_the_caps_on_their_planes():
    F = -np.ones((14, 12, 10))
    F[:9, 3:8, :6] = 1.0  # a staircase block touching the planes x = 0 and z = 0
    F[:5, 3:8, 6:8] = 1.0
    s = lattice_surface(F, (0, 0, 0), (1, 1, 1))
    planes = [(0, 0.0), (2, 0.0)]
    smooth = taubin_smooth(s, 20, planes=planes, tol=1e-9)
    assert closed_manifold_problems(smooth.vertices, smooth.faces) == []
    assert smooth.volume == pytest.approx(s.volume, rel=1e-10)
    for axis, value in planes:
        on = np.abs(s.vertices[:, axis] - value) <= 1e-9
        assert on.sum() > 10 and np.all(smooth.vertices[on, axis] == value)

    with pytest.raises(ConfigError, match="integer >= 0"):
        taubin_smooth(s, -1)


def test_taubin_smoothing_damps_the_high_frequencies_without_shrinking(rng):
    """A sphere with radial noise of 3 % of its radius. Taubin's filter multiplies a mode of the
    umbrella operator with eigenvalue k by ((1 - 0.5 k)(1 + 0.53 k))^N, at most 0.765^10 = 0.069 for
    k >= 1 after N = 10 steps: the umbrella energy sum |L v|^2, which such modes dominate, falls below
    that fraction, and the volume stays."""
    from contopt.io.surface import adjacency

    s = _sphere(0.1)
    r = np.linalg.norm(s.vertices, axis=1)
    noisy = TriangleSurface(s.vertices * (1.0 + 0.03 * rng.standard_normal(len(r)))[:, None], s.faces)
    smooth = taubin_smooth(noisy, 10)
    W = adjacency(s)
    energy = lambda surf: float(np.sum((W @ surf.vertices - surf.vertices) ** 2))  # noqa: E731
    assert energy(smooth) < 0.765**10 * energy(noisy)
    assert smooth.volume == pytest.approx(noisy.volume, rel=1e-10)
    spread = lambda surf: float(np.std(np.linalg.norm(surf.vertices, axis=1)))  # noqa: E731
    assert spread(smooth) < 0.5 * spread(noisy)


# ------------------------------------------------------------------------------------------ files
@pytest.fixture(scope="module")
def sphere():
    return _sphere(0.2)


def test_binary_stl_has_its_header_count_and_unit_normals(sphere, tmp_path):
    path = write_surface(sphere, tmp_path / "part.stl")
    data = path.read_bytes()
    (count,) = struct.unpack("<I", data[80:84])
    assert count == sphere.n_faces and len(data) == 84 + 50 * count
    assert not data[:5].lower().startswith(b"solid")  # else readers take it for ASCII
    rec = np.frombuffer(data, dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")], offset=84)
    np.testing.assert_allclose(rec["v"], sphere.corners(), atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(rec["n"], axis=1), 1.0, atol=1e-6)
    outward = np.einsum("kd,kd->k", rec["n"], rec["v"].mean(axis=1))  # the sphere is centred at 0
    assert np.all(outward > 0)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # meshio probes ASCII STL as binary
@pytest.mark.parametrize(
    "name, binary, tol",
    [
        ("part.stl", True, 1e-6),
        ("part.stl", False, 1e-8),
        ("part.ply", True, 0.0),
        ("part.ply", False, 0.0),
        ("part.obj", False, 0.0),
    ],
)
def test_files_read_back_as_the_same_closed_surface(sphere, tmp_path, name, binary, tol):
    path = write_surface(sphere, tmp_path / name, binary=binary)
    back = read_surface(path)
    assert (back.n_vertices, back.n_faces) == (sphere.n_vertices, sphere.n_faces)
    assert closed_manifold_problems(back.vertices, back.faces) == []
    assert back.volume == pytest.approx(sphere.volume, rel=max(tol, 1e-15) * 10)
    np.testing.assert_allclose(np.sort(back.vertices, axis=0), np.sort(sphere.vertices, axis=0), atol=tol * 10)
    other = meshio.read(path)  # an independent reader
    assert len(other.cells_dict["triangle"]) == sphere.n_faces


def test_an_unknown_extension_is_a_config_error(sphere, tmp_path):
    with pytest.raises(ConfigError, match=r"unknown surface file extension '\.step'.*\.stl, \.ply, \.obj"):
        write_surface(sphere, tmp_path / "part.step")
