"""Force against displacement along a solve's load path: what a person expects to see of contact.

:class:`LoadPathRecorder` is an ``on_step`` callback of :func:`contopt.solve.static.solve_static`.
After every converged load step it keeps

* the load factor ``t``;
* for each prescribed displacement (each ``Dirichlet`` of the model, in order): the mean
  prescribed displacement of its nodes (3,) and the sum of the reactions on its dofs (3,): the
  force the support or the motion puts on the body (the residual on constrained dofs, the
  reaction :attr:`State.reactions` reports; a dof that two conditions share counts in both);
* for each contact interface: the normal force ``sum_A lam_A a_A`` (the pressure integrated over
  the overlap of the deformed surfaces, as :meth:`ContactDiscretization.total_force`) and, with
  friction, the size of the friction force.

:meth:`LoadPathRecorder.curves` returns them as plain lists (JSON), starting from the unloaded
bodies at ``t = 0`` (every condition and load is scaled by ``t`` from zero). A condition whose
prescribed displacement is zero throughout is a ``support``; one that moves is a ``motion``, and
its ``travel`` (length of the mean displacement) and ``force_along`` (the force's component along
that displacement: positive where the body resists the motion's push) make its force-displacement
curve.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from contopt.solve.system import System


@dataclass(frozen=True, eq=False)
class Condition:
    """One prescribed displacement: its name, its constrained dofs (k, m), the nodes' reference
    coordinates and the Dirichlet itself."""

    name: str
    dofs: np.ndarray
    points: np.ndarray
    bc: object

    def displacement(self, t: float) -> np.ndarray:
        """(3,) mean prescribed displacement of the nodes at load factor t (0 for free components)."""
        out = np.zeros(3)
        if len(self.points):
            out[self.bc.component_indices] = self.bc.values(self.points, t).mean(axis=0)  # type: ignore[attr-defined]
        return out

    def force(self, reactions: np.ndarray) -> np.ndarray:
        """(3,) sum of the reactions on the condition's dofs (0 for free components)."""
        out = np.zeros(3)
        out[self.bc.component_indices] = np.asarray(reactions)[self.dofs].sum(axis=0)  # type: ignore[attr-defined]
        return out


def conditions(system: System) -> list[Condition]:
    """The model's prescribed displacements as :class:`Condition` s, named ``body/set (xyz)``."""
    disc = system.disc
    model = disc.model
    out = []
    for bc in model.dirichlet:
        i = model.body_index(bc.body)
        mesh = model.bodies[i].mesh
        nodes = mesh.node_set(bc.node_set)
        dofs = 3 * (disc.blocks[i].node_offset + nodes[:, None]) + bc.component_indices[None, :]
        out.append(Condition(f"{bc.body}/{bc.node_set} ({bc.components})", dofs, mesh.points[nodes], bc))
    return out


class LoadPathRecorder:
    """Per converged load step, the forces and displacements of the module docstring (``on_step``)."""

    def __init__(self, system: System):
        self.conditions = conditions(system)
        contact = system.contact if system.has_contact else None
        self.interfaces = [b.interface.label for b in contact.blocks] if contact is not None else []
        self.t: list[float] = [0.0]
        self.displacements: list[np.ndarray] = [np.zeros((len(self.conditions), 3))]
        self.forces: list[np.ndarray] = [np.zeros((len(self.conditions), 3))]
        self.normal: list[np.ndarray] = [np.zeros(len(self.interfaces))]
        self.friction: list[np.ndarray] = [np.zeros(len(self.interfaces))]
        self.has_friction = False

    def __call__(self, state) -> None:
        if state.reactions is None:
            return  # no evaluation at the converged state: nothing to read
        self.t.append(float(state.t))
        self.displacements.append(np.array([c.displacement(state.t) for c in self.conditions]).reshape(-1, 3))
        self.forces.append(np.array([c.force(state.reactions) for c in self.conditions]).reshape(-1, 3))
        normal, friction = np.zeros(len(self.interfaces)), np.zeros(len(self.interfaces))
        for i, res in enumerate(state.contact):
            normal[i] = float(np.dot(np.asarray(res.lam), np.asarray(res.a)))
            if res.friction is not None:
                self.has_friction = True
                friction[i] = float(np.linalg.norm(res.friction_force))
        self.normal.append(normal)
        self.friction.append(friction)

    @property
    def steps(self) -> int:
        """Converged load steps recorded (the unloaded start not counted)."""
        return len(self.t) - 1

    def curves(self) -> dict:
        """The recorded path as JSON-ready lists (see the module docstring)."""
        d, f = np.stack(self.displacements), np.stack(self.forces)  # (steps + 1, conditions, 3)
        motions = []
        for j, c in enumerate(self.conditions):
            travel = np.linalg.norm(d[:, j], axis=1)
            unit = np.divide(d[:, j], travel[:, None], out=np.zeros_like(d[:, j]), where=travel[:, None] > 0)
            moves = bool(travel.max() > 0)
            motions.append(
                {
                    "name": c.name,
                    "kind": "motion" if moves else "support",
                    "displacement": d[:, j].tolist(),
                    "force": f[:, j].tolist(),
                    "travel": travel.tolist(),
                    "force_along": np.einsum("ij,ij->i", f[:, j], unit).tolist(),
                    "force_size": np.linalg.norm(f[:, j], axis=1).tolist(),
                }
            )
        normal, friction = np.stack(self.normal), np.stack(self.friction)
        interfaces = []
        for i, name in enumerate(self.interfaces):
            entry = {"name": name, "normal_force": normal[:, i].tolist()}
            if self.has_friction:
                entry["friction_force"] = friction[:, i].tolist()
            interfaces.append(entry)
        return {"load_factor": list(self.t), "motions": motions, "interfaces": interfaces}
