"""report.html in a real headless browser: it loads offline without errors and its WebGL views draw.

Drives the system's chromium (Debian package ``chromium``, installed by scripts/setup-system.sh)
with Playwright (the ``dev`` extra), offline, with a fresh profile, WebGL through SwiftShader
(software; no GPU needed). The pixels are read back twice: with ``gl.readPixels`` of each view's
canvas and from a screenshot of the page as a person sees it. Without chromium the test fails
with what to install, unless this machine cannot install it itself (not root, or no apt-get):
then it is skipped and says so.
"""

import base64
import io
import os
import shutil

import matplotlib.image as mpimg
import numpy as np
import pytest
from _report_page import ReportPage  # tests/optimize/_report_page.py

from contopt.io.scene import Scene, SceneMesh
from contopt.io.webview import VIEWER_CSS, viewer_html

#: chromium headless, nothing from the network, WebGL by SwiftShader
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]
#: the views' background (gl.clearColor 0.965, 0.969, 0.976)
BACKGROUND = np.array([246, 247, 249])
_CANVAS = '.cv-view[data-view="{}"] canvas'
_READ_PIXELS = """(selector) => {
  const c = document.querySelector(selector), gl = c.getContext("webgl");
  const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight, px = new Uint8Array(w * h * 4);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
  let s = "";
  for (let i = 0; i < px.length; i += 32768) s += String.fromCharCode.apply(null, px.subarray(i, i + 32768));
  return {w: w, h: h, data: btoa(s)};  // base64: a million numbers as JSON would take seconds
}"""
_NEXT_FRAME = "() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))"


def _chromium() -> str:
    """The chromium executable, or a failure (a skip only where the set-up cannot install it)."""
    given = os.environ.get("CONTOPT_CHROMIUM")
    if given:
        if not os.access(given, os.X_OK):
            pytest.fail(f"CONTOPT_CHROMIUM={given} is not an executable; point it at chromium or unset it")
        return given
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        if shutil.which(name):
            return shutil.which(name)
    if hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("apt-get"):
        pytest.fail(
            "chromium is not installed: run `bash scripts/setup-system.sh` (apt-get install chromium; "
            "`make test` runs it) to test report.html in a browser"
        )
    pytest.skip(
        "chromium is not installed and this machine cannot install it by itself (not root, or no apt-get: "
        "not Debian/Ubuntu); install chromium (or set CONTOPT_CHROMIUM) to test report.html in a browser"
    )


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    """A Playwright browser context: system chromium, offline, fresh user-data-dir."""
    try:
        from playwright.sync_api import Error, sync_playwright
    except ImportError:
        pytest.fail("playwright is not installed: pip install -e '.[dev]' (`make test` does) to test report.html")
    executable = _chromium()
    profile = tmp_path_factory.mktemp("chromium-profile")
    with sync_playwright() as pw:
        try:
            context = pw.chromium.launch_persistent_context(
                str(profile),
                executable_path=executable,
                headless=True,
                args=CHROMIUM_ARGS,
                offline=True,
                viewport={"width": 1400, "height": 1000},
            )
        except Error as err:
            pytest.fail(f"chromium ({executable}) does not start: {str(err).splitlines()[0]}")
        context.set_default_timeout(60_000)
        yield context
        context.close()


class Opened:
    """A page of ``path`` with its console errors, page errors and requests recorded."""

    def __init__(self, context, path):
        self.errors, self.requests = [], []
        self.page = page = context.new_page()
        page.on("console", lambda m: self.errors.append(f"console.{m.type}: {m.text}") if m.type == "error" else None)
        page.on("pageerror", lambda e: self.errors.append(f"page error: {e}"))
        page.on("request", lambda r: self.requests.append(r.url))
        page.goto(path.as_uri())
        page.wait_for_function("window.contoptReport && window.contoptReport.ready")
        page.evaluate(_NEXT_FRAME)

    def status(self) -> dict:
        return self.page.evaluate("window.contoptReport")

    def pixels(self, view: str) -> np.ndarray:
        """(h, w, 3) uint8 of the view's WebGL drawing buffer (gl.readPixels; rows bottom up)."""
        got = self.page.evaluate(_READ_PIXELS, _CANVAS.format(view))
        data = np.frombuffer(base64.b64decode(got["data"]), dtype=np.uint8)
        return data.reshape(got["h"], got["w"], 4)[..., :3]

    def screenshot(self, view: str) -> np.ndarray:
        """(h, w, 3) uint8 of the view's canvas as composited on the page."""
        png = self.page.locator(_CANVAS.format(view)).screenshot()
        return np.round(mpimg.imread(io.BytesIO(png), format="png")[..., :3] * 255).astype(np.uint8)

    def redraw(self) -> None:
        self.page.evaluate(_NEXT_FRAME)


def _drawn(img: np.ndarray) -> float:
    """Share of the pixels that are not the background."""
    return float(np.mean(np.abs(img.astype(int) - BACKGROUND).max(axis=-1) > 8))


def _reddish(img: np.ndarray) -> int:
    """Pixels of the red/orange end of the colours (iso-surface red, high contact pressure)."""
    r, g, b = (img[..., k].astype(int) for k in range(3))
    return int(np.sum((r > g + 60) & (r > b + 60)))


def _changed(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean(np.abs(a.astype(int) - b.astype(int)).max(axis=-1) > 8)) if a.shape == b.shape else 1.0


@pytest.fixture(scope="module")
def opened(browser, report_run):
    out, _ = report_run
    return Opened(browser, out / "report.html"), ReportPage((out / "report.html").read_text(encoding="utf-8"))


def test_loads_offline_without_errors_and_draws(opened):
    page, parsed = opened
    assert page.errors == [] and page.status()["errors"] == []
    assert all(url.startswith(("file:", "data:")) for url in page.requests), page.requests
    meshes = parsed.scene()["meshes"]
    status = page.status()["views"]
    assert status["design"]["triangles"] == sum(m["n_triangles"] for m in meshes)
    assert status["deformed"]["triangles"] == sum(m["n_triangles"] for m in meshes if m["role"] != "domain")
    for view in ("design", "deformed"):
        gl, shot = page.pixels(view), page.screenshot(view)
        assert np.abs(gl[0, 0].astype(int) - BACKGROUND).max() <= 2  # a corner: the background
        assert _drawn(gl) > 0.05 and _drawn(shot) > 0.05, view
    assert _reddish(page.pixels("design")) > 500  # the iso-surface nu = 0.5 in red
    assert _reddish(page.pixels("deformed")) > 50  # pressure colours beyond the pale end of the map
    bar = page.page.locator(".cv-colourbar")
    assert bar.count() == 1 and "contact pressure" in bar.inner_text()


def test_mouse_and_toggles_change_the_picture(opened):
    page, _ = opened
    p = page.page
    before = page.pixels("design")
    box = p.locator(_CANVAS.format("design")).bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    p.mouse.move(cx, cy)
    p.mouse.down()
    p.mouse.move(cx + 120, cy + 40, steps=6)
    p.mouse.up()
    page.redraw()
    assert _changed(before, page.pixels("design")) > 0.02  # orbited
    p.mouse.move(cx, cy)
    p.mouse.wheel(0, 400)
    page.redraw()
    p.mouse.dblclick(cx, cy)
    page.redraw()
    assert _changed(before, page.pixels("design")) < 0.002  # reset to the first view
    iso = p.locator('.cv-view[data-view="design"] input[type=checkbox][data-role="iso"]')
    iso.uncheck()
    page.redraw()
    assert _reddish(page.pixels("design")) == 0  # without the iso-surface nothing is red
    iso.check()
    page.redraw()
    deformed = page.pixels("deformed")
    p.locator(".cv-scale").fill("0")
    p.locator(".cv-scale").dispatch_event("change")
    page.redraw()
    assert page.status()["views"]["deformed"]["scale"] == 0
    assert _changed(deformed, page.pixels("deformed")) > 0.005  # the reference configuration
    assert page.errors == []


def test_wide_meshes_draw_with_uint32_indices(browser, tmp_path):
    """Over 65535 vertices a mesh needs 32-bit indices (OES_element_index_uint)."""
    n = 300
    x, y = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n), indexing="ij")
    points = np.column_stack([x.ravel(), y.ravel(), 0.05 * np.sin(6 * x.ravel())]).astype(np.float32)
    k = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    tri = np.concatenate([np.column_stack([k, k + n, k + 1]), np.column_stack([k + 1, k + n, k + n + 1])])
    mesh = SceneMesh(
        body="sheet",
        role="body",
        points=points,
        triangles=tri,
        displacement=0 * points,
        values=points[:, 0].copy(),
        triangles_before=len(tri),
    )
    scene = Scene(
        meshes=(mesh,),
        value_name="contact_pressure",
        value_range=(0.0, 1.0),
        level=0.5,
        files=(),
        max_triangles=len(tri),
    )
    path = tmp_path / "wide.html"
    path.write_text(
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><style>{VIEWER_CSS}</style></head><body>"
        + viewer_html(scene, {"design": "design", "deformed": "deformed"})
        + "</body></html>"
    )
    assert ReportPage(path.read_text()).scene()["meshes"][0]["index_bytes"] == 4
    page = Opened(browser, path)
    assert page.errors == [] and page.status()["views"]["deformed"]["triangles"] == len(tri)
    assert _drawn(page.pixels("deformed")) > 0.05 and _reddish(page.pixels("deformed")) > 50
