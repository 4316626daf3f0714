"""Contact laws: how a nonmortar node's weighted gap becomes a pressure, and the outer loop around Newton.

A law is an object on :class:`contopt.contact.interface.ContactInterface`. It owns

* its options (the penalty ``eps``; for the augmented Lagrangian its tolerances and strategy),
* its state per interface between Newton solves (:class:`LawState`: multipliers, penalty in use),
* the update and convergence test that run after each Newton solve (:meth:`ContactLaw.advance`),
  what to do when a Newton solve fails (:meth:`ContactLaw.retreat`) and how accurately a Newton
  solve that an update will follow needs to be solved (:meth:`ContactLaw.early_stop`),
* the rows it hands the adjoint (:meth:`ContactLaw.adjoint_rows`).

The solver (:func:`contopt.solve.static.solve_static`) only sees these methods through
:class:`contopt.contact.system.ContactDiscretization`; it knows no law by name.

Laws
----
* :class:`Penalty`: ``lam_A = eps <-gbar_A>``, no outer loop. ``eps`` is a pressure per unit
  gap: the penetration at pressure ``p`` is ``p / eps``. The adjoint sees ``lam`` as a function
  of ``u``.
* :class:`AugmentedLagrangian`: ``lam_A = <p_A - eps_A gbar_A>`` with Uzawa updates
  ``p <- lam`` until the multipliers and the gaps converge (paper eqs. 26-28). The adjoint sees
  ``g_A = 0`` on the active nodes as constraints.

Per-node penalty of the augmented Lagrangian (off by default)
-------------------------------------------------------------
A node whose support is only partly covered by the other surface has a small overlap area
``a_A = ∫_overlap N_A da`` against its full area ``A_A = ∫ N_A da``. ``max_coverage_scale > 1``
gives such nodes ``eps_A = eps s_A`` with ``s_A = clip(A_A / a_A, 1, max_coverage_scale)``, frozen
during each Newton solve, so that their own error contracts at the rate of a fully covered node.

It is off (``max_coverage_scale = 1``) because it changes the answer where the multipliers are not
unique. When the partly covered face is the nonmortar one, its active nodes outnumber what the
mortar side can resolve: only the nodal forces ``G^T lam`` are determined, and any multipliers
with the same forces are a solution. An update adds ``-eps_A g_A / a_A``, and ``g`` lies in the
range of ``G``, so the part of ``p`` that produces no force (measured in the metric
``sum_A a_A p_A^2 / eps_A``) never changes: from ``p = 0`` the iteration ends at the multipliers
of least ``sum_A a_A p_A^2 / eps_A``. With one ``eps`` that is the smoothest pressure field (a
uniform pressure on a patch test); with ``eps_A ~ 1/a_A`` barely covered nodes weigh nothing and
absorb the freedom (measured on a block under a uniform load on a larger rotated support taken
as nonmortar: nodes covered 4e-4 of their area end at 0.9976 of the uniform pressure, the same
forces to 1e-10). The scaling bought no iterations there or on the pressed rotated block (Newton
iterations 25 against 34, 15 against 20), since the convergence measure already counts the
pressure change of a node with its coverage ``min(1, a_A/A_A)``: a sliver's ill-determined
pressure, which carries almost no force, does not hold the iteration up.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np
import scipy.sparse as sp

from contopt.contact.enforcement import NodeTerms, node_terms
from contopt.errors import ConfigError

log = logging.getLogger(__name__)

#: the smallest pressure_rtol / gap_rtol accepted: float64 resolves relative changes of ~1e-16, and
#: the multiplier update amplifies the round-off of the gaps by the penalty (measured: the relative
#: pressure change stalls at 1e-10..1e-9 with a penalty grown 1e4 times)
MIN_RTOL = 1e-13


#: a stalled update whose largest nodal force change ``w_A |lam_A - p_A| a_A`` is within this factor of the
#: Newton solve's residual norm changed the multipliers by the equilibrium's own imbalance: they cannot be
#: known better than the forces they balance (measured on the seam's stalls, issue 35: 1.3-2.5x |r|; a
#: real update 140x and more)
NOISE_FACTOR = 10.0

#: what an intermediate load step of the augmented Lagrangian does (AugmentationOptions.intermediate)
INTERMEDIATE = ("update", "converge")


@dataclass(frozen=True)
class AugmentationOptions:
    """Options of the augmented-Lagrangian (Uzawa) loop around Newton.

    max_updates : multiplier updates per load step before the loop stops with an error
    pressure_rtol : converged when the largest nodal pressure change is below this times the
        largest nodal pressure
    gap_rtol : and the largest penetration below this times the median nonmortar facet size
    intermediate : ``"update"`` (one multiplier update per intermediate load step) or ``"converge"``
        (every load step converged), see below
    penalty_growth : the factor eps grows by after an update that did not bring convergence 4x closer
    max_penalty_stiffness : the largest penalty, relative to the stiffer body's ``E'/h`` (below)
    inexact : how loosely a Newton solve that a multiplier update follows is solved (below)
    max_coverage_scale : cap of the penalty factor of partly covered nodes; 1 switches it off
    patience : updates without halving the distance to convergence before the loop counts as stalled

    Converged when the largest nodal pressure change (weighted by the node's coverage, see the
    module docstring) is below ``pressure_rtol`` times the largest nodal pressure, and the largest
    normalized penetration below ``gap_rtol`` times the median nonmortar facet size.

    ``intermediate``: ``"update"`` (default) makes one Newton solve and one multiplier update per
    intermediate load step and converges the augmentations at the final load factor only:
    elastic frictionless contact is path independent, so the intermediate states need not satisfy
    the constraint exactly, and this saves most of the Newton iterations. ``"converge"``
    converges every load step (for load histories that are wanted accurately step by step).

    Penalty growth (the method of multipliers' classical rule): when an update did not reduce the
    distance to convergence (the larger of the multiplier change and the penetration, each over
    its tolerance) by at least 4x, eps is multiplied by ``penalty_growth``, up to
    ``max_penalty_stiffness * E_max / h`` (never below the interface's own eps; ``E_max``: the larger
    of the two bodies' ``E' = E/(1-nu^2)``, ``h``: the median nonmortar facet size), i.e. a nodal
    contact stiffness ``eps a_A`` of at most ``max_penalty_stiffness`` times the stiffer body's
    ``E' h``. There every update already cuts a node's error about ``max_penalty_stiffness``-fold
    (the local compliance is at least ``1/(E_max h)``), so a larger eps saves at most an update,
    while it makes the contact the stiffest part of the tangent and its round-off Newton's floor.
    ``penalty_growth=1`` keeps eps fixed.

    ``inexact``: a Newton solve that a multiplier update will follow stops once
    ``|r| <= inexact * dp * r_ref`` (``dp``: the relative multiplier change the update is about
    to make); the last augmentation is always solved to the Newton tolerances. ``0`` solves every
    augmentation fully.

    ``max_coverage_scale``: cap of the per-node penalty factor ``A_A / a_A`` of partly covered
    nodes; 1 (default) switches it off. Above 1 the pressures of partly covered nodes may depend
    on it where the multipliers are not unique (module docstring); the forces do not.

    Stall: when the distance to convergence has not halved over ``patience`` updates while the
    penalty can grow no further, the iteration has reached what round-off allows. The step is
    then accepted (with a warning) if both measures are within 100x of their tolerances or the
    update's largest nodal force change is within :data:`NOISE_FACTOR` times the residual of a
    solve run to Newton's criteria, and otherwise stops at once with an error that says what was
    reached; so does running out of
    ``max_updates``. Neither is retried with a smaller load step: the multipliers of a converged
    Newton solve do not converge better from a shorter step.
    """

    max_updates: int = 50
    pressure_rtol: float = 1e-6
    gap_rtol: float = 1e-6
    intermediate: str = "update"
    penalty_growth: float = 10.0
    max_penalty_stiffness: float = 1e3
    inexact: float = 1e-2
    max_coverage_scale: float = 1.0
    patience: int = 5

    def __post_init__(self):
        for key in ("max_updates", "patience"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ConfigError(f"augmentation.{key} must be a positive integer, got {v!r}")
        for key in ("pressure_rtol", "gap_rtol"):
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and v > 0):
                raise ConfigError(f"augmentation.{key} must be > 0, got {v!r}")
            if v < MIN_RTOL:
                raise ConfigError(
                    f"augmentation.{key} = {v:g} is below what round-off allows: float64 pressures "
                    f"and gaps cannot be converged to better than about {MIN_RTOL:g} relative; "
                    f"use a value >= {MIN_RTOL:g} (1e-10 is already very tight)"
                )
        for key in ("penalty_growth", "max_coverage_scale"):
            if not (getattr(self, key) >= 1.0):
                raise ConfigError(f"augmentation.{key} must be >= 1, got {getattr(self, key)!r}")
        if not (self.max_penalty_stiffness > 0):
            raise ConfigError(f"augmentation.max_penalty_stiffness must be > 0, got {self.max_penalty_stiffness!r}")
        if not (0.0 <= self.inexact < 1.0):
            raise ConfigError(f"augmentation.inexact must lie in [0, 1), got {self.inexact!r}")
        if self.intermediate not in INTERMEDIATE:
            raise ConfigError(f"augmentation.intermediate must be 'update' or 'converge', got {self.intermediate!r}")


@dataclass(frozen=True, eq=False)
class LawState:
    """One interface's law state between Newton solves (all arrays (n,) over its nonmortar nodes).

    p : multipliers (zero for the penalty law)
    eps : interface penalty in use (the augmented Lagrangian may grow it)
    scale : per-node penalty factor, ``eps_A = eps * scale_A`` (ones for the penalty law)
    eps_own : the interface's own penalty
    eps_max : the largest penalty growth may reach (:meth:`ContactLaw.max_penalty`, at least eps_own)
    eps_start : penalty at the start of every load step (eps_own, or a warm start's grown one)
    eps_prev, last_error, best_error, since_best, grow, updates : the outer loop's record within
        the current load step (see :class:`AugmentationOptions`)
    traction : (n, 3) friction tractions at the end of the last load step (None without friction)
    x_prev : (N, 3) positions of all nodes at the end of the last load step, from which the step's
        slip is measured (None without friction; shared by the interfaces, not copied)
    """

    p: np.ndarray
    eps: float
    scale: np.ndarray
    eps_own: float
    eps_start: float
    eps_max: float = math.inf
    eps_prev: float = 0.0
    last_error: float | None = None
    best_error: float = math.inf
    since_best: int = 0
    grow: bool = True
    updates: int = 0
    traction: np.ndarray | None = None
    x_prev: np.ndarray | None = None

    @property
    def penalties(self) -> np.ndarray:
        """(n,) the per-node penalty ``eps * scale``."""
        return self.eps * self.scale


@dataclass(frozen=True)
class Measures:
    """How far one interface is from the law's fixed point after a Newton solve.

    pressure_change : largest coverage-weighted nodal pressure change over the largest nodal
        pressure (0 without pressure); penetration : deepest ``max(0, -g_A/a_A) / h``
    """

    pressure_change: float
    penetration: float


@dataclass(frozen=True, eq=False)
class Outcome:
    """What a law decided after a Newton solve.

    status : ``"done"`` (this interface needs no further update in this load step),
        ``"continue"`` (solve again with ``state``) or ``"failed"`` (``message`` says why)
    state : the state to go on with (for "done": the one to carry to the next load step)
    """

    status: str
    state: LawState
    measures: Measures
    message: str = ""


@dataclass(frozen=True, eq=False)
class PenaltyRows:
    """Adjoint rows of a penalty interface: the pressures ``lam = eps <-g/a>`` are functions of u.

    W : (n, n_free) rows ``w_A = dg_A - gbar_A da_A``; stiff : (n,) ``eps H_A / a_A``
    """

    W: sp.csr_matrix
    stiff: np.ndarray


@dataclass(frozen=True, eq=False)
class ConstraintRows:
    """Adjoint rows of a multiplier interface: ``g_A = 0`` on the active nodes.

    active : positions of the active nodes in the interface's node list; W : (k, n_free) their
    rows; D : (k,) their penalty weights ``eps_A / a_A`` (the tangent's ``G^T D G`` part);
    closed : (m, n_free) rows and (m,) weights of nodes the tangent counted closed although they
    carry no pressure (the adjoint takes their rank-one terms back out)
    """

    active: np.ndarray
    W: sp.csr_matrix
    D: np.ndarray
    closed_W: sp.csr_matrix
    closed_stiff: np.ndarray


class ContactLaw:
    """Base class of the contact laws (see the module docstring for the protocol)."""

    name: ClassVar[str] = ""
    #: default eps = factor * E* / h (E*: contact modulus of the pair, h: median nonmortar facet size)
    eps_factor: ClassVar[float] = 1.0
    #: True when the adjoint treats the law's pressures as multipliers of constraints g_A = 0
    constrains: ClassVar[bool] = False
    eps: float | None = None

    def _check_eps(self) -> None:
        if self.eps is not None and not (isinstance(self.eps, (int, float)) and np.isfinite(self.eps) and self.eps > 0):
            raise ConfigError(f"{type(self).__name__}.eps must be a positive number, got {self.eps!r}")

    def resolve_eps(self, e_star: float, h: float) -> float:
        """The penalty in use: ``eps``, or ``eps_factor * E* / h`` when it is None."""
        return float(self.eps) if self.eps is not None else self.eps_factor * e_star / h

    def max_penalty(self, e_max: float, h: float) -> float:
        """The largest penalty the outer loop may grow to, with ``e_max`` the stiffer body's ``E'``
        and ``h`` the median nonmortar facet size (no growth: infinity)."""
        return math.inf

    def start(
        self,
        n: int,
        eps: float,
        p: np.ndarray | None = None,
        eps_start: float | None = None,
        eps_max: float = math.inf,
    ) -> LawState:
        """A new state over ``n`` nodes with penalty ``eps`` (from a warm start: ``p`` and a grown
        ``eps_start``); growth stops at ``eps_max`` (or ``eps`` where that is larger)."""
        p = np.zeros(n) if p is None else np.asarray(p, dtype=np.float64).copy()
        if p.shape != (n,):
            raise ConfigError(f"contact multipliers must have one value per nonmortar node ({n}), got {p.shape}")
        e0 = float(eps if eps_start is None else eps_start)
        return LawState(
            p=p, eps=e0, scale=np.ones(n), eps_own=float(eps), eps_start=e0, eps_prev=e0, eps_max=max(eps, eps_max)
        )

    def begin_step(self, state: LawState) -> LawState:
        """The state at the start of a load step: the outer loop's record cleared."""
        return replace(
            state,
            eps=state.eps_start,
            eps_prev=state.eps_start,
            last_error=None,
            best_error=math.inf,
            since_best=0,
            grow=True,
            updates=0,
        )

    def with_coverage(self, state: LawState, coverage: np.ndarray) -> LawState:
        """The state with its per-node penalty factors set from the nodes' coverage ``a_A/A_A``."""
        return state

    def multipliers_and_penalties(self, state: LawState, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The multipliers ``p`` and penalties ``eps`` (each (k,)) of the nodes ``nodes`` (indices or
        mask): the pressure is ``max(0, p - eps g/a)``."""
        raise NotImplementedError

    def node_terms(
        self, g: np.ndarray, a: np.ndarray, state: LawState, nodes: np.ndarray, touch: float | np.ndarray
    ) -> NodeTerms:
        """Potential terms of the nodes ``nodes`` (indices or mask) with gaps g and areas a."""
        p, eps = self.multipliers_and_penalties(state, nodes)
        return node_terms(g, a, p, eps, touch=touch)

    def measures(self, result, state: LawState, h: float) -> Measures:
        """Distance to the fixed point of an evaluation ``result`` (an InterfaceResult)."""
        return Measures(pressure_change=0.0, penetration=deepest_penetration(result, h))

    def advance(self, result, state: LawState, final: bool, h: float, residual: float = 0.0) -> Outcome:
        """After a converged Newton solve that ended at residual norm ``residual``: update, test, decide
        (:class:`Outcome`)."""
        return Outcome("done", state, self.measures(result, state, h))

    def retreat(self, state: LawState) -> LawState | None:
        """After a failed Newton solve: a state to try again with, or None (the load step fails)."""
        return None

    def settle(self, result, state: LawState, h: float) -> Outcome:
        """After a Newton solve that followed an update failed and :meth:`retreat` had nothing to try:
        whether the last converged solve (its ``result`` with the ``state`` it was solved with) is
        accepted ("done") or the load step fails without a cutback ("failed": a shorter step would
        reach the same multipliers and the same failing solve). A law without an outer loop takes it."""
        return Outcome("done", state, self.measures(result, state, h))

    def early_stop(self, result, state: LawState, h: float) -> float | None:
        """How accurately the current Newton solve must be solved: None (no opinion: no update
        follows), 0 (to the Newton tolerances) or a factor f (stop at ``|r| <= f r_ref``)."""
        return None

    @property
    def converges_every_step(self) -> bool:
        """Does every load step end at an equilibrium of this law (not only the last)? An adjoint of
        a response at an intermediate step needs it."""
        return True

    def adjoint_rows(self, W, stiff: np.ndarray, lam: np.ndarray):
        """:class:`PenaltyRows` or :class:`ConstraintRows` for the adjoint (W on the free dofs)."""
        raise NotImplementedError

    def describe(self) -> str:
        return self.name


@dataclass(frozen=True)
class Penalty(ContactLaw):
    """Penalty enforcement: ``lam_A = eps <-gbar_A>`` (no outer loop).

    eps : pressure per unit gap (force/length^3); default ``100 E*/h`` (``E*``: contact modulus
        ``1/E* = 1/E1' + 1/E2'``, ``E' = E/(1-nu^2)``; ``h``: median nonmortar facet size), so a
        pressure p penetrates ``p h / (100 E*)``.
    """

    eps: float | None = None
    name: ClassVar[str] = "penalty"
    eps_factor: ClassVar[float] = 100.0
    constrains: ClassVar[bool] = False

    def __post_init__(self):
        self._check_eps()

    def multipliers_and_penalties(self, state, nodes):
        p = np.zeros_like(state.p)[nodes]
        return p, np.full(p.shape, state.eps)

    def adjoint_rows(self, W, stiff, lam):
        return PenaltyRows(W=W, stiff=stiff)


@dataclass(frozen=True)
class AugmentedLagrangian(ContactLaw):
    """Augmented-Lagrangian enforcement with Uzawa updates (paper eqs. 26-28).

    eps : penalty, pressure per unit gap; default ``10 E*/h`` (see :class:`Penalty`). The paper's
        eps = 10 (E = 1) is ``eps=10``.
    options : :class:`AugmentationOptions` (tolerances, penalty growth, inexact solves, ...)
    """

    eps: float | None = None
    options: AugmentationOptions = field(default_factory=AugmentationOptions)
    name: ClassVar[str] = "alm"
    eps_factor: ClassVar[float] = 10.0
    constrains: ClassVar[bool] = True

    def __post_init__(self):
        self._check_eps()
        if not isinstance(self.options, AugmentationOptions):
            raise ConfigError(
                f"AugmentedLagrangian.options must be AugmentationOptions, got {type(self.options).__name__}"
            )

    def with_options(self, options: AugmentationOptions | None) -> AugmentedLagrangian:
        return self if options is None else replace(self, options=options)

    def max_penalty(self, e_max, h):
        return self.options.max_penalty_stiffness * e_max / h

    def with_coverage(self, state, coverage):
        cap = self.options.max_coverage_scale
        scale = np.where(coverage > 0, np.clip(1.0 / np.maximum(coverage, 1.0 / cap), 1.0, cap), 1.0)
        return replace(state, scale=scale)

    def multipliers_and_penalties(self, state, nodes):
        return state.p[nodes], state.penalties[nodes]

    def measures(self, result, state, h):
        pen = deepest_penetration(result, h)
        weight = np.minimum(1.0, result.coverage)
        scale = float((weight * np.abs(result.lam)).max(initial=0.0))
        change = float((weight * np.abs(result.lam - state.p)).max(initial=0.0))
        return Measures(pressure_change=change / scale if scale > 0 else 0.0, penetration=pen)

    def _converged(self, m: Measures, factor: float = 1.0) -> bool:
        o = self.options
        return m.pressure_change <= factor * o.pressure_rtol and m.penetration <= factor * o.gap_rtol

    @property
    def converges_every_step(self) -> bool:
        return self.options.intermediate == "converge"

    def advance(self, result, state, final, h, residual=0.0):
        o = self.options
        m = self.measures(result, state, h)
        updated = self.with_coverage(
            replace(state, p=np.array(result.lam, dtype=np.float64), updates=state.updates + 1), result.coverage
        )
        if not (final or o.intermediate == "converge"):
            return Outcome("done", updated, m)  # carry the improved multipliers to the next step
        if self._converged(m):
            return Outcome("done", state, m)
        error = max(m.pressure_change / o.pressure_rtol, m.penetration / o.gap_rtol)
        eps, grow = state.eps, state.grow
        if (
            state.eps > state.eps_prev
            and state.last_error is not None
            and error > state.last_error
            and m.penetration <= o.gap_rtol
        ):
            # the gaps are closed and the grown penalty made the pressure change larger: it is now the
            # penalty times the round-off of the gaps, not a contraction. Back off, grow no more.
            eps, grow = state.eps_prev, False
        elif grow and state.last_error is not None and error > 0.25 * state.last_error:
            eps = max(state.eps, min(state.eps * o.penalty_growth, state.eps_max))
        improved = error < 0.5 * state.best_error
        nxt = replace(
            updated,
            eps=eps,
            eps_prev=state.eps,
            last_error=error,
            grow=grow,
            best_error=error if improved else state.best_error,
            since_best=0 if improved else state.since_best + 1,
        )
        at_cap = eps >= state.eps_max or not grow or o.penalty_growth == 1.0
        stalled = nxt.since_best >= o.patience and at_cap
        if not stalled and nxt.updates < o.max_updates:
            return Outcome("continue", nxt, m)
        reached = (
            f"pressure change {m.pressure_change:.2e} (target {o.pressure_rtol:.1e}), penetration "
            f"{m.penetration:.2e} h (target {o.gap_rtol:.1e})"
        )
        # a stall whose force change is the solve's own residual: more updates only move that noise about
        change = _force_change(result, state) if stalled else np.inf
        near = self._converged(m, 100.0)
        if near or change <= NOISE_FACTOR * residual:
            log.warning(
                "augmented Lagrangian %s at %s, %s with eps %.3g; accepting the state",
                "stalled" if stalled else f"ran out of {o.max_updates} updates",
                reached,
                "within 100x of the targets"
                if near
                else f"its force change {change:.2e} within {NOISE_FACTOR:g}x the solve's residual {residual:.2e}",
                state.eps,
            )
            return Outcome("done", state, m)
        if stalled:
            message = (
                f"the augmented-Lagrangian updates stall at {reached} after {nxt.updates} updates: "
                f"below what this solve can attain; loosen augmentation.pressure_rtol / gap_rtol to about "
                f"{_loosened(m, o)}"
            )
        else:
            message = (
                f"the augmented Lagrangian did not converge in {o.max_updates} updates ({reached}); raise "
                f"augmentation.max_updates, loosen the tolerances, or use more load steps if the contact "
                f"zone changes a lot"
            )
        return Outcome("failed", nxt, m, message)

    def retreat(self, state):
        if state.eps == state.eps_prev:
            return None
        # a grown penalty can make the active set chatter: go back to the last eps that converged
        # (from the same converged u) and stop growing it in this step
        log.info("  Newton failed after the penalty grew; back to eps = %.3g", state.eps_prev)
        return replace(state, eps=state.eps_prev, grow=False)

    def settle(self, result, state, h):
        o = self.options
        m = self.measures(result, state, h)
        reached = (
            f"pressure change {m.pressure_change:.2e} (target {o.pressure_rtol:.1e}), penetration "
            f"{m.penetration:.2e} h (target {o.gap_rtol:.1e})"
        )
        if self._converged(m, 100.0):
            log.warning(
                "augmented Lagrangian: Newton failed after update %d; the last converged solve, at %s (within 100x "
                "of the targets), is accepted",
                state.updates + 1,
                reached,
            )
            return Outcome("done", state, m)
        message = (
            f"Newton failed after multiplier update {state.updates + 1}, the last converged solve at {reached}; "
            f"a shorter load step reaches the same multipliers: loosen augmentation.pressure_rtol / gap_rtol to "
            f"about {_loosened(m, o)}, or lower augmentation.max_penalty_stiffness (eps {state.eps:.3g})"
        )
        return Outcome("failed", state, m, message)

    def early_stop(self, result, state, h):
        o = self.options
        if o.inexact == 0.0:
            return 0.0
        m = self.measures(result, state, h)
        return 0.0 if self._converged(m) else o.inexact * m.pressure_change

    def adjoint_rows(self, W, stiff, lam):
        active = np.flatnonzero(lam > 0)
        # a node at zero pressure but within round-off of closing got the penalty in the tangent:
        # the paper treats it as inactive, so the adjoint takes its rank-one term back out
        closed = np.flatnonzero((stiff > 0) & ~(lam > 0))
        return ConstraintRows(
            active=active, W=W[active], D=stiff[active], closed_W=W[closed], closed_stiff=stiff[closed]
        )

    def describe(self) -> str:
        return f"alm (pressure_rtol {self.options.pressure_rtol:g}, gap_rtol {self.options.gap_rtol:g})"


def deepest_penetration(result, h: float) -> float:
    """``max(0, -g_A / a_A) / h`` over the nodes with overlap of an InterfaceResult."""
    has = result.has_overlap
    return float(np.maximum(0.0, -result.g[has] / result.a[has]).max(initial=0.0)) / h


def _force_change(result, state: LawState) -> float:
    """The largest coverage-weighted nodal force change ``w_A |lam_A - p_A| a_A`` of an update."""
    weight = np.minimum(1.0, result.coverage)
    return float((weight * np.abs(result.lam - state.p) * result.a).max(initial=0.0))


def _loosened(m: Measures, o: AugmentationOptions) -> str:
    p = max(o.pressure_rtol, 10.0 ** math.ceil(math.log10(max(m.pressure_change, 1e-300))))
    g = max(o.gap_rtol, 10.0 ** math.ceil(math.log10(max(m.penetration, 1e-300))))
    return f"{p:.0e} / {g:.0e}"


#: the laws by the names the problem files and the command line use
LAWS: dict[str, type[ContactLaw]] = {"alm": AugmentedLagrangian, "penalty": Penalty}


def law_named(name: str, **kwargs) -> ContactLaw:
    """The law ``name`` (a key of :data:`LAWS`) with its options."""
    if name not in LAWS:
        raise ConfigError(f"unknown contact law {name!r}; choose one of {sorted(LAWS)}")
    return LAWS[name](**kwargs)
