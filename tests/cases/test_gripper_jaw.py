"""The bundled case from CAD, gripper-jaw: its STEP file is the one examples/cad/gripper_jaw.py writes,
the sets its problem file names are the surfaces it says, and (slow) it runs and exports its design."""

import math
import runpy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from contopt.cases.optimization import OPTIMIZATION_CASES, optimization_case

gmsh = pytest.importorskip("gmsh")
ROOT = Path(__file__).resolve().parents[2]


def test_the_step_file_is_what_the_script_writes(tmp_path, monkeypatch):
    from contopt.mesh.cad import cad_surfaces

    monkeypatch.setattr(sys, "argv", ["gripper_jaw.py", str(tmp_path / "jaw.step")])
    runpy.run_path(str(ROOT / "examples" / "cad" / "gripper_jaw.py"), run_name="__main__")
    bundled = cad_surfaces(OPTIMIZATION_CASES["gripper-jaw"].path.with_suffix(".step"))
    written = cad_surfaces(tmp_path / "jaw.step")
    assert [s.name for s in written] == [s.name for s in bundled]
    assert [s.area for s in written] == pytest.approx([s.area for s in bundled], rel=1e-12)


def test_its_sets_are_the_bottom_and_the_groove():
    jaw = optimization_case("gripper-jaw").model.body("jaw").mesh
    assert np.all(jaw.points[jaw.node_set("surface_5"), 2] == 0.0)
    groove = jaw.points[jaw.node_set("surface_8")]
    radius = np.hypot(groove[:, 0] - 1.0, groove[:, 2] - 1.25)  # the groove's nodes lie on its cylinder
    np.testing.assert_allclose(radius, 0.4, rtol=1e-7)
    fine = optimization_case("gripper-jaw", mesh="fine").model.body("jaw").mesh
    assert fine.n_cells > 2 * jaw.n_cells


@pytest.mark.slow
def test_it_runs_and_exports_its_design(tmp_path):
    run = [sys.executable, "-m", "contopt", "-q", "run", "gripper-jaw", "--max-iter", "2", "--no-plot"]
    out = subprocess.run([*run, "--out", str(tmp_path / "r")], capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    stl = tmp_path / "jaw.stl"
    export = [sys.executable, "-m", "contopt", "export-design", str(tmp_path / "r"), "--out", str(stl)]
    out = subprocess.run(export, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0 and stl.is_file(), out.stderr[-3000:]
    assert math.isfinite(stl.stat().st_size) and stl.stat().st_size > 84
