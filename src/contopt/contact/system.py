"""Contact contributions to the residual and tangent, for every interface of a model.

Per evaluation (every Newton iteration, so large sliding is followed):
search (numpy) -> segmentation topology (numpy) -> mortar integrals and
their derivatives (JAX) -> node terms of each interface's contact law ->
residual ``sum_A dphi/dg dg_A + dphi/da da_A`` and tangent
``sum_A (eps H/a) w_A w_A^T + sum_pairs (weighted second derivatives)``
(see :mod:`contopt.contact.enforcement`). The tangent is exact.

The laws' states (one :class:`contopt.contact.laws.LawState` per interface:
multipliers, penalty in use) are inputs. Between Newton solves the solver
asks :meth:`ContactDiscretization.advance` what the laws decide, and after
a converged load step :meth:`ContactDiscretization.verify` checks the state
independently of the pairing (:mod:`contopt.contact.verify`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from contopt.contact.enforcement import NodeTerms
from contopt.contact.facets import as_contact_facets
from contopt.contact.friction import FrictionTerms, friction_terms
from contopt.contact.interface import ContactInterface, facet_sizes
from contopt.contact.laws import ContactLaw, LawState, deepest_penetration
from contopt.contact.pairing import (
    Parents,
    full_areas,
    pair_batch,
    paired,
    rejected_near_active,
    search,
    tri6_parents,
)
from contopt.contact.verify import SideAdvice, check_interface, coarse_side_warnings, depths
from contopt.errors import ConfigError
from contopt.timing import Stopwatch


@dataclass(frozen=True, eq=False)
class InterfaceBlock:
    """Precomputed data of one interface.

    Attributes
    ----------
    nm_facet_nodes : (F, 4) global node ids of the nonmortar facets
    m_facet_nodes : (G, 4) global node ids of the mortar facets
    nodes : (n,) global ids of the nonmortar nodes (the multiplier unknowns)
    nm_local : (F, 4) index of each nonmortar facet node in ``nodes``
    body, mortar_body : indices of the two bodies; node_offsets : their first global node ids
    eps : the law's own penalty on this interface; eps_max : the largest it may grow to; skin : search skin
    h : median nonmortar facet size (reference); eps_t : tangential penalty of friction (0 without)
    sides : what the mortar rule says of the sides (a coarse nonmortar under a finer or curved mortar)
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
    mortar_body: int = -1
    node_offsets: tuple = (0, 0)
    eps_t: float = 0.0
    sides: SideAdvice = SideAdvice()
    eps_max: float = math.inf
    #: with a tet10 side: the parent faces the quadratic kernels integrate on (gaps and slips)
    parents: Parents | None = None

    @property
    def friction(self):
        """The interface's :class:`contopt.contact.coulomb.Coulomb`, or None."""
        return self.interface.friction

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.size)

    @property
    def law(self) -> ContactLaw:
        return self.interface.law


@dataclass(frozen=True, eq=False)
class InterfaceResult:
    """What one interface looked like at one evaluation (all arrays over its nonmortar nodes).

    g, a : weighted gaps and overlap areas ``∫_overlap N_A da``; coverage : ``a_A / A_A`` with
    ``A_A = ∫ N_A da`` over the node's whole (deformed) support; has_overlap : a > 0;
    lam : pressures; rejected_near_active : facet pairs dropped as not facing / folded whose
    nonmortar facet has a node with pressure (reported by the state check)
    """

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
    coverage: np.ndarray | None = None
    rejected_near_active: int = 0
    #: with friction: the nodal tractions (n, 3) and stick flags (FrictionTerms without r and K)
    friction: FrictionTerms | None = None

    @property
    def traction(self) -> np.ndarray:
        """(n, 3) friction tractions on the nonmortar nodes (zeros without friction)."""
        return np.zeros((len(self.lam), 3)) if self.friction is None else self.friction.traction

    @property
    def friction_force(self) -> np.ndarray:
        """(3,) ``sum_A t_A a_A``: the friction force the nonmortar body exerts on the mortar body
        (along the nonmortar's slip; the nonmortar receives its opposite)."""
        return (self.traction * self.a[:, None]).sum(axis=0)

    @property
    def n_active(self) -> int:
        return int(np.count_nonzero(self.lam > 0))

    @property
    def contact_area(self) -> float:
        """``sum a_A`` over the nodes with pressure."""
        return float(self.a[self.lam > 0].sum())


@dataclass(frozen=True, eq=False)
class ContactEvaluation:
    """Residual (n_dofs,), exact tangent ``K`` and its part ``K_normal`` without the
    second derivatives of the mortar integrals (the positive semi-definite
    ``sum_A (eps H_A / a_A) w_A w_A^T``), potential, per-interface results."""

    r: np.ndarray
    K: sp.csr_matrix | None
    energy: float | None
    results: tuple
    seconds: float
    K_normal: sp.csr_matrix | None = None


@dataclass(frozen=True, eq=False)
class Advance:
    """What the laws decided after a Newton solve (see :meth:`ContactDiscretization.advance`).

    status : ``"done"``, ``"continue"`` or ``"failed"``; states : the laws' states to go on with;
    outcomes : per interface; message : why it failed
    """

    status: str
    states: tuple
    outcomes: tuple
    message: str = ""


@dataclass(frozen=True, eq=False)
class ContactDiscretization:
    """All interfaces of a model, with the global node coordinates they need."""

    blocks: tuple
    X: np.ndarray  # (n_nodes_total, 3) reference coordinates of all bodies stacked
    n_dofs: int

    @property
    def empty(self) -> bool:
        return not self.blocks

    # ---------------------------------------------------------------- the laws' states
    def start_states(self, multipliers: tuple = (), eps: tuple = ()) -> tuple:
        """Each interface's law state at the start of a solve: zero multipliers and the own
        penalty, or a warm start's ``multipliers`` and (grown) ``eps`` (one entry per interface)."""
        multipliers, eps = tuple(multipliers or ()), tuple(eps or ())
        for name, given in (("multipliers", multipliers), ("eps", eps)):
            if given and len(given) != len(self.blocks):
                raise ConfigError(
                    f"a warm start needs {name} for every contact interface ({len(self.blocks)}), got {len(given)}"
                )
        return tuple(
            b.law.start(
                b.n_nodes, b.eps, multipliers[i] if multipliers else None, float(eps[i]) if eps else None, b.eps_max
            )
            for i, b in enumerate(self.blocks)
        )

    def zero_multipliers(self) -> tuple:
        return tuple(np.zeros(b.n_nodes) for b in self.blocks)

    @property
    def has_friction(self) -> bool:
        return any(b.friction is not None for b in self.blocks)

    def loose_steps(self) -> list[str]:
        """The labels of the interfaces whose intermediate load steps end short of their law's
        equilibrium (an augmented Lagrangian that updates once per intermediate step; with friction
        every step converges, see :meth:`advance`)."""
        return [b.interface.label for b in self.blocks if not (b.law.converges_every_step or b.friction is not None)]

    def begin_step(self, states: tuple, u: np.ndarray | None = None) -> tuple:
        """The states at the start of a load step from the converged ``u`` (n_dofs,): the laws'
        outer-loop records cleared, and with friction the positions the step's slip is measured from."""
        states = tuple(b.law.begin_step(s) for b, s in zip(self.blocks, states))
        if not self.has_friction:
            return states
        x = self.X + (np.zeros(self.n_dofs) if u is None else np.asarray(u)).reshape(-1, 3)
        return tuple(
            s
            if b.friction is None
            else replace(s, x_prev=x, traction=np.zeros((b.n_nodes, 3)) if s.traction is None else s.traction)
            for b, s in zip(self.blocks, states)
        )

    def with_coverage(self, states: tuple, results: tuple) -> tuple:
        """The states with their per-node penalty factors set from an evaluation's coverage."""
        return tuple(b.law.with_coverage(s, r.coverage) for b, s, r in zip(self.blocks, states, results))

    def advance(self, results: tuple, states: tuple, final: bool, residual: float = 0.0) -> Advance:
        """Each law's update and test after a Newton solve whose last evaluation gave ``results``, its
        residual norm ``residual`` (what the laws may count as the equilibrium's noise).

        Done when every law is done (the states to carry on are then what each law returned:
        for a converged augmented Lagrangian the multipliers of the solve itself); failed as soon
        as one law fails; otherwise continue with the updated states.
        """
        # friction is path dependent: every load step converges its augmentations before its
        # tractions become the next step's history
        outcomes = tuple(
            b.law.advance(r, s, final or b.friction is not None, b.h, residual)
            for b, s, r in zip(self.blocks, states, results)
        )
        failed = [(b, o) for b, o in zip(self.blocks, outcomes) if o.status == "failed"]
        states = tuple(o.state for o in outcomes)
        if failed:
            return Advance(
                "failed",
                states,
                outcomes,
                "; ".join(f"contact interface {b.interface.label}: {o.message}" for b, o in failed),
            )
        done = all(o.status == "done" for o in outcomes)
        return Advance("done" if done else "continue", states, outcomes)

    def end_step(self, states: tuple, results: tuple, u: np.ndarray) -> tuple:
        """The states to carry to the next load step from a converged one at ``u`` with the last
        evaluation's ``results``: with friction its tractions, measured from ``u`` on (so that the
        state evaluated again at ``u`` gives the same forces)."""
        if not self.has_friction:
            return states
        x = self.X + np.asarray(u).reshape(-1, 3)
        return tuple(
            s if b.friction is None else replace(s, traction=r.traction.copy(), x_prev=x)
            for b, s, r in zip(self.blocks, states, results)
        )

    def retreat(self, states: tuple) -> tuple | None:
        """States to retry a failed Newton solve with (a law backing off), or None."""
        retreated = [b.law.retreat(s) for b, s in zip(self.blocks, states)]
        if all(r is None for r in retreated):
            return None
        return tuple(s if r is None else r for s, r in zip(states, retreated))

    def settle(self, results: tuple, states: tuple) -> Advance:
        """After a Newton solve that followed an update failed with nothing to retreat to: each
        law's verdict on the last converged solve (``results``, solved with ``states``), see
        :meth:`ContactLaw.settle`; done when every interface accepts it."""
        outcomes = tuple(b.law.settle(r, s, b.h) for b, s, r in zip(self.blocks, states, results))
        failed = [(b, o) for b, o in zip(self.blocks, outcomes) if o.status == "failed"]
        message = "; ".join(f"contact interface {b.interface.label}: {o.message}" for b, o in failed)
        return Advance("failed" if failed else "done", tuple(o.state for o in outcomes), outcomes, message)

    def early_stop(self, results: tuple, states: tuple) -> float | None:
        """How accurately the running Newton solve must be solved (see :meth:`ContactLaw.early_stop`):
        None or 0 means to the Newton tolerances, f > 0 stop at ``|r| <= f r_ref``. One interface's
        update follows the solve whatever the others say: the smallest f > 0 stands where there is one
        (an interface without contact, converged, made the seam's other interface solve every update
        to the Newton tolerances, 17 iterations by halves each)."""
        factors = [b.law.early_stop(r, s, b.h) for b, s, r in zip(self.blocks, states, results)]
        positive = [f for f in factors if f is not None and f > 0.0]
        return min(positive) if positive else None

    # ------------------------------------------------------------------- evaluation
    def evaluate(
        self, u: np.ndarray, states: tuple, tangent: bool = True, touch: float = 0.0, closed: tuple | None = None
    ) -> ContactEvaluation:
        """Contact residual (n_dofs,), tangent (CSR) and potential at displacement u.

        ``states``: the laws' states per interface (:meth:`start_states`); ``touch`` (a length):
        nodes whose trial gap is below it count as closed in the tangent (see
        :func:`contopt.contact.enforcement.node_terms`; at least 1e-10 h). ``closed`` (per interface,
        (n_nodes,) bool, or None): nodes that count as closed in the tangent whatever their gap.
        """
        clock = Stopwatch()
        x = self.X + u.reshape(-1, 3)
        r = np.zeros(self.n_dofs)
        normal: list = []
        geometric: list = []
        energy, results = 0.0, list[InterfaceResult]()
        for block, state in zip(self.blocks, states):
            mask = None if closed is None else closed[len(results)]
            res, r_b, K_b, e_b = evaluate_interface(block, x, state, self.n_dofs, tangent, touch, mask)
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
        return ContactEvaluation(
            r=r,
            K=K,
            energy=None if self.has_friction else energy,  # friction has no potential
            results=tuple(results),
            seconds=clock.seconds,
            K_normal=K_normal,
        )

    def penetrations(self, results: tuple) -> list[float]:
        """Per interface, the deepest normalized penetration ``max(0, -g_A/a_A) / h``."""
        return [deepest_penetration(r, b.h) for b, r in zip(self.blocks, results)]

    def penetration(self, results: tuple) -> float:
        """The deepest normalized penetration over the interfaces."""
        return max(self.penetrations(results), default=0.0)

    # --------------------------------------------------------------------- checks
    def verify(self, u: np.ndarray, results: tuple) -> tuple:
        """The independent penetration check of every interface at u (:mod:`contopt.contact.verify`)."""
        x = self.X + u.reshape(-1, 3)
        out = []
        for b, res in zip(self.blocks, results):
            iface = b.interface
            out.append(
                check_interface(
                    iface.label,
                    x,
                    b.nm_facet_nodes,
                    b.m_facet_nodes,
                    b.nodes,
                    b.nm_local,
                    res.lam,
                    res.has_overlap,
                    b.h,
                    b.skin,
                    iface.check,
                    (iface.nonmortar[0], iface.mortar[0]),
                    b.node_offsets,
                    res.rejected_near_active,
                    b.sides,
                )
            )
        return tuple(out)

    def coarse_side_warnings(self, checks: tuple) -> list[str]:
        """:func:`contopt.contact.verify.coarse_side_warnings` of the interfaces' ``checks``."""
        return coarse_side_warnings(self.blocks, checks)

    def too_deep(self, u: np.ndarray) -> str:
        """Why ``u`` cannot be a contact state, or "": some node lies deeper inside the other body
        than the contact search reaches (the pairs that should hold it are lost). Cheap enough
        for every line-search trial; Newton shortens a step that would drive a surface through."""
        x = self.X + u.reshape(-1, 3)
        for b in self.blocks:
            if not b.interface.check.enabled:
                continue
            # nodes found within the skin of the surface are left as found: only the deeper ones decide
            d = depths(x, b.nm_facet_nodes, b.m_facet_nodes, b.nodes, exact_outside=False, within=b.skin).deepest
            if d > b.skin:
                return (
                    f"contact interface {b.interface.label}: a node would lie {d:.3g} ({d / b.h:.2g} h) inside the "
                    f"other body, deeper than the contact search reaches (skin {b.skin:.3g})"
                )
        return ""

    # --------------------------------------------------------------------- output
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

    def contact_fields(self, results: tuple | None, bodies, node_offsets) -> dict:
        """Nodal output per nonmortar body: ``contact_pressure`` (n_nodes,) and, on interfaces with
        friction, ``friction_traction`` (n_nodes, 3) (the traction on the nonmortar, against its slip).
        ``results``: an evaluation's per-interface results, or None (zeros)."""
        lam = self.zero_multipliers() if results is None else tuple(r.lam for r in results)
        out = self.pressure_fields(lam, bodies, node_offsets)
        for i, block in enumerate(self.blocks):
            if block.friction is None:
                continue
            body = bodies[block.body]
            field = out[body.name].setdefault("friction_traction", np.zeros((body.mesh.n_nodes, 3)))
            if results is not None:
                field[block.nodes - node_offsets[block.body]] -= results[i].traction
        return out

    def overlap_areas(self, u: np.ndarray, weights: tuple | None = None) -> tuple[tuple, np.ndarray | None]:
        """Overlap areas ``a_A = ∫_overlap N_A da`` per interface at u, and with ``weights`` (one
        (n,) array per interface) the derivative ``sum_A weights_A da_A/du`` (n_dofs,).

        The segmentation topology is that of u, held fixed in the derivative (as everywhere).
        """
        x = self.X + u.reshape(-1, 3)
        areas: list[np.ndarray] = []
        vjp = np.zeros(self.n_dofs)  # returned with weights only
        for i, block in enumerate(self.blocks):
            batch = paired(block, x)
            if batch is None:
                areas.append(np.zeros(block.n_nodes))
                continue
            loc = batch.loc
            if weights is None:
                _, ap = batch.values()
            else:
                _, ap, J = batch.values_and_jacobians()
                r_pairs = np.einsum("pk,pkj->pj", np.asarray(weights[i])[loc], J[:, loc.shape[1] :, :])
                vjp += np.bincount(batch.dofs.ravel(), weights=r_pairs.ravel(), minlength=self.n_dofs)
            areas.append(np.bincount(loc.ravel(), weights=ap.ravel(), minlength=block.n_nodes))
        return tuple(areas), (vjp if weights is not None else None)

    def total_force(self, u: np.ndarray, lam: tuple) -> np.ndarray:
        """(n_interfaces,) total contact force ``sum_A lam_A a_A``: the pressure integrated over the
        overlap of the deformed surfaces, i.e. the normal force the bodies exchange."""
        areas, _ = self.overlap_areas(u)
        return np.array([float(np.dot(a, lam_b)) for a, lam_b in zip(areas, lam)])


def evaluate_interface(
    block: InterfaceBlock,
    x: np.ndarray,
    state: LawState,
    n_dofs: int,
    tangent: bool,
    touch: float = 0.0,
    closed: np.ndarray | None = None,
):
    """One interface at coordinates x (N, 3): ``(InterfaceResult, residual (n_dofs,), (K_normal, K_geometric) or None,
    energy)`` with the law ``state``; ``closed`` ((n_nodes,) bool): nodes closed in the tangent whatever their gap."""
    n = block.n_nodes
    x_nm, x_m = x[block.nm_facet_nodes], x[block.m_facet_nodes]
    candidates, pairs, seg = search(block, x_nm, x_m)
    empty = InterfaceResult(
        g=np.zeros(n),
        a=np.zeros(n),
        has_overlap=np.zeros(n, bool),
        terms=None,
        lam=np.zeros(n),
        n_pairs=0,
        coverage=np.zeros(n),
    )
    if seg is None or not seg.active.any():
        empty = replace(
            empty, rejected_near_active=rejected_near_active(block, x_nm, x_m, candidates, pairs, seg, state.p)
        )
        return empty, np.zeros(n_dofs), None, 0.0
    keep = np.asarray(seg.active)
    batch = pair_batch(block, x, pairs[keep], np.asarray(seg.topo)[keep])
    gp, ap = batch.values()
    loc = batch.loc  # (P, k) local node ids
    g = np.bincount(loc.ravel(), weights=gp.ravel(), minlength=n)
    a = np.bincount(loc.ravel(), weights=ap.ravel(), minlength=n)
    full = full_areas(block, x_nm)
    # nodes whose overlap is a vanishing sliver carry no constraint (no division by ~0)
    has = a > 1e-10 * block.h**2
    reach = max(touch, 1e-10 * block.h)
    terms = block.law.node_terms(
        g[has], a[has], state, has, touch=reach if closed is None else np.where(closed[has], np.inf, reach)
    )
    d_g, d_a, gbar, stiff, lam = (np.zeros(n) for _ in range(5))
    d_g[has], d_a[has], gbar[has], stiff[has], lam[has] = terms.d_g, terms.d_a, terms.gbar, terms.stiff, terms.lam
    coverage = np.where(has, a / np.maximum(full, 1e-300), 0.0)
    result = InterfaceResult(
        g=g,
        a=a,
        has_overlap=has,
        terms=terms,
        lam=lam,
        n_pairs=len(batch.X),
        coverage=coverage,
        rejected_near_active=rejected_near_active(block, x_nm, x_m, candidates, pairs, seg, lam),
    )
    energy = float(terms.energy.sum())
    # derivatives only where the potential is not locally flat: open nodes with p = 0 have
    # zero weights and zero stiffness, and most candidate pairs are of that kind
    weights = np.concatenate([d_g[loc], d_a[loc]], axis=1)  # (P, 2k)
    live = (weights != 0).any(axis=1) | (stiff[loc] != 0).any(axis=1)
    if not live.any():
        zero = sp.csr_matrix((n_dofs, n_dofs))
        if tangent:
            result = replace(result, W=sp.csr_matrix((n, n_dofs)), stiff=stiff)
        return result, np.zeros(n_dofs), ((zero, zero) if tangent else None), energy
    batch, weights = batch.take(live), weights[live]
    loc, k, nd = batch.loc, batch.loc.shape[1], batch.dofs.shape[1]  # k weighted nodes, nd dofs a pair
    _, _, J = batch.values_and_jacobians()
    dofs = batch.dofs
    r_pairs = np.einsum("pk,pkj->pj", weights, J)
    r = np.bincount(dofs.ravel(), weights=r_pairs.ravel(), minlength=n_dofs)
    fric = None
    if block.friction is not None:
        fric = _friction(block, state, batch, stiff, n_dofs, tangent)
        r = r + fric.r
        result = replace(result, friction=replace(fric, r=None, K=None))  # S, Z, D, T: for a path adjoint
    if not tangent:
        return result, r, None, energy
    # rank-one node terms: W has one row per node, w_A = dg_A - gbar_A da_A
    rows = np.repeat(loc, nd, axis=1).reshape(-1, k, nd)
    vals = J[:, :k, :] - gbar[loc][:, :, None] * J[:, k:, :]  # (P, k, nd)
    cols = np.broadcast_to(dofs[:, None, :], vals.shape)
    W = sp.csr_matrix((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(n, n_dofs))
    K1 = (W.T @ sp.diags(stiff) @ W).tocsr()
    result = replace(result, W=W, stiff=stiff)
    H = batch.weighted_hessians(weights)  # (P, nd, nd)
    K2 = sp.csr_matrix(
        (H.ravel(), (np.repeat(dofs, nd, axis=1).ravel(), np.tile(dofs, (1, nd)).ravel())), shape=(n_dofs, n_dofs)
    )
    if fric is not None:
        K1 = (K1 + fric.K).tocsr()  # with the rank-one normal terms: kept in the modified tangent too
    return result, r, (K1, K2), energy


def _friction(block: InterfaceBlock, state: LawState, batch, stiff, n_dofs, tangent):
    """The interface's friction terms (:func:`contopt.contact.friction.friction_terms`) on its live pairs."""
    if state.x_prev is None or state.traction is None:
        raise ValueError(
            "a friction interface's law state has no history: start the load step with begin_step(states, u)"
        )
    p, eps = block.law.multipliers_and_penalties(state, np.arange(block.n_nodes))
    f, old = block.friction, state.x_prev[batch.nodes]
    args = (batch.X, old, batch.topo, batch.loc, batch.dofs, block.n_nodes, n_dofs, state.traction, p, eps)
    return friction_terms(*args, block.eps_t, f.mu, stiff > 0, tangent, f.edge, sub=batch.sub, kinds=batch.kinds)


def discretize_contact(model, disc) -> ContactDiscretization:
    """Precompute every interface of ``model`` on top of its bulk discretization ``disc``."""
    X = np.concatenate([b.mesh.points for b in model.bodies], axis=0)
    blocks = []
    for iface in model.interfaces:
        ids, bodies, faces = [], [], []
        for side in ("nonmortar", "mortar"):
            body_name, facet_set = getattr(iface, side)
            i = model.body_index(body_name)
            faces.append(disc.blocks[i].node_offset + model.bodies[i].mesh.facet_nodes(facet_set))
            ids.append(as_contact_facets(faces[-1]))
            bodies.append(i)
        nm, m = ids
        nodes, local = np.unique(nm, return_inverse=True)
        parents = tri6_parents(faces[0], faces[1], nodes)
        h = float(np.median(facet_sizes(X[nm])))
        skin = iface.skin if iface.skin is not None else 0.5 * h
        blocks.append(
            InterfaceBlock(
                interface=iface,
                nm_facet_nodes=nm,
                m_facet_nodes=m,
                nodes=nodes,
                nm_local=local.reshape(nm.shape),
                body=bodies[0],
                eps=iface.default_eps(model),
                skin=float(skin),
                h=h,
                mortar_body=bodies[1],
                node_offsets=tuple(disc.blocks[i].node_offset for i in bodies),
                eps_t=iface.friction_eps(model),
                sides=iface.side_advice(model),
                eps_max=iface.max_eps(model),
                parents=parents,
            )
        )
    return ContactDiscretization(blocks=tuple(blocks), X=X, n_dofs=disc.n_dofs)
