"""Check adjoint sensitivities against central finite differences of the full nonlinear solve.

For each direction ``v`` (random over the designed cells, and single cells
``e_k``) the nonlinear problem is re-solved at ``rho +- h v`` from the
converged state (warm start: same displacements and multipliers, one load
step) with tight tolerances, and ``(theta(rho + h v) - theta(rho - h v)) / 2h``
is compared with ``dtheta/drho . v``. Every response is evaluated on the
same perturbed solves, so checking several responses costs no more solves.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from contopt.adjoint.path import path_sensitivities, solve_path
from contopt.adjoint.sensitivity import AdjointOptions, AdjointResult, sensitivities
from contopt.errors import ConfigError
from contopt.responses.base import Fields, Response
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import AugmentationOptions, State, solve_static
from contopt.solve.system import System

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


def contact_cells(problem: System, cells: np.ndarray) -> np.ndarray:
    """Those of ``cells`` that own a node of a contact surface (either side)."""
    if not problem.has_contact:
        return np.zeros(0, np.int64)
    assert problem.contact is not None  # has_contact
    disc = problem.disc
    surface = np.zeros(sum(b.n_nodes for b in disc.blocks), bool)
    for block in problem.contact.blocks:
        surface[block.nm_facet_nodes.ravel()] = True
        surface[block.m_facet_nodes.ravel()] = True
    owner = np.zeros(disc.n_cells, bool)
    for i, b in enumerate(disc.blocks):
        cells_i = disc.model.bodies[i].mesh.cells + b.node_offset
        owner[b.cell_offset : b.cell_offset + b.n_cells] = surface[cells_i].any(axis=1)
    return cells[owner[cells]]


def pick_cells(
    problem: System, gradients: list[np.ndarray], cells: np.ndarray, n: int, rng: np.random.Generator
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
    near = np.intersect1d(contact_cells(problem, ok), ok)
    chosen = (
        list(near[np.argsort(-np.max([np.abs(g[near]) for g in gradients], axis=0))][: min(3, n)]) if near.size else []
    )
    rest = np.setdiff1d(ok, chosen)
    k = min(n - len(chosen), rest.size)
    chosen += list(rng.choice(rest, size=k, replace=False)) if k > 0 else []
    return [int(c) for c in chosen]


def check_gradient(
    problem,
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
) -> GradientCheck:
    """Compare adjoint sensitivities with central finite differences (see the module docstring).

    Parameters
    ----------
    problem : Model or System
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
    state : a converged state at ``rho`` solved with tight tolerances (solved here if None)
    n_steps : load steps of the first solve (default ``newton.n_steps``)
    stencil : 2 (``(f(h) - f(-h)) / 2h``) or 4 points (fourth order: allows a larger h, so the
        round-off of the converged pressures, ~1e-11 relative, is divided by less)
    """
    prob = System.of(problem)
    disc = prob.disc
    responses = (responses,) if isinstance(responses, Response) else tuple(responses)
    rho = disc.check_rho(rho)
    cells = np.arange(disc.n_cells) if cells is None else np.asarray(cells, dtype=np.int64)
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
    h_cell = 10.0 * h if h_cell is None else h_cell
    reach = max(h, h_cell) * (2 if stencil == 4 else 1)
    if not (h > 0 and h_cell > 0) or reach >= 0.5 * float(rho[cells].min()):
        raise ConfigError(
            f"h and h_cell must be positive and their reach below half the smallest rho being "
            f"perturbed, got h={h!r}, h_cell={h_cell!r}"
        )
    newton = newton or TIGHT_NEWTON
    augmentation = augmentation or TIGHT_AUGMENTATION
    rng = np.random.default_rng(seed)
    seconds = {}

    t0 = time.perf_counter()
    first = replace(newton, n_steps=n_steps) if n_steps else newton
    record = None
    if prob.has_friction:
        # path dependent: the adjoint runs back over the load steps, and every difference is a whole
        # path from the undeformed bodies with the same steps
        if state is not None:
            raise ConfigError("with friction the check solves the path itself: do not pass state=")
        state, record = solve_path(prob, rho, first, linear)
    elif state is None:
        state = solve_static(prob, rho, newton=first, linear=linear, augmentation=augmentation)
    seconds["primal"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    if record is not None:
        result = path_sensitivities(prob, record, responses, linear)
    else:
        result = sensitivities(prob, state, responses, adjoint, linear)
    seconds["adjoint"] = time.perf_counter() - t0

    directions = []
    for k in range(n_random):
        v = np.zeros(disc.n_cells)
        v[cells] = rng.standard_normal(cells.size)
        directions.append((f"random {k + 1}", v / np.abs(v).max(), h))
    for c in pick_cells(prob, [s.gradient for s in result.sensitivities], cells, n_cells, rng):
        v = np.zeros(disc.n_cells)
        v[c] = 1.0
        directions.append((f"cell {c}", v, h_cell))

    warm = replace(newton, n_steps=1)

    flips = [False]
    base = _stick_flags(record)

    def values(r):
        if record is not None:
            s, path = solve_path(prob, r, first, linear)
            flips[0] |= not np.array_equal(_stick_flags(path), base)
        else:
            s = solve_static(prob, r, newton=warm, linear=linear, augmentation=augmentation, start=state)
        fields = Fields.from_state(prob, s)
        return np.array([resp.value(fields) for resp in responses])

    t0 = time.perf_counter()
    rows = []
    for label, v, h in directions:
        flips[0] = False
        fd = (values(rho + h * v) - values(rho - h * v)) / (2.0 * h)
        if stencil == 4:
            fd2 = (values(rho + 2 * h * v) - values(rho - 2 * h * v)) / (4.0 * h)
            fd = (4.0 * fd - fd2) / 3.0
        for sens, d in zip(result.sensitivities, fd):
            a = float(sens.gradient @ v)
            # relative to the size of the summed terms: a random direction can sum +- contributions
            # to almost nothing, and the error of that sum is no larger than its terms' round-off
            terms = float(np.abs(sens.gradient * v).sum())
            rel = abs(a - d) / max(abs(a), abs(d), terms, 1e-300)
            rows.append(CheckRow(sens.name, label, a, float(d), rel, rel <= tol, kink=flips[0] and rel > tol))
    seconds["finite_differences"] = time.perf_counter() - t0
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


def _stick_flags(record) -> np.ndarray:
    """Every friction node's state at every load step of a recorded path: 0 no friction, 1 stick,
    2 slip (empty without a path)."""
    if record is None:
        return np.zeros(0, np.int8)
    codes = [
        np.where(r.friction.stick, 1, np.where(np.abs(r.friction.traction).sum(axis=1) > 0, 2, 0))
        for st in record.states
        for r in st.contact
        if r.friction is not None
    ]
    return np.concatenate(codes).astype(np.int8) if codes else np.zeros(0, np.int8)
