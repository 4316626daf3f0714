"""The paper's section 7.1 / 7.2 forward problem: a stiff cylindrical die pressed into a slab.

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
"""

from __future__ import annotations

import numpy as np

from contopt.assembly.model import Body, BodyForce, Dirichlet, Model
from contopt.contact.interface import ContactInterface
from contopt.errors import ConfigError
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import box, cylinder_shell_sector

SLAB_MESHES = {"coarse": (23, 10, 8), "fine": (45, 20, 15)}
SLAB_SIZE = (9.0, 4.0, 3.0)
DIE_RADIUS = 3.0
DIE_ARC_DEG = 100.0
DIE_THICKNESS = 0.3
DIE_OVERHANG = 0.3
DIE_DIVISIONS = (12, 8, 1)
INDENTATION = 0.6
LOAD_STEPS = 6


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
                                     enforcement=enforcement, eps=eps),),
        loads=(BodyForce("slab", tuple(body_force)),) if body_force is not None else (),
    )
