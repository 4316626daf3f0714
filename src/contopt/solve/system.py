"""The system the solver drives to equilibrium: a model's bulk and contact discretizations.

:class:`System` is built once per model and reused by every solve, adjoint and response of it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from contopt.assembly.model import Model
from contopt.assembly.system import Discretization, Evaluation, Layout, ModifiedTangent, discretize
from contopt.contact.laws import AugmentationOptions, AugmentedLagrangian
from contopt.contact.system import ContactDiscretization, discretize_contact
from contopt.errors import ConfigError
from contopt.solve.linear import Geometry
from contopt.solve.newton import DEFAULT_ADVICE

#: normalized penetration (of the facet size) beyond which Newton drops the contact-geometry
#: part of the tangent (see System.evaluate); converged penetrations are ~1e-2 (penalty) or less
DEEP_PENETRATION = 0.1
#: the rounded cone edges (Coulomb.edge) of the continuation that solves a failed frictional load step
#: again (measured: the friction clamp's failing trial designs converge with an edge of 0.1 or more)
EDGE_LADDER = (0.4, 0.2, 0.1)
#: with friction, Newton mostly fails where nodes change between stick and slip from one iteration
#: to the next; what is left to try once even the cone-edge continuation failed
FRICTION_ADVICE = (
    f"{DEFAULT_ADVICE}; with friction, where nodes change between stick and slip from one iteration to the "
    "next: a wider rounded cone edge (friction.edge = 0.1 to 0.15), a softer stick penalty (friction.eps, "
    "e.g. 10 E*/h) or newton.stall_rtol (docs/friction.md, limits)"
)


@dataclass(frozen=True, eq=False)
class System:
    """A model's bulk discretization ``disc`` and its contact discretization ``contact`` (None
    without interfaces)."""

    disc: Discretization
    contact: ContactDiscretization | None

    @property
    def has_contact(self) -> bool:
        return self._live_contact() is not None

    def _live_contact(self) -> ContactDiscretization | None:
        """``contact`` when there is some (not None and not empty), else None."""
        return self.contact if self.contact is not None and not self.contact.empty else None

    @property
    def model(self) -> Model:
        return self.disc.model

    @classmethod
    def of(cls, model: Model | Discretization | System) -> System:
        """The system of a Model (discretized now), of a Discretization, or a System itself."""
        if isinstance(model, System):
            return model
        if isinstance(model, Model):
            disc = discretize(model)
        elif isinstance(model, Discretization):
            disc = model
        else:
            raise ConfigError(f"expected a Model, a Discretization or a System, got {type(model).__name__}")
        if not disc.model.interfaces:
            return cls(disc=disc, contact=None)
        return cls(disc=disc, contact=discretize_contact(disc.model, disc))

    def geometry(self, u: np.ndarray | None = None) -> Geometry:
        """Where the free dofs sit at displacement ``u`` (n_dofs,) (None: the reference positions),
        for an iterative linear solver's rigid-body modes."""
        points = np.concatenate([b.mesh.points for b in self.model.bodies]).astype(np.float64)
        if u is not None:
            points += np.asarray(u).reshape(-1, 3)
        return Geometry(points=points, free=self.disc.free, comm=self.disc.comm, contact=bool(self.model.interfaces))

    def with_augmentation(self, options: AugmentationOptions | None) -> System:
        """The system with ``options`` replacing the options of every augmented-Lagrangian interface."""
        if options is None:
            return self

        def change(interface):
            law = interface.law
            if not isinstance(law, AugmentedLagrangian):
                return interface
            return replace(interface, law=law.with_options(options))

        return self._with_interfaces(change)

    def with_cone_edge(self, edge: float) -> System:
        """The system with every frictional interface's rounded cone edge at least ``edge``
        (:class:`contopt.contact.coulomb.Coulomb`): a smoother law, for a continuation."""

        def change(interface):
            friction = interface.friction
            if friction is None or friction.edge >= edge:
                return interface
            return replace(interface, friction=replace(friction, edge=edge))

        return self._with_interfaces(change)

    def _with_interfaces(self, change: Callable) -> System:
        """The system with ``change(interface)`` in place of every contact interface (unchanged
        blocks are kept as they are)."""
        contact = self._live_contact()
        if contact is None:
            return self
        blocks = []
        for b in contact.blocks:
            interface = change(b.interface)
            blocks.append(b if interface is b.interface else replace(b, interface=interface))
        return replace(self, contact=replace(contact, blocks=tuple(blocks)))

    @property
    def path_dependent(self) -> bool:
        """The laws make a state depend on the load path that led to it (friction: a slip is
        measured from the last load step): a solve records its load steps (:attr:`State.path`),
        starts from the undeformed bodies, and the adjoint runs back over the steps."""
        contact = self._live_contact()
        return contact is not None and contact.has_friction

    @property
    def symmetric(self) -> bool:
        """Is the tangent symmetric? Not with friction (its residual has no potential)."""
        return not self.path_dependent

    def smoothing_stages(self) -> tuple[System, ...]:
        """Smoother variants of this system to solve a failed load step through, smoothest first
        (empty when its laws offer none): with friction, the cone's rounded edge widened to each of
        :data:`EDGE_LADDER` above the interfaces' own (measured: the friction clamp's failing
        trial designs converge with an edge of 0.1 or more)."""
        contact = self._live_contact()
        if contact is None or not contact.has_friction:
            return ()
        own = min(b.friction.edge for b in contact.blocks if b.friction is not None)
        return tuple(self.with_cone_edge(edge) for edge in EDGE_LADDER if edge > own)

    def advice(self, advice: str) -> str:
        """What to try after a Newton failure whose advice is ``advice``, for this system's laws."""
        return FRICTION_ADVICE if self.path_dependent and advice == DEFAULT_ADVICE else advice

    def start_states(self, multipliers: tuple = (), eps: tuple = ()) -> tuple:
        """The contact laws' states at the start of a solve (empty without contact)."""
        contact = self._live_contact()
        return contact.start_states(multipliers, eps) if contact is not None else ()

    def admissible(self, u) -> str:
        """Why ``u`` cannot be a state of this system, or "" (see
        :meth:`contopt.contact.system.ContactDiscretization.too_deep`)."""
        contact = self._live_contact()
        return contact.too_deep(u) if contact is not None else ""

    def evaluate(
        self,
        u,
        t: float,
        layout: Layout,
        states: tuple,
        tangent: bool = True,
        touch: float = 0.0,
        full: bool = True,
        closed: tuple | None = None,
    ) -> Evaluation:
        """Bulk + contact residual, potential and tangent at load factor t with the laws' states.

        Where some node penetrates deeper than :data:`DEEP_PENETRATION` facet
        sizes (a transient of the first iterations after contact starts, never
        an equilibrium of a sensible eps), the evaluation also offers the tangent
        without the second derivatives of the mortar integrals: weighted by the
        spurious pressures of such a state they are large and indefinite. On
        the fine die-slab with a die exactly as wide as the slab the exact step
        then needed line-search factors of 1/16..1/256 and the first load step
        failed in 25 iterations; with the modified tangent it converged in 10,
        quadratically once shallow.

        ``touch`` (a length): contact nodes closer than this count as closed in
        the tangent (the residual is unchanged); the solver passes the size of
        a load step's prescribed increment to the step's first evaluation. ``closed`` (per interface,
        (n_nodes,) bool): contact nodes that count as closed in the tangent whatever their gap (the
        active-set prediction, :mod:`contopt.solve.activeset`).
        ``full``: the evaluation holds the whole tangent too (:class:`Evaluation`); the solver and the
        adjoint need its free blocks only and say ``full=False``.
        """
        ev = self.disc.evaluate(u, t, layout.rho, tangent, mass=layout.mass, full=full)
        contact = self._live_contact()
        if contact is None:
            return ev
        ec = contact.evaluate(u, states, tangent, touch, closed)
        ev.timings.contact += ec.seconds
        terms, K_free, K_fc, modified = ev.K_terms, ev.K_free, ev.K_fc, None
        # every rank evaluates the contact (replicated), rank 0 alone adds its tangent to its part
        if tangent and self.disc.comm.rank == 0:
            K_normal = ec.K_normal
            # evaluated with the tangent: the matrices are there
            assert ev.K_free is not None and ev.K_fc is not None and ec.K is not None and K_normal is not None
            free = self.disc.free
            rows = ec.K[free]
            terms = None if ev.K_terms is None else (*ev.K_terms, ec.K)
            K_free = (ev.K_free + rows[:, free]).tocsr()
            K_fc = (ev.K_fc + rows[:, self.disc.constrained]).tocsr()
            del rows
        if tangent and contact.penetration(ec.results) > DEEP_PENETRATION:
            assert ev.K_free is not None and ec.K_normal is not None
            rank0 = self.disc.comm.rank == 0
            modified = ModifiedTangent(K_bulk=ev.K_free, K_normal=ec.K_normal if rank0 else None, free=self.disc.free)
        energy = None if ev.energy is None or ec.energy is None else ev.energy + ec.energy
        return Evaluation(
            r=ev.r + ec.r,
            K_terms=terms,
            K_free=K_free,
            timings=ev.timings,
            energy=energy,
            contact=ec.results,
            modified=modified,
            reduce=ev.reduce,
            K_fc=K_fc,
        )
