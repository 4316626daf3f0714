"""Density method: cone filter ``phi = G d`` over element centroids (paper eq. 33)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from contopt.errors import ConfigError


def cone_filter(points: np.ndarray, sites: np.ndarray, site_volumes: np.ndarray, radius: float) -> sp.csr_matrix:
    """Normalized cone filter from design sites to evaluation points.

    ``G_ij = (r - |X_i - Y_j|) V_j / sum_k (r - |X_i - Y_k|) V_k`` for
    ``|X_i - Y_j| < r``, else 0: each row is a weighted mean, so the rows sum
    to one and a uniform design stays uniform. The neighbour pairs come from a
    KD-tree, so building G costs O(nnz log n), not O(n^2).

    Parameters
    ----------
    points : (k, 3) evaluation points (element centroids, possibly mapped by a symmetry)
    sites : (n, 3) design variable locations (centroids of the design cells)
    site_volumes : (n,) volumes of the design cells
    radius : filter radius r in the mesh's length unit

    Returns
    -------
    (k, n) CSR matrix
    """
    if not np.isfinite(radius) or radius <= 0:
        raise ConfigError(f"filter radius must be > 0, got {radius!r}")
    points, sites = np.asarray(points, np.float64), np.asarray(sites, np.float64)
    pairs = cKDTree(points).sparse_distance_matrix(cKDTree(sites), radius, output_type="ndarray")
    i, j, dist = pairs["i"], pairs["j"], pairs["v"]
    w = (radius - dist) * np.asarray(site_volumes, np.float64)[j]
    keep = w > 0
    G = sp.csr_matrix((w[keep], (i[keep], j[keep])), shape=(len(points), len(sites)))
    sums = np.asarray(G.sum(axis=1)).ravel()
    empty = np.flatnonzero(sums <= 0)
    if empty.size:
        raise ConfigError(
            f"filter radius {radius:g} reaches no design cell from {empty.size} evaluation point(s) "
            f"(e.g. at {points[empty[0]].round(6).tolist()}); increase the radius above the cell size"
        )
    G = sp.diags(1.0 / sums) @ G
    G.sort_indices()
    return G.tocsr()
