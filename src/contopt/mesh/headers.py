"""How many cells a mesh file declares, from its headers, before a reader spends minutes and gigabytes on it.

The memory check (:func:`contopt.mesh.core.check_mesh_size`) refuses a generated mesh too large for the
machine before it is made; a mesh file of the same size would otherwise be read whole first (a
2-million-cell file: 50-155 s and 4.1 GB). :func:`declared_cells` reads only what says the size:

* Gmsh (``.msh``, MSH 2.2 and 4.1, ASCII and binary): the ``$Elements`` section is found in the
  memory-mapped file (a byte search, not a parse) and its hexahedra counted from the block headers
  (4.1, and 2.2 binary) or from the second word of each element line (2.2 ASCII);
* VTU: ``NumberOfCells`` of the pieces in the file's first 64 KiB (the quads of the facet sets
  included: a few per cent of a large mesh);
* Exodus II: the dimension ``num_elem`` of the netCDF header.

Whatever cannot be read this way gives None: the reader then says what is wrong with the file.
"""

from __future__ import annotations

import mmap
import re
import struct
from pathlib import Path

#: Gmsh's element type of the 8-node hexahedron, and the nodes of each type a binary block may hold
_GMSH_HEX = 5
_GMSH_NODES = {1: 2, 2: 3, 3: 4, 4: 4, 5: 8, 6: 6, 7: 5, 15: 1}
_VTU_HEAD = 64 * 1024


def declared_cells(path: str | Path, fmt: str) -> int | None:
    """The hexahedra (Gmsh) or cells (VTU, Exodus) the file at ``path`` of format ``fmt`` ("gmsh", "vtu",
    "exodus") declares, read from its headers; None when they cannot be read so."""
    try:
        if fmt == "gmsh":
            return _gmsh(Path(path))
        if fmt == "vtu":
            return _vtu(Path(path))
        return _exodus(Path(path))
    except (OSError, ValueError, IndexError, struct.error):  # a damaged header: the reader will say so
        return None


def _vtu(path: Path) -> int | None:
    with open(path, "rb") as fh:
        head = fh.read(_VTU_HEAD)
    counts = re.findall(rb"<Piece\b[^>]*\bNumberOfCells=\"(\d+)\"", head)
    return sum(int(c) for c in counts) if counts else None


def _exodus(path: Path) -> int | None:
    try:
        import netCDF4
    except ImportError:  # the reader says netCDF4 is needed
        return None
    with netCDF4.Dataset(str(path)) as data:  # opening reads the header only
        dim = data.dimensions.get("num_elem")
        return None if dim is None else int(dim.size)


def _gmsh(path: Path) -> int | None:
    with open(path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
        start = mm.find(b"$MeshFormat")
        if start < 0:
            return None
        mm.seek(start)
        mm.readline()
        version, binary, size_t = mm.readline().split()[:3]
        at = mm.find(b"\n$Elements", mm.tell())  # past the nodes without reading them
        if at < 0:
            return None
        mm.seek(at + 1)
        mm.readline()
        if version.startswith(b"4"):
            return _gmsh4(mm, binary == b"1", int(size_t))
        return _gmsh2(mm, binary == b"1")


def _gmsh4(mm: mmap.mmap, binary: bool, size_t: int) -> int:
    """Hexahedra of an MSH 4.1 ``$Elements`` section, from its block headers (at ``mm``'s position)."""
    word = {4: "i", 8: "q"}[size_t]
    if binary:
        blocks = struct.unpack(f"<{word}", mm.read(size_t))[0]
        mm.read(3 * size_t)
    else:
        blocks = int(mm.readline().split()[0])
    hexes = 0
    for _ in range(blocks):
        if binary:
            _, _, kind, n = struct.unpack(f"<iii{word}", mm.read(12 + size_t))
        else:
            _, _, kind, n = (int(v) for v in mm.readline().split()[:4])
        if kind == _GMSH_HEX:
            hexes += n
        if binary:
            if kind not in _GMSH_NODES:
                break  # a block that cannot be skipped: what was counted is a lower bound
            mm.seek(min(mm.tell() + n * (1 + _GMSH_NODES[kind]) * size_t, mm.size()))
        else:
            for _ in range(n):
                if not mm.readline():
                    return hexes  # cut short: the blocks declared so far
    return hexes


def _gmsh2(mm: mmap.mmap, binary: bool) -> int:
    """Hexahedra of an MSH 2.2 ``$Elements`` section (at ``mm``'s position)."""
    total = int(mm.readline().split()[0])
    hexes = seen = 0
    while seen < total:
        if binary:
            kind, n, tags = struct.unpack("<iii", mm.read(12))
            if kind not in _GMSH_NODES:
                break
            mm.seek(min(mm.tell() + n * (1 + tags + _GMSH_NODES[kind]) * 4, mm.size()))
        else:
            line = mm.readline()
            if not line or line.startswith(b"$"):
                break
            kind, n = int(line.split(None, 2)[1]), 1
        hexes += n if kind == _GMSH_HEX else 0
        seen += n
    return hexes
