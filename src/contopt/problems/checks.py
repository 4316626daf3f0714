"""Gradient checks of the named cases (``contopt check-gradient CASE``).

:func:`check_case` builds a case, puts a random grey material field on its
designed body (so the check is not made at a special design), and compares
the adjoint sensitivities of the built-in responses that apply to the case
with central finite differences (:func:`contopt.adjoint.check.check_gradient`).
"""

from __future__ import annotations

import numpy as np

from contopt.adjoint.check import GradientCheck, check_gradient
from contopt.adjoint.sensitivity import AdjointOptions
from contopt.errors import ConfigError
from contopt.problems.forward import FORWARD_CASES, case_options, forward_case
from contopt.responses.functionals import BUILTIN, builtin
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.static import Problem

#: the tolerances the issue sets for the two enforcements (tight primal tolerances)
DEFAULT_TOL = {"penalty": 1e-6, "alm": 1e-5, None: 1e-6}


def case_responses(case_name: str, model, names=None) -> list:
    """The built-in responses to check on a case (default: every one that is not identically zero)."""
    case = FORWARD_CASES[case_name]
    if names is None:
        names = ["strain-energy", "volume-fraction"]
        if model.loads:
            names.insert(1, "compliance")
        if model.interfaces:
            names[1:1] = ["contact-force", "pressure-variance"]
    out = []
    for name in names:
        if name not in BUILTIN:
            raise ConfigError(f"unknown response {name!r}; choose from {sorted(BUILTIN)}")
        if name in ("contact-force", "pressure-variance") and not model.interfaces:
            raise ConfigError(f"response {name!r} needs contact, and case {case_name!r} has none")
        kwargs = {"bodies": (case.design_body,)} if name in ("strain-energy", "volume-fraction") else {}
        out.append(builtin(name, **kwargs))
    return out


def check_case(name: str, mesh: str | None = None, divisions: int | None = None, enforcement: str | None = None,
               responses=None, rho: str = "random", n_random: int = 1, n_cells: int = 5, h: float = 1e-4,
               tol: float | None = None, method: str = "schur-cg", seed: int = 0,
               linear: LinearSolverOptions | None = None) -> GradientCheck:
    """Gradient check of a named case (see the module docstring).

    Parameters
    ----------
    mesh : ``coarse`` | ``fine`` (die cases); divisions : cells per edge (other cases)
    enforcement : ``alm`` | ``penalty`` (contact cases; default the case's)
    responses : built-in response names (default :func:`case_responses`)
    rho : ``"random"`` (uniform in [0.5, 1] on the designed body) or ``"full"`` (all ones)
    tol : default 1e-6 for penalty and contact-free cases, 1e-5 for ALM
    """
    if name not in FORWARD_CASES:
        raise ConfigError(f"unknown case {name!r}; choose one of {sorted(FORWARD_CASES)}")
    case = FORWARD_CASES[name]
    kwargs = case_options(name, mesh, divisions, enforcement)
    if rho not in ("random", "full"):
        raise ConfigError(f"rho must be 'random' or 'full', got {rho!r}")
    model, n_steps = forward_case(name, **kwargs)
    prob = Problem.build(model)
    disc = prob.disc
    cells = np.arange(disc.n_cells)[disc.cell_slice(case.design_body)]
    field = np.ones(disc.n_cells)
    if rho == "random":
        field[cells] = np.random.default_rng(seed).uniform(0.5, 1.0, cells.size)
    enf = model.interfaces[0].enforcement if model.interfaces else None
    tol = DEFAULT_TOL[enf] if tol is None else tol
    return check_gradient(prob, case_responses(name, model, responses), rho=field, cells=cells, n_random=n_random,
                          n_cells=n_cells, h=h, tol=tol, adjoint=AdjointOptions(method=method), seed=seed,
                          linear=linear, n_steps=n_steps)
