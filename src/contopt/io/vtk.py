"""VTU files per load step (or design iteration) and a ParaView ``.pvd`` series.

Each body is written to its own VTU (reference coordinates; use ParaView's
"Warp By Vector" with ``displacement``) and listed in the ``.pvd`` with its
``part`` index, so ParaView opens all bodies and all steps from one file.
The ``.pvd`` is rewritten after every entry, so a run that stops early
(or is still going) leaves a series that opens.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

from contopt.errors import ConfigError
from contopt.io.files import write_atomically

#: meshio's cell type of each width of ``cells`` (meshio holds tetra10 in VTK's node order, as contopt does)
MESHIO_TYPE = {8: "hexahedron", 4: "tetra", 10: "tetra10"}


def write_vtu(
    path: str | os.PathLike,
    points: np.ndarray,
    cells: np.ndarray,
    point_data: dict | None = None,
    cell_data: dict | None = None,
) -> Path:
    """Write one body (hex8, tet4 or tet10 cells) as VTU (binary, zlib). Arrays: point (n, ...) and cell (m, ...).

    Written atomically; a failure raises :class:`~contopt.errors.OutputError` and leaves no temporary.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    mesh = meshio.Mesh(
        points=np.asarray(points, dtype=np.float64),
        cells=[(MESHIO_TYPE[np.shape(cells)[1]], np.asarray(cells, dtype=np.int64))],
        point_data={k: np.asarray(v, dtype=np.float64) for k, v in (point_data or {}).items()},
        cell_data={k: [np.asarray(v, dtype=np.float64).reshape(len(cells), -1)] for k, v in (cell_data or {}).items()},
    )
    # whole or not at all: a run killed or out of disk space leaves no half VTU for a viewer
    return write_atomically(path, lambda tmp: meshio.write(tmp, mesh, file_format="vtu"))


def read_vtu(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, dict, dict]:
    """``(points (n, 3), cells (m, 8 | 4 | 10), point data, cell data)`` of a VTU as :func:`write_vtu` writes it.

    Cell data of the first block of hexahedra (or else of tetrahedra) only; ConfigError when the file
    cannot be read or has no such cells.
    """
    path = Path(path)
    try:
        mesh = meshio.read(path, file_format="vtu")
    except Exception as err:  # meshio raises many kinds for a file that is not a VTU
        raise ConfigError(f"cannot read {path} as a VTU file: {' '.join(str(err).split())[:160]}") from None
    blocks = [i for kind in MESHIO_TYPE.values() for i, block in enumerate(mesh.cells) if block.type == kind]
    if not blocks:
        raise ConfigError(f"{path} has no hexahedra or tetrahedra (contopt's VTU files hold one body each)")
    i = blocks[0]
    cells = np.asarray(mesh.cells[i].data, dtype=np.int64)
    cell_data = {k: np.asarray(v[i], dtype=np.float64) for k, v in mesh.cell_data.items()}
    point_data = {k: np.asarray(v, dtype=np.float64) for k, v in mesh.point_data.items()}
    return np.asarray(mesh.points, dtype=np.float64), cells, point_data, cell_data


@dataclass
class PVDSeries:
    """A ParaView collection file listing (time, part, file) entries; rewritten on every add."""

    path: Path
    entries: list = field(default_factory=list)

    def __post_init__(self):
        self.path = Path(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)

    def add(self, time: float, file: str | os.PathLike, part: int = 0) -> None:
        rel = os.path.relpath(Path(file).resolve(), self.path.parent.resolve())
        self.entries.append((float(time), int(part), rel))
        self.write()

    def write(self) -> None:
        lines = [
            '<?xml version="1.0"?>',
            '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
            "  <Collection>",
        ]
        for time, part, rel in self.entries:
            lines.append(f'    <DataSet timestep="{time:.12g}" group="" part="{part}" file={quoteattr(rel)}/>')
        lines += ["  </Collection>", "</VTKFile>", ""]
        text = "\n".join(lines)
        write_atomically(self.path, lambda tmp: tmp.write_text(text))  # a viewer never sees half a file


def read_pvd(path: str | os.PathLike) -> list[tuple[float, int, Path]]:
    """Entries (time, part, absolute file path) of a ``.pvd`` written by :class:`PVDSeries`."""
    path = Path(path)
    root = ET.parse(path).getroot()
    return [
        (float(d.attrib["timestep"]), int(d.get("part", 0)), path.parent / d.attrib["file"])
        for d in root.iter("DataSet")
    ]


def write_state(
    directory: str | os.PathLike,
    bodies,
    fields: dict,
    time: float,
    index: int,
    series: PVDSeries,
    extra_cell_data: dict | None = None,
    extra_point_data: dict | None = None,
) -> list[Path]:
    """Write every body of a state as ``<body>_<index>.vtu`` and add them to ``series``.

    ``bodies``: the model's bodies (name and mesh each); ``fields`` maps body name -> (point data,
    cell data), what the state shows (:func:`contopt.solve.fields.state_fields`); ``extra_*_data``
    map body name -> {array name: values} for further fields (e.g. contact pressure).
    """
    directory = Path(directory)
    files = []
    for i, body in enumerate(bodies):
        point, cell = fields[body.name]
        pdata = {**point, **(extra_point_data or {}).get(body.name, {})}
        cdata = {**cell, **(extra_cell_data or {}).get(body.name, {})}
        f = write_vtu(directory / f"{body.name}_{index:04d}.vtu", body.mesh.points, body.mesh.cells, pdata, cdata)
        series.add(time, f, part=i)
        files.append(f)
    return files
