"""The paper's section 7.4: a sabot between a slug and a launch tube, under a transverse acceleration.

Units: mm, N, MPa (N/mm^2), tonne/mm^3, s (a consistent set: force = tonne mm / s^2 = N).

Three coaxial bodies along z, upper half modelled (z in [0, 25.4]; the plane
z = 0 is the symmetry plane of the 50.8 mm long parts):

* slug: aluminium cylinder r = 25.3, E = 69 GPa, nu = 0.33, density 2.70e-9;
* sabot: ring r = 25.4 .. 50.7, fibre composite E = 6 GPa, nu = 0.33, density
  1.80e-9 (the paper gives no density; a typical glass/epoxy value);
* annulus (launch tube): steel ring r = 50.8 .. 76.2, E = 210 GPa,
  nu = 0.26, density 7.85e-9.

Supports: the axial displacement of every body's bottom face (z = 0,
symmetry); the annulus' outer surface fixed radially and tangentially (x
and y); y fixed at two points on the x axis of the slug (A, B) and of the
sabot (C, D) against rigid rotation about z and translation along y. The
slug and the sabot are then held in x only by contact across the 0.1 mm
clearances: see "held by contact" below.

Load: the 10,000 g transverse acceleration in e1 by inertia relief: the
d'Alembert body force ``-density * a`` on the slug and the sabot (the
projectile; the tube is not accelerated with it). The sabot's load
follows its material: volume loads scale with the design's volume
fraction nu (:mod:`contopt.assembly.system`).

Contact (ALM, mortar): sabot inner surface (nonmortar: the finer, softer
side) on the slug, sabot outer surface on the annulus.

Held by contact: at the start the slug and the sabot touch nothing (0.1 mm
clearances), so their stiffness is singular in x. Each carries a
:class:`SoftSupport` of stiffness ``density |a| / clearance`` that fades
as ``1 - t`` over the load: the gaps close at about half the load and the
springs are exactly zero at the full load, so the equilibrium, the
compliance and its adjoint are those of the model without springs.

Design (paper 7.4): the sabot, a B-spline level set of 11 x 6 x 6 cubic
control points over the box of the first half sector of 5 (cyclic +
reflection symmetry: ``phi(r, alpha) = phi(r, alpha*)``), united by
R-functions (eq. 46) with solid skins for r < 28.575 and r > 47.625
(eq. 45, slope m = 5 per mm); minimize compliance (eq. 42) under a volume
fraction of 0.5.

Meshes: "coarse" (default, about 2.9k cells: minutes per design iteration
on 2 cores) and "fine", the paper's 10,780 / 46,816 / 13,552 cells
(slug O-grid 14 x 14 x 11; sabot 224 x 19 x 11; annulus 112 x 11 x 11).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from contopt.assembly.model import Acceleration, Body, Dirichlet, Model, SoftSupport
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import law_named
from contopt.design import BSplineGrid, Design, DesignedBody, Heaviside, Simp
from contopt.design.space import RadialSkin
from contopt.design.symmetry import CyclicSymmetry
from contopt.errors import ConfigError, MeshError
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.core import Mesh
from contopt.mesh.generators import annulus, cylinder
from contopt.optimize.problem import DesignProblem
from contopt.responses.functionals import Compliance
from contopt.solve.newton import NewtonOptions

LENGTH = 25.4  # the modelled upper half of the 50.8 mm parts
R_SLUG, R_SABOT, R_TUBE = 25.3, (25.4, 50.7), (50.8, 76.2)
SKIN_RADII = (28.575, 47.625)
CLEARANCE = 0.1  # slug-sabot and sabot-tube radial clearances
G_MM = 9810.0  # standard gravity in mm/s^2
ACCELERATION = 10_000.0 * G_MM
MATERIALS = {  # E (MPa), Poisson's ratio, density (tonne/mm^3)
    "slug": (69_000.0, 0.33, 2.70e-9),
    "sabot": (6_000.0, 0.33, 1.80e-9),
    "annulus": (210_000.0, 0.26, 7.85e-9),
}
#: per mesh: slug (n_core, n_r, n_z), sabot and annulus (n_theta, n_r, n_z)
SABOT_MESHES = {
    "coarse": {"slug": (6, 4, 4), "sabot": (60, 8, 4), "annulus": (40, 3, 4)},
    "fine": {"slug": (14, 14, 11), "sabot": (224, 19, 11), "annulus": (112, 11, 11)},
}
CONTROL_POINTS = (11, 6, 6)
N_SECTORS = 5
VOLUME_FRACTION = 0.5
LOAD_STEPS = 4


def _point_set(mesh: Mesh, points, body: str) -> np.ndarray:
    """Node indices of the nodes at ``points`` (k, 3); each must exist in the mesh (to 1e-6 of its size)."""
    out = []
    scale = float(np.ptp(mesh.points, axis=0).max())
    for p in np.asarray(points, dtype=float):
        d = np.linalg.norm(mesh.points - p, axis=1)
        i = int(np.argmin(d))
        if d[i] > 1e-6 * scale:
            raise MeshError(f"{body}: no node at {tuple(p)} for a y support (nearest {d[i]:.3g} away); use an even "
                            "number of cells around so that the x axis carries nodes")
        out.append(i)
    return np.array(out, dtype=np.int64)


def _meshes(divisions: dict) -> dict:
    center = (0.0, 0.0, LENGTH / 2)
    slug = cylinder(R_SLUG, LENGTH, divisions["slug"], center=center)
    sabot = annulus(*R_SABOT, LENGTH, divisions["sabot"], center=center)
    tube = annulus(*R_TUBE, LENGTH, divisions["annulus"], center=center)
    slug = slug.with_sets(node_sets={"AB": _point_set(slug, [(-R_SLUG, 0, 0), (R_SLUG, 0, 0)], "slug")})
    sabot = sabot.with_sets(node_sets={"CD": _point_set(sabot, [(-R_SABOT[0], 0, 0), (R_SABOT[0], 0, 0)], "sabot")})
    return {"slug": slug, "sabot": sabot, "annulus": tube}


def sabot(mesh: str = "coarse", divisions: dict | None = None, acceleration: float = ACCELERATION,
          enforcement: str = "alm", eps: float | None = None, materials: dict | None = None) -> Model:
    """The three-body model (module docstring). ``divisions`` overrides the named mesh per body."""
    if divisions is None:
        if mesh not in SABOT_MESHES:
            raise ConfigError(f"sabot mesh must be one of {sorted(SABOT_MESHES)}, got {mesh!r}")
        divisions = SABOT_MESHES[mesh]
    missing = {"slug", "sabot", "annulus"} - set(divisions)
    if missing:
        raise ConfigError(f"sabot divisions need entries for {sorted(missing)}")
    mats = {**MATERIALS, **(materials or {})}
    meshes = _meshes(divisions)
    bodies = tuple(Body(name, meshes[name], replace(neo_hookean(E, nu), mass_density=rho))
                   for name, (E, nu, rho) in mats.items())
    clearance = CLEARANCE
    a = (float(acceleration), 0.0, 0.0)
    held = ("slug", "sabot")
    return Model(
        bodies=bodies,
        dirichlet=(*(Dirichlet(b, "zmin", "z", 0.0) for b in mats),
                   Dirichlet("annulus", "outer", "xy", 0.0),
                   Dirichlet("slug", "AB", "y", 0.0), Dirichlet("sabot", "CD", "y", 0.0)),
        loads=tuple(Acceleration(b, a) for b in held),
        interfaces=(ContactInterface(nonmortar=("sabot", "inner"), mortar=("slug", "outer"),
                                     law=law_named(enforcement, eps=eps)),
                    ContactInterface(nonmortar=("sabot", "outer"), mortar=("annulus", "inner"),
                                     law=law_named(enforcement, eps=eps))),
        soft_supports=tuple(SoftSupport(b, mats[b][2] * abs(acceleration) / clearance) for b in held),
    )


def sabot_design(volume_fraction: float = VOLUME_FRACTION, control_points=CONTROL_POINTS, degree: int = 3,
                 eta: float = 10.0, p: float = 3.0, nu0: float = 1e-2) -> Design:
    """B-spline level set over the first half of sector 1 of 5, skins by R-functions (paper 7.4)."""
    skins = (RadialSkin(SKIN_RADII[0], "inside", slope=5.0), RadialSkin(SKIN_RADII[1], "outside", slope=5.0))
    grid = BSplineGrid.with_control_points(tuple(control_points), degree=degree)
    return Design(bodies=(DesignedBody("sabot", grid, volume_fraction=volume_fraction,
                                       symmetry=CyclicSymmetry(N_SECTORS, reflection=True), skins=skins),),
                  heaviside=Heaviside(eta), simp=Simp(p, nu0))


def sabot_problem(mesh: str = "coarse", divisions: dict | None = None, eta: float | None = None,
                  enforcement: str = "alm", **design) -> DesignProblem:
    """Minimize the compliance of the three bodies under the inertia load, sabot volume fraction <= 0.5."""
    if eta is not None:
        design["eta"] = eta
    return DesignProblem(model=sabot(mesh, divisions, enforcement=enforcement), design=sabot_design(**design),
                         objective=Compliance(), normalize="full",
                         newton=NewtonOptions(n_steps=LOAD_STEPS))
