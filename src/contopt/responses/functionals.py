"""General functionals (paper eq. 14) and the built-in responses (eqs. 41-44).

    theta = sum over bodies ∫ pi(u, grad u, rho) dV  +  ∫_gamma zeta(lam) da

``pi`` is integrated with the cells' 2x2x2 Gauss rule in the reference
configuration. ``zeta`` is integrated where the surfaces touch, by one of three quadratures:

* ``"overlap"`` (default): ``sum_A zeta(lam_A) a_A`` with the mortar overlap areas
  ``a_A = ∫_overlap N_A da`` that the contact evaluation itself uses (over the part of the
  deformed nonmortar surface that the mortar surface covers). For ``zeta(lam) = lam`` this is
  the normal force the bodies exchange: on a flat interface it equals the reaction exactly,
  also where the nonmortar surface is only partly covered.
* ``"gauss"``: the paper's appendix A reading, over the whole deformed nonmortar facets with the
  pressure interpolated bilinearly from the nodal pressures (``lam = M Lambda_f``, area element
  ``s = |x_xi1 ^ x_xi2|``, 2x2 Gauss per facet). On a partly covered nonmortar surface this
  counts the pressure of a boundary node over the uncovered part of its facets too: a small
  block standing inside a larger face read 2.9 to 56 times the load it transmits.
* ``"nodal"``: ``sum_A zeta(lam_A) A_A`` with the whole nodal areas ``A_A = ∫ N_A da``.

On tet10 faces ``"gauss"`` and ``"nodal"`` integrate on the tri6 parents' curved surface with the
multipliers' field ``sum_A lam_A W_A`` (and ``A_A = ∫ W_A da``): :mod:`contopt.responses.surface`.

The partial derivatives come from JAX (and, for the overlap areas, from the mortar kernels'
exact Jacobians); the dependence on the deformed geometry (the paper's ``zeta div_gamma``
term) is included. The segmentation topology is held fixed, as in the adjoint.

Built in:

* :class:`StrainEnergy`: ``∫ W* dV``, the stored energy of the (SIMP-scaled)
  material, F-bar as in the analysis; the paper's ``f_a`` is its negative.
* :class:`Compliance`: ``t f_ext . u`` (eq. 42; body forces and tractions do
  not depend on the design here).
* :class:`ContactForce`: ``∫ lam da`` over the overlap (the force the bodies exchange); the
  paper's ``f_c`` is its negative (its eq. 43 reading: ``quadrature="gauss"``).
* :class:`PressureVariance`: overlap-area-weighted variance of the nodal pressures
  over the active contact area (nodes with ``lam > 0``); ``normalized=True``
  divides by the squared mean (a dimensionless uniformity measure).
* :class:`VolumeFraction`: ``∫ rho dV / |Omega|`` of the field it is given
  (eq. 44: the design layer passes the volume fraction ``nu``, not the
  stiffness factor).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from functools import cache

import jax
import jax.numpy as jnp
import numpy as np

from contopt.errors import ConfigError
from contopt.fem.element import element_energy
from contopt.responses.base import Combination, Fields, Partials, Response, as_fields
from contopt.responses.catalog import QUADRATURES
from contopt.responses.cells import bulk_integral
from contopt.responses.exchanged import checked_direction, resultant
from contopt.responses.surface import surface_integral


# ------------------------------------------------------------------ bulk integrals
@cache
def energy_integrand(energy, use_fbar: bool) -> Callable:
    """Cell integrand ``W_e`` of a body's material (one object per material, so jit caches it)."""

    def integrand(u, X, grad, wdet, rho, N, params):
        return element_energy(u, grad, wdet, rho, params, energy, use_fbar)

    return integrand


@cache
def pointwise_integrand(pi: Callable) -> Callable:
    """Cell integrand ``sum_q wdet_q pi(u_q, grad u_q, rho[, X_q])`` of a quadrature-point density."""
    with_x = _n_positional(pi) >= 4

    def integrand(u, X, grad, wdet, rho, N, params):
        uq, Xq = N @ u, N @ X  # (q, 3)
        G = jnp.einsum("ai,qaJ->qiJ", u, grad)  # du_i/dX_J
        point = (lambda a, b, c: pi(a, b, rho, c)) if with_x else (lambda a, b, c: pi(a, b, rho))
        return jnp.dot(wdet, jax.vmap(point)(uq, G, Xq))

    return integrand


def _n_positional(fn: Callable) -> int:
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return 3
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    if any(p.kind == inspect.Parameter.VAR_POSITIONAL for p in params):
        return 4
    return sum(1 for p in params if p.kind in kinds)


# ------------------------------------------------------------------ selections
def selected_bodies(disc, bodies) -> list[int]:
    """Indices of the bodies named ``bodies`` (None: all); ConfigError naming an unknown one."""
    if bodies is None:
        return list(range(len(disc.blocks)))
    names = [b.name for b in disc.blocks]
    out = []
    for name in bodies:
        if name not in names:
            raise ConfigError(f"response body {name!r} is not a body of the model; bodies: {names}")
        out.append(names.index(name))
    return out


def _interface_indices(system, interfaces) -> list[int]:
    """The positions of the interfaces named ``interfaces`` (their ``ContactInterface.name``; None: all)."""
    if not system.has_contact:
        if interfaces:
            raise ConfigError("the response names contact interfaces but the model has none")
        return []
    blocks = system.contact.blocks
    if interfaces is None:
        return list(range(len(blocks)))
    names = [b.interface.name for b in blocks]
    out = []
    for key in interfaces:
        if key not in names or not isinstance(key, str):
            hint = "; interfaces are named, not numbered" if isinstance(key, (int, np.integer)) else ""
            raise ConfigError(f"response interface {key!r} not found{hint}; the model's interfaces: {names}")
        out.append(names.index(key))
    return out


def as_names(v):
    """A response's selection as a tuple (a single name or index as a 1-tuple; None stays None)."""
    if v is None:
        return None
    return (v,) if isinstance(v, (str, int)) else tuple(v)


# ------------------------------------------------------------------ responses
class Functional(Response):
    """``sum_bodies ∫ pi dV + ∫_gamma zeta da`` (paper eq. 14) from plain JAX-traceable functions.

    Parameters
    ----------
    pi : ``pi(u, grad_u, rho)`` or ``pi(u, grad_u, rho, X)`` -> scalar density per reference
        volume at a quadrature point: u (3,), grad_u (3, 3) = du_i/dX_J, rho scalar, X (3,)
    zeta : ``zeta(lam)`` -> scalar density per deformed area where the surfaces touch (lam: scalar
        pressure)
    bodies : names of the bodies ``pi`` is integrated over (default: all)
    interfaces : names of the interfaces ``zeta`` is integrated over (``ContactInterface.name``; default: all)
    quadrature : ``"overlap"`` (default; the mortar overlap areas), ``"gauss"`` (the paper's
        appendix A: whole nonmortar facets, 2x2 Gauss, pressure interpolated) or ``"nodal"``
        (whole nodal areas); see the module docstring
    """

    def __init__(
        self,
        pi: Callable | None = None,
        zeta: Callable | None = None,
        bodies=None,
        interfaces=None,
        quadrature: str = "overlap",
        name: str = "functional",
    ):
        if pi is None and zeta is None and not self._has_own_bulk():
            raise ConfigError("a Functional needs pi (volume density) or zeta (surface density)")
        for key, f in (("pi", pi), ("zeta", zeta)):
            if f is not None and not callable(f):
                raise ConfigError(f"Functional.{key} must be a function, got {f!r}")
        if quadrature not in QUADRATURES:
            raise ConfigError(f"Functional.quadrature must be one of {QUADRATURES}, got {quadrature!r}")
        self.pi, self.zeta, self.quadrature, self.name = pi, zeta, quadrature, name
        self.bodies, self.interfaces = as_names(bodies), as_names(interfaces)

    def _has_own_bulk(self) -> bool:
        return False

    def _integrand(self, block) -> Callable:
        return pointwise_integrand(self.pi)

    def _bulk(self) -> bool:
        return self.pi is not None or self._has_own_bulk()

    def check(self, system) -> None:
        """Unknown bodies or interfaces, and a response only over contact (``zeta`` alone, e.g.
        :class:`ContactForce`) on a model without contact, are ConfigErrors (it would be 0 silently)."""
        selected_bodies(system.disc, self.bodies)
        if self.zeta is None:
            return
        _interface_indices(system, self.interfaces)
        if not self._bulk() and not system.has_contact:
            raise ConfigError(
                f"response {self.name!r} integrates over contact interfaces, but the model has none; "
                "add a contact interface or choose another response"
            )

    def evaluate(self, fields: Fields, gradient: bool = True):
        fields = as_fields(fields, self.name)
        self.check(fields.system)
        partials = Partials.zeros(fields) if gradient else None
        value = 0.0
        if self._bulk():
            value += bulk_integral(
                fields, selected_bodies(fields.disc, self.bodies), self._integrand, gradient, partials
            )
        if self.zeta is not None:
            value += surface_integral(
                fields,
                _interface_indices(fields.system, self.interfaces),
                self.zeta,
                self.quadrature,
                gradient,
                partials,
            )
        return value, partials

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


class StrainEnergy(Functional):
    """``∫ W* dV`` over the bodies (default all): the stored energy, F-bar as in the analysis."""

    def __init__(self, bodies=None, name: str = "strain_energy"):
        super().__init__(bodies=bodies, name=name)

    def _has_own_bulk(self) -> bool:
        return True

    def _integrand(self, block) -> Callable:
        return energy_integrand(block.energy, block.fbar)


def _identity(lam):
    return lam


def _square(lam):
    return lam * lam


def _active(lam):
    return jnp.where(lam > 0.0, 1.0, 0.0)


class ContactForce(Functional):
    """``∫ lam da`` where the surfaces touch: the normal force the bodies exchange (paper eq. 43,
    sign +). ``quadrature="overlap"`` (default) integrates over the mortar overlap, so on a flat
    interface it equals the reaction also when the nonmortar surface is partly covered;
    ``"gauss"`` is the paper's appendix A reading over the whole nonmortar facets.

    ``direction`` ([x, y, z] or ``"norm"``): instead, the resultant of the interface's residual
    forces, ``|F . e|`` or ``|F|`` with F the force one body exerts on the other
    (:mod:`contopt.contact.force`): the reaction to Newton's tolerance wherever the interface is the
    only load path, also on curved or coarse surfaces where the pressure integral is not.
    """

    def __init__(self, interfaces=None, quadrature: str = "overlap", name: str = "contact_force", direction=None):
        super().__init__(zeta=_identity, interfaces=interfaces, quadrature=quadrature, name=name)
        self.direction = checked_direction(direction)

    def evaluate(self, fields: Fields, gradient: bool = True):
        if self.direction is None:
            return super().evaluate(fields, gradient)
        fields = as_fields(fields, self.name)
        self.check(fields.system)
        indices = _interface_indices(fields.system, self.interfaces)
        return resultant(fields, indices, self.direction, gradient, self.name)


class FrictionForce(Response):
    """``e . sum_A a_A t_A``: the friction force that the nonmortar body exerts on the mortar body
    (along the nonmortar's slip) in the direction ``e`` (normalized here), over the interfaces with
    friction (or those named). The holding force of a clamp: the force along the pull that friction
    transmits. It depends on the load path through the tractions (:mod:`contopt.adjoint.path`)."""

    name = "friction_force"

    def __init__(self, direction, interfaces=None, name: str = "friction_force"):
        e = np.asarray(direction, dtype=np.float64)
        if e.shape != (3,) or not np.all(np.isfinite(e)) or not np.linalg.norm(e) > 0:
            raise ConfigError(f"FrictionForce.direction must be a nonzero vector [x, y, z], got {direction!r}")
        self.direction, self.interfaces, self.name = e / np.linalg.norm(e), as_names(interfaces), name

    def _indices(self, system) -> list[int]:
        chosen = _interface_indices(system, self.interfaces)
        rough = [i for i in chosen if system.contact.blocks[i].friction is not None]
        if not rough:
            raise ConfigError(
                f"response {self.name!r} needs a contact interface with friction; the model's "
                f"{'chosen ' if self.interfaces else ''}interfaces have none (add friction = mu)"
            )
        return rough

    def check(self, system) -> None:
        self._indices(system)

    def evaluate(self, fields: Fields, gradient: bool = True):
        fields = as_fields(fields, self.name)
        system = fields.system
        indices = self._indices(system)
        if len(fields.traction) != len(fields.lam):
            raise ConfigError(f"response {self.name!r} needs the state's friction tractions (Fields.from_state)")
        contact = system.contact
        assert contact is not None  # _indices found an interface
        blocks = contact.blocks
        along = tuple(
            fields.traction[i] @ self.direction if i in indices else np.zeros(b.n_nodes) for i, b in enumerate(blocks)
        )
        areas, vjp = contact.overlap_areas(fields.u, along if gradient else None)
        value = float(sum(np.dot(areas[i], along[i]) for i in indices))
        if not gradient:
            return value, None
        traction = [np.zeros((b.n_nodes, 3)) for b in blocks]
        for i in indices:
            traction[i] = areas[i][:, None] * self.direction[None, :]
        assert vjp is not None  # asked for with gradient
        zero = Partials.zeros(fields)
        return value, Partials(u=vjp, lam=zero.lam, rho=zero.rho, traction=tuple(traction))


def _variance(v):
    area, first, second = v[0], v[1], v[2]
    mean = first / area
    return second / area - mean * mean


def _relative_variance(v):
    return _variance(v) / (v[1] / v[0]) ** 2


class PressureVariance(Combination):
    """Area-weighted variance of the nodal pressures over the active nodes (``lam > 0``).

    ``A = sum_active a_A``, ``mean = sum a_A lam_A / A``, ``var = sum a_A lam_A^2 / A - mean^2``
    with the overlap areas ``a_A``; ``normalized=True`` returns ``var / mean^2``. The active set
    is held fixed in the derivative (as in the adjoint); the areas follow the deformation.
    """

    def __init__(self, interfaces=None, normalized: bool = False, name: str | None = None):
        parts = tuple(
            Functional(zeta=z, interfaces=interfaces, quadrature="overlap", name=n)
            for z, n in ((_active, "active_area"), (_identity, "force"), (_square, "second_moment"))
        )
        super().__init__(
            parts,
            _relative_variance if normalized else _variance,
            name=name or ("pressure_relative_variance" if normalized else "pressure_variance"),
        )

    undefined_hint = ": no node is in contact (active area 0), the bodies do not touch"

    def check(self, system) -> None:
        if not system.has_contact:  # named as itself, not as one of its parts
            raise ConfigError(
                f"response {self.name!r} integrates over contact interfaces, but the model has none; "
                "add a contact interface or choose another response"
            )
        super().check(system)


class _Linear(Response):
    """``c . field`` with ``field`` the state's ``u`` or ``rho``: subclasses give ``c``."""

    field = "u"

    def __init__(self, bodies=None, name: str = ""):
        self.bodies, self.name = as_names(bodies), name or self.name

    def coefficients(self, fields: Fields) -> np.ndarray:
        raise NotImplementedError

    def check(self, system) -> None:
        if self.bodies is not None:
            selected_bodies(system.disc, self.bodies)

    def evaluate(self, fields: Fields, gradient: bool = True):
        fields = as_fields(fields, self.name)
        c = self.coefficients(fields)
        value = float(c @ getattr(fields, self.field))
        if not gradient:
            return value, None
        p = Partials.zeros(fields)
        getattr(p, self.field)[:] = c
        return value, p


class Compliance(_Linear):
    """``t f_ext(mass) . u`` (paper eq. 42): work of the body forces and tractions.

    Volume loads scale with the cells' material share ``mass`` (design-dependent
    inertia loads), so the compliance also has an explicit ``mass`` partial,
    ``t f_volume^T u``.
    """

    name = "compliance"

    def _mask(self, disc) -> np.ndarray | None:
        if self.bodies is None:
            return None
        mask = np.zeros(disc.n_dofs, bool)
        for i in selected_bodies(disc, self.bodies):
            mask[disc.body_slice(i)] = True
        return mask

    def coefficients(self, fields: Fields) -> np.ndarray:
        disc = fields.disc
        f = fields.t * disc.f_ext(fields.mass)
        mask = self._mask(disc)
        return f if mask is None else np.where(mask, f, 0.0)

    def evaluate(self, fields: Fields, gradient: bool = True):
        value, p = super().evaluate(fields, gradient)
        fields = as_fields(fields, self.name)
        disc = fields.disc
        if p is not None and disc.has_volume_loads:
            mask = self._mask(disc)
            u = fields.u if mask is None else np.where(mask, fields.u, 0.0)
            p.mass[:] = fields.t * (disc.f_volume.T @ u)
        return value, p


class VolumeFraction(_Linear):
    """``sum_e rho_e V_e / sum_e V_e`` over the bodies (eq. 44 with the volume-fraction field)."""

    name = "volume_fraction"
    field = "rho"

    def coefficients(self, fields: Fields) -> np.ndarray:
        disc = fields.disc
        weights = np.zeros(disc.n_cells)
        for i in selected_bodies(disc, self.bodies):
            b = disc.blocks[i]
            weights[b.cell_offset : b.cell_offset + b.n_cells] = b.volume
        return weights / weights.sum()


#: the classes of the built-in responses (:data:`contopt.responses.catalog.RESPONSES` says what each is)
BUILTIN = {
    "strain-energy": StrainEnergy,
    "compliance": Compliance,
    "contact-force": ContactForce,
    "friction-force": FrictionForce,
    "pressure-variance": PressureVariance,
    "volume-fraction": VolumeFraction,
}

# the stress response builds on this module's bulk integral, so it is registered from here, last
from contopt.responses.stress import Stress  # noqa: E402

BUILTIN["stress"] = Stress


def _path_responses() -> dict:
    # the load-path responses (built on ContactForce, which they import when built) by their names
    from contopt.responses.path import ForceMax, ForceMin, ForceTarget

    return {"force-target": ForceTarget, "force-max": ForceMax, "force-min": ForceMin}


def builtin(name: str, **kwargs) -> Response:
    """A built-in response by its CLI name (see :data:`BUILTIN`)."""
    if name not in BUILTIN:
        raise ConfigError(f"unknown response {name!r}; choose one of {sorted(BUILTIN)}")
    return BUILTIN[name](**kwargs)


BUILTIN.update(_path_responses())
