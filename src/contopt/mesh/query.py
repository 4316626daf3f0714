"""Where points lie in a mesh: containing cell and reference coordinates, distance to the boundary.

Hex8 meshes as below; in a tet4 / tet10 mesh a point's reference coordinates are those of the
corner tetrahedron (an affine map: exact for tet4 and straight-sided tet10), ``xi >= 0`` and
``xi + eta + zeta <= 1`` inside, and the boundary's triangles are the faces' corners.

* :func:`locate_points`: for each point the cell containing it and its reference coordinates
  ``xi in [-1, 1]^3`` (inverse trilinear map by Newton), or -1 outside the mesh.
* :func:`boundary_distance`: the distance of each point to the mesh's boundary surface
  (its boundary quads split into triangles), exact within a band, a bound beyond it.

Both are vectorized over points and use KD-trees of cell centroids or boundary points to
find candidates, so they cost ``O(points log cells)``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from contopt.mesh.core import HEX_FACES, TET_FACES

#: reference coordinates of the hex8 nodes (VTK order, see :mod:`contopt.mesh.core`)
_NODES_XI = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    dtype=np.float64,
)
#: a point counts as inside a cell when its reference coordinates exceed 1 by at most this
XI_TOL = 1e-9
_NEWTON_STEPS = 12
#: points located at a time (bounds the memory of the candidate pairs)
_CHUNK = 1 << 17
#: a Newton step below this no longer changes the reference coordinates (XI_TOL is 1e-9)
_XI_STEP = 1e-13


def trilinear(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions (k, 8) and their derivatives (k, 8, 3) at reference points xi (k, 3)."""
    f = 1.0 + xi[:, None, :] * _NODES_XI  # (k, 8, 3)
    N = np.prod(f, axis=-1) / 8.0
    dN = np.empty(f.shape)
    for a in range(3):
        b, c = [d for d in range(3) if d != a]
        dN[..., a] = _NODES_XI[:, a] * f[..., b] * f[..., c] / 8.0
    return N, dN


def _candidates(corners: np.ndarray, points: np.ndarray, pad: float) -> tuple[np.ndarray, np.ndarray]:
    """(point, cell) pairs with the point inside the cell's bounding box (grown by ``pad``)."""
    centroids = corners.mean(axis=1)
    radius = float(np.max(np.linalg.norm(corners - centroids[:, None, :], axis=2))) + pad
    pairs = cKDTree(points).sparse_distance_matrix(cKDTree(centroids), radius, output_type="ndarray")
    i, e = pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)
    lo, hi = corners.min(axis=1) - pad, corners.max(axis=1) + pad
    inside = np.all((points[i] >= lo[e]) & (points[i] <= hi[e]), axis=1)
    return i[inside], e[inside]


def _inverse_map(corners: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Reference coordinates (k, 3) of points (k, 3) in cells with corners (k, 8, 3), and the residual (k,).

    Newton stops for a pair once its step no longer changes ``xi`` (most cells are near
    parallelepipeds, where the map is almost affine: two or three steps), after
    ``_NEWTON_STEPS`` at the most.
    """
    xi = np.zeros_like(points)
    active = np.arange(len(points))
    corners_t = corners.transpose(0, 2, 1)  # (k, 3, 8): batched products, faster than einsum here
    for _ in range(_NEWTON_STEPS):
        N, dN = trilinear(xi[active])
        r = points[active] - (N[:, None, :] @ corners[active])[:, 0]
        step = np.linalg.solve(corners_t[active] @ dN, r[..., None])[..., 0]
        xi[active] = np.clip(xi[active] + step, -3.0, 3.0)  # far outside a cell the map is meaningless
        active = active[np.abs(step).max(axis=1) > _XI_STEP]
        if len(active) == 0:
            break
    N, _ = trilinear(xi)
    return xi, np.linalg.norm(points - (N[:, None, :] @ corners)[:, 0], axis=1)


def _tet_inverse_map(corners: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Reference coordinates (k, 3) of points (k, 3) in tets with corners (k, 4, 3), and how far
    outside (k,): the most negative barycentric coordinate, negated (<= 0 inside)."""
    edges = (corners[:, 1:] - corners[:, :1]).transpose(0, 2, 1)  # (k, 3, 3) columns x_a - x_0
    xi = np.linalg.solve(edges, (points - corners[:, 0])[..., None])[..., 0]
    bary = np.concatenate([1.0 - xi.sum(axis=1, keepdims=True), xi], axis=1)
    return xi, -bary.min(axis=1)


def locate_points(mesh, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cell containing each point and the point's reference coordinates there.

    Parameters
    ----------
    mesh : a :class:`~contopt.mesh.core.Mesh` (or anything with ``points`` (n, 3), ``cells`` (m, 8 | 4 | 10))
    points : (k, 3)

    Returns
    -------
    cell : (k,) int64, -1 for points outside the mesh (a point on a face shared by two
        cells gets one of them); xi : (k, 3) reference coordinates (0 outside)
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    cell = np.full(len(points), -1, np.int64)
    xi = np.zeros((len(points), 3))
    if len(points) == 0:
        return cell, xi
    cells = np.asarray(mesh.cells)
    tets = cells.shape[1] != 8
    corners = np.asarray(mesh.points)[cells[:, :4] if tets else cells]
    size = float(np.ptp(corners.reshape(-1, 3), axis=0).max())
    # in chunks of points: the candidate pairs' corners take 192 bytes a pair (1.5 GB for the
    # paper-size sabot's design surface, 1.5M lattice points, at once)
    for start in range(0, len(points), _CHUNK):
        part = slice(start, start + _CHUNK)
        i, e = _candidates(corners, points[part], 1e-9 * size)
        if len(i) == 0:
            continue
        if tets:
            ref, outside = _tet_inverse_map(corners[e], points[part][i])
            ok = outside <= XI_TOL
        else:
            ref, res = _inverse_map(corners[e], points[part][i])
            ok = (np.abs(ref).max(axis=1) <= 1.0 + XI_TOL) & (res <= 1e-9 * size)
        i, e, ref = i[ok] + start, e[ok], ref[ok]
        first = np.unique(i, return_index=True)[1]
        cell[i[first]], xi[i[first]] = e[first], ref[first]
    return cell, xi


def boundary_triangles(mesh, facets: np.ndarray | None = None) -> np.ndarray:
    """(2 k, 3, 3) corners of the boundary quads (all, or the given (k, 2) facets) split into triangles;
    (k, 3, 3) the corners of a tet mesh's boundary triangles."""
    facets = mesh.boundary_facets() if facets is None else np.asarray(facets, dtype=np.int64).reshape(-1, 2)
    if np.shape(mesh.cells)[1] != 8:
        return np.asarray(mesh.points)[np.asarray(mesh.cells)[facets[:, 0][:, None], TET_FACES[facets[:, 1], :3]]]
    quads = np.asarray(mesh.points)[np.asarray(mesh.cells)[facets[:, 0][:, None], HEX_FACES[facets[:, 1]]]]
    return np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


def point_triangle_distance(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Distances (k,) from points p (k, 3) to triangles tri (k, 3, 3) (closest point by regions)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac, ap = b - a, c - a, p - a
    dot = lambda u, v: np.einsum("kd,kd->k", u, v)  # noqa: E731
    d1, d2 = dot(ab, ap), dot(ac, ap)
    bp, cp = p - b, p - c
    d3, d4, d5, d6 = dot(ab, bp), dot(ac, bp), dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    # inside the face: barycentric from the three sub-areas
    den = va + vb + vc
    den = np.where(np.abs(den) > 0, den, 1.0)
    q = a + ab * (vb / den)[:, None] + ac * (vc / den)[:, None]
    best = np.linalg.norm(p - q, axis=1)
    inside = (va >= 0) & (vb >= 0) & (vc >= 0)
    edges = np.full(len(p), np.inf)
    for s, t in ((a, b), (a, c), (b, c)):
        st = t - s
        u = np.clip(dot(p - s, st) / np.maximum(dot(st, st), 1e-300), 0.0, 1.0)
        edges = np.minimum(edges, np.linalg.norm(p - (s + st * u[:, None]), axis=1))
    return np.where(inside, best, edges)


def boundary_distance(triangles: np.ndarray, points: np.ndarray, band: float) -> np.ndarray:
    """Distance (k,) from points (k, 3) to a triangulated surface (t, 3, 3).

    Exact where the distance is below ``band``; beyond it a value that is at least ``band``
    (the distance to the nearest triangle corner, ``d``). With R the largest centroid-to-corner
    distance, a point at distance ``delta`` has a corner within ``delta + 2 R`` (so ``d < band + 2 R``
    wherever ``delta < band``) and its nearest triangle's centroid within ``delta + R <= d + R``,
    which bounds the candidates searched.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    corners = triangles.reshape(-1, 3)
    d, _ = cKDTree(corners).query(points)
    centroids = triangles.mean(axis=1)
    R = float(np.max(np.linalg.norm(triangles - centroids[:, None, :], axis=2)))
    near = np.flatnonzero(d < band + 2.0 * R)
    tree = cKDTree(centroids)
    d = d.copy()
    # in chunks: a (point, candidate triangle) pair takes ~400 bytes, and a point of the paper-size
    # sabot's design lattice has ~25 candidates
    for start in range(0, len(near), _CHUNK // 8):
        some = near[start : start + _CHUNK // 8]
        lists = tree.query_ball_point(points[some], d[some] + R * (1.0 + 1e-9))
        counts = np.fromiter((len(c) for c in lists), np.int64, len(lists))
        i = np.repeat(np.arange(len(some)), counts)
        t = np.concatenate([np.asarray(c, dtype=np.int64) for c in lists])
        exact = point_triangle_distance(points[some][i], triangles[t])
        best = np.full(len(some), np.inf)
        np.minimum.at(best, i, exact)
        d[some] = np.minimum(d[some], best)
    return d
