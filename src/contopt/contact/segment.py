"""Mortar segmentation of (nonmortar facet, mortar facet) pairs: clipping *topology* in numpy.

Puso & Laursen (2004) integrate the mortar gaps over the overlap of the two
facets projected onto an auxiliary plane. This module decides, from the current
coordinates, *which* lines bound that overlap polygon; :mod:`contopt.contact.mortar`
then recomputes the polygon from this topology in JAX so that gaps are
differentiated exactly while the combinatorics stay fixed (docs/formulation.md §4).

Auxiliary plane of a pair: through the nonmortar facet centre ``x0`` (mean of
its 4 nodes), unit normal ``n0 = normalize((x2 - x0) x (x3 - x1))`` (the
bilinear surface normal at the centre, outward of the nonmortar body since
facets are ordered by :data:`contopt.mesh.core.HEX_FACES`). In-plane basis
``t1 = normalize(in-plane part of (x1 + x2 - x0 - x3))``, ``t2 = n0 x t1``: the
nonmortar quad is counter-clockwise in ``(t1, t2)``, a mortar quad facing it
is clockwise.

Topology of a polygon vertex, one row ``(kind, i, j)`` of ``topo``:

======  ===================================================================
kind    meaning
======  ===================================================================
 0      nonmortar node ``i`` (``j = -1``)
 1      mortar node ``j`` (``i = -1``)
 2      nonmortar edge ``i`` (nodes i, i+1 mod 4) x mortar edge ``j`` (nodes j, j+1 mod 4)
-1      padding (``i = j = -1``)
======  ===================================================================

Vertices are listed counter-clockwise in ``(t1, t2)`` (positive area).

How: Sutherland-Hodgman clips the projected mortar quad (traversed in
reverse so it is counter-clockwise) against the four edge lines of the
projected nonmortar quad. Every vertex carries the label of the line its
*outgoing* edge lies on (nonmortar edge ``i`` or mortar edge ``j``), so a
vertex is the intersection of its incoming and outgoing lines; two nonmortar
lines meet at a nonmortar node, two mortar lines at a mortar node. Afterwards
(near-)coincident consecutive vertices are merged (the merged vertex is the
intersection of the outer two lines) and vertices whose two lines are
(near-)parallel are dropped (they are collinear with their neighbours), so
no 2x2 intersection system that JAX later solves is singular. Finally every
vertex is recomputed from its topology and checked against the clipped one.

Both projected quads must be strictly convex (Sutherland-Hodgman needs a
convex clip region, the fan triangulation a convex polygon, the inverse
bilinear map a unique inverse); a pair with a non-convex projection is
rejected with reason ``NONCONVEX_*`` rather than integrated wrongly.
The gap sign is physics and never a reason to reject: penetrated and open
pairs are both segmented.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

logger = logging.getLogger(__name__)

#: Most vertices of a clipped polygon (a convex quad clipped by 4 half-planes).
MAX_VERTICES = 8
#: A mortar edge whose two ends lie within this distance (times the facet size) of a nonmortar edge
#: line counts as on it (outside the facet; :func:`_on_line_band`, :func:`_inside`). Ten times the
#: vertex-merging distance on purpose: a mortar edge a distance d inside a nearly parallel nonmortar
#: edge cuts off slivers whose shared vertex, where the two lines cross, moves as 1/angle with the
#: nodes, and the derivatives through it do not cancel between the pairs
#: (``tests/contact/test_segment.py``: a weighted gap's slope of 0.97 instead of 0.0051 for d from
#: 3e-10 to 1e-8). Measured on the contact matrix's seam (a roller edge over the blocks' shared edge
#: line, both at y = 0.2, the roller nonmortar): slivers 1e-10 h wide left a residual of 7e-11 at the
#: symmetric state, Newton's step moved the blocks' edge 2e-7 h off the roller's, the new slivers'
#: residual (7e-7, half that at twice the distance) drove it off by two every iteration, and the cell
#: failed after 176 Newton iterations; with this band it converges in 45. A band of 1e-7 converged it
#: too (40) but made the seam with the blocks' tops nonmortar stall at t = 0.61 (residual jumps of 1e-4
#: as the roller's vertices crossed the band's edge). 1e-8 (issue 35): with 1e-9 the seam's ALM cells
#: with the roller nonmortar at nu 0.49 crept after their multiplier updates (the y of the blocks' corner
#: on that line doubling every Newton iteration, the residual halving) and stalled at |r| ~ 1e-9 (E ratio
#: 1e4, 1e5: the stall error after 102 and 72 iterations; 1e2: Newton failed); with 1e-8 they converge
#: quadratically in 30 to 34. A strip narrower than the band is counted outside by both pairs: the area
#: lost is at most band x edge length.
ON_LINE_BAND = 1e-8
#: A mortar edge from a vertex within the band to one beyond it but within this many bands lies along the
#: line (:func:`_inside`): both ends count by their side. Steeper edges and edges that cross the line keep
#: the vertex within the band outside, so that no sliver is cut off where an edge crosses at an angle.
ALONG = 1e4
# working buffer of the clipper: round-off near-degenerate inputs may emit a few
# more vertices before merging brings them back to <= 8
_BUFFER = 16


class Reject(IntEnum):
    """Why a pair is inactive (``Segmentation.reason``); ``ACTIVE`` for kept pairs."""

    ACTIVE = 0
    DEGENERATE_NONMORTAR = 1  #: zero-area nonmortar facet
    DEGENERATE_MORTAR = 2  #: zero-area mortar facet
    NOT_FACING = 3  #: mortar centre normal not within max_angle of -n0
    NONCONVEX_NONMORTAR = 4  #: projected nonmortar quad not strictly convex
    NONCONVEX_MORTAR = 5  #: projected mortar quad not strictly convex (or folded)
    EMPTY = 6  #: projections do not overlap (fewer than 3 vertices)
    SLIVER = 7  #: area <= area_tol * facet area, or a thin ill-conditioned polygon between nearly coincident edges
    TOPOLOGY = 8  #: clipping produced an inconsistent polygon (should not happen)


@dataclass(frozen=True, eq=False)
class Segmentation:
    """Overlap polygons of P candidate pairs, as topology (see module docstring).

    Attributes (read-only arrays)
    ----------------------------
    topo : (P, 8, 3) int64 rows ``(kind, i, j)``, padding ``(-1, -1, -1)``;
        all padding for inactive pairs (so they integrate to exactly zero)
    n_vertices : (P,) int64 vertices of the polygon (0 for inactive pairs)
    active : (P,) bool polygon with >= 3 vertices and area > area_tol * facet area
    reason : (P,) int8 :class:`Reject` code (``Reject.ACTIVE`` = 0 for active pairs)
    area : (P,) float64 overlap area on the auxiliary plane (0 for inactive pairs)
    facet_area : (P,) float64 area of the projected nonmortar quad
    """

    topo: np.ndarray
    n_vertices: np.ndarray
    active: np.ndarray
    reason: np.ndarray
    area: np.ndarray
    facet_area: np.ndarray

    @property
    def n_pairs(self) -> int:
        return int(self.active.shape[0])

    @property
    def n_active(self) -> int:
        return int(self.active.sum())

    def counts(self) -> dict[str, int]:
        """Number of pairs per :class:`Reject` reason (only reasons that occur)."""
        codes, n = np.unique(self.reason, return_counts=True)
        return {Reject(int(c)).name: int(k) for c, k in zip(codes, n)}


# ---------------------------------------------------------------- geometry
def _cross2(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _normalize(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0.0, n, 1.0), n[..., 0]


def auxiliary_frame(x_nm: np.ndarray):
    """Auxiliary plane of each nonmortar facet (same construction as the JAX kernel).

    Parameters
    ----------
    x_nm : (P, 4, 3) nonmortar facet nodes

    Returns
    -------
    x0 : (P, 3) facet centre; n0, t1, t2 : (P, 3) orthonormal frame, ``n0`` outward;
    normal_norm : (P,) ``|(x2 - x0) x (x3 - x1)|`` (twice the area of a flat facet)
    """
    x0 = x_nm.mean(axis=1)
    n0, nn = _normalize(np.cross(x_nm[:, 2] - x_nm[:, 0], x_nm[:, 3] - x_nm[:, 1]))
    e = x_nm[:, 1] + x_nm[:, 2] - x_nm[:, 0] - x_nm[:, 3]
    t1, _ = _normalize(e - np.sum(e * n0, axis=1, keepdims=True) * n0)
    t2 = np.cross(n0, t1)
    return x0, n0, t1, t2, nn


def _shoelace(p, count=None):
    """Signed area of polygons (P, M, 2) with ``count`` valid vertices each (default M)."""
    P, M = p.shape[:2]
    count = np.full(P, M) if count is None else count
    ar = np.arange(M)
    nxt = np.where(ar[None, :] + 1 < count[:, None], ar[None, :] + 1, 0)
    q = np.take_along_axis(p, nxt[..., None], axis=1)
    c = _cross2(p, q) * (ar[None, :] < count[:, None])
    return 0.5 * c.sum(axis=1)


def _corner_crosses(p):
    """(P, 4) cross products at the corners of quads (P, 4, 2); all > 0 iff strictly convex CCW."""
    e = np.roll(p, -1, axis=1) - p
    return _cross2(e, np.roll(e, -1, axis=1))


def triangles(x: np.ndarray) -> np.ndarray:
    """(P,) bool: which facets x (P, 4, 3) (or (P, 4, 2)) are triangles, stored as a quad whose node 3
    repeats node 0 (:func:`contopt.contact.facets.contact_facets`)."""
    return np.all(x[:, 3] == x[:, 0], axis=-1)


def _facet_corner_crosses(p, tri):
    """:func:`_corner_crosses` of facets p (P, 4, 2); a triangle's (``tri`` (P,)) are all its three
    corners' one value, twice its signed area (a triangle is convex: only its orientation is tested)."""
    c = _corner_crosses(p)
    t = _cross2(p[:, 1] - p[:, 0], p[:, 2] - p[:, 1])
    return np.where(tri[:, None], t[:, None], c)


def _strictly_convex(p, tri, facet_area, sign):
    """(P,) bool: facets p (P, 4, 2) strictly convex, turning counter-clockwise (``sign`` 1.0) or
    clockwise (-1.0) at every corner by more than 1e-10 of ``facet_area`` (P,)."""
    return np.all(sign * _facet_corner_crosses(p, tri) > 1e-10 * np.abs(facet_area)[:, None], axis=1)


def vertex_coordinates(pn: np.ndarray, pm: np.ndarray, topo: np.ndarray) -> np.ndarray:
    """2D polygon vertices (P, 8, 2) from topology (numpy twin of the JAX rule; padding -> 0).

    Parameters
    ----------
    pn, pm : (P, 4, 2) projected nonmortar / mortar quads; topo : (P, 8, 3)
    """
    kind, i, j = topo[..., 0], np.clip(topo[..., 1], 0, 3), np.clip(topo[..., 2], 0, 3)
    take = lambda p, k: np.take_along_axis(p, k[..., None], axis=1)  # noqa: E731
    a, b = take(pn, i), take(pn, (i + 1) % 4)
    c, d = take(pm, j), take(pm, (j + 1) % 4)
    den = _cross2(b - a, d - c)
    is2 = (kind == 2) & (den != 0.0)
    s = np.where(is2, _cross2(c - a, d - c), 0.0) / np.where(is2, den, 1.0)
    v = np.where((kind == 0)[..., None], a, np.where((kind == 1)[..., None], c, a + s[..., None] * (b - a)))
    return np.where((kind >= 0)[..., None], v, 0.0)


# ----------------------------------------------------------------- clipping
def _clip(pn, pm, start, band, tri_nm=None, tri_m=None):
    """Sutherland-Hodgman of the reversed mortar quads against the nonmortar edge lines; a vertex
    beyond a line, or within ``band`` (P,) of it on an edge along it (:func:`_inside`), is outside.
    ``tri_nm``, ``tri_m`` (P,) bool: the facet is a triangle (node 3 repeats node 0,
    :func:`triangles`): a nonmortar triangle has no clip line 3, a mortar triangle starts as the
    3-gon of its nodes 0, 2, 1.

    Returns vertices (P, B, 2), outgoing-line labels (P, B) (0..3 nonmortar
    edge, 4..7 = 4 + mortar edge), counts (P,) and an overflow flag (P,).
    """
    P = pn.shape[0]
    B = _BUFFER
    V = np.zeros((P, B, 2))
    lab = np.full((P, B), -1, dtype=np.int64)
    # reversed mortar order 0,3,2,1 is counter-clockwise; the edge leaving node 0
    # towards node 3 is mortar edge 3 (nodes 3, 0), and so on
    V[:, :4] = pm[:, [0, 3, 2, 1]]
    lab[:, :4] = 4 + np.array([3, 2, 1, 0])
    cnt = np.where(start, 4, 0)
    if tri_m is not None and tri_m.any():
        V[tri_m, :4] = np.concatenate([pm[tri_m][:, [0, 2, 1]], np.zeros((int(tri_m.sum()), 1, 2))], axis=1)
        lab[tri_m, :4] = np.array([6, 5, 4, -1])
        cnt = np.where(start, np.where(tri_m, 3, 4), 0)
    overflow = np.zeros(P, dtype=bool)
    ar = np.arange(B)
    rows = np.arange(P)[:, None]
    for c in range(4):
        A = pn[:, c]
        e = pn[:, (c + 1) % 4] - A
        d = _cross2(e[:, None, :], V - A[:, None, :]) / np.maximum(np.linalg.norm(e, axis=1), 1e-300)[:, None]
        valid = ar[None, :] < cnt[:, None]
        nxt = np.where(ar[None, :] + 1 < cnt[:, None], ar[None, :] + 1, 0)
        inside = _inside(d, band, valid, nxt, rows, cnt)
        if c == 3 and tri_nm is not None:  # a triangle has three clip lines
            inside |= tri_nm[:, None]
        Q = V[rows, nxt]
        dQ, inQ, labQ = d[rows, nxt], inside[rows, nxt], lab[rows, nxt]
        cross_ = valid & (inside != inQ)
        den = np.where(cross_, d - dQ, 1.0)
        t = np.clip(np.where(cross_, d, 0.0) / den, 0.0, 1.0)
        I = V + t[..., None] * (Q - V)
        # entering (P out, Q in): emit I (continues along P->Q), then Q;
        # leaving (P in, Q out): emit I, whose outgoing edge runs along clip line c
        e1 = cross_
        e1lab = np.where(inQ, lab, c)
        e2 = valid & inQ
        flags = np.stack([e1, e2], axis=2).reshape(P, 2 * B)
        pts = np.stack([I, Q], axis=2).reshape(P, 2 * B, 2)
        labs = np.stack([e1lab, labQ], axis=2).reshape(P, 2 * B)
        newcnt = flags.sum(axis=1)
        over = newcnt > B
        overflow |= over
        flags &= ~over[:, None]
        newcnt = np.where(over, 0, newcnt)
        pos = np.cumsum(flags, axis=1) - 1
        r, k = np.nonzero(flags)
        V = np.zeros((P, B, 2))
        lab = np.full((P, B), -1, dtype=np.int64)
        V[r, pos[r, k]] = pts[r, k]
        lab[r, pos[r, k]] = labs[r, k]
        cnt = newcnt
    return V, lab, cnt, overflow


def _inside(d, band, valid, nxt, rows, cnt):
    """(P, B) which polygon vertices lie inside a clip line, from their signed distances ``d`` (P, B):
    beyond ``band`` (P,); or within it, on the inside, with a polygon edge to a neighbour beyond the band
    but within :data:`ALONG` bands (the edge lies along the line), unless an edge from it has both ends
    within the band (it is on the line). So the two pairs either side of a mortar edge along a nonmortar
    edge take it alike. Vertex by vertex, an edge with one end within the band and the other just beyond
    (a symmetry plane's node lines 4e-11 and 1.1e-10 h apart, Newton's error) bounded one pair partly by
    the nonmortar edge while the strip beyond was dropped, and the residual jumped by 1e-7 at every such
    crossing, which the line search then halved towards (the tutorial pressed 0.6, its first trial
    design). Edges that cross the line or leave it steeply keep their vertex within the band outside."""
    near = valid & (np.abs(d) <= band[:, None])
    beyond = d > band[:, None]
    along = near & near[rows, nxt] & (cnt[:, None] >= 2)  # the edge from vertex k to the next
    ar = np.arange(d.shape[1])[None, :]
    prv = np.where(ar >= 1, ar - 1, np.maximum(cnt[:, None] - 1, 0))
    on = along | along[rows, prv]
    # a neighbour just beyond the band: the edge to it lies along the line, on the inside
    close = beyond & (d <= ALONG * band[:, None])
    return beyond | ((d > 0) & near & ~on & (close[rows, nxt] | close[rows, prv]))


def _on_line_band(pn, facet_area, area_tol, floor, tri_nm=None):
    """(P,) how near a nonmortar edge line a mortar edge's two ends count as on it: ``area_tol`` x the facet's
    area over its shortest edge, the widest strip along an edge that the area test would drop as a
    sliver, and at least ``floor``, the distance within which the clipped polygon's vertices merge
    (a narrower strip collapses to fewer than three vertices).

    On the line counts as outside: where a mortar edge lies along a nonmortar edge (a symmetry plane,
    a matching mesh), the pair on its near side is then bounded by the nonmortar edge and the strip
    on its far side is empty, both alike however round-off places the mortar edge within the band.
    Counted inside, a mortar edge 1.4e-13 inside bounded the near pair while the far strip (area 8e-13
    of the facet) was dropped: the pair's area followed the mortar edge with no strip to cancel it,
    and the residual jumped (2.3e-6 on the tutorial's roller) as round-off moved the edge across."""
    edges = np.linalg.norm(np.roll(pn, -1, axis=1) - pn, axis=2)
    if tri_nm is not None:  # a triangle's edge 3 (node 0 to its repeat) is no edge
        edges[:, 3] = np.where(tri_nm, np.inf, edges[:, 3])
    edges = edges.min(axis=1)
    return np.maximum(area_tol * np.abs(facet_area) / np.maximum(edges, 1e-300), floor)


def _line_directions(pn, pm):
    """(P, 8, 2) direction of line label l: nonmortar edge l (l < 4) or mortar edge l - 4."""
    dn = np.roll(pn, -1, axis=1) - pn
    dm = np.roll(pm, -1, axis=1) - pm
    return np.concatenate([dn, dm], axis=1)


def _simplify(V, lab, cnt, dirs, tol_merge, par_tol):
    """Merge coincident consecutive vertices, drop vertices on two (near-)parallel lines.

    One vertex per pair and pass; a pass costs a few vectorized operations and
    only near-degenerate pairs need more than one.
    """
    P, B = lab.shape
    ar = np.arange(B)
    rows = np.arange(P)[:, None]
    dnorm = np.linalg.norm(dirs, axis=2)
    for _ in range(2 * B):
        valid = (ar[None, :] < cnt[:, None]) & (cnt[:, None] >= 3)
        nxt = np.where(ar[None, :] + 1 < cnt[:, None], ar[None, :] + 1, 0)
        prv = np.where(ar[None, :] >= 1, ar[None, :] - 1, np.maximum(cnt[:, None] - 1, 0))
        dist = np.linalg.norm(V[rows, nxt] - V, axis=2)
        dup = valid & (dist <= tol_merge[:, None])
        lin, lout = lab[rows, prv], lab
        lin_c, lout_c = np.clip(lin, 0, 7), np.clip(lout, 0, 7)
        sin = np.abs(_cross2(dirs[rows, lin_c], dirs[rows, lout_c])) / np.maximum(
            dnorm[rows, lin_c] * dnorm[rows, lout_c], 1e-300
        )
        col = valid & ((lin == lout) | (sin < par_tol))
        any_dup, any_col = dup.any(axis=1), col.any(axis=1)
        act = any_dup | any_col
        if not act.any():
            break
        kd = np.argmax(dup, axis=1)
        rem = np.where(any_dup, nxt[np.arange(P), kd], np.argmax(col, axis=1))
        # the merged vertex keeps the incoming line of the first and the outgoing
        # line of the second: it is their intersection
        p_dup = np.nonzero(any_dup)[0]
        lab[p_dup, kd[p_dup]] = lab[p_dup, rem[p_dup]]
        idx = np.minimum(ar[None, :] + (act[:, None] & (ar[None, :] >= rem[:, None])), B - 1)
        V = V[rows, idx]
        lab = lab[rows, idx]
        cnt = cnt - act
    return V, lab, cnt


def _shared_node(a, b, n=4):
    """Node shared by edges a and b (edge k = nodes k, k+1 mod n: n = 4 a quad, 3 a triangle), -1 if
    not adjacent."""
    return np.where(b == (a + 1) % n, b, np.where(a == (b + 1) % n, a, -1))


def _topology(lab, cnt, n_nm=4, n_m=4):
    """(P, 8, 3) topology from outgoing-line labels; second output flags inconsistent pairs.
    ``n_nm``, ``n_m``: nodes of the nonmortar / mortar facets, 4 or (P, 1) arrays of 3 or 4."""
    P, B = lab.shape
    ar = np.arange(B)
    rows = np.arange(P)[:, None]
    valid = ar[None, :] < cnt[:, None]
    prv = np.where(ar[None, :] >= 1, ar[None, :] - 1, np.maximum(cnt[:, None] - 1, 0))
    lin, lout = lab[rows, prv], lab
    nm_in, nm_out = lin < 4, lout < 4
    kind = np.where(nm_in & nm_out, 0, np.where(~nm_in & ~nm_out, 1, 2))
    node0 = _shared_node(lin, lout, n_nm)
    node1 = _shared_node(lin - 4, lout - 4, n_m)
    i = np.where(kind == 0, node0, np.where(kind == 2, np.where(nm_in, lin, lout), -1))
    j = np.where(kind == 1, node1, np.where(kind == 2, np.where(nm_in, lout, lin) - 4, -1))
    bad = valid & (((kind == 0) & (node0 < 0)) | ((kind == 1) & (node1 < 0)))
    topo = np.stack([kind, i, j], axis=2)
    topo = np.where(valid[..., None], topo, -1)
    return topo[:, :MAX_VERTICES], bad.any(axis=1) | (cnt > MAX_VERTICES)


# --------------------------------------------------------------------- API
def segment_pairs(
    x_nm: np.ndarray,
    x_m: np.ndarray,
    *,
    max_angle_deg: float = 60.0,
    area_tol: float = 1e-12,
    eps: float = 1e-12,
    parallel_tol: float = 1e-10,
    band: float = ON_LINE_BAND,
) -> Segmentation:
    """Clip the projected mortar facet against the projected nonmortar facet, for P pairs.

    Parameters
    ----------
    x_nm : (P, 4, 3) nonmortar facet nodes, current configuration, outward ordering
    x_m : (P, 4, 3) mortar facet nodes, current configuration, outward ordering
        (of the mortar body: a facing mortar facet is oriented opposite to ``n0``)
    max_angle_deg : a pair is kept only if the mortar centre normal ``n_m`` satisfies
        ``n0 . n_m <= -cos(max_angle_deg)`` (the facets face each other)
    area_tol : a pair is kept only if its overlap area > ``area_tol`` * nonmortar facet area.
        Small on purpose (conservation of the overlap areas); slivers kept just above it have
        large but exact second derivatives (~ 1/angle between their nearly parallel edges)
    eps : relative length tolerance (times sqrt(facet area)): vertices within ``100 eps`` of each
        other are merged, and a mortar edge within that distance of a nonmortar edge line (or
        ``band``, or the widest strip ``area_tol`` drops) counts as on it: outside (:func:`_on_line_band`)
    parallel_tol : a vertex whose two lines make an angle with sine below this is dropped (it is
        collinear with its neighbours; it would make the 2x2 intersection system singular)
    band : a mortar edge with both ends within ``band`` sqrt(facet area) of a nonmortar edge line is on it

    Returns
    -------
    Segmentation with topo (P, 8, 3), n_vertices, active, reason, area, facet_area
    """
    x_nm = np.asarray(x_nm, dtype=np.float64)
    x_m = np.asarray(x_m, dtype=np.float64)
    if x_nm.ndim != 3 or x_nm.shape[1:] != (4, 3) or x_m.shape != x_nm.shape:
        raise ValueError(f"x_nm and x_m must both have shape (P, 4, 3), got {x_nm.shape} and {x_m.shape}")
    P = x_nm.shape[0]
    tri_nm, tri_m = triangles(x_nm), triangles(x_m)
    x0, n0, t1, t2, nn = auxiliary_frame(x_nm)
    basis = np.stack([t1, t2], axis=2)  # (P, 3, 2)
    pn = np.einsum("pki,pij->pkj", x_nm - x0[:, None], basis)
    pm = np.einsum("pki,pij->pkj", x_m - x0[:, None], basis)

    facet_area = _shoelace(pn)
    rel = x_nm - x0[:, None]
    scale2 = np.maximum(np.sum(rel * rel, axis=(1, 2)), 1e-300)  # ~ 2 * facet area
    h = np.sqrt(np.abs(facet_area))
    reason = np.zeros(P, dtype=np.int8)

    def reject(mask, why):
        reason[(reason == 0) & mask] = why

    reject(nn <= 1e-12 * scale2, Reject.DEGENERATE_NONMORTAR)
    reject(~_strictly_convex(pn, tri_nm, facet_area, 1.0), Reject.NONCONVEX_NONMORTAR)
    nm_vec = np.cross(x_m[:, 2] - x_m[:, 0], x_m[:, 3] - x_m[:, 1])
    n_m, nm_norm = _normalize(nm_vec)
    reject(nm_norm <= 1e-12 * scale2, Reject.DEGENERATE_MORTAR)
    reject(np.sum(n0 * n_m, axis=1) > -np.cos(np.deg2rad(max_angle_deg)), Reject.NOT_FACING)
    # facing mortar quads project clockwise: every corner cross product negative
    reject(~_strictly_convex(pm, tri_m, facet_area, -1.0), Reject.NONCONVEX_MORTAR)

    ok = reason == 0
    band_nm = _on_line_band(pn, facet_area, area_tol, np.maximum(100 * eps, band) * h, tri_nm)
    V, lab, cnt, overflow = _clip(pn, pm, ok, band_nm, tri_nm, tri_m)
    V, lab, cnt = _simplify(V, lab, cnt, _line_directions(pn, pm), 100 * eps * h, parallel_tol)
    reject(ok & overflow, Reject.TOPOLOGY)
    reject(ok & (cnt < 3), Reject.EMPTY)
    cnt = np.where(reason == 0, cnt, 0)

    topo, bad = _topology(lab, cnt, np.where(tri_nm, 3, 4)[:, None], np.where(tri_m, 3, 4)[:, None])
    reject(bad, Reject.TOPOLOGY)
    # Recompute from topology exactly as JAX will and check against the clipper.
    # Round-off moves an intersection of lines crossing at an angle theta >=
    # parallel_tol by ~1e-16 h / theta along them (harmless); a larger deviation
    # means the topology does not describe the clipped polygon. That happens
    # for slivers between nearly coincident edges (width ~ round-off / tolerance,
    # lines crossing outside the clipped segments): dropped as slivers, losing
    # their tiny area. Anything else would be a bug: TOPOLOGY.
    W = vertex_coordinates(pn, pm, topo)
    nv = np.minimum(cnt, MAX_VERTICES)
    dev = np.max(np.linalg.norm(W - V[:, :MAX_VERTICES], axis=2) * (topo[..., 0] >= 0), axis=1)
    off = (reason == 0) & (dev > 1e-4 * h)
    thin = np.abs(_shoelace(V[:, :MAX_VERTICES], nv)) <= 1e-6 * np.abs(facet_area)
    reject(off & thin, Reject.SLIVER)
    reject(off, Reject.TOPOLOGY)
    area = _shoelace(W, nv)
    reject((reason == 0) & ~(area > area_tol * np.abs(facet_area)), Reject.SLIVER)

    active = reason == Reject.ACTIVE
    topo = np.where(active[:, None, None], topo, -1).astype(np.int64)
    n_vertices = np.where(active, nv, 0).astype(np.int64)
    area = np.where(active, area, 0.0)
    arrays = (topo, n_vertices, active, reason, area, facet_area)
    for arr in arrays:
        arr.setflags(write=False)
    seg = Segmentation(*arrays)
    if logger.isEnabledFor(logging.DEBUG):
        logger.debug("segmented %d pairs: %s", P, seg.counts())
    return seg
