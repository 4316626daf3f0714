"""Structured generators: exact volumes and areas, outward normals, sets, quality."""

import numpy as np
import pytest

from contopt.errors import MeshError
from contopt.mesh import (
    annulus,
    boundary_facets,
    box,
    cylinder,
    cylinder_shell_sector,
    merge_nodes,
    scaled_jacobian,
)

_REF = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    dtype=float,
)


def hex_volumes(mesh):
    """(m,) exact volumes of trilinear hexes (2x2x2 Gauss is exact for det J)."""
    x = mesh.points[mesh.cells]  # (m, 8, 3)
    vol = np.zeros(mesh.n_cells)
    g = 1 / np.sqrt(3)
    for xi in np.array(np.meshgrid([-g, g], [-g, g], [-g, g])).reshape(3, -1).T:
        f = 1 + _REF * xi  # (8, 3)
        dN = _REF * np.stack([f[:, 1] * f[:, 2], f[:, 0] * f[:, 2], f[:, 0] * f[:, 1]], axis=1) / 8
        vol += np.linalg.det(np.einsum("mni,nj->mij", x, dN))
    return vol


def facet_vectors(mesh, name):
    """(k, 3) vector area of each facet (exact for bilinear quads), outward by HEX_FACES."""
    p = mesh.points[mesh.facet_nodes(name)]
    return 0.5 * np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])


def facet_centres(mesh, name):
    return mesh.points[mesh.facet_nodes(name)].mean(axis=1)


def check_common(mesh, names):
    """Invariants every generated mesh must satisfy."""
    assert mesh.points.dtype == np.float64
    assert sorted(mesh.facet_sets) == sorted(names)
    assert sorted(mesh.node_sets) == sorted([*names, "all"])
    size = np.ptp(mesh.points, axis=0).max()
    merged, _, _ = merge_nodes(mesh.points, mesh.cells, 1e-10 * size)
    assert len(merged) == mesh.n_nodes, "duplicate nodes"
    assert np.array_equal(np.unique(mesh.cells), np.arange(mesh.n_nodes)), "unused nodes"
    assert np.all(hex_volumes(mesh) > 0)
    assert scaled_jacobian(mesh).min() > 0.3
    # the named facet sets partition the boundary
    sets = np.concatenate([mesh.facet_set(k) for k in names])
    assert len(np.unique(sets, axis=0)) == len(sets)
    assert np.array_equal(np.unique(sets, axis=0), boundary_facets(mesh.cells))
    for k in names:
        nodes = np.unique(mesh.facet_nodes(k))
        assert np.array_equal(mesh.node_sets[k], nodes), k
        # with the closed boundary, the vector areas of all facets sum to zero
    total = sum(facet_vectors(mesh, k).sum(axis=0) for k in names)
    assert np.allclose(total, 0.0, atol=1e-12 * size**2)


# ------------------------------------------------------------------------ box
BOX_NAMES = ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"]


def test_box_counts_volume_areas_and_normals():
    L, n, o = (2.0, 3.0, 0.5), (4, 3, 2), (1.0, -1.0, 2.0)
    mesh = box(L, n, origin=o)
    check_common(mesh, BOX_NAMES)
    assert mesh.n_nodes == 5 * 4 * 3 and mesh.n_cells == 24
    assert np.array_equal(mesh.node_sets["all"], np.arange(60))
    assert hex_volumes(mesh).sum() == pytest.approx(L[0] * L[1] * L[2], rel=1e-14)
    assert np.allclose(mesh.points.min(axis=0), o)
    assert np.allclose(mesh.points.max(axis=0), np.add(o, L))
    for axis, (lo, hi) in enumerate([("xmin", "xmax"), ("ymin", "ymax"), ("zmin", "zmax")]):
        area = np.prod([L[a] for a in range(3) if a != axis])
        for name, sign, coord in ((lo, -1, o[axis]), (hi, 1, o[axis] + L[axis])):
            vec = facet_vectors(mesh, name)
            normal = np.zeros(3)
            normal[axis] = sign
            assert np.linalg.norm(vec, axis=1).sum() == pytest.approx(area, rel=1e-14)
            assert np.allclose(vec / np.linalg.norm(vec, axis=1)[:, None], normal)
            assert np.allclose(mesh.points[mesh.node_sets[name], axis], coord)
            others = [a for a in range(3) if a != axis]
            assert len(mesh.node_sets[name]) == np.prod([n[a] + 1 for a in others])


def test_box_geometric_grading_ratio():
    mesh = box((1.0, 2.0, 3.0), (5, 1, 4), grading=4.0)
    x = np.unique(mesh.points[:, 0])
    h = np.diff(x)
    assert len(h) == 5
    assert h[-1] / h[0] == pytest.approx(4.0, rel=1e-12)
    assert np.allclose(h[1:] / h[:-1], 4.0**0.25)
    assert x[0] == 0.0 and x[-1] == 1.0
    assert np.allclose(np.unique(mesh.points[:, 1]), [0.0, 2.0])  # one cell: ratio has no effect
    assert hex_volumes(mesh).sum() == pytest.approx(6.0, rel=1e-13)


def test_box_per_axis_and_explicit_grading():
    z = np.array([0.0, 0.1, 0.3, 1.0])
    mesh = box((2.0, 1.0, 99.0), (2, 3, 99), origin=(0, 0, 5), grading=(None, 0.5, z))
    check_common(mesh, BOX_NAMES)
    assert np.allclose(np.unique(mesh.points[:, 0]), [0.0, 1.0, 2.0])
    hy = np.diff(np.unique(mesh.points[:, 1]))
    assert hy[-1] / hy[0] == pytest.approx(0.5)
    assert np.array_equal(np.unique(mesh.points[:, 2]), z)  # absolute coordinates
    assert mesh.n_cells == 2 * 3 * 3
    assert hex_volumes(mesh).sum() == pytest.approx(2.0, rel=1e-13)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(divisions=(0, 1, 1)), "nx must be a positive integer"),
        (dict(divisions=(1.5, 1, 1)), "nx must be a positive integer"),
        (dict(lengths=(1, -1, 1)), r"lengths\[y\] must be a positive"),
        (dict(grading=-2.0), "grading for axis x"),
        (dict(grading=(None, None, [0.0, 1.0, 0.5])), "strictly increasing"),
        (dict(grading=(1.0, 2.0)), "sequence of 3"),
    ],
)
def test_box_rejects_bad_arguments(kwargs, match):
    with pytest.raises(MeshError, match=match):
        box(**kwargs)


# ------------------------------------------------------------------- annulus
ANNULUS_NAMES = ["inner", "outer", "zmin", "zmax"]


def radial(mesh, name, centre=(0.0, 0.0)):
    """Unit radial direction (in x-y) at each facet centre."""
    c = facet_centres(mesh, name)[:, :2] - centre
    return c / np.linalg.norm(c, axis=1)[:, None]


def test_full_ring_merges_the_seam_and_has_exact_polygonal_volume():
    ri, ro, L, (nt, nr, nz) = 0.5, 1.2, 0.7, (12, 3, 2)
    mesh = annulus(ri, ro, L, (nt, nr, nz), center=(1.0, 2.0, 3.0))
    check_common(mesh, ANNULUS_NAMES)
    assert mesh.n_nodes == nt * (nr + 1) * (nz + 1)  # no seam duplicates
    assert mesh.n_cells == nt * nr * nz
    dt = 2 * np.pi / nt
    polygonal = nt * 0.5 * np.sin(dt) * (ro**2 - ri**2) * L
    assert hex_volumes(mesh).sum() == pytest.approx(polygonal, rel=1e-13)
    assert polygonal == pytest.approx(np.pi * (ro**2 - ri**2) * L, rel=0.05)
    # outer surface: chords of length 2 ro sin(dt/2)
    out = facet_vectors(mesh, "outer")
    assert np.linalg.norm(out, axis=1).sum() == pytest.approx(nt * 2 * ro * np.sin(dt / 2) * L, rel=1e-13)
    assert np.all(np.einsum("ki,ki->k", out[:, :2], radial(mesh, "outer", (1.0, 2.0))) > 0)
    inn = facet_vectors(mesh, "inner")
    assert np.all(np.einsum("ki,ki->k", inn[:, :2], radial(mesh, "inner", (1.0, 2.0))) < 0)
    assert np.allclose(np.linalg.norm(mesh.points[mesh.node_sets["outer"], :2] - [1, 2], axis=1), ro)
    zmin = facet_vectors(mesh, "zmin")
    assert np.all(zmin[:, 2] < 0) and np.allclose(zmin[:, :2], 0)
    assert np.allclose(mesh.points[mesh.node_sets["zmax"], 2], 3.0 + L / 2)


def test_ring_volume_converges_to_the_annulus():
    exact = np.pi * (1.0 - 0.25)
    errors = [abs(hex_volumes(annulus(0.5, 1.0, 1.0, (n, 1, 1))).sum() - exact) / exact for n in (8, 16, 32)]
    assert errors[0] > errors[1] > errors[2]
    assert errors[1] / errors[2] == pytest.approx(4.0, rel=0.02)  # second order in 1/n
    assert errors[2] < 7e-3


def test_annular_sector_sets_and_volume():
    t0, t1 = 0.3, 1.5
    ri, ro, L, (nt, nr, nz) = 1.0, 2.0, 0.5, (6, 2, 1)
    mesh = annulus(ri, ro, L, (nt, nr, nz), theta=(t0, t1))
    check_common(mesh, [*ANNULUS_NAMES, "theta_start", "theta_end"])
    assert mesh.n_nodes == (nt + 1) * (nr + 1) * (nz + 1)
    polygonal = nt * 0.5 * np.sin((t1 - t0) / nt) * (ro**2 - ri**2) * L
    assert hex_volumes(mesh).sum() == pytest.approx(polygonal, rel=1e-13)
    for name, t, sign in (("theta_start", t0, -1), ("theta_end", t1, 1)):
        p = mesh.points[mesh.node_sets[name]]
        assert np.allclose(np.arctan2(p[:, 1], p[:, 0]), t)
        tangent = np.array([-np.sin(t), np.cos(t), 0.0])
        vec = facet_vectors(mesh, name)
        assert np.allclose(vec / np.linalg.norm(vec, axis=1)[:, None], sign * tangent)
        assert np.linalg.norm(vec, axis=1).sum() == pytest.approx((ro - ri) * L)


def test_annulus_rejects_bad_arguments():
    with pytest.raises(MeshError, match="n_theta >= 3"):
        annulus(0.5, 1.0, 1.0, (2, 1, 1))
    with pytest.raises(MeshError, match="r_inner .* must be smaller"):
        annulus(1.0, 1.0, 1.0)
    with pytest.raises(MeshError, match="theta must satisfy"):
        annulus(0.5, 1.0, 1.0, theta=(0.0, 7.0))


# ------------------------------------------------------------------ cylinder
@pytest.mark.parametrize("n, nr, nz", [(1, 1, 1), (2, 1, 3), (4, 2, 2), (6, 3, 1)])
def test_cylinder_counts_volume_area_and_quality(n, nr, nz):
    R, L, c = 0.8, 1.5, np.array([0.5, -0.5, 1.0])
    mesh = cylinder(R, L, (n, nr, nz), center=c)
    check_common(mesh, ["outer", "zmin", "zmax"])
    per_layer = (n + 1) ** 2 + 4 * n * nr
    assert mesh.n_nodes == per_layer * (nz + 1)
    assert mesh.n_cells == (n * n + 4 * n * nr) * nz
    m = 4 * n  # the circle is a regular m-gon
    assert hex_volumes(mesh).sum() == pytest.approx(0.5 * m * R**2 * np.sin(2 * np.pi / m) * L, rel=1e-12)
    out = facet_vectors(mesh, "outer")
    assert len(out) == m * nz
    assert np.linalg.norm(out, axis=1).sum() == pytest.approx(m * 2 * R * np.sin(np.pi / m) * L, rel=1e-12)
    cos = np.einsum("ki,ki->k", out[:, :2], radial(mesh, "outer", c[:2])) / np.linalg.norm(out, axis=1)
    assert np.allclose(cos, 1.0)  # chords: normal exactly radial at the facet centre
    assert np.allclose(np.linalg.norm(mesh.points[mesh.node_sets["outer"], :2] - c[:2], axis=1), R)
    zmin = facet_vectors(mesh, "zmin")
    assert np.all(zmin[:, 2] < 0) and np.abs(zmin[:, 2]).sum() == pytest.approx(
        0.5 * m * R**2 * np.sin(2 * np.pi / m), rel=1e-12
    )
    assert np.allclose(mesh.points[:, 2].min(), c[2] - L / 2)
    assert scaled_jacobian(mesh).min() > 0.7


def test_cylinder_volume_converges_to_pi_r2_l():
    errs = [abs(hex_volumes(cylinder(1.0, 1.0, (n, 2, 1))).sum() - np.pi) / np.pi for n in (2, 4, 8)]
    assert errs[0] > errs[1] > errs[2]
    assert errs[1] / errs[2] == pytest.approx(4.0, rel=0.02)
    assert errs[2] == pytest.approx((2 * np.pi / 32) ** 2 / 6, rel=0.01)  # 1 - sin(x)/x


def test_cylinder_rejects_core_reaching_the_circle():
    with pytest.raises(MeshError, match="core corners"):
        cylinder(1.0, 1.0, core_size=0.8, core_roundness=0.0)
    with pytest.raises(MeshError, match="core_roundness"):
        cylinder(1.0, 1.0, core_roundness=1.0)


# ------------------------------------------------------------- shell sector
SHELL_NAMES = ["outer", "inner", "arc_start", "arc_end", "side_min", "side_max"]
AXES = {  # (u, v, w) of the documented convention
    "x": ([0, 1, 0], [0, 0, 1], [1, 0, 0]),
    "y": ([1, 0, 0], [0, 0, 1], [0, 1, 0]),
    "z": ([1, 0, 0], [0, 1, 0], [0, 0, 1]),
}


def cyl_coords(points, centre, axis):
    """(r, angle, s) of points in the shell's documented convention."""
    u, v, w = (np.array(a, float) for a in AXES[axis])
    d = points - centre
    a, b = d @ u, d @ v
    return np.hypot(a, b), np.arctan2(b, a), d @ w


def test_default_shell_sector_is_a_die_touching_below():
    R, arc, W, T, n = 2.0, 0.8, 0.6, 0.25, (8, 3, 2)
    c = np.array([0.0, 0.0, 2.0])
    mesh = cylinder_shell_sector(R, arc, W, T, n, center=c)  # axis y, bottom
    check_common(mesh, SHELL_NAMES)
    assert mesh.n_nodes == 9 * 4 * 3 and mesh.n_cells == 8 * 3 * 2
    # lowest point on the outer surface, directly below the centre
    assert mesh.points[:, 2].min() == pytest.approx(c[2] - R, abs=1e-14)
    low = mesh.points[mesh.points[:, 2] == mesh.points[:, 2].min()]
    assert np.allclose(low[:, 0], 0.0)
    r, a, s = cyl_coords(mesh.points, c, "y")
    assert np.allclose(r[mesh.node_sets["outer"]], R)
    assert np.allclose(r[mesh.node_sets["inner"]], R - T)
    assert np.allclose(a[mesh.node_sets["arc_start"]], -np.pi / 2 - arc / 2)
    assert np.allclose(a[mesh.node_sets["arc_end"]], -np.pi / 2 + arc / 2)
    assert np.allclose(s[mesh.node_sets["side_min"]], -W / 2)
    assert np.allclose(s[mesh.node_sets["side_max"]], W / 2)
    polygonal = n[0] * 0.5 * np.sin(arc / n[0]) * (R**2 - (R - T) ** 2) * W
    assert hex_volumes(mesh).sum() == pytest.approx(polygonal, rel=1e-13)
    out = facet_vectors(mesh, "outer")
    assert np.linalg.norm(out, axis=1).sum() == pytest.approx(n[0] * 2 * R * np.sin(arc / n[0] / 2) * W, rel=1e-13)
    assert np.all(out[:, 2] < 0)  # the contact surface faces down, towards the slab
    side = facet_vectors(mesh, "side_max")
    assert np.allclose(side / np.linalg.norm(side, axis=1)[:, None], [0, 1, 0])


@pytest.mark.parametrize("axis", ["x", "y", "z"])
@pytest.mark.parametrize("outward", [True, False])
def test_shell_sector_axes_orientation_and_outward(axis, outward):
    R, T, mid = 1.0, 0.2, 0.4
    c = np.array([0.3, -0.2, 0.1])
    mesh = cylinder_shell_sector(R, 1.0, 0.5, T, (4, 2, 1), center=c, axis=axis, mid_angle=mid, outward=outward)
    check_common(mesh, SHELL_NAMES)
    r, a, s = cyl_coords(mesh.points, c, axis)
    lo, hi = (R - T, R) if outward else (R, R + T)
    assert np.allclose(r[mesh.node_sets["outer"]], hi)
    assert np.allclose(r[mesh.node_sets["inner"]], lo)
    assert np.allclose(a.min(), mid - 0.5) and np.allclose(a.max(), mid + 0.5)
    assert np.allclose([s.min(), s.max()], [-0.25, 0.25])
    u, v, w = (np.array(x, float) for x in AXES[axis])
    for name, sign in (("outer", 1), ("inner", -1)):
        vec = facet_vectors(mesh, name)
        d = facet_centres(mesh, name) - c
        d -= np.outer(d @ w, w)
        assert np.all(sign * np.einsum("ki,ki->k", vec, d) > 0), name


def test_shell_sector_rejects_bad_arguments():
    with pytest.raises(MeshError, match="arc must be below 2\\*pi"):
        cylinder_shell_sector(1.0, 7.0, 1.0, 0.1)
    with pytest.raises(MeshError, match="thickness .* smaller than radius"):
        cylinder_shell_sector(1.0, 1.0, 1.0, 1.0)
    with pytest.raises(MeshError, match="axis must be one of"):
        cylinder_shell_sector(1.0, 1.0, 1.0, 0.1, axis="w")
    # outward=False allows a thickness beyond the radius
    assert cylinder_shell_sector(1.0, 1.0, 1.0, 2.0, outward=False).n_cells == 16


# ------------------------------------------------------------- merge_nodes
def test_merge_nodes_joins_two_boxes():
    a = box((1, 1, 1), (2, 1, 1))
    b = box((1, 1, 1), (1, 1, 1), origin=(1.0, 0.0, 0.0))
    pts = np.concatenate([a.points, b.points + 1e-13])
    cells = np.concatenate([a.cells, b.cells + a.n_nodes])
    merged, new_cells, old_to_new = merge_nodes(pts, cells, 1e-9)
    assert len(merged) == a.n_nodes + b.n_nodes - 4  # the shared face x = 1
    assert np.array_equal(merged[: a.n_nodes], a.points)  # first occurrences kept in order
    assert np.array_equal(new_cells[:2], a.cells)
    assert np.allclose(merged[new_cells], pts[cells], atol=1e-12)
    assert old_to_new.shape == (len(pts),)


@pytest.mark.parametrize(
    "make",
    [
        lambda: box((1, 1, 1), (100_000,) * 3),
        lambda: box((1, 1, 1), (2000, 2000, 2000)),
        lambda: cylinder(1.0, 1.0, divisions=(100_000, 1000, 100_000)),
        lambda: annulus(1.0, 2.0, 1.0, divisions=(10**6, 10**6, 10)),
        lambda: cylinder_shell_sector(1.0, 1.0, 1.0, 0.1, divisions=(10**6, 10**6, 10)),
    ],
)
def test_a_wildly_large_mesh_is_refused_with_the_memory_it_needs_before_allocating(make):
    import tracemalloc

    tracemalloc.start()
    try:
        with pytest.raises(
            MeshError,
            match=r"would have [0-9.e+]+ cells; an analysis of it needs at least "
            r"[0-9.]+ [KMGTPE]iB of memory and this machine has .*fewer divisions",
        ):
            make()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1_000_000  # refused from the counts alone


def test_a_model_too_large_for_this_machine_is_refused_before_it_is_discretized(monkeypatch):
    from contopt.assembly.model import Body, Dirichlet, Model
    from contopt.material import neo_hookean
    from contopt.mesh import core
    from contopt.solve.system import System

    model = Model(
        bodies=(Body("b", box((1, 1, 1), (4, 4, 4)), neo_hookean(1.0, 0.3)),), dirichlet=(Dirichlet("b", "zmin"),)
    )
    monkeypatch.setattr(core, "available_memory", lambda: 1 << 19)  # a machine of 512 KiB
    with pytest.raises(
        MeshError,
        match=r"the model would have 64 cells; .* at least 1 MiB .* this machine has "
        r"512 KiB: use coarser meshes",
    ):
        System.of(model)
