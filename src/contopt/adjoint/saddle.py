"""The adjoint of one equilibrium (paper sections 4-5): a saddle point through the active contact.

On the augmented-Lagrangian interfaces the active nodes (``lam_A > 0``, the paper's rule: zero
pressure is inactive) satisfy ``g_A(u) = 0`` (:mod:`contopt.adjoint.common`). Differentiating this
saddle point, the adjoint ``(w, beta)`` of a response ``theta(u, lam, rho)`` solves

    K_lag w - G^T beta = dtheta/du,     -G w = dtheta/dlam      (G: rows w_A, A active)

and ``dtheta/drho = dtheta/drho|explicit - w . dR/drho`` (paper eq. 21).
Design-dependent volume loads (``R = ... - t f_volume mass``) add in the same
way ``dtheta/dmass = dtheta/dmass|explicit + t f_volume^T w``.
The converged tangent ``K`` of the augmented-Lagrangian Newton solve is
``K_lag + G^T D G`` with ``D = diag(eps/a_A)``, so with ``mu = beta - D dtheta/dlam``

    K w = dtheta/du + G^T mu,           G w = -dtheta/dlam.

One factorization of ``K`` serves every response and every iteration:

* ``"schur-cg"`` (default): conjugate gradients on the Schur complement
  ``G K^-1 G^T mu = -dtheta/dlam - G K^-1 dtheta/du``, preconditioned by
  ``D`` (``D S -> I`` as eps grows); one solve with the factor per iteration. With an iterative
  backend the first solves go to ``1e-2 rtol`` and later ones to that times ``scale / |r_k|``
  (``scale``: the larger of ``|dtheta/dlam|`` and ``|G K^-1 dtheta/du|``; at most
  ``RELAXED_RTOL``): a solve's error enters ``w`` scaled by a step that shrinks with the Schur
  residual ``r_k`` (relaxed inexact Krylov, Simoncini & Szyld 2003).
* ``"uzawa"``: the paper's Algorithm 1: ``mu <- mu - D (G w + dtheta/dlam)``,
  one solve per update (the multiplier iteration of the primal, now linear).
* ``"direct"``: factorize the saddle-point matrix ``[[K, -G^T], [-G, 0]]``
  (symmetric indefinite) and solve once.

Penalty interfaces have no constraint: one solve with the converged tangent gives ``w`` (paper 5.1).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from contopt.adjoint.common import AdjointResult, AdjointRows, Sensitivity, adjoint_rhs, contact_rows, residual_vjp
from contopt.adjoint.options import AdjointOptions
from contopt.errors import ConfigError, ConvergenceError
from contopt.responses.base import Fields
from contopt.solve.linear import LinearSolverOptions, factorize
from contopt.solve.linear.options import ITERATIVE
from contopt.solve.static import State
from contopt.solve.system import System
from contopt.timing import timed

log = logging.getLogger(__name__)
RELAXED_RTOL = 1e-4  # the loosest inner solve of schur-cg's late iterations


@dataclass(frozen=True, eq=False)
class Saddle:
    """One equilibrium's adjoint operator: the converged tangent ``K`` (free x free; contact
    correction applied) and the contact rows; the factors are made on first use and freed after."""

    system: System
    state: State
    K: sp.csr_matrix
    rows: AdjointRows
    linear: LinearSolverOptions
    factors: dict

    def factor(self, kind: str, seconds: dict):
        """The stiffness factor ``"K"`` (shared by every response) or the ``"saddle"`` one."""
        if kind in self.factors:
            return self.factors[kind]
        with timed(seconds, "factorize"):
            if kind == "K":
                # its own factor (Newton's kept one is of an earlier iterate): every solve exact
                self.factors[kind] = factorize(
                    self.K, replace(self.linear, factor_reuse=False), self.system.geometry(self.state.u)
                )
            else:  # indefinite: a factorization, whatever solves the stiffness
                self.factors[kind] = factorize(saddle_matrix(self.K, self.rows.G), factorization_only(self.linear))
        return self.factors[kind]

    def free(self) -> None:
        for f in self.factors.values():
            f.free()


def static_sensitivities(
    system: System, state: State, fields: Fields, evaluated: list, options: AdjointOptions, linear, seconds: dict
) -> AdjointResult:
    """The adjoint of the equilibrium ``state`` for the responses ``evaluated`` (``(name, (value, partials))``
    each, at ``fields``) sharing one factorization; ``seconds`` gathers the phases."""
    with timed(seconds, "evaluate"):
        saddle = _saddle(system, state, fields, linear)
    if system.disc.comm.distributed and options.method == "direct" and saddle.rows.G.shape[0]:
        raise ConfigError(
            "adjoint method 'direct' factors the saddle-point matrix on one process; in a distributed run "
            "use AdjointOptions(method='schur-cg') (the default) or 'uzawa'"
        )
    # an iterative solve inside schur-cg/uzawa: 100x tighter than their own tolerance, so that
    # the outer iteration converges to it (both measure relative residuals)
    inner_rtol = min(linear.krylov_rtol, 1e-2 * options.rtol)
    out = []
    try:
        for name, (value, partials) in evaluated:
            b, c = adjoint_rhs(partials, saddle.rows, system.disc.free)
            f0 = seconds["factorize"]
            with timed(seconds, "solve"):
                w_f, mu, n_solves, its, res = _solve(saddle, b, c, options, inner_rtol, name, seconds)
            seconds["solve"] -= seconds["factorize"] - f0  # a first factorization inside counts apart
            with timed(seconds, "vjp"):
                w, d_rho, d_mass = residual_vjp(system, state, w_f)
            out.append(
                Sensitivity(
                    name=name,
                    value=value,
                    gradient=partials.rho - d_rho,
                    w=w,
                    beta=_beta(saddle.rows, mu, c, fields.lam),
                    linear_solves=n_solves,
                    iterations=its,
                    residual=res,
                    mass_gradient=partials.mass - d_mass,
                )
            )
            log.info("adjoint %s: %d solves, %d iterations, constraint residual %.1e", name, n_solves, its, res)
    finally:
        saddle.free()
    return AdjointResult(
        sensitivities=tuple(out),
        method=options.method,
        seconds=seconds,
        linear_solves=sum(s.linear_solves for s in out),
        factorizations=len(saddle.factors),
        active=tuple(0 if idx is None else idx[0].size for idx in saddle.rows.index),
    )


def _saddle(system: System, state: State, fields: Fields, linear) -> Saddle:
    """The converged tangent at ``state`` (its evaluation's, or evaluated again) and the contact rows."""
    disc = system.disc
    ev = state.evaluation
    if ev is None or ev.K_free is None:
        ev = system.evaluate(state.u, state.t, state.layout or disc.layout(), state.laws, tangent=True, full=False)
    K = ev.K_free
    assert K is not None  # evaluated with the tangent
    rows, correction = contact_rows(system, ev.contact, fields.lam, disc.free)
    if correction is not None and disc.comm.rank == 0:  # K: this rank's part (contopt.parallel)
        K = (K - correction).tocsr()
    return Saddle(system=system, state=state, K=K, rows=rows, linear=linear, factors={})


def _solve(saddle: Saddle, b, c, options: AdjointOptions, inner_rtol: float, name: str, seconds: dict):
    """``(w_free, mu, solves, iterations, residual)`` of one response's right-hand sides ``b``, ``c``."""
    if saddle.rows.G.shape[0] == 0:
        return Accurate(saddle.factor("K", seconds), inner_rtol).solve(b), np.zeros(0), 1, 0, 0.0
    if options.method == "direct":
        return direct(saddle.factor("saddle", seconds), saddle.rows, b, c)
    solver = schur_cg if options.method == "schur-cg" else uzawa
    return solver(Accurate(saddle.factor("K", seconds), inner_rtol), saddle.rows, b, c, options, name)


def _beta(rows: AdjointRows, mu, c, lam) -> tuple:
    """Adjoint multipliers per interface, ``beta = mu + D dtheta/dlam`` on the active nodes."""
    out = []
    beta = mu + rows.D * c if mu.size else mu
    for idx, lam_b in zip(rows.index, lam):
        full = np.zeros_like(lam_b)
        if idx is not None and beta.size:
            active, span = idx
            full[active] = beta[span]
        out.append(full)
    return tuple(out)


def _scale(c, Gw0) -> float:
    return max(float(np.linalg.norm(c)), float(np.linalg.norm(Gw0)), 1e-300)


def schur_cg(factor, rows: AdjointRows, b, c, options: AdjointOptions, name: str):
    """Preconditioned CG on ``S mu = -c - G K^-1 b``, ``S = G K^-1 G^T``, preconditioner ``D``;
    ``(w, mu, solves, iterations, residual)``."""
    G, D = rows.G, rows.D
    w = factor.solve(b)
    solves = 1
    r = -c - G @ w
    scale = _scale(c, G @ w)
    mu = np.zeros_like(c)
    if np.linalg.norm(r) <= options.rtol * scale:
        return w, mu, solves, 0, float(np.linalg.norm(r) / scale)
    z = D * r
    p = z.copy()
    rz = float(r @ z)
    for it in range(1, options.max_iter + 1):
        # the error of this solve enters w scaled by the step, which shrinks with r: its tolerance
        # may grow as |r| falls (inexact Krylov, Simoncini & Szyld 2003)
        y = factor.solve(G.T @ p, relax=scale / max(float(np.linalg.norm(r)), 1e-300))
        solves += 1
        q = G @ y
        pq = float(p @ q)
        if not pq > 0:
            raise ConvergenceError(
                f"adjoint ({name}): the contact Schur complement is not positive definite "
                f"(p.Sp = {pq:.3e}); use AdjointOptions(method='direct')",
                [],
                None,
            )
        alpha = rz / pq
        mu += alpha * p
        w += alpha * y
        r -= alpha * q
        res = float(np.linalg.norm(r)) / scale
        if res <= options.rtol:
            return w, mu, solves, it, res
        z = D * r
        rz, rz_old = float(r @ z), rz
        p = z + (rz / rz_old) * p
    raise ConvergenceError(
        f"adjoint ({name}): schur-cg did not reach rtol {options.rtol:g} in {options.max_iter} "
        f"iterations (residual {res:.2e}); raise AdjointOptions.max_iter or use method='direct'",
        [],
        None,
    )


def uzawa(factor, rows: AdjointRows, b, c, options: AdjointOptions, name: str):
    """The paper's Algorithm 1 with a fixed factor: ``mu <- mu - D (G w + c)``, ``w = K^-1 (b + G^T mu)``."""
    G, D = rows.G, rows.D
    mu = np.zeros_like(c)
    w = factor.solve(b)
    solves = 1
    scale = _scale(c, G @ w)
    for it in range(0, options.max_iter + 1):
        g_adj = G @ w + c
        res = float(np.linalg.norm(g_adj)) / scale
        if res <= options.rtol:
            return w, mu, solves, it, res
        if it == options.max_iter:
            break
        mu -= D * g_adj
        w = factor.solve(b + G.T @ mu)
        solves += 1
    raise ConvergenceError(
        f"adjoint ({name}): uzawa did not reach rtol {options.rtol:g} in {options.max_iter} "
        f"updates (residual {res:.2e}); use method='schur-cg' or 'direct'",
        [],
        None,
    )


class Accurate:
    """A factor whose solves ask an iterative backend for relative residual ``rtol``, or for up to
    ``relax`` times that (never looser than ``RELAXED_RTOL``) where the caller's error allows."""

    def __init__(self, factor, rtol: float):
        self.factor, self.rtol = factor, rtol

    def solve(self, b: np.ndarray, relax: float = 1.0) -> np.ndarray:
        return self.factor.solve(b, rtol=min(max(RELAXED_RTOL, self.rtol), self.rtol * max(relax, 1.0)))


def factorization_only(linear: LinearSolverOptions) -> LinearSolverOptions:
    """``linear`` restricted to factorizations (the saddle-point matrix is indefinite: no CG)."""
    if linear.backend in ITERATIVE:
        return replace(linear, backend="auto", iterative_above=2**62, trial_above=2**62, factor_reuse=False)
    return replace(linear, iterative_above=2**62, trial_above=2**62, factor_reuse=False)


def saddle_matrix(K: sp.csr_matrix, G: sp.csr_matrix) -> sp.csr_matrix:
    n_c = G.shape[0]
    return sp.bmat([[K, -G.T], [-G, sp.csr_matrix((n_c, n_c))]], format="csr")


def direct(saddle, rows: AdjointRows, b, c):
    """One solve with the factored saddle-point matrix: ``(w, mu, 1, 0, residual)``."""
    n = b.size
    x = saddle.solve(np.concatenate([b, c]))
    w, mu = x[:n], x[n:]
    # no unconstrained solve here to measure against: the size of the terms of G w is the scale
    res = float(np.linalg.norm(rows.G @ w + c)) / _scale(c, abs(rows.G) @ np.abs(w))
    return w, mu, 1, 0, res
