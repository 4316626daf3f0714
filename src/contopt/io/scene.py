"""Triangle surfaces of a run's last VTU files, for the interactive 3D view of ``report.html``.

:func:`run_scene` reads the last VTU of each body (:func:`contopt.io.render.last_vtus`) and
returns a :class:`Scene` of triangle surfaces in the reference configuration, each with the
nodal displacement (so that a viewer shows the reference design and the deformed state from
the same triangles) and a nodal colour value (contact pressure, or the displacement magnitude
when the model has no contact):

* ``iso``: a designed body's region ``nu >= level`` (0.5), bounded by the iso-surface
  ``nu = level`` of the nodal average of the cell values ``nu`` and by the body's boundary where
  ``nu > level`` there (VTK ``clip_scalar``; displacement and pressure interpolated with it);
* ``domain``: a designed body's whole boundary (the design domain, drawn faintly);
* ``body``: the whole boundary of a body without ``nu`` (a die, a tube).

Vertices are split at sharp edges (feature angle 30 degrees), so that a viewer averaging the face
normals at the vertices draws crisp box edges. Scenes over ``max_triangles`` are decimated
(``vtkDecimatePro``, which keeps a subset of the vertices and so their exact values); each
surface records its triangle count before. Nothing here needs OpenGL.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from contopt import extras
from contopt.errors import ConfigError

#: the volume fraction whose iso-surface bounds a designed body's material
ISO_LEVEL = 0.5
#: the default cap on the triangles of a scene (all surfaces together)
MAX_TRIANGLES = 60_000
#: vertices whose faces meet at a sharper angle than this (degrees) are split
FEATURE_ANGLE = 30.0
ROLES = ("iso", "domain", "body")
_VTU_NAME = re.compile(r"^(?P<body>.+)_(?P<index>\d+)$")


@dataclass(frozen=True, eq=False)
class SceneMesh:
    """One triangle surface of a body.

    body : the body's name; role : one of :data:`ROLES`
    points : (n, 3) float32 reference coordinates; triangles : (m, 3) int64 vertex indices
    displacement : (n, 3) float32 nodal displacement
    values : (n,) float32 colour value (see :attr:`Scene.value_name`), or None: the body has none
        (e.g. the mortar side of a contact interface), drawn in a plain colour
    triangles_before : triangle count before decimation (== m when not decimated)
    """

    body: str
    role: str
    points: np.ndarray
    triangles: np.ndarray
    displacement: np.ndarray
    values: np.ndarray | None
    triangles_before: int

    @property
    def decimated(self) -> bool:
        return self.triangles_before > len(self.triangles)


@dataclass(frozen=True, eq=False)
class Scene:
    """The surfaces of a run's last state.

    meshes : :class:`SceneMesh` es, in body order (iso before domain)
    value_name : "contact_pressure" or "displacement_magnitude" (no body has contact pressure)
    value_range : (0, max) of the values over the iso and body surfaces (max 1 when all are zero)
    level : the iso level of ``nu``; files : the VTU files read (one per body)
    max_triangles : the cap the scene was decimated to
    """

    meshes: tuple
    value_name: str
    value_range: tuple
    level: float
    files: tuple
    max_triangles: int

    @property
    def n_triangles(self) -> int:
        return int(sum(len(m.triangles) for m in self.meshes))

    @property
    def triangles_before(self) -> int:
        return int(sum(m.triangles_before for m in self.meshes))


def body_name(path: str | os.PathLike) -> str:
    """The body of a VTU file written by :func:`contopt.io.vtk.write_state` (``<body>_NNNN.vtu``)."""
    stem = Path(path).stem
    m = _VTU_NAME.match(stem)
    return m["body"] if m else stem


def _flat(grid, name: str) -> None:
    """meshio writes one-component arrays as (k, 1): make them (k,)."""
    for data in (grid.cell_data, grid.point_data):
        if name in data and data[name].ndim > 1 and data[name].shape[1] == 1:
            data[name] = np.asarray(data[name]).ravel()


def _triangle_surface(volume):
    """The boundary of a volume mesh as triangles, vertices split at sharp edges (PolyData)."""
    try:
        surf = volume.extract_surface(algorithm=None)  # PyVista >= 0.47; its future default
    except TypeError:
        surf = volume.extract_surface()
    surf = surf.triangulate().clean()
    if surf.n_cells == 0:
        return surf
    return surf.compute_normals(
        split_vertices=True, feature_angle=FEATURE_ANGLE, consistent_normals=True, auto_orient_normals=False
    )


def _mesh(body: str, role: str, surf, value_name: str | None) -> SceneMesh:
    tri = np.asarray(surf.faces).reshape(-1, 4)[:, 1:] if surf.n_cells else np.zeros((0, 3), np.int64)
    n = surf.n_points
    u = (
        np.asarray(surf.point_data["displacement"]).reshape(n, 3)
        if "displacement" in surf.point_data
        else np.zeros((n, 3))
    )
    values = None
    if value_name == "displacement_magnitude":
        values = np.linalg.norm(u, axis=1)
    elif value_name is not None and value_name in surf.point_data:
        values = np.asarray(surf.point_data[value_name]).reshape(n)
    return SceneMesh(
        body=body,
        role=role,
        points=np.asarray(surf.points, dtype=np.float32),
        triangles=np.asarray(tri, dtype=np.int64),
        displacement=u.astype(np.float32),
        values=None if values is None else values.astype(np.float32),
        triangles_before=len(tri),
    )


def _body_meshes(name: str, grid, value_name: str, level: float) -> list[SceneMesh]:
    """The surfaces of one body (see the module docstring for the roles)."""
    for key in ("nu", "contact_pressure"):
        _flat(grid, key)
    if "nu" not in grid.cell_data:
        return [_mesh(name, "body", _triangle_surface(grid), value_name)]
    nodal = grid.cell_data_to_point_data(pass_cell_data=False)  # the iso-surface needs nodal nu
    region = nodal.clip_scalar(scalars="nu", value=level, invert=False)
    out = [_mesh(name, "iso", _triangle_surface(region), value_name)] if region.n_cells else []
    return out + [_mesh(name, "domain", _triangle_surface(grid), None)]


def decimate(mesh: SceneMesh, target: int) -> SceneMesh:
    """``mesh`` with about ``target`` triangles (unchanged when it has no more), vertices and their
    values kept exactly (``vtkDecimatePro``)."""
    import pyvista as pv

    m = len(mesh.triangles)
    if m <= target:
        return mesh
    faces = np.hstack([np.full((m, 1), 3), mesh.triangles]).ravel()
    surf = pv.PolyData(np.asarray(mesh.points, dtype=np.float64), faces)
    surf.point_data["displacement"] = mesh.displacement
    if mesh.values is not None:
        surf.point_data["values"] = mesh.values
    small = surf.decimate_pro(1.0 - target / m, preserve_topology=False)
    tri = np.asarray(small.faces).reshape(-1, 4)[:, 1:]
    values = np.asarray(small.point_data["values"], dtype=np.float32) if mesh.values is not None else None
    return SceneMesh(
        body=mesh.body,
        role=mesh.role,
        points=np.asarray(small.points, dtype=np.float32),
        triangles=tri.astype(np.int64),
        displacement=np.asarray(small.point_data["displacement"], dtype=np.float32).reshape(-1, 3),
        values=values,
        triangles_before=mesh.triangles_before,
    )


def _budget(meshes: list[SceneMesh], max_triangles: int) -> list[int]:
    """Triangles allowed per mesh: all of them under the cap, else shares proportional to their counts
    (the faint domain surfaces get a fifth of theirs first: they are context)."""
    counts = np.array([len(m.triangles) for m in meshes], dtype=np.float64)
    if counts.sum() <= max_triangles:
        return [int(c) for c in counts]
    weight = counts * np.array([0.2 if m.role == "domain" else 1.0 for m in meshes])
    share = np.minimum(counts, np.floor(max_triangles * weight / weight.sum()))
    return [int(max(s, 1)) for s in share]


def check_max_triangles(value) -> int:
    """``value`` as an int if it is a whole number >= 100, else ConfigError."""
    try:
        ok = int(value) == float(value) and int(value) >= 100
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ConfigError(f"max_triangles (--max-triangles) must be a whole number of at least 100, got {value!r}")
    return int(value)


def run_scene(files, level: float = ISO_LEVEL, max_triangles: int = MAX_TRIANGLES) -> Scene:
    """The :class:`Scene` of VTU files (one per body, e.g. :func:`contopt.io.render.last_vtus`).

    level : the iso level of ``nu`` (0 < level < 1); max_triangles : cap over all surfaces (>= 100)
    """
    extras.require("viz", "the 3D view needs")  # pyvista
    import pyvista as pv

    if not 0.0 < float(level) < 1.0:
        raise ConfigError(f"level must lie strictly between 0 and 1 (a volume fraction), got {level!r}")
    max_triangles = check_max_triangles(max_triangles)
    files = tuple(Path(f) for f in files)
    if not files:
        raise FileNotFoundError("no VTU files to show (the run wrote none: vtu 'none' without pictures)")
    grids = [(body_name(f), pv.read(f)) for f in files]
    contact = any("contact_pressure" in g.point_data for _, g in grids)
    value_name = "contact_pressure" if contact else "displacement_magnitude"
    meshes = [m for name, grid in grids for m in _body_meshes(name, grid, value_name, float(level))]
    meshes = [decimate(m, t) for m, t in zip(meshes, _budget(meshes, max_triangles))]
    shown = [m.values for m in meshes if m.values is not None and m.role != "domain" and m.values.size]
    top = float(max(v.max() for v in shown)) if shown else 0.0
    return Scene(
        meshes=tuple(meshes),
        value_name=value_name,
        value_range=(0.0, top if top > 0 else 1.0),
        level=float(level),
        files=files,
        max_triangles=max_triangles,
    )
