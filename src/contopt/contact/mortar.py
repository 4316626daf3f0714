"""Mortar integrals of one (nonmortar facet, mortar facet) pair in JAX, with exact derivatives.

For a pair with fixed clipping topology (from :func:`contopt.contact.segment.segment_pairs`)
this module computes, as smooth functions of the 8 nodal coordinates,

    g_A = ∫ N_A(xi_nm) (x_m(xi_m) - x_nm(xi_nm)) . n0 da,      a_A = ∫ N_A(xi_nm) da,

over the overlap polygon on the auxiliary plane (Puso & Laursen 2004; docs/formulation.md
§4). ``g_A >= 0`` is open (the mortar point lies on the ``+n0`` side,
outside the nonmortar body), negative is penetration.

Steps (all differentiable, no data-dependent control flow):

1. auxiliary plane (centre, ``n0`` = normalized cross product of the diagonals)
   and in-plane basis, exactly as :func:`contopt.contact.segment.auxiliary_frame`;
2. polygon vertices from the topology: nodes, or edge-edge intersections solved
   as 2x2 linear systems of the two projected edge lines;
3. fan triangulation from the first vertex (n - 2 triangles for n vertices;
   pairs are batched by vertex count, so the common quadrilateral overlap
   costs 2 triangles); padded vertices repeat the last real one so their
   triangles have exactly zero area;
4. Radon's 7-point degree-5 triangle rule (:data:`TRIANGLE_POINTS`);
5. each point mapped back to both projected quads by Newton on the bilinear map
   (:data:`N_NEWTON` iterations from (0, 0), machine precision on strongly
   distorted convex quads). The iterations are not differentiated: a
   ``custom_jvp`` gives the derivative of the exact root by the implicit
   function theorem, ``J dxi = dpts - sum_a N_a(xi) dp_a``, and since the rule
   calls the root again, second derivatives are exact too;
6. the gap at a point is the difference of the interpolated heights above the
   plane of the two facets (both points project onto the same plane point).

Every division and square root is guarded with ``jnp.where`` *before* it is
taken, so padded or degenerate pairs give finite values and finite (zero)
derivatives instead of NaN.

Batched helpers (jit + vmap over fixed-size chunks, numpy in / numpy out). The derivative
modes were chosen by measurement (values and Jacobians by ``vjp`` over 8 cotangents, Hessians
forward-over-reverse through the projection, the inverse map differentiated by its implicit
``custom_jvp`` rule rather than through unrolled iterations): docs/performance.md, "Mortar kernels".
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from contopt.contact.segment import triangles
from contopt.export_cache import Kernel
from contopt.timing import Stopwatch

#: Radon's 7-point rule on a triangle, exact for polynomials of degree <= 5.
#: Barycentric coordinates (7, 3); weights (7,) sum to 1 (multiply by the triangle area).
TRIANGLE_DEGREE = 5
_r15 = np.sqrt(15.0)
_a1, _a2 = (6.0 - _r15) / 21.0, (6.0 + _r15) / 21.0
_w1, _w2 = (155.0 - _r15) / 1200.0, (155.0 + _r15) / 1200.0
TRIANGLE_POINTS = np.array(
    [[1 / 3, 1 / 3, 1 / 3]]
    + [[1 - 2 * _a1, _a1, _a1], [_a1, 1 - 2 * _a1, _a1], [_a1, _a1, 1 - 2 * _a1]]
    + [[1 - 2 * _a2, _a2, _a2], [_a2, 1 - 2 * _a2, _a2], [_a2, _a2, 1 - 2 * _a2]]
)
TRIANGLE_WEIGHTS = np.array([9 / 40] + 3 * [_w1] + 3 * [_w2])
TRIANGLE_POINTS.setflags(write=False)
TRIANGLE_WEIGHTS.setflags(write=False)

#: Newton iterations of the inverse bilinear map (from (0, 0)).
N_NEWTON = 10
# Newton iterates are kept in this box: only points of degenerate (inactive,
# zero-weight) pairs ever reach it, and it keeps them finite
_XI_BOX = 4.0

#: Pairs per kernel call (padded): 64 was fastest for Hessians (docs/performance.md, "Mortar kernels").
DEFAULT_CHUNK = 64
#: fan triangles for the largest polygon (8 vertices: two quads clipped)
MAX_TRIANGLES = 6
#: kernel variants: (largest vertex count, fan triangles); a pair goes to the first that fits
TRIANGLE_BUCKETS = ((4, 2), (8, MAX_TRIANGLES))


# ------------------------------------------------------------ small helpers
def _cross2(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _safe_normalize(v, tiny):
    """v / |v|, or 0 when |v|^2 <= tiny (guarded so the derivative is finite too)."""
    s = jnp.sum(v * v, axis=-1, keepdims=True)
    ok = s > tiny
    return jnp.where(ok, v / jnp.sqrt(jnp.where(ok, s, 1.0)), 0.0)


def bilinear_shape(xi):
    """Bilinear shape functions (..., 4) at reference points xi (..., 2); corners (-1,-1),(1,-1),(1,1),(-1,1)."""
    s, t = xi[..., 0], xi[..., 1]
    return 0.25 * jnp.stack([(1 - s) * (1 - t), (1 + s) * (1 - t), (1 + s) * (1 + t), (1 - s) * (1 + t)], axis=-1)


def _bilinear_coefficients(p):
    """X(s, t) = c0 + c1 s + c2 t + c3 s t for a quad p (4, 2)."""
    c0 = 0.25 * (p[0] + p[1] + p[2] + p[3])
    c1 = 0.25 * (-p[0] + p[1] + p[2] - p[3])
    c2 = 0.25 * (-p[0] - p[1] + p[2] + p[3])
    c3 = 0.25 * (p[0] - p[1] + p[2] - p[3])
    return c0, c1, c2, c3


def _newton_step(xi, coef, pts, det_tiny):
    c0, c1, c2, c3 = coef
    s, t = xi[..., 0:1], xi[..., 1:2]
    r = c0 + c1 * s + c2 * t + c3 * (s * t) - pts
    j0 = c1 + c3 * t  # dX/ds
    j1 = c2 + c3 * s  # dX/dt
    det = _cross2(j0, j1)
    det = jnp.where(jnp.abs(det) > det_tiny, det, 1.0)
    ds = (j1[..., 1] * r[..., 0] - j1[..., 0] * r[..., 1]) / det
    dt = (-j0[..., 1] * r[..., 0] + j0[..., 0] * r[..., 1]) / det
    return xi - jnp.stack([ds, dt], axis=-1)


@partial(jax.custom_jvp, nondiff_argnums=(3,))
def _inverse_bilinear(p, pts, det_tiny, n_iter):
    coef = _bilinear_coefficients(p)
    xi = jnp.zeros(pts.shape[:-1] + (2,), dtype=pts.dtype)
    step = lambda _, z: jnp.clip(_newton_step(z, coef, pts, det_tiny), -_XI_BOX, _XI_BOX)  # noqa: E731
    return jax.lax.fori_loop(0, n_iter, step, xi)


@_inverse_bilinear.defjvp
def _inverse_bilinear_jvp(n_iter, primals, tangents):
    # implicit function theorem on X(xi; p) = pts: Jac dxi = dpts - sum_a N_a(xi) dp_a.
    # The rule calls the primal again, so higher derivatives reuse it and are exact.
    p, pts, det_tiny = primals
    dp, dpts, _ = tangents
    xi = _inverse_bilinear(p, pts, det_tiny, n_iter)
    _, c1, c2, c3 = _bilinear_coefficients(p)
    s, t = xi[..., 0:1], xi[..., 1:2]
    j0 = c1 + c3 * t
    j1 = c2 + c3 * s
    det = _cross2(j0, j1)
    det = jnp.where(jnp.abs(det) > det_tiny, det, 1.0)
    rhs = dpts - bilinear_shape(xi) @ dp
    ds = (j1[..., 1] * rhs[..., 0] - j1[..., 0] * rhs[..., 1]) / det
    dt = (-j0[..., 1] * rhs[..., 0] + j0[..., 0] * rhs[..., 1]) / det
    return xi, jnp.stack([ds, dt], axis=-1)


def inverse_bilinear(p, pts, det_tiny=0.0, n_iter=None):
    """Reference coordinates (n, 2) of plane points pts (n, 2) in the quad p (4, 2).

    ``n_iter`` (default :data:`N_NEWTON`) Newton iterations from (0, 0); the
    derivatives are those of the exact root (implicit function theorem), to
    any order. ``det_tiny`` guards the 2x2 solves of degenerate quads.
    """
    n_iter = N_NEWTON if n_iter is None else int(n_iter)
    return _inverse_bilinear(p, pts, jnp.asarray(det_tiny, dtype=pts.dtype) + 1e-300, n_iter)


def triangle_shape(p, pts, det_tiny):
    """Linear shape functions (n, 4) of the triangle p[:3] (p (4, 2)) at plane points pts (n, 2), the
    fourth (the repeated node's) zero. The linear map is inverted exactly: no Newton, and the
    derivatives are those of a 2x2 solve."""
    j0, j1 = p[1] - p[0], p[2] - p[0]
    det = _cross2(j0, j1)
    det = jnp.where(jnp.abs(det) > det_tiny, det, 1.0)
    r = pts - p[0]
    s = _cross2(r, j1) / det
    t = _cross2(j0, r) / det
    return jnp.stack([1.0 - s - t, s, t, jnp.zeros_like(s)], axis=-1)


def _facet_shape(p, pts, det_tiny, tri):
    """Shape functions (n, 4) of the facet p (4, 2) at pts (n, 2): linear of a triangle (``tri``,
    static), bilinear of a quad."""
    if tri:
        return triangle_shape(p, pts, det_tiny)
    return bilinear_shape(inverse_bilinear(p, pts, det_tiny))


# ------------------------------------------------------------------- kernel
def as_quads(x, tri_nm, tri_m):
    """Nodes (8, 3) with a triangle's node 3 (7) set to its node 0 (4): the kernels' values and
    derivatives then depend on a triangle's three nodes only (the fourth slot repeats node 0)."""
    if tri_nm:
        x = x.at[3].set(x[0])
    if tri_m:
        x = x.at[7].set(x[4])
    return x


def auxiliary_basis(x):
    """Nodes (8, 3) relative to the nonmortar centre (8, 3), and the auxiliary plane's normal
    ``n0`` and in-plane basis ``t1``, ``t2`` (3,) each."""
    xn = x[:4]
    y = x - jnp.mean(xn, axis=0)
    tiny = 1e-30 * jnp.sum(y[:4] * y[:4]) + 1e-300
    n0 = _safe_normalize(jnp.cross(xn[2] - xn[0], xn[3] - xn[1]), tiny)
    e = xn[1] + xn[2] - xn[0] - xn[3]
    t1 = _safe_normalize(e - jnp.dot(e, n0) * n0, tiny)
    return y, n0, t1, jnp.cross(n0, t1)


def _plane_coordinates(x, tri_nm=False, tri_m=False):
    """(24,) nodes (8 x 3, node-major) -> (24,) = plane coordinates q (8 x 2, node-major), heights h (8,).
    ``tri_nm``, ``tri_m`` (static): that facet is a triangle (:func:`as_quads`)."""
    y, n0, t1, t2 = auxiliary_basis(as_quads(x.reshape(8, 3), tri_nm, tri_m))
    q = jnp.stack([y @ t1, y @ t2], axis=-1)
    return jnp.concatenate([q.reshape(16), y @ n0])


def polygon_operator(q, topo, n_tri=MAX_TRIANGLES, tri_nm=False, tri_m=False):
    """Gap operator and areas of the overlap polygon, from plane coordinates only.

    q (16,) plane coordinates of the 8 nodes; ``n_tri`` (static) triangles of
    the fan, enough for polygons of ``n_tri + 2`` vertices; ``tri_nm``, ``tri_m`` (static) the
    facet is a triangle (its node 3 repeats node 0, so its edge 2 ends at node "3"). Returns C (4, 8)
    with ``g = C @ h`` (g is linear in the heights h) and a (4,).
    """
    pn, pm, pts, wts, det_tiny = polygon_points(q, topo, n_tri)
    Nn = _facet_shape(pn, pts, det_tiny, tri_nm)
    Nm = _facet_shape(pm, pts, det_tiny, tri_m)
    wN = wts[:, None] * Nn
    C = jnp.concatenate([-(wN.T @ Nn), wN.T @ Nm], axis=1)
    return C, jnp.sum(wN, axis=0)


def polygon_points(q, topo, n_tri=MAX_TRIANGLES):
    """The overlap polygon's integration points from plane coordinates q (16,) of the 8 facet nodes:
    ``(pn (4, 2), pm (4, 2), pts (7 n_tri, 2), wts (7 n_tri,), det_tiny)``, the projected facets, the
    points on the plane and their weights (area included), and the guard of 2x2 solves."""
    q = q.reshape(8, 2)
    pn, pm = q[:4], q[4:]
    kind = topo[:, 0]
    i = jnp.clip(topo[:, 1], 0, 3)
    j = jnp.clip(topo[:, 2], 0, 3)
    a0, b0 = pn[i], pn[(i + 1) % 4]
    c0, d0 = pm[j], pm[(j + 1) % 4]
    den = _cross2(b0 - a0, d0 - c0)
    ok = (kind == 2) & (den != 0.0)
    s = jnp.where(ok, _cross2(c0 - a0, d0 - c0), 0.0) / jnp.where(ok, den, 1.0)
    v = jnp.where((kind == 0)[:, None], a0, jnp.where((kind == 1)[:, None], c0, a0 + s[:, None] * (b0 - a0)))

    valid = kind >= 0
    nv = jnp.sum(valid)
    # fan from vertex 0 (the overlap of two convex quads is convex): n - 2 triangles.
    # Padded vertices repeat the last real one, so their triangles have exactly zero
    # area and their Gauss points lie on a chord of the polygon, where the inverse maps are tame.
    v = jnp.where(valid[:, None], v, v[jnp.maximum(nv - 1, 0)])
    vb, vc = v[1 : n_tri + 1], v[2 : n_tri + 2]
    area2 = _cross2(vb - v[0], vc - v[0])  # (n_tri,) twice the signed triangle areas

    L = jnp.asarray(TRIANGLE_POINTS)
    pts = L[None, :, 0:1] * v[0] + L[None, :, 1:2] * vb[:, None, :] + L[None, :, 2:3] * vc[:, None, :]
    pts = pts.reshape(-1, 2)  # (7 n_tri, 2)
    wts = (0.5 * area2[:, None] * jnp.asarray(TRIANGLE_WEIGHTS)[None, :]).reshape(-1)
    return pn, pm, pts, wts, 1e-14 * jnp.sum(pn * pn)


def pair_integrals(x, topo, n_tri=MAX_TRIANGLES, tri_nm=False, tri_m=False):
    """Weighted gaps and areas of ONE pair (``n_tri`` static: polygons up to ``n_tri + 2`` vertices).

    Parameters
    ----------
    x : (8, 3) nodes: 4 nonmortar (outward ordering) then 4 mortar; a triangle (``tri_nm``,
        ``tri_m``, static) is its 3 nodes and a 4th slot that is ignored (its node 0 stands there
        in :func:`contopt.contact.facets.contact_facets`); its g and a there are 0
    topo : (8, 3) int rows ``(kind, i, j)`` of the overlap polygon, see
        :mod:`contopt.contact.segment`; all ``-1`` gives zeros

    Returns
    -------
    g : (4,) ``g_A = ∫ N_A (x_m - x_nm) . n0 da`` (>= 0 open, < 0 penetration)
    a : (4,) ``a_A = ∫ N_A da`` (sum = overlap area on the auxiliary plane)
    """
    y = _plane_coordinates(jnp.reshape(x, 24), tri_nm, tri_m)
    C, a = polygon_operator(y[:16], topo, n_tri, tri_nm, tri_m)
    return C @ y[16:], a


# ------------------------------------------------------------ batched calls
@partial(jax.jit, static_argnames=("n_tri", "tri_nm", "tri_m"))
def _values_batch(X, topo, n_tri, tri_nm=False, tri_m=False):
    return jax.vmap(partial(pair_integrals, n_tri=n_tri, tri_nm=tri_nm, tri_m=tri_m))(X, topo)


def _values_jac_one(x, topo, n_tri, tri_nm, tri_m):
    def f(z):
        g, a = pair_integrals(z, topo, n_tri, tri_nm, tri_m)
        return jnp.concatenate([g, a])

    y, pullback = jax.vjp(f, x.reshape(24))
    (J,) = jax.vmap(pullback)(jnp.eye(8, dtype=y.dtype))
    return y[:4], y[4:], J


@partial(jax.jit, static_argnames=("n_tri", "tri_nm", "tri_m"))
def _values_jac_batch(X, topo, n_tri, tri_nm=False, tri_m=False):
    return jax.vmap(partial(_values_jac_one, n_tri=n_tri, tri_nm=tri_nm, tri_m=tri_m))(X, topo)


def _weighted_hessian_one(x, topo, w, n_tri, tri_nm, tri_m):
    # The costly part (polygon, Gauss points, inverse maps) depends on the 16
    # plane coordinates q only and the gaps are linear in the 8 heights h, so
    # the Hessian is taken in (q, h) -- 16 forward-over-reverse directions
    # instead of 24, the h-h block is zero -- and chained through the cheap
    # 24 -> 24 projection, curvature of the projection included.
    x = x.reshape(24)
    plane = partial(_plane_coordinates, tri_nm=tri_nm, tri_m=tri_m)
    y, Jy = plane(x), jax.jacfwd(plane)(x)
    q, h = y[:16], y[16:]

    def grad_q(qq):
        def f(q_):
            C, a = polygon_operator(q_, topo, n_tri, tri_nm, tri_m)
            c = w[:4] @ C  # (8,) coefficients of the heights
            return jnp.dot(c, h) + jnp.dot(w[4:], a), c

        return jax.grad(f, has_aux=True)(qq)

    (fq, c), lin = jax.linearize(grad_q, q)
    A, B = jax.vmap(lin, out_axes=-1)(jnp.eye(16, dtype=q.dtype))  # (16, 16), (8, 16)
    Hy = jnp.block([[A, B.T], [B, jnp.zeros((8, 8), dtype=q.dtype)]])
    fy = jax.lax.stop_gradient(jnp.concatenate([fq, c]))
    # second-order part of the chain rule: curvature of the projection itself
    Hproj = jax.hessian(lambda z: jnp.dot(fy, plane(z)))(x)
    H = Jy.T @ Hy @ Jy + Hproj
    return 0.5 * (H + H.T)  # symmetric to the last bit, as the assembled tangent expects


@partial(jax.jit, static_argnames=("n_tri", "tri_nm", "tri_m"))
def _hessian_batch(X, topo, w, n_tri, tri_nm=False, tri_m=False):
    return jax.vmap(partial(_weighted_hessian_one, n_tri=n_tri, tri_nm=tri_nm, tri_m=tri_m))(X, topo, w)


# the kernels as called: through jax.export, traced once per variant and kept on disk (contopt.export_cache)
VALUES_BATCH = Kernel(_values_batch)
VALUES_JAC_BATCH = Kernel(_values_jac_batch)
HESSIAN_BATCH = Kernel(_hessian_batch)


def pad_chunk(a: np.ndarray, size: int) -> np.ndarray:
    """a (k, ...) padded to (size, ...) with copies of its last row (a chunk's fixed size)."""
    if len(a) == size:
        return a
    return np.concatenate([a, np.repeat(a[-1:], size - len(a), axis=0)], axis=0)


def run_chunked(fn, arrays, out_shapes, chunk):
    """``fn(*arrays, n_tri=...)`` over fixed-size chunks of the leading axis (last chunk padded with copies);
    ``arrays[1]`` is the pairs' topology (P, 8, 3), which sorts them into vertex-count buckets.

    Pairs are grouped by their polygon's vertex count: a quadrilateral overlap
    (the common case on meshes of similar size) needs 2 triangles instead of
    6, and the cost of every kernel is proportional to the Gauss points.
    """
    n = len(arrays[0])
    outs = [np.zeros((n,) + s) for s in out_shapes]
    n_vertices = (np.asarray(arrays[1])[:, :, 0] >= 0).sum(axis=1)
    X = np.asarray(arrays[0])
    tri_nm, tri_m = triangles(X[:, :4]), triangles(X[:, 4:])
    for n_tri, members, kinds in _kernel_variants(n_vertices, tri_nm, tri_m):
        # one compiled size per bucket: tracing the Hessian costs ~2 s per shape and process,
        # padding a few pairs up to a chunk costs milliseconds
        for start in range(0, len(members), chunk):
            idx = members[start : start + chunk]
            # numpy in: the jitted call moves it to the device (contopt.assembly.kernels.run_chunked)
            res = fn(*[pad_chunk(a[idx], chunk) for a in arrays], n_tri=n_tri, **kinds)
            res = res if isinstance(res, tuple) else (res,)
            for o, r in zip(outs, res):
                o[idx] = np.asarray(r)[: len(idx)]
    return outs


def _kernel_variants(n_vertices: np.ndarray, tri_nm: np.ndarray, tri_m: np.ndarray):
    """[(n_tri, indices, static facet kinds)] of the non-empty groups of pairs: by vertex bucket and
    by (nonmortar, mortar) facet kind; quad pairs pass no kind (the quad kernels as they were)."""
    out = []
    for tn in (False, True):
        for tm in (False, True):
            kinds = {"tri_nm": True} if tn else {}
            kinds |= {"tri_m": True} if tm else {}
            sel = (tri_nm == tn) & (tri_m == tm)
            for n_tri, members in triangle_buckets(np.where(sel, n_vertices, -1)):
                if len(members):
                    out.append((n_tri, members, kinds))
    return out


def triangle_buckets(n_vertices: np.ndarray):
    """[(n_tri, indices)] over :data:`TRIANGLE_BUCKETS`."""
    out, lower = [], -1
    for max_vertices, n_tri in TRIANGLE_BUCKETS:
        out.append((n_tri, np.flatnonzero((n_vertices > lower) & (n_vertices <= max_vertices))))
        lower = max_vertices
    return out


def check_pairs(X, topo):
    X = np.asarray(X, dtype=np.float64)
    topo = np.asarray(topo, dtype=np.int32)
    if X.ndim != 3 or X.shape[1:] != (8, 3):
        raise ValueError(f"X must have shape (P, 8, 3) (4 nonmortar then 4 mortar nodes), got {X.shape}")
    if topo.shape != (X.shape[0], 8, 3):
        raise ValueError(f"topo must have shape (P, 8, 3) matching X, got {topo.shape}")
    return X, topo


def pair_values(X, topo, chunk: int = DEFAULT_CHUNK):
    """Weighted gaps and areas of P pairs.

    Parameters
    ----------
    X : (P, 8, 3) nodes of each pair (4 nonmortar, then 4 mortar)
    topo : (P, 8, 3) topology from ``segment_pairs(...).topo``

    Returns
    -------
    g : (P, 4), a : (P, 4) numpy float64
    """
    X, topo = check_pairs(X, topo)
    return tuple(run_chunked(VALUES_BATCH, (X, topo), [(4,), (4,)], chunk))


def pair_values_and_jacobians(X, topo, chunk: int = DEFAULT_CHUNK):
    """Weighted gaps, areas and their exact derivatives for P pairs.

    Returns
    -------
    g : (P, 4), a : (P, 4)
    J : (P, 8, 24) rows 0..3 = dg_A/dx, rows 4..7 = da_A/dx; columns node-major
        (node 0 x, y, z, node 1 x, ...), nodes 0..3 nonmortar, 4..7 mortar
    """
    X, topo = check_pairs(X, topo)
    return tuple(run_chunked(VALUES_JAC_BATCH, (X, topo), [(4,), (4,), (8, 24)], chunk))


def pair_weighted_hessians(X, topo, w, chunk: int = DEFAULT_CHUNK):
    """Hessians (P, 24, 24) of ``s = sum_A w[:, A] g_A + w[:, 4 + A] a_A`` per pair.

    Parameters
    ----------
    X : (P, 8, 3); topo : (P, 8, 3); w : (P, 8) weights of (g_0..g_3, a_0..a_3)
    """
    X, topo = check_pairs(X, topo)
    w = np.asarray(w, dtype=np.float64)
    if w.shape != (X.shape[0], 8):
        raise ValueError(f"w must have shape (P, 8), got {w.shape}")
    return run_chunked(HESSIAN_BATCH, (X, topo, w), [(24, 24)], chunk)[0]


def precompile(chunk: int = DEFAULT_CHUNK) -> float:
    """Compile (or load from the persistent cache) every kernel variant; returns the seconds spent.

    The kernels otherwise compile on first use, in the middle of a Newton
    solve; benchmarks call this first so that per-iteration timings are
    steady-state figures and compilation is reported on its own.
    """
    clock = Stopwatch()
    for _, n_tri in TRIANGLE_BUCKETS:
        X = jnp.zeros((chunk, 8, 3))
        topo = jnp.full((chunk, 8, 3), -1, dtype=jnp.int32)
        jax.block_until_ready(VALUES_BATCH(X, topo, n_tri=n_tri))
        jax.block_until_ready(VALUES_JAC_BATCH(X, topo, n_tri=n_tri))
        jax.block_until_ready(HESSIAN_BATCH(X, topo, jnp.zeros((chunk, 8)), n_tri=n_tri))
    return clock.seconds
