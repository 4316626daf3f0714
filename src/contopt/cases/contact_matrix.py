"""A matrix of small contact problems as users pose them, each solved and measured (issue 35 §5).

Every cell is one geometry with a soft body (neo-Hookean, E = 1, Poisson ratio ``nu``) and a tool
(E = ``ratio``, nu = 0.3), a contact law (``"penalty"`` or ``"alm"``) and the side whose surface is
nonmortar (``"soft"`` or ``"tool"``). Geometries (a few thousand dofs at most):

* ``flat-punch``: a box punch with sharp edges pressed 10 % of the block's thickness into a block.
* ``cylinder``: a deformable cylinder (axis along y) driven down at its two end faces onto a block.
* ``sphere``: a box indenter whose bottom is bent to a sphere cap, pressed into a block.
* ``partly-covered``: the rotated small block of tests/contact/test_partial_cover.py pressed into a
  larger face held rigidly; the larger body is the soft one, so ``"soft"`` makes the larger face
  nonmortar (its nodes along the small block's edges are only partly covered).
* ``seam``: a rigidly driven roller pressed into and slid across the seam of two touching blocks
  (two interfaces, one per block; the seam faces are held in x, as against each other).
* ``wrap``: a thin soft sheet clamped at both ends pushed up by a rigidly driven roller by one sheet
  thickness, so that it wraps the roller.

:func:`run_cell` solves one cell and measures it into a JSON-ready dict; :func:`run_cells` runs
cells each in a worker process with a wall-clock budget, so that no cell can hang the matrix.
"""

from __future__ import annotations

import itertools
import logging
import multiprocessing as mp
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from contopt.assembly.model import Body, Dirichlet, Model
from contopt.config import setup_jax
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import AugmentationOptions, AugmentedLagrangian, Penalty
from contopt.material import neo_hookean
from contopt.mesh.core import Mesh
from contopt.mesh.generators import box, cylinder
from contopt.timing import Stopwatch

GEOMETRIES = ("flat-punch", "cylinder", "sphere", "partly-covered", "seam", "wrap")
RATIOS = (1.0, 1e2, 1e4, 1e5)
NUS = (0.3, 0.49)
LAWS = ("penalty", "alm")
SIDES = ("soft", "tool")
#: Newton's tolerance of the matrix: the library's default, what users get (1e-12 made the seam's
#: solves stagnate at their round-off floor, measured |r| ~ 4e-8, and fail where 1e-9 converges)
RTOL = 1e-9
#: the tests' tolerance: the exchanged force and the reaction differ by about rtol times the
#: reference force, far below the 1e-8 the tests ask
TIGHT_RTOL = 1e-12
#: the augmented Lagrangian's pressure and gap tolerances (the default 1e-6 of the gap is what the
#: tests' 0.01 h bound on the penetration has a wide margin against)
ALM_RTOL = 1e-8


@dataclass(frozen=True)
class Cell:
    """One cell of the matrix."""

    geometry: str
    ratio: float
    nu: float
    law: str
    side: str

    def fields(self) -> dict:
        """The cell as the first fields of its measurement."""
        return {"geometry": self.geometry, "ratio": self.ratio, "nu": self.nu, "law": self.law, "nonmortar": self.side}

    def key(self) -> str:
        return f"{self.geometry} E{self.ratio:g} nu{self.nu:g} {self.law} nm={self.side}"


@dataclass(frozen=True)
class Problem:
    """A built cell: the model, the body held at its support (whose reactions are the force the
    interfaces transmit), the load steps, and which nonmortar nodes count for the pressure spread
    (a predicate of their reference coordinates, or None where the pressure is not uniform)."""

    model: Model
    held: str
    n_steps: int
    direction: tuple = (0.0, 0.0, 1.0)
    uniform: Callable[[np.ndarray], np.ndarray] | None = None


def grid(geometries=GEOMETRIES, ratios=RATIOS, nus=NUS, laws=LAWS, sides=SIDES) -> list[Cell]:
    return [Cell(*c) for c in itertools.product(geometries, ratios, nus, laws, sides)]


def fast_subset() -> list[Cell]:
    """A handful of cells that run in well under a minute together (tests, quick benchmark)."""
    return grid(geometries=("flat-punch", "partly-covered"), ratios=(1.0, 1e4), nus=(0.3,), sides=("soft",))


def _law(name: str):
    if name == "penalty":
        return Penalty()
    return AugmentedLagrangian(options=AugmentationOptions(pressure_rtol=ALM_RTOL, gap_rtol=ALM_RTOL))


def _interface(cell: Cell, soft: tuple, tool: tuple):
    nonmortar, mortar = (soft, tool) if cell.side == "soft" else (tool, soft)
    return ContactInterface(nonmortar=nonmortar, mortar=mortar, law=_law(cell.law))


def _materials(cell: Cell):
    return neo_hookean(1.0, cell.nu), neo_hookean(cell.ratio, 0.3)


def _roller(radius: float, length: float, n_core: int, center) -> Mesh:
    """A cylinder with its axis along y (the generator builds along z): x -> (x, -z, y) + center."""
    roller = cylinder(radius=radius, length=length, divisions=(n_core, 1, 2))
    return roller.transformed(np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]), center)


def flat_punch(cell: Cell) -> Problem:
    """Block [0, 1]^2 x [0, 0.5] clamped at its bottom (facets 0.125), punch [0.2, 0.8]^2 x
    [0.5, 0.8] (facets 0.15, its edges off the block's node lines: non-matching) pressed 0.05 by its
    top in 4 load steps."""
    soft, tool = _materials(cell)
    block = box((1.0, 1.0, 0.5), (8, 8, 3))
    punch = box((0.6, 0.6, 0.3), (4, 4, 2), origin=(0.2, 0.2, 0.5))
    model = Model(
        bodies=(Body("block", block, soft), Body("punch", punch, tool)),
        dirichlet=(Dirichlet("block", "zmin", "xyz"), Dirichlet("punch", "zmax", "xyz", (0.0, 0.0, -0.05))),
        interfaces=(_interface(cell, ("block", "zmax"), ("punch", "zmin")),),
    )

    def interior(X):  # more than one block facet (0.125) inside the punch's edges
        return np.all(np.abs(X[:, :2] - 0.5) <= 0.3 - 0.125 + 1e-9, axis=1)

    return Problem(model, "block", 4, uniform=interior)


def cylinder_on_block(cell: Cell) -> Problem:
    """A cylinder (radius 0.2, length 0.6 along y, 16-gon) touching the top of a block
    [-0.5, 0.5] x [0, 0.6] x [-0.3, 0], its end faces driven 0.03 down."""
    soft, tool = _materials(cell)
    block = box((1.0, 0.6, 0.3), (8, 4, 3), origin=(-0.5, 0.0, -0.3))
    cyl = _roller(0.2, 0.6, 4, (0.0, 0.3, 0.2))
    push = (0.0, 0.0, -0.03)
    model = Model(
        bodies=(Body("block", block, soft), Body("cyl", cyl, tool)),
        dirichlet=(
            Dirichlet("block", "zmin", "xyz"),
            Dirichlet("cyl", "zmin", "xyz", push),
            Dirichlet("cyl", "zmax", "xyz", push),
        ),
        interfaces=(_interface(cell, ("block", "zmax"), ("cyl", "outer")),),
    )
    return Problem(model, "block", 4)


def sphere_on_block(cell: Cell) -> Problem:
    """A box indenter [-0.3, 0.3]^2 x [0, 0.4] whose bottom is bent to a sphere cap of radius 0.6
    (z += R - sqrt(R^2 - x^2 - y^2), fading out towards its top) touching a block
    [-0.5, 0.5]^2 x [-0.4, 0] at one point, its top pressed 0.04 (10 % of the block)."""
    soft, tool = _materials(cell)
    block = box((1.0, 1.0, 0.4), (8, 8, 3), origin=(-0.5, -0.5, -0.4))
    ind = box((0.6, 0.6, 0.4), (6, 6, 3), origin=(-0.3, -0.3, 0.0))
    p = np.array(ind.points)
    radius = 0.6
    cap = radius - np.sqrt(radius**2 - p[:, 0] ** 2 - p[:, 1] ** 2)
    p[:, 2] += cap * (1.0 - p[:, 2] / 0.4)
    ind = Mesh(p, ind.cells, ind.node_sets, ind.facet_sets)
    model = Model(
        bodies=(Body("block", block, soft), Body("ind", ind, tool)),
        dirichlet=(Dirichlet("block", "zmin", "xyz"), Dirichlet("ind", "zmax", "xyz", (0.0, 0.0, -0.04))),
        interfaces=(_interface(cell, ("block", "zmax"), ("ind", "zmin")),),
    )
    return Problem(model, "block", 4)


def partly_covered(cell: Cell) -> Problem:
    """tests/contact/test_partial_cover.py ``_patch``: the large block (2 x 2, 5 x 5 facets on top)
    held rigidly is the soft body; the small one (0.6 x 0.6, rotated 20 degrees, non-matching), the
    tool, is pressed 0.02 into it. The large face stays flat: the pressure is uniform (a patch test)."""
    soft, tool = _materials(cell)
    big = box((2.0, 2.0, 0.5), (5, 5, 1))
    small = box((0.6, 0.6, 0.4), (3, 3, 2), origin=(-0.3, -0.3, 0.5))
    c, s = np.cos(np.deg2rad(20.0)), np.sin(np.deg2rad(20.0))
    small = small.transformed(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), [1.0, 1.0, 0.0])
    model = Model(
        bodies=(Body("big", big, soft), Body("small", small, tool)),
        dirichlet=(Dirichlet("big", "all", "xyz"), Dirichlet("small", "zmax", "xyz", (0.0, 0.0, -0.02))),
        interfaces=(_interface(cell, ("big", "zmax"), ("small", "zmin")),),
    )
    return Problem(model, "big", 1, uniform=lambda X: np.ones(len(X), bool))


def seam(cell: Cell) -> Problem:
    """Two blocks [-0.5, 0] and [0, 0.5] x [0, 0.4] x [-0.3, 0] touching at x = 0 (their seam faces
    held in x), clamped at their bottoms; a roller (radius 0.2, all nodes driven: a rigid tool)
    starting at x = -0.1 moves by (0.2, 0, -0.03): pressed in while it slides across the seam."""
    soft, tool = _materials(cell)
    left = box((0.5, 0.4, 0.3), (4, 2, 3), origin=(-0.5, 0.0, -0.3))
    right = box((0.5, 0.4, 0.3), (4, 2, 3), origin=(0.0, 0.0, -0.3))
    roller = _roller(0.2, 0.6, 4, (-0.1, 0.2, 0.2))
    model = Model(
        bodies=(Body("left", left, soft), Body("right", right, soft), Body("roller", roller, tool)),
        dirichlet=(
            Dirichlet("left", "zmin", "xyz"),
            Dirichlet("right", "zmin", "xyz"),
            Dirichlet("left", "xmax", "x"),
            Dirichlet("right", "xmin", "x"),
            Dirichlet("roller", "all", "xyz", (0.2, 0.0, -0.03)),
        ),
        interfaces=(
            _interface(cell, ("left", "zmax"), ("roller", "outer")),
            _interface(cell, ("right", "zmax"), ("roller", "outer")),
        ),
    )
    # the held body is the roller: its reactions are all the force the two interfaces transmit
    return Problem(model, "roller", 6)


def wrap(cell: Cell) -> Problem:
    """A sheet [-0.4, 0.4] x [0, 0.2] x [0, 0.05] clamped at both ends; a 24-gon roller of radius
    0.2 (all nodes driven: a rigid tool) touching its bottom pushes it up one thickness."""
    soft, tool = _materials(cell)
    sheet = box((0.8, 0.2, 0.05), (24, 2, 2), origin=(-0.4, 0.0, 0.0))
    roller = _roller(0.2, 0.4, 6, (0.0, 0.1, -0.2))
    model = Model(
        bodies=(Body("sheet", sheet, soft), Body("roller", roller, tool)),
        dirichlet=(
            Dirichlet("sheet", "xmin", "xyz"),
            Dirichlet("sheet", "xmax", "xyz"),
            Dirichlet("roller", "all", "xyz", (0.0, 0.0, 0.05)),
        ),
        interfaces=(_interface(cell, ("sheet", "zmin"), ("roller", "outer")),),
    )
    return Problem(model, "sheet", 4)


BUILDERS = {
    "flat-punch": flat_punch,
    "cylinder": cylinder_on_block,
    "sphere": sphere_on_block,
    "partly-covered": partly_covered,
    "seam": seam,
    "wrap": wrap,
}


def _iteration_counts(logs) -> dict:
    its = sum(lg.iterations for lg in logs)
    converged = sum(lg.iterations for lg in logs if lg.converged)
    return {
        "newton_iterations": int(its),
        "newton_iterations_converged": int(converged),
        "load_steps": len({round(lg.t, 12) for lg in logs}),
        "cutbacks": sum(1 for lg in logs if not lg.converged),
    }


def _spread(problem: Problem, system, state) -> float | None:
    """std/mean of the pressures of the active, fully covered nonmortar nodes that ``uniform``
    selects (over all interfaces); None where the geometry has no uniform zone or none is active."""
    if problem.uniform is None:
        return None
    points = np.concatenate([np.asarray(b.mesh.points) for b in system.model.bodies])
    pressures = []
    for block, res in zip(system.contact.blocks, state.contact):
        keep = (res.lam > 0) & (res.coverage > 0.99) & problem.uniform(points[block.nodes])
        pressures.append(res.lam[keep])
    p = np.concatenate(pressures)
    return float(p.std() / p.mean()) if p.size >= 2 else None


def _forces(problem: Problem, system, state) -> dict:
    from contopt.responses import ContactForce, Fields  # JAX: in the workers only (run_cells)

    fields = Fields.from_state(system, state)
    e = np.asarray(problem.direction)
    reaction = state.reactions[system.disc.body_slice(problem.held)].reshape(-1, 3).sum(axis=0)
    r = abs(float(reaction @ e))
    exchanged = float(ContactForce(direction=list(e)).value(fields))
    integral = float(ContactForce().value(fields))
    return {
        "reaction": r,
        "exchanged_force": exchanged,
        "pressure_integral": integral,
        "force_vs_reaction": abs(exchanged - r) / r if r > 0 else None,
        "integral_vs_reaction": abs(integral - r) / r if r > 0 else None,
    }


def run_cell(cell: Cell, rtol: float = RTOL) -> dict:
    """Solve one cell and measure it (see the module docstring); a cell that fails measures what it
    can: its error's first line, the iterations of the solves it tried, its time."""
    from contopt.solve.newton import NewtonOptions  # JAX: in the workers only (run_cells)
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    out: dict = {**cell.fields(), "converged": False, "error": ""}
    clock = Stopwatch()
    try:
        problem = BUILDERS[cell.geometry](cell)
        system = System.of(problem.model)
        assert system.contact is not None  # every cell has contact interfaces
        out["dofs"] = int(system.disc.n_dofs)
        out["rtol"] = rtol
        out["h"] = [float(b.h) for b in system.contact.blocks]
        state = solve_static(system, newton=NewtonOptions(n_steps=problem.n_steps, rtol=rtol))
    except Exception as err:  # noqa: BLE001 - every failure is a measurement of the cell
        out["wall_seconds"] = clock.seconds
        lines = str(err).splitlines() or [""]
        out["error"] = f"{type(err).__name__}: {lines[0]}"
        out["error_lines"] = len(lines)
        logs = getattr(err, "logs", None)
        if logs:
            out.update(_iteration_counts(logs))
        last = getattr(err, "last_state", None)
        out["t_reached"] = float(getattr(last, "t", 0.0)) if last is not None else 0.0
        return out
    out["wall_seconds"] = clock.seconds
    out["converged"] = True
    out.update(_iteration_counts(state.logs))
    out["alm_updates"] = int(state.alm_updates)
    out["active_nodes"] = int(sum(r.n_active for r in state.contact))
    depth = [c.max_depth / b.h for c, b in zip(state.checks, system.contact.blocks)]
    out["penetration_over_h"] = float(max(depth))
    out.update(_forces(problem, system, state))
    out["pressure_spread"] = _spread(problem, system, state)
    return out


def _worker(conn) -> None:
    """Runs the cells the parent sends until it sends None (one process for many cells: JAX is
    imported and the kernels compiled once)."""
    logging.basicConfig(level=logging.ERROR)
    warnings.simplefilter("ignore")
    setup_jax()
    while True:
        cell = conn.recv()
        if cell is None:
            return
        conn.send(run_cell(cell))


def _timed_out(cell: Cell, budget: float) -> dict:
    return {
        **cell.fields(),
        "converged": False,
        "error": f"timed out after {budget:g} s",
        "timed_out": True,
        "wall_seconds": budget,
    }


def run_cells(cells, budget: float = 300.0, on_result=None) -> list[dict]:
    """Run ``cells`` in a worker process, each within ``budget`` seconds of wall: a cell over it is
    recorded as timed out and its worker killed (the next cell gets a fresh one). ``on_result`` is
    called with each cell's dict as it comes (progress, partial output)."""
    ctx = mp.get_context("spawn")  # a forked JAX process can deadlock
    results: list[dict] = []
    proc = conn = None
    for cell in cells:
        if proc is None or not proc.is_alive():
            conn, child = ctx.Pipe()
            proc = ctx.Process(target=_worker, args=(child,), daemon=True)
            proc.start()
        assert conn is not None  # opened with the worker
        conn.send(cell)
        if conn.poll(budget):
            try:
                result = conn.recv()
            except EOFError:  # the worker died (memory, a crash): measured as a failure
                result = dict(_timed_out(cell, budget), error="worker process died", timed_out=False)
                proc = None
        else:
            proc.kill()
            proc.join()
            proc = None
            result = _timed_out(cell, budget)
        result["cell"] = cell.key()
        results.append(result)
        if on_result is not None:
            on_result(result)
    if proc is not None:
        assert conn is not None  # the worker's
        conn.send(None)
        proc.join(timeout=10)
    return results
