import json
import shutil
import subprocess
import sys

import pytest

from contopt.cli import main


def test_console_script_help():
    exe = shutil.which("contopt")
    cmd = [exe, "--help"] if exe else [sys.executable, "-m", "contopt.cli", "--help"]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0
    assert "forward" in out.stdout and "list" in out.stdout


def test_list_and_info(capsys):
    assert main(["list"]) == 0
    assert "block-compression" in capsys.readouterr().out
    assert main(["info"]) == 0
    assert "sparse solvers" in capsys.readouterr().out


def test_forward_writes_results(tmp_path, capsys):
    assert main(["-q", "forward", "block-twist", "--divisions", "2", "--steps", "3", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["converged"] and (tmp_path / "block-twist.pvd").exists()
    assert "ParaView" in capsys.readouterr().out


@pytest.mark.parametrize("args, needle", [
    (["forward", "nope"], "unknown forward case 'nope'"),
    (["forward", "--solver", "mumps", "--divisions", "2"], "backend"),
])
def test_bad_input_is_one_line_error(args, needle, tmp_path, capsys):
    assert main(["-q", *args, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and err.startswith("contopt: error:") and "Traceback" not in err


def test_check_gradient_passes_and_can_fail(capsys):
    args = ["-q", "check-gradient", "two-blocks", "--divisions", "2", "--cells", "2", "--enforcement", "penalty"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "PASSED" in out and "contact_force" in out and "cell" in out and "random 1" in out
    # an impossible tolerance makes the same check fail with exit status 1
    assert main([*args, "--tol", "1e-300"]) == 1
    out = capsys.readouterr().out
    assert "FAILED" in out and "exceeds tolerance" in out


def test_check_gradient_of_an_optimization_case_checks_the_design_variables(capsys):
    """cantilever is only an optimization case: df/dx, dg/dx from the design variables."""
    assert main(["-q", "check-gradient", "cantilever", "--tol", "1e-5"]) == 0
    out = capsys.readouterr().out
    assert "design gradient check" in out and "objective / random 0" in out and "volume[beam]" in out
    assert main(["-q", "check-gradient", "cantilever", "--tol", "1e-30"]) == 1  # it can fail
    assert "FAILED" in capsys.readouterr().out


@pytest.mark.parametrize("args, needle", [
    (["check-gradient", "nope"], "unknown case 'nope'"),
    (["check-gradient", "block-compression", "--enforcement", "alm"], "no contact"),
    (["check-gradient", "two-blocks", "--response", "stress"], "unknown response 'stress'"),
    (["check-gradient", "die-slab", "--divisions", "3"], "--mesh coarse|fine"),
])
def test_check_gradient_bad_input(args, needle, capsys):
    assert main(["-q", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and err.startswith("contopt: error:") and "\n" not in err


def _run_args(out, *extra):
    return ["-q", "run", "cantilever", "--max-iter", "8", "--out", str(out), "--vtu", "none", "--no-plot", *extra]


def test_run_killed_with_sigkill_resumes_to_the_same_history(tmp_path):
    """kill -9 after three iterations, resume: the history is the uninterrupted one.

    The replayed rows are the killed run's, bit for bit. The analyses after them agree to
    round-off: the resumed process analyses its first matrix afresh where the uninterrupted one
    reused the analysis (ordering, scaling) of an earlier matrix (LinearSolverOptions.pardiso_reuse).
    All runs are processes of their own with ``MKL_CBWR=AUTO,STRICT``, so that MKL's threaded
    reductions do not add their own differences.
    """
    import os
    import signal
    import time

    env = {**os.environ, "MKL_CBWR": "AUTO,STRICT"}

    def cli(out, *extra):
        return [sys.executable, "-m", "contopt.cli", *_run_args(out, *extra)]

    done = subprocess.run(cli(tmp_path / "whole"), env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "f/|f0|" in done.stdout and "it   8/8" in done.stdout
    whole = json.loads((tmp_path / "whole" / "history.json").read_text())

    cut = tmp_path / "cut"
    proc = subprocess.Popen(cli(cut), env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 300
    try:
        while time.time() < deadline:
            path = cut / "history.json"
            if path.exists() and len(json.loads(path.read_text() or "[]")) >= 3:
                break
            assert proc.poll() is None, "the run ended before it could be killed"
            time.sleep(0.02)
        assert proc.poll() is None, "the run ended before it could be killed"
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    before = json.loads((cut / "history.json").read_text())
    assert 3 <= len(before) < len(whole)

    again = subprocess.run(cli(cut, "--resume"), env=env, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    resumed = json.loads((cut / "history.json").read_text())
    assert resumed[:len(before)] == before  # replayed rows, timings included
    assert len(resumed) == len(whole)
    for r, w in zip(resumed, whole):
        assert (r["cold_solves"], r["evaluations"]) == (w["cold_solves"], w["evaluations"])  # same warm starts
        assert r["objective"] == pytest.approx(w["objective"], rel=1e-9)
        # g = volume fraction - bound: near zero once active, so compared to the bound's size
        assert list(r["constraints"].values()) == pytest.approx(list(w["constraints"].values()), rel=1e-9, abs=1e-9)
    summary, reference = (json.loads((d / "summary.json").read_text()) for d in (cut, tmp_path / "whole"))
    assert summary["normalized_objective"] == pytest.approx(reference["normalized_objective"], rel=1e-9)
    assert summary["analyses"] == reference["analyses"] and summary["replayed"] >= len(before)


@pytest.mark.parametrize("args, needle", [
    (["run", "nope"], "unknown optimization case 'nope'"),
    (["run", "cantilever", "--design", "voxels"], "--design must be one of"),
    (["run", "cantilever", "--mesh", "huge"], "--mesh must be one of"),
    (["run", "cantilever", "--resume"], "nothing to resume"),
])
def test_run_bad_input_is_one_line_error(args, needle, tmp_path, capsys):
    assert main(["-q", *args, "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and err.startswith("contopt: error:") and "Traceback" not in err


def test_run_into_an_unwritable_directory_is_one_line_error(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    assert main(["-q", "run", "cantilever", "--max-iter", "1", "--out", str(blocker)]) == 2
    err = capsys.readouterr().err.strip()
    assert "cannot write the run directory" in err and "Traceback" not in err
