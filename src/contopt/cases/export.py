"""A run directory's optimized design as a surface file: ``export_design(RUN_DIR, "part.stl")``.

The run's problem is rebuilt from the directory (:func:`contopt.cases.spec.load_run_spec`)
and checked against the checkpoint's fingerprint; the design is the one of the run's last
iteration (its evaluation in the checkpoint), or of its last analysis when no iteration has
been recorded yet. The surface itself is made by :mod:`contopt.design.surface`.
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from contopt.cases.spec import load_run_spec
from contopt.design.surface import BodySurface, SurfaceOptions, write_design_surfaces
from contopt.errors import ConfigError
from contopt.io.surface import surface_format
from contopt.optimize.history import Checkpoint, read_history
from contopt.optimize.report import run_directory
from contopt.solve.system import System

log = logging.getLogger(__name__)

#: the volume check of the issue: surface volume within this of volume fraction x domain volume
VOLUME_TOLERANCE = 0.02


@dataclass(frozen=True, eq=False)
class ExportResult:
    """What :func:`export_design` wrote.

    run_dir : the run directory; iteration : the optimizer iteration exported (None: no
    iteration recorded yet); evaluation : its analysis in the checkpoint
    surfaces : one :class:`~contopt.design.surface.BodySurface` per designed body; files : their paths
    note : which record could not be read and was gone past (None when the last iteration's was read)
    """

    run_dir: Path
    iteration: int | None
    evaluation: int
    surfaces: tuple
    files: tuple
    note: str | None = None

    def lines(self) -> list[str]:
        """What the command line prints: one line per file, and a note for a volume that disagrees."""
        if self.note is not None:
            where = "the last readable analysis"
        elif self.iteration is not None:
            where = f"iteration {self.iteration}"
        else:
            where = "no iteration recorded yet: the last analysis"
        out = [f"{self.run_dir}: design of {where} (analysis {self.evaluation})"]
        if self.note is not None:
            out.append(f"  note: {self.note}")
        for s, path in zip(self.surfaces, self.files):
            out.append(f"wrote {path}: {s.line()}")
            if not abs(s.relative_difference) <= VOLUME_TOLERANCE:
                out.append(
                    f"  note: the volumes differ by more than {VOLUME_TOLERANCE:.0%}: the surface bounds "
                    "nu > 1/2, and a grey design (0 < nu < 1) has material on both sides of it"
                )
        return out


def _read_x(ckpt: Checkpoint, index: int) -> np.ndarray:
    with np.load(ckpt.record_path(index), allow_pickle=False) as data:
        return np.asarray(data["x"], dtype=np.float64).copy()


def _readable_x(ckpt: Checkpoint, chosen: int, use: str, fix: str) -> tuple[np.ndarray, int, str | None]:
    """(x, its analysis, a note) of analysis ``chosen``, or when it cannot be read of the last readable
    one before it (the note says which and why, and that it ``use``); ConfigError ending in ``fix``
    when none can be read."""
    why = None
    for j in range(chosen, -1, -1):
        try:
            x = _read_x(ckpt, j)
        except Exception as err:  # a damaged file: say which, and go back as --resume does
            reason = " ".join(str(err).split())[:120]
            why = why or f"{ckpt.record_path(j).name} cannot be read ({type(err).__name__}: {reason})"
            continue
        return x, j, None if j == chosen else f"{why}; the design of analysis {j}, the last readable one, {use}"
    raise ConfigError(
        f"{ckpt.root} has no readable record of a design: {why}, and neither can any record before it; {fix}"
    )


def final_design(run_dir: Path) -> tuple[np.ndarray, int | None, int]:
    """(x, iteration, evaluation) of the run's last recorded iteration.

    The iteration's evaluation is the last one made by then (index < its ``analyses``) whose
    objective equals the row's (a line search may have evaluated trial points after it). When
    that record cannot be read, the last readable one before it is taken (iteration None, and a
    warning says which): :func:`export_design` says so in its :meth:`ExportResult.lines`.
    """
    x, iteration, evaluation, note = last_design(run_dir)
    if note is not None:
        log.warning("%s", note)
    return x, iteration, evaluation


def last_design(
    run_dir: Path, use: str = "is exported", fix: str = "start the run again with --overwrite"
) -> tuple[np.ndarray, int | None, int, str | None]:
    """:func:`final_design` and the note on an unreadable record it went past (None when none),
    which says that the design taken ``use``; ``fix`` ends the error when no record can be read."""
    ckpt = Checkpoint(run_dir)
    n = 0
    while ckpt.record_path(n).exists():
        n += 1
    if n == 0:
        raise ConfigError(
            f"{run_dir} has no completed analysis yet (no checkpoint/eval_00000.npz): wait until "
            "the run has analysed its first design"
        )
    rows = read_history(run_dir)
    if not rows:
        x, chosen, note = _readable_x(ckpt, n - 1, use, fix)
        return x, None, chosen, note
    row = rows[-1]
    made = max(1, min(int(row.get("analyses", n)), n))
    chosen = made - 1
    for j in range(made - 1, -1, -1):
        try:
            with np.load(ckpt.record_path(j), allow_pickle=False) as data:
                if float(data["f"]) == row["objective"]:
                    chosen = j
                    break
        except Exception:  # an unreadable record cannot be the match
            continue
    x, evaluation, note = _readable_x(ckpt, chosen, use, fix)
    return x, (int(row["iteration"]) if note is None else None), evaluation, note


def design_variables(space, x: np.ndarray, eta: float | None = None) -> np.ndarray:
    """The design variables of a recorded ``x``: a robust run's records end with the bound
    (:mod:`contopt.optimize.robust`), which is dropped; ``eta``: the sharpness ``x`` was made at (an
    eta continuation's stage, :func:`recorded_eta`), rescaled to the space's (the same volume fraction)."""
    if space.design.robust is not None and x.shape == (space.n + 1,):
        x = x[: space.n]
    if eta is not None and eta != space.design.heaviside.eta and x.shape == (space.n,):
        x = np.clip(x * (eta / space.design.heaviside.eta), space.lower, space.upper)
    return x


def recorded_eta(run_dir: Path, evaluation: int) -> float | None:
    """The Heaviside sharpness of analysis ``evaluation`` of a run with an eta continuation (the
    stages in ``checkpoint/meta.json``); None for a run without one."""
    stages = json.loads(Checkpoint(run_dir).meta_path.read_text()).get("eta_stages") or []
    made = [float(s["eta"]) for s in stages if int(s["first_analysis"]) <= evaluation]
    return made[-1] if made else None


def run_design_space(run_dir: Path):
    """The run's design space and discretization, rebuilt and checked against the checkpoint."""
    spec = load_run_spec(run_dir)
    disc = spec.discretization
    if disc is None:
        disc = System.of(spec.problem.model).disc
    space = spec.problem.design.build(disc)
    meta = json.loads(Checkpoint(run_dir).meta_path.read_text()).get("fingerprint", {})
    ran = {"n_design": meta.get("n_design"), "design": meta.get("design")}
    now = {"n_design": space.n, "design": json.loads(json.dumps(space.summary()))}
    differ = [k for k in ran if ran[k] is not None and ran[k] != now[k]]
    if differ:
        raise ConfigError(
            f"the problem rebuilt from {run_dir} is not the one that ran (its {', '.join(differ)} "
            "differ from the checkpoint's); was problem.toml edited?"
        )
    return space, disc


def export_design(
    run_dir: str | os.PathLike,
    out: str | os.PathLike | None = None,
    options: SurfaceOptions | None = None,
    binary: bool = True,
) -> ExportResult:
    """Write the surface of the optimized design of the run in ``run_dir``.

    out : the file (.stl, .ply or .obj; default ``run_dir/design.stl``); with several designed
        bodies one file per body, ``<stem>_<body><suffix>``
    options : lattice refinement, smoothing, mirror planes (:class:`SurfaceOptions`)
    binary : binary STL / PLY (OBJ is text)

    Returns the surfaces with their volume check (surface volume against the design's volume
    fraction times the domain volume).
    """
    run_dir = run_directory(run_dir)
    out = Path(out) if out is not None else run_dir / "design.stl"
    surface_format(out)
    x, iteration, evaluation, note = last_design(run_dir)
    space, disc = run_design_space(run_dir)
    x = design_variables(space, x, recorded_eta(run_dir, evaluation))
    if x.shape != (space.n,):
        raise ConfigError(
            f"analysis {evaluation} in {run_dir} has {x.size} design variables, the problem "
            f"{space.n}; the checkpoint belongs to another problem"
        )
    made = write_design_surfaces(space, x, disc, out, options, binary=binary)
    surfaces: tuple[BodySurface, ...] = tuple(m for m, _ in made)
    return ExportResult(
        run_dir=run_dir,
        iteration=iteration,
        evaluation=evaluation,
        surfaces=surfaces,
        files=tuple(Path(p) for _, p in made),
        note=note,
    )
