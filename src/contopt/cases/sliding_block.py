"""A block pressed onto a base and then dragged along it: the forward case of Coulomb friction.

Geometry: base ``[0, 2] x [0, 1] x [0, 0.3]`` (neo-Hookean E = 1000, nu = 0.3, clamped at z = 0: a
stiff floor whose surface stays flat); block ``[0.2, 0.7] x [0.27, 0.77] x [0.3, 0.55]`` (E = 1,
nu = 0), ``divisions`` cells across, resting on it with its facet edges off the base's. The block's
top face is pressed down by ``press`` over the first half of the load and dragged by ``pull`` along
x over the second half (a path: with friction the order matters). Contact: block bottom =
nonmortar, base top = mortar, Coulomb friction ``mu`` (None: frictionless).

Sliding at ``pull`` beyond the stick range, the friction force is ``mu`` times the normal force
(tests/contact/test_friction.py checks it to 1e-6).
"""

from __future__ import annotations

from contopt.assembly.model import Body, Dirichlet, LoadPath, Model
from contopt.contact.coulomb import Coulomb
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import law_named
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import box


def press_then_pull(press: float, pull: float, back: float = 0.0) -> LoadPath:
    """Top-face motion (x, y, z): down by ``press`` over t <= 1/2, then along x by ``pull`` over the
    rest (with ``back``: by ``pull`` over 1/2..3/4, then back by ``back``)."""
    if back:
        return LoadPath(((0.5, 0.0, 0.0, -press), (0.75, pull, 0.0, -press), (1.0, pull - back, 0.0, -press)))
    return LoadPath(((0.5, 0.0, 0.0, -press), (1.0, pull, 0.0, -press)))


def sliding_block(
    divisions: int = 4,
    mu: float | None = 0.3,
    press: float = 0.01,
    pull: float = 0.1,
    back: float = 0.0,
    law: str = "penalty",
    eps: float | None = None,
) -> Model:
    """The pressed and dragged block (module docstring)."""
    n = int(divisions)
    block = box((0.5, 0.5, 0.25), (n, n, max(1, n // 2)), origin=(0.2, 0.27, 0.3))
    base = box((2.0, 1.0, 0.3), (12, 4, 2))
    return Model(
        bodies=(Body("block", block, neo_hookean(1.0, 0.0)), Body("base", base, neo_hookean(1000.0, 0.3))),
        dirichlet=(
            Dirichlet("block", "zmax", "xyz", press_then_pull(press, pull, back)),
            Dirichlet("base", "zmin", "xyz"),
        ),
        interfaces=(
            ContactInterface(
                ("block", "zmin"),
                ("base", "zmax"),
                law=law_named(law, eps=eps),
                friction=None if mu is None else Coulomb(mu),
            ),
        ),
    )
