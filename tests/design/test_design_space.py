"""The whole design chain of a model: known values and vjp against central finite differences."""

import numpy as np
import pytest

from contopt.assembly.model import Body, Dirichlet, Model
from contopt.assembly.system import discretize
from contopt.design import (
    REALIZATIONS,
    BoxRegion,
    BSplineGrid,
    CyclicSymmetry,
    Density,
    Design,
    DesignedBody,
    Heaviside,
    RadialSkin,
    Robust,
    Simp,
)
from contopt.errors import ConfigError
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import annulus, box


def _disc():
    """Three bodies: a box (density), a ring sector (B-spline with symmetry and skins), a box not designed."""
    mat = neo_hookean(1.0, 0.3)
    slab = Body("slab", box((3.0, 2.0, 1.0), (6, 4, 2)), mat)
    ring = Body("ring", annulus(1.0, 2.0, 0.5, divisions=(20, 4, 2)), mat)
    other = Body("other", box((1.0, 1.0, 1.0), (1, 1, 1), origin=(5.0, 0.0, 0.0)), mat)
    bcs = [Dirichlet(b, "zmin", "xyz", 0.0) for b in ("slab", "ring", "other")]
    return discretize(Model(bodies=(slab, ring, other), dirichlet=bcs))


def _design(eta=6.0):
    ring = DesignedBody(
        "ring",
        BSplineGrid((3, 2, 1), degree=3),
        volume_fraction=0.5,
        symmetry=CyclicSymmetry(n_sectors=5),
        skins=(RadialSkin(1.2, "inside"), RadialSkin(1.8, "outside")),
        void=BoxRegion((-3.0, -3.0, 0.2), (3.0, 3.0, 1.0)),
    )
    slab = DesignedBody("slab", Density(radius=0.8), volume_fraction=0.4, solid=[0, 1])
    return Design(bodies=(slab, ring), heaviside=Heaviside(eta), simp=Simp(3.0, 1e-2))


def test_initial_design_is_uniformly_grey_at_the_volume_fraction():
    disc = _disc()
    space = Design(
        bodies=(
            DesignedBody("slab", Density(0.8), volume_fraction=0.4),
            DesignedBody("ring", BSplineGrid((3, 2, 1)), volume_fraction=0.3),
        )
    ).build(disc)
    f = space.forward(space.initial())
    np.testing.assert_allclose(f.nu[disc.cell_slice("slab")], 0.4, rtol=1e-12)
    np.testing.assert_allclose(f.nu[disc.cell_slice("ring")], 0.3, rtol=1e-12)
    np.testing.assert_array_equal(f.nu[disc.cell_slice("other")], 1.0)
    np.testing.assert_array_equal(f.rho[disc.cell_slice("other")], 1.0)
    np.testing.assert_allclose(space.volume_fractions(f), [0.4, 0.3], rtol=1e-12)
    np.testing.assert_allclose(f.rho[disc.cell_slice("slab")], 0.99 * 0.4**3 + 0.01, rtol=1e-12)
    assert space.n == disc.blocks[0].n_cells + 6 * 5 * 4


def test_initial_design_with_skins_and_fixed_regions_meets_the_volume_fraction():
    """Solid skins / fixed cells would push the plain grey start off its volume fraction: the start
    is the uniform level that meets it, and stays uniform over the free variables."""
    space = _design(eta=10.0).build(_disc())
    x = space.initial()
    np.testing.assert_allclose(space.volume_fractions(space.forward(x)), [0.4, 0.5], atol=1e-9)
    for p in space.parts:
        assert np.ptp(x[p.x]) == 0.0
    plain = space.design.heaviside.inverse(0.5)
    assert abs(x[space.parts[1].x][0] - plain) > 1e-3  # the ring's skins really moved it


def test_skins_fixed_regions_and_symmetry_in_the_forward_map(rng):
    disc = _disc()
    space = _design(eta=10.0).build(disc)
    x = rng.uniform(-1, 1, space.n)
    f = space.forward(x)
    ring = space.parts[1]
    X = ring.centroids
    r = np.hypot(X[:, 0], X[:, 1])
    nu = f.nu[ring.cells]
    void = X[:, 2] >= 0.2
    np.testing.assert_array_equal(nu[void], 0.0)
    skin = ((r < 1.1) | (r > 1.9)) & ~void  # R-union with slope 5: solid well inside the skins
    assert np.all(nu[skin] > 0.5)
    # cyclic + reflection symmetry: cells at mirrored angles have the same level set
    alpha = np.degrees(np.arctan2(X[:, 1], X[:, 0])) % 360
    for a, b in [(9.0, 63.0), (9.0, 297.0), (27.0, 45.0)]:  # 9 = 72 - 63 = 360 - 297 and 27 + 45 = 72
        i = np.flatnonzero((np.abs(alpha - a) < 1e-6) & ~void)
        j = np.flatnonzero((np.abs(alpha - b) < 1e-6) & ~void)
        assert i.size and i.size == j.size
        order_i, order_j = np.lexsort((X[i, 2], r[i])), np.lexsort((X[j, 2], r[j]))
        np.testing.assert_allclose(f.phi[ring.cells][i[order_i]], f.phi[ring.cells][j[order_j]], rtol=1e-12)
    slab = space.parts[0]
    np.testing.assert_array_equal(f.nu[slab.cells][[0, 1]], 1.0)
    assert space.summary()[1]["G_nonzeros"] == 64 * (disc.blocks[1].n_cells)


@pytest.mark.parametrize("eta", [2.0, 10.0])
def test_design_chain_vjp_matches_central_differences(eta, rng):
    disc = _disc()
    space = _design(eta).build(disc)
    x = rng.uniform(-0.2, 0.2, space.n)
    rho_bar, nu_bar, v = rng.normal(size=disc.n_cells), rng.normal(size=disc.n_cells), rng.normal(size=space.n)
    f = space.forward(x)
    g = space.vjp(f, rho_bar, nu_bar)
    h = 1e-6

    def scalar(xx):
        ff = space.forward(xx)
        return rho_bar @ ff.rho + nu_bar @ ff.nu

    fd = (scalar(x + h * v) - scalar(x - h * v)) / (2 * h)
    assert g @ v == pytest.approx(fd, rel=1e-7)
    for i in rng.choice(space.n, 6, replace=False):  # single variables, both parameterizations
        e = np.zeros(space.n)
        e[i] = 1.0
        assert g[i] == pytest.approx((scalar(x + h * e) - scalar(x - h * e)) / (2 * h), rel=1e-6, abs=1e-9)


def test_volume_fraction_gradients_match_central_differences(rng):
    disc = _disc()
    space = _design().build(disc)
    x = rng.uniform(-0.3, 0.3, space.n)
    J = space.volume_gradients(space.forward(x))
    v, h = rng.normal(size=space.n), 1e-6
    fd = (space.volume_fractions(space.forward(x + h * v)) - space.volume_fractions(space.forward(x - h * v))) / (2 * h)
    np.testing.assert_allclose(J @ v, fd, rtol=1e-7)
    assert np.all(J[0, space.parts[1].x] == 0) and np.all(J[1, space.parts[0].x] == 0)


def test_full_design_and_errors():
    disc = _disc()
    space = _design().build(disc)
    full = space.full()
    ring = space.parts[1]
    np.testing.assert_array_equal(full.nu[ring.cells], np.where(ring.fixed == 0, 0.0, 1.0))
    with pytest.raises(ConfigError, match="needs 120 entries|needs"):
        space.forward(np.zeros(3))
    with pytest.raises(ConfigError, match="unknown body"):
        Design(DesignedBody("nope", Density(1.0))).build(disc)
    with pytest.raises(ConfigError, match="volume_fraction"):
        DesignedBody("slab", Density(1.0), volume_fraction=1.2)
    with pytest.raises(ConfigError, match="both solid and void"):
        Design(DesignedBody("slab", Density(1.0), solid=[3], void=[3])).build(disc)
    with pytest.raises(ConfigError, match="designed once"):
        Design((DesignedBody("slab", Density(1.0)), DesignedBody("slab", Density(2.0))))
    with pytest.raises(ConfigError, match="envelope must be a closed TriangleSurface"):
        DesignedBody("slab", Density(1.0), envelope="bracket.stl")


def test_robust_realizations_chain_and_checks(rng):
    """Each realization's chain (filter, shifted projection, SIMP) against central differences; the
    eroded design has the least material, the dilated the most; level sets are refused."""
    disc = _disc()
    slab = DesignedBody("slab", Density(radius=0.8), volume_fraction=0.4, solid=[0, 1])
    design = Design(bodies=(slab,), heaviside=Heaviside(6.0), robust=Robust(0.1))
    x = rng.uniform(-0.4, 0.4, design.build(disc).n)
    rho_bar, v, h = rng.normal(size=disc.n_cells), rng.normal(size=len(x)), 1e-6
    nus = []
    for k in REALIZATIONS:
        space = design.realization(k).build(disc)
        assert space.design.robust is None and space.design.heaviside.threshold == Robust(0.1).threshold(k)
        f = space.forward(x)
        nus.append(f.nu)
        fd = (rho_bar @ space.forward(x + h * v).rho - rho_bar @ space.forward(x - h * v).rho) / (2 * h)
        assert space.vjp(f, rho_bar) @ v == pytest.approx(fd, rel=1e-7)
    free = disc.cell_slice("slab")
    assert np.all(nus[0][free] <= nus[1][free]) and np.all(nus[1][free] <= nus[2][free])
    assert design.build(disc).summary()[0]["robust"] == {"delta": 0.1}
    with pytest.raises(ConfigError, match="robust applies to density designs only; body 'ring' is a B-spline"):
        Design(bodies=(slab, DesignedBody("ring", BSplineGrid((3, 2, 1)))), robust=Robust(0.1))
    with pytest.raises(ConfigError, match="has no robust formulation"):
        Design(bodies=(slab,)).realization("eroded")


def _bracket_space(parameterization, eta=6.0):
    """A voxel bracket (tests/mesh/_envelope.py) with a keep-in box and a keep-out closed surface."""
    from _envelope import bracket  # tests/_envelope.py

    from contopt.design import SurfaceRegion
    from contopt.mesh.voxel import voxelize

    mesh = voxelize(bracket(), 0.2)
    slot = bracket(np.array([(0.75, -1.0), (1.25, -1.0), (1.25, 1.0), (0.75, 1.0)]), 0.4, origin=(0.0, 0.2, 0.0))
    body = Body("bracket", mesh, neo_hookean(1.0, 0.3))
    disc = discretize(Model(bodies=(body,), dirichlet=[Dirichlet("bracket", "zmax", "xyz", 0.0)]))
    spec = DesignedBody(
        "bracket",
        parameterization,
        volume_fraction=0.4,
        solid=BoxRegion((1.55, -1.0, -1.0), (3.0, 3.0, 3.0)),
        void=SurfaceRegion(slot, "slot"),
    )
    return disc, Design(spec, heaviside=Heaviside(eta), simp=Simp(3.0, 1e-2)).build(disc)


@pytest.mark.parametrize("parameterization", [Density(0.45), BSplineGrid((4, 2, 4), degree=2)])
def test_keep_in_and_keep_out_hold_exactly_without_bleeding_and_fd_correct(parameterization, rng):
    disc, space = _bracket_space(parameterization)
    (part,) = space.parts
    X = part.centroids
    slot = (np.abs(X[:, 0] - 1.0) < 0.25) & (X[:, 1] > 0.2) & (X[:, 1] < 0.6) & (X[:, 2] < 1.0)
    np.testing.assert_array_equal(part.fixed == 0, slot)
    np.testing.assert_array_equal(part.fixed == 1, X[:, 0] > 1.55)
    x = rng.uniform(-0.5, 0.5, space.n)
    f = space.forward(x)
    np.testing.assert_array_equal(f.nu[part.fixed == 1], 1.0)
    np.testing.assert_array_equal(f.nu[part.fixed == 0], 0.0)
    rho_bar, v, h = rng.normal(size=disc.n_cells), rng.normal(size=space.n), 1e-6
    fd = (rho_bar @ space.forward(x + h * v).rho - rho_bar @ space.forward(x - h * v).rho) / (2 * h)
    g = space.vjp(f, rho_bar)
    assert g @ v == pytest.approx(fd, rel=1e-7)
    if isinstance(parameterization, Density):
        # no bleed: free cells read free cells' variables only, so a fixed cell's variable moves nothing
        free = part.fixed < 0
        assert part.G[free][:, ~free].nnz == 0
        np.testing.assert_array_equal(g[~free], 0.0)
        np.testing.assert_allclose(np.asarray(part.G[free].sum(axis=1)).ravel(), 1.0, rtol=1e-12)
        y = np.where(free, -1.0, 1.0)  # void where free, solid variables in the fixed cells
        np.testing.assert_allclose(space.forward(y).phi[free], -1.0, rtol=1e-12)
