"""The paper's sections 7.1-7.3: a stiff cylindrical die pressed into a slab, and its design problems.

Geometry (units of the paper; E = 1 slab):

* slab 9 x 4 x 3 (x in [0, 9], y in [0, 4], z in [0, 3]), neo-Hookean E = 1,
  nu = 0.3; fixed on its bottom face (7.1) or on its face x = 9 (7.2,
  ``support="right"``); meshes coarse 23 x 10 x 8, fine 45 x 20 x 15;
* die: a cylindrical shell sector, contact (outer) radius 3, E = 1000,
  nu = 0.3, meshed 12 x 8 x 1 (arc x width x thickness), axis along y
  through (4.5, 2, 6) so that its lowest line rests on the slab's top at
  its centre; its inner surface is moved by (0, 0, -0.6) over the load steps.

The paper does not state the die's arc, width or thickness. Our choice:
arc 100 degrees (the contact zone of a 0.6 indentation has a half-width
of about sqrt(2 R d) = 1.9, i.e. +-39 degrees: it stays inside the arc),
width 4.6 (the slab's width plus an overhang of 0.3 on each side),
thickness 0.3 (R/10; at E = 1000 the die is effectively rigid). Contact:
slab top = nonmortar, die outer surface = mortar.

Why the overhang: with a die exactly as wide as the slab, the slab's side
edges bulge sideways (0.14 on the fine mesh) out from under the die, the
die's edge indents the slab's top along a line, and the edge nodes see
only a sliver of the die (2 % or less of their nodal area). That coincident
edge-on-edge configuration is singular (a flat-punch edge) and was the
reason the fine mesh's augmentations did not converge; an overhanging die
keeps the whole slab top under the die, which is what the paper's figures
show.

Design problems (:func:`die_slab_problem`): the slab is the hold-all domain,
volume fraction <= 0.4, designed by a cone filter of radius 0.7 (density
method, one variable per cell) or by 13 x 8 x 7 tri-cubic B-spline control
points over the slab (patch sizes 0.9, 0.8, 0.75); eta = 10, p = 3,
nu0 = 1e-2. 7.1 and 7.2 minimize ``f_a = -(strain energy of the slab)``
(eq. 41, ``support`` "bottom" / "right"), 7.3 minimizes ``f_c = -(total
contact force)`` (eq. 43); both are divided by ``|f^0|`` of the full design.
"""

from __future__ import annotations

import numpy as np

from contopt.assembly.model import Body, BodyForce, Dirichlet, Model
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import law_named
from contopt.design import BSplineGrid, Density, Design, DesignedBody, Heaviside, Simp
from contopt.errors import ConfigError
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import box, cylinder_shell_sector
from contopt.optimize.problem import DesignProblem
from contopt.responses.functionals import ContactForce, StrainEnergy
from contopt.solve.newton import NewtonOptions

SLAB_MESHES = {"coarse": (23, 10, 8), "fine": (45, 20, 15)}
SLAB_SIZE = (9.0, 4.0, 3.0)
DIE_RADIUS = 3.0
DIE_ARC_DEG = 100.0
DIE_THICKNESS = 0.3
DIE_OVERHANG = 0.3
DIE_DIVISIONS = (12, 8, 1)
INDENTATION = 0.6
LOAD_STEPS = 6

DESIGN_BODY = "slab"
PARAMETERIZATIONS = ("bspline", "density")
SUPPORTS = ("bottom", "right")
OBJECTIVES = ("strain-energy", "contact-force")


def die_slab(mesh: str = "coarse", support: str = "bottom", enforcement: str = "alm",
             eps: float | None = None, slab_divisions=None, body_force=None) -> Model:
    """The die-slab model (see module docstring).

    Parameters
    ----------
    mesh : ``"coarse"`` (23 x 10 x 8) or ``"fine"`` (45 x 20 x 15) slab; ignored with ``slab_divisions``
    support : ``"bottom"`` (paper 7.1) or ``"right"`` (the cantilever of 7.2, fixed at x = 9)
    enforcement, eps : contact enforcement and penalty (default: ContactInterface's)
    body_force : optional constant force per volume on the slab (not in the paper; makes the
        compliance of eq. 42 non-zero, e.g. for gradient checks)
    """
    if slab_divisions is None:
        if mesh not in SLAB_MESHES:
            raise ConfigError(f"mesh must be one of {sorted(SLAB_MESHES)}, got {mesh!r}")
        slab_divisions = SLAB_MESHES[mesh]
    if support not in ("bottom", "right"):
        raise ConfigError(f"support must be 'bottom' or 'right', got {support!r}")
    slab = box(SLAB_SIZE, slab_divisions)
    die = cylinder_shell_sector(radius=DIE_RADIUS, arc=np.deg2rad(DIE_ARC_DEG), width=SLAB_SIZE[1] + 2 * DIE_OVERHANG,
                                thickness=DIE_THICKNESS, divisions=DIE_DIVISIONS,
                                center=(SLAB_SIZE[0] / 2, SLAB_SIZE[1] / 2, SLAB_SIZE[2] + DIE_RADIUS),
                                axis="y", mid_angle=-np.pi / 2)
    fixed = "zmin" if support == "bottom" else "xmax"
    return Model(
        bodies=(Body("slab", slab, neo_hookean(1.0, 0.3)), Body("die", die, neo_hookean(1000.0, 0.3))),
        dirichlet=(Dirichlet("slab", fixed, "xyz", 0.0),
                   Dirichlet("die", "inner", "xyz", (0.0, 0.0, -INDENTATION))),
        interfaces=(ContactInterface(nonmortar=("slab", "zmax"), mortar=("die", "outer"),
                                     law=law_named(enforcement, eps=eps)),),
        loads=(BodyForce("slab", tuple(body_force)),) if body_force is not None else (),
    )


def die_design(parameterization: str = "bspline", volume_fraction: float = 0.4, radius: float = 0.7,
               control_points=(13, 8, 7), degree: int = 3, eta: float = 10.0, p: float = 3.0,
               nu0: float = 1e-2) -> Design:
    """The slab's design (paper 7.1): cone filter of ``radius`` over the cells (density) or a
    B-spline grid of ``control_points`` over the slab box [0, 9] x [0, 4] x [0, 3]."""
    if parameterization not in PARAMETERIZATIONS:
        raise ConfigError(f"design must be one of {PARAMETERIZATIONS}, got {parameterization!r}")
    if parameterization == "density":
        param = Density(radius=float(radius))
    else:
        param = BSplineGrid.with_control_points(control_points, degree=degree, origin=(0.0, 0.0, 0.0),
                                                lengths=SLAB_SIZE)
    return Design(bodies=(DesignedBody(DESIGN_BODY, param, volume_fraction=volume_fraction),),
                  heaviside=Heaviside(eta), simp=Simp(p, nu0))


def die_slab_problem(parameterization: str = "bspline", mesh: str = "coarse", support: str = "bottom",
                     objective: str = "strain-energy", eta: float | None = None, enforcement: str = "alm",
                     eps: float | None = None, slab_divisions=None, normalize="full",
                     **design) -> DesignProblem:
    """Paper 7.1 (``support="bottom"``), 7.2 (``"right"``) or 7.3 (``objective="contact-force"``).

    objective : "strain-energy" minimizes ``-(strain energy of the slab)`` (eq. 41: the slab is
        the domain omega); "contact-force" minimizes ``-(total contact force)`` (eq. 43)
    eta : Heaviside sharpness (None: the paper's 10); further keywords go to :func:`die_design`

    Cold solves (the full design that normalizes f, the first design, a failed warm start's
    fall-back) use the forward case's :data:`LOAD_STEPS`; the design iterations after the first
    start from the last converged state in one step (DesignProblem's warm start).
    """
    if objective not in OBJECTIVES:
        raise ConfigError(f"objective must be one of {OBJECTIVES}, got {objective!r}")
    if eta is not None:
        design["eta"] = eta
    response = -StrainEnergy(bodies=(DESIGN_BODY,)) if objective == "strain-energy" else -ContactForce()
    return DesignProblem(
        model=die_slab(mesh, support, enforcement, eps, slab_divisions=slab_divisions),
        design=die_design(parameterization, **design),
        objective=response,
        normalize=normalize,
        newton=NewtonOptions(n_steps=LOAD_STEPS),
    )
