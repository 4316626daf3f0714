"""What ``report.html`` says in words: the status with the next command, the result as the user
means it, the run's files and the problem that ran.

Each function reads a run directory's own records (``summary.json``, ``checkpoint/meta.json``'s
fingerprint, ``problem.toml``, the problem's summary in words) and returns an HTML fragment;
:mod:`contopt.optimize.report_html` places them on the page.

The problem's summary (bodies, supports, motions, contact interfaces with their nonmortar side, the
design, the objective) is made where the problem is known, by :mod:`contopt.cases.problem_summary`,
and kept in the run directory: ``checkpoint/problem_summary.json`` (:data:`PROBLEM_SUMMARY`) of an
optimization, the ``"problem"`` entry of a forward run's ``summary.json``. Each is a list of
``{"topic": ..., "text": ...}``; :func:`problem_sentences` shows it, or says it was not recorded.
"""

from __future__ import annotations

import html
import json
import re
import shlex
from pathlib import Path

#: where an optimization's run directory keeps the problem's summary in words (written by contopt.cases)
PROBLEM_SUMMARY = Path("checkpoint") / "problem_summary.json"

#: the files a run directory may hold that a user opens next, with what each is for
RUN_FILES = (
    ("design.stl", "the design's closed surface (CAD, printing)"),
    ("design.pvd", "every iteration's bodies for ParaView"),
    ("problem.toml", "the problem file that ran"),
    ("history.csv", "one row per iteration"),
    ("summary.json", "the run's result"),
    ("curves.json", "force against displacement along the load path, per support, motion and contact interface"),
    ("ipopt.log", "IPOPT's own log"),
)


def file_links(run_dir: Path) -> str:
    """A list of links to the run's files that exist, relative to the run directory (they work
    when the folder is moved or zipped); '' when there are none."""
    items = [
        f'<li><a href="{html.escape(name)}" data-file="{html.escape(name)}"><code>{html.escape(name)}</code></a>: '
        f"{html.escape(what)}</li>"
        for name, what in RUN_FILES
        if (run_dir / name).is_file()
    ]
    return f'<ul class="files" id="files">{"".join(items)}</ul>' if items else ""


def next_command(command: str | None, *flags: str, valued: tuple = ("--max-iter",)) -> str | None:
    """``command`` (the ``contopt run`` line that made the run) with ``flags`` added in place of any
    ``--resume``, ``--overwrite`` and options ``valued`` (``--max-iter N``) it had; None without a command."""
    if not command:
        return None
    try:
        words = shlex.split(command)
    except ValueError:
        return None
    out: list[str] = []
    skip = False
    for w in words:
        if skip:
            skip = False
            continue
        if w in ("--resume", "--overwrite"):
            continue
        if w in valued:
            skip = True
            continue
        if w.startswith(tuple(f"{v}=" for v in valued)):
            continue
        out.append(w)
    return shlex.join([*out, *flags])


def status_sentence(summary: dict | None, command: str | None, iterations: int | None) -> str:
    """The run's status in words, with the command that goes on from it (HTML)."""
    if summary is None:
        go_on = next_command(command, "--resume")
        tail = f"; continue it with <code>{html.escape(go_on)}</code>" if go_on else "; continue it with --resume"
        return f"Not finished: running now, or interrupted{tail}."
    status, message = summary.get("status"), str(summary.get("message", ""))
    n = summary.get("iterations", iterations)
    if status == "converged":
        return f"Converged after {n} iterations ({html.escape(message)})."
    if status == "max_iter":
        more = max(40, 2 * int(n or 0))
        go_on = next_command(command, "--resume", "--max-iter", str(more))
        tail = f"; continue with <code>{html.escape(go_on)}</code>" if go_on else ""
        return f"Stopped at the iteration limit ({n} iterations) before converging{tail}."
    if status == "failed":
        return f"Failed at iteration {n}: {html.escape(message)}."
    return f"Stopped after {n} iterations: {html.escape(message)}."


def _response_words(name: str) -> str:
    """``strain_energy[slab]`` -> ``strain energy of slab``."""
    m = re.fullmatch(r"(.+?)\[(.+)\]", name)
    base, where = (m[1], m[2]) if m else (name, "")
    words = base.replace("_", " ")
    return f"{words} of {where}" if where else words


def result_sentence(summary: dict | None, fingerprint: dict) -> str:
    """The objective as the user means it: a maximized response as its value and its share of the
    reference design's (``normalize = "full"`` or ``"initial"``), with the material used; '' when
    the run has no summary."""
    if not summary or summary.get("objective") is None:
        return ""
    name = str(fingerprint.get("objective") or summary.get("objective_name") or "objective")
    maximized = name.startswith("-")  # a maximized response is minimized as its negative
    response = _response_words(name[1:] if maximized else name)
    value = -float(summary["objective"]) if maximized else float(summary["objective"])
    scale = summary.get("objective_scale")
    reference = {"full": "the full design's", "initial": "the initial design's"}.get(str(summary.get("normalize")))
    fractions = summary.get("volume_fractions", {})
    material = ", ".join(f"{100 * vf:.1f} % of {body}'s volume" for body, vf in fractions.items())
    sense = "maximized" if maximized else "minimized"
    if reference and scale:
        text = f"{response} ({sense}): {100 * value / float(scale):.1f} % of {reference} ({value:.4g})"
    else:
        text = f"{response} ({sense}): {value:.4g}"
    return html.escape(text + (f", with {material}" if material else "") + ".")


def problem_source(run_dir: Path) -> str:
    """The problem file that ran, collapsed; '' when the run directory keeps none."""
    try:
        text = (run_dir / "problem.toml").read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return ""
    return (
        '<details class="problem" id="problem"><summary><code>problem.toml</code>: the problem that ran '
        f"(click to show)</summary><pre>{html.escape(text)}</pre></details>"
    )


def recorded_summary(run_dir: Path) -> list | None:
    """The problem's summary an optimization's run directory keeps (:data:`PROBLEM_SUMMARY`), or None."""
    try:
        return json.loads((run_dir / PROBLEM_SUMMARY).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def problem_sentences(sentences) -> str:
    """The problem's summary in words (a list of ``{"topic", "text"}``) as HTML; a note saying it was
    not recorded when there is none (a run made before contopt recorded it, or from Python without
    :mod:`contopt.cases`) or it is not such a list."""
    items = (
        [s for s in sentences if isinstance(s, dict) and isinstance(s.get("text"), str)]
        if isinstance(sentences, list)
        else []
    )
    if not items:
        return (
            '<p class="note" id="problem-summary">The problem\'s summary in words was not recorded in this run '
            "directory (a run made before contopt kept it, or one started from Python without a problem file).</p>"
        )
    shown = "".join(
        f'<li data-topic="{html.escape(str(s.get("topic", "")))}">{html.escape(s["text"])}</li>' for s in items
    )
    return f'<ul class="problem-summary" id="problem-summary">{shown}</ul>'
