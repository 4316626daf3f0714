"""General functionals (paper eq. 14) and the built-in responses (eqs. 41-44).

    theta = sum over bodies ∫ pi(u, grad u, rho) dV  +  ∫_gamma zeta(lam) da

``pi`` is integrated with the cells' 2x2x2 Gauss rule in the reference
configuration; ``zeta`` over the deformed nonmortar surface of each
interface with the pressure interpolated bilinearly from the nodal
pressures (paper appendix A: ``lam = M Lambda_f``, area element
``s = |x_xi1 ^ x_xi2|``, 2x2 Gauss on each facet), or with ``quadrature="nodal"``
as ``sum_A zeta(lam_A) a_A`` with the nodal areas ``a_A = ∫ N_A da``. The
partial derivatives come from JAX; the dependence of the surface integral
on the deformed geometry (the paper's ``zeta div_gamma`` term) is included.

Built in:

* :class:`StrainEnergy`: ``∫ W* dV``, the stored energy of the (SIMP-scaled)
  material, F-bar as in the analysis; the paper's ``f_a`` is its negative.
* :class:`Compliance`: ``t f_ext . u`` (eq. 42; body forces and tractions do
  not depend on the design here).
* :class:`ContactForce`: ``∫_gamma lam da``; the paper's ``f_c`` is its negative.
* :class:`PressureVariance`: area-weighted variance of the nodal pressures
  over the active contact area (nodes with ``lam > 0``); ``normalized=True``
  divides by the squared mean (a dimensionless uniformity measure).
* :class:`VolumeFraction`: ``∫ rho dV / |Omega|`` of the field it is given
  (eq. 44: the design layer passes the volume fraction ``nu``, not the
  stiffness factor).
"""

from __future__ import annotations

import inspect
from functools import lru_cache, partial
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from contopt.assembly.kernels import DEFAULT_CHUNK, _run_chunked
from contopt.errors import ConfigError
from contopt.fem.element import element_energy
from contopt.fem.hex8 import quad_gauss
from contopt.responses.base import Combination, Fields, Partials, Response


# ------------------------------------------------------------------ bulk integrals
@lru_cache(maxsize=None)
def energy_integrand(energy, use_fbar: bool) -> Callable:
    """Cell integrand ``W_e`` of a body's material (one object per material, so jit caches it)."""

    def integrand(u, X, grad, wdet, rho, N, params):
        return element_energy(u, grad, wdet, rho, params, energy, use_fbar)

    return integrand


@lru_cache(maxsize=None)
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


@partial(jax.jit, static_argnames=("integrand", "gradient"))
def _bulk_batch(u, X, grad, wdet, rho, N, params, integrand, gradient):
    if not gradient:
        return jax.vmap(integrand, in_axes=(0, 0, 0, 0, 0, None, None))(u, X, grad, wdet, rho, N, params)
    f = jax.value_and_grad(integrand, argnums=(0, 4))
    value, (du, drho) = jax.vmap(f, in_axes=(0, 0, 0, 0, 0, None, None))(u, X, grad, wdet, rho, N, params)
    return value, du, drho


def bulk_integral(fields: Fields, body_indices, integrand_for: Callable, gradient: bool, partials: Partials | None):
    """``sum_cells integrand`` over the bodies; adds its partials into ``partials`` (in place)."""
    disc = fields.disc
    total = 0.0
    for i in body_indices:
        b = disc.blocks[i]
        cells = disc.model.bodies[i].mesh.cells
        X = disc.model.bodies[i].mesh.points[cells]
        rho = fields.rho[b.cell_offset:b.cell_offset + b.n_cells]
        fn = partial(_bulk_batch, integrand=integrand_for(b), gradient=gradient)
        shapes = [(), (8, 3), ()] if gradient else [()]
        outs = _run_chunked(fn, b.n_cells, DEFAULT_CHUNK, (fields.u[b.dofs].reshape(-1, 8, 3), X,
                            b.geometry.grad, b.geometry.wdet, rho),
                            (jnp.asarray(b.geometry.N), jnp.asarray(b.params)), shapes)
        total += float(outs[0].sum())
        if gradient:
            partials.u[:] += np.bincount(b.dofs.ravel(), weights=outs[1].reshape(-1), minlength=disc.n_dofs)
            partials.rho[b.cell_offset:b.cell_offset + b.n_cells] += outs[2]
    return total


# --------------------------------------------------------------- surface integrals
_NQ, _DNQ, _WQ = quad_gauss(2)  # facet Gauss points: N (q, 4), dN (q, 4, 2), weights (q,)


def _facet_integral(x, lam, zeta, nodal):
    """One bilinear facet: x (4, 3) deformed nodes, lam (4,) nodal pressures."""
    tang = jnp.einsum("ai,qak->qki", x, _DNQ)  # (q, 2, 3)
    s = jnp.linalg.norm(jnp.cross(tang[:, 0], tang[:, 1]), axis=-1)  # (q,)
    if nodal:
        areas = jnp.einsum("q,qa,q->a", _WQ, _NQ, s)  # this facet's share of ∫ N_A da
        return jnp.dot(areas, jax.vmap(zeta)(lam))
    return jnp.dot(_WQ * s, jax.vmap(zeta)(_NQ @ lam))


@partial(jax.jit, static_argnames=("zeta", "nodal", "gradient"))
def _surface_batch(x, lam, zeta, nodal, gradient):
    f = partial(_facet_integral, zeta=zeta, nodal=nodal)
    if not gradient:
        return jax.vmap(f)(x, lam)
    value, (dx, dlam) = jax.vmap(jax.value_and_grad(f, argnums=(0, 1)))(x, lam)
    return value, dx, dlam


def surface_integral(fields: Fields, interface_indices, zeta: Callable, nodal: bool, gradient: bool,
                     partials: Partials | None) -> float:
    """``∫_gamma zeta(lam) da`` over the deformed nonmortar surfaces; adds partials in place."""
    contact = fields.problem.contact
    total = 0.0
    if contact is None:
        return total
    x_all = contact.X + fields.u.reshape(-1, 3)
    for i in interface_indices:
        block = contact.blocks[i]
        x = jnp.asarray(x_all[block.nm_facet_nodes])
        lam = jnp.asarray(fields.lam[i][block.nm_local])
        out = _surface_batch(x, lam, zeta, nodal, gradient)
        if not gradient:
            total += float(np.asarray(out).sum())
            continue
        value, dx, dlam = (np.asarray(o) for o in out)
        total += float(value.sum())
        dofs = 3 * block.nm_facet_nodes[:, :, None] + np.arange(3)
        partials.u[:] += np.bincount(dofs.ravel(), weights=dx.ravel(), minlength=partials.u.size)
        partials.lam[i][:] += np.bincount(block.nm_local.ravel(), weights=dlam.ravel(),
                                          minlength=block.n_nodes)
    return total


# ------------------------------------------------------------------ selections
def _body_indices(disc, bodies) -> list[int]:
    if bodies is None:
        return list(range(len(disc.blocks)))
    names = [b.name for b in disc.blocks]
    out = []
    for name in bodies:
        if name not in names:
            raise ConfigError(f"response body {name!r} is not a body of the model; bodies: {names}")
        out.append(names.index(name))
    return out


def _interface_indices(problem, interfaces) -> list[int]:
    if problem.contact is None or problem.contact.empty:
        if interfaces:
            raise ConfigError("the response names contact interfaces but the model has none")
        return []
    blocks = problem.contact.blocks
    if interfaces is None:
        return list(range(len(blocks)))
    labels = [b.interface.label for b in blocks]
    out = []
    for key in interfaces:
        if isinstance(key, (int, np.integer)) and 0 <= key < len(blocks):
            out.append(int(key))
        elif key in labels:
            out.append(labels.index(key))
        else:
            raise ConfigError(f"response interface {key!r} not found; interfaces are 0..{len(blocks) - 1} "
                              f"or by label {labels}")
    return out


def _as_tuple(v):
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
    zeta : ``zeta(lam)`` -> scalar density per deformed nonmortar area (lam: scalar pressure)
    bodies : names of the bodies ``pi`` is integrated over (default: all)
    interfaces : indices or labels of the interfaces ``zeta`` is integrated over (default: all)
    quadrature : ``"gauss"`` (2x2 per facet, pressure interpolated) or ``"nodal"``
    """

    def __init__(self, pi: Callable | None = None, zeta: Callable | None = None, bodies=None, interfaces=None,
                 quadrature: str = "gauss", name: str = "functional"):
        if pi is None and zeta is None and not self._has_own_bulk():
            raise ConfigError("a Functional needs pi (volume density) or zeta (surface density)")
        for key, f in (("pi", pi), ("zeta", zeta)):
            if f is not None and not callable(f):
                raise ConfigError(f"Functional.{key} must be a function, got {f!r}")
        if quadrature not in ("gauss", "nodal"):
            raise ConfigError(f"Functional.quadrature must be 'gauss' or 'nodal', got {quadrature!r}")
        self.pi, self.zeta, self.quadrature, self.name = pi, zeta, quadrature, name
        self.bodies, self.interfaces = _as_tuple(bodies), _as_tuple(interfaces)

    def _has_own_bulk(self) -> bool:
        return False

    def _integrand(self, block) -> Callable:
        return pointwise_integrand(self.pi)

    def _bulk(self) -> bool:
        return self.pi is not None or self._has_own_bulk()

    def evaluate(self, fields: Fields, gradient: bool = True):
        partials = Partials.zeros(fields) if gradient else None
        value = 0.0
        if self._bulk():
            value += bulk_integral(fields, _body_indices(fields.disc, self.bodies), self._integrand, gradient,
                                   partials)
        if self.zeta is not None:
            value += surface_integral(fields, _interface_indices(fields.problem, self.interfaces), self.zeta,
                                      self.quadrature == "nodal", gradient, partials)
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
    """``∫_gamma lam da`` over the deformed nonmortar surfaces (paper eq. 43 / appendix A, sign +)."""

    def __init__(self, interfaces=None, name: str = "contact_force"):
        super().__init__(zeta=_identity, interfaces=interfaces, name=name)


def _variance(v):
    area, first, second = v[0], v[1], v[2]
    mean = first / area
    return second / area - mean * mean


def _relative_variance(v):
    return _variance(v) / (v[1] / v[0]) ** 2


class PressureVariance(Combination):
    """Area-weighted variance of the nodal pressures over the active nodes (``lam > 0``).

    ``A = sum_active a_A``, ``mean = sum a_A lam_A / A``, ``var = sum a_A lam_A^2 / A - mean^2``;
    ``normalized=True`` returns ``var / mean^2``. The active set is held fixed
    in the derivative (as in the adjoint); the nodal areas follow the deformation.
    """

    def __init__(self, interfaces=None, normalized: bool = False, name: str | None = None):
        parts = tuple(Functional(zeta=z, interfaces=interfaces, quadrature="nodal", name=n)
                      for z, n in ((_active, "active_area"), (_identity, "force"), (_square, "second_moment")))
        super().__init__(parts, _relative_variance if normalized else _variance,
                         name=name or ("pressure_relative_variance" if normalized else "pressure_variance"))


class _Linear(Response):
    """``c . field`` with ``field`` the state's ``u`` or ``rho``: subclasses give ``c``."""

    field = "u"

    def __init__(self, bodies=None, name: str = ""):
        self.bodies, self.name = _as_tuple(bodies), name or self.name

    def coefficients(self, fields: Fields) -> np.ndarray:
        raise NotImplementedError

    def evaluate(self, fields: Fields, gradient: bool = True):
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
        for i in _body_indices(disc, self.bodies):
            mask[disc.body_slice(i)] = True
        return mask

    def coefficients(self, fields: Fields) -> np.ndarray:
        disc = fields.disc
        f = fields.t * disc.f_ext(fields.mass)
        mask = self._mask(disc)
        return f if mask is None else np.where(mask, f, 0.0)

    def evaluate(self, fields: Fields, gradient: bool = True):
        value, p = super().evaluate(fields, gradient)
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
        for i in _body_indices(disc, self.bodies):
            b = disc.blocks[i]
            weights[b.cell_offset:b.cell_offset + b.n_cells] = b.geometry.volume
        return weights / weights.sum()


BUILTIN = {
    "strain-energy": StrainEnergy,
    "compliance": Compliance,
    "contact-force": ContactForce,
    "pressure-variance": PressureVariance,
    "volume-fraction": VolumeFraction,
}


def builtin(name: str, **kwargs) -> Response:
    """A built-in response by its CLI name (see :data:`BUILTIN`)."""
    if name not in BUILTIN:
        raise ConfigError(f"unknown response {name!r}; choose one of {sorted(BUILTIN)}")
    return BUILTIN[name](**kwargs)
