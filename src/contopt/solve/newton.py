"""Full Newton with the exact tangent and a backtracking line search.

One load step (:func:`newton_step`) drives ``r_free(u) = 0`` at a fixed load
factor. Prescribed displacements are imposed by elimination: the increment
of the constrained dofs ``du_c = g(t) - u_c`` enters the first iteration as
``K_ff du_f = -(r_f + K_fc du_c)`` (a consistent predictor), so a large
prescribed motion never drags only the boundary layer of cells along.

:mod:`contopt.solve.stepping` advances the load factor from 0 to 1 in such steps.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from contopt.assembly.system import ModifiedTangent, Timings
from contopt.errors import ConfigError, LinearSolverError
from contopt.solve.forcing import forcing_term, model_agreement
from contopt.solve.linear import Geometry, LinearSolverOptions, factorize
from contopt.solve.linesearch import Merit, Watch, line_search, lowers_energy

log = logging.getLogger(__name__)

#: a residual below ROUNDOFF * |diag(K) x| (x: the free dofs' nodal positions) is round-off of the
#: internal forces, not an imbalance: a force is computed from positions and gaps to relative
#: accuracy eps, so a dof of stiffness K_ii carries an error of about eps K_ii |x_i|
ROUNDOFF = 100 * np.finfo(float).eps
#: a full Newton step below SQRT_EPS * |u| that no longer lowers the residual: u is known to half the
#: digits of float64 and what remains of the residual is round-off of an ill-conditioned tangent
#: (a penalty grown 1e3 times on a stiff punch: |r| creeping between 1e-9 and 1e-7 forever)
SQRT_EPS = float(np.sqrt(np.finfo(float).eps))


@dataclass(frozen=True)
class NewtonOptions:
    """Newton and load-stepping settings (validated at construction).

    rtol : converged when ``|r_free| <= rtol * r_ref`` (``r_ref``: the largest of
        the external load, the reactions and the step's first residual)
    atol : absolute residual floor (for problems with no load at all); also converged when
        ``|r_free|`` is at the round-off of the internal forces, ``ROUNDOFF * |diag(K) x|`` with x
        the free dofs' positions (a step that loads nothing: a body moving freely before it touches
        another; a nearly incompressible body), or when two full Newton steps in a row are below
        ``SQRT_EPS * |u|`` without lowering ``|r_free|`` below ``sqrt(rtol) r_ref`` by half (the
        round-off floor of an ill-conditioned tangent, measured by the solve itself)
    utol : and ``|du| <= utol * |u|`` for the last increment
    max_iter : Newton iterations per step before the step counts as failed
    line_search : ``"backtracking"`` or ``"none"``
    n_steps : initial number of equal load steps
    min_step : smallest load-factor increment before giving up
    max_step : largest increment after regrowth (default: the initial one)
    grow, cutback : step growth factor after an easy step / reduction after a failure
    easy_iterations : a step converged within this many iterations lets the step grow
    watchdog : iterations a full Newton step that raised the energy gets to bring it below the
        point it left (a nonmonotone "watchdog" line search); 0 takes no such step. Where a contact
        zone closes, the tangent of an iterate with the nodes still open misses their stiffness, so
        the full step overshoots into the other body and the backtracking line search keeps only
        1/8..1/32 of it, iteration after iteration; from the overshot point the tangent has the
        right contact nodes and the next step lands near equilibrium. When the iterations allowed
        do not get below, Newton goes back to that point and backtracks along its step after all,
        and the rest of the load step backtracks as with 0.
        Taken only far from convergence and with an energy (not with friction); the contact solver
        turns it off in the solves after a multiplier update, which start at an equilibrium.
    stall_rtol : None (default): a solve that stagnates (less than a halving of ``|r|`` over six
        iterations) or reaches ``max_iter`` fails and the load step is cut back. A number (>=
        rtol, < 1): such a solve is accepted, with a warning and "accepted at stagnation" in its
        log, when ``|r_free| <= stall_rtol * r_ref``. For frictional contact, whose nonsmooth
        stick/slip law can leave Newton creeping at residuals near its tolerance (docs/friction.md);
        the state then balances to ``stall_rtol`` instead of ``rtol``, and gradients are as
        accurate as that.
    """

    rtol: float = 1e-9
    atol: float = 1e-14
    utol: float = 1e-6
    max_iter: int = 25
    line_search: str = "backtracking"
    max_line_search: int = 8
    n_steps: int = 1
    min_step: float = 1e-4
    max_step: float | None = None
    grow: float = 1.5
    cutback: float = 0.5
    easy_iterations: int = 6
    divergence_factor: float = 1e8
    watchdog: int = 2
    stall_rtol: float | None = None

    def __post_init__(self):
        if self.line_search not in ("backtracking", "none"):
            raise ConfigError(f"newton.line_search must be 'backtracking' or 'none', got {self.line_search!r}")
        for key in ("rtol", "utol", "min_step", "grow", "divergence_factor"):
            if not (getattr(self, key) > 0):
                raise ConfigError(f"newton.{key} must be > 0, got {getattr(self, key)!r}")
        if not (self.atol >= 0):
            raise ConfigError(f"newton.atol must be >= 0, got {self.atol!r}")
        if not (0 < self.cutback < 1):
            raise ConfigError(f"newton.cutback must lie in (0, 1), got {self.cutback!r}")
        for key in ("max_iter", "n_steps", "easy_iterations", "max_line_search", "watchdog"):
            v, lowest = getattr(self, key), 0 if key in ("max_line_search", "watchdog") else 1
            if isinstance(v, bool) or not isinstance(v, int) or v < lowest:
                what = "a non-negative" if lowest == 0 else "a positive"
                raise ConfigError(f"newton.{key} must be {what} integer, got {v!r}")
        if self.stall_rtol is not None and (
            isinstance(self.stall_rtol, bool)
            or not isinstance(self.stall_rtol, (int, float))
            or not (self.rtol <= self.stall_rtol < 1)
        ):
            raise ConfigError(
                f"newton.stall_rtol must be None or a number in [rtol, 1) = [{self.rtol:g}, 1), got {self.stall_rtol!r}"
            )
        if self.max_step is not None and not (0 < self.max_step <= 1):
            raise ConfigError(f"newton.max_step must lie in (0, 1], got {self.max_step!r}")


@dataclass(frozen=True)
class NewtonLog:
    """Record of one load step (converged or not).

    ``residuals[k]`` is ``|r_free|`` after iteration k (index 0: before the
    first update); ``seconds`` totals per phase over the step.
    """

    t: float
    dt: float
    converged: bool
    iterations: int
    residuals: tuple
    increments: tuple
    alphas: tuple
    r_ref: float
    seconds: dict
    message: str = ""
    extra: dict = field(default_factory=dict)
    tangents: str = ""  # per iteration: "e" exact, "m" modified tangent
    krylov: tuple = ()  # per iteration, the iterative linear solver's iterations (empty for a direct one)

    @property
    def convergence_rates(self) -> list[float]:
        """Observed orders ``log(r_{k+1}/r_ref) / log(r_k/r_ref)`` (2 for quadratic)."""
        if self.r_ref <= 0:
            return []
        # residuals[0] precedes the first update; under a prescribed jump it is ~0 and says nothing
        start = 1 if self.residuals and self.residuals[0] < 1e-8 * self.r_ref else 0
        rel = [r / self.r_ref for r in self.residuals[start:]]
        return [math.log(b) / math.log(a) for a, b in zip(rel[:-1], rel[1:]) if 0 < a < 1 and 0 < b]

    def summary(self) -> str:
        res = " ".join(f"{r:.2e}" for r in self.residuals)
        status = "converged" if self.converged else "FAILED"
        kinds = f" (tangents {self.tangents})" if "m" in self.tangents else ""
        krylov = f" ({sum(self.krylov)} Krylov it)" if self.krylov else ""
        return f"t={self.t:.4g} dt={self.dt:.3g} {status} in {self.iterations} it{kinds}{krylov}; |r|: {res}"


#: what to try when a load step fails even at the minimum step
DEFAULT_ADVICE = (
    "try more load steps (newton.n_steps), a smaller min_step, or check the model for inverted "
    "elements or unsupported bodies"
)


class StepFailure(Exception):
    """A load step did not converge (internal: triggers a cutback).

    ``retry=False``: a smaller load step would not help (e.g. the contact multipliers stall at
    the final load): the solve stops at once. ``advice``: what to try, for the final error.
    ``logs``: every Newton solve of the failed step (default: the failed one, ``log``).
    ``cause``: what failed, where not Newton itself (``"check"``: the contact state check).
    """

    def __init__(
        self,
        message: str,
        log_: NewtonLog,
        structural: bool = False,
        retry: bool = True,
        advice: str = DEFAULT_ADVICE,
        logs: Sequence[NewtonLog] = (),
        cause: str = "",
    ):
        super().__init__(message)
        self.log = log_
        self.logs = tuple(logs) or (log_,)
        self.structural = structural
        self.retry = retry
        self.advice = advice
        self.cause = cause


class Evaluated(Protocol):
    """What ``evaluate(u, tangent)`` returns to :func:`newton_step`: an
    :class:`~contopt.assembly.system.Evaluation` or any object with these attributes."""

    @property
    def r(self) -> np.ndarray: ...  # (n,) residual

    @property
    def K_free(self) -> Any | None: ...  # the tangent's free x free block

    @property
    def K_fc(self) -> Any | None: ...  # its free x constrained block (the prescribed increment's)

    @property
    def modified(self) -> ModifiedTangent | None: ...  # a tangent to factor instead of K_free, where offered

    @property
    def energy(self) -> float | None: ...

    @property
    def timings(self) -> Timings: ...

    @property
    def reduce(self) -> Callable[[np.ndarray], np.ndarray]: ...  # sums a vector over the ranks


Evaluate = Callable[[np.ndarray, bool], Evaluated]


def newton_step(
    evaluate: Evaluate,
    u0: np.ndarray,
    free: np.ndarray,
    constrained: np.ndarray,
    u_c_target: np.ndarray,
    t: float,
    dt: float,
    f_scale: float,
    options: NewtonOptions,
    linear: LinearSolverOptions,
    good_enough: Callable | None = None,
    admissible: Callable[[np.ndarray], str] | None = None,
    geometry: Callable[[np.ndarray], Geometry] | None = None,
    guess: np.ndarray | None = None,
):
    """Solve one load step. Returns ``(u, log, last_evaluation)``; raises StepFailure.

    ``evaluate(u, tangent)`` returns an object with ``r`` (n,), ``K_free`` (free x free CSR),
    ``K_fc`` (free x constrained) and ``timings``; ``f_scale`` is the norm of the external load
    at this load factor.

    ``good_enough(ev, r_norm, r_ref) -> bool`` (optional) ends the solve early
    after an iteration, before the tolerances are met: the augmented-Lagrangian
    loop uses it to stop polishing an equilibrium that the next multiplier
    update will move anyway. The log then says ``message="good enough"``.

    ``admissible(u) -> str`` (optional) says why a line-search trial point cannot be a state
    ("" when it can): such a trial is shortened like one with a non-finite residual. Contact
    uses it so that no iterate drives a surface through the other (energy falls that way).

    ``geometry(u)`` (optional) says where the free dofs' nodes are at ``u``: an iterative linear
    solver builds its preconditioner's rigid-body modes from it. An iterative solve stops at
    :func:`forcing_term` (inexact Newton); ``guess`` (free dofs,) is where the first iteration's
    iterative solve starts (a predicted increment; a direct solver does not need one).
    """
    seconds = {"kernels": 0.0, "scatter": 0.0, "factorize": 0.0, "solve": 0.0, "contact": 0.0}
    residuals: list[float] = []
    increments: list[float] = []
    alphas: list[float] = []
    kinds: list[str] = []
    krylov: list[int] = []
    eta = linear.krylov_eta_max
    agreement = None  # of the last step with its linear model (iterative solves)
    u = u0.copy()

    def account(ev):
        for k, v in ev.timings.as_dict().items():
            seconds[k] += v

    def make_log(converged, it, message="", r_ref=1.0):
        return NewtonLog(
            t=t,
            dt=dt,
            converged=converged,
            iterations=it,
            residuals=tuple(residuals),
            increments=tuple(increments),
            alphas=tuple(alphas),
            r_ref=r_ref,
            seconds=dict(seconds),
            message=message,
            tangents="".join(kinds),
            krylov=tuple(krylov),
        )

    if admissible is not None:
        check = admissible

        def admissible(v):  # timed with the contact work it belongs to
            t0 = time.perf_counter()
            why = check(v)
            seconds["contact"] += time.perf_counter() - t0
            return why

    du_c = u_c_target - u[constrained]
    ev = evaluate(u, True)
    account(ev)
    r_ref = max(f_scale, float(np.linalg.norm(ev.r[constrained])), float(np.linalg.norm(ev.r[free])))
    roundoff = _roundoff(ev, u, free, geometry)
    full_steps: list[float] = []  # |du_f| of each iteration before the line search
    residuals.append(float(np.linalg.norm(ev.r[free])))
    watch: Watch | None = None  # the point a nonmonotone full step left
    # once Newton has had to go back, the rest of the load step is monotone: a warm start whose full
    # steps overshoot one after another would otherwise go out and back until it stagnates
    armed = options.watchdog > 0
    for it in range(1, options.max_iter + 1):
        rhs = -ev.r[free]
        if np.any(du_c):
            rhs = rhs - ev.reduce(ev.K_fc @ du_c)  # K_fc: this rank's part in a distributed run
        # an evaluation far from equilibrium may offer a better-behaved tangent than the exact one
        K_free = ev.K_free if ev.modified is None else ev.modified.K_free()
        kinds.append("e" if K_free is ev.K_free else "m")
        point, reduce = Merit(r=ev.r, energy=ev.energy), ev.reduce
        del ev
        lin = None
        try:
            t0 = time.perf_counter()
            factor = factorize(K_free, linear, None if geometry is None else geometry(u))
            t1 = time.perf_counter()
            eta = forcing_term(linear, residuals, eta, max(options.rtol * r_ref, options.atol), agreement)
            du_f = factor.solve(rhs, rtol=eta, x0=guess if it == 1 else None)
            if getattr(factor, "iterative", False):
                krylov.append(int(sum(factor.info["iterations"])))
                lin = reduce(K_free @ du_f) - rhs  # K_free: this rank's part in a distributed run
            factor.free()  # release before the next factorization: bounds peak memory
            del K_free
            seconds["factorize"] += t1 - t0
            seconds["solve"] += time.perf_counter() - t1
        except LinearSolverError as e:
            raise StepFailure(
                f"linear solve failed: {e}", make_log(False, it, str(e), r_ref), structural=(it == 1)
            ) from e
        du = np.zeros_like(u)
        du[free] = du_f
        full_steps.append(float(np.linalg.norm(du_f)))
        du[constrained] = du_c
        near = residuals[-1] <= np.sqrt(options.rtol) * r_ref
        moving = bool(np.any(du_c))  # while prescribed motion remains the merit functions are not comparable
        # a full step that raises the energy is taken one at a time, far from convergence
        watching = (
            watch is None and armed and not near and not moving and point.energy is not None
            and options.line_search != "none" and float(du[free] @ point.r[free]) < 0
        )  # fmt: skip
        u_from = u
        u, ev, alpha, why = line_search(
            evaluate, u, du, point, free, near, moving, options, account, admissible, nonmonotone=watching
        )
        step = alpha * float(np.linalg.norm(du_f))
        if u is not None and watching and not lowers_energy(ev, point, du, free, alpha):
            watch = Watch(u=u_from, point=point, du=du)
            log.debug("Newton iteration %d: full step taken although the energy rose (watchdog)", it)
        elif u is not None and watch is not None:
            if lowers_energy(ev, watch.point, watch.du, free, 1.0):
                # below in energy but not in residual: the excursion came back to where it left (an
                # active set flipping between two states, each full step re-armed: the penalty Hertz
                # cycled 1e-6 -> 1e-4 -> 1e-6 for six iterations); the rest of the load step backtracks
                armed = float(np.linalg.norm(ev.r[free])) < 0.5 * float(np.linalg.norm(watch.point.r[free]))
                watch = None
            elif watch.tries + 1 < options.watchdog:
                watch = replace(watch, tries=watch.tries + 1)
            else:
                # the iterations after the full step did not get below where it started: back there,
                # and backtrack along that step as without the watchdog (its full length is known bad)
                log.debug("Newton iteration %d: back to where the watchdog's full step started", it)
                del ev
                back = 0.5 * watch.du
                u, ev, alpha, why = line_search(
                    evaluate, watch.u, back, watch.point, free, False, False, options, account, admissible
                )
                step = alpha * float(np.linalg.norm(back[free]))
                alpha, lin, watch, armed = 0.5 * alpha, None, None, False
        if u is None:
            raise StepFailure(
                f"line search found no admissible step: {why}"
                if why
                else "line search found no finite residual (elements inverted?)",
                make_log(False, it, "no admissible step" if why else "non-finite residual", r_ref),
            )
        alphas.append(alpha)
        if lin is not None:
            agreement = model_agreement(ev.r[free], point.r[free], lin, float(np.linalg.norm(rhs)), alpha)
        du_c = u_c_target - u[constrained]
        r_norm = float(np.linalg.norm(ev.r[free]))
        residuals.append(r_norm)
        increments.append(step)
        r_ref = max(r_ref, float(np.linalg.norm(ev.r[constrained])))
        if it == 1 and watch is None:  # an overshot full step's residual is no scale of the step
            r_ref = max(r_ref, r_norm)
        u_norm = max(float(np.linalg.norm(u)), 1e-300)
        floor = max(options.atol, roundoff)
        done = r_norm <= max(options.rtol * r_ref, floor) and increments[-1] <= options.utol * u_norm
        # round-off floor: the increment no longer changes u and the residual is already small
        stalled = increments[-1] <= 1e3 * np.finfo(float).eps * u_norm and r_norm <= np.sqrt(options.rtol) * r_ref
        if (done or stalled or r_norm <= floor) and not np.any(du_c):
            return u, make_log(True, it, r_ref=r_ref), ev
        if _at_roundoff(full_steps, residuals, u_norm, np.sqrt(options.rtol) * r_ref) and not np.any(du_c):
            log.info("Newton at the round-off floor: |r| = %.3e, full steps %.2e |u|", r_norm, full_steps[-1] / u_norm)
            return u, make_log(True, it, "round-off floor", r_ref=r_ref), ev
        if good_enough is not None and not np.any(du_c) and good_enough(ev, r_norm, r_ref):
            return u, make_log(True, it, "good enough", r_ref=r_ref), ev
        if it >= 10 and r_norm > 0.5 * residuals[-7] and not np.any(du_c):
            if _accept_stall(options, r_norm, r_ref, "stagnated"):
                return u, make_log(True, it, "accepted at stagnation", r_ref=r_ref), ev
            # less than a halving over the last six iterations: a smaller load step is cheaper
            raise StepFailure(
                f"Newton stagnated (|r| = {r_norm:.3e} after {it} iterations, "
                f"{residuals[-7]:.3e} six iterations before)",
                make_log(False, it, "stagnated", r_ref),
            )
        if r_norm > options.divergence_factor * max(r_ref, 1e-300):
            raise StepFailure(f"Newton diverged (|r| = {r_norm:.3e})", make_log(False, it, "diverged", r_ref))
    if ev is not None and not np.any(du_c) and _accept_stall(options, residuals[-1], r_ref, "reached max_iter"):
        return u, make_log(True, options.max_iter, "accepted at stagnation", r_ref=r_ref), ev
    raise StepFailure(
        f"no convergence in {options.max_iter} iterations (|r| = {residuals[-1]:.3e}, "
        f"target {options.rtol * r_ref:.3e})",
        make_log(False, options.max_iter, "max_iter", r_ref),
    )


def _roundoff(ev: Evaluated, u: np.ndarray, free: np.ndarray, geometry) -> float:
    """``ROUNDOFF * |diag(K_free) x|``: the round-off of the internal forces at the evaluation ``ev``,
    with x the free dofs' positions (from ``geometry(u)``; ``|u|`` without one)."""
    if ev.K_free is None:
        return 0.0
    # summed over the ranks' parts: every rank takes the same decisions
    diagonal = np.abs(ev.reduce(ev.K_free.diagonal()))
    x = np.abs(u[free]) if geometry is None else np.abs(geometry(u).points.reshape(-1)[free])
    return ROUNDOFF * float(np.linalg.norm(diagonal * x))


def _at_roundoff(full_steps: list, residuals: list, u_norm: float, bound: float) -> bool:
    """Two full Newton steps in a row below ``SQRT_EPS * u_norm`` that did not halve the residual, which is
    below ``bound``: the solve's own measure of its round-off floor (``NewtonOptions.atol``)."""
    if len(full_steps) < 2 or len(residuals) < 3:
        return False
    return max(full_steps[-2:]) <= SQRT_EPS * u_norm and residuals[-1] > 0.5 * residuals[-3] and residuals[-1] <= bound


def _accept_stall(options: NewtonOptions, r_norm: float, r_ref: float, how: str) -> bool:
    """Whether a solve that stalled is accepted (``options.stall_rtol``), said in a warning."""
    if options.stall_rtol is None or not r_norm <= options.stall_rtol * r_ref:
        return False
    log.warning(
        "Newton %s at |r| = %.3e = %.2g of the reference (stall_rtol %g): accepted", how, r_norm,
        r_norm / r_ref, options.stall_rtol,
    )  # fmt: skip
    return True
