"""Tet4 and tet10 bodies assembled and solved, against known answers.

- patch test: a uniform large stretch prescribed on the boundary of a distorted tet mesh is
  reproduced exactly inside (any isoparametric element holds a linear field);
- a cantilever under a small tip load against the Euler-Bernoulli deflection ``P L^3 / (3 E I)``
  and against hex8 on the same geometry (tet10 converges with hex8; tet4 is far too stiff on a
  coarse mesh and stiffens less as it is refined);
- a uniform traction on tri3 / tri6 facets sums to traction times area;
- hex8 and tet bodies in one model; the tet4 locking warning.
"""

import logging

import numpy as np
import pytest

from contopt.assembly import model as model_module
from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.assembly.system import discretize
from contopt.material.hyperelastic import MooneyRivlin, neo_hookean
from contopt.mesh import Mesh, box
from contopt.mesh.tets import tetrahedralize, to_tet10
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static

TIGHT = NewtonOptions(rtol=1e-13, atol=1e-15, utol=1e-12, n_steps=2, max_iter=30)
FACES = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")


@pytest.fixture(params=[1, 2], ids=["tet4", "tet10"])
def order(request):
    return request.param


def solve(mesh, mat, dirichlet, loads=(), newton=TIGHT):
    model = Model(bodies=[Body("b", mesh, mat)], dirichlet=dirichlet, loads=list(loads))
    disc = discretize(model)
    state = solve_static(disc, newton=newton)
    return disc, disc.body_displacement(state.u, "b")


def distorted_tets(rng, order):
    """A unit cube of 162 tets, interior corners moved by up to a tenth of the cell size; tet10 straight-sided.

    Straight sides: with curved ones det J is cubic and the 4-point rule of degree 2 integrates
    the nodal forces of a uniform stress only approximately (0.6 % off at these distortions).
    """
    base = tetrahedralize(box((1.0, 1.0, 1.0), (3, 3, 3)), 1)
    bnd = np.unique(np.concatenate([base.node_set(s) for s in FACES]))
    pts = base.points.copy()
    interior = np.setdiff1d(np.arange(base.n_nodes), bnd)
    pts[interior] += rng.uniform(-0.033, 0.033, (len(interior), 3))
    cells = base.cells
    if order == 2:
        pts, cells = to_tet10(pts, cells)
        ends = base.cells[:, [[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]]].reshape(-1, 2)
        bnd = np.union1d(bnd, cells[:, 4:].ravel()[np.isin(ends, bnd).all(axis=1)])
    return Mesh(pts, cells, {"boundary": bnd}, {}), np.setdiff1d(np.arange(len(pts)), bnd)


def test_patch_test_uniform_stretch_on_distorted_mesh(rng, order):
    mesh, interior = distorted_tets(rng, order)
    pts = mesh.points
    assert len(interior) >= 8  # the cube's 8 interior corners, and tet10's interior edge nodes
    F = np.array([[1.3, 0.1, 0.0], [0.0, 0.85, 0.05], [0.02, 0.0, 1.1]])
    mat = MooneyRivlin.from_E_nu(1.0, 0.3, b_fraction=0.3)
    _, u = solve(mesh, mat, [Dirichlet("b", "boundary", "xyz", lambda X, t: t * X @ (F - np.eye(3)).T)])
    exact = pts @ (F - np.eye(3)).T
    # Newton stops at a relative residual of 1e-13: the field is exact to round-off times the condition
    np.testing.assert_allclose(u[interior], exact[interior], atol=1e-9)


def cantilever_tip(kind, div, L=10.0, h=1.0, nu=0.3):
    """Tip deflection over the Euler-Bernoulli one, of a beam clamped at x = 0 with a small end load."""
    E, P = 1.0, 1e-6  # tip deflection ~4e-3 h: linear
    mesh = box((L, h, h), div)
    if kind != "hex8":
        mesh = tetrahedralize(mesh, 1 if kind == "tet4" else 2)
    _, u = solve(
        mesh,
        neo_hookean(E, nu),
        [Dirichlet("b", "xmin", "xyz")],
        [Traction("b", "xmax", (0.0, 0.0, -P / h**2))],
        NewtonOptions(n_steps=1),
    )
    return -u[mesh.node_set("xmax"), 2].mean() / (P * L**3 / (3 * E * h**4 / 12))


def test_cantilever_tet10_against_beam_and_hex8():
    """L/h = 10: shear adds ~0.8 % to the beam's deflection, the clamp's Poisson constraint takes some off."""
    tet10 = cantilever_tip("tet10", (20, 2, 2))
    hex8 = cantilever_tip("hex8", (20, 2, 2))
    assert tet10 == pytest.approx(1.0, abs=0.02)  # measured 0.997
    assert hex8 == pytest.approx(1.0, abs=0.03)  # measured 0.983
    assert tet10 == pytest.approx(hex8, rel=0.03)


def test_cantilever_tet4_locks_and_converges_from_below():
    coarse, fine = cantilever_tip("tet4", (20, 2, 2)), cantilever_tip("tet4", (40, 4, 4))
    assert coarse < 0.6  # measured 0.51: constant-strain tets are stiff in bending
    assert coarse < fine < 1.0
    assert fine > 0.7  # measured 0.79


def test_traction_on_triangle_facets_sums_to_traction_times_area(order):
    mesh = tetrahedralize(box((2.0, 1.0, 0.5), (2, 2, 1)), order)
    model = Model(
        bodies=[Body("b", mesh, neo_hookean(1.0, 0.3))],
        dirichlet=[Dirichlet("b", "xmin", "xyz")],
        loads=[Traction("b", "zmax", (0.1, -0.2, 0.3))],
    )
    f = discretize(model).f_ext_unit.reshape(-1, 3)
    np.testing.assert_allclose(f.sum(axis=0), 2.0 * np.array([0.1, -0.2, 0.3]), rtol=1e-13)
    top = mesh.node_set("zmax")
    assert np.abs(np.delete(f, top, axis=0)).max() == 0.0


def test_mixed_model_hex8_and_tet10_bodies():
    """Two separate beams in one model: each as in its own model, to the solver's tolerance."""
    hexes = box((4.0, 1.0, 1.0), (4, 1, 1))
    tets = tetrahedralize(box((4.0, 1.0, 1.0), (4, 1, 1)), 2).transformed(translation=(0.0, 3.0, 0.0))
    mat = neo_hookean(1.0, 0.3)
    bcs = [Dirichlet(n, "xmin", "xyz") for n in ("h", "t")]
    loads = [Traction(n, "xmax", (0.0, 0.0, -0.01)) for n in ("h", "t")]
    model = Model(bodies=[Body("h", hexes, mat), Body("t", tets, mat)], dirichlet=bcs, loads=loads)
    disc = discretize(model)
    u = solve_static(disc, newton=TIGHT).u
    for name, mesh in (("h", hexes), ("t", tets)):
        alone, ua = solve(mesh, mat, [Dirichlet("b", "xmin", "xyz")], [Traction("b", "xmax", (0.0, 0.0, -0.01))])
        np.testing.assert_allclose(disc.body_displacement(u, name), ua, atol=1e-10)


def test_tet4_warns_once_that_it_locks(caplog, monkeypatch):
    monkeypatch.setattr(model_module, "_WARNED", set())
    mesh = tetrahedralize(box((1.0, 1.0, 1.0), (1, 1, 1)), 1)
    with caplog.at_level(logging.WARNING, logger="contopt.assembly.model"):
        Body("soft", mesh, neo_hookean(1.0, 0.3))
        assert not caplog.records
        Body("rubber", mesh, neo_hookean(1.0, 0.49))
        Body("rubber2", mesh, neo_hookean(1.0, 0.49))
        Body("quadratic", tetrahedralize(box((1.0, 1.0, 1.0), (1, 1, 1)), 2), neo_hookean(1.0, 0.49))
    assert len(caplog.records) == 1
    message = caplog.records[0].getMessage()
    assert "\n" not in message and "tet4" in message and "0.45" in message and "tet10" in message


def test_contact_on_a_tet_body_is_accepted_on_either_side():
    from contopt.contact.interface import ContactInterface

    block = box((1.0, 1.0, 0.5), (2, 2, 1))
    die = tetrahedralize(box((1.0, 1.0, 0.5), (2, 2, 1), origin=(0.0, 0.0, 0.5)), 2)
    mat = neo_hookean(1.0, 0.3)
    for surfaces in ((("slab", "zmax"), ("die", "zmin")), (("die", "zmin"), ("slab", "zmax"))):
        model = Model(
            bodies=[Body("slab", block, mat), Body("die", die, mat)],
            dirichlet=[Dirichlet("slab", "zmin", "xyz"), Dirichlet("die", "zmax", "xyz")],
            interfaces=[ContactInterface(*surfaces)],
        )
        assert model.interfaces[0].nonmortar == surfaces[0]  # validated: the sets exist and face each other
