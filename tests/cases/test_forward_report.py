"""report.html and curves.json of `contopt forward` runs: the status, the case, the curves, the links."""

import json
import re
from pathlib import Path

import pytest

from contopt.cases import forward as forward_module
from contopt.cases.forward import block_compression, run_forward
from contopt.cases.two_blocks import two_blocks
from contopt.cli import main
from contopt.errors import ConvergenceError
from contopt.solve.newton import NewtonOptions

COMMAND = "contopt forward two-blocks --out results"


@pytest.fixture(scope="module")
def punch(tmp_path_factory):
    out = tmp_path_factory.mktemp("forward")
    summary = run_forward(
        two_blocks(divisions=2),
        out,
        newton=NewtonOptions(n_steps=3),
        name="two-blocks",
        description="a punch pressed into a block",
        command=COMMAND,
    )
    return out, summary


def _hrefs(text: str) -> list[str]:
    return re.findall(r'<a href="([^"]+)"', text)


def _curves_data(text: str) -> dict:
    m = re.search(r'<script type="application/json" id="curves-data">(.*?)</script>', text, re.S)
    assert m is not None
    return json.loads(m[1])


def test_the_curves_follow_the_solve(punch):
    out, summary = punch
    data = json.loads((out / "curves.json").read_text())
    assert data["kind"] == "forward"
    (curve,) = data["curves"]
    assert curve["complete"] and curve["steps"] == summary["load_steps"] == len(curve["load_factor"]) - 1
    (interface,) = curve["interfaces"]
    assert interface["normal_force"][-1] == pytest.approx(summary["contact_force"][0], rel=1e-9)
    motion = next(m for m in curve["motions"] if m["kind"] == "motion")
    assert motion["name"] == "punch/zmax (xyz)" and motion["force_along"][-1] > 0


def test_the_page_says_what_ran_and_links_its_files(punch):
    out, summary = punch
    text = (out / "report.html").read_text(encoding="utf-8")
    assert "Converged: the whole load in 3 load steps" in text and "a punch pressed into a block" in text
    assert COMMAND in text
    links = _hrefs(text)
    assert set(links) == {"two-blocks.pvd", "summary.json", "curves.json"}
    assert all((out / link).is_file() for link in links)
    assert _curves_data(text) == json.loads((out / "curves.json").read_text())
    assert 'data-picture="curves"' in text and (out / "curves.png").is_file()
    assert 'class="cv-view"' in text  # the 3D view of the last load step
    assert "Design history" not in text and "checkpoint" not in text  # no design parts
    model = two_blocks(divisions=2)  # the problem in words, from the model that ran
    assert [s["topic"] for s in summary["problem"]] == ["bodies", "supports", "motions", "contact"]
    for body in model.bodies:
        assert f"{body.name} (hex8, {len(body.mesh.cells)} cells, neo-Hookean" in text
    clamp, push = model.dirichlet
    assert f"{clamp.body}/{clamp.node_set} fixed in x, y, z" in text
    assert f"Prescribed motions over 3 load steps: {push.body}/{push.node_set} moved by (0.02, 0, -0.06)" in text
    (iface,) = model.interfaces
    assert f"interface {iface.name}: nonmortar side {'/'.join(iface.nonmortar)} (given by the user)" in text
    assert text.index('id="problem-summary"') < text.index('id="files"')
    assert re.search(r'<script[^>]* src=|<link[^>]* href="http', text) is None  # nothing to fetch


def test_contopt_report_rewrites_a_forward_page(punch, capsys):
    out, _ = punch
    (out / "report.html").unlink()
    (out / "curves.png").unlink()
    assert main(["-q", "report", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "two-blocks, converged, 3 load steps" in printed and f"report: {out / 'report.html'}" in printed
    assert (out / "report.html").is_file() and (out / "curves.png").is_file()


def test_a_failed_forward_run_says_what_to_try(tmp_path):
    model = block_compression(divisions=2, strain=1.2)
    with pytest.raises(ConvergenceError):
        run_forward(
            model,
            tmp_path,
            newton=NewtonOptions(n_steps=4, min_step=0.05, max_iter=8),
            name="bad",
            command="contopt forward block-compression --out r --steps 4",
        )
    summary = json.loads((tmp_path / "summary.json").read_text())
    (curve,) = json.loads((tmp_path / "curves.json").read_text())["curves"]
    assert curve["complete"] is False and "minimum load step" in curve["error"]
    assert curve["steps"] == summary["load_steps"] >= 1
    text = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert f"Failed after {summary['load_steps']} converged load steps" in text
    assert "contopt forward block-compression --out r --steps 8" in text  # the next command
    assert all((tmp_path / link).is_file() for link in _hrefs(text))
    assert Path(tmp_path / "bad.pvd").is_file()


def test_a_model_the_summary_cannot_describe_still_runs_and_says_so(tmp_path, monkeypatch, caplog):
    """The problem in words is a nicety of the report: a model built in Python that it cannot
    describe is solved all the same, and the page says the summary was not recorded."""

    def cannot(*args, **kwargs):
        raise AttributeError("'Interface' object has no attribute 'nonmortar'")

    monkeypatch.setattr(forward_module, "model_summary", cannot)
    summary = run_forward(block_compression(divisions=2, strain=0.1), tmp_path, name="cube")
    assert summary["converged"] and "problem" not in summary
    assert "the problem's summary in words is left out of the report" in caplog.text
    assert "summary in words was not recorded" in (tmp_path / "report.html").read_text(encoding="utf-8")
