"""Which facet pairs of an interface overlap at given positions: search, facing filter, segmentation.

Shared by the contact evaluation (:mod:`contopt.contact.system`) and its outputs; the functions take
an :class:`contopt.contact.system.InterfaceBlock` (the interface's facets and search skin).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

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


def paired(block: InterfaceBlock, x: np.ndarray):
    """The segmented pairs of one interface at x: (X8 (P, 8, 3), topo, nonmortar local ids (P, 4),
    global nodes (P, 8)), or None when no pair overlaps."""
    x_nm, x_m = x[block.nm_facet_nodes], x[block.m_facet_nodes]
    _, pairs, seg = search(block, x_nm, x_m)
    if seg is None or not seg.active.any():
        return None
    keep = np.asarray(seg.active)
    pairs, topo = pairs[keep], np.asarray(seg.topo)[keep]
    X8 = np.concatenate([x_nm[pairs[:, 0]], x_m[pairs[:, 1]]], axis=1)
    nodes8 = np.concatenate([block.nm_facet_nodes[pairs[:, 0]], block.m_facet_nodes[pairs[:, 1]]], axis=1)
    return X8, topo, block.nm_local[pairs[:, 0]], nodes8


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
