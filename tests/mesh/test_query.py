"""Point location in hex8 meshes and distances to their boundary, against geometry known in closed form."""

import numpy as np
import pytest

from contopt.mesh import query
from contopt.mesh.generators import annulus, box
from contopt.mesh.query import boundary_distance, boundary_triangles, locate_points, point_triangle_distance, trilinear


@pytest.fixture(params=["whole", "chunks"])
def chunks(request, monkeypatch):
    """The points located (and distances computed) at once, or in many chunks of 97 (12)."""
    if request.param == "chunks":
        monkeypatch.setattr(query, "_CHUNK", 97)


def _map(mesh, cell, xi):
    N, _ = trilinear(xi)
    return np.einsum("ka,kad->kd", N, mesh.points[mesh.cells[cell]])


def test_points_are_located_in_a_box_and_mapped_back(rng, chunks):
    mesh = box((2.0, 1.0, 0.5), (8, 4, 3), origin=(1.0, -1.0, 0.0))
    p = rng.uniform([0.8, -1.2, -0.1], [3.2, 0.2, 0.6], size=(4000, 3))
    cell, xi = locate_points(mesh, p)
    inside = np.all((p >= [1.0, -1.0, 0.0]) & (p <= [3.0, 0.0, 0.5]), axis=1)
    np.testing.assert_array_equal(cell >= 0, inside)
    assert np.abs(xi).max() <= 1.0 + 1e-9
    np.testing.assert_allclose(_map(mesh, cell[inside], xi[inside]), p[inside], atol=1e-12)
    # mesh nodes and face points lie on the closed cells
    c, _ = locate_points(mesh, mesh.points)
    assert np.all(c >= 0)


def test_points_are_located_in_a_curved_ring(rng, chunks):
    """The annulus' cells have straight chords: a point is inside when its radius lies between
    those of the polygons through the nodes at its angle."""
    n = 24
    mesh = annulus(1.0, 2.0, 0.5, (n, 3, 2), center=(0.0, 0.0, 0.25))
    p = rng.uniform([-2.1, -2.1, -0.1], [2.1, 2.1, 0.6], size=(6000, 3))
    cell, xi = locate_points(mesh, p)
    r, a = np.hypot(p[:, 0], p[:, 1]), np.mod(np.arctan2(p[:, 1], p[:, 0]), 2 * np.pi / n)
    chord = np.cos(np.pi / n) / np.cos(a - np.pi / n)  # radius of the polygon at this angle, per unit radius
    inside = (r > 1.0 * chord) & (r < 2.0 * chord) & (p[:, 2] > 0) & (p[:, 2] < 0.5)
    margin = np.minimum.reduce([np.abs(r - chord), np.abs(r - 2 * chord), np.abs(p[:, 2]), np.abs(p[:, 2] - 0.5)])
    clear = margin > 1e-9
    np.testing.assert_array_equal((cell >= 0)[clear], inside[clear])
    np.testing.assert_allclose(_map(mesh, cell[cell >= 0], xi[cell >= 0]), p[cell >= 0], atol=1e-12)


def test_point_triangle_distance_against_dense_sampling(rng):
    tri = rng.normal(size=(300, 3, 3))
    p = rng.normal(size=(300, 3)) * 2.0
    d = point_triangle_distance(p, tri)
    k = 60  # barycentric samples of each triangle: the minimum over them is an upper bound within ~ size / k
    u, v = np.meshgrid(np.linspace(0, 1, k + 1), np.linspace(0, 1, k + 1))
    keep = u + v <= 1.0
    u, v = u[keep], v[keep]
    samples = (
        tri[:, None, 0]
        + u[None, :, None] * (tri[:, None, 1] - tri[:, None, 0])
        + v[None, :, None] * (tri[:, None, 2] - tri[:, None, 0])
    )
    sampled = np.linalg.norm(samples - p[:, None, :], axis=2).min(axis=1)
    size = np.linalg.norm(tri - tri.mean(axis=1, keepdims=True), axis=2).max(axis=1)
    assert np.all(d <= sampled + 1e-12)
    assert np.all(sampled - d <= 2.0 * size / k)


def test_boundary_distance_is_exact_in_its_band_and_a_bound_beyond(rng, chunks):
    mesh = box((2.0, 1.0, 1.0), (8, 4, 4))
    p = rng.uniform(-0.5, 2.5, size=(5000, 3))
    band = 0.3
    d = boundary_distance(boundary_triangles(mesh), p, band)
    inside = np.all((p >= 0) & (p <= [2, 1, 1]), axis=1)
    exact = np.where(
        inside, np.minimum(p, [2, 1, 1] - p).min(axis=1), np.linalg.norm(p - np.clip(p, 0, [2, 1, 1]), axis=1)
    )
    near = exact < band
    np.testing.assert_allclose(d[near], exact[near], atol=1e-12)
    assert np.all(d[~near] >= band) and np.all(d >= exact - 1e-12)


def test_boundary_triangles_cover_the_boundary_with_outward_normals():
    mesh = annulus(1.0, 2.0, 0.5, (12, 2, 2))
    tri = boundary_triangles(mesh)
    volume = np.einsum("kd,kd->k", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0
    n = 12  # the mesh: a 12-gon ring with straight chords
    assert volume == pytest.approx(0.5 * n / 2 * np.sin(2 * np.pi / n) * (4.0 - 1.0), rel=1e-12)
