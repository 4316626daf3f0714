"""The optimization chain end to end: gradients, a linear SIMP reference, both optimizers, outputs, resume."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from _cantilever import cantilever_problem  # tests/optimize/_cantilever.py
from _top3d import LinearSimpCantilever  # tests/optimize/_top3d.py (independent linear code)

from contopt import extras
from contopt.adjoint.check import TIGHT_NEWTON
from contopt.errors import ConfigError, ConvergenceError
from contopt.optimize import problem as problem_module
from contopt.optimize.base import EvaluationFailure
from contopt.optimize.driver import OutputOptions, optimize
from contopt.optimize.ipopt import IpoptOptions
from contopt.optimize.mma import MMAOptions, run_mma
from contopt.optimize.problem import Constraint, DesignNLP
from contopt.responses import StrainEnergy

#: the tests that run IPOPT (cyipopt, the ipopt extra)
NEEDS_IPOPT = pytest.mark.skipif(not extras.installed("ipopt"), reason=extras.missing("ipopt", "IPOPT needs"))

SMALL = (12, 4, 2)


def _small(design="density", **kw):
    return cantilever_problem(design, divisions=SMALL, **kw)


@pytest.mark.parametrize("design", ["density", "bspline"])
def test_design_gradients_match_central_differences(design, rng):
    """df/dx and dg/dx through design maps, nonlinear solve and adjoint, with a response constraint.

    Errors are measured against the size of the summed terms ``sum_i |g_i v_i|`` (a random
    direction can cancel them to a small sum, as in contopt.adjoint.check). The load gives strains
    of ~1e-3: at the default 1e-6 the strain energy density (~1e-12) is computed as a difference of
    O(1) invariants and loses digits that a difference quotient divides by h.
    """
    pb = replace(_small(design, load=1e-3), constraints=(Constraint(StrainEnergy(), upper=1e-5),), newton=TIGHT_NEWTON)
    nlp = DesignNLP(pb)
    x = np.clip(nlp.space.initial() + rng.uniform(-0.1, 0.1, nlp.n), -1, 1)
    rec = nlp.record(x)
    assert rec.g.shape == (2,) and rec.dg.shape == (2, nlp.n)
    h = 1e-5
    for v in (rng.normal(size=nlp.n), np.eye(nlp.n)[int(np.argmax(np.abs(rec.df)))]):
        plus, minus = nlp.record(x + h * v), nlp.record(x - h * v)
        size = np.abs(rec.df * v).sum()
        assert abs(rec.df @ v - (plus.f - minus.f) / (2 * h)) <= 1e-6 * size
        size = np.abs(rec.dg * v).sum(axis=1)
        assert np.all(np.abs(rec.dg @ v - (plus.g - minus.g) / (2 * h)) <= 1e-6 * size)


def test_one_analysis_per_design_and_warm_start(monkeypatch, caplog):
    nlp = DesignNLP(_small())
    x0 = nlp.space.initial()
    first = nlp.record(x0)
    # the full design solved for |f^0| hands its displacement to the first design
    assert not first.cold and nlp.records_made == 1
    unscaled = DesignNLP(replace(_small(), normalize="none"))
    assert unscaled.record(x0).cold  # nothing solved before: from zero
    np.testing.assert_allclose(unscaled.last.objective, first.objective, rtol=1e-8)
    nlp.evaluate(x0), nlp.evaluate(x0.copy())
    assert nlp.records_made == 1  # cached by x
    second = nlp.record(x0 * 0.9)
    assert not second.cold

    # a warm start that fails falls back to a cold solve with the same answer
    calls = []
    original = problem_module.solve_static

    def flaky(*args, **kw):
        calls.append(kw.get("start") is not None)
        if kw.get("start") is not None:
            raise ConvergenceError("forced")
        return original(*args, **kw)

    monkeypatch.setattr(problem_module, "solve_static", flaky)
    with caplog.at_level("INFO", logger="contopt.optimize.problem"):
        third = nlp.record(x0 * 0.8)
    assert calls == [True, False] and third.cold
    # a routine fall-back: one short line at INFO (shown with -v), not a warning that reads like a failure
    notes = [r for r in caplog.records if "solving from zero" in r.getMessage()]
    assert len(notes) == 1 and notes[0].levelname == "INFO" and len(notes[0].getMessage()) < 120
    fresh = DesignNLP(_small())
    fresh.scale = nlp.scale
    np.testing.assert_allclose(fresh.record(x0 * 0.8).f, third.f, rtol=1e-8)

    def broken(*args, **kw):
        raise ConvergenceError("forced")

    monkeypatch.setattr(problem_module, "solve_static", broken)
    with pytest.raises(EvaluationFailure, match="evaluation 3 failed"):
        nlp.record(x0 * 0.7)


class _ReferenceNLP:
    """The independent linear code in the optimizer protocol (same scaling as contopt's problem)."""

    def __init__(self, ref, scale, vf, n):
        self.ref, self.scale, self.vf, self.n, self.m = ref, scale, vf, n, 1
        self.lower, self.upper = -np.ones(n), np.ones(n)

    def evaluate(self, x):
        from contopt.optimize.base import DesignEvaluation

        c, dc, v, dv = self.ref.evaluate(x)
        return DesignEvaluation(f=c / self.scale, g=np.array([v - self.vf]), df=dc / self.scale, dg=dv[None])

    def iteration(self, info):
        return True


def test_cantilever_compliance_matches_an_independent_linear_simp_code():
    """Small load: the hyperelastic optimum approaches the linear one (plain hex8 in both, F-bar off).

    Both runs make 80 MMA iterations from the same grey start (no early stop). Their paths part
    early (the compliances differ by ~1e-4 from the nonlinearity and MMA amplifies that where the
    Heaviside saturates), so the designs differ in detail, but the optimal compliances must agree.
    eta = 5: with eta = 10 both codes sit on long plateaus whose length varies from run to run.
    """
    pb = cantilever_problem("density", fbar=False, eta=5.0)
    opts = MMAOptions(max_iter=80, kkt_tol=0.0, change_tol=0.0)
    res = optimize(pb, "mma", opts)
    mesh = pb.model.bodies[0].mesh
    h = pb.design.bodies[0].parameterization.radius
    ref = LinearSimpCantilever(
        mesh.points,
        mesh.cells,
        mesh.node_set("xmin"),
        mesh.facet_nodes("tip"),
        pb.model.loads[0].traction,
        1.0,
        0.3,
        h,
        5.0,
        3.0,
        1e-2,
    )
    scale = ref.compliance(np.ones(len(mesh.cells)))
    out = run_mma(_ReferenceNLP(ref, scale, 0.3, res.x.size), np.full(res.x.size, _x0(pb)), opts)
    c_ref, _, v_ref, _ = ref.evaluate(out.x)
    assert res.objective == pytest.approx(c_ref, rel=0.03)
    assert res.volume_fractions[0] <= 0.3 + 1e-3 and v_ref <= 0.3 + 1e-3
    assert res.normalized_objective < 0.2 * res.history[0]["objective"]  # the optimizer did its job
    # and our compliance of the reference's design agrees with the linear code to the nonlinearity
    assert DesignNLP(pb).record(out.x).objective == pytest.approx(c_ref, rel=1e-3)


def _x0(pb):
    return pb.design.heaviside.inverse(pb.design.bodies[0].volume_fraction)


@pytest.mark.parametrize(
    "optimizer, options",
    [("mma", MMAOptions(max_iter=8)), pytest.param("ipopt", IpoptOptions(max_iter=20), marks=NEEDS_IPOPT)],
)
@pytest.mark.parametrize("design", ["density", "bspline"])
def test_both_optimizers_reduce_compliance_and_hold_the_volume(optimizer, options, design):
    """IPOPT takes an infeasible path (volume up to +0.012 in its first iterations) and needs more."""
    res = optimize(_small(design), optimizer, options)
    f = [r["objective"] for r in res.history]
    assert res.normalized_objective < 0.5 * f[0]
    assert res.volume_fractions[0] <= 0.3 + 1e-3
    assert res.iterations == len(res.history) - 1 <= options.max_iter
    assert res.analyses >= res.iterations


def test_run_directory_outputs(tmp_path):
    rows = []
    res = optimize(
        _small(), "mma", MMAOptions(max_iter=3), out=tmp_path, progress=lambda row, eta: rows.append((row, eta))
    )
    assert [r["iteration"] for r, _ in rows] == [0, 1, 2, 3] and rows[-1][1] == 0.0 and rows[0][1] > 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["iterations"] == 3 and summary["normalized_objective"] == pytest.approx(res.normalized_objective)
    assert summary["volume_fraction"] == pytest.approx(res.volume_fractions[0])
    assert 0 <= summary["grey_fraction"] <= 1 and summary["design"][0]["G_nonzeros"] > 0
    history = (tmp_path / "history.csv").read_text().splitlines()
    assert len(history) == 5 and "seconds.primal" in history[0] and "constraints.volume[beam]<=0.3" in history[0]
    pvd = (tmp_path / "design.pvd").read_text()
    assert pvd.count("<DataSet") == 4 and (tmp_path / "vtu" / "beam_0003.vtu").stat().st_size > 0
    import meshio

    nu = meshio.read(tmp_path / "vtu" / "beam_0003.vtu").cell_data["nu"][0].ravel()
    np.testing.assert_allclose(nu, res.fields.nu, rtol=1e-12)
    png = (tmp_path / "convergence.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    assert len(list((tmp_path / "checkpoint").glob("eval_*.npz"))) == res.analyses


def test_checkpoint_guards(tmp_path):
    with pytest.raises(ConfigError, match="nothing to resume"):
        optimize(_small(), "mma", MMAOptions(max_iter=1), out=tmp_path, resume=True)
    optimize(_small(), "mma", MMAOptions(max_iter=1), out=tmp_path, outputs=OutputOptions(vtu="none", plot=False))
    with pytest.raises(ConfigError, match="already holds a run"):
        optimize(_small(), "mma", MMAOptions(max_iter=1), out=tmp_path)
    with pytest.raises(ConfigError, match="different run .*design"):
        optimize(_small("bspline"), "mma", MMAOptions(max_iter=1), out=tmp_path, resume=True)
    with pytest.raises(ConfigError, match="optimizer must be one of"):
        optimize(_small(), "sgd")
    with pytest.raises(ConfigError, match="must be MMAOptions"):
        optimize(_small(), "mma", IpoptOptions())


class _Stop(Exception):
    pass


@pytest.mark.parametrize(
    "optimizer, options",
    [("mma", MMAOptions(max_iter=6)), pytest.param("ipopt", IpoptOptions(max_iter=6), marks=NEEDS_IPOPT)],
)
def test_resume_after_an_interruption_reproduces_the_iterates(tmp_path, optimizer, options):
    whole = optimize(_small(), optimizer, options, out=tmp_path / "whole", outputs=OutputOptions(vtu="none"))

    def stop_at_3(row, eta):
        if row["iteration"] == 3:
            raise _Stop

    with pytest.raises(_Stop):
        optimize(
            _small(), optimizer, options, out=tmp_path / "cut", progress=stop_at_3, outputs=OutputOptions(vtu="none")
        )
    resumed = optimize(
        _small(), optimizer, options, out=tmp_path / "cut", resume=True, outputs=OutputOptions(vtu="none")
    )
    # to round-off: a fresh analysis after the replay may differ from the uninterrupted run's in
    # the last bits (MKL's threaded reductions; tests/test_cli.py shows bitwise equality with MKL_CBWR)
    np.testing.assert_allclose(
        [r["objective"] for r in resumed.history], [r["objective"] for r in whole.history], rtol=1e-9
    )
    np.testing.assert_allclose(resumed.x, whole.x, rtol=1e-8, atol=1e-10)
    assert resumed.analyses == whole.analyses and resumed.replayed >= 4 and whole.replayed == 0
    rows = json.loads((tmp_path / "cut" / "history.json").read_text())
    assert [r["iteration"] for r in rows] == list(range(len(whole.history)))


def _two_blocks_problem(law):
    from contopt.adjoint.check import TIGHT_AUGMENTATION
    from contopt.cases.two_blocks import two_blocks
    from contopt.design import BSplineGrid, Design, DesignedBody
    from contopt.optimize.problem import DesignProblem

    design = Design(DesignedBody("block", BSplineGrid((2, 2, 1)), volume_fraction=0.5))
    return DesignProblem(
        model=two_blocks(law=law),
        design=design,
        objective=-StrainEnergy(),
        newton=TIGHT_NEWTON,
        augmentation=TIGHT_AUGMENTATION,
    )


@pytest.mark.parametrize("law, tol", [("penalty", 1e-6), ("alm", 1e-5)])
def test_design_gradient_through_contact(law, tol, rng):
    """Maximize the block's strain energy under a punch: df/dx against central differences."""
    nlp = DesignNLP(_two_blocks_problem(law))
    x = nlp.space.initial() + rng.uniform(-0.05, 0.05, nlp.n)
    rec = nlp.record(x)
    assert rec.pressures and rec.pressures[0].max() > 0  # contact is active
    v, h = rng.normal(size=nlp.n), 1e-4
    fd = (nlp.record(x + h * v).f - nlp.record(x - h * v).f) / (2 * h)
    assert abs(rec.df @ v - fd) <= tol * np.abs(rec.df * v).sum()


def test_contact_optimization_warm_starts_and_improves(tmp_path):
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import AugmentationOptions

    pb = replace(_two_blocks_problem("alm"), newton=NewtonOptions(), augmentation=AugmentationOptions())
    res = optimize(pb, "mma", MMAOptions(max_iter=3), out=tmp_path)
    f = [r["objective"] for r in res.history]
    assert f[-1] < f[0] < 0  # -strain energy / |full design's|, decreasing
    # every design, the first included (from the full design's displacement), is warm-started
    assert sum(r["cold_solves"] for r in res.history) == 0 and res.history[1]["alm_updates"] > 0
    assert res.volume_fractions[0] <= 0.5 + 1e-3
    import meshio

    punch = meshio.read(tmp_path / "vtu" / "punch_0003.vtu").point_data["contact_pressure"]
    np.testing.assert_allclose(np.sort(punch[punch > 0]), np.sort(res.record.pressures[0][res.record.pressures[0] > 0]))


def test_objective_normalizations():
    raw = DesignNLP(_small(normalize="none"))
    x0 = raw.space.initial()
    f0 = raw.record(x0).f
    initial = DesignNLP(_small(normalize="initial"))
    assert initial.record(x0).f == pytest.approx(1.0, rel=1e-12) and initial.scale == pytest.approx(f0, rel=1e-12)
    assert initial.record(x0 * 0.5).f == pytest.approx(raw.record(x0 * 0.5).f / f0, rel=1e-9)
    assert DesignNLP(_small(normalize=2.0)).record(x0).f == pytest.approx(f0 / 2.0, rel=1e-12)
    full = DesignNLP(_small())
    rec = full.record(x0)  # warm-started from the full design, raw's from zero: equal to Newton's tolerance
    assert full.scale < f0 and rec.f == pytest.approx(f0 / full.scale, rel=1e-8)  # the solid beam is stiffer
    np.testing.assert_allclose(rec.df, raw.record(x0).df / full.scale, rtol=1e-7)
    with pytest.raises(ConfigError, match="normalize must be one of"):
        _small(normalize="max")
    with pytest.raises(ConfigError, match="cannot be normalized"):
        DesignNLP(replace(_small(), objective=StrainEnergy() * 0.0)).record(x0)


def test_an_implausible_warm_start_is_solved_again_from_zero(monkeypatch, caplog):
    """A warm start that 'converges' with the contact gone (under a prescribed motion) or to an
    objective of exactly 0 is not believed: the design is solved again from zero."""
    pb = _two_blocks_problem("penalty")
    nlp = DesignNLP(pb)
    x0 = nlp.space.initial()
    first = nlp.record(x0)
    assert not first.cold and np.count_nonzero(first.pressures[0]) > 0
    original = problem_module.solve_static
    solves = []

    def contact_lost_when_warm(*args, **kw):
        state = original(*args, **kw)
        solves.append("warm" if kw.get("start") is not None else "cold")
        if kw.get("start") is None:
            return state
        gone = tuple(replace(r, lam=np.zeros_like(r.lam)) for r in state.contact)
        return replace(state, contact=gone)

    monkeypatch.setattr(problem_module, "solve_static", contact_lost_when_warm)
    with caplog.at_level("INFO", logger="contopt.optimize.problem"):
        second = nlp.record(x0 + 0.02)
    assert solves == ["warm", "cold"] and second.cold
    assert np.count_nonzero(second.pressures[0]) > 0
    assert any("solving from zero to confirm" in r.getMessage() for r in caplog.records)
    # the check can fail: without it the warm result (no contact, objective 0) would have been kept
    monkeypatch.setattr(DesignNLP, "_implausible", lambda self, state, adj: "")
    solves.clear()
    third = nlp.record(x0 + 0.04)
    assert solves == ["warm"] and not third.cold and np.count_nonzero(third.pressures[0]) == 0


def test_a_response_the_model_cannot_have_is_refused_before_any_analysis(monkeypatch):
    """A contact-force objective or constraint on a model without contact was 0 (then 'cannot
    normalize'), an unknown response body an error after the full-design analysis."""
    from contopt.responses import ContactForce

    def no_analysis(*args, **kwargs):
        raise AssertionError("an analysis ran")

    monkeypatch.setattr(problem_module, "solve_static", no_analysis)
    for problem in (
        replace(_small(), objective=ContactForce()),
        replace(_small(), constraints=(Constraint(ContactForce(), lower=1.0),)),
        replace(_small(), objective=StrainEnergy(bodies="nope")),
    ):
        with pytest.raises(ConfigError, match="integrates over contact interfaces, but the model has none|'nope'"):
            DesignNLP(problem)


def _shift_recorded_designs(run: Path, shift: float) -> None:
    """Every checkpointed evaluation's design moved by ``shift`` (what another run's round-off would give)."""
    for f in sorted((run / "checkpoint").glob("eval_*.npz")):
        with np.load(f, allow_pickle=False) as d:
            arrays = {k: d[k] for k in d.files}
        arrays["x"] = arrays["x"] + shift
        with open(f, "wb") as fh:
            np.savez(fh, **arrays)


@pytest.mark.parametrize("shift, replayed", [(1e-13, "all"), (1e-6, "none")])
def test_a_resume_replays_designs_that_differ_by_round_off_only(tmp_path, shift, replayed):
    """IPOPT's iterates differ in their last bits from one run to the next on a loaded machine: a recorded
    analysis is replayed where the optimizer asks for its design but for round-off, not where it asks for
    another design."""
    quiet = OutputOptions(vtu="none", plot=False)
    whole = optimize(_small(), "mma", MMAOptions(max_iter=2), out=tmp_path / "run", outputs=quiet)
    _shift_recorded_designs(tmp_path / "run", shift)
    resumed = optimize(_small(), "mma", MMAOptions(max_iter=2), out=tmp_path / "run", resume=True, outputs=quiet)
    assert resumed.analyses == whole.analyses
    assert resumed.replayed == (whole.analyses if replayed == "all" else 0)
    np.testing.assert_allclose(resumed.x, whole.x, rtol=1e-8, atol=1e-10)
