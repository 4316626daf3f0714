"""Quasi-static equilibrium of a model: load steps -> Newton -> the contact laws' outer loop.

:func:`solve_static` reads as the algorithm. The load factor goes from 0 to 1 in steps
(cut back after a failure, :func:`contopt.solve.stepping.solve_load_steps`). Each step solves
Newton at fixed contact-law states, asks the laws what they decide
(:meth:`contopt.contact.system.ContactDiscretization.advance`: done, solve again with updated
multipliers, or fail) and, once they are done, checks the state independently of the contact
pairing (:meth:`~contopt.contact.system.ContactDiscretization.verify`). A state in which a node
lies inside the other body without pressure to hold it is never accepted: the step is cut back,
and an error names the interface, the node and its penetration when that does not help. The
solver knows no contact law by name.
"""

from __future__ import annotations

import itertools
import logging
import time
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from contopt.assembly.model import Model
from contopt.assembly.system import Discretization, Evaluation, Layout
from contopt.contact.laws import AugmentationOptions
from contopt.errors import ConfigError, ConvergenceError
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton import (
    DEFAULT_ADVICE,
    NewtonLog,
    NewtonOptions,
    StepFailure,
    newton_step,
)
from contopt.solve.stepping import StepResult, solve_load_steps
from contopt.solve.system import DEEP_PENETRATION, System

log = logging.getLogger(__name__)

__all__ = ["AugmentationOptions", "DEEP_PENETRATION", "State", "System", "solve_static"]

#: the rounded cone edges (Coulomb.edge) of the continuation that solves a failed frictional load step
#: again (measured: the friction clamp's failing trial designs converge with an edge of 0.1 or more)
EDGE_LADDER = (0.4, 0.2, 0.1)
#: with friction, Newton mostly fails where nodes change between stick and slip from one iteration
#: to the next; what is left to try once even the cone-edge continuation failed
FRICTION_ADVICE = (
    f"{DEFAULT_ADVICE}; with friction, where nodes change between stick and slip from one iteration to the "
    "next: a wider rounded cone edge (friction.edge = 0.1 to 0.15), a softer stick penalty (friction.eps, "
    "e.g. 10 E*/h) or newton.stall_rtol (docs/friction.md, limits)"
)


@dataclass(frozen=True, eq=False)
class State:
    """A converged equilibrium (returned, never stored on the model); also a warm start.

    Attributes
    ----------
    u : (n_dofs,) stacked displacements
    t : load factor reached (1.0 when the whole load was applied)
    layout : the design the state was solved for (stiffness factor ``rho`` and material share
        ``mass`` per cell); ``rho`` and ``mass`` read it
    logs : NewtonLog of every Newton solve (failed ones included)
    reactions : (n_dofs,) residual = reaction forces on constrained dofs, ~0 elsewhere
    laws : the contact laws' states per interface (multipliers, penalty in use) of the last
        Newton solve; ``multipliers`` and ``eps`` read them
    contact : per-interface InterfaceResult at the converged state (gaps, pressures, ...)
    checks : per-interface :class:`contopt.contact.verify.CheckReport` of the converged state
    alm_updates : number of multiplier updates over all load steps
    evaluation : the Evaluation (residual, tangent, contact results) at ``u`` with the law
        states of the last Newton solve: the converged tangent that the adjoint reuses

    A warm start needs only ``u`` and ``laws``: ``State(u=u)`` starts from a displacement alone.
    """

    u: np.ndarray
    t: float = 1.0
    layout: Layout | None = field(repr=False, default=None)
    logs: tuple = ()
    reactions: np.ndarray | None = field(repr=False, default=None)
    laws: tuple = ()
    contact: tuple = ()
    checks: tuple = ()
    alm_updates: int = 0
    evaluation: Evaluation | None = field(repr=False, default=None)

    @property
    def rho(self) -> np.ndarray | None:
        return None if self.layout is None else self.layout.rho

    @property
    def mass(self) -> np.ndarray | None:
        return None if self.layout is None else self.layout.mass

    @property
    def multipliers(self) -> tuple:
        """Per interface, the multipliers of the last Newton solve (zero for penalty interfaces)."""
        return tuple(s.p for s in self.laws)

    @property
    def eps(self) -> tuple:
        """Per interface, the penalty in use at the end (an augmented Lagrangian may have grown it)."""
        return tuple(s.eps for s in self.laws)

    @property
    def newton_iterations(self) -> int:
        return int(sum(lg.iterations for lg in self.logs if lg.converged))

    @property
    def seconds(self) -> dict:
        out: dict = {}
        for lg in self.logs:
            for k, v in lg.seconds.items():
                out[k] = out.get(k, 0.0) + v
        return out


def solve_static(
    model: Model | Discretization | System,
    rho=None,
    newton: NewtonOptions | None = None,
    linear: LinearSolverOptions | None = None,
    augmentation: AugmentationOptions | None = None,
    start: State | None = None,
    on_step=None,
    mass=None,
) -> State:
    """Solve for equilibrium at load factor 1 (in load steps from 0, or from ``start``).

    Parameters
    ----------
    model : a Model, its Discretization or its :class:`System` (reuses the precomputation)
    rho : (n_cells,) stiffness factor per cell over all bodies (default ones)
    mass : (n_cells,) material share per cell that scales body forces and accelerations (default:
        None, the loads as given); a design problem passes the volume fraction nu
    augmentation : options replacing those of every augmented-Lagrangian interface for this solve
    start : start from this state's displacement and contact-law states (e.g. the last
        design's): near a converged state the multipliers then need a few updates instead of a
        dozen. Its penalties (grown by the augmentations) are the start of every load step;
        growth stays capped relative to the interfaces' own eps.
    on_step : called with a :class:`State` after every converged load step (output, progress)

    Raises :class:`contopt.errors.ConvergenceError` (with logs and the last converged state) when a
    load step cannot converge, when the contact laws cannot converge at a load (no cutback: a
    shorter step would not help them), or when every converged state of a step fails the contact
    check even at the minimum step.
    """
    system = System.of(model).with_augmentation(augmentation)
    disc = system.disc
    layout = disc.layout(rho, mass)
    newton = newton or NewtonOptions()
    linear = linear or LinearSolverOptions()
    f_norm = float(np.linalg.norm(disc.f_ext(layout.mass)[disc.free]))
    start = _checked_start(start, disc.n_dofs)
    if system.has_friction:
        if start is not None:
            raise ConfigError(
                "a warm start cannot be used with friction: the frictional state depends on the whole load "
                "path, so every solve starts from the undeformed bodies (drop start=...)"
            )
        if linear.symmetric:
            linear = replace(linear, symmetric=False)  # the frictional tangent is unsymmetric
    laws0 = _start_laws(system, start, layout)
    counter = {"updates": 0, "in_contact": False}
    pace: list[np.ndarray] = []  # the last converged step's increment of the free dofs per unit load

    def step(u, t, dt, laws):
        # an iterative solver starts the step's first solve from the last step's pace: where the
        # response is linear (bodies moved before they touch) that is the answer, and Newton
        # needs one iteration as with a direct solver instead of three to seven (fine die-slab)
        guess = dt * pace[0] if pace else None
        result = _load_step_or_continue(system, layout, u, t, dt, laws, f_norm, newton, linear, counter, guess)
        pace[:] = [(result.u - u)[disc.free] / dt]
        return result

    def step_callback(res: StepResult):
        if on_step is not None:
            on_step(_state(res, layout, res.logs, counter["updates"]))

    try:
        logs, last = solve_load_steps(
            step,
            disc.n_dofs,
            disc.constrained,
            disc.prescribed,
            newton,
            u0=None if start is None else start.u,
            state0=laws0,
            on_step=step_callback,
        )
    except ConvergenceError as err:
        # what the caller gets back is a State, like a converged solve's (t < 1 when the load stopped short)
        last = err.last_state
        if last is not None and not isinstance(last, State):
            err.last_state = _state(last, layout, tuple(err.logs), counter["updates"])
        raise
    state = _state(last, layout, tuple(logs), counter["updates"])
    if system.contact is not None:
        for warning in system.contact.coarse_side_warnings(state.checks):
            log.warning("%s", warning)
    return state


def _checked_start(start: State | None, n_dofs: int) -> State | None:
    """The warm start as given, its displacement float64; ConfigError for anything but a State of this system."""
    if start is None:
        return None
    if not isinstance(start, State):
        raise ConfigError(f"start must be a State (e.g. State(u=u) or a previous solve's), got {type(start).__name__}")
    u = np.asarray(start.u, dtype=np.float64)
    if u.shape != (n_dofs,):
        raise ConfigError(
            f"start.u must have one value per dof ({n_dofs}), got {u.shape}: the state belongs to another model"
        )
    return replace(start, u=u)


def _start_laws(system: System, start: State | None, layout: Layout) -> tuple:
    """The contact laws' states to start from: fresh, or the warm start's, with the per-node
    penalty factors of the start displacement's coverage."""
    if not system.has_contact:
        return ()
    if start is None:
        return system.start_states()
    if not isinstance(start, State):
        raise ConfigError(f"start must be a State (e.g. State(u=u) or a previous solve's), got {type(start).__name__}")
    u = np.asarray(start.u, dtype=np.float64)
    if u.shape != (system.disc.n_dofs,):
        raise ConfigError(f"start.u must have one value per dof ({system.disc.n_dofs}), got {u.shape}")
    laws = system.start_states(start.multipliers, start.eps) if start.laws else system.start_states()
    contact = system.contact
    assert contact is not None  # has_contact
    results = contact.evaluate(u, laws, tangent=False).results
    return contact.with_coverage(laws, results)


def _load_step_or_continue(
    system: System, layout: Layout, u, t, dt, laws, f_norm, newton, linear, counter, guess
) -> StepResult:
    """:func:`_load_step`; where a frictional step fails, the same step again through a continuation
    in the cone's rounded edge: solved with the edges of :data:`EDGE_LADDER` wider than the
    interfaces' own, widest first, each from the last one's solution, then with their own. The
    history (the slip's origin, the last step's tractions) is the step's throughout, so what it
    returns is the step with the interfaces' own law. Otherwise (or when the continuation fails
    too) the first failure stands, and the step is cut back."""
    try:
        return _load_step(system, layout, u, t, dt, laws, f_norm, newton, linear, counter, guess)
    except StepFailure as fail:
        contact = system.contact
        # a law that smooths stick and slip cannot help a singular tangent or a failed contact check
        if not system.has_friction or fail.structural or not fail.retry or fail.cause == "check":
            raise
        assert contact is not None  # has_friction
        own = min(b.friction.edge for b in contact.blocks if b.friction is not None)
        stages = [w for w in EDGE_LADDER if w > own]
        if not stages:
            raise
        log.info("load step to t=%.4g: %s; solving it again with the cone edge widened to %s", t, fail, stages)
        logs, v = list(fail.logs), u
        try:
            for edge in [*stages, own]:  # the last stage is the system itself
                stage = system.with_cone_edge(edge) if edge > own else system
                result = _load_step(stage, layout, u, t, dt, laws, f_norm, newton, linear, counter, None, u_init=v)
                logs.extend(result.logs)
                v = result.u
        except StepFailure as again:
            log.info("load step to t=%.4g: the continuation failed too, at edge %g: %s", t, edge, again)
            fail.logs = (*logs, *again.logs)
            raise fail from again
        log.info("load step to t=%.4g converged through the cone-edge continuation", t)
        return replace(result, logs=tuple(logs))


def _load_step(
    system: System, layout: Layout, u, t, dt, laws, f_norm, newton, linear, counter, guess, u_init=None
) -> StepResult:
    """One load step: Newton at fixed law states, the laws' decision, again until done; then the check.

    ``u_init`` (default ``u``): where Newton starts, when not from the last step's ``u`` (which
    stays the origin of the step's slip)."""
    disc, contact = system.disc, system.contact
    if not system.has_contact:
        u, lg, ev = newton_step(
            lambda v, tangent: system.evaluate(v, t, layout, (), tangent, full=False),
            u,
            disc.free,
            disc.constrained,
            disc.prescribed(t),
            t,
            dt,
            t * f_norm,
            newton,
            linear,
            geometry=system.geometry,
            guess=guess,
        )
        return StepResult(t=t, u=u, logs=(lg,), evaluation=ev, state=())
    assert contact is not None  # has_contact
    laws = contact.begin_step(laws, u)
    u = u if u_init is None else u_init
    # contact-aware predictor while no node carries pressure yet: the step's first tangent treats
    # as closed every contact node that the prescribed increment could close, so the predictor
    # pushes the touched body instead of driving the pusher through it (fine die-slab, first step:
    # residual after the predictor 0.079 instead of 4.5, 8 iterations instead of a failure). Once
    # contact is established the plain predictor is better.
    reach = 0.0 if counter["in_contact"] else float(np.abs(disc.prescribed(t) - u[disc.constrained]).max(initial=0.0))
    logs: list[NewtonLog] = []
    solved = None  # (u, law states) of the step's last converged Newton solve
    for update in itertools.count():
        touch = [reach if update == 0 else 0.0]
        ev = None  # the previous solve's tangent is not held through this one's (65 MB, fine die-slab)

        # the closures run inside this iteration's newton_step only: the loop variables are current
        def evaluate(v, tangent, laws=laws):  # noqa: B023
            value, touch[0] = touch[0], 0.0  # noqa: B023
            return system.evaluate(v, t, layout, laws, tangent, value, full=False)

        def good_enough(ev, r_norm, r_ref, laws=laws):
            factor = contact.early_stop(ev.contact, laws)
            return factor is not None and r_norm <= factor * r_ref

        try:
            u_new, lg, ev = newton_step(
                evaluate,
                u,
                disc.free,
                disc.constrained,
                disc.prescribed(t),
                t,
                dt,
                t * f_norm,
                # a solve after a multiplier update starts at an equilibrium, where energies differ by
                # round-off: no full step that raises it (the Hertz test's updates stalled with one)
                newton if update == 0 else replace(newton, watchdog=0),
                linear,
                good_enough=good_enough,
                admissible=system.admissible,
                geometry=system.geometry,
                guess=guess if update == 0 else None,
            )
        except StepFailure as fail:
            fail.log = _with_extra(fail.log, alm_update=update)
            fail.logs = (*logs, fail.log)
            retreated = contact.retreat(laws)
            if retreated is None and solved is not None and not fail.structural:
                # a solve after a multiplier update starts at an equilibrium of this load: the laws judge the
                # last converged solve (accepted near their targets). Past the second update a shorter load
                # step would reach the same multipliers and fail the same way: an error, no cutback
                logs.append(fail.log)
                u, laws, ev = _settle(system, layout, t, solved, fail, logs, retry=update < 2)
                break
            if retreated is None:
                if contact.has_friction and fail.advice == DEFAULT_ADVICE:
                    fail.advice = FRICTION_ADVICE
                raise
            logs.append(fail.log)
            laws = retreated
            continue
        u = u_new
        solved = (u, laws)
        counter["in_contact"] = any(res.n_active > 0 for res in ev.contact)
        decision = contact.advance(ev.contact, laws, final=t >= 1.0)
        logs.append(_logged(lg, update, laws, ev, decision))
        if decision.status == "failed":
            raise StepFailure(decision.message, logs[-1], retry=False, logs=logs)
        if any(s.updates > p.updates for s, p in zip(decision.states, laws)):
            counter["updates"] += 1
        laws = decision.states
        if decision.status == "done":
            laws = contact.end_step(laws, ev.contact, u)
            break
    started = time.perf_counter()
    checks = contact.verify(u, ev.contact)
    last = logs[-1]
    logs[-1] = replace(
        last, seconds={**last.seconds, "check": last.seconds.get("check", 0.0) + time.perf_counter() - started}
    )
    failed = [c for c in checks if not c.ok]
    if failed:
        advice = "; ".join(dict.fromkeys(c.advice for c in failed))
        raise StepFailure(" ".join(c.message for c in failed), logs[-1], advice=advice, logs=logs, cause="check")
    for c in checks:
        if c.rejected_near_active:
            log.warning(
                "contact interface %s: %d facet pair(s) next to nodes with pressure were dropped as not "
                "facing or folded; the state check found no unheld penetration",
                c.label,
                c.rejected_near_active,
            )
    return StepResult(t=t, u=u, logs=tuple(logs), evaluation=ev, state=laws, extra={"checks": checks})


def _settle(system: System, layout: Layout, t: float, solved: tuple, fail: StepFailure, logs: list, retry: bool):
    """``(u, laws, evaluation)`` of the last converged solve ``solved = (u, laws)`` of a load step whose
    next solve failed, if the laws accept it; else ``fail`` again (``retry``: a cutback may help) or a
    StepFailure without cutback."""
    contact = system.contact
    assert contact is not None  # only contact steps update multipliers
    u, laws = solved
    ev = system.evaluate(u, t, layout, laws, True, 0.0, full=False)
    results = tuple(ev.contact or ())
    verdict = contact.settle(results, laws)
    if verdict.status == "failed" and retry:
        raise fail
    if verdict.status == "failed":
        raise StepFailure(f"{verdict.message} ({fail})", logs[-1], retry=False, logs=logs) from fail
    return u, contact.end_step(verdict.states, results, u), ev


def _logged(lg, update, laws, ev, decision):
    """The Newton log with the contact measures of this solve, also written to the log."""
    measures = [o.measures for o in decision.outcomes]
    extra = dict(
        alm_update=update,
        pressure_change=max(m.pressure_change for m in measures),
        penetration=max(m.penetration for m in measures),
        eps=[s.eps for s in laws],
        active=[res.n_active for res in ev.contact],
        contact_area=[res.contact_area for res in ev.contact],
        interfaces=[{"pressure_change": m.pressure_change, "penetration": m.penetration} for m in measures],
    )
    log.info(
        "  contact: %s active nodes, area %s, pressure change %s, penetration %s h, eps %s",
        extra["active"],
        [f"{a:.4g}" for a in extra["contact_area"]],
        [f"{m.pressure_change:.2e}" for m in measures],
        [f"{m.penetration:.2e}" for m in measures],
        [f"{e:.3g}" for e in extra["eps"]],
    )
    return _with_extra(lg, **extra)


def _state(res: StepResult, layout: Layout, logs, updates) -> State:
    ev = res.evaluation
    contact = tuple(ev.contact) if ev is not None and ev.contact is not None else ()
    checks = tuple((res.extra or {}).get("checks", ()))
    return State(
        u=res.u,
        t=res.t,
        layout=layout,
        logs=tuple(logs),
        reactions=None if ev is None else ev.r,
        laws=tuple(res.state or ()),
        contact=contact,
        checks=checks,
        alm_updates=updates,
        evaluation=ev,
    )


def _with_extra(lg, **extra):
    return replace(lg, extra={**lg.extra, **extra})


def __getattr__(name: str):
    # the system was called Problem until 0.1: keep the old import path working for a release
    if name == "Problem":
        warnings.warn(
            "contopt.solve.static.Problem is now contopt.solve.system.System", DeprecationWarning, stacklevel=2
        )
        return System
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
