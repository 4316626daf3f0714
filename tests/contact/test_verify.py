"""The independent check of a contact state (contopt.contact.verify): closest points against brute
force, and states it must reject (surfaces driven through each other) or accept (held contact,
nodes beside an open surface, curved surfaces discretized differently)."""

import numpy as np
import pytest

from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import Penalty
from contopt.contact.verify import PenetrationCheck, signed_distances, surface
from contopt.errors import ConfigError
from contopt.material import neo_hookean
from contopt.mesh.generators import annulus, box
from contopt.solve.system import System


def _brute_force(points, surf):
    """Signed distance over every triangle, by dense sampling of each triangle's closest point."""
    from contopt.contact.verify import closest_on_triangles

    n, t = len(points), len(surf.tri)
    p = np.repeat(points, t, axis=0)
    tri = np.tile(surf.tri, (n, 1, 1))
    y, _ = closest_on_triangles(p, tri)
    d = np.linalg.norm(p - y, axis=1).reshape(n, t)
    return d.min(axis=1)


def test_closest_points_are_exact_against_all_triangles(rng):
    # a warped 6 x 5 surface and points near it, far from it and behind it
    mesh = box((3.0, 2.5, 1.0), (6, 5, 1))
    x = mesh.points + 0.05 * rng.standard_normal(mesh.points.shape)
    facets = mesh.facet_nodes("zmax")
    surf = surface(x, facets)
    points = np.concatenate(
        [rng.uniform([-1, -1, -2], [4, 3.5, 3], (300, 3)), x[facets].mean(axis=1) + [0.0, 0.0, -0.01]]
    )
    signed, facet = signed_distances(points, surf)
    exact = _brute_force(points, surf)
    finite = np.isfinite(signed)
    np.testing.assert_allclose(np.abs(signed[finite]), exact[finite], rtol=1e-12, atol=1e-14)
    # just below each facet centre: 0.01 inside, in that facet
    below = slice(300, None)
    np.testing.assert_array_less(signed[below], 0.0)
    assert np.all(facet[below] == np.arange(len(facets)))
    # the cheap variant (for Newton's line search) is exact wherever a point is behind the surface
    quick, _ = signed_distances(points, surf, exact_outside=False)
    behind = signed < 0
    np.testing.assert_array_equal(quick[behind], signed[behind])
    assert np.all(quick[~behind] >= 0)
    # beside the open surface, not under it: never a penetration
    beside = np.array([[-0.5, 1.0, 0.5], [4.0, 1.0, 0.2], [1.0, 3.5, 0.9]])
    assert np.all(np.isinf(signed_distances(beside, surf)[0]))


def test_closest_points_on_a_graded_surface_are_exact(rng):
    # facets from 0.001 to 0.3 wide (the Hertz block's top): the largest facet's radius no longer
    # bounds the search near the small ones, and the points behind take the per-triangle bound
    mesh = box((1.0, 1.0, 1.0), (20, 20, 1))
    x = mesh.points.copy()
    x[:, :2] = 3.0 * x[:, :2] ** 3
    surf = surface(x, mesh.facet_nodes("zmax"))
    assert surf.radii.max() > 100 * surf.radii.min()
    points = np.concatenate(
        [
            rng.uniform([0.0, 0.0, 0.9], [0.05, 0.05, 1.0], (200, 3)),  # behind the smallest facets
            rng.uniform([0.0, 0.0, 0.0], [3.0, 3.0, 1.0], (200, 3)),  # behind, anywhere, deep too
            rng.uniform([-0.5, -0.5, 1.0], [3.5, 3.5, 2.0], (100, 3)),  # in front
        ]
    )
    signed, _ = signed_distances(points, surf)
    exact = _brute_force(points, surf)
    finite = np.isfinite(signed)
    assert finite[:400].all()
    np.testing.assert_allclose(np.abs(signed[finite]), exact[finite], rtol=1e-12, atol=1e-14)
    np.testing.assert_array_less(signed[:400], 0.0)
    quick, _ = signed_distances(points, surf, exact_outside=False)
    np.testing.assert_array_equal(quick[:400], signed[:400])
    # Newton's admissibility guard asks only for what lies deeper than the search's skin: the points
    # found within it are left as found (never deeper than it), every deeper one is exact
    skin = 0.05
    guard, _ = signed_distances(points, surf, exact_outside=False, within=skin)
    deep = signed < -skin
    assert 20 < deep.sum() < 390  # both kinds are there
    np.testing.assert_array_equal(guard[deep], signed[deep])
    shallow = signed[:400] >= -skin
    np.testing.assert_array_less(-guard[:400][shallow], skin * (1 + 1e-12))
    assert np.all(np.abs(guard[:400]) >= np.abs(signed[:400]))  # the distances of the nearest candidates
    assert -guard.min() == -signed.min()  # the deepest, as the guard reports it


def _blocks(law="penalty"):
    """A small block (nonmortar, its bottom) pressed on a larger one (mortar, its top)."""
    upper = box((0.6, 0.6, 0.3), (3, 3, 2), origin=(0.2, 0.2, 1.0))
    lower = box((1.0, 1.0, 1.0), (4, 4, 2))
    model = Model(
        bodies=(Body("up", upper, neo_hookean(1.0, 0.3)), Body("lo", lower, neo_hookean(1.0, 0.3))),
        dirichlet=(Dirichlet("up", "zmax", "xy"), Dirichlet("lo", "zmin", "xyz")),
        loads=(Traction("up", "zmax", (0.0, 0.0, -1e-2)),),
        interfaces=(ContactInterface(("up", "zmin"), ("lo", "zmax"), law=law),),
    )
    return System.of(model)


def _moved(system, dz):
    u = np.zeros(system.disc.n_dofs)
    up = system.disc.body_slice("up")
    u[up] = np.tile([0.0, 0.0, dz], system.disc.blocks[0].n_nodes)
    return u


def test_a_block_driven_into_the_other_without_pressure_is_rejected():
    system = _blocks()
    h = system.contact.blocks[0].h
    u = _moved(system, -0.4 * h)  # 0.4 h inside: within the search, so paired and pressed
    held = system.contact.evaluate(u, system.start_states(), tangent=False).results
    report = system.contact.verify(u, held)[0]
    assert report.ok and report.worst.held and report.worst.relative == pytest.approx(0.4, rel=1e-9)
    # the same geometry with the pressures of a state that lost its pairs
    lost = tuple(
        type(r)(
            g=r.g,
            a=r.a,
            has_overlap=np.zeros_like(r.has_overlap),
            terms=r.terms,
            lam=np.zeros_like(r.lam),
            n_pairs=0,
            coverage=r.coverage,
        )
        for r in held
    )
    report = system.contact.verify(u, lost)[0]
    assert not report.ok and report.flagged > 0
    assert not report.worst.held and report.worst.relative == pytest.approx(0.4, rel=1e-9)
    for word in ("up/zmin -> lo/zmax", "node", "inside body", "no contact pressure"):
        assert word in report.message
    assert "\n" not in report.message
    # deeper than the search reaches: rejected even where pressure acts
    deep = _moved(system, -1.5 * system.contact.blocks[0].skin)
    results = system.contact.evaluate(deep, system.start_states(), tangent=False).results
    report = system.contact.verify(deep, results)[0]
    assert not report.ok and "deeper than the contact search reaches" in report.message
    assert system.admissible(deep) and not system.admissible(u)


def test_a_block_that_went_through_the_other_is_rejected():
    # the small block pushed entirely through the top face (1.5 below it): no facet pair sees it
    system = _blocks()
    u = _moved(system, -1.5)
    results = system.contact.evaluate(u, system.start_states(), tangent=False).results
    assert results[0].n_active == 0  # the pairing sees no contact at all
    report = system.contact.verify(u, results)[0]
    assert not report.ok and report.worst.depth > 0.5


def test_bodies_apart_or_touching_pass(rng):
    system = _blocks()
    for dz in (0.05, 0.0):
        u = _moved(system, dz)
        results = system.contact.evaluate(u, system.start_states(), tangent=False).results
        report = system.contact.verify(u, results)[0]
        assert report.ok and report.flagged == 0 and report.max_depth <= 1e-12


@pytest.mark.parametrize("n_bore, n_shaft", [(40, 12), (12, 40)])
def test_two_discretizations_of_one_cylinder_interpenetrate_only_by_their_sag(n_bore, n_shaft):
    # a shaft in a bore of the same radius, one round in 40 facets, the other in 12: the vertices of
    # the fine polygon stick out of the coarse one's chords by up to its sag, with no load at all
    shaft = annulus(r_inner=0.5, r_outer=1.0, length=0.5, divisions=(n_shaft, 2, 1))
    bore = annulus(r_inner=1.0, r_outer=1.5, length=0.5, divisions=(n_bore, 2, 1))
    model = Model(
        bodies=(Body("bore", bore, neo_hookean(1.0, 0.3)), Body("shaft", shaft, neo_hookean(1.0, 0.3))),
        interfaces=(ContactInterface(("bore", "inner"), ("shaft", "outer"), law=Penalty()),),
    )
    system = System.of(model)
    u = np.zeros(system.disc.n_dofs)
    results = system.contact.evaluate(u, system.start_states(), tangent=False).results
    report = system.contact.verify(u, results)[0]
    # the shaft's vertices (radius 1, angles 2 pi k / n_shaft) lie beyond the bore's chords by
    # cos(phi) - cos(pi / n_bore), phi their angle from the nearest chord's midpoint
    angles = 2 * np.pi * np.arange(n_shaft) / n_shaft
    phi = np.mod(angles, 2 * np.pi / n_bore) - np.pi / n_bore
    expected = float((np.cos(phi) - np.cos(np.pi / n_bore)).max())
    h = system.contact.blocks[0].h
    assert report.max_depth == pytest.approx(expected, rel=1e-9)  # they interpenetrate by the sag ...
    assert report.max_depth > 5 * PenetrationCheck().tolerance * h  # ... above the plain tolerance
    assert report.ok  # ... and that is the discretization, not lost contact
    unchecked = System.of(
        Model(
            bodies=model.bodies,
            interfaces=(
                ContactInterface(
                    ("bore", "inner"), ("shaft", "outer"), law=Penalty(), check=PenetrationCheck(enabled=False)
                ),
            ),
        )
    )
    assert unchecked.contact.verify(u, results)[0].max_depth == 0.0  # a disabled check measures nothing


def test_check_options_are_validated():
    for bad in (0.0, 1.0, -1e-3, "1e-3"):
        with pytest.raises(ConfigError, match="tolerance"):
            PenetrationCheck(tolerance=bad)
    with pytest.raises(ConfigError, match="enabled"):
        PenetrationCheck(enabled="yes")


def test_folded_facets_next_to_pressure_are_reported_and_their_penetration_rejected():
    system = _blocks()
    contact = system.contact
    h = contact.blocks[0].h
    u = _moved(system, -0.2 * h)  # the small block pressed into the large one: pressure everywhere under it
    lo = system.model.body("lo").mesh
    top = lo.node_set("zmax")
    k = system.disc.blocks[1].node_offset + top[np.argmin(np.linalg.norm(lo.points[top, :2] - [0.5, 0.5], axis=1))]

    def poke(sideways):
        """One node of the large block's face pushed up into the small block, and sideways."""
        v = u.copy()
        v[3 * k : 3 * k + 3] += [sideways, 0.0, 0.5 * h]
        res = contact.evaluate(v, system.start_states(), tangent=False).results[0]
        return res, contact.verify(v, (res,))[0]

    res, report = poke(0.075)  # tilted facets: still segmented, nothing dropped
    assert res.rejected_near_active == 0 and not report.ok
    res, report = poke(0.3)  # sideways past its neighbours: the facets fold and their pairs are dropped
    assert res.rejected_near_active > 0 and report.rejected_near_active == res.rejected_near_active
    assert not report.ok and report.worst.side == "mortar" and report.worst.relative > 0.5
