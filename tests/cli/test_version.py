"""The version is written once, in pyproject.toml; the package and the command read it from the install."""

import subprocess
import sys
import tomllib
from importlib.metadata import version
from pathlib import Path

import pytest

import contopt
from contopt.cli import main

ROOT = Path(__file__).resolve().parents[2]


def test_the_version_is_pyprojects_and_the_command_says_it(capsys):
    written = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["version"]
    assert version("contopt") == written, "the installed contopt is stale: reinstall it (make setup)"
    assert contopt.__version__ == written
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and capsys.readouterr().out.strip() == f"contopt {written}"


def test_the_version_is_not_written_in_the_source():
    written = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["version"]
    copies = [p for p in (ROOT / "src" / "contopt").rglob("*.py") if f'"{written}"' in p.read_text(encoding="utf-8")]
    assert not copies, copies


def test_python_dash_m_contopt_is_the_command():
    out = subprocess.run([sys.executable, "-m", "contopt", "--version"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == f"contopt {contopt.__version__}"
