"""The contact face of a rigid tool: a quadrilateral surface and the one layer of hex8 cells under it.

A rigid tool has no unknowns: every node follows its prescribed rigid motion. The contact code works
on the facets of hex8 bodies, so the tool is given as its surface (:class:`QuadSurface`, outward
normals by the right-hand rule) extruded into ONE layer of hex8 cells on its inner side
(:func:`tool_layer`). A trilinear cell moved rigidly has ``F = R`` at every point whatever its shape,
so the layer stores no energy and exerts no force of its own: the reaction on its nodes is the
force the contact transmits.

Surfaces
--------
plane_surface      a rectangular patch of a plane
cylinder_surface   the mantle of a circular cylinder, or an arc of it
sphere_surface     a sphere (an equiangular cube-sphere) or a cap of it
read_surface       a triangulated or quadrilateral surface from STL or any surface file meshio reads
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from contopt.errors import MeshError
from contopt.mesh.core import Mesh, scaled_jacobian
from contopt.mesh.generators import merge_nodes

log = logging.getLogger(__name__)

__all__ = [
    "QuadSurface",
    "cylinder_surface",
    "plane_surface",
    "read_surface",
    "sphere_surface",
    "surface_from_cells",
    "tool_layer",
]

#: a coordinate axis by its letter
_UNIT = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, 1.0, 0.0]), "z": np.array([0.0, 0.0, 1.0])}
#: nodes closer than this times the surface's size are one node (a file's duplicated vertices)
_MERGE = 1e-9


@dataclass(frozen=True, eq=False)
class QuadSurface:
    """Quadrilateral facets: the contact face of a rigid tool.

    points : (n, 3) float64 coordinates
    quads : (m, 4) int64 node indices, counter-clockwise seen from outside (the right-hand rule gives
        the outward normal, towards the body the tool touches)

    Construction checks shapes, finite coordinates, index ranges and that no facet is degenerate.
    """

    points: np.ndarray
    quads: np.ndarray

    def __post_init__(self):
        pts = np.array(self.points, dtype=np.float64)
        quads = np.asarray(self.quads)
        if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
            raise MeshError(f"a surface's points must be finite (n, 3) coordinates, got shape {pts.shape}")
        if quads.ndim != 2 or quads.shape[1] != 4 or len(quads) == 0 or not np.issubdtype(quads.dtype, np.integer):
            raise MeshError(f"a surface's quads must be (m >= 1, 4) integer node indices, got {quads.shape}")
        if quads.min() < 0 or quads.max() >= len(pts):
            raise MeshError(f"a surface's quads refer to nodes outside 0..{len(pts) - 1}")
        quads = np.array(quads, dtype=np.int64)
        pts.setflags(write=False)
        quads.setflags(write=False)
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "quads", quads)
        areas, size = self.areas(), float(np.max(np.ptp(pts, axis=0)))
        if not (areas > 1e-12 * size**2).all():
            bad = int(np.argmin(areas))
            raise MeshError(f"facet {bad} of the surface is degenerate (area {areas[bad]:.3g}, nodes {quads[bad]})")

    def vector_areas(self) -> np.ndarray:
        """(m, 3) area times unit normal of each facet (exact for a bilinear quad: half the cross
        product of its diagonals)."""
        x = self.points[self.quads]
        return 0.5 * np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])

    def areas(self) -> np.ndarray:
        """(m,) the facets' projected areas (their true areas where they are flat)."""
        return np.linalg.norm(self.vector_areas(), axis=1)

    def normals(self) -> np.ndarray:
        """(m, 3) unit outward normals at the facet centres."""
        v = self.vector_areas()
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    def flipped(self) -> QuadSurface:
        """The same facets with their normals reversed (a bore instead of a pin)."""
        return QuadSurface(self.points, self.quads[:, ::-1])

    def scaled(self, factor: float) -> QuadSurface:
        """The surface with every coordinate times ``factor`` (a CAD file in mm for a model in m)."""
        if not (np.isfinite(factor) and factor > 0):
            raise MeshError(f"scale must be a positive number, got {factor!r}")
        return QuadSurface(self.points * float(factor), self.quads)


def _unit(name: str, v) -> np.ndarray:
    """(3,) the unit vector of ``v``: a letter "x", "y", "z" or three numbers."""
    if isinstance(v, str):
        if v not in _UNIT:
            raise MeshError(f'{name} must be "x", "y", "z" or a vector [x, y, z], got {v!r}')
        return _UNIT[v].copy()
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or not np.linalg.norm(a) > 0:
        raise MeshError(f"{name} must be a nonzero vector [x, y, z], got {v!r}")
    return a / np.linalg.norm(a)


def _point(name: str, v) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise MeshError(f"{name} must be a point [x, y, z], got {v!r}")
    return a


def _count(name: str, v) -> int:
    if isinstance(v, bool) or int(v) != v or v < 1:
        raise MeshError(f"{name} must be a positive integer, got {v!r}")
    return int(v)


def _length(name: str, v) -> float:
    v = float(v)
    if not (np.isfinite(v) and v > 0):
        raise MeshError(f"{name} must be a positive length, got {v!r}")
    return v


def _tangent(normal: np.ndarray) -> np.ndarray:
    """(3,) a unit vector normal to ``normal``: the coordinate axis least along it (x first among equals),
    made orthogonal (so the sides of a patch facing z run along x and y)."""
    a = _UNIT["xyz"[int(np.argmin(np.abs(normal)))]]
    t = a - (a @ normal) * normal
    return t / np.linalg.norm(t)


def _grid_quads(ni: int, nj: int, periodic_i: bool = False) -> np.ndarray:
    """(ni nj, 4) quads of a grid of nodes numbered ``i + n_i_nodes * j``, counter-clockwise in (i, j)."""
    nin = ni if periodic_i else ni + 1
    i, j = (g.ravel() for g in np.meshgrid(np.arange(ni), np.arange(nj), indexing="xy"))
    i1 = (i + 1) % nin if periodic_i else i + 1
    return np.stack([i + nin * j, i1 + nin * j, i1 + nin * (j + 1), i + nin * (j + 1)], axis=1)


def plane_surface(center, normal, size, divisions=(1, 1)) -> QuadSurface:
    """A rectangle of a plane: the face of a flat punch, a floor, an anvil.

    center : (3,) the rectangle's centre; normal : (3,) its outward normal (towards the body it
    touches); size : its side lengths (a, b), or one length for a square; divisions : (n_a, n_b)
    facets along its sides. Side a runs along the coordinate axis least along the normal, made
    orthogonal to it (x for a normal along z), side b along ``normal x a``.
    """
    c, n = _point("center", center), _unit("normal", normal)
    sa, sb = (size, size) if np.ndim(size) == 0 else tuple(size)
    a_len, b_len = _length("size", sa), _length("size", sb)
    na, nb = (_count("divisions", d) for d in divisions)
    e1 = _tangent(n)
    e2 = np.cross(n, e1)
    s, t = np.meshgrid(a_len * (np.linspace(0, 1, na + 1) - 0.5), b_len * (np.linspace(0, 1, nb + 1) - 0.5))
    points = c + s.reshape(-1, 1) * e1 + t.reshape(-1, 1) * e2
    return QuadSurface(points, _grid_quads(na, nb))


def cylinder_surface(radius, length, center, axis="z", divisions=(32, 1), arc=2 * np.pi, normal=None) -> QuadSurface:
    """The mantle of a circular cylinder, outward normals: a roller, a round die, a pin.

    radius : its radius; length : its extent along the axis, centred on ``center``; center : (3,) a point
    on the axis; axis : "x", "y", "z" or a vector; divisions : (n_around, n_along) facets (the circle is a
    polygon of its nodes); arc : the angle it spans (radians, up to the full 2 pi); normal : (3,) the
    outward normal in the middle of the arc (made orthogonal to the axis; default: the axis's first
    normal direction: y for "x", x for "y" and "z", as the generators' ``cylinder_shell_sector``).
    An arc's nodes are those of ``cylinder_shell_sector`` of the same radius, arc and middle.
    """
    c, w = _point("center", center), _unit("axis", axis)
    r, length = _length("radius", radius), _length("length", length)
    n_around, n_along = (_count("divisions", d) for d in divisions)
    arc = float(arc)
    full = abs(arc - 2 * np.pi) <= 1e-12
    if not (0 < arc <= 2 * np.pi + 1e-12):
        raise MeshError(f"arc must lie in (0, 2 pi], got {arc!r}")
    if full and n_around < 3:
        raise MeshError(f"a full cylinder needs divisions n_around >= 3, got {n_around}")
    if normal is None:
        m = {"x": _UNIT["y"], "y": _UNIT["x"], "z": _UNIT["x"]}[axis] if isinstance(axis, str) else _tangent(w)
    else:
        m = _unit("normal", normal)
        m = m - (m @ w) * w
        if not np.linalg.norm(m) > 1e-9:
            raise MeshError(f"normal {normal!r} lies along the axis: give the outward normal in the arc's middle")
        m = m / np.linalg.norm(m)
    v = np.cross(w, m)
    beta = arc * (np.linspace(0, 1, n_around + 1) - 0.5)
    if full:
        beta = beta[:-1]
    s = length * (np.linspace(0, 1, n_along + 1) - 0.5)
    B, S = np.meshgrid(beta, s)  # [j, i]: i around, j along
    points = c + r * (np.cos(B).reshape(-1, 1) * m + np.sin(B).reshape(-1, 1) * v) + S.reshape(-1, 1) * w
    return QuadSurface(points, _grid_quads(n_around, n_along, periodic_i=full))


def _sphere_patch(d: np.ndarray, e1: np.ndarray, half: float, n: int):
    """(points ((n+1)^2, 3) on the unit sphere, quads (n^2, 4)) of the equiangular patch around ``d``:
    the directions ``d + tan(a) e1 + tan(b) e2`` for a, b in [-half, half] (e2 = d x e1)."""
    e2 = np.cross(d, e1)
    t = np.tan(half * np.linspace(-1.0, 1.0, n + 1))
    A, B = np.meshgrid(t, t)  # [j, i]
    p = d + A.reshape(-1, 1) * e1 + B.reshape(-1, 1) * e2
    return p / np.linalg.norm(p, axis=1, keepdims=True), _grid_quads(n, n)


def sphere_surface(radius, center, divisions=8, normal=None, angle=None) -> QuadSurface:
    """A sphere, or a cap of it, outward normals: a ball indenter.

    radius : its radius; center : (3,) its centre; divisions : facets along each side of the six
    cube-sphere patches (the whole sphere: 6 divisions^2 facets) or of the cap; normal : (3,) the
    direction from the centre to the cap's middle (default -z: a ball pressing down); angle : the
    cap's half-width, radians up to pi/3, from its middle to the middle of each of its four edges
    (None: the whole sphere). The facets are equiangular: their sides subtend equal angles.
    """
    c, r = _point("center", center), _length("radius", radius)
    n = _count("divisions", divisions)
    if angle is None:
        patches = []
        for k in range(3):
            for sign in (1.0, -1.0):
                d = sign * _UNIT["xyz"[k]]
                patches.append(_sphere_patch(d, _UNIT["xyz"[(k + 1) % 3]], np.pi / 4, n))
        pts = np.concatenate([p for p, _ in patches])
        quads = np.concatenate([q + i * (n + 1) ** 2 for i, (_, q) in enumerate(patches)])
        # the patches share their edges: one node each (the unit sphere's round-off only)
        pts, quads, _ = merge_nodes(pts, quads, 1e-9)
        return QuadSurface(c + r * pts, quads)
    angle = float(angle)
    if not 0 < angle <= np.pi / 3 + 1e-12:
        raise MeshError(f"angle (the cap's half-width) must lie in (0, pi/3], got {angle!r}")
    d = _unit("normal", (0.0, 0.0, -1.0) if normal is None else normal)
    pts, quads = _sphere_patch(d, _tangent(d), angle, n)
    return QuadSurface(c + r * pts, quads)


def surface_from_cells(points, triangles=None, quads=None) -> QuadSurface:
    """A quad surface from triangles (k, 3) and/or quads (l, 4) of ``points`` (n, 3), each ordered
    counter-clockwise seen from outside.

    Quads alone are kept. Otherwise every triangle becomes 3 quads through its edge midpoints and
    centroid and every quad 4 through its edge midpoints and centre: every edge is halved, so the
    quads of neighbouring facets share their nodes (a conforming surface). Coincident nodes (a
    file's duplicated vertices) are merged, unused ones dropped.
    """
    p = np.asarray(points, dtype=np.float64)
    tri = np.zeros((0, 3), np.int64) if triangles is None else np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    quad = np.zeros((0, 4), np.int64) if quads is None else np.asarray(quads, dtype=np.int64).reshape(-1, 4)
    if len(tri) + len(quad) == 0:
        raise MeshError("the surface has no triangles or quadrilaterals")
    size = float(np.ptp(p, axis=0).max()) if len(p) else 1.0
    # merged first, so that neighbouring facets share their edges' midpoints
    p, _, old_to_new = merge_nodes(p, np.zeros((0, 1), np.int64), _MERGE * size)
    tri, quad = old_to_new[tri], old_to_new[quad]
    if len(tri):
        p, quad = _split(p, tri, quad)
    used, q = np.unique(quad, return_inverse=True)
    return QuadSurface(p[used], q.reshape(-1, 4))


def _split(p: np.ndarray, tri: np.ndarray, quad: np.ndarray):
    """(points, quads): triangles into 3 and quads into 4 quads through the edge midpoints."""
    facets = [(tri, 3), (quad, 4)]
    edges = np.concatenate([np.stack([f[:, i], f[:, (i + 1) % k]], axis=-1) for f, k in facets for i in range(k)])
    key = np.sort(edges, axis=1)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    mid = len(p) + inv  # the midpoint node of each (facet, edge)
    points = [p, 0.5 * (p[uniq[:, 0]] + p[uniq[:, 1]])]
    centre = len(p) + len(uniq)
    out, offset = [], 0
    for f, k in facets:
        m = mid[offset : offset + k * len(f)].reshape(k, len(f)).T  # (F, k): midpoint of edge i (i -> i+1)
        offset += k * len(f)
        c = centre + np.arange(len(f))
        points.append(p[f].mean(axis=1))
        centre += len(f)
        for i in range(k):  # corner i, the midpoint after it, the centre, the midpoint before it
            out.append(np.stack([f[:, i], m[:, i], c, m[:, (i - 1) % k]], axis=1))
    return np.concatenate(points), np.concatenate(out)


def read_surface(path, scale: float = 1.0, flip: bool = False) -> QuadSurface:
    """The surface in a file (STL, or any surface mesh meshio reads: .obj, .ply, .vtu, .msh, ...):
    its triangles and quadrilaterals (other cells are left out), coordinates times ``scale``, through
    :func:`surface_from_cells`. A closed surface is oriented outward (its enclosed volume positive);
    an open one keeps the file's orientation, reversed by ``flip``."""
    import meshio  # the core's dependency, imported where a file is read

    path = Path(path)
    if not path.exists():
        raise MeshError(f"no such surface file: {path}")
    try:
        with warnings.catch_warnings():
            # meshio tells ASCII from binary STL by a size product that overflows on ASCII files
            warnings.simplefilter("ignore", RuntimeWarning)
            m = meshio.read(path)
    except Exception as e:  # meshio raises many kinds for an unreadable file
        raise MeshError(f"cannot read the surface file {path}: {e}") from None
    tri = [c.data for c in m.cells if c.type == "triangle"]
    quad = [c.data for c in m.cells if c.type == "quad"]
    if not tri and not quad:
        raise MeshError(
            f"the file {path} has no triangles or quadrilaterals (cells: {sorted({c.type for c in m.cells})}); "
            "a rigid tool needs its surface"
        )
    surface = surface_from_cells(
        np.asarray(m.points, dtype=np.float64)[:, :3] * float(scale),
        np.concatenate(tri) if tri else None,
        np.concatenate(quad) if quad else None,
    )
    surface = oriented(surface, str(path))
    return surface.flipped() if flip else surface


def _directed_edges(quads: np.ndarray) -> np.ndarray:
    return np.stack([quads, np.roll(quads, -1, axis=1)], axis=-1).reshape(-1, 2)


def oriented(surface: QuadSurface, what: str = "the surface") -> QuadSurface:
    """``surface`` checked for consistently oriented facets (no edge run the same way by two) and, when
    closed (every edge shared by two facets), turned outward (its enclosed volume positive)."""
    edges = _directed_edges(surface.quads)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    if (counts > 1).any():
        raise MeshError(
            f"{what}: neighbouring facets are ordered inconsistently (an edge run the same way by two of "
            "them); fix the file's facet orientation (each counter-clockwise seen from outside)"
        )
    _, undirected = np.unique(np.sort(edges, axis=1), axis=0, return_counts=True)
    if (undirected == 2).all():
        x = surface.points[surface.quads]
        volume = float(np.einsum("ij,ij->", x.mean(axis=1), surface.vector_areas())) / 3.0
        if volume < 0:
            log.info("%s is closed and ordered inward: reversed to outward normals", what)
            return surface.flipped()
    return surface


def _vertex_normals(surface: QuadSurface) -> np.ndarray:
    """(n, 3) unit normals at the nodes: the area-weighted mean of their facets' normals."""
    acc = np.zeros_like(surface.points)
    va = surface.vector_areas()
    for k in range(4):
        np.add.at(acc, surface.quads[:, k], va)
    size = np.linalg.norm(acc, axis=1)
    if not (size > 0).all():
        bad = int(np.argmin(size))
        raise MeshError(
            f"the surface's normals cancel at node {bad} {surface.points[bad].tolist()} (facets folded onto "
            "each other there); a rigid tool needs a surface that faces one way"
        )
    return acc / size[:, None]


def tool_layer(surface: QuadSurface, thickness: float = 0.5) -> Mesh:
    """The hex8 Mesh of a rigid tool: one layer of cells under ``surface``, on its inner side.

    thickness : how deep the layer reaches under each node, as a fraction of its shortest facet edge
    (0.5: cells about half as deep as wide). A node moves inward along its normal (the mean of its
    facets'), so the cells do not invert where the surface bends by less than a right angle per facet.

    Returns a Mesh whose cell c has its nodes 4-7 on facet c (so its local face 1 is the facet, with
    the facet's outward normal) and nodes 0-3 under them; facet set ``surface``; node sets
    ``surface`` (its nodes) and ``all``.
    """
    thickness = float(thickness)
    if not (np.isfinite(thickness) and 0 < thickness <= 2):
        raise MeshError(f"thickness must lie in (0, 2] (a fraction of the facet size), got {thickness!r}")
    x, q = surface.points, surface.quads
    edges = np.sort(_directed_edges(q), axis=1)
    lengths = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)
    shortest = np.full(len(x), np.inf)
    np.minimum.at(shortest, edges[:, 0], lengths)
    np.minimum.at(shortest, edges[:, 1], lengths)
    inner = x - (thickness * shortest)[:, None] * _vertex_normals(surface)
    n = len(x)
    cells = np.concatenate([q + n, q], axis=1)
    mesh = Mesh(
        np.concatenate([x, inner]),
        cells,
        {"all": np.arange(2 * n), "surface": np.arange(n)},
        {"surface": np.stack([np.arange(len(q)), np.ones(len(q), np.int64)], axis=1)},
        check=False,
    )
    quality = scaled_jacobian(mesh)
    if not (quality > 0.01).all():
        bad = int(np.argmin(quality))
        raise MeshError(
            f"the tool's layer would invert under facet {bad} (at {x[q[bad]].mean(axis=0).round(6).tolist()}, "
            f"scaled Jacobian {quality[bad]:.3g}): the surface folds sharply there; give a smaller thickness "
            f"than {thickness} or facets that turn by less than a right angle"
        )
    return Mesh(mesh.points, mesh.cells, mesh.node_sets, mesh.facet_sets)
