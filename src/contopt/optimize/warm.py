"""The warm start of a design's analysis from a design whose contact cells were stiffer: the penalty in stages.

A penalty interface's ``eps`` is fixed by the bodies' materials (``100 E*/h``), not by the design. Under a
prescribed motion a design whose cells at the contact are ``s`` times softer than the start design's
deforms alike, so the start displacement is nearly its equilibrium under a penalty ``s`` times smaller;
under the interface's own penalty, ``1/s`` times stiffer against the soft cells, the contact must close
again to a much smaller penetration. Newton's full steps then flip the active set (the tutorial pressed
0.6: the grey design, ``s`` = 0.037, from the full design's displacement stagnated at |r| ~ 1e-3 with
10 to 60 active nodes from one iteration to the next) and the analysis fell back to a solve from zero
(202 Newton iterations in 33 load steps cut to 1/100 of the path). Where such a warm start fails and the
cells are more than :data:`SOFTER` times softer, :func:`warm_solve` solves at ``s eps`` first and then raises
the penalty at most :data:`STAGE` times per solve up to ``eps``, each solve one step from the last (17 Newton
iterations there); :func:`cold_solve` does the same from zero, ``s`` measured against the full design, its first
stage :data:`FIRST` times softer still. A stage short of the last is only the next one's start: it stops at
:data:`STAGE_RTOL` and :data:`STAGE_UTOL`; the last converges to the caller's tolerances (docs/performance.md,
issue 35 §3).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from contopt.contact.interface import surface_modulus
from contopt.contact.laws import Penalty
from contopt.errors import ConvergenceError
from contopt.solve.static import State, solve_static
from contopt.solve.system import System

log = logging.getLogger(__name__)

#: the penalty grows this many times per staged solve (the tutorial pressed 0.6, its first trial design from zero
#: with FIRST 3 and loose stages: 2 and 2.5 times stiffer 58 and 57 Newton iterations; with every stage solved to the
#: tolerances 3 times 81, 2 times 73, 1.5 times 107; one jump of 27 times stagnated)
STAGE = 2.0
#: a failed warm start tries stages only where the contact cells are more than this many times softer (the grey
#: design from the full one: 27); the tutorial's first trial design at 0.6, 3.6 times softer than the grey one,
#: is no softer copy of it, and its stages failed as its one solve did
SOFTER = 10.0
#: a solve from zero starts this many times softer still than the full design's relative penalty: with less
#: penetration to resist, the soft beam wraps round the tool in fewer and easier load steps (the tutorial's first
#: trial design at 0.6: 2 load steps of 9-10 iterations against 4 of 7-13 and a failed one; 5 times did not converge)
FIRST = 3.0
#: the tolerances of a stage short of the last (NewtonOptions.rtol and utol): its state is the next stage's start
#: only, whose penalty jump puts back a residual of about 1e-3 r_ref (that trial design: 95 -> 74 iterations)
STAGE_RTOL = 1e-4
STAGE_UTOL = 1e-2
#: the smallest factor a failed stage is cut back to (its square root each time) before the solve fails
MIN_STAGE = 1.2


def one_step(newton):
    """``newton`` (NewtonOptions) as one load step from a start, without cutbacks: a shorter step from the last
    design's loaded state is no easier (the sabot's soft supports pull it back)."""
    return replace(newton, n_steps=1, min_step=1.0, max_step=1.0)


def side_cells(system: System, body: int, facet_nodes: np.ndarray) -> np.ndarray:
    """Global ids of the cells of body ``body`` with a node among ``facet_nodes`` (global node ids)."""
    disc = system.disc
    block, mesh = disc.blocks[body], system.model.bodies[body].mesh
    local = np.unique(np.asarray(facet_nodes).reshape(-1)) - block.node_offset
    return block.cell_offset + np.flatnonzero(np.isin(mesh.cells, local).any(axis=1))


def softening(system: System, rho: np.ndarray, rho_start: np.ndarray | None) -> tuple:
    """Per contact interface, how much stiffer its penalty is against the cells at the contact now than
    at the start design: ``E*(rho_start) / E*(rho)`` (>= 1 where softer now; 1 for a law other than the
    penalty, or without ``rho_start``), with ``E*`` the pair's contact modulus ``1/(1/E1 + 1/E2)`` and
    each side's modulus scaled by the median stiffness factor of the cells at its surface."""
    contact = system.contact
    if contact is None or rho_start is None:
        return ()
    out = []
    for b in contact.blocks:
        if not isinstance(b.law, Penalty):
            out.append(1.0)
            continue
        model = system.model
        sides = (
            (b.body, b.nm_facet_nodes, b.interface.nonmortar),
            (b.mortar_body, b.m_facet_nodes, b.interface.mortar),
        )
        inv_now = inv_start = 0.0
        for body, facets, surface in sides:
            modulus = surface_modulus(model, surface)
            if not np.isfinite(modulus):
                continue  # a rigid tool
            cells = side_cells(system, body, facets)
            inv_now += 1.0 / (modulus * float(np.median(rho[cells])))
            inv_start += 1.0 / (modulus * float(np.median(rho_start[cells])))
        out.append(max(1.0, inv_now / inv_start) if inv_start > 0 else 1.0)
    return tuple(out)


def staged(ratios: tuple) -> bool:
    """Whether the ``ratios`` of :func:`softening` call for penalty stages (one above :data:`SOFTER`)."""
    return max(ratios, default=1.0) > SOFTER


def warm_solve(system: System, rho: np.ndarray, start: State, solve: Callable = solve_static, **options) -> State:
    """Equilibrium at ``rho`` in one load step from ``start`` (``solve_static``'s ``options``); where that fails
    and an interface's contact cells are more than :data:`SOFTER` times softer than at ``start`` (its
    ``layout``), the penalty in stages (module docstring). The State returned holds every solve's logs (the
    failed one's too); a stage that fails raises the ConvergenceError of :func:`solve_static`. ``solve``:
    what solves (``solve_static``; the caller's, so that a test can stand in for it)."""
    try:
        return solve(system, rho, start=start, **options)
    except ConvergenceError as err:
        ratios = softening(system, rho, start.rho)
        if not staged(ratios):
            raise
        log.info("warm start did not converge, %.3g times softer at the contact: the penalty in stages", max(ratios))
        failed = tuple(err.logs)
    state = staged_solve(system, rho, start, ratios, options["newton"], solve, **options)
    return replace(state, logs=failed + state.logs)


def cold_solve(system: System, rho: np.ndarray, solve: Callable = solve_static, **options) -> State:
    """Equilibrium at ``rho`` through ``options["newton"]``'s load steps from zero, the penalty of an interface
    whose contact cells are more than :data:`SOFTER` times softer than the full design's first at the
    full design's relative stiffness (``eps`` over the ratio), then in one-step stages up to ``eps``; where a
    stage fails, the plain solve from zero after all (the State's logs hold the failed stages' first)."""
    ratios = softening(system, rho, np.ones_like(rho))
    # a frictional state depends on its path and refuses a start; a load-path response reads every step
    if not staged(ratios) or options.get("stops") or system.path_dependent:
        return solve(system, rho, **options)
    start = State(u=np.zeros(system.disc.n_dofs), laws=system.start_states())
    newton = options["newton"]
    try:
        first = tuple(r * FIRST if r > 1.0 else r for r in ratios)
        return staged_solve(system, rho, start, first, newton, solve, **(options | {"newton": one_step(newton)}))
    except ConvergenceError as err:
        log.info("the penalty stages from zero did not converge (%s): the plain solve from zero", err)
        failed = tuple(err.logs)
    state = solve(system, rho, **options)
    return replace(state, logs=failed + state.logs)


def staged_solve(
    system: System, rho: np.ndarray, start: State, ratios: tuple, first, solve: Callable = solve_static, **options
) -> State:
    """The solve from ``start`` with Newton options ``first`` at each penalty interface's ``eps`` over its ratio,
    then one step (``options["newton"]``) per stage, :data:`STAGE` times stiffer each, up to ``eps``; a stage
    that fails is tried again from the last converged one with the square root of its factor, down to
    :data:`MIN_STAGE` (then its ConvergenceError is raised, with every stage's logs)."""
    assert system.contact is not None  # a ratio above 1 comes from a penalty interface
    own = tuple(b.eps for b in system.contact.blocks)
    eps_start = start.eps if start.laws else own

    def penalties(level: float) -> tuple:
        return tuple(e_s if r <= 1.0 else e * max(1.0 / r, level) for e, e_s, r in zip(own, eps_start, ratios))

    level, factor, newton = 1.0 / max(ratios), STAGE, first
    level_done = level
    logs: list = []
    state, last = start, None
    while True:
        laws = system.start_states(state.multipliers if state.laws else (), penalties(level))
        log.info("penalty stage: eps %s", [f"{e:.3g}" for e in penalties(level)])
        try:
            stage_newton = newton if level >= 1.0 else _loose(newton)
            last = solve(system, rho, start=State(u=state.u, laws=laws), **(options | {"newton": stage_newton}))
        except ConvergenceError as err:
            logs.extend(err.logs)
            factor = math.sqrt(factor)
            if last is None or factor < MIN_STAGE:
                err.logs = logs  # every stage's, the converged ones too
                raise
            level = _next_level(level_done, factor)
            continue
        logs.extend(last.logs)
        state, level_done, newton = last, level, options["newton"]
        if level >= 1.0:
            return replace(state, logs=tuple(logs))
        level = _next_level(level, factor)


def _loose(newton):
    """``newton`` for a stage short of the last, which is only the next stage's start: converged at
    :data:`STAGE_RTOL` and :data:`STAGE_UTOL` (or the user's looser tolerances)."""
    rtol = max(newton.rtol, STAGE_RTOL)
    stall = None if newton.stall_rtol is None else max(newton.stall_rtol, rtol)
    return replace(newton, rtol=rtol, utol=max(newton.utol, STAGE_UTOL), stall_rtol=stall)


def _next_level(level: float, factor: float) -> float:
    """The next stage's penalty level after ``level`` (< 1): the remaining factor ``1/level`` in equal steps
    of at most ``factor`` (no sliver of a last stage)."""
    steps = max(1, math.ceil(-math.log(level) / math.log(factor) - 1e-9))
    return min(1.0, level * math.exp(-math.log(level) / steps))
