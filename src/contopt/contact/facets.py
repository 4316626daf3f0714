"""A contact surface's facets as the mortar code holds them: (F, 4) node ids, quads and triangles alike.

A hex8 facet is its quad. A tet4 facet (tri3) is stored as a quad whose node 3 repeats its node 0:
``[a, b, c, a]``. Most quad formulas then hold for it unchanged (the diagonals' cross product
``(x2 - x0) x (x3 - x1)`` is the triangle's ``(x1 - x0) x (x2 - x0)``; edge k runs from node k to
node k + 1 mod 4 for k = 0, 1, 2), and a triangle is known by its repeated node
(:func:`contopt.contact.segment.triangles`); segmentation and the mortar kernels treat its edge 3
as no edge and its fourth slot as weightless (docs/contact.md, "Triangle facets").

A tet10 facet (tri6: corners 0-2, then the midpoints of edges 01, 12, 20) is split into four tri3
sub-facets on its six nodes (:data:`TRI6_SPLIT`), each a flat triangle (Puso, Laursen and Solberg
2008 for quadratic elements). The sub-facets are searched and segmented; the integrals are the
parent's (:func:`contact_parents`, :mod:`contopt.contact.quadratic`), the gaps' and the friction
slips' alike.
"""

from __future__ import annotations

import numpy as np

#: the four tri3 sub-facets of a tri6 facet (local nodes, outward ordering as the parent's)
TRI6_SPLIT = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]], dtype=np.int64)
TRI6_SPLIT.setflags(write=False)


def padded_triangles(tri: np.ndarray) -> np.ndarray:
    """(k, 4) ``[a, b, c, a]`` of triangles (k, 3)."""
    tri = np.asarray(tri)
    return np.concatenate([tri, tri[:, :1]], axis=1)


def as_contact_facets(nodes: np.ndarray) -> np.ndarray:
    """(F, 4) contact facets of facet node ids (k, 4) quads, (k, 3) tri3 or (k, 6) tri6 (F = 4k)."""
    nodes = np.asarray(nodes)
    width = nodes.shape[1] if nodes.ndim == 2 else -1
    if width == 4:
        return nodes
    if width == 3:
        return padded_triangles(nodes)
    if width == 6:
        return padded_triangles(nodes[:, TRI6_SPLIT].reshape(-1, 3))
    raise ValueError(f"facet nodes must have shape (k, 4), (k, 3) or (k, 6), got {nodes.shape}")


def contact_facets(mesh, name_or_facets) -> np.ndarray:
    """(F, 4) contact facets of a mesh's facet set (name or (k, 2) ``(cell, local face)``)."""
    return as_contact_facets(mesh.facet_nodes(name_or_facets))


#: the facet kind of each width of facet nodes (:data:`contopt.contact.quadratic.KINDS`)
_KIND = {4: "quad", 3: "tri3", 6: "tri6"}


def facet_kind(nodes: np.ndarray) -> str:
    """``"quad"``, ``"tri3"`` or ``"tri6"`` of facet node ids (k, 4), (k, 3) or (k, 6)."""
    width = np.shape(nodes)[1] if np.ndim(nodes) == 2 else -1
    if width not in _KIND:
        raise ValueError(f"facet nodes must have shape (k, 4), (k, 3) or (k, 6), got {np.shape(nodes)}")
    return _KIND[width]


def contact_parents(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each contact facet's parent, as :mod:`contopt.contact.quadratic` takes it: (F, 6) node ids and
    (F,) sub-facet, row for row with :func:`as_contact_facets`. A tri6 parent is its six nodes and
    its sub-facet 0-3 (:data:`TRI6_SPLIT`); a quad is its four nodes, a tri3 its three, the rest of
    the six slots filled with node 0 (ignored) and sub-facet 0."""
    nodes = np.asarray(nodes)
    kind = facet_kind(nodes)
    if kind == "tri6":
        return np.repeat(nodes, 4, axis=0), np.tile(np.arange(4), len(nodes))
    fill = np.repeat(nodes[:, :1], 6 - nodes.shape[1], axis=1)
    return np.concatenate([nodes, fill], axis=1), np.zeros(len(nodes), dtype=np.int64)
