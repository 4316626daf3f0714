"""Small numpy Q1 (hex8, trilinear) linear-elastic stiffness assembler for solver tests.

Self-contained on purpose: the linear-solver tests and benchmark must not depend
on the (concurrently developed) FE layer of contopt.

Node ordering of a cell follows VTK (see ``contopt.mesh.core``): bottom face
``(0,0,0) (1,0,0) (1,1,0) (0,1,0)`` then the top face above it.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

# Reference coordinates of the 8 nodes, VTK_HEXAHEDRON order, shape (8, 3).
_XI_NODES = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    dtype=np.float64,
)


def hex8_stiffness(E: float = 1.0, nu: float = 0.3, h: float = 1.0) -> np.ndarray:
    """Stiffness of one cube element of side ``h``; shape (24, 24), dofs node-major (x, y, z)."""
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    D = np.zeros((6, 6))
    D[:3, :3] = lam
    D[np.arange(3), np.arange(3)] += 2 * mu
    D[np.arange(3, 6), np.arange(3, 6)] = mu
    g = 1 / np.sqrt(3.0)
    Ke = np.zeros((24, 24))
    for q in np.array(np.meshgrid([-g, g], [-g, g], [-g, g], indexing="ij")).reshape(3, -1).T:
        # dN/dxi of the trilinear shape functions at q, shape (8, 3)
        f = 1 + _XI_NODES * q  # (8, 3)
        dN = np.empty((8, 3))
        dN[:, 0] = _XI_NODES[:, 0] * f[:, 1] * f[:, 2] / 8
        dN[:, 1] = _XI_NODES[:, 1] * f[:, 0] * f[:, 2] / 8
        dN[:, 2] = _XI_NODES[:, 2] * f[:, 0] * f[:, 1] / 8
        dNdx = dN * (2.0 / h)
        B = np.zeros((6, 24))
        B[0, 0::3] = dNdx[:, 0]
        B[1, 1::3] = dNdx[:, 1]
        B[2, 2::3] = dNdx[:, 2]
        B[3, 0::3], B[3, 1::3] = dNdx[:, 1], dNdx[:, 0]
        B[4, 1::3], B[4, 2::3] = dNdx[:, 2], dNdx[:, 1]
        B[5, 0::3], B[5, 2::3] = dNdx[:, 2], dNdx[:, 0]
        Ke += B.T @ D @ B * (h / 2) ** 3
    return Ke


def cube_cells(n: int) -> np.ndarray:
    """Connectivity of an ``n^3`` structured hex mesh of the unit cube; shape (n^3, 8)."""

    def node(i, j, k):
        return i + (n + 1) * (j + (n + 1) * k)

    i, j, k = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij"))
    return np.stack(
        [
            node(i, j, k),
            node(i + 1, j, k),
            node(i + 1, j + 1, k),
            node(i, j + 1, k),
            node(i, j, k + 1),
            node(i + 1, j, k + 1),
            node(i + 1, j + 1, k + 1),
            node(i, j + 1, k + 1),
        ],
        axis=1,
    )


def cube_stiffness(n: int, *, clamp: bool = True, E: np.ndarray | float = 1.0, nu: float = 0.3) -> sp.csr_matrix:
    """Global stiffness of the unit cube meshed with ``n^3`` hex8 elements.

    ``E`` is a scalar or one Young's modulus per element, shape (n^3,). With
    ``clamp`` the nodes on the face x = 0 are fixed (their dofs removed), so the
    matrix is SPD with ``3 (n+1)^2 n`` dofs; without it, it has the 6 rigid body
    modes and ``3 (n+1)^3`` dofs. Returned as canonical CSR, shape (ndof, ndof).
    """
    cells = cube_cells(n)
    Ke = hex8_stiffness(1.0, nu, 1.0 / n)
    Ee = np.broadcast_to(np.asarray(E, dtype=np.float64), (cells.shape[0],))
    dofs = (3 * cells[:, :, None] + np.arange(3)).reshape(-1, 24)  # (ncell, 24)
    rows = np.repeat(dofs, 24, axis=1).ravel()
    cols = np.tile(dofs, (1, 24)).ravel()
    vals = (Ee[:, None, None] * Ke).ravel()
    ndof = 3 * (n + 1) ** 3
    K = sp.coo_matrix((vals, (rows, cols)), shape=(ndof, ndof)).tocsr()
    K.sum_duplicates()
    # Symmetrize exactly: the quadrature sum is symmetric only up to round-off.
    K = ((K + K.T) * 0.5).tocsr()
    if clamp:
        K = keep_dofs(K, np.setdiff1d(np.arange(ndof), x0_face_dofs(n)))
    K.sort_indices()
    return K


def x0_face_dofs(n: int, components=(0, 1, 2)) -> np.ndarray:
    """Dofs of the given displacement components of the nodes on the face x = 0; sorted."""
    nodes = np.flatnonzero(np.arange((n + 1) ** 3) % (n + 1) == 0)
    return np.sort((3 * nodes[:, None] + np.asarray(components)).ravel())


def keep_dofs(K: sp.spmatrix, dofs: np.ndarray) -> sp.csr_matrix:
    """The square sub-matrix ``K[dofs][:, dofs]`` as canonical CSR."""
    K = sp.csr_matrix(K)[dofs][:, dofs].tocsr()
    K.sort_indices()
    return K
