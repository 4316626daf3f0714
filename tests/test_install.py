"""The wheel installs into a fresh venv and runs: the core alone, and with the viz extra.

Builds contopt's wheel from this source tree, makes a fresh venv, installs the wheel with pip from
the package registry (pip's cache makes a second run fast) and runs ``contopt run cantilever
--max-iter 2`` and ``contopt forward die-slab --mesh coarse`` in it. The core writes the results
(VTU, CSV, JSON, STL) and says in one line that the pictures were skipped and how to get them;
with ``viz`` the pictures and report.html are there. Skipped when the registry cannot be reached.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from contopt.extras import EXTRAS

ROOT = Path(__file__).resolve().parents[1]
#: what a run must write without the viz extra
RESULTS = ("summary.json", "history.csv", "history.json", "design.pvd", "design.stl", "problem.toml")
PICTURES = ("design.png", "deformed.png", "convergence.png", "report.html")
SKIPPED = "pictures and report.html skipped: they need the viz extra (not installed): pip install 'contopt[viz]'"


def _pip(python, *args, timeout=900) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(python), "-m", "pip", *args], capture_output=True, text=True, timeout=timeout, env=_clean_env()
    )


def _clean_env(venv: Path | None = None) -> dict:
    """The environment without this checkout's contopt (PYTHONPATH) or its venv; the JAX cache kept."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "CONTOPT_WITHOUT")}
    if venv is not None:
        env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    return env


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """contopt's wheel, built from a copy of the sources (the checkout gets no build/ or egg-info)."""
    probe = _pip(sys.executable, "index", "versions", "jax", "--retries", "0", "--timeout", "15", timeout=120)
    if probe.returncode != 0:
        pytest.skip(f"the package registry is unreachable: {probe.stderr.strip().splitlines()[-1:]}")
    tree = tmp_path_factory.mktemp("source")
    shutil.copytree(ROOT / "src", tree / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, tree / name)
    out = tmp_path_factory.mktemp("wheel")
    built = _pip(sys.executable, "wheel", "--no-deps", "-q", "-w", str(out), str(tree))
    assert built.returncode == 0, built.stderr[-3000:]
    (path,) = out.glob("contopt-*.whl")
    return path


def _venv(where: Path, wheel: Path) -> Path:
    subprocess.run([sys.executable, "-m", "venv", str(where)], check=True, timeout=300)
    _install(where, str(wheel))
    return where


def _install(venv: Path, what: str) -> None:
    done = _pip(venv / "bin" / "python", "install", "-q", what)
    assert done.returncode == 0, done.stderr[-3000:]


def _contopt(venv: Path, cwd: Path, *args: str) -> str:
    """What ``contopt ARGS`` said, checked for exit status 0 and no traceback."""
    done = subprocess.run(
        [str(venv / "bin" / "contopt"), *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=900,
        env=_clean_env(venv),
    )
    said = done.stdout + done.stderr
    assert done.returncode == 0, f"contopt {' '.join(args)}: {said[-3000:]}"
    assert "Traceback" not in said, said[-3000:]
    return said


def _run_both(venv: Path, cwd: Path) -> str:
    """``contopt run cantilever --max-iter 2`` (what it said) and ``contopt forward die-slab --mesh coarse``
    in ``cwd``, their result files checked."""
    said = _contopt(venv, cwd, "run", "cantilever", "--max-iter", "2", "--out", "run")
    _contopt(venv, cwd, "forward", "die-slab", "--mesh", "coarse", "--out", "forward")
    for name in RESULTS:
        assert (cwd / "run" / name).is_file(), name
    assert list((cwd / "run" / "vtu").glob("*.vtu"))
    assert (cwd / "forward" / "die-slab.pvd").is_file()
    assert len(list((cwd / "forward").glob("*.vtu"))) >= 2
    return said


@pytest.fixture(scope="module")
def venv(tmp_path_factory, wheel) -> Path:
    """A fresh venv with the wheel installed, core only (the viz test adds the extra to it)."""
    return _venv(tmp_path_factory.mktemp("venv") / "venv", wheel)


def test_the_core_wheel_runs_and_says_the_pictures_were_skipped(tmp_path, venv):
    modules = sum(EXTRAS.values(), ())
    ask = f"import importlib.util as u; print([m for m in {modules} if u.find_spec(m)])"
    python = venv / "bin" / "python"
    lean = subprocess.run([str(python), "-c", ask], capture_output=True, text=True, env=_clean_env(venv))
    if lean.stdout.strip() == "['matplotlib', 'pyvista', 'vtkmodules']":
        pytest.fail("the viz test ran first and installed viz into the shared venv: run this file in its order")
    assert lean.stdout.strip() == "[]", f"the core installed modules of extras: {lean.stdout}{lean.stderr}"
    run = _run_both(venv, tmp_path)
    assert [line for line in run.splitlines() if SKIPPED in line], run[-3000:]
    assert not [name for name in PICTURES if (tmp_path / "run" / name).exists()]


def test_the_wheel_with_viz_draws_the_pictures(tmp_path, venv, wheel):
    _install(venv, f"{wheel}[viz]")
    run = _run_both(venv, tmp_path)
    assert "skipped" not in run
    for name in PICTURES:
        assert (tmp_path / "run" / name).is_file(), f"{name} missing: {run[-3000:]}"
