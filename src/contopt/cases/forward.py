"""Forward (analysis-only) examples and a runner that writes VTU + PVD per load step.

Examples
--------
``block-compression``: a cube clamped on its bottom face, its top face pushed
down by 40 % of the height with the top held laterally (barrelling, large
strain, nonuniform). ``block-twist``: the same cube, its top face rotated by
90 degrees about the vertical axis while compressed by 30 %.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from contopt import extras
from contopt.assembly.model import Body, Dirichlet, Model
from contopt.cases.die_slab import die_slab
from contopt.cases.problem_summary import as_json, model_summary
from contopt.cases.sliding_block import sliding_block
from contopt.cases.two_blocks import two_blocks
from contopt.contact.coulomb import Coulomb
from contopt.errors import ConfigError, ConvergenceError
from contopt.io.vtk import PVDSeries, write_state
from contopt.material.hyperelastic import MooneyRivlin
from contopt.mesh.generators import box
from contopt.optimize.curves import CURVES_NAME, path_entry, write_curves
from contopt.optimize.history import atomic_write_text
from contopt.optimize.report_forward import write_forward_report
from contopt.solve.curves import LoadPathRecorder
from contopt.solve.fields import state_fields
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static
from contopt.solve.system import System
from contopt.timing import Stopwatch

log = logging.getLogger(__name__)


def block_compression(
    divisions: int = 8, strain: float = 0.4, E: float = 1.0, nu: float = 0.45, size: float = 1.0
) -> Model:
    """Cube of side ``size`` clamped at z=0, top face pushed down by ``strain * size``, held laterally."""
    mesh = box((size, size, size), (divisions,) * 3)
    mat = MooneyRivlin.from_E_nu(E, nu, b_fraction=0.2)
    return Model(
        bodies=(Body("block", mesh, mat),),
        dirichlet=(
            Dirichlet("block", "zmin", "xyz", 0.0),
            Dirichlet("block", "zmax", "xyz", (0.0, 0.0, -strain * size)),
        ),
    )


def block_twist(
    divisions: int = 8,
    angle_deg: float = 90.0,
    strain: float = 0.3,
    E: float = 1.0,
    nu: float = 0.45,
    size: float = 1.0,
) -> Model:
    """Cube clamped at z=0, top face rotated by ``angle_deg`` about the cube's axis and compressed."""
    mesh = box((size, size, size), (divisions,) * 3)
    mat = MooneyRivlin.from_E_nu(E, nu, b_fraction=0.2)
    c = 0.5 * size

    def top(X, t):
        a = np.deg2rad(angle_deg) * t
        x, y = X[:, 0] - c, X[:, 1] - c
        ux = np.cos(a) * x - np.sin(a) * y - x
        uy = np.sin(a) * x + np.cos(a) * y - y
        return np.stack([ux, uy, np.full_like(ux, -strain * size * t)], axis=1)

    return Model(
        bodies=(Body("block", mesh, mat),),
        dirichlet=(Dirichlet("block", "zmin", "xyz", 0.0), Dirichlet("block", "zmax", "xyz", top)),
    )


@dataclass(frozen=True)
class ForwardCase:
    """A named model builder; ``design_body`` is the body whose material a design (or a gradient check) changes."""

    name: str
    build: Callable[..., Model]
    n_steps: int
    description: str
    design_body: str
    contact: bool = False
    #: the direction the case drags a body in (the friction force checked along it), or None
    pull: tuple | None = None


def _die_cantilever(**kw):
    return die_slab(support="right", **kw)


FORWARD_CASES = {
    "block-compression": ForwardCase(
        "block-compression",
        block_compression,
        4,
        "cube clamped at the bottom, top pushed down 40 % (barrelling)",
        "block",
    ),
    "block-twist": ForwardCase(
        "block-twist", block_twist, 6, "cube clamped at the bottom, top twisted 90 degrees and compressed 30 %", "block"
    ),
    "die-slab": ForwardCase(
        "die-slab",
        die_slab,
        6,
        "paper 7.1: stiff cylindrical die pressed 0.6 into a slab fixed at its bottom (contact)",
        "slab",
        contact=True,
    ),
    "die-cantilever": ForwardCase(
        "die-cantilever",
        _die_cantilever,
        6,
        "paper 7.2: the same die pressed into the slab fixed at x = 9 (contact)",
        "slab",
        contact=True,
    ),
    "sliding-block": ForwardCase(
        "sliding-block",
        sliding_block,
        4,
        "a block pressed onto a stiff base, then dragged 0.1 along it with Coulomb friction mu = 0.3",
        "block",
        contact=True,
        pull=(1.0, 0.0, 0.0),
    ),
    "two-blocks": ForwardCase(
        "two-blocks",
        two_blocks,
        3,
        "a stiff punch pressed 0.06 into a block with a little sliding (small contact case)",
        "block",
        contact=True,
    ),
}


def case_options(name: str, mesh: str | None = None, divisions: int | None = None, law: str | None = None) -> dict:
    """Keyword arguments for a case's builder from the command-line choices, checked against the case."""
    die = name.startswith("die-")
    kwargs: dict[str, str | int] = {}
    if mesh is not None:
        if not die:
            raise ConfigError("--mesh applies to the die cases; use --divisions for the others")
        kwargs["mesh"] = mesh
    if divisions is not None:
        if die:
            raise ConfigError("--divisions does not apply to the die cases; use --mesh coarse|fine|xl|xxl")
        kwargs["divisions"] = divisions
    if law is not None:
        if not FORWARD_CASES[name].contact:
            raise ConfigError(f"case {name!r} has no contact: --law does not apply")
        kwargs["law"] = law
    return kwargs


def forward_case(name: str, friction: float | None = None, **kwargs) -> tuple[Model, int]:
    """The case's model and load steps; ``friction``: Coulomb friction with this coefficient on
    every contact interface (replacing the case's own)."""
    if name not in FORWARD_CASES:
        raise ConfigError(f"unknown forward case {name!r}; choose one of {sorted(FORWARD_CASES)}")
    case = FORWARD_CASES[name]
    model = case.build(**kwargs)
    if friction is not None:
        if not case.contact:
            raise ConfigError(f"case {name!r} has no contact: --friction does not apply")
        model = with_friction(model, friction)
    return model, case.n_steps


def with_friction(model: Model, mu: float) -> Model:
    """The model with Coulomb friction ``mu`` (tangential penalty: its default) on every interface."""
    friction = Coulomb(mu)
    return replace(model, interfaces=tuple(replace(i, friction=friction) for i in model.interfaces))


def run_forward(
    model: Model,
    out_dir: str | Path,
    newton: NewtonOptions | None = None,
    linear: LinearSolverOptions | None = None,
    name: str = "solution",
    description: str = "",
    command: str | None = None,
) -> dict:
    """Solve a model, writing ``<name>.pvd`` and VTU files per load step into ``out_dir``.

    Returns a summary dict (also written to ``summary.json``, with ``"kind": "forward"``, the case
    ``name``, its ``description``, the ``command`` that ran it and the ``problem`` in words,
    :mod:`contopt.cases.problem_summary`). Along the way it records the
    force-displacement curves of every support, motion and contact interface (``curves.json``,
    :mod:`contopt.optimize.curves`); at the end it writes ``report.html``
    (:mod:`contopt.optimize.report_forward`, with the viz extra). If a step fails, everything
    converged so far is already on disk and the summary records the failure before the error is
    re-raised.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    system = System.of(model)
    disc = system.disc
    series = PVDSeries(out / f"{name}.pvd")
    steps = {"count": 0}
    offsets = [b.node_offset for b in disc.blocks]
    contact = system.contact if system.has_contact else None
    extra = contact.contact_fields(None, model.bodies, offsets) if contact is not None else None
    undeformed = state_fields(disc, np.zeros(disc.n_dofs), None)
    write_state(out, model.bodies, undeformed, 0.0, 0, series, extra_point_data=extra)

    recorder = LoadPathRecorder(system)

    def on_step(state):
        recorder(state)
        steps["count"] += 1
        extra = contact.contact_fields(state.contact, model.bodies, offsets) if contact is not None else None
        fields = state_fields(disc, state.u, state.rho)
        write_state(out, model.bodies, fields, state.t, steps["count"], series, extra_point_data=extra)

    clock = Stopwatch()
    summary = {
        "kind": "forward",
        "case": name,
        "description": description,
        **({"command": command} if command else {}),
        "dofs": int(disc.n_dofs),
        "free_dofs": int(disc.free.size),
        "cells": int(disc.n_cells),
        "pvd": str(series.path),
        **_problem_in_words(model, newton),
    }
    try:
        state = solve_static(system, newton=newton, linear=linear, on_step=on_step)
    except ConvergenceError as e:
        summary.update(converged=False, error=str(e), load_steps=steps["count"], seconds=clock.seconds)
        _write_results(out, summary, recorder, f"{type(e).__name__}: {e}".splitlines()[0])
        raise
    summary.update(
        converged=True,
        load_steps=steps["count"],
        newton_iterations=state.newton_iterations,
        strain_energy=disc.strain_energy(state.u, state.rho),
        seconds=clock.seconds,
        seconds_by_phase=state.seconds,
        max_displacement=float(np.abs(state.u).max()),
        alm_updates=state.alm_updates,
    )
    if contact is not None:
        lam = tuple(r.lam for r in state.contact)
        summary.update(
            contact_force=contact.total_force(state.u, lam).tolist(),
            active_nodes=[r.n_active for r in state.contact],
        )
        if any(r.friction is not None for r in state.contact):
            summary.update(friction_force=[r.friction_force.tolist() for r in state.contact])
    _write_results(out, summary, recorder)
    return summary


def _problem_in_words(model: Model, newton: NewtonOptions | None) -> dict:
    """``{"problem": the model in words}`` for the report (:mod:`contopt.cases.problem_summary`), or
    ``{}`` when a model built in Python holds what it cannot describe (logged: the solve goes on)."""
    try:
        return {"problem": as_json(model_summary(model, (newton or NewtonOptions()).n_steps))}
    except (AttributeError, TypeError, ValueError) as err:
        log.warning("the problem's summary in words is left out of the report: %s: %s", type(err).__name__, err)
        return {}


def _write_results(out: Path, summary: dict, recorder: LoadPathRecorder, error: str | None = None) -> None:
    """``summary.json``, ``curves.json`` and (with the viz extra) ``report.html`` of a forward run;
    the report is a convenience whose failure is logged."""
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2))
    write_curves(out / CURVES_NAME, "forward", [{"label": "analysis", **path_entry(recorder, error)}])
    if not extras.installed("viz"):
        log.info(extras.missing("viz", "report.html skipped: it needs"))
        return
    try:
        log.info("report: %s", write_forward_report(out))
    except Exception as err:  # the results are on disk whatever the page does
        log.warning("report.html of %s not written (%s: %s)", out, type(err).__name__, err)


def forward_lines(name: str, summary: dict) -> list[str]:
    """What the command line prints after a forward run: the solve, friction per interface, the PVD."""
    lines = [
        f"{name}: {summary['load_steps']} load steps, {summary['newton_iterations']} Newton iterations, "
        f"{summary['seconds']:.1f} s; strain energy {summary['strain_energy']:.6g}"
    ]
    for i, (f, n) in enumerate(zip(summary.get("friction_force", ()), summary.get("contact_force", ()))):
        t = float(np.linalg.norm(f))
        lines.append(f"interface {i}: normal force {n:.6g}, friction force {t:.6g} (ratio {t / n if n else 0.0:.6g})")
    lines.append(f"open {summary['pvd']} in ParaView")
    return lines
