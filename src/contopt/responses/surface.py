"""Surface integrals ``∫_gamma zeta(lam) da`` of the contact pressure (the ``zeta`` term of
:class:`contopt.responses.functionals.Functional`), by one of three quadratures (``quadrature``):

* ``"overlap"``: ``sum_A zeta(lam_A) a_A`` with the mortar overlap areas of the contact evaluation
  (``a_A = ∫_overlap N_A da``; on tri6 faces ``∫_overlap W_A da``, :mod:`contopt.contact.quadratic`).
* ``"gauss"``: over the whole deformed nonmortar facets with the pressure field interpolated from
  the multipliers. Bilinear facets (hex8; tet4 as degenerate quads): ``lam = N . Lambda`` and the
  area element ``s = |x_xi1 ^ x_xi2|``, 2x2 Gauss per facet (the paper's appendix A).
* ``"nodal"``: ``sum_A zeta(lam_A) A_A`` with the whole nodal areas ``A_A = ∫ N_A da``.

On a tet10 nonmortar surface both whole-surface readings integrate on the tri6 parent faces, not on
their four flat sub-facets: the positions ``x(xi) = sum_b N_b(xi) x_b`` with the six quadratic shape
functions, the curved surface's own area element ``|x_s ^ x_t|``, and the pressure field the
multipliers define, ``p_h = sum_A lam_A W_A`` with the transformed weights ``W`` (corner
``N_c + alpha (N_m + N_m')``, midpoint ``(1 - 2 alpha) N_m``) that the gaps are weighted with and
that carry the multipliers' forces (:mod:`contopt.contact.quadratic`). The points: Radon's 7-point
rule on each of the reference triangle's four sub-triangles (exact in xi to degree 5:
:func:`contopt.contact.quadratic.tri6_surface`).

* ``"gauss"`` on tri6: ``∫ zeta(p_h) da``.
* ``"nodal"`` on tri6: ``sum_A zeta(lam_A) A_A`` with the lumped areas ``A_A = ∫ W_A da`` over the
  node's parent faces, not ``∫ N_A da``. The tri6's ``∫ N_A da`` is the consistent nodal load of a
  unit pressure (0 at a corner, 1/3 of a flat face's area at a midpoint): with it a corner's
  multiplier would count nothing. ``∫ W_A da`` is each multiplier's own share of the face (2/15 at a
  corner, 1/5 at a midpoint of a flat face, summing to the face's area), the area it is a pressure
  over: the area the weighted gap ``g_A = ∫ W_A gap da`` is normalised by. So for ``zeta(lam) = lam``
  the nodal and the Gauss reading are the same integral ``∫ p_h da`` (to rounding); for a nonlinear
  ``zeta`` they differ as they do on bilinear facets.

A uniform pressure ``lam`` (every ``lam_A = lam``) gives ``lam`` times the curved surface's area by
all three on a fully covered surface (``sum_A W_A = 1``). The partial derivatives (in u through the
deformed positions, in the multipliers) come from JAX, exactly; the overlap areas' from the mortar
kernels' Jacobians.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from contopt.contact.quadratic import TRI6_RULE_WEIGHTS, tri6_surface
from contopt.contact.system import ContactDiscretization
from contopt.fem.hex8 import quad_gauss
from contopt.responses.base import Fields, Partials

_NQ, _DNQ, _WQ = quad_gauss(2)  # facet Gauss points: N (q, 4), dN (q, 4, 2), weights (q,)


def _facet_integral(x, lam, zeta, nodal):
    """One bilinear facet: x (4, 3) deformed nodes, lam (4,) nodal pressures."""
    tang = jnp.einsum("ai,qak->qki", x, _DNQ)  # (q, 2, 3)
    s = jnp.linalg.norm(jnp.cross(tang[:, 0], tang[:, 1]), axis=-1)  # (q,)
    if nodal:
        areas = jnp.einsum("q,qa,q->a", _WQ, _NQ, s)  # this facet's share of ∫ N_A da
        return jnp.dot(areas, jax.vmap(zeta)(lam))
    return jnp.dot(_WQ * s, jax.vmap(zeta)(_NQ @ lam))


def tri6_face_integral(x, lam, zeta, nodal):
    """One tri6 parent face: x (6, 3) deformed nodes, lam (6,) multipliers (module docstring)."""
    _, da = tri6_surface(x)  # (q,)
    if nodal:
        return jnp.dot(da @ TRI6_RULE_WEIGHTS, jax.vmap(zeta)(lam))  # ∫ W_A da, lumped
    return jnp.dot(da, jax.vmap(zeta)(TRI6_RULE_WEIGHTS @ lam))


@partial(jax.jit, static_argnames=("zeta", "nodal", "gradient", "tri6"))
def _surface_batch(x, lam, zeta, nodal, gradient, tri6):
    f = partial(tri6_face_integral if tri6 else _facet_integral, zeta=zeta, nodal=nodal)
    if not gradient:
        return jax.vmap(f)(x, lam)
    value, (dx, dlam) = jax.vmap(jax.value_and_grad(f, argnums=(0, 1)))(x, lam)
    return value, dx, dlam


def nonmortar_faces(block) -> tuple[np.ndarray, np.ndarray]:
    """The faces the whole-surface quadratures integrate on: (k, 4) bilinear facets or (k, 6) tri6
    parents' global node ids, and their nodes' positions (k, 4|6) in the interface's nodes."""
    par = block.parents
    if par is None or par.kinds[0] != "tri6":
        return block.nm_facet_nodes, block.nm_local
    first = par.nm_sub == 0  # a parent's four sub-facets: one row each
    return par.nm_nodes[first], par.nm_local[first]


def surface_integral(
    fields: Fields, interface_indices, zeta: Callable, quadrature: str, gradient: bool, partials: Partials | None
) -> float:
    """``∫ zeta(lam) da`` over the interfaces by ``quadrature`` (module docstring); adds partials in place."""
    contact = fields.system.contact
    if contact is None or not interface_indices:
        return 0.0
    if quadrature == "overlap":
        return _overlap_integral(contact, fields, interface_indices, zeta, gradient, partials)
    total = 0.0
    x_all = contact.X + fields.u.reshape(-1, 3)
    for i in interface_indices:
        block = contact.blocks[i]
        nodes, local = nonmortar_faces(block)
        x = jnp.asarray(x_all[nodes])
        lam = jnp.asarray(fields.lam[i][local])
        out = _surface_batch(x, lam, zeta, quadrature == "nodal", gradient, nodes.shape[1] == 6)
        if not gradient:
            total += float(np.asarray(out).sum())
            continue
        assert partials is not None  # given with gradient
        value, dx, dlam = (np.asarray(o) for o in out)
        total += float(value.sum())
        dofs = 3 * nodes[:, :, None] + np.arange(3)
        partials.u[:] += np.bincount(dofs.ravel(), weights=dx.ravel(), minlength=partials.u.size)
        partials.lam[i][:] += np.bincount(local.ravel(), weights=dlam.ravel(), minlength=block.n_nodes)
    return total


@partial(jax.jit, static_argnames=("zeta",))
def _zeta_and_slope(lam, zeta):
    return jax.vmap(jax.value_and_grad(zeta))(lam)


def _overlap_integral(
    contact: ContactDiscretization,
    fields: Fields,
    interface_indices,
    zeta: Callable,
    gradient: bool,
    partials: Partials | None,
) -> float:
    """``sum_A a_A(u) zeta(lam_A)`` with the mortar overlap areas of ``contact`` (that of
    ``fields.system``); partials ``a_A zeta'(lam_A)`` and ``sum_A zeta(lam_A) da_A/du``."""
    values, slopes = [], []
    for i, block in enumerate(contact.blocks):
        if i in interface_indices:
            v, d = _zeta_and_slope(jnp.asarray(fields.lam[i], dtype=jnp.float64), zeta)
            values.append(np.asarray(v))
            slopes.append(np.asarray(d))
        else:
            values.append(np.zeros(block.n_nodes))
            slopes.append(np.zeros(block.n_nodes))
    areas, vjp = contact.overlap_areas(fields.u, tuple(values) if gradient else None)
    if gradient:
        assert partials is not None  # given with gradient
        partials.u[:] += vjp
        for i in interface_indices:
            partials.lam[i][:] += areas[i] * slopes[i]
    return float(sum(np.dot(areas[i], values[i]) for i in interface_indices))
