"""Sensitivities through a path-dependent solve (Coulomb friction): the adjoint runs back over the load steps.

Load step k solves ``R_k(u_k, u_{k-1}, h_{k-1}; rho) = 0`` and leaves the history
``h_k = H_k(u_k, u_{k-1}, h_{k-1})`` (the friction tractions, :mod:`contopt.contact.friction`): the
slips of step k are measured from the positions of step k-1 and its tractions. For a response
``theta(u_N, h_N, rho)`` of the last state, with adjoint displacements ``w_k`` (free dofs) and history
adjoints ``v_k`` (per friction interface, 3 per nonmortar node), backward from ``k = N``:

    v_N     = dtheta/dh_N        (nonzero for a response of the tractions: FrictionForce)
    q_{k+1} = S_{k+1} w_{k+1} - v_{k+1},     v_k = -T_{k+1}^T q_{k+1}     (k < N)
    K_k^T w_k = [k = N] dtheta/du_N + S_{k+1}^T Bs_{k+1}^T q_{k+1} + Z_k^T B_k^T v_k

    dtheta/drho = dtheta/drho|_explicit - sum_k w_k^T dR_k/drho

where, from the friction terms of step k's converged evaluation (:class:`FrictionTerms`): ``S`` the
slips' virtual-work rows (``r = S^T t``), ``Z = dz/du``, ``B = dt/dz`` and its slip block ``Bs``,
``T = dt/dt_prev``; the slips depend on the last step's positions through ``-S``, so
``dR_{k+1}/du_k = -S^T Bs S`` and ``dH_{k+1}/du_k = -Bs S`` (the ``S_{k+1}`` terms are absent at
``k = N``). ``K_k`` is step k's exact (unsymmetric) tangent. One factorization of ``K_k^T`` per load
step serves every response.

The normal law must be the penalty law (its pressures are functions of ``u``); the augmented
Lagrangian's multipliers would be a second history.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace

import numpy as np

from contopt.adjoint.sensitivity import AdjointResult, Sensitivity, adjoint_rhs, contact_rows, refuse_path_alm
from contopt.errors import ConfigError
from contopt.responses.base import Fields, Response
from contopt.solve.linear import LinearSolverOptions, factorize
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import State, solve_static
from contopt.solve.system import System

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class PathRecord:
    """The converged load steps of one solve, for :func:`path_sensitivities`.

    states : the converged :class:`State` of every load step in order (without their tangents, but
        the last as :func:`solve_path` returned it);
    u0 : (n_dofs,) the displacement the first step started from; laws0 : the contact laws' states
    it started with
    """

    states: tuple
    u0: np.ndarray
    laws0: tuple


def solve_path(
    model, rho=None, newton: NewtonOptions | None = None, linear: LinearSolverOptions | None = None, mass=None
) -> tuple[State, PathRecord]:
    """:func:`contopt.solve.static.solve_static` that also records every converged load step."""
    system = System.of(model)
    steps: list[State] = []
    state = solve_static(system, rho, newton, linear, on_step=lambda s: steps.append(_light(s)), mass=mass)
    u0 = np.zeros(system.disc.n_dofs)
    u0[system.disc.constrained] = system.disc.prescribed(0.0)
    # the last step as returned: its converged tangent serves the adjoint's first step
    return state, PathRecord(states=(*steps[:-1], state), u0=u0, laws0=system.start_states())


def _light(state: State) -> State:
    """The state without its tangent and the friction Jacobians of its results (the adjoint
    evaluates every step again): what a record keeps of every load step."""
    contact = tuple(
        r if r.friction is None else replace(r, W=None, friction=replace(r.friction, S=None, Z=None, D=None, T=None))
        for r in state.contact
    )
    return replace(state, evaluation=None, contact=contact)


def _check(system: System, record: PathRecord, responses) -> tuple:
    responses = (responses,) if isinstance(responses, Response) else tuple(responses)
    for r in responses:
        if not isinstance(r, Response):
            raise ConfigError(f"responses must be Response objects (e.g. StrainEnergy()), got {type(r).__name__}")
    if not isinstance(record, PathRecord) or not record.states:
        raise ConfigError("path_sensitivities needs the PathRecord of a converged solve (from solve_path)")
    if record.states[-1].t < 1.0 - 1e-12:
        raise ConfigError(f"the adjoint needs a solve that reached the full load, got t = {record.states[-1].t:.4g}")
    refuse_path_alm(system.model)
    return responses


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


def path_sensitivities(
    model, record: PathRecord, responses, linear: LinearSolverOptions | None = None
) -> AdjointResult:
    """Values and ``dtheta/drho`` of ``responses`` at the end of the recorded path (module docstring),
    as an :class:`AdjointResult` (``method="path"``, a factorization per load step).

    model : the Model or System the path was solved on; record : from :func:`solve_path`
    """
    system = System.of(model)
    responses = _check(system, record, responses)
    disc, contact, free = system.disc, system.contact, system.disc.free
    linear = replace(linear or LinearSolverOptions(), symmetric=False, factor_reuse=False)
    final = record.states[-1]
    fields = Fields.from_state(system, final)
    evaluated = [r.evaluate(fields, gradient=True) for r in responses]
    n = len(responses)
    grads = [p.rho.copy() for _, p in evaluated]
    mass_grads = [p.mass.copy() for _, p in evaluated]
    w_next: list = [None] * n
    v_next: list[dict] = [{} for _ in range(n)]
    fr_next: list = []
    seconds = {"evaluate": 0.0, "factorize": 0.0, "solve": 0.0, "vjp": 0.0}
    for k in range(len(record.states) - 1, -1, -1):
        state = record.states[k]
        prev_u, prev_laws = (record.u0, record.laws0) if k == 0 else (record.states[k - 1].u, record.states[k - 1].laws)
        t0 = time.perf_counter()
        laws = contact.begin_step(prev_laws, prev_u) if contact is not None else ()
        ev = state.evaluation
        if ev is None or ev.K_free is None:  # recorded steps keep no tangent; the last one may
            ev = system.evaluate(state.u, state.t, state.layout or disc.layout(), laws, tangent=True, full=False)
        fr = _friction_blocks(ev, free)
        rhs = [np.zeros(free.size) for _ in range(n)]
        if k == len(record.states) - 1:
            cons = contact_rows(system, ev.contact, fields.lam, free)[0] if contact is not None else None
            for j, (_, partials) in enumerate(evaluated):
                rhs[j] = adjoint_rhs(partials, cons, free)[0] if cons is not None else partials.u[free].copy()
        seconds["evaluate"] += time.perf_counter() - t0
        for j, (_, partials) in enumerate(evaluated):
            # v_k[i]: the adjoint of interface i's tractions at this step (none where it carries no
            # friction: its tractions are zero whatever u is)
            if w_next[j] is None:  # the last step: the response's own dependence on the tractions
                given = partials.traction
                v_k = {i: given[i].ravel().copy() if given else np.zeros(3 * len(D)) for (i, _, _, D, _) in fr}
            else:
                v_k = {i: np.zeros(3 * len(D)) for (i, _, _, D, _) in fr}
                for i, S1, _, D1, T1 in fr_next:
                    q = S1 @ w_next[j] - v_next[j][i]
                    if i in v_k:  # the next step's history: these tractions
                        v_k[i] = -_per_node(T1, q)
                    # and these positions (the next step's slips are measured from them)
                    rhs[j] += S1.T @ _per_node(D1[:, :, 2:5], q)
            for i, _, Z, D, _ in fr:
                rhs[j] += Z.T @ _per_node(D, v_k[i])
            v_next[j] = v_k
        t0 = time.perf_counter()
        assert ev.K_free is not None  # evaluated with the tangent
        factor = factorize(ev.K_free.T.tocsr(), linear, system.geometry(state.u))
        seconds["factorize"] += time.perf_counter() - t0
        try:
            for j in range(n):
                t0 = time.perf_counter()
                w_next[j] = factor.solve(rhs[j])
                seconds["solve"] += time.perf_counter() - t0
                t0 = time.perf_counter()
                w = np.zeros(disc.n_dofs)
                w[free] = w_next[j]
                grads[j] -= disc.residual_rho_vjp(state.u, w, state.rho)
                mass_grads[j] -= disc.residual_mass_vjp(w, state.t)
                seconds["vjp"] += time.perf_counter() - t0
        finally:
            factor.free()
        fr_next = fr
    log.info(
        "path adjoint over %d load steps: %s",
        len(record.states),
        ", ".join(f"{k} {v:.2f} s" for k, v in seconds.items()),
    )
    out = []
    for j, (response, (value, _)) in enumerate(zip(responses, evaluated)):
        w = np.zeros(disc.n_dofs)
        w[free] = w_next[j]
        out.append(
            Sensitivity(
                name=response.name,
                value=value,
                gradient=grads[j],
                w=w,
                beta=(),
                linear_solves=len(record.states),  # one per load step
                iterations=0,
                residual=0.0,
                mass_gradient=mass_grads[j],
            )
        )
    return AdjointResult(
        sensitivities=tuple(out),
        method="path",
        seconds=seconds,
        linear_solves=n * len(record.states),
        factorizations=len(record.states),
        active=(),
    )
