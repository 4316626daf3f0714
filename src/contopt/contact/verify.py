"""An independent check of a converged contact state: is anything inside the other body unheld?

The mortar evaluation sees penetration only through the facet pairs that the search and the
segmentation kept. When a Newton iterate jumps far (a large first increment, a warm start from
another design), a surface can pass through the other one; the pairs are then dropped as "not
facing" or "behind", no pressure remains, and the solver converges to a state with the bodies
inside each other and zero contact force. This check does not trust the pairing. It projects
every nonmortar node onto the mortar surface, and every mortar node onto the nonmortar surface
(closest point over all facets, each bilinear facet split into four triangles about its centre),
and takes the signed distance along the outward normal at that point as the penetration.

A penetration is *unheld*, and rejects the state, when it is deeper than the tolerance and no
contact pressure holds it: a nonmortar node with no pressure at itself or at a facet neighbour,
a mortar node in a nonmortar facet none of whose nodes touches a facet with pressure (the
mortar method enforces weighted gaps: a corner of the mortar surface may dip between nonmortar
nodes where pressure acts). The tolerance is ``tolerance * h`` plus, where the surfaces are
curved, 1.5 times their chordal sags (``size * kink / 8``: facet size times the angle between
neighbouring facets) at the node and at the facet it is in: a coarse polygon pressed into a
finer one by a load elsewhere (the slug pushed sideways in the sabot's bore) protrudes by its
own sag between the chords of the other without any pressure at that spot. Anything
deeper than the contact search's skin rejects the state whether held or not: the pairs that
hold it are about to be lost. Projections that land on the free edge of an open surface (a
node beside the surface, not under it) are not penetrations. At a ridge between facets the
point is outside if it is outside either facet, so a sharp convex edge never reports a false
penetration.

Cost: a KD-tree over the triangle centres per surface and ~12 exact point-triangle distances
per node, once per converged load step.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from contopt.errors import ConfigError

_K = 12  # nearest triangle centres tried per point before the exact bound decides


@dataclass(frozen=True)
class PenetrationCheck:
    """Options of the check (on :class:`contopt.contact.interface.ContactInterface`).

    tolerance : unheld penetration allowed, as a fraction of the median nonmortar facet size h
        (converged states have none; the mortar method's weak enforcement leaves nodal
        penetrations of a few 1e-4 h at the edge of a contact zone)
    enabled : False skips the check (not recommended: a state with bodies inside each other
        then passes as converged)
    """

    tolerance: float = 1e-3
    enabled: bool = True

    def __post_init__(self):
        if not (isinstance(self.tolerance, (int, float)) and 0 < self.tolerance < 1):
            raise ConfigError(
                f"contact check tolerance must lie in (0, 1) (a fraction of the facet size), got {self.tolerance!r}"
            )
        if not isinstance(self.enabled, bool):
            raise ConfigError(f"contact check enabled must be true or false, got {self.enabled!r}")


@dataclass(frozen=True)
class Finding:
    """The deepest penetration of a check: which node, where, how deep, and why it counts."""

    side: str  # "nonmortar" or "mortar": the side the node belongs to
    body: str
    node: int  # node id within its body
    position: tuple
    depth: float
    relative: float  # depth / h
    held: bool
    other: str  # the body it penetrates

    def describe(self) -> str:
        x = ", ".join(f"{v:.4g}" for v in self.position)
        return (
            f"node {self.node} of body {self.body!r} (the {self.side} side, at ({x})) lies {self.depth:.3g} "
            f"({self.relative:.3g} h) inside body {self.other!r}"
        )


@dataclass(frozen=True, eq=False)
class CheckReport:
    """The check of one interface at one state.

    ok : no unheld or too deep penetration; flagged : number of nodes that reject the state
    worst : the deepest rejecting node (or, when ok, the deepest penetration; None without any)
    depth_nonmortar : (n,) penetration of each nonmortar node (0 where none), a length
    depth_mortar : (m,) same for the mortar nodes; mortar_nodes : (m,) their global ids
    rejected_near_active : facet pairs dropped as not facing / folded next to nodes with pressure
    message : one line for an error or a log (empty when ok)
    advice : what helps against the failure seen (empty when ok), see :func:`advice_for`
    """

    label: str
    ok: bool
    flagged: int
    worst: Finding | None
    depth_nonmortar: np.ndarray
    depth_mortar: np.ndarray
    mortar_nodes: np.ndarray
    rejected_near_active: int
    message: str = ""
    advice: str = ""

    @property
    def max_depth(self) -> float:
        return float(max(self.depth_nonmortar.max(initial=0.0), self.depth_mortar.max(initial=0.0)))


@dataclass(frozen=True, eq=False)
class Surface:
    """A facet set triangulated for closest-point queries (current configuration).

    tri : (T, 3, 3) triangles (centre, node i, node i+1) of each facet, outward orientation;
    facet : (T,) facet of each triangle; edge_free : (T,) its facet edge (node i, i+1) is a free
    edge of the surface; node_free : (T, 3) each vertex lies on the surface's free boundary
    """

    tri: np.ndarray
    facet: np.ndarray
    edge_free: np.ndarray
    node_free: np.ndarray
    normal: np.ndarray
    centre: np.ndarray
    radius: float  # the largest of radii
    tree: cKDTree
    sag: np.ndarray  # (F,) chordal sag of each facet: size * (largest kink to a neighbour) / 8
    radii: np.ndarray  # (T,) each triangle's largest distance from its centre


def surface(x: np.ndarray, facet_nodes: np.ndarray) -> Surface:
    """Triangulated surface of facets with node ids ``facet_nodes`` (F, 4) at coordinates x; a
    triangle (node 3 repeating node 0, :mod:`contopt.contact.facets`) gives three triangles, a quad four."""
    xf = x[facet_nodes]  # (F, 4, 3)
    c = xf.mean(axis=1)  # inside a padded triangle too (weights 1/2, 1/4, 1/4)
    i = np.arange(4)
    tri_nodes = np.stack([facet_nodes[:, i], facet_nodes[:, (i + 1) % 4]], axis=2).reshape(-1, 2)
    real = tri_nodes[:, 0] != tri_nodes[:, 1]  # a triangle's edge 3 is no edge
    tri = np.stack([np.repeat(c[:, None], 4, axis=1), xf[:, i], xf[:, (i + 1) % 4]], axis=2).reshape(-1, 3, 3)
    tri, tri_nodes, owner = tri[real], tri_nodes[real], np.repeat(np.arange(len(facet_nodes)), 4)[real]
    edges = np.sort(tri_nodes, axis=1)
    _, inverse, counts = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
    edge_free = counts[inverse.ravel()] == 1
    free_nodes = np.unique(edges[edge_free])
    node_free = np.concatenate([np.zeros((len(tri), 1), bool), np.isin(tri_nodes, free_nodes)], axis=1)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    centre = tri.mean(axis=1)
    radii = np.linalg.norm(tri - centre[:, None], axis=2).max(axis=1, initial=0.0)
    return Surface(
        tri=tri,
        facet=owner,
        edge_free=edge_free,
        node_free=node_free,
        normal=n,
        centre=centre,
        radius=float(radii.max(initial=0.0)),
        tree=cKDTree(centre),
        sag=_sags(xf, inverse.ravel(), edge_free, owner),
        radii=radii,
    )


def _sags(xf: np.ndarray, edge_id: np.ndarray, edge_free: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """(F,) size * kink / 8 of facets xf (F, 4, 3); edge_id (E,): each facet edge's id (shared edges
    have one id), edge_free (E,), owner (E,) its facet."""
    nf = np.cross(xf[:, 2] - xf[:, 0], xf[:, 3] - xf[:, 1])
    nf /= np.maximum(np.linalg.norm(nf, axis=1, keepdims=True), 1e-300)
    shared = ~edge_free
    order = np.argsort(edge_id[shared], kind="stable")
    ids, owners = edge_id[shared][order], owner[shared][order]
    first = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    pairs = (
        np.stack([owners[first], owners[np.minimum(first + 1, len(owners) - 1)]], axis=1)
        if len(first)
        else np.zeros((0, 2), np.int64)
    )
    kink = np.arccos(np.clip(np.einsum("ij,ij->i", nf[pairs[:, 0]], nf[pairs[:, 1]]), -1.0, 1.0))
    largest = np.zeros(len(xf))
    np.maximum.at(largest, pairs[:, 0], kink)
    np.maximum.at(largest, pairs[:, 1], kink)
    size = np.sqrt(0.5 * np.linalg.norm(np.cross(xf[:, 2] - xf[:, 0], xf[:, 3] - xf[:, 1]), axis=1))
    return size * largest / 8.0


def closest_on_triangles(p: np.ndarray, tri: np.ndarray):
    """Closest points of points p (K, 3) on triangles tri (K, 3, 3) (Ericson, Real-Time Collision
    Detection 5.1.5). Returns the points (K, 3) and the region (K,): 0 face, 1-3 vertex a/b/c,
    4 edge ab, 5 edge ac, 6 edge bc."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac, ap = b - a, c - a, p - a
    dot = lambda u, v: np.einsum("ki,ki->k", u, v)  # noqa: E731
    d1, d2 = dot(ab, ap), dot(ac, ap)
    bp, cp = p - b, p - c
    d3, d4 = dot(ab, bp), dot(ac, bp)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    vc, vb, va = d1 * d4 - d3 * d2, d5 * d2 - d1 * d6, d3 * d6 - d5 * d4
    safe = lambda num, den: num / np.where(den != 0.0, den, 1.0)  # noqa: E731
    cases = [
        (d1 <= 0) & (d2 <= 0),
        (d3 >= 0) & (d4 <= d3),
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),
        (d6 >= 0) & (d5 <= d6),
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),
        (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),
    ]
    v_ab = safe(d1, d1 - d3)[:, None]
    w_ac = safe(d2, d2 - d6)[:, None]
    w_bc = safe(d4 - d3, (d4 - d3) + (d5 - d6))[:, None]
    den = va + vb + vc
    v, w = safe(vb, den)[:, None], safe(vc, den)[:, None]
    points = [a, b, a + v_ab * ab, c, a + w_ac * ac, b + w_bc * (c - b)]
    regions = [1, 2, 4, 3, 5, 6]
    out = a + ab * v + ac * w
    region = np.zeros(len(p), dtype=np.int64)
    done = np.zeros(len(p), bool)
    for case, pt, reg in zip(cases, points, regions):
        take = case & ~done
        out = np.where(take[:, None], pt, out)
        region[take] = reg
        done |= take
    return out, region


def signed_distances(
    points: np.ndarray, surf: Surface, exact_outside: bool = True, within: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance of points (N, 3) to the surface (< 0: behind it, inside its body) and the
    facet of the closest point (N,). Points whose closest point lies on the surface's free edge
    (beside an open surface, not under it) get +inf: they cannot penetrate it.

    ``exact_outside=False``: a point whose nearest candidates put it outside keeps that answer
    (its distance may be overestimated); only points found behind the surface are made exact.
    Cheaper for far points, and enough to find penetrations.
    ``within`` (a length): a point whose nearest candidates already lie within it keeps that answer
    too: its exact distance is no larger, so it cannot lie deeper than ``within`` (enough to ask
    whether anything lies deeper: :meth:`contopt.contact.system.ContactDiscretization.too_deep`;
    every point that may lie deeper is made exact, so the deepest beyond ``within`` is exact).
    """
    n_pts, n_tri = len(points), len(surf.tri)
    if n_pts == 0 or n_tri == 0:
        return np.full(n_pts, np.inf), np.full(n_pts, -1)
    best_d = np.full(n_pts, np.inf)
    best_s, best_f = np.full(n_pts, np.inf), np.full(n_pts, -1)
    todo = np.arange(n_pts)
    # exact: a triangle beyond the k nearest centres is at least (k-th centre distance - radius) away;
    # points far from the surface need more candidates, so ask again with 4x as many, then one by one
    for k in (min(_K, n_tri), min(4 * _K, n_tri)):
        if todo.size == 0:
            break
        dist_c, idx = surf.tree.query(points[todo], k=k)
        dist_c, idx = dist_c.reshape(todo.size, k), idx.reshape(todo.size, k)
        best_d[todo], best_s[todo], best_f[todo] = _evaluate(points[todo], surf, idx)
        unsure = (k < n_tri) & (dist_c[:, -1] - surf.radius < best_d[todo])
        if not exact_outside:
            unsure &= best_s[todo] < 0
        if within is not None:
            unsure &= best_d[todo] > within
        todo = todo[unsure]
    if todo.size:
        idx = _ball_candidates(points[todo], surf, best_d[todo])
        best_d[todo], best_s[todo], best_f[todo] = _evaluate(points[todo], surf, idx)
    return best_s, best_f


def _ball_candidates(points: np.ndarray, surf: Surface, best_d: np.ndarray) -> np.ndarray:
    """(n, m) the triangles that may lie nearer to points (n, 3) than best_d (n,), each row padded
    with its first (a repeat changes no minimum).

    A triangle is at least ``|p - centre| - radius`` away: the ball of the largest radius finds
    every candidate; each triangle's own radius keeps only those that can win or tie (on a graded
    surface the largest facets are far bigger than those near the point: hundreds against a few).
    """
    balls = surf.tree.query_ball_point(points, best_d + surf.radius + 1e-12)
    counts = np.fromiter((len(b) for b in balls), np.int64, len(balls))
    cand = np.fromiter(itertools.chain.from_iterable(balls), np.int64, int(counts.sum()))
    row = np.repeat(np.arange(len(points)), counts)
    lower = np.linalg.norm(surf.centre[cand] - points[row], axis=1) - surf.radii[cand]
    # ties count to a relative 1e-9 (_evaluate): keep those too; best_d's own triangle always passes
    keep = lower <= best_d[row] * (1.0 + 1e-8) + 1e-12
    cand, row = cand[keep], row[keep]
    per_row = np.bincount(row, minlength=len(points))
    start = np.concatenate([[0], np.cumsum(per_row)[:-1]])
    idx = np.empty((len(points), max(int(np.max(per_row, initial=0)), 1)), dtype=np.int64)
    idx[:] = cand[np.minimum(start, len(cand) - 1)][:, None] if len(cand) else 0
    idx[row, np.arange(len(cand)) - start[row]] = cand
    return idx


def _evaluate(points: np.ndarray, surf: Surface, idx: np.ndarray):
    """Distance, sign-resolved signed distance and facet of each point over its candidate triangles."""
    n_pts, k = idx.shape
    p = np.repeat(points, k, axis=0)
    t = idx.ravel()
    y, region = closest_on_triangles(p, surf.tri[t])
    diff = p - y
    dist = np.linalg.norm(diff, axis=1)
    along = np.einsum("ki,ki->k", diff, surf.normal[t])
    # off the free edge of an open surface: the closest point is on a free edge or free vertex
    # and the point is not straight above or below it
    on_free = (
        ((region == 6) & surf.edge_free[t])
        | ((region == 2) & surf.node_free[t, 1])
        | ((region == 3) & surf.node_free[t, 2])
    )
    off = on_free & (np.abs(along) < (1.0 - 1e-9) * dist)
    signed = np.where(off, np.inf, np.sign(along) * dist)
    dist, signed = dist.reshape(n_pts, k), signed.reshape(n_pts, k)
    best = dist.min(axis=1)
    ties = dist <= best[:, None] * (1.0 + 1e-9) + 1e-300
    # at a ridge the point is outside when it is outside either facet
    s = np.where(ties, signed, -np.inf).max(axis=1)
    first = np.argmax(np.where(ties, signed, -np.inf), axis=1)
    facet = surf.facet[idx[np.arange(n_pts), first]]
    return best, s, facet


def _node_sags(sag: np.ndarray, facets: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """(n,) the largest sag of the facets around each of ``nodes`` (global ids, sorted unique)."""
    out = np.zeros(len(nodes))
    np.maximum.at(out, np.searchsorted(nodes, facets.ravel()), np.repeat(sag, 4))
    return out


@dataclass(frozen=True, eq=False)
class Depths:
    """Penetration of every node of an interface into the other body (lengths, 0 where none).

    nonmortar : (n,) of the nonmortar nodes, into the mortar body; mortar_facet : (n,) the mortar
    facet of each one's closest point; mortar : (m,) of the mortar nodes ``mortar_nodes``, into the
    nonmortar body; nonmortar_facet : (m,) likewise; surfaces : (nonmortar, mortar) Surface
    """

    nonmortar: np.ndarray
    mortar_facet: np.ndarray
    mortar: np.ndarray
    nonmortar_facet: np.ndarray
    mortar_nodes: np.ndarray
    surfaces: tuple

    @property
    def deepest(self) -> float:
        return float(max(self.nonmortar.max(initial=0.0), self.mortar.max(initial=0.0)))


def depths(
    x: np.ndarray,
    nm_facets: np.ndarray,
    m_facets: np.ndarray,
    nm_nodes: np.ndarray,
    exact_outside: bool = True,
    within: float | None = None,
) -> Depths:
    """Closest-point penetrations both ways at coordinates x (see the module docstring;
    ``exact_outside``, ``within``: see :func:`signed_distances`)."""
    m_nodes = np.unique(m_facets)
    nonmortar, mortar = surface(x, nm_facets), surface(x, m_facets)
    s_nm, m_facet = signed_distances(x[nm_nodes], mortar, exact_outside, within)
    s_m, nm_facet = signed_distances(x[m_nodes], nonmortar, exact_outside, within)
    depth = lambda s: np.where(np.isfinite(s), np.maximum(0.0, -s), 0.0)  # noqa: E731
    return Depths(
        nonmortar=depth(s_nm),
        mortar_facet=m_facet,
        mortar=depth(s_m),
        nonmortar_facet=nm_facet,
        mortar_nodes=m_nodes,
        surfaces=(nonmortar, mortar),
    )


def check_interface(
    label: str,
    x: np.ndarray,
    nm_facets: np.ndarray,
    m_facets: np.ndarray,
    nm_nodes: np.ndarray,
    nm_local: np.ndarray,
    lam: np.ndarray,
    has_overlap: np.ndarray,
    h: float,
    reach: float,
    options: PenetrationCheck,
    names: tuple,
    node_offsets: tuple,
    rejected_near_active: int = 0,
    side_advice: SideAdvice | None = None,
) -> CheckReport:
    """Check one interface at coordinates x (all nodes, (N, 3)).

    nm_facets, m_facets : (F, 4), (G, 4) global node ids of the facets; nm_nodes : (n,) the
    nonmortar nodes (the pressure unknowns) and nm_local (F, 4) their positions in it; lam :
    (n,) pressures; has_overlap : (n,) nodes with overlap; h : facet size; reach : the search's
    skin; names : (nonmortar body, mortar body); node_offsets : their first global node ids;
    side_advice : what the mortar rule says of the interface's sides (for the advice).
    """
    if not options.enabled:
        m_nodes = np.unique(m_facets)
        return CheckReport(
            label, True, 0, None, np.zeros(len(nm_nodes)), np.zeros(len(m_nodes)), m_nodes, rejected_near_active
        )
    d = depths(x, nm_facets, m_facets, nm_nodes)
    nonmortar, mortar = d.surfaces
    m_nodes = d.mortar_nodes
    pressed = lam > 0
    neighbour = np.zeros(len(nm_nodes), bool)
    pressed_facet = pressed[nm_local].any(axis=1)  # (F,)
    np.logical_or.at(neighbour, nm_local.ravel(), np.repeat(pressed_facet, 4))
    held_nm = pressed | (has_overlap & neighbour)
    # the mortar method enforces weighted gaps: a corner of the mortar surface may dip into the nonmortar
    # one between nodes. It is held when pressure acts on the facet it dips into or next to it.
    near_pressed = neighbour[nm_local].any(axis=1)  # (F,) a node of the facet touches a pressed facet
    held_m = np.where(d.nonmortar_facet >= 0, near_pressed[np.maximum(d.nonmortar_facet, 0)], False)

    tol = options.tolerance * h
    tol_nm = tol + 1.5 * (mortar.sag[np.maximum(d.mortar_facet, 0)] + _node_sags(nonmortar.sag, nm_facets, nm_nodes))
    tol_m = tol + 1.5 * (nonmortar.sag[np.maximum(d.nonmortar_facet, 0)] + _node_sags(mortar.sag, m_facets, m_nodes))
    bad_nm = ((d.nonmortar > tol_nm) & ~held_nm) | (d.nonmortar > reach)
    bad_m = ((d.mortar > tol_m) & ~held_m) | (d.mortar > reach)
    flagged = int(bad_nm.sum() + bad_m.sum())
    sides = (("nonmortar", nm_nodes, d.nonmortar, held_nm, bad_nm), ("mortar", m_nodes, d.mortar, held_m, bad_m))
    worst: Finding | None = None
    for which, (side, nodes, depth, held, bad) in enumerate(sides):
        pool = np.flatnonzero(bad if flagged else depth > 0)
        if pool.size == 0:
            continue
        j = pool[np.argmax(depth[pool])]
        if worst is None or depth[j] > worst.depth:
            worst = Finding(
                side=side,
                body=names[which],
                node=int(nodes[j] - node_offsets[which]),
                position=tuple(float(v) for v in x[nodes[j]]),
                depth=float(depth[j]),
                relative=float(depth[j] / h),
                held=bool(held[j]),
                other=names[1 - which],
            )
    message, advice = "", ""
    if flagged:
        assert worst is not None  # a flagged node is in the pool of its side
        why = (
            f"deeper than the contact search reaches (skin {reach:.3g})"
            if worst.depth > reach
            else "where no contact pressure holds it"
        )
        message = f"contact interface {label}: {worst.describe()}, {why} ({flagged} node(s) fail the check): {LOST}"
        advice = advice_for(worst, reach, side_advice or SideAdvice())
    return CheckReport(
        label=label,
        ok=flagged == 0,
        flagged=flagged,
        worst=worst,
        depth_nonmortar=d.nonmortar,
        depth_mortar=d.mortar,
        mortar_nodes=m_nodes,
        rejected_near_active=rejected_near_active,
        message=message,
        advice=advice,
    )


@dataclass(frozen=True)
class SideAdvice:
    """What the mortar rule says of an interface's sides, for the advice of a failed check.

    mismatch : why the other surface should be nonmortar (finer or more curved, see
    :func:`contopt.contact.interface.choose_sides`), "" when the sides are right;
    swap : the surface to make nonmortar instead (``body/set``); size : the facet size to refine
    the nonmortar surface to (that of the mortar)
    """

    mismatch: str = ""
    swap: str = ""
    size: float = 0.0


#: pointwise penetration (over the nonmortar facet size) of mortar nodes beyond which a coarse
#: nonmortar side is reported: the mortar method's weak enforcement leaves a few 1e-4 h
COARSE_SIDE_DEPTH = 0.01


def coarse_side_warnings(blocks, checks) -> list[str]:
    """A warning per interface (``blocks``: InterfaceBlocks with ``sides``, ``h`` and ``interface``)
    whose nonmortar side is the coarse one (:class:`SideAdvice`) and whose state check (``checks``,
    one CheckReport an interface) shows mortar nodes sunk by more than :data:`COARSE_SIDE_DEPTH` h
    into it: held by the weighted gaps, so no check rejects them."""
    out = []
    for b, c in zip(blocks, checks):
        deepest = float(c.depth_mortar.max(initial=0.0))
        if b.sides.mismatch and deepest > COARSE_SIDE_DEPTH * b.h:
            out.append(
                f"contact interface {b.interface.label}: mortar nodes lie up to {deepest:.3g} "
                f"({deepest / b.h:.2g} h) inside the nonmortar surface, which is the coarse side "
                f"({b.sides.mismatch}); swap the sides (nonmortar = {b.sides.swap}, or give surfaces to have "
                f"them chosen) or refine the nonmortar surface to facets of about {b.sides.size:.2g}"
            )
    return out


#: the check's reading of a node unheld (a step that a smaller one would not have taken)
LOST = "the contact pairs were lost, a step too large for the contact to follow or a surface driven through the other"
#: the advice for a surface driven through the other or lost pairs (what a smaller step changes)
STEP_ADVICE = (
    "use more or smaller load steps (newton.n_steps, newton.max_step) or a larger contact search skin, and "
    "check that the prescribed motion is physically possible"
)


def advice_for(worst: Finding, reach: float, sides: SideAdvice) -> str:
    """What helps against the failure ``worst``: a node deeper than the search reaches or a nonmortar
    node unheld is a surface driven through the other (smaller steps); a mortar node sunk between
    the nodes of a coarser or flatter nonmortar is the mortar discretization (swap the sides or
    refine), which no load step, skin or penalty changes."""
    if worst.depth <= reach and worst.side == "mortar" and sides.mismatch:
        return (
            f"the nonmortar surface is the coarse side: {sides.mismatch}; its weighted gaps cannot hold the "
            f"mortar's nodes between its own, whatever the load steps or the penalty. Swap the sides "
            f"(nonmortar = {sides.swap}, or give surfaces = [a, b] to have them chosen) or refine the nonmortar "
            f"surface to facets of about {sides.size:.2g}"
        )
    if worst.depth <= reach and worst.side == "mortar":
        return f"{STEP_ADVICE}; or refine the nonmortar surface, whose weighted gaps let this node sink between its own"
    return STEP_ADVICE
