"""Svanberg's method of moving asymptotes (MMA), after his 2007 note.

Solves the :class:`~contopt.optimize.base.NLP`

    minimize f(x)  subject to  g_i(x) <= 0 (i = 1..m),  lower <= x <= upper

through Svanberg's augmented problem in the variables x (n), y (m), z:

    minimize   f(x) + a0 z + sum_i (c_i y_i + d_i y_i^2 / 2)
    subject to g_i(x) - a_i z - y_i <= 0,  lower <= x <= upper,  y >= 0,  z >= 0

with a0 = 1, a_i = 0, d_i = 1 and c_i = ``MMAOptions.c`` (1000). The elastic
variables y_i make every subproblem feasible; for c_i large enough they are 0 at
a solution of a feasible problem. Each iteration (:func:`mmasub`) updates the
moving asymptotes, builds the convex separable approximation at the current
point and solves it with a primal-dual interior point method (:func:`subsolv`);
the subproblem's solution is the next iterate.

Reference: K. Svanberg, "MMA and GCMMA - two methods for nonlinear
optimization", KTH Stockholm, 2007 (the asymptote rules, the move limits with
albefa = 0.1 and the raa0 = 1e-5 terms of section 3, the subproblem solver of
section 5 and the KKT conditions of section 6).

Stopping measure
----------------
After the new iterate ``x_k`` is evaluated, :func:`kkt_residual` forms the
residual of the KKT conditions of the augmented problem at ``(x_k, y, z)`` with
the multipliers (lam, xsi, eta, mu, zet, s) of the subproblem just solved, as
Svanberg's ``kktcheck`` does: gradient of the Lagrangian (n), the y and z
stationarity (m + 1), the constraint residuals with slacks (m), and the
complementarity products of the bounds ``lower <= x <= upper`` (2n), of y, z
(m + 1) and of the constraints (m). ``IterationInfo.optimality`` is

    ||residual||_2 / sqrt(n)

(a root-mean-square over the design variables, so that the measure does not
grow with the mesh), and MMA stops as "converged" when it is below
``MMAOptions.kkt_tol``, or when ``max_j |x_k - x_{k-1}|_j / (upper_j - lower_j)``
is below ``MMAOptions.change_tol``. Like any first-order residual it scales
with f and g: scale them to order 1 (Svanberg recommends f in [1, 100]).
Sensitivities that vanish without the variable being at a bound (e.g. a
saturated Heaviside projection) also make it small; where the steps are still
at the move limit, a tighter kkt_tol (or kkt_tol = 0 and change_tol alone) is
the safer stop.

A known trait of the method: where every gradient of a variable vanishes at
an interior point (an unconstrained interior minimum), its approximations are
nearly flat, the steps go most of the way to the asymptotes, and the iterates
oscillate within about ASYMIN (upper - lower) of the minimum rather than
converging (GCMMA's conservative updates address this). Minima on the bounds
or with active constraints converge as usual.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass

import numpy as np

from contopt.errors import ConfigError
from contopt.optimize.base import (
    NLP,
    DesignEvaluation,
    EvaluationFailure,
    IterationInfo,
    OptimizerResult,
    bounds_and_start,
    checked,
)
from contopt.optimize.mma_subsolv import EPSIMIN, PrimalDual, Subproblem, subsolv

__all__ = [
    "EPSIMIN",
    "MMAOptions",
    "PrimalDual",
    "Subproblem",
    "asymptotes",
    "kkt_residual",
    "mmasub",
    "run_mma",
    "subsolv",
]

log = logging.getLogger(__name__)

ALBEFA = 0.1  # alfa, beta stay this fraction of the way from x to the asymptotes
RAA0 = 1e-5  # keeps p, q > 0 where a derivative vanishes: strictly convex subproblems
XMAMIEPS = 1e-5  # floor of (upper - lower) in the raa0 term
ASYMIN = 0.01  # asymptotes between ASYMIN and ASYMAX times (upper - lower) from x
ASYMAX = 10.0
A0 = 1.0  # a0, a_i = 0, d_i = 1: the augmented problem is the NLP itself when y = 0
D = 1.0


def _option_real(key: str, value, allowed: str, ok) -> float:
    """``value`` as a float if finite and ``ok(value)``, else ConfigError naming ``mma.key``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ConfigError(f"mma.{key} must be a number in {allowed}, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and ok(v)):
        raise ConfigError(f"mma.{key} must lie in {allowed}, got {value!r}")
    return v


@dataclass(frozen=True)
class MMAOptions:
    """Options of :func:`run_mma`, validated at construction.

    max_iter : iterations after the initial design (>= 0)
    move : move limit as a fraction of (upper - lower), in (0, 1]
    kkt_tol : stop when ||KKT residual||_2 / sqrt(n) < kkt_tol (module docstring); 0 disables
    change_tol : stop when ``max |x_k - x_{k-1}| / (upper - lower) < change_tol``; 0 disables
    asyinit : initial asymptote distance as a fraction of (upper - lower), in (0, 1]
    asyincr : asymptote widening factor where x moves monotonically, >= 1
    asydecr : asymptote narrowing factor where x oscillates, in (0, 1]
    c : the c_i of the elastic variables y_i (> 0); large enough to make y = 0
        at a solution of a feasible problem
    backtracks : where the analysis of the new iterate fails (EvaluationFailure), try the
        points halfway, a quarter, ... of the way from the last accepted iterate, at most this
        many times, before stopping with status "failed" (>= 0; 0: stop at once)
    """

    max_iter: int = 100
    move: float = 0.2
    kkt_tol: float = 1e-3
    change_tol: float = 1e-3
    asyinit: float = 0.5
    asyincr: float = 1.2
    asydecr: float = 0.7
    c: float = 1000.0
    backtracks: int = 3

    def __post_init__(self):
        for key in ("max_iter", "backtracks"):
            v = getattr(self, key)
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or v < 0:
                raise ConfigError(f"mma.{key} must be an integer >= 0, got {v!r}")
            object.__setattr__(self, key, int(v))
        checks = {
            "move": ("(0, 1]", lambda v: 0.0 < v <= 1.0),
            "kkt_tol": ("[0, inf)", lambda v: v >= 0.0),
            "change_tol": ("[0, inf)", lambda v: v >= 0.0),
            "asyinit": ("(0, 1]", lambda v: 0.0 < v <= 1.0),
            "asyincr": ("[1, inf)", lambda v: v >= 1.0),
            "asydecr": ("(0, 1]", lambda v: 0.0 < v <= 1.0),
            "c": ("(0, inf)", lambda v: v > 0.0),
        }
        for key, (allowed, ok) in checks.items():
            object.__setattr__(self, key, _option_real(key, getattr(self, key), allowed, ok))


def asymptotes(
    k: int,
    x: np.ndarray,
    xold1: np.ndarray,
    xold2: np.ndarray,
    low: np.ndarray | None,
    upp: np.ndarray | None,
    lower: np.ndarray,
    upper: np.ndarray,
    options: MMAOptions,
) -> tuple[np.ndarray, np.ndarray]:
    """Asymptotes (low, upp), each (n,), for MMA iteration ``k`` (1-based) at ``x = x_{k-1}``.

    ``xold1 = x_{k-2}``, ``xold2 = x_{k-3}`` and ``low, upp`` of iteration k - 1
    are used from k = 3 on.
    """
    width = upper - lower
    if k <= 2:
        return x - options.asyinit * width, x + options.asyinit * width
    # an oscillating variable gets tighter asymptotes (more conservative), a
    # monotonically moving one looser asymptotes (faster)
    trend = (x - xold1) * (xold1 - xold2)
    factor = np.where(trend > 0.0, options.asyincr, np.where(trend < 0.0, options.asydecr, 1.0))
    low = x - factor * (xold1 - low)
    upp = x + factor * (upp - xold1)
    low = np.minimum(np.maximum(low, x - ASYMAX * width), x - ASYMIN * width)
    upp = np.minimum(np.maximum(upp, x + ASYMIN * width), x + ASYMAX * width)
    return low, upp


def move_limits(
    x: np.ndarray, low: np.ndarray, upp: np.ndarray, lower: np.ndarray, upper: np.ndarray, move: float
) -> tuple[np.ndarray, np.ndarray]:
    """Subproblem bounds (alfa, beta), each (n,): the box, the move limit, and off the asymptotes."""
    width = upper - lower
    alfa = np.maximum(np.maximum(low + ALBEFA * (x - low), x - move * width), lower)
    beta = np.minimum(np.minimum(upp - ALBEFA * (upp - x), x + move * width), upper)
    return alfa, beta


def approximation_terms(
    x: np.ndarray, low: np.ndarray, upp: np.ndarray, lower: np.ndarray, upper: np.ndarray, ev: DesignEvaluation
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """MMA coefficients (p0, q0: (n,); P, Q: (m, n); b: (m,)) of the evaluation ``ev`` at ``x``.

    ``p = (upp - x)^2 (1.001 df+ + 0.001 df- + raa0/(upper - lower))`` and ``q``
    likewise with ``(x - low)^2`` and the roles of df+ and df- swapped: the
    approximation matches value and gradient at ``x`` and is strictly convex.
    """
    ux = upp - x
    xl = x - low
    floor = RAA0 / np.maximum(upper - lower, XMAMIEPS)

    def terms(grad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        plus = np.maximum(grad, 0.0)
        minus = np.maximum(-grad, 0.0)
        both = 0.001 * (plus + minus) + floor
        return (plus + both) * ux**2, (minus + both) * xl**2

    p0, q0 = terms(ev.df)
    P, Q = terms(ev.dg)
    b = P @ (1.0 / ux) + Q @ (1.0 / xl) - ev.g
    return p0, q0, P, Q, b


def mmasub(
    k: int,
    x: np.ndarray,
    xold1: np.ndarray,
    xold2: np.ndarray,
    low: np.ndarray | None,
    upp: np.ndarray | None,
    lower: np.ndarray,
    upper: np.ndarray,
    ev: DesignEvaluation,
    options: MMAOptions,
) -> tuple[PrimalDual, Subproblem, int]:
    """One MMA iteration ``k`` (1-based) from ``x = x_{k-1}`` with its evaluation ``ev``.

    Returns the subproblem's primal-dual solution (its ``x`` is the next iterate,
    (n,)), the subproblem (asymptotes etc.) and the number of Newton steps taken.
    """
    m = ev.g.shape[0]
    low, upp = asymptotes(k, x, xold1, xold2, low, upp, lower, upper, options)
    alfa, beta = move_limits(x, low, upp, lower, upper, options.move)
    p0, q0, P, Q, b = approximation_terms(x, low, upp, lower, upper, ev)
    sub = Subproblem(
        low=low,
        upp=upp,
        alfa=alfa,
        beta=beta,
        p0=p0,
        q0=q0,
        P=P,
        Q=Q,
        b=b,
        a0=A0,
        a=np.zeros(m),
        c=np.full(m, options.c),
        d=np.full(m, D),
    )
    solution, newton_steps = subsolv(sub)
    return solution, sub, newton_steps


def kkt_residual(
    w: PrimalDual,
    lower: np.ndarray,
    upper: np.ndarray,
    ev: DesignEvaluation,
    a0: float = A0,
    a: np.ndarray | None = None,
    c: np.ndarray | float = 1000.0,
    d: np.ndarray | float = D,
) -> np.ndarray:
    """Residual (3n + 4m + 2,) of the KKT conditions of the augmented problem (Svanberg's ``kktcheck``).

    ``w`` holds the point ``(x, y, z)`` and the multipliers, ``ev`` the NLP's
    values and gradients at ``w.x``; the bound multipliers xsi, eta belong to
    ``lower`` and ``upper``. Zero exactly at a KKT point.
    """
    m = ev.g.shape[0]
    a = np.zeros(m) if a is None else a
    return np.concatenate(
        [
            ev.df + ev.dg.T @ w.lam - w.xsi + w.eta,
            c + d * w.y - w.mu - w.lam,
            [a0 - w.zet - a @ w.lam],
            ev.g - a * w.z - w.y + w.s,
            w.xsi * (w.x - lower),
            w.eta * (upper - w.x),
            w.mu * w.y,
            [w.zet * w.z],
            w.lam * w.s,
        ]
    )


def _evaluate(nlp: NLP, x: np.ndarray, n: int, m: int) -> DesignEvaluation:
    """``nlp.evaluate(x)`` as float64 arrays of the right shapes; non-finite values count as a failure."""
    ev = checked(nlp.evaluate(x.copy()), n, m)
    if not (math.isfinite(ev.f) and all(np.all(np.isfinite(a)) for a in (ev.g, ev.df, ev.dg))):
        raise EvaluationFailure("the evaluation returned non-finite values (f, g, df or dg)")
    return ev


def _evaluate_backtracking(
    nlp: NLP, x: np.ndarray, w: PrimalDual, n: int, m: int, backtracks: int
) -> tuple[PrimalDual, DesignEvaluation, int]:
    """Evaluate the subproblem's solution ``w.x``; where the analysis fails, the points
    ``x + 2^-j (w.x - x)``, j = 1..backtracks (they stay inside the box and the move limits).

    Returns ``(w, ev, tries)`` with ``w.x`` the point evaluated; raises the last
    :class:`EvaluationFailure` when all ``backtracks + 1`` tries failed. Why: a failed analysis (a design whose large
    deformation Newton cannot follow) is usually a step too far, and a shorter one succeeds.
    """
    for j in range(backtracks + 1):
        trial = w.x if j == 0 else x + 0.5**j * (w.x - x)
        try:
            return dataclasses.replace(w, x=trial), _evaluate(nlp, trial, n, m), j + 1
        except EvaluationFailure as exc:
            if j == backtracks:
                raise
            log.warning("MMA: the analysis of the new iterate failed (%s); trying %g of the step", exc, 0.5 ** (j + 1))
    raise AssertionError("not reached: backtracks >= 0 (MMAOptions), so the last try returned or raised")


def run_mma(nlp: NLP, x0: np.ndarray, options: MMAOptions | None = None) -> OptimizerResult:
    """Minimize ``nlp`` from ``x0`` with MMA; one ``nlp.evaluate`` per iteration.

    ``nlp.iteration`` is called with iteration 0 at ``x0`` and after each new
    iterate; returning False stops with status "stopped". An
    :class:`EvaluationFailure` stops with status "failed" and the last accepted
    iterate, after ``options.backtracks`` shorter steps failed too (the KKT
    residual of a shortened step is formed with the full step's subproblem
    multipliers); any other exception propagates. x0 outside the bounds raises
    :class:`ConfigError`.

    ``IterationInfo.optimality`` is ||KKT residual||_2 / sqrt(n) (module
    docstring), ``change`` is max |x_k - x_{k-1}|; ``extra`` holds ``kkt_max``
    (largest residual entry), ``change_scaled`` (the change over upper - lower,
    compared with change_tol), ``subproblem_iterations`` (Newton steps of
    subsolv), ``asymptote_width_min``/``_max`` (min/max of upp - low), ``y_max``
    (largest elastic variable: > 0 where the subproblem could not satisfy a
    constraint) and ``lam`` (the m constraint multipliers, a list of floats).
    """
    options = MMAOptions() if options is None else options
    n, m = int(nlp.n), int(nlp.m)
    lower, upper, x = bounds_and_start(nlp, x0, "mma", finite=True)
    width = upper - lower

    try:
        ev = _evaluate(nlp, x, n, m)
    except EvaluationFailure as exc:
        log.warning("MMA: the evaluation of the initial design failed: %s", exc)
        return OptimizerResult(
            x=x,
            f=float("nan"),
            g=np.full(m, np.nan),
            iterations=0,
            status="failed",
            message=f"evaluation failed at the initial design: {exc}",
            evaluations=1,
        )
    evaluations = 1

    def result(k: int, status: str, message: str) -> OptimizerResult:
        log.info("MMA %s after %d iterations: %s", status, k, message)
        return OptimizerResult(
            x=x.copy(), f=ev.f, g=ev.g.copy(), iterations=k, status=status, message=message, evaluations=evaluations
        )

    if not nlp.iteration(IterationInfo(iteration=0, x=x.copy(), f=ev.f, g=ev.g.copy())):
        return result(0, "stopped", "stopped by the iteration callback at iteration 0")

    xold1, xold2, low, upp = x, x, None, None
    for k in range(1, options.max_iter + 1):
        w, sub, newton_steps = mmasub(k, x, xold1, xold2, low, upp, lower, upper, ev, options)
        low, upp = sub.low, sub.upp
        try:
            w, ev_new, tries = _evaluate_backtracking(nlp, x, w, n, m, options.backtracks)
            evaluations += tries
        except EvaluationFailure as exc:
            evaluations += options.backtracks + 1
            log.warning("MMA: evaluation failed at iteration %d: %s", k, exc)
            return result(k - 1, "failed", f"evaluation failed at MMA iteration {k}: {exc}")

        residual = kkt_residual(w, lower, upper, ev_new, c=sub.c, d=sub.d)
        optimality = float(np.linalg.norm(residual) / math.sqrt(n))
        step = np.abs(w.x - x)
        change = float(np.max(step))
        change_scaled = float(np.max(step / width))
        xold2, xold1, x, ev = xold1, x, w.x, ev_new
        extra = {
            "kkt_max": float(np.max(np.abs(residual))),
            "change_scaled": change_scaled,
            "subproblem_iterations": newton_steps,
            "asymptote_width_min": float(np.min(upp - low)),
            "asymptote_width_max": float(np.max(upp - low)),
            "y_max": float(np.max(w.y, initial=0.0)),
            "lam": [float(v) for v in w.lam],
        }
        log.debug(
            "MMA it %d: f = %.6g, max g = %.3g, kkt = %.3g, change = %.3g",
            k,
            ev.f,
            float(np.max(ev.g, initial=-np.inf)),
            optimality,
            change,
        )
        info = IterationInfo(
            iteration=k, x=x.copy(), f=ev.f, g=ev.g.copy(), optimality=optimality, change=change, extra=extra
        )
        if not nlp.iteration(info):
            return result(k, "stopped", f"stopped by the iteration callback at iteration {k}")
        if optimality < options.kkt_tol:
            return result(k, "converged", f"KKT residual {optimality:.3g} < kkt_tol {options.kkt_tol:g}")
        if change_scaled < options.change_tol:
            return result(k, "converged", f"relative change {change_scaled:.3g} < change_tol {options.change_tol:g}")
    return result(options.max_iter, "max_iter", f"reached max_iter = {options.max_iter}")
