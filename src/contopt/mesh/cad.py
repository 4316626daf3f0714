"""A body's mesh from a CAD file (STEP, IGES, BREP or STL), meshed by Gmsh's Python API.

``element = "tet"``: Gmsh's tetrahedra as they are, of edge about ``size``: tet4 (``order = 1``)
or tet10 (``order = 2``, the edge nodes on the CAD's curved surfaces), the CAD's surfaces as facet
sets of triangles (tri3 / tri6). Gmsh numbers tet10's nodes 8 and 9 the other way round from VTK;
they are swapped here.

``element = "hex8"`` (the default): Gmsh does not hex-mesh an arbitrary solid directly; so Gmsh
meshes the solid with tetrahedra of edge about ``2 * size`` and splits each tetrahedron into four
hexahedra (``Mesh.SubdivisionAlgorithm = 2``: the nodes are the tetrahedron's corners, its edge
midpoints, its face centres and its centroid). Every hexahedron is valid (positive Jacobian at its
corners, checked here) but skewed: scaled Jacobians down to about 0.1, against 1 for a cube. The
split halves the edges, so the hexes' edges are about ``size`` long (their mean about 0.75 size).
Gmsh's recombination of tetrahedra into hexes (``Mesh.Recombine3DAll``) leaves prisms, pyramids and
tetrahedra in most solids, which a hex8 mesh cannot hold, so it is not used.

The CAD's surfaces become facet sets (and node sets of the same name): the quads Gmsh puts on each
surface (each triangle of the surface mesh split into three) are the faces of the hexes there. A
surface is named by the CAD's own name where the file gives one (Gmsh's entity name, the last part
of its ``/``-separated label path), else ``surface_N`` with N Gmsh's tag of the surface. STEP files
rarely name faces; Gmsh gives each surface of a file the same tag on every read, so ``surface_N``
is stable for a file. :func:`cad_surfaces` lists them without meshing (``contopt mesh --list``).

Units are the file's numbers: Gmsh (OpenCASCADE) reads STEP and IGES in millimetres whatever unit
they declare; BREP and STL carry no unit. ``scale`` multiplies every coordinate (0.001: a CAD in mm
for a model in m), and ``size`` is in the scaled unit.

Gmsh is the optional extra ``cad`` (``pip install 'contopt[cad]'``).
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from contopt import extras
from contopt.errors import ConfigError, MeshError
from contopt.mesh.core import Mesh, check_mesh_size, scaled_jacobian
from contopt.mesh.formats import Raw
from contopt.mesh.io import mesh_of_raw

__all__ = ["CAD_SUFFIXES", "CadOptions", "CadSurface", "cad_surfaces", "cad_triangles", "mesh_cad", "surface_set_name"]

#: the CAD files read, by suffix (lower case)
CAD_SUFFIXES = {
    ".step": "step",
    ".stp": "step",
    ".iges": "iges",
    ".igs": "iges",
    ".brep": "brep",
    ".stl": "stl",
}
#: Gmsh's element types: 4-node quad, 8-node hexahedron
_QUAD, _HEX = 3, 5
#: Gmsh's element types of tets by order: (volume, its width, face, its width)
_TET = {1: (4, 4, 2, 3), 2: (11, 10, 9, 6)}
#: Gmsh's tet10 node order to VTK's (edges (2,3) and (1,3) swapped)
_GMSH_TET10 = np.array([0, 1, 2, 3, 4, 5, 6, 7, 9, 8])
#: the mesh's element type, by the ``element`` key
ELEMENTS = ("hex8", "tet")
#: hexes per unit volume at size 1, to refuse a mesh too large before meshing: a regular tetrahedron
#: of edge 2 has volume 8 / (6 sqrt 2) and splits into 4 hexes; Delaunay meshes hold somewhat more
_HEXES_PER_VOLUME = 4 * 6 * math.sqrt(2) / 8
#: an STL's facets meeting at more than this angle bound different surfaces
_STL_ANGLE = math.radians(40.0)


@dataclass(frozen=True)
class CadOptions:
    """How a CAD file is meshed.

    size : the elements' edge length, about (in the scaled unit); for hex8 Gmsh meshes tetrahedra of
        edge 2 size and splits each into four hexes
    order : the element order: 1 (hex8 or tet4) or 2 (tet10: element = "tet")
    scale : every coordinate of the CAD is multiplied by it (0.001: a CAD in mm for a model in m)
    element : "hex8" (Gmsh's tetrahedra split into hexes) or "tet" (Gmsh's tetrahedra: tet4 or
        tet10 by the order)
    """

    size: float
    order: int = 1
    scale: float = 1.0
    element: str = "hex8"

    def __post_init__(self):
        for key in ("size", "scale"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
                raise ConfigError(f"mesh.{key} must be a number > 0 (a length in the model's unit), got {v!r}")
        if self.element not in ELEMENTS:
            raise ConfigError(f'mesh.element must be "hex8" or "tet", got {self.element!r}')
        if isinstance(self.order, bool) or self.order not in (1, 2):
            raise ConfigError(f"mesh.order must be 1 (hex8 or tet4) or 2 (tet10), got {self.order!r}")
        if self.order == 2 and self.element == "hex8":
            raise ConfigError('mesh.order = 2 is tet10: set element = "tet" (hex8 is linear)')


@dataclass(frozen=True)
class CadSurface:
    """One surface of a CAD solid: its facet set's ``name``, Gmsh's ``tag`` and its ``area`` (scaled unit^2)."""

    name: str
    tag: int
    area: float


def surface_set_name(tag: int, label: str) -> str:
    """The facet set of a CAD surface: the last part of its label path ``Shapes/part/top`` (``top``),
    or ``surface_<tag>`` when it has none."""
    last = label.rpartition("/")[2].strip()
    return last or f"surface_{tag}"


def _cad_kind(path: Path) -> str:
    kind = CAD_SUFFIXES.get(path.suffix.lower())
    if kind is None:
        raise MeshError(f"{path}: not a CAD file; the suffixes read are {', '.join(CAD_SUFFIXES)}")
    if not path.is_file():
        raise MeshError(f"CAD file {path} not found")
    return kind


def _gmsh():
    extras.require("cad", "meshing a CAD file needs")
    try:
        import gmsh
    except OSError as err:  # the wheel's libgmsh links X and GL libraries a bare Linux lacks
        raise extras.MissingExtra(
            f"meshing a CAD file needs Gmsh, whose library does not load here ({err}); {extras.install_hint('cad')}"
        ) from err
    return gmsh


@contextmanager
def _session(gmsh):
    """A Gmsh model of its own, quiet, removed after; Gmsh is initialized for it unless it already was."""
    ours = not gmsh.isInitialized()
    if ours:
        # not interruptible: Ctrl-C and SIGTERM stay the command line's (contopt.cli)
        gmsh.initialize(readConfigFiles=False, interruptible=False)
    terminal = gmsh.option.getNumber("General.Terminal")
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("contopt-cad")
    try:
        yield
    finally:
        gmsh.model.remove()
        gmsh.option.setNumber("General.Terminal", terminal)
        if ours:
            gmsh.finalize()


@contextmanager
def _options(gmsh, values: dict):
    """Gmsh's numeric options set to ``values``, and back to what they were after."""
    saved = {k: gmsh.option.getNumber(k) for k in values}
    try:
        for key, value in values.items():
            gmsh.option.setNumber(key, value)
        yield
    finally:
        for key, value in saved.items():
            gmsh.option.setNumber(key, value)


#: how OpenCASCADE reads each kind: IGES holds faces, which are sewn into a solid
_READ_OPTIONS = {
    "step": {},
    "brep": {},
    "iges": {"Geometry.OCCSewFaces": 1, "Geometry.OCCMakeSolids": 1},
}


def _load(gmsh, path: Path, kind: str, scale: float) -> int:
    """Read the CAD into the current model, scaled; Gmsh's tag of its one volume."""
    try:
        if kind == "stl":
            gmsh.merge(str(path))
            gmsh.model.mesh.affineTransform([scale, 0, 0, 0, 0, scale, 0, 0, 0, 0, scale, 0])
            # the triangles become surfaces split at sharp edges only (not into parametrizable patches, whose
            # reprojected subdivision inverted hexes), bounding a volume
            gmsh.model.mesh.classifySurfaces(_STL_ANGLE, True, False, math.pi)
            gmsh.model.mesh.createGeometry()
            loop = gmsh.model.geo.addSurfaceLoop([tag for _, tag in gmsh.model.getEntities(2)])
            gmsh.model.geo.addVolume([loop])
            gmsh.model.geo.synchronize()
        else:
            with _options(gmsh, {"Geometry.OCCScaling": scale, **_READ_OPTIONS[kind]}):
                gmsh.merge(str(path))
    except Exception as err:  # Gmsh raises Exception with its last error message
        raise MeshError(f"{path}: Gmsh cannot read it as {kind.upper()}: {err}") from err
    volumes = [tag for _, tag in gmsh.model.getEntities(3)]
    if len(volumes) != 1:
        what = "no solid (only surfaces: a closed shell is needed)" if not volumes else f"{len(volumes)} solids"
        raise MeshError(f"{path}: the CAD holds {what}; a body is meshed from one solid: fuse or split it in the CAD")
    return volumes[0]


def _boundary(gmsh, volume: int) -> list[tuple[str, int]]:
    """(facet set name, tag) of each surface bounding the volume, by tag."""
    tags = sorted({abs(tag) for _, tag in gmsh.model.getBoundary([(3, volume)], oriented=False)})
    return [(surface_set_name(tag, gmsh.model.getEntityName(2, tag)), tag) for tag in tags]


def cad_surfaces(path, scale: float = 1.0) -> list[CadSurface]:
    """The surfaces of the solid in a CAD file, as :func:`mesh_cad` names its facet sets (no meshing).

    Areas are the CAD's (OpenCASCADE's) for STEP, IGES and BREP, the triangles' for STL.
    """
    path = Path(path)
    kind = _cad_kind(path)
    CadOptions(size=1.0, scale=scale)  # checks scale
    gmsh = _gmsh()
    with _session(gmsh):
        volume = _load(gmsh, path, kind, scale)
        out = []
        for name, tag in _boundary(gmsh, volume):
            area = gmsh.model.occ.getMass(2, tag) if kind != "stl" else _stl_area(gmsh, tag)
            out.append(CadSurface(name, tag, float(area)))
    return out


def _stl_area(gmsh, tag: int) -> float:
    _, _, nodes = gmsh.model.mesh.getElements(2, tag)
    tri = np.asarray(nodes[0], np.int64).reshape(-1, 3)
    index, points = _nodes(gmsh)
    p = points[index[tri]]
    return float(0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum())


def _nodes(gmsh) -> tuple[np.ndarray, np.ndarray]:
    """The row of each Gmsh node tag (an index array, -1 for unused tags) and the nodes' coordinates
    (n, 3) of the whole model."""
    tags, coords, _ = gmsh.model.mesh.getNodes()
    tags = np.asarray(tags, np.int64)
    index = np.full(int(tags.max()) + 1, -1, np.int64)
    index[tags] = np.arange(len(tags))
    return index, np.asarray(coords, np.float64).reshape(-1, 3)


def _elements(gmsh, dim: int, tag: int, etype: int, width: int, what: str) -> np.ndarray:
    """(m, width) Gmsh node tags of the elements of type ``etype`` on entity (dim, tag); MeshError for others."""
    types, _, nodes = gmsh.model.mesh.getElements(dim, tag)
    others = [int(t) for t in types if int(t) != etype]
    if others:
        names = [gmsh.model.mesh.getElementProperties(t)[0] for t in others]
        raise MeshError(
            f"Gmsh meshed {what} with {', '.join(names)} besides the expected cells; remesh with another size"
        )
    if not len(types):
        return np.zeros((0, width), np.int64)
    return np.asarray(nodes[0], np.int64).reshape(-1, width)


def mesh_cad(path, size: float, *, order: int = 1, scale: float = 1.0, element: str = "hex8") -> Mesh:
    """The hex8 (or tet4 / tet10) mesh of the one solid in a CAD file, its surfaces as named facet and node sets.

    Parameters
    ----------
    path : ``.step``/``.stp``, ``.iges``/``.igs``, ``.brep`` or ``.stl`` (a closed surface)
    size, order, scale, element : see :class:`CadOptions`

    Returns
    -------
    Mesh with points (n, 3) in the CAD's unit times ``scale``, cells (m, 8) (or (m, 4), (m, 10)), and per CAD surface a
    facet set and a node set named as :func:`surface_set_name` says. MeshError when the file holds no
    solid or several, when Gmsh fails, or when a hex is not valid.
    """
    options = CadOptions(size=size, order=order, scale=scale, element=element)
    path = Path(path)
    kind = _cad_kind(path)
    gmsh = _gmsh()
    with _session(gmsh):
        volume = _load(gmsh, path, kind, options.scale)
        if kind != "stl":  # a mesh too fine is refused before Gmsh spends minutes on it
            # tets of edge size: 8 times as many as the tets of edge 2 size the hexes come from, a quarter of them
            per_volume = _HEXES_PER_VOLUME * (2.0 if options.element == "tet" else 1.0)
            bulk = gmsh.model.occ.getMass(3, volume) * per_volume / options.size**3
            check_mesh_size(int(bulk), f"the mesh of {path} at size {options.size:g}", "use a larger size")
        if options.element == "tet":
            return mesh_of_raw(_tet_mesh(gmsh, path, volume, options.size, options.order))
        raw = _hex_mesh(gmsh, path, volume, options.size)
    inverted = scaled_jacobian(raw.points, raw.cells) <= 0
    if inverted.any():  # a sliver tetrahedron splits into hexes with a negative corner: said before Mesh does
        raise MeshError(
            f"{path}: {int(inverted.sum())} of the {len(raw.cells)} hexes Gmsh made at size {options.size:g} are "
            "inverted (split from sliver tetrahedra); try a somewhat different size"
        )
    return mesh_of_raw(raw)


def _hex_mesh(gmsh, path: Path, volume: int, size: float) -> Raw:
    """Mesh the volume with tetrahedra of edge 2 size split into hexes: the Raw content, sets by surface."""
    try:
        with _options(gmsh, {k: 2.0 * size if v is None else v for k, v in _MESH_OPTIONS.items()}):
            gmsh.model.mesh.generate(3)
    except Exception as err:
        raise MeshError(f"{path}: Gmsh could not mesh it at size {size:g}: {err}; try another size") from err
    index, points = _nodes(gmsh)
    hexes = index[_elements(gmsh, 3, volume, _HEX, 8, f"{path}'s solid")]
    quads: dict[str, list[np.ndarray]] = {}
    for name, tag in _boundary(gmsh, volume):
        quads.setdefault(name, []).append(index[_elements(gmsh, 2, tag, _QUAD, 4, f"surface {tag}")])
    groups = {name: np.concatenate(parts) for name, parts in quads.items()}
    return Raw(str(path), points, hexes, quad_groups=groups)


def cad_triangles(path, size: float | None = None, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The surface of the one solid in a CAD file as triangles: points (n, 3) (scaled) and triangles
    (m, 3) of edge about ``size`` (default: a fiftieth of the solid's bounding-box diagonal).

    For a design envelope (:mod:`contopt.mesh.voxel`): Gmsh meshes the surfaces only (2D).
    """
    path = Path(path)
    kind = _cad_kind(path)
    gmsh = _gmsh()
    with _session(gmsh):
        volume = _load(gmsh, path, kind, scale)
        if size is None:
            box = np.asarray(gmsh.model.getBoundingBox(3, volume), np.float64)
            size = float(np.linalg.norm(box[3:] - box[:3])) / 50.0
        options = {"Mesh.MeshSizeMin": size, "Mesh.MeshSizeMax": size, "Mesh.MeshSizeFromCurvature": 0}
        try:
            with _options(gmsh, {**options, "Mesh.ElementOrder": 1, "Mesh.RecombineAll": 0}):
                gmsh.model.mesh.generate(2)
        except Exception as err:
            raise MeshError(f"{path}: Gmsh could not mesh its surface at size {size:g}: {err}") from err
        index, points = _nodes(gmsh)
        tris = [index[_elements(gmsh, 2, tag, 2, 3, f"surface {tag}")] for _, tag in _boundary(gmsh, volume)]
    return points, np.concatenate(tris)


def _tet_mesh(gmsh, path: Path, volume: int, size: float, order: int) -> Raw:
    """Mesh the volume with tetrahedra of edge ``size`` and order 1 or 2: the Raw content (VTK node order)."""
    options = {"Mesh.MeshSizeMin": size, "Mesh.MeshSizeMax": size, "Mesh.MeshSizeFromCurvature": 0}
    options.update({"Mesh.ElementOrder": order, "Mesh.SubdivisionAlgorithm": 0, "Mesh.RecombineAll": 0})
    try:
        with _options(gmsh, options):
            gmsh.model.mesh.generate(3)
    except Exception as err:
        raise MeshError(f"{path}: Gmsh could not mesh it at size {size:g}: {err}; try another size") from err
    cell_type, width, face_type, face_width = _TET[order]
    index, points = _nodes(gmsh)
    tets = index[_elements(gmsh, 3, volume, cell_type, width, f"{path}'s solid")]
    if order == 2:
        tets = tets[:, _GMSH_TET10]
    faces: dict[str, list[np.ndarray]] = {}
    for name, tag in _boundary(gmsh, volume):
        tri = index[_elements(gmsh, 2, tag, face_type, face_width, f"surface {tag}")]
        faces.setdefault(name, []).append(tri[:, :3])  # a facet is known by its corners
    groups = {name: np.concatenate(parts) for name, parts in faces.items()}
    return Raw(str(path), points, tets, quad_groups=groups)


#: Gmsh's options for the hex mesh (None: the tetrahedra's size, 2 size)
_MESH_OPTIONS = {
    "Mesh.MeshSizeMin": None,
    "Mesh.MeshSizeMax": None,
    "Mesh.MeshSizeFromCurvature": 0,
    "Mesh.ElementOrder": 1,
    "Mesh.SubdivisionAlgorithm": 2,  # each tetrahedron split into 4 hexes (and each triangle into 3 quads)
    "Mesh.RecombineAll": 0,
}
