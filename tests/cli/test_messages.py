"""One-line errors that speak of what the user typed (a flag, a file), never of contopt's internals, and
state each thing once."""

import pytest

from contopt.cases.spec import bundled_cases
from contopt.cli import main
from contopt.cli.exits import FAILED, USAGE


def _error(args: list[str], status: int, capsys) -> str:
    assert main(["-q", *args]) == status
    err = capsys.readouterr().err.strip()
    assert err.startswith("contopt: error: ") and "\n" not in err and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("mu", ["-1", "nan", "inf"])
def test_a_bad_friction_coefficient_names_the_flag(mu, tmp_path, capsys):
    err = _error(["forward", "sliding-block", "--friction", mu, "--out", str(tmp_path)], USAGE, capsys)
    assert err.startswith("contopt: error: --friction must be a friction coefficient, a number >= 0")
    assert "Coulomb" not in err and not any(tmp_path.iterdir())


@pytest.mark.parametrize("command", [["forward", "block-compression"], ["check-gradient", "block-compression"]])
def test_an_unknown_solver_names_the_flag(command, tmp_path, capsys):
    err = _error([*command, "--solver", "nosuch"], USAGE, capsys)
    assert err == (
        "contopt: error: --solver: 'nosuch' is not one of 'auto', 'pardiso', 'cholmod', 'petsc', 'scipy' "
        "(`contopt info` lists those installed here)"
    )


def test_a_body_without_supports_is_said_once_to_lack_them(tmp_path, capsys):
    """The linear solver names the likely causes; the load stepping must not add the same cause again."""
    text = bundled_cases()["cantilever"].read_text(encoding="utf-8")
    start, end = text.index("[[supports]]"), text.index("[[loads]]")
    path = tmp_path / "free.toml"
    path.write_text(text[:start] + text[end:], encoding="utf-8")
    small = ["--set", "bodies[0].mesh.divisions=[6, 2, 2]", "--vtu", "none", "--no-plot", "--max-iter", "1"]
    err = _error(["run", str(path), *small, "--out", str(tmp_path / "run")], FAILED, capsys)
    assert "the tangent stiffness is singular" in err and err.count("without support") == 1
    assert ". ." not in err and ".. " not in err  # one full stop between sentences


def test_report_of_a_file_says_it_is_a_file(tmp_path, capsys):
    path = tmp_path / "summary.json"
    path.write_text("{}")
    err = _error(["report", str(path)], USAGE, capsys)
    assert err == f"contopt: error: {path} is a file, not a run directory: give the directory `contopt run --out` wrote"
