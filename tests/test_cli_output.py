"""What `contopt run` shows and writes for a person (issue: output a user can act on)."""

import json
import os
import pty
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from contopt import extras
from contopt.cli import build_parser, main, run_spec
from contopt.cli.progress import progress_line as _progress_line
from contopt.io.render import up_axis

ROOT = Path(__file__).resolve().parents[1]
CANTILEVER = ["run", "cantilever", "--no-plot", "--vtu", "none"]


def _lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.strip()]


def test_a_run_says_what_it_does_before_the_first_iteration(tmp_path, capsys):
    assert main([*CANTILEVER, "--max-iter", "1", "--out", str(tmp_path / "r")]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out  # not a terminal: plain lines only
    lines = _lines(out)
    order = [
        "reading the problem",
        "compiling the kernels",
        "kernels ready in",
        "reference analysis",
        "load step to t=",
        "it   0/1",
        "it   1/1",
        "after 1 iterations",
    ]
    positions = [next(i for i, line in enumerate(lines) if key in line) for key in order]
    assert positions == sorted(positions), lines
    assert lines[0].startswith("[") and " s] reading the problem" in lines[0]  # stamped from the start


def test_a_frictional_run_prepares_its_kernels_too(tmp_path, capsys):
    # the warm-up evaluates the model once before the first analysis; a frictional law needs the
    # start of a load step for that (it used to fail quietly and leave the compiling to the analysis)
    args = ["run", "friction-clamp", "--max-iter", "0", "--no-plot", "--vtu", "none", "--out", str(tmp_path / "r")]
    assert main(args) == 0
    lines = _lines(capsys.readouterr().out)
    ready = next(i for i, line in enumerate(lines) if "kernels ready in" in line)
    assert ready < next(i for i, line in enumerate(lines) if "reference analysis" in line)


def test_an_interactive_terminal_gets_a_live_status_line(tmp_path):
    leader, follower = pty.openpty()
    code = (
        "import sys; from contopt.cli import main; "
        f"sys.exit(main({[*CANTILEVER, '--max-iter', '1', '--out', str(tmp_path / 'r')]!r}))"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code],
        stdin=follower,
        stdout=follower,
        stderr=follower,
        cwd=ROOT,
        env={**os.environ, "COLUMNS": "120"},
    )
    os.close(follower)
    chunks = []
    while True:
        try:
            data = os.read(leader, 65536)
        except OSError:  # the child closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    assert proc.wait(timeout=300) == 0
    os.close(leader)
    text = b"".join(chunks).decode("utf-8", "replace")
    assert "kernels ready in" in text and "it   1/1" in text
    assert "\x1b[" in text  # the live line is drawn with terminal control sequences


@pytest.mark.skipif(not extras.installed("ipopt"), reason=extras.missing("ipopt", "IPOPT needs"))
def test_ipopt_is_quiet_and_keeps_its_summary_in_the_run_directory(tmp_path):
    # a real process: in-process, pytest's own log capture would hide what the terminal shows
    out = tmp_path / "r"
    args = [
        "run",
        "cantilever",
        "--optimizer",
        "ipopt",
        "--max-iter",
        "2",
        "--no-plot",
        "--vtu",
        "none",
        "--out",
        str(out),
    ]
    done = subprocess.run(
        [sys.executable, "-c", f"import sys; from contopt.cli import main; sys.exit(main({args!r}))"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    text = done.stdout + done.stderr
    assert "b'" not in text and "_cb" not in text, text
    assert sum(" it " in line for line in text.splitlines()) == 3
    log = (out / "ipopt.log").read_text()
    assert "iter" in log and "objective" in log.lower()


def test_set_works_on_a_named_case_and_its_variants(tmp_path, capsys):
    out = tmp_path / "r"
    assert (
        main([*CANTILEVER, "--set", "design.bodies[0].volume_fraction=0.25", "--max-iter", "0", "--out", str(out)]) == 0
    )
    summary = json.loads((out / "summary.json").read_text())
    assert np.ravel(summary["volume_fraction"]) == pytest.approx([0.25], abs=2e-3)
    fine = run_spec(
        build_parser().parse_args(
            [*CANTILEVER, "--mesh", "fine", "--design", "bspline", "--set", "design.bodies[0].volume_fraction=0.25"]
        )
    )
    assert fine.case == "cantilever" and fine.model.body("beam").mesh.n_cells == 48 * 16 * 8
    body = fine.problem.design.bodies[0]
    assert body.volume_fraction == 0.25 and body.parameterization.patches == (24, 8, 4)


def test_a_resumed_run_marks_the_replayed_iterations(tmp_path, capsys):
    out = tmp_path / "r"
    assert main([*CANTILEVER, "--max-iter", "2", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main([*CANTILEVER, "--max-iter", "3", "--out", str(out), "--resume"]) == 0
    lines = [line for line in _lines(capsys.readouterr().out) if " it " in line]
    assert [("replayed from the checkpoint" in line) for line in lines] == [True, True, True, False], lines


def test_the_results_line_lists_the_pictures_and_the_report(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["run", "cantilever", "--max-iter", "1", "--out", str(out)]) == 0
    last = _lines(capsys.readouterr().out)[-1]
    for name in ("report.html", "summary.json", "design.png", "deformed.png", "convergence.png", "design.stl"):
        assert name in last, last
        assert (out / name).exists()


def test_replayed_rows_say_so_instead_of_their_old_timings():
    row = {
        "iteration": 3,
        "objective": 1.0,
        "constraints": {"v": -0.1},
        "optimality": 0.1,
        "newton_iterations": 2,
        "seconds": {"iteration": 9.0},
    }
    assert "s/it" in _progress_line(row, 5.0, 10)
    replayed = _progress_line({**row, "replayed": True}, 5.0, 10)
    assert "replayed from the checkpoint" in replayed and "s/it" not in replayed


def _grid(u, designed=False):
    u = np.asarray(u, dtype=float).reshape(-1, 3)
    return (
        "b",
        SimpleNamespace(point_data={"displacement": u}, cell_data={"nu": 1} if designed else {}, n_points=len(u)),
    )


def test_the_picture_is_upright_along_the_push():
    roller = _grid([[0.0, -0.02, 0.0]] * 4)  # pushed down along y: y is up
    beam = _grid([[0.001, -0.005, 0.002]] * 4, designed=True)
    assert up_axis([beam, roller]) == 1
    assert up_axis([beam, _grid([[0.0, 0.0, -0.6]] * 2)]) == 2  # a die pressed down along z
    assert up_axis([beam]) == 1  # only designed bodies: theirs
    assert up_axis([beam, roller], up="x") == 0  # the problem file's view_up wins
    assert up_axis([_grid(np.zeros((3, 3)))]) == 2  # nothing moves: z
    with pytest.raises(Exception, match="up axis"):
        up_axis([beam], up="w")


def test_the_tutorials_sample_output_is_that_of_a_run():
    out = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "tutorial_output.py"), "--check"],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=ROOT,
    )
    assert out.returncode == 0, out.stdout + out.stderr[-2000:]
