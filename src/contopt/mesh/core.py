"""The frozen ``Mesh`` (hex8, tet4 or tet10 cells) with named node and facet sets.

Node ordering of a cell follows VTK / Gmsh (``VTK_HEXAHEDRON``): nodes 0-3 are
the bottom face counter-clockwise seen from above (outside is below), nodes
4-7 the top face above them, so that for the unit cube

    0 (0,0,0)  1 (1,0,0)  2 (1,1,0)  3 (0,1,0)
    4 (0,0,1)  5 (1,0,1)  6 (1,1,1)  7 (0,1,1)

and the reference coordinates are ``xi = 2*X - 1``.

A facet is a boundary face given by ``(cell, local_face)``; local faces are
listed in :data:`HEX_FACES` with nodes ordered so that the right-hand rule
gives the *outward* normal.

Tetrahedra follow VTK too: tet4 nodes 0-3 with ``(x1-x0) x (x2-x0) . (x3-x0) > 0``; tet10 adds
the edge midpoints 4-9 on edges (0,1), (1,2), (0,2), (0,3), (1,3), (2,3) (``VTK_QUADRATIC_TETRA``;
Gmsh swaps 8 and 9, meshio and :mod:`contopt.mesh.cad` reorder). Their faces, :data:`TET_FACES`,
are triangles (tri3 / tri6), in Exodus side order. A mesh's element type follows from its cells'
width (8, 4 or 10 nodes): :attr:`Mesh.element`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from contopt.config import address_space_left, address_space_limit
from contopt.errors import MeshError

#: Local node indices of the six faces of a hex8, ordered for outward normals.
#: Face k is the face where reference coordinate ``HEX_FACE_AXIS[k]`` equals
#: ``HEX_FACE_SIDE[k]`` (+1 or -1).
HEX_FACES = np.array(
    [
        [0, 3, 2, 1],  # zeta = -1
        [4, 5, 6, 7],  # zeta = +1
        [0, 1, 5, 4],  # eta  = -1
        [1, 2, 6, 5],  # xi   = +1
        [2, 3, 7, 6],  # eta  = +1
        [3, 0, 4, 7],  # xi   = -1
    ],
    dtype=np.int64,
)
HEX_FACE_AXIS = np.array([2, 2, 1, 0, 1, 0], dtype=np.int64)
HEX_FACE_SIDE = np.array([-1, 1, -1, 1, 1, -1], dtype=np.int64)
#: Local node indices of the four faces of a tet10 (tri6: corners, then the midpoints of edges
#: (a,b), (b,c), (c,a)), ordered for outward normals, in Exodus side order; the first three
#: columns are the tet4 faces. Face k lies opposite node ``TET_FACE_OPPOSITE[k]``.
TET_FACES = np.array(
    [
        [0, 1, 3, 4, 8, 7],  # eta  = 0
        [1, 2, 3, 5, 9, 8],  # xi + eta + zeta = 1
        [0, 3, 2, 7, 9, 6],  # xi   = 0
        [0, 2, 1, 6, 5, 4],  # zeta = 0
    ],
    dtype=np.int64,
)
TET_FACE_OPPOSITE = np.array([2, 0, 1, 3], dtype=np.int64)
#: element type -> nodes a cell; nodes a face; the faces' local node table
ELEMENTS = {"hex8": (8, 4, HEX_FACES), "tet4": (4, 3, TET_FACES[:, :3]), "tet10": (10, 6, TET_FACES)}
_ELEMENT_OF_WIDTH = {v[0]: k for k, v in ELEMENTS.items()}
HEX_FACES.setflags(write=False)
TET_FACES.setflags(write=False)
TET_FACE_OPPOSITE.setflags(write=False)
HEX_FACE_AXIS.setflags(write=False)
HEX_FACE_SIDE.setflags(write=False)


#: a lower bound of the memory an analysis needs per hex8 cell, in bytes: geometry at the Gauss
#: points, the dof map, the tangent's sparsity pattern and scatter map (building the discretization
#: alone peaked at about 41 kB a cell on 1k-14k-cell boxes; Newton and the factorization need more)
ANALYSIS_BYTES_PER_CELL = 16 * 1024
#: the limit when the machine's memory cannot be read (256 TiB)
_UNKNOWN_MEMORY_LIMIT = 2**48


def available_memory() -> int | None:
    """Bytes of memory this process may use: the physical memory, or a smaller cgroup limit; None if unknown."""
    sizes = []
    try:
        sizes.append(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        pass
    try:
        text = open("/sys/fs/cgroup/memory.max").read().strip()
        if text.isdigit():
            sizes.append(int(text))
    except OSError:
        pass
    sizes = [n for n in sizes if n > 0]
    return min(sizes) if sizes else None


def format_bytes(n: float) -> str:
    """``512 B``, ``1.5 GiB``, ``14.2 EiB``."""
    units = ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB")
    k = 0
    while n >= 1024 and k < len(units) - 1:
        n, k = n / 1024, k + 1
    return f"{int(n)} B" if k == 0 else f"{n:.3g} {units[k]}"


def check_mesh_size(n_cells: int, what: str, advice: str = "use fewer cells") -> None:
    """MeshError when an analysis of ``n_cells`` hex8 cells would need more memory than this machine
    has, or than the process's address-space limit (``ulimit -v``) leaves (a lower bound,
    :data:`ANALYSIS_BYTES_PER_CELL` a cell): called before anything is allocated."""
    need = float(n_cells) * ANALYSIS_BYTES_PER_CELL
    have = available_memory()
    limit = have if have is not None else _UNKNOWN_MEMORY_LIMIT
    machine = f"this machine has {format_bytes(have)}" if have is not None else "more than any machine has"
    space = address_space_left()
    if space is not None and space < limit:
        total = address_space_limit()
        limit, machine = (
            space,
            f"the address-space limit (ulimit -v) of {format_bytes(total or 0)} leaves {format_bytes(space)}",
        )
        advice = f"{advice}, or raise the limit"
    if need > limit:
        raise MeshError(
            f"{what} would have {float(n_cells):.3g} cells; an analysis of it needs at least "
            f"{format_bytes(need)} of memory and {machine}: {advice}"
        )


def element_of(cells) -> str:
    """``"hex8"``, ``"tet4"`` or ``"tet10"`` from the width of (m, n) cells; MeshError otherwise."""
    shape = np.shape(cells)
    if len(shape) != 2 or shape[1] not in _ELEMENT_OF_WIDTH:
        raise MeshError(f"cells must have shape (m, 8) (hex8), (m, 4) (tet4) or (m, 10) (tet10), got {tuple(shape)}")
    return _ELEMENT_OF_WIDTH[shape[1]]


def face_table(element: str) -> np.ndarray:
    """(faces, nodes a face) local node indices of an element type's faces, outward ordering."""
    return ELEMENTS[element][2]


def _frozen(a, dtype) -> np.ndarray:
    out = np.array(a, dtype=dtype, copy=True)
    out.setflags(write=False)
    return out


def _indices(value, what: str) -> np.ndarray:
    """``value`` as an integer array; MeshError for floats or booleans (never silently truncated)."""
    arr = np.asarray(value)
    if arr.size and arr.dtype == bool:
        raise MeshError(f"{what} must be integer indices, got a boolean array; pass np.flatnonzero(mask)")
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise MeshError(
            f"{what} must be integer indices, got {arr.dtype} values (first {arr.ravel()[0].item()!r}); "
            "convert whole numbers explicitly, e.g. np.asarray(values, dtype=np.int64)"
        )
    return arr


def _frozen_sets(sets, dtype, width) -> Mapping[str, np.ndarray]:
    out = {}
    for name, value in dict(sets or {}).items():
        kind = "node set" if width is None else "facet set"
        arr = _frozen(_indices(value, f"{kind} {str(name)!r}"), dtype)
        if width is None:
            arr = _frozen(arr.reshape(-1), dtype)
        elif arr.size == 0:
            arr = _frozen(np.zeros((0, width)), dtype)
        elif arr.ndim != 2 or arr.shape[1] != width:
            raise MeshError(f"facet set {name!r} must have shape (k, 2) = (cell, local face), got {arr.shape}")
        out[str(name)] = arr
    return MappingProxyType(out)


@dataclass(frozen=True, eq=False)
class Mesh:
    """A mesh of one body: hex8, tet4 or tet10 cells (one type a mesh).

    Attributes
    ----------
    points : (n_nodes, 3) float64 reference coordinates
    cells : (n_cells, 8) int64 node indices, VTK hexahedron ordering; or (n_cells, 4) tet4 /
        (n_cells, 10) tet10, VTK ordering (the element type follows from the width: :attr:`element`)
    node_sets : name -> (k,) int64 node indices
    facet_sets : name -> (k, 2) int64 rows ``(cell, local_face)``, boundary faces only (local faces
        0-5 of :data:`HEX_FACES`, 0-3 of :data:`TET_FACES`)

    Construction checks shapes, integer indices (float or boolean ones are refused, never
    truncated; float32 points are converted to float64), index ranges, positive element volumes
    (an inverted or degenerate cell raises :class:`MeshError` naming it) and
    that every facet set lies on the boundary. Arrays are read-only; methods
    that change the mesh return a new ``Mesh``.
    """

    points: np.ndarray
    cells: np.ndarray
    node_sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    facet_sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    check: bool = field(default=True, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "points", _frozen(self.points, np.float64))
        object.__setattr__(self, "cells", _frozen(_indices(self.cells, "cells"), np.int64))
        object.__setattr__(self, "node_sets", _frozen_sets(self.node_sets, np.int64, None))
        object.__setattr__(self, "facet_sets", _frozen_sets(self.facet_sets, np.int64, 2))
        if self.points.ndim != 2 or self.points.shape[1] != 3:
            raise MeshError(f"points must have shape (n, 3), got {self.points.shape}")
        element_of(self.cells)
        if self.check:
            validate(self)

    # ------------------------------------------------------------------ sizes
    @property
    def n_nodes(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_cells(self) -> int:
        return int(self.cells.shape[0])

    @property
    def element(self) -> str:
        """The element type: ``"hex8"``, ``"tet4"`` or ``"tet10"``."""
        return element_of(self.cells)

    @property
    def is_tet(self) -> bool:
        return self.element != "hex8"

    # ------------------------------------------------------------- named sets
    def node_set(self, name: str) -> np.ndarray:
        """Node indices of a named node set, or of the nodes of a facet set."""
        if name in self.node_sets:
            return self.node_sets[name]
        if name in self.facet_sets:
            return np.unique(self.facet_nodes(name).ravel())
        raise MeshError(
            f"unknown node set {name!r}; this mesh has node sets {sorted(self.node_sets)} "
            f"and facet sets {sorted(self.facet_sets)}"
        )

    def facet_set(self, name: str) -> np.ndarray:
        """(k, 2) rows ``(cell, local_face)`` of a named facet set."""
        if name not in self.facet_sets:
            raise MeshError(f"unknown facet set {name!r}; this mesh has facet sets {sorted(self.facet_sets)}")
        return self.facet_sets[name]

    def facet_nodes(self, name_or_facets) -> np.ndarray:
        """(k, 4) node indices of facets (outward-normal ordering); (k, 3) tri3 / (k, 6) tri6 of tets."""
        facets = self.facet_set(name_or_facets) if isinstance(name_or_facets, str) else np.asarray(name_or_facets)
        return self.cells[facets[:, 0][:, None], face_table(self.element)[facets[:, 1]]]

    def with_sets(self, node_sets=None, facet_sets=None) -> Mesh:
        """A new mesh with extra (or replaced) named sets."""
        ns = dict(self.node_sets)
        ns.update(node_sets or {})
        fs = dict(self.facet_sets)
        fs.update(facet_sets or {})
        return Mesh(self.points, self.cells, ns, fs)

    def transformed(self, rotation=None, translation=None) -> Mesh:
        """A rigidly moved copy: ``x -> R x + t`` (sets kept)."""
        R = np.eye(3) if rotation is None else np.asarray(rotation, float)
        t = np.zeros(3) if translation is None else np.asarray(translation, float)
        return Mesh(self.points @ R.T + t, self.cells, self.node_sets, self.facet_sets)

    def boundary_facets(self) -> np.ndarray:
        """(k, 2) all boundary faces ``(cell, local_face)``, sorted."""
        return boundary_facets(self.cells)

    def __reduce__(self):
        """Pickled as its arrays and sets (a process pool sends models to its workers), not checked again."""
        return (Mesh, (self.points, self.cells, dict(self.node_sets), dict(self.facet_sets), False))

    def __repr__(self) -> str:
        return (
            f"Mesh(n_nodes={self.n_nodes}, n_cells={self.n_cells}, "
            + ("" if self.element == "hex8" else f"element={self.element!r}, ")
            + f"node_sets={sorted(self.node_sets)}, facet_sets={sorted(self.facet_sets)})"
        )


# ---------------------------------------------------------------------------
def boundary_facets(cells: np.ndarray) -> np.ndarray:
    """(k, 2) rows ``(cell, local_face)`` of faces that belong to one cell only (any element type)."""
    cells = np.asarray(cells, dtype=np.int64)
    m = cells.shape[0]
    table = HEX_FACES if cells.shape[1] == 8 else TET_FACES[:, :3]  # a tet face is known by its corners
    nf, width = table.shape
    faces = cells[:, table].reshape(-1, width)
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    on_boundary = counts[inverse.reshape(-1)] == 1
    idx = np.nonzero(on_boundary)[0]
    return np.stack([idx // nf, idx % nf], axis=1) if m else np.zeros((0, 2), np.int64)


_CORNER_NEIGHBOURS = np.array([[1, 3, 4], [2, 0, 5], [3, 1, 6], [0, 2, 7], [7, 5, 0], [4, 6, 1], [5, 7, 2], [6, 4, 3]])


def _corner_edges(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m, 8, 3, 3) edge vectors leaving each corner, ordered so that their
    determinant is positive for a right-handed (VTK-ordered) cell."""
    x = np.asarray(points, dtype=np.float64)[np.asarray(cells)]  # (m, 8, 3)
    return x[:, _CORNER_NEIGHBOURS, :] - x[:, :, None, :]


def cell_jacobian_dets(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m, 8) det(dX/dxi) of each cell at its 8 corner nodes (sign and degeneracy check).

    For a trilinear hex a positive Jacobian at the 8 corners is the standard
    practical validity test. The value is the determinant of the three edge
    vectors leaving the corner, i.e. 8 times det(dX/dxi) there.
    """
    return np.linalg.det(_corner_edges(points, cells))


def scaled_jacobian(mesh_or_points, cells=None) -> np.ndarray:
    """(m,) scaled Jacobian of each hex8: the minimum over its 8 corners of
    ``det(e1, e2, e3) / (|e1| |e2| |e3|)`` with ``e*`` the corner's edges.

    1 for a rectangular box, <= 0 for an inverted or degenerate cell; the
    usual acceptance threshold is about 0.2-0.3. Accepts a :class:`Mesh` or
    ``(points (n, 3), cells (m, 8))``.
    """
    if cells is None:
        points, cells = mesh_or_points.points, mesh_or_points.cells
    else:
        points = mesh_or_points
    e = _corner_edges(points, cells)
    lengths = np.linalg.norm(e, axis=-1).prod(axis=-1)  # (m, 8)
    dets = np.linalg.det(e)
    with np.errstate(divide="ignore", invalid="ignore"):
        sj = np.where(lengths > 0, dets / np.where(lengths > 0, lengths, 1.0), 0.0)
    return sj.min(axis=1) if len(sj) else np.zeros(0)


def validate(mesh: Mesh, rel_tol: float = 1e-12) -> None:
    """Raise :class:`MeshError` naming the first problem found.

    A cell is rejected when a corner Jacobian is ``<= rel_tol`` times the
    product of that corner's three edge lengths (i.e. its scaled Jacobian is
    not positive), so the test does not depend on the cell's size.
    """
    pts, cells = mesh.points, mesh.cells
    if not np.all(np.isfinite(pts)):
        bad = int(np.nonzero(~np.all(np.isfinite(pts), axis=1))[0][0])
        raise MeshError(f"node {bad} has a non-finite coordinate {pts[bad]}")
    if cells.size and (cells.min() < 0 or cells.max() >= len(pts)):
        bad = int(np.nonzero((cells < 0).any(1) | (cells >= len(pts)).any(1))[0][0])
        raise MeshError(f"cell {bad} refers to a node outside 0..{len(pts) - 1}: {cells[bad].tolist()}")
    if cells.size and cells.shape[1] != 8:
        _validate_tets(pts, cells, rel_tol)
    elif cells.size:
        dup = (np.diff(np.sort(cells, axis=1), axis=1) == 0).any(axis=1)
        if dup.any():
            bad = int(np.nonzero(dup)[0][0])
            raise MeshError(f"cell {bad} is degenerate: repeated nodes {cells[bad].tolist()}")
        e = _corner_edges(pts, cells)
        dets = np.linalg.det(e)
        # Relative to each corner's own edge lengths, not to the bounding box:
        # a tiny but well-shaped cell in a graded mesh is valid, a collapsed
        # cell of any size is not.
        lengths = np.linalg.norm(e, axis=-1).prod(axis=-1)
        tol = rel_tol * lengths
        if (dets <= tol).any():
            bad = int(np.nonzero((dets <= tol).any(axis=1))[0][0])
            kind = "inverted" if (dets[bad] < -tol[bad]).all() else "inverted or degenerate"
            scaled = dets[bad] / np.where(lengths[bad] > 0, lengths[bad], 1.0)
            raise MeshError(
                f"cell {bad} is {kind} (scaled corner Jacobians {np.round(scaled, 3).tolist()}); "
                "check its node ordering (VTK hexahedron: bottom face 0-1-2-3 counter-clockwise "
                "seen from the top face 4-5-6-7) and its geometry"
            )
    for name, nodes in mesh.node_sets.items():
        if nodes.size and (nodes.min() < 0 or nodes.max() >= len(pts)):
            raise MeshError(f"node set {name!r} refers to nodes outside 0..{len(pts) - 1}")
    if mesh.facet_sets:
        bnd = boundary_facets(cells)
        nf = 6 if cells.shape[1] == 8 else 4
        bcode = bnd[:, 0] * 6 + bnd[:, 1]
        for name, facets in mesh.facet_sets.items():
            if facets.size == 0:
                continue
            if (
                facets[:, 0].min() < 0
                or facets[:, 0].max() >= len(cells)
                or facets[:, 1].min() < 0
                or facets[:, 1].max() >= nf
            ):
                raise MeshError(
                    f"facet set {name!r} has a row outside cells 0..{len(cells) - 1} / local faces 0..{nf - 1}"
                )
            off = facets[~np.isin(facets[:, 0] * 6 + facets[:, 1], bcode)]
            if len(off):
                raise MeshError(
                    f"facet set {name!r} is not on the boundary: {len(off)} of its {len(facets)} "
                    f"faces are shared by two cells (first: cell {off[0, 0]}, local face {off[0, 1]})"
                )


def tet_volumes(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(m,) signed volumes of the corner tetrahedra (nodes 0-3) of tet4 / tet10 cells."""
    x = np.asarray(points, dtype=np.float64)[np.asarray(cells)[:, :4]]
    e = x[:, 1:] - x[:, :1]
    return np.linalg.det(e) / 6.0


def _validate_tets(pts: np.ndarray, cells: np.ndarray, rel_tol: float) -> None:
    """MeshError naming the first tet with repeated nodes or a non-positive corner volume."""
    dup = (np.diff(np.sort(cells, axis=1), axis=1) == 0).any(axis=1)
    if dup.any():
        bad = int(np.nonzero(dup)[0][0])
        raise MeshError(f"cell {bad} is degenerate: repeated nodes {cells[bad].tolist()}")
    x = pts[cells[:, :4]]
    e = x[:, 1:] - x[:, :1]
    dets = np.linalg.det(e)
    lengths = np.linalg.norm(e, axis=-1).prod(axis=-1)
    bad = np.nonzero(dets <= rel_tol * lengths)[0]
    if bad.size:
        c = int(bad[0])
        raise MeshError(
            f"tetrahedron {c} is inverted or degenerate (6 x volume {dets[c]:.3g}); check its node "
            "ordering (VTK tetra: (x1-x0) x (x2-x0) . (x3-x0) > 0) and its geometry"
        )
