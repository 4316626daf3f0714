"""Assembly of loads, Dirichlet data and several bodies."""

import numpy as np
import pytest

from contopt.assembly.model import Acceleration, Body, BodyForce, Dirichlet, Interface, Model, Traction
from contopt.assembly.system import discretize
from contopt.contact import ContactInterface, Penalty
from contopt.errors import ConfigError, MeshError
from contopt.material import MooneyRivlin, neo_hookean
from contopt.mesh.generators import box
from contopt.solve.static import solve_static


def _one_block(**kw):
    return Model(bodies=(Body("b", box((2.0, 1.0, 3.0), (2, 3, 4)), neo_hookean(1.0, 0.3, mass_density=2.5)),), **kw)


def test_traction_and_body_forces_integrate_to_resultants():
    m = _one_block(
        loads=(
            Traction("b", "xmax", (0.5, -1.0, 2.0)),
            BodyForce("b", (0.0, 0.0, -3.0)),
            Acceleration("b", (4.0, 0.0, 0.0)),
        )
    )
    d = discretize(m)
    f = d.f_ext_unit.reshape(-1, 3).sum(axis=0)
    area, vol = 1.0 * 3.0, 2.0 * 1.0 * 3.0
    expected = area * np.array([0.5, -1.0, 2.0]) + vol * np.array([0.0, 0.0, -3.0]) - 2.5 * vol * np.array([4.0, 0, 0])
    np.testing.assert_allclose(f, expected, rtol=1e-13, atol=1e-13)
    # the traction only loads the nodes of the xmax face
    fx = discretize(_one_block(loads=(Traction("b", "xmax", (1.0, 0, 0)),))).f_ext_unit.reshape(-1, 3)
    off = np.setdiff1d(np.arange(len(fx)), m.bodies[0].mesh.node_set("xmax"))
    assert np.abs(fx[off]).max() == 0.0


def test_dirichlet_values_scale_with_load_factor_and_callables_get_t():
    rot = lambda X, t: np.stack([t * X[:, 1], -t * X[:, 0]], axis=1)  # noqa: E731
    m = _one_block(
        dirichlet=(
            Dirichlet("b", "zmin", "xyz", 0.0),
            Dirichlet("b", "zmax", "z", -0.2),
            Dirichlet("b", "xmin", "xy", rot),
        )
    )
    d = discretize(m)
    mesh = m.bodies[0].mesh
    for t in (0.25, 1.0):
        full = np.full(d.n_dofs, np.nan)
        full[d.constrained] = d.prescribed(t)
        u = full.reshape(-1, 3)
        top = np.setdiff1d(mesh.node_set("zmax"), np.union1d(mesh.node_set("xmin"), mesh.node_set("zmin")))
        np.testing.assert_allclose(u[top, 2], -0.2 * t)
        left = np.setdiff1d(mesh.node_set("xmin"), mesh.node_set("zmin"))
        X = mesh.points[left]
        np.testing.assert_allclose(u[left, 0], t * X[:, 1])
        np.testing.assert_allclose(u[left, 1], -t * X[:, 0])
    assert d.free.size + d.constrained.size == d.n_dofs


def test_two_bodies_stack_and_solve_independently():
    mesh_a = box((1.0, 1.0, 1.0), (2, 2, 2))
    mesh_b = box((1.0, 1.0, 2.0), (2, 2, 3), origin=(3.0, 0.0, 0.0))
    mat_a, mat_b = neo_hookean(1.0, 0.3), MooneyRivlin.from_E_nu(5.0, 0.4, 0.3)
    bcs = lambda name, dz: (Dirichlet(name, "zmin"), Dirichlet(name, "zmax", "xyz", (0.0, 0.0, dz)))  # noqa: E731
    both = Model(bodies=(Body("a", mesh_a, mat_a), Body("b", mesh_b, mat_b)), dirichlet=bcs("a", -0.3) + bcs("b", 0.4))
    sa = solve_static(Model(bodies=(Body("a", mesh_a, mat_a),), dirichlet=bcs("a", -0.3)))
    sb = solve_static(Model(bodies=(Body("b", mesh_b, mat_b),), dirichlet=bcs("b", 0.4)))
    s = solve_static(both)
    d = discretize(both)
    assert d.n_dofs == 3 * (mesh_a.n_nodes + mesh_b.n_nodes)
    np.testing.assert_allclose(d.body_displacement(s.u, "a").ravel(), sa.u, atol=1e-10)
    np.testing.assert_allclose(d.body_displacement(s.u, "b").ravel(), sb.u, atol=1e-10)
    assert d.cell_slice("b") == slice(mesh_a.n_cells, mesh_a.n_cells + mesh_b.n_cells)


def test_rho_scales_the_stiffness_of_its_cells():
    m = _one_block(dirichlet=(Dirichlet("b", "zmin"),), loads=(Traction("b", "zmax", (0.0, 0.0, 1e-3)),))
    d = discretize(m)
    u = np.random.default_rng(0).standard_normal(d.n_dofs) * 1e-2
    rho = np.full(d.n_cells, 0.25)
    r1, r2 = d.evaluate(u, 0.0, None, tangent=False).r, d.evaluate(u, 0.0, rho, tangent=False).r
    np.testing.assert_allclose(r2, 0.25 * r1, rtol=1e-12, atol=1e-15)
    with pytest.raises(ConfigError, match="one value per cell"):
        d.evaluate(u, 0.0, np.ones(3))
    with pytest.raises(ConfigError, match="> 0"):
        d.evaluate(u, 0.0, np.zeros(d.n_cells))


def test_bad_names_give_clear_errors():
    mesh = box((1, 1, 1), (1, 1, 1))
    body = Body("b", mesh, neo_hookean(1.0, 0.3))
    with pytest.raises(ConfigError, match="unknown body 'nope'"):
        Model(bodies=(body,), dirichlet=(Dirichlet("nope", "zmin"),))
    with pytest.raises(MeshError, match="unknown node set 'top'.*zmax"):
        Model(bodies=(body,), dirichlet=(Dirichlet("b", "top"),))
    with pytest.raises(MeshError, match="unknown facet set 'side'"):
        Model(bodies=(body,), loads=(Traction("b", "side", (1, 0, 0)),))
    with pytest.raises(ConfigError, match="components"):
        Dirichlet("b", "zmin", "xw")
    # an interface is whatever follows the declared protocol (label, resolved, validate)
    with pytest.raises(ConfigError, match="interfaces must be ContactInterface.*got tuple"):
        Model(bodies=(body,), interfaces=(("b", "zmin"),))
    assert isinstance(ContactInterface(("b", "zmin"), ("c", "zmax"), law=Penalty()), Interface)
    with pytest.raises(ConfigError, match="mass_density"):
        Model(bodies=(body,), loads=(Acceleration("b", (1, 0, 0)),))
    with pytest.raises(ConfigError, match="unique"):
        Model(bodies=(body, body))


def test_a_traction_on_an_empty_facet_set_is_refused():
    """As the problem files refuse it: a load on no face would vanish silently."""
    mesh = box((1, 1, 1), (2, 2, 2))
    empty = mesh.with_sets(facet_sets={"band": np.zeros((0, 2), np.int64)})
    body = Body("b", empty, neo_hookean(1.0, 0.3))
    with pytest.raises(ConfigError, match=r"Traction on b/band: the facet set is empty"):
        Model(bodies=(body,), dirichlet=(Dirichlet("b", "zmin"),), loads=(Traction("b", "band", (1, 0, 0)),))


def test_a_warm_start_of_another_model_or_kind_is_a_config_error():
    from contopt.solve.static import State

    model = _one_block(dirichlet=(Dirichlet("b", "zmin"),), loads=(Traction("b", "zmax", (0.0, 0.0, -0.01)),))
    state = solve_static(model)
    with pytest.raises(
        ConfigError,
        match=r"start.u must have one value per dof \(180\), got \(7,\): the state "
        r"belongs to another model",
    ):
        solve_static(model, start=State(u=np.zeros(7)))
    with pytest.raises(ConfigError, match=r"start must be a State .* got ndarray"):
        solve_static(model, start=state.u)
    warm = solve_static(model, start=State(u=state.u.astype(np.float32)))  # converted, not mixed
    assert warm.u.dtype == np.float64 and np.allclose(warm.u, state.u, rtol=1e-6, atol=1e-12)


def test_a_load_path_is_piecewise_linear_from_zero_and_checked():
    from contopt.assembly.model import LoadPath

    path = LoadPath(((0.5, 0.0, 0.0, -0.01), (1.0, 0.1, 0.0, -0.01)))
    X = np.zeros((3, 3))
    np.testing.assert_allclose(path(X, 0.25), np.tile([0.0, 0.0, -0.005], (3, 1)), atol=1e-16)
    np.testing.assert_allclose(path(X, 0.75), np.tile([0.05, 0.0, -0.01], (3, 1)), atol=1e-16)
    np.testing.assert_allclose(path(X, 1.0), np.tile([0.1, 0.0, -0.01], (3, 1)), atol=1e-16)
    for bad in ((), ((0.5, 1.0), (0.4, 2.0)), ((0.5, 1.0),), ((0.0, 1.0), (1.0, 2.0)), (("a", 1.0),)):
        with pytest.raises(ConfigError, match="LoadPath"):
            LoadPath(bad)
    with pytest.raises(ConfigError, match="load path has 3 values per row"):
        Dirichlet("b", "top", "z", path)


def test_the_tangent_assembled_chunk_by_chunk_is_the_sum_of_the_element_tangents():
    """evaluate() adds each chunk's element tangents as the kernels make them (two bodies, chunks
    of 16 cells, the last one padded): the CSR data is that of the element tangents summed whole,
    bitwise, and the tangent is the residual's derivative."""
    from contopt.assembly.kernels import element_residuals_tangents

    mesh_a, mesh_b = box((1.0, 1.0, 2.0), (3, 3, 4)), box((1.0, 1.0, 1.0), (2, 3, 3), origin=(2.0, 0.0, 0.0))
    model = Model(bodies=(Body("a", mesh_a, neo_hookean(1.0, 0.3)), Body("b", mesh_b, neo_hookean(3.0, 0.4))))
    d = discretize(model, chunk=16)
    u = np.random.default_rng(1).standard_normal(d.n_dofs) * 0.05
    rho = np.linspace(0.2, 1.0, d.n_cells)
    K = d.evaluate(u, 0.0, rho).K_terms[0]
    whole = [
        element_residuals_tangents(
            u[b.dofs].reshape(-1, 8, 3),
            b.geometry.grad,
            b.geometry.wdet,
            rho[b.owned_cells],
            b.params,
            b.energy,
            b.fbar,
            chunk=16,
        )[2]
        for b in d.blocks
    ]
    assert np.array_equal(K.data, d.pattern.assemble_data(whole))
    v, h = np.random.default_rng(2).standard_normal(d.n_dofs), 1e-6
    fd = (d.evaluate(u + h * v, 0.0, rho, tangent=False).r - d.evaluate(u - h * v, 0.0, rho, tangent=False).r) / (2 * h)
    assert np.linalg.norm(K @ v - fd) <= 1e-6 * np.linalg.norm(fd)
