"""The optimization loop: optimizer + design problem + history, checkpoints and output.

``optimize(problem, optimizer="mma"|"ipopt", out=DIR)`` runs the optimizer on
the :class:`DesignNLP` of ``problem`` and, per iteration, appends a history
row (objective, constraints, optimality, solver effort, seconds split into
primal / adjoint / design / optimizer / output, and the one full-design solve
that normalizes the objective), writes the design and state
as VTU + ``design.pvd``, redraws ``convergence.png`` and reports progress; at the end it
writes ``summary.json``, the pictures, the design's surface ``design.stl`` and ``report.html``.
``resume=True`` continues a run that was interrupted, however it stopped
(see :mod:`contopt.optimize.history`).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from contopt.errors import ConfigError
from contopt.io.plots import plot_convergence
from contopt.io.vtk import PVDSeries, write_state
from contopt.optimize.base import IterationInfo, OptimizerResult
from contopt.optimize.history import Checkpoint, atomic_write_text, read_history, write_history
from contopt.optimize.problem import DesignNLP, DesignProblem, Record

log = logging.getLogger(__name__)

OPTIMIZERS = ("mma", "ipopt")
VTU_MODES = ("every", "final", "none")
#: a cell counts as grey when its volume fraction lies strictly between these
GREY_BAND = (0.1, 0.9)


@dataclass(frozen=True)
class OutputOptions:
    """What a run writes besides the checkpoint and history.

    vtu : design and state VTU files for "every" iteration, the "final" one only, or "none"
    plot : redraw ``convergence.png`` after every iteration, and at the end draw the pictures of
        :func:`contopt.optimize.report.make_pictures` (from the final VTU, written even with vtu="none")

    A run directory always gets ``report.html`` at the end (:mod:`contopt.optimize.report_html`):
    the summary, the pictures there are and a 3D view of the final VTU (none with vtu="none" and
    plot=False).
    """

    vtu: str = "every"
    plot: bool = True

    def __post_init__(self):
        if self.vtu not in VTU_MODES:
            raise ConfigError(f"output.vtu must be one of {VTU_MODES}, got {self.vtu!r}")


@dataclass(frozen=True, eq=False)
class OptimizationResult:
    """Where the optimization ended.

    x : (n,) final design; fields : its design chain (nu, rho per cell); record : its evaluation
    history : one dict per iteration (as in ``history.json``)
    status, message : from the optimizer (see :data:`contopt.optimize.base.STATUSES`)
    iterations : optimizer iterations; analyses : design evaluations (primal + adjoint) over the whole run
    replayed : analyses of an interrupted run answered from its checkpoint (resume)
    scale : the objective scale |f^0|; out : the run directory (or None)
    """

    x: np.ndarray
    fields: object
    record: Record
    history: list
    status: str
    message: str
    iterations: int
    analyses: int
    replayed: int
    scale: float
    design_summary: list
    out: Path | None = None
    seconds: float = 0.0

    @property
    def objective(self) -> float:
        """The unscaled objective at the final design."""
        return self.record.objective

    @property
    def normalized_objective(self) -> float:
        """``f / |f^0|`` (the optimizer's objective)."""
        return self.record.f

    @property
    def volume_fractions(self) -> np.ndarray:
        return self.record.volume_fractions


def grey_fraction(space, fields) -> float:
    """Volume share of the free designed cells with ``0.1 < nu < 0.9`` (0 = black and white)."""
    lo, hi = GREY_BAND
    grey = total = 0.0
    for p in space.parts:
        free = p.fixed < 0
        nu = fields.nu[p.cells][free]
        grey += float(p.volumes[free][(nu > lo) & (nu < hi)].sum())
        total += float(p.volumes[free].sum())
    return grey / total if total > 0 else 0.0


def _run_optimizer(name: str, nlp: DesignNLP, x0: np.ndarray, options) -> OptimizerResult:
    from contopt.optimize.ipopt import run_ipopt
    from contopt.optimize.mma import run_mma

    return (run_mma if name == "mma" else run_ipopt)(nlp, x0, options)


def _resolve_options(optimizer: str, options):
    """The optimizer's options: those given (checked for the optimizer) or its defaults."""
    if optimizer not in OPTIMIZERS:
        raise ConfigError(f"optimizer must be one of {OPTIMIZERS}, got {optimizer!r}")
    from contopt.optimize.ipopt import IpoptOptions
    from contopt.optimize.mma import MMAOptions

    expected = MMAOptions if optimizer == "mma" else IpoptOptions
    if options is None:
        return expected()
    if not isinstance(options, expected):
        raise ConfigError(f"options for {optimizer!r} must be {expected.__name__}, got {type(options).__name__}")
    return options


def _fingerprint(nlp: DesignNLP, problem: DesignProblem, optimizer: str, options) -> dict:
    disc = nlp.system.disc
    opts = repr(dataclasses.replace(options, max_iter=0))  # more iterations may resume
    return json.loads(json.dumps({
        "n_design": nlp.n, "n_cells": disc.n_cells, "n_dofs": disc.n_dofs, "design": nlp.space.summary(),
        "objective": problem.objective.name, "constraints": nlp.constraint_names,
        "normalize": str(problem.normalize), "optimizer": optimizer, "options": opts,
    }))


class _Run:
    """The per-iteration bookkeeping of one :func:`optimize` call."""

    def __init__(self, nlp: DesignNLP, out: Path | None, outputs: OutputOptions, saved_rows: list,
                 progress: Callable | None, max_iter: int):
        self.nlp, self.out, self.outputs = nlp, out, outputs
        self.saved, self.progress, self.max_iter = saved_rows, progress, max_iter
        self.rows: list[dict] = []
        self.seen = 0            # evaluations accounted for in earlier rows
        self.mark = time.perf_counter()
        self.started = self.mark
        self.series = PVDSeries(out / "design.pvd") if out is not None and outputs.vtu != "none" else None

    def row(self, info: IterationInfo) -> tuple[dict, bool]:
        """The history row of an iteration, and whether it is the stored row of a replayed iteration."""
        nlp = self.nlp
        rec = nlp.record(info.x)
        new = nlp.log[self.seen:]
        self.seen = len(nlp.log)
        now = time.perf_counter()
        spent = {k: sum(e["seconds"].get(k, 0.0) for e in new) for k in ("primal", "adjoint", "design", "reference")}
        interval = now - self.mark
        row = {
            "iteration": int(info.iteration),
            "objective": float(info.f),
            "objective_raw": float(rec.objective),
            "constraints": {n: float(v) for n, v in zip(nlp.constraint_names, info.g)},
            "volume_fractions": {n: float(v) for n, v in zip(nlp.space.names, rec.volume_fractions)},
            "responses": dict(rec.responses),
            "optimality": float(info.optimality),
            "change": float(info.change),
            "evaluations": len(new),
            "analyses": nlp.n_evaluations,
            "newton_iterations": int(sum(e["newton_iterations"] for e in new)),
            "alm_updates": int(sum(e["alm_updates"] for e in new)),
            "cold_solves": int(sum(e["cold"] for e in new)),
            "seconds": {**spent, "optimizer": max(interval - sum(spent.values()), 0.0), "output": 0.0},
        }
        k = row["iteration"]
        if k < len(self.saved) and self.saved[k].get("objective") == row["objective"]:
            return self.saved[k], True  # replayed: keep the row (and its timings) of the interrupted run
        return row, False

    def __call__(self, info: IterationInfo) -> bool:
        row, replayed = self.row(info)
        t0 = time.perf_counter()
        if self.out is not None:
            if self.outputs.vtu == "every":
                self.write_vtu(info.x, row["iteration"])
            if self.outputs.plot:
                plot_convergence(self.rows + [row], self.out / "convergence.png")
        if not replayed:
            row["seconds"]["output"] = time.perf_counter() - t0
            row["seconds"]["iteration"] = sum(v for k, v in row["seconds"].items() if k != "iteration")
            row["elapsed"] = (self.rows[-1]["elapsed"] if self.rows else 0.0) + row["seconds"]["iteration"]
        self.rows.append(row)
        if self.out is not None:
            write_history(self.out, self.rows)
        if self.progress is not None:
            self.progress(row, self.eta(row["iteration"]))
        self.mark = time.perf_counter()
        return True

    def eta(self, iteration: int) -> float:
        """Seconds left if the run goes to max_iter at the mean pace of the iterations after the first."""
        done = [r["seconds"]["iteration"] for r in self.rows[1:]] or [self.rows[-1]["seconds"]["iteration"]]
        return float(np.mean(done)) * max(self.max_iter - iteration, 0)

    def write_vtu(self, x: np.ndarray, index: int) -> None:
        nlp = self.nlp
        rec = nlp.record(x)
        fields = nlp.fields(x)
        disc = nlp.system.disc
        cell = {}
        for p in nlp.space.parts:
            cell[p.spec.body] = {"nu": fields.nu[p.cells], "phi": fields.phi_tilde[p.cells]}
        point = {}
        if nlp.system.has_contact and rec.pressures:
            point = nlp.system.contact.pressure_fields(rec.pressures, disc.model.bodies,
                                                     [b.node_offset for b in disc.blocks])
        write_state(self.out / "vtu", disc, rec.u, fields.rho, float(index), index, self.series,
                    extra_cell_data=cell, extra_point_data=point)


def optimize(problem: DesignProblem, optimizer: str = "mma", options=None, out=None, resume: bool = False,
             overwrite: bool = False, outputs: OutputOptions | None = None,
             progress: Callable[[dict, float], None] | None = None) -> OptimizationResult:
    """Optimize ``problem`` from the all-grey design.

    Parameters
    ----------
    optimizer : "mma" or "ipopt"; options : MMAOptions / IpoptOptions (defaults if None)
    out : run directory (checkpoint, history, VTU, plots, summary.json); None keeps everything in memory
    resume : continue the run in ``out`` (same problem and options; max_iter may grow)
    overwrite : start afresh in an ``out`` that holds another run
    progress : called after every iteration with (history row, estimated seconds left)
    """
    options = _resolve_options(optimizer, options)
    outputs = outputs or OutputOptions()
    if resume and out is None:
        raise ConfigError("resume needs the run directory (out=...)")
    started = time.perf_counter()
    nlp = DesignNLP(problem)
    meta, records, saved = {}, [], []
    ckpt = None
    if out is not None:
        out = Path(out)
        ckpt = Checkpoint(out)
        meta = ckpt.start(_fingerprint(nlp, problem, optimizer, options), resume, overwrite)
        if not resume:
            _clear_outputs(out)
        if resume:
            records, saved = ckpt.records(), read_history(out)
            log.info("resuming %s: %d recorded evaluations, %d iterations", out, len(records), len(saved))
        nlp.scale = meta.get("scale")
        nlp.replay = records

        def on_record(rec: Record):
            if "scale" not in meta:  # before the record: a replayed record needs the scale it was made with
                meta["scale"] = nlp.scale
                ckpt.update_meta(scale=nlp.scale)
            ckpt.save(rec)

        nlp.on_record = on_record
    run = _Run(nlp, out, outputs, saved, progress, options.max_iter)
    nlp.on_iteration = run
    result = _run_optimizer(optimizer, nlp, nlp.space.initial(), options)
    rec = nlp.record(result.x)
    fields = nlp.fields(result.x)
    pictures = out is not None and outputs.plot
    if out is not None and (outputs.vtu == "final" or (pictures and outputs.vtu == "none")):
        if run.series is None:  # vtu="none": the pictures are drawn from the final VTU
            run.series = PVDSeries(out / "design.pvd")
        run.write_vtu(result.x, result.iterations)
    res = OptimizationResult(x=result.x, fields=fields, record=rec, history=run.rows, status=result.status,
                             message=result.message, iterations=result.iterations, analyses=nlp.n_evaluations,
                             replayed=nlp.replayed, scale=float(nlp.scale), design_summary=nlp.space.summary(),
                             out=out, seconds=time.perf_counter() - started)
    if out is not None:
        data = summary(res, nlp, optimizer)
        if pictures:
            data["pictures"] = _pictures(out)
            data["surface"] = _design_surface(out, nlp, result.x)
        atomic_write_text(out / "summary.json", json.dumps(data, indent=1))
        _report_page(out)
    log.info("optimization %s after %d iterations (%d analyses): objective %.6g", result.status,
             result.iterations, nlp.n_evaluations, rec.f)
    return res


#: what a run writes besides its checkpoint (removed when a fresh run starts in the directory)
OUTPUTS = ("vtu", "design.pvd", "history.json", "history.csv", "convergence.png", "summary.json",
           "design.png", "deformed.png", "pressure_history.png", "report.html", "design.stl")
#: the surface of the final design (``design_<body>.stl`` per body when several are designed)
SURFACE_FILE = "design.stl"


def _report_page(out: Path) -> None:
    """``report.html`` of the finished run; a failure is logged and never ends the run."""
    from contopt.optimize.report_html import write_report_html

    try:
        write_report_html(out)
    except Exception as err:  # like the pictures: a convenience, the results stay whatever happens here
        log.warning("report.html of %s not written (%s: %s); the results are kept", out, type(err).__name__, err)


def _pictures(out: Path) -> dict:
    """The run's pictures ({key: file relative to ``out``}); a failure is logged and never ends the run."""
    from contopt.optimize.report import make_pictures

    try:
        made = make_pictures(out)
    except Exception as err:  # a picture is a convenience: the results stay whatever the renderer does
        log.warning("pictures of %s not made (%s: %s); the results are kept", out, type(err).__name__, err)
        return {}
    return {key: str(Path(path).relative_to(out)) for key, path in made.items()}


def _design_surface(out: Path, nlp: DesignNLP, x: np.ndarray) -> dict:
    """Write the final design's surface (:mod:`contopt.design.surface`); {body: its numbers and file}.

    Like the pictures, a failure is logged and never ends the run.
    """
    from contopt.design.surface import write_design_surfaces

    try:
        made = write_design_surfaces(nlp.space, x, nlp.system.disc, out / SURFACE_FILE)
    except Exception as err:  # a convenience: the results stay whatever the surface extraction does
        log.warning("design surface of %s not made (%s: %s); the results are kept", out, type(err).__name__, err)
        return {}
    for m, path in made:
        log.info("design surface %s: %s", path, m.line())
    return {m.body: {**m.summary(), "file": str(Path(path).relative_to(out))} for m, path in made}


def _clear_outputs(out: Path) -> None:
    for path in out.glob("design_*.stl"):
        path.unlink()
    for name in OUTPUTS:
        path = out / name
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()


def summary(res: OptimizationResult, nlp: DesignNLP, optimizer: str) -> dict:
    """The numbers a person (or a table) wants from a finished run."""
    rows = res.history
    mean = {k: float(np.mean([r["seconds"][k] for r in rows[1:]])) if len(rows) > 1 else float("nan")
            for k in ("primal", "adjoint", "design", "optimizer", "output", "iteration")}
    return {
        "optimizer": optimizer,
        "status": res.status,
        "message": res.message,
        "iterations": res.iterations,
        "analyses": res.analyses,
        "replayed": res.replayed,
        "objective": res.objective,
        "normalized_objective": res.normalized_objective,
        "objective_scale": res.scale,
        "normalize": str(nlp.problem.normalize),
        "volume_fraction": (float(res.volume_fractions[0]) if len(res.volume_fractions) == 1
                            else [float(v) for v in res.volume_fractions]),
        "volume_fractions": {n: float(v) for n, v in zip(nlp.space.names, res.volume_fractions)},
        "constraints": {n: float(v) for n, v in zip(nlp.constraint_names, res.record.g)},
        "grey_fraction": grey_fraction(nlp.space, res.fields),
        "grey_band": list(GREY_BAND),
        "design": res.design_summary,
        "seconds_total": res.seconds,
        "seconds_per_iteration": mean,
    }
