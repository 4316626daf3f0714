"""The exit statuses of ``contopt`` (contopt.cli.exits): each one from a real, cheap invocation, and the one
table that the command's --help and docs/cli.md show."""

import json
import os
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from contopt.cases.spec import bundled_cases
from contopt.cli import COMMANDS, main
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


def _default_signals() -> None:
    """In the child before exec: SIGINT and SIGTERM at their defaults, whatever the test runner inherited."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _signalled_run(out: Path, signum: int, rows: int) -> tuple[int, str]:
    """An endless small run sent ``signum`` once its history has ``rows`` rows: its status and stderr."""
    run = subprocess.Popen(
        [sys.executable, "-m", "contopt", *_small_run(out, *ENDLESS)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        # a test run started in the background (`make test &`) ignores SIGINT, and so would the child: its
        # Ctrl-C would never arrive (the run went on until the 120 s timeout). The default, as at a terminal
        preexec_fn=_default_signals,
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


def _under_ulimit(kib: int, *args: str) -> subprocess.CompletedProcess:
    """``contopt ARGS`` in a shell whose address space is limited to ``kib`` KiB (``ulimit -v``)."""
    command = f"ulimit -v {kib} && exec {shlex.quote(sys.executable)} -m contopt {shlex.join(args)}"
    return subprocess.run(["bash", "-c", command], capture_output=True, text=True, timeout=300)


def test_a_memory_error_anywhere_in_a_command_is_one_line_and_3(monkeypatch, capsys):
    def list_that_runs_out(args):
        raise MemoryError()

    monkeypatch.setitem(COMMANDS, "list", list_that_runs_out)
    assert main(["-q", "list"]) == FAILED
    err = capsys.readouterr().err
    assert err.startswith("contopt: error: out of memory") and err.count("\n") == 1 and "Traceback" not in err
    assert "use a coarser mesh or raise the limit" in err


def test_the_interpreter_failing_under_a_tiny_address_space_is_one_line(monkeypatch, capsys):
    """Under `ulimit -v` 400 MB compiling a module's bytecode can end in a SystemError (seen once on a
    fresh checkout, where nothing was compiled yet): one line; without such a limit it is a bug, reported
    with its traceback."""
    import contopt.cli.exits as exits

    def list_that_fails(args):
        raise SystemError("<built-in function compile> returned NULL without setting an exception")

    monkeypatch.setitem(COMMANDS, "list", list_that_fails)
    monkeypatch.setattr(exits, "address_space_limit", lambda: 400_000 * 1024)
    assert main(["-q", "list"]) == FAILED
    err = capsys.readouterr().err
    assert err.startswith("contopt: error: Python failed (<built-in function compile>") and err.count("\n") == 1
    assert "raise the limit (ulimit -v)" in err
    monkeypatch.setattr(exits, "address_space_limit", lambda: None)
    main(["-q", "list"])
    err = capsys.readouterr().err
    assert "Traceback" in err and "unexpected error (SystemError)" in err


@pytest.mark.skipif(not sys.platform.startswith("linux") or shutil.which("bash") is None, reason="ulimit -v of bash")
def test_an_address_space_too_small_for_jax_is_one_line_naming_the_limit(tmp_path):
    """Under `ulimit -v` 400 MB jaxlib cannot map its library (or Python its bytecode): one line, no traceback."""
    done = _under_ulimit(400_000, "-q", "run", "cantilever", "--max-iter", "1", "--out", str(tmp_path / "run"))
    assert done.returncode == FAILED, done.stderr[-2000:]
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("contopt: error: ") and "under the address-space limit (ulimit -v) of 391 MiB" in last
    assert last.endswith("raise the limit (ulimit -v)") and "Traceback" not in done.stderr


@pytest.mark.skipif(not sys.platform.startswith("linux") or shutil.which("bash") is None, reason="ulimit -v of bash")
def test_a_mesh_too_large_for_the_address_space_limit_is_refused_before_it_is_built(tmp_path):
    """200,000 cells need at least 3.05 GiB (16 KiB a cell), more than `ulimit -v` 2.86 GiB allows: refused
    at once (it ran for 38 s into a MemoryError traceback)."""
    big = ("--set", "bodies[0].mesh.divisions=[100, 40, 50]", "--max-iter", "1", "--out", str(tmp_path / "run"))
    done = _under_ulimit(3_000_000, "-q", "run", "cantilever", *big)
    assert done.returncode == USAGE, done.stderr[-2000:]
    (line,) = [s for s in done.stderr.splitlines() if s.startswith("contopt: error:")]
    assert "would have 2e+05 cells; an analysis of it needs at least 3.05 GiB" in line
    assert "the address-space limit (ulimit -v) of 2.86 GiB leaves" in line and line.endswith("or raise the limit")
