import json
import shutil
import subprocess
import sys

import numpy as np
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
    out = capsys.readouterr().out
    assert "sparse solvers" in out
    from contopt.solve.linear import BACKENDS, available_backends

    for name in BACKENDS:  # each says whether it is there, and why not
        line = next(ln for ln in out.splitlines() if ln.split()[:1] == [name])
        assert ("not available:" in line) == (name not in available_backends())


def test_forward_writes_results(tmp_path, capsys):
    assert main(["-q", "forward", "block-twist", "--divisions", "2", "--steps", "3", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["converged"] and (tmp_path / "block-twist.pvd").exists()
    assert "ParaView" in capsys.readouterr().out


def test_forward_with_friction_writes_the_tractions_and_prints_the_force_ratio(tmp_path, capsys):
    import meshio

    assert main(["-q", "forward", "sliding-block", "--friction", "0.2", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    (f,), (n,) = summary["friction_force"], summary["contact_force"]
    assert np.linalg.norm(f) / n == pytest.approx(0.2, rel=1e-6)  # dragged 0.1: every node slides
    assert f"ratio {np.linalg.norm(f) / n:.6g}" in capsys.readouterr().out
    block = meshio.read(tmp_path / "block_0004.vtu")
    traction = block.point_data["friction_traction"]
    assert traction[:, 0].min() < 0 and traction[:, 0].max() <= 0  # on the block, against its drag (+x)
    assert main(["-q", "forward", "block-twist", "--friction", "0.2", "--out", str(tmp_path)]) == 2
    assert "has no contact" in _one_line_error(capsys)


@pytest.mark.parametrize(
    "args, needle",
    [
        (["forward", "nope"], "unknown forward case 'nope'"),
        (["forward", "--solver", "mumps", "--divisions", "2"], "--solver: 'mumps' is not one of"),
    ],
)
def test_bad_input_is_one_line_error(args, needle, tmp_path, capsys):
    assert main(["-q", *args, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and err.startswith("contopt: error:") and "Traceback" not in err


def test_check_gradient_passes_and_can_fail(capsys):
    args = ["-q", "check-gradient", "two-blocks", "--divisions", "2", "--cells", "2", "--law", "penalty"]
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


@pytest.mark.parametrize(
    "args, needle",
    [
        (["check-gradient", "nope"], "unknown case 'nope'"),
        (["check-gradient", "block-compression", "--law", "alm"], "no contact"),
        (["check-gradient", "two-blocks", "--response", "von-mises"], "unknown response 'von-mises'"),
        (["check-gradient", "die-slab", "--divisions", "3"], "--mesh coarse|fine"),
    ],
)
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
    assert resumed[: len(before)] == before  # replayed rows, timings included
    assert len(resumed) == len(whole)
    for r, w in zip(resumed, whole):
        assert (r["cold_solves"], r["evaluations"]) == (w["cold_solves"], w["evaluations"])  # same warm starts
        assert r["objective"] == pytest.approx(w["objective"], rel=1e-9)
        # g = volume fraction - bound: near zero once active, so compared to the bound's size
        assert list(r["constraints"].values()) == pytest.approx(list(w["constraints"].values()), rel=1e-9, abs=1e-9)
    summary, reference = (json.loads((d / "summary.json").read_text()) for d in (cut, tmp_path / "whole"))
    assert summary["normalized_objective"] == pytest.approx(reference["normalized_objective"], rel=1e-9)
    assert summary["analyses"] == reference["analyses"] and summary["replayed"] >= len(before)


@pytest.mark.parametrize(
    "args, needle",
    [
        (["run", "nope"], "unknown optimization case 'nope'"),
        (["run", "cantilever", "--design", "voxels"], "--design must be one of"),
        (["run", "cantilever", "--mesh", "huge"], "--mesh must be one of"),
        (["run", "cantilever", "--resume"], "nothing to resume"),
    ],
)
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


# --- the run directory ------------------------------------------------------------------------------


def _small_run_args(out, *extra):
    """The cantilever on a 12x4x2 mesh (96 cells) from its problem file, quiet and without output files."""
    from contopt.cases.spec import bundled_cases

    return [
        "-q",
        "run",
        str(bundled_cases()["cantilever"]),
        "--set",
        "bodies[0].mesh.divisions=[12, 4, 2]",
        "--max-iter",
        "2",
        "--out",
        str(out),
        "--vtu",
        "none",
        "--no-plot",
        *extra,
    ]


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("contopt: error:") and "\n" not in err and "Traceback" not in err, err
    return err


def test_run_of_a_directory_another_process_writes_is_refused_naming_its_pid(tmp_path, capsys):
    """A real second writer: a run that goes on (no stopping test, a huge --max-iter) holds the directory;
    --overwrite and --resume of it are refused with its PID; once it is killed (-9) the lock is gone."""
    import os
    import signal
    import time

    out = tmp_path / "run"
    endless = ("--set", "optimizer.mma.kkt_tol=0", "--set", "optimizer.mma.change_tol=0")
    first = subprocess.Popen(
        [sys.executable, "-m", "contopt.cli", *_small_run_args(out, "--max-iter", "1000000", *endless)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.time() + 300
        while not (out / "history.json").exists():  # written while the first run holds the lock
            assert first.poll() is None and time.time() < deadline, "the first run ended before it was tested"
            time.sleep(0.05)
        for flag in ("--overwrite", "--resume"):
            assert main(_small_run_args(out, flag)) == 2
            assert f"is in use by another run (PID {first.pid}" in _one_line_error(capsys)
        assert first.poll() is None  # it still runs, its files untouched
        os.kill(first.pid, signal.SIGKILL)
    finally:
        if first.poll() is None:
            first.kill()
        first.wait(timeout=60)
    assert main(_small_run_args(out, "--resume", *endless)) == 0  # kill -9 released the lock
    assert json.loads((out / "summary.json").read_text())["replayed"] >= 1


def test_run_resume_with_overwrite_is_refused(tmp_path, capsys):
    assert main(_small_run_args(tmp_path, "--resume", "--overwrite")) == 2
    assert "--resume and --overwrite exclude each other" in _one_line_error(capsys)


def test_run_on_a_full_disk_is_one_line_saying_what_was_kept_and_resumes(tmp_path, capsys, monkeypatch):
    import errno
    import os

    real = os.fsync

    def fsync(fd):  # the disk fills up while the third analysis is stored
        if "eval_00002" in os.readlink(f"/proc/self/fd/{fd}"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(fd)

    out = tmp_path / "run"
    with monkeypatch.context() as patch:
        patch.setattr(os, "fsync", fsync)
        assert main(_small_run_args(out)) == 2
    err = _one_line_error(capsys)
    assert f"cannot write {out / 'checkpoint' / 'eval_00002.npz'}: No space left on device" in err
    assert "keeps its 2 recorded analyses and the history of 2 iterations" in err and "--resume" in err
    assert not [p for p in out.rglob("*") if ".tmp" in p.name]
    assert main(_small_run_args(out, "--resume")) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["iterations"] == 2 and summary["replayed"] == 2


def test_run_whose_first_analysis_fails_writes_its_state_and_a_rerun_needs_no_overwrite(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(_small_run_args(out, "--set", "loads[0].traction=[0.0, -10.0, 0.0]")) == 3  # the analysis failed
    err = _one_line_error(capsys)
    assert "the analysis of the full design" in err and f"is in {out / 'design.pvd'}" in err
    assert 'has status "failed"' in err and "without --overwrite" in err
    summary = json.loads((out / "summary.json").read_text())
    state = summary["failed_analysis"]["last_converged_state"]
    assert summary["status"] == "failed" and (out / state["files"][0]).exists()
    assert "loads[0].traction=" in (out / "problem.toml").read_text()  # what ran, kept with the failure
    assert main(["-q", "report", str(out), "--no-pictures"]) == 0
    assert "failed analysis: the full design" in capsys.readouterr().out
    assert main(_small_run_args(out)) == 0  # no --overwrite needed: nothing was completed
    assert json.loads((out / "summary.json").read_text())["status"] == "max_iter"


def test_run_whose_trial_designs_all_fail_exits_with_status_3_and_keeps_its_results(tmp_path, capsys, monkeypatch):
    from contopt.errors import ContoptError
    from contopt.optimize import problem

    real = problem.DesignNLP.solve_state
    calls = []

    def later_analyses_fail(self, *args, **kwargs):
        calls.append(1)
        if len(calls) > 2:  # the full design (the scale) and the start analyse; every trial design fails
            raise ContoptError("Newton stagnated (forced by the test)")
        return real(self, *args, **kwargs)

    monkeypatch.setattr(problem.DesignNLP, "solve_state", later_analyses_fail)
    out = tmp_path / "run"
    assert main(_small_run_args(out)) == 3  # the optimizer failed
    captured = capsys.readouterr()
    assert "the optimization failed:" in captured.err and "forced by the test" in captured.err
    summary = json.loads((out / "summary.json").read_text())
    # what was reached is kept: the start's analysis, in the summary and the history
    assert summary["status"] == "failed" and np.isfinite(summary["objective"])
    assert len((out / "history.csv").read_text().strip().splitlines()) == 2


def test_run_with_a_huge_max_iter_has_a_sane_eta_and_ipopt_refuses_it(tmp_path, capsys):
    from contopt.cli.progress import duration as _duration
    from contopt.cli.progress import progress_line as _progress_line

    row = {
        "iteration": 3,
        "objective": 1.0,
        "constraints": {"v": -0.1},
        "optimality": 0.1,
        "newton_iterations": 2,
        "seconds": {"iteration": 0.3},
    }
    line = _progress_line(row, 0.3 * (10**20 - 3), 10**20)
    assert line.endswith("ETA > 99 days") and len(line) < 120
    assert _progress_line(row, 125.0, 500).endswith("ETA <= 2m05s")
    assert _duration(3 * 86400 + 4 * 3600) == "3d04h" and _duration(float("nan")) == "> 99 days"
    assert main(_small_run_args(tmp_path, "--optimizer", "ipopt", "--max-iter", str(10**12))) == 2
    assert "ipopt.max_iter must be an integer in [0, 2147483647]" in _one_line_error(capsys)


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--divisions", "2", "--steps", "0"], "--steps must be a positive number of load steps, got 0"),
        (["--divisions", "2", "--steps", "-2"], "--steps must be a positive number of load steps, got -2"),
        (["--divisions", "100000"], "would have 1e+15 cells; an analysis of it needs at least"),
    ],
)
def test_forward_refuses_zero_steps_and_a_wildly_large_mesh(args, needle, tmp_path, capsys):
    assert main(["-q", "forward", "block-compression", *args, "--out", str(tmp_path)]) == 2
    assert needle in _one_line_error(capsys)
