"""The optimized design of a run directory as a surface: `contopt run` writes design.stl, `contopt
export-design` (and export_design) rebuild the run's problem and write STL / PLY / OBJ."""

import json
import shutil

import numpy as np
import pytest
from _surfaces import closed_manifold_problems  # tests/_surfaces.py (independent surface checks)

from contopt.cases.export import VOLUME_TOLERANCE, export_design
from contopt.cli import main
from contopt.design.surface import SurfaceOptions
from contopt.errors import ConfigError
from contopt.io.surface import read_surface

BEAM_VOLUME = 3.0 * 1.0 * 0.5  # the bundled cantilever's design domain


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """The bundled cantilever (density design, coarse) optimized to the end: about 15 s."""
    out = tmp_path_factory.mktemp("cantilever") / "run"
    assert main(["-q", "run", "cantilever", "--out", str(out), "--vtu", "final"]) == 0
    return out


def test_run_writes_a_closed_surface_enclosing_the_designs_volume(run_dir):
    """design.stl of the finished run: closed, outward, and its volume within 2 % of the run's
    volume fraction (summary.json) times the beam's volume."""
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["grey_fraction"] < 0.2  # a converged design, mostly black and white
    surface = read_surface(run_dir / "design.stl")
    assert closed_manifold_problems(surface.vertices, surface.faces) == []
    target = summary["volume_fraction"] * BEAM_VOLUME
    assert abs(surface.volume - target) <= VOLUME_TOLERANCE * target
    numbers = summary["surface"]["beam"]
    assert numbers["file"] == "design.stl" and numbers["watertight"] and numbers["manifold"]
    assert numbers["volume"] == pytest.approx(surface.volume, rel=1e-5)  # the file is float32
    assert numbers["design_volume"] == pytest.approx(target, rel=1e-9)


def test_export_design_rebuilds_the_run_and_writes_any_format(run_dir, tmp_path):
    rows = json.loads((run_dir / "history.json").read_text())
    result = export_design(run_dir, tmp_path / "beam.obj", SurfaceOptions(refine=2))
    assert result.iteration == rows[-1]["iteration"] and result.files == (tmp_path / "beam.obj",)
    (bs,) = result.surfaces
    back = read_surface(tmp_path / "beam.obj")
    assert closed_manifold_problems(back.vertices, back.faces) == []
    assert back.volume == pytest.approx(bs.volume, rel=1e-12)
    assert bs.design_volume == pytest.approx(rows[-1]["volume_fractions"]["beam"] * BEAM_VOLUME, rel=1e-9)
    assert abs(bs.relative_difference) <= VOLUME_TOLERANCE
    lines = result.lines()
    assert "iteration" in lines[0] and lines[1].startswith(f"wrote {tmp_path / 'beam.obj'}: beam:")
    assert not any("note" in line for line in lines)


def test_a_run_without_its_recipe_is_rebuilt_from_problem_toml(run_dir, tmp_path):
    """Runs made before the recipe was stored: problem.toml and the command line atop it."""
    copy = tmp_path / "old"
    shutil.copytree(run_dir, copy)
    (copy / "checkpoint" / "problem.json").unlink()
    assert (copy / "problem.toml").read_text().startswith("# contopt run cantilever")
    old = export_design(copy, tmp_path / "old.stl")
    new = export_design(run_dir, tmp_path / "new.stl")
    assert old.surfaces[0].volume == pytest.approx(new.surfaces[0].volume, rel=1e-12)
    (copy / "problem.toml").unlink()
    with pytest.raises(ConfigError, match="does not say which problem ran"):
        export_design(copy, tmp_path / "none.stl")


def test_a_changed_problem_is_refused(run_dir, tmp_path):
    copy = tmp_path / "edited"
    shutil.copytree(run_dir, copy)
    recipe = json.loads((copy / "checkpoint" / "problem.json").read_text())
    assert recipe["text"].strip() == 'case = "cantilever"' and recipe["design"] is None
    recipe["design"] = "bspline"  # as if the run had been `contopt run cantilever --design bspline`
    (copy / "checkpoint" / "problem.json").write_text(json.dumps(recipe))
    with pytest.raises(ConfigError, match="is not the one that ran"):
        export_design(copy, tmp_path / "x.stl")


def test_export_design_on_the_command_line(run_dir, tmp_path, capsys):
    out = tmp_path / "part.ply"
    png = tmp_path / "part.png"
    assert (
        main(["-q", "export-design", str(run_dir), "--out", str(out), "--smooth", "0", "--ascii", "--png", str(png)])
        == 0
    )
    text = capsys.readouterr().out
    assert f"wrote {out}: beam:" in text and "volume fraction" in text and f"picture: {png}" in text
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out.read_bytes().startswith(b"ply\nformat ascii 1.0")
    assert closed_manifold_problems(*(lambda s: (s.vertices, s.faces))(read_surface(out))) == []


def _error(args, capsys) -> str:
    assert main(["-q", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("contopt: error:") and "\n" not in err and "Traceback" not in err
    return err


def test_command_line_errors_are_one_line(run_dir, tmp_path, capsys):
    assert "no such directory" in _error(["export-design", str(tmp_path / "nowhere")], capsys)
    empty = tmp_path / "started"
    (empty / "checkpoint").mkdir(parents=True)
    shutil.copy(run_dir / "checkpoint" / "meta.json", empty / "checkpoint" / "meta.json")
    assert "no completed analysis" in _error(["export-design", str(empty)], capsys)
    err = _error(["export-design", str(run_dir), "--out", str(tmp_path / "part.step")], capsys)
    assert "unknown surface file extension '.step'" in err and ".stl, .ply, .obj" in err
    assert "--mirror needs AXIS=VALUE" in _error(["export-design", str(run_dir), "--mirror", "q=1"], capsys)
    assert "refine must be an integer from 1 to 12" in _error(["export-design", str(run_dir), "--refine", "0"], capsys)
    assert not (tmp_path / "part.step").exists()


def test_the_final_design_is_the_last_iterations_analysis(run_dir):
    from contopt.cases.export import final_design

    x, iteration, evaluation = final_design(run_dir)
    with np.load(run_dir / "checkpoint" / f"eval_{evaluation:05d}.npz") as data:
        np.testing.assert_array_equal(x, data["x"])
        rows = json.loads((run_dir / "history.json").read_text())
        assert float(data["f"]) == rows[-1]["objective"] and iteration == rows[-1]["iteration"]


def test_a_damaged_last_record_exports_the_last_readable_one_and_says_which(run_dir, tmp_path, capsys):
    from contopt.cases.export import final_design

    copy = shutil.copytree(run_dir, tmp_path / "run")
    _, _, last = final_design(copy)
    damaged = copy / "checkpoint" / f"eval_{last:05d}.npz"
    damaged.write_bytes(damaged.read_bytes()[:100])  # cut short, as by a crash of the disk
    assert main(["-q", "export-design", str(copy), "--out", str(tmp_path / "part.stl")]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0] == f"{copy}: design of the last readable analysis (analysis {last - 1})"
    assert printed[1].startswith(f"  note: {damaged.name} cannot be read (")
    assert printed[1].endswith(f"; the design of analysis {last - 1}, the last readable one, is exported")
    result = export_design(copy, tmp_path / "again.stl")
    assert result.evaluation == last - 1 and result.iteration is None
    with np.load(copy / "checkpoint" / f"eval_{last - 1:05d}.npz") as data:
        np.testing.assert_array_equal(final_design(copy)[0], data["x"])
    for path in (copy / "checkpoint").glob("eval_*.npz"):
        path.write_bytes(b"not a record")
    err = _error(["export-design", str(copy), "--out", str(tmp_path / "none.stl")], capsys)
    assert "has no readable record of a design" in err and "--overwrite" in err
