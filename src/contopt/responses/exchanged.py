"""The force the bodies exchange through their interfaces, read as the resultant of the interface's
residual forces (``ContactForce(direction=...)``; :mod:`contopt.contact.force`)."""

from __future__ import annotations

import numpy as np

from contopt.contact.force import exchanged_force
from contopt.errors import ConfigError
from contopt.responses.base import Fields, Partials


def checked_direction(direction):
    """None, ``"norm"`` or a unit (3,) vector from a ``direction`` given as None, "norm" or [x, y, z]."""
    if direction is None or (isinstance(direction, str) and direction == "norm"):
        return direction
    e = np.asarray(direction, dtype=np.float64) if not isinstance(direction, str) else np.zeros(0)
    if e.shape != (3,) or not np.all(np.isfinite(e)) or not np.linalg.norm(e) > 0:
        raise ConfigError(f'ContactForce.direction must be a nonzero vector [x, y, z] or "norm", got {direction!r}')
    return e / np.linalg.norm(e)


def resultant(fields: Fields, indices: list[int], direction, gradient: bool, name: str):
    """``sum_i |F_i . e|`` (``direction`` e) or ``sum_i |F_i|`` ("norm") over the interfaces ``indices``,
    with ``F_i`` the force its nonmortar body exerts on its mortar body; ``(value, Partials or None)``."""
    system = fields.system
    contact = system.contact
    if contact is None or len(fields.laws) != len(contact.blocks):
        raise ConfigError(
            f"response {name!r} needs the state's contact-law states: use Fields.from_state(system, state)"
        )
    partials = Partials.zeros(fields) if gradient else None
    value = 0.0
    for i in indices:
        mortar = system.disc.body_slice(contact.blocks[i].mortar_body)
        f = exchanged_force(contact, fields.u, fields.laws, i, mortar)
        if isinstance(direction, str):  # the norm
            size = float(np.linalg.norm(f.force))
            value += size
            weights = f.force / size if size > 0 else np.zeros(3)
        else:
            along = float(f.force @ direction)
            value += abs(along)
            weights = np.sign(along) * direction
        if partials is not None:
            partials.u[:] += f.d_u @ weights
            partials.lam[i][:] += f.d_lam @ weights
    return value, partials
