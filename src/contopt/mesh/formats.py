"""The file formats behind :mod:`contopt.mesh.io`: readers into a format-independent :class:`Raw`
content, writers of a :class:`~contopt.mesh.core.Mesh` (Gmsh, VTU, Exodus II; see
:mod:`contopt.mesh.io` for what each format holds)."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from contopt.errors import MeshError
from contopt.mesh.core import HEX_FACES, TET_FACES, Mesh

#: meshio's 3D cell types read as bodies, by element type; and the facet types each takes
VOLUME_TYPES = {"hexahedron": "hex8", "tetra": "tet4", "tetra10": "tet10"}
MESHIO_VOLUME = {v: k for k, v in VOLUME_TYPES.items()}
FACET_TYPES = {"hex8": ("quad",), "tet4": ("triangle",), "tet10": ("triangle6", "triangle")}
MESHIO_FACET = {"hex8": "quad", "tet4": "triangle", "tet10": "triangle6"}

log = logging.getLogger(__name__)

#: Prefixes of the VTU membership arrays.
VTU_FACET_PREFIX = "facetset:"


VTU_NODE_PREFIX = "nodeset:"


#: Exodus side (1-based) of each local face of HEX_FACES, and back.
_EXODUS_SIDE = np.array([5, 6, 1, 2, 3, 4], dtype=np.int64)


_FACE_OF_EXODUS_SIDE = np.argsort(_EXODUS_SIDE)  # side s (1..6) -> local face [s - 1]


# --------------------------------------------------------------------- helpers
@dataclass
class Raw:
    """Format-independent content of a file, in the file's node numbering."""

    path: str
    points: np.ndarray  # (n, 3)
    cells: np.ndarray  # (m, 8) hex8 cells; or (m, 4) tet4 / (m, 10) tet10 (VTK order), one type a file
    bodies: dict[str, np.ndarray] = field(default_factory=dict)  # name -> cell indices
    quad_groups: dict[str, np.ndarray] = field(default_factory=dict)  # name -> (q, 4) quads, (q, 3 | 6) triangles
    node_groups: dict[str, np.ndarray] = field(default_factory=dict)  # name -> node indices


def _meshio():
    import meshio

    return meshio


#: what a file of each format must be, for the message when it is not
_EXPECTED = {
    "gmsh": "a Gmsh mesh file (MSH 2.2 or 4.1, beginning with $MeshFormat)",
    "vtu": "a VTK XML unstructured grid (beginning with <?xml or <VTKFile)",
    "exodus": "an Exodus II mesh file (netCDF)",
}


#: how a file of each format begins (after blank space), to tell a damaged file from another kind of file
_SIGNATURES = {
    "gmsh": (b"$MeshFormat",),
    "vtu": (b"<?xml", b"<VTKFile"),
    "exodus": (b"CDF", b"\x89HDF"),
}


def _begins_as(path: Path, fmt: str) -> bool:
    """Does the file begin as a file of ``fmt`` does?"""
    try:
        with open(path, "rb") as fh:
            head = fh.read(256).lstrip()
    except OSError:
        return False
    return head.startswith(_SIGNATURES[fmt])


def _what_it_is(path: Path) -> str:
    """What the start of a file looks like, in words (for the message when it cannot be read)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(256)
    except OSError as err:
        return f"it cannot be opened ({err.strerror or err})"
    if not head:
        return "the file is empty"
    try:
        first = head.decode("utf-8").strip().splitlines()[0] if head.strip() else ""
    except UnicodeDecodeError:
        return "it holds binary data"
    return f"it begins with {first[:40]!r}" if first else "it holds only blank space"


def _read_with_meshio(path: Path, fmt: str):
    """meshio's reader of ``fmt`` on ``path``; MeshError naming the file and what was expected otherwise.

    Calls the format's own reader: ``meshio.read`` prints a ReadError and exits the process.
    """
    meshio = _meshio()
    reader = {"gmsh": meshio.gmsh.read, "vtu": meshio.vtu.read, "exodus": meshio.exodus.read}[fmt]
    try:
        return reader(str(path))
    except Exception as exc:  # meshio raises many kinds on malformed input
        reason = " ".join(str(exc).split())[:200]
        hint = ""
        if "gmsh:physical" in reason:
            hint = (
                " (meshio cannot read MSH 4.1 files in which only some entities belong to "
                "physical groups, as Gmsh writes them with Mesh.SaveAll=1: save without "
                "SaveAll, with every element in a physical group)"
            )
        detail = f"; the reader says: {type(exc).__name__}: {reason}" if reason else ""
        if _begins_as(path, fmt):  # the right kind of file, damaged: saying it is another kind would contradict
            raise MeshError(
                f"{path} begins as {_EXPECTED[fmt].split(' (')[0]} but cannot be read: it is cut short or "
                f"damaged{detail}{hint}; write it again"
            ) from exc
        raise MeshError(f"{path} is not {_EXPECTED[fmt]}: {_what_it_is(path)}{detail}{hint}") from exc


def _netcdf4(action: str):
    try:
        import netCDF4
    except ImportError as exc:
        raise MeshError(
            f"{action} Exodus files needs the optional package netCDF4 (pip install netCDF4); or use .msh or .vtu"
        ) from exc
    return netCDF4


def _unique_rows_in_order(key: np.ndarray) -> np.ndarray:
    """Indices of the first occurrence of each distinct row of ``key``, in order."""
    if len(key) == 0:
        return np.zeros(0, np.int64)
    _, first = np.unique(key, axis=0, return_index=True)
    return np.sort(first)


def _check_cell_types(path, blocks) -> str:
    """The file's element type (``hex8``, ``tet4`` or ``tet10``); MeshError for other 3D cells, for two
    kinds of 3D cells in one file and for a file without any."""
    counts: dict[str, int] = {}
    others: dict[str, int] = {}
    for b in blocks:
        counts[b.type] = counts.get(b.type, 0) + len(b.data)
        if b.type not in VOLUME_TYPES and b.dim == 3 and len(b.data):
            others[b.type] = others.get(b.type, 0) + len(b.data)
    if others:
        raise MeshError(
            f"{path}: only hexahedra (hex8) and tetrahedra (tet4, tet10) are supported, but the file holds "
            + ", ".join(f"{c} {t}" for t, c in sorted(others.items()))
            + " cells; remesh the volume with hexahedra or tetrahedra"
        )
    kinds = [t for t in VOLUME_TYPES if counts.get(t, 0)]
    if not kinds:
        raise MeshError(
            f"{path}: no hexahedra or tetrahedra found; cell types in the file: "
            f"{ {t: c for t, c in sorted(counts.items())} }"
        )
    if len(kinds) > 1:
        raise MeshError(
            f"{path}: the file holds {' and '.join(kinds)} cells; a mesh holds one element type: "
            "write each body to its own file (or read the bodies of one type)"
        )
    return VOLUME_TYPES[kinds[0]]


def _check_facet_type(path, what: str, cell_type: str, element: str) -> None:
    """MeshError when ``what`` (a facet group, said as the format names it) holds cells that are no faces."""
    if cell_type not in FACET_TYPES[element]:
        raise MeshError(
            f"{path}: {what} holds {cell_type} elements; the facets of {element} cells are "
            f"{' or '.join(FACET_TYPES[element])} elements"
        )


# -------------------------------------------------------------------- readers
def read_gmsh(path: Path) -> Raw:
    m = _read_with_meshio(path, "gmsh")
    element = _check_cell_types(path, m.cells)
    field_data = {str(k): np.asarray(v).reshape(-1) for k, v in (m.field_data or {}).items()}
    tag_name = {(int(v[0]), int(v[1])): k for k, v in field_data.items() if len(v) >= 2}
    physical = m.cell_data.get("gmsh:physical")
    named_sets = {k: v for k, v in (m.cell_sets or {}).items() if k in field_data}

    hex_blocks: list[np.ndarray] = []
    body_parts: dict[str, list[np.ndarray]] = {}
    quad_parts: dict[str, list[np.ndarray]] = {}
    node_parts: dict[str, list[np.ndarray]] = {}
    n_hex = 0
    for bi, block in enumerate(m.cells):
        data = np.asarray(block.data, dtype=np.int64)
        dim = block.dim
        groups: dict[str, np.ndarray] = {}
        if physical is not None and bi < len(physical):
            tags = np.asarray(physical[bi]).reshape(-1)
            for t in np.unique(tags):
                if t == 0:
                    continue  # Gmsh's "no physical group"
                name = tag_name.get((int(t), dim), str(int(t)))
                groups[name] = np.nonzero(tags == t)[0]
        for name, per_block in named_sets.items():
            idx = per_block[bi] if bi < len(per_block) else None
            if idx is not None and len(idx) and int(field_data[name][1]) == dim:
                groups[name] = np.union1d(groups.get(name, np.zeros(0, np.int64)), np.asarray(idx, np.int64))
        if block.type == MESHIO_VOLUME[element]:
            hex_blocks.append(data)
            for name, idx in groups.items():
                body_parts.setdefault(name, []).append(n_hex + idx)
            n_hex += len(data)
        elif dim == 2:
            for name, idx in groups.items():
                _check_facet_type(path, f"physical group {name!r}", block.type, element)
                quad_parts.setdefault(name, []).append(data[idx][:, :3] if element == "tet10" else data[idx])
        elif dim in (0, 1):
            for name, idx in groups.items():
                node_parts.setdefault(name, []).append(np.unique(data[idx]))

    hexes = np.concatenate(hex_blocks, axis=0)
    bodies = {k: np.concatenate(v) for k, v in body_parts.items()}
    # Gmsh 2.2 repeats an element once per physical group it belongs to.
    first = _unique_rows_in_order(np.sort(hexes, axis=1))
    if len(first) < len(hexes):
        _, inverse = np.unique(np.sort(hexes, axis=1), axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        rank = np.full(int(np.max(inverse)) + 1, -1, np.int64)
        rank[inverse[first]] = np.arange(len(first))
        bodies = {k: np.unique(rank[inverse[v]]) for k, v in bodies.items()}
        hexes = hexes[first]
    quad_groups = {}
    for name, parts in quad_parts.items():
        q = np.concatenate(parts, axis=0)
        quad_groups[name] = q[_unique_rows_in_order(np.sort(q, axis=1))]
    node_groups = {k: np.unique(np.concatenate(v)) for k, v in node_parts.items()}
    width = 4 if element == "hex8" else 3  # a tet10's facet is known by its corners
    # named groups without elements: empty sets written by write_mesh, or
    # groups lost by Gmsh itself (MSH 2.2 with Mesh.SaveAll=1 drops all tags)
    for name, v in field_data.items():
        dim = int(v[1]) if len(v) >= 2 else -1
        empty = (dim == 2 and name not in quad_groups) or (dim in (0, 1) and name not in node_groups)
        if empty:
            log.info("%s: physical group %r has no elements; read as an empty set", path, name)
        if dim == 2 and name not in quad_groups:
            quad_groups[name] = np.zeros((0, width), np.int64)
        elif dim in (0, 1) and name not in node_groups:
            node_groups[name] = np.zeros(0, np.int64)
    return Raw(str(path), np.asarray(m.points, np.float64), hexes, bodies, quad_groups, node_groups)


def read_vtu(path: Path) -> Raw:
    m = _read_with_meshio(path, "vtu")
    element = _check_cell_types(path, m.cells)
    hex_blocks: list[np.ndarray] = []
    quad_parts: dict[str, list[np.ndarray]] = {}
    width = 4 if element == "hex8" else 3  # a tet10's facet is known by its corners
    for bi, block in enumerate(m.cells):
        data = np.asarray(block.data, dtype=np.int64)
        if block.type == MESHIO_VOLUME[element]:
            hex_blocks.append(data)
            continue
        for key, per_block in m.cell_data.items():
            if not key.startswith(VTU_FACET_PREFIX):
                continue
            name = key[len(VTU_FACET_PREFIX) :]
            member = np.asarray(per_block[bi]).reshape(len(data), -1)[:, 0] != 0
            if not member.any():
                continue
            _check_facet_type(path, f"facet set {name!r} (cell data {key!r})", block.type, element)
            quad_parts.setdefault(name, []).append(data[member][:, :width])
    quad_groups = {}
    for key in m.cell_data:
        if key.startswith(VTU_FACET_PREFIX):
            name = key[len(VTU_FACET_PREFIX) :]
            parts = quad_parts.get(name, [np.zeros((0, width), np.int64)])
            q = np.concatenate(parts, axis=0)
            quad_groups[name] = q[_unique_rows_in_order(np.sort(q, axis=1))]
    node_groups = {
        key[len(VTU_NODE_PREFIX) :]: np.nonzero(np.asarray(v).reshape(len(m.points), -1)[:, 0] != 0)[0]
        for key, v in m.point_data.items()
        if key.startswith(VTU_NODE_PREFIX)
    }
    hexes = np.concatenate(hex_blocks, axis=0)
    return Raw(str(path), np.asarray(m.points, np.float64), hexes, {}, quad_groups, node_groups)


def _nc_names(nc, var: str, count: int) -> list[str]:
    if var not in nc.variables or count == 0:
        return [""] * count
    v = nc.variables[var]
    v.set_auto_mask(False)
    out = []
    for row in np.asarray(v[:]).reshape(count, -1):
        out.append(b"".join(bytes(c) for c in row).decode("utf-8", "replace").strip("\x00 ").strip())
    return out


def _nc_ids(nc, var: str, count: int) -> list[int]:
    if var in nc.variables and count:
        return [int(i) for i in np.asarray(nc.variables[var][:]).reshape(-1)]
    return list(range(1, count + 1))


def read_exodus(path: Path) -> Raw:
    netCDF4 = _netcdf4("reading")
    m = _read_with_meshio(path, "exodus")
    element = _check_cell_types(path, m.cells)
    with netCDF4.Dataset(path) as nc:
        dims = nc.dimensions
        n_blk = len(dims["num_el_blk"]) if "num_el_blk" in dims else len(m.cells)
        sizes = [len(dims[f"num_el_in_blk{i + 1}"]) for i in range(n_blk) if f"num_el_in_blk{i + 1}" in dims]
        if sizes != [len(b.data) for b in m.cells]:
            raise MeshError(f"{path}: element blocks could not be matched to meshio's cell blocks")
        blk_names = _nc_names(nc, "eb_names", n_blk)
        blk_ids = _nc_ids(nc, "eb_prop1", n_blk)
        n_ns = len(dims["num_node_sets"]) if "num_node_sets" in dims else 0
        ns_names = _nc_names(nc, "ns_names", n_ns)
        ns_ids = _nc_ids(nc, "ns_prop1", n_ns)
        node_groups = {}
        for i in range(n_ns):
            name = ns_names[i] or f"nodeset_{ns_ids[i]}"
            var = f"node_ns{i + 1}"
            nodes = np.asarray(nc.variables[var][:], np.int64) - 1 if var in nc.variables else np.zeros(0, np.int64)
            node_groups[name] = np.unique(nodes)
        n_ss = len(dims["num_side_sets"]) if "num_side_sets" in dims else 0
        ss_names = _nc_names(nc, "ss_names", n_ss)
        ss_ids = _nc_ids(nc, "ss_prop1", n_ss)
        side_sets = {}
        for i in range(n_ss):
            name = ss_names[i] or f"sideset_{ss_ids[i]}"
            if f"elem_ss{i + 1}" in nc.variables:
                elems = np.asarray(nc.variables[f"elem_ss{i + 1}"][:], np.int64) - 1
                sides = np.asarray(nc.variables[f"side_ss{i + 1}"][:], np.int64)
            else:
                elems = sides = np.zeros(0, np.int64)
            side_sets[name] = (elems, sides)

    # global element number (block order) -> hex index
    hex_of_global = np.full(sum(sizes), -1, np.int64)
    hex_blocks, bodies, start, n_hex = [], {}, 0, 0
    for i, block in enumerate(m.cells):
        n = len(block.data)
        if block.type == MESHIO_VOLUME[element]:
            hex_blocks.append(np.asarray(block.data, np.int64))
            hex_of_global[start : start + n] = n_hex + np.arange(n)
            bodies[blk_names[i] or f"block_{blk_ids[i]}"] = n_hex + np.arange(n)
            n_hex += n
        start += n
    hexes = np.concatenate(hex_blocks, axis=0)
    quad_groups = {}
    for name, (elems, sides) in side_sets.items():
        if len(elems) and (elems.min() < 0 or elems.max() >= len(hex_of_global)):
            raise MeshError(f"{path}: side set {name!r} refers to elements beyond the {len(hex_of_global)} in the file")
        h = hex_of_global[elems]
        n_sides = 6 if element == "hex8" else 4
        if (h < 0).any() or (len(sides) and (sides.min() < 1 or sides.max() > n_sides)):
            raise MeshError(f"{path}: side set {name!r} refers to sides of elements other than the {element} cells")
        if element == "hex8":
            quad_groups[name] = hexes[h[:, None], HEX_FACES[_FACE_OF_EXODUS_SIDE[sides - 1]]]
        else:  # TET_FACES are in Exodus side order; a facet is known by its corners
            quad_groups[name] = hexes[h[:, None], TET_FACES[sides - 1, :3]]
    return Raw(str(path), np.asarray(m.points, np.float64), hexes, bodies, quad_groups, node_groups)


# -------------------------------------------------------------------- writers
def _check_names(mesh: Mesh, extra=()) -> None:
    for name in [*mesh.node_sets, *mesh.facet_sets, *extra]:
        if not name or any(c in name for c in '"\n\r\x00'):
            raise MeshError(f"set name {name!r} cannot be written: use a non-empty name without quotes or newlines")


def _gmsh_node_sets(mesh: Mesh) -> dict[str, np.ndarray]:
    """Node sets to write as physical points (those a reader cannot recreate)."""
    out = {}
    for name, nodes in mesh.node_sets.items():
        if name in mesh.facet_sets:
            facet_nodes = np.unique(mesh.facet_nodes(name))
            if np.array_equal(np.unique(nodes), facet_nodes):
                continue
            raise MeshError(
                f"node set {name!r} has the name of a facet set but other nodes; Gmsh files "
                "hold one physical group per name: rename one of them before writing .msh"
            )
        out[name] = np.unique(nodes)
    return out


def write_gmsh(path: Path, mesh: Mesh, version: str, binary: bool, body_name: str) -> None:
    meshio = _meshio()
    _check_names(mesh, [body_name])
    if body_name in mesh.facet_sets or body_name in mesh.node_sets:
        raise MeshError(f"body_name {body_name!r} is also a set name; choose another body_name")
    node_sets = _gmsh_node_sets(mesh)
    points = [mesh.points]
    dim_tags = [np.tile([3, 1], (mesh.n_nodes, 1))]
    cells = [(MESHIO_VOLUME[mesh.element], mesh.cells)]
    physical = [np.full(mesh.n_cells, 1, np.int32)]
    geometrical = [np.full(mesh.n_cells, 1, np.int32)]
    field_data = {body_name: np.array([1, 3])}
    tag = 1
    for dim, cell_type, groups in (
        (2, MESHIO_FACET[mesh.element], {k: mesh.facet_nodes(k) for k in mesh.facet_sets}),
        (0, "vertex", {k: v[:, None] for k, v in node_sets.items()}),
    ):
        for entity, (name, conn) in enumerate(groups.items(), start=1):
            tag += 1
            field_data[name] = np.array([tag, dim])
            if len(conn) == 0:
                continue  # only the name is written; reading gives an empty set
            cells.append((cell_type, conn))
            physical.append(np.full(len(conn), tag, np.int32))
            geometrical.append(np.full(len(conn), entity, np.int32))
            # meshio's MSH 4.1 writer derives the geometric entities from the
            # nodes' entities, so every written entity needs a node of its own:
            # an unused copy of one of its nodes, dropped again on reading.
            points.append(mesh.points[conn[:1, 0]])
            dim_tags.append(np.array([[dim, entity]]))
    if version == "4.1":
        out = meshio.Mesh(
            np.concatenate(points, axis=0),
            cells,
            point_data={"gmsh:dim_tags": np.concatenate(dim_tags, axis=0)},
            cell_data={"gmsh:physical": physical, "gmsh:geometrical": geometrical},
            field_data=field_data,
        )
    else:
        out = meshio.Mesh(
            mesh.points,
            cells,
            cell_data={"gmsh:physical": physical, "gmsh:geometrical": geometrical},
            field_data=field_data,
        )
    meshio.gmsh.write(str(path), out, fmt_version=version, binary=binary)


def write_vtu(path: Path, mesh: Mesh, binary: bool) -> None:
    meshio = _meshio()
    _check_names(mesh)
    cells = [(MESHIO_VOLUME[mesh.element], mesh.cells)]
    cell_data = {}
    if mesh.facet_sets:
        all_facets = np.unique(np.concatenate([np.zeros((0, 2), np.int64), *mesh.facet_sets.values()]), axis=0)
        code = all_facets[:, 0] * 6 + all_facets[:, 1]
        if len(all_facets):
            cells.append((MESHIO_FACET[mesh.element], mesh.facet_nodes(all_facets)))
        for name, facets in mesh.facet_sets.items():
            member = np.isin(code, facets[:, 0] * 6 + facets[:, 1]).astype(np.int32)
            blocks = [np.zeros(mesh.n_cells, np.int32)]
            if len(all_facets):
                blocks.append(member)
            cell_data[VTU_FACET_PREFIX + name] = blocks
    point_data = {}
    for name, nodes in mesh.node_sets.items():
        member = np.zeros(mesh.n_nodes, np.int32)
        member[nodes] = 1
        point_data[VTU_NODE_PREFIX + name] = member
    out = meshio.Mesh(mesh.points, cells, point_data=point_data, cell_data=cell_data)
    meshio.vtu.write(str(path), out, binary=binary)


def write_exodus(path: Path, mesh: Mesh, body_name: str) -> None:
    netCDF4 = _netcdf4("writing")
    meshio = _meshio()
    _check_names(mesh, [body_name])
    too_long = [n for n in [*mesh.node_sets, *mesh.facet_sets, body_name] if len(n.encode()) > 32]
    if too_long:
        raise MeshError(f"Exodus names hold at most 32 bytes; too long: {too_long}")
    if mesh.n_nodes >= 2**31 or mesh.n_cells >= 2**31:
        raise MeshError("mesh too large for 32-bit Exodus indices")
    out = meshio.Mesh(
        mesh.points,
        [(MESHIO_VOLUME[mesh.element], mesh.cells.astype(np.int32))],
        point_sets={k: np.asarray(v, np.int32) for k, v in mesh.node_sets.items() if len(v)},
    )
    if path.exists():
        path.unlink()  # netCDF4 will not overwrite some existing files
    meshio.exodus.write(str(path), out)
    with netCDF4.Dataset(path, "a") as nc:

        def put_names(var, dim, names):
            v = nc.createVariable(var, "S1", (dim, "len_string"))
            v.set_auto_mask(False)
            arr = np.zeros((len(names), len(nc.dimensions["len_string"])), "S1")
            for i, name in enumerate(names):
                b = name.encode()
                arr[i, : len(b)] = np.frombuffer(b, "S1")
            v[:] = arr

        # Exodus ids are positive; meshio numbers its blocks and node sets from 0.
        for var in ("eb_prop1", "ns_prop1"):
            if var in nc.variables:
                nc.variables[var][:] = np.arange(1, len(nc.variables[var]) + 1)
                nc.variables[var].setncattr("name", "ID")
        if "eb_status" not in nc.variables:
            nc.createVariable("eb_status", "i4", ("num_el_blk",))[:] = 1
        if "eb_names" not in nc.variables:
            put_names("eb_names", "num_el_blk", [body_name])
        # node sets: meshio writes the non-empty ones; empty ones are dropped
        dropped = [k for k, v in mesh.node_sets.items() if len(v) == 0]
        if dropped:
            log.warning("%s: empty node sets %s are not written", path, dropped)
        if "ns_prop1" in nc.variables and "ns_status" not in nc.variables:
            nc.createVariable("ns_status", "i4", ("num_node_sets",))[:] = 1
        names = list(mesh.facet_sets)
        if names:
            nc.createDimension("num_side_sets", len(names))
            nc.createVariable("ss_status", "i4", ("num_side_sets",))[:] = [
                1 if len(mesh.facet_sets[k]) else 0 for k in names
            ]
            ids = nc.createVariable("ss_prop1", "i4", ("num_side_sets",))
            ids[:] = np.arange(1, len(names) + 1)
            ids.setncattr("name", "ID")
            put_names("ss_names", "num_side_sets", names)
            for i, name in enumerate(names, start=1):
                facets = mesh.facet_sets[name]
                if len(facets) == 0:
                    continue  # as the Exodus library does: an empty set has no arrays
                nc.createDimension(f"num_side_ss{i}", len(facets))
                nc.createVariable(f"elem_ss{i}", "i4", (f"num_side_ss{i}",))[:] = facets[:, 0] + 1
                side = _EXODUS_SIDE[facets[:, 1]] if mesh.element == "hex8" else facets[:, 1] + 1
                nc.createVariable(f"side_ss{i}", "i4", (f"num_side_ss{i}",))[:] = side
