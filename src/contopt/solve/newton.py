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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from contopt.assembly.system import ModifiedTangent, Timings
from contopt.errors import LinearSolverError, UnavailableSolverError
from contopt.solve.forcing import forcing_term, model_agreement
from contopt.solve.linear import Geometry, LinearSolverOptions, factorize
from contopt.solve.linesearch import Landing, Merit, Watchdog, watched_line_search
from contopt.solve.newton_options import NewtonOptions
from contopt.timing import timed
from contopt.vectors import norm

log = logging.getLogger(__name__)

#: a residual below ROUNDOFF * |diag(K) x| (x: the free dofs' nodal positions) is round-off of the
#: internal forces, not an imbalance: a force is computed from positions and gaps to relative
#: accuracy eps, so a dof of stiffness K_ii carries an error of about eps K_ii |x_i|
ROUNDOFF = 100 * np.finfo(float).eps
#: a full Newton step below SQRT_EPS * |u| that no longer lowers the residual: u is known to half the
#: digits of float64 and what remains of the residual is round-off of an ill-conditioned tangent
#: (a penalty grown 1e3 times on a stiff punch: |r| creeping between 1e-9 and 1e-7 forever)
SQRT_EPS = float(np.sqrt(np.finfo(float).eps))
#: the message of a solve stopped early because a multiplier update follows (its residual is no noise floor)
GOOD_ENOUGH = "good enough"


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
        # the steps the line search kept, where any was shortened: halvings show a kink or a jump
        alphas = "" if all(a == 1.0 for a in self.alphas) else "; alpha: " + " ".join(f"{a:.3g}" for a in self.alphas)
        return f"t={self.t:.4g} dt={self.dt:.3g} {status} in {self.iterations} it{kinds}{krylov}; |r|: {res}{alphas}"


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
    ``stalled``: ``|r| / r_ref`` of a solve that stagnated or ran out of iterations close to its tolerance (within
    ``sqrt(rtol)`` of the reference), None otherwise: where two load steps in a row stall so, a
    smaller one does not help either (:func:`contopt.solve.stepping.cut_back`). ``depth``: for a
    failed contact check, the deepest unheld node's penetration over the facet size.
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
        stalled: float | None = None,
        depth: float | None = None,
    ):
        super().__init__(message)
        self.log = log_
        self.logs = tuple(logs) or (log_,)
        self.structural = structural
        self.retry = retry
        self.advice = advice
        self.cause = cause
        self.stalled = stalled
        self.depth = depth


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
    first: Evaluated | None = None,
    predict: Callable | None = None,
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
    iterative solve starts (a predicted increment; a direct solver does not need one). ``first``:
    the evaluation at ``u0`` with its tangent when the caller made it (the load step's
    contact-aware predictor evaluates its own; default ``evaluate(u0, True)``). Its tangent is let go of
    once factored, as every iteration's: a caller that keeps no name of it frees it then. ``predict(step,
    before, x, results, system, direction, it)`` (optional; ``results``: the tangent's contact results) may
    re-solve each iteration's direction (:class:`contopt.solve.activeset.ActiveSetPredictor`).
    """
    step = LoadStep(
        evaluate, free, constrained, u_c_target, t, dt, options, linear, admissible, geometry, guess, predict
    )  # fmt: skip
    u = u0.copy()
    ev = evaluate(u, True) if first is None else first
    del first  # ``ev`` alone holds it: let go of once factored
    step.account(ev)
    x = step.start(u, ev, f_scale)
    for it in range(1, options.max_iter + 1):
        K, system = linear_system(step, x, ev)
        results = getattr(ev, "contact", None) if step.predict is not None else None  # what predict reads of it
        del ev  # the tangent's matrices are not held through the factorization and the line search
        y, direction = solve_linear(step, x, K, system, it)
        del K  # nor the factored one through the line search
        if step.predict is not None:
            y, system, direction = step.predict(step, x, y, results, system, direction, it)
        x = y
        x, ev = search(step, x, system, direction, it)
        message = verdict(step, x, ev, it, good_enough)
        if message is not None:
            return x.u, step.log(x, it, True, message), ev
    return x.u, step.log(x, options.max_iter, True, out_of_iterations(step, x)), ev


@dataclass(frozen=True, eq=False)
class Iterate:
    """Where Newton stands after an iteration (the first: at the load step's start), and the step's
    record so far. Each iteration returns the next; the evaluation at ``u`` travels beside it, so that
    Newton can let go of its tangent once factored (:func:`newton_step`).

    u : (n,) displacement; du_c : (n_constrained,) the prescribed increment still to go
    r_ref : the residual's reference (the largest of the load, the reactions and the step's first residual)
    roundoff : the round-off of the internal forces at the step's start (:func:`_roundoff`)
    residuals : ``|r_free|`` at the start and after each iteration; increments : ``|alpha du_f|``;
    full_steps : ``|du_f|`` before the line search; alphas : the line search's factors; tangents :
    "e" exact, "m" modified, per iteration; krylov : an iterative solver's iterations per iteration
    eta, agreement : the last forcing term and the last step's agreement with its linear model
    dog : the watchdog (:class:`~contopt.solve.linesearch.Watchdog`)
    """

    u: np.ndarray
    du_c: np.ndarray
    r_ref: float
    roundoff: float
    residuals: tuple[float, ...]
    eta: float
    dog: Watchdog
    increments: tuple[float, ...] = ()
    full_steps: tuple[float, ...] = ()
    alphas: tuple[float, ...] = ()
    tangents: str = ""
    krylov: tuple[int, ...] = ()
    agreement: float | None = None
    factorizations: int = 0  # the active-set prediction's extra ones (contopt.solve.activeset)

    @property
    def moving(self) -> bool:
        """Prescribed motion remains: the step is not done, and the merit functions are not comparable."""
        return bool(np.any(self.du_c))


@dataclass(frozen=True, eq=False)
class LoadStep:
    """What a load step's Newton solve works with, fixed over its iterations (:func:`newton_step`'s
    arguments), and the tally of its phases' seconds (``seconds``)."""

    evaluate: Evaluate
    free: np.ndarray
    constrained: np.ndarray
    u_c_target: np.ndarray
    t: float
    dt: float
    options: NewtonOptions
    linear: LinearSolverOptions
    admissible: Callable[[np.ndarray], str] | None
    geometry: Callable[[np.ndarray], Geometry] | None
    guess: np.ndarray | None
    predict: Callable | None = None
    seconds: dict = field(
        default_factory=lambda: {"kernels": 0.0, "scatter": 0.0, "factorize": 0.0, "solve": 0.0, "contact": 0.0}
    )

    def account(self, ev: Evaluated) -> None:
        """Add an evaluation's timings to the step's."""
        for k, v in ev.timings.as_dict().items():
            self.seconds[k] += v

    def refusal(self, u: np.ndarray) -> str:
        """Why ``u`` cannot be a state (``admissible``), timed with the contact work it belongs to."""
        assert self.admissible is not None
        with timed(self.seconds, "contact"):
            return self.admissible(u)

    def start(self, u: np.ndarray, ev: Evaluated, f_scale: float) -> Iterate:
        """The iterate at the step's start ``u``, evaluated as ``ev``."""
        r_norm = norm(ev.r[self.free])
        return Iterate(
            u=u,
            du_c=self.u_c_target - u[self.constrained],
            r_ref=max(f_scale, norm(ev.r[self.constrained]), r_norm),
            roundoff=_roundoff(ev, u, self.free, self.geometry),
            residuals=(r_norm,),
            eta=self.linear.krylov_eta_max,
            dog=Watchdog(armed=self.options.watchdog > 0),
        )

    def log(self, x: Iterate, it: int, converged: bool, message: str = "") -> NewtonLog:
        """The step's log after ``it`` iterations that got it to ``x``."""
        return NewtonLog(
            t=self.t,
            dt=self.dt,
            converged=converged,
            iterations=it,
            residuals=x.residuals,
            increments=x.increments,
            alphas=x.alphas,
            r_ref=x.r_ref,
            seconds=dict(self.seconds),
            message=message,
            tangents=x.tangents,
            krylov=x.krylov,
            extra={"factorizations": len(x.tangents) + x.factorizations} if self.predict is not None else {},
        )


@dataclass(frozen=True, eq=False)
class LinearSystem:
    """A Newton iteration's ``K du_f = rhs`` but its matrix ``K`` (held apart, to be let go of once
    solved): ``rhs`` (n_free,), the point it linearizes at (residual and energy), the sum over the
    ranks, and which tangent ``K`` is ("e" exact, "m" modified)."""

    rhs: np.ndarray
    point: Merit
    reduce: Callable[[np.ndarray], np.ndarray]
    tangent: str


@dataclass(frozen=True, eq=False)
class Direction:
    """A Newton iteration's step ``du`` (n,): the linear solve's ``du_f`` on the free dofs, the prescribed
    increment on the constrained; ``lin = K du_f - rhs`` (n_free,), the linear solve's residual where
    it is iterative (else None)."""

    du: np.ndarray
    lin: np.ndarray | None


def linear_system(step: LoadStep, x: Iterate, ev: Evaluated) -> tuple[Any, LinearSystem]:
    """Newton's tangent at ``x`` (evaluated as ``ev``) and the rest of its linear system, with the
    prescribed increment in the right-hand side: ``K_ff du_f = -(r_f + K_fc du_c)``. Far from
    equilibrium an evaluation may offer a better-behaved tangent than the exact one: Newton takes it."""
    rhs = -ev.r[step.free]
    if x.moving:
        rhs = rhs - ev.reduce(ev.K_fc @ x.du_c)  # K_fc: this rank's part in a distributed run
    K = ev.K_free if ev.modified is None else ev.modified.K_free()
    tangent = "e" if K is ev.K_free else "m"
    return K, LinearSystem(rhs=rhs, point=Merit(r=ev.r, energy=ev.energy), reduce=ev.reduce, tangent=tangent)


def solve_linear(step: LoadStep, x: Iterate, K, system: LinearSystem, it: int) -> tuple[Iterate, Direction]:
    """Factor ``K`` and solve iteration ``it``'s system, an iterative solver to the forcing term; returns
    ``x`` with the iteration's tangent, forcing term, Krylov iterations and full step recorded, and the
    step. Raises StepFailure when the linear solve fails (structural in the first iteration)."""
    x = replace(x, tangents=x.tangents + system.tangent)
    options, linear = step.options, step.linear
    try:
        with timed(step.seconds, "factorize"):
            factor = factorize(K, linear, None if step.geometry is None else step.geometry(x.u))
        with timed(step.seconds, "solve"):
            target = max(options.rtol * x.r_ref, options.atol)
            eta = forcing_term(linear, x.residuals, x.eta, target, x.agreement)
            du_f = factor.solve(system.rhs, rtol=eta, x0=step.guess if it == 1 else None)
            lin = None
            if getattr(factor, "iterative", False):
                x = replace(x, krylov=(*x.krylov, int(sum(factor.info["iterations"]))))
                lin = system.reduce(K @ du_f) - system.rhs  # K: this rank's part in a distributed run
            factor.free()  # release before the next factorization: bounds peak memory
    except UnavailableSolverError:
        raise  # a usage error: no smaller load step makes the solver appear
    except LinearSolverError as e:
        raise StepFailure(f"linear solve failed: {e}", step.log(x, it, False, str(e)), structural=(it == 1)) from e
    du = np.zeros_like(x.u)
    du[step.free] = du_f
    du[step.constrained] = x.du_c
    return replace(x, eta=eta, full_steps=(*x.full_steps, norm(du_f))), Direction(du=du, lin=lin)


def search(step: LoadStep, x: Iterate, system: LinearSystem, direction: Direction, it: int) -> tuple[Iterate, Any]:
    """The line search along the iteration's step, with the watchdog beside it; the next iterate and its
    evaluation (with the tangent). Raises StepFailure when no trial point is finite and admissible."""
    near = x.residuals[-1] <= np.sqrt(step.options.rtol) * x.r_ref
    refusal = None if step.admissible is None else step.refusal
    landing = watched_line_search(
        step.evaluate, x.u, direction.du, system.point, step.free, near, x.moving, step.options, step.account,
        refusal, x.dog, it,
    )  # fmt: skip
    if landing.u is None:
        why = landing.why
        raise StepFailure(
            f"line search found no admissible step: {why}"
            if why
            else "line search found no finite residual (elements inverted?)",
            step.log(x, it, False, "no admissible step" if why else "non-finite residual"),
        )
    return landed(step, x, system, direction, landing, it), landing.ev


def landed(
    step: LoadStep, x: Iterate, system: LinearSystem, direction: Direction, landing: Landing, it: int
) -> Iterate:
    """The iterate the line search landed on: its residual, the step's length and factor, the linear
    model's agreement with it (iterative solves, along this iteration's step only), the reference
    grown by the reactions (and in the first iteration by the residual), the watchdog after it."""
    ev, u, free = landing.ev, landing.u, step.free
    assert u is not None
    r_norm = norm(ev.r[free])
    agreement = x.agreement
    if direction.lin is not None and not landing.back:
        rhs_norm = norm(system.rhs)
        agreement = model_agreement(ev.r[free], system.point.r[free], direction.lin, rhs_norm, landing.alpha)
    r_ref = max(x.r_ref, norm(ev.r[step.constrained]))
    if it == 1 and landing.dog.watch is None:  # an overshot full step's residual is no scale of the step
        r_ref = max(r_ref, r_norm)
    return replace(
        x,
        u=u,
        du_c=step.u_c_target - u[step.constrained],
        r_ref=r_ref,
        residuals=(*x.residuals, r_norm),
        increments=(*x.increments, landing.length),
        alphas=(*x.alphas, landing.alpha),
        agreement=agreement,
        dog=landing.dog,
    )


def verdict(step: LoadStep, x: Iterate, ev: Evaluated, it: int, good_enough: Callable | None) -> str | None:
    """After iteration ``it``: the message of a converged solve ("" where the tolerances are met), or
    None to go on. Raises StepFailure where Newton stagnates (less than a halving of ``|r|`` over six
    iterations: a smaller load step is cheaper) or diverges; a stagnation below ``sqrt(rtol) r_ref`` whose
    full steps are below ``utol |u|`` is converged ("displacement converged", :func:`_negligible_steps`)."""
    options, r_norm = step.options, x.residuals[-1]
    if not x.moving:
        message = converged(step, x, ev, good_enough)
        if message is not None:
            return message
        if it >= 10 and r_norm > 0.5 * x.residuals[-7]:
            if _accept_stall(options, r_norm, x.r_ref, "stagnated"):
                return "accepted at stagnation"
            near = r_norm <= np.sqrt(options.rtol) * x.r_ref
            if near and _negligible_steps(x, options.utol, "stagnated"):
                return "displacement converged"
            raise StepFailure(
                f"Newton stagnated (|r| = {r_norm:.3e} after {it} iterations, "
                f"{x.residuals[-7]:.3e} six iterations before)",
                step.log(x, it, False, "stagnated"),
                stalled=r_norm / x.r_ref if near else None,
            )
    if r_norm > options.divergence_factor * max(x.r_ref, 1e-300):
        raise StepFailure(f"Newton diverged (|r| = {r_norm:.3e})", step.log(x, it, False, "diverged"))
    return None


def converged(step: LoadStep, x: Iterate, ev: Evaluated, good_enough: Callable | None) -> str | None:
    """Whether ``x`` (no prescribed motion left) is converged, and how ("": the tolerances; "round-off
    floor"; "good enough"), or None (:class:`NewtonOptions`: rtol, atol, utol)."""
    options, r_norm, r_ref = step.options, x.residuals[-1], x.r_ref
    u_norm = max(norm(x.u), 1e-300)
    floor = max(options.atol, x.roundoff)
    done = r_norm <= max(options.rtol * r_ref, floor) and x.increments[-1] <= options.utol * u_norm
    # round-off floor: the increment no longer changes u and the residual is already small
    stalled = x.increments[-1] <= 1e3 * np.finfo(float).eps * u_norm and r_norm <= np.sqrt(options.rtol) * r_ref
    if done or stalled or r_norm <= floor:
        return ""
    if _at_roundoff(x.full_steps, x.residuals, u_norm, np.sqrt(options.rtol) * r_ref):
        log.info("Newton at the round-off floor: |r| = %.3e, full steps %.2e |u|", r_norm, x.full_steps[-1] / u_norm)
        return "round-off floor"
    if good_enough is not None and good_enough(ev, r_norm, r_ref):
        return GOOD_ENOUGH
    return None


def out_of_iterations(step: LoadStep, x: Iterate) -> str:
    """``max_iter`` iterations without convergence: the message of a solve accepted at stagnation
    (``NewtonOptions.stall_rtol``) or creeping below ``sqrt(rtol) r_ref`` with full steps below ``utol |u|``
    ("displacement converged", as at a stagnation); else raises StepFailure."""
    options = step.options
    if not x.moving and _accept_stall(options, x.residuals[-1], x.r_ref, "reached max_iter"):
        return "accepted at stagnation"
    # close to the tolerance and converging linearly at best (the last iteration won less than a digit): a
    # quadratic solve merely cut short by max_iter is not stalled (the seam's creeps by halves for 25 iterations)
    creeping = len(x.residuals) >= 2 and x.residuals[-1] > 0.1 * x.residuals[-2]
    near = not x.moving and creeping and x.residuals[-1] <= np.sqrt(options.rtol) * x.r_ref
    if near and _negligible_steps(x, options.utol, "crept to max_iter"):
        return "displacement converged"
    raise StepFailure(
        f"no convergence in {options.max_iter} iterations (|r| = {x.residuals[-1]:.3e}, "
        f"target {options.rtol * x.r_ref:.3e})",
        step.log(x, options.max_iter, False, "max_iter"),
        stalled=x.residuals[-1] / x.r_ref if near else None,
    )


def _roundoff(ev: Evaluated, u: np.ndarray, free: np.ndarray, geometry) -> float:
    """``ROUNDOFF * |diag(K_free) x|``: the round-off of the internal forces at the evaluation ``ev``,
    with x the free dofs' positions (from ``geometry(u)``; ``|u|`` without one)."""
    if ev.K_free is None:
        return 0.0
    # summed over the ranks' parts: every rank takes the same decisions
    diagonal = np.abs(ev.reduce(ev.K_free.diagonal()))
    x = np.abs(u[free]) if geometry is None else np.abs(geometry(u).points.reshape(-1)[free])
    return ROUNDOFF * norm(diagonal * x)


def _at_roundoff(full_steps: Sequence[float], residuals: Sequence[float], u_norm: float, bound: float) -> bool:
    """Two full Newton steps in a row below ``SQRT_EPS * u_norm`` that did not halve the residual, which is
    below ``bound``: the solve's own measure of its round-off floor (``NewtonOptions.atol``)."""
    if len(full_steps) < 2 or len(residuals) < 3:
        return False
    return max(full_steps[-2:]) <= SQRT_EPS * u_norm and residuals[-1] > 0.5 * residuals[-3] and residuals[-1] <= bound


def _negligible_steps(x: Iterate, utol: float, how: str) -> bool:
    """Whether the last two full Newton steps, from the exact tangent, are below ``utol * |u|``: at a
    stagnation near the tolerance (or a creep by halvings to ``max_iter``), the state is known to the
    displacement tolerance, whatever noise the residual carries (the slivers of a sharp contact edge:
    issue 35), said in the log."""
    u_norm = norm(x.u)
    if len(x.full_steps) < 2 or x.tangents[-2:] != "ee" or not max(x.full_steps[-2:]) <= utol * u_norm:
        return False
    log.info(
        "Newton %s at |r| = %.3e = %.2g of the reference with full steps %.2e |u| <= utol %g: converged",
        how, x.residuals[-1], x.residuals[-1] / x.r_ref, max(x.full_steps[-2:]) / max(u_norm, 1e-300), utol,
    )  # fmt: skip
    return True


def _accept_stall(options: NewtonOptions, r_norm: float, r_ref: float, how: str) -> bool:
    """Whether a solve that stalled is accepted (``options.stall_rtol``), said in a warning."""
    if options.stall_rtol is None or not r_norm <= options.stall_rtol * r_ref:
        return False
    log.warning(
        "Newton %s at |r| = %.3e = %.2g of the reference (stall_rtol %g): accepted", how, r_norm,
        r_norm / r_ref, options.stall_rtol,
    )  # fmt: skip
    return True
