"""Reference geometry of any element type: hex8 (:mod:`contopt.fem.hex8`) or tet4 / tet10
(:mod:`contopt.fem.tet`), chosen by the cells' width."""

from __future__ import annotations

import numpy as np

from contopt.fem import hex8, tet
from contopt.fem.hex8 import CellGeometry


def cell_geometry(points: np.ndarray, cells: np.ndarray) -> CellGeometry:
    """Shape gradients (m, q, n, 3), weights (m, q), volumes (m,) and N (q, n) of every cell."""
    if np.shape(cells)[1] == 8:
        return hex8.cell_geometry(points, cells)
    return tet.cell_geometry(points, cells)


def face_quadrature(points: np.ndarray, cells: np.ndarray, facets: np.ndarray):
    """N (k, q, n), wda (k, q), outward normals (k, q, 3) on boundary faces ``(cell, local face)``."""
    if np.shape(cells)[1] == 8:
        return hex8.face_quadrature(points, cells, facets)
    return tet.face_quadrature(points, cells, facets)
