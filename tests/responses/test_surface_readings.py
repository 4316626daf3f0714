"""The whole-surface pressure integrals on tet10 faces (``quadrature="gauss"`` and ``"nodal"``): on the
tri6 parents' curved surface with the multipliers' field ``sum_A lam_A W_A`` (contopt.responses.surface).

Checked against a closed-form and a numerically integrated area, the lumped areas of a flat face,
central finite differences of the partials, and a solved uniform-pressure patch's support reaction.
"""

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import dblquad

from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.contact.interface import ContactInterface
from contopt.material import neo_hookean
from contopt.mesh.generators import box
from contopt.mesh.tets import tetrahedralize
from contopt.responses import ContactForce, Fields, Functional
from contopt.responses.surface import nonmortar_faces, tri6_face_integral
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import AugmentationOptions, solve_static
from contopt.solve.system import System

#: the unit reference triangle's six nodes (corners, then midpoints 01, 12, 20) in the plane z = 0
FLAT = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.5, 0, 0], [0.5, 0.5, 0], [0, 0.5, 0]], dtype=float)


def _identity(v):
    return v


def _lifted(c):
    """FLAT with its midpoints lifted by c: the surface z = 4 c (L0 L1 + L1 L2 + L2 L0) over the triangle."""
    return FLAT + np.array([0, 0, 0, c, c, c])[:, None] * [0.0, 0.0, 1.0]


def _curved_area(c):
    """The lifted face's area by adaptive quadrature of ``sqrt(1 + z_s^2 + z_t^2)`` (independent of the rule)."""

    def element(t, s):
        L0 = 1 - s - t
        zs, zt = 4 * c * (L0 - s), 4 * c * (L0 - t)  # d/ds and d/dt of the sum
        return np.sqrt(1 + zs**2 + zt**2)

    return dblquad(element, 0, 1, 0, lambda s: 1 - s, epsabs=1e-14, epsrel=1e-13)[0]


def _flat_subfacets_area(x6):
    """The area of the four flat tri3 sub-facets the mortar segmentation splits a tri6 into."""
    tris = x6[[[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]]]
    return 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1).sum()


@pytest.mark.parametrize("nodal", [False, True], ids=["gauss", "nodal"])
def test_a_curved_tri6_face_integrates_its_own_area_not_its_flat_subfacets(nodal):
    c = 0.1  # slopes up to 0.4
    x6 = _lifted(c)
    area = float(tri6_face_integral(jnp.asarray(x6), jnp.ones(6), _identity, nodal))
    exact = _curved_area(c)
    # the rule (Radon's on four sub-triangles) against adaptive quadrature: measured 5.2e-8 relative
    # (falling as c^6: 1.2e-9 at c = 0.05, 9e-6 at c = 0.3), so 10x that
    assert area == pytest.approx(exact, rel=5e-7)
    flat = _flat_subfacets_area(x6)
    assert abs(flat - exact) > 1e3 * 5e-7 * exact  # measured 0.62 %: the sub-facets read another area
    # a flat face: the closed form 1/2, and the lumped areas int W_A da: 2/15 at a corner, 1/5 at a midpoint
    assert float(tri6_face_integral(jnp.asarray(FLAT), jnp.ones(6), _identity, nodal)) == pytest.approx(0.5, rel=1e-14)


def test_the_nodal_areas_of_a_flat_tri6_are_the_shares_of_its_multipliers():
    import jax

    lumped = jax.grad(tri6_face_integral, argnums=1)(jnp.asarray(FLAT), jnp.ones(6), _identity, True)
    np.testing.assert_allclose(np.asarray(lumped), 0.5 * np.array([2, 2, 2, 3, 3, 3]) / 15, rtol=1e-14)


# ------------------------------------------------------------------ a tet10 interface
P = 1e-3  # small strain: pressure / E
TIGHT = NewtonOptions(rtol=1e-12, utol=1e-10)
ALM = AugmentationOptions(pressure_rtol=1e-10, gap_rtol=1e-10)


def _patch_model():
    """A tet10 block (2 x 2 x 1 cells, its bottom tri6 faces nonmortar) under a uniform dead load on a
    3 x 3 x 1 hex8 block, both on rollers: a uniform contact pressure (tests/contact/test_triangle_contact.py)."""
    upper = tetrahedralize(box((1.0, 1.0, 0.5), (2, 2, 1), origin=(0.0, 0.0, 1.0)), 2)
    lower = box((1.0, 1.0, 1.0), (3, 3, 1))
    mat = neo_hookean(1.0, 0.3)
    rollers = [Dirichlet(b, s, d) for b in ("top", "bottom") for s, d in (("xmin", "x"), ("ymin", "y"))]
    return Model(
        bodies=(Body("top", upper, mat), Body("bottom", lower, mat)),
        dirichlet=(*rollers, Dirichlet("bottom", "zmin", "z")),
        loads=(Traction("top", "zmax", (0.0, 0.0, -P)),),
        interfaces=(ContactInterface(nonmortar=("top", "zmin"), mortar=("bottom", "zmax")),),
    )


@pytest.fixture(scope="module")
def system():
    s = System.of(_patch_model())
    assert s.contact.blocks[0].parents.kinds[0] == "tri6"
    return s


def _random_fields(system, seed=0, scale=0.02):
    """Random displacements (the nonmortar faces curved) and pressures, 70 % of the nodes active."""
    rng = np.random.default_rng(seed)
    u = scale * rng.standard_normal(system.disc.n_dofs)
    lam = tuple(
        np.where(rng.uniform(size=b.n_nodes) < 0.7, rng.uniform(0.1, 2.0, b.n_nodes), 0.0)
        for b in system.contact.blocks
    )
    return Fields(system=system, u=u, rho=np.ones(system.disc.n_cells), lam=lam, t=1.0)


RESPONSES = [
    ContactForce(quadrature="gauss"),
    ContactForce(quadrature="nodal"),
    Functional(zeta=lambda v: v**3, quadrature="gauss", name="cube-gauss"),
    Functional(zeta=lambda v: jnp.sin(v), quadrature="nodal", name="sin-nodal"),
]


@pytest.mark.parametrize("response", RESPONSES, ids=lambda r: f"{r.name}-{r.quadrature}")
def test_partials_on_tri6_parents_match_central_differences(system, response):
    f = _random_fields(system)
    value, p = response.evaluate(f)
    assert value == pytest.approx(response.value(f), rel=1e-14)
    rng = np.random.default_rng(7)
    du = rng.standard_normal(f.u.size)
    dlam = tuple((lam > 0) * rng.standard_normal(lam.size) for lam in f.lam)
    h = 1e-6

    def at(s):
        lam = tuple(v + s * d for v, d in zip(f.lam, dlam))
        return response.value(Fields(system=system, u=f.u + s * du, rho=f.rho, lam=lam, t=1.0))

    fd = (at(h) - at(-h)) / (2 * h)
    exact = p.u @ du + sum(a @ b for a, b in zip(p.lam, dlam))
    assert np.linalg.norm(p.u) > 0 and exact != 0  # the geometry's derivative is in the check
    # central differences' truncation O(h^2) and rounding O(eps |value| / h): ~1e-9 relative
    assert exact == pytest.approx(fd, rel=1e-7, abs=1e-10 * max(1.0, abs(value)))


def test_the_gauss_and_nodal_readings_are_one_integral_for_a_linear_zeta(system):
    """``sum_A lam_A int W_A da = int (sum_A lam_A W_A) da``: the two agree to rounding on curved faces."""
    f = _random_fields(system, seed=3)
    gauss = ContactForce(quadrature="gauss").value(f)
    assert ContactForce(quadrature="nodal").value(f) == pytest.approx(gauss, rel=1e-13)
    # and both read the parents, not the flat sub-facets: with every lam_A = 1, the curved faces' area
    ones = Fields(system=system, u=f.u, rho=f.rho, lam=tuple(np.ones_like(v) for v in f.lam), t=1.0)
    nodes, _ = nonmortar_faces(system.contact.blocks[0])
    x = system.contact.X + f.u.reshape(-1, 3)
    flat = sum(_flat_subfacets_area(x6) for x6 in x[nodes])
    assert abs(ContactForce(quadrature="gauss").value(ones) - flat) > 1e-4 * flat


@pytest.mark.slow  # 57 s beside a benchmark on the shared 2-core machine (mostly compiling)
def test_all_three_quadratures_read_the_support_reaction_of_a_uniform_pressure(system):
    state = solve_static(system, newton=TIGHT, augmentation=ALM)
    fields = Fields.from_state(system, state)
    lower = system.disc.body_slice("bottom")
    reaction = abs(state.reactions[lower].reshape(-1, 3)[:, 2].sum())  # the support pushes up
    assert reaction == pytest.approx(P, rel=1e-6)  # the dead load, all of it through the contact
    # the solver's stopping criteria as a relative bound (tests/contact/test_triangle_contact.py)
    tol = 10.0 * max(state.logs[-1].extra["pressure_change"], ALM.pressure_rtol) + 1e3 * TIGHT.rtol
    assert tol < 1e-6  # the check is not vacuous
    for quadrature in ("overlap", "gauss", "nodal"):
        assert ContactForce(quadrature=quadrature).value(fields) == pytest.approx(reaction, rel=tol), quadrature
