"""``curves.json``: force against displacement along the load path, at the first and the last design.

An optimization solves each design warm-started in one load step, so the run itself has no load
path to show. At its end (when it draws its pictures) the driver solves the first design and the
last one again from the unloaded bodies in at least :data:`CURVE_STEPS` equal load steps and
records, per step, the reaction of every prescribed displacement and the force of every contact
interface (:class:`contopt.solve.curves.LoadPathRecorder`). ``contopt forward`` records the same
along its own solve. The file (written atomically)::

    {"kind": "optimization" | "forward",
     "curves": [{"label": "first design (iteration 0)", "design": "first", "iteration": 0,
                 "steps": 8, "complete": true,
                 "load_factor": [...], "motions": [...], "interfaces": [...]}, ...]}

``complete`` is false when the solve stopped early (``error`` says why; the steps that converged
are kept). :func:`contopt.io.plots.plot_curves` draws it as ``curves.png``.
"""

from __future__ import annotations

import json
import logging
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from contopt.errors import ContoptError
from contopt.io.files import write_atomically
from contopt.timing import Stopwatch

if TYPE_CHECKING:  # the solver (JAX) loads with the solves: reading curves.json for a report needs none
    from contopt.solve.newton import NewtonOptions

log = logging.getLogger("contopt.optimize.driver")

#: the file in a run directory
CURVES_NAME = "curves.json"
#: the fewest load steps of a curve (equal steps; a cutback adds more)
CURVE_STEPS = 8


def curve_newton(newton: NewtonOptions) -> NewtonOptions:
    """``newton`` with at least :data:`CURVE_STEPS` equal load steps that never grow, the free flight's too
    (no leap over it: the curves show the tool's whole travel)."""
    n = max(newton.n_steps, CURVE_STEPS)
    return replace(newton, n_steps=n, max_step=min(newton.max_step or 1.0, 1.0 / n), leap=False)


def record_path(system, solve) -> dict:
    """Run ``solve(on_step)`` and return its recorded curves with ``steps`` and ``complete`` (and
    ``error`` when the solve failed: the steps that converged are kept)."""
    from contopt.solve.curves import LoadPathRecorder

    recorder = LoadPathRecorder(system)
    try:
        solve(recorder)
    except ContoptError as err:
        return path_entry(recorder, f"{type(err).__name__}: {err}".splitlines()[0])
    return path_entry(recorder)


def path_entry(recorder, error: str | None = None) -> dict:
    """What a :class:`~contopt.solve.curves.LoadPathRecorder` recorded, as a curve set of ``curves.json``:
    ``complete`` (false with the ``error`` that stopped the solve), ``steps`` and the curves."""
    stop = {"error": error} if error else {}
    return {"complete": error is None, **stop, "steps": recorder.steps, **recorder.curves()}


def design_curves(nlp, x: np.ndarray, label: str, design: str, iteration: int) -> dict:
    """The curves of design ``x`` of a :class:`~contopt.optimize.problem.DesignNLP`, solved cold."""
    from contopt.solve.static import solve_static

    pb = nlp.problem
    fields = nlp.fields(x)
    mass = fields.nu if nlp.system.disc.has_volume_loads else None

    def solve(on_step):
        return solve_static(
            nlp.system,
            fields.rho,
            newton=curve_newton(pb.newton),
            linear=pb.linear,
            augmentation=pb.augmentation,
            mass=mass,
            on_step=on_step,
        )

    entry = record_path(nlp.system, solve)
    return {"label": label, "design": design, "iteration": int(iteration), **entry}


def write_curves(path: Path, kind: str, entries: list[dict], target: dict | None = None) -> Path:
    """Write ``curves.json`` (atomically); ``target``: :func:`target_curve`, drawn with the contact forces."""
    data = {"kind": kind, "curves": entries, **({"target": target} if target else {})}
    text = json.dumps(data, indent=1)
    return write_atomically(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def target_curve(response) -> dict | None:
    """The target force-displacement curve of a load-path objective (``force-target``, also negated or
    scaled), as ``{"name", "load_factor", "force"}`` lists; None when the objective has none (or reads a
    displacement or an energy, which the force curves cannot show)."""
    for r in (response, *getattr(response, "parts", ())):
        target = getattr(r, "target", None)
        if target is not None and r.stops and getattr(r, "on", "contact") in ("contact", "reaction"):  # forces
            return {"name": r.name, "load_factor": target[:, 0].tolist(), "force": target[:, 1].tolist()}
    return None


def write_design_curves(out: Path, nlp, x_last: np.ndarray, iterations: int, write: bool = True) -> Path | None:
    """Solve the first design and the last one along the load path and write ``out/curves.json``
    (``write``: this rank writes; every rank of a distributed run solves). A failure is logged and
    never ends the run."""
    clock = Stopwatch()
    try:
        entries = [
            design_curves(nlp, nlp.space.initial(), "first design (iteration 0)", "first", 0),
            design_curves(nlp, x_last, f"last design (iteration {iterations})", "last", iterations),
        ]
        target = target_curve(nlp.problem.objective)
        path = write_curves(out / CURVES_NAME, "optimization", entries, target) if write else None
    except Exception as err:  # a convenience: the results stay whatever happens here
        log.warning("%s of %s not written (%s: %s); the results are kept", CURVES_NAME, out, type(err).__name__, err)
        return None
    log.info("force-displacement curves of the first and the last design in %.1f s", clock.seconds)
    return path


def read_curves(run_dir: Path) -> dict | None:
    """``curves.json`` of a run directory, or None when it has none or it cannot be read."""
    try:
        data = json.loads((Path(run_dir) / CURVES_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and data.get("curves") else None
