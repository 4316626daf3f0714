"""Newton's line search: backtracking on the energy (Armijo) or the residual norm, and beside it the
nonmonotone "watchdog" full step (``NewtonOptions.watchdog``) with what it remembers
(:func:`watched_line_search`)."""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from contopt.vectors import dot, norm

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Merit:
    """What the line search needs of the point it leaves: its residual (n,) and energy. Newton
    keeps only this of an evaluation once the tangent is factored, so that the tangent's
    matrices are not held through the factorization and the line search's evaluations."""

    r: np.ndarray
    energy: float | None


@dataclass(frozen=True, eq=False)
class Watch:
    """The point ``u`` (n,) that a full step raising the energy left, with its merit and step ``du``
    (n,): Newton comes back here, and backtracks along ``du``, when ``tries`` iterations have not
    brought the energy below it (``NewtonOptions.watchdog``)."""

    u: np.ndarray
    point: Merit
    du: np.ndarray
    tries: int = 0


@dataclass(frozen=True, eq=False)
class Watchdog:
    """The watchdog over a load step: the point that a full step raising the energy left (``watch``;
    None: none pending) and whether it may take such a step (``armed``). Once Newton has had to go
    back, the rest of the load step is monotone: a warm start whose full steps overshoot one after
    another would otherwise go out and back until it stagnates."""

    watch: Watch | None = None
    armed: bool = True

    def watching(self, point: Merit, du: np.ndarray, free: np.ndarray, near: bool, moving: bool, options) -> bool:
        """Whether the full step ``du`` from ``point`` is taken whatever its energy: one at a time, far from
        convergence (not ``near``), with no prescribed motion left (not ``moving``: the merit functions
        are not comparable then), with an energy, and along a descent direction."""
        return (
            self.watch is None and self.armed and not near and not moving and point.energy is not None
            and options.line_search != "none" and dot(du[free], point.r[free]) < 0
        )  # fmt: skip


@dataclass(frozen=True, eq=False)
class Landing:
    """Where :func:`watched_line_search` took Newton: ``u`` (n,) and its evaluation ``ev`` with the
    tangent (both None: no trial point was finite and admissible; ``why``: the last refusal, or "");
    ``alpha``, the fraction of the iteration's step taken (on the way back: of the watched full
    step); ``length``, the length of the step taken (its free part); ``dog``, the watchdog after it;
    ``back``: the step went back to where the watchdog's full step started (not along this
    iteration's step: its linear model says nothing of it)."""

    u: np.ndarray | None
    ev: Any
    alpha: float
    length: float
    dog: Watchdog
    why: str = ""
    back: bool = False


def lowers_energy(ev, point: Merit, du: np.ndarray, free: np.ndarray, alpha: float) -> bool:
    """Armijo's sufficient decrease of the energy from ``point`` to ``ev``, reached by ``alpha du``."""
    if ev.energy is None or point.energy is None:
        return False
    slope = dot(du[free], point.r[free])
    return bool(ev.energy <= point.energy + 1e-4 * alpha * slope)


def line_search(evaluate, u, du, ev0, free, near, jump, options, account, admissible=None, nonmonotone=False):
    """Backtracking on the total potential energy (Armijo), or on |r_free| where there is none.

    A hyperelastic step from a near-incompressible state can raise the
    residual norm while lowering the energy, so the energy is the merit
    function whenever the evaluation provides it. Near convergence (residual
    below sqrt(rtol) of the reference) energy differences drown in round-off
    and the residual norm is the merit function: taking any step there, or
    any step whose energy is "lower" by round-off, let a contact node at the
    edge of the active set flip back and forth forever. After a prescribed
    jump any finite step is taken.
    A trial point that ``admissible`` refuses is shortened like a non-finite one.
    ``nonmonotone``: the full step is taken when it is admissible and finite, whatever its energy
    (the caller watches what follows, ``NewtonOptions.watchdog``).
    Returns (u_new, evaluation_with_tangent, alpha, ""); (None, None, 0, why) if no
    trial point had a finite residual and was admissible (why: the last refusal, or "").
    """
    r0 = norm(ev0.r[free])
    slope = dot(du[free], ev0.r[free])  # dPi/dalpha at 0 along the free part
    use_energy = ev0.energy is not None and slope < 0
    alpha, best, why = 1.0, None, ""
    rising = None  # the last trial refused because the energy rose along du there: (alpha, evaluation)
    n_try = 1 if options.line_search == "none" else options.max_line_search + 1
    for _ in range(n_try):
        trial = u + alpha * du
        refused = admissible(trial) if admissible is not None else ""
        if refused:
            why = refused
            alpha *= 0.5
            continue
        ev = evaluate(trial, alpha == 1.0)
        account(ev)
        rn = norm(ev.r[free])
        if np.isfinite(rn) and (ev.energy is None or np.isfinite(ev.energy)):
            if use_energy and not near:
                ok = lowers_energy(ev, ev0, du, free, alpha)
            else:
                ok = rn <= (1.0 - 1e-4 * alpha) * r0
            # a trial so far off that it offers a modified tangent (contact: a deep penetration) is no
            # point to go on from: the watchdog's full step is not taken there
            if nonmonotone and alpha == 1.0 and ev.modified is None:
                ok = True
            if ok and use_energy and not near and not jump and rising is not None and rising[0] == 2 * alpha:
                alpha, ev = refine(evaluate, u, du, (alpha, ev), rising, ev0, free, account, admissible)
                trial = u + alpha * du
            if ok or jump or options.line_search == "none":
                return trial, ev if ev.K_free is not None else tangent_at(evaluate, trial, account), alpha, ""
            if best is None or rn < best[1]:
                best = (alpha, rn)
            rising = (alpha, ev) if use_energy and slope_at(ev, du, free) > 0 else None
        else:
            rising = None
        alpha *= 0.5
    if best is None:
        return None, None, 0.0, why
    # no sufficient decrease: take the best finite step and let Newton go on
    alpha = best[0]
    trial = u + alpha * du
    return trial, tangent_at(evaluate, trial, account), alpha, ""


#: evaluations that :func:`refine` spends narrowing the bracket of the energy's minimum along a step
REFINE = 4


def slope_at(ev, du: np.ndarray, free: np.ndarray) -> float:
    """The energy's derivative along ``du`` at an evaluation: ``dPi/dalpha = du . r`` (free part)."""
    return dot(du[free], ev.r[free])


def refine(evaluate, u, du, low, high, ev0, free, account, admissible):
    """The step to the energy's minimum along ``du`` between ``low`` (accepted by Armijo, energy still
    falling) and ``high = 2 low`` (energy rising): regula falsi on the slope (Illinois), and the point
    of least energy that keeps Armijo's decrease. ``low``, ``high``: ``(alpha, evaluation)``.

    Where a contact zone closes along the step, the energy falls along it until the surfaces touch and
    rises steeply beyond (the tangent of the open iterate has no contact stiffness, so Newton's step is
    the free body's): the halving alone keeps the largest 2^-k short of the touch, the next iteration
    finds the same open tangent, and Newton creeps toward the other body a factor 2..4 at a time (the
    tutorial's roller pressed 0.25 into the grey beam: 1/4, 1/16, 1/64, 1/256 in a row). The point near
    the minimum lies at the touch, where the next tangent holds the closed nodes. The slope is nearly
    piecewise linear there (a penalty's energy is quadratic in the penetration), which the secant
    through the bracket's slopes finds in a step or two where bisection would need ten.
    """
    lo, hi = (low[0], slope_at(low[1], du, free)), (high[0], slope_at(high[1], du, free))
    if lo[1] >= 0:
        return low
    best, side = low, 0  # side: which end the last secant point replaced (Illinois halves the other's slope)
    for _ in range(REFINE):
        alpha = lo[0] + (hi[0] - lo[0]) * lo[1] / (lo[1] - hi[1])
        trial = u + alpha * du
        ev = None if admissible is not None and admissible(trial) else evaluate(trial, False)
        if ev is not None:
            account(ev)
        if ev is None or ev.energy is None or not np.isfinite(ev.energy) or not np.all(np.isfinite(ev.r[free])):
            hi, side = (alpha, hi[1]), 1
            continue
        if lowers_energy(ev, ev0, du, free, alpha) and ev.energy < best[1].energy:
            best = (alpha, ev)
        s = slope_at(ev, du, free)
        if s < 0:
            lo, hi = (alpha, s), (hi if side != -1 else (hi[0], 0.5 * hi[1]))
            side = -1
        else:
            hi, lo = (alpha, s), (lo if side != 1 else (lo[0], 0.5 * lo[1]))
            side = 1
        if abs(s) <= 1e-3 * abs(slope_at(low[1], du, free)):
            break  # the minimum, to well within what Newton's next step corrects
    return best


def tangent_at(evaluate, u, account):
    ev = evaluate(u, True)
    account(ev)
    return ev


def watched_line_search(
    evaluate, u, du, point: Merit, free, near: bool, moving: bool, options, account, admissible, dog: Watchdog, it: int
) -> Landing:
    """:func:`line_search` along ``du`` from ``u`` (at ``point``) with the watchdog beside it
    (``NewtonOptions.watchdog``): a full step that raises the energy is taken where
    :meth:`Watchdog.watching` says so, and remembered; the iterations after it either bring the energy
    below the point it left or, after ``options.watchdog`` of them, Newton goes back there and
    backtracks along that step (:func:`go_back`). ``it``: Newton's iteration, for the debug log."""
    watching = dog.watching(point, du, free, near, moving, options)
    u_new, ev, alpha, why = line_search(
        evaluate, u, du, point, free, near, moving, options, account, admissible, nonmonotone=watching
    )
    if u_new is None:
        return Landing(u=None, ev=None, alpha=alpha, length=0.0, dog=dog, why=why)
    length = alpha * norm(du[free])
    if watching and not lowers_energy(ev, point, du, free, alpha):
        log.debug("Newton iteration %d: full step taken although the energy rose (watchdog)", it)
        return Landing(u_new, ev, alpha, length, Watchdog(Watch(u=u, point=point, du=du), dog.armed))
    watch = dog.watch
    if watch is None:
        return Landing(u_new, ev, alpha, length, dog)
    if lowers_energy(ev, watch.point, watch.du, free, 1.0):
        # below in energy but not in residual: the excursion came back to where it left (an active set
        # flipping between two states, each full step re-armed: the penalty Hertz cycled 1e-6 -> 1e-4 ->
        # 1e-6 for six iterations); the rest of the load step backtracks
        armed = norm(ev.r[free]) < 0.5 * norm(watch.point.r[free])
        return Landing(u_new, ev, alpha, length, Watchdog(None, armed))
    if watch.tries + 1 < options.watchdog:
        return Landing(u_new, ev, alpha, length, Watchdog(replace(watch, tries=watch.tries + 1), dog.armed))
    log.debug("Newton iteration %d: back to where the watchdog's full step started", it)
    del ev  # its tangent is not held through the way back's evaluations
    return go_back(evaluate, watch, free, options, account, admissible)


def go_back(evaluate, watch: Watch, free, options, account, admissible) -> Landing:
    """The iterations after the watched full step did not get below where it started: back there, and
    backtrack along that step as without the watchdog (its full length is known bad). The rest of the
    load step backtracks (the watchdog disarmed)."""
    back = 0.5 * watch.du
    u, ev, alpha, why = line_search(
        evaluate, watch.u, back, watch.point, free, False, False, options, account, admissible
    )
    length = alpha * norm(back[free])
    return Landing(u, ev, 0.5 * alpha, length, Watchdog(None, armed=False), why=why, back=True)
