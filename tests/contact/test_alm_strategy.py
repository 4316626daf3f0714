"""How the solver drives contact to convergence: inexact augmentations, the modified tangent
at deep penetration, and the merit function near convergence."""

from types import SimpleNamespace

import numpy as np

from contopt.assembly.model import Body, Dirichlet, Model
from contopt.cases.die_slab import die_slab
from contopt.contact.interface import ContactInterface
from contopt.material import neo_hookean
from contopt.mesh.generators import box
from contopt.solve.linesearch import line_search
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import AugmentationOptions, solve_static
from contopt.solve.system import DEEP_PENETRATION, System


def test_inexact_augmentations_reach_the_same_equilibrium_in_fewer_iterations():
    prob = System.of(die_slab(slab_divisions=(9, 4, 3)))
    full = solve_static(prob, newton=NewtonOptions(n_steps=2), augmentation=AugmentationOptions(inexact=0.0))
    fast = solve_static(prob, newton=NewtonOptions(n_steps=2))
    assert fast.t == full.t == 1.0
    assert fast.newton_iterations < full.newton_iterations
    assert any(lg.message == "good enough" for lg in fast.logs)
    assert not any(lg.message == "good enough" for lg in full.logs)
    last = fast.logs[-1]  # the accepted augmentation is solved to the Newton tolerances
    assert last.message == "" and last.residuals[-1] <= 1e-9 * last.r_ref
    lam_full, lam_fast = full.contact[0].lam, fast.contact[0].lam
    assert np.abs(lam_fast - lam_full).max() <= 1e-5 * lam_full.max()
    assert np.abs(fast.u - full.u).max() <= 1e-6 * np.abs(full.u).max()


def _pressed(depth):
    lower = box((1.0, 1.0, 0.5), (4, 4, 2), origin=(0.0, 0.0, -0.5))
    upper = box((0.6, 0.6, 0.3), (3, 3, 1), origin=(0.2, 0.2, 0.0))
    model = Model(
        bodies=(Body("lo", lower, neo_hookean(1.0, 0.3)), Body("up", upper, neo_hookean(1.0, 0.3))),
        dirichlet=(Dirichlet("lo", "zmin", "xyz"), Dirichlet("up", "zmax", "xyz")),
        interfaces=(ContactInterface(("lo", "zmax"), ("up", "zmin"), law="penalty"),),
    )
    prob = System.of(model)
    u = np.zeros(prob.disc.n_dofs)
    up = prob.disc.body_slice("up")
    u[up] = np.tile([0.0, 0.0, -depth * prob.contact.blocks[0].h], prob.disc.blocks[1].n_nodes)
    return prob, u


def test_deep_penetration_offers_the_tangent_without_gap_curvature():
    prob, u = _pressed(2.0 * DEEP_PENETRATION)
    p = prob.start_states()
    ev = prob.evaluate(u, 1.0, prob.disc.layout(), p)
    assert ev.modified is not None
    M = ev.modified.K_free().toarray()
    bulk = prob.disc.evaluate(u, 1.0).K_free.toarray()
    normal = M - bulk
    # the modified contact part is the positive semi-definite sum of eps H/a w w^T
    assert np.linalg.eigvalsh(normal).min() >= -1e-10 * np.abs(normal).max()
    assert np.abs(ev.K_free.toarray() - M).max() > 1e-6 * np.abs(normal).max()  # curvature was dropped
    shallow, u_shallow = _pressed(0.5 * DEEP_PENETRATION)
    assert shallow.evaluate(u_shallow, 1.0, shallow.disc.layout(), p).modified is None


def test_near_convergence_the_residual_norm_is_the_merit():
    # the full step "lowers" the energy (as round-off can) but doubles the residual: near
    # convergence it is refused; far from it the energy decides
    def evaluate(u, tangent):
        r = np.array([2e-6]) if u[0] > 0.75 else np.array([0.5e-6])
        return SimpleNamespace(r=r, energy=-1e-9 * u[0], K_free=np.eye(1), timings=None)

    ev0 = SimpleNamespace(r=np.array([-1e-6]), energy=0.0, K_free=np.eye(1))
    args = (np.zeros(1), np.ones(1), ev0, np.arange(1))
    _, _, alpha_near, _ = line_search(evaluate, *args, True, False, NewtonOptions(), lambda ev: None)
    _, _, alpha_far, _ = line_search(evaluate, *args, False, False, NewtonOptions(), lambda ev: None)
    assert alpha_near == 0.5 and alpha_far == 1.0


def test_touch_closes_nearby_open_nodes_in_the_tangent_only():
    # the blocks are apart by 0.2 h: no contact force, no contact stiffness, unless the
    # caller (the predictor of a prescribed increment) asks for nodes within reach
    prob, u = _pressed(-0.2)
    h = prob.contact.blocks[0].h
    p = prob.start_states()
    plain = prob.evaluate(u, 1.0, prob.disc.layout(), p)
    reach = prob.evaluate(u, 1.0, prob.disc.layout(), p, touch=0.5 * h)
    np.testing.assert_array_equal(plain.r, reach.r)
    assert plain.energy == reach.energy and np.all(plain.contact[0].lam == 0)
    bulk = prob.disc.evaluate(u, 1.0).K
    assert abs(plain.K - bulk).max() == 0
    extra = (reach.K - bulk).toarray()
    assert np.abs(extra).max() > 0 and np.linalg.eigvalsh(extra).min() >= -1e-10 * np.abs(extra).max()
    assert abs(prob.evaluate(u, 1.0, prob.disc.layout(), p, touch=0.1 * h).K - bulk).max() == 0  # out of reach
