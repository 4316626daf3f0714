"""The validation benchmarks' models (docs/validation.md), shared by tests/validation/ and benchmarks/validation.py.

Each builder reads its numbers from the benchmark's public source, named in its docstring and in
docs/validation.md; the lengths, moduli and loads are the source's, in its units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from contopt.assembly.model import Body, Dirichlet, LoadPath, Model, RigidMotion
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import AugmentedLagrangian
from contopt.errors import ConfigError
from contopt.material import neo_hookean
from contopt.mesh.generators import box
from contopt.mesh.tool import plane_surface, tool_layer

# --- (a) MOOSE modules/contact/test/tests/hertz_spherical/hertz_contact.i ----------------------
#: the input file's header: R1 = R2 = 2, E1 = E2 = 1.40625e7, nu1 = nu2 = 0.25
HERTZ_RADIUS, HERTZ_E, HERTZ_NU = 2.0, 1.40625e7, 0.25
#: the header's effective radius 1/R = 1/R1 + 1/R2 and modulus 1/E = (1 - nu1^2)/E1 + (1 - nu2^2)/E2
HERTZ_R_EFF = 1.0 / (2.0 / HERTZ_RADIUS)
HERTZ_E_EFF = 1.0 / (2.0 * (1 - HERTZ_NU**2) / HERTZ_E)
#: the header's load F = 10000, contact radius a = 0.1 and approach d = 0.01 of the two spheres
HERTZ_F, HERTZ_A, HERTZ_D = 1.0e4, 0.1, 0.01


def hertz_closed_form(force: float) -> tuple[float, float]:
    """The header's closed form ``(a, d)`` for the compressive load ``force``: ``a^3 = 3 F R / (4 E)``,
    ``d = a^2 / R`` (R, E the effective radius and modulus)."""
    a = (3.0 * force * HERTZ_R_EFF / (4.0 * HERTZ_E_EFF)) ** (1.0 / 3.0)
    return float(a), float(a * a / HERTZ_R_EFF)


def hertz_force(approach: float) -> float:
    """The closed form's load for the two spheres' approach ``d``: ``F = 4/3 E sqrt(R) d^(3/2)``."""
    return float(4.0 / 3.0 * HERTZ_E_EFF * np.sqrt(HERTZ_R_EFF) * approach**1.5)


def _coords(h: float, fine: float, ratio: float, from_top: bool = False) -> np.ndarray:
    """(n+1,) node coordinates on [0, 1]: uniform ``h`` up to ``fine`` from 0 (or from 1, ``from_top``),
    each further cell ``ratio`` x longer, no end cell under half its neighbour."""
    x = list(np.arange(0.0, fine + 1e-9 * h, h))
    dx = h
    while x[-1] < 1.0 - 1e-12:
        dx *= ratio
        x.append(min(x[-1] + dx, 1.0))
    if len(x) > 2 and x[-1] - x[-2] < 0.5 * (x[-2] - x[-3]):
        x.pop(-2)
    s = np.array(x)
    return 1.0 - s[::-1] if from_top else s


def _shell(points: np.ndarray, axis: int, core: float) -> np.ndarray:
    """Map a shell block's parameters to the ball: ``points`` (n, 3) hold (u, v) on the core cube's face
    ``axis`` and the radial parameter s in column ``axis``; ``(1 - s) core f + s f / |f|`` with f the
    face point (u, v, 1) (the 1 in column ``axis``)."""
    f = points.copy()
    s = f[:, axis].copy()
    f[:, axis] = 1.0
    return (1 - s)[:, None] * core * f + s[:, None] * f / np.linalg.norm(f, axis=1)[:, None]


def hemisphere_octant(radius: float, h: float, fine: float = 0.1, ratio: float = 1.4, core: float = 0.5):
    """The quarter of a hemisphere that MOOSE's hertz_contact.i meshes (x >= 0, y >= 0 by symmetry), pole
    at the origin, equator in the plane z = ``radius``: an O-grid of the ball's octant, a core cube of
    half-size ``core radius`` and three shell blocks from its outer faces to the sphere.

    Cells of about ``h radius`` within about ``fine radius`` of the pole (along the sphere and in depth),
    graded by ``ratio`` beyond. Facet and node sets: ``cap`` (the sphere within about 55 degrees of the
    pole: the contact surface), ``equator`` (where the load acts), ``xmin`` and ``ymin`` (the symmetry
    planes). Returns a hex8 Mesh.
    """
    from contopt.mesh.core import HEX_FACES, Mesh, boundary_facets, cell_jacobian_dets
    from contopt.mesh.generators import merge_nodes

    g = _coords(h, fine, ratio)  # along the sphere from the pole: u, v
    s = _coords(h / (1 - core), fine / (1 - core), ratio, from_top=True)  # radial, fine at the sphere
    w = np.linspace(0.0, 1.0, 7)  # the core's height, away from the contact: coarse
    blocks = [
        (core * np.asarray(box(grading=(g, g, w)).points), box(grading=(g, g, w)).cells),
        (_shell(np.asarray(box(grading=(g, g, s)).points), 2, core), box(grading=(g, g, s)).cells),
        (_shell(np.asarray(box(grading=(s, g, w)).points), 0, core), box(grading=(s, g, w)).cells),
        (_shell(np.asarray(box(grading=(g, s, w)).points), 1, core), box(grading=(g, s, w)).cells),
    ]
    points, cells, offset = [], [], 0
    for p, c in blocks:
        points.append(p)
        cells.append(np.asarray(c) + offset)
        offset += len(p)
    x, c, _ = merge_nodes(np.concatenate(points), np.concatenate(cells), 1e-9)
    x = radius * x
    x[:, 2] = radius - x[:, 2]  # the pole at the origin, the ball above it
    c = np.where((cell_jacobian_dets(x, c).min(axis=1) < 0)[:, None], c[:, [4, 5, 6, 7, 0, 1, 2, 3]], c)
    keep = np.unique(c)
    renumber = np.full(len(x), -1)
    renumber[keep] = np.arange(len(keep))
    x, c = x[keep], renumber[c]
    facets = boundary_facets(c)
    centre = x[c[facets[:, 0][:, None], HEX_FACES[facets[:, 1]]]].mean(axis=1)
    tol = 1e-9 * radius
    on = {
        "xmin": np.abs(centre[:, 0]) < tol,
        "ymin": np.abs(centre[:, 1]) < tol,
        "equator": np.abs(centre[:, 2] - radius) < tol,
    }
    sphere = ~(on["xmin"] | on["ymin"] | on["equator"])
    on["cap"] = sphere & (centre[:, 2] < (1 - np.cos(np.deg2rad(55.0))) * radius)
    facet_sets = {k: facets[v] for k, v in on.items()}
    node_sets = {k: np.unique(c[f[:, 0][:, None], HEX_FACES[f[:, 1]]]) for k, f in facet_sets.items()}
    return Mesh(x, c, node_sets | {"all": np.arange(len(x))}, facet_sets)


def hertz_sphere_model(h: float, approach: float = HERTZ_D, steps: int = 4, ratio: float = 1.4) -> Model:
    """MOOSE's hertz_contact.i: one quarter hemisphere (R = 2, E = 1.40625e7, nu = 0.25; the mesh of
    :func:`hemisphere_octant` with cells of ``h R`` near the pole, graded by ``ratio``) on a rigid
    frictionless plane (MOOSE: block 1000 clamped on its contact face), symmetry planes x = 0 and
    y = 0, the equator moved down.

    Two equal spheres pressed together touch on their plane of symmetry, which stays flat and carries
    no shear: each sphere is one sphere on a rigid frictionless plane, pressed by half their ``approach``
    (the equator moves ``approach / 2`` along the quadratic path ``t^2``, touching first).
    Contact: the augmented Lagrangian with ``10 E'/h`` (E' the sphere's ``E / (1 - nu^2)``).
    """
    e_plane = HERTZ_E / (1 - HERTZ_NU**2)
    size = h * HERTZ_RADIUS
    sphere = hemisphere_octant(HERTZ_RADIUS, h, ratio=ratio)
    half = 0.5 * approach
    path = LoadPath(tuple((t, -half * t * t) for t in np.linspace(0.0, 1.0, steps + 1)[1:]))
    extent = 0.6 * HERTZ_RADIUS  # the plane reaches beyond the cap around the pole
    n = int(np.ceil(extent / (2 * size)))
    plane = tool_layer(plane_surface([extent / 2, extent / 2, 0.0], [0.0, 0.0, 1.0], extent, (n, n)))
    return Model(
        bodies=(
            Body("sphere", sphere, neo_hookean(HERTZ_E, HERTZ_NU)),
            Body("plane", plane, rigid=RigidMotion()),
        ),
        dirichlet=(
            Dirichlet("sphere", "xmin", "x"),
            Dirichlet("sphere", "ymin", "y"),
            Dirichlet("sphere", "equator", "z", path),
        ),
        interfaces=(
            ContactInterface(
                nonmortar=("sphere", "cap"),
                mortar=("plane", "surface"),
                law=AugmentedLagrangian(eps=10.0 * e_plane / size),
            ),
        ),
    )


def hertz_sphere_results(system, state, approach: float = HERTZ_D) -> dict:
    """The solved :func:`hertz_sphere_model` against the header's closed form.

    ``force``: the whole contact's load (4 times the quarter's pressure resultant); ``a``: the contact
    radius from the pressure's second moment (``int r^2 p / int p = 2 a^2 / 5`` for Hertz's
    ``p0 sqrt(1 - r^2/a^2)``: an integral measure, not where the edge falls in a facet); ``a_edge``:
    the outermost node that carries pressure; ``a_closed`` and ``d_closed``: the closed form for
    ``force``; ``force_closed``: the closed form's load for ``approach`` (the approach of the two
    equators, which includes the hemispheres' own compression: Hertz's is that of distant points);
    ``p0`` and ``p0_closed``: the peak nodal pressure and Hertz's ``3 F / (2 pi a^2)``.
    """
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "contact"))
    from _hertz import pressure_moments  # tests/contact/_hertz.py

    lam = np.asarray(state.contact[0].lam)
    block = system.contact.blocks[0]
    x = system.contact.X + state.u.reshape(-1, 3)
    force = 4.0 * float(system.contact.total_force(state.u, (lam,))[0])
    m0, m2 = pressure_moments(x[block.nm_facet_nodes], lam[block.nm_local], axes=(0, 1))
    r = np.linalg.norm(x[block.nodes, :2], axis=1)
    a_closed, d_closed = hertz_closed_form(force)
    return {
        "force": force,
        "force_closed": hertz_force(approach),
        "a": float(np.sqrt(2.5 * m2 / m0)),
        "a_edge": float(r[lam > 0].max()),
        "a_closed": a_closed,
        "d_closed": d_closed,
        "p0": float(lam.max()),
        "p0_closed": float(3 * force / (2 * np.pi * a_closed**2)),
        "approach": approach,
    }


# --- (d) Zimmerman & Ateshian (2018) §3.5, the stacked blocks ---------------------------------
#: per block from the top: (E, nu, cells per side); the paper's moduli (MPa) and Poisson ratios, as
#: LLNL Smith's stacked-blocks example reproduces them (docs/validation.md (d)); no interface with matching nodes
STACK_BLOCKS = ((10.0, 0.1, 4), (0.3, 0.4, 7), (10.0, 0.1, 4), (0.3, 0.4, 7))
#: per interface from the top: the friction coefficient
STACK_MU = (0.05, 0.05, 1.0)
#: block edge (mm) and the top's downward travel (mm: half the stack's 8 mm)
STACK_SIZE, STACK_PRESS = 2.0, 2.0


def stacked_blocks_model(press: float = STACK_PRESS, cells: tuple | None = None) -> Model:
    """Four 2 mm cubes stacked (blocks 1-4 from the top, 1 and 3 stiff, 2 and 4 soft), the bottom of
    block 4 clamped, the top of block 1 moved down by ``press`` (x and y held), Coulomb friction of
    :data:`STACK_MU` between neighbours; ``cells`` overrides the cells per side of each block.
    Nonmortar: the soft (finer) block's face at each interface. The augmented Lagrangian normal law
    and friction's default penalty (contact.md)."""
    from contopt.contact.coulomb import Coulomb

    cells = cells or tuple(n for _, _, n in STACK_BLOCKS)
    bodies = []
    for k, ((e, nu, _), n) in enumerate(zip(STACK_BLOCKS, cells)):
        z0 = (3 - k) * STACK_SIZE
        mesh = box((STACK_SIZE,) * 3, (n, n, n), origin=(0.0, 0.0, z0))
        bodies.append(Body(f"block{k + 1}", mesh, neo_hookean(e, nu)))
    pairs = (
        (("block2", "zmax"), ("block1", "zmin")),
        (("block2", "zmin"), ("block3", "zmax")),
        (("block4", "zmax"), ("block3", "zmin")),
    )
    interfaces = tuple(
        ContactInterface(nonmortar=nm, mortar=m, law=AugmentedLagrangian(), friction=Coulomb(mu))
        for (nm, m), mu in zip(pairs, STACK_MU)
    )
    return Model(
        bodies=tuple(bodies),
        dirichlet=(
            Dirichlet("block4", "zmin", "xyz"),
            Dirichlet("block1", "zmax", "xyz", (0.0, 0.0, -press)),
        ),
        interfaces=interfaces,
    )


# --- (c) Kratos Examples contact_structural_mechanics/validation/double_arch ------------------
#: the half-ring's centre (m), its radii (inner layer 0.085-0.09, outer 0.09-0.095: double_arch_hexa.mdpa)
ARCH_CENTRE, ARCH_RADII = (0.125, 0.145), (0.085, 0.09, 0.095)
#: Young's moduli (Pa) from StructuralMaterials.json: the base (Parts_Auto1), the outer layer (Parts_Auto2)
#: and the inner layer (Parts_Auto3); nu = 0.3 for all
ARCH_E_BASE, ARCH_E_OUTER, ARCH_E_INNER, ARCH_NU = 3.0e8, 1.0e9, 1.0e11, 0.3
#: the base (m): 0.25 long, 0.05 high; the depth 0.05; the ends' travel at the reference's last point
ARCH_BASE, ARCH_DEPTH, ARCH_TRAVEL = (0.25, 0.05), 0.05, 0.07


def double_arch_model(
    n_theta: int = 48,
    n_layer: int = 2,
    h_base: float = 0.0025,
    mu: float = 0.0,
    travel: float = ARCH_TRAVEL,
    e_base: float = ARCH_E_BASE,
):
    """``(model, rho)``: Kratos' double arch in plane strain (every node's z held, as Kratos holds the
    ring's), the half x >= 0.125 with the symmetry plane x = 0.125 held in x: the lower half-ring (two
    layers, ``n_layer`` cells across each, ``n_theta`` around the quarter) on the base (cells of
    ``h_base``, its bottom clamped, Young's modulus ``e_base``: Kratos' 3e8 unless a study changes it),
    both ring ends moved down by ``travel`` (x held); frictionless or Coulomb ``mu``. ``rho``
    (n_cells,): the ring is one body of the inner layer's material and its outer layer's cells carry
    the stiffness factor E_outer / E_inner."""
    from contopt.contact.coulomb import Coulomb
    from contopt.mesh.generators import annulus

    cx, cy = ARCH_CENTRE
    r0, r1, r2 = ARCH_RADII
    ring = annulus(
        r0, r2, ARCH_DEPTH, (n_theta, 2 * n_layer, 1), theta=(1.5 * np.pi, 2 * np.pi), center=(cx, cy, ARCH_DEPTH / 2)
    )
    nx, ny = int(round((ARCH_BASE[0] / 2) / h_base)), int(round(ARCH_BASE[1] / h_base))
    base = box((ARCH_BASE[0] / 2, ARCH_BASE[1], ARCH_DEPTH), (nx, ny, 1), origin=(cx, 0.0, 0.0))
    centre = np.asarray(ring.points)[np.asarray(ring.cells)].mean(axis=1)
    outer = np.hypot(centre[:, 0] - cx, centre[:, 1] - cy) > r1
    rho = np.concatenate([np.where(outer, ARCH_E_OUTER / ARCH_E_INNER, 1.0), np.ones(base.n_cells)])
    friction = {} if mu == 0 else {"friction": Coulomb(mu)}
    model = Model(
        bodies=(
            Body("ring", ring, neo_hookean(ARCH_E_INNER, ARCH_NU)),
            Body("base", base, neo_hookean(e_base, ARCH_NU)),
        ),
        dirichlet=(
            Dirichlet("ring", "all", "z"),
            Dirichlet("base", "all", "z"),
            Dirichlet("base", "ymin", "xy"),
            Dirichlet("base", "xmin", "x"),
            Dirichlet("ring", "theta_start", "x"),
            Dirichlet("ring", "theta_end", "xy", (0.0, -travel)),
        ),
        interfaces=(ContactInterface(surfaces=(("ring", "outer"), ("base", "ymax")), **friction),),
    )
    return model, rho


def arch_centre_node(model) -> int:
    """The ring's node at the bottom of its outer surface (the reference's "displacement centre")."""
    mesh = model.body("ring").mesh
    nodes = mesh.node_set("outer")
    p = np.asarray(mesh.points)[nodes]
    return int(nodes[np.argmin(np.abs(p[:, 0] - ARCH_CENTRE[0]) + p[:, 2])])


def arch_ring_model(n_theta: int = 48, n_layer: int = 2, travel: float = 1e-5):
    """``(model, rho)``: the double arch's quarter ring alone (plane strain) with its bottom section
    clamped (held in x and y: a rigid base) and its end moved down by ``travel`` (x held)."""
    from contopt.assembly.model import Dirichlet, Model

    model, rho = double_arch_model(n_theta=n_theta, n_layer=n_layer, travel=travel)
    ring = model.body("ring")
    dirichlet = (
        Dirichlet("ring", "all", "z"),
        Dirichlet("ring", "theta_start", "xy"),
        Dirichlet("ring", "theta_end", "xy", (0.0, -travel)),
    )
    return Model(bodies=(ring,), dirichlet=dirichlet), rho[: ring.mesh.n_cells]


def arch_ring_beam_stiffness(shear: bool = True) -> float:
    """The quarter ring's end stiffness (N/m per metre of depth) of :func:`arch_ring_model` as a
    curved composite beam (plane strain moduli, bending about the layers' modulus-weighted centroid,
    axial and, with ``shear``, Timoshenko shear with kappa = 5/6 of the layers' summed G t): the
    compliance of the end (unit Fx, Fy, M) integrated along the arc from the clamped bottom, inverted,
    its yy entry (the end clamped: x and rotation held)."""
    nu = ARCH_NU
    r0, r1, r2 = ARCH_RADII
    e1, e2 = ARCH_E_INNER / (1 - nu**2), ARCH_E_OUTER / (1 - nu**2)
    ea = e1 * (r1 - r0) + e2 * (r2 - r1)
    rn = (e1 * (r1**2 - r0**2) + e2 * (r2**2 - r1**2)) / (2 * ea)
    ei = (e1 * ((r1 - rn) ** 3 - (r0 - rn) ** 3) + e2 * ((r2 - rn) ** 3 - (r1 - rn) ** 3)) / 3
    ga = 5 / 6 * (ARCH_E_INNER * (r1 - r0) + ARCH_E_OUTER * (r2 - r1)) / (2 * (1 + nu))
    phi = np.linspace(0.0, np.pi / 2, 4001)  # from the bottom to the end
    x, y = rn * np.sin(phi), -rn * np.cos(phi)
    w = np.full_like(phi, rn * phi[1])
    w[[0, -1]] /= 2
    moment = np.stack([-(y[-1] - y), x[-1] - x, np.ones_like(x)])  # of a unit Fx, Fy, M at the end
    axial = np.stack([np.cos(phi), np.sin(phi), 0 * x])
    transverse = np.stack([-np.sin(phi), np.cos(phi), 0 * x])
    parts = [(moment, ei), (axial, ea)] + ([(transverse, ga)] if shear else [])
    c = sum((f[:, None] * f[None] / k * w).sum(-1) for f, k in parts)
    return float(np.linalg.inv(c)[1, 1])


# --- (b) Kratos Examples contact_structural_mechanics/validation/shallow_ironing_3D -----------
#: Young's moduli (Pa) from StructuralMaterials.json: the indenter (Parts_Auto1, 420 hexes of
#: shallow_ironing3D.mdpa, x 0.2-1.4, y 4.0-5.2) and the block (Parts_Auto2, 120 x 20 x 5 hexes,
#: 12 x 4 x 1); nu = 0.32 for both
IRON_E_INDENTER, IRON_E_BLOCK, IRON_NU = 68.96e8, 68.96e7, 0.32
#: the block (x, y, z extent from the origin), the indenter's x range, its top, and the radius and
#: centre (x, y) of its cylindrical bottom (the mdpa's nodes: the arc from (0.2, 4.3) through
#: (0.8, 4.0) to (1.4, 4.3) lies on r = 0.75 about (0.8, 4.75), the same at every z)
IRON_BLOCK, IRON_X, IRON_TOP = (12.0, 4.0, 1.0), (0.2, 1.4), 5.2
IRON_RADIUS, IRON_CENTRE = 0.75, (0.8, 4.75)
#: ProjectParameters_literature.json: the mesh's indenter touches the block; it moves down 0.8 from
#: t = 0.2 to 1 (the literature's 1 mm from a gap of 0.2), then 10 along x to t = 2
IRON_PRESS, IRON_SLIDE, IRON_T_TOUCH = 0.8, 10.0, 0.2
#: ProjectParameters_frictional.json's friction_coefficients
IRON_MU = 0.3


def kratos_neo_hookean_energy(I1, I2, J, params):
    """Kratos' HyperElastic3DLaw: ``W = mu/2 (I1 - 3) - mu ln J + lambda/2 (ln J)^2`` (``params``: mu,
    lambda), the coupled neo-Hookean; contopt's :func:`contopt.material.neo_hookean` is the decoupled
    ``kappa/2 (ln J)^2 + mu/2 (I1bar - 3)``. The two agree at small strain."""
    import jax.numpy as jnp

    mu, lam = params[0], params[1]
    ln_j = jnp.log(J)
    return 0.5 * mu * (I1 - 3.0) - mu * ln_j + 0.5 * lam * ln_j**2


@dataclass(frozen=True)
class KratosNeoHookean:
    """A :class:`contopt.material.hyperelastic.Material` with Kratos' energy
    (:func:`kratos_neo_hookean_energy`) from Young's modulus and Poisson's ratio."""

    E: float
    nu: float
    mass_density: float = 0.0

    def __post_init__(self):
        if not (self.E > 0 and -1.0 < self.nu < 0.5):
            raise ConfigError(f"KratosNeoHookean needs E > 0 and -1 < nu < 0.5, got E={self.E}, nu={self.nu}")

    @property
    def youngs_modulus(self) -> float:
        return float(self.E)

    @property
    def poisson_ratio(self) -> float:
        return float(self.nu)

    @property
    def params(self) -> np.ndarray:
        mu = self.E / (2 * (1 + self.nu))
        return np.array([mu, self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))], dtype=np.float64)

    @property
    def energy(self):
        return kratos_neo_hookean_energy


def ironing_indenter(nx: int = 8, ny: int = 4, nz: int = 2):
    """The indenter of shallow_ironing3D.mdpa as a hex8 ``box`` mapped onto its shape: x in
    :data:`IRON_X`, from the cylindrical bottom (facet set ``ymin``: the contact surface) up to
    y = :data:`IRON_TOP` (``ymax``: where it is driven), z from 0 (``zmin``) to 1."""
    from contopt.mesh.core import Mesh

    mesh = box((1.0, 1.0, IRON_BLOCK[2]), (nx, ny, nz))
    p = np.asarray(mesh.points).copy()
    x = IRON_X[0] + (IRON_X[1] - IRON_X[0]) * p[:, 0]
    bottom = IRON_CENTRE[1] - np.sqrt(IRON_RADIUS**2 - (x - IRON_CENTRE[0]) ** 2)
    p[:, 1] = bottom + p[:, 1] * (IRON_TOP - bottom)
    p[:, 0] = x
    return Mesh(p, mesh.cells, mesh.node_sets, mesh.facet_sets)


def ironing_block(h: float = 0.25, nz: int = 2, ratio: float = 1.3):
    """The 12 x 4 x 1 block: cells of ``h`` along x, ``h`` at the top graded by ``ratio`` down to the
    clamped bottom, ``nz`` across the depth."""
    y = IRON_BLOCK[1] - _coords(h / IRON_BLOCK[1], h / IRON_BLOCK[1], ratio)[::-1] * IRON_BLOCK[1]
    nx = int(round(IRON_BLOCK[0] / h))
    return box(IRON_BLOCK, (nx, 1, nz), grading=(None, y, None))


def ironing_model(
    mu: float = 0.0,
    h: float = 0.25,
    nz: int = 2,
    press_steps: int = 8,
    slide_steps: int = 40,
    slide: float = IRON_SLIDE,
    indenter: tuple = (8, 4, 2),
    kratos_law: bool = True,
):
    """``(model, n_steps, time)``: Kratos' shallow ironing in 3D (ProjectParameters_literature.json).

    The block (:func:`ironing_block`, neo-Hookean E = 68.96e7, nu = 0.32) clamped at its bottom, the
    indenter (:func:`ironing_indenter`, E = 68.96e8) touching it, both held in z on the plane z = 0
    (Kratos' DISPLACEMENT_Auto3), the indenter's top moved down by 0.8 in ``press_steps`` equal
    steps, then along x by ``slide`` (the literature's 10) in ``slide_steps``. Contact: the indenter's
    cylindrical bottom nonmortar (Kratos' slave), the block's top mortar, the augmented Lagrangian
    with its defaults (frictionless: one multiplier update per intermediate load step, converged at
    the last; with friction converged at every step); frictionless or Coulomb ``mu``. The material:
    Kratos' coupled neo-Hookean (:class:`KratosNeoHookean`, the source's HyperElastic3DLaw), or with
    ``kratos_law=False`` contopt's :func:`contopt.material.neo_hookean`. ``time(t)``: the reference's time at load
    factor ``t`` (0.2 at touching, 1 at full depth, 1 + slide/10 at the end)."""
    from contopt.contact.coulomb import Coulomb

    n_steps = press_steps + slide_steps
    s1 = press_steps / n_steps
    path = LoadPath(((s1, 0.0, -IRON_PRESS, 0.0), (1.0, slide, -IRON_PRESS, 0.0))) if slide_steps else None
    path = path or LoadPath(((1.0, 0.0, -IRON_PRESS, 0.0),))

    def time(t: float) -> float:
        if t <= s1:
            return IRON_T_TOUCH + (1 - IRON_T_TOUCH) * t / s1
        return 1.0 + slide / IRON_SLIDE * (t - s1) / (1 - s1)

    friction = {} if mu == 0 else {"friction": Coulomb(mu)}
    law = KratosNeoHookean if kratos_law else neo_hookean
    model = Model(
        bodies=(
            Body("block", ironing_block(h, nz), law(IRON_E_BLOCK, IRON_NU)),
            Body("indenter", ironing_indenter(*indenter), law(IRON_E_INDENTER, IRON_NU)),
        ),
        dirichlet=(
            Dirichlet("block", "ymin", "xyz"),
            Dirichlet("block", "zmin", "z"),
            Dirichlet("indenter", "zmin", "z"),
            Dirichlet("indenter", "ymax", "xyz", path),
        ),
        interfaces=(
            ContactInterface(
                nonmortar=("indenter", "ymin"),
                mortar=("block", "ymax"),
                law=AugmentedLagrangian(),
                **friction,
            ),
        ),
    )
    return model, n_steps, time


def ironing_forces(system, state) -> tuple[float, float]:
    """``(F_x, F_y)`` on the indenter's driven top as the reference plots them: F_y the block's push
    up on the indenter (minus the support's y reaction), F_x the support's x reaction that drives it (positive
    along the slide; the reference plots both positive)."""
    model = system.disc.model
    top = system.disc.blocks[model.body_index("indenter")].node_offset + model.body("indenter").mesh.node_set("ymax")
    r = np.asarray(state.reactions).reshape(-1, 3)[top].sum(axis=0)
    return float(r[0]), -float(r[1])


def ironing_reference(mu: float) -> dict:
    """``{"Fy": (n, 2), "Fx": (m, 2)}``: time (s) and force (N) of the reference curves read off
    Kratos' figure (tests/validation/data/ironing_*_reference.csv), frictionless or ``mu`` = 0.3."""
    from pathlib import Path

    name = "ironing_frictionless_reference.csv" if mu == 0 else "ironing_frictional_reference.csv"
    lines = (Path(__file__).parent / "data" / name).read_text().splitlines()
    rows = [ln.split(",") for ln in lines if ln[:2] in ("Fy", "Fx")]
    return {k: np.array([[float(r[1]), 1e8 * float(r[2])] for r in rows if r[0] == k]) for k in ("Fy", "Fx")}
