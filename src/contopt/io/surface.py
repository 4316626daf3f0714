"""Closed triangle surfaces: iso-surfaces of lattice fields, smoothing, checks and STL / PLY / OBJ files.

Pure geometry (no design or mesh knowledge), used by :mod:`contopt.design.surface`:

* :func:`lattice_surface`: the surface ``F = 0`` of a field sampled on a regular lattice,
  ``F > 0`` inside, by marching cubes (Lewiner's, ``skimage.measure.marching_cubes``). The
  lattice is padded with one layer of void, so the surface is closed (watertight) even
  where the solid reaches the lattice's outer planes; those caps lie on the outer planes.
* :func:`taubin_smooth`: Taubin's lambda/mu smoothing, vertices on given planes kept on
  them, and the enclosed volume restored afterwards by an offset along the vertex normals.
* :func:`check_surface`: watertight (every edge in exactly two triangles), consistently
  oriented, no non-manifold edges or vertices, enclosed (signed) volume.
* :func:`write_surface` / :func:`read_surface`: binary (default) or ASCII STL, PLY, OBJ.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from contopt.errors import ConfigError

#: file formats by suffix
FORMATS = (".stl", ".ply", ".obj")
#: Taubin's pass-band parameters (lambda > 0, mu < -lambda): smoothing without shrinkage
TAUBIN_LAMBDA, TAUBIN_MU = 0.5, -0.53
#: cap vertices this close to the lattice's outer planes (in spacings) are put onto them
CAP_TOL = 1e-5
_STL_RECORD = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attribute", "<u2")])


@dataclass(frozen=True, eq=False)
class TriangleSurface:
    """A triangle surface.

    vertices : (n, 3) float64 coordinates; faces : (m, 3) int64 vertex indices, counter-clockwise
    seen from outside (right-hand rule gives the outward normal)
    """

    vertices: np.ndarray
    faces: np.ndarray

    def __post_init__(self):
        v = np.asarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        f = np.asarray(self.faces, dtype=np.int64).reshape(-1, 3)
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise ConfigError(f"surface faces index vertices 0..{len(v) - 1}, got {f.min()}..{f.max()}")
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    def corners(self) -> np.ndarray:
        """(m, 3, 3) the coordinates of each face's corners."""
        return self.vertices[self.faces]

    def face_normals(self) -> np.ndarray:
        """(m, 3) area-weighted normals (length = twice the face area)."""
        c = self.corners()
        return np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])

    @property
    def area(self) -> float:
        return float(0.5 * np.linalg.norm(self.face_normals(), axis=1).sum())

    @property
    def volume(self) -> float:
        """Enclosed volume by the divergence theorem (positive for outward-oriented closed surfaces)."""
        c = self.corners()
        return float(np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])).sum() / 6.0)

    def transformed(self, matrix=None, shift=None) -> TriangleSurface:
        """``x -> A x + b``; a reflection (det A < 0) reverses the faces so they stay outward."""
        A = np.eye(3) if matrix is None else np.asarray(matrix, dtype=np.float64)
        b = np.zeros(3) if shift is None else np.asarray(shift, dtype=np.float64)
        faces = self.faces[:, ::-1] if np.linalg.det(A) < 0 else self.faces
        return TriangleSurface(self.vertices @ A.T + b, faces)


def merge(surfaces) -> TriangleSurface:
    """One surface holding all the given ones (vertices are not welded)."""
    verts, faces, offset = [], [], 0
    for s in surfaces:
        verts.append(s.vertices)
        faces.append(s.faces + offset)
        offset += s.n_vertices
    if not verts:
        return TriangleSurface(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    return TriangleSurface(np.concatenate(verts), np.concatenate(faces))


# ---------------------------------------------------------------------------------- marching cubes
def lattice_surface(field: np.ndarray, origin, spacing) -> TriangleSurface:
    """The closed surface ``field = 0`` of a lattice field (``> 0`` inside), outward oriented.

    field : (n_x, n_y, n_z) values at ``origin + (i, j, k) * spacing``; origin, spacing : (3,)

    The field is padded with one layer of strongly negative values, so the solid is closed
    at the lattice's outer planes and its caps lie on them. Values within 1e-3 of the typical
    jump across the surface (the median ``|F_a - F_b|`` over lattice edges that change sign)
    from zero count as void by that margin: marching cubes would otherwise put several vertices
    on one lattice point (zero-area triangles); the surface moves by about 1e-3 spacings there.
    Returns an empty surface when no value is positive.
    """
    from skimage.measure import marching_cubes

    F = np.asarray(field, dtype=np.float64)
    if F.ndim != 3 or min(F.shape) < 1:
        raise ConfigError(f"a lattice field must be a 3-D array, got shape {F.shape}")
    if not np.all(np.isfinite(F)):
        raise ConfigError("the lattice field has non-finite values")
    spacing = np.asarray(spacing, dtype=np.float64)
    origin = np.asarray(origin, dtype=np.float64)
    top = float(np.abs(F).max()) if F.size else 0.0
    if not np.any(F > 0) or top == 0.0:
        return TriangleSurface(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    tiny = 1e-3 * _jump(F)
    F = np.where(np.abs(F) < tiny, -tiny, F)
    padded = np.pad(F, 1, constant_values=-1e6 * top)  # float32 inside skimage: 1e6 keeps 7 digits
    verts, faces, _, _ = marching_cubes(
        padded.astype(np.float32), 0.0, gradient_direction="ascent", allow_degenerate=True
    )
    verts = (_on_edges(np.asarray(verts, dtype=np.float64), padded) - 1.0) * spacing + origin
    upper = origin + (np.array(F.shape) - 1) * spacing
    return _snap_caps(verts, np.asarray(faces, dtype=np.int64), origin, upper, CAP_TOL * spacing)


def _jump(F: np.ndarray) -> float:
    """The median ``|F_a - F_b|`` over lattice edges whose ends have opposite signs (max |F| if none)."""
    jumps: list[np.ndarray] = []
    for k in range(3):
        a, b = np.moveaxis(F, k, 0)[:-1], np.moveaxis(F, k, 0)[1:]
        change = (a > 0) != (b > 0)
        jumps.append(np.abs(a - b)[change])
    every = np.concatenate(jumps)
    return float(np.median(every)) if every.size else float(np.abs(F).max())


def _on_edges(verts: np.ndarray, field: np.ndarray) -> np.ndarray:
    """Vertices (index coordinates) placed on their lattice edges again in float64.

    skimage interpolates in float32; each vertex lies on the lattice edge along the axis of its
    largest fractional coordinate, where ``t = F_a / (F_a - F_b)`` is recomputed from the float64
    field. Vertices on a lattice point (no fractional part) stay.
    """
    base = np.rint(verts)
    frac = np.abs(verts - base)
    axis = np.argmax(frac, axis=1)
    rows = np.flatnonzero(frac[np.arange(len(verts)), axis] > 0)
    if len(rows) == 0:
        return verts
    lower = base[rows].astype(np.int64)
    ax = axis[rows]
    lower[np.arange(len(rows)), ax] = np.floor(verts[rows, ax]).astype(np.int64)
    upper = lower.copy()
    upper[np.arange(len(rows)), ax] += 1
    fa, fb = field[tuple(lower.T)], field[tuple(upper.T)]
    ok = (fa > 0) != (fb > 0)  # a sign change along the edge, as marching cubes saw it
    out = verts.copy()
    t = fa[ok] / (fa[ok] - fb[ok])
    out[rows[ok], ax[ok]] = lower[ok, ax[ok]] + t
    out[rows[ok]] = np.where(np.arange(3) == ax[ok][:, None], out[rows[ok]], lower[ok])
    return out


def _snap_caps(verts: np.ndarray, faces: np.ndarray, lower, upper, tol) -> TriangleSurface:
    """Put the caps exactly on the lattice's outer planes and close its edges and corners.

    Against the void padding a cap vertex sits 1e-6 of a spacing outside its plane; where the
    solid reaches an edge (corner) of the lattice box, each lattice point there has two (three)
    such vertices with slivers between them. Snapping the vertices onto the planes makes those
    vertices identical: they are welded and the slivers, now with a repeated vertex, dropped.
    """
    verts = verts.copy()
    for bound in (lower, upper):
        near = np.abs(verts - bound) <= tol
        verts[near] = np.broadcast_to(bound, verts.shape)[near]
    unique, inverse = np.unique(verts, axis=0, return_inverse=True)
    faces = inverse.ravel()[faces]
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    faces = faces[keep]
    used, compact = np.unique(faces, return_inverse=True)
    return TriangleSurface(unique[used], compact.reshape(-1, 3))


# ---------------------------------------------------------------------------------- smoothing
def adjacency(surface: TriangleSurface) -> sp.csr_matrix:
    """(n, n) row-normalized vertex adjacency (the umbrella operator's averaging part)."""
    f = surface.faces
    i = np.concatenate([f[:, 0], f[:, 1], f[:, 2], f[:, 1], f[:, 2], f[:, 0]])
    j = np.concatenate([f[:, 1], f[:, 2], f[:, 0], f[:, 0], f[:, 1], f[:, 2]])
    n = surface.n_vertices
    A = sp.csr_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    A.data[:] = 1.0  # an edge shared by two faces counts once
    deg = np.asarray(A.sum(axis=1)).ravel()
    return sp.diags(1.0 / np.maximum(deg, 1.0)) @ A


def vertex_normals(surface: TriangleSurface) -> np.ndarray:
    """(n, 3) unit normals: the area-weighted mean of the adjacent faces' normals."""
    fn = surface.face_normals()
    out = np.zeros_like(surface.vertices)
    for k in range(3):
        np.add.at(out, surface.faces[:, k], fn)
    norm = np.linalg.norm(out, axis=1, keepdims=True)
    return out / np.where(norm > 0, norm, 1.0)


def _plane_projector(vertices: np.ndarray, planes, tol: float):
    """A function removing, for each vertex on a kept plane, the motion off that plane."""
    on = []
    for axis, value in planes:
        on.append((int(axis), np.abs(vertices[:, int(axis)] - float(value)) <= tol))

    def project(delta: np.ndarray) -> np.ndarray:
        for axis, mask in on:
            delta[mask, axis] = 0.0
        return delta

    return project


def taubin_smooth(
    surface: TriangleSurface, iterations: int, planes=(), tol: float = 0.0, keep_volume: bool = True
) -> TriangleSurface:
    """Taubin lambda/mu smoothing (lambda 0.5, mu -0.53) of ``iterations`` double steps.

    planes : ``(axis, value)`` pairs: vertices within ``tol`` of such a plane move only within it
        (caps on the design domain's faces stay flat and in place)
    keep_volume : afterwards, offset the vertices along their normals (projected onto their
        planes) so that the enclosed volume is the one before smoothing (to 1e-10 relative)
    """
    if not isinstance(iterations, (int, np.integer)) or iterations < 0:
        raise ConfigError(f"smoothing iterations must be an integer >= 0, got {iterations!r}")
    if iterations == 0 or surface.n_faces == 0:
        return surface
    W = adjacency(surface)
    project = _plane_projector(surface.vertices, planes, tol)
    v = surface.vertices.copy()
    for _ in range(iterations):
        for factor in (TAUBIN_LAMBDA, TAUBIN_MU):
            v += factor * project(W @ v - v)
    out = TriangleSurface(v, surface.faces)
    if keep_volume:
        out = _restore_volume(out, surface.volume, project)
    return out


def _restore_volume(surface: TriangleSurface, target: float, project, steps: int = 8) -> TriangleSurface:
    """Offset along (projected) vertex normals until the enclosed volume is ``target``.

    dV/ddelta is the sum over vertices of (projected normal) . (a third of the adjacent area
    vectors); a few Newton steps reach round-off because V is cubic in delta.
    """
    v = surface.vertices.copy()
    for _ in range(steps):
        s = TriangleSurface(v, surface.faces)
        gap = target - s.volume
        if abs(gap) <= 1e-12 * max(abs(target), 1e-300):
            break
        fn = s.face_normals() / 6.0  # dV/dv = (1/6) sum of the adjacent faces' cross products
        grad = np.zeros_like(v)
        for k in range(3):
            np.add.at(grad, s.faces[:, k], fn)
        direction = project(vertex_normals(s))
        rate = float(np.sum(direction * grad))
        if rate <= 0:
            break
        v = v + (gap / rate) * direction
    return TriangleSurface(v, surface.faces)


# ---------------------------------------------------------------------------------- checks
@dataclass(frozen=True)
class SurfaceCheck:
    """What :func:`check_surface` found.

    boundary_edges : edges in one triangle only (0 for a watertight surface)
    nonmanifold_edges : edges in more than two triangles
    misoriented_edges : edges whose two triangles run through them in the same direction
    nonmanifold_vertices : vertices whose triangles form more than one fan (two solids touching there)
    degenerate_faces : triangles with a repeated vertex or (numerically) zero area
    components : connected pieces; volume : enclosed volume (> 0: normals point outward); area
    """

    n_vertices: int
    n_faces: int
    boundary_edges: int
    nonmanifold_edges: int
    misoriented_edges: int
    nonmanifold_vertices: int
    degenerate_faces: int
    components: int
    volume: float
    area: float

    @property
    def watertight(self) -> bool:
        return self.boundary_edges == 0 and self.nonmanifold_edges == 0

    @property
    def manifold(self) -> bool:
        return self.nonmanifold_edges == 0 and self.nonmanifold_vertices == 0

    @property
    def oriented(self) -> bool:
        return self.misoriented_edges == 0

    @property
    def ok(self) -> bool:
        """Watertight, manifold, consistently oriented with outward normals, no degenerate faces."""
        return (
            self.n_faces > 0
            and self.watertight
            and self.manifold
            and self.oriented
            and self.degenerate_faces == 0
            and self.volume > 0
        )

    def problems(self) -> list[str]:
        out = [
            f"{n} {what}"
            for n, what in (
                (self.boundary_edges, "open edges"),
                (self.nonmanifold_edges, "non-manifold edges"),
                (self.misoriented_edges, "inconsistently oriented edges"),
                (self.nonmanifold_vertices, "non-manifold vertices"),
                (self.degenerate_faces, "degenerate faces"),
            )
            if n
        ]
        if self.n_faces and self.volume <= 0:
            out.append(f"normals point inward (volume {self.volume:.6g})")
        return out


def _components(n: int, edges: np.ndarray) -> tuple[int, np.ndarray]:
    graph = sp.csr_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)


def _fans(faces: np.ndarray, n_vertices: int) -> int:
    """Vertices whose incident triangles form more than one fan (connected by shared edges).

    Node (v, a) of the link graph stands for the edge v-a; each triangle (v, a, b) joins (v, a)
    and (v, b). A manifold vertex's link is one connected cycle.
    """
    v = faces.ravel()
    a = np.roll(faces, -1, axis=1).ravel()
    b = np.roll(faces, -2, axis=1).ravel()
    keys, inverse = np.unique(np.concatenate([np.stack([v, a], 1), np.stack([v, b], 1)]), axis=0, return_inverse=True)
    inverse = inverse.ravel()
    m = len(v)
    _, label = _components(len(keys), np.stack([inverse[:m], inverse[m:]], 1))
    per_vertex = np.unique(np.stack([keys[:, 0], label], 1), axis=0)[:, 0]
    return int(np.sum(np.bincount(per_vertex, minlength=n_vertices) > 1))


def check_surface(surface: TriangleSurface, area_tol: float = 1e-14) -> SurfaceCheck:
    """Edge, vertex and orientation checks of a triangle surface (see :class:`SurfaceCheck`).

    area_tol : a face is degenerate below ``area_tol`` times the squared bounding-box diagonal
    """
    f = surface.faces
    if len(f) == 0:
        return SurfaceCheck(surface.n_vertices, 0, 0, 0, 0, 0, 0, 0, 0.0, 0.0)
    directed = np.stack([f, np.roll(f, -1, axis=1)], axis=2).reshape(-1, 2)
    undirected, inverse, counts = np.unique(np.sort(directed, axis=1), axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    forward = np.bincount(inverse, weights=(directed[:, 0] < directed[:, 1]).astype(float), minlength=len(undirected))
    pairs = counts == 2
    diag = float(np.linalg.norm(np.ptp(surface.vertices, axis=0))) if surface.n_vertices else 0.0
    areas = 0.5 * np.linalg.norm(surface.face_normals(), axis=1)
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    used = np.unique(f)
    n_comp, label = _components(surface.n_vertices, undirected)
    return SurfaceCheck(
        n_vertices=surface.n_vertices,
        n_faces=len(f),
        boundary_edges=int(np.sum(counts == 1)),
        nonmanifold_edges=int(np.sum(counts > 2)),
        misoriented_edges=int(np.sum(pairs & (forward != 1))),
        nonmanifold_vertices=_fans(f, surface.n_vertices),
        degenerate_faces=int(np.sum(repeated | (areas <= area_tol * diag * diag))),
        components=int(len(np.unique(label[used]))),
        volume=surface.volume,
        area=surface.area,
    )


# ---------------------------------------------------------------------------------- files
def surface_format(path: str | os.PathLike) -> str:
    """The format of ``path`` by its suffix (".stl", ".ply", ".obj"); ConfigError for others."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise ConfigError(
            f"unknown surface file extension {Path(path).suffix or '(none)'!r} in {str(path)!r}; "
            f"use one of {', '.join(FORMATS)}"
        )
    return suffix


def _stl_bytes(surface: TriangleSurface, binary: bool, header: str) -> bytes:
    c = surface.corners()
    n = surface.face_normals()
    n = n / np.where(np.linalg.norm(n, axis=1, keepdims=True) > 0, np.linalg.norm(n, axis=1, keepdims=True), 1)
    if not binary:
        lines = [f"solid {header[:60]}"]
        for normal, tri in zip(n, c):
            lines.append("  facet normal {:.9e} {:.9e} {:.9e}\n    outer loop".format(*normal))
            lines += ["      vertex {:.9e} {:.9e} {:.9e}".format(*p) for p in tri]
            lines.append("    endloop\n  endfacet")
        lines.append(f"endsolid {header[:60]}\n")
        return "\n".join(lines).encode("ascii")
    rec = np.zeros(len(c), dtype=_STL_RECORD)
    rec["normal"], rec["vertices"] = n, c
    # a binary STL header must not start with "solid" (readers take such files for ASCII)
    text = header.encode("ascii", "replace")[:80]
    text = (b"contopt " + text)[:80] if text.lower().startswith(b"solid") else text
    return text.ljust(80, b" ") + struct.pack("<I", len(c)) + rec.tobytes()


def _ply_bytes(surface: TriangleSurface, binary: bool, header: str) -> bytes:
    fmt = "binary_little_endian" if binary else "ascii"
    head = (
        f"ply\nformat {fmt} 1.0\ncomment {header}\nelement vertex {surface.n_vertices}\n"
        "property double x\nproperty double y\nproperty double z\n"
        f"element face {surface.n_faces}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    if not binary:
        body = "".join("{!r} {!r} {!r}\n".format(*map(float, p)) for p in surface.vertices)
        body += "".join("3 {} {} {}\n".format(*t) for t in surface.faces)
        return (head + body).encode("ascii")
    face = np.zeros(surface.n_faces, dtype=[("n", "u1"), ("v", "<i4", (3,))])
    face["n"], face["v"] = 3, surface.faces
    return head.encode("ascii") + surface.vertices.astype("<f8").tobytes() + face.tobytes()


def _obj_bytes(surface: TriangleSurface, header: str) -> bytes:
    lines = [f"# {header}"]
    lines += ["v {!r} {!r} {!r}".format(*map(float, p)) for p in surface.vertices]
    lines += ["f {} {} {}".format(*(t + 1)) for t in surface.faces]
    return ("\n".join(lines) + "\n").encode("ascii")


def write_surface(
    surface: TriangleSurface, path: str | os.PathLike, binary: bool = True, header: str = "contopt design surface"
) -> Path:
    """Write ``surface`` as STL (binary by default, float32), PLY (float64) or OBJ by the suffix of ``path``.

    The file is written under a temporary name and renamed, so a reader never sees half a file.
    """
    path = Path(path)
    fmt = surface_format(path)
    if fmt == ".stl":
        data = _stl_bytes(surface, binary, header)
    elif fmt == ".ply":
        data = _ply_bytes(surface, binary, header)
    else:
        data = _obj_bytes(surface, header)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.tmp")
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError as err:
        raise ConfigError(f"cannot write {path}: {err}; choose another --out") from err
    return path


def _weld(corners: np.ndarray) -> TriangleSurface:
    """Triangles given by (m, 3, 3) corner coordinates -> a surface sharing identical vertices."""
    verts, inverse = np.unique(corners.reshape(-1, 3), axis=0, return_inverse=True)
    return TriangleSurface(verts, inverse.reshape(-1, 3))


def _read_stl(data: bytes) -> TriangleSurface:
    if len(data) >= 84:
        (count,) = struct.unpack("<I", data[80:84])
        if len(data) == 84 + count * _STL_RECORD.itemsize:
            rec = np.frombuffer(data, dtype=_STL_RECORD, count=count, offset=84)
            return _weld(rec["vertices"].astype(np.float64))
    words = data.decode("ascii", "replace").split()
    coords = []
    for k, w in enumerate(words):
        if w == "vertex":
            coords.append([float(x) for x in words[k + 1 : k + 4]])
    if not coords or len(coords) % 3:
        raise ConfigError("not an STL file: neither a binary STL of consistent size nor ASCII facets")
    return _weld(np.array(coords).reshape(-1, 3, 3))


def _ply_header(data: bytes) -> tuple[list[str], int]:
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ConfigError("not a PLY file: no 'ply' ... 'end_header' header")
    stop = data.index(b"\n", end) + 1
    return data[:stop].decode("ascii").splitlines(), stop


_PLY_TYPES = {
    "char": "i1",
    "uchar": "u1",
    "short": "<i2",
    "ushort": "<u2",
    "int": "<i4",
    "uint": "<u4",
    "float": "<f4",
    "double": "<f8",
    "int8": "i1",
    "uint8": "u1",
    "int32": "<i4",
    "uint32": "<u4",
    "float32": "<f4",
    "float64": "<f8",
}


def _read_ply(data: bytes) -> TriangleSurface:
    """PLY with a vertex element (x, y, z first, scalar properties) and triangle faces."""
    lines, start = _ply_header(data)
    binary = any(ln.startswith("format binary_little_endian") for ln in lines)
    # (name, count, properties): the header's elements in order, each property its words after "property"
    elements: list[tuple[str, int, list[list[str]]]] = []
    current: tuple[str, int, list[list[str]]] | None = None
    for ln in lines:
        w = ln.split()
        if w[:1] == ["element"]:
            current = (w[1], int(w[2]), [])
            elements.append(current)
        elif w[:1] == ["property"] and current is not None:
            current[2].append(w[1:])
    sizes = {name: n for name, n, _ in elements}
    props = {name: p for name, _, p in elements}
    if [p[-1] for p in props.get("vertex", [])][:3] != ["x", "y", "z"] or "face" not in sizes:
        raise ConfigError("PLY file without vertex x, y, z and face elements")
    if not binary:
        rows = data[start:].decode("ascii").split("\n")
        nv = sizes["vertex"]
        verts = np.array([r.split()[:3] for r in rows[:nv]], dtype=np.float64)
        faces = np.array([r.split()[1:4] for r in rows[nv : nv + sizes["face"]]], dtype=np.int64)
        return TriangleSurface(verts, faces)
    vdtype = np.dtype([(p[-1], _PLY_TYPES[p[0]]) for p in props["vertex"]])
    vert = np.frombuffer(data, dtype=vdtype, count=sizes["vertex"], offset=start)
    _, count_type, index_type, _ = props["face"][0]
    fdtype = np.dtype([("n", _PLY_TYPES[count_type]), ("v", _PLY_TYPES[index_type], (3,))])
    face = np.frombuffer(data, dtype=fdtype, count=sizes["face"], offset=start + vert.nbytes)
    if np.any(face["n"] != 3):
        raise ConfigError("PLY file with faces that are not triangles")
    return TriangleSurface(np.stack([vert["x"], vert["y"], vert["z"]], 1).astype(np.float64), face["v"])


def _read_obj(data: bytes) -> TriangleSurface:
    verts, faces = [], []
    for ln in data.decode("ascii", "replace").splitlines():
        w = ln.split()
        if w[:1] == ["v"]:
            verts.append([float(x) for x in w[1:4]])
        elif w[:1] == ["f"]:
            idx = [int(x.split("/")[0]) for x in w[1:]]
            idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
            faces += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]  # fan of a polygon
    return TriangleSurface(np.array(verts).reshape(-1, 3), np.array(faces, dtype=np.int64).reshape(-1, 3))


def read_surface(path: str | os.PathLike) -> TriangleSurface:
    """Read an STL (binary or ASCII; identical corners welded), PLY or OBJ surface."""
    path = Path(path)
    fmt = surface_format(path)
    try:
        data = path.read_bytes()
    except OSError as err:
        raise ConfigError(f"cannot read {path}: {err}") from err
    return {".stl": _read_stl, ".ply": _read_ply, ".obj": _read_obj}[fmt](data)
