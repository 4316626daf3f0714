"""Tetrahedra: tet4 and tet10 shape functions, quadrature and reference geometry.

Reference coordinates ``xi = (xi, eta, zeta)`` with ``xi, eta, zeta >= 0`` and
``xi + eta + zeta <= 1``; barycentric ``L = (1 - xi - eta - zeta, xi, eta, zeta)``; node
ordering as in :mod:`contopt.mesh.core` (VTK). Everything here is numpy: the reference
geometry is computed once per mesh and handed to the same JAX kernels as hex8
(:mod:`contopt.fem.element`), which take any number of nodes a cell.

Quadrature (volume):

- tet4: one point at the centroid. Its shape gradients are constant, so F is constant in the
  cell and one point integrates every energy exactly.
- tet10: the symmetric 4-point rule of degree 2 (points at barycentric ``(a, b, b, b)``
  permutations, ``a = (5 + 3 sqrt 5) / 20``, weight 1/24 each). It integrates the quadratic
  element's mass and the small-strain stiffness (a product of two linear gradients, degree 2)
  exactly, its weights are positive (the 5-point Keast rule of degree 3 has a negative weight,
  which makes a sum of energy densities indefinite), and it is the rule of the usual
  quadratic-tet codes (Abaqus C3D10). More points do not make the element stiffer or softer to
  first order; the tests check the kernel against the beam solution and a patch test.

Faces: the 3-point rule of degree 2 on the triangle (points at ``(1/6, 1/6)`` and its
permutations), exact for a uniform traction on a flat tri6 face.
"""

from __future__ import annotations

import numpy as np

from contopt.errors import MeshError
from contopt.fem.hex8 import CellGeometry
from contopt.mesh.core import TET_FACES

#: (4, 3) reference coordinates of the corner nodes
TET_NODES_XI = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
#: the corner pair of each tet10 edge node 4-9 (VTK)
TET10_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]], dtype=np.int64)
#: (10, 3) reference coordinates of the tet10 nodes
TET10_NODES_XI = np.vstack([TET_NODES_XI, TET_NODES_XI[TET10_EDGES].mean(axis=1)])


def tet_quadrature(n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Volume rule of the element: (xi (q, 3), w (q,)); weights sum to the reference volume 1/6."""
    if n_nodes == 4:
        return np.full((1, 3), 0.25), np.array([1.0 / 6.0])
    a, b = (5.0 + 3.0 * np.sqrt(5.0)) / 20.0, (5.0 - np.sqrt(5.0)) / 20.0
    L = np.full((4, 4), b) + np.eye(4) * (a - b)  # barycentric, one row a point
    return L[:, 1:], np.full(4, 1.0 / 24.0)


def tri_quadrature() -> tuple[np.ndarray, np.ndarray]:
    """Face rule on the reference triangle (0,0), (1,0), (0,1): (st (3, 2), w (3,)), degree 2."""
    st = np.array([[1.0 / 6.0, 1.0 / 6.0], [2.0 / 3.0, 1.0 / 6.0], [1.0 / 6.0, 2.0 / 3.0]])
    return st, np.full(3, 1.0 / 6.0)


def _barycentric(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """L (..., 4) and dL/dxi (4, 3)."""
    xi = np.asarray(xi, dtype=np.float64)
    L = np.concatenate([1.0 - xi.sum(axis=-1, keepdims=True), xi], axis=-1)
    dL = np.vstack([-np.ones(3), np.eye(3)])
    return L, dL


def shape(xi: np.ndarray, n_nodes: int) -> np.ndarray:
    """Shape functions at points xi (..., 3) -> (..., n_nodes), n_nodes 4 or 10."""
    L, _ = _barycentric(xi)
    if n_nodes == 4:
        return L
    corners = L * (2.0 * L - 1.0)
    edges = 4.0 * L[..., TET10_EDGES[:, 0]] * L[..., TET10_EDGES[:, 1]]
    return np.concatenate([corners, edges], axis=-1)


def shape_grad(xi: np.ndarray, n_nodes: int) -> np.ndarray:
    """Derivatives dN/dxi at points xi (..., 3) -> (..., n_nodes, 3)."""
    L, dL = _barycentric(xi)
    if n_nodes == 4:
        return np.broadcast_to(dL, L.shape[:-1] + (4, 3)).copy()
    corners = (4.0 * L - 1.0)[..., :, None] * dL  # (..., 4, 3)
    i, j = TET10_EDGES[:, 0], TET10_EDGES[:, 1]
    edges = 4.0 * (L[..., i, None] * dL[j] + L[..., j, None] * dL[i])  # (..., 6, 3)
    return np.concatenate([corners, edges], axis=-2)


def cell_geometry(points: np.ndarray, cells: np.ndarray) -> CellGeometry:
    """Shape gradients and weights of every tet4 / tet10 cell at its rule (numpy, once per mesh).

    Raises MeshError naming the first cell with a non-positive Jacobian at a quadrature point
    (a tet10 whose edge nodes fold it).
    """
    n = np.shape(cells)[1]
    xi, w = tet_quadrature(n)
    dN = shape_grad(xi, n)  # (q, n, 3)
    X = np.asarray(points, dtype=np.float64)[np.asarray(cells)]  # (m, n, 3)
    J = np.einsum("maj,qak->mqjk", X, dN)
    det = np.linalg.det(J)
    if (det <= 0).any():
        bad = int(np.nonzero((det <= 0).any(axis=1))[0][0])
        raise MeshError(f"cell {bad} has a non-positive Jacobian at a quadrature point (inverted or degenerate)")
    grad = np.einsum("qak,mqkj->mqaj", dN, np.linalg.inv(J))
    wdet = det * w
    return CellGeometry(grad=grad, wdet=wdet, volume=wdet.sum(axis=1), N=shape(xi, n))


def face_quadrature(points: np.ndarray, cells: np.ndarray, facets: np.ndarray):
    """Quadrature on boundary faces of tets in the reference configuration.

    facets : (k, 2) rows (cell, local face of :data:`contopt.mesh.core.TET_FACES`)

    Returns N (k, q, n) cell shape functions at the face points, wda (k, q) weight * area
    element, normal (k, q, 3) outward unit normals.
    """
    facets = np.asarray(facets, dtype=np.int64).reshape(-1, 2)
    n = np.shape(cells)[1]
    st, w = tri_quadrature()
    corners = TET_NODES_XI[TET_FACES[facets[:, 1], :3]]  # (k, 3, 3) reference corners of each face
    a, b = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    xi = corners[:, None, 0] + st[None, :, :1] * a[:, None] + st[None, :, 1:] * b[:, None]  # (k, q, 3)
    X = np.asarray(points)[np.asarray(cells)[facets[:, 0]]]  # (k, n, 3)
    J = np.einsum("kaj,kqai->kqji", X, shape_grad(xi, n))  # (k, q, 3 space, 3 ref)
    ns = np.cross(np.einsum("kqji,ki->kqj", J, a), np.einsum("kqji,ki->kqj", J, b))
    da = np.linalg.norm(ns, axis=-1)
    return shape(xi, n), w * da, ns / da[..., None]
