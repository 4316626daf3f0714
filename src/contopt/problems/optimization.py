"""Named optimization cases for ``contopt run`` and the benchmarks."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import Callable

from contopt.errors import ConfigError
from contopt.optimize.problem import DesignProblem
from contopt.problems.cantilever import PARAMETERIZATIONS, cantilever_problem
from contopt.problems.die_slab import die_slab_problem
from contopt.problems.sabot import sabot_problem

MESHES = {"cantilever": {"coarse": (24, 8, 4), "fine": (48, 16, 8)}}


@dataclass(frozen=True)
class OptimizationCase:
    """A named design problem: ``build(design, mesh, eta)`` returns a DesignProblem.

    optimizer : the optimizer a run uses unless told otherwise
    optimizer_options : per optimizer name, keyword arguments of its options that suit the case
        (given options on the command line or in a TOML file win)
    """

    name: str
    build: Callable[..., DesignProblem]
    description: str
    designs: tuple = PARAMETERIZATIONS
    default_design: str = "density"
    meshes: tuple = ("coarse", "fine")
    optimizer: str = "mma"
    optimizer_options: dict = field(default_factory=dict)


def _cantilever(design: str, mesh: str, eta: float | None) -> DesignProblem:
    return cantilever_problem(design, divisions=MESHES["cantilever"][mesh], **({"eta": eta} if eta else {}))


def _die(design: str, mesh: str, eta: float | None, **kw) -> DesignProblem:
    return die_slab_problem(design, mesh, eta=eta, **kw)


_DIE = "volume fraction 0.4, slab meshes coarse 23x10x8 / fine 45x20x15"
# MMA's default KKT tolerance (1e-3) stops the die problems after 3 iterations while the design still
# moves at the move limit (fully solid/void cells' variables drift without changing f, so no change rule)
_DIE_OPTIONS = {"mma": {"kkt_tol": 5e-5, "change_tol": 0.0}}
OPTIMIZATION_CASES = {
    "cantilever": OptimizationCase(
        "cantilever", _cantilever,
        "3D cantilever (no contact): minimize compliance, volume fraction 0.3 (coarse 24x8x4, fine 48x16x8)"),
    "die-slab": OptimizationCase(
        "die-slab", _die, f"paper 7.1: die pressed into a slab fixed at its bottom, maximize its strain energy; {_DIE}",
        designs=("bspline", "density"), default_design="bspline", optimizer_options=_DIE_OPTIONS),
    "die-cantilever": OptimizationCase(
        "die-cantilever", partial(_die, support="right"),
        f"paper 7.2: the die-slab problem with the slab fixed at x = 9; {_DIE}",
        designs=("bspline", "density"), default_design="bspline", optimizer_options=_DIE_OPTIONS),
    "die-slab-contact-force": OptimizationCase(
        "die-slab-contact-force", partial(_die, objective="contact-force"),
        f"paper 7.3: the die-slab problem maximizing the total contact force; {_DIE}",
        designs=("bspline",), default_design="bspline", optimizer_options=_DIE_OPTIONS),
    "sabot": OptimizationCase(
        "sabot", lambda design, mesh, eta: sabot_problem(mesh, eta=eta),
        "paper 7.4: sabot between slug and launch tube under a 10,000 g transverse acceleration, minimize "
        "compliance, volume fraction 0.5, 5-fold cyclic + reflection symmetry (coarse ~2.9k cells; fine: the "
        "paper's 10,780 / 46,816 / 13,552)",
        designs=("bspline",), default_design="bspline", optimizer="ipopt"),
}


def optimization_case(name: str, design: str | None = None, mesh: str | None = None,
                      eta: float | None = None) -> DesignProblem:
    """Build a named case; errors name the option and the allowed values."""
    if name not in OPTIMIZATION_CASES:
        raise ConfigError(f"unknown optimization case {name!r}; choose one of {sorted(OPTIMIZATION_CASES)}")
    case = OPTIMIZATION_CASES[name]
    design = design or case.default_design
    if design not in case.designs:
        raise ConfigError(f"case {name!r}: --design must be one of {case.designs}, got {design!r}")
    mesh = mesh or case.meshes[0]
    if mesh not in case.meshes:
        raise ConfigError(f"case {name!r}: --mesh must be one of {case.meshes}, got {mesh!r}")
    if eta is not None and not eta > 0:
        raise ConfigError(f"--eta must be > 0, got {eta!r}")
    return case.build(design, mesh, eta)

