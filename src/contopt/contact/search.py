"""Broad phase of the contact search: candidate (nonmortar, mortar) facet pairs.

The two contact surfaces are given as facet node coordinates in the current
configuration, ``x_nm`` (F, 4, 3) and ``x_m`` (G, 4, 3): bilinear quadrilateral
faces of hex8 elements, nodes ordered so that the right-hand rule gives the
outward normal of the facet's own body (:data:`contopt.mesh.core.HEX_FACES`).
The search is redone every Newton iteration, with no memory of the previous
pairing, so it must be cheap and must tolerate arbitrary sliding.

A pair (i, j) is a candidate when the axis-aligned bounding boxes (AABBs) of
nonmortar facet i and mortar facet j, each enlarged by ``skin`` on every side,
overlap (touching counts). :func:`candidate_pairs` returns exactly the pairs of
the O(F G) oracle :func:`candidate_pairs_bruteforce`.

Algorithm
---------
Facets of each side are split into size classes (sorted by the largest half
extent of the enlarged box; a class spans at most a factor 2, with all
facets below ``2**-10`` of the largest lumped into the first class). Two boxes
overlap iff ``|c_nm - c_m| <= h_nm + h_m`` on every axis (c: centre, h: half
extents), so for a (nonmortar class, mortar class) pair whose class boxes
overlap, every overlapping pair has its centres within the Euclidean distance
``|H_nm + H_m|`` (H: the classes' largest half extents per axis). A
:class:`scipy.spatial.cKDTree` dual-tree query
(``sparse_distance_matrix``) on the box centres with that radius gives a
superset of the overlapping pairs, and an exact vectorised AABB test keeps the
overlapping ones. The radius is padded by a few hundred ulps of the
coordinate magnitude so that round-off in the centres cannot lose a touching
pair. Measured alternatives, all slower: the tighter Chebyshev query
(``p=inf``, ~2x slower traversal in cKDTree), ``query_ball_point`` with a
radius per facet (list output), ``query_ball_tree``, and a uniform hash grid
in numpy (which also degrades with one huge facet).

Complexity: O((F + G) log(F + G)) for the trees plus O(C) for the candidates,
with C at most the number of pairs whose centres lie within the class-pair
radius. The size classes keep a few large facets (e.g. a die meshed 10x
coarser, or a single huge facet) from inflating the radius of everyone else's
query: a huge facet only pays for the facets near its own box (with a single
class, 4096 x 4096 facets plus one facet spanning the surface take 1.4 s
instead of 6 ms), and there are at most ``(log2(max/min size) + 1)**2``
class pairs, with at most 11 classes per side. For facets of similar size on
a surface, C is about 1.5x the number of true pairs; facets with an elongated
AABB (aspect ratio a) may give up to ~a times more candidates than true
pairs, since the query region is a ball. Strongly mixed sizes cost most
through the number of class pairs (see the random-cloud timing in docs/performance.md).

Timings against the brute-force oracle and a single size class, and the command that measures
them: docs/performance.md ("Contact search").
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = [
    "candidate_pairs",
    "candidate_pairs_bruteforce",
    "default_skin",
    "facing_filter",
]

#: Sizes within one class differ by at most this factor, so a class pair's
#: query radius is at most about twice the one each member needs.
_CLASS_RATIO = 2.0
#: Facets smaller than this fraction of the largest go into the first class;
#: caps the number of classes (and class pairs) for near-degenerate facets.
_CLASS_FLOOR = 2.0**-10

_EMPTY_PAIRS = np.zeros((0, 2), dtype=np.int64)


# --------------------------------------------------------------------- helpers
def _facets(x, name: str) -> np.ndarray:
    """(k, 4, 3) float64 view/copy of facet coordinates, checked."""
    x = np.asarray(x, dtype=np.float64)
    if x.size == 0:
        return np.zeros((0, 4, 3))
    if x.ndim != 3 or x.shape[1:] != (4, 3):
        raise ValueError(f"{name} must have shape (k, 4, 3) (facets, nodes, xyz), got {x.shape}")
    if not np.all(np.isfinite(x)):
        bad = int(np.nonzero(~np.isfinite(x).all(axis=(1, 2)))[0][0])
        raise ValueError(f"{name}: facet {bad} has non-finite coordinates")
    return x


def _skin(skin) -> float:
    s = float(skin)
    if not (np.isfinite(s) and s >= 0):
        raise ValueError(f"skin must be a finite number >= 0, got {skin!r}")
    return s


def _boxes(x: np.ndarray, skin: float) -> tuple[np.ndarray, np.ndarray]:
    """Enlarged AABBs of facets x (k, 4, 3): ``lo, hi`` (k, 3).

    Shared by the fast search and the oracle so that both test overlap on
    the very same floats (touching boxes at skin 0 are decided identically).
    """
    # pairwise minimum of the 4 nodes is ~3x faster than x.min(axis=1)
    lo = np.minimum(np.minimum(x[:, 0], x[:, 1]), np.minimum(x[:, 2], x[:, 3]))
    hi = np.maximum(np.maximum(x[:, 0], x[:, 1]), np.maximum(x[:, 2], x[:, 3]))
    lo -= skin
    hi += skin
    return lo, hi


def _overlap(lo1, hi1, lo2, hi2, i, j) -> np.ndarray:
    """(K,) bool: box i of side 1 overlaps box j of side 2 (closed boxes)."""
    # per-axis 1-D gathers from contiguous columns: ~5x faster than one (K, 3) gather + all(axis=1)
    lo1, hi1, lo2, hi2 = (np.ascontiguousarray(a.T) for a in (lo1, hi1, lo2, hi2))
    ok = lo1[0][i] <= hi2[0][j]
    for a in range(3):
        if a:
            ok &= lo1[a][i] <= hi2[a][j]
        ok &= lo2[a][j] <= hi1[a][i]
    return ok


def _size_classes(size: np.ndarray) -> list[np.ndarray]:
    """Partition of ``range(len(size))`` into classes of similar size.

    size : (k,) >= 0. Returns index arrays; within a class the largest size
    is at most ``_CLASS_RATIO`` times the smallest (or than the floor).
    """
    order = np.argsort(size, kind="stable")
    s = size[order]
    floor = _CLASS_FLOOR * s[-1]
    classes = []
    start = 0
    while start < len(s):
        # lim >= s[start], so the class is never empty and the loop ends
        lim = _CLASS_RATIO * max(s[start], floor)
        end = int(np.searchsorted(s, lim, side="right"))
        classes.append(order[start:end])
        start = end
    return classes


def _sorted_pairs(i: np.ndarray, j: np.ndarray, n_m: int) -> np.ndarray:
    code = np.sort(i.astype(np.int64) * n_m + j)
    return np.stack(np.divmod(code, n_m), axis=1)


def _centres_radii(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Node means c (k, 3) and radii r (k,): the largest node distance from c.

    A point of a bilinear facet is a convex combination of its nodes, so it
    lies within r of c (the diagonals do not bound this: a trapezoid's long
    edge can exceed both).
    """
    c = x.mean(axis=1)
    return c, np.linalg.norm(x - c[:, None], axis=2).max(axis=1)


def _area_vectors(x: np.ndarray) -> np.ndarray:
    """(k, 3) cross product of the diagonals: twice the exact vector area of a bilinear quad."""
    return np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])


# ------------------------------------------------------------------------- API
def candidate_pairs(x_nm, x_m, skin: float) -> np.ndarray:
    """All facet pairs whose skin-enlarged bounding boxes overlap.

    Parameters
    ----------
    x_nm : (F, 4, 3) nonmortar facet node coordinates (current configuration)
    x_m : (G, 4, 3) mortar facet node coordinates
    skin : >= 0, added to every side of every box (so surfaces up to
        ``2 * skin`` apart are paired)

    Returns
    -------
    (P, 2) int64 rows ``(nonmortar facet, mortar facet)``, unique and sorted
    lexicographically; identical to :func:`candidate_pairs_bruteforce`.
    F or G may be 0 (then P = 0). Degenerate facets (repeated or collinear
    nodes) are handled like any other box. See the module docstring for the
    algorithm, its complexity and measured timings.
    """
    boxes = _checked_boxes(x_nm, x_m, skin)
    if boxes is None:
        return _EMPTY_PAIRS.copy()
    lo1, hi1, lo2, hi2 = boxes
    G = len(lo2)
    c1, h1 = 0.5 * (lo1 + hi1), 0.5 * (hi1 - lo1)
    c2, h2 = 0.5 * (lo2 + hi2), 0.5 * (hi2 - lo2)
    # round-off of c and h is a few ulps of the coordinates, not of the (much
    # smaller) facet size: pad the radius in absolute terms
    scale = max(np.abs(lo1).max(), np.abs(hi1).max(), np.abs(lo2).max(), np.abs(hi2).max())
    pad = 256.0 * np.finfo(np.float64).eps * scale

    sides = []
    for lo, hi, c, h in ((lo1, hi1, c1, h1), (lo2, hi2, c2, h2)):
        classes = []
        for idx in _size_classes(h.max(axis=1)):
            classes.append(
                (
                    idx,
                    lo[idx].min(axis=0),
                    hi[idx].max(axis=0),
                    h[idx].max(axis=0),
                    # sliding-midpoint build: ~3x cheaper than the balanced
                    # (median) one and no slower to query on surface-like data
                    cKDTree(c[idx], balanced_tree=False, compact_nodes=False),
                )
            )
        sides.append(classes)

    ii, jj = [], []
    for idx1, glo1, ghi1, gh1, t1 in sides[0]:
        for idx2, glo2, ghi2, gh2, t2 in sides[1]:
            if np.any(glo1 > ghi2) or np.any(glo2 > ghi1):
                continue  # no member of one class can reach the other
            # overlap needs |c_nm - c_m| <= gh1 + gh2 on each axis, hence within
            # this Euclidean radius; p=2 is ~2x faster in cKDTree than the
            # tighter Chebyshev cube (p=inf), more than paying for the ~1.5x
            # extra candidates that the exact test then removes
            radius = float(np.linalg.norm(gh1 + gh2)) * (1.0 + 1e-12) + pad
            d = t1.sparse_distance_matrix(t2, radius, p=2.0, output_type="ndarray")
            if len(d):
                ii.append(idx1[d["i"]])
                jj.append(idx2[d["j"]])
    if not ii:
        return _EMPTY_PAIRS.copy()
    i, j = np.concatenate(ii), np.concatenate(jj)
    ok = _overlap(lo1, hi1, lo2, hi2, i, j)
    return _sorted_pairs(i[ok], j[ok], G)


def _checked_boxes(x_nm, x_m, skin):
    """Validated inputs as skin-padded boxes ``(lo1, hi1, lo2, hi2)``, or None when a side has no facets."""
    x_nm, x_m = _facets(x_nm, "x_nm"), _facets(x_m, "x_m")
    skin = _skin(skin)
    if len(x_nm) == 0 or len(x_m) == 0:
        return None
    return (*_boxes(x_nm, skin), *_boxes(x_m, skin))


def candidate_pairs_bruteforce(x_nm, x_m, skin: float) -> np.ndarray:
    """O(F G) reference for :func:`candidate_pairs` (same arguments and result).

    Tests every pair, in row blocks so that memory stays bounded.
    """
    boxes = _checked_boxes(x_nm, x_m, skin)
    if boxes is None:
        return _EMPTY_PAIRS.copy()
    lo1, hi1, lo2, hi2 = boxes
    G = len(lo2)
    block = max(1, 2**22 // G)
    out = []
    for s in range(0, len(lo1), block):
        ok = np.all((lo1[s : s + block, None] <= hi2[None]) & (lo2[None] <= hi1[s : s + block, None]), axis=2)
        i, j = np.nonzero(ok)
        out.append(np.stack([i + s, j], axis=1).astype(np.int64))
    return np.concatenate(out)  # np.nonzero is row-major: already sorted and unique


def default_skin(x_nm, x_m) -> float:
    """A default search skin: 0.2 x the mean edge length of the finer surface.

    Parameters
    ----------
    x_nm : (F, 4, 3), x_m : (G, 4, 3) facet node coordinates

    Returns
    -------
    float >= 0 (0.0 when both sides are empty).

    Why this value: with the search refreshed every Newton iteration the skin
    only has to cover what changes before the next refresh, i.e. gaps that
    may close and penetrations within one iteration, which are small against
    the element size. Pairs up to ``2 * skin = 0.4 h`` apart are found, while
    for conforming meshes of edge h the in-plane candidate stencil stays 3 x 3
    facets (neighbour centres are h apart, boxes reach ``h + 2 skin = 1.4 h < 2 h``),
    so the skin costs almost nothing in the narrow phase. The finer side's
    length is used because it sets the resolution of the contact zone; the
    coarser side's would multiply the candidates of every fine facet.
    """
    x_nm, x_m = _facets(x_nm, "x_nm"), _facets(x_m, "x_m")
    means = [float(np.linalg.norm(np.roll(x, -1, axis=1) - x, axis=2).mean()) for x in (x_nm, x_m) if len(x)]
    return 0.2 * min(means) if means else 0.0


def facing_filter(x_nm, x_m, pairs, max_angle_deg: float = 75.0, skin: float | None = None) -> np.ndarray:
    """Drop candidate pairs whose facets cannot be in contact.

    Parameters
    ----------
    x_nm : (F, 4, 3), x_m : (G, 4, 3) facet node coordinates
    pairs : (P, 2) int rows ``(nonmortar facet, mortar facet)``, e.g. from
        :func:`candidate_pairs`
    max_angle_deg : in (0, 180]; the largest angle between the nonmortar
        normal and the *reversed* mortar normal. Each facet's normal
        (right-hand rule over its 4 nodes, i.e. the cross product of the
        diagonals) points out of its own body, so facets that face each other
        have opposite normals (angle 0). 90 drops only pairs whose normals
        point into the same half-space.
    skin : the search skin (default :func:`default_skin`)

    Returns
    -------
    (P', 2) int64, the kept rows in their original order.

    A pair is dropped when (a) the normals are further than ``max_angle_deg``
    from facing, or (b) the mortar facet's centre lies behind the nonmortar
    facet (inside the nonmortar body) by more than ``skin + r_nm + r_m``,
    measured along the nonmortar normal n from the nonmortar centre; c is a
    facet's node mean and r its largest node distance from c (a facet size:
    ``r_nm + r_m`` is the diagonal for two equal squares). (b) never drops a
    pair in which a point q of the mortar facet lies within ``skin`` of a
    point p of the nonmortar facet, warped or not:
    ``(c_m - c_nm).n = (q - p).n + (p - c_nm).n - (q - c_m).n >= -skin - r_nm - r_m``.
    It removes e.g. the far face of a thin part whose boxes overlap; a
    penetration deeper than a facet size, which only a diverged iterate
    produces, is then no longer paired.
    A pair with a degenerate facet (zero area: no normal) is kept by both
    (a) and, when the nonmortar facet is degenerate, (b).
    """
    x_nm, x_m = _facets(x_nm, "x_nm"), _facets(x_m, "x_m")
    max_angle_deg = float(max_angle_deg)
    if not (0.0 < max_angle_deg <= 180.0):
        raise ValueError(f"max_angle_deg must lie in (0, 180], got {max_angle_deg!r}")
    skin = default_skin(x_nm, x_m) if skin is None else _skin(skin)
    pairs = np.asarray(pairs, dtype=np.int64)
    if pairs.size == 0:
        return _EMPTY_PAIRS.copy()
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise ValueError(f"pairs must have shape (P, 2), got {pairs.shape}")
    if (
        pairs[:, 0].min() < 0
        or pairs[:, 0].max() >= len(x_nm)
        or pairs[:, 1].min() < 0
        or pairs[:, 1].max() >= len(x_m)
    ):
        raise ValueError(f"pairs index outside the facets (F={len(x_nm)}, G={len(x_m)})")
    i, j = pairs[:, 0], pairs[:, 1]
    c_nm, r_nm = _centres_radii(x_nm)
    c_m, r_m = _centres_radii(x_m)

    def unit_normals(x, r):
        n = _area_vectors(x)
        norm = np.linalg.norm(n, axis=1)
        # |n| is twice the area; relative to r^2 it tells slivers (no reliable
        # direction) from genuine facets
        valid = norm > 1e-12 * r * r
        return n / np.where(valid, norm, 1.0)[:, None], valid

    n_nm, v_nm = unit_normals(x_nm, r_nm)
    n_m, v_m = unit_normals(x_m, r_m)
    n_i = n_nm[i]
    # 1e-12: at max_angle_deg = 90 exactly perpendicular facets count as facing
    facing = -np.einsum("ij,ij->i", n_i, n_m[j]) >= np.cos(np.radians(max_angle_deg)) - 1e-12
    facing |= ~(v_nm[i] & v_m[j])
    depth = np.einsum("ij,ij->i", c_m[j] - c_nm[i], n_i)  # < 0: behind the nonmortar facet
    not_behind = ~v_nm[i] | (depth >= -(skin + r_nm[i] + r_m[j]))
    return pairs[facing & not_behind]
