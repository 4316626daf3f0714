"""What a run writes of a design's state, and of each load case's.

A run directory's ``design.pvd`` and ``vtu/`` show the problem's analysis (with load cases, the first
case's, as before), its pictures too. A problem with load cases also gets, per case, ``cases/NAME/``
with that case's ``design.pvd`` and ``vtu/`` (written whenever the run's own VTU files are: every
iteration or the final one) and its pictures of the deformed bodies and the stress
(``deformed.png``, ``stress.png``), each from the case's own state of that evaluation (the
:class:`~contopt.optimize.load_case.CaseStart` its record keeps, replayed ones included).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from contopt import extras
from contopt.io.vtk import PVDSeries, write_state
from contopt.solve.fields import state_fields

if TYPE_CHECKING:
    from contopt.optimize.problem import DesignNLP
    from contopt.solve.system import System

# the driver's logger: these are steps of a run, and users and tests filter the run's messages by it
log = logging.getLogger("contopt.optimize.driver")

#: the folder of the load cases' outputs in a run directory
CASES_DIR = "cases"


def write_design_state(
    directory: Path, series: PVDSeries, nlp: DesignNLP, system: System, u: np.ndarray, fields, pressures, index: int
) -> list[Path]:
    """One VTU per body in ``directory`` of the displacement ``u`` (n_dofs,) of ``system`` at the design
    ``fields``, with the nodal contact ``pressures`` (one array per interface, may be empty), as entry
    ``index`` of ``series``; the designed bodies carry ``nu`` and ``phi`` (and the robust
    formulation's eroded and dilated ``nu``)."""
    disc = system.disc
    cell = {}
    for p in nlp.space.parts:
        cell[p.spec.body] = {"nu": fields.nu[p.cells], "phi": fields.phi_tilde[p.cells]}
    for body, extra in nlp.realization_fields(fields).items():
        cell[body].update(extra)
    point: dict = {}
    contact = system.contact if system.has_contact else None
    if contact is not None and pressures:
        point = contact.pressure_fields(pressures, disc.model.bodies, [b.node_offset for b in disc.blocks])
    return write_state(
        directory,
        disc.model.bodies,
        state_fields(disc, u, fields.rho),
        float(index),
        index,
        series,
        extra_cell_data=cell,
        extra_point_data=point,
    )


def write_case_states(out: Path, nlp: DesignNLP, x: np.ndarray, index: int, series: dict) -> list[Path]:
    """Each load case's VTU files of the iterate ``x`` (the cases its record keeps) under
    ``out/cases/NAME/`` as entry ``index``; ``series``: {case name: its PVDSeries}, filled here.
    Nothing without load cases."""
    cases = getattr(nlp, "cases", ())
    rec = nlp.record(x)
    if not cases or len(rec.cases) != len(cases):
        return []
    fields = nlp.fields(x)
    files = []
    for case, start in zip(cases, rec.cases):
        folder = out / CASES_DIR / case.name
        if case.name not in series:
            series[case.name] = PVDSeries(folder / "design.pvd")
        files += write_design_state(
            folder / "vtu", series[case.name], nlp, case.system, start.u, fields, start.pressures, index
        )
    return files


def draw_case_pictures(out: Path, nlp: DesignNLP, up: str | None) -> dict:
    """Each load case's ``deformed.png`` and ``stress.png`` from its last VTU files, {"cases/NAME/deformed":
    file relative to ``out``, ...}; like the run's pictures, a failure is logged and never ends the run."""
    cases = getattr(nlp, "cases", ())
    if not cases or not extras.installed("viz"):  # draw_pictures said what the pictures need
        return {}
    from contopt.io.render import last_vtus, render_deformed  # PyVista: only when pictures are drawn
    from contopt.io.stress_map import has_stress, render_stress

    made = {}
    for case in cases:
        folder = out / CASES_DIR / case.name
        files = last_vtus(folder)
        if not files:
            continue
        title = f"load case {case.name}"
        try:
            made[f"{CASES_DIR}/{case.name}/deformed"] = render_deformed(
                files, folder / "deformed.png", title=title, up=up
            )
            if has_stress(files):
                made[f"{CASES_DIR}/{case.name}/stress"] = render_stress(
                    files, folder / "stress.png", title=title, up=up
                )
        except Exception as err:  # a convenience: the results stay whatever the renderer does
            log.warning("pictures of load case %s not made (%s: %s)", case.name, type(err).__name__, err)
    return {key: str(Path(path).relative_to(out)) for key, path in made.items()}
