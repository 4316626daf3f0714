"""A start design carried from one design space to another (contopt run --design-from)."""

import dataclasses

import numpy as np
import pytest

from contopt.assembly.model import Body, Dirichlet, Model
from contopt.assembly.system import discretize
from contopt.design import BSplineGrid, Density, Design, DesignedBody, Heaviside
from contopt.design.transfer import (
    VOLUME_TOL,
    body_fields,
    interpolator,
    meet_volume_limits,
    start_design,
    volume_fraction_field,
)
from contopt.errors import ConfigError
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import box

LENGTHS = (3.0, 1.0, 0.5)


def _space(divisions, param, eta=10.0, body="beam", vf=0.4, lengths=LENGTHS):
    mesh = box(lengths, divisions)
    disc = discretize(
        Model(bodies=(Body(body, mesh, neo_hookean(1.0, 0.3)),), dirichlet=[Dirichlet(body, "xmin", "xyz", 0.0)])
    )
    return Design(bodies=(DesignedBody(body, param, volume_fraction=vf),), heaviside=Heaviside(eta)).build(disc)


def _linear(X):
    """The analytic field: linear in x, from -0.08 to 0.1 over the beam (inside the bounds)."""
    return -0.08 + 0.06 * X[:, 0]


def test_the_same_mesh_and_design_is_copied_bit_for_bit(rng):
    space = _space((12, 4, 2), Density(0.3))
    x = rng.uniform(-1.0, 1.0, space.n)
    y, how = start_design(_space((12, 4, 2), Density(0.3)), body_fields(space, x))
    assert how == {"beam": "copied"}
    assert y.tobytes() == x.tobytes()


def test_a_bspline_on_another_mesh_keeps_its_control_values(rng):
    grid = BSplineGrid((4, 2, 1), origin=(0.0, 0.0, 0.0), lengths=LENGTHS)
    coarse, fine = _space((12, 4, 2), grid), _space((24, 8, 4), grid)
    x = rng.uniform(-1.0, 1.0, coarse.n)
    y, how = start_design(fine, body_fields(coarse, x))
    assert how == {"beam": "copied"} and y.tobytes() == x.tobytes()


def test_coarse_to_fine_density_reproduces_a_linear_field():
    """Density design variables linear in x on the coarse mesh, the same filter on the fine mesh: the
    fine mesh's variables are the same line (exact on the tensor grid, also at the outer centroids
    beyond the coarse ones)."""
    coarse, fine = _space((12, 4, 2), Density(0.3)), _space((24, 8, 4), Density(0.3))
    x = _linear(coarse.parts[0].sites)
    y, how = start_design(fine, body_fields(coarse, x))
    assert how == {"beam": "interpolated"}
    np.testing.assert_allclose(y, _linear(fine.parts[0].sites), atol=1e-12)
    # the volume fractions (the physical density) agree to the filters' difference at the boundary
    nu_c, nu_f = coarse.forward(x).nu, fine.forward(y).nu
    assert abs(coarse.volume_fractions(coarse.forward(x))[0] - fine.volume_fractions(fine.forward(y))[0]) < 2e-3
    assert nu_c.min() < 0.2 and nu_c.max() > 0.7 and nu_f.min() < 0.2


def test_another_filter_takes_the_filtered_level_set():
    """A smaller filter radius on the fine mesh: its variables are the coarse level set G x (which the
    coarse filter bends within a radius of the ends x = 0 and x = 3, and leaves linear between)."""
    coarse, fine = _space((12, 4, 2), Density(0.3)), _space((24, 8, 4), Density(0.15))
    x = _linear(coarse.parts[0].sites)
    y, how = start_design(fine, body_fields(coarse, x))
    assert how == {"beam": "interpolated"}
    sites = fine.parts[0].sites
    inner = (sites[:, 0] > 0.5) & (sites[:, 0] < 2.5)
    np.testing.assert_allclose(y[inner], _linear(sites[inner]), atol=1e-12)
    # at the ends the bent level set, not the line: the variables x alone would give the line
    ends = ~inner
    phi = coarse.forward(x).phi
    assert np.max(np.abs(y[ends] - _linear(sites[ends]))) > 1e-3
    np.testing.assert_allclose(y, interpolator(coarse.parts[0].centroids, phi)(sites), atol=1e-12)


def test_a_sharper_target_scales_the_level_set_to_keep_nu():
    coarse, fine = _space((12, 4, 2), Density(0.3), eta=5.0), _space((24, 8, 4), Density(0.3), eta=10.0)
    x = _linear(coarse.parts[0].sites)
    y, _ = start_design(fine, body_fields(coarse, x))
    np.testing.assert_allclose(y, 0.5 * _linear(fine.parts[0].sites), atol=1e-12)


def test_density_to_bspline_fits_the_level_set():
    grid = BSplineGrid((6, 2, 1), origin=(0.0, 0.0, 0.0), lengths=LENGTHS)
    coarse, target = _space((12, 4, 2), Density(0.3)), _space((24, 8, 4), grid)
    x = _linear(coarse.parts[0].sites)
    y, how = start_design(target, body_fields(coarse, x))
    assert how == {"beam": "fitted"}
    # a linear level set is a spline: the fit reproduces the coarse filtered field (linear inside,
    # bent by the filter within a radius of the ends)
    phi = target.forward(y).phi
    X = target.parts[0].centroids
    inner = (X[:, 0] > 0.5) & (X[:, 0] < 2.5)
    np.testing.assert_allclose(phi[inner], _linear(X[inner]), atol=2e-3)


def test_a_volume_fraction_field_is_inverted_through_the_heaviside():
    fine = _space((24, 8, 4), Density(0.15))
    coarse = _space((12, 4, 2), Density(0.3))
    X = coarse.parts[0].centroids
    nu = 0.2 + 0.2 * X[:, 0]  # from 0.2 to 0.8
    y, how = start_design(fine, {"beam": volume_fraction_field("beam", X, nu, 10.0)})
    assert how == {"beam": "interpolated"}
    back = Heaviside(10.0).forward(y)
    np.testing.assert_allclose(back, 0.2 + 0.2 * fine.parts[0].sites[:, 0], atol=1e-9)


def test_bounds_and_bodies():
    coarse, fine = _space((12, 4, 2), Density(0.3), eta=20.0), _space((24, 8, 4), Density(0.15), eta=5.0)
    y, _ = start_design(fine, body_fields(coarse, np.ones(coarse.n)))
    np.testing.assert_array_equal(y, 1.0)  # 4 x the level set, clipped into the bounds
    other = _space((12, 4, 2), Density(0.3), body="slab")
    with pytest.raises(ConfigError, match="no design of body 'beam'.*it designs 'slab'"):
        start_design(fine, body_fields(other, np.zeros(other.n)))


def test_scattered_points_interpolate_linearly_inside_and_nearest_outside(rng):
    points = rng.uniform(0.0, 1.0, (400, 3))
    f = interpolator(points, 1.0 + points @ [1.0, 2.0, 3.0])
    inside = rng.uniform(0.3, 0.7, (50, 3))
    np.testing.assert_allclose(f(inside), 1.0 + inside @ [1.0, 2.0, 3.0], atol=1e-9)
    far = np.array([[5.0, 5.0, 5.0]])
    nearest = points[np.argmin(np.linalg.norm(points - far, axis=1))]
    assert f(far)[0] == pytest.approx(1.0 + nearest @ [1.0, 2.0, 3.0])


def test_a_body_of_another_shape_is_refused():
    """A field that knows its body's box: a target within it (another mesh) takes it, a longer body is
    refused (its design would be extrapolated)."""
    coarse = _space((12, 4, 2), Density(0.3))
    extent = (np.zeros(3), np.array(LENGTHS))
    fields = {"beam": dataclasses.replace(body_fields(coarse, np.zeros(coarse.n))["beam"], extent=extent)}
    start_design(_space((24, 8, 4), Density(0.3)), fields)
    longer = _space((24, 4, 2), Density(0.3), lengths=(6.0, 1.0, 0.5))
    with pytest.raises(ConfigError, match=r"body 'beam' of the start design spans \[0, 3\].*another shape"):
        start_design(longer, fields)


@pytest.mark.parametrize("param", [Density(0.3), BSplineGrid((4, 2, 1), origin=(0.0, 0.0, 0.0), lengths=LENGTHS)])
def test_a_start_above_the_volume_limit_is_lowered_to_it(param):
    """The level set is lowered by one amount (the shape kept) until the volume fraction is the limit."""
    space = _space((12, 4, 2), param, vf=0.3)
    x = 0.5 * _linear(space.parts[0].sites) + 0.02  # volume fraction about 0.6
    before = space.volume_fractions(space.forward(x))[0]
    y, lowered = meet_volume_limits(space, x)
    after = space.volume_fractions(space.forward(y))[0]
    assert before > 0.5 and lowered == {"beam": (pytest.approx(before), pytest.approx(after))}
    assert after == pytest.approx(0.3, abs=1e-9)
    shift = y - x
    np.testing.assert_allclose(shift, shift[0], atol=1e-12)  # uniform: nothing reached a bound
    assert shift[0] < 0


def test_a_start_within_the_volume_limit_is_kept():
    space = _space((12, 4, 2), Density(0.3), vf=0.3)
    for target in (0.2, 0.3 + 0.5 * VOLUME_TOL):  # below the limit, and above it within the tolerance
        x = np.full(space.n, Heaviside(10.0).inverse(target))
        y, lowered = meet_volume_limits(space, x)
        assert lowered == {} and y.tobytes() == x.tobytes()
    y, lowered = meet_volume_limits(space, np.full(space.n, Heaviside(10.0).inverse(0.3 + 2 * VOLUME_TOL)))
    assert list(lowered) == ["beam"]
