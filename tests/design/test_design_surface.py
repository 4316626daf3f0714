"""Surfaces of designs: level sets and density fields with known volumes, symmetry and mirror expansion."""

import numpy as np
import pytest
from _surfaces import closed_manifold_problems  # tests/_surfaces.py (independent surface checks)

from contopt.assembly.model import Body, Model
from contopt.assembly.system import discretize
from contopt.design import BoxRegion, BSplineGrid, CyclicSymmetry, Density, Design, DesignedBody, Heaviside
from contopt.design.surface import SurfaceOptions, body_surface, surface_paths, write_design_surfaces
from contopt.errors import ConfigError
from contopt.io.surface import read_surface
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import annulus, box

MAT = neo_hookean(1.0, 0.3)


def _space(meshes: dict, designed: dict, eta: float = 10.0):
    """(space, disc) of a model with the given bodies {name: mesh} and designs {name: DesignedBody kwargs}."""
    disc = discretize(Model(bodies=tuple(Body(n, m, MAT) for n, m in meshes.items())))
    design = Design(bodies=tuple(DesignedBody(n, **kw) for n, kw in designed.items()), heaviside=Heaviside(eta))
    return design.build(disc), disc


def _closed(bs):
    assert closed_manifold_problems(bs.surface.vertices, bs.surface.faces) == []


# ------------------------------------------------------------------------------- B-spline evaluation
def test_bspline_values_match_the_matrix_inside_and_continue_linear_fields_outside(rng):
    grid = BSplineGrid((3, 2, 4))
    box_ = (np.array([0.0, -1.0, 2.0]), np.array([3.0, 2.0, 1.0]))
    d = rng.normal(size=grid.n_control)
    inside = box_[0] + rng.uniform(size=(500, 3)) * box_[1]
    np.testing.assert_allclose(grid.values(d, inside, box_), grid.matrix(inside, box_) @ d, rtol=1e-13, atol=1e-13)
    # Greville values of a linear field reproduce it inside; the continued end patches reproduce it outside
    c = np.array([0.3, -1.2, 0.7])
    linear = 0.4 + grid.greville(box_) @ c
    outside = box_[0] - 0.2 + rng.uniform(size=(500, 3)) * (box_[1] + 0.4)
    np.testing.assert_allclose(grid.values(linear, outside, box_), 0.4 + outside @ c, atol=1e-12)


# ------------------------------------------------------------------------------- level sets with known volumes
def _quadratic_fit(space, values_at):
    """Control values of a field the cubic splines reproduce (quadratics), by least squares on many points."""
    p = space.parts[0]
    grid = p.spec.parameterization
    box_ = grid.box(p.centroids)
    X = box_[0] + np.random.default_rng(0).uniform(size=(4 * grid.n_control, 3)) * box_[1]
    d, *_ = np.linalg.lstsq(grid.matrix(X, box_).toarray(), values_at(X), rcond=None)
    assert np.allclose(grid.matrix(X, box_) @ d, values_at(X), atol=1e-10)  # reproduced exactly
    return d


def test_sphere_level_set_encloses_the_sphere_volume():
    """phi = R^2 - |X - c|^2 is a quadratic, which cubic B-splines represent exactly: its zero is a
    sphere. The lattice surface is within area * h^2 / (2 R) of 4/3 pi R^3 (as for marching cubes of
    any smooth surface of curvature 1/R: chords of up to sqrt(3) h have a sagitta of 3 h^2 / (8 R))."""
    center, R = np.array([1.0, 1.0, 0.75]), 0.55
    space, disc = _space({"b": box((2.0, 2.0, 1.5), (10, 10, 8))}, {"b": dict(parameterization=BSplineGrid((4, 4, 3)))})
    x = _quadratic_fit(space, lambda X: R * R - np.sum((X - center) ** 2, axis=1))
    bs = body_surface(space, x, disc)
    _closed(bs)
    h = float(bs.spacing.max())
    assert h <= 0.2 / 3.0 + 1e-12  # 3 lattice spacings per cell
    assert abs(bs.volume - 4.0 / 3.0 * np.pi * R**3) <= bs.surface.area * h * h / (2.0 * R)
    assert bs.kind == "level set" and bs.copies == 1
    assert bs.relative_difference == pytest.approx((bs.volume - bs.design_volume) / bs.design_volume)


def test_half_space_level_set_is_exact_and_capped_on_the_box():
    """phi = z0 - z (linear, reproduced exactly): the part below a plane, closed by the body's faces."""
    lengths = np.array([3.0, 1.0, 1.0])
    space, disc = _space({"b": box(tuple(lengths), (12, 4, 4))}, {"b": dict(parameterization=BSplineGrid((3, 1, 1)))})
    p = space.parts[0]
    z0 = 0.4137
    x = z0 - p.sites[:, 2]
    bs = body_surface(space, x, disc, options=SurfaceOptions(refine=2))
    _closed(bs)
    assert bs.volume == pytest.approx(3.0 * 1.0 * z0, rel=1e-12)
    np.testing.assert_allclose(bs.surface.vertices.min(axis=0), [0, 0, 0], atol=1e-15)
    np.testing.assert_allclose(bs.surface.vertices.max(axis=0), [3.0, 1.0, z0], atol=1e-12)
    full = body_surface(space, np.ones(p.n), disc)  # all material: the domain itself
    assert full.volume == pytest.approx(full.domain_volume, rel=1e-12)
    assert full.domain_volume == pytest.approx(3.0, rel=1e-12) and full.volume_fraction == pytest.approx(1.0)


def test_cells_fixed_solid_keep_their_material():
    """Everything void but a block of cells fixed solid: the block, its faces between lattice points
    (at most half a spacing off, so within area * h / 2 of the block's volume)."""
    space, disc = _space(
        {"b": box((2.0, 1.0, 1.0), (8, 4, 4))},
        {"b": dict(parameterization=BSplineGrid((2, 1, 1)), solid=BoxRegion((0.5, 0.25, 0.0), (1.5, 0.75, 0.5)))},
    )
    p = space.parts[0]
    assert np.sum(p.fixed == 1) == 4 * 2 * 2
    bs = body_surface(space, -np.ones(p.n), disc)
    _closed(bs)
    block = 1.0 * 0.5 * 0.5
    area = 2 * (1.0 * 0.5 + 1.0 * 0.5 + 0.5 * 0.5)
    assert abs(bs.volume - block) <= area * float(bs.spacing.max()) / 2.0


# ------------------------------------------------------------------------------- density designs
def _density_space(mesh):
    """A density design whose filter reaches a cell's own centroid only: nu_e = H(x_e)."""
    return _space({"b": mesh}, {"b": dict(parameterization=Density(radius=1e-3))})


def test_density_iso_surface_of_a_linear_field_is_its_plane():
    """nu linear in x at the centroids: the volume-weighted nodal mean of a linear field is the field
    at interior nodes, trilinear interpolation reproduces it and marching cubes cuts its plane
    exactly, so {nu > 1/2} is the slab x > x0 to round-off (smoothing off)."""
    L = 2.0
    space, disc = _density_space(box((L, 1.0, 0.5), (16, 4, 2)))
    p = space.parts[0]
    nu = 0.2 + 0.5 * p.centroids[:, 0] / L  # nu = 1/2 at x0 = 1.2, three cells from either end
    x = np.arctanh(2.0 * nu - 1.0) / 10.0  # H(x) = nu with eta 10
    np.testing.assert_allclose(space.forward(x).nu, nu, rtol=1e-12)
    bs = body_surface(space, x, disc, options=SurfaceOptions(smooth=0))
    _closed(bs)
    assert bs.kind == "density"
    assert bs.volume == pytest.approx((L - 1.2) * 1.0 * 0.5, rel=1e-10)
    smoothed = body_surface(space, x, disc)  # default Taubin smoothing keeps the volume
    assert smoothed.volume == pytest.approx(bs.volume, rel=1e-9)


def test_density_block_is_closed_between_its_chamfered_and_its_full_volume():
    """A block of solid cells (nu = 1, 0 around): nodal means are 1/2 on its faces, 1/4 on its edges,
    so the iso-surface keeps the faces and cuts the edges: per unit edge length it loses the area
    {u + v + uv < 1} of the edge cell's cross-section, (2 ln 2 - 1) c^2, at the corners at most c^3."""
    c = 0.25
    space, disc = _density_space(box((2.0, 2.0, 2.0), (8, 8, 8)))
    p = space.parts[0]
    block = np.all((p.centroids > 0.5) & (p.centroids < 1.5), axis=1)
    bs = body_surface(space, np.where(block, 1.0, -1.0), disc, options=SurfaceOptions(smooth=0))
    _closed(bs)
    edge_loss = (2.0 * np.log(2.0) - 1.0) * c * c * 12 * 1.0
    expected = 1.0 - edge_loss
    h = float(bs.spacing.max())
    assert abs(bs.volume - expected) <= 8 * c**3 + bs.surface.area * h * h
    assert bs.volume < 1.0


# ------------------------------------------------------------------------------- symmetry and mirrors
@pytest.fixture(scope="module")
def rings():
    """The same design (phi = z - z0: material above z0) on a half sector of a 5-fold ring (the
    fundamental region of cyclic + reflection symmetry) and on the whole ring."""
    beta = 2 * np.pi / 5
    z0 = 0.37
    out = {}
    for name, theta, n in (("half-sector", (0.0, beta / 2), 6), ("ring", (0.0, 2 * np.pi), 60)):
        mesh = annulus(4.0, 5.0, 1.0, (n, 4, 4), theta=theta, center=(0.0, 0.0, 0.5))
        space, disc = _space(
            {"ring": mesh}, {"ring": dict(parameterization=BSplineGrid((3, 2, 2)), symmetry=CyclicSymmetry(5))}
        )
        x = space.parts[0].sites[:, 2] - z0
        out[name] = (space, disc, x, z0)
    return out


def test_a_half_sector_expands_to_the_whole_ring(rings):
    """Ten images of the half sector make the ring: the expanded surface is one closed piece around
    the axis, encloses ten times the sector's material, and agrees with the whole ring's surface.
    Both are within this of the polygonal ring's exact volume (quadratic in the spacing h): chords of
    up to sqrt(3) h on walls of radius R >= 4 (sagitta 3 h^2 / (8 R) over the area) and, where two
    faces meet (the plane z = z0 and the top z = 1 with both walls: four circles), marching cubes'
    chamfer between lattice points half a spacing off the faces, h^2 / 8 per unit length."""
    space, disc, x, z0 = rings["half-sector"]
    bs = body_surface(space, x, disc)
    _closed(bs)
    assert bs.copies == 10 and bs.surface.volume > 0
    from contopt.io.surface import check_surface

    assert check_surface(bs.surface).components == 1
    v = bs.surface.vertices
    assert np.hypot(v[:, 0], v[:, 1]).max() == pytest.approx(5.0, abs=0.1)
    for k in range(10):  # material at every angle
        a = np.arctan2(v[:, 1], v[:, 0]) % (2 * np.pi)
        assert np.any((a >= k * np.pi / 5) & (a < (k + 1) * np.pi / 5))
    sector = float(space.parts[0].volumes.sum())
    exact = 10 * sector * (1.0 - z0)
    assert bs.domain_volume == pytest.approx(10 * sector)
    edges = 2 * 2 * np.pi * (4.0 + 5.0)

    def tolerance(b):
        h = float(b.spacing.max())
        return b.surface.area * 3 * h * h / (8 * 4.0) + edges * h * h / 8

    assert abs(bs.volume - exact) <= tolerance(bs)
    ring_space, ring_disc, ring_x, _ = rings["ring"]
    whole = body_surface(ring_space, ring_x, ring_disc)
    _closed(whole)
    assert whole.copies == 1
    assert abs(whole.volume - exact) <= tolerance(whole)


def test_mirror_doubles_the_part_across_the_plane(rings):
    space, disc, x, z0 = rings["half-sector"]
    once = body_surface(space, x, disc)
    twice = body_surface(space, x, disc, options=SurfaceOptions(mirror=(("z", 0.0),)))
    _closed(twice)
    from contopt.io.surface import check_surface

    assert twice.copies == 20 and check_surface(twice.surface).components == 2  # material above z0 and below -z0
    assert twice.volume == pytest.approx(2.0 * once.volume, rel=0.01)
    assert twice.surface.vertices[:, 2].min() == pytest.approx(-1.0, abs=1e-6)
    # all material of a box body mirrored at its bottom face: a box of twice the height, exact
    bspace, bdisc = _space({"b": box((1.0, 1.0, 0.5), (4, 4, 2))}, {"b": dict(parameterization=BSplineGrid((1, 1, 1)))})
    full = body_surface(bspace, np.ones(bspace.n), bdisc, options=SurfaceOptions(mirror=(("z", 0.0),)))
    _closed(full)
    assert full.volume == pytest.approx(1.0, rel=1e-12) and full.copies == 2
    with pytest.raises(ConfigError, match="both sides of the mirror plane z = 0.25"):
        body_surface(bspace, np.ones(bspace.n), bdisc, options=SurfaceOptions(mirror=(("z", 0.25),)))


@pytest.mark.parametrize("plane", [1000.0, 1e308, -2.0])
def test_a_mirror_plane_far_from_the_body_is_refused_saying_where_the_body_lies(plane):
    """z = 1000 made a lattice across the gap (minutes), z = 1e308 overflowed to inf (a ValueError); a gap
    up to the body's size is a plane it may be mirrored across."""
    bspace, bdisc = _space({"b": box((1.0, 1.0, 0.5), (4, 4, 2))}, {"b": dict(parameterization=BSplineGrid((1, 1, 1)))})
    x = np.ones(bspace.n)
    with pytest.raises(ConfigError) as err:
        body_surface(bspace, x, bdisc, options=SurfaceOptions(mirror=(("z", plane),)))
    message = str(err.value)
    assert message.startswith(f"the mirror plane z = {plane:g} lies ") and "\n" not in message
    assert (
        "body 'b', which spans z from 0 to 0.5; mirror across a plane the model ends at (e.g. z=0 or z=0.5)" in message
    )
    near = body_surface(bspace, x, bdisc, options=SurfaceOptions(mirror=(("z", -1.0),)))  # a gap of 1: two boxes
    from contopt.io.surface import check_surface

    assert near.copies == 2 and check_surface(near.surface).components == 2


# ------------------------------------------------------------------------------- options, bodies, files
@pytest.mark.parametrize(
    "kwargs, needle",
    [
        (dict(refine=0), "refine must be an integer from 1 to 12"),
        (dict(refine=2.5), "refine must be an integer"),
        (dict(smooth=-1), "smoothing must be an integer >= 0"),
        (dict(mirror=(("w", 0.0),)), "axis x, y or z"),
        (dict(mirror=(("z", 0.0), ("z", 1.0))), "one mirror plane per axis"),
    ],
)
def test_bad_options_are_config_errors(kwargs, needle):
    with pytest.raises(ConfigError, match=needle):
        SurfaceOptions(**kwargs)


def test_several_bodies_write_one_file_each(tmp_path):
    meshes = {"a": box((1.0, 1.0, 1.0), (4, 4, 4)), "b": box((1.0, 1.0, 1.0), (4, 4, 4), origin=(2.0, 0.0, 0.0))}
    space, disc = _space(
        meshes, {"a": dict(parameterization=BSplineGrid((1, 1, 1))), "b": dict(parameterization=Density(radius=0.3))}
    )
    with pytest.raises(ConfigError, match="several bodies"):
        body_surface(space, np.ones(space.n), disc)
    with pytest.raises(ConfigError, match="body 'c' is not designed"):
        body_surface(space, np.ones(space.n), disc, body="c")
    assert surface_paths(tmp_path / "part.stl", ["a"]) == [tmp_path / "part.stl"]
    made = write_design_surfaces(space, np.ones(space.n), disc, tmp_path / "part.ply")
    assert [p.name for _, p in made] == ["part_a.ply", "part_b.ply"]
    for bs, path in made:
        back = read_surface(path)
        assert closed_manifold_problems(back.vertices, back.faces) == []
        assert back.volume == pytest.approx(bs.volume, rel=1e-12)
    assert [bs.kind for bs, _ in made] == ["level set", "density"]
