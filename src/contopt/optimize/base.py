"""What an optimizer sees: a smooth nonlinear program in numpy float64.

    minimize f(x)  subject to  g_j(x) <= 0 (j = 1..m),  lower <= x <= upper

The problem adapter (:mod:`contopt.optimize.problem`) turns a design problem
into this form; the optimizers (:mod:`contopt.optimize.mma`,
:mod:`contopt.optimize.ipopt`) only know this protocol. Both are
deterministic: the same answers to the same ``x`` give the same iterates,
which is what resuming a run by replay relies on.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from contopt.errors import ConfigError, ContoptError

STATUSES = ("converged", "max_iter", "stopped", "failed")
#: the optimizers a design problem can be run with (contopt.optimize.driver.optimize)
OPTIMIZERS = ("mma", "ipopt")


class EvaluationFailure(ContoptError, RuntimeError):
    """The analysis at a trial design failed (e.g. Newton did not converge).

    An optimizer with a line search (IPOPT) backs off from such a point; one
    without (MMA) stops and reports it.
    """


@dataclass(frozen=True, eq=False)
class DesignEvaluation:
    """Values and gradients of one design ``x`` (n design variables, m constraints).

    f : objective value
    g : (m,) constraint values, feasible where ``g <= 0``
    df : (n,) gradient of f
    dg : (m, n) gradients of the constraints (dense: m is small)
    """

    f: float
    g: np.ndarray
    df: np.ndarray
    dg: np.ndarray


@dataclass(frozen=True, eq=False)
class IterationInfo:
    """One optimizer iteration, reported after the iterate ``x`` was accepted.

    iteration : 0 for the initial design, then 1, 2, ...
    x : (n,) the accepted iterate
    f, g : its objective and (m,) constraint values
    optimality : the optimizer's own stationarity measure (IPOPT: scaled dual
        infeasibility; MMA: norm of the KKT residual), nan where undefined
    change : ``max |x_k - x_{k-1}|`` (nan at iteration 0)
    extra : optimizer-specific numbers (IPOPT: inf_pr, mu, alpha_pr, ...)
    """

    iteration: int
    x: np.ndarray
    f: float
    g: np.ndarray
    optimality: float = float("nan")
    change: float = float("nan")
    extra: dict = field(default_factory=dict)


class NLP(Protocol):
    """The nonlinear program an optimizer solves (see the module docstring)."""

    n: int
    m: int
    lower: np.ndarray  # (n,)
    upper: np.ndarray  # (n,)

    def evaluate(self, x: np.ndarray) -> DesignEvaluation:
        """Values and gradients at ``x``; may raise :class:`EvaluationFailure`."""

    def iteration(self, info: IterationInfo) -> bool:
        """Called once per accepted iterate (0 = initial design); return False to stop."""


@dataclass(frozen=True, eq=False)
class OptimizerResult:
    """Where an optimizer stopped.

    x : (n,) last accepted iterate; f, g its values
    iterations : number of iterations after the initial design
    status : one of :data:`STATUSES`
    message : the optimizer's own words
    evaluations : number of calls to ``evaluate`` (cache hits of the adapter included)
    """

    x: np.ndarray
    f: float
    g: np.ndarray
    iterations: int
    status: str
    message: str = ""
    evaluations: int = 0


def bounds_and_start(nlp: NLP, x0, who: str, finite: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``lower, upper, x0`` of ``nlp`` as float64 (n,) arrays, checked for an optimizer named ``who``.

    ConfigError unless the bounds are ordered (``finite``: finite with lower < upper, as MMA's
    asymptotes need; else lower <= upper, infinite allowed) and x0 lies within them.
    """
    n = int(nlp.n)
    lower = np.array(nlp.lower, dtype=np.float64).reshape(-1)
    upper = np.array(nlp.upper, dtype=np.float64).reshape(-1)
    x = np.array(x0, dtype=np.float64).reshape(-1)
    if lower.shape != (n,) or upper.shape != (n,) or x.shape != (n,):
        raise ConfigError(
            f"{who}: lower, upper and x0 must have n = {n} entries, got {lower.size}, {upper.size} and {x.size}"
        )
    if finite:
        if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper)) and np.all(lower < upper)):
            raise ConfigError(f"{who}: the bounds must be finite with lower < upper for every variable")
    elif np.any(np.isnan(lower)) or np.any(np.isnan(upper)) or np.any(lower > upper):
        raise ConfigError(f"{who}: the bounds must satisfy lower <= upper for every variable")
    outside = np.flatnonzero(~np.isfinite(x) | (x < lower) | (x > upper))
    if outside.size:
        j = int(outside[0])
        raise ConfigError(
            f"{who}: x0 must lie within [lower, upper]; x0[{j}] = {x[j]!r} is outside "
            f"[{lower[j]!r}, {upper[j]!r}] ({outside.size} such entries)"
        )
    return lower, upper, x


def checked(ev: DesignEvaluation, n: int, m: int) -> DesignEvaluation:
    """``ev`` as float64 arrays of shapes (m,), (n,), (m, n); ValueError on wrong shapes (a bug,
    not a failed analysis)."""
    g = np.asarray(ev.g, dtype=np.float64).reshape(-1)
    df = np.asarray(ev.df, dtype=np.float64).reshape(-1)
    dg = np.asarray(ev.dg, dtype=np.float64).reshape(m, -1) if m else np.zeros((0, n))
    if g.shape != (m,) or df.shape != (n,) or dg.shape != (m, n):
        raise ValueError(
            f"nlp.evaluate returned g {g.shape}, df {df.shape}, dg {dg.shape}; expected ({m},), ({n},), ({m}, {n})"
        )
    return DesignEvaluation(f=float(ev.f), g=g, df=df, dg=dg)


#: a resumed run replays a recorded analysis where the optimizer asks for its design to within this (max-norm,
#: relative to the design's largest value and at least 1): IPOPT's iterates differ in their last bits from one
#: run to the next on a loaded machine (its threaded reductions), and an analysis 1e-10 away differs from the
#: recorded one far below Newton's tolerance
SAME_DESIGN = 1e-10


def same_design(recorded: np.ndarray, x: np.ndarray) -> bool:
    """Whether the optimizer's ``x`` (n,) is the ``recorded`` design (n,) but for round-off (:data:`SAME_DESIGN`)."""
    recorded, x = np.asarray(recorded), np.asarray(x)
    if recorded.shape != x.shape:
        return False
    scale = max(1.0, float(np.max(np.abs(recorded), initial=0.0)))
    return bool(np.max(np.abs(recorded - x), initial=0.0) <= SAME_DESIGN * scale)
