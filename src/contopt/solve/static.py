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
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from contopt.assembly.model import Model
from contopt.assembly.system import Discretization, Evaluation, Layout
from contopt.contact.laws import AugmentationOptions
from contopt.errors import ConfigError, ConvergenceError
from contopt.solve.activeset import ActiveSetPredictor
from contopt.solve.freeflight import free_flight
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton import GOOD_ENOUGH, NewtonLog, NewtonOptions, StepFailure, newton_step
from contopt.solve.stepping import StepResult, solve_load_steps
from contopt.solve.system import DEEP_PENETRATION, System
from contopt.timing import timed

log = logging.getLogger(__name__)

__all__ = ["AugmentationOptions", "DEEP_PENETRATION", "State", "System", "solve_static"]


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
    path : the converged state of every load step in order, the last one included, each without
        its evaluation and the contact results' matrices (:meth:`light`); recorded when the system
        is path dependent (:attr:`System.path_dependent`) or when asked (``record_path``), else
        empty. The adjoint runs back over it, and a response may be evaluated at any of its steps.

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
    path: tuple = field(repr=False, default=())

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

    def light(self) -> State:
        """This state without its evaluation and the matrices of its contact results (friction
        Jacobians included): what a recorded load path keeps of every step."""
        contact = tuple(
            replace(r, W=None)
            if r.friction is None
            else replace(r, W=None, friction=replace(r.friction, S=None, Z=None, D=None, T=None))
            for r in self.contact
        )
        return replace(self, evaluation=None, contact=contact, path=())


@dataclass(frozen=True, eq=False)
class StepContext:
    """What every load step of one solve shares: the system, the design, the size of the external
    load (``f_norm`` at t = 1) and the solver options."""

    system: System
    layout: Layout
    f_norm: float
    newton: NewtonOptions
    linear: LinearSolverOptions


@dataclass(frozen=True, eq=False)
class Carry:
    """What a converged load step hands the next (:attr:`StepResult.state`).

    laws : the contact laws' states; in_contact : some node carried pressure at the end of the step;
    updates : multiplier updates so far; pace : (n_free,) the step's increment of the free dofs per
    unit load (None before the first step)
    """

    laws: tuple = ()
    in_contact: bool = False
    updates: int = 0
    pace: np.ndarray | None = field(repr=False, default=None)


def solve_static(
    model: Model | Discretization | System,
    rho=None,
    newton: NewtonOptions | None = None,
    linear: LinearSolverOptions | None = None,
    augmentation: AugmentationOptions | None = None,
    start: State | None = None,
    on_step=None,
    mass=None,
    record_path: bool | None = None,
    stops: tuple = (),
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
        growth stays capped relative to the interfaces' own eps. A path-dependent system
        (friction) refuses a start: its states depend on the whole load path.
    on_step : called with a :class:`State` after every converged load step (output, progress)
    record_path : keep every load step's state in :attr:`State.path` (default: when the system is
        path dependent, where the adjoint needs them)
    stops : load factors in (0, 1] that load steps must end on (a load-path response reads the
        states there, :mod:`contopt.responses.path`); the steps are cut to land on them

    Raises :class:`contopt.errors.ConvergenceError` (with logs and the last converged state) when a
    load step cannot converge, when the contact laws cannot converge at a load (no cutback: a
    shorter step would not help them), or when every converged state of a step fails the contact
    check even at the minimum step.
    """
    system = System.of(model).with_augmentation(augmentation)
    disc = system.disc
    layout = disc.layout(rho, mass)
    linear = linear or LinearSolverOptions()
    start = _checked_start(start, system)
    ctx = StepContext(
        system=system,
        layout=layout,
        f_norm=float(np.linalg.norm(disc.f_ext(layout.mass)[disc.free])),
        newton=newton or NewtonOptions(),
        linear=linear if system.symmetric or not linear.symmetric else replace(linear, symmetric=False),
    )
    record = system.path_dependent if record_path is None else bool(record_path)
    path: list[State] = []

    def step_callback(res: StepResult):
        if record or on_step is not None:
            state = _state(res, layout, res.logs)
            if record:
                path.append(state.light())
            if on_step is not None:
                on_step(state)

    try:
        logs, last = solve_load_steps(
            partial(_paced_step, ctx),
            disc.n_dofs,
            disc.constrained,
            disc.prescribed,
            ctx.newton,
            u0=None if start is None else start.u,
            state0=Carry(laws=_start_laws(system, start)),
            on_step=step_callback,
            stops=_checked_stops(stops),
            # the load steps before the bodies can touch in one, in a solve from zero whose every step is not read
            leap=None if start is not None or record or stops else free_flight(system, ctx.newton),
        )
    except ConvergenceError as err:
        # what the caller gets back is a State, like a converged solve's (t < 1 when the load stopped short)
        if isinstance(err.last_state, StepResult):
            err.last_state = _state(err.last_state, layout, tuple(err.logs))
        raise
    state = replace(_state(last, layout, tuple(logs)), path=tuple(path))
    if system.contact is not None:
        for warning in system.contact.coarse_side_warnings(state.checks):
            log.warning("%s", warning)
    return state


def _checked_stops(stops) -> tuple:
    """``stops`` as sorted floats in (0, 1) (1, the end, is left out); ConfigError for anything else."""
    try:
        out = tuple(sorted(float(s) for s in stops))
    except (TypeError, ValueError) as err:
        raise ConfigError(f"stops must be a sequence of load factors in (0, 1], got {stops!r}") from err
    if any(not 0.0 < s <= 1.0 for s in out):
        raise ConfigError(f"stops must be load factors in (0, 1], got {stops!r}")
    return tuple(s for s in out if s < 1.0 - 1e-12)


def _checked_start(start: State | None, system: System) -> State | None:
    """The warm start as given, its displacement float64; ConfigError for anything but a State of this system."""
    if start is None:
        return None
    if not isinstance(start, State):
        raise ConfigError(f"start must be a State (e.g. State(u=u) or a previous solve's), got {type(start).__name__}")
    if system.path_dependent:
        raise ConfigError(
            "a warm start cannot be used with friction: the frictional state depends on the whole load "
            "path, so every solve starts from the undeformed bodies (drop start=...)"
        )
    u = np.asarray(start.u, dtype=np.float64)
    n_dofs = system.disc.n_dofs
    if u.shape != (n_dofs,):
        raise ConfigError(
            f"start.u must have one value per dof ({n_dofs}), got {u.shape}: the state belongs to another model"
        )
    return replace(start, u=u)


def _start_laws(system: System, start: State | None) -> tuple:
    """The contact laws' states to start from: fresh, or the warm start's (checked), with the per-node
    penalty factors of the start displacement's coverage."""
    contact = system.contact
    if not system.has_contact:
        return ()
    assert contact is not None  # has_contact
    if start is None:
        return system.start_states()
    laws = system.start_states(start.multipliers, start.eps) if start.laws else system.start_states()
    results = contact.evaluate(start.u, laws, tangent=False).results
    return contact.with_coverage(laws, results)


def _paced_step(ctx: StepContext, u: np.ndarray, t: float, dt: float, carry: Carry) -> StepResult:
    """:func:`_step_or_continue` from the last step's pace: an iterative solver starts the step's first
    solve there. Where the response is linear (bodies moved before they touch) that is the answer,
    and Newton needs one iteration as with a direct solver instead of three to seven (fine die-slab)."""
    guess = None if carry.pace is None else dt * carry.pace
    result = _step_or_continue(ctx, u, t, dt, carry, guess)
    free = ctx.system.disc.free
    return replace(result, state=replace(result.state, pace=(result.u - u)[free] / dt))


def _step_or_continue(ctx: StepContext, u, t: float, dt: float, carry: Carry, guess) -> StepResult:
    """:func:`_load_step`; where it fails, the same step again through the system's smoothing stages
    (:meth:`System.smoothing_stages`: with friction, wider rounded cone edges), smoothest first, each
    from the last one's solution, then with the system itself. The history (the slip's origin, the
    last step's tractions) is the step's throughout, so what it returns is the step of the system's
    own laws. Otherwise (or when the continuation fails too) the first failure stands, and the step
    is cut back."""
    try:
        return _load_step(ctx, u, t, dt, carry, guess)
    except StepFailure as fail:
        stages = ctx.system.smoothing_stages()
        # a smoother law cannot help a singular tangent or a failed contact check
        if not stages or fail.structural or not fail.retry or fail.cause == "check":
            raise
        log.info("load step to t=%.4g: %s; solving it again through %d smoother stages", t, fail, len(stages))
        logs, v, reached = list(fail.logs), u, 0
        try:
            for reached, stage in enumerate([*stages, ctx.system], start=1):  # noqa: B007 (reported below)
                result = _load_step(replace(ctx, system=stage), u, t, dt, carry, None, u_init=v)
                logs.extend(result.logs)
                v = result.u
        except StepFailure as again:
            log.info(
                "load step to t=%.4g: the continuation failed too, at stage %d of %d: %s",
                t,
                reached,
                len(stages) + 1,
                again,
            )
            fail.logs = (*logs, *again.logs)
            raise fail from again
        log.info("load step to t=%.4g converged through the continuation", t)
        return replace(result, logs=tuple(logs))


def _load_step(ctx: StepContext, u, t: float, dt: float, carry: Carry, guess, u_init=None) -> StepResult:
    """One load step: Newton at fixed law states, the laws' decision, again until done; then the check.

    ``u_init`` (default ``u``): where Newton starts, when not from the last step's ``u`` (which
    stays the origin of the step's slip)."""
    system, disc = ctx.system, ctx.system.disc
    if not system.has_contact:
        u, lg, ev = newton_step(
            lambda v, tangent: system.evaluate(v, t, ctx.layout, (), tangent, full=False),
            u,
            disc.free,
            disc.constrained,
            disc.prescribed(t),
            t,
            dt,
            t * ctx.f_norm,
            ctx.newton,
            ctx.linear,
            geometry=system.geometry,
            guess=guess,
        )
        return StepResult(t=t, u=u, logs=(lg,), evaluation=ev, state=carry)
    solved = _contact_step(ctx, u, t, dt, carry, guess, u_init)
    return _checked(ctx, solved)


@dataclass(frozen=True, eq=False)
class _Solved:
    """A load step's converged contact solves: the last one's displacement, law states and evaluation,
    every solve's log, the multiplier updates made and whether a node carries pressure."""

    t: float
    u: np.ndarray
    laws: tuple
    evaluation: Evaluation
    logs: tuple
    updates: int
    in_contact: bool


def _contact_step(ctx: StepContext, u, t: float, dt: float, carry: Carry, guess, u_init) -> _Solved:
    """Newton at fixed law states, then the laws' decision (done, update, fail), until done."""
    system, disc = ctx.system, ctx.system.disc
    contact = system.contact
    assert contact is not None  # has_contact
    laws = contact.begin_step(carry.laws, u)
    u = u if u_init is None else u_init
    # contact-aware predictor: the step's first tangent treats as closed every contact node that the
    # prescribed increment could close, so the predictor pushes the touched body instead of driving the
    # pusher through it (fine die-slab, first step: residual after the predictor 0.079 instead of 4.5,
    # 8 iterations instead of a failure). Once in contact, with frictionless penalty laws, it also holds
    # the nodes at the edge of the growing zone at their touch instead of pushing them 0.1 h deep, and
    # the solve takes no watchdog full step: the iterate is near equilibrium with the edge nodes about
    # their touch, where a full step flips them and costs 2-3 iterations out and back (the penalty Hertz
    # line, issue 35: 59 -> 33 Newton iterations on the test's mesh). With an augmented Lagrangian the
    # fine die-slab took 23 Newton iterations and 13 updates instead of 19 and 11 with it: not there.
    reach = float(np.abs(disc.prescribed(t) - u[disc.constrained]).max(initial=0.0))
    if carry.in_contact and not _penalty_only(contact):
        reach = 0.0
    watch = not (carry.in_contact and reach > 0)
    logs: list[NewtonLog] = []
    updates, in_contact = carry.updates, carry.in_contact
    solved = None  # (u, law states) of the step's last converged Newton solve
    for update in itertools.count():
        try:
            u_new, lg, ev = _solve_at(ctx, u, t, dt, laws, first=update == 0, reach=reach, guess=guess, watch=watch)
        except StepFailure as fail:
            fail.log = _with_extra(fail.log, alm_update=update)
            fail.logs = (*logs, fail.log)
            retreated = contact.retreat(laws)
            if retreated is None and solved is not None and not fail.structural:
                # a solve after a multiplier update starts at an equilibrium of this load: the laws judge the
                # last converged solve (accepted near their targets). Past the second update a shorter load
                # step would reach the same multipliers and fail the same way: an error, no cutback
                logs.append(fail.log)
                u, laws, ev = _settle(ctx, t, solved, fail, logs, retry=update < 2)
                return _Solved(t, u, laws, ev, tuple(logs), updates, in_contact)
            if retreated is None:
                fail.advice = system.advice(fail.advice)
                raise
            logs.append(fail.log)
            laws = retreated
            continue
        u = u_new
        solved = (u, laws)
        in_contact = any(res.n_active > 0 for res in ev.contact)
        # the residual a solve run to Newton's own criteria ended at is the equilibrium's noise; an early
        # stop's is not (a tighter solve would lower it)
        noise = 0.0 if lg.message == GOOD_ENOUGH else lg.residuals[-1]
        decision = contact.advance(ev.contact, laws, final=t >= 1.0, residual=noise)
        logs.append(_logged(lg, update, laws, ev, decision))
        if decision.status == "failed":
            raise StepFailure(decision.message, logs[-1], retry=False, logs=logs)
        updates += any(s.updates > p.updates for s, p in zip(decision.states, laws))
        laws = decision.states
        if decision.status == "done":
            return _Solved(t, u, contact.end_step(laws, ev.contact, u), ev, tuple(logs), updates, in_contact)
        del ev  # this solve's last tangent is not held through the next solve (the next one makes its own)
    raise AssertionError("unreachable: itertools.count() does not end")


def _penalty_only(contact) -> bool:
    """Whether every interface of ``contact`` has a penalty law (no multipliers) and no friction."""
    return all(not b.law.constrains and b.friction is None for b in contact.blocks)


def _solve_at(ctx: StepContext, u, t: float, dt: float, laws: tuple, first: bool, reach: float, guess, watch: bool):
    """One Newton solve at fixed law states: ``(u, log, evaluation)`` or StepFailure. The step's
    ``first`` solve starts from ``guess`` and its first evaluation's tangent counts as closed the
    nodes within ``reach`` (the contact-aware predictor); later ones start at an equilibrium. ``watch``:
    the first solve may take the watchdog's full steps (``NewtonOptions.watchdog``); later ones never."""
    system, disc = ctx.system, ctx.system.disc
    contact = system.contact
    assert contact is not None  # has_contact

    def evaluate(v, tangent):
        return system.evaluate(v, t, ctx.layout, laws, tangent, full=False)

    def good_enough(ev, r_norm, r_ref):
        factor = contact.early_stop(ev.contact, laws)
        return factor is not None and r_norm <= factor * r_ref

    # a solve after a multiplier update starts at an equilibrium, where energies differ by
    # round-off: no full step that raises it (the Hertz test's updates stalled with one). The starting
    # tangent alone sees the predictor's reach; it is made in the call, so that no name here holds it
    # through the solve (newton_step lets go of it once factored)
    return newton_step(
        evaluate,
        u,
        disc.free,
        disc.constrained,
        disc.prescribed(t),
        t,
        dt,
        t * ctx.f_norm,
        ctx.newton if first and watch else replace(ctx.newton, watchdog=0),
        ctx.linear,
        good_enough=good_enough,
        admissible=system.admissible,
        geometry=system.geometry,
        guess=guess if first else None,
        first=system.evaluate(u, t, ctx.layout, laws, True, reach if first else 0.0, full=False),
        predict=(
            ActiveSetPredictor(system, t, ctx.layout, laws, ctx.newton.active_set)
            if ctx.newton.active_set > 0 and _penalty_only(contact)
            else None
        ),
    )


def _checked(ctx: StepContext, solved: _Solved) -> StepResult:
    """The load step's result once its state passes the contact check; StepFailure (cause "check")
    naming the interface, the node and its penetration otherwise."""
    contact = ctx.system.contact
    assert contact is not None  # a contact step
    assert solved.evaluation.contact is not None  # a contact evaluation
    logs = list(solved.logs)
    seconds = dict(logs[-1].seconds)
    with timed(seconds, "check"):
        checks = contact.verify(solved.u, solved.evaluation.contact)
    logs[-1] = replace(logs[-1], seconds=seconds)
    failed = [c for c in checks if not c.ok]
    if failed:
        advice = "; ".join(dict.fromkeys(c.advice for c in failed))
        depth = max((c.worst.relative for c in failed if c.worst is not None), default=0.0)
        raise StepFailure(
            " ".join(c.message for c in failed), logs[-1], advice=advice, logs=logs, cause="check", depth=depth
        )
    for c in checks:
        if c.rejected_near_active:
            log.warning(
                "contact interface %s: %d facet pair(s) next to nodes with pressure were dropped as not "
                "facing or folded; the state check found no unheld penetration",
                c.label,
                c.rejected_near_active,
            )
    carry = Carry(laws=solved.laws, in_contact=solved.in_contact, updates=solved.updates)
    return StepResult(
        t=solved.t, u=solved.u, logs=tuple(logs), evaluation=solved.evaluation, state=carry, extra={"checks": checks}
    )


def _settle(ctx: StepContext, t: float, solved: tuple, fail: StepFailure, logs: list, retry: bool):
    """``(u, laws, evaluation)`` of the last converged solve ``solved = (u, laws)`` of a load step whose
    next solve failed, if the laws accept it; else ``fail`` again (``retry``: a cutback may help) or a
    StepFailure without cutback."""
    contact = ctx.system.contact
    assert contact is not None  # only contact steps update multipliers
    u, laws = solved
    ev = ctx.system.evaluate(u, t, ctx.layout, laws, True, 0.0, full=False)
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


def _state(res: StepResult, layout: Layout, logs) -> State:
    ev = res.evaluation
    contact = tuple(ev.contact) if ev is not None and ev.contact is not None else ()
    checks = tuple((res.extra or {}).get("checks", ()))
    carry = res.state if isinstance(res.state, Carry) else Carry()
    return State(
        u=res.u,
        t=res.t,
        layout=layout,
        logs=tuple(logs),
        reactions=None if ev is None else ev.r,
        laws=tuple(carry.laws),
        contact=contact,
        checks=checks,
        alm_updates=carry.updates,
        evaluation=ev,
    )


def _with_extra(lg, **extra):
    return replace(lg, extra={**lg.extra, **extra})
