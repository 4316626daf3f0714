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

from dataclasses import dataclass
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

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
    """

    system: System
    u: np.ndarray
    rho: np.ndarray
    lam: tuple
    t: float = 1.0
    mass: np.ndarray | None = None

    def __post_init__(self):
        if self.mass is None:
            object.__setattr__(self, "mass", np.ones_like(np.asarray(self.rho, dtype=np.float64)))

    @classmethod
    def from_state(cls, system: System, state: State) -> "Fields":
        """The fields of a :class:`contopt.solve.static.State` (pressures of its last evaluation)."""
        lam = tuple(np.asarray(res.lam, dtype=np.float64) for res in state.contact)
        rho = state.rho if state.rho is not None else np.ones(system.disc.n_cells)
        return cls(system=system, u=np.asarray(state.u), rho=np.asarray(rho), lam=lam, t=float(state.t),
                   mass=None if state.mass is None else np.asarray(state.mass))

    @property
    def disc(self):
        return self.system.disc


@dataclass(frozen=True, eq=False)
class Partials:
    """Partial derivatives of one response: ``u`` (n_dofs,), ``lam`` (per interface), ``rho`` and
    ``mass`` (n_cells,; mass: the explicit dependence through design-dependent volume loads)."""

    u: np.ndarray
    lam: tuple
    rho: np.ndarray
    mass: np.ndarray | None = None

    def __post_init__(self):
        if self.mass is None:
            object.__setattr__(self, "mass", np.zeros_like(np.asarray(self.rho, dtype=np.float64)))

    @classmethod
    def zeros(cls, fields: Fields) -> "Partials":
        return cls(u=np.zeros_like(fields.u), lam=tuple(np.zeros_like(v) for v in fields.lam),
                   rho=np.zeros_like(fields.rho))

    @classmethod
    def combine(cls, parts: list["Partials"], coefficients) -> "Partials":
        """``sum_k c_k parts[k]``."""
        first = parts[0]
        u, rho, mass = np.zeros_like(first.u), np.zeros_like(first.rho), np.zeros_like(first.rho)
        lam = [np.zeros_like(v) for v in first.lam]
        for c, p in zip(coefficients, parts):
            c = float(c)
            u += c * p.u
            rho += c * p.rho
            mass += c * p.mass
            for a, b in zip(lam, p.lam):
                a += c * b
        return Partials(u=u, lam=tuple(lam), rho=rho, mass=mass)


class Response:
    """Base class: subclasses implement :meth:`evaluate` and set ``name``."""

    name: str = "response"

    def evaluate(self, fields: Fields, gradient: bool = True) -> tuple[float, Partials | None]:
        """Value and (with ``gradient``) the partial derivatives at ``fields``."""
        raise NotImplementedError

    def value(self, fields: Fields) -> float:
        return self.evaluate(fields, gradient=False)[0]

    # ---- algebra: every combination is a Combination with exact partials
    def __neg__(self) -> "Response":
        return Combination((self,), _negate, name=f"-{self.name}")

    def __mul__(self, c) -> "Response":
        c = float(c)
        return Combination((self,), _Scale(c), name=f"{c:g}*{self.name}")

    __rmul__ = __mul__

    def __add__(self, other: "Response") -> "Response":
        if not isinstance(other, Response):
            return NotImplemented
        return Combination((self, other), _add, name=f"{self.name}+{other.name}")

    def __sub__(self, other: "Response") -> "Response":
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
        if not parts or not all(isinstance(p, Response) for p in parts):
            raise TypeError("Combination parts must be a non-empty tuple of Response objects")
        self.parts = tuple(parts)
        self.combine = combine
        self.name = name

    def evaluate(self, fields: Fields, gradient: bool = True):
        results = [p.evaluate(fields, gradient) for p in self.parts]
        values = jnp.asarray([v for v, _ in results], dtype=jnp.float64)
        value = float(self.combine(values))
        if not gradient:
            return value, None
        weights = np.asarray(jax.grad(lambda v: self.combine(v))(values))
        parts = [pt for _, pt in results]
        return value, Partials.combine(parts, weights)

    def __repr__(self) -> str:
        return f"Combination({self.name!r})"
