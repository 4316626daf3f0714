"""The surface of an optimized design: a closed triangle surface of each designed body's material.

For each designed body the material's indicator is sampled on a regular lattice finer than
the FE mesh (``refine`` lattice spacings per cell, per direction) and its zero level extracted
by marching cubes (:func:`contopt.io.surface.lattice_surface`):

* B-spline level sets: ``phi~ = phi v skins`` (the level set after the R-function union,
  whose zero is ``nu = 1/2``) evaluated at every lattice point, not only at the centroids;
* density designs: the volume fraction ``nu`` averaged to the nodes (weights: cell volumes)
  and interpolated trilinearly, minus 1/2; Taubin smoothing (volume kept) by default;
* cells fixed solid or void keep their value.

Outside the body the lattice is void, so the surface closes where the material reaches the
body's boundary. When the body fills its bounding box the lattice is aligned with the box
and the caps lie exactly on its faces. Otherwise (a ring, a sector) the body enters as
``min(indicator, s * distance to the boundary)``, with ``s`` the indicator's slope at its
zero, which puts the caps on the mesh's boundary to the lattice's interpolation accuracy.
A body voxelized from a closed surface (``DesignedBody.envelope``) enters also as its minimum with
the signed distance to that surface: the part is cut to the envelope, not only to the staircase.

Symmetry: every lattice point is mapped into the modelled region first: across model
symmetry planes (``SurfaceOptions.mirror``, e.g. the sabot's z = 0) and into the cyclic
symmetry's fundamental region, exactly as the design chain maps centroids. A mesh of one
sector (or half sector) therefore gives the whole part, in one watertight surface.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from contopt.assembly.model import Model
from contopt.assembly.system import Discretization
from contopt.design.bspline import BSplineGrid
from contopt.design.maps import r_union
from contopt.design.symmetry import AXES, CyclicSymmetry
from contopt.errors import ConfigError
from contopt.io.surface import (
    TriangleSurface,
    check_surface,
    lattice_surface,
    surface_format,
    taubin_smooth,
    write_surface,
)
from contopt.mesh.core import Mesh
from contopt.mesh.query import boundary_distance, boundary_triangles, locate_points, trilinear
from contopt.mesh.voxel import inside_surface
from contopt.timing import Stopwatch

log = logging.getLogger(__name__)

AXIS_INDEX = {"x": 0, "y": 1, "z": 2}
#: Taubin double steps when SurfaceOptions.smooth is None, by kind of design
DEFAULT_SMOOTHING = {"density": 10, "level set": 0}
#: the distance to the boundary is computed exactly within this many lattice spacings
_BAND = 2.0


@dataclass(frozen=True)
class SurfaceOptions:
    """How a design's surface is made.

    refine : lattice spacings per FE cell size in each direction (1..12)
    smooth : Taubin double steps (volume kept); None: 10 for density designs, 0 for level sets
    mirror : model symmetry planes ``(("z", 0.0), ...)``: the modelled part is mirrored across
        them (the sabot models the upper half of its parts: ``mirror=(("z", 0.0),)``)
    """

    refine: int = 3
    smooth: int | None = None
    mirror: tuple = ()

    def __post_init__(self):
        if (
            isinstance(self.refine, bool)
            or not isinstance(self.refine, (int, np.integer))
            or not 1 <= self.refine <= 12
        ):
            raise ConfigError(f"surface refine must be an integer from 1 to 12, got {self.refine!r}")
        if self.smooth is not None and (
            isinstance(self.smooth, bool) or not isinstance(self.smooth, (int, np.integer)) or self.smooth < 0
        ):
            raise ConfigError(f"surface smoothing must be an integer >= 0 (Taubin steps), got {self.smooth!r}")
        planes = []
        for item in self.mirror:
            try:
                axis, value = item
                value = float(value)
            except (TypeError, ValueError):
                raise ConfigError(f"a mirror plane is (axis, value) such as ('z', 0.0), got {item!r}") from None
            if axis not in AXIS_INDEX or not np.isfinite(value):
                raise ConfigError(f"a mirror plane needs an axis x, y or z and a finite value, got {item!r}")
            planes.append((axis, value))
        if len({a for a, _ in planes}) != len(planes):
            raise ConfigError(f"one mirror plane per axis at most, got {planes}")
        object.__setattr__(self, "mirror", tuple(planes))


@dataclass(frozen=True, eq=False)
class BodySurface:
    """The surface of one designed body and the volumes to compare it with.

    body : the body's name; kind : "level set" or "density"
    surface : the closed triangle surface (outward normals)
    volume : enclosed by the surface; design_volume : ``sum nu_e V_e`` times the copies;
    domain_volume : ``sum V_e`` times the copies; copies : images of the modelled body that
        make up the part (cyclic sectors times mirror planes)
    grey_volume : the part of design_volume in cells with 0.1 < nu < 0.9 (times the copies)
    lattice : lattice points per direction; spacing : (3,); seconds : time to make it
    bounds : (lower (3,), upper (3,)) of the whole part's design domain
    """

    body: str
    kind: str
    surface: TriangleSurface
    volume: float
    design_volume: float
    domain_volume: float
    copies: int
    grey_volume: float
    lattice: tuple
    spacing: np.ndarray
    seconds: float = 0.0
    bounds: tuple = ()

    @property
    def relative_difference(self) -> float:
        """``(volume - design_volume) / design_volume`` (nan for an empty design)."""
        return (self.volume - self.design_volume) / self.design_volume if self.design_volume > 0 else float("nan")

    @property
    def volume_fraction(self) -> float:
        return self.design_volume / self.domain_volume

    def summary(self) -> dict:
        """JSON-ready numbers of the surface and its volume check."""
        chk = check_surface(self.surface)
        return {
            "body": self.body,
            "kind": self.kind,
            "triangles": self.surface.n_faces,
            "vertices": self.surface.n_vertices,
            "volume": self.volume,
            "design_volume": self.design_volume,
            "domain_volume": self.domain_volume,
            "volume_fraction": self.volume_fraction,
            "relative_difference": self.relative_difference,
            "grey_volume": self.grey_volume,
            "copies": self.copies,
            "lattice": list(self.lattice),
            "spacing": [float(h) for h in self.spacing],
            "watertight": chk.watertight,
            "manifold": chk.manifold,
            "components": chk.components,
            "seconds": self.seconds,
        }

    def line(self) -> str:
        """One line: triangles, the volume check."""
        grey = f"; grey {self.grey_volume / self.design_volume:.1%} of it" if self.design_volume > 0 else ""
        copies = f" (x{self.copies} copies of the model)" if self.copies > 1 else ""
        return (
            f"{self.body}: {self.surface.n_faces} triangles; volume {self.volume:.6g} vs volume fraction "
            f"{self.volume_fraction:.4f} x domain {self.domain_volume:.6g} = {self.design_volume:.6g}{copies}: "
            f"{self.relative_difference:+.2%}{grey}"
        )


# ----------------------------------------------------------------------------------- geometry
def _polar(points: np.ndarray, sym: CyclicSymmetry) -> tuple[np.ndarray, np.ndarray]:
    """Radius and angle from ``sym.start`` (k,) of points (k, 3) about the symmetry's axis."""
    i, j, _ = AXES[sym.axis]
    rel = points - np.array(sym.center)
    return np.hypot(rel[:, i], rel[:, j]), np.arctan2(rel[:, j], rel[:, i]) - sym.start


def _cyclic_images(points: np.ndarray, sym: CyclicSymmetry) -> np.ndarray:
    """(g k, 3) the points under every rotation (and reflection) of the symmetry group."""
    i, j, _ = AXES[sym.axis]
    r, alpha = _polar(points, sym)
    out = []
    for sign in (1.0, -1.0) if sym.reflection else (1.0,):
        for k in range(sym.n_sectors):
            a = sign * alpha + k * sym.sector_angle + sym.start
            p = points.copy()
            p[:, i] = sym.center[i] + r * np.cos(a)
            p[:, j] = sym.center[j] + r * np.sin(a)
            out.append(p)
    return np.concatenate(out)


def _cyclic_copies(mesh, sym: CyclicSymmetry | None) -> int:
    """How many images of the mesh go around the axis: 1 for a full ring, 10 for a half sector of 5.

    The mesh's angular span is 2 pi less the largest gap between its nodes' angles; a span of
    2 pi / c (rounded) means c images, which must divide the symmetry group's order.
    """
    if sym is None:
        return 1
    r, alpha = _polar(np.asarray(mesh.points), sym)
    size = float(np.ptp(mesh.points, axis=0).max())
    a = np.sort(np.mod(alpha[r > 1e-9 * size], 2.0 * np.pi))
    if len(a) < 2:
        return 1
    gaps = np.diff(np.concatenate([a, [a[0] + 2.0 * np.pi]]))
    span = 2.0 * np.pi - float(gaps.max())
    copies = int(round(2.0 * np.pi / span)) if span > 0 else 1
    order = sym.n_sectors * (2 if sym.reflection else 1)
    if copies < 1 or order % copies:
        log.warning(
            "the mesh spans %.1f degrees about the symmetry axis, not a whole number of symmetry "
            "regions; its surface is not expanded",
            np.degrees(span),
        )
        return 1
    return copies


@dataclass(frozen=True, eq=False)
class _Geometry:
    """Where a designed body's part lies: the mesh, the maps into it, the part's bounds.

    mirror : ((axis index, plane, side), ...) with side +1 when the mesh lies above the plane
    cyclic : images of the mesh about the symmetry axis; lower, upper : (3,) the whole part's bounds
    box : the part fills [lower, upper] (the lattice is then aligned with it)
    """

    mesh: Mesh
    symmetry: CyclicSymmetry | None
    mirror: tuple
    cyclic: int
    lower: np.ndarray
    upper: np.ndarray
    box: bool

    @property
    def copies(self) -> int:
        return self.cyclic * 2 ** len(self.mirror)

    def model_points(self, points: np.ndarray) -> np.ndarray:
        """Points mapped across the mirror planes onto the modelled side."""
        out = points.copy()
        for axis, plane, side in self.mirror:
            out[:, axis] = plane + side * np.abs(out[:, axis] - plane)
        return out

    def design_points(self, model_points: np.ndarray) -> np.ndarray:
        """Model points mapped into the symmetry's fundamental region (where the design is evaluated)."""
        return model_points if self.symmetry is None else self.symmetry.map(model_points)


def _geometry(mesh, body: str, symmetry, options: SurfaceOptions, volume: float) -> _Geometry:
    pts = np.asarray(mesh.points, dtype=np.float64)
    size = float(np.ptp(pts, axis=0).max())
    mirror = []
    for axis, plane in options.mirror:
        k = AXIS_INDEX[axis]
        above, below = np.all(pts[:, k] >= plane - 1e-9 * size), np.all(pts[:, k] <= plane + 1e-9 * size)
        if not (above or below):
            raise ConfigError(
                f"body {body!r} lies on both sides of the mirror plane {axis} = {plane:g} "
                f"({axis} from {pts[:, k].min():.6g} to {pts[:, k].max():.6g}); mirror across "
                "a plane the model ends at"
            )
        lo, hi = float(pts[:, k].min()), float(pts[:, k].max())
        gap = lo - plane if above else plane - hi
        if gap > size:  # a plane far from the body: a lattice across the gap (or an overflow to inf)
            raise ConfigError(
                f"the mirror plane {axis} = {plane:g} lies {gap:.3g} away from body {body!r}, which spans "
                f"{axis} from {lo:.6g} to {hi:.6g}; mirror across a plane the model ends at "
                f"(e.g. {axis}={lo:g} or {axis}={hi:g})"
            )
        mirror.append((k, plane, 1.0 if above else -1.0))
    cyclic = _cyclic_copies(mesh, symmetry)
    images = _cyclic_images(pts, symmetry) if cyclic > 1 else pts
    for k, plane, _ in mirror:
        flipped = images.copy()
        flipped[:, k] = 2.0 * plane - flipped[:, k]
        images = np.concatenate([images, flipped])
    lower, upper = images.min(axis=0), images.max(axis=0)
    whole = volume * cyclic * 2 ** len(mirror)
    box = cyclic == 1 and abs(whole - float(np.prod(upper - lower))) <= 1e-9 * whole
    return _Geometry(mesh, symmetry, tuple(mirror), cyclic, lower, upper, box)


def _lattice(geom: _Geometry, refine: int) -> tuple[np.ndarray, np.ndarray, tuple]:
    """(origin (3,), spacing (3,), shape) of the sampling lattice.

    ``refine`` spacings per median cell extent in each direction, plus one: on a uniform mesh the
    lattice then misses the interior node planes, where a nodally averaged 0/1 design is exactly
    1/2 (marching cubes would meet values on the level itself). A box part is spanned exactly.
    Other parts get void around them and the lattice is shifted by half a spacing: a flat face
    of theirs on a lattice plane would have distance 0 there, and marching cubes would cut the
    edges where it meets another face by a chamfer of h^2/2 (h^2/8 half way between planes).
    """
    corners = np.asarray(geom.mesh.points)[np.asarray(geom.mesh.cells)]
    cell = np.median(np.ptp(corners, axis=1), axis=0)
    extent = geom.upper - geom.lower
    intervals = np.maximum(np.ceil(refine * extent / np.maximum(cell, 1e-300) - 1e-9), 1).astype(int) + 1
    spacing = extent / intervals
    if geom.box:
        return geom.lower.copy(), spacing, tuple(int(n) + 1 for n in intervals)
    return geom.lower - 1.5 * spacing, spacing, tuple(int(n) + 4 for n in intervals)


def _lattice_points(origin: np.ndarray, spacing: np.ndarray, shape: tuple) -> np.ndarray:
    axes = [origin[k] + spacing[k] * np.arange(shape[k]) for k in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def _open_facets(geom: _Geometry) -> np.ndarray:
    """(k, 2) boundary facets of the mesh that bound the part: those on a mirror plane, or (for
    a mesh of a sector) on a plane of the symmetry through its axis, join an image and are left out."""
    mesh = geom.mesh
    facets = mesh.boundary_facets()
    quads = np.asarray(mesh.points)[mesh.facet_nodes(facets)]  # (k, 4, 3)
    tol = 1e-9 * float(np.ptp(mesh.points, axis=0).max())
    keep = np.ones(len(facets), bool)
    for axis, plane, _ in geom.mirror:
        keep &= ~np.all(np.abs(quads[..., axis] - plane) <= tol, axis=1)
    sym = geom.symmetry
    if sym is not None and geom.cyclic > 1:
        i, j, _ = AXES[sym.axis]
        rel = quads - np.array(sym.center)
        step = sym.sector_angle / (2 if sym.reflection else 1)
        for k in range(int(round(2.0 * np.pi / step))):
            gamma = sym.start + k * step
            normal = (-np.sin(gamma), np.cos(gamma))  # in-plane normal of the plane at angle gamma
            keep &= ~np.all(np.abs(rel[..., i] * normal[0] + rel[..., j] * normal[1]) <= tol, axis=1)
    return facets[keep]


def _nodal(mesh, nu: np.ndarray, volumes: np.ndarray) -> np.ndarray:
    """(n_nodes,) volume-weighted mean of the cells' nu around each node."""
    cells = np.asarray(mesh.cells)
    n = cells.shape[1]
    w = np.repeat(volumes, n)
    num = np.bincount(cells.ravel(), weights=w * np.repeat(nu, n), minlength=mesh.n_nodes)
    den = np.bincount(cells.ravel(), weights=w, minlength=mesh.n_nodes)
    return num / np.where(den > 0, den, 1.0)


def _indicator(part, x: np.ndarray, nu: np.ndarray, geom: _Geometry, y_model, y_design, cell, xi) -> np.ndarray:
    """(k,) the material's indicator at the lattice points: > 0 in the material (0 on its surface).

    Density: nodal nu interpolated, minus 1/2 (-1/2 outside the mesh). Level set: phi~ there;
    cells fixed solid or void at +-max|phi~|.
    """
    spec = part.spec
    inside = cell >= 0
    if not isinstance(spec.parameterization, BSplineGrid):
        nodal = _nodal(geom.mesh, nu, part.volumes)
        cells = np.asarray(geom.mesh.cells)
        if cells.shape[1] == 8:
            N, _ = trilinear(xi[inside])
        else:  # tets: linear between the corners (barycentric coordinates)
            N, cells = np.concatenate([1.0 - xi[inside].sum(axis=1, keepdims=True), xi[inside]], axis=1), cells[:, :4]
        out = np.full(len(cell), -0.5)
        out[inside] = np.einsum("ka,ka->k", N, nodal[cells[cell[inside]]]) - 0.5
        return out
    param = spec.parameterization
    centroids = spec.symmetry.map(part.centroids) if spec.symmetry is not None else part.centroids
    phi = param.values(x[part.x], y_design, param.box(centroids))
    if spec.skins:
        skin = np.asarray(spec.skins[0](y_model), dtype=np.float64)
        for s in spec.skins[1:]:
            skin = r_union(skin, np.asarray(s(y_model), dtype=np.float64), spec.skin_eps)
        phi = r_union(phi, skin, spec.skin_eps)
    fixed = np.full(len(cell), -1, np.int8)
    fixed[inside] = part.fixed[cell[inside]]
    top = max(float(np.abs(phi).max()), 1.0)
    return np.where(fixed == 1, top, np.where(fixed == 0, -top, phi))


def _gradient_inside(phi: np.ndarray, inside: np.ndarray, spacing: np.ndarray, shape: tuple) -> np.ndarray:
    """|grad phi| (k,) by differences between lattice neighbours inside the body only (one-sided at
    its boundary, where the values outside mean nothing)."""
    f, ok = phi.reshape(shape), inside.reshape(shape)
    total = np.zeros(shape)
    for k in range(3):
        step = np.zeros(shape)
        count = np.zeros(shape)
        lo = (slice(None),) * k + (slice(0, shape[k] - 1),)
        hi = (slice(None),) * k + (slice(1, shape[k]),)
        both = ok[lo] & ok[hi]
        diff = np.where(both, (f[hi] - f[lo]) / spacing[k], 0.0)
        for side in (lo, hi):  # the difference counts for both its ends
            step[side] += diff
            count[side] += both
        total += (step / np.maximum(count, 1)) ** 2
    return np.sqrt(total).ravel()


def _with_domain(geom: _Geometry, phi, inside, y_design, spacing, shape) -> np.ndarray:
    """The part as one field in length units: ``min(phi / |grad phi|, d)`` inside, ``-d`` outside.

    d: distance to the part's boundary (exact on the lattice points next to it); phi / |grad phi|
    is about the distance to phi's zero, so either surface, and their intersection, is placed by
    marching cubes as a distance field would place it. Both are capped at a few spacings.
    """
    cap = 2.0 * _BAND * float(spacing.max())
    grad = _gradient_inside(phi, inside, spacing, shape)
    length = phi / np.maximum(np.maximum(grad, np.abs(phi) / cap), 1e-300)
    grid = inside.reshape(shape)
    layer = np.zeros(shape, bool)
    for k in range(3):
        n = shape[k]
        differ = grid.take(range(n - 1), axis=k) != grid.take(range(1, n), axis=k)
        layer[(slice(None),) * k + (slice(0, n - 1),)] |= differ
        layer[(slice(None),) * k + (slice(1, n),)] |= differ
    layer = layer.ravel()
    triangles = boundary_triangles(geom.mesh, _open_facets(geom))
    dist = boundary_distance(triangles, y_design[layer], _BAND * float(spacing.max()))
    field = np.where(inside, length, -cap)
    field[layer] = np.where(inside[layer], np.minimum(length[layer], dist), -dist)
    return field


def _envelope_field(envelope: TriangleSurface, y_design: np.ndarray, spacing: np.ndarray) -> np.ndarray:
    """(k,) signed distance of the points (k, 3) to the body's envelope, > 0 inside, capped as in
    :func:`_with_domain`: its minimum with the part's field cuts the voxels' staircase to the envelope."""
    cap = 2.0 * _BAND * float(spacing.max())
    triangles = envelope.vertices[envelope.faces]
    dist = np.minimum(boundary_distance(triangles, y_design, _BAND * float(spacing.max())), cap)
    return np.where(inside_surface(envelope, y_design), dist, -dist)


# ----------------------------------------------------------------------------------- entry points
def _model_of(model: Model | Discretization) -> Model:
    """The Model of a Model or of its Discretization; ConfigError for anything else."""
    if isinstance(model, Discretization):
        return model.model
    if not isinstance(model, Model):
        raise ConfigError(f"the design's surface needs the Model or its Discretization, got {type(model).__name__}")
    return model


def _part(space, body: str | None):
    names = [p.spec.body for p in space.parts]
    if body is None:
        if len(names) != 1:
            raise ConfigError(f"the design has several bodies {names}: name the body whose surface to make")
        return space.parts[0]
    if body not in names:
        raise ConfigError(f"body {body!r} is not designed; designed bodies: {names}")
    return space.parts[names.index(body)]


def body_surface(space, x, model, body: str | None = None, options: SurfaceOptions | None = None) -> BodySurface:
    """The closed surface of one designed body's material at design ``x`` (see the module docstring).

    space : the :class:`~contopt.design.space.DesignSpace`; x : (n,) its design vector
    model : the Model or the Discretization the space was built on (for the meshes)
    body : the designed body (may be omitted when there is one)
    """
    clock = Stopwatch()
    options = options or SurfaceOptions()
    part = _part(space, body)
    model = _model_of(model)
    mesh = model.bodies[model.body_index(part.spec.body)].mesh
    x = space.check_x(x)
    nu = space.forward(x).nu[part.cells]
    level_set = isinstance(part.spec.parameterization, BSplineGrid)
    kind = "level set" if level_set else "density"
    geom = _geometry(mesh, part.spec.body, part.spec.symmetry, options, float(part.volumes.sum()))
    origin, spacing, shape = _lattice(geom, options.refine)
    y_model = geom.model_points(_lattice_points(origin, spacing, shape))
    y_design = geom.design_points(y_model)
    envelope = part.spec.envelope
    if level_set and geom.box and envelope is None and not np.any(part.fixed >= 0):
        cell, xi = np.zeros(len(y_design), np.int64), None  # the box is the body: nothing to locate
    else:
        cell, xi = locate_points(mesh, y_design)
    inside = cell >= 0
    if geom.box and not inside.all():
        raise ConfigError(
            f"body {part.spec.body!r}: {int(np.sum(~inside))} lattice point(s) of its bounding box "
            "were not found in its mesh"
        )
    phi = _indicator(part, x, nu, geom, y_model, y_design, cell, xi)
    field = phi if geom.box and envelope is None else _with_domain(geom, phi, inside, y_design, spacing, shape)
    if envelope is not None:
        field = np.minimum(field, _envelope_field(envelope, y_design, spacing))
    surface = lattice_surface(field.reshape(shape), origin, spacing)
    steps = DEFAULT_SMOOTHING[kind] if options.smooth is None else options.smooth
    planes = [(k, v) for k in range(3) for v in (geom.lower[k], geom.upper[k])] if geom.box else []
    surface = taubin_smooth(surface, steps, planes, tol=1e-6 * float(spacing.min()))
    grey = (nu > 0.1) & (nu < 0.9)
    return BodySurface(
        body=part.spec.body,
        kind=kind,
        surface=surface,
        volume=surface.volume,
        design_volume=float(part.volumes @ nu) * geom.copies,
        domain_volume=float(part.volumes.sum()) * geom.copies,
        copies=geom.copies,
        grey_volume=float(part.volumes[grey] @ nu[grey]) * geom.copies,
        lattice=shape,
        spacing=spacing,
        seconds=clock.seconds,
        bounds=(geom.lower, geom.upper),
    )


def design_surfaces(space, x, model, options: SurfaceOptions | None = None) -> list[BodySurface]:
    """:func:`body_surface` of every designed body, in the design's order."""
    return [body_surface(space, x, model, p.spec.body, options) for p in space.parts]


def surface_paths(out, bodies) -> list[Path]:
    """Where the surfaces of ``bodies`` go: ``out`` itself for one body, ``<stem>_<body><suffix>`` for several."""
    out = Path(out)
    bodies = list(bodies)
    if len(bodies) == 1:
        return [out]
    return [out.with_name(f"{out.stem}_{b}{out.suffix}") for b in bodies]


def write_design_surfaces(
    space, x, model, out, options: SurfaceOptions | None = None, binary: bool = True
) -> list[tuple[BodySurface, Path]]:
    """Make and write the surface of every designed body (see :func:`surface_paths` for the names).

    The format follows the suffix of ``out`` (.stl, binary unless ``binary=False``; .ply; .obj).
    Returns ``(BodySurface, path)`` per body.
    """
    surface_format(out)  # an unknown suffix fails before any work
    made = design_surfaces(space, x, model, options)
    paths = surface_paths(out, [m.body for m in made])
    for m, path in zip(made, paths):
        write_surface(
            m.surface, path, binary=binary, header=f"contopt design surface of body {m.body}, volume {m.volume:.6g}"
        )
    return list(zip(made, paths))
