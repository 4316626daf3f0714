"""Contact contributions to the residual and tangent, for every interface of a model.

Per evaluation (every Newton iteration, so large sliding is followed):
search (numpy) -> segmentation topology (numpy) -> mortar integrals and
their derivatives (JAX) -> node terms of the penalty / ALM potential ->
residual ``sum_A dphi/dg dg_A + dphi/da da_A`` and tangent
``sum_A (eps H/a) w_A w_A^T + sum_pairs (weighted second derivatives)``
(see :mod:`contopt.contact.enforcement`). The tangent is exact.

The multipliers ``p`` (one array per interface, over its nonmortar nodes)
are inputs: the ALM loop that updates them lives in the solver.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from contopt.contact.enforcement import NodeTerms, node_terms
from contopt.contact.interface import ContactInterface, facet_sizes
from contopt.contact.mortar import pair_values, pair_values_and_jacobians, pair_weighted_hessians
from contopt.contact.search import candidate_pairs, facing_filter
from contopt.contact.segment import segment_pairs
from contopt.fem.hex8 import quad_gauss


@dataclass(frozen=True, eq=False)
class InterfaceBlock:
    """Precomputed data of one interface.

    Attributes
    ----------
    nm_facet_nodes : (F, 4) global node ids of the nonmortar facets
    m_facet_nodes : (G, 4) global node ids of the mortar facets
    nodes : (n,) global ids of the nonmortar nodes (the multiplier unknowns)
    nm_local : (F, 4) index of each nonmortar facet node in ``nodes``
    eps, skin : enforcement parameters in use
    h : median nonmortar facet size (reference)
    """

    interface: ContactInterface
    nm_facet_nodes: np.ndarray
    m_facet_nodes: np.ndarray
    nodes: np.ndarray
    nm_local: np.ndarray
    body: int
    eps: float
    skin: float
    h: float

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.size)


@dataclass(frozen=True, eq=False)
class InterfaceResult:
    """What one interface looked like at one evaluation (all arrays over its nonmortar nodes)."""

    g: np.ndarray
    a: np.ndarray
    has_overlap: np.ndarray
    terms: NodeTerms | None
    lam: np.ndarray
    n_pairs: int
    #: with a tangent: rows ``w_A = dg_A - gbar_A da_A`` (n, n_dofs) of the live pairs, and the
    #: rank-one weights ``stiff_A = eps H_A / a_A`` (n,): the contact tangent's ``W^T diag(stiff) W``.
    #: The adjoint uses them as the constraint gradients and their penalty.
    W: sp.csr_matrix | None = None
    stiff: np.ndarray | None = None

    @property
    def n_active(self) -> int:
        return int(np.count_nonzero(self.lam > 0))


@dataclass(frozen=True, eq=False)
class ContactEvaluation:
    """Residual (n_dofs,), exact tangent ``K`` and its part ``K_normal`` without the
    second derivatives of the mortar integrals (the positive semi-definite
    ``sum_A (eps H_A / a_A) w_A w_A^T``), potential, per-interface results."""

    r: np.ndarray
    K: sp.csr_matrix | None
    energy: float
    results: tuple
    seconds: float
    K_normal: sp.csr_matrix | None = None


@dataclass(frozen=True, eq=False)
class ContactDiscretization:
    """All interfaces of a model, with the global node coordinates they need."""

    blocks: tuple
    X: np.ndarray  # (n_nodes_total, 3) reference coordinates of all bodies stacked
    n_dofs: int

    @property
    def empty(self) -> bool:
        return not self.blocks

    def zero_multipliers(self) -> tuple:
        return tuple(np.zeros(b.n_nodes) for b in self.blocks)

    def evaluate(self, u: np.ndarray, p: tuple, tangent: bool = True, eps: tuple | None = None,
                 touch: float = 0.0) -> ContactEvaluation:
        """Contact residual (n_dofs,), tangent (CSR) and potential at displacement u.

        ``p``: multipliers per interface; ``eps``: penalty per interface
        (default: each interface's own, ``block.eps``); ``touch`` (a length):
        nodes whose trial gap is below it count as closed in the tangent (see
        :func:`contopt.contact.enforcement.node_terms`; at least 1e-10 h).
        """
        eps = eps if eps is not None else tuple(b.eps for b in self.blocks)
        t0 = time.perf_counter()
        x = self.X + u.reshape(-1, 3)
        r = np.zeros(self.n_dofs)
        normal, geometric, energy, results = [], [], 0.0, []
        for block, p_block, eps_block in zip(self.blocks, p, eps):
            res, r_b, K_b, e_b = _evaluate_interface(block, x, p_block, eps_block, self.n_dofs, tangent, touch)
            r += r_b
            energy += e_b
            results.append(res)
            if K_b is not None:
                normal.append(K_b[0])
                geometric.append(K_b[1])
        K = K_normal = None
        if tangent:
            K_normal = sum(normal, sp.csr_matrix((self.n_dofs, self.n_dofs))).tocsr()
            K = (K_normal + sum(geometric, sp.csr_matrix((self.n_dofs, self.n_dofs)))).tocsr()
        return ContactEvaluation(r=r, K=K, energy=energy, results=tuple(results),
                                 seconds=time.perf_counter() - t0, K_normal=K_normal)

    def penetration(self, results: tuple, enforcement: tuple = ("alm", "penalty")) -> float:
        """Deepest normalized penetration ``max(0, -g_A/a_A) / h`` over the interfaces with these enforcements."""
        pen = 0.0
        for block, res in zip(self.blocks, results):
            if block.interface.enforcement in enforcement and res.terms is not None:
                pen = max(pen, float(np.maximum(0.0, -res.terms.gbar).max(initial=0.0)) / block.h)
        return pen

    def pressure_fields(self, lam: tuple, bodies, node_offsets) -> dict:
        """Nodal contact pressure per nonmortar body, for output: {body name: {"contact_pressure": (n_nodes,)}}.

        ``bodies``: the model's bodies; ``node_offsets``: each body's first global node id.
        """
        out: dict = {}
        for block, lam_b in zip(self.blocks, lam):
            body = bodies[block.body]
            field = out.setdefault(body.name, {}).setdefault("contact_pressure", np.zeros(body.mesh.n_nodes))
            field[block.nodes - node_offsets[block.body]] += lam_b
        return out

    def total_force(self, u: np.ndarray, lam: tuple) -> np.ndarray:
        """(n_interfaces,) total contact force ``∫ lam da`` over the deformed nonmortar surfaces."""
        x = self.X + u.reshape(-1, 3)
        out = []
        for block, lam_b in zip(self.blocks, lam):
            w = nodal_areas(x[block.nm_facet_nodes])  # (F, 4)
            out.append(float(np.sum(w * lam_b[block.nm_local])))
        return np.array(out)


def nodal_areas(x: np.ndarray) -> np.ndarray:
    """(F, 4) ``∫ N_A da`` of each node over each deformed bilinear facet x (F, 4, 3) (2x2 Gauss)."""
    N, dN, w = quad_gauss(2)
    tang = np.einsum("fai,qak->fqki", x, dN)  # (F, q, 2, 3)
    da = np.linalg.norm(np.cross(tang[:, :, 0], tang[:, :, 1]), axis=-1)  # (F, q)
    return np.einsum("q,fq,qa->fa", w, da, N)


def _evaluate_interface(block: InterfaceBlock, x: np.ndarray, p: np.ndarray, eps: float, n_dofs: int,
                        tangent: bool, touch: float = 0.0):
    n = block.n_nodes
    x_nm, x_m = x[block.nm_facet_nodes], x[block.m_facet_nodes]
    pairs = candidate_pairs(x_nm, x_m, block.skin)
    if len(pairs):
        pairs = facing_filter(x_nm, x_m, pairs, block.interface.max_angle_deg, skin=block.skin)
    empty = InterfaceResult(g=np.zeros(n), a=np.zeros(n), has_overlap=np.zeros(n, bool), terms=None,
                            lam=np.zeros(n), n_pairs=0)
    if len(pairs) == 0:
        return empty, np.zeros(n_dofs), None, 0.0
    seg = segment_pairs(x_nm[pairs[:, 0]], x_m[pairs[:, 1]], max_angle_deg=block.interface.max_angle_deg)
    keep = np.asarray(seg.active)
    pairs, topo = pairs[keep], np.asarray(seg.topo)[keep]
    if len(pairs) == 0:
        return empty, np.zeros(n_dofs), None, 0.0
    X8 = np.concatenate([x_nm[pairs[:, 0]], x_m[pairs[:, 1]]], axis=1)  # (P, 8, 3)
    gp, ap = pair_values(X8, topo)
    loc = block.nm_local[pairs[:, 0]]  # (P, 4) local node ids
    g = np.bincount(loc.ravel(), weights=gp.ravel(), minlength=n)
    a = np.bincount(loc.ravel(), weights=ap.ravel(), minlength=n)
    # nodes whose overlap is a vanishing sliver carry no constraint (no division by ~0)
    has = a > 1e-10 * block.h**2
    terms = node_terms(g[has], a[has], p[has], eps, touch=max(touch, 1e-10 * block.h))
    d_g, d_a, gbar, stiff, lam = (np.zeros(n) for _ in range(5))
    d_g[has], d_a[has], gbar[has], stiff[has], lam[has] = terms.d_g, terms.d_a, terms.gbar, terms.stiff, terms.lam
    result = InterfaceResult(g=g, a=a, has_overlap=has, terms=terms, lam=lam, n_pairs=len(pairs))
    energy = float(terms.energy.sum())
    # derivatives only where the potential is not locally flat: open nodes with p = 0 have
    # zero weights and zero stiffness, and most candidate pairs are of that kind
    weights = np.concatenate([d_g[loc], d_a[loc]], axis=1)  # (P, 8)
    live = (weights != 0).any(axis=1) | (stiff[loc] != 0).any(axis=1)
    if not live.any():
        zero = sp.csr_matrix((n_dofs, n_dofs))
        if tangent:
            result = replace(result, W=sp.csr_matrix((n, n_dofs)), stiff=stiff)
        return result, np.zeros(n_dofs), ((zero, zero) if tangent else None), energy
    X8, topo, loc, weights = X8[live], topo[live], loc[live], weights[live]
    live_pairs = pairs[live]
    _, _, J = pair_values_and_jacobians(X8, topo)
    nodes8 = np.concatenate([block.nm_facet_nodes[live_pairs[:, 0]], block.m_facet_nodes[live_pairs[:, 1]]], axis=1)
    dofs = (3 * nodes8[:, :, None] + np.arange(3)).reshape(-1, 24)
    r_pairs = np.einsum("pk,pkj->pj", weights, J)
    r = np.bincount(dofs.ravel(), weights=r_pairs.ravel(), minlength=n_dofs)
    if not tangent:
        return result, r, None, energy
    # rank-one node terms: W has one row per node, w_A = dg_A - gbar_A da_A
    rows = np.repeat(loc, 24, axis=1).reshape(-1, 4, 24)
    vals = J[:, :4, :] - gbar[loc][:, :, None] * J[:, 4:, :]  # (P, 4, 24)
    cols = np.broadcast_to(dofs[:, None, :], vals.shape)
    W = sp.csr_matrix((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(n, n_dofs))
    K1 = (W.T @ sp.diags(stiff) @ W).tocsr()
    result = replace(result, W=W, stiff=stiff)
    H = pair_weighted_hessians(X8, topo, weights)  # (P, 24, 24)
    K2 = sp.csr_matrix((H.ravel(), (np.repeat(dofs, 24, axis=1).ravel(), np.tile(dofs, (1, 24)).ravel())),
                       shape=(n_dofs, n_dofs))
    return result, r, (K1, K2), energy


def discretize_contact(model, disc) -> ContactDiscretization:
    """Precompute every interface of ``model`` on top of its bulk discretization ``disc``."""
    X = np.concatenate([b.mesh.points for b in model.bodies], axis=0)
    blocks = []
    for iface in model.interfaces:
        ids = []
        for side in ("nonmortar", "mortar"):
            body_name, facet_set = getattr(iface, side)
            i = model.body_index(body_name)
            mesh = model.bodies[i].mesh
            ids.append(disc.blocks[i].node_offset + mesh.facet_nodes(facet_set))
        nm, m = ids
        nodes, local = np.unique(nm, return_inverse=True)
        h = float(np.median(facet_sizes(X[nm])))
        eps = iface.eps if iface.eps is not None else iface.default_eps(model)
        skin = iface.skin if iface.skin is not None else 0.5 * h
        blocks.append(InterfaceBlock(interface=iface, nm_facet_nodes=nm, m_facet_nodes=m, nodes=nodes,
                                     nm_local=local.reshape(nm.shape), body=model.body_index(iface.nonmortar[0]),
                                     eps=float(eps), skin=float(skin), h=h))
    return ContactDiscretization(blocks=tuple(blocks), X=X, n_dofs=disc.n_dofs)
