"""Cell integrands over the bodies: their per-cell values and exact partials, summed or handed out.

A cell integrand is a JAX function ``integrand(u, X, grad, wdet, rho, N, params) -> scalar`` of one
cell: u (n, 3) its nodes' displacements, X (n, 3) their reference positions, grad (q, n, 3) and
wdet (q,) the shape gradients and weights at its quadrature points, rho its stiffness factor, N
(q, n) the shape functions and params the material's parameters. :func:`bulk_integral` sums it
over the cells (the functionals, the p-norm stress); :func:`cell_terms` hands out each cell's value
and partials, for an aggregate that is no sum of the cells' values (the KS stress).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from contopt.assembly.kernels import DEFAULT_CHUNK, run_chunked
from contopt.responses.base import Fields


@partial(jax.jit, static_argnames=("integrand", "gradient"))
def _bulk_batch(u, X, grad, wdet, rho, N, params, integrand, gradient):
    if not gradient:
        return jax.vmap(integrand, in_axes=(0, 0, 0, 0, 0, None, None))(u, X, grad, wdet, rho, N, params)
    f = jax.value_and_grad(integrand, argnums=(0, 4))
    value, (du, drho) = jax.vmap(f, in_axes=(0, 0, 0, 0, 0, None, None))(u, X, grad, wdet, rho, N, params)
    return value, du, drho


@dataclass(frozen=True, eq=False)
class CellTerms:
    """One body's cells (of those this rank evaluates, those asked for): ``body`` its index, ``cells``
    (k,) their places in the model's cells (of ``rho``), ``dofs`` (k, 3n) their dofs, ``value`` (k,)
    the integrand, and with the gradient ``du`` (k, n, 3) and ``drho`` (k,) its partials (else None)."""

    body: int
    cells: np.ndarray
    dofs: np.ndarray
    value: np.ndarray
    du: np.ndarray | None
    drho: np.ndarray | None


def cell_terms(
    fields: Fields, body_indices, integrand_for: Callable, gradient: bool, cells_of=None
) -> Iterator[CellTerms]:
    """The integrand ``integrand_for(block)`` of every cell of the bodies ``body_indices`` that this
    rank evaluates (all of them in a serial run; :mod:`contopt.parallel`), one :class:`CellTerms` a
    body; ``cells_of(i)``: a (m,) boolean mask of body ``i``'s cells to take (default: all)."""
    disc = fields.disc
    for i in body_indices:
        b = disc.blocks[i]
        mesh = disc.model.bodies[i].mesh
        (dofs, grad, wdet), (cells,) = b.kernel_inputs(), b.owned(mesh.cells)
        keep = np.arange(len(cells)) if cells_of is None else np.flatnonzero(b.owned(cells_of(i))[0])
        if not len(keep):
            continue
        dofs, cells, grad, wdet = dofs[keep], cells[keep], grad[keep], wdet[keep]
        rho_ids = b.owned_cells.start + keep  # the kept cells' places in the model's cells
        fn = partial(_bulk_batch, integrand=integrand_for(b), gradient=gradient)
        n = cells.shape[1]  # nodes a cell: 8 hex8, 4 tet4, 10 tet10
        shapes = [(), (n, 3), ()] if gradient else [()]
        outs = run_chunked(
            fn,
            dofs.shape[0],
            DEFAULT_CHUNK,
            (fields.u[dofs].reshape(-1, n, 3), mesh.points[cells], grad, wdet, fields.rho[rho_ids]),
            (jnp.asarray(b.geometry.N), jnp.asarray(b.params)),
            shapes,
        )
        du, drho = (outs[1], outs[2]) if gradient else (None, None)
        yield CellTerms(body=i, cells=rho_ids, dofs=dofs, value=outs[0], du=du, drho=drho)


def add_partials(fields: Fields, terms: CellTerms, weights: np.ndarray, d_u: np.ndarray, d_rho: np.ndarray) -> None:
    """Adds ``sum_e weights_e d(value_e)/du`` into ``d_u`` (n_dofs,) and ``.../drho`` into ``d_rho``
    (n_cells,), in place (this rank's cells; the caller sums over the ranks)."""
    assert terms.du is not None and terms.drho is not None  # evaluated with the gradient
    d_u += np.bincount(
        terms.dofs.ravel(), weights=(weights[:, None, None] * terms.du).reshape(-1), minlength=fields.disc.n_dofs
    )
    d_rho[terms.cells] += weights * terms.drho


def bulk_integral(fields: Fields, body_indices, integrand_for: Callable, gradient: bool, partials, cells_of=None):
    """``sum_cells integrand`` over the bodies; adds its partials into ``partials`` (in place).
    ``cells_of(i)``: a (m,) boolean mask of body ``i``'s cells to integrate over (default: all)."""
    disc = fields.disc
    total = 0.0
    d_u, d_rho = (np.zeros(disc.n_dofs), np.zeros(disc.n_cells)) if gradient else (None, None)
    for terms in cell_terms(fields, body_indices, integrand_for, gradient, cells_of):
        total += float(terms.value.sum())
        if d_u is not None and d_rho is not None:
            add_partials(fields, terms, np.ones(terms.cells.size), d_u, d_rho)
    if d_u is not None and d_rho is not None:
        assert partials is not None  # given with gradient
        partials.u[:] += disc.comm.sum(d_u)
        partials.rho[:] += disc.comm.sum(d_rho)
    return disc.comm.sum(total)
