"""What the static and the path adjoint share: the responses and the state they are asked for, the
rows each contact law hands the adjoint, the right-hand sides, and the results.

At a converged state the residual is ``R(u, lam; rho) = r_b(u; rho) - sum_A lam_A w_A`` with
``w_A = dg_A/du``. A law with multipliers (the augmented Lagrangian) hands the rows of its active
nodes as constraints ``g_A(u) = 0`` (:class:`contopt.contact.laws.ConstraintRows`); the penalty
law's pressures ``lam_A = eps <-g_A/a_A>`` are functions of ``u``, so ``dtheta/dlam`` moves into
the right-hand side as ``-W^T diag(eps H/a) dtheta/dlam`` (:class:`contopt.contact.laws.PenaltyRows`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from contopt.contact.laws import ConstraintRows, PenaltyRows
from contopt.errors import ConfigError
from contopt.responses.base import Partials, Response
from contopt.solve.static import State
from contopt.solve.system import System


@dataclass(frozen=True, eq=False)
class Sensitivity:
    """One response's value and total derivative.

    Attributes
    ----------
    name, value : the response
    gradient : (n_cells,) dtheta/drho
    mass_gradient : (n_cells,) dtheta/dmass (the material share scaling the volume loads; zero without them)
    w : (n_dofs,) adjoint displacement (of the load step the response is evaluated at); beta : per
        interface, adjoint multipliers (zero where inactive; empty for the path adjoint)
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
    """Sensitivities of several responses at one state, with the cost of getting them.

    method : the saddle-point method of the static adjoint, or ``"path"`` (a factorization per load step)
    """

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
class AdjointRows:
    """The constraint rows on the free dofs and their penalty weights, per interface.

    G : (n_c, n_free) the active rows of the multiplier laws, stacked; D : (n_c,) their penalty
    weights; index : per interface, (positions in its node list, slice in G's rows) or None;
    penalty : per interface, ``(W_free, stiff)`` of a penalty law, else None
    """

    G: sp.csr_matrix
    D: np.ndarray
    index: tuple
    penalty: tuple

    @classmethod
    def none(cls, n_free: int) -> AdjointRows:
        """No contact: no rows."""
        return cls(sp.csr_matrix((0, n_free)), np.zeros(0), (), ())


def checked_responses(responses) -> tuple:
    """``responses`` (one Response or several) as a tuple; ConfigError for anything else."""
    responses = (responses,) if isinstance(responses, Response) else tuple(responses)
    for r in responses:
        if not isinstance(r, Response):
            raise ConfigError(
                f"responses must be Response objects (e.g. StrainEnergy(), ContactForce()), got {type(r).__name__}"
            )
    return responses


def step_state(system: System, state: State, step: int | None) -> tuple[State, int | None]:
    """The state a response is evaluated at, and its index in ``state.path`` (None: ``state`` itself).

    ``step`` (None: the final state, which must have reached the full load) indexes the recorded
    load steps :attr:`State.path` like a sequence (``-1`` the last). ConfigError for a state of
    another system, a path not recorded or a step out of range.
    """
    if not isinstance(state, State):
        raise ConfigError(f"sensitivities needs the State that solve_static returned, got {type(state).__name__}")
    if state.u.shape != (system.disc.n_dofs,):
        raise ConfigError(
            f"the state does not belong to this system: it has {state.u.size} dofs, the system {system.disc.n_dofs}"
        )
    if state.t < 1.0 - 1e-12:
        raise ConfigError(f"the adjoint needs the state at the full load (t = 1), got t = {state.t:.4g}")
    if step is None:
        return state, None
    n = len(state.path)
    if not n:
        raise ConfigError("step= needs the load steps of the solve: solve with solve_static(..., record_path=True)")
    if not isinstance(step, (int, np.integer)) or not -n <= step < n:
        raise ConfigError(f"step must be an integer index into the {n} recorded load steps, got {step!r}")
    k = int(step) % n
    loose = system.contact.loose_steps() if system.contact is not None and k < n - 1 else []
    if loose:
        raise ConfigError(
            f"contact interface {loose[0]}: its augmented Lagrangian converges the final load step only, so an "
            f'earlier step ({step}) is no equilibrium to differentiate; set augmentation.intermediate = "converge"'
        )
    return (state if k == n - 1 else state.path[k]), k


def contact_rows(system: System, results, lam, free) -> tuple[AdjointRows, sp.csr_matrix | None]:
    """The rows each interface's law hands the adjoint (constraints of a multiplier law, pressures
    as functions of u for a penalty law), and the tangent correction for nodes the tangent
    counted closed that carry no pressure."""
    contact = system.contact
    if contact is None or not system.has_contact:
        return AdjointRows.none(free.size), None
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
    G = sp.vstack(rows).tocsr() if rows else sp.csr_matrix((0, free.size))
    D = np.concatenate(D_parts) if D_parts else np.zeros(0)
    return AdjointRows(G=G, D=D, index=tuple(index), penalty=tuple(penalty)), correction


def adjoint_rhs(partials: Partials, rows: AdjointRows, free) -> tuple[np.ndarray, np.ndarray]:
    """(dtheta/du on the free dofs incl. penalty pressure terms, dtheta/dlam on the constrained rows)."""
    b = partials.u[free].copy()
    c = np.zeros(rows.G.shape[0])
    for dlam, idx, pen in zip(partials.lam, rows.index, rows.penalty):
        if pen is not None:  # lam_A = eps <-g/a>: dlam/du = -stiff_A w_A
            W, stiff = pen
            b -= W.T @ (stiff * dlam)
        if idx is not None:
            active, span = idx
            c[span] = dlam[active]
    return b, c


def residual_vjp(system: System, state: State, w_free: np.ndarray):
    """``(w, w . dR/drho, w . dR/dmass)`` at ``state``: the adjoint displacement ``w`` (n_dofs,) from its
    free dofs, and its products with the residual's design derivatives ((n_cells,) each), which a
    response's total derivative subtracts from its explicit one."""
    disc = system.disc
    w = np.zeros(disc.n_dofs)
    w[disc.free] = w_free
    return w, disc.residual_rho_vjp(state.u, w, state.rho), disc.residual_mass_vjp(w, state.t)
