"""``report.html`` of a ``contopt forward`` run: the status, the problem, the curves and the files.

A forward run has no design, no optimizer and no checkpoint: its directory holds ``summary.json``
(with ``"kind": "forward"``), ``curves.json``, ``<case>.pvd`` and one VTU per body and load
step. :func:`write_forward_report` draws ``curves.png`` and writes the page (atomically) with the
same look as an optimization's (:mod:`contopt.optimize.report_html`): the status in words with
the command that goes on, the case and its problem in words (``summary.json``'s ``"problem"``,
:mod:`contopt.optimize.report_story`), a summary table, the force-displacement curves along the
load path, links to the files and the 3D view of the last load step.
"""

from __future__ import annotations

import html
import json
import logging
import os
from pathlib import Path

from contopt.io.plots import plot_curves
from contopt.io.scene import MAX_TRIANGLES, check_max_triangles
from contopt.io.vtk import read_pvd
from contopt.optimize.curves import CURVES_NAME, read_curves
from contopt.optimize.history import atomic_write_text
from contopt.optimize.report_html import REPORT_NAME, page_start, views
from contopt.optimize.report_sections import curves_section
from contopt.optimize.report_story import next_command, problem_sentences

log = logging.getLogger(__name__)

#: the summary keys shown in the table, with their labels
_ROWS = (
    ("case", "case"),
    ("description", "description"),
    ("converged", "converged"),
    ("load_steps", "load steps"),
    ("newton_iterations", "Newton iterations"),
    ("cells", "cells"),
    ("dofs", "dofs"),
    ("strain_energy", "strain energy"),
    ("max_displacement", "largest displacement component"),
    ("contact_force", "contact force per interface"),
    ("friction_force", "friction force per interface"),
    ("seconds", "seconds"),
)


def forward_summary(path: str | os.PathLike) -> dict | None:
    """The ``summary.json`` of a forward run directory, or None when ``path`` is not one."""
    try:
        data = json.loads((Path(path) / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and data.get("kind") == "forward" else None


def _pvd(run_dir: Path, summ: dict) -> Path:
    return run_dir / Path(str(summ.get("pvd", f"{summ.get('case', 'solution')}.pvd"))).name


def last_step_files(run_dir: Path, summ: dict) -> list[Path]:
    """The VTU file of each body at the last load step listed in the run's ``.pvd``."""
    try:
        entries = read_pvd(_pvd(run_dir, summ))
    except (OSError, ValueError) as err:
        log.info("no 3D view of %s: %s", run_dir, err)
        return []
    last: dict[int, tuple[float, Path]] = {}
    for time, part, path in entries:
        if part not in last or time >= last[part][0]:
            last[part] = (time, path)
    files = [last[p][1] for p in sorted(last)]
    return files if all(f.exists() for f in files) else []


def status_sentence(summ: dict) -> str:
    """The forward run's status in words, with the command that goes on (HTML)."""
    steps = summ.get("load_steps")
    if summ.get("converged"):
        return (
            f"Converged: the whole load in {steps} load steps, {summ.get('newton_iterations')} Newton iterations, "
            f"{float(summ.get('seconds', 0.0)):.1f} s."
        )
    more = max(8, 2 * int(steps or 0))
    again = next_command(summ.get("command"), "--steps", str(more), valued=("--steps",))
    tail = f" Try smaller steps: <code>{html.escape(again)}</code>." if again else ""
    return (
        f"Failed after {steps} converged load steps: {html.escape(str(summ.get('error', '')).splitlines()[0])}. "
        f"The converged steps are in <code>{html.escape(_pvd(Path(), summ).name)}</code>.{tail}"
    )


def _links(run_dir: Path, summ: dict) -> str:
    names = [
        (_pvd(run_dir, summ).name, "every load step's bodies for ParaView"),
        ("summary.json", "the run's result"),
        (CURVES_NAME, "force against displacement along the load path, per support, motion and contact interface"),
    ]
    items = [
        f'<li><a href="{html.escape(n)}" data-file="{html.escape(n)}"><code>{html.escape(n)}</code></a>: '
        f"{html.escape(what)}</li>"
        for n, what in names
        if (run_dir / n).is_file()
    ]
    return f'<ul class="files" id="files">{"".join(items)}</ul>'


def _table(summ: dict) -> str:
    rows = []
    for key, label in _ROWS:
        if key not in summ:
            continue
        value = summ[key]
        shown = ", ".join(f"{v:.6g}" for v in value) if isinstance(value, list) and key == "contact_force" else value
        if isinstance(value, float):
            shown = f"{value:.6g}"
        rows.append(
            f'<tr><th>{html.escape(label)}</th><td data-key="{key}" data-value="{html.escape(json.dumps(value))}">'
            f"{html.escape(str(shown))}</td></tr>"
        )
    return f'<table class="summary" id="summary">{"".join(rows)}</table>'


def forward_report_html(run_dir: str | os.PathLike, max_triangles: int = MAX_TRIANGLES) -> str:
    """The page of a forward run directory as a string."""
    run_dir = Path(run_dir)
    summ = forward_summary(run_dir)
    if summ is None:
        raise ValueError(f"{run_dir} is not a forward run directory: no summary.json of kind 'forward'")
    max_triangles = check_max_triangles(max_triangles)
    title = f"contopt forward: {summ.get('case', run_dir.name)}"
    status = "converged" if summ.get("converged") else "failed"
    command = summ.get("command")
    problem = f"{html.escape(str(summ.get('case')))}: {html.escape(str(summ.get('description', '')))}" + (
        f"; ran as <code>{html.escape(command)}</code>" if command else ""
    )
    return f"""{page_start(title, status, status_sentence(summ))}
<h2>Problem</h2>
<p class="story" id="problem">{problem}</p>
{problem_sentences(summ.get("problem"))}
<h2>Files</h2>
{_links(run_dir, summ)}
<h2>Summary</h2>
{_table(summ)}
<h2>Force and displacement along the load path</h2>
{curves_section(run_dir)}
<h2>3D view</h2>
{views(run_dir, max_triangles, last_step_files(run_dir, summ))}
</main></body></html>
"""


def write_forward_report(run_dir: str | os.PathLike, max_triangles: int = MAX_TRIANGLES) -> Path:
    """Draw ``curves.png`` (from ``curves.json``) and write ``report.html`` of a forward run; its path."""
    run_dir = Path(run_dir)
    curves = read_curves(run_dir)
    if curves is not None:
        try:
            plot_curves(curves, run_dir / "curves.png")
        except ValueError as err:  # nothing to draw
            log.info("no curves.png: %s", err)
    path = run_dir / REPORT_NAME
    atomic_write_text(path, forward_report_html(run_dir, max_triangles))
    return path
