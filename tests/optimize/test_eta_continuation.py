"""A continuation of the Heaviside sharpness within one run ([design] eta_continuation)."""

import json
from dataclasses import replace

import numpy as np
import pytest
from _cantilever import cantilever_problem  # tests/optimize/_cantilever.py

from contopt import extras
from contopt.cases.optimization import OPTIMIZATION_CASES
from contopt.cases.spec import load_spec
from contopt.design import Design, EtaContinuation, Robust
from contopt.errors import ConfigError
from contopt.optimize.continuation import rescale, schedule, stage_problem
from contopt.optimize.driver import OutputOptions, optimize
from contopt.optimize.history import Checkpoint
from contopt.optimize.ipopt import IpoptOptions
from contopt.optimize.mma import MMAOptions
from contopt.optimize.multicase import design_nlp

SMALL = (12, 4, 2)
QUIET = OutputOptions(vtu="none", plot=False)


def _continued(problem, cont, robust=None):
    d = problem.design
    return replace(problem, design=Design(d.bodies, d.heaviside, d.simp, robust=robust, eta_continuation=cont))


def test_the_schedule_of_sharpnesses_and_iterations():
    cont = EtaContinuation(start=4, factor=1.5, every=3)
    assert cont.etas(10.0) == (4.0, 6.0, 9.0, 10.0)
    assert EtaContinuation(start=2, factor=2, every=1).etas(8.0) == (2.0, 4.0, 8.0)  # no step of factor 1 at the end
    # a stage's rows are the iterations after its start (the first stage's also iteration 0)
    stages = schedule(cont, 10.0, [3, 3, 1, 5])
    assert [(s["eta"], s["first_iteration"], s["last_iteration"]) for s in stages] == [
        (4.0, 0, 3),
        (6.0, 4, 6),
        (9.0, 7, 7),
        (10.0, 8, 12),
    ]
    for bad, word in (({"factor": 1.0}, "factor"), ({"every": 0}, "every"), ({"start": -1}, "start")):
        with pytest.raises(ConfigError, match=f"eta_continuation.{word}"):
            EtaContinuation(**bad)
    with pytest.raises(ConfigError, match="start .* below the design's eta"):
        cont.etas(4.0)


@pytest.mark.parametrize(("design", "robust"), [("density", None), ("density", Robust(0.15)), ("bspline", None)])
def test_rescaling_keeps_the_volume_fraction(design, robust, rng):
    """x eta_old / eta_new: the same (intermediate) volume fraction under the sharper Heaviside (the
    B-spline's level set is linear in its control values too)."""
    pb = _continued(cantilever_problem(design, divisions=SMALL), EtaContinuation(4, 1.5, 2), robust)
    soft, sharp = (design_nlp(stage_problem(pb, eta)).space for eta in (4.0, 10.0))
    x = rng.uniform(-1.0, 1.0, soft.n)
    y = rescale(x, 4.0, 10.0, sharp.lower, sharp.upper)
    np.testing.assert_allclose(sharp.forward(y).nu, soft.forward(x).nu, rtol=0, atol=1e-12)
    assert np.abs(y).max() <= 0.4 * np.abs(x).max() + 1e-15


def _stage_of(stages, iteration):
    return [s for s in stages if s["after_iteration"] < iteration or s["after_iteration"] == iteration == 0][-1]


def test_a_run_raises_eta_and_a_resumed_run_continues_the_schedule(tmp_path):
    """Rows carry the eta of their stage (meta.json lists the stages); a run cut in its third stage
    and resumed ends where the uninterrupted one does."""
    pb = _continued(cantilever_problem("density", divisions=SMALL), EtaContinuation(4, 1.5, 2))
    whole = optimize(pb, "mma", MMAOptions(max_iter=8, kkt_tol=0), out=tmp_path / "whole", outputs=QUIET)
    stages = json.loads((tmp_path / "whole" / "checkpoint" / "meta.json").read_text())["eta_stages"]
    assert [(s["eta"], s["after_iteration"]) for s in stages] == [(4.0, 0), (6.0, 2), (9.0, 4), (10.0, 6)]
    assert [r["iteration"] for r in whole.history] == list(range(9)) and whole.iterations == 8
    assert [r["eta"] for r in whole.history] == [4.0] * 3 + [6.0] * 2 + [9.0] * 2 + [10.0] * 2
    assert all(r["eta"] == _stage_of(stages, r["iteration"])["eta"] for r in whole.history)
    assert whole.volume_fractions[0] <= 0.3 + 2e-3
    # continuity at each raise: the stage's first analysis (the rescaled design at the new eta) has the
    # volume fraction of the previous stage's last iterate
    records = {rec.index: rec for rec in Checkpoint(tmp_path / "whole").records()}
    for s in stages[1:]:
        start = records[s["first_analysis"]]
        before = whole.history[s["after_iteration"]]["volume_fractions"]["beam"]
        assert start.volume_fractions[0] == pytest.approx(before, abs=1e-12)

    optimize(pb, "mma", MMAOptions(max_iter=5, kkt_tol=0), out=tmp_path / "cut", outputs=QUIET)
    resumed = optimize(pb, "mma", MMAOptions(max_iter=8, kkt_tol=0), out=tmp_path / "cut", outputs=QUIET, resume=True)
    assert resumed.replayed >= 6 and resumed.iterations == 8
    assert [r["eta"] for r in resumed.history] == [r["eta"] for r in whole.history]
    # the replayed part is identical; after it the analyses start cold instead of warm: Newton's tolerance
    assert resumed.history[4]["objective"] == whole.history[4]["objective"]
    np.testing.assert_allclose(resumed.x, whole.x, rtol=0, atol=1e-6)


def test_the_robust_cantilever_continued_from_eta_4_keeps_an_eroded_design(tmp_path):
    """At eta = 10 from the grey start the eroded design is void and the optimizer stops at once
    (test_robust.py); started at 4 and raised to 10 within the run it is not."""
    pb = _continued(cantilever_problem("density", divisions=SMALL), EtaContinuation(4, 1.6, 3), Robust(0.15))
    res = optimize(pb, "mma", MMAOptions(max_iter=10), out=tmp_path, outputs=QUIET)
    nlp = design_nlp(stage_problem(pb, 10.0))
    eroded = nlp.members["eroded"].space.forward(res.x[: nlp.space.n]).nu
    assert res.history[-1]["eta"] == 10.0 and res.iterations == 10
    assert eroded.max() > 0.9, eroded.max()
    worst = [max(r["responses"][f"objective[{k}]"] for k in ("eroded", "intermediate", "dilated")) for r in res.history]
    assert worst[-1] < 0.6 * worst[0]


def test_a_resumed_robust_run_continues_in_a_later_stage(tmp_path):
    """Cut in its second stage: the bound variable of that stage's start comes from its recorded analysis."""
    pb = _continued(cantilever_problem("density", divisions=SMALL), EtaContinuation(4, 2.5, 2), Robust(0.15))
    whole = optimize(pb, "mma", MMAOptions(max_iter=4, kkt_tol=0), out=tmp_path / "whole", outputs=QUIET)
    cut = optimize(pb, "mma", MMAOptions(max_iter=3, kkt_tol=0), out=tmp_path / "cut", outputs=QUIET)
    resumed = optimize(pb, "mma", MMAOptions(max_iter=4, kkt_tol=0), out=tmp_path / "cut", outputs=QUIET, resume=True)
    assert [r["eta"] for r in whole.history] == [4.0] * 3 + [10.0] * 2 == [r["eta"] for r in resumed.history]
    assert resumed.replayed == cut.analyses  # every recorded analysis, the second stage's start included
    assert resumed.history[3]["objective"] == whole.history[3]["objective"]
    np.testing.assert_allclose(resumed.x, whole.x, rtol=0, atol=1e-6)


@pytest.mark.skipif(not extras.installed("ipopt"), reason=extras.missing("ipopt", "IPOPT needs"))
def test_ipopt_is_entered_again_at_each_raise():
    pb = _continued(cantilever_problem("density", divisions=SMALL), EtaContinuation(4, 2.5, 3), Robust(0.15))
    res = optimize(pb, "ipopt", IpoptOptions(max_iter=5), outputs=QUIET)
    assert [r["eta"] for r in res.history] == [4.0] * 4 + [10.0] * 2 and res.iterations == 5
    assert [r["iteration"] for r in res.history] == list(range(6))


def test_the_problem_file_keys():
    path = OPTIMIZATION_CASES["cantilever"].path
    keys = {"design.eta_continuation": {"start": 4, "factor": 2, "every": 5}}
    design = load_spec(path, keys, check=False).problem.design
    assert design.eta_continuation == EtaContinuation(4.0, 2.0, 5) and design.heaviside.eta == 10.0
    with pytest.raises(ConfigError, match=r"design\.eta_continuation.*below the design's eta"):
        load_spec(path, keys, eta=3.0, check=False)
    with pytest.raises(ConfigError, match=r"design\.eta_continuation\.factor"):
        load_spec(path, {"design.eta_continuation": {"factor": 0.5}}, check=False)


def test_a_run_stopped_before_the_last_stage_is_carried_at_its_own_eta(tmp_path):
    """--design-from (and export-design) of a run whose last design was made at eta 6 (its second
    stage): its variables are read at 6, so the volume fraction carried to eta 10 is the run's."""
    from contopt.cases.design_from import design_from
    from contopt.cases.export import run_design_space
    from contopt.cli import main

    cont = "design.eta_continuation={start = 4, factor = 1.5, every = 2}"
    mesh = "bodies[0].mesh.divisions=[12, 4, 2]"
    args = ["-q", "run", "cantilever", "--set", mesh, "--set", cont, "--max-iter", "3", "--no-plot"]
    assert main([*args, "--vtu", "none", "--out", str(tmp_path / "run")]) == 0
    last = json.loads((tmp_path / "run" / "history.json").read_text())[-1]
    assert last["eta"] == 6.0
    space, _ = run_design_space(tmp_path / "run")
    assert space.design.heaviside.eta == 10.0
    x = design_from(tmp_path / "run")(space)
    assert space.volume_fractions(space.forward(x))[0] == pytest.approx(last["volume_fractions"]["beam"], abs=1e-12)
