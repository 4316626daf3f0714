"""The two-way-press case (src/contopt/cases/files/two-way-press.toml): two load cases, each pressing
the block with one plate and taking the other away, read from the file; each case's analysis touches
with its own plate only, and its energy is that of the same model with only that plate's motion."""

import dataclasses

import numpy as np
import pytest

from contopt.cases.optimization import optimization_case
from contopt.optimize.multicase import design_nlp
from contopt.optimize.problem import DesignNLP


def test_the_case_reads_two_load_cases_moving_one_plate_each():
    problem = optimization_case("two-way-press")
    assert [c.name for c in problem.load_cases] == ["down", "side"] and problem.combine == "worst"
    down, side = (c.model for c in problem.load_cases)
    assert down.body("top-plate").rigid.offset(1.0) == pytest.approx([0.0, 0.0, -0.08])
    assert down.body("side-plate").rigid.offset(1.0) == pytest.approx([0.1, 0.0, 0.0])
    assert side.body("side-plate").rigid.offset(1.0) == pytest.approx([-0.08, 0.0, 0.0])
    assert problem.model.body("top-plate").rigid.offset(1.0) == pytest.approx([0.0, 0.0, 0.0])


@pytest.mark.slow
def test_each_case_presses_with_its_own_plate_and_is_the_model_with_that_motion():
    problem = dataclasses.replace(optimization_case("two-way-press"), normalize="none")
    nlp = design_nlp(problem)
    x = nlp.space.initial()
    rec = nlp.record(x)
    down, side = rec.states
    assert [r.n_active > 0 for r in down.contact] == [True, False]  # top, side
    assert [r.n_active > 0 for r in side.contact] == [False, True]
    alone = DesignNLP(dataclasses.replace(problem, model=problem.load_cases[1].model, load_cases=(), combine="sum"))
    expected = alone.record(x).objective
    assert rec.responses["-strain_energy[side]"] == pytest.approx(expected, rel=1e-8)
    assert np.isclose(rec.objective, max(rec.responses.values()))  # the worse (larger negated) energy
