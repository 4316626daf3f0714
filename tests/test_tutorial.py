"""The tutorial's problem (docs/tutorial.md): examples/tutorial.py and examples/tutorial.toml build the same
problem, and its optimization starts the right way."""

import importlib.util
from pathlib import Path

import meshio
import numpy as np
from _compare import problem_differences  # tests/_compare.py

from contopt.assembly.system import discretize
from contopt.cases.spec import load_spec
from contopt.optimize.mma import MMAOptions

ROOT = Path(__file__).resolve().parents[1]
TOML = ROOT / "examples" / "tutorial.toml"


def tutorial_module():
    spec = importlib.util.spec_from_file_location("contopt_tutorial_example", ROOT / "examples" / "tutorial.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_python_and_toml_build_the_same_problem():
    toml, python = load_spec(TOML), tutorial_module().bridge_problem()
    assert problem_differences(toml.problem, python) == []
    a, b = toml.model, python.model
    for x, y in zip(a.bodies, b.bodies, strict=True):
        assert x.name == y.name and x.material == y.material
        np.testing.assert_array_equal(x.mesh.points, y.mesh.points)
        np.testing.assert_array_equal(x.mesh.cells, y.mesh.cells)
    for x, y in zip(a.dirichlet, b.dirichlet, strict=True):
        assert (x.body, x.node_set, x.components) == (y.body, y.node_set, y.components)
        np.testing.assert_array_equal(
            a.body(x.body).mesh.node_set(x.node_set), b.body(y.body).mesh.node_set(y.node_set)
        )
        np.testing.assert_array_equal(np.atleast_1d(x.value), np.atleast_1d(y.value))
    assert len(a.body("beam").mesh.node_set("left_pad")) == 3 * 5  # two cells long, the beam's depth wide
    assert [(i.nonmortar, i.mortar, i.law) for i in a.interfaces] == [
        (i.nonmortar, i.mortar, i.law) for i in b.interfaces
    ]
    summary = toml.problem.design.build(discretize(a)).summary()
    assert summary == python.design.build(discretize(b)).summary()
    assert summary[0]["n_design"] == 16 * 4 * 4
    # what tutorial.py runs
    assert toml.optimizer == "mma" and toml.options == MMAOptions(max_iter=40, move=0.1, asyinit=0.1)


def test_the_full_beam_resolves_its_contact():
    """The roller's contact zone spans more than one node column of the nonmortar surface, and no node of
    either surface lies more than 0.01 h inside the other body (the pointwise check, contact/verify.py).
    With the beam's top (facets 0.125) as nonmortar under a 16-gon roller pressed 0.02, one column carried
    the contact and the roller's lowest line sank 0.07 h into the beam."""
    from contopt.solve.static import System, solve_static

    spec = load_spec(TOML)
    system = System.of(spec.model)
    state = solve_static(system, newton=spec.problem.newton)
    block, result, check = system.contact.blocks[0], state.contact[0], state.checks[0]
    x = system.contact.X[block.nodes, 0]  # the nonmortar nodes' x (reference), the roller's axis along z
    pressed = result.lam > 0
    columns = np.unique(np.round(x[pressed], 9))
    assert len(columns) > 1, columns
    assert check.ok and check.max_depth < 0.01 * block.h, check.max_depth / block.h
    assert system.contact.coarse_side_warnings(state.checks) == []
    assert block.interface.nonmortar == ("roller", "outer")  # the finer surface, chosen by contopt
    # the roller is moved rigidly: its reaction is the contact force the beam's pads take up
    pushed = -state.reactions[system.disc.body_slice("roller")][1::3].sum()
    assert pushed > 0


def test_two_iterations_raise_the_contact_force_and_hold_the_volume(tmp_path):
    spec = load_spec(TOML, {"run.max_iter": 2})
    res = spec.run(out=tmp_path)
    f = [row["objective"] for row in res.history]  # -(contact force) / (that of the full beam)
    assert len(f) == 3 and f[2] < f[0] < 0
    assert res.volume_fractions[0] <= 0.3 + 1e-3
    # what the tutorial says the run writes
    for name in (
        "history.csv",
        "history.json",
        "summary.json",
        "convergence.png",
        "design.pvd",
        "vtu/beam_0002.vtu",
        "vtu/roller_0002.vtu",
        "checkpoint/meta.json",
    ):
        assert (tmp_path / name).exists(), name
    beam = meshio.read(tmp_path / "vtu" / "beam_0002.vtu")
    assert {"displacement", "nu"} <= set(beam.point_data) | set(beam.cell_data)
    roller = meshio.read(tmp_path / "vtu" / "roller_0002.vtu")  # the nonmortar side carries the pressure
    assert {"displacement", "contact_pressure"} <= set(roller.point_data)


def test_the_tutorial_imports_only_the_public_api():
    import ast

    tree = ast.parse((ROOT / "examples" / "tutorial.py").read_text(encoding="utf-8"))
    modules = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.module}
    modules |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    assert {m for m in modules if m.startswith("contopt")} == {"contopt"}, modules
