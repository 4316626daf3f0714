"""Several load cases (contopt.optimize.load_case, contopt.optimize.multicase): the reader's keys and
errors, each case's analysis against the same problem with only that case, the gradients of the
weighted sum and of each case's worst-case row against central differences, the bound formulation's
beta, per-case warm starts, and MMA and IPOPT lowering the worst case."""

import dataclasses

import numpy as np
import pytest

from contopt import extras
from contopt.cases.checks import check_design_problem
from contopt.cases.spec import SpecError, load_spec
from contopt.cli.progress import progress_line
from contopt.errors import ConfigError
from contopt.optimize.driver import optimize
from contopt.optimize.ipopt import IpoptOptions
from contopt.optimize.load_case import LoadCase
from contopt.optimize.mma import MMAOptions
from contopt.optimize.multicase import LoadCasesNLP, design_nlp
from contopt.optimize.output_options import OutputOptions
from contopt.optimize.problem import DesignNLP
from contopt.optimize.report import report_text

#: a small cantilever clamped at x = 0, its end pulled down in one case and sideways in the other
TWO_CASES = """\
[[bodies]]
name = "beam"
mesh = { generator = "box", lengths = [2.0, 1.0, 0.5], divisions = [6, 3, 2] }
material = { model = "neo-hookean", E = 1.0, nu = 0.3 }

[[supports]]
body = "beam"
set = "xmin"

[design]

[[design.bodies]]
body = "beam"
volume_fraction = 0.4
density = { radius = 0.4 }

[objective]
response = "compliance"
combine = "worst"

[[load_cases]]
name = "down"
[[load_cases.loads]]
type = "traction"
body = "beam"
set = "xmax"
traction = [0.0, -1e-3, 0.0]

[[load_cases]]
name = "side"
weight = 2.0
[[load_cases.loads]]
type = "traction"
body = "beam"
set = "xmax"
traction = [0.0, 0.0, 1e-3]

[[constraints]]
response = "compliance"
case = "side"
upper = 100.0
"""

#: the same beam with only the "down" case's load, as a file without load cases says it
DOWN_ONLY = TWO_CASES.split("[[load_cases]]")[0].replace('combine = "worst"\n', "") + (
    '[[loads]]\ntype = "traction"\nbody = "beam"\nset = "xmax"\ntraction = [0.0, -1e-3, 0.0]\n'
)


def two_cases(combine="worst", **kw):
    return dataclasses.replace(load_spec(TWO_CASES, check=False).problem, combine=combine, **kw)


def test_the_reader_makes_one_model_per_case_over_the_shared_bodies():
    problem = load_spec(TWO_CASES, check=False).problem
    assert [c.name for c in problem.load_cases] == ["down", "side"]
    assert [c.weight for c in problem.load_cases] == [1.0, 2.0]
    assert problem.combine == "worst" and problem.constraints[0].case == "side"
    down, side = (c.model for c in problem.load_cases)
    assert down.bodies == side.bodies == problem.model.bodies
    assert down.dirichlet == side.dirichlet == problem.model.dirichlet  # the file's support holds in both
    assert down.loads[0].traction == (0.0, -1e-3, 0.0) and side.loads[0].traction == (0.0, 0.0, 1e-3)
    assert problem.model.loads == ()


def test_a_robust_design_with_load_cases_is_refused_in_one_line():
    from contopt.design import Robust

    problem = two_cases("sum")
    robust = dataclasses.replace(problem, design=dataclasses.replace(problem.design, robust=Robust(0.15)))
    with pytest.raises(ConfigError, match=r"robust design .* several load cases .* drop one of them") as err:
        design_nlp(robust)
    assert "\n" not in str(err.value)


def test_without_load_cases_the_problem_is_the_one_analysis_of_today():
    problem = load_spec(DOWN_ONLY, check=False).problem
    assert problem.load_cases == () and problem.combine == "sum"
    assert type(design_nlp(problem)) is DesignNLP


@pytest.mark.parametrize(
    "old, new, message",
    [
        ('case = "side"', 'case = "sdie"', r"constraints\[0\].case: unknown load case 'sdie'; did you mean 'side'"),
        ("weight = 2.0", "weight = 0.0", r"load_cases\[1\].weight: must be > 0"),
        ("weight = 2.0", 'weight = "2"', r"load_cases\[1\].weight: must be a number"),
        ('name = "side"', 'name = "down"', r"load_cases\[1\].name: duplicate load case name 'down'"),
        ('name = "side"', 'name = "side"\n[[load_cases.bodies]]', r"load_cases\[1\].bodies: unknown key.*shared"),
        ('combine = "worst"', 'combine = "mean"', r"objective.combine: must be one of \['sum', 'worst'\]"),
        ("[[load_cases.loads]]\ntype", '[[load_cases.motions]]\nbody = "beam"\n[[load_cases.loads]]\ntype', "deform"),
        ("[[load_cases.loads]]\ntype", '[[load_cases.motions]]\nbody = "bam"\n[[load_cases.loads]]\ntype', "'bam'"),
    ],
)
def test_the_reader_checks_the_cases_keys_in_one_line(old, new, message):
    with pytest.raises(SpecError, match=message) as info:
        load_spec(TWO_CASES.replace(old, new, 1), check=False)
    assert "\n" not in str(info.value)


def test_case_keys_need_load_cases():
    with pytest.raises(SpecError, match=r"objective.combine: combines the objectives of \[\[load_cases\]\]"):
        load_spec(DOWN_ONLY.replace('response = "compliance"\n', 'response = "compliance"\ncombine = "sum"\n', 1))
    text = DOWN_ONLY + '[[constraints]]\nresponse = "compliance"\ncase = "down"\nupper = 1.0\n'
    with pytest.raises(SpecError, match=r"constraints\[0\].case: names a load case; the file has no"):
        load_spec(text, check=False)


def test_a_load_case_is_checked_at_construction():
    problem = load_spec(TWO_CASES, check=False).problem
    with pytest.raises(ConfigError, match="weight must be a positive number"):
        LoadCase("a", problem.model, weight=-1.0)
    other = dataclasses.replace(problem.model, bodies=problem.model.bodies[:1], dirichlet=())
    renamed = dataclasses.replace(other.bodies[0], name="plank")
    with pytest.raises(ConfigError, match="other bodies"):
        dataclasses.replace(problem, load_cases=(LoadCase("a", dataclasses.replace(other, bodies=(renamed,))),))
    with pytest.raises(ConfigError, match='combine = "worst" needs load cases'):
        dataclasses.replace(problem, load_cases=(), constraints=(), combine="worst")


def test_each_case_is_the_analysis_of_the_problem_with_only_its_loads():
    """A case's response is what the same problem with only that case's loads gives; the weighted sum
    is the objective of "sum", the larger weighted case that of "worst"."""
    single = DesignNLP(dataclasses.replace(load_spec(DOWN_ONLY, check=False).problem, normalize="none"))
    x = single.space.initial()
    expected = single.record(x).objective
    for combine in ("sum", "worst"):
        nlp = design_nlp(two_cases(combine, normalize="none"))
        rec = nlp.record(x)
        down, side = rec.responses["compliance[down]"], rec.responses["compliance[side]"]
        assert down == pytest.approx(expected, rel=1e-8)
        assert side != pytest.approx(down, rel=1e-3)  # another load, another answer
        assert rec.objective == pytest.approx(down + 2 * side if combine == "sum" else max(down, 2 * side), rel=1e-12)


@pytest.mark.parametrize("combine", ["sum", "worst"])
def test_the_gradients_of_the_combined_objective_and_each_case_match_central_differences(combine):
    rows = check_design_problem(two_cases(combine), n_random=2, seed=3)
    labels = {label.split(" / ")[0] for label, *_ in rows}
    if combine == "worst":
        assert {"objective[down]<=beta", "objective[side]<=beta"} <= labels
    else:
        assert "objective" in labels
    assert "compliance<=100[side]" in labels
    for label, adj, fd, err in rows:
        assert abs(adj) > 0, label
        assert err < 1e-5, (label, adj, fd)


def test_the_worst_case_adds_beta_minimized_above_each_case():
    nlp = design_nlp(two_cases("worst"))
    assert isinstance(nlp, LoadCasesNLP) and nlp.n == nlp.space.n + 1
    x0 = nlp.start(nlp.space.initial())
    rec = nlp.record(x0)
    rows = rec.g[-2:]  # w_c f_c / s of each case
    assert x0[-1] == pytest.approx(rows.max()) and rec.f == pytest.approx(rows.max())
    assert nlp.lower[-1] < x0[-1] < nlp.upper[-1]
    ev = nlp.evaluate(np.append(x0[:-1], x0[-1] + 0.5))
    assert ev.f == x0[-1] + 0.5 and ev.df[-1] == 1.0 and not ev.df[:-1].any()
    np.testing.assert_allclose(ev.g[-2:], rows - x0[-1] - 0.5)
    np.testing.assert_array_equal(ev.dg[-2:, -1], [-1.0, -1.0])
    assert not ev.dg[:-2, -1].any()


def test_each_case_starts_from_its_own_last_state():
    nlp = design_nlp(two_cases("sum"))
    x = nlp.space.initial()
    first = nlp.record(x)
    assert set(nlp.starts) == {"down", "side"}
    down, side = (s.u for s in first.states)
    assert np.abs(down - side).max() > 0.1 * np.abs(down).max()  # two different equilibria
    second = nlp.record(np.clip(x + 0.01, nlp.lower, nlp.upper))
    assert not second.cold  # both cases warm-started, each from its own state
    for c, state in zip(("down", "side"), second.states):  # the converged displacement and multipliers
        np.testing.assert_array_equal(nlp.starts[c].u, state.u)


@pytest.mark.slow
@pytest.mark.parametrize("optimizer", ["mma", "ipopt"])
def test_the_optimizers_lower_the_worst_case_and_the_history_shows_each_case(optimizer, tmp_path):
    if optimizer == "ipopt" and not extras.installed("ipopt"):
        pytest.skip(extras.missing("ipopt", "this test needs"))
    options = MMAOptions(max_iter=5) if optimizer == "mma" else IpoptOptions(max_iter=5)
    outputs = OutputOptions(vtu="none", plot=False)
    res = optimize(two_cases("worst"), optimizer, options, out=tmp_path / "run", outputs=outputs)
    first, last = res.history[0]["responses"], res.history[-1]["responses"]
    for row in res.history:
        assert row["cases"] == {
            "down": row["responses"]["compliance[down]"],
            "side": row["responses"]["compliance[side]"],
        }
    assert "cases [down " in progress_line(res.history[-1], 0.0, 5)
    assert f"load case side: objective {first['compliance[side]']:.6g} at iteration 0" in report_text(tmp_path / "run")

    def worst(r):
        return max(r["compliance[down]"], 2 * r["compliance[side]"])

    assert worst(last) < 0.9 * worst(first)
    assert set(res.history[-1]["constraints"]) >= {"objective[down]<=beta", "objective[side]<=beta"}
    assert res.x.size == res.record.x.size + 1  # the design's variables, then beta


def test_the_checkpoint_keeps_each_cases_state(tmp_path):
    from contopt.optimize.history import Checkpoint

    nlp = design_nlp(two_cases("sum"))
    rec = nlp.record(nlp.space.initial())
    assert [c.u is not None for c in rec.cases] == [True, True]
    ckpt = Checkpoint(tmp_path)
    ckpt.start({"case": "two"}, resume=False)
    ckpt.save(rec)
    (back,) = ckpt.records()
    for a, b, state in zip(back.cases, rec.cases, rec.states):
        np.testing.assert_array_equal(a.u, state.u)
        assert a.eps == b.eps and len(a.multipliers) == len(b.multipliers) == 0  # no contact here


def test_an_interrupted_run_resumes_each_case_from_its_own_state(tmp_path):
    """The resumed run's first new analyses warm-start each case from the state its checkpoint kept,
    as the uninterrupted run did: the same iterates (to round-off) and no cold solve (the first
    design starts from the full design's displacement; resumed with no case's state, the first new
    analysis would be cold)."""
    quiet = OutputOptions(vtu="none", plot=False)
    whole = optimize(two_cases("worst"), "mma", MMAOptions(max_iter=4), out=tmp_path / "whole", outputs=quiet)
    optimize(two_cases("worst"), "mma", MMAOptions(max_iter=2), out=tmp_path / "cut", outputs=quiet)
    resumed = optimize(
        two_cases("worst"), "mma", MMAOptions(max_iter=4), out=tmp_path / "cut", outputs=quiet, resume=True
    )
    assert resumed.iterations == whole.iterations == 4 and resumed.replayed >= 3
    assert [r["cold_solves"] for r in resumed.history] == [r["cold_solves"] for r in whole.history] == [0] * 5
    # Newton's rtol (1e-10 of the load, its default) on a warm start from the same state: round-off apart
    np.testing.assert_allclose(
        [r["objective"] for r in resumed.history], [r["objective"] for r in whole.history], rtol=1e-9
    )
    np.testing.assert_allclose(resumed.x, whole.x, rtol=1e-8, atol=1e-10)


def test_each_case_gets_its_own_vtu_files_and_pictures(tmp_path):
    import meshio

    from contopt.optimize.case_outputs import draw_case_pictures

    out = tmp_path / "run"
    res = optimize(
        two_cases("sum"), "mma", MMAOptions(max_iter=1), out=out, outputs=OutputOptions(vtu="final", plot=False)
    )
    u = {}
    for case, state in zip(("down", "side"), res.record.cases):
        (vtu,) = (out / "cases" / case / "vtu").glob("beam_*.vtu")
        assert (out / "cases" / case / "design.pvd").exists()
        u[case] = meshio.read(vtu).point_data["displacement"]
        np.testing.assert_allclose(u[case].ravel(), state.u, rtol=1e-6, atol=1e-12)  # the VTU's float precision
    assert np.abs(u["down"][:, 1]).max() > 10 * np.abs(u["down"][:, 2]).max()  # pulled down (-y) ...
    assert np.abs(u["side"][:, 2]).max() > 10 * np.abs(u["side"][:, 1]).max()  # ... and sideways (z)
    first = meshio.read(sorted((out / "vtu").glob("beam_*.vtu"))[-1]).point_data["displacement"]
    np.testing.assert_array_equal(first, u["down"])  # the run's own VTU: the first case, as before
    if extras.installed("viz"):
        made = draw_case_pictures(out, design_nlp(two_cases("sum")), None)
        assert set(made) >= {"cases/down/deformed", "cases/side/deformed"}
        assert all((out / p).stat().st_size > 0 for p in made.values())
