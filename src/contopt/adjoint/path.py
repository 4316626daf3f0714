"""The adjoint of a path-dependent solve (Coulomb friction): it runs back over the recorded load steps.

Load step k solves ``R_k(u_k, u_{k-1}, h_{k-1}; rho) = 0`` and leaves the history
``h_k = H_k(u_k, u_{k-1}, h_{k-1})`` (the friction tractions, :mod:`contopt.contact.friction`): the
slips of step k are measured from the positions of step k-1 and its tractions. For a response
``theta(u_N, h_N, rho)`` of load step N (the last one, or any recorded step: the later steps do not
change it), with adjoint displacements ``w_k`` (free dofs) and history
adjoints ``v_k`` (per friction interface, 3 per nonmortar node), backward from ``k = N``:

    v_N     = dtheta/dh_N        (nonzero for a response of the tractions: FrictionForce)
    q_{k+1} = S_{k+1} w_{k+1} - v_{k+1},     v_k = -T_{k+1}^T q_{k+1}     (k < N)
    K_k^T w_k = [k = N] dtheta/du_N + S_{k+1}^T Bs_{k+1}^T q_{k+1} + Z_k^T B_k^T v_k

    dtheta/drho = dtheta/drho|_explicit - sum_k w_k^T dR_k/drho

where, from the friction terms of step k's converged evaluation (:class:`FrictionTerms`): ``S`` the
slips' virtual-work rows (``r = S^T t``), ``Z = dz/du``, ``B = dt/dz`` and its slip block ``Bs``,
``T = dt/dt_prev``; the slips depend on the last step's positions through ``-S``, so
``dR_{k+1}/du_k = -S^T Bs S`` and ``dH_{k+1}/du_k = -Bs S`` (the ``S_{k+1}`` terms are absent at
``k = N``). ``K_k`` is step k's exact (unsymmetric) tangent. One factorization per load step
serves every response.

With the penalty normal law the pressures are functions of ``u``. With the augmented Lagrangian
every load step of a friction interface converges its multipliers (its tractions become the next
step's history), so step k is the saddle point ``R_k(u_k, lam_k) = 0``, ``g_A(u_k) = 0`` on its
active nodes (``lam_A > 0``, the paper's rule), with ``dR_k/dlam = -G^T + S^T P`` and
``dH_k/dlam = P``, ``P = dt/dlam`` per active node. The gap enters a traction through its pressure
``max(0, p - eps_A g/a)`` alone, so ``P = -(a/eps_A) dt/dg`` comes with ``B``. Step k's adjoint
``(w_k, beta_k)`` solves

    K_k^T w_k - G^T mu_k       = (the right-hand side above)
    (-G + P^T S) w_k           = [k = N] dtheta/dlam + P^T v_k

with ``K_k`` and ``B`` the augmented Lagrangian's converged tangent and law Jacobian (penalty
``eps_A/a_A`` in them) and ``mu_k = beta_k - diag(eps_A/a_A) dtheta/dlam``: the terms the penalty
adds to ``K_k`` and to ``B`` are multiples of the constraint rows, which the second equation
fixes (the saddle point of :mod:`contopt.adjoint.saddle` with friction). The bordered matrix is
unsymmetric and indefinite: one LU per load step, with iterative refinement.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from contopt.adjoint.common import AdjointResult, AdjointRows, Sensitivity, adjoint_rhs, contact_rows, residual_vjp
from contopt.adjoint.saddle import factorization_only
from contopt.errors import ConfigError
from contopt.responses.base import Fields, Partials
from contopt.solve.linear import LinearSolverOptions, factorize
from contopt.solve.static import State
from contopt.solve.system import System
from contopt.timing import timed

log = logging.getLogger(__name__)


def recorded_steps(system: System, state: State, last: int | None) -> tuple:
    """The converged states of load steps 0..``last`` (None: all) of ``state``'s recorded path, the
    final one as ``state`` itself (its converged tangent serves the adjoint's first step)."""
    if not state.path:
        raise ConfigError(
            "the adjoint of a path-dependent system (friction) needs the load steps of the solve: solve it with "
            "solve_static, which records them in State.path"
        )
    n = len(state.path)
    k = n - 1 if last is None else last
    return (*state.path[:k], state) if k == n - 1 else state.path[: k + 1]


def _friction_blocks(ev, free) -> list:
    """Per friction interface of an evaluation: its index, (S, Z) on the free dofs, D (n, 3, 8), T (n, 3, 3)."""
    out = []
    for i, res in enumerate(ev.contact or ()):
        fr = res.friction
        if fr is None:
            continue
        assert fr.S is not None and fr.Z is not None and fr.D is not None and fr.T is not None  # with a tangent
        out.append((i, fr.S.tocsc()[:, free].tocsr(), fr.Z.tocsc()[:, free].tocsr(), fr.D, fr.T))
    return out


def _per_node(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``M_A^T v_A`` for every node: M (n, 3, m), v (3 n,) -> (m n,)."""
    return np.einsum("nij,ni->nj", M, v.reshape(-1, 3)).ravel()


def _start(system: System) -> tuple[np.ndarray, tuple]:
    """The displacement (n_dofs,) and the contact laws' states the first load step started from."""
    disc = system.disc
    u0 = np.zeros(disc.n_dofs)
    u0[disc.constrained] = disc.prescribed(0.0)
    return u0, system.start_states()


@dataclass(frozen=True, eq=False)
class StepOperator:
    """Load step k's transposed adjoint operator and what its right-hand sides need.

    K : (n_free, n_free) the step's converged tangent (the augmented Lagrangian's, nodes counted
    closed without pressure taken back out); rows : its constraint rows G (the augmented-Lagrangian
    interfaces' active nodes); friction : :func:`_friction_blocks`; pressure : per friction
    interface with active nodes, ``(span in G's rows, P (k, 3 n))``: ``P = dt/dlam`` of its active
    nodes, the tractions' dependence on the pressures the constraints hold (module docstring).
    """

    K: sp.csr_matrix
    rows: AdjointRows
    friction: list
    pressure: dict

    def matrix(self) -> sp.csr_matrix:
        """``K^T``, or ``[[K^T, -G^T], [-G + P S, 0]]`` with constraints (unsymmetric, indefinite)."""
        G = self.rows.G
        if G.shape[0] == 0:
            return self.K.T.tocsr()
        E = sp.lil_matrix(G.shape)
        for i, S, _, _, _ in self.friction:
            if i in self.pressure:
                span, P = self.pressure[i]
                E[span] = P @ S
        return sp.bmat([[self.K.T, -G.T], [-G + E.tocsr(), None]], format="csr")

    def pressure_rhs(self, v: dict) -> np.ndarray:
        """``P^T``-terms of the constraint rows' right-hand side from the history adjoints ``v``."""
        c = np.zeros(self.rows.G.shape[0])
        for i, (span, P) in self.pressure.items():
            c[span] += P @ v[i]
        return c


def path_partials(system: System, steps: tuple, evaluated: list) -> list:
    """``evaluated`` (``(name, (value, {k: Partials}))`` each, as :meth:`Response.evaluate_path`
    gives them) with every key an index into ``steps`` (None, the final state, is the last) and
    the partials of one step summed. ConfigError where a response reads an earlier step that an
    augmented Lagrangian leaves unconverged (not an equilibrium to differentiate)."""
    last = len(steps) - 1
    out = []
    for name, (value, parts) in evaluated:
        by_step: dict = {}
        for k, partials in parts.items():
            k = last if k is None else int(k)
            by_step[k] = partials if k not in by_step else Partials.combine([by_step[k], partials], [1.0, 1.0])
        out.append((name, (value, by_step)))
    early = any(k < last for _, (_, parts) in out for k in parts)
    loose = system.contact.loose_steps() if early and system.contact is not None else []
    if loose:
        raise ConfigError(
            f"contact interface {loose[0]}: its augmented Lagrangian converges the final load step only, so the "
            "earlier steps a load-path response reads are no equilibria to differentiate; set "
            'augmentation.intermediate = "converge"'
        )
    return out


def path_sensitivities(
    system: System, steps: tuple, fields: Fields, evaluated: list, linear: LinearSolverOptions | None, seconds: dict
) -> AdjointResult:
    """Values and ``dtheta/drho`` of the responses ``evaluated`` through the load steps ``steps``
    (module docstring), as an :class:`AdjointResult` (``method="path"``, a factorization per load
    step). ``evaluated``: ``(name, (value, partials))`` each, the partials at ``fields`` of the last
    of ``steps``, or ``{k: Partials}`` per index k into ``steps`` (:func:`path_partials`) for a
    response of several steps: each step's ``dtheta/du_k`` joins its adjoint's right-hand side."""
    disc, free = system.disc, system.disc.free
    linear = replace(linear or LinearSolverOptions(), symmetric=False, factor_reuse=False)
    n = len(evaluated)
    per_step = [p if isinstance(p, dict) else {len(steps) - 1: p} for _, (_, p) in evaluated]
    grads = [sum((p.rho for p in parts.values()), np.zeros(disc.n_cells)) for parts in per_step]
    mass_grads = [sum((p.mass for p in parts.values()), np.zeros(disc.n_cells)) for parts in per_step]
    w_next: list = [None] * n
    v_next: list[dict] = [{} for _ in range(n)]
    fr_next: list = []
    start = _start(system)
    for k in range(len(steps) - 1, -1, -1):
        with timed(seconds, "evaluate"):
            op = _step_operator(system, steps, k, start)
            rhs = []
            for j in range(n):
                given = per_step[j].get(k)
                b, c = (
                    adjoint_rhs(given, op.rows, free)
                    if given is not None
                    else (np.zeros(free.size), np.zeros(op.rows.G.shape[0]))
                )
                v_next[j] = _history_adjoint(given, op.friction, fr_next, w_next[j], v_next[j], b)
                rhs.append(np.concatenate([b, c + op.pressure_rhs(v_next[j])]))
        constrained = op.rows.G.shape[0] > 0
        with timed(seconds, "factorize"):
            M = op.matrix()
            if constrained:  # indefinite: a factorization, whatever solves the stiffness
                factor = factorize(M, factorization_only(linear))
            else:
                factor = factorize(M, linear, system.geometry(steps[k].u))
        try:
            for j in range(n):
                with timed(seconds, "solve"):
                    x = _refined(factor, M, rhs[j]) if constrained else factor.solve(rhs[j])
                    w_next[j] = x[: free.size]
                with timed(seconds, "vjp"):
                    _, d_rho, d_mass = residual_vjp(system, steps[k], w_next[j])
                grads[j] -= d_rho
                mass_grads[j] -= d_mass
        finally:
            factor.free()
        fr_next = op.friction
    log.info("path adjoint over %d load steps: %s", len(steps), ", ".join(f"{k} {v:.2f} s" for k, v in seconds.items()))
    out = []
    for j, (name, (value, _)) in enumerate(evaluated):
        w = np.zeros(disc.n_dofs)
        w[free] = w_next[j]
        out.append(
            Sensitivity(
                name=name,
                value=value,
                gradient=grads[j],
                w=w,
                beta=(),
                linear_solves=len(steps),  # one per load step
                mass_gradient=mass_grads[j],
            )
        )
    return AdjointResult(
        sensitivities=tuple(out),
        method="path",
        seconds=seconds,
        linear_solves=n * len(steps),
        factorizations=len(steps),
        active=(),
    )


def _step_operator(system: System, steps: tuple, k: int, start: tuple) -> StepOperator:
    """Load step k's :class:`StepOperator`, from its converged evaluation (evaluated again where the
    recorded step kept no tangent) with the laws' states it was solved with."""
    disc, contact, free = system.disc, system.contact, system.disc.free
    state = steps[k]
    prev_u, prev_laws = start if k == 0 else (steps[k - 1].u, steps[k - 1].laws)
    ev = state.evaluation
    if ev is None or ev.K_free is None:  # recorded steps keep no tangent; the last one may
        laws = _step_laws(contact, state.laws, prev_u, prev_laws) if contact is not None else ()
        ev = system.evaluate(state.u, state.t, state.layout or disc.layout(), laws, tangent=True, full=False)
    assert ev.K_free is not None  # evaluated with the tangent
    lam = tuple(r.lam for r in ev.contact or ())
    rows, correction = contact_rows(system, ev.contact, lam, free)
    K = ev.K_free if correction is None or disc.comm.rank != 0 else (ev.K_free - correction).tocsr()
    friction = _friction_blocks(ev, free)
    pressure = {}
    for i, _, _, D, _ in friction:
        assert contact is not None  # friction lives on its interfaces
        idx = rows.index[i]
        if idx is not None and idx[0].size:
            pressure[i] = (idx[1], pressure_derivative(contact.blocks[i], state.laws[i], ev.contact[i], D, idx[0]))
    return StepOperator(K=K, rows=rows, friction=friction, pressure=pressure)


def _step_laws(contact, laws: tuple, prev_u: np.ndarray, prev_laws: tuple) -> tuple:
    """The laws' states a load step was solved with: its converged multipliers and penalties
    (``laws``), and the history (positions and tractions) of the step before."""
    history = contact.begin_step(prev_laws, prev_u)
    return tuple(replace(s, traction=h.traction, x_prev=h.x_prev) for s, h in zip(laws, history))


def pressure_derivative(block, law_state, result, D: np.ndarray, active: np.ndarray) -> sp.csr_matrix:
    """(k, 3 n) ``dt_A/dlam_A`` of the ``active`` nodes of a friction interface as rows: the
    interface's ``block`` (:class:`contopt.contact.system.InterfaceBlock`), the ``law_state`` and
    ``result`` (its InterfaceResult) of the evaluation whose law Jacobians are ``D`` (n, 3, 8).

    The gap enters a node's traction through its pressure ``lam = max(0, p - eps_A g/a)`` alone
    (:func:`contopt.contact.friction.node_traction`), so ``dt/dlam = -(a/eps_A) dt/dg``.
    """
    _, eps = block.law.multipliers_and_penalties(law_state, active)
    P = -(result.a[active] / eps)[:, None] * D[active, :, 0]  # (k, 3)
    rows = np.repeat(np.arange(active.size), 3)
    cols = (3 * active[:, None] + np.arange(3)).ravel()
    return sp.csr_matrix((P.ravel(), (rows, cols)), shape=(active.size, D.shape[0] * 3))


def _refined(factor, M: sp.csr_matrix, b: np.ndarray, steps: int = 3) -> np.ndarray:
    """``M^-1 b`` from an LU of an indefinite matrix with a zero block, with a few steps of
    iterative refinement (pivoting there may lose digits that the gradients need)."""
    x = factor.solve(b)
    scale = max(float(np.linalg.norm(b)), 1e-300)
    for _ in range(steps):
        r = b - M @ x
        if np.linalg.norm(r) <= 1e-14 * scale:
            break
        x = x + factor.solve(r)
    return x


def _history_adjoint(partials, fr: list, fr_next: list, w_next, v_next: dict, rhs: np.ndarray) -> dict:
    """The adjoint ``v_k`` of each friction interface's tractions at step k (none where it carries no
    friction: its tractions are zero whatever u is): the response's own dependence on them at this
    step (``partials``, None where it reads none here) plus the next step's ``(w, v)`` terms (none
    at the last step, ``w_next`` None); adds its terms to ``rhs`` in place."""
    given = partials.traction if partials is not None else ()
    v_k = {i: given[i].ravel().copy() if given else np.zeros(3 * len(D)) for (i, _, _, D, _) in fr}
    if w_next is not None:
        for i, S1, _, D1, T1 in fr_next:
            q = S1 @ w_next - v_next[i]
            if i in v_k:  # the next step's history: these tractions
                v_k[i] -= _per_node(T1, q)
            # and these positions (the next step's slips are measured from them)
            rhs += S1.T @ _per_node(D1[:, :, 2:5], q)
    for i, _, Z, D, _ in fr:
        rhs += Z.T @ _per_node(D, v_k[i])
    return v_k
