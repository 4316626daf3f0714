"""Tetrahedral meshes from hex8 ones, and tet10 from tet4: for tests, comparisons and conversions.

:func:`tetrahedralize` cuts every hex8 into six tetrahedra along its 0-6 diagonal (Kuhn's
split). On a structured grid (:mod:`contopt.mesh.generators`), where every cell is a translate
of the others, the cut of a shared face is the same diagonal from both sides, so the tet mesh
is conforming; the named sets are carried over (a hex face becomes two triangles).
:func:`to_tet10` adds the edge midpoints (straight-sided tet10).
"""

from __future__ import annotations

import itertools

import numpy as np

from contopt.errors import MeshError
from contopt.mesh.core import HEX_FACES, TET_FACES, Mesh, boundary_facets

#: VTK hex node of each corner bit pattern (x, y, z) of the unit cube
_HEX_NODE = {
    (0, 0, 0): 0,
    (1, 0, 0): 1,
    (1, 1, 0): 2,
    (0, 1, 0): 3,
    (0, 0, 1): 4,
    (1, 0, 1): 5,
    (1, 1, 1): 6,
    (0, 1, 1): 7,
}
#: the tet4 corners (VTK orientation) of each edge node 4-9
_TET10_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]], dtype=np.int64)


def _kuhn_tets() -> np.ndarray:
    """(6, 4) hex-local nodes of the six tets along the 0-6 diagonal, positively oriented."""
    out = []
    for perm in itertools.permutations(range(3)):
        corner, path = [0, 0, 0], [0]
        for axis in perm:
            corner[axis] = 1
            path.append(_HEX_NODE[(corner[0], corner[1], corner[2])])
        e = np.eye(3)
        x = [np.zeros(3), e[perm[0]], e[perm[0]] + e[perm[1]], np.ones(3)]
        if np.linalg.det(np.array([x[1] - x[0], x[2] - x[0], x[3] - x[0]])) < 0:
            path[1], path[2] = path[2], path[1]
        out.append(path)
    return np.array(out, dtype=np.int64)


_KUHN = _kuhn_tets()


def to_tet10(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Straight-sided tet10 from tet4: (points (n + n_edges, 3), cells (m, 10)); the first n points kept."""
    points, tets = np.asarray(points, np.float64), np.asarray(tets, np.int64)
    edges = np.sort(tets[:, _TET10_EDGES], axis=-1).reshape(-1, 2)  # (m*6, 2)
    unique, inverse = np.unique(edges, axis=0, return_inverse=True)
    mid = points[unique].mean(axis=1)
    cells = np.hstack([tets, len(points) + inverse.reshape(len(tets), 6)])
    return np.vstack([points, mid]), cells


def tetrahedralize(mesh: Mesh, order: int = 1) -> Mesh:
    """The hex8 ``mesh`` cut into 6 tets a cell (``order`` 1: tet4, 2: tet10), its named sets kept.

    Cell ``6 e + k`` of the result lies in hex ``e``. Conforming on structured grids (every cell
    a translate of one box, or numbered as one); MeshError for a mesh that is not hex8, or whose
    cut would not conform (two cells cutting a face they share along different diagonals).
    """
    if mesh.element != "hex8":
        raise MeshError(f"tetrahedralize takes a hex8 mesh, got {mesh.element}")
    if order not in (1, 2):
        raise MeshError(f"tetrahedralize: order must be 1 (tet4) or 2 (tet10), got {order!r}")
    tets = mesh.cells[:, _KUHN].reshape(-1, 4)
    bnd = boundary_facets(tets)  # (k, 2) tet faces on the boundary
    split = (len(bnd) - 2 * len(mesh.boundary_facets())) // 4  # an interior face cut two ways: 4 loose triangles
    if split:
        raise MeshError(
            f"tetrahedralize: {split} interior faces would be cut along different diagonals by their two cells "
            "(a non-conforming tet mesh); the hex cells must be numbered as one structured grid (box, "
            "cylinder_shell_sector, annulus; not cylinder's o-grid)"
        )
    tri = tets[bnd[:, 0][:, None], TET_FACES[bnd[:, 1], :3]]  # (k, 3)
    hexes = bnd[:, 0] // 6
    quads = mesh.cells[hexes][:, HEX_FACES]  # (k, 6, 4): every face of the parent hex
    inside = (tri[:, None, :, None] == quads[:, :, None, :]).any(-1).all(-1)  # (k, 6)
    local = inside.argmax(axis=1)
    code = hexes * 6 + local
    facet_sets = {}
    for name, facets in mesh.facet_sets.items():
        facet_sets[name] = bnd[np.isin(code, facets[:, 0] * 6 + facets[:, 1])]
    points, cells, node_sets = mesh.points, tets, dict(mesh.node_sets)
    if order == 2:
        points, cells = to_tet10(points, tets)
        # an edge node belongs to a node set when both its corners do (the edge lies on the set)
        edge_nodes = cells[:, 4:].ravel()
        ends = tets[:, _TET10_EDGES].reshape(-1, 2)
        for name, nodes in mesh.node_sets.items():
            inset = np.isin(ends, nodes).all(axis=1)
            node_sets[name] = np.union1d(nodes, edge_nodes[inset])
    return Mesh(points, cells, node_sets, facet_sets)
