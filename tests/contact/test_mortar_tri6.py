"""Mortar integrals of tet10 faces (tri6, :mod:`contopt.contact.quadratic`): the weights, exact patch
sums of a flat face, the consistent load of a uniform pressure, exact derivatives (central
differences), and the linear kernels unchanged."""

import numpy as np
import pytest

from contopt.contact import segment_pairs
from contopt.contact.facets import TRI6_SPLIT, contact_parents, padded_triangles
from contopt.contact.quadratic import (
    TRI6_ALPHA,
    TRI6_RULE_WEIGHTS,
    quadratic_values,
    quadratic_values_and_jacobians,
    quadratic_weighted_hessians,
    tri6_shape,
    tri6_surface,
    tri6_weights,
)

CH = 8
MIDS = np.array([[0, 1], [1, 2], [2, 0]])


def tri6(corners, z=0.0, bulge=0.0):
    """(6, 3) a tri6 over 2D corners (3, 2) at height z, its midpoints raised by ``bulge``."""
    c = np.c_[np.asarray(corners, float), np.full(3, z)]
    m = c[MIDS].mean(axis=1) + [0.0, 0.0, bulge]
    return np.vstack([c, m])


def flipped(x6):
    """The same tri6 with the opposite orientation (a mortar face looking down)."""
    return x6[[0, 2, 1, 5, 4, 3]]


def quad6(center, side, z, down=True):
    sq = (np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) - 0.5) * side + center
    q = np.c_[sq, np.full(4, z)]
    q = q[[0, 3, 2, 1]] if down else q
    return np.vstack([q, q[:1], q[:1]])


def pairs(nm6, m6, kinds):
    """Every (sub-facet, sub-facet) pair of two parents that overlaps: X (P, 12, 3), topo, sub (P, 2)."""
    subs = {"tri6": range(4), "quad": [0], "tri3": [0]}
    rows = []
    for k in subs[kinds[0]]:
        for j in subs[kinds[1]]:
            rows.append((k, j))
    sub = np.array(rows)

    def seg_nodes(x6, kind, k):
        if kind == "quad":
            return x6[:4]
        if kind == "tri3":
            return x6[[0, 1, 2, 0]]
        return x6[padded_triangles(TRI6_SPLIT)[k]]

    xn = np.array([seg_nodes(nm6, kinds[0], k) for k, _ in rows])
    xm = np.array([seg_nodes(m6, kinds[1], j) for _, j in rows])
    seg = segment_pairs(xn, xm)
    X = np.repeat(np.concatenate([nm6, m6])[None], len(rows), axis=0)
    return X[seg.active], seg.topo[seg.active], sub[seg.active]


def test_weights_are_a_positive_partition_of_unity():
    rng = np.random.default_rng(1)
    xi = rng.uniform(0, 0.5, size=(50, 2))
    W = np.asarray(tri6_weights(tri6_shape(xi)))
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-15)
    # integrals on the reference triangle (area 1/2) with Radon's rule (exact to degree 5)
    from contopt.contact.mortar import TRIANGLE_POINTS, TRIANGLE_WEIGHTS

    Wq = np.asarray(tri6_weights(tri6_shape(TRIANGLE_POINTS[:, 1:])))
    ints = 0.5 * TRIANGLE_WEIGHTS @ Wq
    a = TRI6_ALPHA
    np.testing.assert_allclose(ints, 0.5 * np.r_[[2 * a / 3] * 3, [(1 - 2 * a) / 3] * 3], rtol=1e-14)


@pytest.mark.parametrize("mortar", ["quad", "tri6"])
def test_covered_flat_face_gets_the_weights_integrals_and_a_uniform_gap(mortar):
    """A flat tri6 under a larger parallel mortar face at gap d: a_A = ∫ W_A over the face and
    g_A = d a_A, summed over the sub-facet pairs; the mortar nodes get the consistent load."""
    d = 0.1
    nm = tri6([(0, 0), (1, 0), (0.2, 0.9)])
    m = quad6((0.4, 0.4), 3.0, d) if mortar == "quad" else flipped(tri6([(-1, -1), (3, -1), (-1, 3)], z=d))
    X, topo, sub = pairs(nm, m, ("tri6", mortar))
    g, a, J = quadratic_values_and_jacobians(X, topo, sub, ("tri6", mortar), chunk=CH)
    e1, e2 = nm[1] - nm[0], nm[2] - nm[0]
    area = 0.5 * abs(e1[0] * e2[1] - e1[1] * e2[0])
    A = a.sum(axis=0)
    al = TRI6_ALPHA
    np.testing.assert_allclose(A, area * np.r_[[2 * al / 3] * 3, [(1 - 2 * al) / 3] * 3], rtol=1e-13)
    np.testing.assert_allclose(g.sum(axis=0), d * A, rtol=1e-13)
    # uniform pressure: force on node b = sum_A dg_A/dx_b; the nonmortar's is -∫ N_b n0 (0 at the
    # corners, area/3 at the midpoints), the mortar's ∫ N_b over the overlap
    f = J[:, :6].sum(axis=(0, 1)).reshape(12, 3)
    np.testing.assert_allclose(f[:6, 2], -area * np.r_[0, 0, 0, 1, 1, 1] / 3, atol=1e-14)
    np.testing.assert_allclose(f[6:, 2].sum(), area, rtol=1e-13)


def test_the_parent_surface_rule_lumps_what_a_covered_flat_face_overlaps():
    """The whole-surface rule (``tri6_surface``: contopt.responses.surface's gauss and nodal on tet10)
    gives a flat tri6 the overlap areas ``∫ W_A`` the mortar kernels give it when fully covered, and
    its points lie on the face; on a bulged face its area element's derivative in the nodes matches
    central differences."""
    nm = tri6([(0, 0), (1, 0), (0.2, 0.9)], z=0.3)
    X, topo, sub = pairs(nm, quad6((0.4, 0.4), 3.0, 0.4), ("tri6", "quad"))
    _, a = quadratic_values(X, topo, sub, ("tri6", "quad"), chunk=CH)
    y, da = (np.asarray(v) for v in tri6_surface(nm))
    np.testing.assert_allclose(da @ TRI6_RULE_WEIGHTS, a.sum(axis=0), rtol=1e-13)
    np.testing.assert_allclose(y[:, 2], 0.3, rtol=1e-15)
    # d(sum_q da_q f_q)/dx for fixed weights f against central differences on a curved face
    import jax

    bulged = tri6([(0, 0), (1, 0.1), (0.2, 0.9)], bulge=0.2) + 0.02 * np.random.default_rng(2).normal(size=(6, 3))
    f = np.linspace(0.5, 1.5, da.size)
    grad = np.asarray(jax.grad(lambda x: tri6_surface(x)[1] @ f)(bulged))
    d = np.random.default_rng(3).normal(size=(6, 3))
    h = 1e-6
    fd = (np.asarray(tri6_surface(bulged + h * d)[1]) @ f - np.asarray(tri6_surface(bulged - h * d)[1]) @ f) / (2 * h)
    assert np.sum(grad * d) == pytest.approx(fd, rel=1e-7)  # O(h^2) truncation, O(eps / h) rounding: ~1e-10


def _cases():
    rng = np.random.default_rng(7)
    nm = tri6([(0, 0), (1, 0.1), (0.2, 0.9)], bulge=0.03) + 0.01 * rng.normal(size=(6, 3))
    m6 = flipped(tri6([(0.1, -0.2), (1.1, 0.3), (-0.1, 0.8)], z=-0.02, bulge=-0.02)) + 0.01 * rng.normal(size=(6, 3))
    q = quad6((0.45, 0.35), 0.7, -0.03) + 0.01 * rng.normal(size=(6, 3))
    q[4:] = q[0]
    tri = np.vstack([m6[:3], m6[:1], m6[:1], m6[:1]])
    qn = quad6((0.5, 0.4), 0.8, 0.0, down=False)
    qn[:4] += 0.01 * rng.normal(size=(4, 3))
    qn[4:] = qn[0]
    kinds = [("tri6", "tri6"), ("tri6", "quad"), ("tri6", "tri3"), ("quad", "tri6")]
    return list(zip([nm, nm, nm, qn], [m6, q, tri, m6], kinds))


def _moved(X, k, h):
    Y = X.reshape(len(X), 36).copy()
    Y[:, k] += h
    return Y.reshape(X.shape)


@pytest.mark.parametrize("case", range(4))
def test_jacobian_and_hessian_match_central_differences(case):
    nm, m, kinds = _cases()[case]
    X, topo, sub = pairs(nm, m, kinds)
    assert len(X) >= 3 and (topo[:, :, 0] == 2).any()  # clipped polygons, several sub-facets
    g, a, J = quadratic_values_and_jacobians(X, topo, sub, kinds, chunk=CH)
    assert (g < 0).any() and np.abs(g).max() > 1e-4
    fd = np.zeros_like(J)
    h = 1e-6
    for k in range(36):
        gp, ap = quadratic_values(_moved(X, k, h), topo, sub, kinds, chunk=CH)
        gm, am = quadratic_values(_moved(X, k, -h), topo, sub, kinds, chunk=CH)
        fd[:, :, k] = np.concatenate([gp - gm, ap - am], axis=1) / (2 * h)
    scale = np.abs(fd).max()
    assert np.abs(J - fd).max() <= 1e-7 * scale
    w = np.random.default_rng(3).normal(size=(len(X), 12))
    H = quadratic_weighted_hessians(X, topo, sub, w, kinds, chunk=CH)
    assert np.array_equal(H, H.transpose(0, 2, 1))
    fdH = np.zeros_like(H)
    for k in range(36):
        Jp = quadratic_values_and_jacobians(_moved(X, k, h), topo, sub, kinds, chunk=CH)[2]
        Jm = quadratic_values_and_jacobians(_moved(X, k, -h), topo, sub, kinds, chunk=CH)[2]
        fdH[:, :, k] = np.einsum("pa,paj->pj", w, Jp - Jm) / (2 * h)
    assert np.abs(H).max() > 1e-3
    assert np.abs(H - fdH).max() <= 1e-6 * np.abs(fdH).max()


def test_parents_follow_the_split_row_for_row():
    nodes = np.array([[10, 11, 12, 13, 14, 15], [20, 21, 22, 23, 24, 25]])
    parents, sub = contact_parents(nodes)
    assert parents.shape == (8, 6) and np.array_equal(sub, [0, 1, 2, 3, 0, 1, 2, 3])
    assert np.array_equal(parents[5], nodes[1])
    quads, sub = contact_parents(np.array([[1, 2, 3, 4]]))
    assert np.array_equal(quads, [[1, 2, 3, 4, 1, 1]]) and not sub.any()
