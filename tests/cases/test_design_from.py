"""`contopt run --design-from` (``[run] design_from``): a run started from another run's design, a
VTU or a PVD file, on the same or another mesh."""

import json
import shutil

import numpy as np
import pytest

from contopt.cases.spec import bundled_cases, load_run_spec
from contopt.cli import main
from contopt.design import Heaviside
from contopt.design.transfer import VOLUME_TOL, body_fields, start_design
from contopt.io.vtk import write_vtu
from contopt.mesh.generators import box

LENGTHS = (3.0, 1.0, 0.5)  # the bundled cantilever's beam
COARSE, FINE = [6, 2, 2], [12, 4, 4]
ETA = 10.0  # the cantilever's Heaviside sharpness
#: the density filter's radius on both meshes: more than a coarse cell, so that it bends a linear field at
#: the beam's ends (the file's 0.25, half a coarse cell, would filter nothing there)
RADIUS = 0.6


def _run(out, divisions, *extra):
    """`contopt run` of the bundled cantilever file on a ``divisions`` mesh, quiet, without pictures;
    its exit status."""
    return main(
        [
            "-q",
            "run",
            str(bundled_cases()["cantilever"]),
            "--set",
            f"bodies[0].mesh.divisions={divisions}",
            "--set",
            f"design.bodies[0].density.radius={RADIUS}",
            "--out",
            str(out),
            "--no-plot",
            *extra,
        ]
    )


def _x(out, index=0) -> np.ndarray:
    """The design variables of analysis ``index`` of the run in ``out``."""
    with np.load(out / "checkpoint" / f"eval_{index:05d}.npz", allow_pickle=False) as data:
        return np.asarray(data["x"]).copy()


def _space(out):
    spec = load_run_spec(out)
    return spec.problem.design.build(spec.discretization)


def _linear(X):
    """The analytic level set: linear in x, -0.2 at x = 0 to -0.05 at x = 3 (volume fraction about
    0.1, below the cantilever's limit 0.3)."""
    return -0.2 + 0.05 * X[:, 0]


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("contopt: error:") and "\n" not in err and "Traceback" not in err, err
    return err


@pytest.fixture(scope="module")
def analytic(tmp_path_factory):
    """A VTU of the coarse beam whose volume fraction is H(the linear level set) at its cell centres, and
    a run of the coarse beam started from it (no iteration: its one analysis is of the start)."""
    root = tmp_path_factory.mktemp("analytic")
    mesh = box(LENGTHS, COARSE)
    centres = mesh.points[mesh.cells].mean(axis=1)
    vtu = write_vtu(
        root / "beam_0000.vtu", mesh.points, mesh.cells, cell_data={"nu": Heaviside(ETA).forward(_linear(centres))}
    )
    assert _run(root / "coarse", COARSE, "--max-iter", "0", "--vtu", "none", "--design-from", str(vtu)) == 0
    return vtu, root / "coarse"


@pytest.fixture(scope="module")
def optimized(tmp_path_factory):
    """The coarse beam after two MMA iterations (its VTU files kept)."""
    out = tmp_path_factory.mktemp("optimized") / "run"
    assert _run(out, COARSE, "--max-iter", "2") == 0
    return out


def test_a_vtu_field_is_the_first_design(analytic):
    """nu = H(phi) in the VTU, H^-1 read back: the coarse run's first design is the linear level set."""
    _, coarse = analytic
    space = _space(coarse)
    np.testing.assert_allclose(_x(coarse), _linear(space.parts[0].sites), rtol=0, atol=1e-12)
    assert np.array_equal(np.load(coarse / "checkpoint" / "start.npy"), _x(coarse))


def test_a_coarse_run_seeds_a_finer_mesh_exactly_for_a_linear_field(analytic, tmp_path, capsys):
    """The same filter radius on twice the cells each way: the design field is interpolated linearly,
    which reproduces a linear field at every fine cell (the outer ones beyond the coarse centres too).
    The filtered field would not: the filter bends it at the ends."""
    _, coarse = analytic
    fine = tmp_path / "fine"
    assert _run(fine, FINE, "--max-iter", "0", "--vtu", "none", "--design-from", str(coarse)) == 0
    space = _space(fine)
    assert space.n == 2**3 * _space(coarse).n
    np.testing.assert_allclose(_x(fine), _linear(space.parts[0].sites), rtol=0, atol=1e-12)
    coarse_space = _space(coarse)
    bent = coarse_space.forward(_x(coarse)).phi - _linear(coarse_space.parts[0].centroids)
    assert np.max(np.abs(bent)) > 1e-3
    summary = json.loads((fine / "summary.json").read_text())
    assert summary["volume_fraction"] < 0.3 - VOLUME_TOL  # feasible: not lowered


def test_an_optimized_coarse_design_is_interpolated_onto_the_fine_mesh(optimized, tmp_path):
    """The fine run's first design is the coarse run's last one carried by design.transfer."""
    fine = tmp_path / "fine"
    assert _run(fine, FINE, "--max-iter", "1", "--vtu", "none", "--design-from", str(optimized)) == 0
    last = _x(optimized, json.loads((optimized / "summary.json").read_text())["analyses"] - 1)
    expected, how = start_design(_space(fine), body_fields(_space(optimized), last))
    assert how == {"beam": "interpolated"}
    assert _x(fine).tobytes() == expected.tobytes()
    grey = _space(fine).initial()
    assert np.max(np.abs(_x(fine) - grey)) > 0.1  # not the grey start


def test_the_same_mesh_copies_the_design_bit_for_bit(optimized, tmp_path):
    history = json.loads((optimized / "history.json").read_text())
    assert max(history[-1]["constraints"].values()) <= VOLUME_TOL  # a start the volume limit keeps
    same = tmp_path / "same"
    assert _run(same, COARSE, "--max-iter", "0", "--vtu", "none", "--design-from", str(optimized)) == 0
    last = _x(optimized, history[-1]["analyses"] - 1)
    assert _x(same).tobytes() == last.tobytes()
    # the same design, analysed from zero here and from the last state there: the same objective to round-off
    assert json.loads((same / "history.json").read_text())[0]["objective"] == pytest.approx(
        history[-1]["objective"], rel=1e-9
    )


def test_a_density_design_seeds_a_bspline_one_fitted_to_its_level_set(optimized, tmp_path, caplog):
    """Another parameterization: the B-spline's control values fitted to the density run's level set;
    the volume fraction it gives follows the density run's (at the nearest coarse cell)."""
    out = tmp_path / "bspline"
    args = [str(bundled_cases()["cantilever"]), "--design", "bspline", "--set", f"bodies[0].mesh.divisions={FINE}"]
    extra = ["--max-iter", "0", "--vtu", "none", "--no-plot", "--out", str(out), "--design-from", str(optimized)]
    assert main(["-q", "run", *args, *extra]) == 0
    assert "body 'beam' fitted" in caplog.text
    last = _x(optimized, json.loads((optimized / "summary.json").read_text())["analyses"] - 1)
    source, target = _space(optimized), _space(out)
    nu_source = source.forward(last).nu
    nu_target = target.forward(_x(out)).nu
    near = [np.argmin(np.linalg.norm(source.parts[0].centroids - c, axis=1)) for c in target.parts[0].centroids]
    correlation = np.corrcoef(nu_source[near], nu_target)[0, 1]
    assert correlation > 0.9  # a grey start: constant, no correlation
    assert target.volume_fractions(target.forward(_x(out)))[0] <= 0.3 + VOLUME_TOL


def test_the_pvd_and_its_last_vtu_give_the_same_start(optimized, tmp_path):
    starts = []
    for source in (optimized / "design.pvd", optimized / "vtu" / "beam_0002.vtu"):
        out = tmp_path / source.suffix[1:]
        assert _run(out, FINE, "--max-iter", "0", "--vtu", "none", "--design-from", str(source)) == 0
        starts.append(_x(out))
    assert starts[0].tobytes() == starts[1].tobytes()


def test_a_start_above_the_volume_limit_is_lowered_to_it_and_said(tmp_path, caplog):
    mesh = box(LENGTHS, COARSE)
    vtu = write_vtu(
        tmp_path / "beam_0000.vtu", mesh.points, mesh.cells, cell_data={"nu": np.full(len(mesh.cells), 0.8)}
    )
    out = tmp_path / "run"
    assert _run(out, COARSE, "--max-iter", "0", "--vtu", "none", "--design-from", str(vtu)) == 0
    assert (
        "had volume fraction 0.8000, above its limit 0.3: its level set was lowered uniformly to 0.3000" in caplog.text
    )
    fraction = json.loads((out / "history.json").read_text())[0]["volume_fractions"]["beam"]
    assert fraction == pytest.approx(0.3, abs=1e-9)


def test_the_problem_file_key_is_relative_to_the_working_directory(analytic, tmp_path, monkeypatch, capsys):
    """``[run] design_from``: a VTU whose name names no body of the file is taken for its one designed body."""
    vtu, coarse = analytic
    shutil.copy(vtu, tmp_path / "seed.vtu")
    monkeypatch.chdir(tmp_path)
    problem = tmp_path / "beam.toml"
    problem.write_text(
        'case = "cantilever"\n[run]\nmax_iter = 0\nvtu = "none"\nplot = false\nout = "run"\ndesign_from = "seed.vtu"\n'
    )
    mesh = ["--set", f"bodies[0].mesh.divisions={COARSE}", "--set", f"design.bodies[0].density.radius={RADIUS}"]
    assert main(["-q", "run", str(problem), *mesh]) == 0
    assert _x(tmp_path / "run").tobytes() == _x(coarse).tobytes()
    problem.write_text(problem.read_text().replace("seed.vtu", "nowhere.vtu"))
    capsys.readouterr()
    assert main(["-q", "run", str(problem), "--overwrite"]) == 2
    assert _one_line_error(capsys).startswith("contopt: error: run.design_from nowhere.vtu: there is no such")


def _damaged(run, tmp_path):
    copy = tmp_path / "damaged"
    shutil.copytree(run, copy)
    for record in (copy / "checkpoint").glob("eval_*.npz"):
        record.write_bytes(b"not a record")
    return copy


def _renamed(tmp_path):
    """A problem file of the cantilever whose body is called 'bar'."""
    text = bundled_cases()["cantilever"].read_text().replace('"beam"', '"bar"')
    path = tmp_path / "bar.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    "make, extra, needle",
    [
        (lambda run, tmp: tmp / "nowhere", (), "there is no such directory or file; give the --out directory"),
        (lambda run, tmp: tmp, (), "the directory is not a run directory (it has no checkpoint/meta.json)"),
        (lambda run, tmp: run / "problem.toml", (), "a .toml file holds no design; give the --out directory"),
        (
            _damaged,
            (),
            "has no readable record of a design: eval_00002.npz cannot be read (ValueError: ",
        ),
        (
            lambda run, tmp: run,
            ("--set", "bodies[0].mesh.lengths=[6.0, 1.0, 0.5]"),
            "body 'beam' of the start design spans [0, 3] x [0, 1] x [0, 0.5], this one's cell centres span",
        ),
        (lambda run, tmp: run, ("--resume",), "--design-from and --resume exclude each other"),
    ],
)
def test_bad_sources_are_one_line_errors(optimized, tmp_path, capsys, make, extra, needle):
    out = tmp_path / "out"
    source = make(optimized, tmp_path)
    assert _run(out, COARSE, "--max-iter", "0", "--design-from", str(source), *extra) == 2
    err = _one_line_error(capsys)
    assert needle in err, err
    if "--resume" not in extra:
        assert err.startswith(f"contopt: error: --design-from {source}: ")
        assert not out.exists()  # refused before the run directory was made


def test_a_run_without_a_readable_record_says_to_start_from_its_vtu_files(optimized, tmp_path, capsys):
    source = _damaged(optimized, tmp_path)
    assert _run(tmp_path / "out", COARSE, "--max-iter", "0", "--design-from", str(source)) == 2
    err = _one_line_error(capsys)
    assert err.endswith(
        f"and neither can any record before it; start from its VTU files (--design-from {source / 'design.pvd'}) "
        "or from another run"
    )
    assert (
        _run(tmp_path / "pvd", COARSE, "--max-iter", "0", "--vtu", "none", "--design-from", str(source / "design.pvd"))
        == 0
    )


def test_a_start_of_other_bodies_is_a_one_line_error(optimized, tmp_path, capsys):
    args = ["-q", "run", str(_renamed(tmp_path)), "--set", f"bodies[0].mesh.divisions={COARSE}"]
    assert main([*args, "--out", str(tmp_path / "out"), "--max-iter", "0", "--design-from", str(optimized)]) == 2
    err = _one_line_error(capsys)
    assert "the start design has no design of body 'bar' (it designs 'beam'); start from a design of the same" in err


def test_a_vtu_without_a_volume_fraction_is_a_one_line_error(tmp_path, capsys):
    mesh = box(LENGTHS, COARSE)
    vtu = write_vtu(tmp_path / "beam_0000.vtu", mesh.points, mesh.cells, cell_data={"rho": np.ones(len(mesh.cells))})
    assert _run(tmp_path / "out", COARSE, "--max-iter", "0", "--design-from", str(vtu)) == 2
    assert "beam_0000.vtu has no volume fraction field 'nu' (cell or point data)" in _one_line_error(capsys)
