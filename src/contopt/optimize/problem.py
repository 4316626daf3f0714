"""The design problem as an optimizer sees it: one primal solve per design, cached by x.

``DesignNLP.evaluate(x)`` runs the whole chain once per distinct ``x``::

    x --design.forward--> nu, rho --solve_static--> State --adjoint--> dtheta/drho --design.vjp--> df/dx

(volume loads such as inertia follow the material: the solve gets ``mass = nu``
and the adjoint's ``dtheta/dmass`` enters the vjp as ``nu_bar``).

and keeps the result, so the objective, constraints, their gradients and the
iteration callback at the same ``x`` cost nothing more. Gradients are computed
with the values (the adjoint costs a few % of the primal), which makes every
evaluation a complete record that a checkpoint can store and a resumed run can
replay. The next primal starts from the last converged displacement,
multipliers and penalty (warm start), and falls back to a cold solve from zero
with the full load stepping when the warm start does not converge.
"""

from __future__ import annotations

import logging
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from contopt.adjoint.sensitivity import AdjointOptions, sensitivities
from contopt.assembly.model import Model
from contopt.assembly.system import Discretization
from contopt.design.space import Design, DesignFields, DesignSpace
from contopt.errors import ConfigError, ContoptError, ConvergenceError, UnavailableSolverError
from contopt.optimize.base import DesignEvaluation, EvaluationFailure, IterationInfo, same_design
from contopt.optimize.load_case import check_load_cases
from contopt.optimize.warm import cold_solve, one_step, warm_solve
from contopt.responses.base import Fields, Response
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import AugmentationOptions, State, solve_static
from contopt.solve.system import System
from contopt.timing import Stopwatch, timed

log = logging.getLogger(__name__)
#: what a person waiting for the first iteration wants to see (the command line prints it)
progress_log = logging.getLogger("contopt.progress")

NORMALIZATIONS = ("full", "initial", "none")
CACHE_SIZE = 4


@dataclass(frozen=True, eq=False)
class Constraint:
    """A response kept within bounds: ``lower <= response <= upper`` (either may be None).

    The optimizer sees ``(response - upper) / scale <= 0`` and
    ``(lower - response) / scale <= 0``; ``scale`` defaults to the bound's
    magnitude (1 for a zero bound). ``case``: the load case whose analysis the response reads
    (a problem with load cases; None: every case, one row each).
    """

    response: Response
    upper: float | None = None
    lower: float | None = None
    scale: float | None = None
    case: str | None = None

    def __post_init__(self):
        if not isinstance(self.response, Response):
            raise ConfigError(f"Constraint.response must be a Response, got {type(self.response).__name__}")
        if self.upper is None and self.lower is None:
            raise ConfigError(f"constraint on {self.response.name!r} needs an upper or a lower bound")
        for key in ("upper", "lower", "scale"):
            v = getattr(self, key)
            if v is not None and not np.isfinite(float(v)):
                raise ConfigError(f"constraint on {self.response.name!r}: {key} must be finite, got {v!r}")
        if self.scale is not None and float(self.scale) <= 0:
            raise ConfigError(f"constraint on {self.response.name!r}: scale must be > 0, got {self.scale!r}")

    def rows(self) -> list[tuple[str, float, float]]:
        """``(name, sign, bound)`` per optimizer constraint ``sign (r - bound) / scale <= 0``."""
        out = []
        if self.upper is not None:
            out.append((f"{self.response.name}<={self.upper:g}", 1.0, float(self.upper)))
        if self.lower is not None:
            out.append((f"{self.response.name}>={self.lower:g}", -1.0, float(self.lower)))
        return out

    def scale_for(self, bound: float) -> float:
        return float(self.scale) if self.scale is not None else (abs(bound) or 1.0)


@dataclass(frozen=True, eq=False)
class DesignProblem:
    """What to optimize: a model, its design, an objective to minimize and constraints.

    Volume constraints (eq. 44) come from each designed body's ``volume_fraction``.

    normalize : divide the objective by ``|f^0|`` with f^0 at the full design
        ("full", the paper's ``f/|f^0|``), at the initial design ("initial"), or
        not at all ("none"); a number divides by that number
    newton, linear, augmentation : solver options of the cold solves (the first
        design, and the fall-back); warm starts use one load step
    warm_start : start each primal from the last converged one
    load_cases : :class:`~contopt.optimize.load_case.LoadCase` s, each its own supports, motions
        and loads over ``model``'s bodies and interfaces; () analyses ``model`` alone
    combine : the cases' objectives as their weighted "sum" or the "worst" (the bound formulation)
    case_workers : worker processes that analyse the load cases in parallel (1: one after the other
        in this process; :mod:`contopt.optimize.case_pool`)
    """

    model: Model | Discretization | System
    design: Design
    objective: Response
    constraints: tuple = ()
    normalize: str | float = "full"
    newton: NewtonOptions = field(default_factory=NewtonOptions)
    linear: LinearSolverOptions = field(default_factory=LinearSolverOptions)
    augmentation: AugmentationOptions = field(default_factory=AugmentationOptions)
    adjoint: AdjointOptions = field(default_factory=AdjointOptions)
    warm_start: bool = True
    load_cases: tuple = ()
    combine: str = "sum"
    case_workers: int = 1

    def __post_init__(self):
        w = self.case_workers
        if isinstance(w, bool) or not isinstance(w, int) or w < 1:
            raise ConfigError(f"case_workers must be an integer >= 1, got {w!r}")
        if not isinstance(self.design, Design):
            raise ConfigError(f"DesignProblem.design must be a Design, got {type(self.design).__name__}")
        if not isinstance(self.objective, Response):
            raise ConfigError(f"DesignProblem.objective must be a Response, got {type(self.objective).__name__}")
        cons = (self.constraints,) if isinstance(self.constraints, Constraint) else tuple(self.constraints)
        for c in cons:
            if not isinstance(c, Constraint):
                raise ConfigError(f"constraints must be Constraint(response, upper=..., lower=...), got {c!r}")
        object.__setattr__(self, "constraints", cons)
        if self.load_cases or self.combine != "sum":
            model = self.model if isinstance(self.model, Model) else System.of(self.model).disc.model
            object.__setattr__(self, "load_cases", check_load_cases(model, self.load_cases, self.combine))
        names = [c.name for c in self.load_cases]
        for c in cons:
            if c.case is not None and c.case not in names:
                raise ConfigError(f"constraint on {c.response.name!r} names load case {c.case!r}; the cases: {names}")
        n = self.normalize
        if isinstance(n, str):
            if n not in NORMALIZATIONS:
                raise ConfigError(f"normalize must be one of {NORMALIZATIONS} or a positive number, got {n!r}")
        elif not (isinstance(n, (int, float)) and np.isfinite(n) and n > 0):
            raise ConfigError(f"normalize must be one of {NORMALIZATIONS} or a positive number, got {n!r}")


@dataclass(frozen=True, eq=False)
class Record:
    """Everything one design evaluation produced (what a checkpoint stores).

    index : evaluation number (0 = first); x : (n,) the design
    f : scaled objective; g : (m,) constraints (<= 0 feasible); df (n,), dg (m, n)
    objective : unscaled objective value; responses : {constraint response name: value}
    volume_fractions : (n_parts,) per designed body
    u, multipliers, eps : the converged state (the next warm start)
    pressures : per interface, the nodal contact pressures of that state (for output)
    newton_iterations, alm_updates, newton_solves, cold : solver effort (cold: a solve from zero)
    seconds : {"primal", "adjoint", "design", "reference" (the full-design solve that normalizes f, once)}
    states : a problem with load cases: each case's converged State (not checkpointed); u ...
        pressures are then the first case's; cases : each case's :class:`~contopt.optimize.load_case.CaseStart`
        (checkpointed: its next warm start and its output)
    """

    index: int
    x: np.ndarray
    f: float
    g: np.ndarray
    df: np.ndarray
    dg: np.ndarray
    objective: float
    responses: dict
    volume_fractions: np.ndarray
    u: np.ndarray
    multipliers: tuple
    eps: tuple
    pressures: tuple
    newton_iterations: int
    alm_updates: int
    newton_solves: int
    cold: bool
    seconds: dict
    states: tuple = ()
    cases: tuple = ()

    def evaluated(self) -> DesignEvaluation:
        return DesignEvaluation(f=self.f, g=self.g, df=self.df, dg=self.dg)


@dataclass(frozen=True, eq=False)
class FailedAnalysis:
    """An analysis that failed, and what it reached (kept so that nothing computed is lost).

    design : what was analysed, in words ("the full design (...)", "design evaluation 3")
    fields : its design chain (nu, rho, phi_tilde per cell)
    error : the error; a ConvergenceError carries ``last_state``, the last converged load step
        (``t``, ``u`` and its evaluation or contact results), and ``logs``
    """

    design: str
    fields: DesignFields
    error: Exception

    @property
    def last_state(self):
        return getattr(self.error, "last_state", None)


class _StepReport:
    """Reports each converged load step of a solve on the progress log (Newton iterations, seconds)."""

    def __init__(self):
        self.clock = Stopwatch()

    def __call__(self, state: State) -> None:
        its = state.newton_iterations  # the step's own solves: on_step gets the step's logs
        progress_log.info(
            "  load step to t=%.3g: %d Newton iteration%s (%.1f s so far)",
            state.t,
            its,
            "s" * (its != 1),
            self.clock.seconds,
        )


def _first_clause(err: Exception) -> str:
    """The first sentence of an error message (for a one-line log)."""
    text = str(err)
    return text.split(". ")[0].rstrip(".")


def solve_design(
    system: System,
    pb: DesignProblem,
    augmentation: AugmentationOptions,
    stops: tuple,
    rho: np.ndarray,
    mass: np.ndarray | None,
    start: State | None,
    on_step: Callable | None = None,
) -> tuple[State, bool]:
    """Equilibrium of ``system`` at ``rho`` (n_cells,) with volume loads scaled by ``mass``: one load
    step from ``start`` (a converged State of a nearby design; None: none) when ``pb.warm_start``
    allows, else (or when that fails) from zero through ``pb.newton``'s steps and the load factors
    ``stops``; ``(state, cold)``. A pure function of its arguments: each load case keeps its own
    ``start`` (:mod:`contopt.optimize.multicase`)."""
    # a path-dependent state (friction) or a load-path response's is solved from the undeformed bodies every time
    if pb.warm_start and start is not None and not system.path_dependent and not stops:
        try:
            # one step, no cutbacks (a failure goes straight to the cold solve); the penalty in stages where
            # the contact cells are softer than the start's (contopt.optimize.warm)
            options = {"newton": one_step(pb.newton), "linear": pb.linear, "augmentation": augmentation, "mass": mass}
            state = warm_solve(system, rho, start, solve_static, **options)
            return state, False
        except ConvergenceError as err:
            log.info("warm start did not converge (%s); solving from zero", _first_clause(err))
    return cold_solve(
        system,
        rho,
        solve_static,
        newton=pb.newton,
        linear=pb.linear,
        augmentation=augmentation,
        mass=mass,
        on_step=on_step,
        stops=stops,
        record_path=True if stops else None,
    ), True


class DesignNLP:
    """A :class:`DesignProblem` in the optimizer protocol (:class:`contopt.optimize.base.NLP`).

    Parameters
    ----------
    problem : the design problem
    scale : objective scale already known (e.g. from a checkpoint); None computes it
        as ``problem.normalize`` says on first use
    on_record : called with each new :class:`Record` (the checkpoint writer)
    on_iteration : called with each :class:`IterationInfo`; returns False to stop
    replay : records of an interrupted run, answered in order without solving as
        long as the optimizer asks for the same designs
    """

    def __init__(
        self,
        problem: DesignProblem,
        scale: float | None = None,
        on_record: Callable[[Record], None] | None = None,
        on_iteration: Callable[[IterationInfo], bool] | None = None,
        replay=(),
    ):
        self.problem = problem
        self.system = System.of(problem.model)
        self.space: DesignSpace = problem.design.build(self.system.disc)
        self.n = self.space.n
        self.lower, self.upper = self.space.lower, self.space.upper
        self.constraint_names = [
            f"volume[{name}]<={p.spec.volume_fraction:g}"
            for name, p in zip(self.space.names, self.space.parts)
            if p.spec.volume_fraction is not None
        ]
        for response in self._responses():  # before any analysis: an unknown body, contact without contact
            response.check(self.system)
        # a load-path response (contopt.responses.path) reads the equilibria at its load factors:
        # every design is solved from zero through them, each step's multipliers converged
        self.stops = tuple(sorted({s for r in self._responses() for s in r.stops}))
        self.augmentation = (
            replace(problem.augmentation, intermediate="converge") if self.stops else problem.augmentation
        )
        if self.stops:
            self.system = self.system.with_augmentation(self.augmentation)
        self._rows = [(c, sign, bound) for c in problem.constraints for (_, sign, bound) in c.rows()]
        self.constraint_names += [name for c in problem.constraints for (name, _, _) in c.rows()]
        self.m = len(self.constraint_names)
        self.scale = scale
        self.on_record, self.on_iteration = on_record, on_iteration
        self.replay = list(replay)
        self._cache: OrderedDict[bytes, Record] = OrderedDict()
        self._start: State | None = None  # the next analysis' warm start
        self.records_made = 0  # evaluations solved in this session
        self.replayed = 0  # evaluations answered from the checkpoint
        self.n_evaluations = 0  # records produced overall (replayed + solved): the next index
        self.last: Record | None = None
        self.last_state: State | None = None
        self.failure: FailedAnalysis | None = None  # the last analysis that failed
        self.log: list[dict] = []  # one summary per distinct evaluation, replayed or solved, in order

    # --- the NLP protocol ---------------------------------------------------------------------------------------

    def evaluate(self, x: np.ndarray) -> DesignEvaluation:
        return self.record(x).evaluated()

    def iteration(self, info: IterationInfo) -> bool:
        return True if self.on_iteration is None else bool(self.on_iteration(info) is not False)

    def design_x(self, x: np.ndarray) -> np.ndarray:
        """The design's variables (n_design,) of the optimizer's ``x`` (n,): ``x`` itself here."""
        return x

    def case_objectives(self, rec: Record) -> dict:
        """``{load case: its objective, unscaled}`` of a record; {} for a problem without load cases."""
        return {}

    def start(self, x0: np.ndarray) -> np.ndarray:
        """The optimizer's start (n,) for the design ``x0`` (n_design,): ``x0`` itself (a problem
        with more variables than the design's appends them, :mod:`contopt.optimize.multicase`)."""
        return x0

    def realization_fields(self, fields: DesignFields) -> dict:
        """Cell fields of other realizations of the design, per body, for the output (none here)."""
        return {}

    # --- records ------------------------------------------------------------------------------------------------

    def record(self, x: np.ndarray) -> Record:
        """The evaluation at x: from the cache, from the replayed checkpoint, or solved now."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        key = x.tobytes()
        if key in self._cache:
            self._cache.move_to_end(key)
            return self._cache[key]
        rec = self._from_replay(x)
        solved = rec is None
        if rec is None:
            rec = self._solve(x)
            self.records_made += 1
            if self.on_record is not None:
                self.on_record(rec)
        self.n_evaluations = rec.index + 1
        self.log.append(
            {
                "index": rec.index,
                "newton_iterations": rec.newton_iterations,
                "alm_updates": rec.alm_updates,
                "cold": rec.cold,
                "seconds": dict(rec.seconds),
            }
        )
        self.last = rec
        # the layout of a design solved now: the next warm start stages the penalty from it (optimize.warm)
        layout = self.last_state.layout if solved and self.last_state is not None else None
        self._start = State(u=rec.u, laws=self.system.start_states(rec.multipliers, rec.eps), layout=layout)
        self._cache[key] = rec
        while len(self._cache) > CACHE_SIZE:
            self._cache.popitem(last=False)
        return rec

    def _from_replay(self, x: np.ndarray) -> Record | None:
        if not self.replay:
            return None
        rec = self.replay[0]
        if rec.index == self.n_evaluations and same_design(rec.x, x):
            self.replay.pop(0)
            self.replayed += 1
            return rec
        log.warning(
            "the optimizer asked for another design than the checkpoint's evaluation %d (%s); the remaining "
            "%d recorded evaluations are dropped and the run continues with new analyses",
            rec.index,
            f"max |x - x_recorded| = {np.max(np.abs(rec.x - x)):.2e}" if rec.x.shape == x.shape else "another size",
            len(self.replay),
        )
        self.replay.clear()
        return None

    def fields(self, x) -> DesignFields:
        return self.space.forward(x)

    def _responses(self) -> list[Response]:
        seen, out = set(), [self.problem.objective]
        for c in self.problem.constraints:
            if id(c.response) not in seen:
                seen.add(id(c.response))
                out.append(c.response)
        return out

    def solve_state(
        self, rho: np.ndarray, mass: np.ndarray | None = None, warm: bool = True, on_step: Callable | None = None
    ) -> tuple[State, bool]:
        """Equilibrium at ``rho`` (with volume loads scaled by ``mass``): warm-started from the last
        design when possible (and ``warm``); ``(state, cold)``. ``on_step``: see :func:`solve_static`."""
        return solve_design(
            self.system, self.problem, self.augmentation, self.stops, rho, mass, self._start if warm else None, on_step
        )

    def _mass(self, fields: DesignFields) -> np.ndarray | None:
        """Volume loads follow the material that is there: mass = nu (1 in bodies not designed)."""
        return fields.nu if self.system.disc.has_volume_loads else None

    def _nu_bar(self, mass_gradient) -> np.ndarray | None:
        return mass_gradient if self.system.disc.has_volume_loads else None

    def objective_scale(self) -> float | None:
        """``|f^0|`` as ``problem.normalize`` says (solving the full design once when asked);
        None for "initial" until the first design is solved."""
        if self.scale is not None:
            return self.scale
        n = self.problem.normalize
        if n == "none":
            self.scale = 1.0
        elif not isinstance(n, str):
            self.scale = float(n)
        elif n == "full":
            full = self.space.full()
            progress_log.info(
                "reference analysis: the full design, whose objective normalizes f (%d load step%s from zero)",
                self.problem.newton.n_steps,
                "s" * (self.problem.newton.n_steps != 1),
            )
            try:
                state, _ = self.solve_state(full.rho, self._mass(full), on_step=_StepReport())
            except UnavailableSolverError:
                raise  # a usage error, no design's fault
            except ContoptError as err:
                self.failure = FailedAnalysis(
                    "the full design (the reference that normalizes the objective)", full, err
                )
                raise
            self.scale = self._scale_from(self.problem.objective.value(Fields.from_state(self.system, state)), "full")
            # The first design starts from the full design's displacement, not its pressures: under a
            # prescribed motion the grey design deforms alike (its pressures are rho times smaller, and
            # starting from the full ones diverges); under loads it deforms more but Newton still
            # converges in about half the iterations of a solve from zero (die-slab coarse: 7 against
            # 48, sabot coarse: 13 against 26). A failure falls back to the cold solve as always.
            self._start = State(u=state.u, layout=state.layout)
        return self.scale

    def _scale_from(self, f0: float, where: str) -> float:
        if not np.isfinite(f0) or f0 == 0.0:
            raise ConfigError(
                f"the objective is {f0!r} at the {where} design, so it cannot be normalized by it; "
                "set normalize to 'none' or to a positive number"
            )
        return abs(float(f0))

    def _solve(self, x: np.ndarray) -> Record:
        index = self.n_evaluations
        seconds = {"primal": 0.0, "adjoint": 0.0, "design": 0.0, "reference": 0.0}
        with timed(seconds, "reference"):  # the full-design solve of normalize="full", on first use
            scale = self.objective_scale()
        with timed(seconds, "design"):
            fields = self.space.forward(x)
        with timed(seconds, "primal"):
            state, cold, adj = self._analyze(fields, index)
        seconds["primal"] -= adj.total_seconds
        seconds["adjoint"] = adj.total_seconds
        responses = self._responses()
        values = {id(r): (s.value, s.gradient, s.mass_gradient) for r, s in zip(responses, adj.sensitivities)}
        with timed(seconds, "design"):
            f_raw, f_rho, f_mass = values[id(self.problem.objective)]
            if scale is None:  # normalize="initial": this is the initial design
                scale = self.scale = self._scale_from(f_raw, "initial")
            df = self.space.vjp(fields, rho_bar=f_rho, nu_bar=self._nu_bar(f_mass)) / scale
            vf = self.space.volume_fractions(fields)
            g, dg = self._constraints(fields, vf, values)
        self.last_state = state
        return Record(
            index=index,
            x=x.copy(),
            f=f_raw / scale,
            g=g,
            df=df,
            dg=dg,
            objective=f_raw,
            responses={c.response.name: values[id(c.response)][0] for c in self.problem.constraints},
            volume_fractions=vf,
            u=state.u,
            multipliers=tuple(state.multipliers),
            eps=tuple(state.eps),
            pressures=tuple(res.lam for res in state.contact),
            newton_iterations=state.newton_iterations,
            alm_updates=state.alm_updates,
            newton_solves=sum(1 for lg in state.logs if lg.converged),
            cold=cold,
            seconds=seconds,
        )

    def _analyze(self, fields: DesignFields, index: int):
        """Primal and adjoint at a design: ``(state, cold, adjoint result)``.

        A warm-started result that is implausible (:meth:`_implausible`) is solved again from
        zero; if that confirms it, a warning says so (the state passed the contact check, so the
        bodies do not penetrate: the contact really opened).
        """
        state, cold, adj = self._primal_and_adjoint(fields, index, warm=True)
        doubt = self._implausible(state, adj)
        if doubt and not cold:
            log.info("design evaluation %d: %s after a warm start; solving from zero to confirm", index, doubt)
            state, cold, adj = self._primal_and_adjoint(fields, index, warm=False)
            doubt = self._implausible(state, adj)
        if doubt:
            log.warning(
                "design evaluation %d: %s (confirmed by a solve from zero, which passed the contact check)",
                index,
                doubt,
            )
        return state, cold, adj

    def _primal_and_adjoint(self, fields: DesignFields, index: int, warm: bool):
        pb = self.problem
        try:
            state, cold = self.solve_state(fields.rho, self._mass(fields), warm=warm)
        except UnavailableSolverError:
            raise  # a usage error, no design's fault
        except ContoptError as err:
            design = f"design evaluation {index}" + (" (the initial design)" if index == 0 else "")
            self.failure = FailedAnalysis(design, fields, err)
            raise EvaluationFailure(f"the analysis of design evaluation {index} failed: {err}") from err
        adj = sensitivities(self.system, state, self._responses(), pb.adjoint, pb.linear)
        return state, cold, adj

    def _implausible(self, state: State, adj) -> str:
        """Why a solved state is suspicious, or "": an objective of exactly 0, or the contact of an
        interface vanishing since the last design while a motion is prescribed."""
        if adj.sensitivities[0].value == 0.0:
            return "the objective is exactly 0"
        if self.last is None or not self._moves:
            return ""
        for i, (before, res) in enumerate(zip(self.last.pressures, state.contact)):
            n_before = int(np.count_nonzero(np.asarray(before) > 0))
            if n_before and res.n_active == 0:
                assert self.system.contact is not None  # the state has contact results
                label = self.system.contact.blocks[i].interface.label
                return (
                    f"the contact of interface {label} vanished ({n_before} nodes with pressure at the last "
                    "design, none now) while a motion is prescribed"
                )
        return ""

    @property
    def _moves(self) -> bool:
        """Does the model prescribe a nonzero motion?"""
        disc = self.system.disc
        return bool(np.any(disc.prescribed(1.0) != 0.0))

    def _constraints(self, fields: DesignFields, vf: np.ndarray, values: dict) -> tuple[np.ndarray, np.ndarray]:
        """``g`` (m,) and ``dg`` (m, n): volume constraints first, then the response constraints' rows."""
        g, dg = [], []
        for p, v in zip(self.space.parts, vf):
            if p.spec.volume_fraction is not None:
                g.append(v - p.spec.volume_fraction)
                dg.append(self.space.volume_gradient(fields, p))
        for c, sign, bound in self._rows:
            value, grad_rho, grad_mass = values[id(c.response)]
            s = c.scale_for(bound)
            g.append(sign * (value - bound) / s)
            dg.append(sign * self.space.vjp(fields, rho_bar=grad_rho, nu_bar=self._nu_bar(grad_mass)) / s)
        return np.array(g, dtype=np.float64), np.array(dg, dtype=np.float64).reshape(len(g), self.n)
