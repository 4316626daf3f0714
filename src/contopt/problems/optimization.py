"""Named optimization cases for ``contopt run`` and the benchmarks."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from contopt.errors import ConfigError
from contopt.optimize.problem import DesignProblem
from contopt.problems.cantilever import PARAMETERIZATIONS, cantilever_problem

MESHES = {"cantilever": {"coarse": (24, 8, 4), "fine": (48, 16, 8)}}


@dataclass(frozen=True)
class OptimizationCase:
    """A named design problem: ``build(design, mesh, eta)`` returns a DesignProblem."""

    name: str
    build: Callable[..., DesignProblem]
    description: str
    designs: tuple = PARAMETERIZATIONS
    default_design: str = "density"
    meshes: tuple = ("coarse", "fine")


def _cantilever(design: str, mesh: str, eta: float | None) -> DesignProblem:
    return cantilever_problem(design, divisions=MESHES["cantilever"][mesh], **({"eta": eta} if eta else {}))


OPTIMIZATION_CASES = {
    "cantilever": OptimizationCase(
        "cantilever", _cantilever,
        "3D cantilever (no contact): minimize compliance, volume fraction 0.3 (coarse 24x8x4, fine 48x16x8)"),
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
