"""Read and write hex8, tet4 and tet10 meshes with their named sets, through meshio.

Tetrahedra: a file holds one element type. Gmsh's ``tetra`` / ``tetra10`` cells (meshio puts
tetra10 into VTK's node order) are read as tet4 / tet10 bodies, and ``triangle`` (tet4) or
``triangle6`` / ``triangle`` (tet10) physical groups as facet sets, matched to the tets' boundary
faces by their corners, exactly as quads are to hex faces below; VTU the same with ``tetra`` /
``tetra10`` and triangle cells; Exodus with ``TETRA`` / ``TETRA10`` blocks and side sets (sides 1-4
are :data:`~contopt.mesh.core.TET_FACES` in order).

Formats (chosen by the file suffix)
-----------------------------------
``.msh``  Gmsh, versions 4.1 and 2.2, ASCII or binary.
    Reading: the hexahedra are the body. A physical group of dimension 2
    (4-node quads) becomes a facet set: each quad is matched to the boundary
    face of a hex with the same four nodes, whatever the quad's orientation;
    by default it also becomes a node set of the same name. Physical groups of
    dimension 0 and 1 become node sets. Physical groups of dimension 3 are
    bodies: ``read_mesh(path, body=NAME)`` keeps the hexes of one of them and
    ``read_bodies(path)`` splits the file into one mesh per body (nodes
    renumbered in both cases). An unnamed physical group is named by its
    number, e.g. ``"7"``.
    Writing: the hexes form the 3D physical group ``body_name`` ("body"),
    each facet set a 2D physical group of quads (outward ordering), each node
    set a 0D physical group of point elements. A node set whose name is also
    a facet set name and which holds exactly that facet set's nodes is not
    written separately (reading recreates it). Version 4.1 is written with one
    extra, unused node per written set, which meshio needs to give every set
    its own geometric entity; reading drops nodes used by no hexahedron, so a
    round trip gives back the same points, cells and sets.
``.vtu``  VTK XML unstructured grid.
    Writing: the hexahedra first, then the union of all facet sets as quad
    cells (outward ordering). Each facet set ``NAME`` is an int32 cell-data
    array ``facetset:NAME`` (1 on the quads of the set, 0 elsewhere); each
    node set ``NAME`` an int32 point-data array ``nodeset:NAME`` (1 on its
    nodes). Reading applies the same scheme to any VTU file: arrays with other
    names, and quads outside every ``facetset:`` array, are ignored, so a file
    that holds only hexahedra reads as a mesh without sets. Write binary
    (the default): meshio's ASCII VTU keeps only 12 significant digits.
``.e``, ``.exo``, ``.ex2``  Exodus II (needs the optional ``netCDF4`` package).
    Element blocks of hexahedra are bodies (named by ``eb_names``, else
    ``block_<id>``), node sets are node sets (``ns_names``, else
    ``nodeset_<id>``) and side sets are facet sets (``ss_names``, else
    ``sideset_<id>``). meshio reads and writes the nodes, blocks and node
    sets but knows no side sets nor block names; those are read and appended
    here with netCDF4 directly.

Every reader raises :class:`~contopt.errors.MeshError` for an unsupported
suffix, a file without hexahedra or tetrahedra, other 3D cells (wedges,
pyramids), two element types in one file, a facet group with cells other than
the faces of its cells (quads of hexes, triangles of tets), or a face of a
named group that is not a boundary face of any cell (the group is named).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from contopt.errors import MeshError
from contopt.mesh.core import HEX_FACES, TET_FACES, Mesh, boundary_facets, check_mesh_size
from contopt.mesh.formats import (
    Raw,
    read_exodus,
    read_gmsh,
    read_vtu,
    write_exodus,
    write_gmsh,
    write_vtu,
)
from contopt.mesh.headers import declared_cells

__all__ = ["SUPPORTED_SUFFIXES", "mesh_of_raw", "read_bodies", "read_mesh", "write_mesh"]

log = logging.getLogger(__name__)

SUPPORTED_SUFFIXES = {
    ".msh": "gmsh",
    ".vtu": "vtu",
    ".e": "exodus",
    ".exo": "exodus",
    ".ex2": "exodus",
}


_GMSH_FORMATS = {"gmsh": "4.1", "gmsh41": "4.1", "gmsh22": "2.2"}


def _format_of(path: Path) -> str:
    fmt = SUPPORTED_SUFFIXES.get(path.suffix.lower())
    if fmt is None:
        raise MeshError(
            f"unsupported mesh file type {path.suffix!r} ({path}); supported suffixes: {sorted(SUPPORTED_SUFFIXES)}"
        )
    return fmt


def _row_lookup(table: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """(q,) index of each row of ``queries`` in ``table`` (unique rows), or -1."""
    if len(queries) == 0:
        return np.zeros(0, np.int64)
    if len(table) == 0:
        return np.full(len(queries), -1, np.int64)
    both = np.concatenate([table, queries], axis=0)
    _, inverse = np.unique(both, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    position = np.full(int(np.max(inverse)) + 1, -1, np.int64)
    position[inverse[: len(table)]] = np.arange(len(table))
    return position[inverse[len(table) :]]


def _boundary_keys(cells: np.ndarray):
    """Boundary facets (k, 2) of ``cells`` and their sorted node keys (k, 4): hex8; (k, 3): the corners of tets."""
    bnd = boundary_facets(cells)
    table = HEX_FACES if cells.shape[1] == 8 else TET_FACES[:, :3]
    keys = np.sort(cells[bnd[:, 0][:, None], table[bnd[:, 1]]], axis=1)
    return bnd, keys


def _check_hexes(raw: Raw, hexes: np.ndarray, sel: np.ndarray) -> None:
    """Blame a broken hexahedron on itself (before its faces make a facet group look wrong).

    hexes : (m, 8) the selected hexes in file node numbering; sel : (m,) their indices in the file
    """
    bad = (hexes < 0) | (hexes >= len(raw.points))
    if bad.any():
        k = int(np.nonzero(bad.any(axis=1))[0][0])
        raise MeshError(
            f"{raw.path}: cell {int(sel[k])} (0-based in file order) refers to a node outside "
            f"0..{len(raw.points) - 1}: {hexes[k].tolist()}"
        )
    repeated = (np.diff(np.sort(hexes, axis=1), axis=1) == 0).any(axis=1)
    if repeated.any():
        k = int(np.nonzero(repeated)[0][0])
        what = "hexahedron" if hexes.shape[1] == 8 else "tetrahedron"
        raise MeshError(
            f"{raw.path}: {what} {int(sel[k])} (0-based in file order) is degenerate: repeated "
            f"nodes {hexes[k].tolist()} (0-based file numbering; {int(repeated.sum())} such cells); "
            f"a cell needs {hexes.shape[1]} distinct nodes: remesh (collapsed hexes, e.g. wedges, are not supported)"
        )


# ----------------------------------------------------------------- assembling
def _assemble(raw: Raw, body: str | None, facet_node_sets: bool, body_keys=None) -> Mesh:
    """The Mesh of all hexes (``body=None``) or of one body of ``raw``."""
    if body is None:
        sel = np.arange(len(raw.cells))
    else:
        if body not in raw.bodies:
            raise MeshError(
                f"{raw.path}: no body {body!r}; bodies (3D physical groups / element "
                f"blocks) in the file: {sorted(raw.bodies)}"
            )
        sel = raw.bodies[body]
        if len(sel) == 0:
            raise MeshError(f"{raw.path}: body {body!r} has no cells")
    hexes = raw.cells[sel]
    _check_hexes(raw, hexes, sel)
    used = np.unique(hexes)  # sorted: keeps the file's node order
    new_index = np.full(len(raw.points), -1, np.int64)
    new_index[used] = np.arange(len(used))
    points = raw.points[used]
    cells = new_index[hexes]
    bnd, bkeys = _boundary_keys(cells)

    facet_sets: dict[str, np.ndarray] = {}
    for name, quads in raw.quad_groups.items():
        if len(quads) == 0:
            facet_sets[name] = np.zeros((0, 2), np.int64)
            continue
        if quads.shape[1] != bkeys.shape[1]:
            kind = {4: "quads", 3: "triangles"}[quads.shape[1]]
            raise MeshError(
                f"{raw.path}: facet group {name!r} holds {kind}, which are not faces of the file's "
                f"{'hexahedra' if cells.shape[1] == 8 else 'tetrahedra'}"
            )
        q = new_index[quads]
        keys = np.sort(q, axis=1)
        pos = _row_lookup(bkeys, keys)
        pos[(q < 0).any(axis=1)] = -1
        ok = pos >= 0
        if not ok.all():
            bad = quads[~ok]
            if body is not None:
                # quads on the boundary of another body belong to that body
                elsewhere = _row_lookup(body_keys, np.sort(bad, axis=1)) >= 0
                bad = bad[~elsewhere]
            if len(bad):
                raise MeshError(
                    f"{raw.path}: facet group {name!r}: {len(bad)} of its {len(quads)} quads "
                    f"are not boundary faces of any hexahedron (first: the quad of nodes "
                    f"{bad[0].tolist()}, 0-based in file order); interior faces cannot be facets. "
                    "If the file holds several bodies that share nodes, read them with "
                    "read_bodies() or read_mesh(..., body=NAME)"
                )
            if not ok.any():
                log.debug("%s: facet group %r is not on body %r, skipped", raw.path, name, body)
                continue
        facets = bnd[pos[ok]]
        facet_sets[name] = np.unique(facets, axis=0)

    node_sets: dict[str, np.ndarray] = {}
    for name, nodes in raw.node_groups.items():
        new = new_index[nodes]
        kept = np.unique(new[new >= 0])
        if len(kept) < len(nodes):
            if body is not None and len(kept) == 0:
                log.debug("%s: node group %r is not on body %r, skipped", raw.path, name, body)
                continue
            if body is None:
                log.warning(
                    "%s: node group %r: %d of its nodes belong to no hexahedron and are dropped",
                    raw.path,
                    name,
                    int((new < 0).sum()),
                )
        node_sets[name] = kept
    if facet_node_sets:
        for name, facets in facet_sets.items():
            if name not in node_sets:
                node_sets[name] = np.unique(Mesh(points, cells, check=False).facet_nodes(facets))
    return Mesh(points, cells, node_sets, facet_sets)


def mesh_of_raw(raw: Raw, facet_node_sets: bool = True) -> Mesh:
    """The Mesh of all hexes of a format's :class:`~contopt.mesh.formats.Raw` content (a mesher's
    output): its quad groups matched to hex faces as facet sets, as :func:`read_mesh` does."""
    return _assemble(raw, None, facet_node_sets)


def _all_body_boundary_keys(raw: Raw) -> np.ndarray:
    """Sorted node keys (in file numbering) of the boundary faces of every body."""
    keys = [_boundary_keys(raw.cells[sel])[1] for sel in raw.bodies.values() if len(sel)]
    keys.append(_boundary_keys(raw.cells)[1])
    return np.unique(np.concatenate(keys, axis=0), axis=0)


_READERS = {"gmsh": read_gmsh, "vtu": read_vtu, "exodus": read_exodus}


def _read_raw(path) -> tuple[Raw, str]:
    path = Path(path)
    fmt = _format_of(path)
    if not path.is_file():
        raise MeshError(f"mesh file {path} not found")
    declared = declared_cells(path, fmt)  # from the headers: a file too large is refused before it is read
    if declared is not None:
        check_mesh_size(declared, f"the mesh file {path} (by its header)", "use a coarser mesh")
    return _READERS[fmt](path), fmt


def read_mesh(path, body: str | None = None, *, facet_node_sets: bool | None = None) -> Mesh:
    """Read a hex8, tet4 or tet10 mesh with its named node and facet sets.

    Parameters
    ----------
    path : ``.msh`` (Gmsh 2.2/4.1), ``.vtu`` or ``.e``/``.exo``/``.ex2``
        (Exodus II); see the module docstring for how each stores the sets
    body : ``None`` for all hexahedra of the file, or the name of one body
        (Gmsh 3D physical group, Exodus element block): only its hexes are
        kept, nodes are renumbered, and only the sets that touch it are kept
        (a facet group on an interface whose nodes two bodies share is a
        boundary of both, so both bodies get it, each with its own outward
        faces)
    facet_node_sets : also give each facet set a node set of the same name
        (its nodes) unless the file has such a node set. Default: True for
        Gmsh (a Physical Surface is how a Gmsh user names boundary nodes),
        False for VTU and Exodus (their node sets are stored explicitly).

    Returns
    -------
    Mesh whose nodes are those used by its hexahedra, in file order; facet
    sets as sorted unique ``(cell, local_face)`` rows, node sets sorted.
    """
    raw, fmt = _read_raw(path)
    if facet_node_sets is None:
        facet_node_sets = fmt == "gmsh"
    body_keys = _all_body_boundary_keys(raw) if body is not None else None
    return _assemble(raw, body, facet_node_sets, body_keys)


def read_bodies(path, *, facet_node_sets: bool | None = None) -> dict[str, Mesh]:
    """Read each body of a file as its own :class:`Mesh` (nodes renumbered).

    Bodies are the Gmsh 3D physical groups or the Exodus element blocks; a
    file without any (or a VTU file) gives ``{"all": read_mesh(path)}``.
    Hexes outside every body are left out (logged). Each mesh keeps the sets
    that touch it; see :func:`read_mesh` for ``facet_node_sets``.
    """
    raw, fmt = _read_raw(path)
    if facet_node_sets is None:
        facet_node_sets = fmt == "gmsh"
    if not raw.bodies:
        return {"all": _assemble(raw, None, facet_node_sets)}
    covered = np.zeros(len(raw.cells), bool)
    for sel in raw.bodies.values():
        covered[sel] = True
    if not covered.all():
        log.warning("%s: %d hexahedra belong to no body and are left out", raw.path, int((~covered).sum()))
    keys = _all_body_boundary_keys(raw)
    return {name: _assemble(raw, name, facet_node_sets, keys) for name in raw.bodies}


def write_mesh(
    path,
    mesh: Mesh,
    *,
    file_format: str | None = None,
    binary: bool = True,
    body_name: str = "body",
) -> None:
    """Write a mesh with its named sets (see the module docstring per format).

    Parameters
    ----------
    path : ``.msh``, ``.vtu`` or ``.e``/``.exo``/``.ex2``
    mesh : the mesh
    file_format : for ``.msh`` only: ``"gmsh"`` (MSH 4.1, default) or
        ``"gmsh22"`` (MSH 2.2)
    binary : binary (default) or ASCII, for ``.msh`` and ``.vtu``
        (ASCII VTU keeps only 12 significant digits)
    body_name : name of the body (Gmsh 3D physical group, Exodus element
        block); must differ from every set name for ``.msh``
    """
    path = Path(path)
    fmt = _format_of(path)
    if file_format is not None and (fmt != "gmsh" or file_format not in _GMSH_FORMATS):
        raise MeshError(
            f"file_format={file_format!r} is not valid for {path.suffix!r}; for .msh use one of "
            f"{sorted(_GMSH_FORMATS)}; other formats take no file_format"
        )
    if fmt == "gmsh":
        write_gmsh(path, mesh, _GMSH_FORMATS[file_format or "gmsh"], binary, body_name)
    elif fmt == "vtu":
        write_vtu(path, mesh, binary)
    else:
        write_exodus(path, mesh, body_name)
