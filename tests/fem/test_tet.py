"""Tet4 and tet10: shape functions, rules, face quadrature and the element energy, residual, tangent.

References: exact properties of linear and quadratic interpolation, integrals of monomials over
the reference tetrahedron (``int x^a y^b z^c = a! b! c! / (a + b + c + 3)!``), the divergence
theorem on a curved tet10, central finite differences of the element energy and residual, and
``jax.hessian`` of the element energy.
"""

from functools import partial
from math import factorial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _analytic import rel_err  # tests/_analytic.py (hand formulas)

from contopt.errors import MeshError
from contopt.fem.element import element_energy, element_residual_tangent
from contopt.fem.tet import (
    TET10_NODES_XI,
    cell_geometry,
    face_quadrature,
    shape,
    shape_grad,
    tet_quadrature,
)
from contopt.material.energy import mooney_rivlin_energy
from contopt.material.hyperelastic import MooneyRivlin, neo_hookean
from contopt.mesh.core import Mesh

ENERGY = mooney_rivlin_energy
MATERIALS = {
    "neo-hookean": neo_hookean(1.0, 0.45),
    "mooney-rivlin": MooneyRivlin.from_E_nu(1.0, 0.45, b_fraction=0.3),
}


@pytest.fixture(params=sorted(MATERIALS))
def mat(request):
    return MATERIALS[request.param]


@pytest.fixture(params=[4, 10], ids=["tet4", "tet10"])
def n(request):
    return request.param


def curved_tet(rng, n, amount=0.05):
    """A distorted tet: corners moved by up to 0.15, tet10's edge nodes off their midpoints by ``amount``."""
    X = TET10_NODES_XI[:n] * np.array([1.0, 1.3, 0.8]) + rng.uniform(-0.15, 0.15, (n, 3)) * (np.arange(n) < 4)[:, None]
    if n == 10:
        from contopt.fem.tet import TET10_EDGES

        X[4:] = X[TET10_EDGES].mean(axis=1) + rng.uniform(-amount, amount, (6, 3))
    return X


def geometry(X):
    g = cell_geometry(X, np.arange(len(X))[None, :])
    return g.grad[0], g.wdet[0], g.volume[0]


# --------------------------------------------------------- shape functions
def test_shape_functions_partition_of_unity_and_kronecker(rng, n):
    nodes = TET10_NODES_XI[:n]
    np.testing.assert_allclose(shape(nodes, n), np.eye(n), atol=1e-15)
    xi = rng.dirichlet(np.ones(4), 20)[:, 1:]
    np.testing.assert_allclose(shape(xi, n).sum(axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(shape_grad(xi, n).sum(axis=1), 0.0, atol=1e-13)


def test_shape_gradients_match_fd(rng, n):
    xi = rng.dirichlet(np.ones(4), 5)[:, 1:]
    h = 1e-6
    fd = np.stack([(shape(xi + h * e, n) - shape(xi - h * e, n)) / (2 * h) for e in np.eye(3)], axis=-1)
    assert rel_err(shape_grad(xi, n), fd) <= 1e-8


@pytest.mark.parametrize("powers", [(0, 0, 0), (1, 0, 0), (0, 1, 1), (2, 0, 0), (0, 0, 2), (1, 1, 0)])
def test_rules_integrate_monomials_exactly(powers):
    a, b, c = powers
    exact = factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + 3)
    for n in (4, 10):
        if n == 4 and a + b + c > 1:
            continue  # the 1-point rule is of degree 1
        xi, w = tet_quadrature(n)
        assert np.dot(w, xi[:, 0] ** a * xi[:, 1] ** b * xi[:, 2] ** c) == pytest.approx(exact, rel=1e-14)
    assert (tet_quadrature(10)[1] > 0).all()


def test_shape_gradients_reproduce_linear_field_on_curved_cell(rng, n):
    X = curved_tet(rng, n)
    A, c = rng.standard_normal((3, 3)), rng.standard_normal(3)
    grad, wdet, _ = geometry(X)
    G = np.einsum("ai,qaJ->qiJ", X @ A.T + c, grad)
    np.testing.assert_allclose(G, np.broadcast_to(A, G.shape), atol=1e-12)


def test_straight_tet_volume_is_det_over_6(rng, n):
    X = curved_tet(rng, 4)
    if n == 10:
        from contopt.mesh.tets import to_tet10

        points, cells = to_tet10(X, np.arange(4)[None])
        X = points[cells[0]]
    assert geometry(X)[2] == pytest.approx(np.linalg.det(X[1:4] - X[0]) / 6.0, rel=1e-13)


def test_face_quadrature_divergence_theorem_on_curved_cell(rng, n):
    """sum over faces of int x n dA = 3 V and int n dA = 0 (closed surface), on a curved tet10."""
    X = curved_tet(rng, n)
    facets = np.array([[0, f] for f in range(4)])
    N, wda, normal = face_quadrature(X, np.arange(n)[None], facets)
    x = np.einsum("kqa,aj->kqj", N, X)
    V = geometry(X)[2]
    assert np.einsum("kq,kqj,kqj->", wda, x, normal) == pytest.approx(3.0 * V, rel=1e-12 if n == 4 else 2e-3)
    np.testing.assert_allclose(np.einsum("kq,kqj->j", wda, normal), 0.0, atol=1e-12 if n == 4 else 1e-3)


def test_straight_face_area_and_outward_normals():
    X = TET10_NODES_XI.copy()
    N, wda, normal = face_quadrature(X, np.arange(10)[None], np.array([[0, f] for f in range(4)]))
    areas = wda.sum(axis=1)
    np.testing.assert_allclose(areas, [0.5, np.sqrt(3) / 2, 0.5, 0.5], rtol=1e-14)
    centroid = X[:4].mean(axis=0)
    x = np.einsum("kqa,aj->kqj", N, X)
    assert (np.einsum("kqj,kqj->kq", x - centroid, normal) > 0).all()


def test_inverted_tet_is_refused():
    X = TET10_NODES_XI[:4][[0, 2, 1, 3]]
    with pytest.raises(MeshError, match="tetrahedron 0 is inverted or degenerate"):
        Mesh(X, [np.arange(4)])


# ------------------------------------------------------------ the kernels
@partial(jax.jit, static_argnames=())
def energies(us, grad, wdet, params):
    return jax.vmap(lambda u: element_energy(u, grad, wdet, 1.0, params, ENERGY, False))(us)


@jax.jit
def residuals(us, grad, wdet, params):
    return jax.vmap(lambda u: element_residual_tangent(u, grad, wdet, 1.0, params, ENERGY, False, tangent=False)[1])(us)


@pytest.fixture
def deformed(rng, n):
    X = curved_tet(rng, n)
    F0 = np.diag([1.3, 0.8, 1.1]) + 0.15 * rng.uniform(-1, 1, (3, 3))
    u = X @ (F0 - np.eye(3)).T + 0.03 * rng.standard_normal((n, 3))
    grad, wdet, _ = geometry(X)
    F = np.eye(3) + np.einsum("ai,qaJ->qiJ", u, grad)
    assert np.linalg.det(F).min() > 0.3
    return u, grad, wdet


def _perturbations(u, h):
    k = u.size
    E = np.eye(k).reshape(k, *u.shape) * h
    return np.concatenate([u[None] + E, u[None] - E])


def test_residual_matches_fd_of_energy(mat, deformed):
    u, grad, wdet = deformed
    k = u.size
    W, r, _ = element_residual_tangent(u, grad, wdet, 1.0, mat.params, ENERGY, False)
    h = 1e-6
    e = np.asarray(energies(_perturbations(u, h), grad, wdet, mat.params))
    r_fd = ((e[:k] - e[k:]) / (2 * h)).reshape(u.shape)
    assert rel_err(r, r_fd) <= 1e-6
    np.testing.assert_allclose(np.asarray(r).sum(axis=0), 0.0, atol=1e-12 * np.abs(r).max())


def test_tangent_matches_fd_of_residual_and_hessian(mat, deformed):
    u, grad, wdet = deformed
    k = u.size
    _, _, K = element_residual_tangent(u, grad, wdet, 1.0, mat.params, ENERGY, False)
    K = np.asarray(K).reshape(k, k)
    h = 1e-6
    rs = np.asarray(residuals(_perturbations(u, h), grad, wdet, mat.params)).reshape(2 * k, k)
    assert rel_err(K, ((rs[:k] - rs[k:]) / (2 * h)).T) <= 1e-6
    H = jax.hessian(element_energy)(jnp.asarray(u), grad, wdet, 1.0, mat.params, ENERGY, False)
    assert rel_err(K, np.asarray(H).reshape(k, k)) <= 1e-12
    assert np.linalg.norm(K - K.T) <= 1e-12 * np.linalg.norm(K)
