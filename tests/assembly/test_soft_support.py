"""SoftSupport: a body held only by contact solves, and the springs are gone at the full load."""

import numpy as np
import pytest

from contopt.assembly.model import Body, BodyForce, Dirichlet, Model, SoftSupport
from contopt.assembly.system import discretize
from contopt.contact.interface import ContactInterface
from contopt.errors import ConfigError, ContoptError
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import box
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static

GAP, B = 0.01, 0.05


def _floating(soft: bool) -> Model:
    """A block resting GAP above a clamped base, pushed down by its own weight; only x, y of its top fixed."""
    base = box((1.0, 1.0, 0.5), (3, 3, 2))
    top = box((0.6, 0.6, 0.3), (2, 2, 1), origin=(0.2, 0.2, 0.5 + GAP))
    return Model(
        bodies=(Body("base", base, neo_hookean(1.0, 0.3)), Body("top", top, neo_hookean(1.0, 0.3))),
        dirichlet=(Dirichlet("base", "zmin", "xyz", 0.0), Dirichlet("top", "zmax", "xy", 0.0)),
        loads=(BodyForce("top", (0.0, 0.0, -B)),),
        interfaces=(ContactInterface(nonmortar=("top", "zmin"), mortar=("base", "zmax"), law="penalty"),),
        soft_supports=(SoftSupport("top", stiffness=B / GAP),) if soft else (),
    )


def test_a_body_held_only_by_contact_needs_and_gets_soft_support():
    with pytest.raises(ContoptError):  # singular until the gap closes
        solve_static(_floating(False), newton=NewtonOptions(n_steps=4, min_step=0.05))
    model = _floating(True)
    state = solve_static(model, newton=NewtonOptions(n_steps=4))
    disc = discretize(model)
    assert state.t == 1.0
    top = disc.body_displacement(state.u, "top")
    assert top[:, 2].max() < -GAP * 0.9  # it moved down onto the base
    # at t = 1 the springs are gone: the contact force carries the whole weight
    weight = B * 0.6 * 0.6 * 0.3
    reaction = state.reactions[disc.body_slice("base")].reshape(-1, 3)[:, 2].sum()
    assert reaction == pytest.approx(weight, rel=1e-8)  # r = f_int - f_ext: the support pushes up
    assert disc.spring_stiffness(1.0) is None and disc.spring_stiffness(0.25).max() > 0


def test_soft_support_stiffness_is_lumped_volume_times_k():
    disc = discretize(_floating(True))
    k = disc.spring_stiffness(0.0)[disc.body_slice("top")]
    assert k.sum() == pytest.approx(3 * (B / GAP) * 0.6 * 0.6 * 0.3, rel=1e-12)
    assert np.all(disc.spring_stiffness(0.0)[disc.body_slice("base")] == 0)
    with pytest.raises(ConfigError, match="stiffness"):
        SoftSupport("top", stiffness=-1.0)


def test_the_springs_are_in_the_tangent_on_its_own_pattern():
    """The springs go into the diagonal of the assembled tangent (no other sparsity): K is the
    residual's central difference, K_free its free block, and the pattern the one without springs."""
    disc = discretize(_floating(True))
    u = 1e-3 * np.random.default_rng(0).standard_normal(disc.n_dofs)
    t = 0.25
    ev = disc.evaluate(u, t)
    K = ev.K
    assert len(ev.K_terms) == 1 and K.nnz == disc.pattern.nnz
    assert abs(K - disc.evaluate(u, 1.0).K).max() == pytest.approx(disc.spring_stiffness(t).max(), rel=1e-12)
    free = disc.free
    assert abs(ev.K_free - K[free][:, free]).max() == 0.0
    v = np.random.default_rng(1).standard_normal(disc.n_dofs)
    h = 1e-6
    fd = (disc.evaluate(u + h * v, t, tangent=False).r - disc.evaluate(u - h * v, t, tangent=False).r) / (2 * h)
    assert np.linalg.norm(K @ v - fd) <= 1e-7 * np.linalg.norm(fd)
    assert np.allclose(ev.K_dot(v), K @ v, rtol=0, atol=1e-12 * np.abs(K @ v).max())
