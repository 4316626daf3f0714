"""Coulomb friction on tet10 faces (the parents' quadratic geometry and transformed weights,
:func:`contopt.contact.quadratic.quadratic_pair_slip`): a frictional patch test in full slip across
non-matching tet10 and hex8 meshes, and the exact unsymmetric tangent."""

from dataclasses import replace

import numpy as np
import pytest

from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.cases.sliding_block import sliding_block
from contopt.contact.coulomb import Coulomb
from contopt.contact.interface import ContactInterface
from contopt.material import neo_hookean
from contopt.mesh.generators import box
from contopt.mesh.tets import tetrahedralize
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System

MU, P = 0.5, 1e-5
TIGHT = NewtonOptions(rtol=1e-12, utol=1e-12, n_steps=2)


def _sliding_patch(tet10_side):
    """Two blocks (nu = 0) on the same unit footprint, non-matching (3 x 3 tet10 cells on 5 x 5 hex8,
    or 3 x 3 hex8 on 5 x 5 tet10); the upper one pressed by a dead pressure p and dragged along x by
    its top face, far enough to slide everywhere: with the complementary shear mu p on the x faces of
    both, a uniform state (compression + simple shear) whose pressure is p and friction traction mu p.
    The drag, 2e-5, is four times the shear's own (gamma h = 2 mu p / E x 0.5 = 5e-6); at 7.5e-6, 28
    of the 49 nodes still stuck. The block slides 1.5e-5 off the base's edge, and the nodes there
    lose that share of their support's contact area, which shows in the pressures at ~1e-4
    (measured 1.24e-4 with the tet10 block, 5.4e-5 with a 3 x 3 x 2 hex8 block in its place)."""
    upper = box((1.0, 1.0, 0.5), (3, 3, 2), origin=(0.0, 0.0, 1.0))
    lower = box((1.0, 1.0, 1.0), (5, 5, 2))
    if tet10_side == "upper":
        upper = tetrahedralize(upper, 2)
    else:
        lower = tetrahedralize(lower, 2)
    tau = MU * P
    shear = []
    for body in ("upper", "lower"):
        shear += [Traction(body, "xmax", (0.0, 0.0, tau)), Traction(body, "xmin", (0.0, 0.0, -tau))]
    mat = neo_hookean(1.0, 0.0)
    return Model(
        bodies=(Body("upper", upper, mat), Body("lower", lower, mat)),
        dirichlet=(Dirichlet("lower", "zmin", "xyz"), Dirichlet("upper", "zmax", "xy", (2e-5, 0.0))),
        loads=(Traction("upper", "zmax", (0.0, 0.0, -P)), *shear),
        interfaces=(ContactInterface(("upper", "zmin"), ("lower", "zmax"), law="penalty", friction=Coulomb(MU)),),
    )


@pytest.mark.parametrize(
    "tet10_side", ["upper", pytest.param("lower", marks=pytest.mark.slow)], ids=["tri6-on-quad", "quad-on-tri6"]
)
def test_frictional_patch_test_slides_at_uniform_pressure_and_mu_times_it(tet10_side):
    # as tests/contact/test_friction.py's stick patch test, exact in the small-strain limit: what the
    # dead loads turning with the shear and the sliver slid off the base leave (docstring of
    # _sliding_patch) is the tolerance. On the split's flat triangles (before) the nodal forces were
    # not the tet10's consistent load and the pressures were off by up to 100 %
    model = _sliding_patch(tet10_side)
    state = solve_static(model, newton=TIGHT)
    res = state.contact[0]
    active = res.a > 0
    assert (res.lam[active] > 0).all() and not res.friction.stick[active].any()  # every node slides
    np.testing.assert_allclose(res.lam[active], P, rtol=3e-4)
    t = np.tile([MU * P, 0.0, 0.0], (active.sum(), 1))
    np.testing.assert_allclose(res.traction[active], t, rtol=0, atol=3e-4 * MU * P)
    # the drag's reaction on the top face is the friction force the contact transmits
    top = model.bodies[0].mesh.node_set("zmax")
    reaction = state.reactions[: 3 * model.bodies[0].mesh.n_nodes].reshape(-1, 3)[top].sum(axis=0)
    assert reaction[0] == pytest.approx(MU * P, rel=1e-6)  # measured 2.5e-8


def _tet10_block(model, **material):
    block = model.bodies[0]
    body = replace(block, mesh=tetrahedralize(block.mesh, 2), **material)
    return replace(model, bodies=(body, model.bodies[1]))


def test_the_unsymmetric_tangent_on_tet10_faces_is_exact(rng):
    # the tet10 block pushed into the base and sheared unevenly from a previous position with
    # tractions on the nodes: sticking and sliding nodes, corners and midpoints
    model = _tet10_block(sliding_block(divisions=2, mu=0.3, pull=0.0))
    system = System.of(model)
    contact = system.contact
    assert contact.blocks[0].parents is not None and contact.blocks[0].parents.kinds == ("tri6", "quad")
    X = contact.X
    nodes = np.arange(model.bodies[0].mesh.n_nodes)
    u = np.zeros((len(X), 3))
    u[nodes, 2] = -0.004
    u[nodes, 0] = 0.0005 + 0.003 * (X[nodes, 1] - 0.27)
    u[nodes, 1] = 0.001 * X[nodes, 0]
    states = contact.begin_step(system.start_states(), np.zeros(system.disc.n_dofs))
    nn = contact.blocks[0].n_nodes
    states = (replace(states[0], traction=0.02 * rng.normal(size=(nn, 3))),)
    ev = contact.evaluate(u.ravel(), states)
    stick = ev.results[0].friction.stick
    sliding = (np.abs(ev.results[0].traction).sum(1) > 0) & ~stick
    assert stick.sum() >= 3 and sliding.sum() >= 3
    assert abs(ev.K - ev.K.T).max() > 1e-3 * abs(ev.K).max()
    v = rng.normal(size=system.disc.n_dofs)
    h = 1e-7
    fd = (
        contact.evaluate(u.ravel() + h * v, states, tangent=False).r
        - contact.evaluate(u.ravel() - h * v, states, tangent=False).r
    ) / (2 * h)
    assert np.linalg.norm(ev.K @ v - fd) <= 1e-6 * np.linalg.norm(fd)
