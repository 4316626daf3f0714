"""Quasi-static equilibrium of a model: load stepping + Newton on its discretization."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from contopt.assembly.model import Model
from contopt.assembly.system import Discretization, discretize
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton import NewtonOptions, StepResult, solve_load_steps


@dataclass(frozen=True, eq=False)
class State:
    """A converged equilibrium (returned, never stored on the model).

    Attributes
    ----------
    u : (n_dofs,) stacked displacements
    t : load factor reached (1.0 when the whole load was applied)
    rho : (n_cells,) stiffness factors used
    logs : NewtonLog of every attempted load step
    reactions : (n_dofs,) residual = reaction forces on constrained dofs, ~0 elsewhere
    """

    u: np.ndarray
    t: float
    rho: np.ndarray
    logs: tuple
    reactions: np.ndarray = field(repr=False, default=None)

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


def solve_static(model: Model | Discretization, rho=None, newton: NewtonOptions | None = None,
                 linear: LinearSolverOptions | None = None, u0: np.ndarray | None = None,
                 on_step=None) -> State:
    """Solve for equilibrium at load factor 1 (in load steps from 0).

    Parameters
    ----------
    model : a Model, or its Discretization (to reuse precomputation across solves)
    rho : (n_cells,) stiffness factor per cell over all bodies (default ones)
    u0 : (n_dofs,) start from this displacement instead of zero (e.g. the last design's)
    on_step : called with a :class:`State` after every converged load step (output, progress)

    Raises :class:`contopt.errors.ConvergenceError` (with logs and the last
    converged state) when a load step cannot converge.
    """
    disc = model if isinstance(model, Discretization) else discretize(model)
    rho = disc.check_rho(rho)
    newton = newton or NewtonOptions()
    linear = linear or LinearSolverOptions()
    f_norm = float(np.linalg.norm(disc.f_ext_unit[disc.free]))

    def evaluate_at(t):
        return lambda u, tangent: disc.evaluate(u, t, rho, tangent)

    def step_callback(step: StepResult):
        if on_step is not None:
            on_step(State(u=step.u, t=step.t, rho=rho, logs=(step.log,), reactions=step.evaluation.r))

    u, logs, last = solve_load_steps(
        evaluate_at, disc.n_dofs, disc.free, disc.constrained, disc.prescribed, lambda t: t * f_norm,
        newton, linear, u0=u0, on_step=step_callback)
    reactions = last.evaluation.r if last is not None else disc.evaluate(u, 1.0, rho, False).r
    return State(u=u, t=1.0, rho=rho, logs=tuple(logs), reactions=reactions)
