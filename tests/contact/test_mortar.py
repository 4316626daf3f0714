"""Mortar integrals (JAX): quadrature, inverse map, patch tests, exact derivatives, degenerate pairs.

Every batched call uses ``chunk=CH`` so each kernel compiles once for the whole file.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _clipping import clipped_area  # tests/contact/_clipping.py

from contopt.contact import (
    TRIANGLE_DEGREE,
    TRIANGLE_POINTS,
    TRIANGLE_WEIGHTS,
    Reject,
    bilinear_shape,
    inverse_bilinear,
    pair_integrals,
    pair_values,
    pair_values_and_jacobians,
    pair_weighted_hessians,
    segment_pairs,
)
from contopt.mesh import box

CH = 16

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def nm_facet(z=0.0):
    return np.c_[SQUARE, np.full(4, z)]


def m_square(center, side, angle_deg, z):
    """Mortar square facing down (clockwise seen from +z)."""
    a = np.deg2rad(angle_deg)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    ccw = (SQUARE - 0.5) * side @ R.T + np.asarray(center, float)
    return np.c_[ccw[[0, 3, 2, 1]], np.full(4, z)]


def diamond(center, half_diagonal, z):
    return m_square(center, half_diagonal * np.sqrt(2.0), 45.0, z)


#: mortar facets over the unit nonmortar square giving 3, 4, ..., 8 vertices
SHAPES = [
    (diamond((1.0, 1.0), np.sqrt(0.5), 0.1), 3),
    (m_square((0.8, 0.7), 1.0, 3.0, 0.1), 4),
    (diamond((0.0, 0.0), 1.5, 0.1), 5),
    (diamond((0.5, -0.25), 1.35, 0.1), 6),
    (diamond((0.4, 0.4), 0.9, 0.1), 7),
    (diamond((0.5, 0.5), 0.7, 0.1), 8),
]


def stack(x_nm, x_m):
    return np.concatenate([x_nm, x_m], axis=1)


def warped_pairs(seed=7, warp=0.03):
    """The six shapes with every node moved in-plane and out of plane (non-planar facets, varied gaps)."""
    rng = np.random.default_rng(seed)
    x_nm = np.repeat(nm_facet()[None], len(SHAPES), axis=0)
    x_m = np.array([s for s, _ in SHAPES])
    x_nm = x_nm + rng.uniform(-warp, warp, x_nm.shape) * [1, 1, 2]
    x_m = x_m + rng.uniform(-warp, warp, x_m.shape) * [1, 1, 2] + [0, 0, -0.1]  # some points penetrate
    # a 3D tilt so the auxiliary plane is not a coordinate plane
    a = 0.3
    R = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    return x_nm @ R.T, x_m @ R.T


# ----------------------------------------------------------- building blocks
def test_triangle_rule_is_exact_to_its_degree():
    from math import factorial

    assert TRIANGLE_DEGREE >= 4 and TRIANGLE_WEIGHTS.sum() == pytest.approx(1.0, abs=1e-15)
    assert np.all(TRIANGLE_WEIGHTS > 0) and np.allclose(TRIANGLE_POINTS.sum(axis=1), 1.0)
    # reference triangle (0,0), (1,0), (0,1): x = L1, y = L2, area 1/2
    x, y = TRIANGLE_POINTS[:, 1], TRIANGLE_POINTS[:, 2]
    for deg in range(TRIANGLE_DEGREE + 2):
        for a in range(deg + 1):
            b = deg - a
            exact = factorial(a) * factorial(b) / factorial(a + b + 2)
            quad = 0.5 * np.dot(TRIANGLE_WEIGHTS, x**a * y**b)
            if deg <= TRIANGLE_DEGREE:
                assert quad == pytest.approx(exact, rel=1e-14, abs=1e-16), (a, b)
    # and not of degree + 1 (the rule is what it claims, no more)
    errs = [
        abs(
            0.5 * np.dot(TRIANGLE_WEIGHTS, x**a * y ** (TRIANGLE_DEGREE + 1 - a))
            - factorial(a) * factorial(TRIANGLE_DEGREE + 1 - a) / factorial(TRIANGLE_DEGREE + 3)
        )
        for a in range(TRIANGLE_DEGREE + 2)
    ]
    assert max(errs) > 1e-8


@pytest.mark.parametrize(
    "quad",
    [
        [[0, 0], [1, 0], [1, 1], [0, 1]],
        [[0, 0], [3, 0], [2, 1], [1, 1]],  # trapezoid 3:1
        [[0, 0], [1, 0], [1.8, 1.2], [0.1, 0.6]],
        [[0, 0], [1, 0], [0.52, 0.5], [0, 1]],  # interior angle near 180 degrees
        [[0, 0], [4, 0], [4.2, 0.3], [0.1, 0.25]],  # aspect ratio 15, skewed
        [[0, 0], [1, 0], [1.5, 2.0], [0, 1]],
        [[5, 5], [5, 6], [4, 6], [4, 5]],  # clockwise (as mortar quads are)
    ],
)
def test_inverse_bilinear_map_converges_to_machine_precision(quad, rng):
    p = np.asarray(quad, float)
    xi = np.r_[rng.uniform(-1, 1, (500, 2)), [[1, 1], [-1, -1], [1, -1], [-1, 1], [0, 0]]]
    pts = np.asarray(bilinear_shape(jnp.asarray(xi))) @ p
    got = np.asarray(inverse_bilinear(jnp.asarray(p), jnp.asarray(pts)))
    diag1, diag2 = p[2] - p[0], p[3] - p[1]
    size = np.sqrt(abs(diag1[0] * diag2[1] - diag1[1] * diag2[0]) / 2)
    residual = np.asarray(bilinear_shape(jnp.asarray(got))) @ p - pts
    assert np.abs(residual).max() <= 1e-14 * size
    assert np.abs(got - xi).max() <= 1e-12


# ----------------------------------------------------------------- patch tests
def test_identical_facets_at_offset_give_exact_nodal_areas():
    d = 0.37
    x_nm = nm_facet()[None]
    x_m = m_square((0.5, 0.5), 1.0, 0.0, d)[None]
    seg = segment_pairs(x_nm, x_m)
    g, a = pair_values(stack(x_nm, x_m), seg.topo, chunk=CH)
    assert np.allclose(a, 0.25, rtol=1e-14) and np.allclose(g, 0.25 * d, rtol=1e-13)


@pytest.mark.parametrize("k", range(len(SHAPES)))
def test_single_pairs_flat_parallel_g_equals_d_times_a(k):
    d = 0.1
    x_nm = nm_facet()[None]
    x_m = SHAPES[k][0][None]
    seg = segment_pairs(x_nm, x_m)
    g, a = pair_values(stack(x_nm, x_m), seg.topo, chunk=CH)
    assert seg.n_vertices[0] == SHAPES[k][1]
    assert a.sum() == pytest.approx(seg.area[0], rel=1e-13)
    assert np.allclose(g, d * a, rtol=1e-13, atol=1e-16)


def _patch(lengths, divisions, origin, angle_deg, d):
    """All pairs of the 3x3 top face of a unit block and the rotated bottom face of a block above it."""
    lower = box((1.0, 1.0, 0.5), (3, 3, 1), origin=(0.0, 0.0, -0.5))
    upper = box(tuple(lengths) + (0.5,), tuple(divisions) + (1,), origin=tuple(origin) + (d,))
    a = np.deg2rad(angle_deg)
    R = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    c = np.array([0.5, 0.5, 0.0])
    upper = upper.transformed(R, c - R @ c)
    facets = lower.facet_nodes("zmax")
    x_m = upper.points[upper.facet_nodes("zmin")]
    i, j = np.meshgrid(np.arange(len(facets)), np.arange(len(x_m)), indexing="ij")
    i, j = i.ravel(), j.ravel()
    return dict(
        x_nm=lower.points[facets[i]], x_m=x_m[j], nodes=facets[i], facets=facets, n_nodes=lower.n_nodes, R=R, c=c
    )


def _nodal_sums(values, nodes, n_nodes):
    out = np.zeros(n_nodes)
    np.add.at(out, nodes.ravel(), values.ravel())
    return out


@pytest.mark.parametrize(
    "lengths, divisions, origin, angle, total, covered",
    [
        ((1.5, 1.5), (4, 4), (-0.25, -0.25), 5.0, 1.0, True),  # 4x4 grid rotated 5 degrees
        ((1.0, 1.0), (3, 3), (0.0, 0.0), 0.0, 1.0, True),  # identical grids, aligned
        ((1.0, 1.0), (3, 3), (-0.1, 0.05), 0.0, 0.9 * 0.95, False),  # shifted by a fraction of a cell
        ((1.2, 1.2), (4, 5), (-0.1, -0.15), 3.0, 1.0, True),  # different sizes, rotated
        ((1.2, 1.1), (4, 4), (0.1, -0.2), 0.0, 0.9 * 0.9, False),  # non-matching, collinear grid lines
    ],
)
def test_patch_sums_are_exact(lengths, divisions, origin, angle, total, covered):
    d = 0.05
    pt = _patch(lengths, divisions, origin, angle, d)
    seg = segment_pairs(pt["x_nm"], pt["x_m"])
    g, a = pair_values(stack(pt["x_nm"], pt["x_m"]), seg.topo, chunk=CH)
    A = _nodal_sums(a, pt["nodes"], pt["n_nodes"])
    G = _nodal_sums(g, pt["nodes"], pt["n_nodes"])
    assert np.allclose(G, d * A, rtol=1e-13, atol=1e-16)  # node by node
    assert a.sum() == pytest.approx(total, rel=1e-13)
    if covered:
        # each nonmortar facet (area 1/9) fully covered: the integral of N_A is 1/36 per corner
        expected = _nodal_sums(np.full(pt["facets"].shape, 1.0 / 36.0), pt["facets"], pt["n_nodes"])
        assert np.allclose(A, expected, rtol=1e-13, atol=1e-16)


def test_partial_patch_total_area_matches_the_outline_overlap():
    d = -0.02  # penetrated: same geometry, negative gaps
    lengths, origin = (0.8, 0.7), (0.35, 0.45)
    pt = _patch(lengths, (4, 4), origin, 5.0, d)
    R, c = pt["R"], pt["c"]
    seg = segment_pairs(pt["x_nm"], pt["x_m"])
    g, a = pair_values(stack(pt["x_nm"], pt["x_m"]), seg.topo, chunk=CH)
    # independent oracle: plain half-plane clipping of the two convex patch outlines
    corners = np.array(origin) + SQUARE * np.array(lengths)
    outline = (corners - c[:2]) @ R[:2, :2].T + c[:2]
    exact = clipped_area(outline, SQUARE)
    assert a.sum() == pytest.approx(exact, rel=1e-13)
    assert g.sum() == pytest.approx(d * exact, rel=1e-13)
    G = _nodal_sums(g, pt["nodes"], pt["n_nodes"])
    assert np.allclose(G, d * _nodal_sums(a, pt["nodes"], pt["n_nodes"]), rtol=1e-13, atol=1e-16)


# ------------------------------------------------------------------ derivatives
def _fd_jacobian(X, topo, eps=1e-6):
    P = len(X)
    J = np.zeros((P, 8, 24))
    flat = X.reshape(P, 24)
    for k in range(24):
        vals = []
        for s in (1, -1):
            Y = flat.copy()
            Y[:, k] += s * eps
            g, a = pair_values(Y.reshape(P, 8, 3), topo, chunk=CH)
            vals.append(np.concatenate([g, a], axis=1))
        J[:, :, k] = (vals[0] - vals[1]) / (2 * eps)
    return J


def _fd_weighted_hessian(X, topo, w, eps=1e-6):
    P = len(X)
    H = np.zeros((P, 24, 24))
    flat = X.reshape(P, 24)
    for k in range(24):
        grads = []
        for s in (1, -1):
            Y = flat.copy()
            Y[:, k] += s * eps
            _, _, J = pair_values_and_jacobians(Y.reshape(P, 8, 3), topo, chunk=CH)
            grads.append(np.einsum("pa,paj->pj", w, J))
        H[:, :, k] = (grads[0] - grads[1]) / (2 * eps)
    return H


def _rel(a, b):
    return np.linalg.norm(a - b, axis=(1, 2)) / np.linalg.norm(b, axis=(1, 2))


@pytest.fixture(scope="module")
def warped():
    x_nm, x_m = warped_pairs()
    seg = segment_pairs(x_nm, x_m)
    return stack(x_nm, x_m), seg


def test_warped_pairs_cover_3_to_8_vertices_with_nonzero_gaps(warped):
    X, seg = warped
    assert sorted(seg.n_vertices) == [3, 4, 5, 6, 7, 8]
    g, a = pair_values(X, seg.topo, chunk=CH)
    assert np.all(a.sum(axis=1) > 0.05) and np.all(np.abs(g) > 1e-4) and (g < 0).any()


def test_jacobian_matches_central_differences(warped):
    X, seg = warped
    g, a, J = pair_values_and_jacobians(X, seg.topo, chunk=CH)
    g0, a0 = pair_values(X, seg.topo, chunk=CH)
    assert np.allclose(g, g0, rtol=1e-14, atol=1e-16) and np.allclose(a, a0, rtol=1e-14, atol=1e-16)
    assert np.all(_rel(J, _fd_jacobian(X, seg.topo)) <= 1e-6)


def test_weighted_hessian_matches_central_differences_and_is_symmetric(warped, rng):
    X, seg = warped
    w = rng.normal(size=(len(X), 8))
    H = pair_weighted_hessians(X, seg.topo, w, chunk=CH)
    assert np.array_equal(H, H.transpose(0, 2, 1))
    assert np.all(_rel(H, _fd_weighted_hessian(X, seg.topo, w)) <= 1e-6)


def test_values_are_invariant_under_rigid_motion(warped, rng):
    X, seg = warped
    g, a = pair_values(X, seg.topo, chunk=CH)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    Q *= np.sign(np.linalg.det(Q))  # a rotation
    g2, a2 = pair_values(X @ Q.T + [2.0, -5.0, 3.0], seg.topo, chunk=CH)
    assert np.allclose(g2, g, rtol=1e-12, atol=1e-12 * np.abs(g).max())
    assert np.allclose(a2, a, rtol=1e-12, atol=1e-12 * np.abs(a).max())


def test_single_pair_kernel_agrees_with_batched_call(warped):
    X, seg = warped
    g, a = jax.jit(pair_integrals)(jnp.asarray(X[3]), jnp.asarray(seg.topo[3]))
    gb, ab = pair_values(X, seg.topo, chunk=CH)
    assert np.allclose(g, gb[3], rtol=1e-14) and np.allclose(a, ab[3], rtol=1e-14)


# ------------------------------------------------------------- degenerate pairs
def _degenerate_cases():
    x_nm = nm_facet()
    return {
        "empty": (x_nm, m_square((3.5, 0.5), 1.0, 0.0, 0.1)),
        "edge_touch": (x_nm, m_square((1.5, 0.5), 1.0, 0.0, 0.1)),
        "zero_area_mortar": (x_nm, np.c_[[[0.2, 0.2], [0.4, 0.4], [0.6, 0.6], [0.8, 0.8]], np.full(4, 0.1)]),
        "collapsed_mortar": (x_nm, np.full((4, 3), 0.3)),
        "same_facing": (x_nm, m_square((0.5, 0.5), 1.0, 0.0, 0.1)[[0, 3, 2, 1]]),
        "collapsed_nonmortar": (np.full((4, 3), 0.5), m_square((0.5, 0.5), 1.0, 0.0, 0.1)),
    }


def test_degenerate_pairs_are_inactive_zero_and_nan_free(rng):
    cases = _degenerate_cases()
    x_nm = np.array([c[0] for c in cases.values()])
    x_m = np.array([c[1] for c in cases.values()])
    seg = segment_pairs(x_nm, x_m)
    assert not seg.active.any(), seg.counts()
    assert Reject.ACTIVE not in seg.reason
    X = stack(x_nm, x_m)
    # all-padding topology (what segment_pairs returns) and also the octagon topology
    # of a live pair forced onto the degenerate geometry: finite everywhere
    octagon = segment_pairs(nm_facet()[None], diamond((0.5, 0.5), 0.7, 0.1)[None]).topo
    for topo in (seg.topo, np.repeat(octagon, len(X), axis=0)):
        g, a, J = pair_values_and_jacobians(X, topo, chunk=CH)
        H = pair_weighted_hessians(X, topo, rng.normal(size=(len(X), 8)), chunk=CH)
        assert np.isfinite(g).all() and np.isfinite(a).all() and np.isfinite(J).all() and np.isfinite(H).all()
    g, a, J = pair_values_and_jacobians(X, seg.topo, chunk=CH)
    H = pair_weighted_hessians(X, seg.topo, np.ones((len(X), 8)), chunk=CH)
    assert not g.any() and not a.any() and not J.any() and not H.any()


def test_padding_contributes_exactly_zero_to_a_live_pair():
    x_nm, x_m = nm_facet()[None], diamond((0.5, 0.5), 0.7, 0.1)[None]
    seg = segment_pairs(x_nm, x_m)
    X = stack(x_nm, x_m)
    # padding slots filled with garbage indices behave like padding only through kind = -1
    topo = seg.topo.copy()
    g, a = pair_values(X, topo, chunk=CH)
    assert a.sum() == pytest.approx(0.82, rel=1e-13)
    tri = segment_pairs(x_nm, diamond((1.0, 1.0), np.sqrt(0.5), 0.1)[None]).topo
    assert (tri[0, :, 0] == -1).sum() == 5
    g3, a3, J3 = pair_values_and_jacobians(stack(x_nm, diamond((1.0, 1.0), np.sqrt(0.5), 0.1)[None]), tri, chunk=CH)
    assert a3.sum() == pytest.approx(0.25, rel=1e-13) and np.isfinite(J3).all()


def test_batched_calls_check_shapes_and_accept_zero_pairs():
    with pytest.raises(ValueError, match=r"\(P, 8, 3\)"):
        pair_values(np.zeros((2, 4, 3)), np.zeros((2, 8, 3), int))
    with pytest.raises(ValueError, match=r"\(P, 8\)"):
        pair_weighted_hessians(np.zeros((2, 8, 3)), np.zeros((2, 8, 3), int), np.zeros((2, 4)))
    g, a = pair_values(np.zeros((0, 8, 3)), np.zeros((0, 8, 3), int))
    assert g.shape == (0, 4) and a.shape == (0, 4)


def test_batches_by_vertex_count_agree_with_the_six_triangle_fan(warped):
    # pairs of <= 4 vertices run in the 2-triangle bucket, the others in the 6-triangle one
    X, seg = warped
    gb, ab = pair_values(X, seg.topo, chunk=CH)
    one = jax.jit(pair_integrals, static_argnames="n_tri")
    for k in range(len(X)):
        g6, a6 = one(jnp.asarray(X[k]), jnp.asarray(seg.topo[k]), n_tri=6)
        assert np.allclose(gb[k], g6, rtol=1e-13, atol=1e-15) and np.allclose(ab[k], a6, rtol=1e-13, atol=1e-15)
        if seg.n_vertices[k] <= 4:
            g2, a2 = one(jnp.asarray(X[k]), jnp.asarray(seg.topo[k]), n_tri=2)
            assert np.allclose(g2, g6, rtol=1e-13, atol=1e-15) and np.allclose(a2, a6, rtol=1e-13, atol=1e-15)
