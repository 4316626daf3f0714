"""Coulomb friction in the mortar contact: a pulled block sticks below mu and slides at exactly mu N,
the history carries across load steps, mu = 0 is frictionless, and the unsymmetric tangent is exact.

The block (E = 1, nu = 0: pressing it does not spread its base, which friction would resist with
slip at its edges) stands on a longer, stiff base (E = 1000, so its surface stays flat to ~1e-4 and
the contact frame is the x-y plane) whose bottom is clamped. Its top face is moved along a path:
pressed down by ``PRESS`` over the first half of the load, then pulled along x. The reactions on the
top face are the forces the contact exerts on the block (it carries no other load). The block's
facet edges are kept off the base's: where the two meshes' edges coincide exactly, the segmentation
of the overlap flips between topologies at round-off and Newton stalls at ~1e-8 relative.
"""

from dataclasses import replace

import numpy as np
import pytest

from contopt.assembly.model import Body, Dirichlet, Model
from contopt.cases.sliding_block import sliding_block
from contopt.contact.interface import ContactInterface
from contopt.errors import ConfigError, ConvergenceError
from contopt.material import neo_hookean
from contopt.mesh.generators import box
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import AugmentationOptions, State, solve_static
from contopt.solve.system import System

PRESS = 0.01
TIGHT = NewtonOptions(rtol=1e-11, utol=1e-11, n_steps=4)


def block_model(mu, pull, law=None, back=0.0):
    return sliding_block(mu=mu, pull=pull, back=back, press=PRESS, law=law or "penalty")


def top_force(model, state):
    """(3,) the force the top face exerts on the block: minus the contact's, ``sum t a - e_z sum lam a``
    (the friction traction t points along the block's slip, the force it exerts against it)."""
    mesh = model.bodies[0].mesh
    nodes = mesh.node_set("zmax")
    return state.reactions.reshape(-1, 3)[nodes].sum(axis=0)


def contact_forces(state):
    """(tangential (3,), normal) forces the block's contact surface carries: sum t_A a_A, sum lam_A a_A."""
    res = state.contact[0]
    return (res.traction * res.a[:, None]).sum(axis=0), float(res.lam @ res.a)


@pytest.fixture(scope="module")
def sliding():
    model = block_model(0.3, 0.1)
    return model, solve_static(model, newton=TIGHT)


def test_a_block_pulled_far_slides_at_exactly_mu_times_the_normal_force(sliding):
    model, state = sliding
    res = state.contact[0]
    active = res.lam > 0
    assert active.sum() == 25 and not res.friction.stick[active].any()  # every node slides
    # on the cone node by node
    np.testing.assert_allclose(np.linalg.norm(res.traction[active], axis=1), 0.3 * res.lam[active], rtol=1e-12)
    # the friction force over the normal force: mu, up to the spread of the nodes' slip directions
    tangential, normal = contact_forces(state)
    assert np.linalg.norm(tangential) / normal == pytest.approx(0.3, rel=1e-6)
    # the block carries only the top-face force and the contact (Newton's tolerance bounds the rest);
    # the stiff base's surface tilts by ~1e-4 under the block
    F = top_force(model, state)
    np.testing.assert_allclose(F, tangential - [0, 0, normal], rtol=0, atol=1e-5 * normal)
    assert F[0] / abs(F[2]) == pytest.approx(0.3, rel=1e-3)  # the top face pulls forward against friction


def test_a_block_pulled_a_little_sticks_below_mu():
    model = block_model(0.3, 0.002)
    state = solve_static(model, newton=TIGHT)
    res = state.contact[0]
    active = res.lam > 0
    assert active.sum() == 25 and res.friction.stick[active].all()
    F = top_force(model, state)
    assert 0 < F[0] < 0.3 * abs(F[2])
    # and the same pull with a smaller coefficient slides
    state = solve_static(block_model(0.02, 0.002), newton=TIGHT)
    res = state.contact[0]
    assert not res.friction.stick[res.lam > 0].any()


def test_the_friction_history_carries_across_load_steps(sliding):
    # slide forward, then move back a little: the tractions unload elastically (stick) and keep
    # their sign instead of jumping to -mu N, as a path-independent law would
    _, forward = sliding
    model = block_model(0.3, 0.1, back=1e-3)
    state = solve_static(model, newton=TIGHT)
    res = state.contact[0]
    active = res.lam > 0
    # most nodes unload elastically; every traction keeps pointing forward (a path-independent law
    # would give -mu lam everywhere: the block moved back)
    assert res.friction.stick[active].sum() >= 15 and (res.traction[active, 0] > 0).all()
    F, F_slide = top_force(model, state), top_force(block_model(0.3, 0.1), forward)
    assert 0 < F[0] < 0.95 * 0.3 * abs(F[2]) and F_slide[0] == pytest.approx(0.3 * abs(F_slide[2]), rel=1e-3)


def test_mu_zero_reproduces_frictionless_contact_to_round_off():
    free = solve_static(block_model(None, 0.05), newton=TIGHT)
    zero = solve_static(block_model(0.0, 0.05), newton=TIGHT)
    assert not zero.contact[0].traction.any()
    np.testing.assert_allclose(zero.u, free.u, rtol=0, atol=1e-12 * np.abs(free.u).max())


def test_friction_with_the_augmented_lagrangian_converges_every_step_and_slides_at_mu():
    alm = AugmentationOptions(pressure_rtol=1e-9, gap_rtol=1e-9)
    model = block_model(0.3, 0.1, law="alm")
    state = solve_static(model, newton=NewtonOptions(rtol=1e-11, utol=1e-11, n_steps=4), augmentation=alm)
    # every load step converged its multipliers: its last log reached the tolerances
    steps = [lg for lg in state.logs if lg.converged]
    assert state.alm_updates >= 4
    pen = [lg.extra["penetration"] for lg in steps]
    assert min(pen) >= 0 and pen[-1] <= 1e-7
    tangential, normal = contact_forces(state)
    assert np.linalg.norm(tangential) / normal == pytest.approx(0.3, rel=1e-6)


def test_the_unsymmetric_tangent_is_exact(rng):
    # a state with sticking and sliding nodes and a history: the block pushed into the base and
    # sheared unevenly from a previous position with tractions on the nodes
    model = block_model(0.3, 0.0)
    system = System.of(model)
    contact = system.contact
    n = system.disc.n_dofs
    X = contact.X
    block_nodes = np.arange(model.bodies[0].mesh.n_nodes)
    u_prev = np.zeros((len(X), 3))
    u = np.zeros((len(X), 3))
    u[block_nodes, 2] = -0.004
    u[block_nodes, 0] = 0.0005 + 0.003 * (X[block_nodes, 1] - 0.27)  # slip grows across the block
    u[block_nodes, 1] = 0.001 * X[block_nodes, 0]
    states = contact.begin_step(system.start_states(), u_prev.ravel())
    nn = contact.blocks[0].n_nodes
    states = (states[0].__class__(**{**states[0].__dict__, "traction": 0.02 * rng.normal(size=(nn, 3))}),)
    ev = contact.evaluate(u.ravel(), states)
    stick = ev.results[0].friction.stick
    sliding = (np.abs(ev.results[0].traction).sum(1) > 0) & ~stick
    assert stick.sum() >= 3 and sliding.sum() >= 3
    assert abs(ev.K - ev.K.T).max() > 1e-3 * abs(ev.K).max()  # not symmetric
    v = rng.normal(size=n)
    h = 1e-7
    rp = contact.evaluate(u.ravel() + h * v, states, tangent=False).r
    rm = contact.evaluate(u.ravel() - h * v, states, tangent=False).r
    fd = (rp - rm) / (2 * h)
    assert np.linalg.norm(ev.K @ v - fd) <= 1e-6 * np.linalg.norm(fd)


def test_friction_refuses_a_warm_start_and_bad_coefficients():
    model = block_model(0.3, 0.01)
    with pytest.raises(ConfigError, match="warm start"):
        solve_static(model, start=State(u=np.zeros(System.of(model).disc.n_dofs)))
    with pytest.raises(ConfigError, match="friction"):
        ContactInterface(("block", "zmin"), ("base", "zmax"), friction="0.3")
    with pytest.raises(ConfigError, match="mu"):
        ContactInterface(("block", "zmin"), ("base", "zmax"), friction=-1.0)


def test_a_frictional_solve_that_fails_says_what_to_try_for_friction():
    hopeless = NewtonOptions(max_iter=1, n_steps=1, min_step=0.5)
    with pytest.raises(ConvergenceError, match=r"friction\.edge = 0\.1 to 0\.15.*friction\.eps") as err:
        solve_static(block_model(0.3, 0.1), newton=hopeless)
    assert "minimum load step" in str(err.value)
    with pytest.raises(ConvergenceError) as err:  # frictionless: the general advice alone
        solve_static(block_model(None, 0.1), newton=hopeless)
    assert "minimum load step" in str(err.value) and "friction" not in str(err.value)


def test_a_failed_frictional_step_is_solved_again_through_a_continuation_in_the_cone_edge(monkeypatch, sliding):
    import contopt.solve.static as static

    model, plain = sliding
    real, calls = static._load_step, []

    def third_step_fails_once(ctx, u, t, *rest, **kwargs):
        calls.append((t, [b.friction.edge for b in ctx.system.contact.blocks], "u_init" in kwargs))
        if len(calls) == 3:  # the third load step's first attempt: a real failure (one iteration allowed)
            ctx = replace(ctx, newton=replace(ctx.newton, max_iter=1))
        return real(ctx, u, t, *rest, **kwargs)

    monkeypatch.setattr(static, "_load_step", third_step_fails_once)
    state = solve_static(model, newton=TIGHT)
    third = [c for c in calls if c[0] == 0.75]
    # no cutback: the step again with edges 0.4, 0.2, 0.1, each from the last one's solution, then its own
    assert [c[1] for c in third] == [[0.05], [0.4], [0.2], [0.1], [0.05]]
    assert [c[2] for c in third] == [False, True, True, True, True]
    assert [lg.t for lg in state.logs].count(0.75) == 5 and not state.logs[2].converged
    # the same equilibrium as the plain solve: the step's history and the interface's own law
    scale = np.abs(plain.u).max()
    np.testing.assert_allclose(state.u, plain.u, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(state.contact[0].traction, plain.contact[0].traction, rtol=0, atol=1e-9)


def test_an_optimization_with_friction_takes_either_normal_law_and_its_adjoint_needs_the_path():
    from contopt.adjoint.sensitivity import sensitivities
    from contopt.design import Density, Design, DesignedBody
    from contopt.optimize.problem import DesignProblem
    from contopt.responses import StrainEnergy

    design = Design(DesignedBody("block", Density(0.2), volume_fraction=0.5))
    for law in ("penalty", "alm"):
        problem = DesignProblem(model=block_model(0.3, 0.01, law=law), objective=StrainEnergy("block"), design=design)
        assert problem.model.interfaces[0].law.name == law
    model = block_model(0.3, 0.01)
    with pytest.raises(ConfigError, match="needs the load steps"):  # a state without its path
        sensitivities(System.of(model), State(u=np.zeros(System.of(model).disc.n_dofs)), StrainEnergy())


# ------------------------------------------------------------------------------ patch test
def _patch_model(mu, divisions_upper=3, divisions_lower=5, p=1e-5, tau=2e-6):
    """Two blocks (nu = 0) on the same unit footprint, non-matching meshes, the upper one under a dead
    pressure p and shear tau on its top and the complementary shear on the x faces of both: a uniform
    state (compression + simple shear) whose contact pressure is p and friction traction tau, held
    tangentially by friction alone."""
    from contopt.assembly.model import Traction

    upper = box((1.0, 1.0, 0.5), (divisions_upper, divisions_upper, 2), origin=(0.0, 0.0, 1.0))
    lower = box((1.0, 1.0, 1.0), (divisions_lower, divisions_lower, 2))
    shear = []
    for body in ("upper", "lower"):
        shear += [Traction(body, "xmax", (0.0, 0.0, tau)), Traction(body, "xmin", (0.0, 0.0, -tau))]
    return Model(
        bodies=(Body("upper", upper, neo_hookean(1.0, 0.0)), Body("lower", lower, neo_hookean(1.0, 0.0))),
        dirichlet=(Dirichlet("lower", "zmin", "xyz"),),
        loads=(Traction("upper", "zmax", (tau, 0.0, -p)), *shear),
        interfaces=(ContactInterface(("upper", "zmin"), ("lower", "zmax"), law="penalty", friction=mu),),
    )


@pytest.mark.parametrize("nonmatching", [(3, 5), (5, 3)], ids=["coarse-on-fine", "fine-on-coarse"])
def test_frictional_patch_test_transmits_uniform_pressure_and_shear(nonmatching):
    # the homogeneous state is exact in the small-strain limit: at finite strain the dead loads turn
    # with the shear gamma ~ 4 tau / E, which tilts the pressure by ~ gamma p / tau relative across
    # the face (measured 6e-4 at p = 1e-3, E = 1). At p = 1e-5 that is ~6e-6; Newton adds less.
    model = _patch_model(0.5, *nonmatching)
    state = solve_static(model, newton=NewtonOptions(rtol=1e-12, utol=1e-12))
    res = state.contact[0]
    assert (res.lam > 0).all() and res.friction.stick.all()
    np.testing.assert_allclose(res.lam, 1e-5, rtol=1e-4)
    np.testing.assert_allclose(res.traction, np.tile([2e-6, 0.0, 0.0], (len(res.lam), 1)), rtol=0, atol=1e-4 * 2e-6)
