"""`contopt check-gradient` on a problem file, read as `contopt run` reads it (--set included): df/dx and
dg/dx through the whole chain for responses and formulations no bundled case uses."""

import pytest

from contopt.cases.spec import bundled_cases
from contopt.cli import main
from contopt.cli.exits import CHECK_FAILED, DONE, USAGE

SMALL = ("--set", "bodies[0].mesh.divisions=[6, 2, 2]")  # the cantilever, 24 cells
FORCE_MAX = (
    "--set",
    'objective={response = "force-max", steps = 3, sharpness = 1e4, on = "displacement", bodies = "beam", '
    'set = "tip", direction = [0.0, -1.0, 0.0], sense = "minimize"}',
)


@pytest.fixture
def cantilever(tmp_path):
    path = tmp_path / "beam.toml"
    path.write_text(bundled_cases()["cantilever"].read_text(encoding="utf-8"), encoding="utf-8")
    return str(path)


def _rows(out: str) -> dict:
    """The table's relative errors by row label."""
    rows = {}
    for line in out.splitlines():
        if " / random " in line:
            label, _, rest = line.partition(" / random ")
            rows[label] = float(rest.split()[3])
    return rows


def test_check_gradient_of_a_problem_file_passes_and_can_fail(cantilever, capsys):
    assert main(["-q", "check-gradient", cantilever, *SMALL]) == DONE
    out = capsys.readouterr().out
    assert "189 dofs, 24 cells" in out and "objective compliance" in out and "passed" in out
    rows = _rows(out)
    assert set(rows) == {"objective", "volume[beam]<=0.3"} and max(rows.values()) < 1e-5
    # no finite difference agrees to 1e-30: the same check fails with exit status 1
    assert main(["-q", "check-gradient", cantilever, *SMALL, "--tol", "1e-30"]) == CHECK_FAILED
    assert "FAILED" in capsys.readouterr().out


def test_force_max_on_a_displacement_is_checked_through_set(cantilever, capsys):
    """A load-path response of a model without contact (on = "displacement"), set from the command line."""
    assert main(["-q", "check-gradient", cantilever, *SMALL, *FORCE_MAX]) == DONE
    out = capsys.readouterr().out
    assert "objective force_max" in out and max(_rows(out).values()) < 1e-5


def test_the_robust_formulation_checks_each_realization(cantilever, capsys):
    robust = ("--set", "design.robust.delta=0.15", "--set", "design.eta=4")  # eta 4: the eroded design is not void
    assert main(["-q", "check-gradient", cantilever, *SMALL, *robust]) == DONE
    rows = _rows(capsys.readouterr().out)
    bounds = {f"objective[{r}]<=bound" for r in ("eroded", "intermediate", "dilated")}
    assert bounds <= set(rows) and max(rows.values()) < 1e-5


def _error(args: list[str], capsys) -> str:
    assert main(["-q", *args]) == USAGE
    err = capsys.readouterr().err.strip()
    assert err.startswith("contopt: error: ") and "\n" not in err and "Traceback" not in err, err
    return err


def test_a_missing_file_is_one_line(tmp_path, capsys):
    missing = tmp_path / "nope.toml"
    err = _error(["check-gradient", str(missing)], capsys)
    assert err.startswith(f"contopt: error: no such problem file: {missing}")


def test_a_model_only_file_is_no_optimization_problem(tmp_path, capsys):
    text = bundled_cases()["cantilever"].read_text(encoding="utf-8")
    path = tmp_path / "model.toml"
    path.write_text(text[: text.index("[design]")], encoding="utf-8")
    err = _error(["check-gradient", str(path)], capsys)
    assert f"{path} is no optimization problem" in err and "check its design gradients" in err
    assert "optimize it" in _error(["run", str(path), "--out", str(tmp_path / "run")], capsys)


def test_set_on_an_analysis_case_and_an_unknown_name_are_one_line(capsys):
    err = _error(["check-gradient", "block-compression", "--set", "newton.max_iter=3"], capsys)
    assert "'block-compression' is an analysis case" in err
    err = _error(["check-gradient", "nope"], capsys)
    assert "unknown case 'nope'" in err and "block-compression" in err and "cantilever" in err
