"""Structured hex8 meshes of simple shapes, with named node and facet sets.

Every generator returns a validated :class:`~contopt.mesh.core.Mesh`
(float64 points, VTK hexahedron ordering, positive corner Jacobians, no
duplicate nodes). Each named boundary surface is given both as a facet set
``(cell, local_face)`` and as a node set of the same name (the nodes of those
facets); every mesh also has the node set ``"all"``.

Generators
----------
box                    rectangular block, optionally graded per axis
cylinder_shell_sector  curved shell sector (e.g. a cylindrical die)
annulus                full ring or annular sector around the z axis
cylinder               solid circular cylinder (O-grid) along the z axis
"""

from __future__ import annotations

import logging
from numbers import Real

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from contopt.errors import MeshError
from contopt.mesh.core import (  # noqa: F401 (re-export)
    HEX_FACES,
    Mesh,
    cell_jacobian_dets,
    check_mesh_size,
    scaled_jacobian,
)

__all__ = [
    "annulus",
    "box",
    "cylinder",
    "cylinder_shell_sector",
    "merge_nodes",
    "scaled_jacobian",
]

log = logging.getLogger(__name__)

#: Local hex face (index into HEX_FACES) of each logical side of a structured
#: block whose cell (i, j, k) has nodes (i,j,k), (i+1,j,k), (i+1,j+1,k), (i,j+1,k)
#: and the same at k+1: i runs along xi, j along eta, k along zeta.
_BLOCK_FACE = {"imin": 5, "imax": 3, "jmin": 2, "jmax": 4, "kmin": 0, "kmax": 1}

#: (u, v, w) for a cylinder axis: points are ``r (cos a u + sin a v) + s w``.
_AXES = {
    "x": (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])),
    "y": (np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])),
    "z": (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])),
}


# --------------------------------------------------------------------- helpers
def merge_nodes(points, cells, tol: float):
    """Merge nodes closer than ``tol`` (absolute distance).

    Parameters
    ----------
    points : (n, 3) float
    cells : (m, k) int node indices
    tol : merge distance; clusters are formed transitively

    Returns
    -------
    points : (n', 3) float64, one node per cluster, in order of each cluster's
        lowest original index (so a mesh without duplicates is unchanged)
    cells : (m, k) int64 renumbered
    old_to_new : (n,) int64 map from old to new node index

    Unused nodes are kept; cells made degenerate by the merge are not removed
    (constructing a :class:`Mesh` from them raises).
    """
    pts = np.asarray(points, dtype=np.float64)
    cells = np.asarray(cells, dtype=np.int64)
    n = len(pts)
    if n == 0:
        return pts.copy(), cells.copy(), np.zeros(0, np.int64)
    pairs = cKDTree(pts).query_pairs(r=float(tol), output_type="ndarray")
    if len(pairs) == 0:
        return pts.copy(), cells.copy(), np.arange(n, dtype=np.int64)
    graph = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    # representative = lowest index of each cluster; keep representatives' order
    rep = np.full(labels.max() + 1, n, dtype=np.int64)
    np.minimum.at(rep, labels, np.arange(n))
    order = np.argsort(rep)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    old_to_new = rank[labels].astype(np.int64)
    return pts[rep[order]], old_to_new[cells], old_to_new


def _check_divisions(divisions, names) -> tuple[int, ...]:
    div = tuple(divisions)
    if len(div) != len(names):
        raise MeshError(f"divisions must have {len(names)} entries {names}, got {divisions!r}")
    out = []
    for name, d in zip(names, div):
        if int(d) != d or d < 1:
            raise MeshError(f"divisions: {name} must be a positive integer, got {d!r}")
        out.append(int(d))
    check_mesh_size(int(np.prod(out, dtype=object)), f"a mesh of divisions {tuple(out)}", "use fewer divisions")
    return tuple(out)


def _positive(name, value) -> float:
    value = float(value)
    if not np.isfinite(value) or value <= 0:
        raise MeshError(f"{name} must be a positive finite number, got {value!r}")
    return value


def _axis_coords(axis: str, length, n: int, origin: float, grading) -> np.ndarray:
    """(n+1,) node coordinates along one box axis (see :func:`box`)."""
    if grading is not None and np.ndim(grading) == 1:
        x = np.asarray(grading, dtype=np.float64)
        if len(x) < 2 or not np.all(np.isfinite(x)) or np.any(np.diff(x) <= 0):
            raise MeshError(
                f"grading for axis {axis}: explicit coordinates must be a finite, strictly "
                f"increasing 1D array of at least 2 values, got {x.tolist()}"
            )
        return x
    length = _positive(f"lengths[{axis}]", length)
    if grading is None:
        return origin + length * np.linspace(0.0, 1.0, n + 1)
    if not isinstance(grading, Real) or not np.isfinite(float(grading)) or grading <= 0:
        raise MeshError(
            f"grading for axis {axis} must be None, a positive ratio (last/first element "
            f"size) or a 1D array of coordinates, got {grading!r}"
        )
    if n == 1:
        return np.array([origin, origin + length])
    q = float(grading) ** (1.0 / (n - 1))
    h = q ** np.arange(n)
    x = np.concatenate([[0.0], np.cumsum(h / h.sum())])
    x[-1] = 1.0  # exact end point despite round-off in the sum
    return origin + length * x


def _block(X: np.ndarray, names: dict[str, str], periodic_i: bool = False):
    """Hex8 cells of a structured grid of nodes.

    Parameters
    ----------
    X : (n0+1, n1+1, n2+1, 3) node coordinates over logical indices (i, j, k)
    names : logical side ("imin", ..., "kmax") -> facet set name; sides not
        listed get no facet set
    periodic_i : the plane i = n0 coincides with i = 0 and is merged into it
        (its nodes are not created; the sides imin/imax are then interior)

    Returns
    -------
    points (N, 3), cells (n0*n1*n2, 8), facet_sets {name: (k, 2)}

    A left-handed grid (negative Jacobians) is reversed along k, and the
    names of kmin/kmax swapped, so that every set keeps its geometric meaning.
    """
    X = np.asarray(X, dtype=np.float64)
    n0, n1, n2 = (s - 1 for s in X.shape[:3])
    names = dict(names)
    for attempt in range(2):
        ni = n0 if periodic_i else n0 + 1
        # node numbering: i fastest, then j, then k
        idx = np.arange(ni * (n1 + 1) * (n2 + 1), dtype=np.int64).reshape(n2 + 1, n1 + 1, ni)
        idx = idx.transpose(2, 1, 0)  # (ni, n1+1, n2+1)
        if periodic_i:
            idx = np.concatenate([idx, idx[:1]], axis=0)
        points = X[:ni].transpose(2, 1, 0, 3).reshape(-1, 3)
        # cell c = i + n0*(j + n1*k)
        ck, cj, ci = (g.ravel() for g in np.meshgrid(np.arange(n2), np.arange(n1), np.arange(n0), indexing="ij"))
        cells = np.stack(
            [
                idx[ci, cj, ck],
                idx[ci + 1, cj, ck],
                idx[ci + 1, cj + 1, ck],
                idx[ci, cj + 1, ck],
                idx[ci, cj, ck + 1],
                idx[ci + 1, cj, ck + 1],
                idx[ci + 1, cj + 1, ck + 1],
                idx[ci, cj + 1, ck + 1],
            ],
            axis=1,
        )
        dets = cell_jacobian_dets(points, cells)
        if np.all(dets > 0):
            break
        if attempt == 0 and np.all(dets < 0):
            X = X[:, :, ::-1]
            names = {{"kmin": "kmax", "kmax": "kmin"}.get(side, side): name for side, name in names.items()}
            continue
        bad = int(np.nonzero((dets <= 0).any(axis=1))[0][0])
        raise MeshError(
            f"the requested geometry gives an inverted or degenerate cell {bad}; "
            "check the dimensions (e.g. a thickness or inner radius that is too large)"
        )
    side_cells = {
        "imin": ci == 0,
        "imax": ci == n0 - 1,
        "jmin": cj == 0,
        "jmax": cj == n1 - 1,
        "kmin": ck == 0,
        "kmax": ck == n2 - 1,
    }
    facet_sets = {}
    for side, name in names.items():
        if periodic_i and side in ("imin", "imax"):
            continue
        c = np.nonzero(side_cells[side])[0]
        facet_sets[name] = np.stack([c, np.full_like(c, _BLOCK_FACE[side])], axis=1)
    return points, cells, facet_sets


def _finish(points, cells, facet_sets) -> Mesh:
    """Mesh with a node set per facet set (its nodes) and node set ``all``."""
    cells = np.asarray(cells, dtype=np.int64)
    node_sets = {"all": np.arange(len(points), dtype=np.int64)}
    for name, facets in facet_sets.items():
        node_sets[name] = np.unique(cells[facets[:, 0][:, None], HEX_FACES[facets[:, 1]]])
    return Mesh(points, cells, node_sets, facet_sets)


# ------------------------------------------------------------------ generators
def box(lengths=(1.0, 1.0, 1.0), divisions=(1, 1, 1), origin=(0.0, 0.0, 0.0), grading=None) -> Mesh:
    """Rectangular block ``[ox, ox+Lx] x [oy, oy+Ly] x [oz, oz+Lz]``.

    Parameters
    ----------
    lengths : (3,) edge lengths (Lx, Ly, Lz)
    divisions : (3,) number of cells (nx, ny, nz)
    origin : (3,) the corner with the smallest coordinates
    grading : per-axis node spacing. ``None`` (uniform), one positive float
        for all three axes, or a sequence of three entries, each of which is
        ``None`` (uniform), a positive float ``r`` (geometric progression
        whose last cell along the axis is ``r`` times as long as the first)
        or a 1D array of strictly increasing absolute node coordinates along
        that axis, which then replaces that axis's ``lengths``, ``divisions``
        and ``origin``. An explicit coordinate array must always be given
        inside the three-entry sequence, e.g. ``grading=(None, None, z)``.

    Returns
    -------
    Mesh with ``(nx+1)(ny+1)(nz+1)`` nodes numbered x fastest, then y, then
    z, and ``nx*ny*nz`` cells in the same order. Facet sets and node sets
    ``xmin, xmax, ymin, ymax, zmin, zmax``; node set ``all``.
    """
    lengths = tuple(lengths)
    origin = np.asarray(origin, dtype=np.float64).reshape(-1)
    if len(lengths) != 3 or origin.shape != (3,):
        raise MeshError(f"lengths and origin must have 3 entries, got {lengths!r} and {origin.tolist()}")
    gradings: list  # per axis: None, a ratio or a coordinate array
    if grading is None or isinstance(grading, Real):
        gradings = [grading] * 3
    else:
        gradings = list(grading)
        if len(gradings) != 3:
            raise MeshError(
                "grading must be None, one ratio, or a sequence of 3 per-axis entries "
                f"(None, ratio or coordinate array), got {len(gradings)} entries"
            )
    divs = list(divisions)
    if len(divs) != 3:
        raise MeshError(f"divisions must have 3 entries (nx, ny, nz), got {divisions!r}")
    for a in range(3):
        if gradings[a] is not None and np.ndim(gradings[a]) == 1:
            divs[a] = len(gradings[a]) - 1 if len(gradings[a]) >= 2 else 1
    nx, ny, nz = _check_divisions(divs, ("nx", "ny", "nz"))
    coords = [_axis_coords(ax, lengths[a], (nx, ny, nz)[a], origin[a], gradings[a]) for a, ax in enumerate("xyz")]
    X = np.stack(np.meshgrid(*coords, indexing="ij"), axis=-1)
    names = {"imin": "xmin", "imax": "xmax", "jmin": "ymin", "jmax": "ymax", "kmin": "zmin", "kmax": "zmax"}
    return _finish(*_block(X, names))


def cylinder_shell_sector(
    radius: float,
    arc: float,
    width: float,
    thickness: float,
    divisions=(8, 2, 1),
    center=(0.0, 0.0, 0.0),
    axis: str = "y",
    mid_angle: float = -np.pi / 2,
    outward: bool = True,
) -> Mesh:
    """A sector of a thick cylindrical shell, e.g. a curved die.

    Geometry: the cylinder axis is the line through ``center`` along ``axis``.
    A point of the shell is ``center + r (cos(a) u + sin(a) v) + s w`` with

    ========  ======  ======  ======
    axis      u       v       w
    ========  ======  ======  ======
    ``"x"``   +y      +z      +x
    ``"y"``   +x      +z      +y
    ``"z"``   +x      +y      +z
    ========  ======  ======  ======

    so for ``axis="y"`` the angle ``a`` is measured in the x-z plane from +x
    (``a = 0``) towards +z, and ``a = -pi/2`` points along -z (the bottom).
    The sector spans ``a`` in ``mid_angle -+ arc/2`` and ``s`` in
    ``-+ width/2``. With ``outward=True`` (default) the surface of radius
    ``radius`` is the OUTER (convex) one and the shell extends radially
    inward: ``r`` in ``[radius - thickness, radius]``. With ``outward=False``
    the surface of radius ``radius`` is the INNER (concave) one and ``r`` is
    in ``[radius, radius + thickness]``.

    The default orientation is a die above a slab: its lowest point,
    ``center - radius * e_z``, is on the outer surface.

    Parameters
    ----------
    radius : radius of the reference surface (see ``outward``)
    arc : opening angle in radians, ``0 < arc < 2 pi``
    width : extent along the axis, centred on ``center``
    thickness : radial thickness (``< radius`` when ``outward``)
    divisions : (n_arc, n_width, n_thick) cells along the arc, the axis and
        the thickness
    center, axis, mid_angle, outward : see above

    Returns
    -------
    Mesh with facet sets and node sets ``outer`` (largest radius), ``inner``
    (smallest radius), ``arc_start`` (angle ``mid_angle - arc/2``),
    ``arc_end`` (angle ``mid_angle + arc/2``), ``side_min`` and ``side_max``
    (the flat ends at ``s = -width/2`` and ``s = +width/2`` along the axis),
    and node set ``all``.
    """
    n_arc, n_w, n_t = _check_divisions(divisions, ("n_arc", "n_width", "n_thick"))
    radius = _positive("radius", radius)
    width = _positive("width", width)
    thickness = _positive("thickness", thickness)
    arc = _positive("arc", arc)
    if arc >= 2 * np.pi:
        raise MeshError(f"arc must be below 2*pi (use annulus for a full ring), got {arc}")
    if axis not in _AXES:
        raise MeshError(f"axis must be one of 'x', 'y', 'z', got {axis!r}")
    if outward and thickness >= radius:
        raise MeshError(f"thickness {thickness} must be smaller than radius {radius} when outward=True")
    u, v, w = _AXES[axis]
    c = np.asarray(center, dtype=np.float64).reshape(3)
    r0, r1 = (radius - thickness, radius) if outward else (radius, radius + thickness)
    a = mid_angle - arc / 2 + arc * np.linspace(0.0, 1.0, n_arc + 1)
    s = width * (np.linspace(0.0, 1.0, n_w + 1) - 0.5)
    r = np.linspace(r0, r1, n_t + 1)
    A, S, R = np.meshgrid(a, s, r, indexing="ij")
    X = c + (R * np.cos(A))[..., None] * u + (R * np.sin(A))[..., None] * v + S[..., None] * w
    names = {
        "imin": "arc_start",
        "imax": "arc_end",
        "jmin": "side_min",
        "jmax": "side_max",
        "kmin": "inner",
        "kmax": "outer",
    }
    return _finish(*_block(X, names))


def annulus(
    r_inner: float,
    r_outer: float,
    length: float,
    divisions=(16, 2, 2),
    theta=(0.0, 2 * np.pi),
    center=(0.0, 0.0, 0.0),
) -> Mesh:
    """Thick ring (or annular sector) around the z axis.

    Occupies ``r_inner <= r <= r_outer``, ``theta[0] <= theta <= theta[1]``
    (angle from +x towards +y) and ``z`` in ``center_z -+ length/2``, with
    the axis through ``(center_x, center_y)``. When ``theta`` spans exactly
    ``2 pi`` the ring is closed: the nodes of the seam are shared (no
    duplicates) and there are no ``theta_*`` sets.

    Parameters
    ----------
    r_inner, r_outer : radii, ``0 < r_inner < r_outer``
    length : extent along z
    divisions : (n_theta, n_r, n_z) cells around, across and along; a closed
        ring needs ``n_theta >= 3``
    theta : (start, end) angles in radians, ``0 < end - start <= 2 pi``
    center : (3,) centre of the ring

    Returns
    -------
    Mesh with facet sets and node sets ``inner``, ``outer``, ``zmin``,
    ``zmax`` and, for a sector, ``theta_start`` and ``theta_end``; node set
    ``all``.
    """
    n_th, n_r, n_z = _check_divisions(divisions, ("n_theta", "n_r", "n_z"))
    r_inner = _positive("r_inner", r_inner)
    r_outer = _positive("r_outer", r_outer)
    length = _positive("length", length)
    if r_inner >= r_outer:
        raise MeshError(f"r_inner {r_inner} must be smaller than r_outer {r_outer}")
    t0, t1 = (float(t) for t in theta)
    span = t1 - t0
    closed = abs(span - 2 * np.pi) <= 1e-12 * 2 * np.pi
    if span <= 0 or (span > 2 * np.pi and not closed):
        raise MeshError(f"theta must satisfy 0 < end - start <= 2*pi, got {theta!r}")
    if closed and n_th < 3:
        raise MeshError(f"a closed ring needs n_theta >= 3, got {n_th}")
    c = np.asarray(center, dtype=np.float64).reshape(3)
    t = t0 + span * np.linspace(0.0, 1.0, n_th + 1)
    r = np.linspace(r_inner, r_outer, n_r + 1)
    z = c[2] + length * (np.linspace(0.0, 1.0, n_z + 1) - 0.5)
    T, R, Z = np.meshgrid(t, r, z, indexing="ij")
    X = np.stack([c[0] + R * np.cos(T), c[1] + R * np.sin(T), Z], axis=-1)
    names = {
        "imin": "theta_start",
        "imax": "theta_end",
        "jmin": "inner",
        "jmax": "outer",
        "kmin": "zmin",
        "kmax": "zmax",
    }
    return _finish(*_block(X, names, periodic_i=closed))


def _ogrid_disk(radius: float, n: int, n_r: int, core_size: float, roundness: float):
    """2D O-grid of a disk centred at the origin.

    Returns points (N, 2), quads (Q, 4) counter-clockwise, and outer_quads
    (4n,) indices of the quads whose local edge 1 (nodes 1-2) is on the
    circle.
    """
    # Angle-uniform parameters so that the core boundary nodes, hence the
    # radial ring lines and the nodes on the circle, are equally spaced in angle.
    phi = np.linspace(-np.pi / 4, np.pi / 4, n + 1)
    xi = np.tan(phi)
    xi[0], xi[-1] = -1.0, 1.0
    XI, ETA = np.meshgrid(xi, xi, indexing="xy")  # [j, i] -> (xi_i, eta_j)
    rho = np.maximum(np.abs(XI), np.abs(ETA))
    d = np.hypot(XI, ETA)
    # Blend each square level set towards a circle: radius (1-b) d + b rho.
    # roundness b=0 is a square core (sharp ring corners), b=1 a round core
    # (flat, degenerate core corners).
    f = np.where(d > 0, (1 - roundness) + roundness * rho / np.where(d > 0, d, 1.0), 1.0)
    a = core_size * radius
    core = np.stack([a * XI * f, a * ETA * f], axis=-1).reshape(-1, 2)  # node c(i,j) = i + (n+1) j
    cidx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)  # [j, i]
    qi, qj = (g.ravel() for g in np.meshgrid(np.arange(n), np.arange(n), indexing="xy"))
    core_quads = np.stack([cidx[qj, qi], cidx[qj, qi + 1], cidx[qj + 1, qi + 1], cidx[qj + 1, qi]], axis=1)
    # core boundary, counter-clockwise from the corner (1, -1)
    loop = np.concatenate(
        [
            cidx[np.arange(0, n), n],  # xi = +1, eta rising
            cidx[n, np.arange(n, 0, -1)],  # eta = +1, xi falling
            cidx[np.arange(n, 0, -1), 0],  # xi = -1, eta falling
            cidx[0, np.arange(0, n)],  # eta = -1, xi rising
        ]
    )
    m = 4 * n
    theta = -np.pi / 4 + np.arange(m) * (np.pi / (2 * n))
    rb = np.linalg.norm(core[loop], axis=1)
    direction = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    layers = [core[loop] + (t / n_r) * (radius - rb)[:, None] * direction for t in range(1, n_r)]
    layers.append(radius * direction)
    ring_pts = np.concatenate(layers, axis=0)
    n_core = len(core)
    ridx = np.empty((n_r + 1, m), dtype=np.int64)
    ridx[0] = loop
    ridx[1:] = n_core + np.arange(n_r * m).reshape(n_r, m)
    S, T = (g.ravel() for g in np.meshgrid(np.arange(m), np.arange(n_r), indexing="xy"))
    S1 = (S + 1) % m
    ring_quads = np.stack([ridx[T, S], ridx[T + 1, S], ridx[T + 1, S1], ridx[T, S1]], axis=1)
    points = np.concatenate([core, ring_pts], axis=0)
    quads = np.concatenate([core_quads, ring_quads], axis=0)
    outer = len(core_quads) + np.nonzero(T == n_r - 1)[0]
    return points, quads, outer


def cylinder(
    radius: float,
    length: float,
    divisions=(4, 2, 4),
    center=(0.0, 0.0, 0.0),
    core_size: float = 0.5,
    core_roundness: float = 0.5,
) -> Mesh:
    """Solid circular cylinder along z, meshed with an O-grid.

    The cross-section is a core block of ``n_core x n_core`` cells (a square
    of half-width ``core_size * radius`` whose sides are bulged towards a
    circle by ``core_roundness``) surrounded by a ring of ``n_r`` cells
    radially and ``4 n_core`` cells around; the nodes on the circle are
    equally spaced in angle and ring lines are radial. The cross-section is
    extruded over ``z`` in ``center_z -+ length/2`` with ``n_z`` layers.

    Parameters
    ----------
    radius, length : cylinder radius and extent along z
    divisions : (n_core, n_r, n_z)
    center : (3,) centre of the cylinder
    core_size : half-width of the core square relative to ``radius``, in (0, 1)
    core_roundness : 0 (square core) .. 1 (round core, degenerate core
        corners, not allowed); the default 0.5 gives scaled Jacobians above
        about 0.5

    Returns
    -------
    Mesh with ``(n_core+1)^2 + 4 n_core n_r`` nodes per layer and
    ``(n_core^2 + 4 n_core n_r) n_z`` cells; facet sets and node sets
    ``outer``, ``zmin``, ``zmax``; node set ``all``. The circle is
    approximated by a polygon of ``4 n_core`` sides.
    """
    n, n_r, n_z = _check_divisions(divisions, ("n_core", "n_r", "n_z"))
    radius = _positive("radius", radius)
    length = _positive("length", length)
    if not 0 < core_size < 1:
        raise MeshError(f"core_size must be in (0, 1), got {core_size}")
    if not 0 <= core_roundness < 1:
        raise MeshError(f"core_roundness must be in [0, 1), got {core_roundness}")
    if core_size * (1 + (np.sqrt(2) - 1) * (1 - core_roundness)) >= 1:
        raise MeshError(
            f"the core corners (core_size {core_size}, core_roundness {core_roundness}) "
            "reach the outer circle; lower core_size or raise core_roundness"
        )
    c = np.asarray(center, dtype=np.float64).reshape(3)
    p2, q2, outer2 = _ogrid_disk(radius, n, n_r, core_size, core_roundness)
    z = c[2] + length * (np.linspace(0.0, 1.0, n_z + 1) - 0.5)
    n2, nq = len(p2), len(q2)
    points = np.concatenate([np.column_stack([p2 + c[:2], np.full(n2, zk)]) for zk in z], axis=0)
    k = np.arange(n_z)
    bottom = (q2[None, :, :] + (k * n2)[:, None, None]).reshape(-1, 4)
    cells = np.concatenate([bottom, bottom + n2], axis=1)  # cell = k * nq + q
    outer_cells = (outer2[None, :] + (k * nq)[:, None]).ravel()
    facet_sets = {
        "outer": np.stack([outer_cells, np.full_like(outer_cells, 3)], axis=1),  # 2D edge 1 -> face 3
        "zmin": np.stack([np.arange(nq), np.zeros(nq, np.int64)], axis=1),
        "zmax": np.stack([(n_z - 1) * nq + np.arange(nq), np.ones(nq, np.int64)], axis=1),
    }
    mesh = _finish(points, cells, facet_sets)
    log.debug("cylinder O-grid: min scaled Jacobian %.3f", scaled_jacobian(mesh).min())
    return mesh
