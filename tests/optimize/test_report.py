"""Pictures and the text report of real (tiny) runs, through the driver and `contopt report`."""

import json
import logging
import shutil

import matplotlib.image as mpimg
import numpy as np
import pytest
from _cantilever import cantilever_problem  # tests/optimize/_cantilever.py

from contopt.cli import main
from contopt.errors import ConfigError
from contopt.optimize import report as report_module
from contopt.optimize.driver import OutputOptions, optimize
from contopt.optimize.history import Checkpoint, read_history
from contopt.optimize.mma import MMAOptions
from contopt.optimize.report import make_pictures, pressure_history, report_text

PNG = b"\x89PNG\r\n\x1a\n"


def _png_size(path) -> tuple[int, int]:
    """(width, height) of a PNG, after checking it is one and not blank."""
    assert path.read_bytes()[:8] == PNG
    img = mpimg.imread(path)[..., :3]
    assert img.std() > 0.02
    return img.shape[1], img.shape[0]


def _contact_problem():
    """The punch-on-block design problem of tests/optimize/test_topopt.py, at default tolerances."""
    from contopt.cases.two_blocks import two_blocks
    from contopt.design import BSplineGrid, Design, DesignedBody
    from contopt.optimize.problem import DesignProblem
    from contopt.responses import StrainEnergy

    design = Design(DesignedBody("block", BSplineGrid((2, 2, 1)), volume_fraction=0.5))
    return DesignProblem(model=two_blocks(), design=design, objective=-StrainEnergy())


@pytest.fixture(scope="module")
def cantilever_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("cantilever")
    res = optimize(cantilever_problem("density", divisions=(12, 4, 2)), "mma", MMAOptions(max_iter=2), out=out)
    return out, res


@pytest.fixture(scope="module")
def contact_run(tmp_path_factory):
    """vtu="none": the driver writes the final VTU for the pictures all the same."""
    out = tmp_path_factory.mktemp("contact")
    res = optimize(_contact_problem(), "mma", MMAOptions(max_iter=2), out=out, outputs=OutputOptions(vtu="none"))
    return out, res


def test_a_run_draws_its_pictures(cantilever_run):
    out, res = cantilever_run
    summary = json.loads((out / "summary.json").read_text())
    assert summary["pictures"] == {
        "design": "design.png",
        "sections": "sections.png",
        "deformed": "deformed.png",
        "stress": "stress.png",
        "convergence": "convergence.png",
        "curves": "curves.png",
    }  # no contact: no pressure history
    assert _png_size(out / "design.png") == (1200, 900) and _png_size(out / "deformed.png") == (1200, 900)
    assert _png_size(out / "sections.png") == (1500, 560)  # three panels side by side
    assert not (out / "pressure_history.png").exists()


def test_make_pictures_again_at_another_size(cantilever_run, tmp_path):
    out = shutil.copytree(cantilever_run[0], tmp_path / "run")
    made = make_pictures(out, size=(400, 300))
    assert list(made) == ["design", "sections", "deformed", "stress", "convergence", "curves"]
    assert _png_size(made["design"]) == (400, 300) and _png_size(made["deformed"]) == (400, 300)
    assert _png_size(made["stress"]) == (400, 300)
    with pytest.raises(ConfigError, match="size must be two positive integers"):
        make_pictures(out, size=(400, -1))


def test_report_text_of_a_finished_run(cantilever_run):
    out, res = cantilever_run
    text = report_text(out)
    newton = sum(r["newton_iterations"] for r in res.history)
    for part in (
        str(out),
        "objective compliance",
        "status: max_iter",
        "iterations: 2",
        f"analyses: {res.analyses}",
        f"f/|f0| = {res.normalized_objective:.6g}",
        f"beam {res.volume_fractions[0]:.4f}",
        "grey fraction (0.1 < nu < 0.9): ",
        f"Newton iterations: {newton} in total",
        "mean seconds per iteration: primal ",
        "adjoint ",
        "design ",
        "optimizer ",
        "design.png",
        "summary.json",
    ):
        assert part in text, part


def test_report_text_of_an_interrupted_run(cantilever_run, tmp_path):
    out = shutil.copytree(cantilever_run[0], tmp_path / "run")
    (out / "summary.json").unlink()
    text = report_text(out)
    last = read_history(out)[-1]
    assert "not finished" in text and "--resume" in text and f"f/|f0| = {last['objective']:.6g}" in text


def test_a_run_whose_meta_json_was_deleted_is_still_reported(cantilever_run, tmp_path, caplog):
    out = shutil.copytree(cantilever_run[0], tmp_path / "run")
    meta = out / "checkpoint" / "meta.json"
    text = meta.read_text()
    meta.unlink()
    assert report_text(out) == report_text(cantilever_run[0]).replace(str(cantilever_run[0]), str(out))
    assert json.loads(meta.read_text()) == json.loads(text)
    assert any("meta.json was missing; rebuilt from its copy" in r.getMessage() for r in caplog.records)


def test_damaged_records_are_reported_in_one_line(cantilever_run, tmp_path):
    out = shutil.copytree(cantilever_run[0], tmp_path / "run")
    records = sorted((out / "checkpoint").glob("eval_*.npz"))
    assert not any(s.startswith("checkpoint:") for s in report_text(out).splitlines())
    records[1].write_bytes(b"not a record")
    (line,) = [s for s in report_text(out).splitlines() if s.startswith("checkpoint:")]
    assert line.startswith(f"checkpoint: 1 of its {len(records)} records cannot be read (the first, eval_00001.npz: ")
    assert line.endswith("--resume replays the 1 before it and analyses the rest again")
    for path in records:
        path.write_bytes(b"not a record")
    (line,) = [s for s in report_text(out).splitlines() if s.startswith("checkpoint:")]
    assert line.startswith(f"checkpoint: none of its {len(records)} records can be read (eval_00000.npz: ")
    assert line.endswith("; --resume analyses every design again")


def test_not_a_run_directory(tmp_path):
    with pytest.raises(ConfigError, match=r"no such directory"):
        report_text(tmp_path / "missing")
    with pytest.raises(ConfigError, match=r"is not a run directory: it has no checkpoint/meta.json"):
        make_pictures(tmp_path)
    (tmp_path / "summary.json").write_text("{}")
    with pytest.raises(ConfigError, match=r"summary.json is a file, not a run directory: give the directory"):
        report_text(tmp_path / "summary.json")


def test_contact_run_has_a_pressure_history(contact_run):
    out, res = contact_run
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["pictures"]) == {
        "design",
        "sections",
        "deformed",
        "stress",
        "convergence",
        "pressure_history",
        "curves",
    }
    assert sorted(p.name for p in (out / "vtu").iterdir()) == ["block_0002.vtu", "punch_0002.vtu"]
    assert _png_size(out / "pressure_history.png")[0] > 0
    its, lam, f = pressure_history(out)
    records = Checkpoint(out).records()
    np.testing.assert_array_equal(its, [0, 1, 2])
    np.testing.assert_allclose(f, [r["objective"] for r in res.history], rtol=0, atol=0)
    # MMA evaluates each iterate once, in order: row k is record k
    np.testing.assert_array_equal(lam, np.stack([r.pressures[0] for r in records[:3]]))
    np.testing.assert_array_equal(lam[-1], res.record.pressures[0])
    assert lam.shape[1] == len(res.record.pressures[0]) and lam.max() > 0
    # without a history the evaluations are used in order
    its2, lam2, _ = pressure_history(out, rows=[])
    np.testing.assert_array_equal(its2, np.arange(len(records)))
    assert lam2.shape == (len(records), lam.shape[1])


def test_cli_report(contact_run, tmp_path, capsys):
    out = shutil.copytree(contact_run[0], tmp_path / "run")
    for name in ("design.png", "deformed.png", "pressure_history.png"):
        (out / name).unlink()
    assert main(["-q", "report", str(out), "--size", "320", "240"]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert f"f/|f0| = {summary['normalized_objective']:.6g}" in printed
    assert "pictures: " in printed and str(out / "pressure_history.png") in printed
    assert _png_size(out / "design.png") == (320, 240)
    assert main(["-q", "report", str(out), "--no-pictures"]) == 0
    assert "pictures: " not in capsys.readouterr().out
    assert main(["-q", "report", str(out), "--size", "0", "240"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "size must be two positive integers" in captured.err


def test_cli_report_of_a_non_run_directory(tmp_path, capsys):
    assert main(["-q", "report", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(tmp_path) in err and "checkpoint/meta.json" in err


def test_a_failed_picture_never_fails_the_run(tmp_path, monkeypatch, caplog):
    def broken(*args, **kw):
        raise RuntimeError("no OpenGL here")

    monkeypatch.setattr(report_module, "render_design", broken)
    with caplog.at_level(logging.WARNING, logger="contopt.optimize.driver"):
        res = optimize(
            cantilever_problem("density", divisions=(12, 4, 2)),
            "mma",
            MMAOptions(max_iter=1),
            out=tmp_path,
            outputs=OutputOptions(vtu="final"),
        )
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["pictures"] == {} and summary["iterations"] == res.iterations == 1
    assert (tmp_path / "vtu" / "beam_0001.vtu").exists() and (tmp_path / "history.json").exists()
    assert any("pictures of" in r.message and "no OpenGL here" in r.message for r in caplog.records)


def test_curves_of_the_first_and_the_last_design(report_run):
    """curves.json: both designs solved along the load path; at full load the last design's curve is
    the state the run analysed (solved there warm-started in one step)."""
    from contopt.optimize.curves import CURVE_STEPS, read_curves
    from contopt.solve.system import System

    out, res = report_run
    data = read_curves(out)
    assert data["kind"] == "optimization"
    first, last = data["curves"]
    assert (first["design"], first["iteration"], last["design"], last["iteration"]) == ("first", 0, "last", 2)
    for curve in (first, last):
        assert curve["complete"] and curve["steps"] >= CURVE_STEPS and curve["load_factor"][-1] == 1.0
        assert all(len(m["force"]) == curve["steps"] + 1 for m in curve["motions"])
    system = System.of(_contact_problem().model)
    force = system.contact.total_force(res.record.u, res.record.pressures)
    assert last["interfaces"][0]["normal_force"][-1] == pytest.approx(float(force[0]), rel=1e-3)
    # the optimizer made the block stiffer where the punch presses: it pushes back harder
    assert last["interfaces"][0]["normal_force"][-1] > first["interfaces"][0]["normal_force"][-1]
