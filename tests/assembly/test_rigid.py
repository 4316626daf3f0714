"""Rigid tools in a Model: the prescribed rigid motion, the stress-free layer, and what a rigid body refuses."""

import pickle

import numpy as np
import pytest

from contopt.assembly.model import Body, BodyForce, Dirichlet, LoadPath, Model, RigidMotion, SoftSupport
from contopt.assembly.system import discretize
from contopt.contact import ContactInterface
from contopt.errors import ConfigError
from contopt.material import neo_hookean
from contopt.mesh.generators import box
from contopt.mesh.tool import sphere_surface, tool_layer

AXIS = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])


def test_a_rigid_motion_rotates_about_its_axis_through_its_point_and_translates():
    m = RigidMotion(translation=(0.1, 0.2, -0.3), axis=3 * AXIS, point=(1.0, 0.0, 2.0), angle=np.pi / 2)
    R = m.rotation(1.0)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R @ AXIS, AXIS, atol=1e-15)  # the axis stays
    # a point on the axis only translates; one off it turns by the angle about it
    X = np.array([[1.0, 0.0, 2.0], [1.0, 0.0, 2.0] + 0.7 * AXIS, [1.0, 0.0, 2.0] + np.cross(AXIS, [0, 0, 1.0])])
    x = X + m(X, 1.0)
    np.testing.assert_allclose(x[:2] - X[:2], [[0.1, 0.2, -0.3]] * 2, atol=1e-15)
    r0, r1 = X[2] - X[0], x[2] - x[0]
    assert r0 @ r1 == pytest.approx(0.0, abs=1e-15) and np.cross(r0, r1) @ AXIS > 0  # a right-handed quarter turn
    # at half the load: half the translation and half the angle
    np.testing.assert_allclose(m.offset(0.5), [0.05, 0.1, -0.15])
    np.testing.assert_allclose(m.rotation(0.5), RigidMotion(axis=AXIS, angle=np.pi / 4).rotation(1.0), atol=1e-15)


def test_a_rigid_motion_follows_paths_and_pickles():
    m = RigidMotion(
        translation=LoadPath(((0.5, 0.0, 0.0, -0.1), (1.0, 0.4, 0.0, -0.1))),
        angle=LoadPath(((0.5, 0.0), (1.0, 0.3))),
    )
    np.testing.assert_allclose(m.offset(0.25), [0.0, 0.0, -0.05])
    np.testing.assert_allclose(m.rotation(0.5), np.eye(3))
    np.testing.assert_allclose(m.rotation(0.75), RigidMotion(angle=0.15).rotation(1.0), atol=1e-15)
    assert pickle.loads(pickle.dumps(m)) == m and repr(pickle.loads(pickle.dumps(m))) == repr(m)
    for bad, match in (
        ({"translation": LoadPath(((1.0, 0.1),))}, "needs 3"),
        ({"angle": LoadPath(((1.0, 0.1, 0.2),))}, "needs 1"),
        ({"axis": (0, 0, 0)}, "nonzero"),
        ({"angle": "30"}, "radians"),
        ({"point": (1, 2)}, "point"),
    ):
        with pytest.raises(ConfigError, match=match):
            RigidMotion(**bad)


def _tool_and_block(motion, **model):
    tool = tool_layer(sphere_surface(0.5, [0.0, 0.0, 1.5], divisions=3))
    block = Body("block", box((1.0, 1.0, 1.0), (1, 1, 1), origin=(-0.5, -0.5, 0.0)), neo_hookean(1.0, 0.3))
    return Model(bodies=(block, Body("tool", tool, rigid=motion)), **model)


def test_the_layer_stores_no_energy_and_exerts_no_force_under_a_large_rigid_motion():
    """A trilinear cell moved rigidly has F = R at every point: zero energy and zero nodal forces to
    round-off, whatever its shape (the sphere's layer is far from box-shaped)."""
    model = _tool_and_block(RigidMotion(translation=(0.3, -1.0, 2.0), axis=AXIS, point=(0.2, 0.0, 1.0), angle=2.2))
    disc = discretize(model)
    tool = disc.body_slice("tool")
    assert np.isin(np.arange(disc.n_dofs)[tool], disc.constrained).all()  # no unknowns
    u = np.zeros(disc.n_dofs)
    u[disc.constrained] = disc.prescribed(1.0)
    ev = disc.evaluate(u, 1.0, tangent=False)
    # E = 1, cells of about 0.3: a strain of round-off gives forces of ~1e-17
    assert abs(ev.energy) < 1e-15 and np.abs(ev.r[tool]).max() < 1e-15
    # the same nodes stretched by 1 % are not stress-free: the test can fail
    stretched = u.copy()
    stretched[tool] += 0.01 * model.body("tool").mesh.points.ravel()
    assert np.abs(disc.evaluate(stretched, 1.0, tangent=False).r[tool]).max() > 1e-4


def test_a_rigid_body_refuses_a_material_supports_loads_and_a_design_side():
    tool = tool_layer(sphere_surface(0.5, [0.0, 0.0, 1.5], divisions=2))
    with pytest.raises(ConfigError, match="takes no material"):
        Body("tool", tool, neo_hookean(1.0, 0.3), rigid=RigidMotion())
    with pytest.raises(ConfigError, match="or the body rigid"):
        Body("block", tool)
    with pytest.raises(ConfigError, match="remove the support on tool/surface"):
        _tool_and_block(RigidMotion(), dirichlet=(Dirichlet("tool", "surface", "z", -0.1),))
    with pytest.raises(ConfigError, match="a load on it does nothing"):
        _tool_and_block(RigidMotion(), loads=(BodyForce("tool", (0, 0, -1.0)),))
    with pytest.raises(ConfigError, match="a soft support on it does nothing"):
        _tool_and_block(RigidMotion(), soft_supports=(SoftSupport("tool", 1.0),))
    # its motion is the one Dirichlet on it, once, also in a model rebuilt from it
    model = _tool_and_block(RigidMotion(translation=(0, 0, -0.1)))
    assert [(bc.body, bc.node_set, bc.components) for bc in model.dirichlet] == [("tool", "all", "xyz")]
    assert len(Model(model.bodies, model.dirichlet).dirichlet) == 1


def test_a_rigid_surface_is_the_mortar_side():
    sides = (("tool", "surface"), ("block", "zmax"))
    # chosen: the tool's facets are finer than the block's (the size rule would make it nonmortar)
    model = _tool_and_block(RigidMotion(), interfaces=(ContactInterface(surfaces=sides),))
    iface = model.interfaces[0]
    assert iface.nonmortar == ("block", "zmax") and "rigid tool" in iface.choice and "rigid" in iface.choice
    assert iface.mismatch(model) == ""
    with pytest.raises(ConfigError, match="must be the mortar side: swap nonmortar and mortar"):
        _tool_and_block(RigidMotion(), interfaces=(ContactInterface(*sides),))
    # E* is the deformable side's E' alone, and the penalty's cap follows it
    E1 = 1.0 / (1 - 0.3**2)
    assert iface.default_eps(model) == pytest.approx(iface.law.resolve_eps(E1, 1.0), rel=1e-12)
    assert np.isfinite(iface.max_eps(model))
    # two rigid bodies cannot be in contact
    other = Body("other", tool_layer(sphere_surface(0.5, [0.0, 0.0, -1.0], divisions=2)), rigid=RigidMotion())
    with pytest.raises(ConfigError, match="both bodies are rigid"):
        Model(
            bodies=(*model.bodies, other),
            interfaces=(ContactInterface(surfaces=(("tool", "surface"), ("other", "surface"))),),
        )
