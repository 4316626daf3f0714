"""What a response sees of a solved state, what it returns, and how responses combine.

A response is a scalar ``theta(u, lam, rho)`` of a converged state: the
displacements ``u`` (n_dofs,), the contact pressures ``lam`` (one array per
interface over its nonmortar nodes) and the per-cell material field ``rho``
(n_cells,). Besides its value it returns the partial derivatives
(:class:`Partials`) with the other two held fixed; the adjoint
(:mod:`contopt.adjoint`) turns them into the total derivative ``dtheta/drho``.

Responses combine: ``-r``, ``2.0 * r``, ``r1 + r2`` and
:class:`Combination` (any JAX-traceable function of several responses'
values, e.g. a ratio) are responses with exact partials by the chain rule.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from contopt.errors import ConfigError
from contopt.solve.static import State
from contopt.solve.system import System


@dataclass(frozen=True, eq=False)
class Fields:
    """A solved state as the responses see it.

    Attributes
    ----------
    system : the :class:`contopt.solve.system.System` that was solved
    u : (n_dofs,) displacements
    rho : (n_cells,) material field (stiffness factor per cell, stacked over bodies)
    lam : per interface, (n_nonmortar_nodes,) contact pressures (>= 0)
    t : load factor of the state (external loads are ``t * disc.f_ext(mass)``)
    mass : (n_cells,) material share per cell scaling the volume loads (ones when the state had none)
    traction : per interface, (n_nonmortar_nodes, 3) friction tractions (zeros without friction;
        empty when not given)
    laws : per interface, the contact laws' states of the state's last solve (multipliers,
        penalties: what the interface's forces are evaluated with; empty when not given)
    path : the :class:`State` of every recorded load step (:attr:`State.path`, the last one at
        this state's load factor; empty when not recorded): what a load-path response reads
    """

    system: System
    u: np.ndarray
    rho: np.ndarray
    lam: tuple
    t: float = 1.0
    mass: np.ndarray | None = None
    traction: tuple = ()
    laws: tuple = ()
    path: tuple = ()

    def __post_init__(self):
        """Checks every array against the system (ConfigError: another model's state) and converts
        them to float64 (float32 input is converted here, never mixed into the partials)."""
        if not isinstance(self.system, System):
            raise ConfigError(
                f"Fields.system must be the System that was solved (System.of(model)), got {type(self.system).__name__}"
            )
        disc = self.system.disc
        contact = self.system.contact
        blocks = contact.blocks if contact is not None and self.system.has_contact else ()
        lam = tuple(self.lam) if isinstance(self.lam, (tuple, list)) else None
        if lam is None or len(lam) != len(blocks):
            raise ConfigError(
                f"Fields.lam must hold one pressure array per contact interface of the system "
                f"({len(blocks)}), got {_describe(self.lam)}"
            )
        mass = np.ones(disc.n_cells) if self.mass is None else self.mass
        for name, value, n, what in (
            ("u", self.u, disc.n_dofs, "dofs"),
            ("rho", self.rho, disc.n_cells, "cells"),
            ("mass", mass, disc.n_cells, "cells"),
        ):
            object.__setattr__(self, name, _checked(value, n, f"Fields.{name}", what))
        object.__setattr__(
            self,
            "lam",
            tuple(
                _checked(v, b.n_nodes, f"Fields.lam[{i}]", "nonmortar nodes")
                for i, (v, b) in enumerate(zip(lam, blocks))
            ),
        )
        object.__setattr__(self, "t", float(self.t))

    @classmethod
    def from_state(cls, system: System, state: State) -> Fields:
        """The fields of a :class:`contopt.solve.static.State` (pressures of its last evaluation)."""
        if not isinstance(state, State):
            raise ConfigError(
                f"Fields.from_state needs the State that solve_static returned, got {type(state).__name__}"
            )
        system = System.of(system)
        lam = tuple(np.asarray(res.lam, dtype=np.float64) for res in state.contact)
        rho = state.rho if state.rho is not None else np.ones(system.disc.n_cells)
        return cls(
            system=system,
            u=np.asarray(state.u),
            rho=np.asarray(rho),
            lam=lam,
            t=float(state.t),
            mass=None if state.mass is None else np.asarray(state.mass),
            traction=tuple(np.asarray(res.traction, dtype=np.float64) for res in state.contact),
            laws=tuple(state.laws),
            path=tuple(state.path),
        )

    @property
    def disc(self):
        return self.system.disc


def _describe(value) -> str:
    return f"{len(value)} arrays" if isinstance(value, (tuple, list)) else type(value).__name__


def _checked(value, n: int, name: str, what: str) -> np.ndarray:
    """``value`` as a float64 (n,) array; ConfigError when it has another shape (another model's state)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ConfigError(f"{name} must be an array of numbers, got {type(value).__name__}") from err
    if arr.shape != (n,):
        raise ConfigError(
            f"{name} has shape {arr.shape} but the system has {n} {what}: it belongs to another "
            "model (use the System the state was solved with)"
        )
    return arr


def as_fields(fields, who: str) -> Fields:
    """``fields`` if it is a :class:`Fields`, else ConfigError naming the response ``who``."""
    if not isinstance(fields, Fields):
        hint = " (Fields.from_state(system, state))" if isinstance(fields, State) else ""
        raise ConfigError(f"response {who!r} is evaluated on Fields{hint}, got {type(fields).__name__}")
    return fields


@dataclass(frozen=True, eq=False, init=False)
class Partials:
    """Partial derivatives of one response: ``u`` (n_dofs,), ``lam`` (per interface), ``rho`` and
    ``mass`` (n_cells,; mass: the explicit dependence through design-dependent volume loads; zeros
    when not given), ``traction`` (per interface (n, 3): the friction tractions of the state, a
    history the path adjoint runs back through; empty when the response does not depend on them)."""

    u: np.ndarray
    lam: tuple
    rho: np.ndarray
    mass: np.ndarray
    traction: tuple

    # written out (not the dataclass's) because mass may be left out: the attribute is always an array
    def __init__(
        self, u: np.ndarray, lam: tuple, rho: np.ndarray, mass: np.ndarray | None = None, traction: tuple = ()
    ) -> None:
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "lam", lam)
        object.__setattr__(self, "rho", rho)
        object.__setattr__(self, "mass", np.zeros_like(np.asarray(rho, dtype=np.float64)) if mass is None else mass)
        object.__setattr__(self, "traction", tuple(traction))

    @classmethod
    def zeros(cls, fields: Fields) -> Partials:
        return cls(
            u=np.zeros_like(fields.u), lam=tuple(np.zeros_like(v) for v in fields.lam), rho=np.zeros_like(fields.rho)
        )

    @classmethod
    def combine(cls, parts: list[Partials], coefficients) -> Partials:
        """``sum_k c_k parts[k]``."""
        first = parts[0]
        u, rho, mass = np.zeros_like(first.u), np.zeros_like(first.rho), np.zeros_like(first.rho)
        lam = [np.zeros_like(v) for v in first.lam]
        shapes = next((p.traction for p in parts if p.traction), ())
        traction = [np.zeros_like(v) for v in shapes]
        for c, p in zip(coefficients, parts):
            c = float(c)
            u += c * p.u
            rho += c * p.rho
            mass += c * p.mass
            for a, b in zip(lam, p.lam):
                a += c * b
            for a, b in zip(traction, p.traction):
                a += c * b
        return Partials(u=u, lam=tuple(lam), rho=rho, mass=mass, traction=tuple(traction))


class Response:
    """Base class: subclasses implement :meth:`evaluate` and set ``name``."""

    name: str = "response"

    def evaluate(self, fields: Fields, gradient: bool = True) -> tuple[float, Partials | None]:
        """Value and (with ``gradient``) the partial derivatives at ``fields``."""
        raise NotImplementedError

    def value(self, fields: Fields) -> float:
        return self.evaluate(as_fields(fields, self.name), gradient=False)[0]

    def evaluate_path(self, fields: Fields, gradient: bool = True) -> tuple[float, dict]:
        """Value and (with ``gradient``) the partial derivatives per load step it reads: ``{k:
        Partials}`` with ``k`` an index into ``fields.path``, or None for the state ``fields`` itself
        (a response of one state, this default). Load-path responses (:mod:`contopt.responses.path`)
        read several steps; the adjoint then runs back over the path."""
        value, partials = self.evaluate(fields, gradient)
        return value, ({None: partials} if gradient else {})

    #: load factors at which the solve must end a load step for this response (a load-path response's)
    stops: tuple = ()

    def check(self, system: System) -> None:
        """ConfigError when this response cannot be evaluated on ``system`` (an unknown body, a contact
        response on a model without contact); called before any analysis. Nothing to check here."""

    # ---- algebra: every combination is a Combination with exact partials
    def __neg__(self) -> Response:
        return Combination((self,), _negate, name=f"-{self.name}")

    def __mul__(self, c) -> Response:
        c = float(c)
        return Combination((self,), _Scale(c), name=f"{c:g}*{self.name}")

    __rmul__ = __mul__

    def __add__(self, other: Response) -> Response:
        if not isinstance(other, Response):
            return NotImplemented
        return Combination((self, other), _add, name=f"{self.name}+{other.name}")

    def __sub__(self, other: Response) -> Response:
        return self + (-other)


def _negate(v):
    return -v[0]


def _add(v):
    return v[0] + v[1]


@dataclass(frozen=True)
class _Scale:
    c: float

    def __call__(self, v):
        return self.c * v[0]


class Combination(Response):
    """``combine(values of parts)`` with ``combine`` a JAX-traceable function of a (k,) array.

    Example: the normalized objective ``f / |f0|`` is ``Combination((f,), lambda v: v[0] / abs(f0))``.
    """

    def __init__(self, parts: tuple, combine: Callable, name: str = "combination"):
        if not isinstance(parts, (tuple, list)) or not parts or not all(isinstance(p, Response) for p in parts):
            raise ConfigError(f"Combination parts must be a non-empty tuple of Response objects, got {parts!r}")
        if not callable(combine):
            raise ConfigError(f"Combination.combine must be a function of the parts' values, got {combine!r}")
        self.parts = tuple(parts)
        self.combine = combine
        self.name = name

    def check(self, system: System) -> None:
        for p in self.parts:
            p.check(system)

    @property
    def stops(self) -> tuple:  # type: ignore[override]
        return tuple(sorted({s for p in self.parts for s in p.stops}))

    def evaluate_path(self, fields: Fields, gradient: bool = True):
        if not self.stops:
            return super().evaluate_path(fields, gradient)
        fields = as_fields(fields, self.name)
        self.check(fields.system)
        results = [p.evaluate_path(fields, gradient) for p in self.parts]
        values = jnp.asarray([v for v, _ in results], dtype=jnp.float64)
        value = float(self.combine(values))
        if not gradient:
            return value, {}
        weights = np.asarray(jax.grad(lambda v: self.combine(v))(values))
        keys = {k for _, parts in results for k in parts}
        zero = Partials.zeros(fields)
        merged = {k: Partials.combine([parts.get(k, zero) for _, parts in results], weights) for k in keys}
        return value, merged

    def evaluate(self, fields: Fields, gradient: bool = True):
        fields = as_fields(fields, self.name)
        self.check(fields.system)
        results = [p.evaluate(fields, gradient) for p in self.parts]
        values = jnp.asarray([v for v, _ in results], dtype=jnp.float64)
        value = float(self.combine(values))
        weights = np.asarray(jax.grad(lambda v: self.combine(v))(values)) if gradient else np.zeros(0)
        if not (np.isfinite(value) and np.all(np.isfinite(weights))):
            shown = ", ".join(f"{p.name} = {float(v):.6g}" for p, v in zip(self.parts, values))
            raise ConfigError(
                f"response {self.name!r} is undefined at this state ({shown}){self.undefined_hint}; "
                "choose a response that is defined there, or change the model so that it is"
            )
        if not gradient:
            return value, None
        parts = [pt for _, pt in results]
        return value, Partials.combine(parts, weights)

    #: what an undefined value usually means, for the error (subclasses say it for their parts)
    undefined_hint = ""

    def __repr__(self) -> str:
        return f"Combination({self.name!r})"
