"""One load case of a design problem: its own supports, motions and loads over the shared bodies,
interfaces and design (``[[load_cases]]`` in a problem file; docs/optimization.md, "Several load cases").

A :class:`~contopt.optimize.problem.DesignProblem` with ``load_cases`` analyses every design once per
case and combines the cases' objectives (``combine``):

* ``"sum"``: ``f = sum_c w_c f_c``, the weighted sum;
* ``"worst"``: ``f = max_c w_c f_c`` by the bound formulation: one more variable ``beta``, and the
  optimizer minimizes ``beta`` subject to ``w_c f_c / s - beta <= 0`` for each case (``s`` the
  objective's scale). A maximized response is negated, so its worst case is the mirror: the
  smallest response is maximized.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from contopt.assembly.model import Model
from contopt.errors import ConfigError

#: how the cases' objectives make the one the optimizer sees
COMBINES = ("sum", "worst")


@dataclass(frozen=True, eq=False)
class LoadCase:
    """A load case: ``name``, its ``model`` (the problem's bodies and interfaces with this case's
    supports, motions and loads) and ``weight`` (> 0) in the combined objective."""

    name: str
    model: Model
    weight: float = 1.0

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"a load case needs a name (a non-empty string), got {self.name!r}")
        if not isinstance(self.model, Model):
            raise ConfigError(f"load case {self.name!r}: model must be a Model, got {type(self.model).__name__}")
        w = self.weight
        if isinstance(w, bool) or not isinstance(w, (int, float)) or not math.isfinite(w) or w <= 0:
            raise ConfigError(f"load case {self.name!r}: weight must be a positive number, got {w!r}")


@dataclass(frozen=True, eq=False)
class CaseStart:
    """What a load case's converged state leaves for its next analysis and its output, as a checkpoint
    keeps it: ``u`` (n_dofs,) the displacement, per interface its ``multipliers`` (n_nodes,), its penalty
    ``eps`` (a float) and its nodal ``pressures`` (n_nodes,). A warm start from it is the same in the
    run that made it and in a resumed one (the one-case run's ``Record.u``, ``multipliers``, ``eps``)."""

    u: np.ndarray
    multipliers: tuple
    eps: tuple
    pressures: tuple

    @classmethod
    def of(cls, state) -> CaseStart:
        """From a converged :class:`contopt.solve.static.State`."""
        return cls(
            u=np.asarray(state.u),
            multipliers=tuple(np.asarray(m) for m in state.multipliers),
            eps=tuple(float(e) for e in state.eps),
            pressures=tuple(np.asarray(res.lam) for res in state.contact),
        )


def check_load_cases(model: Model, cases: tuple, combine: str) -> tuple:
    """``cases`` as a tuple of LoadCase over ``model``'s bodies and interfaces; ConfigError naming the
    first that is not (a duplicate name, other bodies, other interfaces) or an unknown ``combine``."""
    if combine not in COMBINES:
        raise ConfigError(f"combine must be one of {COMBINES}, got {combine!r}")
    cases = tuple(cases)
    if combine == "worst" and not cases:
        raise ConfigError('combine = "worst" needs load cases (load_cases=...); one analysis has no worst case')
    seen: set[str] = set()
    names = [b.name for b in model.bodies]
    interfaces = [i.name for i in model.interfaces]
    for c in cases:
        if not isinstance(c, LoadCase):
            raise ConfigError(f"load_cases must be LoadCase(name, model, weight), got {c!r}")
        if c.name in seen:
            raise ConfigError(f"duplicate load case name {c.name!r}")
        seen.add(c.name)
        if [b.name for b in c.model.bodies] != names:
            raise ConfigError(f"load case {c.name!r} has other bodies than the problem's {names}")
        if [b.mesh.n_nodes for b in c.model.bodies] != [b.mesh.n_nodes for b in model.bodies]:
            raise ConfigError(f"load case {c.name!r} has other meshes than the problem's bodies")
        if [i.name for i in c.model.interfaces] != interfaces:
            raise ConfigError(f"load case {c.name!r} has other contact interfaces than the problem's {interfaces}")
    return cases
