"""report.html without a browser: what it shows and embeds, read back from the HTML.

The run (two MMA iterations of the punch-on-block problem, tests/optimize/conftest.py) is
shared with tests/optimize/test_report_browser.py, which opens the page in chromium.
"""

import base64
import html
import json
import logging
import re
import shutil

import meshio
import numpy as np
import pytest
from _cantilever import cantilever_problem  # tests/optimize/_cantilever.py
from _report_page import ReportPage  # tests/optimize/_report_page.py

from contopt.cli import main
from contopt.errors import ConfigError
from contopt.io.render import last_vtus
from contopt.io.webview import decode_array
from contopt.optimize import report_html as report_html_module
from contopt.optimize.driver import OutputOptions, optimize
from contopt.optimize.history import read_history
from contopt.optimize.mma import MMAOptions
from contopt.optimize.report_html import write_report_html
from contopt.optimize.report_story import PROBLEM_SUMMARY

#: the faces of a VTK hexahedron (node positions in the cell)
HEX_FACES = ((0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7))


def _page(run_dir) -> ReportPage:
    return ReportPage((run_dir / "report.html").read_text(encoding="utf-8"))


def _at(data: dict, key: str):
    """summary.json's value at a data-key ("a.b": data["a"]["b"]; b may contain dots)."""
    if key in data:
        return data[key]
    head, _, rest = key.partition(".")
    return data[head][rest]


def test_the_driver_writes_one_self_contained_file(report_run):
    out, _ = report_run
    text = (out / "report.html").read_text(encoding="utf-8")
    page = ReportPage(text)
    assert text.startswith("<!DOCTYPE html>") and text.rstrip().endswith("</html>")
    assert page.external == []  # nothing by URL: no CDN, no file next to it
    assert all("src" not in attrs for attrs, _ in page.scripts)  # scripts inline
    assert "<link" not in text and "@import" not in text
    assert not any(p.name.startswith(".report") for p in out.iterdir())  # the atomic write's temporary is gone


def test_summary_table_equals_summary_json(report_run):
    out, res = report_run
    summary = json.loads((out / "summary.json").read_text())
    cells = _page(out).cells
    expected = {
        "status",
        "optimizer",
        "iterations",
        "analyses",
        "objective",
        "normalized_objective",
        "objective_scale",
        "grey_fraction",
        "seconds_total",
        "volume_fractions.block",
    }
    expected |= {f"constraints.{name}" for name in summary["constraints"]}
    expected |= {f"seconds_per_iteration.{stage}" for stage in summary["seconds_per_iteration"]}
    assert expected <= set(cells)
    for key in expected:
        assert cells[key][0] == _at(summary, key), key
    assert cells["normalized_objective"][1] == f"{res.normalized_objective:.6g}"
    assert cells["iterations"][1] == "2" and cells["status"][1].startswith("max_iter")
    assert cells["volume_fractions.block"][1] == f"{res.volume_fractions[0]:.4f} (limit 0.5)"
    assert cells["grey_fraction"][1] == f"{summary['grey_fraction']:.4f}"
    assert cells["case"][0] is None and "not recorded" in cells["case"][1]  # a run from Python


def test_case_and_command_from_the_problem_file(report_run, tmp_path):
    out = shutil.copytree(report_run[0], tmp_path / "run")
    (out / "problem.toml").write_text('# contopt run blocks.toml --max-iter 2\n# (its flags ...)\nname = "blocks"\n')
    write_report_html(out)
    cells = _page(out).cells
    assert cells["case"] == ("blocks", "blocks")
    assert cells["command"][0] == "contopt run blocks.toml --max-iter 2"


def test_the_status_the_result_and_the_files_in_words(report_run, tmp_path):
    out = shutil.copytree(report_run[0], tmp_path / "run")  # moved: the links are relative
    (out / "problem.toml").write_text('# contopt run blocks.toml --max-iter 2 --overwrite\nname = "blocks"\n')
    summary = json.loads((out / "summary.json").read_text())
    write_report_html(out)
    text = (out / "report.html").read_text(encoding="utf-8")
    page = _page(out)
    assert page.links and all((out / link).is_file() for link in page.links)  # every link resolves
    assert {"problem.toml", "history.csv", "summary.json", "design.pvd"} <= set(page.links)
    assert '<details class="problem"' in text and "name = &quot;blocks&quot;" in text
    assert summary["status"] == "max_iter"  # two MMA iterations: stopped, with the command that goes on
    assert "Stopped at the iteration limit (2 iterations)" in text
    assert "contopt run blocks.toml --resume --max-iter 40" in text
    # the contact problem maximizes the strain energy (minimizes its negative): shown as the positive
    # share of the full design's, with the material used
    share = 100 * -summary["objective"] / summary["objective_scale"]
    assert summary["normalize"] == "full" and share > 0
    assert f"strain energy (maximized): {share:.1f} % of the full design" in text
    assert f"{100 * summary['volume_fraction']:.1f} % of" in text


def _problem_items(text: str) -> dict:
    """{topic: sentence} of the page's problem summary (its list items, unescaped)."""
    block = re.search(r'<ul class="problem-summary" id="problem-summary">(.*?)</ul>', text, re.S)
    assert block is not None, "no problem summary on the page"
    return {t: html.unescape(x) for t, x in re.findall(r'<li data-topic="([^"]*)">(.*?)</li>', block[1], re.S)}


def test_the_problem_in_words_near_the_top(report_run, report_problem, tmp_path):
    """The page says what the problem is: the facts of the problem that ran, before the files and the
    table; a run directory that did not keep the summary says so."""
    out, _ = report_run
    text = (out / "report.html").read_text(encoding="utf-8")
    items = _problem_items(text)
    recorded = json.loads((out / PROBLEM_SUMMARY).read_text(encoding="utf-8"))
    assert items == {s["topic"]: s["text"] for s in recorded}
    problem = report_problem
    model = problem.model
    for body in model.bodies:
        assert f"{body.name} (hex8, {len(body.mesh.cells):,} cells, neo-Hookean" in items["bodies"]
    clamp, push = model.dirichlet
    assert f"{clamp.body}/{clamp.node_set} fixed in x, y, z" in items["supports"]
    shift, _, depth = push.value
    assert f"{push.body}/{push.node_set} moved by ({shift:g}, 0, {depth:g})" in items["motions"]
    assert f"over {problem.newton.n_steps} load step" in items["motions"]
    (iface,) = model.interfaces
    nonmortar = "/".join(iface.nonmortar)
    assert f"interface {iface.name}: nonmortar side {nonmortar} (given by the user)" in items["contact"]
    (designed,) = problem.design.bodies
    assert f"Design: {designed.body} (" in items["design"]
    assert f"volume fraction \u2264 {designed.volume_fraction:g}" in items["design"]
    assert items["objective"].startswith("Objective: maximize the strain energy of all bodies")
    assert text.index('id="problem-summary"') < text.index('id="files"') < text.index('id="summary"')
    old = shutil.copytree(out, tmp_path / "old")  # a run directory of a release that did not keep it
    (old / PROBLEM_SUMMARY).unlink()
    write_report_html(old)
    again = (old / "report.html").read_text(encoding="utf-8")
    assert "summary in words was not recorded" in again and 'class="problem-summary"' not in again


def test_pictures_are_embedded(report_run):
    out, _ = report_run
    summary = json.loads((out / "summary.json").read_text())
    pictures = _page(out).pictures
    assert (
        set(pictures)
        == set(summary["pictures"])
        == {"design", "sections", "deformed", "stress", "convergence", "pressure_history", "curves"}
    )
    for key, src in pictures.items():
        head, _, data = src.partition(",")
        assert head == "data:image/png;base64"
        assert base64.b64decode(data) == (out / f"{key}.png").read_bytes()


def _boundary_nodes(cells: np.ndarray) -> np.ndarray:
    """Nodes on faces that belong to one hexahedron only (numpy, independent of VTK)."""
    faces = np.concatenate([cells[:, list(f)] for f in HEX_FACES])
    key = np.sort(faces, axis=1)
    _, index, count = np.unique(key, axis=0, return_index=True, return_counts=True)
    return np.unique(faces[index[count == 1]])


def _decoded(mesh: dict) -> dict:
    n, m = mesh["n_points"], mesh["n_triangles"]
    index = np.uint16 if mesh["index_bytes"] == 2 else np.uint32
    out = {
        "points": decode_array(mesh["points"], np.float32, (n, 3)),
        "displacement": decode_array(mesh["displacement"], np.float32, (n, 3)),
        "triangles": decode_array(mesh["triangles"], index, (m, 3)).astype(np.int64),
        "values": None if mesh["values"] is None else decode_array(mesh["values"], np.float32, (n,)),
    }
    assert (
        len(base64.b64decode(mesh["points"])) == 12 * n
        and len(base64.b64decode(mesh["triangles"])) == 3 * m * mesh["index_bytes"]
    )
    return out


def test_mesh_arrays_decode_to_the_bodies_of_the_last_vtu(report_run):
    out, _ = report_run
    scene = _page(out).scene()
    vtu = {p.stem.rsplit("_", 1)[0]: meshio.read(p) for p in last_vtus(out)}
    assert [(m["body"], m["role"]) for m in scene["meshes"]] == [
        ("block", "iso"),
        ("block", "domain"),
        ("punch", "body"),
    ]
    pressure_max = 0.0
    for mesh in scene["meshes"]:
        arrays = _decoded(mesh)
        body = vtu[mesh["body"]]
        assert mesh["n_triangles"] == mesh["triangles_before"] > 0  # under the cap: not decimated
        assert arrays["triangles"].max() < mesh["n_points"] and arrays["triangles"].min() >= 0
        lo, hi = body.points.min(axis=0), body.points.max(axis=0)
        assert np.all(arrays["points"] >= lo - 1e-6) and np.all(arrays["points"] <= hi + 1e-6)
        if mesh["role"] == "iso":
            continue  # interpolated points: checked by their bounds above
        # a whole boundary: exactly the boundary nodes of the hex mesh, with their displacement and pressure
        nodes = _boundary_nodes(body.cells_dict["hexahedron"])
        ref = {tuple(p): i for i, p in enumerate(body.points.astype(np.float32))}
        which = np.array([ref[tuple(p)] for p in arrays["points"]])
        assert set(which) == set(nodes)
        np.testing.assert_array_equal(arrays["displacement"], body.point_data["displacement"][which].astype(np.float32))
        if "contact_pressure" in body.point_data and mesh["role"] == "body":
            p = np.ravel(body.point_data["contact_pressure"])
            np.testing.assert_array_equal(arrays["values"], p[which].astype(np.float32))
            pressure_max = max(pressure_max, float(p.max()))
        elif mesh["role"] == "domain" or "contact_pressure" not in body.point_data:
            assert arrays["values"] is None
    assert pressure_max > 0 and scene["value_name"] == "contact_pressure"
    assert scene["value_range"][0] == 0.0 and scene["value_range"][1] == pytest.approx(pressure_max, rel=1e-6)
    lut = decode_array(scene["lut"], np.uint8, (256, 3))
    assert lut[0].sum() > lut[-1].sum() + 300  # pale (zero pressure) to dark red


def test_a_triangle_cap_decimates_and_says_so(report_run, tmp_path):
    out = shutil.copytree(report_run[0], tmp_path / "run")
    write_report_html(out, max_triangles=150)
    text = (out / "report.html").read_text(encoding="utf-8")
    scene = ReportPage(text).scene()
    total = sum(m["n_triangles"] for m in scene["meshes"])
    before = sum(m["triangles_before"] for m in scene["meshes"])
    assert total <= 150 < before and "Decimated to stay under 150 triangles" in text
    for mesh in scene["meshes"]:
        arrays = _decoded(mesh)  # sizes consistent after decimation too
        assert arrays["triangles"].max() < mesh["n_points"]
    with pytest.raises(ConfigError, match="max_triangles .* at least 100"):
        write_report_html(out, max_triangles=10)


def test_a_run_without_summary_or_vtu(report_run, tmp_path):
    out = shutil.copytree(report_run[0], tmp_path / "run")
    (out / "summary.json").unlink()
    shutil.rmtree(out / "vtu")
    (out / "design.pvd").unlink()
    write_report_html(out)
    page = _page(out)
    last = read_history(out)[-1]
    assert "not finished" in page.cells["status"][1]
    assert page.cells["iterations"][0] == last["iteration"]
    assert page.cells["normalized_objective"][0] == last["objective"]
    assert page.scene() is None and "there is no 3D view" in (out / "report.html").read_text()


def test_cli_report_writes_report_html(report_run, tmp_path, capsys):
    out = shutil.copytree(report_run[0], tmp_path / "run")
    (out / "report.html").unlink()
    assert main(["-q", "report", str(out), "--no-pictures", "--no-html"]) == 0
    assert not (out / "report.html").exists() and "report: " not in capsys.readouterr().out
    assert main(["-q", "report", str(out), "--no-pictures", "--max-triangles", "200"]) == 0
    assert f"report: {out / 'report.html'}" in capsys.readouterr().out
    assert sum(m["n_triangles"] for m in _page(out).scene()["meshes"]) <= 200
    assert main(["-q", "report", str(out), "--max-triangles", "5"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "--max-triangles" in captured.err and len(captured.err.splitlines()) == 1


def test_a_failed_report_never_fails_the_run(tmp_path, monkeypatch, caplog):
    def broken(*args, **kw):
        raise RuntimeError("disk full")

    monkeypatch.setattr(report_html_module, "write_report_html", broken)
    with caplog.at_level(logging.WARNING, logger="contopt.optimize.driver"):
        res = optimize(
            cantilever_problem("density", divisions=(12, 4, 2)),
            "mma",
            MMAOptions(max_iter=1),
            out=tmp_path,
            outputs=OutputOptions(vtu="final", plot=False),
        )
    assert res.iterations == 1 and (tmp_path / "summary.json").exists() and not (tmp_path / "report.html").exists()
    assert any("report.html of" in r.message and "disk full" in r.message for r in caplog.records)
    # the same run without contact, and without pictures (plot=False): colours by the displacement magnitude
    write_report_html(tmp_path)
    page = _page(tmp_path)
    scene = page.scene()
    assert page.pictures == {} and scene["value_name"] == "displacement_magnitude"
    (mesh,) = [m for m in scene["meshes"] if m["role"] == "iso"]
    arrays = _decoded(mesh)
    np.testing.assert_allclose(arrays["values"], np.linalg.norm(arrays["displacement"], axis=1), rtol=1e-6)
    assert scene["value_range"][1] == pytest.approx(float(arrays["values"].max()), rel=1e-6)
