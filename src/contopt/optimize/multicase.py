"""A design problem with several load cases in the optimizer protocol (:mod:`contopt.optimize.load_case`).

Every design is analysed once per case: each case is its own :class:`System` (the shared bodies,
interfaces and design cells with the case's supports, motions and loads), solved warm-started
from that case's own last converged state, which the NLP keeps explicitly per case (in the
:class:`~contopt.optimize.problem.Record` of each evaluation, ``cases``, which the checkpoint keeps:
a resumed run warm-starts each case as the uninterrupted run did), and each case's
responses get their gradients through that case's own adjoint. :func:`analyze_case` is a pure
function of the case, the design and the case's start: with ``case_workers > 1`` the cases are
analysed in worker processes (:mod:`contopt.optimize.case_pool`, the same bits as here), else one
after the other in this process; so is each case's reference analysis of ``normalize = "full"``
(:func:`reference_case`, the full design solved from zero), once, before the first evaluation.

With ``combine = "worst"`` the optimizer's variables are the design's and ``beta``, the last one
(the bound formulation, :mod:`contopt.optimize.bound`): ``f = beta`` and one constraint
``w_c f_c / s - beta <= 0`` per case.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from contopt.adjoint.sensitivity import sensitivities
from contopt.design.space import DesignFields
from contopt.errors import ConfigError, ContoptError, UnavailableSolverError
from contopt.optimize.base import DesignEvaluation, EvaluationFailure
from contopt.optimize.bound import bound_evaluation, bound_limits
from contopt.optimize.load_case import CaseStart
from contopt.optimize.problem import DesignNLP, DesignProblem, FailedAnalysis, Record, progress_log, solve_design
from contopt.responses.base import Fields, Response
from contopt.solve.static import AugmentationOptions, State
from contopt.solve.system import System
from contopt.timing import timed

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class CaseSetup:
    """What one load case's analysis needs: its ``name``, ``weight``, ``system``, the load factors
    ``stops`` its load-path responses read and the ``augmentation`` it is solved with."""

    name: str
    weight: float
    system: System
    stops: tuple
    augmentation: AugmentationOptions


def design_nlp(problem: DesignProblem, pool=None, **kw) -> DesignNLP:
    """The NLP of ``problem``: a :class:`LoadCasesNLP` (its cases analysed by ``pool``, a
    :class:`~contopt.optimize.case_pool.CasePool`, when one is given) when it has load cases, a
    :class:`contopt.optimize.robust.RobustNLP` when its design is robust, else a DesignNLP."""
    robust = getattr(problem.design, "robust", None) is not None
    if problem.load_cases and robust:
        raise ConfigError(
            "a robust design ([design] robust) with several load cases ([[load_cases]]) is not supported yet; "
            "drop one of them"
        )
    if problem.load_cases:
        return LoadCasesNLP(problem, pool=pool, **kw)
    if robust:
        from contopt.optimize.robust import RobustNLP  # which imports this module's neighbours, not it

        return RobustNLP(problem, **kw)
    return DesignNLP(problem, **kw)


def analyze_case(
    case: CaseSetup, pb: DesignProblem, responses: list, fields: DesignFields, mass, start: State | None
) -> tuple[State, bool, object]:
    """Primal and adjoint of one case at a design: ``(state, cold, adjoint result)``; warm-started from
    ``start`` (None: from zero), solved again from zero when a warm start gives an objective of exactly 0."""
    state, cold = solve_design(case.system, pb, case.augmentation, case.stops, fields.rho, mass, start)
    adj = sensitivities(case.system, state, responses, pb.adjoint, pb.linear)
    if adj.sensitivities[0].value == 0.0 and not cold:
        log.info("load case %s: the objective is exactly 0 after a warm start; solving from zero", case.name)
        state, cold = solve_design(case.system, pb, case.augmentation, case.stops, fields.rho, mass, None)
        adj = sensitivities(case.system, state, responses, pb.adjoint, pb.linear)
    return state, cold, adj


def reference_case(case: CaseSetup, pb: DesignProblem, full: DesignFields, mass) -> tuple[float, State]:
    """The full design's objective in one case (``normalize = "full"``), solved from zero, and the warm
    start it gives the case's first analysis: its displacement, not its pressures (as DesignNLP's)."""
    state, _ = solve_design(case.system, pb, case.augmentation, case.stops, full.rho, mass, None)
    return float(pb.objective.value(Fields.from_state(case.system, state))), State(u=state.u)


def case_start(case: CaseSetup, start: CaseStart) -> State:
    """The warm start of ``case`` from its :class:`CaseStart`: the displacement, the multipliers and
    the penalties (as DesignNLP's from its record), whether the record was made now or replayed."""
    return State(u=start.u, laws=case.system.start_states(start.multipliers, start.eps))


class LoadCasesNLP(DesignNLP):
    """A :class:`DesignProblem` with ``load_cases`` in the optimizer protocol (see the module docstring).

    ``n`` counts the optimizer's variables (the design's, and ``beta`` for the worst case);
    ``space.n`` the design's. :meth:`record` takes either; records are made and cached per design.
    """

    def __init__(self, problem: DesignProblem, pool=None, **kw):
        super().__init__(problem, **kw)
        self.pool = pool  # a CasePool (contopt.optimize.case_pool) that analyses the cases; None: here
        self.cases = tuple(self._setup(c) for c in problem.load_cases)
        self.system = self.cases[0].system  # outputs (VTU, pictures, curves) show the first case
        for case in self.cases:
            for response in self._responses():
                response.check(case.system)
        self.worst = problem.combine == "worst"
        names = [c.name for c in self.cases]
        self._case_rows = [
            (c, case, sign, bound)
            for c in problem.constraints
            for case in ([c.case] if c.case is not None else names)
            for (_, sign, bound) in c.rows()
        ]
        n_volume = sum(p.spec.volume_fraction is not None for p in self.space.parts)
        self.constraint_names = self.constraint_names[:n_volume]
        self.constraint_names += [
            f"{name}[{case}]"
            for c in problem.constraints
            for case in ([c.case] if c.case is not None else names)
            for (name, _, _) in c.rows()
        ]
        if self.worst:
            self.constraint_names += [f"objective[{name}]<=beta" for name in names]
        self.m = len(self.constraint_names)
        self.starts: dict[str, State | None] = dict.fromkeys(names)  # each case's next warm start
        if self.worst:  # beta's bounds are set by start(), from the start design's worst case
            self.n = self.space.n + 1
            self.lower = np.append(self.space.lower, -1.0)
            self.upper = np.append(self.space.upper, 1.0)

    def _setup(self, case) -> CaseSetup:
        system = System.of(case.model)
        if self.stops:
            system = system.with_augmentation(self.augmentation)
        return CaseSetup(case.name, float(case.weight), system, self.stops, self.augmentation)

    # --- the optimizer's variables ------------------------------------------------------------------------------

    def start(self, x0: np.ndarray) -> np.ndarray:
        """The design ``x0`` and, for the worst case, ``beta`` = its worst case (analysing it), with
        beta's bounds ten times its magnitude (at least 10) either side."""
        if not self.worst:
            return x0
        beta = self.record(x0).f
        self.lower[-1], self.upper[-1] = bound_limits(beta)
        return np.append(x0, beta)

    def design_x(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        return x[: self.space.n] if x.size == self.space.n + 1 and self.worst else x

    def case_objectives(self, rec: Record) -> dict:
        name = self.problem.objective.name
        return {c.name: rec.responses[f"{name}[{c.name}]"] for c in self.cases}

    def record(self, x: np.ndarray) -> Record:
        rec = super().record(self.design_x(x))
        if rec.cases:  # made now or replayed from the checkpoint: the same warm start for each case
            self.starts = {c.name: case_start(c, s) for c, s in zip(self.cases, rec.cases)}
        return rec

    def fields(self, x) -> DesignFields:
        return self.space.forward(self.design_x(x))

    def evaluate(self, x: np.ndarray) -> DesignEvaluation:
        rec = self.record(x)
        if not self.worst:
            return rec.evaluated()
        k = len(self.cases)  # the cases' rows w_c f_c / s come last (_constraints_of): the bound's objectives
        return bound_evaluation(rec.g[-k:], rec.dg[-k:], rec.g[:-k], rec.dg[:-k], t=float(np.asarray(x)[-1]))

    # --- analyses -----------------------------------------------------------------------------------------------

    def objective_scale(self) -> float | None:
        if self.scale is not None or self.problem.normalize != "full":
            return super().objective_scale()
        full = self.space.full()
        progress_log.info("reference analysis: the full design in each of %d load cases", len(self.cases))
        values = []
        for case, (value, start) in zip(self.cases, self._references(full)):
            values.append(value)
            self.starts[case.name] = start
        self.scale = self._scale_from(self._combined(values), "full")
        return self.scale

    def _references(self, full: DesignFields) -> list:
        """Each case's :func:`reference_case`, here or in the pool's workers (each case in its worker,
        in case order); a failed case raises as :meth:`_reference_failed` says, the first in case order."""
        if self.pool is None:
            out = []
            for case in self.cases:
                try:
                    out.append(reference_case(case, self.problem, full, self._mass(full)))
                except ContoptError as err:
                    self._reference_failed(case, err, full)
            return out
        outcomes = self.pool.reference(full, self._mass(full), len(self.cases))
        for case, outcome in zip(self.cases, outcomes):
            _emit(outcome.records)
            if isinstance(outcome.error, ContoptError):
                self._reference_failed(case, outcome.error, full)
            if outcome.error is not None:
                raise outcome.error
        return [o.result for o in outcomes]

    def _reference_failed(self, case: CaseSetup, err: ContoptError, full: DesignFields):
        """Raise ``err``, the failed reference analysis of ``case``, kept in ``failure`` unless it is
        a solver that is not there as it is (a usage error, no design's fault)."""
        if not isinstance(err, UnavailableSolverError):
            self.failure = FailedAnalysis(f"the full design in load case {case.name!r} (the reference)", full, err)
        raise err

    def _combined(self, values) -> float:
        weighted = [c.weight * float(v) for c, v in zip(self.cases, values)]
        return max(weighted) if self.worst else sum(weighted)

    def _solve(self, x: np.ndarray) -> Record:
        index = self.n_evaluations
        seconds = {"primal": 0.0, "adjoint": 0.0, "design": 0.0, "reference": 0.0}
        with timed(seconds, "reference"):
            scale = self.objective_scale()
        with timed(seconds, "design"):
            fields = self.space.forward(x)
        responses = self._responses()
        states, values, cold = [], {}, False
        for case, (state, was_cold, adj) in zip(self.cases, self._analyses(responses, fields, index, seconds)):
            seconds["primal"] -= adj.total_seconds
            seconds["adjoint"] += adj.total_seconds
            states.append(state)
            cold = cold or was_cold
            for r, s in zip(responses, adj.sensitivities):
                values[case.name, id(r)] = (s.value, s.gradient, s.mass_gradient)
        objective = self.problem.objective
        raw = [values[c.name, id(objective)][0] for c in self.cases]
        f_raw = self._combined(raw)
        with timed(seconds, "design"):
            if scale is None:  # normalize="initial": this is the initial design
                scale = self.scale = self._scale_from(f_raw, "initial")
            g, dg, per_case = self._constraints_of(fields, values, scale)
            df = per_case[int(np.argmax([v for v, _ in per_case]))][1] if self.worst else sum(d for _, d in per_case)
        first = states[0]
        responses_out = {f"{objective.name}[{c.name}]": float(v) for c, v in zip(self.cases, raw)}
        for c, name, _, _ in self._case_rows:
            responses_out[f"{c.response.name}[{name}]"] = float(values[name, id(c.response)][0])
        self.last_state = first
        return Record(
            index=index,
            x=x.copy(),
            f=f_raw / scale,
            g=g,
            df=df,
            dg=dg,
            objective=f_raw,
            responses=responses_out,
            volume_fractions=self.space.volume_fractions(fields),
            u=first.u,
            multipliers=tuple(first.multipliers),
            eps=tuple(first.eps),
            pressures=tuple(res.lam for res in first.contact),
            newton_iterations=sum(s.newton_iterations for s in states),
            alm_updates=sum(s.alm_updates for s in states),
            newton_solves=sum(1 for s in states for lg in s.logs if lg.converged),
            cold=cold,
            seconds=seconds,
            states=tuple(states),
            cases=tuple(CaseStart.of(s) for s in states),
        )

    def _analyses(self, responses: list[Response], fields: DesignFields, index: int, seconds: dict) -> list:
        """Each case's ``(state, cold, adjoint result)``, here or in the pool's workers; ``seconds["primal"]``
        gets each case's analysis (its adjoint too, which the caller moves). A failed case raises as
        :meth:`_failed` says, the first in case order."""
        starts = [self.starts.get(c.name) if self.problem.warm_start else None for c in self.cases]
        if self.pool is None:
            out = []
            for case, start in zip(self.cases, starts):
                with timed(seconds, "primal"):
                    try:
                        out.append(analyze_case(case, self.problem, responses, fields, self._mass(fields), start))
                    except ContoptError as err:
                        self._failed(case, err, fields, index)
            return out
        outcomes = self.pool.analyze(fields, self._mass(fields), starts)
        for case, outcome in zip(self.cases, outcomes):
            _emit(outcome.records)
            seconds["primal"] += outcome.seconds
            if isinstance(outcome.error, ContoptError):
                self._failed(case, outcome.error, fields, index)
            if outcome.error is not None:
                raise outcome.error
        return [o.result for o in outcomes]

    def _failed(self, case: CaseSetup, err: ContoptError, fields: DesignFields, index: int):
        """Raise for the failed analysis of ``case``: a solver that is not there as it is, any other
        error as an EvaluationFailure (the optimizer may try another design), kept in ``failure``."""
        if isinstance(err, UnavailableSolverError):
            raise err
        design = f"design evaluation {index} in load case {case.name!r}"
        self.failure = FailedAnalysis(design, fields, err)
        raise EvaluationFailure(f"the analysis of {design} failed: {err}") from err

    def _constraints_of(self, fields: DesignFields, values: dict, scale: float):
        """``g`` (m,), ``dg`` (m, space.n) without beta, and each case's ``(w_c f_c / s, its gradient)``:
        volume rows, the constraints' rows per case, and for the worst case one row per case."""
        g, dg = [], []
        for p, v in zip(self.space.parts, self.space.volume_fractions(fields)):
            if p.spec.volume_fraction is not None:
                g.append(v - p.spec.volume_fraction)
                dg.append(self.space.volume_gradient(fields, p))
        for c, name, sign, bound in self._case_rows:
            value, grad_rho, grad_mass = values[name, id(c.response)]
            s = c.scale_for(bound)
            g.append(sign * (value - bound) / s)
            dg.append(sign * self.space.vjp(fields, rho_bar=grad_rho, nu_bar=self._nu_bar(grad_mass)) / s)
        per_case = []
        for case in self.cases:
            value, grad_rho, grad_mass = values[case.name, id(self.problem.objective)]
            grad = self.space.vjp(fields, rho_bar=grad_rho, nu_bar=self._nu_bar(grad_mass))
            per_case.append((case.weight * value / scale, case.weight * grad / scale))
        if self.worst:
            g += [v for v, _ in per_case]
            dg += [d for _, d in per_case]
        n = self.space.n
        return np.array(g, dtype=np.float64), np.array(dg, dtype=np.float64).reshape(len(g), n), per_case


def _emit(records) -> None:
    """Emit the log ``records`` a worker's analysis made, as this process would have."""
    for record in records:
        if logging.getLogger(record.name).isEnabledFor(record.levelno):
            logging.getLogger(record.name).handle(record)
