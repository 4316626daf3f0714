"""Batched, jit-compiled element kernels over a body's cells, in fixed-size chunks.

Every chunk has the same shape (the last one is padded with copies of a
real cell and its output dropped) so a material type compiles once per
(chunk size, F-bar flag, tangent flag) and memory stays bounded on large
meshes. Inputs and outputs at this boundary are numpy float64.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from contopt.export_cache import Kernel
from contopt.fem.element import cauchy_stress, element_energy, element_residual, element_residual_tangent

#: Cells per kernel call: small chunks stay in cache (docs/performance.md, "Element kernels").
DEFAULT_CHUNK = 256
#: the chunk of meshes of at most this many cells
SMALL_CHUNK = 64


@partial(jax.jit, static_argnames=("energy", "use_fbar", "tangent"))
def _residual_tangent_batch(u, grad, wdet, rho, params, energy, use_fbar, tangent):
    f = partial(element_residual_tangent, energy=energy, use_fbar=use_fbar, tangent=tangent)
    return jax.vmap(f, in_axes=(0, 0, 0, 0, None))(u, grad, wdet, rho, params)


@partial(jax.jit, static_argnames=("energy", "use_fbar"))
def _energy_batch(u, grad, wdet, rho, params, energy, use_fbar):
    f = partial(element_energy, energy=energy, use_fbar=use_fbar)
    return jax.vmap(f, in_axes=(0, 0, 0, 0, None))(u, grad, wdet, rho, params)


@partial(jax.jit, static_argnames=("energy", "use_fbar"))
def _rho_vjp_batch(u, w, grad, wdet, rho, params, energy, use_fbar):
    def one(u, w, grad, wdet, rho):
        return jax.grad(lambda r: jnp.vdot(w, element_residual(u, grad, wdet, r, params, energy, use_fbar)))(rho)

    return jax.vmap(one)(u, w, grad, wdet, rho)


@partial(jax.jit, static_argnames=("energy", "use_fbar"))
def _stress_batch(u, grad, wdet, params, energy, use_fbar):
    f = partial(cauchy_stress, energy=energy, use_fbar=use_fbar)
    return jax.vmap(f, in_axes=(0, 0, 0, None))(u, grad, wdet, params)


# the kernels as called: through jax.export, traced once per variant and kept on disk (contopt.export_cache)
RESIDUAL_TANGENT_BATCH = Kernel(_residual_tangent_batch)
ENERGY_BATCH = Kernel(_energy_batch)
RHO_VJP_BATCH = Kernel(_rho_vjp_batch)
STRESS_BATCH = Kernel(_stress_batch)


def _chunks(n: int, chunk: int):
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        yield start, stop


def _pad(a: np.ndarray, size: int) -> np.ndarray:
    if len(a) == size:
        return a
    reps = np.repeat(a[-1:], size - len(a), axis=0)
    return np.concatenate([a, reps], axis=0)


def run_chunked(fn, n: int, chunk: int, per_cell: tuple, shared: tuple, out_shapes: list, sinks: dict | None = None):
    """Apply ``fn(*per_cell_chunk, *shared)`` chunk by chunk; returns numpy outputs.

    per_cell : arrays of leading size ``n`` (cells), cut into chunks of ``chunk`` rows (the last
        one zero-padded, so each chunk size compiles once); shared : arguments passed whole;
    out_shapes : per output of ``fn``, its shape after the cell axis. Returns a list of arrays
    ``(n,) + out_shapes[k]``; an output ``k`` in ``sinks`` is instead handed chunk by chunk to
    ``sinks[k](start, stop, values)`` (values ``(stop - start,) + out_shapes[k]``, valid during
    the call) and its entry in the list is None: the element tangents of a large mesh are
    assembled without ever being held whole.
    """
    sinks = sinks or {}
    # two chunk shapes at most, so that the bodies of a model share one traced and compiled kernel
    # (each shape costs a trace per process, and a compilation when the cache lacks it); only tiny
    # meshes (tests, single parts) use the small one, where padding to `chunk` would dominate
    chunk = min(chunk, SMALL_CHUNK) if n <= SMALL_CHUNK else chunk
    outs = [None if k in sinks else np.empty((n,) + s) for k, s in enumerate(out_shapes)]
    for start, stop in _chunks(n, chunk):
        # numpy in: the jitted call moves it to the device in C++ (``jnp.asarray`` first cost 0.2 ms an array,
        # a sixth of the residual-only evaluation of the Hertz line's 8,216 cells); the same values and program
        args = [_pad(a[start:stop], chunk) for a in per_cell]
        res = fn(*args, *shared)
        res = res if isinstance(res, tuple) else (res,)
        for k, (o, r) in enumerate(zip(outs, res)):
            if o is None:
                sinks[k](start, stop, np.asarray(r)[: stop - start])
            else:
                o[start:stop] = np.asarray(r)[: stop - start]
    return outs


def element_residuals_tangents(
    u_cells, grad, wdet, rho, params, energy, use_fbar=True, tangent=True, chunk=DEFAULT_CHUNK, tangent_sink=None
):
    """Element energies (m,), residuals (m, 3n) and, with ``tangent``, tangents (m, 3n, 3n).

    Parameters
    ----------
    u_cells : (m, n, 3) nodal displacements of each cell (n = 8 hex8, 4 tet4, 10 tet10)
    grad : (m, q, n, 3) shape gradients; wdet : (m, q); rho : (m,) stiffness factors
    params : (p,) material parameters of ``energy(F, params)``
    tangent_sink : with ``tangent``, ``tangent_sink(start, stop, K)`` receives the tangents
        ``(stop - start, 24, 24)`` of cells ``start:stop`` chunk by chunk, and the third value
        returned is None
    """
    m, n = len(u_cells), u_cells.shape[1]  # n nodes a cell: 8 (hex8), 4 (tet4), 10 (tet10)
    fn = partial(RESIDUAL_TANGENT_BATCH, energy=energy, use_fbar=use_fbar, tangent=tangent)
    shapes = [(), (n, 3), (n, 3, n, 3)] if tangent else [(), (n, 3)]
    sinks = None
    if tangent and tangent_sink is not None:
        sinks = {2: lambda start, stop, K: tangent_sink(start, stop, K.reshape(-1, 3 * n, 3 * n))}
    outs = run_chunked(fn, m, chunk, (u_cells, grad, wdet, rho), (jnp.asarray(params),), shapes, sinks)
    W, r = outs[0], outs[1].reshape(m, 3 * n)
    if not tangent:
        return W, r
    return W, r, None if outs[2] is None else outs[2].reshape(m, 3 * n, 3 * n)


def element_energies(u_cells, grad, wdet, rho, params, energy, use_fbar=True, chunk=DEFAULT_CHUNK):
    """Element strain energies (m,) (scaled by rho)."""
    fn = partial(ENERGY_BATCH, energy=energy, use_fbar=use_fbar)
    return run_chunked(fn, len(u_cells), chunk, (u_cells, grad, wdet, rho), (jnp.asarray(params),), [()])[0]


def element_rho_vjps(u_cells, w_cells, grad, wdet, rho, params, energy, use_fbar=True, chunk=DEFAULT_CHUNK):
    """``d/drho_e (w_e . r_e(u_e, rho_e))`` (m,): the vjp of the element residuals with the material field.

    u_cells, w_cells : (m, 8, 3) displacements and adjoint vectors of each cell
    """
    fn = partial(RHO_VJP_BATCH, energy=energy, use_fbar=use_fbar)
    return run_chunked(fn, len(u_cells), chunk, (u_cells, w_cells, grad, wdet, rho), (jnp.asarray(params),), [()])[0]


def element_stresses(u_cells, grad, wdet, params, energy, use_fbar=True, chunk=DEFAULT_CHUNK):
    """Cauchy stress at each quadrature point (m, q, 3, 3) of the unscaled material.

    Multiply by the element's stiffness factor for the stress of the design.
    """
    q = grad.shape[1]
    fn = partial(STRESS_BATCH, energy=energy, use_fbar=use_fbar)
    return run_chunked(fn, len(u_cells), chunk, (u_cells, grad, wdet), (jnp.asarray(params),), [(q, 3, 3)])[0]
