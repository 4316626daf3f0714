"""The exit statuses of ``contopt`` (contopt.cli.exits): each one from a real, cheap invocation, and the one
table that the command's --help and docs/cli.md show."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from contopt.cases.spec import bundled_cases
from contopt.cli import main
from contopt.cli.exits import (
    CHECK_FAILED,
    DONE,
    EXIT_STATUSES,
    FAILED,
    INTERRUPTED,
    TERMINATED,
    USAGE,
    Terminated,
    exit_status,
)
from contopt.errors import (
    ConfigError,
    ContoptError,
    ConvergenceError,
    LinearSolverError,
    MeshError,
    OutputError,
    UnavailableSolverError,
)
from contopt.optimize import EvaluationFailure
from contopt.optimize.rundir import RunLock

ROOT = Path(__file__).resolve().parents[2]


def _small_run(out, *extra):
    """The cantilever on a 12x4x2 mesh (96 cells) from its problem file, without output files."""
    case = str(bundled_cases()["cantilever"])
    small = ("--set", "bodies[0].mesh.divisions=[12, 4, 2]", "--vtu", "none", "--no-plot")
    return ["-q", "run", case, *small, "--max-iter", "2", "--out", str(out), *extra]


def _rows(history: Path) -> list:
    """The rows of a run's history.json so far (written whole, or not yet)."""
    return json.loads(history.read_text() or "[]") if history.exists() else []


def test_the_table_is_what_help_and_the_docs_say():
    assert (
        sorted(EXIT_STATUSES) == [DONE, CHECK_FAILED, USAGE, FAILED, INTERRUPTED, TERMINATED] == [0, 1, 2, 3, 130, 143]
    )
    out = subprocess.run([sys.executable, "-m", "contopt", "--help"], capture_output=True, text=True, timeout=120)
    assert out.returncode == DONE
    shown = out.stdout.split("exit status:")[1].split()
    docs = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    for code, text in EXIT_STATUSES.items():
        assert " ".join(shown).find(f"{code} {text.split()[0]}") >= 0, (code, out.stdout)
        assert f"| {code} |" in docs, f"docs/cli.md does not list exit status {code}"


@pytest.mark.parametrize(
    "error, status",
    [
        (KeyboardInterrupt(), INTERRUPTED),
        (Terminated(), TERMINATED),
        (ConfigError("bad key"), USAGE),
        (MeshError("inverted element"), USAGE),
        (OutputError("disk full"), USAGE),
        (UnavailableSolverError("no cholmod here"), USAGE),  # a LinearSolverError the user chose
        (ContoptError("anything else contopt says"), USAGE),
        (ConvergenceError("Newton"), FAILED),
        (LinearSolverError("singular"), FAILED),
        (EvaluationFailure("every trial design"), FAILED),
        (IndexError("a bug"), FAILED),
    ],
)
def test_each_error_has_its_status(error, status):
    assert exit_status(error) == status


def test_a_bad_key_in_a_problem_file_is_2(tmp_path, capsys):
    path = tmp_path / "mine.toml"
    path.write_text("max_iterations = 3\n" + bundled_cases()["cantilever"].read_text(encoding="utf-8"))
    assert main(["-q", "run", str(path), "--out", str(tmp_path / "out")]) == USAGE
    err = capsys.readouterr().err.strip()
    assert err.startswith("contopt: error:") and "max_iterations" in err and "\n" not in err


def test_an_unknown_option_is_2():
    out = subprocess.run(
        [sys.executable, "-m", "contopt", "run", "--no-such-option"], capture_output=True, text=True, timeout=120
    )
    assert out.returncode == USAGE and "unrecognized arguments: --no-such-option" in out.stderr


def test_a_check_that_fails_is_1_and_one_that_passes_0(capsys):
    args = ["-q", "check-gradient", "block-compression", "--divisions", "2", "--cells", "1"]
    assert main(args) == DONE
    assert main([*args, "--tol", "1e-300"]) == CHECK_FAILED  # no finite difference agrees to 1e-300
    assert "FAILED" in capsys.readouterr().out


def test_an_analysis_that_fails_is_3_and_keeps_its_state(tmp_path, capsys):
    out = tmp_path / "run"
    # one Newton iteration cannot converge the large-deformation cantilever, and no cutback below 0.5 is allowed
    assert main(_small_run(out, "--set", "newton.max_iter=1", "--set", "newton.min_step=0.5")) == FAILED
    err = capsys.readouterr().err.strip()
    assert err.startswith("contopt: error: the analysis of the full design") and "no convergence in 1 iterations" in err
    assert json.loads((out / "summary.json").read_text())["status"] == "failed"


ENDLESS = ("--set", "optimizer.mma.kkt_tol=0", "--set", "optimizer.mma.change_tol=0", "--max-iter", "1000000")


def _signalled_run(out: Path, signum: int, rows: int) -> tuple[int, str]:
    """An endless small run sent ``signum`` once its history has ``rows`` rows: its status and stderr."""
    run = subprocess.Popen(
        [sys.executable, "-m", "contopt", *_small_run(out, *ENDLESS)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.time() + 300
        while len(_rows(out / "history.json")) < rows:
            assert run.poll() is None and time.time() < deadline, "the run ended before it was signalled"
            time.sleep(0.05)
        os.kill(run.pid, signum)
        _, err = run.communicate(timeout=120)
    finally:
        if run.poll() is None:
            run.kill()
            run.wait(timeout=60)
    return run.returncode, err


def test_an_interrupted_run_is_130_and_resumes_from_what_it_computed(tmp_path, capsys):
    out = tmp_path / "run"
    code, err = _signalled_run(out, signal.SIGINT, 2)  # Ctrl-C
    assert code == INTERRUPTED, err[-2000:]
    assert "contopt: interrupted; results written so far are kept" in err
    kept = json.loads((out / "history.json").read_text())
    assert len(kept) >= 2 and not (out / "summary.json").exists()
    assert main(_small_run(out, "--resume", *ENDLESS[:4], "--max-iter", str(len(kept)))) == DONE
    assert json.loads((out / "summary.json").read_text())["replayed"] >= len(kept) - 1


def test_a_terminated_run_is_143_says_so_in_one_line_and_keeps_its_checkpoint(tmp_path):
    """SIGTERM (kill, a scheduler's time limit) ends a run as Ctrl-C does: one line, the lock released."""
    out = tmp_path / "run"
    code, err = _signalled_run(out, signal.SIGTERM, 1)
    assert code == TERMINATED, err[-2000:]
    assert err.strip().splitlines()[-1] == (
        "contopt: terminated (SIGTERM); results written so far are kept (contopt run --resume continues)"
    )
    assert "Traceback" not in err
    assert len(_rows(out / "history.json")) >= 1 and (out / "checkpoint" / "eval_00000.npz").exists()
    assert json.loads((out / "checkpoint" / "meta.json").read_text())["fingerprint"]
    with RunLock(out):  # released: a --resume may take the directory
        pass
