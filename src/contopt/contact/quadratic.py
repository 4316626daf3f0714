"""Mortar integrals of pairs with a tet10 face (tri6) on either side: the parent's quadratic geometry
and a partition-of-unity weight, with exact derivatives.

A tri6 face (corners 0-2, then the midpoints of edges 01, 12, 20) is segmented as its four flat tri3
sub-facets (:data:`contopt.contact.facets.TRI6_SPLIT`): the clipping topology and the integration
points come from the sub-facets, exactly as for tri3 (:mod:`contopt.contact.mortar`). Each point is
then mapped back to the parent's reference coordinates ``xi`` (the sub-facet's linear coordinates,
affinely), and the gap and the weights are those of the parent:

    g_A = ∫ W_A(xi_nm) (x_m(xi_m) - x_nm(xi_nm)) . n0 da,      a_A = ∫ W_A(xi_nm) da,

with ``x(xi) = sum_b N_b(xi) x_b`` over the six nodes (the tri6 shape functions, :func:`tri6_shape`)
and ``W`` the transformed quadratic basis of Popp, Gee and Wall (2012) (:func:`tri6_weights`): a
corner ``N_c + alpha (N_m + N_m')`` over its two adjacent midpoints, a midpoint ``(1 - 2 alpha) N_m``,
``alpha =`` :data:`TRI6_ALPHA`. ``W`` sums to one and every ``∫ W_A`` is positive (the tri6 corners'
own ``∫ N_c`` is zero, which would leave corner gaps undefined), so a uniform pressure ``lam`` exerts
``lam ∫ N_b da`` on every node ``b``: the consistent load of the tet10, and the patch test passes
(docs/contact.md, "Triangle facets"). Four flat tri3 sub-facets with their own linear functions
give the corners ``1/12`` of the face's force where the tet10's consistent load is 0.

Sides of a pair are one of :data:`KINDS` (static): ``"quad"`` (hex8), ``"tri3"`` (tet4, stored
``[a, b, c, a]``) or ``"tri6"``; a pair is held as 12 nodes, six slots a side: a tri6 its six nodes,
a quad its four and two ignored slots, a tri3 its three and three ignored slots, and ``sub`` (2,)
the tri6 sub-facet each side's points lie on (0 otherwise).

Coulomb friction's slips (:func:`quadratic_pair_slip`) apply the same operator to the step's
displacement increment, as :mod:`contopt.contact.friction` does with the linear one.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from contopt.contact.facets import TRI6_SPLIT
from contopt.contact.mortar import (
    DEFAULT_CHUNK,
    TRIANGLE_POINTS,
    TRIANGLE_WEIGHTS,
    auxiliary_basis,
    bilinear_shape,
    inverse_bilinear,
    pad_chunk,
    polygon_points,
    triangle_buckets,
    triangle_shape,
)
from contopt.export_cache import Kernel

#: the weight's share of a midpoint given to each of its two corners (Popp, Gee and Wall 2012).
#: Any value in (0, 1/2) makes the weights a positive partition of unity, which is what the patch
#: test needs; 1/5 gives a corner 2/15 and a midpoint 1/5 of a flat face's area.
TRI6_ALPHA = 0.2
#: the facet kinds of a pair's sides
KINDS = ("quad", "tri3", "tri6")
#: (6, 2) reference coordinates of the tri6 nodes
TRI6_NODES_XI = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.5, 0.0], [0.5, 0.5], [0.0, 0.5]])
TRI6_NODES_XI.setflags(write=False)
# the midpoints adjacent to each corner: 0 on edges 01 (3) and 20 (5), 1 on 01 and 12 (4), 2 on 12 and 20
_CORNER_MIDS = np.array([[3, 5], [3, 4], [4, 5]])
# a tri3 side's segmented facet: [a, b, c, a] (contopt.contact.facets)
_TRI3_SLOTS = np.array([0, 1, 2, 0])


def tri6_shape(xi):
    """tri6 shape functions (..., 6) at reference points xi (..., 2) (corners, then midpoints 01, 12, 20)."""
    s, t = xi[..., 0], xi[..., 1]
    L = (1.0 - s - t, s, t)
    corners = [L[i] * (2.0 * L[i] - 1.0) for i in range(3)]
    mids = [4.0 * L[0] * L[1], 4.0 * L[1] * L[2], 4.0 * L[2] * L[0]]
    return jnp.stack(corners + mids, axis=-1)


def tri6_weights(N):
    """The transformed basis (..., 6) of tri6 shape functions N (..., 6): a partition of unity whose
    every function has a positive integral (module docstring; ``alpha =`` :data:`TRI6_ALPHA`)."""
    corners = N[..., :3] + TRI6_ALPHA * (N[..., _CORNER_MIDS[:, 0]] + N[..., _CORNER_MIDS[:, 1]])
    return jnp.concatenate([corners, (1.0 - 2.0 * TRI6_ALPHA) * N[..., 3:]], axis=-1)


def _tri6_shape_and_grad(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`tri6_shape` (q, 6) and its derivatives (q, 6, 2) in (s, t) at reference points xi (q, 2),
    in numpy float64 (module constants, made before jax's precision is set)."""
    s, t = xi[:, 0], xi[:, 1]
    L = np.stack([1.0 - s - t, s, t], axis=-1)
    dL = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])
    edges = ((0, 1), (1, 2), (2, 0))
    N = [L[:, i] * (2.0 * L[:, i] - 1.0) for i in range(3)] + [4.0 * L[:, a] * L[:, b] for a, b in edges]
    corners = [(4.0 * L[:, i, None] - 1.0) * dL[i] for i in range(3)]
    mids = [4.0 * (L[:, b, None] * dL[a] + L[:, a, None] * dL[b]) for a, b in edges]
    return np.stack(N, axis=-1), np.stack(corners + mids, axis=-2)


def _parent_rule() -> tuple[np.ndarray, np.ndarray]:
    """(q, 2) reference points and (q,) weights of the parent surface rule (:func:`tri6_surface`)."""
    tris = TRI6_NODES_XI[TRI6_SPLIT]  # (4, 3, 2) the reference sub-triangles, each of area 1/8
    xi = np.einsum("pk,tkd->tpd", TRIANGLE_POINTS, tris).reshape(-1, 2)
    return xi, np.tile(TRIANGLE_WEIGHTS / 8.0, len(tris))


#: the parent surface rule: Radon's 7 points on each of the reference triangle's four sub-triangles
#: (28 points, exact in xi to degree 5): reference points, weights (summing to the area 1/2), the tri6
#: shape functions, their derivatives and the transformed weights there
TRI6_RULE_XI, TRI6_RULE_W = _parent_rule()
TRI6_RULE_N, TRI6_RULE_DN = _tri6_shape_and_grad(TRI6_RULE_XI)
TRI6_RULE_WEIGHTS = np.concatenate(
    [
        TRI6_RULE_N[:, :3] + TRI6_ALPHA * TRI6_RULE_N[:, _CORNER_MIDS].sum(axis=2),
        (1 - 2 * TRI6_ALPHA) * TRI6_RULE_N[:, 3:],
    ],
    axis=1,
)
for _a in (TRI6_RULE_XI, TRI6_RULE_W, TRI6_RULE_N, TRI6_RULE_DN, TRI6_RULE_WEIGHTS):
    _a.setflags(write=False)


def tri6_surface(x6):
    """The curved tri6 surface of nodes x6 (..., 6, 3) at the parent rule's points: positions
    (..., q, 3) and area weights (..., q) ``w_q |x_s ^ x_t|`` (the surface's own area element, not its
    flat sub-facets'), so that ``∫ f da ~ sum_q da_q f(y_q)``; with :data:`TRI6_RULE_WEIGHTS` (q, 6)
    the multiplier field ``sum_A lam_A W_A`` at the points. Plain jax: differentiable in x6."""
    y = jnp.einsum("qa,...ai->...qi", TRI6_RULE_N, x6)
    tang = jnp.einsum("qak,...ai->...qki", TRI6_RULE_DN, x6)
    normal = jnp.cross(tang[..., 0, :], tang[..., 1, :])
    return y, TRI6_RULE_W * jnp.sqrt(jnp.sum(normal**2, axis=-1))


def _segmented(x6, kind, sub):
    """(4, 3) the facet a side is segmented as: the quad, the padded tri3, or tri6 sub-facet ``sub``."""
    if kind == "quad":
        return x6[:4]
    if kind == "tri3":
        return x6[_TRI3_SLOTS]
    return x6[jnp.asarray(np.concatenate([TRI6_SPLIT, TRI6_SPLIT[:, :1]], axis=1))[sub]]


def _shapes(p, pts, det_tiny, kind, sub):
    """(N, W) (n, 6) each: a side's interpolation and weight functions at plane points pts (n, 2), from
    its segmented facet p (4, 2); ignored slots 0."""
    if kind == "quad":
        N = bilinear_shape(inverse_bilinear(p, pts, det_tiny))
        N = jnp.concatenate([N, jnp.zeros_like(N[:, :2])], axis=1)
        return N, N
    lin = triangle_shape(p, pts, det_tiny)[:, :3]  # the sub-facet's (or tri3's) linear coordinates
    if kind == "tri3":
        N = jnp.concatenate([lin, jnp.zeros_like(lin)], axis=1)
        return N, N
    xi = lin @ jnp.asarray(TRI6_NODES_XI)[jnp.asarray(TRI6_SPLIT)[sub]]  # (n, 2) in the parent
    N = tri6_shape(xi)
    return N, tri6_weights(N)


def quadratic_integrals(x, topo, sub, n_tri, kind_nm, kind_m):
    """Weighted gaps and areas of ONE pair with the parents' geometry (module docstring).

    Parameters
    ----------
    x : (12, 3) the nonmortar side's six slots, then the mortar side's
    topo : (8, 3) clipping topology of the segmented facets (:mod:`contopt.contact.segment`)
    sub : (2,) int the tri6 sub-facet of each side (0 for quads and tri3)
    n_tri, kind_nm, kind_m : static; fan triangles and the sides' kinds (:data:`KINDS`)

    Returns
    -------
    g : (6,) ``∫ W_A (x_m - x_nm) . n0 da``; a : (6,) ``∫ W_A da`` (ignored slots 0)
    """
    C, a, y, n0 = quadratic_operator(x, topo, sub, n_tri, kind_nm, kind_m)
    return C @ (y @ n0), a


def quadratic_operator(x, topo, sub, n_tri, kind_nm, kind_m):
    """The mortar operator of ONE pair (arguments as :func:`quadratic_integrals`): ``C`` (6, 12) with
    ``C @ v = ∫ W_A (v_m(xi_m) - v_nm(xi_nm)) da`` for nodal values v (12, ...), the areas ``a`` (6,),
    the positions y (12, 3) relative to the auxiliary plane's centre and its normal n0 (3,)."""
    x = jnp.reshape(x, (12, 3))
    xs = jnp.concatenate([_segmented(x[:6], kind_nm, sub[0]), _segmented(x[6:], kind_m, sub[1])])
    ys, n0, t1, t2 = auxiliary_basis(xs)
    y = x - (xs[0] - ys[0])  # relative to the auxiliary plane's centre, as ys
    basis = jnp.stack([t1, t2], axis=1)
    pn, pm, pts, wts, det_tiny = polygon_points((ys @ basis).reshape(16), topo, n_tri)
    Nn, Wn = _shapes(pn, pts, det_tiny, kind_nm, sub[0])
    Nm, _ = _shapes(pm, pts, det_tiny, kind_m, sub[1])
    wW = wts[:, None] * Wn
    return wW.T @ jnp.concatenate([-Nn, Nm], axis=1), jnp.sum(wW, axis=0), y, n0


def _values_jac_one(x, topo, sub, n_tri, kind_nm, kind_m):
    def f(z):
        return jnp.concatenate(quadratic_integrals(z, topo, sub, n_tri, kind_nm, kind_m))

    y, pullback = jax.vjp(f, x.reshape(36))
    (J,) = jax.vmap(pullback)(jnp.eye(12, dtype=y.dtype))
    return y[:6], y[6:], J


def _hessian_one(x, topo, sub, w, n_tri, kind_nm, kind_m):
    def s(z):
        g, a = quadratic_integrals(z, topo, sub, n_tri, kind_nm, kind_m)
        return jnp.dot(w[:6], g) + jnp.dot(w[6:], a)

    H = jax.jacfwd(jax.grad(s))(x.reshape(36))  # forward over reverse, through the implicit inverse maps
    return 0.5 * (H + H.T)


_STATIC = ("n_tri", "kind_nm", "kind_m")


@partial(jax.jit, static_argnames=_STATIC)
def _values_batch(X, topo, sub, n_tri, kind_nm, kind_m):
    return jax.vmap(partial(quadratic_integrals, n_tri=n_tri, kind_nm=kind_nm, kind_m=kind_m))(X, topo, sub)


@partial(jax.jit, static_argnames=_STATIC)
def _values_jac_batch(X, topo, sub, n_tri, kind_nm, kind_m):
    return jax.vmap(partial(_values_jac_one, n_tri=n_tri, kind_nm=kind_nm, kind_m=kind_m))(X, topo, sub)


@partial(jax.jit, static_argnames=_STATIC)
def _hessian_batch(X, topo, sub, w, n_tri, kind_nm, kind_m):
    return jax.vmap(partial(_hessian_one, n_tri=n_tri, kind_nm=kind_nm, kind_m=kind_m))(X, topo, sub, w)


VALUES_BATCH = Kernel(_values_batch)
VALUES_JAC_BATCH = Kernel(_values_jac_batch)
HESSIAN_BATCH = Kernel(_hessian_batch)


def _run(fn, arrays, out_shapes, kinds, chunk):
    """``fn`` over fixed-size chunks of each vertex-count bucket (as :func:`contopt.contact.mortar.run_chunked`)."""
    kind_nm, kind_m = kinds
    if kind_nm not in KINDS or kind_m not in KINDS:
        raise ValueError(f"facet kinds must be among {KINDS}, got {kinds!r}")
    n = len(arrays[0])
    outs = [np.zeros((n,) + s) for s in out_shapes]
    n_vertices = (np.asarray(arrays[1])[:, :, 0] >= 0).sum(axis=1)
    for n_tri, members in triangle_buckets(n_vertices):
        for start in range(0, len(members), chunk):
            idx = members[start : start + chunk]
            chunked = [jnp.asarray(pad_chunk(a[idx], chunk)) for a in arrays]
            res = fn(*chunked, n_tri=n_tri, kind_nm=kind_nm, kind_m=kind_m)
            res = res if isinstance(res, tuple) else (res,)
            for o, r in zip(outs, res):
                o[idx] = np.asarray(r)[: len(idx)]
    return outs


def _checked(X, topo, sub):
    X = np.asarray(X, dtype=np.float64)
    topo, sub = np.asarray(topo, dtype=np.int32), np.asarray(sub, dtype=np.int32)
    if X.ndim != 3 or X.shape[1:] != (12, 3):
        raise ValueError(f"X must have shape (P, 12, 3) (6 nonmortar then 6 mortar slots), got {X.shape}")
    if topo.shape != (X.shape[0], 8, 3) or sub.shape != (X.shape[0], 2):
        raise ValueError(f"topo and sub must have shapes (P, 8, 3) and (P, 2), got {topo.shape} and {sub.shape}")
    return X, topo, sub


def quadratic_values(X, topo, sub, kinds, chunk: int = DEFAULT_CHUNK):
    """Weighted gaps and areas of P pairs: g (P, 6), a (P, 6) (:func:`quadratic_integrals`).

    X (P, 12, 3), topo (P, 8, 3), sub (P, 2), kinds: (nonmortar, mortar) of :data:`KINDS`.
    """
    X, topo, sub = _checked(X, topo, sub)
    return tuple(_run(VALUES_BATCH, (X, topo, sub), [(6,), (6,)], kinds, chunk))


def quadratic_values_and_jacobians(X, topo, sub, kinds, chunk: int = DEFAULT_CHUNK):
    """g (P, 6), a (P, 6) and J (P, 12, 36): rows dg_A/dx then da_A/dx, columns node-major over the 12 slots."""
    X, topo, sub = _checked(X, topo, sub)
    return tuple(_run(VALUES_JAC_BATCH, (X, topo, sub), [(6,), (6,), (12, 36)], kinds, chunk))


def quadratic_weighted_hessians(X, topo, sub, w, kinds, chunk: int = DEFAULT_CHUNK):
    """Hessians (P, 36, 36) of ``sum_A w[:, A] g_A + w[:, 6 + A] a_A`` per pair; w (P, 12)."""
    X, topo, sub = _checked(X, topo, sub)
    w = np.asarray(w, dtype=np.float64)
    if w.shape != (X.shape[0], 12):
        raise ValueError(f"w must have shape (P, 12), got {w.shape}")
    return _run(HESSIAN_BATCH, (X, topo, sub, w), [(36, 36)], kinds, chunk)[0]


# ------------------------------------------------------------------------------- friction
def quadratic_pair_slip(x, x_prev, topo, sub, n_tri, kind_nm, kind_m, x_moved=None):
    """z (6, 8) of ONE pair: per nonmortar slot ``(g, a, s (3), a n0 (3))`` as
    :func:`contopt.contact.friction.pair_slip`, on the parents' geometry with the transformed weights:
    ``s_A = -(I - n0 n0^T) ∫ W_A (Δx_m(xi_m) - Δx_nm(xi_nm)) da`` (the same operator as the gaps, so
    a uniform traction loads the nodes as the tet10's consistent load). x, x_prev (36,) the 12 slots;
    ``x_moved`` (default x): the positions whose increment is the slip (virtual work)."""
    C, a, y, n0 = quadratic_operator(x, topo, sub, n_tri, kind_nm, kind_m)
    moved = jnp.reshape(x if x_moved is None else x_moved, (12, 3))
    rel = C @ (moved - jnp.reshape(x_prev, (12, 3)))  # (6, 3) ∫ W_A (Δx_m - Δx_nm) da
    s = -(rel - (rel @ n0)[:, None] * n0[None, :])
    return jnp.concatenate([(C @ (y @ n0))[:, None], a[:, None], s, a[:, None] * n0[None, :]], axis=1)


def _slip_rows(x, x_prev, topo, sub, static):
    """(6, 3, 36) the slips' derivative in the moved positions (``-(P0 C) ⊗ I``, the overlap held)."""
    return jax.jacfwd(lambda m: quadratic_pair_slip(x, x_prev, topo, sub, x_moved=m, **static)[:, 2:5])(x)


@partial(jax.jit, static_argnames=_STATIC)
def _slip_jac_batch(X, topo, sub, Xp, n_tri, kind_nm, kind_m):
    static = {"n_tri": n_tri, "kind_nm": kind_nm, "kind_m": kind_m}

    def one(x, topo_, sub_, x_prev):
        x, x_prev = x.reshape(36), x_prev.reshape(36)

        def f(z):
            return quadratic_pair_slip(z, x_prev, topo_, sub_, n_tri, kind_nm, kind_m)

        return f(x), jax.jacfwd(f)(x), _slip_rows(x, x_prev, topo_, sub_, static)

    return jax.vmap(one)(X, topo, sub, Xp)


@partial(jax.jit, static_argnames=_STATIC)
def _slip_hessian_batch(X, topo, sub, Xp, w, n_tri, kind_nm, kind_m):
    static = {"n_tri": n_tri, "kind_nm": kind_nm, "kind_m": kind_m}

    def one(x, topo_, sub_, x_prev, w_):
        x, x_prev = x.reshape(36), x_prev.reshape(36)
        # d/dx of the pair's forces sum_A (ds_A/dx_moved)^T w_A: rows forces, columns positions
        return jax.jacfwd(lambda z: jnp.einsum("kc,kcj->j", w_, _slip_rows(z, x_prev, topo_, sub_, static)))(x)

    return jax.vmap(one)(X, topo, sub, Xp, w)


SLIP_JAC_BATCH = Kernel(_slip_jac_batch)
SLIP_HESSIAN_BATCH = Kernel(_slip_hessian_batch)


def quadratic_slips_and_jacobians(X, X_prev, topo, sub, kinds, chunk: int = DEFAULT_CHUNK):
    """z (P, 6, 8), dz/dx (P, 6, 8, 36) and the slips' virtual-work rows ds/dx_moved (P, 6, 3, 36)
    of P pairs (X, X_prev (P, 12, 3); :func:`quadratic_pair_slip`)."""
    X, topo, sub = _checked(X, topo, sub)
    X_prev, _, _ = _checked(X_prev, topo, sub)
    shapes = [(6, 8), (6, 8, 36), (6, 3, 36)]
    return tuple(_run(SLIP_JAC_BATCH, (X, topo, sub, X_prev), shapes, kinds, chunk))


def quadratic_slip_hessians(X, X_prev, topo, sub, w, kinds, chunk: int = DEFAULT_CHUNK):
    """(P, 36, 36) derivatives of the pairs' friction forces ``sum_A (ds_A/dx_moved)^T w_A`` in the
    positions (rows: forces, columns: positions; w (P, 6, 3) tractions)."""
    X, topo, sub = _checked(X, topo, sub)
    X_prev, _, _ = _checked(X_prev, topo, sub)
    w = np.asarray(w, dtype=np.float64)
    if w.shape != (X.shape[0], 6, 3):
        raise ValueError(f"w must have shape (P, 6, 3), got {w.shape}")
    return _run(SLIP_HESSIAN_BATCH, (X, topo, sub, X_prev, w), [(36, 36)], kinds, chunk)[0]


def precompile(kinds: tuple, chunk: int = DEFAULT_CHUNK) -> float:
    """Compile (or load) every kernel variant of the sides' ``kinds``; returns the seconds spent
    (as :func:`contopt.contact.mortar.precompile`)."""
    from contopt.contact.mortar import TRIANGLE_BUCKETS
    from contopt.timing import Stopwatch

    clock = Stopwatch()
    static = {"kind_nm": kinds[0], "kind_m": kinds[1]}
    X, sub = jnp.zeros((chunk, 12, 3)), jnp.zeros((chunk, 2), dtype=jnp.int32)
    topo = jnp.full((chunk, 8, 3), -1, dtype=jnp.int32)
    for _, n_tri in TRIANGLE_BUCKETS:
        jax.block_until_ready(VALUES_BATCH(X, topo, sub, n_tri=n_tri, **static))
        jax.block_until_ready(VALUES_JAC_BATCH(X, topo, sub, n_tri=n_tri, **static))
        jax.block_until_ready(HESSIAN_BATCH(X, topo, sub, jnp.zeros((chunk, 12)), n_tri=n_tri, **static))
    return clock.seconds
