"""Two sections of ``report.html``: the force-displacement curves and the design history.

:func:`curves_section` shows ``curves.png`` (drawn from ``curves.json``, see
:mod:`contopt.optimize.curves`), a table of where each curve ends and the curves' numbers as JSON
in ``<script type="application/json" id="curves-data">`` (a program, or a test, reads them back).
:func:`history_section` shows the small pictures of ``design_history/`` with a slider that walks
through them. Both are embedded (base64 PNG, inline script): the page still opens offline.
"""

from __future__ import annotations

import base64
import html
import json
import logging
from pathlib import Path

from contopt.optimize.curves import CURVES_NAME, read_curves
from contopt.optimize.report import history_pictures

log = logging.getLogger(__name__)

SECTIONS_CSS = """
.history { background: #fff; border: 1px solid #d8dbe0; border-radius: 6px; padding: 8px; max-width: 760px; }
.history img.frame { width: 100%; height: auto; display: block; }
.history .thumbs { display: flex; gap: 6px; margin-top: 6px; }
.history .thumbs img { width: 110px; height: auto; border: 2px solid transparent; cursor: pointer; }
.history .thumbs img.on { border-color: #c0392b; }
.history input[type=range] { width: 60%; vertical-align: middle; }
table.curves { border-collapse: collapse; background: #fff; font-size: 13px; margin-top: 8px; }
table.curves th, table.curves td { border: 1px solid #d8dbe0; padding: 3px 8px; text-align: left; }
"""

_HISTORY_JS = """
(function () {
  const box = document.getElementById("history");
  if (!box) return;
  const slider = box.querySelector("input[type=range]"), frame = box.querySelector("img.frame");
  const label = box.querySelector(".label"), thumbs = Array.from(box.querySelectorAll(".thumbs img"));
  function show(i) {
    frame.src = thumbs[i].src;
    frame.dataset.iteration = thumbs[i].dataset.iteration;
    label.textContent = "iteration " + thumbs[i].dataset.iteration;
    thumbs.forEach((t, k) => t.classList.toggle("on", k === i));
    slider.value = String(i);
  }
  slider.addEventListener("input", () => show(Number(slider.value)));
  thumbs.forEach((t, k) => t.addEventListener("click", () => show(k)));
})();
"""


def png_source(path: Path) -> str | None:
    """``data:image/png;base64,...`` of a PNG file, or None when it is missing or not a PNG."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        log.warning("%s is not a PNG; left out of report.html", path)
        return None
    return "data:image/png;base64," + base64.b64encode(data).decode()


def _ends(data: dict) -> str:
    """A table of the last point of every curve: per curve set, each motion's force along it and
    each interface's normal force."""
    rows = []
    for entry in data.get("curves", []):
        t = entry.get("load_factor", [0.0])[-1]
        done = "" if entry.get("complete", True) else f" (stopped: {entry.get('error', 'the solve failed')})"
        parts = [
            f"{m['name']}: {m['force_along'][-1]:.4g} at displacement {m['travel'][-1]:.4g}"
            for m in entry.get("motions", [])
            if m["kind"] == "motion"
        ]
        parts += [f"{i['name']}: normal force {i['normal_force'][-1]:.4g}" for i in entry.get("interfaces", [])]
        rows.append(
            f"<tr><th>{html.escape(str(entry.get('label')))}</th><td>{entry.get('steps')} load steps to "
            f"t = {t:.3g}{html.escape(done)}</td><td>{html.escape('; '.join(parts) or '-')}</td></tr>"
        )
    return (
        '<table class="curves"><tr><th>curve set</th><th>path</th><th>at its end</th></tr>' + "".join(rows) + "</table>"
    )


def curves_section(run_dir: Path) -> str:
    """The curves' figure, table and data (see the module docstring), or a note why there are none."""
    data = read_curves(run_dir)
    if data is None:
        return (
            f'<p class="note">No <code>{CURVES_NAME}</code> in this run directory (an optimization writes it '
            "when it draws its pictures: not with <code>--no-plot</code>).</p>"
        )
    src = png_source(run_dir / "curves.png")
    figure = (
        f'<figure class="picture" id="curves"><img src="{src}" alt="curves.png" data-picture="curves">'
        "<figcaption><code>curves.png</code>: each prescribed motion's force along it against its displacement, "
        "each support's reaction against the load factor, each contact interface's force against the first "
        "motion's displacement (or the load factor); one line style per curve set.</figcaption></figure>"
        if src
        else '<p class="note">No <code>curves.png</code>; <code>contopt report DIR</code> draws it.</p>'
    )
    text = json.dumps(data).replace("</", "<\\/")  # no "</script>" inside the script
    return f'{figure}\n{_ends(data)}\n<script type="application/json" id="curves-data">{text}</script>'


def history_section(run_dir: Path) -> str:
    """The design history with its slider, or a note why there is none."""
    frames = [(k, src) for k, path in history_pictures(run_dir) if (src := png_source(path))]
    if not frames:
        return (
            '<p class="note">No design history: it is drawn from the VTU files of every iteration '
            "(<code>--vtu every</code>, the default) of a run of two or more iterations.</p>"
        )
    k_last, src_last = frames[-1]
    thumbs = "".join(
        f'<img src="{src}" alt="iteration {k}" data-iteration="{k}"{" class=on" if k == k_last else ""}>'
        for k, src in frames
    )
    return (
        f'<div class="history" id="history"><img class="frame" src="{src_last}" alt="design" '
        f'data-iteration="{k_last}"><div><input type="range" min="0" max="{len(frames) - 1}" '
        f'value="{len(frames) - 1}" aria-label="iteration"> <span class="label">iteration {k_last}</span></div>'
        f'<div class="thumbs">{thumbs}</div></div>'
        f'<p class="note">The design (nu \u2265 0.1 translucent, nu \u2265 0.9 red) at {len(frames)} iterations, '
        f"from <code>design_history/</code>; drag the slider or click a picture.</p>"
        f"<script>{_HISTORY_JS}</script>"
    )
