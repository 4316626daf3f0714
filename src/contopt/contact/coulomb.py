"""Coulomb friction as a Model describes it: the friction coefficient, the stick penalty and the
rounding of the cone (no JAX; the kinematics and the return map are :mod:`contopt.contact.friction`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from contopt.errors import ConfigError


@dataclass(frozen=True)
class Coulomb:
    """Coulomb friction on a contact interface.

    mu : friction coefficient (>= 0; 0 is frictionless, through the frictional code path)
    eps : tangential penalty of stick, traction per unit elastic slip (force/length^3); default
        ``100 E*/h`` like :class:`contopt.contact.laws.Penalty` (``E*``: contact modulus, ``h``:
        median nonmortar facet size), so a sticking node slips ``t h / (100 E*)`` elastically.
    edge : half-width ``delta`` (0 <= delta < 1) of the rounded edge of the Coulomb cone, relative
        to ``mu lam`` (:func:`contopt.contact.friction.cone_magnitude`); 0 is the sharp cone. The
        default 0.05 keeps Newton from cycling between the stick and the slip linearization of a
        node whose trial traction ends near the cone (measured: the ironing test stalls with the
        sharp cone and converges with 0.02-0.1), and makes responses continuously differentiable
        in the design. A node then sticks exactly below ``(1 - delta) mu lam``, slides exactly
        above ``(1 + delta) mu lam``, and between the two its traction falls short of the cone by
        at most ``delta/4 mu lam``.
    """

    mu: float
    eps: float | None = None
    edge: float = 0.05
    eps_factor: ClassVar[float] = 100.0

    def __post_init__(self):
        if not (_is_real(self.mu) and self.mu >= 0):
            raise ConfigError(f"Coulomb.mu must be a number >= 0 (the friction coefficient), got {self.mu!r}")
        if self.eps is not None and not (_is_real(self.eps) and self.eps > 0):
            raise ConfigError(f"Coulomb.eps must be a positive number (the tangential penalty), got {self.eps!r}")
        if not (_is_real(self.edge) and 0 <= self.edge < 1):
            raise ConfigError(
                f"Coulomb.edge must be a number in [0, 1) (the rounded cone edge's half-width over mu lam), "
                f"got {self.edge!r}"
            )

    def resolve_eps(self, e_star: float, h: float) -> float:
        """The tangential penalty in use: ``eps``, or ``eps_factor * E* / h``."""
        return float(self.eps) if self.eps is not None else self.eps_factor * e_star / h

    def describe(self) -> str:
        eps = "" if self.eps is None else f", eps {self.eps:g}"
        edge = f", edge {self.edge:g}" if self.edge != Coulomb.edge else ""
        return f"coulomb (mu {self.mu:g}{eps}{edge})"


def _is_real(value) -> bool:
    """A finite int or float, not a bool (an option's number from Python or a TOML file)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and bool(np.isfinite(value))
