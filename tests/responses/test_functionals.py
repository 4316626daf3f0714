"""Responses: known values and partial derivatives against central finite differences (fixed state)."""

import jax.numpy as jnp
import numpy as np
import pytest

from contopt.cases.two_blocks import two_blocks
from contopt.errors import ConfigError
from contopt.responses import (
    Combination,
    Compliance,
    ContactForce,
    Fields,
    Functional,
    PressureVariance,
    StrainEnergy,
    VolumeFraction,
    builtin,
)
from contopt.solve.system import System


@pytest.fixture(scope="module")
def prob():
    return System.of(two_blocks(divisions=4, body_force=(0.0, 0.1, -0.2)))


def _fields(prob, seed=0, scale=0.02):
    rng = np.random.default_rng(seed)
    disc = prob.disc
    u = scale * rng.standard_normal(disc.n_dofs)
    rho = rng.uniform(0.3, 1.0, disc.n_cells)
    lam = tuple(
        np.where(rng.uniform(size=b.n_nodes) < 0.7, rng.uniform(0.1, 2.0, b.n_nodes), 0.0) for b in prob.contact.blocks
    )
    return Fields(system=prob, u=u, rho=rho, lam=lam, t=1.0)


def _user_pi(u, G, rho, X):
    return rho**2 * (u @ u) * (1.0 + X[0]) + jnp.sum(G * G)


RESPONSES = [
    StrainEnergy(),
    StrainEnergy(bodies=("block",)),
    Compliance(),
    ContactForce(),
    PressureVariance(),
    PressureVariance(normalized=True),
    VolumeFraction(bodies="block"),
    Functional(pi=_user_pi, zeta=lambda lam: lam**3, name="user-gauss"),
    Functional(zeta=lambda lam: jnp.sin(lam), quadrature="nodal", name="user-nodal"),
    2.0 * StrainEnergy() - ContactForce(),
    Combination((StrainEnergy(), ContactForce()), lambda v: v[0] / v[1], name="ratio"),
]


@pytest.mark.parametrize("response", RESPONSES, ids=lambda r: r.name)
def test_partials_match_central_differences(prob, response):
    f = _fields(prob)
    value, p = response.evaluate(f)
    assert value == pytest.approx(response.value(f), rel=1e-14, abs=1e-300)
    rng = np.random.default_rng(7)
    du = rng.standard_normal(f.u.size)
    drho = rng.standard_normal(f.rho.size)
    active = [(lam > 0).astype(float) for lam in f.lam]  # the active set is held fixed
    dlam = tuple(a * rng.standard_normal(a.size) for a in active)
    h = 1e-6

    def at(s):
        g = Fields(
            system=prob,
            u=f.u + s * du,
            rho=f.rho + s * drho,
            lam=tuple(lam + s * d for lam, d in zip(f.lam, dlam)),
            t=1.0,
        )
        return response.value(g)

    fd = (at(h) - at(-h)) / (2 * h)
    exact = p.u @ du + p.rho @ drho + sum(a @ b for a, b in zip(p.lam, dlam))
    assert exact == pytest.approx(fd, rel=1e-7, abs=1e-10 * max(1.0, abs(value)))


def test_strain_energy_equals_the_analysis_energy(prob):
    f = _fields(prob)
    disc = prob.disc
    assert StrainEnergy().value(f) == pytest.approx(disc.strain_energy(f.u, f.rho), rel=1e-13)
    per_cell = disc.strain_energy(f.u, f.rho, per_cell=True)
    assert StrainEnergy(bodies="punch").value(f) == pytest.approx(per_cell[disc.cell_slice("punch")].sum(), rel=1e-13)
    # its u-partial is the internal force of the analysis
    _, p = StrainEnergy().evaluate(f)
    ev = disc.evaluate(f.u, 0.0, f.rho, tangent=False)
    np.testing.assert_allclose(p.u, ev.r, rtol=1e-10, atol=1e-12)


def test_contact_force_of_a_uniform_pressure_is_pressure_times_area(prob):
    f = _fields(prob)
    lam = tuple(np.full_like(v, 2.5) for v in f.lam)
    zero_u = Fields(system=prob, u=np.zeros_like(f.u), rho=f.rho, lam=lam)
    assert ContactForce().value(zero_u) == pytest.approx(2.5 * 0.36, rel=1e-13)  # punch bottom 0.6 x 0.6
    # stretched in x by 10 % (deformed area): the force follows the deformed surface
    X = prob.contact.X
    stretched = Fields(system=prob, u=(0.1 * X[:, 0:1] * np.array([1.0, 0, 0])).ravel(), rho=f.rho, lam=lam)
    assert ContactForce().value(stretched) == pytest.approx(2.5 * 0.36 * 1.1, rel=1e-13)
    # gauss and nodal quadratures (the paper's readings, over the whole facets) agree for a linear zeta
    nodal = Functional(zeta=lambda v: v, quadrature="nodal")
    assert nodal.value(f) == pytest.approx(ContactForce(quadrature="gauss").value(f), rel=1e-13)


def test_contact_force_counts_only_the_overlap(prob):
    # the punch (nonmortar, 0.6 x 0.6 at x in [0.2, 0.8]) slid 0.5 along x hangs 0.3 over the block's
    # edge: the bodies touch on 0.3 x 0.6, and a uniform pressure transmits 2.5 * 0.18 there
    f = _fields(prob)
    lam = tuple(np.full_like(v, 2.5) for v in f.lam)
    u = np.zeros(prob.disc.n_dofs)
    u[prob.disc.body_slice("punch")] = np.tile([0.5, 0.0, 0.0], prob.disc.blocks[1].n_nodes)
    slid = Fields(system=prob, u=u, rho=f.rho, lam=lam)
    assert ContactForce().value(slid) == pytest.approx(2.5 * 0.18, rel=1e-12)
    assert ContactForce(quadrature="gauss").value(slid) == pytest.approx(2.5 * 0.36, rel=1e-12)  # whole facets
    areas, _ = prob.contact.overlap_areas(u)
    assert areas[0].sum() == pytest.approx(0.18, rel=1e-12)


def test_pressure_variance_known_values(prob):
    f = _fields(prob)
    block = prob.contact.blocks[0]
    uniform = Fields(system=prob, u=np.zeros_like(f.u), rho=f.rho, lam=(np.full(block.n_nodes, 3.0),))
    assert PressureVariance().value(uniform) == pytest.approx(0.0, abs=1e-12)
    # two levels on nodes of equal area share: variance = p(1-p)(a-b)^2 for area fractions p, 1-p
    from contopt.contact.pairing import nodal_areas

    areas = np.bincount(block.nm_local.ravel(), weights=nodal_areas(block_x(prob)).ravel(), minlength=block.n_nodes)
    lam = np.where(np.arange(block.n_nodes) % 2 == 0, 1.0, 4.0)
    lam[0] = 0.0  # inactive: excluded from area and moments
    act = lam > 0
    w = areas[act] / areas[act].sum()
    mean = w @ lam[act]
    var = w @ (lam[act] - mean) ** 2
    g = Fields(system=prob, u=np.zeros_like(f.u), rho=f.rho, lam=(lam,))
    assert PressureVariance().value(g) == pytest.approx(var, rel=1e-12)
    assert PressureVariance(normalized=True).value(g) == pytest.approx(var / mean**2, rel=1e-12)


def block_x(prob):
    return prob.contact.X[prob.contact.blocks[0].nm_facet_nodes]


def test_volume_fraction_and_compliance_values(prob):
    f = _fields(prob)
    disc = prob.disc
    rho = np.full(disc.n_cells, 0.4)
    g = Fields(system=prob, u=f.u, rho=rho, lam=f.lam)
    assert VolumeFraction().value(g) == pytest.approx(0.4, rel=1e-14)
    assert Compliance().value(f) == pytest.approx(disc.f_ext_unit @ f.u, rel=1e-14)
    # the body force acts on the block only
    assert Compliance(bodies="punch").value(f) == pytest.approx(0.0, abs=1e-15)


def test_bad_input_is_named(prob):
    f = _fields(prob)
    with pytest.raises(ConfigError, match="nowhere"):
        StrainEnergy(bodies="nowhere").value(f)
    with pytest.raises(ConfigError, match="interface"):
        ContactForce(interfaces=("nope",)).value(f)
    with pytest.raises(ConfigError, match="quadrature"):
        Functional(zeta=lambda v: v, quadrature="simpson")
    with pytest.raises(ConfigError, match="pi"):
        Functional()
    with pytest.raises(ConfigError, match="unknown response"):
        builtin("max-stress")


@pytest.fixture(scope="module")
def beam():
    """A contact-free system and a solved state of it."""
    from contopt.assembly.model import Body, Dirichlet, Model, Traction
    from contopt.material import neo_hookean
    from contopt.mesh.generators import box
    from contopt.solve.static import solve_static

    model = Model(
        bodies=(Body("beam", box((4.0, 1.0, 1.0), (4, 2, 2)), neo_hookean(1.0, 0.3)),),
        dirichlet=(Dirichlet("beam", "xmin"),),
        loads=(Traction("beam", "xmax", (0.0, 0.0, -0.01)),),
    )
    system = System.of(model)
    return system, solve_static(system)


@pytest.mark.parametrize(
    "response", [ContactForce(), PressureVariance(), Functional(zeta=lambda lam: lam**2)], ids=lambda r: r.name
)
def test_a_contact_response_on_a_model_without_contact_is_an_error_not_zero(beam, response):
    from contopt.adjoint import sensitivities

    system, state = beam
    with pytest.raises(
        ConfigError,
        match=rf"response '{response.name}' integrates over contact interfaces, but "
        r"the model has none",
    ):
        response.value(Fields.from_state(system, state))
    with pytest.raises(ConfigError, match="the model has none"):
        sensitivities(system, state, [StrainEnergy(), response])
    with pytest.raises(ConfigError, match="the model has none"):
        response.check(system)
    # a functional with a volume part too is evaluated (its contact part is zero)
    assert Functional(pi=lambda u, G, rho: rho, zeta=lambda lam: lam).value(Fields.from_state(system, state)) > 0


def test_float32_fields_are_converted_not_mixed_into_the_partials(beam):
    system, state = beam
    f32 = Fields(system, state.u.astype(np.float32), np.ones(system.disc.n_cells, np.float32), ())
    assert f32.u.dtype == f32.rho.dtype == f32.mass.dtype == np.float64
    for response in (StrainEnergy(), Compliance(), VolumeFraction()):
        _, p = response.evaluate(f32)
        assert p.u.dtype == p.rho.dtype == np.float64


def test_fields_of_another_system_or_of_the_wrong_kind_are_config_errors(beam, prob):
    system, state = beam
    with pytest.raises(
        ConfigError,
        match=r"Fields.u has shape \(135,\) but the system has 180 dofs: it belongs to "
        r"another model",
    ):
        Fields.from_state(_other(system), state)
    with pytest.raises(ConfigError, match=r"Fields.lam must hold one pressure array per contact interface"):
        Fields(prob, np.zeros(prob.disc.n_dofs), np.ones(prob.disc.n_cells), ())
    with pytest.raises(ConfigError, match=r"Fields.lam\[0\] has shape \(2,\)"):
        Fields(prob, np.zeros(prob.disc.n_dofs), np.ones(prob.disc.n_cells), (np.zeros(2),))
    with pytest.raises(ConfigError, match=r"Fields.system must be the System"):
        Fields(system.disc.model, state.u, np.ones(system.disc.n_cells), ())
    with pytest.raises(ConfigError, match=r"Fields.from_state needs the State .* got ndarray"):
        Fields.from_state(system, state.u)
    for response in (StrainEnergy(), Compliance(), ContactForce(), 2.0 * StrainEnergy()):
        with pytest.raises(
            ConfigError,
            match=r"is evaluated on Fields \(Fields.from_state\(system, state\)\), "
            r"got State",
        ):
            response.value(state)
    with pytest.raises(ConfigError, match="Combination parts must be a non-empty tuple of Response"):
        Combination(("compliance",), lambda v: v[0])


def _other(system):
    """A system of the same beam with another mesh (180 dofs instead of 135)."""
    from dataclasses import replace

    from contopt.assembly.model import Body
    from contopt.mesh.generators import box

    model = system.disc.model
    body = model.bodies[0]
    return System.of(replace(model, bodies=(Body(body.name, box((4.0, 1.0, 1.0), (4, 2, 3)), body.material),)))
