"""The cantilever of the bundled ``cantilever.toml`` on other meshes and loads (tests of the optimization).

The filter radius stays two cells and the B-spline one patch per two cells, as the file's variants
keep them.
"""

from dataclasses import replace

from contopt.cases.optimization import OPTIMIZATION_CASES
from contopt.cases.spec import load_spec

LENGTHS = (3.0, 1.0, 0.5)


def cantilever_problem(design="density", divisions=(24, 8, 4), load=None, fbar=None, eta=None, normalize=None):
    """The file's problem with ``divisions`` cells, the traction ``load`` (default the file's 1e-6),
    ``fbar`` (default on), the Heaviside sharpness ``eta`` and ``normalize`` (DesignProblem's)."""
    h = min(length / n for length, n in zip(LENGTHS, divisions))
    overrides = {"bodies[0].mesh.divisions": list(divisions)}
    if design == "density":
        overrides["design.bodies[0].density.radius"] = 2 * h
    else:
        overrides["design.bodies[0].bspline.patches"] = [max(1, n // 2) for n in divisions]
    if load is not None:
        overrides["loads[0].traction"] = [0.0, -float(load), 0.0]
    if fbar is not None:
        overrides["bodies[0].fbar"] = fbar
    problem = load_spec(OPTIMIZATION_CASES["cantilever"].path, overrides, design=design, eta=eta, check=False).problem
    return problem if normalize is None else replace(problem, normalize=normalize)
