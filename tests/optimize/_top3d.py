"""An independent linear-elastic SIMP compliance code in the style of top3d (for tests only).

It shares nothing with contopt's analysis: the hex8 stiffness is integrated
here with numpy, the filter is built by brute force, the design chain
(filter -> Heaviside -> ersatz SIMP) and its derivatives are written out by
hand, and compliance sensitivities are the self-adjoint ``-u_e^T K_e u_e``.
Only the mesh arrays and the optimizer's update rule come from outside.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

# VTK hexahedron corner order in the reference cube [-1, 1]^3
CORNERS = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float
)


def isotropic_D(E: float, nu: float) -> np.ndarray:
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    D = np.zeros((6, 6))
    D[:3, :3] = lam
    D[np.arange(6), np.arange(6)] += np.array([2 * mu] * 3 + [mu] * 3)
    return D


def element_stiffness(X: np.ndarray, D: np.ndarray) -> np.ndarray:
    """(m, 24, 24) linear hex8 stiffness of cells with corner coordinates X (m, 8, 3), 2x2x2 Gauss."""
    g = 1 / np.sqrt(3)
    K = np.zeros((len(X), 24, 24))
    for xi in np.array(np.meshgrid([-g, g], [-g, g], [-g, g])).reshape(3, -1).T:
        dN = CORNERS * (1 + CORNERS[:, [1, 2, 0]] * xi[[1, 2, 0]]) * (1 + CORNERS[:, [2, 0, 1]] * xi[[2, 0, 1]]) / 8
        J = np.einsum("mai,aj->mij", X, dN)  # dX_i / dxi_j
        dNdX = np.einsum("aj,mji->mai", dN, np.linalg.inv(J))
        B = np.zeros((len(X), 6, 24))
        for a in range(8):
            bx, by, bz = dNdX[:, a, 0], dNdX[:, a, 1], dNdX[:, a, 2]
            B[:, 0, 3 * a], B[:, 1, 3 * a + 1], B[:, 2, 3 * a + 2] = bx, by, bz
            B[:, 3, 3 * a], B[:, 3, 3 * a + 1] = by, bx
            B[:, 4, 3 * a + 1], B[:, 4, 3 * a + 2] = bz, by
            B[:, 5, 3 * a], B[:, 5, 3 * a + 2] = bz, bx
        K += np.einsum("mki,kl,mlj,m->mij", B, D, B, np.linalg.det(J))
    return K


class LinearSimpCantilever:
    """Compliance of a clamped, traction-loaded hex8 body with the paper's design chain.

    points (n, 3), cells (m, 8); fixed_nodes: clamped nodes; load_facets (k, 4)
    node ids of rectangular facets carrying the traction vector ``traction``.
    """

    def __init__(self, points, cells, fixed_nodes, load_facets, traction, E, nu, radius, eta, p, nu0):
        self.points, self.cells = np.asarray(points), np.asarray(cells)
        n_dofs = 3 * len(self.points)
        self.Ke = element_stiffness(self.points[self.cells], isotropic_D(E, nu))
        self.edofs = (3 * self.cells[:, :, None] + np.arange(3)).reshape(len(self.cells), 24)
        self.rows = np.repeat(self.edofs, 24, axis=1).ravel()
        self.cols = np.tile(self.edofs, 24).ravel()
        fixed = (3 * np.asarray(fixed_nodes)[:, None] + np.arange(3)).ravel()
        self.free = np.setdiff1d(np.arange(n_dofs), fixed)
        self.f = np.zeros(n_dofs)
        for quad in np.asarray(load_facets):
            P = self.points[quad]
            area = np.linalg.norm(P[1] - P[0]) * np.linalg.norm(P[3] - P[0])  # rectangles: each node gets A/4
            for a in quad:
                self.f[3 * a : 3 * a + 3] += np.asarray(traction) * area / 4
        centroids = self.points[self.cells].mean(axis=1)
        vol = np.abs(
            np.linalg.det(
                np.stack([self.points[self.cells[:, i]] - self.points[self.cells[:, 0]] for i in (1, 3, 4)], axis=1)
            )
        )  # boxes: |edge triple product|
        dist = np.linalg.norm(centroids[:, None] - centroids[None], axis=2)
        W = np.maximum(radius - dist, 0.0) * vol[None]
        self.H = W / W.sum(axis=1, keepdims=True)
        self.vol = vol / vol.sum()
        self.eta, self.p, self.nu0 = eta, p, nu0

    def chain(self, d):
        """d -> (nu, rho, dnu/dd diagonal factor as a function)"""
        phi = self.H @ d
        th = np.tanh(self.eta * phi)
        nu = 0.5 + 0.5 * th
        rho = (1 - self.nu0) * nu**self.p + self.nu0
        dnu_dphi = 0.5 * self.eta * (1 - th**2)
        drho_dnu = (1 - self.nu0) * self.p * nu ** (self.p - 1)
        return nu, rho, dnu_dphi, drho_dnu

    def solve(self, rho):
        K = sp.csr_matrix(((self.Ke * rho[:, None, None]).ravel(), (self.rows, self.cols)))
        u = np.zeros_like(self.f)
        u[self.free] = spla.spsolve(K[self.free][:, self.free].tocsc(), self.f[self.free])
        return u

    def compliance(self, rho):
        return float(self.f @ self.solve(rho))

    def evaluate(self, d):
        """Compliance, its gradient, volume fraction and its gradient (all w.r.t. d)."""
        nu, rho, dnu_dphi, drho_dnu = self.chain(d)
        u = self.solve(rho)
        ue = u[self.edofs]
        dc_drho = -np.einsum("mi,mij,mj->m", ue, self.Ke, ue)
        dc = self.H.T @ (dc_drho * drho_dnu * dnu_dphi)
        dv = self.H.T @ (self.vol * dnu_dphi)
        return float(self.f @ u), dc, float(self.vol @ nu), dv
