"""An interactive 3D view of a :class:`contopt.io.scene.Scene` that a browser opens from a file.

:func:`scene_data` encodes the scene as JSON with every array as base64 of its little-endian
bytes (points, displacement and values float32, triangles uint16 or uint32, the colour map 256
RGB uint8); :func:`viewer_html` returns the HTML of two views (the design: iso-surfaces in the
reference configuration; the deformed state coloured by the scene's values, with a colour bar),
the embedded data and the viewer script (``webview.js``, vanilla WebGL 1): no server, no
network, no library. Mouse: left drag orbits, right drag or shift + drag pans, the wheel zooms,
a double click resets; a checkbox per surface shows or hides it.
"""

from __future__ import annotations

import base64
import json
from importlib import resources
from typing import Any

import numpy as np

from contopt.io.render import PRESSURE_CMAP
from contopt.io.scene import Scene

#: the id of the <script type="application/json"> holding the scene
SCENE_ID = "contopt-scene"
#: the two views: id, whether displaced, whether coloured by the values, and per role of a surface:
#: shown at first, plain colour (RGB 0..1), opacity, coloured by its values (when it has them);
#: plain_opacity: the opacity of a surface without values in a coloured view
_GREY, _SOLID = (0.62, 0.64, 0.67), (0.80, 0.20, 0.14)
VIEWS: tuple[dict[str, Any], ...] = (
    {
        "id": "design",
        "deformed": False,
        "colour_by_values": False,
        "styles": {
            "iso": {"visible": True, "color": _SOLID, "opacity": 1.0, "values": False},
            "domain": {"visible": True, "color": _GREY, "opacity": 0.15, "values": False},
            "body": {"visible": True, "color": _GREY, "opacity": 0.35, "values": False},
        },
    },
    {
        "id": "deformed",
        "deformed": True,
        "colour_by_values": True,
        "styles": {
            "iso": {"visible": True, "color": _GREY, "opacity": 1.0, "values": True},
            "domain": {"visible": False, "color": _GREY, "opacity": 0.12, "values": False},
            "body": {"visible": True, "color": _GREY, "opacity": 1.0, "values": True, "plain_opacity": 0.4},
        },
    },
)
_VALUE_LABELS = {"contact_pressure": "contact pressure", "displacement_magnitude": "displacement magnitude"}


def _b64(array: np.ndarray, dtype) -> str:
    return base64.b64encode(np.ascontiguousarray(array, dtype=np.dtype(dtype).newbyteorder("<")).tobytes()).decode()


def decode_array(text: str, dtype, shape) -> np.ndarray:
    """The array of a base64 field of :func:`scene_data` (for tests and tools)."""
    return np.frombuffer(base64.b64decode(text), dtype=np.dtype(dtype).newbyteorder("<")).reshape(shape)


def colour_map(name: str = PRESSURE_CMAP, n: int = 256) -> np.ndarray:
    """(n, 3) uint8 RGB samples of a matplotlib colour map, low to high."""
    from matplotlib import colormaps

    return np.round(colormaps[name](np.linspace(0.0, 1.0, n))[:, :3] * 255).astype(np.uint8)


def mesh_label(body: str, role: str, level: float) -> str:
    """What the checkbox of a surface says."""
    return {"iso": f"{body} (nu \u2265 {level:g})", "domain": f"{body}: design domain"}.get(role, body)


def scene_data(scene: Scene) -> dict:
    """The scene as JSON-able data (see the module docstring); array lengths in ``n_points``, ``n_triangles``."""
    meshes = []
    for m in scene.meshes:
        wide = len(m.points) > 65535  # WebGL 1 draws uint16 indices everywhere, uint32 with an extension
        meshes.append(
            {
                "body": m.body,
                "role": m.role,
                "label": mesh_label(m.body, m.role, scene.level),
                "n_points": int(len(m.points)),
                "n_triangles": int(len(m.triangles)),
                "triangles_before": int(m.triangles_before),
                "index_bytes": 4 if wide else 2,
                "points": _b64(m.points, np.float32),
                "displacement": _b64(m.displacement, np.float32),
                "values": None if m.values is None else _b64(m.values, np.float32),
                "triangles": _b64(m.triangles, np.uint32 if wide else np.uint16),
            }
        )
    return {
        "level": scene.level,
        "value_name": scene.value_name,
        "value_label": _VALUE_LABELS.get(scene.value_name, scene.value_name),
        "value_range": [float(v) for v in scene.value_range],
        "lut": _b64(colour_map(), np.uint8),
        "max_triangles": scene.max_triangles,
        "meshes": meshes,
        "views": list(VIEWS),
    }


def viewer_script() -> str:
    """The viewer's JavaScript (package data ``contopt/io/webview.js``)."""
    return resources.files("contopt.io").joinpath("webview.js").read_text(encoding="utf-8")


def _inline(text: str) -> str:
    """Text safe inside <script>: no "</" closes the element early."""
    return text.replace("</", "<\\/")


def viewer_html(scene: Scene, titles: dict[str, str]) -> str:
    """The HTML of the views, their data and the script, to embed in a page (with :data:`VIEWER_CSS`).

    titles : view id ("design", "deformed") -> its heading, as HTML (the caller escapes plain text)
    """
    data = json.dumps(scene_data(scene), separators=(",", ":"))
    panels = "".join(
        f'<figure class="cv-panel"><figcaption>{titles[v["id"]]}</figcaption>'
        f'<div class="cv-view" data-view="{v["id"]}"></div></figure>'
        for v in VIEWS
    )
    return (
        f'<div class="cv-grid">{panels}</div>\n'
        f'<script type="application/json" id="{SCENE_ID}">{_inline(data)}</script>\n'
        f"<script>\n{_inline(viewer_script())}\n</script>\n"
    )


#: the style sheet of the views (the page includes it in its <style>)
VIEWER_CSS = """
.cv-grid { display: grid; grid-template-columns: repeat(auto-fit, minmax(420px, 1fr)); gap: 16px; }
.cv-panel { margin: 0; border: 1px solid #d8dbe0; border-radius: 6px; background: #fff; padding: 8px; }
.cv-panel figcaption { font-weight: 600; margin-bottom: 6px; }
.cv-canvas { width: 100%; height: 440px; display: block; border-radius: 4px; cursor: grab; touch-action: none; }
.cv-controls { display: flex; flex-wrap: wrap; gap: 6px 16px; align-items: center; margin-top: 6px; font-size: 14px; }
.cv-controls .cv-scale { width: 4.5em; }
.cv-colourbar { margin-top: 8px; font-size: 13px; }
.cv-ramp { height: 14px; border: 1px solid #999; }
.cv-ticks { display: flex; justify-content: space-between; }
.cv-bar-title { margin-bottom: 2px; }
.cv-error { color: #b00020; font-weight: 600; }
"""
