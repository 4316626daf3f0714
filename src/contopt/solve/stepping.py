"""Load stepping: the load factor from 0 to 1 in steps, each a Newton solve (or a step function's
several), cut back after a failure and grown after an easy step.

:func:`solve_load_steps` advances the load factor with automatic cutback (halve the step after a
failure, starting again from the last converged state) and regrowth (x1.5 after an easy step). A
step that fails at the minimum step size raises :class:`~contopt.errors.ConvergenceError` carrying
every step's :class:`~contopt.solve.newton.NewtonLog` and the last converged state.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from contopt.assembly.system import Evaluation
from contopt.contact.verify import LOST
from contopt.errors import ConvergenceError
from contopt.solve.freeflight import Leap
from contopt.solve.newton import NewtonLog, NewtonOptions, StepFailure

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class StepResult:
    """A converged load step: load factor, displacement, its logs, last evaluation and solver state.

    ``state`` is whatever the step function carries from step to step
    (:class:`contopt.solve.static.Carry`: the contact laws' states and what else the next step
    needs). ``logs`` holds one NewtonLog per Newton solve of the step (several with
    augmentations); ``extra`` what else the step function reports (e.g. the contact checks).
    """

    t: float
    u: np.ndarray
    logs: tuple
    evaluation: Evaluation | None
    state: Any = None
    extra: dict | None = None

    @property
    def log(self) -> NewtonLog:
        return self.logs[-1]

    def without_tangent(self) -> StepResult:
        """This result with its evaluation's matrices dropped (its residual and contact kept).

        The next load step starts from here and needs only ``u`` and ``state``; a converged
        step's tangent held through the next one's solve was 65 MB of the fine die-slab's peak.
        The last step keeps its tangent (the adjoint factors it).
        """
        ev = self.evaluation
        if not isinstance(ev, Evaluation) or ev.K_free is None:
            return self
        return replace(self, evaluation=replace(ev, K_terms=None, K_free=None, K_fc=None, modified=None))


StepFunction = Callable[[np.ndarray, float, float, object], StepResult]


def solve_load_steps(
    step: StepFunction,
    n_dofs: int,
    constrained: np.ndarray,
    prescribed: Callable[[float], np.ndarray],
    options: NewtonOptions,
    u0: np.ndarray | None = None,
    state0=None,
    on_step: Callable[[StepResult], None] | None = None,
    t_start: float = 0.0,
    stops: tuple = (),
    leap: Leap | None = None,
):
    """Advance the load factor from ``t_start`` to 1; returns ``(logs, last StepResult)``.

    ``step(u, t, dt, state)`` solves one load step from the converged ``u``
    (and solver ``state``) or raises StepFailure, which cuts the step back. ``stops``: load factors
    in (0, 1) that a load step must end on (a load-path response reads the states there); a step
    that would pass one is shortened to it, without changing the increment the next steps grow from.
    ``leap``: the first step goes to ``leap.t`` in one (the free flight, :mod:`contopt.solve.freeflight`),
    and the steps go on from there as from the stepped path's state; where it fails or does not land on
    the state it expects, the load steps start from the start after all.
    """
    u = np.zeros(n_dofs) if u0 is None else np.array(u0, dtype=np.float64)
    if u0 is None:
        u[constrained] = prescribed(t_start)
    t = t_start
    dt = (1.0 - t_start) / options.n_steps
    max_dt = options.max_step or dt
    logs: list[NewtonLog] = []
    stuck: tuple = ()  # (dt, failure) since the last converged step, while a smaller step changed nothing
    stalled: tuple = ()  # (dt, failure) of the solve's last step that stalled close to its tolerance
    rejected: tuple = ()  # (t_new, dt, failure) of the last step the contact check rejected, until t passes t_new
    last = StepResult(t=t, u=u, logs=(), evaluation=None, state=state0)
    leapt = None if leap is None else _leap(step, last, leap, logs)
    if leapt is not None:
        assert leap is not None  # leapt
        t, last, dt = leap.t, leapt, leap.dt
        if on_step is not None:
            on_step(last)
    while t < 1.0 - 1e-12:
        dt = min(dt, 1.0 - t)
        stop = min((s for s in stops if s > t + 1e-12), default=1.0)
        h = min(dt, stop - t)
        t_new = stop if stop - (t + h) < 1e-12 else t + h
        last = last.without_tangent()
        try:
            result = step(last.u, t_new, h, last.state)
        except StepFailure as fail:
            logs.extend(fail.logs)
            for lg in fail.logs:
                log.debug("%s", lg.summary())
            stuck = (*stuck, (h, fail)) if not stuck or unchanged(stuck[-1][1], fail) else ((h, fail),)
            if fail.stalled is not None:
                # a step no longer than the cutback of an earlier near-tolerance stall, the size that got past
                # it, stalls too: the step's size is not what stalls (the flat punch 1e5 stiffer, nu 0.49)
                if stalled and len(stuck) < 2 and h <= stalled[0] * options.cutback * (1.0 + 1e-9):
                    stuck = (stalled, (h, fail))
                stalled = (h, fail)
            if fail.cause == "check":
                stuck = confirmed(rejected, t_new, h, fail) or stuck
                rejected = (t_new, h, fail)
            dt = cut_back(fail, t, t_new, h, options, logs, last, stuck)
            continue
        stuck = ()
        logs.extend(result.logs)
        for lg in result.logs:
            log.info("%s", lg.summary())
        t, last = t_new, result
        if rejected and t > rejected[0] + 1e-12:
            rejected = ()
        del result  # ``last`` alone holds it: stripped of its tangent before the next step
        if on_step is not None:
            on_step(last)
        if sum(lg.iterations for lg in last.logs) <= options.easy_iterations:
            dt = min(dt * options.grow, max_dt)
    return logs, last


def _leap(step: StepFunction, start: StepResult, leap: Leap, logs: list) -> StepResult | None:
    """The one load step of ``leap`` from ``start``, or None where it fails or does not land on the state it
    expects; its logs go into ``logs`` (a leap not taken: as failed attempts)."""
    try:
        result = step(start.u, leap.t, leap.t, start.state)
    except StepFailure as fail:
        logs.extend(fail.logs)
        log.info("the load step over the free flight to t=%.4g failed (%s): load steps from the start", leap.t, fail)
        return None
    if not leap.lands(result.u):
        why = "elsewhere than the bodies translated by the prescribed motion"
        logs.extend(replace(lg, converged=False, message=why) for lg in result.logs)
        log.info("the load step over the free flight to t=%.4g ended %s: load steps from the start", leap.t, why)
        return None
    logs.extend(result.logs)
    for lg in result.logs:
        log.info("%s (free flight: %d load steps in one)", lg.summary(), leap.skipped)
    return result


def cut_back(
    fail: StepFailure,
    t: float,
    t_new: float,
    dt: float,
    options: NewtonOptions,
    logs: list,
    last: StepResult,
    stuck: tuple = (),
) -> float:
    """The load increment to try after the step from ``t`` to ``t_new`` (of ``dt``) failed: ``dt`` cut back.
    Raises ConvergenceError (with ``logs`` and the ``last`` converged step) where a smaller step would not
    help: a singular tangent, a failure that says so (``retry=False``), two load steps in a row that
    failed alike (``stuck``: ``(dt, StepFailure)`` since the last converged step, see
    :func:`unchanged`), or ``dt`` below ``min_step``."""
    log.info("load step to t=%.4g failed: %s", t_new, fail)
    if len(stuck) >= 2:
        raise ConvergenceError(stuck_message(t, stuck[-2:], options), logs, last) from fail
    if fail.structural and "singular" in str(fail).lower():
        detail = str(fail).rstrip(". ")
        # the linear solver's message may already name the likely causes: they are said once
        cause = (
            ""
            if "without support" in detail
            else (". A body or direction without support (a missing Dirichlet condition or contact) is the usual cause")
        )
        raise ConvergenceError(
            f"the tangent stiffness is singular at t={t_new:.4g}: {detail}{cause}.", logs, last
        ) from fail
    if not fail.retry:
        raise ConvergenceError(f"load step to t={t_new:.4g}: {fail}", logs, last) from fail
    dt *= options.cutback
    if dt < options.min_step:
        raise ConvergenceError(
            f"the load step from t={t:.4g} failed even at the minimum load step {options.min_step:g}: {fail}. "
            f"{fail.advice[:1].upper() + fail.advice[1:]}.",
            logs,
            last,
        ) from fail
    log.info("cutting the load step back to dt=%.4g", dt)
    return dt


def unchanged(before: StepFailure, after: StepFailure) -> bool:
    """Whether the failure of a step cut back (``after``) is the one of the longer step (``before``):
    both stalled close to the tolerance (what remains of the residual is not smooth at that level),
    or both left a node unheld at least half as deep (no step-sized penetration: the discretization
    holds it so). A smaller step does not help either."""
    if before.stalled is not None and after.stalled is not None:
        return True
    if before.cause != "check" or after.cause != "check" or before.depth is None or after.depth is None:
        return False
    return after.depth > 0.5 * before.depth


def confirmed(rejected: tuple, t_new: float, dt: float, fail: StepFailure) -> tuple:
    """``((dt, failure), (dt, failure))`` of two load steps that the contact check rejected alike
    (:func:`unchanged`: at least half as deep) where the later, shorter step started past the
    earlier's start (``rejected``: ``(t_new, dt, failure)`` of the earlier, kept while no step
    converged past its end); ``()`` otherwise.

    The steps between them converged: a shorter step from closer sinks the node as deep, so the
    check rejects the states from there on, not the step that reached them (a step too large leaves
    a penetration that shrinks with it). The seam with the blocks' tops nonmortar (penalty, issue 35):
    a block's corner sinks 0.08 h into the roller at t = 0.667 from t = 0.5 and again from t = 0.583;
    the cutbacks went on past 0.583, 0.625 and 0.656 to two failures in a row (73 Newton iterations
    instead of 40)."""
    if not rejected:
        return ()
    t_a, dt_a, a = rejected
    if dt >= dt_a or not unchanged(a, fail):
        return ()
    return ((dt_a, a), (dt, fail))


def stuck_message(t: float, stuck: tuple, options: NewtonOptions) -> str:
    """The error of two load steps from ``t`` that failed alike (``stuck``: ``(dt, StepFailure)`` of
    each, see :func:`unchanged`)."""
    (dt_a, a), (dt_b, b) = stuck
    t_a = a.log.t - dt_a  # an earlier stall (see solve_load_steps) started elsewhere
    start = f"t={t:.4g}" if abs(t_a - t) < 1e-9 else f"t={t_a:.4g} and t={t:.4g}"
    steps = f"in load steps of {dt_a:.3g} and {dt_b:.3g} from {start} alike"
    if b.cause == "check":
        # not a step too large: the check's reading of lost pairs is dropped
        seen = str(b).replace(f": {LOST}", "")
        return (
            f"{seen}, {steps} ({a.depth:.2g} h and {b.depth:.2g} h deep): a smaller load step does not help, "
            "the nonmortar surface's weighted gaps let the node sink (at an edge or corner of that surface, or "
            "under a finer or more curved mortar). Make the other surface nonmortar (or give surfaces = [a, b] "
            "to have the sides chosen) or refine the nonmortar surface."
        )
    # the acceptance that takes either state: the next power of ten above the larger
    suggest = min(10.0 ** math.ceil(math.log10(max(a.stalled, b.stalled, options.rtol))), 0.1)
    return (
        f"Newton stalled close to its tolerance {steps} (|r| = {a.stalled:.1e} and {b.stalled:.1e} of the "
        f"reference force, newton.rtol = {options.rtol:g}): a smaller load step does not help, the residual is "
        "not smooth at that level (a sharp contact edge, a stiff nonmortar side, a nearly incompressible body). "
        f"Accept such states with newton.stall_rtol = {suggest:g}, or make the softer, finer body the "
        "nonmortar side."
    )
