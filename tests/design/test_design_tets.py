"""The design chain on tetrahedral design domains: centroids and volumes of tets, FD-checked maps."""

import numpy as np
import pytest

from contopt.assembly.model import Body, Dirichlet, Model
from contopt.assembly.system import discretize
from contopt.design import BSplineGrid, Density, Design, DesignedBody, Heaviside, Simp
from contopt.design.space import cell_centroids
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import box
from contopt.mesh.tets import tetrahedralize


def _disc():
    """A tet4 box (density), a tet10 box (B-spline) and a hex8 box (density): one model."""
    mat = neo_hookean(1.0, 0.3)
    bodies = (
        Body("t4", tetrahedralize(box((3.0, 2.0, 1.0), (3, 2, 1)), 1), mat),
        Body("t10", tetrahedralize(box((3.0, 2.0, 1.0), (3, 2, 1), origin=(0.0, 3.0, 0.0)), 2), mat),
        Body("h", box((3.0, 2.0, 1.0), (3, 2, 1), origin=(0.0, 6.0, 0.0)), mat),
    )
    bcs = [Dirichlet(b.name, "zmin", "xyz", 0.0) for b in bodies]
    return discretize(Model(bodies=bodies, dirichlet=bcs))


def _design(eta=6.0):
    return Design(
        bodies=(
            DesignedBody("t4", Density(radius=0.9), volume_fraction=0.4),
            DesignedBody("t10", BSplineGrid((2, 2, 1), degree=2), volume_fraction=0.5),
            DesignedBody("h", Density(radius=1.5), volume_fraction=0.5),
        ),
        heaviside=Heaviside(eta),
        simp=Simp(3.0, 1e-2),
    )


def test_tet_centroids_and_volumes():
    disc = _disc()
    for i, mesh in enumerate(b.mesh for b in disc.model.bodies[:2]):
        X = cell_centroids(mesh)
        corners = mesh.points[mesh.cells[:, :4]]
        vol = np.abs(np.linalg.det(corners[:, 1:] - corners[:, :1])) / 6.0
        np.testing.assert_allclose(disc.blocks[i].volume, vol, rtol=1e-13)
        np.testing.assert_allclose(X, corners.mean(axis=1), rtol=1e-14)
        # the volume-weighted centroids of the 6 tets of a box cell are its centre
        centres = (vol[:, None] * X).reshape(-1, 6, 3).sum(axis=1) / vol.reshape(-1, 6).sum(axis=1)[:, None]
        np.testing.assert_allclose(centres, cell_centroids(box((3.0, 2.0, 1.0), (3, 2, 1))) + [0, 3 * i, 0])


def test_uniform_design_stays_uniform_and_meets_the_volume_fractions():
    disc = _disc()
    space = _design().build(disc)
    f = space.forward(space.initial())
    np.testing.assert_allclose(space.volume_fractions(f), [0.4, 0.5, 0.5], rtol=1e-10)


@pytest.mark.parametrize("eta", [2.0, 10.0])
def test_design_chain_vjp_matches_central_differences_on_tets(eta, rng):
    disc = _disc()
    space = _design(eta).build(disc)
    x = rng.uniform(-0.2, 0.2, space.n)
    rho_bar, nu_bar, v = rng.normal(size=disc.n_cells), rng.normal(size=disc.n_cells), rng.normal(size=space.n)
    g = space.vjp(space.forward(x), rho_bar, nu_bar)
    h = 1e-6

    def scalar(xx):
        ff = space.forward(xx)
        return rho_bar @ ff.rho + nu_bar @ ff.nu

    assert g @ v == pytest.approx((scalar(x + h * v) - scalar(x - h * v)) / (2 * h), rel=1e-7)
    J = space.volume_gradients(space.forward(x))
    fd = (space.volume_fractions(space.forward(x + h * v)) - space.volume_fractions(space.forward(x - h * v))) / (2 * h)
    np.testing.assert_allclose(J @ v, fd, rtol=1e-7)


def test_design_surfaces_of_tet_domains():
    """The STL of designs on tets: a half-space level set on tet10 is exact (the lattice points are
    located in the tets by their barycentric coordinates), and the whole tet4 domain is the box."""
    from _surfaces import closed_manifold_problems  # tests/_surfaces.py

    from contopt.design.surface import SurfaceOptions, body_surface

    mat = neo_hookean(1.0, 0.3)
    mesh = tetrahedralize(box((3.0, 1.0, 1.0), (6, 2, 2)), 2)
    disc = discretize(Model(bodies=(Body("b", mesh, mat),)))
    space = Design(bodies=(DesignedBody("b", BSplineGrid((3, 1, 1))),), heaviside=Heaviside(10.0)).build(disc)
    z0 = 0.4137
    bs = body_surface(space, z0 - space.parts[0].sites[:, 2], disc, options=SurfaceOptions(refine=2))
    assert closed_manifold_problems(bs.surface.vertices, bs.surface.faces) == []
    assert bs.volume == pytest.approx(3.0 * z0, rel=1e-12)
    mesh = tetrahedralize(box((2.0, 1.0, 1.0), (4, 2, 2)), 1)
    disc = discretize(Model(bodies=(Body("b", mesh, mat),)))
    space = Design(bodies=(DesignedBody("b", Density(radius=0.5)),), heaviside=Heaviside(10.0)).build(disc)
    full = body_surface(space, np.ones(space.n), disc)
    assert full.volume == pytest.approx(2.0, rel=1e-3) and full.domain_volume == pytest.approx(2.0, rel=1e-12)
