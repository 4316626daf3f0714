"""Coulomb friction on the mortar segments: slip, return mapping, and their exact derivatives.

Kinematics (docs/formulation.md, "Friction"). For each (nonmortar, mortar) facet pair the mortar
operator ``C`` of :func:`contopt.contact.mortar.polygon_operator` maps the 8 nodal positions to
``∫ N_A (x_m - x_nm) da`` (4 x 3) over the overlap. Applied to the step's displacement increment
``x - x_prev`` it gives the relative displacement of the material points that are in contact now;
its part in the pair's auxiliary plane, with the sign of the nonmortar moving over the mortar, is

    s_A = -(I - n0 n0^T) ∫ N_A (Δx_m - Δx_nm) da              (a volume: area x length)

summed over the node's pairs. It is frame indifferent: a rigid motion of both bodies moves
coincident points alike, and ``s`` is evaluated at the current overlap.

Law per nonmortar node A (pressures, force per area). With the node's normal ``n_A`` (the
``a``-weighted mean of its pairs' plane normals), ``P = I - n_A n_A^T``, the normal pressure
``lam_A`` of the normal law and the traction ``t_prev`` at the end of the last load step:

    trial:  t* = P t_prev + eps_t P s_A / a_A
    stick:  |t*| <= mu lam_A   ->  t_A = t*
    slip:   otherwise           ->  t_A = mu lam_A t* / |t*|   (return onto the Coulomb cone)

The nodal forces are the virtual work of the tractions on the relative motion of the points in
contact, ``r = sum_A (d s_A / d x_moved)^T t_A``: the slip differentiated in the moved positions
alone, the overlap and its weights held (``-(P0 C) ⊗ I`` per pair), so the friction force a body
receives is ``sum_A a_A t_A`` whatever the step size. Stick is a penalty (``eps_t``: traction per
unit elastic slip); slip is exact. The residual has no potential, so the tangent

    K = sum_A (d s_A/dx_moved)^T (d t_A/d z_A) (d z_A/dx) + d/dx [sum_pairs (d s/dx_moved)^T t],
    z_A = (g_A, a_A, s_A, m_A),  m_A = sum_pairs a_A n0

is unsymmetric; both parts come from JAX (the node law through ``jacfwd`` of the return map, the
pair integrals as in :mod:`contopt.contact.mortar`, the overlap's motion and the plane's rotation
included), so it is exact, slip direction and cone curvature included.

The law's options (``mu``, ``eps``, ``edge``) are :class:`contopt.contact.coulomb.Coulomb`, apart
from these kernels so that a Model describing friction loads no JAX.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp

from contopt.contact.mortar import DEFAULT_CHUNK, as_quads, auxiliary_basis, check_pairs, polygon_operator, run_chunked
from contopt.contact.quadratic import quadratic_slip_hessians, quadratic_slips_and_jacobians
from contopt.export_cache import Kernel

#: per nonmortar node of a pair: weighted gap, area, slip (3), area-weighted normal (3)
N_Z = 8
#: nodes per call of the node law (padded): one compiled shape
NODE_CHUNK = 256


# ------------------------------------------------------------------------------ pair kernel
def pair_slip(x, x_prev, topo, n_tri, x_moved=None, tri_nm=False, tri_m=False):
    """z (4, 8) of ONE pair: per nonmortar node ``(g, a, s (3), a n0 (3))`` (module docstring).

    x, x_prev : (24,) current and last-step positions (node-major, 4 nonmortar then 4 mortar);
    topo : (8, 3) the overlap polygon's topology. ``x_moved`` (default x): the positions whose
    increment over ``x_prev`` is the slip, while the overlap, its weights and the plane are those
    of ``x``; the residual differentiates the slip in ``x_moved`` alone (virtual work). ``tri_nm``,
    ``tri_m`` (static): that facet is a triangle (:func:`contopt.contact.mortar.pair_integrals`).
    """
    x8 = as_quads(x.reshape(8, 3), tri_nm, tri_m)
    moved = x8 if x_moved is None else x_moved.reshape(8, 3)
    y, n0, t1, t2 = auxiliary_basis(x8)
    q = jnp.stack([y @ t1, y @ t2], axis=-1).reshape(16)
    C, a = polygon_operator(q, topo, n_tri, tri_nm, tri_m)
    g = C @ (y @ n0)
    rel = C @ (moved - x_prev.reshape(8, 3))  # (4, 3) ∫ N_A (Δx_m - Δx_nm) da
    s = -(rel - (rel @ n0)[:, None] * n0[None, :])
    return jnp.concatenate([g[:, None], a[:, None], s, a[:, None] * n0[None, :]], axis=1)


def _slip_rows(x, x_prev, topo, n_tri, kinds):
    """(4, 3, 24) the derivative of the slips in the moved positions: ``-(P0 C) ⊗ I`` (virtual work)."""
    return jax.jacfwd(lambda y: pair_slip(x, x_prev, topo, n_tri, x_moved=y, **kinds)[:, 2:5])(x)


@partial(jax.jit, static_argnames=("n_tri", "tri_nm", "tri_m"))
def _pair_jac_batch(X, topo, Xp, n_tri, tri_nm=False, tri_m=False):
    kinds = {"tri_nm": tri_nm, "tri_m": tri_m}

    def one(x, topo_, x_prev):
        x, x_prev = x.reshape(24), x_prev.reshape(24)
        f = partial(pair_slip, x_prev=x_prev, topo=topo_, n_tri=n_tri, tri_nm=tri_nm, tri_m=tri_m)
        return f(x), jax.jacfwd(f)(x), _slip_rows(x, x_prev, topo_, n_tri, kinds)

    return jax.vmap(one)(X, topo, Xp)


@partial(jax.jit, static_argnames=("n_tri", "tri_nm", "tri_m"))
def _pair_hessian_batch(X, topo, Xp, w, n_tri, tri_nm=False, tri_m=False):
    kinds = {"tri_nm": tri_nm, "tri_m": tri_m}

    def one(x, topo_, x_prev, w_):
        x, x_prev = x.reshape(24), x_prev.reshape(24)
        # d/dx of the pair's forces sum_A (ds_A/dx_moved)^T w_A: rows forces, columns positions
        return jax.jacfwd(lambda z: jnp.einsum("kc,kcj->j", w_, _slip_rows(z, x_prev, topo_, n_tri, kinds)))(x)

    return jax.vmap(one)(X, topo, Xp, w)


PAIR_JAC = Kernel(_pair_jac_batch)
PAIR_HESSIAN = Kernel(_pair_hessian_batch)


def pair_slips_and_jacobians(X, X_prev, topo, chunk: int = DEFAULT_CHUNK):
    """z (P, 4, 8), dz/dx (P, 4, 8, 24) and the slips' virtual-work rows ds/dx_moved (P, 4, 3, 24)
    of P pairs (X, X_prev: (P, 8, 3); topo (P, 8, 3))."""
    X, topo = check_pairs(X, topo)
    X_prev, _ = check_pairs(X_prev, topo)
    return tuple(run_chunked(PAIR_JAC, (X, topo, X_prev), [(4, N_Z), (4, N_Z, 24), (4, 3, 24)], chunk))


def pair_slip_hessians(X, X_prev, topo, w, chunk: int = DEFAULT_CHUNK):
    """(P, 24, 24) derivatives of the pairs' friction forces ``sum_A (ds_A/dx_moved)^T w_A`` in the
    positions (rows: forces, columns: positions; w: (P, 4, 3) tractions)."""
    X, topo = check_pairs(X, topo)
    X_prev, _ = check_pairs(X_prev, topo)
    w = np.asarray(w, dtype=np.float64)
    return run_chunked(PAIR_HESSIAN, (X, topo, X_prev, w), [(24, 24)], chunk)[0]


# -------------------------------------------------------------------------------- node law
def node_traction(z, t_prev, p, eps_n, eps_t, mu, closed, edge=0.0):
    """Friction traction (3,) of one node and whether it sticks (module docstring).

    z (8,): ``(g, a, s, m)``; t_prev (3,); p, eps_n: the normal law's multiplier and penalty
    (``lam = max(0, p - eps_n g/a)``); closed: the normal law counts the node closed (its
    tangent has the normal stiffness). A closed node without pressure sticks in the tangent (the
    generalized derivative the normal law takes at touching surfaces) with zero traction. edge:
    half-width ``delta`` of the rounded cone edge (:func:`cone_magnitude`); 0 is the sharp cone.
    """
    g, a, s, m = z[0], z[1], z[2:5], z[5:8]
    lam = jnp.maximum(p - eps_n * g / a, 0.0)
    m2 = jnp.dot(m, m)
    n = jnp.where(m2 > 0, m / jnp.sqrt(jnp.where(m2 > 0, m2, 1.0)), 0.0)

    def tangential(v):
        return v - jnp.dot(v, n) * n

    trial = tangential(t_prev) + eps_t * tangential(s) / a
    t2 = jnp.dot(trial, trial)
    norm = jnp.sqrt(jnp.where(t2 > 0, t2, 1.0))
    bound = mu * lam
    engaged = closed & (mu > 0)
    x = jnp.where(t2 > 0, norm, 0.0) / jnp.where(bound > 0, bound, 1.0)
    stick = engaged & (jnp.where(bound > 0, x <= 1.0 - edge, t2 == 0))
    # on the cone (or inside its rounded edge): |t| = bound f(x), along the trial traction
    scale = jnp.where(bound > 0, cone_magnitude(x, edge) / jnp.where(x > 0, x, 1.0), 0.0)
    t = jnp.where(stick, trial, jnp.where(engaged, scale * trial, 0.0))
    return t, stick


def cone_magnitude(x, edge):
    """The traction's magnitude over ``mu lam`` against the trial's, ``x = |t*| / (mu lam)``.

    ``min(x, 1)`` with its corner rounded over ``1 - delta < x < 1 + delta`` (``delta = edge``) by
    the parabola ``x - (x - 1 + delta)^2 / (4 delta)``: value and slope continuous, so Newton does
    not cycle between the stick and the slip linearization of a node whose trial traction ends on
    the cone. The rounded law never exceeds the cone and differs from it by at most
    ``delta / 4 * mu lam`` (at ``x = 1``); ``delta = 0`` is the sharp cone.
    """
    # evaluated on the band only: the branches jnp.where does not take stay finite
    xb = jnp.clip(x, 1.0 - edge, 1.0 + edge)
    rounded = xb - (xb - 1.0 + edge) ** 2 / (4.0 * jnp.maximum(edge, 1e-300))
    return jnp.where(x <= 1.0 - edge, x, jnp.where(x >= 1.0 + edge, 1.0, rounded))


def _node_one(z, t_prev, p, eps_n, eps_t, mu, closed, edge):
    f = partial(node_traction, p=p, eps_n=eps_n, eps_t=eps_t, mu=mu, closed=closed, edge=edge)
    t, stick = f(z, t_prev)
    return t, stick, jax.jacfwd(lambda zz: f(zz, t_prev)[0])(z), jax.jacfwd(lambda tt: f(z, tt)[0])(t_prev)


@jax.jit
def _node_batch(z, t_prev, p, eps_n, eps_t, mu, closed, edge):
    return jax.vmap(_node_one)(z, t_prev, p, eps_n, eps_t, mu, closed, edge)


NODE_LAW = Kernel(_node_batch)


def node_tractions(z, t_prev, p, eps_n, eps_t: float, mu: float, closed, edge: float = 0.0):
    """The node law over k nodes: tractions (k, 3), stick (k,) bool, dt/dz (k, 3, 8), dt/dt_prev (k, 3, 3).

    z (k, 8); t_prev (k, 3); p, eps_n (k,); closed (k,) bool; edge: the cone's rounding.
    """
    k = len(z)
    out_t, out_s, out_d, out_h = np.zeros((k, 3)), np.zeros(k, bool), np.zeros((k, 3, N_Z)), np.zeros((k, 3, 3))
    args = [
        np.asarray(z, np.float64),
        np.asarray(t_prev, np.float64),
        np.asarray(p, np.float64),
        np.asarray(eps_n, np.float64) * np.ones(k),
        np.full(k, float(eps_t)),
        np.full(k, float(mu)),
        np.asarray(closed, bool),
        np.full(k, float(edge)),
    ]
    # padding repeats a real node: its values are finite, and they are cut off again
    for start in range(0, k, NODE_CHUNK):
        idx = np.arange(start, min(start + NODE_CHUNK, k))
        pad = np.concatenate([idx, np.full(NODE_CHUNK - len(idx), idx[-1])])
        t, s, d, h = NODE_LAW(*[jnp.asarray(a[pad]) for a in args])
        out_t[idx], out_s[idx], out_d[idx], out_h[idx] = (np.asarray(v)[: len(idx)] for v in (t, s, d, h))
    return out_t, out_s, out_d, out_h


# ------------------------------------------------------------------------------- assembly
@dataclass(frozen=True, eq=False)
class FrictionTerms:
    """One interface's friction at one evaluation.

    traction : (n, 3) nodal friction tractions (force per area; on the nonmortar, along its slip
    over the mortar: the force on the nonmortar body is ``-traction``); stick : (n,) bool (False
    where the node carries no friction); r : (n_dofs,) residual; K : (n_dofs, n_dofs) CSR tangent
    (unsymmetric) or None.

    With the tangent, what a path adjoint needs (:mod:`contopt.adjoint.path`): S : (3 n, n_dofs) the
    slips' virtual-work rows (``r = S^T t``); Z : (8 n, n_dofs) ``dz/dx``; D : (n, 3, 8) ``dt/dz``;
    T : (n, 3, 3) ``dt/dt_prev`` (the slips depend on the last step's positions through ``-S``).
    """

    traction: np.ndarray
    stick: np.ndarray
    r: np.ndarray | None
    K: sp.csr_matrix | None
    S: sp.csr_matrix | None = None
    Z: sp.csr_matrix | None = None
    D: np.ndarray | None = None
    T: np.ndarray | None = None

    @property
    def n_stick(self) -> int:
        return int(np.count_nonzero(self.stick))

    @property
    def n_slip(self) -> int:
        return int(np.count_nonzero((np.abs(self.traction).sum(axis=1) > 0) & ~self.stick))


def friction_terms(
    X8,
    X8_prev,
    topo,
    loc,
    dofs,
    n: int,
    n_dofs: int,
    t_prev,
    p,
    eps_n,
    eps_t: float,
    mu: float,
    closed,
    tangent,
    edge: float = 0.0,
    sub=None,
    kinds=None,
) -> FrictionTerms:
    """Friction residual and tangent of one interface's live pairs.

    X8, X8_prev : (P, 8, 3) current and last-step positions of each pair's nodes; topo (P, 8, 3);
    loc : (P, 4) the pairs' nonmortar nodes in the interface's node list; dofs : (P, 24) global
    dofs; n : nonmortar nodes; t_prev (n, 3); p, eps_n (n,) the normal law's multipliers and
    penalties; closed (n,) bool: the normal law counts the node closed in its tangent; edge: the
    cone's rounding (:class:`contopt.contact.coulomb.Coulomb`). With a tet10 side, ``kinds`` and
    ``sub`` (P, 2) (:class:`contopt.contact.pairing.PairBatch`): 12 nodes a pair (X8, X8_prev
    (P, 12, 3), loc (P, 6), dofs (P, 36)) and the quadratic kernels
    (:func:`contopt.contact.quadratic.quadratic_pair_slip`).
    """
    if kinds is None:
        z_pairs, J, Js = pair_slips_and_jacobians(X8, X8_prev, topo)
    else:
        z_pairs, J, Js = quadratic_slips_and_jacobians(X8, X8_prev, topo, sub, kinds)
    z = np.zeros((n, N_Z))
    np.add.at(z, loc.ravel(), z_pairs.reshape(-1, N_Z))
    nodes = np.flatnonzero(closed & (z[:, 1] > 0))
    traction, stick = np.zeros((n, 3)), np.zeros(n, bool)
    r = np.zeros(n_dofs)
    if len(nodes) == 0:
        if not tangent:
            return FrictionTerms(traction=traction, stick=stick, r=r, K=None)
        return FrictionTerms(
            traction=traction,
            stick=stick,
            r=r,
            K=sp.csr_matrix((n_dofs, n_dofs)),
            S=sp.csr_matrix((3 * n, n_dofs)),
            Z=sp.csr_matrix((N_Z * n, n_dofs)),
            D=np.zeros((n, 3, N_Z)),
            T=np.zeros((n, 3, 3)),
        )
    t, s, dt, dh = node_tractions(
        z[nodes], t_prev[nodes], p[nodes], eps_n[nodes], eps_t, mu, np.ones(len(nodes), bool), edge
    )
    traction[nodes], stick[nodes] = t, s
    # residual: the virtual work sum_A t_A . delta s_A (slip rows in the moved positions)
    w = traction[loc]  # (P, 4|6, 3)
    r_pairs = np.einsum("pkc,pkcj->pj", w, Js)
    r = np.bincount(dofs.ravel(), weights=r_pairs.ravel(), minlength=n_dofs)
    if not tangent:
        return FrictionTerms(traction=traction, stick=stick, r=r, K=None)
    Z = _node_rows(J, loc, dofs, n, n_dofs, N_Z)  # dz/dx (8 n, n_dofs)
    S = _node_rows(Js, loc, dofs, n, n_dofs, 3)  # virtual-work slip rows (3 n, n_dofs)
    # the law's Jacobians dt_A/dz_A as a (3 n, 8 n) block diagonal
    D = np.zeros((n, 3, N_Z))
    D[nodes] = dt
    T = np.zeros((n, 3, 3))
    T[nodes] = dh
    shape = (n, 3, N_Z)
    rows_b = np.broadcast_to(3 * np.arange(n)[:, None, None] + np.arange(3)[None, :, None], shape)
    cols_b = np.broadcast_to(N_Z * np.arange(n)[:, None, None] + np.arange(N_Z)[None, None, :], shape)
    B = sp.csr_matrix((D.ravel(), (rows_b.ravel(), cols_b.ravel())), shape=(3 * n, N_Z * n))
    K1 = (S.T @ (B @ Z)).tocsr()
    if kinds is None:
        H = pair_slip_hessians(X8, X8_prev, topo, w)
    else:
        H = quadratic_slip_hessians(X8, X8_prev, topo, sub, w, kinds)
    nd = dofs.shape[1]
    K2 = sp.csr_matrix(
        (H.ravel(), (np.repeat(dofs, nd, axis=1).ravel(), np.tile(dofs, (1, nd)).ravel())), shape=(n_dofs, n_dofs)
    )
    return FrictionTerms(traction=traction, stick=stick, r=r, K=(K1 + K2).tocsr(), S=S, Z=Z, D=D, T=T)


def _node_rows(J, loc, dofs, n: int, n_dofs: int, k: int) -> sp.csr_matrix:
    """Pair Jacobians J (P, 4, k, 24) summed into node rows (k n, n_dofs): row ``k A + c``."""
    rows = np.broadcast_to((k * loc[:, :, None] + np.arange(k)[None, None, :])[..., None], J.shape)
    cols = np.broadcast_to(dofs[:, None, None, :], J.shape)
    return sp.csr_matrix((J.ravel(), (rows.ravel(), cols.ravel())), shape=(k * n, n_dofs))
