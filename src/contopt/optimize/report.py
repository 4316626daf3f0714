"""What a person looks at after a run: pictures and a text summary of a run directory.

``make_pictures(DIR)`` draws ``design.png`` and ``deformed.png`` (from the last
VTU of each body, :mod:`contopt.io.render`), ``convergence.png`` (from
``history.json``), for a contact problem ``pressure_history.png`` (from the
checkpoint records), ``curves.png`` (from ``curves.json``, :mod:`contopt.optimize.curves`)
and the design history: small pictures of a few iterations in ``design_history/``.
``report_text(DIR)`` summarizes the run in a few lines. Both read only files, so they work on a
finished, interrupted or running run (``contopt report DIR``).
"""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path

import numpy as np

from contopt.errors import ConfigError
from contopt.io.plots import plot_convergence, plot_curves, plot_pressure_history
from contopt.io.render import (
    DEFAULT_SIZE,
    last_vtus,
    picture_size,
    render_deformed,
    render_design,
    render_sections,
)
from contopt.io.stress_map import has_stress, render_stress
from contopt.io.vtk import read_pvd
from contopt.optimize.curves import read_curves
from contopt.optimize.history import Checkpoint, read_history

log = logging.getLogger(__name__)

#: the pictures of a run directory, by key (file ``<key>.png``)
PICTURES = ("design", "sections", "deformed", "stress", "convergence", "pressure_history", "curves")
#: the folder of the design history's small pictures (``iteration_NNNN.png``)
HISTORY_DIR = "design_history"
#: at most this many iterations in the design history (the first and the last among them)
HISTORY_FRAMES = 6
#: the size of a design history picture (width, height) in pixels
HISTORY_SIZE = (360, 270)
_SECONDS = ("primal", "adjoint", "design", "optimizer")


def run_directory(path: str | os.PathLike) -> Path:
    """``path`` as a Path if it holds a run, else ConfigError naming it and what is missing.

    A run whose ``checkpoint/meta.json`` was deleted still is one: the file is rebuilt from the copy
    its records carry (:meth:`~contopt.optimize.history.Checkpoint.restore_meta`, logged).
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{path} is a file, not a run directory: give the directory `contopt run --out` wrote")
    if not path.is_dir():
        raise ConfigError(f"{path} is not a run directory: there is no such directory")
    if not Checkpoint(path).restore_meta():  # a deleted meta.json comes back from the records' copies
        raise ConfigError(
            f"{path} is not a run directory: it has no checkpoint/meta.json "
            "(written when `contopt run --out DIR` starts)"
        )
    return path


def _evaluations(run_dir: Path) -> list[dict]:
    """f, objective and nodal contact pressures (all interfaces side by side) of each stored evaluation.

    Reads only those arrays of ``checkpoint/eval_NNNNN.npz`` (in index order, up to the first
    missing or unreadable file) and, unlike ``Checkpoint.records``, never renames a file.
    """
    ckpt = Checkpoint(run_dir)
    out: list[dict] = []
    while ckpt.record_path(len(out)).exists():
        try:
            with np.load(ckpt.record_path(len(out)), allow_pickle=False) as data:
                n = int(data["n_interfaces"])
                lam = [np.asarray(data[f"pressures_{i}"], dtype=np.float64).ravel() for i in range(n)]
                out.append(
                    {
                        "f": float(data["f"]),
                        "objective": float(data["objective"]),
                        "pressures": np.concatenate(lam) if lam else np.zeros(0),
                    }
                )
        except Exception as err:  # a damaged or half-visible file ends the readable prefix
            log.debug("stopping at %s: %s", ckpt.record_path(len(out)), err)
            break
    return out


def pressure_history(
    run_dir: str | os.PathLike, rows: list[dict] | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(iterations (k,), pressures (k, n_nodes), normalized objective (k,)), or None without contact.

    With a history, row k is matched to the evaluation of its iterate: the last evaluation made
    by then (index < the row's ``analyses``) whose f and raw objective equal the row's (a line
    search may have evaluated trial points after it); failing a match, the last evaluation made
    by then. Without a history (the run stopped before its first iteration was recorded), every
    stored evaluation is used in order and "iterations" are evaluation indices.
    """
    run_dir = Path(run_dir)
    evals = _evaluations(run_dir)
    if not evals or evals[0]["pressures"].size == 0:
        return None
    rows = read_history(run_dir) if rows is None else rows
    if not rows:
        idx, its = list(range(len(evals))), list(range(len(evals)))
    else:
        idx, its = [], []
        for row in rows:
            made = min(int(row.get("analyses", len(evals))), len(evals))
            if made == 0:
                continue
            match = [
                j
                for j in range(made)
                if evals[j]["f"] == row["objective"]
                and evals[j]["objective"] == row.get("objective_raw", evals[j]["objective"])
            ]
            idx.append(match[-1] if match else made - 1)
            its.append(int(row["iteration"]))
        if not idx:
            return None
    lam = np.stack([evals[j]["pressures"] for j in idx])
    return np.asarray(its, dtype=np.float64), lam, np.array([evals[j]["f"] for j in idx])


def make_pictures(run_dir: str | os.PathLike, size=DEFAULT_SIZE, up: str | None = None) -> dict[str, Path]:
    """Draw the pictures of a run directory; returns {key: path} of those made (see :data:`PICTURES`).

    ``convergence.png`` needs ``history.json``; ``pressure_history.png`` contact pressures in the checkpoint
    (see :func:`pressure_history` for how iterations are matched to evaluations); ``design.png``,
    ``sections.png`` (cuts normal to ``up``, coloured by nu), ``stress.png`` (the solid cells' von Mises stress,
    :mod:`contopt.io.stress_map`) and ``deformed.png`` (``size`` = (width,
    height) pixels) the last VTU of each body, seen with the axis ``up``
    ("x", "y", "z"; default the run's ``view_up``, else the direction the bodies are pushed, see
    :func:`contopt.io.render.up_axis`). A picture whose input is missing is skipped with a log message; a
    rendering failure raises (:class:`contopt.io.render.RenderError`) after the matplotlib plots are written.
    """
    run_dir = run_directory(run_dir)
    size = picture_size(size)
    made: dict[str, Path] = {}
    rows = read_history(run_dir)
    if rows:
        made["convergence"] = plot_convergence(rows, run_dir / "convergence.png")
    hist = pressure_history(run_dir, rows)
    if hist is not None:
        made["pressure_history"] = plot_pressure_history(*hist, run_dir / "pressure_history.png")
    curves = read_curves(run_dir)
    if curves is not None:
        try:
            made["curves"] = plot_curves(curves, run_dir / "curves.png")
        except ValueError as err:  # no support, motion or interface to draw
            log.info("no curves.png: %s", err)
    files = last_vtus(run_dir)
    if not files:
        log.warning("no VTU files in %s: design.png and deformed.png need a run with vtu 'every' or 'final'", run_dir)
        return made
    title = ""
    if rows:
        title = f"iteration {rows[-1]['iteration']}, normalized objective {rows[-1]['objective']:.5g}"
    if up is None:  # the run's own choice, when it made one
        up = (_read_json(run_dir / "summary.json") or {}).get("view_up")
    made["design"] = render_design(files, run_dir / "design.png", size=size, title=title, up=up)
    # cuts show what the iso-surfaces hide behind solid skins (the sabot's interior)
    try:
        made["sections"] = render_sections(files, run_dir / "sections.png", axis=up, title=title)
    except ConfigError as err:  # no designed body in the VTU files: nothing to cut
        log.info("no sections.png: %s", err)
    made["deformed"] = render_deformed(files, run_dir / "deformed.png", size=size, title=title, up=up)
    if has_stress(files):  # VTU files of earlier releases have no von Mises stress
        made["stress"] = render_stress(files, run_dir / "stress.png", size=size, title=title, up=up)
    draw_design_history(run_dir, up)
    return {k: made[k] for k in PICTURES if k in made}


def history_iterations(run_dir: Path, frames: int = HISTORY_FRAMES) -> dict[int, list[Path]]:
    """{iteration: its VTU files} of up to ``frames`` iterations of ``design.pvd``, evenly spread
    from the first to the last; {} when it lists fewer than two iterations with existing files."""
    pvd = run_dir / "design.pvd"
    if not pvd.exists():
        return {}
    by_time: dict[float, list[tuple[int, Path]]] = {}
    for time, part, path in read_pvd(pvd):
        by_time.setdefault(time, []).append((part, path))
    whole = {
        int(round(t)): [p for _, p in sorted(entries)]
        for t, entries in sorted(by_time.items())
        if all(p.exists() for _, p in entries)
    }
    if len(whole) < 2:
        return {}
    its = sorted(whole)
    picks = sorted({its[int(round(k))] for k in np.linspace(0, len(its) - 1, min(frames, len(its)))})
    return {k: whole[k] for k in picks}


def history_pictures(run_dir: Path) -> list[tuple[int, Path]]:
    """(iteration, picture) of the design history drawn in ``run_dir``, in iteration order."""
    out = []
    for path in sorted((run_dir / HISTORY_DIR).glob("iteration_*.png")):
        try:
            out.append((int(path.stem.split("_")[1]), path))
        except ValueError:
            continue
    return sorted(out)


def draw_design_history(run_dir: Path, up: str | None = None) -> list[Path]:
    """Small pictures of the design at up to :data:`HISTORY_FRAMES` iterations (from the VTU files
    of every iteration: a run with vtu "every") in ``design_history/``; the old ones are removed."""
    folder = run_dir / HISTORY_DIR
    for old in folder.glob("iteration_*.png"):
        old.unlink()
    made = []
    for k, files in history_iterations(run_dir).items():
        folder.mkdir(exist_ok=True)
        path = folder / f"iteration_{k:04d}.png"
        made.append(render_design(files, path, size=HISTORY_SIZE, title=f"iteration {k}", up=up))
    return made


def _read_json(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _files(run_dir: Path) -> list[str]:
    out = []
    for path in sorted(run_dir.iterdir()):
        if path.name.startswith("."):
            continue  # temporaries of atomic writes
        if path.is_dir():
            out.append(f"{path.name}/ ({sum(1 for p in path.iterdir() if not p.name.startswith('.'))} files)")
        else:
            out.append(path.name)
    return out


def damaged_records(run_dir: str | os.PathLike) -> str | None:
    """One line on the records of the checkpoint that cannot be read, or None when every one can.

    Reads one number of each ``eval_NNNNN.npz`` and, unlike ``Checkpoint.records``, renames nothing.
    """
    paths = sorted(Checkpoint(run_dir).dir.glob("eval_*.npz"))
    bad: list[tuple[int, str]] = []
    for k, path in enumerate(paths):
        try:
            with np.load(path, allow_pickle=False) as data:
                float(data["f"])
        except Exception as err:  # whatever a damaged file raises
            bad.append((k, f"{path.name}: {type(err).__name__}: {' '.join(str(err).split())[:120]}"))
    if not bad:
        return None
    first, why = bad[0]
    if len(bad) == len(paths):
        which = f"none of its {len(paths)} records can be read ({why}"
    else:
        which = f"{len(bad)} of its {len(paths)} records cannot be read (the first, {why}"
    then = f"replays the {first} before it and analyses the rest again" if first else "analyses every design again"
    return f"checkpoint: {which}); --resume {then}"


def report_text(run_dir: str | os.PathLike) -> str:
    """A human summary of a run directory (finished, interrupted or still running), several lines."""
    run_dir = run_directory(run_dir)
    meta = _read_json(Checkpoint(run_dir).meta_path) or {}
    fp = meta.get("fingerprint", {})
    summ = _read_json(run_dir / "summary.json")
    rows = read_history(run_dir)
    lines = [f"run directory: {run_dir}"]
    extra = {k: v for k, v in meta.items() if k not in ("fingerprint", "scale")}
    for k, v in extra.items():  # e.g. a case name stored by the CLI
        lines.append(f"{k}: {v}")
    if fp:
        cons = ", ".join(fp.get("constraints", [])) or "none"
        lines.append(f"problem: objective {fp.get('objective')}, constraints {cons}, normalize {fp.get('normalize')}")
        lines.append(
            f"model: {fp.get('n_cells')} cells, {fp.get('n_dofs')} dofs, {fp.get('n_design')} design variables"
        )
        for d in fp.get("design", []):
            lines.append(
                f"  designed body {d.get('body')}: {d.get('parameterization')}, "
                f"{d.get('n_design')} variables, {d.get('n_cells')} cells, "
                f"volume fraction <= {d.get('volume_fraction')}"
            )
        options = str(fp.get("options", "")).replace("max_iter=0, ", "")  # the fingerprint leaves max_iter out
        lines.append(f"optimizer: {fp.get('optimizer')} {options}".rstrip())
    if summ is not None:
        lines.append(f"status: {summ.get('status')} ({summ.get('message')})")
        lines.append(
            f"iterations: {summ.get('iterations')}; analyses: {summ.get('analyses')} "
            f"(replayed from the checkpoint: {summ.get('replayed', 0)})"
        )
        if "objective" in summ:
            lines.append(
                f"objective: f = {summ['objective']:.6g}, f/|f0| = {summ['normalized_objective']:.6g} "
                f"(|f0| = {summ.get('objective_scale', float('nan')):.6g})"
            )
        failed = summ.get("failed_analysis")
        if failed:  # the first analysis failed: what it reached
            state = failed.get("last_converged_state")
            lines.append(
                f"failed analysis: {failed.get('design')}; "
                + (
                    f"its last converged state (load factor {state['load_factor']:.4g}): {', '.join(state['files'])}"
                    if state
                    else "no load step converged"
                )
            )
        vf = summ.get("volume_fractions", {})
        grey = summ.get("grey_fraction")
    else:
        n_evals = len(list((run_dir / "checkpoint").glob("eval_*.npz")))
        lines.append("status: not finished (no summary.json): running, or interrupted (continue with --resume)")
        last = rows[-1] if rows else None
        lines.append(f"iterations: {last['iteration'] if last else 0}; analyses: {n_evals}")
        if last:
            lines.append(
                f"objective: f = {last['objective_raw']:.6g}, f/|f0| = {last['objective']:.6g} (last iteration)"
            )
        vf = last.get("volume_fractions", {}) if last else {}
        grey = None
    damage = damaged_records(run_dir)
    if damage is not None:
        lines.append(damage)
    if vf:
        lines.append("volume fraction: " + ", ".join(f"{n} {v:.4f}" for n, v in vf.items()))
    lines.append(
        f"grey fraction (0.1 < nu < 0.9): {grey:.4f}"
        if grey is not None
        else "grey fraction: n/a (needs a finished run)"
    )
    for name in rows[0].get("cases", {}) if rows else ():  # a problem with load cases
        first, last = rows[0]["cases"][name], rows[-1]["cases"].get(name, float("nan"))
        lines.append(f"load case {name}: objective {first:.6g} at iteration 0, {last:.6g} at {rows[-1]['iteration']}")
    if rows:
        newton = sum(int(r.get("newton_iterations", 0)) for r in rows)
        timed = rows[1:] or rows  # the first iteration carries the compilation and the full-design solve
        mean = {k: float(np.mean([r["seconds"].get(k, 0.0) for r in timed])) for k in _SECONDS}
        total = float(np.mean([r["seconds"].get("iteration", 0.0) for r in timed]))
        lines.append(f"Newton iterations: {newton} in total over {len(rows)} iterations")
        lines.append(
            "mean seconds per iteration: "
            + ", ".join(f"{k} {v:.3g}" for k, v in mean.items())
            + f" (whole iteration {total:.3g}, over {len(timed)} iterations)"
        )
    lines.append("files: " + ", ".join(_files(run_dir)))
    return "\n".join(lines)
