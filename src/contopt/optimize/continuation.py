"""A continuation of the Heaviside sharpness within one run (``[design] eta_continuation``).

The run is a sequence of stages, one per sharpness of
:meth:`contopt.design.maps.EtaContinuation.etas`: each stage is a fresh optimizer run (MMA's
asymptotes and move limits start again, IPOPT is entered anew) on the problem at that sharpness,
for ``every`` iterations or until the optimizer converges there; the last stage (the design's
``eta``) runs to the end. Between stages the design variables are multiplied by
``eta_old / eta_new``: the level set, and so the (intermediate) volume fraction
``H(phi) = 1/2 + 1/2 tanh(eta phi)``, is unchanged (the rescaling ``--design-from`` makes, copied
designs, :func:`contopt.design.transfer.start_design`); the robust formulation's eroded and dilated
designs, whose thresholds do not scale with eta, sharpen. The iterations are numbered on through
the stages (a stage's start is not a row of its own: the next row's effort includes it), the
analyses too, so one checkpoint holds the whole run and a resumed run replays it stage by stage.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from contopt.design.maps import EtaContinuation
from contopt.optimize.base import OptimizerResult
from contopt.optimize.history import Checkpoint
from contopt.optimize.multicase import design_nlp
from contopt.optimize.problem import DesignNLP, DesignProblem, progress_log

#: the statuses after which the next stage starts (else the run ends where the stage did)
GO_ON = ("converged", "max_iter")


def continuation(problem: DesignProblem) -> EtaContinuation | None:
    """The problem's continuation of eta, or None."""
    return getattr(problem.design, "eta_continuation", None)


def stage_problem(problem: DesignProblem, eta: float, system=None) -> DesignProblem:
    """``problem`` at the sharpness ``eta``, without the continuation; ``system``: its model, already
    built by an earlier stage (None: the problem's own)."""
    model = problem.model if system is None or problem.load_cases else system
    return replace(problem, model=model, design=problem.design.at_eta(eta))


def rescale(x: np.ndarray, eta_from: float, eta_to: float, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The design variables ``x`` made at sharpness ``eta_from`` for a Heaviside of sharpness ``eta_to``:
    the same level set in units of ``1 / eta`` (``x eta_from / eta_to``), within the bounds."""
    return np.clip(np.asarray(x, dtype=np.float64) * (eta_from / eta_to), lower, upper)


def schedule(cont: EtaContinuation, eta: float, stage_iterations: list[int]) -> list[dict]:
    """The stages as run: ``[{"eta", "first_iteration", "last_iteration"}]`` from the iterations each
    stage made (a stage's rows are the iterations after its start; the first stage's also iteration 0)."""
    etas, out, at = cont.etas(eta), [], 0
    for k, n in enumerate(stage_iterations):
        out.append({"eta": etas[k], "first_iteration": 0 if k == 0 else at + 1, "last_iteration": at + n})
        at += n
    return out


def x_scale(etas: tuple, k: int) -> float:
    """The factor on the design variables when stage ``k`` begins."""
    return etas[k - 1] / etas[k]


def next_stage(prev: DesignNLP, problem: DesignProblem, eta: float) -> DesignNLP:
    """The NLP of the next stage at ``eta``, carrying what ``prev`` holds of the run: the objective
    scale, the analyses' numbering, the checkpoint's writer, what remains to replay and the load
    cases' worker processes."""
    nlp = design_nlp(stage_problem(problem, eta, prev.system), pool=getattr(prev, "pool", None))
    nlp.scale = prev.scale
    nlp.on_record, nlp.on_iteration = prev.on_record, prev.on_iteration
    nlp.replay = prev.replay
    nlp.n_evaluations, nlp.replayed, nlp.records_made = prev.n_evaluations, prev.replayed, prev.records_made
    return nlp


def fingerprint_entry(problem: DesignProblem) -> dict:
    """The run fingerprint's entry of an eta continuation (none without one: older runs still resume)."""
    cont = continuation(problem)
    if cont is None:
        return {}
    return {"eta_continuation": {**dataclasses.asdict(cont), "eta": problem.design.heaviside.eta}}


def run_stages(
    problem: DesignProblem,
    run,
    ckpt: Checkpoint | None,
    x0: np.ndarray,
    options,
    solve: Callable[[DesignNLP, np.ndarray, object], OptimizerResult],
) -> tuple[OptimizerResult, DesignNLP]:
    """Run the optimizer stage by stage from the design ``x0`` (n_design,); ``run.nlp`` is the first
    stage's NLP, ``run.stage(nlp, eta, offset)`` is told each stage's NLP, sharpness and the iterations
    before it (the driver's bookkeeping); ``solve(nlp, x, options)`` runs the optimizer once. The
    checkpoint's ``meta.json`` lists the stages (``eta_stages``: each one's eta, first analysis and
    the iterations before it). Returns the last stage's result (its ``iterations`` the whole run's)
    and NLP."""
    cont = continuation(problem)
    assert cont is not None  # only a problem with a continuation is run by stages
    etas = cont.etas(problem.design.heaviside.eta)
    nlp, x, offset = run.nlp, np.asarray(x0, dtype=np.float64), 0
    stages: list[dict] = []
    result = None
    for k, eta in enumerate(etas):
        if k:
            nlp = next_stage(nlp, problem, eta)
            x = rescale(x, etas[k - 1], eta, nlp.space.lower, nlp.space.upper)
            progress_log.info(
                "eta raised to %g after iteration %d (design variables x %.4g)", eta, offset, etas[k - 1] / eta
            )
        run.stage(nlp, eta, offset)
        stages.append({"eta": eta, "first_analysis": nlp.n_evaluations, "after_iteration": offset})
        if ckpt is not None:
            ckpt.update_meta(eta_stages=stages)
        budget = options.max_iter - offset
        n = budget if k == len(etas) - 1 else min(cont.every, budget)
        result = solve(nlp, nlp.start(x), dataclasses.replace(options, max_iter=n))
        offset += result.iterations
        x = np.asarray(result.x, dtype=np.float64)[: nlp.space.n]  # without a bound variable
        if result.status not in GO_ON or offset >= options.max_iter:
            break
    assert result is not None  # etas is never empty
    return replace(result, iterations=offset), nlp
