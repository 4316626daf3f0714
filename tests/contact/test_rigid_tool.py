"""Rigid tools in contact (Body(rigid=RigidMotion(...)), contopt.mesh.tool): a rigid plane presses a
block as a prescribed displacement of its top does, also while it turns; the force on the tool is the
contact-force response; Hertz against a rigid cylinder (plane strain) and a rigid sphere; a block
slides on a rigid floor at mu times the normal force as on the stiff deformable base; and the
die-slab's slab stores the energy with a rigid die that it stores with the stiff (E ratio 1000)
deformable one."""

import numpy as np
import pytest
from _hertz import E_RIGID, hertz_errors, pressure_moments, rigid_hertz_model  # tests/contact/_hertz.py
from _meshing import graded  # tests/contact/_meshing.py

from contopt.assembly.model import Body, Dirichlet, LoadPath, Model, RigidMotion
from contopt.cases.die_slab import die_slab
from contopt.cases.sliding_block import sliding_block
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import AugmentedLagrangian
from contopt.material import neo_hookean
from contopt.mesh.generators import box
from contopt.mesh.tool import cylinder_surface, plane_surface, sphere_surface, tool_layer
from contopt.responses.base import Fields
from contopt.responses.functionals import ContactForce
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import AugmentationOptions, solve_static
from contopt.solve.system import System

TIGHT = NewtonOptions(rtol=1e-11, utol=1e-11, n_steps=2)
ALM = AugmentationOptions(pressure_rtol=1e-10, gap_rtol=1e-10)
DOWN = 0.05


def _block():
    """A block on symmetry planes (x = 0, y = 0, z = 0): pressed on top it compresses uniaxially."""
    body = Body("block", box((1.0, 1.0, 0.5), (2, 2, 2)), neo_hookean(1.0, 0.3))
    return body, (Dirichlet("block", "xmin", "x"), Dirichlet("block", "ymin", "y"), Dirichlet("block", "zmin", "z"))


@pytest.fixture(scope="module")
def displaced():
    """The block with its top moved down by DOWN (x, y free): the uniaxial answer."""
    body, held = _block()
    model = Model(bodies=(body,), dirichlet=(*held, Dirichlet("block", "zmax", "z", -DOWN)))
    state = solve_static(model, newton=TIGHT)
    return model, state, state.reactions.reshape(-1, 3)[body.mesh.node_set("zmax")].sum(axis=0)


@pytest.mark.parametrize("spin", [0.0, np.pi / 6])
def test_a_rigid_plane_presses_a_block_as_a_displaced_top_does(displaced, spin):
    """The plane (3 x 3 facets over the block's 2 x 2, edges off the block's) moves down by DOWN and,
    frictionless, may spin about its normal without changing the answer; the block's displacements,
    the reaction on the tool's nodes and the contact-force response are those of the displaced top
    to the ALM tolerance."""
    _, reference, F = displaced
    body, held = _block()
    plate = tool_layer(plane_surface([0.5, 0.5, 0.5], [0.0, 0.0, -1.0], 1.6, (3, 3)))
    motion = RigidMotion(translation=(0.0, 0.0, -DOWN), axis=(0.0, 0.0, 1.0), point=(0.5, 0.5, 0.5), angle=spin)
    model = Model(
        bodies=(body, Body("plate", plate, rigid=motion)),
        dirichlet=held,
        interfaces=(ContactInterface(surfaces=(("plate", "surface"), ("block", "zmax"))),),
    )
    assert model.interfaces[0].nonmortar == ("block", "zmax")
    system = System.of(model)
    state = solve_static(system, newton=TIGHT, augmentation=ALM)
    n = body.mesh.n_nodes
    np.testing.assert_allclose(state.u[: 3 * n], reference.u, rtol=0, atol=1e-9 * DOWN)
    on_tool = state.reactions.reshape(-1, 3)[n:].sum(axis=0)  # what holds the tool on its path
    np.testing.assert_allclose(on_tool, F, rtol=0, atol=1e-9 * abs(F[2]))
    fields = Fields.from_state(system, state)
    assert ContactForce(direction=[0.0, 0.0, 1.0]).value(fields) == pytest.approx(abs(F[2]), rel=1e-9)
    assert ContactForce(direction="norm").value(fields) == pytest.approx(abs(F[2]), rel=1e-9)


def test_hertz_line_contact_against_a_rigid_cylinder():
    """tests/contact/test_hertz.py's fast case (a/R = 0.1) with the cylinder a rigid tool: the same
    agreement with plane-strain Hertz (E* the block's E' alone), within 3 %."""
    h = 0.0075
    model, h_cyl = rigid_hertz_model(h, AugmentedLagrangian(eps=10.0 * E_RIGID / h))
    system = System.of(model)
    state = solve_static(
        system,
        newton=NewtonOptions(n_steps=4, rtol=1e-10),
        augmentation=AugmentationOptions(pressure_rtol=1e-8, gap_rtol=1e-8),
    )
    err = hertz_errors(system, model, state, h, h_cyl, e_star=E_RIGID, driven="all")
    print(" ".join(f"{k}={v:.4g}" for k, v in err.items()))
    assert abs(err["a_over_R"] / 0.1 - 1) < 0.1 and err["facets_across"] >= 10 and err["h_cyl_over_h"] <= 1.0
    assert abs(err["reaction"]) < 5e-3  # the force on the tool's nodes is the pressure resultant
    for k in ("peak", "a_fit", "p0_fit", "a_mom"):
        assert abs(err[k]) < 0.03, k
    assert err["rms"] < 0.05


def _top_force(model, state):
    """(3,) the force the top face exerts on the block."""
    return state.reactions.reshape(-1, 3)[model.body("block").mesh.node_set("zmax")].sum(axis=0)


def test_a_block_slides_on_a_rigid_floor_at_mu_times_the_normal_force():
    """tests/contact/test_friction.py's block, pressed and dragged along x, on a rigid plane with the
    deformable base's top facets: every node slides, friction / normal force = mu, and the top face's
    force is the stiff base's (E = 1000 against the block's 1: 1e-3 apart)."""
    newton = NewtonOptions(rtol=1e-11, utol=1e-11, n_steps=4)
    deformable = sliding_block(mu=0.3, pull=0.1)
    floor = tool_layer(plane_surface([1.0, 0.5, 0.3], [0.0, 0.0, 1.0], (2.0, 1.0), (12, 4)))
    iface = deformable.interfaces[0]
    rigid = Model(
        bodies=(deformable.body("block"), Body("base", floor, rigid=RigidMotion())),
        dirichlet=tuple(bc for bc in deformable.dirichlet if bc.body == "block"),
        interfaces=(ContactInterface(("block", "zmin"), ("base", "surface"), law=iface.law, friction=iface.friction),),
    )
    state = solve_static(rigid, newton=newton)
    res = state.contact[0]
    active = res.lam > 0
    assert active.sum() == 25 and not res.friction.stick[active].any()
    tangential, normal = (res.traction * res.a[:, None]).sum(axis=0), float(res.lam @ res.a)
    assert np.linalg.norm(tangential) / normal == pytest.approx(0.3, rel=1e-6)
    F = _top_force(rigid, state)
    n = rigid.body("block").mesh.n_nodes
    np.testing.assert_allclose(state.reactions.reshape(-1, 3)[n:].sum(axis=0), -F, rtol=0, atol=1e-9 * abs(F[2]))
    F_deformable = _top_force(deformable, solve_static(deformable, newton=newton))
    np.testing.assert_allclose(F, F_deformable, rtol=0, atol=2e-3 * abs(F[2]))


@pytest.mark.slow
def test_the_die_slab_with_a_rigid_die_stores_the_energy_of_the_stiff_deformable_die():
    """The paper's die-slab (coarse mesh, ALM) with the die (E = 1000, 1000 times the slab's) replaced
    by a rigid cylinder arc with the nodes of its outer surface, moved down by the same 0.6: the slab's
    strain energy within 1 % (the die's own compliance is the difference)."""
    deformable = die_slab()
    die = cylinder_surface(3.0, 4.6, (4.5, 2.0, 6.4045), "y", (12, 8), arc=np.deg2rad(100.0), normal=(0, 0, -1.0))
    rigid = Model(
        bodies=(deformable.body("slab"), Body("die", tool_layer(die), rigid=RigidMotion(translation=(0, 0, -0.6)))),
        dirichlet=tuple(bc for bc in deformable.dirichlet if bc.body == "slab"),
        interfaces=(ContactInterface(("slab", "zmax"), ("die", "surface"), law=deformable.interfaces[0].law),),
    )
    energies = []
    for model in (deformable, rigid):
        system = System.of(model)
        per_cell = system.disc.strain_energy(solve_static(system).u, per_cell=True)
        energies.append(float(per_cell[system.disc.cell_slice("slab")].sum()))
    print(f"slab energy: deformable die {energies[0]:.6g}, rigid die {energies[1]:.6g}")
    assert energies[1] == pytest.approx(energies[0], rel=0.01)


@pytest.mark.slow
def test_hertz_against_a_rigid_sphere():
    """A rigid sphere (R = 1, an equiangular cap) pressed d = 0.01 (a/R = 0.1) into a quarter block (E = 1,
    nu = 0.3, symmetry planes x = 0 and y = 0, clamped 25 a deep; cells of a/5 up to 1.5 a, graded 1.4x
    beyond): the force within 7 % of Hertz's ``4/3 E* sqrt(R) d^(3/2)`` (the finite block and finite
    strain stiffen it), the half-width from the pressure's second moment (``int r^2 p / int p = 2 a^2 / 5``)
    within 3 % and the peak pressure within 6 % (a nodal value, 5 facets across a) of Hertz's for the
    force the contact carries; that force is the reaction on the tool's nodes to the normals' tilt."""
    h, d, E_star = 0.02, 0.01, 1.0 / (1 - 0.3**2)
    xs = graded(h, 0.15, 2.5, 1.4)
    block = Body("block", box(grading=(xs, xs, -xs[::-1])), neo_hookean(1.0, 0.3))
    cap = sphere_surface(1.0, (0.0, 0.0, 1.0), 34, normal=(0.0, 0.0, -1.0), angle=0.3)  # facets 0.018 < h
    path = LoadPath(tuple((t, 0.0, 0.0, -d * t**2) for t in (0.25, 0.5, 0.75, 1.0)))  # touching first
    model = Model(
        bodies=(block, Body("ball", tool_layer(cap), rigid=RigidMotion(translation=path))),
        dirichlet=(Dirichlet("block", "zmin", "xyz"), Dirichlet("block", "xmin", "x"), Dirichlet("block", "ymin", "y")),
        interfaces=(
            ContactInterface(
                surfaces=(("ball", "surface"), ("block", "zmax")), law=AugmentedLagrangian(eps=10 * E_star / h)
            ),
        ),
    )
    system = System.of(model)
    state = solve_static(
        system,
        newton=NewtonOptions(n_steps=4, rtol=1e-10),
        augmentation=AugmentationOptions(pressure_rtol=1e-8, gap_rtol=1e-8),
    )
    lam = state.contact[0].lam
    force = 4 * float(system.contact.total_force(state.u, (lam,))[0])  # the whole sphere's
    on_tool = -4 * state.reactions.reshape(-1, 3)[block.mesh.n_nodes :, 2].sum()
    contact = system.contact.blocks[0]
    x = system.contact.X + state.u.reshape(-1, 3)
    m0, m2 = pressure_moments(x[contact.nm_facet_nodes], lam[contact.nm_local], axes=(0, 1))
    a = (3 * force / (4 * E_star)) ** (1 / 3)
    p0 = 3 * force / (2 * np.pi * a**2)
    print(f"force {force:.5g} (Hertz {4 / 3 * E_star * d**1.5:.5g}), a {np.sqrt(2.5 * m2 / m0):.5g} ({a:.5g})")
    assert on_tool == pytest.approx(force, rel=5e-3)
    assert force == pytest.approx(4 / 3 * E_star * d**1.5, rel=0.07)
    assert np.sqrt(2.5 * m2 / m0) == pytest.approx(a, rel=0.03)
    assert lam.max() == pytest.approx(p0, rel=0.06)


@pytest.mark.slow
def test_hertz_against_a_rigid_sphere_on_a_tet10_block():
    """The rigid sphere on the quarter block in tet10 (benchmarks/hertz_sphere.py at h = 0.03, half-width
    1.0: 3.3 cells across a, 54k dofs, 4 min): its tri6 top faces carry the Hertz pressure of the
    force they transmit, p0 and a of the elliptic fit within 3 % (measured -1.5 % and +1.4 %), a from
    the second moment on the tri6 parents within 3 % (-1.50 %; -1.3 % on the flat sub-facets before
    issue 39's parent readings); the nodal peak, 9 % high at this resolution, within 12 %
    (hex8 on the same grid: +5.5 %, docs/performance.md, "Hertz sphere")."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from hertz_sphere import run

    row = run("tet10", 0.03, 1.0)
    assert abs(row["error_p0_fit"]) < 0.03 and abs(row["error_a_fit"]) < 0.03
    assert abs(row["error_a"]) < 0.03
    assert abs(row["error_p0"]) < 0.12


@pytest.mark.slow
def test_a_tet10_block_reads_hertz_within_one_percent_where_hertz_holds():
    """The rigid sphere on a tet10 block where Hertz is a fairer reference (docs/performance.md,
    "Hertz sphere"): a/R = 0.025 (d = R / 1600), where the finite strain moves the converged p0 by
    about +0.8 % and a by -0.4 % (32 (a/R) % and -14.5 (a/R) %, measured on hex8 at a/R = 0.1, 0.05
    and 0.025), a block 15 a wide and deep, cells of a/5 up to 1.5 a (graded 1.6x beyond; 80k dofs,
    17 min on the loaded 2-core machine). p0 (the elliptic fit) and a (the pressure's second moment on
    the tri6 parents) within 1 % of Hertz's for the force carried: measured +0.57 % and -0.37 %, the
    finer hex8 grids on the same block -0.54 % in a and +0.8..2.2 % in p0 (the block's own answer is
    known to about 1 % in p0). The fitted p0 scatters by 1-2 % with the set-up at this resolution:
    at a/R = 0.0125 (68-facet cap) it read -1.13 %, the nodal peak +0.36 %."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from hertz_sphere import run

    a = 0.025
    row = run("tet10", a / 5, 15 * a, d=a**2, ratio=1.6)
    print({k: round(v, 5) for k, v in row.items() if k.startswith("error_")})
    assert abs(row["error_p0_fit"]) < 0.01
    assert abs(row["error_a"]) < 0.01
