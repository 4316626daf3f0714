"""A small two-body contact case: a stiff punch pressed into a block (tests, gradient checks, tutorials).

Geometry: block ``[0, 1] x [0, 1] x [0, 0.5]`` (neo-Hookean E = 1, nu = 0.3,
clamped at z = 0, ``divisions`` cells per direction in x and y, half as many
in z); punch ``[0.2, 0.8]^2 x [0.5, 0.9]`` (E = 10, nu = 0.3) resting on the
block, meshed more coarsely than the block so the meshes do not match. The
punch's top face moves by ``(shift, 0, -depth)``: a little sliding with the
indentation. Contact: punch bottom = nonmortar, block top = mortar. The
designed body is the block.

Optional ``body_force``: a constant force per volume on the block (so that
compliance, eq. 42, is not zero).
"""

from __future__ import annotations

from contopt.assembly.model import Body, BodyForce, Dirichlet, Model
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import law_named
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import box


def two_blocks(
    divisions: int = 4,
    depth: float = 0.06,
    shift: float = 0.02,
    law: str = "alm",
    eps: float | None = None,
    body_force=None,
) -> Model:
    """The punch-on-block model (see the module docstring)."""
    n = int(divisions)
    block = box((1.0, 1.0, 0.5), (n, n, max(1, n // 2)))
    m = max(2, (3 * n) // 4)
    punch = box((0.6, 0.6, 0.4), (m, m, max(1, m // 2)), origin=(0.2, 0.2, 0.5))
    loads = (BodyForce("block", tuple(body_force)),) if body_force is not None else ()
    return Model(
        bodies=(Body("block", block, neo_hookean(1.0, 0.3)), Body("punch", punch, neo_hookean(10.0, 0.3))),
        dirichlet=(Dirichlet("block", "zmin", "xyz", 0.0), Dirichlet("punch", "zmax", "xyz", (shift, 0.0, -depth))),
        interfaces=(
            ContactInterface(nonmortar=("punch", "zmin"), mortar=("block", "zmax"), law=law_named(law, eps=eps)),
        ),
        loads=loads,
    )
