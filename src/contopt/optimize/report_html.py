"""``report.html``: one self-contained page about a run directory.

:func:`write_report_html` writes ``DIR/report.html`` (atomically) with the status in words, the
problem (its summary in words, kept by :mod:`contopt.cases`, and the problem file, collapsed:
:mod:`contopt.optimize.report_story`), links to the run's files, the summary table (from
``summary.json``, or from the last history row of a run that has not finished), the run's
pictures embedded as base64 PNG (``design.png``, ``deformed.png``, ``convergence.png``,
``pressure_history.png`` where present), the force-displacement curves along the load path at
the first and the last design and the design history (:mod:`contopt.optimize.report_sections`)
and an interactive 3D view of the last VTU files
(:mod:`contopt.io.scene`, :mod:`contopt.io.webview`): the design's iso-surface ``nu = 0.5`` and
the deformed bodies coloured by contact pressure. Everything is in the one file: a browser opens
it with no server and no network. The optimization driver writes it at the end of every run and
``contopt report DIR`` writes it again.

Each cell of the summary table carries ``data-key`` (the summary key, nested keys joined by ".")
and ``data-value`` (the value as JSON), so that a program can read the table back.
"""

from __future__ import annotations

import datetime
import html
import json
import logging
import os
import tomllib
from pathlib import Path

from contopt import __version__
from contopt.io.render import last_vtus
from contopt.io.scene import ISO_LEVEL, MAX_TRIANGLES, check_max_triangles, run_scene
from contopt.io.webview import VIEWER_CSS, viewer_html
from contopt.optimize.history import Checkpoint, atomic_write_text, read_history
from contopt.optimize.report import PICTURES, run_directory
from contopt.optimize.report_sections import SECTIONS_CSS, curves_section, history_section, png_source
from contopt.optimize.report_story import (
    file_links,
    problem_sentences,
    problem_source,
    recorded_summary,
    result_sentence,
    status_sentence,
)

log = logging.getLogger(__name__)

#: the page's file name in a run directory
REPORT_NAME = "report.html"
_CAPTIONS = {
    "design": "Design: regions nu \u2265 0.1 (translucent green) and nu \u2265 0.9 (red) of the last design.",
    "sections": "Cuts of the designed bodies across the push direction (20, 50, 80 % of their extent), coloured by nu.",
    "deformed": "Deformed bodies coloured by contact pressure; designed bodies show their cells with nu \u2265 0.5.",
    "stress": "Von Mises stress (of the material there) on the deformed designed cells with nu \u2265 0.5.",
    "convergence": "Objective, constraints (feasible \u2264 0), optimality and design change per iteration.",
    "pressure_history": "Nodal contact pressure of every contact node per iteration, and the normalized objective.",
    "curves": "Force against displacement along the load path at the first and the last design.",
}
_STAGES = ("primal", "adjoint", "design", "optimizer", "output", "iteration")


def _read_json(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _problem_file(run_dir: Path) -> tuple[str | None, str | None]:
    """(case or problem name, command line) from the ``problem.toml`` the CLI keeps in the run directory."""
    path = run_dir / "problem.toml"
    try:
        text = path.read_text(encoding="utf-8")
        data = tomllib.loads(text)
    except (OSError, ValueError):
        return None, None
    command = next((ln[2:].strip() for ln in text.splitlines() if ln.startswith("# contopt ")), None)
    name = data.get("case") or data.get("name")
    return (str(name) if name else None), command


def _fmt(value, digits: int = 6) -> str:
    if isinstance(value, bool) or value is None:
        return str(value)
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def _cell(key: str, value, text: str | None = None) -> str:
    """A table cell that shows ``text`` and carries the value for programs (see the module docstring)."""
    shown = _fmt(value) if text is None else text
    return f'<td data-key="{html.escape(key)}" data-value="{html.escape(json.dumps(value))}">{html.escape(shown)}</td>'


def _summary_rows(summ: dict, fingerprint: dict) -> list[tuple[str, str]]:
    """(label, cell HTML) of a finished run's summary."""
    limits = {d.get("body"): d.get("volume_fraction") for d in fingerprint.get("design", summ.get("design", []))}
    rows = [
        ("status", _cell("status", summ.get("status"), f"{summ.get('status')} ({summ.get('message', '')})")),
        ("optimizer", _cell("optimizer", summ.get("optimizer"))),
        ("iterations", _cell("iterations", summ.get("iterations"))),
        (
            "analyses (replayed from the checkpoint)",
            _cell("analyses", summ.get("analyses"), f"{summ.get('analyses')} ({summ.get('replayed', 0)})"),
        ),
        ("objective f", _cell("objective", summ.get("objective"))),
        ("normalized objective f/|f\u2070|", _cell("normalized_objective", summ.get("normalized_objective"))),
        ("objective scale |f\u2070|", _cell("objective_scale", summ.get("objective_scale"))),
    ]
    for body, vf in summ.get("volume_fractions", {}).items():
        limit = f" (limit {_fmt(limits[body], 4)})" if limits.get(body) is not None else ""
        rows.append((f"volume fraction, {body}", _cell(f"volume_fractions.{body}", vf, f"{vf:.4f}{limit}")))
    for name, g in summ.get("constraints", {}).items():
        rows.append((f"constraint {name} (feasible \u2264 0)", _cell(f"constraints.{name}", g, f"{g:+.3e}")))
    band = summ.get("grey_band", [0.1, 0.9])
    grey = summ.get("grey_fraction")
    rows.append(
        (
            f"grey fraction ({_fmt(band[0])} < nu < {_fmt(band[1])})",
            _cell("grey_fraction", grey, "n/a" if grey is None else f"{grey:.4f}"),
        )
    )
    rows.append(
        ("seconds in total", _cell("seconds_total", summ.get("seconds_total"), _fmt(summ.get("seconds_total"), 4)))
    )
    for stage in _STAGES:
        sec = summ.get("seconds_per_iteration", {}).get(stage)
        if sec is not None:
            rows.append(
                (f"mean seconds per iteration: {stage}", _cell(f"seconds_per_iteration.{stage}", sec, _fmt(sec, 3)))
            )
    return rows


def _unfinished_rows(rows: list[dict], run_dir: Path) -> list[tuple[str, str]]:
    """(label, cell HTML) of a run without ``summary.json``: its last history row."""
    n_evals = len(list((run_dir / "checkpoint").glob("eval_*.npz")))
    out = [
        (
            "status",
            _cell("status", None, "not finished (no summary.json): running, or interrupted (continue with --resume)"),
        ),
        ("analyses", _cell("analyses", n_evals)),
    ]
    if rows:
        last = rows[-1]
        out += [
            ("iterations", _cell("iterations", last["iteration"])),
            ("objective f (last iteration)", _cell("objective", last.get("objective_raw"))),
            ("normalized objective f/|f\u2070| (last iteration)", _cell("normalized_objective", last.get("objective"))),
        ]
        for body, vf in last.get("volume_fractions", {}).items():
            out.append((f"volume fraction, {body}", _cell(f"volume_fractions.{body}", vf, f"{vf:.4f}")))
    return out


def _model_rows(fingerprint: dict) -> list[tuple[str, str]]:
    if not fingerprint:
        return []
    rows = [
        (
            "model",
            _cell(
                "model",
                None,
                f"{fingerprint.get('n_cells')} cells, {fingerprint.get('n_dofs')} dofs, "
                f"{fingerprint.get('n_design')} design variables",
            ),
        )
    ]
    rows.append(
        (
            "objective (minimized)",
            _cell(
                "objective_name",
                fingerprint.get("objective"),
                f"{fingerprint.get('objective')}, normalize {fingerprint.get('normalize')}",
            ),
        )
    )
    for d in fingerprint.get("design", []):
        rows.append(
            (
                f"design of {d.get('body')}",
                _cell(
                    f"design.{d.get('body')}",
                    None,
                    f"{d.get('parameterization')}: {d.get('n_design')} variables over {d.get('n_cells')} cells, "
                    f"G nonzeros {d.get('G_nonzeros')}",
                ),
            )
        )
    return rows


def _table(run_dir: Path, fingerprint: dict) -> tuple[str, dict | None]:
    """The summary table's HTML and the summary (None for a run that has not finished)."""
    summ = _read_json(run_dir / "summary.json")
    case, command = _problem_file(run_dir)
    rows = [("case", _cell("case", case, case or "(not recorded: the run did not come from `contopt run`)"))]
    if command:
        rows.append(("command", _cell("command", command)))
    rows.append(("run directory", _cell("run_directory", str(run_dir.resolve()))))
    if summ is not None:
        rows += _summary_rows(summ, fingerprint)
    else:
        rows += _unfinished_rows(read_history(run_dir), run_dir)
    rows += _model_rows(fingerprint)
    body = "\n".join(f"<tr><th>{html.escape(label)}</th>{cell}</tr>" for label, cell in rows)
    return f'<table class="summary" id="summary">\n{body}\n</table>', summ


def _picture(run_dir: Path, key: str) -> str:
    """A figure with ``<key>.png`` embedded as base64, or '' when the run has none."""
    src = png_source(run_dir / f"{key}.png")
    if src is None:
        return ""
    return (
        f'<figure class="picture"><img src="{src}" alt="{key}.png" data-picture="{key}">'
        f"<figcaption><code>{key}.png</code>: {html.escape(_CAPTIONS[key])}</figcaption></figure>"
    )


def _scene_notes(scene, files: list[Path], run_dir: Path) -> str:
    shown = ", ".join(f"<code>{html.escape(os.path.relpath(f, run_dir))}</code>" for f in files)
    cut = [m for m in scene.meshes if m.decimated]
    if cut:
        what = "; ".join(
            f"{html.escape(m.body)} ({m.role}): {m.triangles_before:,} \u2192 {len(m.triangles):,}" for m in cut
        )
        size = (
            f"Decimated to stay under {scene.max_triangles:,} triangles in all "
            f"(vtkDecimatePro, vertices and their values kept): {what} triangles."
        )
    else:
        size = f"Not decimated: {scene.n_triangles:,} triangles in all (the cap is {scene.max_triangles:,})."
    return (
        f'<p class="note">From the last VTU of each body: {shown}. {size} Drag to rotate, right-drag or '
        "shift-drag to pan, scroll to zoom, double-click to reset; the checkboxes show or hide each surface, "
        "<i>displacement \u00d7</i> magnifies the deformation.</p>"
    )


def views(run_dir: Path, max_triangles: int, files: list[Path] | None = None) -> str:
    """The 3D section's HTML: the views of ``files`` (default: the last VTU of each body of the run),
    or why there are none."""
    files = last_vtus(run_dir) if files is None else files
    if not files:
        return (
            '<p class="note">No VTU files in this run directory (a run with <code>--vtu none</code> and '
            "<code>--no-plot</code> writes none), so there is no 3D view.</p>"
        )
    try:
        scene = run_scene(files, level=ISO_LEVEL, max_triangles=max_triangles)
    except Exception as err:  # the rest of the page is still worth having
        log.warning("3D view of %s not made (%s: %s)", run_dir, type(err).__name__, err)
        return f'<p class="note">The 3D view could not be made: {html.escape(f"{type(err).__name__}: {err}")}</p>'
    lo, hi = scene.value_range
    what = (
        "contact pressure"
        if scene.value_name == "contact_pressure"
        else "displacement magnitude (the model has no contact)"
    )
    titles = {
        "design": f"Design: iso-surface nu = {scene.level:g} of the last design (reference configuration)",
        "deformed": f"Deformed configuration coloured by {what}, {lo:.3g} to {hi:.3g}",
    }
    return viewer_html(scene, {k: html.escape(v) for k, v in titles.items()}) + _scene_notes(scene, files, run_dir)


PAGE_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif; color: #1d2330;
       background: #eef0f3; margin: 0; }
main { max-width: 1320px; margin: 0 auto; padding: 16px 24px 40px; }
h1 { font-size: 24px; margin: 8px 0 2px; } h2 { font-size: 19px; margin: 28px 0 10px; }
.sub { color: #5a6270; margin: 0 0 12px; font-size: 14px; }
table.summary { border-collapse: collapse; background: #fff; font-size: 14px; min-width: 60%; }
table.summary th, table.summary td { border: 1px solid #d8dbe0; padding: 4px 10px; text-align: left;
                                     vertical-align: top; }
table.summary th { background: #f6f7f9; font-weight: 600; white-space: nowrap; }
.pictures { display: grid; grid-template-columns: repeat(auto-fit, minmax(480px, 1fr)); gap: 16px; }
figure.picture { margin: 0; background: #fff; border: 1px solid #d8dbe0; border-radius: 6px; padding: 8px; }
figure.picture img { width: 100%; height: auto; display: block; }
figure.picture figcaption, .note { font-size: 13px; color: #5a6270; }
code { font-size: 90%; }
p.story { font-size: 16px; margin: 6px 0; }
ul.problem-summary { font-size: 15px; margin: 6px 0 10px; padding-left: 22px; max-width: 1100px; }
ul.problem-summary li { margin: 3px 0; }
details.problem pre { background: #fff; border: 1px solid #d8dbe0; padding: 8px; overflow-x: auto; font-size: 12px; }
"""


def report_html(run_dir: str | os.PathLike, max_triangles: int = MAX_TRIANGLES) -> str:
    """The page of a run directory (finished, interrupted or running) as a string."""
    run_dir = run_directory(run_dir)
    max_triangles = check_max_triangles(max_triangles)
    fingerprint = (_read_json(Checkpoint(run_dir).meta_path) or {}).get("fingerprint", {})
    table, summ = _table(run_dir, fingerprint)
    case, command = _problem_file(run_dir)
    status = summ.get("status") if summ else "not finished"
    rows = read_history(run_dir) if summ is None else []
    story = status_sentence(summ, command, rows[-1]["iteration"] if rows else None)
    result = result_sentence(summ, fingerprint)
    files = file_links(run_dir) or '<p class="note">No result files in this run directory yet.</p>'
    problem = problem_source(run_dir) or '<p class="note">No <code>problem.toml</code> in this run directory.</p>'
    title = f"contopt run: {case or run_dir.name}"
    convergence = _picture(run_dir, "convergence") or (
        '<p class="note">No <code>convergence.png</code> (a run with <code>--no-plot</code>); '
        "<code>contopt report DIR</code> draws it.</p>"
    )
    pictures = "".join(_picture(run_dir, k) for k in PICTURES if k not in ("convergence", "curves"))
    return f"""{page_start(title, str(status), story)}
{f'<p class="story" id="result">{result}</p>' if result else ""}
<h2>Problem</h2>
{problem_sentences(recorded_summary(run_dir))}
{problem}
<h2>Files</h2>
{files}
<h2>Summary</h2>
{table}
<h2>Convergence</h2>
{convergence}
<h2>Force and displacement along the load path</h2>
{curves_section(run_dir)}
<h2>Design history</h2>
{history_section(run_dir)}
<h2>3D view</h2>
{views(run_dir, max_triangles)}
<h2>Pictures</h2>
<div class="pictures">{pictures or '<p class="note">No pictures in this run directory.</p>'}</div>
</main></body></html>
"""


def page_start(title: str, status: str, story: str) -> str:
    """A report page up to its status sentence ``story`` (HTML): head, styles, title, status and stamp."""
    stamp = datetime.datetime.now().astimezone().isoformat(timespec="seconds")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{html.escape(title)}</title>
<style>{PAGE_CSS}{VIEWER_CSS}{SECTIONS_CSS}</style></head>
<body><main>
<h1>{html.escape(title)}</h1>
<p class="sub">status <b>{html.escape(status)}</b> &middot; written {stamp} by contopt {__version__}
&middot; one self-contained file: opens without a server or a network</p>
<p class="story" id="status">{story}</p>"""


def write_report_html(run_dir: str | os.PathLike, max_triangles: int = MAX_TRIANGLES) -> Path:
    """Write ``DIR/report.html`` atomically (see the module docstring); returns its path.

    max_triangles : cap on the triangles of the 3D view (all surfaces together; decimated above it)
    """
    run_dir = run_directory(run_dir)
    path = run_dir / REPORT_NAME
    atomic_write_text(path, report_html(run_dir, max_triangles))
    return path
