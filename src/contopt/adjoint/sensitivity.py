"""Adjoint sensitivities through contact (paper sections 4-5): the one entry, :func:`sensitivities`.

A state of a path-independent system is one equilibrium: its adjoint is a saddle point through the
active contact (:mod:`contopt.adjoint.saddle`). A state of a path-dependent one (friction) depends
on every load step before it: the adjoint runs back over the steps the solve recorded
(:mod:`contopt.adjoint.path`). What the two share lives in :mod:`contopt.adjoint.common`.
"""

from __future__ import annotations

from contopt.adjoint.common import AdjointResult, Sensitivity, checked_responses, step_state
from contopt.adjoint.path import path_partials, path_sensitivities, recorded_steps
from contopt.adjoint.saddle import AdjointOptions, static_sensitivities
from contopt.errors import ConfigError
from contopt.responses.base import Fields
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.static import State
from contopt.solve.system import System
from contopt.timing import timed

__all__ = ["AdjointOptions", "AdjointResult", "Sensitivity", "sensitivities"]


def sensitivities(
    system: System,
    state: State,
    responses,
    options: AdjointOptions | None = None,
    linear: LinearSolverOptions | None = None,
    step: int | None = None,
) -> AdjointResult:
    """Values and ``dtheta/drho`` (n_cells,) of ``responses`` at a converged ``state`` of ``system``.

    Parameters
    ----------
    system : the :class:`System` the state was solved with (same model, same discretization), or
        its Model
    state : converged :class:`State` at the full load (its ``evaluation`` is reused when present)
    responses : one :class:`Response` or a sequence of them; they share the factorizations
    options : how the saddle point of one equilibrium is solved (not used by the path adjoint)
    step : evaluate the responses at this recorded load step (an index into ``state.path``,
        ``-1`` the last; the solve must have recorded them, ``record_path=True`` where the system
        is not path dependent); default the final state. A load-path response
        (:mod:`contopt.responses.path`) reads its own steps: the solve must have recorded the path
        and stopped on its load factors (``solve_static(..., stops=r.stops, record_path=True)``)
    """
    system = System.of(system)
    responses = checked_responses(responses)
    at, k = step_state(system, state, step)
    along = any(r.stops for r in responses)  # a load-path response reads several steps
    if along and step is not None:
        raise ConfigError("step= is for responses of one state; a load-path response reads its own load steps")
    steps = recorded_steps(system, state, k) if system.path_dependent or along else ()
    options = options or AdjointOptions()
    linear = linear or LinearSolverOptions()
    seconds = {"partials": 0.0, "evaluate": 0.0, "factorize": 0.0, "solve": 0.0, "vjp": 0.0}
    with timed(seconds, "partials"):
        fields = Fields.from_state(system, at)
        if along:
            evaluated = [(r.name, r.evaluate_path(fields, gradient=True)) for r in responses]
            return path_sensitivities(system, steps, fields, path_partials(system, steps, evaluated), linear, seconds)
        evaluated = [(r.name, r.evaluate(fields, gradient=True)) for r in responses]
    if steps:
        return path_sensitivities(system, steps, fields, evaluated, linear, seconds)
    return static_sensitivities(system, at, fields, evaluated, options, linear, seconds)
