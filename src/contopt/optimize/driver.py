"""The optimization loop: optimizer + design problem + history, checkpoints and output.

``optimize(problem, optimizer="mma"|"ipopt", out=DIR)`` runs the optimizer on
the :class:`DesignNLP` of ``problem`` and, per iteration, appends a history
row (objective, constraints, optimality, solver effort, seconds split into
primal / adjoint / design / optimizer / output, and the one full-design solve
that normalizes the objective), writes the design and state
as VTU + ``design.pvd``, redraws ``convergence.png`` and reports progress; at the end it
writes ``summary.json``, the force-displacement curves of the first and the last design
(``curves.json``, :mod:`contopt.optimize.curves`), the pictures, the design's surface
``design.stl`` and ``report.html``.
``resume=True`` continues a run that was interrupted, however it stopped
(see :mod:`contopt.optimize.history`).
"""

from __future__ import annotations

import dataclasses
import io
import json
import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from contopt import extras
from contopt.config import cache_entries
from contopt.design.space import DesignFields
from contopt.design.transfer import meet_volume_limits
from contopt.errors import ConfigError, ContoptError, ConvergenceError, OutputError
from contopt.io.plots import plot_convergence
from contopt.io.vtk import PVDSeries
from contopt.optimize.base import OPTIMIZERS, IterationInfo, OptimizerResult
from contopt.optimize.case_outputs import draw_case_pictures, write_case_states, write_design_state
from contopt.optimize.case_pool import case_pool
from contopt.optimize.continuation import continuation, fingerprint_entry, run_stages, stage_problem
from contopt.optimize.curves import write_design_curves
from contopt.optimize.history import Checkpoint, atomic_write_bytes, atomic_write_text, read_history, write_history
from contopt.optimize.ipopt import IpoptOptions, require_ipopt, run_ipopt
from contopt.optimize.mma import MMAOptions, run_mma
from contopt.optimize.multicase import design_nlp
from contopt.optimize.output_options import OutputOptions
from contopt.optimize.outputs import (
    clear_outputs,
    draw_pictures,
    what_was_kept,
    write_report_page,
    write_surface,
)
from contopt.optimize.problem import DesignNLP, DesignProblem, Record, progress_log
from contopt.optimize.rundir import RunLock
from contopt.timing import Stopwatch

log = logging.getLogger(__name__)

RESUME_AND_OVERWRITE = (
    "--resume and --overwrite exclude each other: --resume continues the run in the directory, "
    "--overwrite discards it; give one of them"
)
#: the start design (optimize's ``start``) in the checkpoint directory
START_FILE = "start.npy"
#: --resume together with a start design
RESUME_AND_START = (
    "--design-from and --resume exclude each other: a resumed run continues from its own start "
    "design; drop --design-from, or start afresh with --overwrite"
)
#: a start design: its variables, or a function of the design space giving them
Start = np.ndarray | Callable[[Any], np.ndarray] | None
#: a cell counts as grey when its volume fraction lies strictly between these
GREY_BAND = (0.1, 0.9)


@dataclass(frozen=True, eq=False)
class OptimizationResult:
    """Where the optimization ended.

    x : (n,) final design; fields : its design chain (nu, rho per cell); record : its evaluation
    history : one dict per iteration (as in ``history.json``)
    status, message : from the optimizer (see :data:`contopt.optimize.base.STATUSES`)
    iterations : optimizer iterations; analyses : design evaluations (primal + adjoint) over the whole run
    replayed : analyses of an interrupted run answered from its checkpoint (resume)
    scale : the objective scale ``|f^0|``; out : the run directory (or None)
    """

    x: np.ndarray
    fields: DesignFields
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


def _prepare_kernels(nlp: DesignNLP) -> None:
    """Compile (or load from the persistent cache) the element and contact kernels before the first
    analysis, and say how long it took: otherwise a user waits for the first line without a word."""
    system = nlp.system
    contact = system.contact if system.has_contact else None
    before, clock = cache_entries(), Stopwatch()
    progress_log.info(
        "compiling the kernels (%d dofs, %d cells%s)",
        system.disc.n_dofs,
        system.disc.n_cells,
        f", {len(contact.blocks)} contact interface(s)" if contact is not None else "",
    )
    states = system.start_states()
    if contact is not None:  # as a load step starts them (a frictional law measures its slip from there)
        states = contact.begin_step(states)
    try:
        system.evaluate(np.zeros(system.disc.n_dofs), 0.0, system.disc.layout(), states)
    except (ContoptError, FloatingPointError, ValueError) as err:  # the analysis will report it properly
        log.debug("kernel warm-up failed: %s", err)
        return
    after = cache_entries()
    if before is None or after is None:
        how = "the compilation cache is off"
    elif after > before:
        how = f"compiled; {after - before} new entries in the compilation cache"
    else:
        how = "loaded from the compilation cache"
    progress_log.info("kernels ready in %.1f s (%s)", clock.seconds, how)


def _run_optimizer(name: str, nlp: DesignNLP, x0: np.ndarray, options, out: Path | None = None) -> OptimizerResult:
    if name == "mma":
        return run_mma(nlp, x0, options)
    # IPOPT's own table and summary go to the run directory, not between the progress lines
    return run_ipopt(nlp, x0, options, log_file=None if out is None else str(out / "ipopt.log"))


def _resolve_options(optimizer: str, options):
    """The optimizer's options: those given (checked for the optimizer) or its defaults."""
    if optimizer not in OPTIMIZERS:
        raise ConfigError(f"optimizer must be one of {OPTIMIZERS}, got {optimizer!r}")
    expected = MMAOptions if optimizer == "mma" else IpoptOptions
    if optimizer == "ipopt":
        require_ipopt()  # before the problem is analysed
    if options is None:
        return expected()
    if not isinstance(options, expected):
        raise ConfigError(f"options for {optimizer!r} must be {expected.__name__}, got {type(options).__name__}")
    return options


def _fingerprint(nlp: DesignNLP, problem: DesignProblem, optimizer: str, options) -> dict:
    disc = nlp.system.disc
    opts = repr(dataclasses.replace(options, max_iter=0))  # more iterations may resume
    return json.loads(
        json.dumps(
            {
                "n_design": nlp.space.n,  # the robust formulation's bound is not a design variable
                "n_cells": disc.n_cells,
                "n_dofs": disc.n_dofs,
                "design": nlp.space.summary(),
                "objective": problem.objective.name,
                "constraints": nlp.constraint_names,
                "normalize": str(problem.normalize),
                "optimizer": optimizer,
                "options": opts,
                **fingerprint_entry(problem),
            }
        )
    )


class _Run:
    """The per-iteration bookkeeping of one :func:`optimize` call."""

    def __init__(
        self,
        nlp: DesignNLP,
        out: Path | None,
        outputs: OutputOptions,
        saved_rows: list,
        progress: Callable | None,
        max_iter: int,
    ):
        self.nlp, self.out, self.outputs = nlp, out, outputs
        self.saved, self.progress, self.max_iter = saved_rows, progress, max_iter
        self.rows: list[dict] = []
        # an eta continuation's: iterations before the stage, its eta, whether it is a later stage
        self.offset, self.sharpness, self.later = 0, float("nan"), False
        self.seen = 0  # evaluations accounted for in earlier rows
        self.mark = Stopwatch()  # since the last iteration's row
        self.series = PVDSeries(out / "design.pvd") if out is not None and outputs.vtu != "none" else None
        self.case_series: dict = {}  # each load case's design.pvd (case_outputs)
        # ranks > 0 of a distributed run write into a scratch directory removed at the end
        # (cli/distributed.py): the pictures, the design's surface and the report page need no other
        # rank, so only rank 0 makes them (the paper-size sabot on two ranks: rank 1 peaked at
        # 3.4 GB instead of 4.7 GB)
        self.primary = nlp.system.disc.comm.rank == 0
        self.draws = outputs.plot and self.primary
        self.plots = self.draws and extras.installed("viz")  # convergence.png every iteration (matplotlib)

    def stage(self, nlp: DesignNLP, eta: float, offset: int) -> None:
        """An eta continuation's next stage (:mod:`contopt.optimize.continuation`) begins."""
        self.later = not np.isnan(self.sharpness)
        self.nlp, self.sharpness, self.offset, self.seen = nlp, eta, offset, 0

    def row(self, info: IterationInfo) -> tuple[dict, bool]:
        """The history row of an iteration, and whether it is the stored row of a replayed iteration."""
        nlp = self.nlp
        rec = nlp.record(info.x)
        info = dataclasses.replace(info, iteration=info.iteration + self.offset)
        new = nlp.log[self.seen :]
        self.seen = len(nlp.log)
        spent = {k: sum(e["seconds"].get(k, 0.0) for e in new) for k in ("primal", "adjoint", "design", "reference")}
        interval = self.mark.seconds
        row: dict[str, Any] = {
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
        if not np.isnan(self.sharpness):
            row["eta"] = self.sharpness
        cases = nlp.case_objectives(rec)
        if cases:  # each load case's objective (unscaled, a maximized response negated)
            row["cases"] = cases
        k = row["iteration"]
        if k < len(self.saved) and self.saved[k].get("objective") == row["objective"]:
            return self.saved[k], True  # replayed: keep the row (and its timings) of the interrupted run
        return row, False

    def __call__(self, info: IterationInfo) -> bool:
        if self.later and info.iteration == 0:  # a later stage's start: its effort goes to the next row
            return True
        row, replayed = self.row(info)
        clock = Stopwatch()
        if self.out is not None:
            if self.outputs.vtu == "every":
                self.write_vtu(info.x, row["iteration"])
            if self.plots:
                plot_convergence(self.rows + [row], self.out / "convergence.png")
        if not replayed:
            row["seconds"]["output"] = clock.seconds
            row["seconds"]["iteration"] = sum(v for k, v in row["seconds"].items() if k != "iteration")
            row["elapsed"] = (self.rows[-1]["elapsed"] if self.rows else 0.0) + row["seconds"]["iteration"]
        self.rows.append(row)
        if self.out is not None:
            write_history(self.out, self.rows)
        if self.progress is not None:  # a replayed row says so (its timings are the interrupted run's)
            self.progress({**row, "replayed": True} if replayed else row, self.eta(row["iteration"]))
        self.mark = Stopwatch()
        return True

    def eta(self, iteration: int) -> float:
        """Seconds left if the run goes to max_iter at the mean pace of the iterations after the first."""
        done = [r["seconds"]["iteration"] for r in self.rows[1:]] or [self.rows[-1]["seconds"]["iteration"]]
        return float(np.mean(done)) * max(self.max_iter - iteration, 0)

    def write_vtu(self, x: np.ndarray, index: int) -> list[Path]:
        """The VTU files of the iterate ``x`` (the record of its evaluation) as iteration ``index``, and
        with load cases each case's (:mod:`contopt.optimize.case_outputs`)."""
        rec = self.nlp.record(x)
        files = self.write_state(rec.u, self.nlp.fields(x), rec.pressures, index)
        assert self.out is not None  # only a run with a directory writes VTU files
        return files + write_case_states(self.out, self.nlp, x, index, self.case_series)

    def write_state(self, u: np.ndarray, fields, pressures: tuple, index: int) -> list[Path]:
        """One VTU per body of the displacement ``u`` (n_dofs,) at the design ``fields``, with the
        nodal contact ``pressures`` (one array per interface, may be empty), as entry ``index``."""
        assert self.out is not None  # only a run with a directory writes VTU files
        if self.series is None:  # vtu="none": the pictures (or a failed analysis) still need one
            self.series = PVDSeries(self.out / "design.pvd")
        return write_design_state(self.out / "vtu", self.series, self.nlp, self.nlp.system, u, fields, pressures, index)


def optimize(
    problem: DesignProblem,
    optimizer: str = "mma",
    options=None,
    out=None,
    resume: bool = False,
    overwrite: bool = False,
    outputs: OutputOptions | None = None,
    progress: Callable[[dict, float], None] | None = None,
    started: Callable[[Path], None] | None = None,
    start: Start = None,
) -> OptimizationResult:
    """Optimize ``problem`` from the all-grey design, or from ``start``.

    Parameters
    ----------
    optimizer : "mma" or "ipopt"; options : MMAOptions / IpoptOptions (defaults if None)
    out : run directory (checkpoint, history, VTU, plots, summary.json); None keeps everything in memory
    resume : continue the run in ``out`` (same problem and options; max_iter may grow)
    overwrite : start afresh in an ``out`` that holds another run (not together with ``resume``)
    progress : called after every iteration with (history row, estimated seconds left)
    started : called with ``out`` once it is locked and prepared, before the first analysis
    start : the start design: (n,) design variables, or a function of the design space giving them
        (:func:`contopt.cases.design_from.design_from` makes one from another run); None: the
        all-grey design. It is clipped into the bounds; a body above its volume limit has its level
        set lowered to meet it (:func:`contopt.design.transfer.meet_volume_limits`, a warning says
        so); ``out/checkpoint/start.npy`` keeps it: a resumed run starts from there again (and
        refuses a ``start``)

    The run holds the lock of ``out`` (:class:`contopt.optimize.rundir.RunLock`) until it returns:
    another run of the same directory is refused with a ConfigError naming this process. A write
    that fails (a full disk) raises :class:`~contopt.errors.OutputError` that says what the
    directory keeps (``resume`` continues from it). When the first analysis fails (no analysis
    completed), its last converged state is written as VTU with a ``summary.json`` of status
    "failed", and the ConvergenceError raised says where.
    """
    options = _resolve_options(optimizer, options)
    outputs = outputs or OutputOptions()
    if resume and out is None:
        raise ConfigError("resume needs the run directory (out=...)")
    if resume and overwrite:
        raise ConfigError(RESUME_AND_OVERWRITE)
    if resume and start is not None:
        raise ConfigError(RESUME_AND_START)
    if out is None:
        return _optimize(problem, optimizer, options, None, (resume, overwrite, start), outputs, progress, started)
    out = Path(out)
    if resume and not out.is_dir():  # before the lock would create it
        raise ConfigError(f"nothing to resume in {out}: there is no such directory; start the run without --resume")
    with RunLock(out):
        try:
            return _optimize(problem, optimizer, options, out, (resume, overwrite, start), outputs, progress, started)
        except OutputError as err:
            raise OutputError(f"{err}; {what_was_kept(out)}", err.errno) from err


def _optimize(problem, optimizer, options, out, how, outputs, progress, started) -> OptimizationResult:
    """:func:`optimize` once its arguments are checked (and ``out`` is locked); ``how``: (resume,
    overwrite, start). The load cases' worker processes, if any, live as long as this call."""
    with case_pool(problem) as pool:
        return _optimize_with(pool, problem, optimizer, options, out, how, outputs, progress, started)


def _optimize_with(pool, problem, optimizer, options, out, how, outputs, progress, started) -> OptimizationResult:
    resume, overwrite, start = how
    clock = Stopwatch()
    cont = continuation(problem)
    nlp = design_nlp(problem if cont is None else stage_problem(problem, cont.start), pool=pool)
    x0 = nlp.space.initial() if resume else _start_design(nlp.space, start)  # before out is touched
    saved, ckpt = ([], None) if out is None else _prepare(nlp, problem, optimizer, options, out, resume, overwrite)
    if out is not None:
        x0 = _kept_start(nlp.space, Checkpoint(out).dir / START_FILE, resume, None if start is None else x0)
    if out is not None and started is not None:
        started(out)
    run = _Run(nlp, out, outputs, saved, progress, options.max_iter)
    nlp.on_iteration = run
    _prepare_kernels(nlp)
    try:
        if cont is None:
            result = _run_optimizer(optimizer, nlp, nlp.start(x0), options, out)
        else:
            solve = lambda nlp, x, opts: _run_optimizer(optimizer, nlp, x, opts, out)  # noqa: E731
            result, nlp = run_stages(problem, run, ckpt, x0, options, solve)
    except ContoptError as err:
        if nlp.n_evaluations == 0 and nlp.failure is not None and not isinstance(err, OutputError):
            raise _first_analysis_failed(run, optimizer) from err
        raise
    if nlp.n_evaluations == 0 and nlp.failure is not None:  # the optimizer stopped at its first analysis
        raise _first_analysis_failed(run, optimizer) from nlp.failure.error
    return _finish(run, result, optimizer, clock)


def _start_design(space, start: Start) -> np.ndarray:
    """The (n,) design a fresh run starts from (see :func:`optimize`'s ``start``): the grey one, or
    ``start`` within the bounds and the volume limits."""
    if start is None:
        return space.initial()
    x = np.clip(space.check_x(start(space) if callable(start) else start), space.lower, space.upper)
    x, lowered = meet_volume_limits(space, x)
    for body, (before, after) in lowered.items():
        limit = next(p.spec.volume_fraction for p in space.parts if p.spec.body == body)
        log.warning(
            "the start design of body %r had volume fraction %.4f, above its limit %.4g: its level set "
            "was lowered uniformly to %.4f",
            body,
            before,
            limit,
            after,
        )
    return x


def _kept_start(space, stored: Path, resume: bool, x: np.ndarray | None) -> np.ndarray:
    """A fresh run's start ``x`` (None: the grey one) stored in ``stored``; a resumed run's read back
    from there (the grey one when the run stored none). Returns the (n,) start."""
    if not resume:
        if x is None:
            return space.initial()
        buf = io.BytesIO()
        np.save(buf, x, allow_pickle=False)
        atomic_write_bytes(stored, buf.getvalue())
        return x
    if not stored.exists():
        return space.initial()  # a run started from the grey design
    try:
        return space.check_x(np.load(stored, allow_pickle=False))
    except (OSError, ValueError, ConfigError) as err:
        raise ConfigError(
            f"cannot resume: {stored} (the run's start design) cannot be read ({err}); start again with --overwrite"
        ) from None


def _prepare(
    nlp: DesignNLP, problem: DesignProblem, optimizer: str, options, out: Path, resume: bool, overwrite: bool
) -> tuple[list[dict], Checkpoint]:
    """Start the checkpoint of ``out`` (a fresh run clears the old outputs, a resume loads the records
    to replay) and connect it to ``nlp``; returns the history rows of the interrupted run and the checkpoint."""
    ckpt = Checkpoint(out)
    meta = ckpt.start(_fingerprint(nlp, problem, optimizer, options), resume, overwrite)
    records, saved = [], []
    if resume:
        records, saved = ckpt.records(), read_history(out)
        log.info("resuming %s: %d recorded evaluations, %d iterations", out, len(records), len(saved))
    else:
        clear_outputs(out)
    nlp.scale = meta.get("scale")
    nlp.replay = records

    def on_record(rec: Record):
        if "scale" not in ckpt.meta:  # before the record: a replayed record needs the scale it was made with
            ckpt.update_meta(scale=nlp.scale)
        ckpt.save(rec)

    nlp.on_record = on_record
    return saved, ckpt


def _finish(run: _Run, result: OptimizerResult, optimizer: str, clock: Stopwatch) -> OptimizationResult:
    """The result of a run that ended (any status), with its final VTU, pictures and summary written."""
    nlp, out, outputs = run.nlp, run.out, run.outputs
    rec = nlp.record(result.x)
    fields = nlp.fields(result.x)
    assert nlp.scale is not None  # fixed by the first evaluation: rec was made with it
    pictures = out is not None and outputs.plot
    if out is not None and (outputs.vtu == "final" or (pictures and outputs.vtu == "none")):
        run.write_vtu(result.x, result.iterations)  # vtu="none": the pictures are drawn from the final VTU
    res = OptimizationResult(
        x=result.x,
        fields=fields,
        record=rec,
        history=run.rows,
        status=result.status,
        message=result.message,
        iterations=result.iterations,
        analyses=nlp.n_evaluations,
        replayed=nlp.replayed,
        scale=float(nlp.scale),
        design_summary=nlp.space.summary(),
        out=out,
        seconds=clock.seconds,
    )
    if out is not None:
        data = summary(res, nlp, optimizer)
        if outputs.view_up is not None:
            data["view_up"] = outputs.view_up  # `contopt report` redraws the pictures the same way
        if pictures and outputs.curves:  # every rank solves (the solves are collective), the first writes
            write_design_curves(out, nlp, result.x, result.iterations, write=run.primary)
        if pictures and run.draws:
            data["pictures"] = {**draw_pictures(out, outputs.view_up), **draw_case_pictures(out, nlp, outputs.view_up)}
            data["surface"] = write_surface(out, nlp, fields.x)
        atomic_write_text(out / "summary.json", json.dumps(data, indent=1))
        if run.primary:
            write_report_page(out)
    log.info(
        "optimization %s after %d iterations (%d analyses): objective %.6g",
        result.status,
        result.iterations,
        nlp.n_evaluations,
        rec.f,
    )
    return res


def _first_analysis_failed(run: _Run, optimizer: str) -> ContoptError:
    """The error to raise when no analysis completed: the failure's message, after its last converged
    state (VTU) and a ``summary.json`` of status "failed" were written to the run directory, and where."""
    failure, out = run.nlp.failure, run.out
    assert failure is not None  # raised only after a failed analysis (_optimize)
    last = failure.last_state
    message = f"the analysis of {failure.design} failed: {failure.error}".rstrip()
    if out is not None:
        files = [] if last is None else run.write_state(np.asarray(last.u), failure.fields, _pressures(last), 0)
        state = (
            None if last is None else {"load_factor": float(last.t), "files": [str(f.relative_to(out)) for f in files]}
        )
        data = {
            "optimizer": optimizer,
            "status": "failed",
            "message": message,
            "iterations": 0,
            "analyses": 0,
            "replayed": 0,
            "normalize": str(run.nlp.problem.normalize),
            "design": run.nlp.space.summary(),
            "failed_analysis": {"design": failure.design, "last_converged_state": state},
        }
        atomic_write_text(out / "summary.json", json.dumps(data, indent=1))
        write_report_page(out)
        where = (
            f"its last converged state (load factor {float(last.t):.4g}) is in {out / 'design.pvd'}"
            if last is not None
            else "no load step converged"
        )
        rerun = "" if Checkpoint(out).has_records() else "; a new run may use the directory without --overwrite"
        message = (
            f"{message.rstrip('.')}. Nothing was recorded; {where}, and {out / 'summary.json'} has status "
            f'"failed"{rerun}'
        )
    if isinstance(failure.error, ContoptError) and not isinstance(failure.error, ConvergenceError):
        return type(failure.error)(message)  # e.g. a LinearSolverError stays one
    return ConvergenceError(message, getattr(failure.error, "logs", None), last)


def _pressures(state) -> tuple:
    """Nodal contact pressures per interface of a converged state: a State or a solver's StepResult."""
    contact = getattr(state, "contact", None) or getattr(getattr(state, "evaluation", None), "contact", None)
    return tuple(np.asarray(res.lam, dtype=np.float64) for res in contact or ())


def summary(res: OptimizationResult, nlp: DesignNLP, optimizer: str) -> dict:
    """The numbers a person (or a table) wants from a finished run."""
    rows = res.history
    mean = {
        k: float(np.mean([r["seconds"][k] for r in rows[1:]])) if len(rows) > 1 else float("nan")
        for k in ("primal", "adjoint", "design", "optimizer", "output", "iteration")
    }
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
        "volume_fraction": (
            float(res.volume_fractions[0])
            if len(res.volume_fractions) == 1
            else [float(v) for v in res.volume_fractions]
        ),
        "volume_fractions": {n: float(v) for n, v in zip(nlp.space.names, res.volume_fractions)},
        # the optimizer's g (a worst case's bound rows with its beta); the record's, cached
        "constraints": {n: float(v) for n, v in zip(nlp.constraint_names, nlp.evaluate(res.x).g)},
        "grey_fraction": grey_fraction(nlp.space, res.fields),
        "grey_band": list(GREY_BAND),
        "design": res.design_summary,
        "seconds_total": res.seconds,
        "seconds_per_iteration": mean,
    }
