"""How a problem file's problem is run: the ``[optimizer]``, ``[run]``, ``[newton]``,
``[augmentation]``, ``[linear]`` and ``[adjoint]`` sections, :class:`RunSpec` (the file, read)
and the recipe a run directory keeps to rebuild its problem (:func:`contopt.cases.spec.load_run_spec`).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from contopt.adjoint.options import AdjointOptions
from contopt.cases.keys_run import RUN
from contopt.cases.problem_summary import problem_summary, record_summary
from contopt.cases.toml_reader import Reader, Table, describe, read_options, toml_value
from contopt.contact.laws import AugmentationOptions
from contopt.errors import OutputError
from contopt.optimize.base import OPTIMIZERS
from contopt.optimize.ipopt import IpoptOptions
from contopt.optimize.mma import MMAOptions
from contopt.optimize.output_options import OutputOptions
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton_options import NewtonOptions

#: where a run directory keeps the recipe of its problem (see RunSpec.recipe)
RECIPE_FILE = Path("checkpoint") / "problem.json"
_FILE_OUT = object()  # RunSpec.run's default: the run directory the file names

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class RunSpec:
    """A problem file, read: the design problem and how to run it.

    problem : the :class:`~contopt.optimize.problem.DesignProblem` (its ``model`` a Model)
    optimizer : "mma" or "ipopt"; options : its MMAOptions / IpoptOptions (``max_iter`` included)
    out : run directory; vtu, plot, view_up : what the run writes (see OutputOptions)
    name, description : from the file (the case name for the short form)
    case : the case a short-form file (or `contopt run CASE`) names, else None
    source : the file (or the label of a text); text : the TOML text as read
    discretization : the model's Discretization built while checking the design (reused by :meth:`run`)
    recipe : the arguments of :func:`load_spec` that made this spec (JSON-ready); :meth:`run` stores
        them in the run directory (``checkpoint/problem.json``) so the run's problem can be rebuilt
        from the directory alone (:func:`load_run_spec`)
    design_from : the start design (``run.design_from``): a run directory, a VTU or a PVD file
        (:func:`contopt.cases.design_from.design_from`); None: the all-grey design

    :meth:`run` also keeps the problem's summary in words (``checkpoint/problem_summary.json``,
    :mod:`contopt.cases.problem_summary`) for report.html, once the run has accepted the directory.
    """

    problem: Any
    optimizer: str
    options: Any
    out: str = "results"
    vtu: str = "every"
    plot: bool = True
    view_up: str | None = None
    name: str = ""
    description: str = ""
    case: str | None = None
    source: str = ""
    text: str = ""
    discretization: Any = None
    recipe: Any = None
    design_from: str | None = None

    @property
    def max_iter(self) -> int:
        return self.options.max_iter

    @property
    def eta(self) -> float:
        return self.problem.design.heaviside.eta

    @property
    def model(self):
        return self.problem.model

    def run(
        self, out=_FILE_OUT, *, resume: bool = False, overwrite: bool = False, outputs=None, progress=None, started=None
    ):
        """Optimize (see :func:`contopt.optimize.driver.optimize`) into the run directory ``out``: by
        default the file's ``run.out``; ``None`` keeps everything in memory. A fresh run starts from
        :attr:`design_from` (read and carried to this design space before the run directory is
        touched), a resumed one from its own start (:attr:`design_from` is then not read)."""
        from contopt.optimize.driver import optimize  # JAX: kept out of load_model

        problem = self.problem
        if self.discretization is not None:
            problem = dataclasses.replace(problem, model=self.discretization)
        start = None
        if not resume and self.design_from is not None:
            problem, start = self._start(problem, self.design_from)
        out = self.out if out is _FILE_OUT else out
        if out is not None and self.recipe is not None:
            progress = _recording(Path(out), self.recipe, progress)
        if out is not None:
            started = _summarizing(problem, started)
        return optimize(
            problem,
            self.optimizer,
            self.options,
            out=out,
            resume=resume,
            overwrite=overwrite,
            outputs=outputs or OutputOptions(vtu=self.vtu, plot=self.plot, view_up=self.view_up),
            progress=progress,
            started=started,
            start=start,
        )

    def _start(self, problem, source: str):
        """``(problem, x0)``: the problem on its discretization and the (n,) start design ``source``
        (:attr:`design_from`) in its design space (ConfigError, one line, when it cannot be carried)."""
        from contopt.assembly.system import discretize
        from contopt.cases.design_from import design_from

        if self.discretization is None:
            problem = dataclasses.replace(problem, model=discretize(problem.model))
        start = design_from(source, self._from_what)
        return problem, start(problem.design.build(problem.model))

    @property
    def _from_what(self) -> str:
        """How the start design was named, for its errors: --design-from, --set or run.design_from."""
        return (self.recipe or {}).get("origins", {}).get("run.design_from") or "run.design_from"


def _recording(out: Path, recipe: dict, progress):
    """``progress`` that first stores the recipe in ``out`` (once the run has accepted the directory)."""
    from contopt.optimize.history import atomic_write_text  # JAX (optimize.problem): kept out of load_model

    done: list[bool] = []

    def wrapped(row, eta):
        if not done:
            done.append(True)
            try:
                atomic_write_text(out / RECIPE_FILE, json.dumps(recipe, indent=1))
            except (OSError, TypeError, ValueError) as err:  # the run goes on; only its rebuild needs this
                log.warning("could not store the problem's recipe in %s: %s", out, err)
        if progress is not None:
            progress(row, eta)

    return wrapped


def _summarizing(problem, started):
    """``started`` that first keeps the problem's summary in words in the run directory (for
    report.html, :mod:`contopt.cases.problem_summary`); a failure to write it is logged, the run goes on."""
    sentences = problem_summary(problem)

    def wrapped(out):
        try:
            record_summary(out, sentences)
        except OutputError as err:
            log.warning("could not keep the problem's summary in %s: %s", out, err)
        if started is not None:
            started(out)

    return wrapped


def header_flags(copy: Path) -> dict:
    """load_spec arguments from the ``# contopt run ...`` line `contopt run` put atop problem.toml."""
    first = copy.read_text(encoding="utf-8").splitlines()[:1]
    words = shlex.split(first[0].lstrip("# ")) if first and first[0].startswith("# contopt run") else []
    flags: dict = {"overrides": {}, "origins": {}}
    for flag, value in zip(words, words[1:]):
        if flag in ("--mesh", "--design"):
            flags[flag[2:]] = value
        elif flag == "--eta":
            flags["eta"] = float(value)
        elif flag == "--set" and "=" in value:
            key, _, text = value.partition("=")
            flags["overrides"][key.strip()] = toml_value(text.strip())
            flags["origins"][key.strip()] = "--set"
    return flags


# --- sections
def read_solver_options(r: Reader, top: Table) -> dict:
    """``{"newton": ..., "augmentation": ..., "linear": ..., "adjoint": ...}`` for the tables present."""
    classes = {
        "newton": NewtonOptions,
        "augmentation": AugmentationOptions,
        "linear": LinearSolverOptions,
        "adjoint": AdjointOptions,
    }
    return {key: read_options(r, cls, top.raw(key), key) for key, cls in classes.items() if top.has(key)}


def read_optimizer(r: Reader, top: Table):
    """``(name, options, outputs, settings)`` of the ``[optimizer]`` and ``[run]`` tables; settings: the
    DesignProblem's fields that [run] gives (``warm_start``, ``case_workers``), those it has."""
    opt = top.sub("optimizer", RUN["optimizer"].names, default=None)
    default = RUN["optimizer"].default("name")
    name = opt.str("name", default, OPTIMIZERS) if opt is not None else default
    why = "the iteration limit is run.max_iter (one for both optimizers)"
    tables = {}
    for key, cls in (("mma", MMAOptions), ("ipopt", IpoptOptions)):  # both are checked, the one named is used
        given = opt is not None and opt.has(key)
        tables[key] = read_options(r, cls, opt.raw(key), opt.key(key), exclude={"max_iter": why}) if given else cls()
    options = tables[name]
    run = top.sub("run", RUN["run"].names, default=None)
    if run is None:
        outputs = {"out": "results", "vtu": "every", "plot": True, "view_up": None, "design_from": None}
        return name, options, outputs, {}
    if run.has("max_iter"):
        options = dataclasses.replace(options, max_iter=run.int("max_iter", minimum=0))
    keys = RUN["run"]
    settings = {
        "warm_start": run.bool("warm_start", keys.default("warm_start")),
        "case_workers": run.int("case_workers", keys.default("case_workers"), minimum=1),
    }
    return name, options, _outputs(run), settings


def _outputs(run: Table) -> dict:
    """The run directory and what is written there (checked by OutputOptions)."""
    outputs = run.guard(
        None, OutputOptions, vtu=run.str("vtu", "every"), plot=run.bool("plot", True), view_up=run.str("view_up", None)
    )
    return {
        "out": run.str("out", "results"),
        "vtu": outputs.vtu,
        "plot": outputs.plot,
        "view_up": outputs.view_up,
        "design_from": run.str("design_from", None),
    }


def read_texts(top: Table) -> tuple[str, str]:
    """The file's ``name`` and ``description``."""
    name = top.str("name", "")
    desc = top.raw("description", "")
    if not isinstance(desc, str):
        raise top.error("description", f"must be a string, got {describe(desc)}")
    return name, desc
