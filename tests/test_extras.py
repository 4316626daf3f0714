"""Without an extra everything else works, and what needs it says in one line how to install it.

``CONTOPT_WITHOUT`` makes contopt act as if the extras it names were not installed (contopt.extras);
tests/test_install.py installs the wheel without them.
"""

import os
import subprocess
import sys

import pytest

from contopt import extras
from contopt.cases.spec import bundled_cases


def _contopt(*args: str, without: str, cwd) -> subprocess.CompletedProcess:
    env = {**os.environ, "CONTOPT_WITHOUT": without}
    return subprocess.run(
        [sys.executable, "-m", "contopt.cli", *args], cwd=cwd, capture_output=True, text=True, timeout=600, env=env
    )


def test_a_hidden_backend_is_not_chosen_and_says_why(tmp_path):
    ask = (
        "from contopt.solve.linear import available_backends, why_unavailable;"
        "print(available_backends()); print(why_unavailable('pardiso'))"
    )
    env = {**os.environ, "CONTOPT_WITHOUT": "pardiso"}
    done = subprocess.run([sys.executable, "-c", ask], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    chosen, why = done.stdout.splitlines()
    assert "pardiso" not in chosen and "scipy" in chosen
    assert why == (
        "the pardiso backend needs the pardiso extra (hidden by CONTOPT_WITHOUT): "
        "pip install 'contopt[pardiso]' (MKL: x86-64 Linux and Windows)"
    )


def test_an_unknown_name_in_contopt_without_is_a_one_line_error(monkeypatch):
    monkeypatch.setenv("CONTOPT_WITHOUT", "viz, pictures")
    with pytest.raises(extras.MissingExtra, match=r"^CONTOPT_WITHOUT names pictures, which is no extra; use some of"):
        extras.installed("viz")


def test_a_run_that_asks_for_ipopt_without_it_says_how_to_install_it_or_run_mma(tmp_path):
    done = _contopt("run", "cantilever", "--optimizer", "ipopt", "--max-iter", "1", without="ipopt", cwd=tmp_path)
    assert done.returncode == 2
    errors = [line for line in done.stderr.splitlines() if line.startswith("contopt: error:")]
    assert errors == [
        "contopt: error: the IPOPT optimizer needs the ipopt extra (hidden by CONTOPT_WITHOUT): "
        "pip install 'contopt[ipopt]' (it compiles against Ipopt: apt-get install coinor-libipopt-dev pkg-config; "
        'or conda-forge\'s cyipopt); or optimize with MMA (--optimizer mma, or name = "mma" under [optimizer])'
    ], done.stderr
    assert "Traceback" not in done.stderr


def test_a_run_without_viz_writes_its_results_and_says_the_pictures_were_skipped(tmp_path):
    done = _contopt("run", "cantilever", "--max-iter", "1", "--out", "run", without="viz", cwd=tmp_path)
    said = done.stdout + done.stderr
    assert done.returncode == 0, said[-3000:]
    skipped = [line for line in said.splitlines() if "skipped" in line]
    assert skipped == [
        "pictures and report.html skipped: they need the viz extra (hidden by CONTOPT_WITHOUT): "
        "pip install 'contopt[viz]'; the results (VTU, CSV, JSON, STL) are written, and "
        "`contopt report run` draws them once it is there"
    ]
    run = tmp_path / "run"
    assert {"summary.json", "history.csv", "design.pvd", "design.stl"} <= {p.name for p in run.iterdir()}
    assert not list(run.glob("*.png")) and not (run / "report.html").exists()
    # asked for pictures, the report says in one line what they need
    report = _contopt("report", "run", without="viz", cwd=tmp_path)
    assert report.returncode == 2
    assert report.stderr.splitlines() == [
        "contopt: error: the plots need the viz extra (hidden by CONTOPT_WITHOUT): pip install 'contopt[viz]'"
    ]


def test_a_solver_the_problem_names_but_this_machine_lacks_is_one_usage_line_before_any_design(tmp_path):
    # no load-step cutback and no "the analysis of the full design failed": installing (or not
    # naming) the solver is what helps
    problem = tmp_path / "p.toml"
    text = bundled_cases()["cantilever"].read_text(encoding="utf-8")
    problem.write_text(text + '\n[linear]\nbackend = "pardiso"\n', encoding="utf-8")
    out = _contopt("run", str(problem), "--max-iter", "1", "--out", "run", without="pardiso", cwd=tmp_path)
    assert out.returncode == 2, out.stderr
    lines = [ln for ln in out.stderr.splitlines() if ln.startswith("contopt: error")]
    assert len(lines) == 1 and "backend 'pardiso' is not available here" in lines[0]
    assert "load step" not in out.stderr and "Traceback" not in out.stderr
