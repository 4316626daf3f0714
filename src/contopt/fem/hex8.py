"""Trilinear hexahedron: shape functions, Gauss rules and reference geometry.

Reference coordinates ``xi in [-1, 1]^3``; node ordering as in
:mod:`contopt.mesh.core` (VTK hexahedron). Everything here is numpy: the
reference geometry is computed once per mesh and handed to the JAX kernels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from contopt.errors import MeshError
from contopt.mesh.core import HEX_FACE_AXIS, HEX_FACE_SIDE

#: (8, 3) reference coordinates of the nodes.
HEX_NODES_XI = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    dtype=np.float64,
)


def gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    """1D Gauss rule with n points on [-1, 1]: (points (n,), weights (n,))."""
    return np.polynomial.legendre.leggauss(n)


def hex_gauss(n: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Tensor Gauss rule on the reference cube: (xi (n^3, 3), w (n^3,))."""
    p, w = gauss_legendre(n)
    # order: xi fastest, zeta slowest
    Z, Y, X = np.meshgrid(p, p, p, indexing="ij")
    WZ, WY, WX = np.meshgrid(w, w, w, indexing="ij")
    xi = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    return xi, (WX * WY * WZ).ravel()


#: (4, 2) reference coordinates of a bilinear facet's nodes (counter-clockwise).
QUAD_NODES_XI = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=np.float64)


def quad_gauss(n: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tensor Gauss rule on the reference facet [-1, 1]^2 with the bilinear shape functions there.

    Returns N (q, 4), dN/dxi (q, 4, 2) and weights (q,), q = n^2.
    """
    p, w = gauss_legendre(n)
    xi = np.array([(a, b) for a in p for b in p])
    f = 1.0 + xi[:, None, :] * QUAD_NODES_XI  # (q, 4, 2)
    N = np.prod(f, axis=-1) / 4.0
    dN = QUAD_NODES_XI * f[..., ::-1] / 4.0
    return N, dN, np.array([a * b for a in w for b in w])


def shape(xi: np.ndarray) -> np.ndarray:
    """Shape functions N at points xi (..., 3) -> (..., 8)."""
    xi = np.asarray(xi, dtype=np.float64)
    return np.prod(1.0 + xi[..., None, :] * HEX_NODES_XI, axis=-1) / 8.0


def shape_grad(xi: np.ndarray) -> np.ndarray:
    """Derivatives dN/dxi at points xi (..., 3) -> (..., 8, 3)."""
    xi = np.asarray(xi, dtype=np.float64)
    f = 1.0 + xi[..., None, :] * HEX_NODES_XI  # (..., 8, 3)
    out = np.empty(f.shape)
    for k in range(3):
        others = [j for j in range(3) if j != k]
        out[..., k] = HEX_NODES_XI[:, k] * f[..., others[0]] * f[..., others[1]] / 8.0
    return out


@dataclass(frozen=True, eq=False)
class CellGeometry:
    """Reference geometry of hex8 cells at a Gauss rule.

    Attributes
    ----------
    grad : (m, q, 8, 3) shape gradients dN_a/dX at each quadrature point
    wdet : (m, q) weight * det(dX/dxi): ``sum_q wdet[e, q] f(q)`` integrates f over cell e
    volume : (m,) reference cell volumes
    N : (q, 8) shape function values at the quadrature points
    """

    grad: np.ndarray
    wdet: np.ndarray
    volume: np.ndarray
    N: np.ndarray


def cell_geometry(points: np.ndarray, cells: np.ndarray, order: int = 2) -> CellGeometry:
    """Precompute shape gradients and weights of every cell (numpy, once per mesh).

    Raises MeshError naming the first cell with a non-positive Jacobian at a
    quadrature point.
    """
    xi, w = hex_gauss(order)
    dN = shape_grad(xi)  # (q, 8, 3)
    X = np.asarray(points, dtype=np.float64)[np.asarray(cells)]  # (m, 8, 3)
    J = np.einsum("maj,qak->mqjk", X, dN)  # dX_j/dxi_k
    det = np.linalg.det(J)
    if (det <= 0).any():
        bad = int(np.nonzero((det <= 0).any(axis=1))[0][0])
        raise MeshError(f"cell {bad} has a non-positive Jacobian at a Gauss point (inverted or degenerate)")
    Jinv = np.linalg.inv(J)  # dxi_k/dX_j
    grad = np.einsum("qak,mqkj->mqaj", dN, Jinv)
    wdet = det * w
    return CellGeometry(grad=grad, wdet=wdet, volume=wdet.sum(axis=1), N=shape(xi))


def face_quadrature(points: np.ndarray, cells: np.ndarray, facets: np.ndarray, order: int = 2):
    """Quadrature on boundary faces in the reference configuration.

    Parameters
    ----------
    facets : (k, 2) rows (cell, local face)

    Returns
    -------
    N : (k, q, 8) cell shape functions at the face points (zero for nodes off the face)
    wda : (k, q) weight * reference area element
    normal : (k, q, 3) outward unit normals
    """
    facets = np.asarray(facets, dtype=np.int64).reshape(-1, 2)
    p, w = gauss_legendre(order)
    s, t = np.meshgrid(p, p, indexing="ij")
    ws = np.outer(w, w).ravel()
    st = np.stack([s.ravel(), t.ravel()], axis=1)  # (q, 2)
    # the two in-face reference axes in cyclic order, so a x b has the sign of +axis
    tang_of_axis = np.array([[1, 2], [2, 0], [0, 1]])
    table = np.empty((6, len(ws), 3))
    for f in range(6):
        ax, (t0, t1) = HEX_FACE_AXIS[f], tang_of_axis[HEX_FACE_AXIS[f]]
        table[f, :, ax] = HEX_FACE_SIDE[f]
        table[f, :, t0], table[f, :, t1] = st[:, 0], st[:, 1]
    xi = table[facets[:, 1]]  # (k, q, 3)
    axis, side = HEX_FACE_AXIS[facets[:, 1]], HEX_FACE_SIDE[facets[:, 1]]
    tang = tang_of_axis[axis]
    k = len(facets)
    X = np.asarray(points)[np.asarray(cells)[facets[:, 0]]]  # (k, 8, 3)
    dN = shape_grad(xi)  # (k, q, 8, 3)
    J = np.einsum("kaj,kqai->kqji", X, dN)  # (k, q, 3 space, 3 ref)
    a = J[np.arange(k), :, :, tang[:, 0]]  # (k, q, 3)
    b = J[np.arange(k), :, :, tang[:, 1]]
    n = np.cross(a, b) * side[:, None, None]
    da = np.linalg.norm(n, axis=-1)
    return shape(xi), ws * da, n / da[..., None]
