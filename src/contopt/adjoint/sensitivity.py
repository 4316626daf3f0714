"""Adjoint sensitivities of responses through contact (paper sections 4-5).

At a converged state the residual is ``R(u, lam; rho) = r_b(u; rho) - sum_A lam_A w_A``
with ``w_A = dg_A/du`` the gradients of the weighted gaps, and on the ALM
interfaces the active nodes (``lam_A > 0``, the paper's rule: zero pressure
is inactive) satisfy ``g_A(u) = 0``. Differentiating this saddle point,
the adjoint ``(w, beta)`` of a response ``theta(u, lam, rho)`` solves

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

Penalty interfaces have no constraint: their pressures ``lam_A = eps <-g_A/a_A>``
are functions of ``u``, so ``dtheta/dlam`` moves into the right-hand side as
``-W^T diag(eps H/a) dtheta/dlam`` and one solve with the converged tangent
gives ``w`` (paper 5.1).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

from contopt.contact.laws import ConstraintRows, PenaltyRows
from contopt.errors import ConfigError, ConvergenceError
from contopt.responses.base import Fields, Partials, Response
from contopt.solve.linear import LinearSolverOptions, factorize
from contopt.solve.linear.options import ITERATIVE
from contopt.solve.static import State
from contopt.solve.system import System

log = logging.getLogger(__name__)

METHODS = ("schur-cg", "uzawa", "direct")
RELAXED_RTOL = 1e-4  # the loosest inner solve of schur-cg's late iterations


@dataclass(frozen=True)
class AdjointOptions:
    """How the adjoint saddle point is solved (see the module docstring).

    rtol : converged when ``|G w + dtheta/dlam| <= rtol * scale`` with ``scale`` the
        larger of ``|dtheta/dlam|`` and ``|G K^-1 dtheta/du|`` (the constraint
        residual of the unconstrained adjoint)
    max_iter : iterations of ``schur-cg`` / ``uzawa`` before giving up
    """

    method: str = "schur-cg"
    rtol: float = 1e-10
    max_iter: int = 200

    def __post_init__(self):
        if self.method not in METHODS:
            raise ConfigError(f"adjoint.method must be one of {METHODS}, got {self.method!r}")
        if not (0 < self.rtol < 1):
            raise ConfigError(f"adjoint.rtol must lie in (0, 1), got {self.rtol!r}")
        if not isinstance(self.max_iter, int) or self.max_iter < 1:
            raise ConfigError(f"adjoint.max_iter must be a positive integer, got {self.max_iter!r}")


@dataclass(frozen=True, eq=False)
class Sensitivity:
    """One response's value and total derivative.

    Attributes
    ----------
    name, value : the response
    gradient : (n_cells,) dtheta/drho
    mass_gradient : (n_cells,) dtheta/dmass (the material share scaling the volume loads; zero without them)
    w : (n_dofs,) adjoint displacement; beta : per interface, adjoint multipliers (zero where inactive)
    linear_solves : solves with the factor (or the saddle-point factor) this response needed
    iterations : schur-cg / uzawa iterations; residual : final relative adjoint-constraint residual
    """

    name: str
    value: float
    gradient: np.ndarray
    w: np.ndarray = field(repr=False)
    beta: tuple = field(repr=False)
    linear_solves: int = 0
    iterations: int = 0
    residual: float = 0.0
    mass_gradient: np.ndarray | None = field(repr=False, default=None)


@dataclass(frozen=True, eq=False)
class AdjointResult:
    """Sensitivities of several responses at one state, with the cost of getting them."""

    sensitivities: tuple
    method: str
    seconds: dict
    linear_solves: int
    factorizations: int
    active: tuple  # per interface: number of constrained (ALM, lam > 0) nodes

    def __getitem__(self, key) -> Sensitivity:
        if isinstance(key, int):
            return self.sensitivities[key]
        for s in self.sensitivities:
            if s.name == key:
                return s
        raise KeyError(key)

    @property
    def total_seconds(self) -> float:
        return float(sum(self.seconds.values()))


@dataclass(frozen=True, eq=False)
class _Constraints:
    """The ALM constraint rows on the free dofs and their penalty weights, per interface."""

    G: sp.csr_matrix  # (n_c, n_free) stacked over ALM interfaces
    D: np.ndarray  # (n_c,)
    index: tuple  # per interface: (positions in its node list, slice in the stacked rows) or None
    penalty: tuple  # per interface: (W_free, stiff) for penalty interfaces, else None


def contact_rows(system: System, results, lam, free) -> tuple[_Constraints, sp.csr_matrix | None]:
    """The rows each interface's law hands the adjoint (constraints of a multiplier law, pressures
    as functions of u for a penalty law), and the tangent correction for nodes the tangent
    counted closed that carry no pressure."""
    contact = system.contact
    assert contact is not None  # called with contact only
    rows: list[sp.csr_matrix] = []
    D_parts: list[np.ndarray] = []
    index: list[tuple[np.ndarray, slice] | None] = []
    penalty: list[tuple[sp.csr_matrix, np.ndarray] | None] = []
    correction = None
    offset = 0
    for block, res, lam_b in zip(contact.blocks, results, lam):
        if res.W is None:  # no pair near this interface: nothing to constrain
            index.append(None)
            penalty.append(None)
            continue
        given = block.law.adjoint_rows(res.W.tocsr()[:, free], res.stiff, lam_b)
        if isinstance(given, PenaltyRows):
            index.append(None)
            penalty.append((given.W, given.stiff))
            continue
        assert isinstance(given, ConstraintRows)
        penalty.append(None)
        index.append((given.active, slice(offset, offset + given.active.size)))
        offset += given.active.size
        rows.append(given.W)
        D_parts.append(given.D)
        if given.closed_stiff.size:
            term = (given.closed_W.T @ sp.diags(given.closed_stiff) @ given.closed_W).tocsr()
            correction = term if correction is None else correction + term
    n_free = free.size
    G = sp.vstack(rows).tocsr() if rows else sp.csr_matrix((0, n_free))
    D = np.concatenate(D_parts) if D_parts else np.zeros(0)
    return _Constraints(G=G, D=D, index=tuple(index), penalty=tuple(penalty)), correction


def adjoint_rhs(partials: Partials, cons: _Constraints, free) -> tuple[np.ndarray, np.ndarray]:
    """(dtheta/du on the free dofs incl. penalty pressure terms, dtheta/dlam on the constrained rows)."""
    b = partials.u[free].copy()
    c = np.zeros(cons.G.shape[0])
    for dlam, idx, pen in zip(partials.lam, cons.index, cons.penalty):
        if pen is not None:  # lam_A = eps <-g/a>: dlam/du = -stiff_A w_A
            W, stiff = pen
            b -= W.T @ (stiff * dlam)
        if idx is not None:
            active, rows = idx
            c[rows] = dlam[active]
    return b, c


def sensitivities(
    system: System,
    state: State,
    responses,
    options: AdjointOptions | None = None,
    linear: LinearSolverOptions | None = None,
) -> AdjointResult:
    """Values and ``dtheta/drho`` (n_cells,) of ``responses`` at a converged ``state`` of ``system``.

    Parameters
    ----------
    system : the :class:`System` the state was solved with (same model, same discretization), or
        its Model
    state : converged :class:`State` (its ``evaluation`` is reused when present)
    responses : one :class:`Response` or a sequence of them; they share the factorization
    """
    options = options or AdjointOptions()
    linear = linear or LinearSolverOptions()
    responses = (responses,) if isinstance(responses, Response) else tuple(responses)
    if not isinstance(state, State):
        raise ConfigError(f"sensitivities needs the State that solve_static returned, got {type(state).__name__}")
    if state.t < 1.0 - 1e-12:
        raise ConfigError(f"the adjoint needs the state at the full load (t = 1), got t = {state.t:.4g}")
    for r in responses:
        if not isinstance(r, Response):
            raise ConfigError(
                f"responses must be Response objects (e.g. StrainEnergy(), ContactForce()), got {type(r).__name__}"
            )
    system = System.of(system)
    disc = system.disc
    refuse_friction(system.model)
    if state.u.shape != (disc.n_dofs,):
        raise ConfigError(
            f"the state does not belong to this system: it has {state.u.size} dofs, the system {disc.n_dofs}"
        )
    free = disc.free
    seconds = {"partials": 0.0, "evaluate": 0.0, "factorize": 0.0, "solve": 0.0, "vjp": 0.0}

    t0 = time.perf_counter()
    fields = Fields.from_state(system, state)
    evaluated = [r.evaluate(fields, gradient=True) for r in responses]
    seconds["partials"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    ev = state.evaluation
    if ev is None or ev.K_free is None:
        ev = system.evaluate(state.u, state.t, state.layout or disc.layout(), state.laws, tangent=True, full=False)
    K = ev.K_free
    cons, correction = (
        contact_rows(system, ev.contact, fields.lam, free)
        if system.has_contact
        else (_Constraints(sp.csr_matrix((0, free.size)), np.zeros(0), (), ()), None)
    )
    if correction is not None and system.disc.comm.rank == 0:  # K: this rank's part (contopt.parallel)
        K = (K - correction).tocsr()
    if system.disc.comm.distributed and options.method == "direct" and cons.G.shape[0]:
        raise ConfigError(
            "adjoint method 'direct' factors the saddle-point matrix on one process; in a distributed run "
            "use AdjointOptions(method='schur-cg') (the default) or 'uzawa'"
        )
    seconds["evaluate"] = time.perf_counter() - t0

    factors: dict = {}

    def factor_of(kind):
        """The stiffness factor (shared by every response) or the saddle-point one, made on first use."""
        if kind not in factors:
            t1 = time.perf_counter()
            if kind == "K":
                # its own factor (Newton's kept one is of an earlier iterate): every solve exact
                factors[kind] = factorize(K, replace(linear, factor_reuse=False), system.geometry(state.u))
            else:  # indefinite: a factorization, whatever solves the stiffness
                factors[kind] = factorize(_saddle_matrix(K, cons.G), _factorization_only(linear))
            seconds["factorize"] += time.perf_counter() - t1
        return factors[kind]

    # an iterative solve inside schur-cg/uzawa: 100x tighter than their own tolerance, so that
    # the outer iteration converges to it (both measure relative residuals)
    inner_rtol = min(linear.krylov_rtol, 1e-2 * options.rtol)
    solves_total, out = 0, []
    try:
        for response, (value, partials) in zip(responses, evaluated):
            b, c = adjoint_rhs(partials, cons, free)
            if cons.G.shape[0] == 0:
                factor = _Accurate(factor_of("K"), inner_rtol)
                t0 = time.perf_counter()
                w_f, mu, n_solves, its, res = factor.solve(b), np.zeros(0), 1, 0, 0.0
            elif options.method == "direct":
                factor = factor_of("saddle")
                t0 = time.perf_counter()
                w_f, mu, n_solves, its, res = _direct(factor, cons, b, c)
            else:
                factor = _Accurate(factor_of("K"), inner_rtol)
                t0 = time.perf_counter()
                solver = _schur_cg if options.method == "schur-cg" else _uzawa
                w_f, mu, n_solves, its, res = solver(factor, cons, b, c, options, response.name)
            seconds["solve"] += time.perf_counter() - t0
            solves_total += n_solves

            t0 = time.perf_counter()
            w = np.zeros(disc.n_dofs)
            w[free] = w_f
            gradient = partials.rho - disc.residual_rho_vjp(state.u, w, state.rho)
            mass_gradient = partials.mass - disc.residual_mass_vjp(w, state.t)
            seconds["vjp"] += time.perf_counter() - t0
            out.append(
                Sensitivity(
                    name=response.name,
                    value=value,
                    gradient=gradient,
                    w=w,
                    beta=_beta(cons, mu, c, fields.lam),
                    linear_solves=n_solves,
                    iterations=its,
                    residual=res,
                    mass_gradient=mass_gradient,
                )
            )
            log.info(
                "adjoint %s: %d solves, %d iterations, constraint residual %.1e", response.name, n_solves, its, res
            )
    finally:
        for f in factors.values():
            f.free()
    active = tuple(0 if idx is None else idx[0].size for idx in cons.index)
    return AdjointResult(
        sensitivities=tuple(out),
        method=options.method,
        seconds=seconds,
        linear_solves=solves_total,
        factorizations=len(factors),
        active=active,
    )


def refuse_friction(model) -> None:
    """ConfigError when an interface of ``model`` has friction: its state depends on the load path,
    and this adjoint differentiates the final equilibrium alone (:mod:`contopt.adjoint.path` runs
    back over the path)."""
    model = getattr(model, "model", model)  # a System or a Discretization: their Model
    rough = [i for i in model.interfaces if i.friction is not None]
    if rough:
        raise ConfigError(
            f"contact interface {rough[0].label} has friction ({rough[0].friction.describe()}): sensitivities "
            "of the final state alone do not apply (the state depends on the whole load path); use "
            "contopt.adjoint.path (solve_path, then path_sensitivities)"
        )


def refuse_path_alm(model) -> None:
    """ConfigError when a friction interface of ``model`` uses the augmented Lagrangian: the path
    adjoint differentiates pressures that are functions of the displacements (the penalty law)."""
    model = getattr(model, "model", model)
    for i in model.interfaces:
        if i.friction is not None and i.law.constrains:
            raise ConfigError(
                f"contact interface {i.label}: sensitivities through friction need the penalty normal law "
                f"(law='penalty', or enforcement = \"penalty\" in a problem file); the augmented Lagrangian's "
                f"multipliers are not differentiated along the load path"
            )


def _beta(cons: _Constraints, mu, c, lam) -> tuple:
    """Adjoint multipliers per interface, ``beta = mu + D dtheta/dlam`` on the active nodes."""
    out = []
    beta = mu + cons.D * c if mu.size else mu
    for idx, lam_b in zip(cons.index, lam):
        full = np.zeros_like(lam_b)
        if idx is not None and beta.size:
            active, rows = idx
            full[active] = beta[rows]
        out.append(full)
    return tuple(out)


def _scale(c, Gw0) -> float:
    return max(float(np.linalg.norm(c)), float(np.linalg.norm(Gw0)), 1e-300)


def _schur_cg(factor, cons: _Constraints, b, c, options: AdjointOptions, name: str):
    """Preconditioned CG on ``S mu = -c - G K^-1 b``, ``S = G K^-1 G^T``, preconditioner ``D``."""
    G, D = cons.G, cons.D
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


def _uzawa(factor, cons: _Constraints, b, c, options: AdjointOptions, name: str):
    """The paper's Algorithm 1 with a fixed factor: ``mu <- mu - D (G w + c)``, ``w = K^-1 (b + G^T mu)``."""
    G, D = cons.G, cons.D
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


class _Accurate:
    """A factor whose solves ask an iterative backend for relative residual ``rtol``, or for up to
    ``relax`` times that (never looser than ``RELAXED_RTOL``) where the caller's error allows."""

    def __init__(self, factor, rtol: float):
        self.factor, self.rtol = factor, rtol

    def solve(self, b: np.ndarray, relax: float = 1.0) -> np.ndarray:
        return self.factor.solve(b, rtol=min(max(RELAXED_RTOL, self.rtol), self.rtol * max(relax, 1.0)))


def _factorization_only(linear: LinearSolverOptions) -> LinearSolverOptions:
    """``linear`` restricted to factorizations (the saddle-point matrix is indefinite: no CG)."""
    if linear.backend in ITERATIVE:
        return replace(linear, backend="auto", iterative_above=2**62, factor_reuse=False)
    return replace(linear, iterative_above=2**62, factor_reuse=False)


def _saddle_matrix(K: sp.csr_matrix, G: sp.csr_matrix) -> sp.csr_matrix:
    n_c = G.shape[0]
    return sp.bmat([[K, -G.T], [-G, sp.csr_matrix((n_c, n_c))]], format="csr")


def _direct(saddle, cons: _Constraints, b, c):
    n = b.size
    x = saddle.solve(np.concatenate([b, c]))
    w, mu = x[:n], x[n:]
    # no unconstrained solve here to measure against: the size of the terms of G w is the scale
    res = float(np.linalg.norm(cons.G @ w + c)) / _scale(c, abs(cons.G) @ np.abs(w))
    return w, mu, 1, 0, res
