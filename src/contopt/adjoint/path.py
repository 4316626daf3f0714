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
``k = N``). ``K_k`` is step k's exact (unsymmetric) tangent. One factorization of ``K_k^T`` per load
step serves every response.

The normal law must be the penalty law (its pressures are functions of ``u``); the augmented
Lagrangian's multipliers are not differentiated along the path yet (:func:`refuse_path_alm`).
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from contopt.adjoint.common import AdjointResult, Sensitivity, adjoint_rhs, contact_rows, residual_vjp
from contopt.assembly.model import Model
from contopt.assembly.system import Discretization
from contopt.errors import ConfigError
from contopt.responses.base import Fields
from contopt.solve.linear import LinearSolverOptions, factorize
from contopt.solve.static import State
from contopt.solve.system import System
from contopt.timing import timed

log = logging.getLogger(__name__)


def refuse_path_alm(model: Model | Discretization | System) -> None:
    """ConfigError when a friction interface of ``model`` (a Model, its Discretization or System) uses
    the augmented Lagrangian: the path adjoint differentiates pressures that are functions of the
    displacements (the penalty law)."""
    model = model if isinstance(model, Model) else model.model
    for i in model.interfaces:
        if i.friction is not None and i.law.constrains:
            raise ConfigError(
                f"contact interface {i.label}: sensitivities through friction need the penalty normal law "
                f"(law='penalty', also in a problem file); the augmented Lagrangian's "
                f"multipliers are not differentiated along the load path"
            )


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


def path_sensitivities(
    system: System, steps: tuple, fields: Fields, evaluated: list, linear: LinearSolverOptions | None, seconds: dict
) -> AdjointResult:
    """Values and ``dtheta/drho`` of the responses ``evaluated`` (``(name, (value, partials))`` each, at
    ``fields`` of the last of ``steps``) through the load steps ``steps`` (module docstring), as an
    :class:`AdjointResult` (``method="path"``, a factorization per load step)."""
    disc, contact, free = system.disc, system.contact, system.disc.free
    linear = replace(linear or LinearSolverOptions(), symmetric=False, factor_reuse=False)
    n = len(evaluated)
    grads = [p.rho.copy() for _, (_, p) in evaluated]
    mass_grads = [p.mass.copy() for _, (_, p) in evaluated]
    w_next: list = [None] * n
    v_next: list[dict] = [{} for _ in range(n)]
    fr_next: list = []
    u0, laws0 = _start(system)
    for k in range(len(steps) - 1, -1, -1):
        state = steps[k]
        prev_u, prev_laws = (u0, laws0) if k == 0 else (steps[k - 1].u, steps[k - 1].laws)
        with timed(seconds, "evaluate"):
            laws = contact.begin_step(prev_laws, prev_u) if contact is not None else ()
            ev = state.evaluation
            if ev is None or ev.K_free is None:  # recorded steps keep no tangent; the last one may
                ev = system.evaluate(state.u, state.t, state.layout or disc.layout(), laws, tangent=True, full=False)
            fr = _friction_blocks(ev, free)
            rhs = [np.zeros(free.size) for _ in range(n)]
            if k == len(steps) - 1:
                rows = contact_rows(system, ev.contact, fields.lam, free)[0]
                for j, (_, (_, partials)) in enumerate(evaluated):
                    rhs[j] = adjoint_rhs(partials, rows, free)[0]
        for j, (_, (_, partials)) in enumerate(evaluated):
            v_next[j] = _history_adjoint(partials, fr, fr_next, w_next[j], v_next[j], rhs[j])
        assert ev.K_free is not None  # evaluated with the tangent
        with timed(seconds, "factorize"):
            factor = factorize(ev.K_free.T.tocsr(), linear, system.geometry(state.u))
        try:
            for j in range(n):
                with timed(seconds, "solve"):
                    w_next[j] = factor.solve(rhs[j])
                with timed(seconds, "vjp"):
                    _, d_rho, d_mass = residual_vjp(system, state, w_next[j])
                grads[j] -= d_rho
                mass_grads[j] -= d_mass
        finally:
            factor.free()
        fr_next = fr
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


def _history_adjoint(partials, fr: list, fr_next: list, w_next, v_next: dict, rhs: np.ndarray) -> dict:
    """The adjoint ``v_k`` of each friction interface's tractions at step k (none where it carries no
    friction: its tractions are zero whatever u is), from the next step's ``(w, v)`` (None at the
    last step: the response's own dependence on the tractions); adds its terms to ``rhs`` in place."""
    if w_next is None:
        given = partials.traction
        v_k = {i: given[i].ravel().copy() if given else np.zeros(3 * len(D)) for (i, _, _, D, _) in fr}
    else:
        v_k = {i: np.zeros(3 * len(D)) for (i, _, _, D, _) in fr}
        for i, S1, _, D1, T1 in fr_next:
            q = S1 @ w_next - v_next[i]
            if i in v_k:  # the next step's history: these tractions
                v_k[i] = -_per_node(T1, q)
            # and these positions (the next step's slips are measured from them)
            rhs += S1.T @ _per_node(D1[:, :, 2:5], q)
    for i, _, Z, D, _ in fr:
        rhs += Z.T @ _per_node(D, v_k[i])
    return v_k
