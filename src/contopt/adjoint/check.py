"""Check adjoint sensitivities against central finite differences of the full nonlinear solve.

For each direction ``v`` (random over the designed cells, and single cells
``e_k``) the nonlinear problem is re-solved at ``rho +- h v`` from the
converged state (warm start: same displacements and multipliers, one load
step) with tight tolerances, and ``(theta(rho + h v) - theta(rho - h v)) / 2h``
is compared with ``dtheta/drho . v``. Every response is evaluated on the
same perturbed solves, so checking several responses costs no more solves.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from contopt.adjoint.common import checked_responses
from contopt.adjoint.sensitivity import AdjointOptions, AdjointResult, sensitivities
from contopt.errors import ConfigError
from contopt.responses.base import Fields
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import AugmentationOptions, State, solve_static
from contopt.solve.system import System
from contopt.timing import timed

#: primal tolerances of a gradient check: the finite differences divide the solve error by h
TIGHT_NEWTON = NewtonOptions(rtol=1e-12)
TIGHT_AUGMENTATION = AugmentationOptions(pressure_rtol=1e-11, gap_rtol=1e-11, inexact=0.0)


@dataclass(frozen=True)
class CheckRow:
    response: str
    direction: str
    adjoint: float
    finite_difference: float
    rel_error: float
    ok: bool
    #: "kink": a perturbation of this direction flipped a friction node between stick and slip
    #: somewhere along the path; the response has a kink there and the difference is not its derivative
    kink: bool = False


@dataclass(frozen=True, eq=False)
class GradientCheck:
    """Rows of adjoint vs finite differences, the tolerance, and what it cost."""

    rows: tuple
    tol: float
    h: float
    h_cell: float
    stencil: int
    adjoint: AdjointResult = field(repr=False)
    state: State = field(repr=False)
    seconds: dict = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        return all(r.ok or r.kink for r in self.rows)

    @property
    def max_rel_error(self) -> float:
        """The largest error of the rows without a kink."""
        return max((r.rel_error for r in self.rows if not r.kink), default=0.0)

    def table(self) -> str:
        width = max([len(r.response) for r in self.rows] + [8])
        head = f"{'response':<{width}}  {'direction':<14} {'adjoint':>16} {'finite diff.':>16} {'rel. error':>10}"
        lines = [head, "-" * len(head)]
        for r in self.rows:
            flag = "  (kink: a stick/slip flip along the path)" if r.kink else "" if r.ok else "  <-- exceeds tolerance"
            lines.append(
                f"{r.response:<{width}}  {r.direction:<14} {r.adjoint:>16.9e} {r.finite_difference:>16.9e} "
                f"{r.rel_error:>10.2e}{flag}"
            )
        verdict = "PASSED" if self.passed else "FAILED"
        lines.append(
            f"{verdict}: largest relative error {self.max_rel_error:.2e} (tolerance {self.tol:.0e}, "
            f"h = {self.h:g}, {self.h_cell:g} for cells, {self.stencil}-point central differences)"
        )
        return "\n".join(lines)


def contact_cells(system: System, cells: np.ndarray) -> np.ndarray:
    """Those of ``cells`` that own a node of a contact surface (either side)."""
    if not system.has_contact:
        return np.zeros(0, np.int64)
    assert system.contact is not None  # has_contact
    disc = system.disc
    surface = np.zeros(sum(b.n_nodes for b in disc.blocks), bool)
    for block in system.contact.blocks:
        surface[block.nm_facet_nodes.ravel()] = True
        surface[block.m_facet_nodes.ravel()] = True
    owner = np.zeros(disc.n_cells, bool)
    for i, b in enumerate(disc.blocks):
        cells_i = disc.model.bodies[i].mesh.cells + b.node_offset
        owner[b.cell_offset : b.cell_offset + b.n_cells] = surface[cells_i].any(axis=1)
    return cells[owner[cells]]


def pick_cells(
    system: System, gradients: list[np.ndarray], cells: np.ndarray, n: int, rng: np.random.Generator
) -> list[int]:
    """``n`` single cells to check: up to 3 at a contact surface, the rest random.

    Only cells whose sensitivity is at least 1 % of the largest, for every
    response, qualify (a finite difference of a negligible entry measures
    round-off); where none does, the largest entries are used.
    """
    score = np.min([np.abs(g[cells]) / max(np.abs(g[cells]).max(), 1e-300) for g in gradients], axis=0)
    ok = cells[score >= 1e-2]
    if ok.size == 0:
        ok = cells[np.argsort(-score)[: max(n, 1)]]
    near = np.intersect1d(contact_cells(system, ok), ok)
    chosen = (
        list(near[np.argsort(-np.max([np.abs(g[near]) for g in gradients], axis=0))][: min(3, n)]) if near.size else []
    )
    rest = np.setdiff1d(ok, chosen)
    k = min(n - len(chosen), rest.size)
    chosen += list(rng.choice(rest, size=k, replace=False)) if k > 0 else []
    return [int(c) for c in chosen]


def check_gradient(
    model,
    responses,
    rho=None,
    cells=None,
    n_random: int = 1,
    n_cells: int = 5,
    h: float = 1e-4,
    h_cell: float | None = None,
    tol: float = 1e-5,
    newton: NewtonOptions | None = None,
    augmentation: AugmentationOptions | None = None,
    linear: LinearSolverOptions | None = None,
    adjoint: AdjointOptions | None = None,
    seed: int = 0,
    state: State | None = None,
    n_steps: int | None = None,
    stencil: int = 4,
    step: int | None = None,
) -> GradientCheck:
    """Compare adjoint sensitivities with central finite differences (see the module docstring).

    Parameters
    ----------
    model : Model or its System
    responses : Response or sequence of responses
    rho : (n_cells,) material field at which to check (default ones)
    cells : indices of the cells that may be perturbed (default all)
    n_random, n_cells : number of random directions and of single cells (:func:`pick_cells`)
    h : finite-difference step in rho along the random directions (their largest entry is 1);
        small, because a random direction moves every cell and a large step can open or close
        a contact node (a kink of the response)
    h_cell : step for single cells (default ``10 h``): one cell moves the state much less, so a
        larger step keeps the difference above the round-off of the converged solves
    tol : relative error above which a row fails; the error is relative to the largest of
        ``|adjoint|``, ``|fd|`` and ``sum_i |g_i v_i|`` (the same for a single cell)
    newton, augmentation : primal options (default: :data:`TIGHT_NEWTON`, :data:`TIGHT_AUGMENTATION`)
    state : a converged state at ``rho`` solved with tight tolerances (solved here if None; a
        path-dependent system or a ``step`` solves it here)
    n_steps : load steps of the first solve (default ``newton.n_steps``)
    stencil : 2 (``(f(h) - f(-h)) / 2h``) or 4 points (fourth order: allows a larger h, so the
        round-off of the converged pressures, ~1e-11 relative, is divided by less)
    step : check the responses at this load step of the solve (:func:`sensitivities`); every
        difference then solves the whole path with the same load steps
    """
    responses = checked_responses(responses)
    # a load-path response reads the equilibria at its load factors: every step's multipliers converged
    stops = tuple(sorted({s for r in responses for s in r.stops}))
    augmentation = augmentation or TIGHT_AUGMENTATION
    augmentation = replace(augmentation, intermediate="converge") if stops else augmentation
    # the solves' augmentation is the system's: the adjoint sees the laws the states were solved with
    system = System.of(model).with_augmentation(augmentation)
    disc = system.disc
    rho = disc.check_rho(rho)
    cells = np.arange(disc.n_cells) if cells is None else np.asarray(cells, dtype=np.int64)
    h_cell = 10.0 * h if h_cell is None else h_cell
    _check_steps(rho, cells, n_random, n_cells, h, h_cell, stencil)
    newton = newton or TIGHT_NEWTON
    paths = Paths(
        system=system,
        first=replace(newton, n_steps=n_steps) if n_steps else newton,
        warm=replace(newton, n_steps=1),
        linear=linear,
        step=step,
        stops=stops,
    )
    if paths.whole and state is not None:
        raise ConfigError(
            "with friction, a step= or a load-path response the check solves the path itself: do not pass state="
        )
    seconds: dict[str, float] = {}
    with timed(seconds, "primal"):
        state = paths.solve(rho) if state is None else state
    with timed(seconds, "adjoint"):
        result = sensitivities(system, state, responses, adjoint, linear, step=step)
    rng = np.random.default_rng(seed)
    directions = _directions(system, result, cells, n_random, n_cells, h, h_cell, rng)
    with timed(seconds, "finite_differences"):
        rows = [row for d in directions for row in _compare(paths, responses, result, state, rho, d, stencil, tol)]
    return GradientCheck(
        rows=tuple(rows),
        tol=tol,
        h=directions[0][2] if directions else h,
        h_cell=h_cell,
        stencil=stencil,
        adjoint=result,
        state=state,
        seconds=seconds,
    )


def _check_steps(rho, cells, n_random, n_cells, h, h_cell, stencil) -> None:
    """ConfigError for no direction, an unknown stencil, or steps that reach past half the smallest rho."""
    if not (
        isinstance(n_random, int)
        and isinstance(n_cells, int)
        and n_random >= 0
        and n_cells >= 0
        and n_random + n_cells >= 1
    ):
        raise ConfigError(
            f"need at least one direction: n_random={n_random!r}, n_cells={n_cells!r} (non-negative integers)"
        )
    if stencil not in (2, 4):
        raise ConfigError(f"stencil must be 2 or 4 (points of the central difference), got {stencil!r}")
    reach = max(h, h_cell) * (2 if stencil == 4 else 1)
    if not (h > 0 and h_cell > 0) or reach >= 0.5 * float(rho[cells].min()):
        raise ConfigError(
            f"h and h_cell must be positive and their reach below half the smallest rho being "
            f"perturbed, got h={h!r}, h_cell={h_cell!r}"
        )


@dataclass(frozen=True, eq=False)
class Paths:
    """How the check solves a design: the whole path from the undeformed bodies with the first solve's
    load steps where the state depends on it (friction), a response is read at a ``step`` or a
    load-path response reads the steps ending on ``stops``; else one load step warm-started from the
    converged state."""

    system: System
    first: NewtonOptions
    warm: NewtonOptions
    linear: LinearSolverOptions | None
    step: int | None
    stops: tuple = ()

    @property
    def whole(self) -> bool:
        return self.system.path_dependent or self.step is not None or bool(self.stops)

    def solve(self, rho, start: State | None = None) -> State:
        """The converged state at ``rho`` (warm-started from ``start`` unless the whole path is solved)."""
        if self.whole or start is None:
            record = None if self.step is None and not self.stops else True
            return solve_static(self.system, rho, self.first, self.linear, record_path=record, stops=self.stops)
        return solve_static(self.system, rho, self.warm, self.linear, start=start)

    def at_step(self, state: State) -> State:
        """The state the responses are read at."""
        return state if self.step is None else state.path[self.step]


def _directions(system: System, result, cells, n_random: int, n_cells: int, h: float, h_cell: float, rng) -> list:
    """``(label, direction (n_cells,), step)``: random ones over ``cells`` (largest entry 1), then single cells."""
    n = system.disc.n_cells
    directions = []
    for k in range(n_random):
        v = np.zeros(n)
        v[cells] = rng.standard_normal(cells.size)
        directions.append((f"random {k + 1}", v / np.abs(v).max(), h))
    for c in pick_cells(system, [s.gradient for s in result.sensitivities], cells, n_cells, rng):
        v = np.zeros(n)
        v[c] = 1.0
        directions.append((f"cell {c}", v, h_cell))
    return directions


def _compare(paths: Paths, responses, result, state: State, rho, direction, stencil: int, tol: float) -> list:
    """The rows of one direction: each response's adjoint derivative against its central difference."""
    label, v, h = direction
    offsets = (1, -1, 2, -2) if stencil == 4 else (1, -1)
    solved = [_values(paths, responses, state, rho + k * h * v) for k in offsets]
    f = [values for values, _ in solved]
    flips = any(not np.array_equal(flags, stick_flags(state)) for _, flags in solved)
    fd = (f[0] - f[1]) / (2.0 * h)
    if stencil == 4:
        fd = (4.0 * fd - (f[2] - f[3]) / (4.0 * h)) / 3.0
    rows = []
    for sens, d in zip(result.sensitivities, fd):
        a = float(sens.gradient @ v)
        # relative to the size of the summed terms: a random direction can sum +- contributions
        # to almost nothing, and the error of that sum is no larger than its terms' round-off
        terms = float(np.abs(sens.gradient * v).sum())
        rel = abs(a - d) / max(abs(a), abs(d), terms, 1e-300)
        rows.append(CheckRow(sens.name, label, a, float(d), rel, rel <= tol, kink=flips and rel > tol))
    return rows


def _values(paths: Paths, responses, state: State, rho) -> tuple[np.ndarray, np.ndarray]:
    """The responses' values at ``rho`` and the stick flags (:func:`stick_flags`) of its solve."""
    s = paths.solve(rho, start=state)
    if paths.step is not None and (len(s.path) != len(state.path) or s.path[paths.step].t != paths.at_step(state).t):
        raise ConfigError(
            f"the perturbed solve's load steps differ from the first one's (a cutback): step {paths.step} "
            "is not the same load; check with a smaller h or more load steps"
        )
    fields = Fields.from_state(paths.system, paths.at_step(s))
    return np.array([resp.value(fields) for resp in responses]), stick_flags(s)


def stick_flags(state: State) -> np.ndarray:
    """Every friction node's state at every recorded load step of a solve: 0 no friction, 1 stick,
    2 slip (empty without a recorded path or friction)."""
    codes = [
        np.where(r.friction.stick, 1, np.where(np.abs(r.friction.traction).sum(axis=1) > 0, 2, 0))
        for st in state.path
        for r in st.contact
        if r.friction is not None
    ]
    return np.concatenate(codes).astype(np.int8) if codes else np.zeros(0, np.int8)
