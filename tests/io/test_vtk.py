import json
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from contopt.assembly.system import discretize
from contopt.cases.forward import block_compression, run_forward
from contopt.errors import ConvergenceError
from contopt.io.vtk import read_pvd
from contopt.solve.fields import von_mises
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static


def test_forward_run_writes_a_step_series_paraview_opens(tmp_path):
    model = block_compression(divisions=2, strain=0.3)
    summary = run_forward(model, tmp_path, newton=NewtonOptions(n_steps=2), name="case")
    entries = read_pvd(tmp_path / "case.pvd")
    assert [e[0] for e in entries] == [0.0, 0.5, 1.0]
    assert ET.parse(tmp_path / "case.pvd").getroot().get("type") == "Collection"
    final = meshio.read(entries[-1][2])
    ref = solve_static(model, newton=NewtonOptions(n_steps=2))
    disc = discretize(model)
    np.testing.assert_allclose(final.point_data["displacement"], disc.body_displacement(ref.u, 0), atol=1e-12)
    sigma = final.cell_data["cauchy_stress"][0].reshape(-1, 3, 3)
    np.testing.assert_allclose(sigma, disc.cauchy_stress(ref.u, 0), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(final.cell_data["von_mises"][0].ravel(), von_mises(sigma), rtol=1e-12)
    np.testing.assert_allclose(final.cell_data["rho_tilde"][0].ravel(), 1.0)
    assert np.allclose(sigma, np.swapaxes(sigma, 1, 2))  # Cauchy stress is symmetric
    saved = json.loads((tmp_path / "summary.json").read_text())
    assert saved["converged"] and saved["load_steps"] == summary["load_steps"] == 2


def test_failed_run_keeps_what_converged(tmp_path):
    model = block_compression(divisions=2, strain=1.2)
    with pytest.raises(ConvergenceError):
        run_forward(model, tmp_path, newton=NewtonOptions(n_steps=4, min_step=0.05, max_iter=8), name="bad")
    saved = json.loads((tmp_path / "summary.json").read_text())
    assert saved["converged"] is False and "minimum load step" in saved["error"]
    entries = read_pvd(tmp_path / "bad.pvd")
    assert len(entries) == saved["load_steps"] + 1 >= 2
    assert all(e[2].exists() for e in entries)
