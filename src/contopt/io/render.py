"""Headless pictures of designs and deformed states (PyVista/VTK offscreen → PNG).

Pure functions from arrays or VTU files to a PNG of a fixed size (default
1200×900), white background, isometric camera and an axes triad:

* :func:`render_design`: the boundaries of the regions ``nu >= 0.1`` (green,
  translucent) and ``nu >= 0.9`` (red) of each designed body, as in the
  iso-surface figures of design papers; bodies without ``nu`` as grey context.
* :func:`render_deformed`: all bodies in the deformed configuration (points +
  displacement), coloured by ``contact_pressure``; designed bodies show only
  their cells with ``nu >= 0.5``.
* :func:`render_sections`: plane cuts of the designed bodies coloured by ``nu``,
  side by side: what an iso-surface hides behind solid skins (the sabot's spokes).

A body is a :class:`BodyGrid` (arrays) or a VTU file as written by
:func:`contopt.io.vtk.write_state`; a run directory stands for the last VTU of
each of its bodies (:func:`last_vtus`).

Rendering needs no display: VTK draws through EGL (``VTK_DEFAULT_OPENGL_WINDOW
=vtkEGLRenderWindow``; Debian packages libegl1, libegl-mesa0, libgl1-mesa-dri,
see ``scripts/setup-system.sh``). Because VTK crashes the whole process when
it draws without a working OpenGL context, the first picture of a process
tries the window types in a child process (EGL, then OSMesa if libOSMesa is
installed, then X if ``DISPLAY`` is set, e.g. under ``xvfb-run``) and raises
:class:`RenderError` when none draws. Nothing here runs at import time.
"""

from __future__ import annotations

import ctypes
import functools
import os
import re
import subprocess
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from contopt import extras
from contopt.errors import ConfigError, ContoptError
from contopt.io.files import write_atomically
from contopt.io.surface import TriangleSurface, read_surface
from contopt.io.vtk import read_pvd

#: the picture size (width, height) in pixels
DEFAULT_SIZE = (1200, 900)
#: volume-fraction levels of the design picture: (translucent green, red)
DESIGN_LEVELS = (0.1, 0.9)
#: designed cells shown in the deformed picture
SOLID_LEVEL = 0.5
#: colour map of the contact pressure (zero = its pale end)
PRESSURE_CMAP = "YlOrRd"
_MAX_EDGED_FACES = 20_000

_WINDOW_ENV = "VTK_DEFAULT_OPENGL_WINDOW"
_EGL, _OSMESA, _X = "vtkEGLRenderWindow", "vtkOSOpenGLRenderWindow", "vtkXOpenGLRenderWindow"
_VTU_NAME = re.compile(r"^(?P<body>.+)_(?P<index>\d+)$")

# Draws a small sphere offscreen and exits 0 only if the window type asked for is the
# one VTK made (it silently falls back to another) and the image is not blank.
_PROBE = """
import sys
import vtkmodules.vtkRenderingOpenGL2
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkFiltersSources import vtkSphereSource
from vtkmodules.vtkRenderingCore import (vtkActor, vtkPolyDataMapper, vtkRenderWindow, vtkRenderer,
                                         vtkWindowToImageFilter)
win = vtkRenderWindow()
if type(win).__name__ != sys.argv[1]:
    sys.exit(3)
win.SetOffScreenRendering(1)
win.SetSize(32, 32)
ren = vtkRenderer()
ren.SetBackground(1, 1, 1)
win.AddRenderer(ren)
sphere = vtkSphereSource()
mapper = vtkPolyDataMapper()
mapper.SetInputConnection(sphere.GetOutputPort())
actor = vtkActor()
actor.SetMapper(mapper)
actor.GetProperty().SetColor(1, 0, 0)
ren.AddActor(actor)
win.Render()
grab = vtkWindowToImageFilter()
grab.SetInput(win)
grab.Update()
img = vtk_to_numpy(grab.GetOutput().GetPointData().GetScalars())
sys.exit(0 if img.size and img.std() > 0 else 4)
"""


class RenderError(ContoptError, RuntimeError):
    """No offscreen OpenGL could be set up (the message says which were tried and what to install)."""


@dataclass(frozen=True, eq=False)
class BodyGrid:
    """One hex8 body and its fields, for a picture.

    name : body name; points : (n, 3) reference coordinates; cells : (m, 8) hex8 (VTK order)
    cell_data : name -> (m,) or (m, k), e.g. ``nu``; point_data : name -> (n,) or (n, k),
    e.g. ``displacement`` (n, 3) and ``contact_pressure`` (n,)
    """

    name: str
    points: np.ndarray
    cells: np.ndarray
    cell_data: Mapping[str, np.ndarray] = field(default_factory=dict)
    point_data: Mapping[str, np.ndarray] = field(default_factory=dict)


def _osmesa_available() -> bool:
    for name in ("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so"):
        try:
            ctypes.CDLL(name)
            return True
        except OSError:
            continue
    return False


def _probe(window: str, timeout: float = 120.0) -> str:
    """'' if ``window`` draws in a child process, else why not."""
    env = {**os.environ, _WINDOW_ENV: window}
    try:
        done = subprocess.run(
            [sys.executable, "-c", _PROBE, window], env=env, capture_output=True, text=True, timeout=timeout
        )
    except (OSError, subprocess.TimeoutExpired) as err:
        return str(err)
    if done.returncode == 0:
        return ""
    code = done.returncode
    reason = {3: "VTK could not create it", 4: "it drew a blank image"}.get(
        code, f"it crashed (signal {-code})" if code < 0 else f"exit status {code}"
    )
    plain = re.sub(r"\x1b\[[0-9;]*m", "", done.stderr)  # VTK colours its log lines
    warn = [ln for ln in plain.splitlines() if "WARN" in ln or "ERR" in ln]
    return reason + (f" ({warn[0].split('|', 1)[-1].strip()})" if warn else "")


@functools.lru_cache(maxsize=1)
def _choose_window() -> str:
    """The first offscreen window type that draws (cached for the process); sets the VTK env var."""
    os.environ.setdefault(_WINDOW_ENV, _EGL)  # headless by default; a value the user set wins
    wanted = os.environ[_WINDOW_ENV]
    candidates = [wanted]
    if _OSMESA not in candidates and _osmesa_available():
        candidates.append(_OSMESA)
    if _X not in candidates and os.environ.get("DISPLAY"):
        candidates.append(_X)
    failures = []
    for window in candidates:
        why = _probe(window)
        if not why:
            os.environ[_WINDOW_ENV] = window  # VTK reads it whenever it makes a render window
            return window
        failures.append(f"{window}: {why}")
    raise RenderError(
        "no offscreen OpenGL for pictures (" + "; ".join(failures) + "); install EGL with Mesa "
        "(apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri, see scripts/setup-system.sh), "
        "or libosmesa6, or run under xvfb-run"
    )


def _pyvista():
    extras.require("viz", "the pictures need")  # pyvista and vtk
    _choose_window()  # before VTK makes its first window
    import pyvista as pv

    return pv


def last_vtus(run_dir: str | os.PathLike) -> list[Path]:
    """The last VTU file of each body of a run directory, in body (part) order.

    Read from ``design.pvd`` when it lists existing files, else from ``vtu/<body>_NNNN.vtu``
    (highest NNNN per body). Empty when the run wrote none.
    """
    run_dir = Path(run_dir)
    pvd = run_dir / "design.pvd"
    if pvd.exists():
        last: dict[int, tuple[float, Path]] = {}
        for time, part, path in read_pvd(pvd):
            if part not in last or time >= last[part][0]:
                last[part] = (time, path)
        files = [last[p][1] for p in sorted(last)]
        if files and all(f.exists() for f in files):
            return files
    found: dict[str, tuple[int, Path]] = {}
    for path in sorted((run_dir / "vtu").glob("*.vtu")):
        m = _VTU_NAME.match(path.stem)
        if m is None:
            continue
        body, index = m["body"], int(m["index"])
        if body not in found or index > found[body][0]:
            found[body] = (index, path)
    return [found[b][1] for b in found]


def _body_name(path: Path) -> str:
    m = _VTU_NAME.match(path.stem)
    return m["body"] if m else path.stem


def body_grids(bodies) -> list[tuple[str, Any]]:
    """(name, pyvista UnstructuredGrid) per body of a run directory, VTU paths or BodyGrids."""
    # Any: pyvista is an optional dependency, imported when a picture is drawn (_pyvista)
    pv = _pyvista()
    if isinstance(bodies, (str, os.PathLike)):
        files = last_vtus(bodies)
        if not files:
            raise FileNotFoundError(f"no VTU files in {bodies} (design.pvd or vtu/*.vtu)")
        bodies = files
    out = []
    for body in bodies:
        if isinstance(body, BodyGrid):
            cells = np.asarray(body.cells, dtype=np.int64)
            grid = pv.UnstructuredGrid({pv.CellType.HEXAHEDRON: cells}, np.asarray(body.points, dtype=np.float64))
            for k, v in body.cell_data.items():
                grid.cell_data[k] = np.asarray(v, dtype=np.float64)
            for k, v in body.point_data.items():
                grid.point_data[k] = np.asarray(v, dtype=np.float64)
            out.append((body.name, grid))
        else:
            path = Path(body)
            out.append((_body_name(path), pv.read(path)))
    return out


def flat_scalar(grid, name: str) -> None:
    """Make ``name`` a flat (k,) array (meshio writes 1-component arrays as (k, 1))."""
    for data in (grid.cell_data, grid.point_data):
        if name in data and data[name].ndim > 1 and data[name].shape[1] == 1:
            data[name] = np.asarray(data[name]).ravel()


def boundary_surface(grid):
    """The boundary surface (PolyData) of a volume mesh."""
    try:
        return grid.extract_surface(algorithm=None)  # PyVista >= 0.47; its future default
    except TypeError:
        return grid.extract_surface()


def new_plotter(size, shape=(1, 1)):
    pv = _pyvista()
    size = picture_size(size)
    pl = pv.Plotter(off_screen=True, window_size=list(size), shape=shape)
    pl.set_background("white")
    return pv, pl


def _write_png(pl, path, size) -> Path:
    """The plotter's picture written atomically to ``path`` (a viewer never sees half a file); closes it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        write_atomically(path, lambda tmp: pl.screenshot(tmp, window_size=list(picture_size(size)), return_img=False))
    finally:
        pl.close()
    return path


def picture_size(size) -> tuple[int, int]:
    """``size`` as (width, height) pixels; ConfigError unless two positive integers."""
    try:
        w, h = (int(s) for s in size)
        ok = w > 0 and h > 0 and all(float(s) == int(s) for s in size)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ConfigError(f"size must be two positive integers (width, height) in pixels, got {size!r}")
    return w, h


AXES = ("x", "y", "z")


def up_axis(grids, up: str | None = None) -> int:
    """The axis drawn upwards: ``up`` when given, else the one the bodies are pushed along.

    The push is the mean displacement of the bodies without a design (a die, a roller: what moves
    the designed body), or of all bodies when every one is designed; its largest component's axis
    points up (the push goes down the picture, as gravity would). z when nothing moves.
    """
    if up is not None:
        if up not in AXES:
            raise ConfigError(f"the picture's up axis must be one of {AXES}, got {up!r}")
        return AXES.index(up)
    movers = [g for _, g in grids if "nu" not in g.cell_data] or [g for _, g in grids]
    means = [
        np.asarray(g.point_data["displacement"]).reshape(-1, 3).mean(axis=0)
        for g in movers
        if "displacement" in g.point_data and g.n_points
    ]
    if not means:
        return 2
    push = max(means, key=lambda m: float(np.linalg.norm(m)))
    return int(np.argmax(np.abs(push))) if np.linalg.norm(push) > 0 else 2


def design_focus(grids) -> tuple | None:
    """Bounds of the designed bodies (what the picture is about), or None to frame everything."""
    designed = [g for _, g in grids if "nu" in g.cell_data]
    if not designed:
        return None
    b = np.array([g.bounds for g in designed]).reshape(-1, 3, 2)
    lo, hi = b[:, :, 0].min(axis=0), b[:, :, 1].max(axis=0)
    pad = 0.15 * (hi - lo).max()
    return tuple(np.ravel(np.column_stack([lo - pad, hi + pad])))


def save_picture(pl, path, size, title: str, up: int = 2, focus: tuple | None = None) -> Path:
    """Isometric camera with axis ``up`` upwards, framed on ``focus`` (bounds) when given, axes triad,
    title; PNG written atomically (a viewer never sees half a file)."""
    if title:
        pl.add_text(title, position="upper_left", font_size=max(6, picture_size(size)[1] // 75), color="black")
    pl.add_axes(color="black", line_width=3)
    view_up = np.eye(3)[up]
    a, b = (i for i in range(3) if i != up)
    pl.view_vector(np.eye(3)[a] + np.eye(3)[b] * -1.0 + 0.8 * view_up, viewup=view_up)
    if focus is None:
        pl.reset_camera()
    else:  # the designed body fills the picture; what sticks out of it may be cut
        pl.reset_camera(bounds=focus)
        pl.camera.zoom(1.3)
    return _write_png(pl, path, size)


def render_design(
    bodies,
    path: str | os.PathLike,
    size: Sequence[int] = DEFAULT_SIZE,
    levels: Sequence[float] = DESIGN_LEVELS,
    context: bool = True,
    title: str = "",
    up: str | None = None,
) -> Path:
    """Iso-surfaces of the volume fraction ``nu`` of the designed bodies as a PNG.

    bodies : a run directory (its last VTU per body), VTU paths, or :class:`BodyGrid` s;
        a body is designed when it has the cell array ``nu`` (m,)
    levels : (low, high): the surface of ``nu >= low`` is drawn green and translucent, that of
        ``nu >= high`` red. ``nu`` is averaged to the nodes first, and each surface is the
        boundary of the clipped region, so it is closed where material meets the domain boundary.
    context : draw the bodies without ``nu`` as light-grey translucent context
    up : the axis drawn upwards (:func:`up_axis`); the picture is framed on the designed bodies
    size : (width, height) in pixels. Returns ``path``.
    """
    size = picture_size(size)
    low, high = (float(v) for v in levels)
    grids = body_grids(bodies)
    axis = up_axis(grids, up)
    pv, pl = new_plotter(size)
    for _name, grid in grids:
        flat_scalar(grid, "nu")
        if "nu" not in grid.cell_data:
            if context:
                pl.add_mesh(boundary_surface(grid), color="lightgrey", opacity=0.25)
            continue
        pl.add_mesh(grid.outline(), color="black", line_width=1)
        nodal = grid.cell_data_to_point_data()
        nodal.set_active_scalars("nu")
        for level, style in ((low, dict(color="green", opacity=0.3)), (high, dict(color="red", opacity=1.0))):
            region = nodal.clip_scalar(scalars="nu", value=level, invert=False)
            if region.n_cells:
                pl.add_mesh(boundary_surface(region), smooth_shading=False, **style)
    return save_picture(pl, path, size, title, axis, design_focus(grids))


def render_deformed(
    bodies,
    path: str | os.PathLike,
    size: Sequence[int] = DEFAULT_SIZE,
    scale: float = 1.0,
    solid: float = SOLID_LEVEL,
    title: str = "",
    up: str | None = None,
) -> Path:
    """The deformed configuration of all bodies, coloured by contact pressure, as a PNG.

    bodies : a run directory (its last VTU per body), VTU paths, or :class:`BodyGrid` s with point
        data ``displacement`` (n, 3) (absent = zero) and ``contact_pressure`` (n,) (absent on one
        body = zero there; absent on all bodies, i.e. no contact: coloured by the displacement
        magnitude instead)
    scale : displacement magnification (1 = the true deformed shape)
    solid : designed bodies (cell array ``nu``) show only the cells with ``nu >= solid``; the rest
        of the body is drawn faintly
    up : the axis drawn upwards (:func:`up_axis`)
    size : (width, height) in pixels. Returns ``path``.

    In a contact model the bodies that carry no pressure (the mortar sides: a die, a roller) are
    drawn translucent, so that the pressure on the surface under them shows.
    """
    size = picture_size(size)
    grids = body_grids(bodies)
    axis = up_axis(grids, up)
    pv, pl = new_plotter(size)
    for _name, grid in grids:
        flat_scalar(grid, "contact_pressure")
    # a model without contact has no pressure to show: its displacement magnitude says more
    contact = any("contact_pressure" in grid.point_data for _, grid in grids)
    key, label = (
        ("contact_pressure", "contact pressure") if contact else ("displacement_magnitude", "displacement magnitude")
    )
    shown = []
    for _name, grid in grids:
        flat_scalar(grid, "nu")
        u = (
            np.asarray(grid.point_data["displacement"]).reshape(-1, 3)
            if "displacement" in grid.point_data
            else np.zeros((grid.n_points, 3))
        )
        grid.points = grid.points + scale * u
        if contact and key not in grid.point_data:
            grid.point_data[key] = np.zeros(grid.n_points)
        if not contact:
            grid.point_data[key] = np.linalg.norm(u, axis=1)
        if "nu" in grid.cell_data:
            kept = grid.threshold(solid, scalars="nu", preference="cell")
            pl.add_mesh(boundary_surface(grid), color="lightgrey", opacity=0.12)
            grid = kept
        if contact and not np.any(np.asarray(grid.point_data[key]) > 0):
            # no pressure on this body: it would only hide the surface the pressure lives on
            if grid.n_cells:
                pl.add_mesh(boundary_surface(grid), color="steelblue", opacity=0.2)
            continue
        if grid.n_cells:
            shown.append(boundary_surface(grid))
    p: np.ndarray = np.concatenate([np.asarray(s.point_data[key]) for s in shown]) if shown else np.zeros(1)
    top = float(p.max()) if p.size and p.max() > 0 else 1.0  # all zero: a legible 0..1 bar
    font = max(8, size[1] // 45)  # VTK's fonts are in pixels: scale them with the picture
    bar = dict(
        title=label,
        color="black",
        vertical=True,
        position_x=0.8,
        position_y=0.2,
        height=0.6,
        width=0.06,
        fmt="%.3g",
        title_font_size=font,
        label_font_size=font,
    )
    edges = sum(s.n_cells for s in shown) <= _MAX_EDGED_FACES
    for i, surf in enumerate(shown):
        # zero pressure is the pale end of the map, so the contact zone stands out; edges give the
        # pale faces an outline against the white background (coarse meshes only: fine ones go black)
        pl.add_mesh(
            surf,
            scalars=key,
            cmap=PRESSURE_CMAP,
            clim=(0.0, top),
            show_scalar_bar=i == 0,
            scalar_bar_args=bar,
            show_edges=edges,
            edge_color="#777777",
            line_width=0.5,
        )
    return save_picture(pl, path, size, title, axis)


def render_surface(
    surfaces,
    path: str | os.PathLike,
    size: Sequence[int] = DEFAULT_SIZE,
    title: str = "",
    color: str = "lightsteelblue",
    boxes=(),
) -> Path:
    """Closed triangle surfaces (e.g. exported designs) shaded, as a PNG.

    surfaces : :class:`contopt.io.surface.TriangleSurface` s, or .stl / .ply / .obj files
    boxes : ``(lower (3,), upper (3,))`` boxes drawn as black outlines (e.g. the design domains)
    Smooth shading, split at edges sharper than 30 degrees (the flat caps on a body's faces keep
    their crisp edges). size : (width, height) in pixels. Returns ``path``.
    """
    size = picture_size(size)
    pv, pl = new_plotter(size)
    for s in surfaces:
        s = s if isinstance(s, TriangleSurface) else read_surface(s)
        if s.n_faces == 0:
            continue
        cells = np.hstack([np.full((s.n_faces, 1), 3), s.faces]).ravel()
        pl.add_mesh(
            pv.PolyData(s.vertices, cells),
            color=color,
            smooth_shading=True,
            split_sharp_edges=True,
            feature_angle=30.0,
            specular=0.2,
        )
    for lower, upper in boxes:
        bounds = [v for pair in zip(lower, upper) for v in pair]
        pl.add_mesh(pv.Box(bounds=bounds).outline(), color="black", line_width=1)
    return save_picture(pl, path, size, title)


#: where :func:`render_sections` cuts, as fractions of the designed bodies' extent along the axis
SECTION_POSITIONS = (0.2, 0.5, 0.8)


def render_sections(
    bodies,
    path: str | os.PathLike,
    axis: str | None = None,
    positions: Sequence[float] = SECTION_POSITIONS,
    size: Sequence[int] = (1500, 560),
    title: str = "",
) -> Path:
    """Cuts of the designed bodies normal to ``axis``, coloured by ``nu`` (0 white .. 1 dark red).

    bodies : as :func:`render_design` (the bodies with the cell array ``nu`` are cut, the others left
        out); axis : "x", "y" or "z" (default: the up axis of :func:`up_axis`, the direction the
        bodies are pushed); positions : where to cut, fractions (0, 1) of the designed bodies'
        extent along ``axis``, one panel each, seen along the axis. Returns ``path``.
    """
    fractions = [float(f) for f in positions]
    if not fractions or not all(0.0 < f < 1.0 for f in fractions):
        raise ConfigError(f"section positions must be fractions strictly between 0 and 1, got {positions!r}")
    size = picture_size(size)
    grids = body_grids(bodies)
    designed = [g for _, g in grids if "nu" in g.cell_data]
    if not designed:
        raise ConfigError("no designed body (cell array 'nu') to cut")
    k = up_axis(grids, axis)
    axis = AXES[k]
    bounds = np.array([g.bounds for g in designed]).reshape(-1, 3, 2)
    lo, hi = bounds[:, k, 0].min(), bounds[:, k, 1].max()
    _, pl = new_plotter(size, shape=(1, len(fractions)))
    for i, f in enumerate(fractions):
        pl.subplot(0, i)
        level = lo + f * (hi - lo)
        origin = np.zeros(3)
        origin[k] = level
        for grid in designed:
            cut = grid.slice(normal=axis, origin=tuple(origin))
            if cut.n_cells:
                # unlit: the colour is the colormap's (a lit cut of nu = 0 looked grey, not white)
                pl.add_mesh(
                    cut,
                    scalars="nu",
                    cmap="Reds",
                    clim=(0.0, 1.0),
                    lighting=False,
                    show_scalar_bar=i == len(fractions) - 1,
                )
        pl.add_text(f"{axis} = {level:.4g}", position="upper_left", font_size=10, color="black")
        pl.view_vector(np.eye(3)[k], viewup=np.eye(3)[(k + 1) % 3])
        pl.reset_camera()
    if title:
        pl.subplot(0, 0)
        pl.add_text(title, position="lower_left", font_size=10, color="black")
    return _write_png(pl, path, size)
