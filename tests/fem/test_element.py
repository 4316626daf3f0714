"""Hex8 shape functions / geometry and the element energy, residual, tangent and stress.

References: exact properties of trilinear interpolation, parallelepiped
volumes (|det| of the edge vectors), an independent divergence-theorem
volume of a distorted cell, central finite differences of the element
energy and residual, ``jax.hessian`` of the element energy, rigid rotations
(objectivity) and homogeneous deformations (F-bar kinematics).
"""

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from _analytic import rel_err  # tests/_analytic.py (hand formulas)

from contopt.fem.element import (
    cauchy_stress,
    deformation_gradients,
    element_energy,
    element_residual_tangent,
)
from contopt.fem.hex8 import HEX_NODES_XI, cell_geometry, face_quadrature, hex_gauss, shape, shape_grad
from contopt.material.energy import mooney_rivlin_energy
from contopt.material.hyperelastic import MooneyRivlin, neo_hookean

ENERGY = mooney_rivlin_energy
MATERIALS = {
    "neo-hookean": neo_hookean(1.0, 0.45),
    "mooney-rivlin": MooneyRivlin.from_E_nu(1.0, 0.45, b_fraction=0.3),
}
UNIT = (HEX_NODES_XI + 1.0) / 2.0  # (8, 3) unit cube, VTK order


@pytest.fixture(params=sorted(MATERIALS))
def mat(request):
    return MATERIALS[request.param]


@pytest.fixture(params=[False, True], ids=["plain", "fbar"])
def use_fbar(request):
    return request.param


# ------------------------------------------------------------------ helpers


def distorted_cell(rng, amount=0.15):
    """A unit cube with every node moved randomly by up to ``amount`` per coordinate (non-planar faces)."""
    X = UNIT * np.array([1.0, 1.3, 0.8]) + rng.uniform(-amount, amount, (8, 3))
    return X


def geometry(X, order=2):
    g = cell_geometry(X, np.arange(8)[None, :], order)
    return g.grad[0], g.wdet[0], g.volume[0]


def large_displacement(rng, X):
    """u = (F0 - I) X + noise: large stretch/shear plus a nonhomogeneous part."""
    F0 = np.diag([1.4, 0.75, 1.1]) + 0.2 * rng.uniform(-1, 1, (3, 3))
    return X @ (F0 - np.eye(3)).T + 0.06 * rng.standard_normal((8, 3))


def min_det_F(u, X):
    """Smallest det F over the 2x2x2 Gauss points and a 5x5x5 grid of the cell (sanity of the test state)."""
    xi = np.stack(np.meshgrid(*[np.linspace(-1, 1, 5)] * 3, indexing="ij"), -1).reshape(-1, 3)
    dN = shape_grad(xi)  # (p, 8, 3)
    Jx = np.einsum("aj,pak->pjk", X, dN)
    Ju = np.einsum("aj,pak->pjk", u, dN)
    F = np.eye(3) + Ju @ np.linalg.inv(Jx)
    grad, _, _ = geometry(X)
    Fq = np.asarray(deformation_gradients(jnp.asarray(u), jnp.asarray(grad)))
    return min(np.linalg.det(F).min(), np.linalg.det(Fq).min())


def rotation_90():
    """An exact rigid rotation by 90 degrees (about z, then about x): integer entries, det +1."""
    Rz = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    return Rx @ Rz


@partial(jax.jit, static_argnames=("use_fbar",))
def energies(us, grad, wdet, rho, params, use_fbar):
    """Element energy of a batch of displacements (k, 8, 3)."""
    return jax.vmap(lambda u: element_energy(u, grad, wdet, rho, params, ENERGY, use_fbar))(us)


@partial(jax.jit, static_argnames=("use_fbar",))
def residuals(us, grad, wdet, rho, params, use_fbar):
    return jax.vmap(lambda u: element_residual_tangent(u, grad, wdet, rho, params, ENERGY, use_fbar, tangent=False)[1])(
        us
    )


@partial(jax.jit, static_argnames=("use_fbar",))
def residual_tangent(u, grad, wdet, rho, params, use_fbar):
    return element_residual_tangent(u, grad, wdet, rho, params, ENERGY, use_fbar, tangent=True)


@partial(jax.jit, static_argnames=("use_fbar",))
def energy_hessian(u, grad, wdet, rho, params, use_fbar):
    return jax.hessian(element_energy)(u, grad, wdet, rho, params, ENERGY, use_fbar)


@partial(jax.jit, static_argnames=("use_fbar",))
def stresses(u, grad, wdet, params, use_fbar):
    return cauchy_stress(u, grad, wdet, params, ENERGY, use_fbar)


def perturbations(u, h):
    """(48, 8, 3): u + h e_k for the 24 dofs, then u - h e_k."""
    E = np.eye(24).reshape(24, 8, 3) * h
    return np.concatenate([u[None] + E, u[None] - E])


# --------------------------------------------------------- shape functions
def test_shape_functions_partition_of_unity_and_kronecker(rng):
    xi = rng.uniform(-1, 1, (50, 3))
    N = shape(xi)
    np.testing.assert_allclose(N.sum(axis=1), 1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(shape_grad(xi).sum(axis=1), 0.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(shape(HEX_NODES_XI), np.eye(8), rtol=0, atol=1e-15)
    # N_a(xi) = prod_k (1 + xi_k xi_a,k) / 8 written out independently for node 6 = (+1, +1, +1)
    np.testing.assert_allclose(N[:, 6], (1 + xi[:, 0]) * (1 + xi[:, 1]) * (1 + xi[:, 2]) / 8, rtol=1e-14)
    # the shape function derivatives are the central differences of the shape functions (exact: N is
    # linear in each coordinate separately)
    h = 1e-3
    for k in range(3):
        d = np.zeros(3)
        d[k] = h
        fd = (shape(xi + d) - shape(xi - d)) / (2 * h)
        np.testing.assert_allclose(shape_grad(xi)[..., k], fd, rtol=0, atol=1e-12)


def test_hex_gauss_integrates_cubics_exactly():
    xi, w = hex_gauss(2)
    assert w.sum() == pytest.approx(8.0, rel=1e-15)
    # int_{-1}^{1} x^2 y^2 z^2 = (2/3)^3 ; x^3 y z^2 odd -> 0
    assert np.dot(w, xi[:, 0] ** 2 * xi[:, 1] ** 2 * xi[:, 2] ** 2) == pytest.approx((2 / 3) ** 3, rel=1e-14)
    assert abs(np.dot(w, xi[:, 0] ** 3 * xi[:, 1] * xi[:, 2] ** 2)) < 1e-15


@pytest.mark.parametrize("order", [2, 3])
def test_shape_gradients_reproduce_linear_field_on_distorted_cell(rng, order):
    X = distorted_cell(rng)
    grad, _, _ = geometry(X, order)
    G = rng.standard_normal((3, 3))
    c = rng.standard_normal(3)
    v = c + X @ G.T  # nodal values of v(X) = c + G X
    grad_v = np.einsum("ai,qaj->qij", v, grad)
    np.testing.assert_allclose(grad_v, np.broadcast_to(G, grad_v.shape), rtol=0, atol=1e-13)
    # and the constant field has zero gradient
    np.testing.assert_allclose(grad.sum(axis=1), 0.0, rtol=0, atol=1e-13)


def test_parallelepiped_volume_is_abs_det_of_edges(rng):
    M = np.array([[1.2, 0.3, -0.2], [0.1, 0.9, 0.4], [-0.3, 0.2, 1.5]])
    X0 = rng.standard_normal(3)
    X = X0 + UNIT @ M.T
    _, wdet, vol = geometry(X)
    assert vol == pytest.approx(abs(np.linalg.det(M)), rel=1e-14)
    # constant Jacobian: every Gauss point has the same weight det/8
    np.testing.assert_allclose(wdet, abs(np.linalg.det(M)) / 8.0, rtol=1e-14)


def _divergence_theorem_volume(X):
    """V = 1/3 sum_faces int X . (X_s x X_t) ds dt over the bilinear faces, 4x4 Gauss (exact).

    Independent of the code under test: each face is parametrized here from
    its four corners (s, t in [0, 1], counter-clockwise seen from outside).
    """
    # faces as corner-node lists, counter-clockwise seen from outside (from the VTK convention)
    faces = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
    p, w = np.polynomial.legendre.leggauss(4)
    p, w = (p + 1) / 2, w / 2
    V = 0.0
    for f in faces:
        a, b, c, d = X[f]
        for s, ws in zip(p, w):
            for t, wt in zip(p, w):
                x = (1 - s) * (1 - t) * a + s * (1 - t) * b + s * t * c + (1 - s) * t * d
                xs = (1 - t) * (b - a) + t * (c - d)
                xt = (1 - s) * (d - a) + s * (c - b)
                V += ws * wt * np.dot(x, np.cross(xs, xt)) / 3.0
    return V


def test_distorted_cell_volume_matches_divergence_theorem(rng):
    for _ in range(3):
        X = distorted_cell(rng, 0.2)
        _, wdet, vol = geometry(X)
        ref = _divergence_theorem_volume(X)
        assert vol == pytest.approx(ref, rel=1e-13)
        assert wdet.sum() == pytest.approx(ref, rel=1e-13)
        # a higher Gauss order gives the same volume (det J is a tensor cubic at most)
        assert geometry(X, 3)[2] == pytest.approx(ref, rel=1e-13)
    # sanity of the reference itself: a box of sides 1 x 1.3 x 0.8
    assert _divergence_theorem_volume(UNIT * [1.0, 1.3, 0.8]) == pytest.approx(1.04, rel=1e-14)


def test_face_quadrature_on_sheared_box_cell():
    M = np.array([[1.0, 0.4, 0.3], [0.0, 1.2, -0.25], [0.0, 0.0, 0.7]])
    X = UNIT @ M.T + np.array([0.5, -1.0, 2.0])
    centre = X.mean(axis=0)
    facets = np.stack([np.zeros(6, int), np.arange(6)], axis=1)
    N, wda, normal = face_quadrature(X, np.arange(8)[None, :], facets)
    for f in range(6):
        # the face is the set of nodes with reference coordinate axis = side; find it from the nodes
        on = [
            (ax, side)
            for ax in range(3)
            for side in (-1, 1)
            if np.all(np.abs(N[f][:, HEX_NODES_XI[:, ax] != side]) < 1e-15)
        ]
        assert len(on) == 1, f
        ax, side = on[0]
        nodes = np.nonzero(HEX_NODES_XI[:, ax] == side)[0]
        P = X[nodes]
        # a parallelogram: the two edge vectors at the node with the lowest other reference coords
        others = [k for k in range(3) if k != ax]
        base = P[np.argmin(HEX_NODES_XI[nodes][:, others].sum(axis=1))]
        edges = [
            X[[a for a in nodes if np.array_equal(HEX_NODES_XI[a][others], e)][0]] - base for e in ([1, -1], [-1, 1])
        ]
        n_ref = np.cross(edges[0], edges[1])
        area = np.linalg.norm(n_ref)
        n_ref /= area
        if np.dot(P.mean(axis=0) - centre, n_ref) < 0:
            n_ref = -n_ref
        assert wda[f].sum() == pytest.approx(area, rel=1e-14), f
        np.testing.assert_allclose(normal[f], np.broadcast_to(n_ref, normal[f].shape), rtol=0, atol=1e-14)
        # the face points lie on the face: N sums to one, zero on the other four nodes
        np.testing.assert_allclose(N[f].sum(axis=1), 1.0, atol=1e-15)
    # closed surface: sum n dA = 0, and the divergence theorem gives the volume
    Xq = np.einsum("kqa,aj->kqj", N, X)
    np.testing.assert_allclose(np.einsum("kq,kqj->j", wda, normal), 0.0, atol=1e-14)
    assert np.einsum("kq,kqj,kqj->", wda, Xq, normal) / 3.0 == pytest.approx(abs(np.linalg.det(M)), rel=1e-13)


def test_face_quadrature_divergence_theorem_on_distorted_cell(rng):
    X = distorted_cell(rng, 0.2)
    facets = np.stack([np.zeros(6, int), np.arange(6)], axis=1)
    N, wda, normal = face_quadrature(X, np.arange(8)[None, :], facets)
    Xq = np.einsum("kqa,aj->kqj", N, X)
    np.testing.assert_allclose(np.einsum("kq,kqj->j", wda, normal), 0.0, atol=1e-14)
    vol = np.einsum("kq,kqj,kqj->", wda, Xq, normal) / 3.0
    assert vol == pytest.approx(_divergence_theorem_volume(X), rel=1e-13)


# ------------------------------------------------- residual and tangent vs FD
@pytest.fixture
def deformed_cell(rng):
    X = distorted_cell(rng)
    u = large_displacement(rng, X)
    assert min_det_F(u, X) > 0.3
    grad, wdet, _ = geometry(X)
    return X, u, grad, wdet


def test_residual_matches_fd_of_energy(mat, use_fbar, deformed_cell):
    X, u, grad, wdet = deformed_cell
    params = mat.params
    W, r, _ = residual_tangent(u, grad, wdet, 1.0, params, use_fbar)
    h = 1e-6
    e = np.asarray(energies(perturbations(u, h), grad, wdet, 1.0, params, use_fbar))
    r_fd = ((e[:24] - e[24:]) / (2 * h)).reshape(8, 3)
    assert rel_err(r, r_fd) <= 1e-6
    assert float(W) == pytest.approx(float(energies(u[None], grad, wdet, 1.0, params, use_fbar)[0]), rel=1e-13)
    # the residual of a free element balances: sum over nodes of the forces is zero
    np.testing.assert_allclose(np.asarray(r).sum(axis=0), 0.0, atol=1e-12 * np.abs(r).max())


def test_tangent_matches_fd_of_residual_and_hessian(mat, use_fbar, deformed_cell):
    X, u, grad, wdet = deformed_cell
    params = mat.params
    _, r, K = residual_tangent(u, grad, wdet, 1.0, params, use_fbar)
    K = np.asarray(K).reshape(24, 24)
    h = 1e-6
    rs = np.asarray(residuals(perturbations(u, h), grad, wdet, 1.0, params, use_fbar)).reshape(48, 24)
    K_fd = ((rs[:24] - rs[24:]) / (2 * h)).T  # column k = dr / du_k
    assert rel_err(K, K_fd) <= 1e-6
    H = np.asarray(energy_hessian(jnp.asarray(u), grad, wdet, 1.0, params, use_fbar)).reshape(24, 24)
    assert rel_err(K, H) <= 1e-12
    assert np.linalg.norm(K - K.T) <= 1e-12 * np.linalg.norm(K)


def test_rho_scales_energy_residual_tangent_linearly(mat, use_fbar, deformed_cell):
    X, u, grad, wdet = deformed_cell
    W1, r1, K1 = residual_tangent(u, grad, wdet, 1.0, mat.params, use_fbar)
    W3, r3, K3 = residual_tangent(u, grad, wdet, 0.3, mat.params, use_fbar)
    assert float(W3) == pytest.approx(0.3 * float(W1), rel=1e-14)
    assert rel_err(r3, 0.3 * np.asarray(r1)) <= 1e-14
    assert rel_err(K3, 0.3 * np.asarray(K1)) <= 1e-14


# --------------------------------------------------------------- objectivity
def test_rigid_rotation_gives_zero_stress_and_residual(mat, use_fbar, rng):
    X = distorted_cell(rng)
    grad, wdet, vol = geometry(X)
    R = rotation_90()
    u = X @ (R - np.eye(3)).T + rng.standard_normal(3)  # rotation plus a translation
    sig = np.asarray(stresses(u, grad, wdet, mat.params, use_fbar))
    assert np.abs(sig).max() <= 1e-12 * mat.mu
    W, r, _ = residual_tangent(u, grad, wdet, 1.0, mat.params, use_fbar)
    assert np.abs(np.asarray(r)).max() <= 1e-12 * mat.mu * vol ** (2 / 3)
    assert abs(float(W)) <= 1e-12 * mat.mu * vol
    # the test can fail: a unit-size strain gives stresses and forces of order mu
    u_strained = X @ (R @ np.diag([1.1, 1.0, 1.0]) - np.eye(3)).T
    assert np.abs(np.asarray(stresses(u_strained, grad, wdet, mat.params, use_fbar))).max() > 0.05 * mat.mu


def test_superposed_rotation_rotates_cauchy_stress(mat, use_fbar, deformed_cell):
    X, u, grad, wdet = deformed_cell
    R = rotation_90()
    q, _ = np.linalg.qr(np.array([[1.0, 0.2, -0.4], [0.3, -1.0, 0.1], [0.5, 0.6, 0.8]]))
    R2 = q if np.linalg.det(q) > 0 else -q  # a general rotation as well
    sig = np.asarray(stresses(u, grad, wdet, mat.params, use_fbar))
    assert np.abs(sig).max() > 0.1 * mat.mu
    W, r, _ = residual_tangent(u, grad, wdet, 1.0, mat.params, use_fbar)
    for Q in (R, R2):
        u_rot = (X + u) @ Q.T - X  # x -> Q x
        sig_rot = np.asarray(stresses(u_rot, grad, wdet, mat.params, use_fbar))
        ref = np.einsum("ij,qjk,lk->qil", Q, sig, Q)
        assert rel_err(sig_rot, ref) <= 1e-12
        # energy invariant, nodal forces rotate with the body
        Wr, rr, _ = residual_tangent(u_rot, grad, wdet, 1.0, mat.params, use_fbar)
        assert float(Wr) == pytest.approx(float(W), rel=1e-12)
        assert rel_err(rr, np.asarray(r) @ Q.T) <= 1e-12


# ------------------------------------------------------------ F-bar kinematics
def test_fbar_equals_plain_for_homogeneous_deformation(mat, rng):
    X = distorted_cell(rng)
    grad, wdet, _ = geometry(X)
    H = 0.25 * rng.uniform(-1, 1, (3, 3))
    u = rng.standard_normal(3) + X @ H.T
    Wp, rp, Kp = residual_tangent(u, grad, wdet, 1.0, mat.params, False)
    Wf, rf, Kf = residual_tangent(u, grad, wdet, 1.0, mat.params, True)
    assert float(Wf) == pytest.approx(float(Wp), rel=1e-12)
    assert rel_err(rf, rp) <= 1e-12
    # the stress is the same at every point and equal in both formulations
    sp = np.asarray(stresses(u, grad, wdet, mat.params, False))
    sf = np.asarray(stresses(u, grad, wdet, mat.params, True))
    assert rel_err(sf, sp) <= 1e-12
    assert rel_err(sp, np.broadcast_to(sp[0], sp.shape)) <= 1e-12
    # (the tangents differ even here: F-bar changes the linearization, not the state)
    assert rel_err(Kf, Kp) > 1e-6


def test_fbar_differs_for_nonhomogeneous_deformation(mat, deformed_cell):
    X, u, grad, wdet = deformed_cell
    Wp, rp, _ = residual_tangent(u, grad, wdet, 1.0, mat.params, False)
    Wf, rf, _ = residual_tangent(u, grad, wdet, 1.0, mat.params, True)
    assert rel_err(rf, rp) > 1e-3
    # the F-bar stress has det Fbar = Theta at every point: its pressure part kappa ln(Theta)/Theta is uniform
    sf = np.asarray(stresses(u, grad, wdet, mat.params, True))
    sp = np.asarray(stresses(u, grad, wdet, mat.params, False))
    Fq = np.asarray(deformation_gradients(jnp.asarray(u), jnp.asarray(grad)))
    theta = np.dot(wdet, np.linalg.det(Fq)) / wdet.sum()
    np.testing.assert_allclose(np.trace(sf, axis1=1, axis2=2) / 3.0, mat.kappa * np.log(theta) / theta, rtol=1e-12)
    assert np.ptp(np.trace(sp, axis1=1, axis2=2)) > 1e-3 * mat.mu
