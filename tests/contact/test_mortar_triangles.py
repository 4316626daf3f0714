"""Mortar segmentation and integrals of triangle facets (tri3, stored as quads whose node 3 repeats
node 0): overlap areas against an independent clipper, patch sums, exact derivatives."""

import numpy as np
import pytest
from _clipping import clipped_area  # tests/contact/_clipping.py

from contopt.contact import pair_values, pair_values_and_jacobians, pair_weighted_hessians, segment_pairs
from contopt.contact.facets import TRI6_SPLIT, as_contact_facets, padded_triangles
from contopt.contact.segment import triangles
from contopt.mesh import box

CH = 16


def tri_up(a, b, c, z=0.0):
    """A padded nonmortar triangle (counter-clockwise seen from +z, normal +z)."""
    return np.c_[np.array([a, b, c, a], float), np.full(4, z)]


def tri_down(a, b, c, z):
    """A padded mortar triangle facing down (clockwise seen from +z)."""
    return np.c_[np.array([a, c, b, a], float), np.full(4, z)]


def quad_up(center, side, angle_deg, z=0.0):
    a = np.deg2rad(angle_deg)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    sq = (np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) - 0.5) * side @ R.T + center
    return np.c_[sq, np.full(4, z)]


def quad_down(center, side, angle_deg, z):
    return quad_up(center, side, angle_deg, z)[[0, 3, 2, 1]]


def outline(x):
    """Counter-clockwise 2D outline of a facet (its distinct nodes, in +z view)."""
    p = x[:3, :2] if triangles(x[None])[0] else x[:, :2]
    area = 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
    return p if area > 0 else p[::-1]


#: (nonmortar, mortar) pairs with a triangle on one side or both, overlaps of 3 to 7 vertices
CASES = [
    (tri_up((0, 0), (1, 0), (0, 1)), quad_down((0.5, 0.5), 0.8, 0.0, 0.1)),
    (tri_up((0, 0), (1, 0), (0, 1)), quad_down((0.3, 0.3), 0.5, 20.0, 0.1)),
    (tri_up((0, 0), (1, 0.2), (0.3, 1)), quad_down((0.4, 0.4), 0.9, 45.0, 0.1)),
    (quad_up((0.5, 0.5), 1.0, 0.0), tri_down((-0.2, 0.3), (1.2, 0.1), (0.6, 1.3), 0.1)),
    (quad_up((0.5, 0.5), 1.0, 0.0), tri_down((0.1, 0.1), (0.9, 0.2), (0.4, 0.8), 0.1)),
    (tri_up((0, 0), (1, 0), (0, 1)), tri_down((0.5, -0.2), (0.6, 0.8), (-0.3, 0.4), 0.1)),
    (tri_up((0, 0), (1, 0), (0.4, 1)), tri_down((0.5, 0.45), (-0.1, 0.3), (0.8, -0.2), 0.1)),
]


def stacked(cases):
    x_nm = np.array([c[0] for c in cases])
    x_m = np.array([c[1] for c in cases])
    return x_nm, x_m, np.concatenate([x_nm, x_m], axis=1)


def test_triangle_overlaps_match_an_independent_clipper():
    x_nm, x_m, X = stacked(CASES)
    seg = segment_pairs(x_nm, x_m)
    assert seg.active.all(), seg.counts()
    assert len(set(seg.n_vertices.tolist())) >= 4  # the cases reach several polygon shapes
    g, a = pair_values(X, seg.topo, chunk=CH)
    for k in range(len(X)):
        exact = clipped_area(outline(x_m[k]), outline(x_nm[k]))
        assert seg.area[k] == pytest.approx(exact, rel=1e-13)
        assert a[k].sum() == pytest.approx(exact, rel=1e-13)
    assert np.allclose(g, 0.1 * a, rtol=1e-13, atol=1e-16)  # flat and parallel: g = d a
    tri_nm = triangles(x_nm)
    assert not a[tri_nm, 3].any() and not g[tri_nm, 3].any()  # the repeated slot weighs nothing


def test_covered_triangle_gets_a_third_of_its_area_per_node():
    x_nm = tri_up((0, 0), (1, 0), (0.2, 0.9))[None]
    x_m = quad_down((0.5, 0.5), 3.0, 10.0, -0.05)[None]
    seg = segment_pairs(x_nm, x_m)
    g, a = pair_values(np.concatenate([x_nm, x_m], axis=1), seg.topo, chunk=CH)
    assert np.allclose(a[0, :3], 0.45 / 3, rtol=1e-13) and np.allclose(g[0, :3], -0.05 * 0.45 / 3, rtol=1e-12)


def _split(quads, diagonal):
    """Triangles (2k, 3) of quads (k, 4), along diagonal 0-2 (0) or 1-3 (1)."""
    if diagonal == 0:
        return np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return np.concatenate([quads[:, [0, 1, 3]], quads[:, [1, 2, 3]]])


@pytest.mark.parametrize("side", ["nonmortar", "mortar", "both"])
def test_triangle_patch_sums_are_exact(side):
    """A 3x3 unit face (triangulated where ``side`` says) under a 4x4 face rotated by 5 degrees."""
    d = 0.05
    lower = box((1.0, 1.0, 0.5), (3, 3, 1), origin=(0.0, 0.0, -0.5))
    upper = box((1.5, 1.5, 0.5), (4, 4, 1), origin=(-0.25, -0.25, d))
    a = np.deg2rad(5.0)
    R = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    c = np.array([0.5, 0.5, 0.0])
    upper = upper.transformed(R, c - R @ c)
    nm, m = lower.facet_nodes("zmax"), upper.facet_nodes("zmin")
    if side in ("nonmortar", "both"):
        nm = padded_triangles(_split(nm, 0))
    if side in ("mortar", "both"):
        m = padded_triangles(_split(m, 1))
    i, j = (v.ravel() for v in np.meshgrid(np.arange(len(nm)), np.arange(len(m)), indexing="ij"))
    x_nm, x_m = lower.points[nm[i]], upper.points[m[j]]
    seg = segment_pairs(x_nm, x_m)
    g, a = pair_values(np.concatenate([x_nm, x_m], axis=1), seg.topo, chunk=CH)
    A, G = np.zeros(lower.n_nodes), np.zeros(lower.n_nodes)
    np.add.at(A, nm[i].ravel(), a.ravel())
    np.add.at(G, nm[i].ravel(), g.ravel())
    assert a.sum() == pytest.approx(1.0, rel=1e-13)
    assert np.allclose(G, d * A, rtol=1e-13, atol=1e-16)
    # each nonmortar facet fully covered: its area over its node count at each of its nodes
    if side == "mortar":  # quads of 1/9: 1/36 at each corner
        per = np.full(nm.shape, 1.0 / 36.0)
    else:  # triangles of 1/18: 1/54 at each of their 3 nodes, none at the repeated slot
        per = np.where(np.arange(4) < 3, 1.0 / 54.0, 0.0) * np.ones((len(nm), 1))
    expected = np.zeros(lower.n_nodes)
    np.add.at(expected, nm.ravel(), per.ravel())
    assert np.allclose(A, expected, rtol=1e-12, atol=1e-16)


def test_tri6_split_covers_the_parent_with_outward_sub_facets():
    tri6 = np.array([[0, 1, 2, 3, 4, 5]])
    sub = as_contact_facets(tri6)
    assert sub.shape == (4, 4) and np.array_equal(sub[:, 3], sub[:, 0])
    p = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    n = np.cross(p[sub[:, 1]] - p[sub[:, 0]], p[sub[:, 2]] - p[sub[:, 0]])
    assert np.allclose(n, [0, 0, 1])  # all four outward as the parent, area 1/2 each
    assert np.array_equal(np.sort(np.unique(TRI6_SPLIT)), np.arange(6))


# ------------------------------------------------------------------ derivatives
def warped_cases(seed=3, warp=0.03):
    rng = np.random.default_rng(seed)
    x_nm, x_m, _ = stacked(CASES)
    tri_nm, tri_m = triangles(x_nm), triangles(x_m)
    x_nm = x_nm + rng.uniform(-warp, warp, x_nm.shape) * [1, 1, 2]
    x_m = x_m + rng.uniform(-warp, warp, x_m.shape) * [1, 1, 2] + [0, 0, -0.1]  # some points penetrate
    # a triangle's repeated slot moves with its node 0 (it is that node)
    x_nm[tri_nm, 3] = x_nm[tri_nm, 0]
    x_m[tri_m, 3] = x_m[tri_m, 0]
    a = 0.3
    R = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    X = np.concatenate([x_nm, x_m], axis=1) @ R.T
    return X, segment_pairs(X[:, :4], X[:, 4:])


def _moved(X, k, step):
    """X with coordinate k (node-major) moved by step, a triangle's repeated slot with its node 0."""
    P = len(X)
    Y = X.reshape(P, 24).copy()
    Y[:, k] += step
    Y = Y.reshape(P, 8, 3)
    node, axis = divmod(k, 3)
    for first, slot in ((0, 3), (4, 7)):
        tri = triangles(X[:, first : first + 4])
        if node == first:
            Y[tri, slot, axis] = Y[tri, first, axis]
    return Y


def _fd_jacobian(X, topo, eps=1e-6):
    J = np.zeros((len(X), 8, 24))
    for k in range(24):
        vals = [np.concatenate(pair_values(_moved(X, k, s * eps), topo, chunk=CH), axis=1) for s in (1, -1)]
        J[:, :, k] = (vals[0] - vals[1]) / (2 * eps)
    return J


def _rel(a, b):
    return np.linalg.norm(a - b, axis=(1, 2)) / np.linalg.norm(b, axis=(1, 2))


def _real_columns(X):
    """(P, 24) bool: the coordinates that are a node's (not a triangle's repeated slot)."""
    keep = np.ones((len(X), 8, 3), bool)
    keep[triangles(X[:, :4]), 3] = False
    keep[triangles(X[:, 4:]), 7] = False
    return keep.reshape(len(X), 24)


def test_triangle_jacobian_matches_central_differences():
    X, seg = warped_cases()
    assert seg.active.all(), seg.counts()
    g, a, J = pair_values_and_jacobians(X, seg.topo, chunk=CH)
    slots = ~(triangles(X[:, :4])[:, None] & (np.arange(4) == 3))  # a triangle's slot 3 is no node
    assert np.all(np.abs(g[slots]) > 1e-5) and (g < 0).any()
    real = _real_columns(X)
    assert not J[~real[:, None, :].repeat(8, axis=1)].any()  # the repeated slot: no derivative
    fd = _fd_jacobian(X, seg.topo)
    assert np.all(_rel(J * real[:, None, :], fd * real[:, None, :]) <= 1e-6)


def test_triangle_weighted_hessian_matches_central_differences(rng):
    X, seg = warped_cases()
    w = rng.normal(size=(len(X), 8))
    H = pair_weighted_hessians(X, seg.topo, w, chunk=CH)
    assert np.array_equal(H, H.transpose(0, 2, 1))
    real = _real_columns(X)
    mask = real[:, :, None] & real[:, None, :]
    assert not H[~mask].any()
    fd = np.zeros_like(H)
    for k in range(24):
        grads = [
            np.einsum("pa,paj->pj", w, pair_values_and_jacobians(_moved(X, k, s * 1e-6), seg.topo, chunk=CH)[2])
            for s in (1, -1)
        ]
        fd[:, :, k] = (grads[0] - grads[1]) / 2e-6
    assert np.all(_rel(H * mask, fd * mask) <= 1e-6)


def test_triangle_friction_slip_jacobian_matches_central_differences(rng):
    from contopt.contact.friction import pair_slips_and_jacobians

    X, seg = warped_cases()
    Xp = X + 0.01 * rng.normal(size=X.shape)
    for t, slot in ((triangles(X[:, :4]), 3), (triangles(X[:, 4:]), 7)):
        Xp[t, slot] = Xp[t, slot - 3]  # the last step's positions: the same nodes
    z, J, _ = pair_slips_and_jacobians(X, Xp, seg.topo, chunk=CH)
    real = _real_columns(X)
    fd = np.zeros_like(J)
    for k in range(24):
        zs = [pair_slips_and_jacobians(_moved(X, k, s * 1e-6), Xp, seg.topo, chunk=CH)[0] for s in (1, -1)]
        fd[..., k] = (zs[0] - zs[1]) / 2e-6
    assert not (J * ~real[:, None, None, :]).any()  # the repeated slot: no derivative
    norm = lambda v: np.sqrt(np.sum(v * v, axis=(1, 2, 3)))  # noqa: E731
    rel = norm((J - fd) * real[:, None, None, :]) / norm(fd)
    assert np.all(rel <= 1e-6)


def test_full_nodal_areas_of_a_padded_triangle_are_a_third_of_its_area():
    # the bilinear map of [a, b, c, a] collapses onto the triangle, its shape functions onto the
    # linear ones (slots 0 and 3 together for node a): 2x2 Gauss is exact
    from contopt.contact.pairing import nodal_areas

    x = np.array([[[0.0, 0.0, 0.0], [2.0, 0.1, 0.0], [0.3, 1.5, 0.2], [0.0, 0.0, 0.0]]])
    a = nodal_areas(x)[0]
    area = 0.5 * np.linalg.norm(np.cross(x[0, 1] - x[0, 0], x[0, 2] - x[0, 0]))
    np.testing.assert_allclose([a[0] + a[3], a[1], a[2]], area / 3, rtol=1e-14)
