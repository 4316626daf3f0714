"""Which facet pairs of an interface overlap at given positions: search, facing filter, segmentation.

Shared by the contact evaluation (:mod:`contopt.contact.system`) and its outputs; the functions take
an :class:`contopt.contact.system.InterfaceBlock` (the interface's facets and search skin). Pairs go
to the kernels as a :class:`PairBatch`: of the linear kernels (:mod:`contopt.contact.mortar`), or on
an interface with a tet10 side of the quadratic ones (:mod:`contopt.contact.quadratic`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from contopt.contact.facets import TRI6_SPLIT, contact_parents, facet_kind
from contopt.contact.mortar import (
    TRIANGLE_POINTS,
    TRIANGLE_WEIGHTS,
    pair_values,
    pair_values_and_jacobians,
    pair_weighted_hessians,
)
from contopt.contact.quadratic import quadratic_values, quadratic_values_and_jacobians, quadratic_weighted_hessians
from contopt.contact.search import candidate_pairs, facing_filter
from contopt.contact.segment import Reject, segment_pairs
from contopt.fem.hex8 import quad_gauss

if TYPE_CHECKING:
    from contopt.contact.system import InterfaceBlock

#: segmentation reasons that drop a pair of facets that may well touch (reported next to pressure)
_SUSPECT = (Reject.NOT_FACING, Reject.NONCONVEX_NONMORTAR, Reject.NONCONVEX_MORTAR)


def nodal_areas(x: np.ndarray) -> np.ndarray:
    """(F, 4) ``∫ N_A da`` of each node over each deformed bilinear facet x (F, 4, 3) (2x2 Gauss)."""
    N, dN, w = quad_gauss(2)
    tang = np.einsum("fai,qak->fqki", x, dN)  # (F, q, 2, 3)
    da = np.linalg.norm(np.cross(tang[:, :, 0], tang[:, :, 1]), axis=-1)  # (F, q)
    return np.einsum("q,fq,qa->fa", w, da, N)


def search(block: InterfaceBlock, x_nm: np.ndarray, x_m: np.ndarray):
    """Candidate pairs, the pairs kept after the facing filter and their segmentation."""
    candidates = candidate_pairs(x_nm, x_m, block.skin)
    if len(candidates) == 0:
        return candidates, candidates, None
    pairs = facing_filter(x_nm, x_m, candidates, block.interface.max_angle_deg, skin=block.skin)
    if len(pairs) == 0:
        return candidates, pairs, None
    seg = segment_pairs(x_nm[pairs[:, 0]], x_m[pairs[:, 1]], max_angle_deg=block.interface.max_angle_deg)
    return candidates, pairs, seg


@dataclass(frozen=True, eq=False)
class Parents:
    """The parent faces of an interface with a tet10 (tri6) side, for :mod:`contopt.contact.quadratic`.

    kinds : (nonmortar, mortar) facet kinds; nm_nodes (F, 6), m_nodes (G, 6) : global node ids of each
    contact facet's parent (:func:`contopt.contact.facets.contact_parents`); nm_sub (F,), m_sub (G,) :
    its sub-facet; nm_local (F, 6) : the parent's nodes' positions in the interface's nonmortar nodes
    """

    kinds: tuple
    nm_nodes: np.ndarray
    m_nodes: np.ndarray
    nm_sub: np.ndarray
    m_sub: np.ndarray
    nm_local: np.ndarray


@dataclass(frozen=True, eq=False)
class PairBatch:
    """Segmented pairs as the kernels take them: 8 nodes a pair (:mod:`contopt.contact.mortar`), or 12
    with ``kinds`` and ``sub`` (:mod:`contopt.contact.quadratic`).

    X (P, k, 3) nodes; topo (P, 8, 3); loc (P, k/2) positions of the weighted nonmortar nodes in the
    interface's nodes; nodes (P, k) global ids; sub (P, 2) tri6 sub-facets
    """

    X: np.ndarray
    topo: np.ndarray
    loc: np.ndarray
    nodes: np.ndarray
    sub: np.ndarray | None = None
    kinds: tuple | None = None

    @property
    def dofs(self) -> np.ndarray:
        """(P, 3k) global dofs, node-major."""
        return (3 * self.nodes[:, :, None] + np.arange(3)).reshape(len(self.nodes), -1)

    def take(self, keep: np.ndarray) -> PairBatch:
        sub = None if self.sub is None else self.sub[keep]
        return PairBatch(self.X[keep], self.topo[keep], self.loc[keep], self.nodes[keep], sub, self.kinds)

    def values(self):
        """g, a (P, k/2)."""
        if self.kinds is None:
            return pair_values(self.X, self.topo)
        return quadratic_values(self.X, self.topo, self.sub, self.kinds)

    def values_and_jacobians(self):
        """g, a (P, k/2) and J (P, k, 3k)."""
        if self.kinds is None:
            return pair_values_and_jacobians(self.X, self.topo)
        return quadratic_values_and_jacobians(self.X, self.topo, self.sub, self.kinds)

    def weighted_hessians(self, w: np.ndarray) -> np.ndarray:
        """(P, 3k, 3k) Hessians of ``w[:, :k/2] . g + w[:, k/2:] . a``."""
        if self.kinds is None:
            return pair_weighted_hessians(self.X, self.topo, w)
        return quadratic_weighted_hessians(self.X, self.topo, self.sub, w, self.kinds)


def tri6_parents(nm_faces: np.ndarray, m_faces: np.ndarray, nodes: np.ndarray) -> Parents | None:
    """The parents of an interface whose nonmortar or mortar faces (k, 3|4|6) global node ids are tri6,
    else None; ``nodes`` (n,) sorted: the interface's nonmortar nodes."""
    kinds = (facet_kind(nm_faces), facet_kind(m_faces))
    if "tri6" not in kinds:
        return None
    (nm6, nm_sub), (m6, m_sub) = contact_parents(nm_faces), contact_parents(m_faces)
    return Parents(kinds, nm6, m6, nm_sub, m_sub, np.searchsorted(nodes, nm6))


def pair_batch(block: InterfaceBlock, x: np.ndarray, pairs: np.ndarray, topo: np.ndarray) -> PairBatch:
    """The kernels' input of segmented ``pairs`` (P, 2) (nonmortar, mortar facet) at x (N, 3)."""
    par = block.parents
    if par is None:
        nodes = np.concatenate([block.nm_facet_nodes[pairs[:, 0]], block.m_facet_nodes[pairs[:, 1]]], axis=1)
        return PairBatch(x[nodes], topo, block.nm_local[pairs[:, 0]], nodes)
    nodes = np.concatenate([par.nm_nodes[pairs[:, 0]], par.m_nodes[pairs[:, 1]]], axis=1)
    sub = np.stack([par.nm_sub[pairs[:, 0]], par.m_sub[pairs[:, 1]]], axis=1)
    return PairBatch(x[nodes], topo, par.nm_local[pairs[:, 0]], nodes, sub, par.kinds)


def full_areas(block: InterfaceBlock, x_nm: np.ndarray) -> np.ndarray:
    """(n,) each nonmortar node's weight integrated over its whole support of deformed facets x_nm
    (F, 4, 3): ``∫ N_A da`` (bilinear, linear), or on tri6 faces ``∫ W_A da`` over the flat sub-facets."""
    sub_areas = nodal_areas(x_nm)
    par = block.parents
    if par is None or par.kinds[0] != "tri6":
        return np.bincount(block.nm_local.ravel(), weights=sub_areas.ravel(), minlength=block.n_nodes)
    w = sub_areas.sum(axis=1)[:, None] * _TRI6_SUB_MEANS[par.nm_sub]  # (F, 6)
    return np.bincount(par.nm_local.ravel(), weights=w.ravel(), minlength=block.n_nodes)


def _tri6_sub_means() -> np.ndarray:
    """(4, 6) the mean of each tri6 weight over each sub-facet (Radon's rule, exact: degree 2)."""
    from contopt.contact.quadratic import TRI6_NODES_XI, tri6_shape, tri6_weights

    out = np.zeros((4, 6))
    for k, tri in enumerate(TRI6_SPLIT):
        xi = TRIANGLE_POINTS @ TRI6_NODES_XI[tri]
        out[k] = TRIANGLE_WEIGHTS @ np.asarray(tri6_weights(tri6_shape(xi)))
    return out


_TRI6_SUB_MEANS = _tri6_sub_means()


def paired(block: InterfaceBlock, x: np.ndarray) -> PairBatch | None:
    """The segmented pairs of one interface at x, or None when no pair overlaps."""
    x_nm, x_m = x[block.nm_facet_nodes], x[block.m_facet_nodes]
    _, pairs, seg = search(block, x_nm, x_m)
    if seg is None or not seg.active.any():
        return None
    keep = np.asarray(seg.active)
    return pair_batch(block, x, pairs[keep], np.asarray(seg.topo)[keep])


def rejected_near_active(block: InterfaceBlock, x_nm, x_m, candidates, pairs, seg, lam: np.ndarray) -> int:
    """Candidate pairs dropped as not facing (by the facing filter or the segmentation) or folded
    although a node of the mortar facet lies behind the nonmortar facet, within its footprint,
    next to pressure (a node of the nonmortar facet has some): contact the pairing cannot see."""
    if len(candidates) == 0:
        return 0
    G = len(block.m_facet_nodes)
    dropped = candidates[~np.isin(candidates[:, 0] * G + candidates[:, 1], pairs[:, 0] * G + pairs[:, 1])]
    if seg is not None:
        suspect = np.isin(np.asarray(seg.reason), [int(r) for r in _SUSPECT])
        dropped = np.concatenate([dropped, pairs[suspect]])
    pressed = (lam[block.nm_local] > 0).any(axis=1)  # (F,)
    dropped = dropped[pressed[dropped[:, 0]]]
    if len(dropped) == 0:
        return 0
    a, b = x_nm[dropped[:, 0]], x_m[dropped[:, 1]]  # (k, 4, 3)
    c = a.mean(axis=1)
    n = np.cross(a[:, 2] - a[:, 0], a[:, 3] - a[:, 1])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    r = np.linalg.norm(a - c[:, None], axis=2).max(axis=1)
    rel = b - c[:, None]
    depth = np.einsum("kai,ki->ka", rel, n)  # (k, 4) < 0: behind the nonmortar facet
    lateral = np.linalg.norm(rel - depth[..., None] * n[:, None], axis=2)
    inside = (depth < -1e-3 * block.h) & (depth > -block.h) & (lateral <= r[:, None])
    return int(inside.any(axis=1).sum())
