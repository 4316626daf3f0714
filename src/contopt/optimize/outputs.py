"""What a run writes besides its checkpoint: the pictures, the design's surface, report.html, and
what a run directory keeps when a write fails.

Each writer here is a convenience: a failure is logged and never ends a run whose results are written.
"""

from __future__ import annotations

import logging
import shutil
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from contopt import extras
from contopt.design.surface import write_design_surfaces
from contopt.optimize import report, report_html
from contopt.optimize.history import read_history

if TYPE_CHECKING:
    from contopt.optimize.problem import DesignNLP

# the driver's logger: these are steps of a run, and users and tests filter the run's messages by it
log = logging.getLogger("contopt.optimize.driver")


def what_was_kept(out: Path) -> str:
    """What a run directory keeps after a failed write, and how to go on."""
    analyses = len(list((out / "checkpoint").glob("eval_*.npz")))
    try:
        rows = len(read_history(out))
    except (OSError, ValueError):
        rows = 0
    if analyses == 0:
        return f"the run stopped and {out} holds no completed analysis; make space and start it again"
    history = f" and the history of {count(rows, 'iteration')}" if rows else ""
    return (
        f"the run stopped; {out} keeps its {count(analyses, 'recorded analysis', 'recorded analyses')}"
        f"{history}, whole; make space and continue with --resume, which replays them"
    )


def count(n: int, one: str, many: str | None = None) -> str:
    return f"{n} {one if n == 1 else (many or one + 's')}"


#: what a run writes besides its checkpoint (removed when a fresh run starts in the directory)
OUTPUTS = (
    "vtu",
    "design.pvd",
    "history.json",
    "history.csv",
    "convergence.png",
    "summary.json",
    "design.png",
    "deformed.png",
    "pressure_history.png",
    "curves.json",
    "curves.png",
    "design_history",
    "report.html",
    "design.stl",
    "cases",
)
#: the surface of the final design (``design_<body>.stl`` per body when several are designed)
SURFACE_FILE = "design.stl"


def write_report_page(out: Path) -> None:
    """``report.html`` of the finished run; a failure is logged and never ends the run."""
    if not extras.installed("viz"):  # its 3D views need PyVista; draw_pictures said so
        log.debug(extras.missing("viz", "report.html skipped: it needs"))
        return
    try:
        report_html.write_report_html(out)
    except Exception as err:  # like the pictures: a convenience, the results stay whatever happens here
        log.warning("report.html of %s not written (%s: %s); the results are kept", out, type(err).__name__, err)


def draw_pictures(out: Path, up: str | None = None) -> dict:
    """The run's pictures ({key: file relative to ``out``}); a failure is logged and never ends the run.

    Without the viz extra, one line says that pictures and report.html were skipped and how to get them.
    """
    if not extras.installed("viz"):
        log.warning(
            "%s; the results (VTU, CSV, JSON, STL) are written, and `contopt report %s` draws them once it is there",
            extras.missing("viz", "pictures and report.html skipped: they need"),
            out,
        )
        return {}
    try:
        made = report.make_pictures(out, up=up)
    except Exception as err:  # a picture is a convenience: the results stay whatever the renderer does
        log.warning("pictures of %s not made (%s: %s); the results are kept", out, type(err).__name__, err)
        return {}
    return {key: str(Path(path).relative_to(out)) for key, path in made.items()}


def write_surface(out: Path, nlp: DesignNLP, x: np.ndarray) -> dict:
    """Write the final design's surface (:mod:`contopt.design.surface`); {body: its numbers and file}.

    Like the pictures, a failure is logged and never ends the run.
    """
    try:
        made = write_design_surfaces(nlp.space, nlp.design_x(x), nlp.system.disc, out / SURFACE_FILE)
    except Exception as err:  # a convenience: the results stay whatever the surface extraction does
        log.warning("design surface of %s not made (%s: %s); the results are kept", out, type(err).__name__, err)
        return {}
    for m, path in made:
        log.info("design surface %s: %s", path, m.line())
    return {m.body: {**m.summary(), "file": str(Path(path).relative_to(out))} for m, path in made}


def clear_outputs(out: Path) -> None:
    for path in out.glob("design_*.stl"):
        path.unlink()
    for name in OUTPUTS:
        path = out / name
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()
