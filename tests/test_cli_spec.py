"""`contopt run FILE.toml`, the flags that replace the file's values, `contopt list` and `contopt export`."""

import json
import re

import pytest
from _compare import problem_differences  # tests/_compare.py

from contopt.cases.spec import SpecError, bundled_cases, cases_dir, load_spec
from contopt.cli import build_parser, main, run_spec

#: a small cantilever (no contact): 48 cells, a few seconds for two iterations
SMALL = """\
name = "small-beam"

[[bodies]]
name = "beam"
mesh = { generator = "box", lengths = [3.0, 1.0, 0.5], divisions = [6, 4, 2] }
material = { model = "neo-hookean", E = 1.0, nu = 0.3 }

[[bodies.sets]]
name = "tip"
from = "xmax"
y = [0.0, 0.25]

[[supports]]
body = "beam"
set = "xmin"

[[loads]]
type = "traction"
body = "beam"
set = "tip"
traction = [0.0, -1e-6, 0.0]

[[design.bodies]]
body = "beam"
volume_fraction = 0.3
density = { radius = 0.5 }

[objective]
response = "compliance"

[optimizer.mma]
move = 0.1

[run]
max_iter = 50
vtu = "final"
"""


def write(tmp_path, text, name="my.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_run_a_problem_file(tmp_path, capsys):
    path = write(tmp_path, SMALL)
    out = tmp_path / "tmp"
    assert main(["-q", "run", str(path), "--max-iter", "2", "--out", str(out), "--no-plot"]) == 0
    stdout = capsys.readouterr().out
    assert re.findall(r"^\[ *[\d.]+ s\] it +(\d)/2 ", stdout, re.M) == ["0", "1", "2"]
    assert "small-beam: max_iter after 2 iterations" in stdout
    assert stdout.strip().endswith(
        f"results in {out}: report.html, summary.json, design.pvd, history.csv, "
        "history.json, problem.toml, vtu/ (1 VTU file)"
    )
    assert (
        '<td data-key="case" data-value="&quot;small-beam&quot;">small-beam</td>' in (out / "report.html").read_text()
    )  # the case, from the problem.toml the CLI keeps
    page = (out / "report.html").read_text()  # the problem in words, as the file describes it
    for said in (
        "One body: beam (hex8, 48 cells, neo-Hookean, E = 1, nu = 0.3, F-bar).",
        "Supports: beam/xmin fixed in x, y, z.",
        "Loads over 1 load step: traction (0, -1e-06, 0) on beam/tip.",
        "Design: beam (density method, cone filter radius 0.5; volume fraction \u2264 0.3)",
        "Objective: minimize the compliance of all bodies, divided by its value at the full design.",
    ):
        assert said in page, said
    summary = json.loads((out / "summary.json").read_text())
    assert summary["iterations"] == 2 and summary["design"][0]["n_design"] == 48
    assert len(json.loads((out / "history.json").read_text())) == 3
    assert (out / "vtu" / "beam_0002.vtu").exists() and not (out / "vtu" / "beam_0001.vtu").exists()  # vtu = final
    assert not (out / "convergence.png").exists()  # --no-plot
    saved = (out / "problem.toml").read_text()  # what was run, next to its results
    assert saved.startswith(f"# contopt run {path} --max-iter 2 --out {out} --no-plot\n") and SMALL in saved
    assert problem_differences(load_spec(out / "problem.toml").problem, load_spec(path).problem) == []


@pytest.mark.parametrize(
    "replace, extra, needle",
    [
        (("E = 1.0", "E = -1.0"), [], "my.toml: bodies[0].material.E: must be > 0, got -1.0"),
        (
            ('set = "xmin"', 'set = "xmn"'),
            [],
            "my.toml: supports[0].set: body 'beam' has no node set 'xmn'; did you mean 'xmin'?",
        ),
        (
            (),
            ["--set", "design.bodies[0].volume_fraction=1.5"],
            "my.toml: --set design.bodies[0].volume_fraction must lie in (0, 1), got 1.5",
        ),
        ((), ["--eta", "-2"], "my.toml: --eta must be a number > 0, got -2.0 (design.eta)"),
        ((), ["--max-iter", "-1"], "my.toml: --max-iter must be an integer >= 0, got -1 (run.max_iter)"),
        ((), ["--mesh", "fine"], "--mesh applies to a file that names a registered case"),
        ((), ["--set", "oops"], "--set needs KEY=VALUE"),
        (("[run]", "[run\n"), [], "my.toml:34:"),
    ],
)
def test_bad_file_or_flag_exits_2_with_one_line(tmp_path, capsys, replace, extra, needle):
    path = write(tmp_path, SMALL.replace(*replace) if replace else SMALL)
    assert main(["-q", "run", str(path), "--out", str(tmp_path / "out"), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("contopt: error: ") and "\n" not in err and needle in err, err
    assert not (tmp_path / "out").exists()  # nothing ran


def test_unknown_case_or_missing_file(tmp_path, capsys):
    assert main(["-q", "run", "nope"]) == 2
    err = capsys.readouterr().err
    assert "unknown optimization case 'nope'" in err and "die-slab" in err and ".toml" in err
    assert main(["-q", "run", str(tmp_path / "missing.toml")]) == 2
    assert "no such problem file" in capsys.readouterr().err


def _spec(*argv):
    return run_spec(build_parser().parse_args(["run", *argv]))


def test_flags_replace_the_files_values():
    path = str(bundled_cases()["die-slab"])
    spec = _spec(
        path,
        "--optimizer",
        "ipopt",
        "--max-iter",
        "3",
        "--eta",
        "6",
        "--out",
        "elsewhere",
        "--vtu",
        "none",
        "--no-plot",
        "--set",
        "design.bodies[0].volume_fraction=0.3",
        "--set",
        "newton.n_steps=4",
    )
    assert (spec.optimizer, spec.max_iter, spec.eta, spec.out, spec.vtu, spec.plot) == (
        "ipopt",
        3,
        6.0,
        "elsewhere",
        "none",
        False,
    )
    assert spec.options.tol == 1e-3  # the file's [optimizer.ipopt]
    assert spec.problem.design.bodies[0].volume_fraction == 0.3 and spec.problem.newton.n_steps == 4
    plain = _spec(path)
    assert (plain.optimizer, plain.max_iter, plain.eta, plain.out, plain.vtu, plain.plot) == (
        "mma",
        100,
        10.0,
        "results/die-slab",
        "every",
        True,
    )


def test_case_names_registered_and_bundled():
    spec = _spec("die-slab", "--design", "density", "--mesh", "coarse", "--eta", "8", "--max-iter", "4")
    assert spec.case == "die-slab" and spec.eta == 8.0 and spec.max_iter == 4 and spec.out == "results/die-slab"
    assert spec.problem.design.bodies[0].parameterization.radius == 0.7
    assert _spec("cantilever").problem.design.bodies[0].parameterization.radius == 0.25
    with pytest.raises(
        Exception,
        match=r"^die-slab: --mesh must be one of \['coarse', 'fine', 'xl', 'xxl'\], got 'medium' "
        r"\(case_options.mesh\)$",
    ):
        _spec("die-slab", "--mesh", "medium")


def test_a_bundled_file_without_a_registered_case(monkeypatch):
    import contopt.cases.optimization as cases

    monkeypatch.setattr(cases, "OPTIMIZATION_CASES", {})
    spec = _spec("die-cantilever", "--max-iter", "5")
    assert spec.case is None and spec.source == "die-cantilever.toml" and spec.max_iter == 5
    assert spec.model.dirichlet[0].node_set == "xmax"


def test_list_shows_the_problem_files(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert str(cases_dir()) in out and "die-slab.toml" in out and "die-slab-contact-force.toml" in out


def test_export_writes_the_bundled_file(tmp_path, capsys, monkeypatch):
    target = tmp_path / "mine.toml"
    assert main(["export", "die-cantilever", "--out", str(target)]) == 0
    assert target.read_text() == bundled_cases()["die-cantilever"].read_text()
    assert f"contopt run {target}" in capsys.readouterr().out
    assert main(["-q", "export", "die-cantilever", "--out", str(target)]) == 2  # no silent overwrite
    assert "already exists" in capsys.readouterr().err
    assert main(["export", "die-cantilever", "--out", str(target), "--force"]) == 0
    capsys.readouterr()
    assert main(["export", "cantilever", "--out", "-"]) == 0
    assert capsys.readouterr().out == bundled_cases()["cantilever"].read_text()
    monkeypatch.chdir(tmp_path)
    assert main(["export", "die-slab"]) == 0 and (tmp_path / "die-slab.toml").exists()
    assert main(["-q", "export", "nope"]) == 2 and "unknown case 'nope'" in capsys.readouterr().err


def test_export_of_a_case_without_a_bundled_file(tmp_path, monkeypatch):
    import contopt.cases.spec as spec_module

    monkeypatch.setattr(spec_module, "bundled_cases", lambda: {})
    target = tmp_path / "short.toml"
    assert main(["export", "die-slab-contact-force", "--out", str(target)]) == 0
    text = target.read_text()
    assert 'case = "die-slab-contact-force"' in text and "[case_options]" in text
    spec = load_spec(target)
    assert spec.case == "die-slab-contact-force" and spec.out == "results/die-slab-contact-force"


def test_case_workers_flag_replaces_the_files_value():
    path = str(bundled_cases()["two-way-press"])
    assert _spec(path).problem.case_workers == 1
    assert _spec(path, "--case-workers", "2").problem.case_workers == 2
    with pytest.raises(SpecError, match="case_workers"):
        _spec(path, "--case-workers", "0")
