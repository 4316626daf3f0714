"""Gradient checks of the named cases (``contopt check-gradient CASE``).

:func:`check_case` builds a case, puts a random grey material field on its
designed body (so the check is not made at a special design), and compares
the adjoint sensitivities of the built-in responses that apply to the case
with central finite differences (:func:`contopt.adjoint.check.check_gradient`).
:func:`check_design_case` checks an optimization case's df/dx and dg/dx (the
whole chain from the design variables) the same way.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from contopt.adjoint.check import TIGHT_AUGMENTATION, TIGHT_NEWTON, GradientCheck, check_gradient
from contopt.adjoint.sensitivity import AdjointOptions
from contopt.cases.forward import FORWARD_CASES, case_options, forward_case
from contopt.cases.optimization import optimization_case
from contopt.errors import ConfigError
from contopt.optimize.multicase import design_nlp
from contopt.responses.functionals import BUILTIN, builtin
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.system import System
from contopt.timing import Stopwatch

#: the tolerances the issue sets for the two contact laws (tight primal tolerances)
DEFAULT_TOL = {"penalty": 1e-6, "alm": 1e-5, None: 1e-6}
#: the material fields a check is made at: uniform in [0.5, 1] on the designed body, or all ones
RHO_FIELDS = ("random", "full")


def case_responses(case_name: str, model, names=None) -> list:
    """The built-in responses to check on a case (default: every one that is not identically zero;
    ``stress`` only when named, over the designed body)."""
    case = FORWARD_CASES[case_name]
    if names is None:
        names = ["strain-energy", "volume-fraction"]
        if model.loads:
            names.insert(1, "compliance")
        if model.interfaces:
            names[1:1] = ["contact-force", "pressure-variance"]
        if case.pull is not None and any(i.friction is not None for i in model.interfaces):
            names.insert(1, "friction-force")
    out = []
    for name in names:
        if name not in BUILTIN:
            raise ConfigError(f"unknown response {name!r}; choose from {sorted(BUILTIN)}")
        if name in ("contact-force", "pressure-variance") and not model.interfaces:
            raise ConfigError(f"response {name!r} needs contact, and case {case_name!r} has none")
        kwargs = {"bodies": (case.design_body,)} if name in ("strain-energy", "volume-fraction", "stress") else {}
        if name == "friction-force":
            if case.pull is None:
                raise ConfigError(f"response 'friction-force' needs a direction: case {case_name!r} pulls along none")
            kwargs = {"direction": case.pull}
        out.append(builtin(name, **kwargs))
    return out


def check_case(
    name: str,
    mesh: str | None = None,
    divisions: int | None = None,
    law: str | None = None,
    responses=None,
    rho: str = "random",
    n_random: int = 1,
    n_cells: int = 5,
    h: float | None = None,
    tol: float | None = None,
    method: str = "schur-cg",
    seed: int = 0,
    linear: LinearSolverOptions | None = None,
) -> GradientCheck:
    """Gradient check of a named case (see the module docstring).

    Parameters
    ----------
    mesh : ``coarse`` | ``fine`` (die cases); divisions : cells per edge (other cases)
    law : ``alm`` | ``penalty`` (contact cases; default the case's)
    responses : built-in response names (default :func:`case_responses`)
    rho : ``"random"`` (uniform in [0.5, 1] on the designed body) or ``"full"`` (all ones)
    h : finite-difference step (default 1e-4; 1e-3 with friction)
    tol : default 1e-6 for penalty and contact-free cases, 1e-5 for ALM and friction
    """
    if name not in FORWARD_CASES:
        raise ConfigError(f"unknown case {name!r}; choose one of {sorted(FORWARD_CASES)}")
    case = FORWARD_CASES[name]
    kwargs = case_options(name, mesh, divisions, law)
    if rho not in RHO_FIELDS:
        raise ConfigError(f"rho must be one of {RHO_FIELDS}, got {rho!r}")
    model, n_steps = forward_case(name, **kwargs)
    system = System.of(model)
    disc = system.disc
    cells = np.arange(disc.n_cells)[disc.cell_slice(case.design_body)]
    field = np.ones(disc.n_cells)
    if rho == "random":
        field[cells] = np.random.default_rng(seed).uniform(0.5, 1.0, cells.size)
    law_name = model.interfaces[0].law.name if model.interfaces else None
    # through friction every difference is a whole load path, converged to ~4e-10 relative (a 1e-13
    # change of one cell moved the sliding block's contact force by that much): h = 1e-4 (1e-3 for
    # single cells) left errors up to 2e-5 from that noise, 1e-3 (1e-2) leaves < 5e-7
    rough = any(i.friction is not None for i in model.interfaces)
    h = (1e-3 if rough else 1e-4) if h is None else h
    if tol is None:
        tol = 1e-5 if rough else DEFAULT_TOL[law_name]
    return check_gradient(
        system,
        case_responses(name, model, responses),
        rho=field,
        cells=cells,
        n_random=n_random,
        n_cells=n_cells,
        h=h,
        tol=tol,
        adjoint=AdjointOptions(method=method),
        seed=seed,
        linear=linear,
        n_steps=n_steps,
    )


@dataclass(frozen=True)
class DesignGradientCheck:
    """Directional derivatives of an optimization case's objective and constraints: adjoint vs FD.

    rows : (label, adjoint, finite difference, relative error) per function and direction; the error
        is relative to ``sum_i |g_i v_i|`` (a random direction can cancel the terms to a small sum)
    """

    case: str
    rows: tuple
    tol: float
    seconds: float

    @property
    def passed(self) -> bool:
        return all(err <= self.tol for *_, err in self.rows)

    def table(self) -> str:
        width = max([34, *(len(label) for label, *_ in self.rows)])  # robust: objective[intermediate]<=bound
        lines = [f"{'function / direction':{width}s} {'adjoint':>14s} {'finite diff.':>14s} {'rel. error':>10s}"]
        for label, adj, fd, err in self.rows:
            flag = "" if err <= self.tol else "  FAIL"
            lines.append(f"{label:{width}s} {adj:14.6e} {fd:14.6e} {err:10.2e}{flag}")
        lines.append(f"tolerance {self.tol:g}: {'passed' if self.passed else 'FAILED'}")
        return "\n".join(lines)


def check_design_case(
    name: str,
    mesh: str | None = None,
    design: str | None = None,
    n_random: int = 1,
    h: float = 1e-4,
    tol: float = 1e-5,
    seed: int = 0,
    law: str | None = None,
) -> DesignGradientCheck:
    """df/dx and dg/dx of optimization case ``name`` (``contopt run``'s cases) along random directions,
    against central differences of the whole chain (design maps, nonlinear solve with tight
    tolerances, responses), at a random perturbation of the grey start; ``law``: every contact
    interface's law instead of the file's."""
    clock = Stopwatch()
    problem = optimization_case(name, design=design, mesh=mesh, law=law)
    rows = check_design_problem(problem, n_random, h, seed)
    return DesignGradientCheck(case=name, rows=rows, tol=tol, seconds=clock.seconds)


def check_design(
    problem, name: str, n_random: int = 1, h: float = 1e-4, tol: float = 1e-5, seed: int = 0
) -> DesignGradientCheck:
    """:func:`check_design_case` of a DesignProblem read elsewhere (a user's problem file, named
    ``name`` in the report): df/dx and dg/dx along ``n_random`` random directions against central
    differences of the whole chain."""
    clock = Stopwatch()
    rows = check_design_problem(problem, n_random, h, seed)
    return DesignGradientCheck(case=name, rows=rows, tol=tol, seconds=clock.seconds)


def check_design_problem(problem, n_random: int = 1, h: float = 1e-4, seed: int = 0) -> tuple:
    """``(label, adjoint, finite difference, relative error)`` rows of the objective and every
    constraint of ``problem`` (a DesignProblem) along ``n_random`` random directions at a random
    perturbation of the grey start, solved with tight tolerances from zero. A problem with load
    cases checks its combined objective; a worst case (load cases, robust) its bound and each
    case's bound row (the max itself has a kink where two cases tie)."""
    newton = replace(TIGHT_NEWTON, n_steps=problem.newton.n_steps)
    nlp = design_nlp(replace(problem, newton=newton, augmentation=TIGHT_AUGMENTATION, warm_start=False))
    rng = np.random.default_rng(seed)
    space = nlp.space  # the design's variables; the optimizer's x may append a bound (worst case, robust)
    x = nlp.start(np.clip(space.initial() + rng.uniform(-0.05, 0.05, space.n), space.lower, space.upper))
    n = len(x)
    # the optimizer's view (evaluate): with a bound (worst case, robust) its rows f_k - bound are checked
    # over the design's variables and the bound's alike (the bound enters linearly, the objective is it)
    rec = nlp.evaluate(x)
    names = ["objective", *nlp.constraint_names]
    rows = []
    for k in range(n_random):
        v = rng.normal(size=n)
        plus, minus = nlp.evaluate(x + h * v), nlp.evaluate(x - h * v)
        values = [(rec.df, plus.f, minus.f), *((rec.dg[i], plus.g[i], minus.g[i]) for i in range(len(rec.g)))]
        for label, (grad, fp, fm) in zip(names, values):
            adj, fd = float(grad @ v), (fp - fm) / (2 * h)
            size = float(np.abs(grad * v).sum()) or 1.0
            rows.append((f"{label} / random {k}", adj, fd, abs(adj - fd) / size))
    return tuple(rows)
