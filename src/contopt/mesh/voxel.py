"""A body's mesh from a closed surface as voxels: a design domain given by its envelope.

:func:`mesh_envelope` reads a closed surface (STL, PLY or OBJ; STEP, IGES or BREP through Gmsh,
the ``cad`` extra), lays a structured grid of cubes of edge ``size`` over its bounding box and keeps
the cubes whose centres lie inside (:func:`inside_surface`). The kept cubes are hex8 cells with
the facet and node sets

* ``boundary``: every boundary face of the voxel body;
* ``xmin`` .. ``zmax``: the boundary faces on the voxel body's bounding-box sides (the faces facing
  -x on the lowest x plane of the kept cells, and so on), where supports and loads usually go;

and the node set ``all``. The voxel body's surface is a staircase within half a cube's diagonal of
the envelope, and its volume converges to the envelope's at first order in ``size``.

Inside test: ray parity (a point is inside when a ray from it crosses the surface an odd number of
times), cast along +x, +y and +z and decided by majority. Each ray starts a tiny generic offset off
the point (``_JITTER`` times the surface's size), so it does not run exactly through the edges and
vertices a grid's centres would otherwise meet on the diagonals of a flat face; where one axis
still meets such a tie, the other two outvote it. Parity needs a closed surface (every edge in two
triangles), not consistent orientation; an open one is refused. pyvista's
``select_enclosed_points`` does the same but is the ``viz`` extra's; this is the core's.
Candidate triangles come from a 2D binning of their projections; on the voxel grid each column of
centres is one line, its crossings found once and counted off for every centre along it.

Units are the file's numbers times ``scale``; ``size`` is in the scaled unit.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from contopt.errors import ConfigError, MeshError
from contopt.io.surface import FORMATS, TriangleSurface, check_surface, read_surface
from contopt.mesh.cad import CAD_SUFFIXES, cad_triangles
from contopt.mesh.core import HEX_FACES, Mesh, check_mesh_size

__all__ = ["ENVELOPE_SUFFIXES", "VoxelOptions", "inside_surface", "mesh_envelope", "read_envelope", "voxelize"]

log = logging.getLogger(__name__)

#: the surface files an envelope is read from: triangle files, and CAD files Gmsh triangulates
ENVELOPE_SUFFIXES = tuple(sorted(set(FORMATS) | set(CAD_SUFFIXES)))
#: a ray starts this far (times the surface's bounding-box diagonal) off its point, in a generic direction
_JITTER = 1e-9
#: the generic in-plane directions of that offset, one per ray axis (irrational ratios)
_OFFSETS = np.array([[0.7548776662, 0.5698402910], [0.6180339887, 0.4142135624], [0.3247179572, 0.8660254038]])
#: the relative rounding of a surface file's coordinates (binary STL holds float32) a grid's extent forgives
_ROUNDING = 1e-6
#: triangle-bin entries the binning aims below (halving the bins until it is)
_BIN_ENTRIES = 1 << 22
#: points tested at a time (bounds the memory of the point-triangle pairs)
_CHUNK = 1 << 16
#: hex8 local face (contopt.mesh.core.HEX_FACES) facing -x, +x, -y, +y, -z, +z
_SIDE_FACES = {"xmin": 5, "xmax": 3, "ymin": 2, "ymax": 4, "zmin": 0, "zmax": 1}


@dataclass(frozen=True)
class VoxelOptions:
    """How an envelope is voxelized.

    size : the cubes' edge length (in the scaled unit)
    scale : every coordinate of the surface file is multiplied by it (0.001: a file in mm for a model in m)
    """

    size: float
    scale: float = 1.0

    def __post_init__(self):
        for key in ("size", "scale"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
                raise ConfigError(f"mesh.{key} must be a number > 0 (a length in the model's unit), got {v!r}")


def read_envelope(path, scale: float = 1.0, size: float | None = None) -> TriangleSurface:
    """The closed triangle surface of a file, its coordinates times ``scale``.

    STL / PLY / OBJ are read as they are; STEP / IGES / BREP are triangulated by Gmsh with triangles
    of edge about ``size`` (default: a fiftieth of the solid's size). MeshError for a missing or
    open surface (an edge in one triangle only) or one with no triangles.
    """
    path = Path(path)
    VoxelOptions(size=1.0 if size is None else size, scale=scale)
    suffix = path.suffix.lower()
    if suffix not in ENVELOPE_SUFFIXES:
        raise MeshError(f"{path}: not a surface or CAD file; the suffixes read are {', '.join(ENVELOPE_SUFFIXES)}")
    if not path.is_file():
        raise MeshError(f"envelope file {path} not found")
    if suffix in FORMATS:
        surface = read_surface(path)
        surface = TriangleSurface(surface.vertices * scale, surface.faces)
    else:
        surface = TriangleSurface(*cad_triangles(path, size, scale))
    check = check_surface(surface)
    if check.n_faces == 0:
        raise MeshError(f"{path}: the file holds no triangles; an envelope is a closed surface")
    if not check.watertight:
        raise MeshError(
            f"{path}: the surface is not closed ({check.boundary_edges} open edges, {check.nonmanifold_edges} "
            "non-manifold edges); an envelope must be a closed surface: close it in the CAD or mesher"
        )
    return surface


def _pairs(uv_points: np.ndarray, uv_tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(point, triangle) pairs whose projected point lies in the triangle's projected bounding box.

    uv_points : (k, 2); uv_tri : (m, 3, 2). The triangles are binned on a 2D grid over their
    bounding box, each in the bins its box covers; a point meets the triangles of its bin.
    """
    lo, hi = uv_tri.min(axis=(0, 1)), uv_tri.max(axis=(0, 1))
    nb = int(np.clip(math.sqrt(len(uv_tri)), 1, 256))
    while True:  # long slivers (CAD exports) cover many bins: coarser bins keep the entries few
        width = np.maximum(hi - lo, 1e-300) / nb
        tlo = np.clip(((uv_tri.min(axis=1) - lo) / width).astype(np.int64), 0, nb - 1)
        thi = np.clip(((uv_tri.max(axis=1) - lo) / width).astype(np.int64), 0, nb - 1)
        span = thi - tlo + 1
        count = span[:, 0] * span[:, 1]
        if nb == 1 or count.sum() <= max(_BIN_ENTRIES, 16 * len(uv_tri)):
            break
        nb //= 2
    tri = np.repeat(np.arange(len(uv_tri)), count)
    local = np.arange(len(tri)) - np.repeat(np.cumsum(count) - count, count)
    bi = tlo[tri, 0] + local // span[tri, 1]
    bj = tlo[tri, 1] + local % span[tri, 1]
    key = bi * nb + bj
    order = np.argsort(key, kind="stable")
    tri, key = tri[order], key[order]
    start = np.searchsorted(key, np.arange(nb * nb), "left")
    stop = np.searchsorted(key, np.arange(nb * nb), "right")
    inbox = np.all((uv_points >= lo) & (uv_points <= hi), axis=1)
    pb = np.clip(((uv_points - lo) / width).astype(np.int64), 0, nb - 1)
    pkey = pb[:, 0] * nb + pb[:, 1]
    n = np.where(inbox, stop[pkey] - start[pkey], 0)
    point = np.repeat(np.arange(len(uv_points)), n)
    offset = np.arange(len(point)) - np.repeat(np.cumsum(n) - n, n)
    return point, tri[start[pkey][point] + offset]


def _crossings(lines: np.ndarray, corners: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Where lines along ``axis`` through (u, v) = ``lines`` (k, 2) cross the triangles ``corners`` (m, 3, 3):
    (the line of each crossing, its coordinate along the axis)."""
    u, v = [a for a in range(3) if a != axis]
    uv = corners[:, :, [u, v]]
    p, t = _pairs(lines, uv)
    rel = uv[t] - lines[p][:, None, :]  # (pairs, 3, 2): the corners as seen from the line
    nxt = rel[:, [1, 2, 0]]
    w = rel[:, :, 0] * nxt[:, :, 1] - rel[:, :, 1] * nxt[:, :, 0]  # (pairs, 3): edge functions
    hit = np.all(w > 0, axis=1) | np.all(w < 0, axis=1)
    p, t, w = p[hit], t[hit], w[hit]
    # the crossing's coordinate: the corners' weighted by the edge function opposite each
    depth = (w[:, [1, 2, 0]] * corners[t][:, :, axis]).sum(axis=1) / w.sum(axis=1)
    return p, depth


def _odd_crossings(points: np.ndarray, corners: np.ndarray, axis: int, jitter: np.ndarray) -> np.ndarray:
    """(k,) bool: the ray from each point along +axis (started ``jitter`` (2,) off it) crosses the
    triangles ``corners`` (m, 3, 3) an odd number of times."""
    p, depth = _crossings(points[:, [a for a in range(3) if a != axis]] + jitter, corners, axis)
    ahead = depth > points[p, axis]
    return (np.bincount(p[ahead], minlength=len(points)) % 2) == 1


def _grid_odd_crossings(centres: list, corners: np.ndarray, axis: int, jitter: np.ndarray) -> np.ndarray:
    """(nx, ny, nz) bool: as :func:`_odd_crossings` for the grid of points ``centres`` (3 arrays of
    coordinates), one line a column of the grid: the crossings ahead of a point are counted from
    the column's crossings sorted into the points' intervals."""
    u, v = [a for a in range(3) if a != axis]
    U, V = np.meshgrid(centres[u], centres[v], indexing="ij")
    p, depth = _crossings(np.column_stack([U.ravel(), V.ravel()]) + jitter, corners, axis)
    n = len(centres[axis])
    slot = np.searchsorted(centres[axis], depth, side="left")  # crossings ahead of points 0 .. slot - 1
    count = np.zeros((U.size, n + 1), np.int64)
    np.add.at(count, (p, slot), 1)
    ahead = np.cumsum(count[:, ::-1], axis=1)[:, ::-1][:, 1:]  # (columns, n): crossings beyond each point
    odd = (ahead % 2 == 1).reshape(len(centres[u]), len(centres[v]), n)
    return np.moveaxis(odd, 2, axis)


def inside_surface(surface: TriangleSurface, points) -> np.ndarray:
    """(k,) bool: which of the points (k, 3) lie inside the closed surface (ray parity along x, y
    and z, by majority; see the module's notes). Points within about 1e-9 of the surface's size
    of the surface may go either way."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    corners = surface.vertices[surface.faces]
    diag = float(np.linalg.norm(np.ptp(surface.vertices, axis=0))) or 1.0
    out = np.zeros(len(points), bool)
    for s in range(0, len(points), _CHUNK):
        chunk = points[s : s + _CHUNK]
        votes = np.zeros(len(chunk), np.int64)
        for axis in range(3):
            votes += _odd_crossings(chunk, corners, axis, _JITTER * diag * _OFFSETS[axis])
        out[s : s + _CHUNK] = votes >= 2
    return out


def _grid_inside(surface: TriangleSurface, centres: list) -> np.ndarray:
    """(nx, ny, nz) bool: :func:`inside_surface` of the grid of points ``centres`` (3 coordinate arrays)."""
    corners = surface.vertices[surface.faces]
    diag = float(np.linalg.norm(np.ptp(surface.vertices, axis=0))) or 1.0
    votes = np.zeros(tuple(len(c) for c in centres), np.int64)
    for axis in range(3):
        votes += _grid_odd_crossings(centres, corners, axis, _JITTER * diag * _OFFSETS[axis])
    return votes >= 2


def _grid(surface: TriangleSurface, size: float) -> tuple[np.ndarray, tuple[int, int, int]]:
    """The grid's lower corner (3,) and cells per axis: the bounding box covered, centred on it."""
    lo, hi = surface.vertices.min(axis=0), surface.vertices.max(axis=0)
    # a box a whole number of sizes long stays that many cells, also when the file rounded it (float32 STL)
    n = np.maximum(np.ceil((hi - lo) / size * (1.0 - _ROUNDING)).astype(np.int64), 1)
    origin = 0.5 * (lo + hi) - 0.5 * n * size
    return origin, (int(n[0]), int(n[1]), int(n[2]))


def _largest_piece(keep: np.ndarray) -> np.ndarray:
    """The largest face-connected piece (scipy.ndimage.label's default: 6 neighbours) of a 3D bool grid."""
    label, n = ndimage.label(keep)
    if n <= 1:
        return keep
    return label == 1 + int(np.argmax(np.bincount(label.ravel())[1:]))


def voxelize(surface: TriangleSurface, size: float, what: str = "the envelope") -> Mesh:
    """The hex8 mesh of the cubes of edge ``size`` whose centres lie inside a closed surface.

    The grid of cubes covers the surface's bounding box (centred on it). When the kept cubes form
    several face-connected pieces only the largest is kept (a loose piece would float: the others
    are said in a warning). Returns a Mesh with points (n, 3), cells (m, 8) and the facet and node
    sets of the module's notes; MeshError when no cube's centre lies inside.
    """
    VoxelOptions(size=size)
    origin, (nx, ny, nz) = _grid(surface, size)
    check_mesh_size(int(abs(surface.volume) / size**3), f"the voxels of {what} at size {size:g}", "use a larger size")
    centres = [origin[a] + size * (np.arange(n) + 0.5) for a, n in enumerate((nx, ny, nz))]
    keep = _grid_inside(surface, centres)
    if not keep.any():
        raise MeshError(f"{what}: no voxel of size {size:g} has its centre inside; use a smaller size")
    piece = _largest_piece(keep)
    if (dropped := int(keep.sum() - piece.sum())) > 0:
        log.warning(
            "%s at size %g: %d of %d voxels are loose pieces (not face-connected to the rest) and are dropped; "
            "a smaller size keeps thin parts",
            what,
            size,
            dropped,
            int(keep.sum()),
        )
    i, j, k = np.nonzero(piece)
    node = lambda a, b, c: (a * (ny + 1) + b) * (nz + 1) + c  # noqa: E731 (the grid's node numbering)
    corners = ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1))  # VTK's
    cells = np.stack([node(i + a, j + b, k + c) for a, b, c in corners], axis=1)
    used, cells = np.unique(cells, return_inverse=True)
    cells = cells.reshape(-1, 8)
    a, rest = np.divmod(used, (ny + 1) * (nz + 1))
    b, c = np.divmod(rest, nz + 1)
    points = origin + size * np.stack([a, b, c], axis=1).astype(np.float64)
    return Mesh(points, cells, *_sets(cells, piece))


def _sets(cells: np.ndarray, piece: np.ndarray) -> tuple[dict, dict]:
    """Node and facet sets: ``boundary``, the bounding-box sides ``xmin`` .. ``zmax`` and ``all``.

    cells : (m, 8) the kept cubes, in the order of ``np.nonzero(piece)``; piece : (nx, ny, nz) bool.
    A cube's face is on the boundary where its neighbour across it is not kept (read off the grid).
    """
    index = np.full(piece.shape, -1, np.int64)
    index[piece] = np.arange(len(cells))
    padded = np.pad(piece, 1)
    rows, sides = [], {}
    for name, face in _SIDE_FACES.items():
        axis, step = "xyz".index(name[0]), 1 if name.endswith("max") else -1
        neighbour = np.roll(padded, -step, axis=axis)[1:-1, 1:-1, 1:-1]
        open_ = piece & ~neighbour
        cube = index[open_]
        rows.append(np.column_stack([cube, np.full(len(cube), face)]))
        ijk = np.column_stack(np.nonzero(open_))[:, axis]
        plane = np.nonzero(piece.any(axis=tuple(a for a in range(3) if a != axis)))[0][[0, -1][step > 0]]
        sides[name] = rows[-1][ijk == plane]
    facets = np.concatenate(rows)
    facet_sets = {"boundary": facets[np.lexsort((facets[:, 1], facets[:, 0]))]}
    for name, f in sides.items():
        facet_sets[name] = f[np.argsort(f[:, 0], kind="stable")]
    node_sets = {"all": np.arange(int(cells.max()) + 1, dtype=np.int64)}
    for name, f in facet_sets.items():
        node_sets[name] = np.unique(cells[f[:, 0][:, None], HEX_FACES[f[:, 1]]])
    return node_sets, facet_sets


def mesh_envelope(path, size: float, *, scale: float = 1.0) -> Mesh:
    """The hex8 voxel mesh of the closed surface in a file (:func:`read_envelope`, :func:`voxelize`).

    Parameters
    ----------
    path : ``.stl``, ``.ply``, ``.obj`` (a closed triangle surface) or ``.step``/``.stp``,
        ``.iges``/``.igs``, ``.brep`` (one solid, triangulated by Gmsh)
    size : the cubes' edge (scaled unit); scale : the file's coordinates are multiplied by it
    """
    options = VoxelOptions(size=size, scale=scale)
    surface = read_envelope(path, options.scale, options.size)
    return voxelize(surface, options.size, str(path))
