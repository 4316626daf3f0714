"""Quantities of one state that a load-path response reads besides the contact force (``on``).

* :class:`Reaction`: ``e . sum_i r_i`` over the dofs ``i`` of a body's prescribed displacement
  (a support or a motion: the model's ``Dirichlet`` conditions on one of its node sets), ``r`` the
  residual ``f_int(u; rho) + r_contact(u, lam) - t f_ext(mass)`` there: the force the support or
  the motion puts on the body, along ``e`` (by default the direction of the motion at the full
  load: the force that drives it, positive where the body resists).
* :class:`MeanDisplacement`: ``e . (1/n) sum_a u_a`` over the n nodes of a node set.

Derivatives, in the adjoint's model (:mod:`contopt.adjoint.common`: the pressures ``lam`` held
fixed in ``d/du``): with the weights ``c`` (n_dofs,), ``e_j`` on the condition's dof of component
j, the reaction's partials are ``d/du = K_b c + K_geo c`` (the bulk tangent, symmetric as the
energy's Hessian, and each interface's tangent at fixed pressures), ``d/dlam = -W c`` (the
interface's rows ``W``: ``r_contact = -W^T lam``), ``d/drho = c . dr/drho`` and ``d/dmass = c .
dr/dmass`` (the volume loads on its nodes). With a penalty law the adjoint adds ``dlam/du`` and the
two make the exact ``K c`` (:mod:`contopt.contact.force` does the same for the exchanged force). A
frictional interface whose nodes the condition holds is refused: its tractions' history is not in
these partials (hold the body on a node set away from the contact).
"""

from __future__ import annotations

import numpy as np

from contopt.contact.system import evaluate_interface
from contopt.errors import ConfigError, MeshError
from contopt.responses.base import Fields, Partials, Response, as_fields
from contopt.solve.curves import conditions


def checked_vector(direction, who: str, required: bool = True) -> np.ndarray | None:
    """``direction`` [x, y, z] as a unit (3,) vector (None where not ``required`` and not given);
    ConfigError naming ``who`` (``Reaction.direction``) otherwise."""
    if direction is None and not required:
        return None
    e = np.zeros(0) if isinstance(direction, str) or direction is None else np.asarray(direction, dtype=np.float64)
    if e.shape != (3,) or not np.all(np.isfinite(e)) or not np.linalg.norm(e) > 0:
        raise ConfigError(f"{who} must be a nonzero vector [x, y, z], got {direction!r}")
    return e / np.linalg.norm(e)


def _body_index(system, body: str, who: str) -> int:
    names = [b.name for b in system.disc.model.bodies]
    if body not in names:
        raise ConfigError(f"{who}: body {body!r} is not a body of the model; bodies: {names}")
    return names.index(body)


class Reaction(Response):
    """The force a body's support or prescribed motion puts on it, along ``direction`` (module docstring).

    Parameters
    ----------
    body : the body's name
    set : the node set of its prescribed displacement (needed where the body has them on several sets)
    direction : [x, y, z] (normalized here); default: the motion's mean displacement at the full load
    """

    name = "reaction"

    def __init__(self, body: str, set: str | None = None, direction=None, name: str = "reaction"):
        if not isinstance(body, str):
            raise ConfigError(f"Reaction.body must be a body's name, got {body!r}")
        if set is not None and not isinstance(set, str):
            raise ConfigError(f"Reaction.set must be a node set's name, got {set!r}")
        self.body, self.set, self.name = body, set, name
        self.direction = checked_vector(direction, "Reaction.direction", required=False)

    def _held(self, system) -> list:
        """The :class:`contopt.solve.curves.Condition` s of the body on its set."""
        _body_index(system, self.body, self.name)
        mine = [c for c in conditions(system) if c.bc.body == self.body]  # type: ignore[attr-defined]
        sets = sorted({c.bc.node_set for c in mine})  # type: ignore[attr-defined]
        if not mine or (self.set is not None and self.set not in sets):
            where = f" on set {self.set!r}" if self.set is not None else ""
            raise ConfigError(
                f"{self.name}: body {self.body!r} has no support or prescribed motion{where}; "
                f"{'its sets with one: ' + str(sets) if sets else 'give it a [[supports]] entry'}"
            )
        if self.set is None and len(sets) > 1:
            raise ConfigError(f"{self.name}: body {self.body!r} is held on several sets {sets}; name one as set")
        return [c for c in mine if self.set is None or c.bc.node_set == self.set]  # type: ignore[attr-defined]

    def _along(self, held: list) -> np.ndarray:
        if self.direction is not None:
            return self.direction
        moved = sum((c.displacement(1.0) for c in held), np.zeros(3))
        if not np.linalg.norm(moved) > 0:
            raise ConfigError(
                f"{self.name}: the support of body {self.body!r} does not move; give direction = [x, y, z]"
            )
        return moved / np.linalg.norm(moved)

    def weights(self, system) -> np.ndarray:
        """(n_dofs,) ``c``: the direction's component on each held dof (0 elsewhere)."""
        held = self._held(system)
        e = self._along(held)
        c = np.zeros(system.disc.n_dofs)
        for cond in held:
            c[cond.dofs] = e[cond.bc.component_indices][None, :]
        return c

    def check(self, system) -> None:
        c = self.weights(system)
        contact = system.contact
        for block in contact.blocks if contact is not None and system.has_contact else ():
            if block.friction is not None and np.any(c.reshape(-1, 3)[_interface_nodes(block)]):
                raise ConfigError(
                    f"{self.name}: the support of body {self.body!r} holds nodes of the frictional contact "
                    f"{block.interface.label}; read the reaction on a node set away from it"
                )

    def evaluate(self, fields: Fields, gradient: bool = True):
        fields = as_fields(fields, self.name)
        system, disc = fields.system, fields.disc
        self.check(system)
        c = self.weights(system)
        ev = disc.evaluate(fields.u, fields.t, fields.rho, tangent=gradient, mass=fields.mass, full=gradient)
        value = float(c @ ev.r)
        partials = Partials.zeros(fields) if gradient else None
        if partials is not None:
            partials.u[:] = ev.reduce(ev.K_dot(c))
            partials.rho[:] = disc.residual_rho_vjp(fields.u, c, fields.rho)
            partials.mass[:] = disc.residual_mass_vjp(c, fields.t)
        value += self._contact(fields, c, partials)
        return value, partials

    def _contact(self, fields: Fields, c: np.ndarray, partials: Partials | None) -> float:
        """``c . r_contact`` of the interfaces whose nodes ``c`` holds; their partials added in place."""
        system = fields.system
        contact = system.contact
        if contact is None or not system.has_contact:
            return 0.0
        if len(fields.laws) != len(contact.blocks):
            raise ConfigError(f"response {self.name!r} needs the state's contact-law states (Fields.from_state)")
        x = contact.X + fields.u.reshape(-1, 3)
        value = 0.0
        for i, block in enumerate(contact.blocks):
            if not np.any(c.reshape(-1, 3)[_interface_nodes(block)]):
                continue
            result, r_b, K_b, _ = evaluate_interface(block, x, fields.laws[i], contact.n_dofs, partials is not None)
            value += float(c @ r_b)
            if partials is not None and K_b is not None and result.W is not None:
                _, K_geo = K_b
                partials.u[:] += K_geo.T @ c
                partials.lam[i][:] -= result.W @ c
        return value

    def __repr__(self) -> str:
        return f"Reaction({self.body!r}, set={self.set!r})"


def _interface_nodes(block) -> np.ndarray:
    """The global node ids of both sides of an interface."""
    return np.unique(np.concatenate([block.nm_facet_nodes.ravel(), block.m_facet_nodes.ravel()]))


class MeanDisplacement(Response):
    """``e . (1/n) sum_a u_a``: the mean displacement of a body's node set along ``direction``.

    Parameters
    ----------
    body, set : the body's name and its node (or facet) set
    direction : [x, y, z] (normalized here)
    """

    name = "displacement"

    def __init__(self, body: str, set: str, direction, name: str = "displacement"):
        if not isinstance(body, str) or not isinstance(set, str):
            raise ConfigError(f"MeanDisplacement needs a body's name and a node set's, got {body!r} and {set!r}")
        self.body, self.set, self.name = body, set, name
        self.direction = checked_vector(direction, "MeanDisplacement.direction")

    def weights(self, system) -> np.ndarray:
        """(n_dofs,) ``c``: ``e / n`` on the set's nodes."""
        i = _body_index(system, self.body, self.name)
        disc = system.disc
        try:
            nodes = disc.model.bodies[i].mesh.node_set(self.set)
        except MeshError as err:
            raise ConfigError(f"{self.name}: body {self.body!r}: {err}") from None
        e = self.direction
        assert e is not None  # required at construction
        c = np.zeros((disc.n_dofs // 3, 3))
        c[disc.blocks[i].node_offset + nodes] = e[None, :] / len(nodes)
        return c.ravel()

    def check(self, system) -> None:
        self.weights(system)

    def evaluate(self, fields: Fields, gradient: bool = True):
        fields = as_fields(fields, self.name)
        c = self.weights(fields.system)
        value = float(c @ fields.u)
        if not gradient:
            return value, None
        partials = Partials.zeros(fields)
        partials.u[:] = c
        return value, partials

    def __repr__(self) -> str:
        return f"MeanDisplacement({self.body!r}, set={self.set!r})"
