"""[design] robust in problem files: read into Design.robust, checked with one-line errors naming the key; and a
response's need of a [[contact]] interface."""

import pytest

from contopt.cases.optimization import OPTIMIZATION_CASES
from contopt.cases.spec import load_spec
from contopt.cases.toml_reader import SpecError
from contopt.design import Robust

CANTILEVER = OPTIMIZATION_CASES["cantilever"].path


def test_robust_is_read_with_its_default():
    assert load_spec(CANTILEVER, {"design.robust": {"delta": 0.2}}, check=False).problem.design.robust == Robust(0.2)
    assert load_spec(CANTILEVER, {"design.robust": {}}, check=False).problem.design.robust == Robust()
    assert load_spec(CANTILEVER, check=False).problem.design.robust is None


@pytest.mark.parametrize(
    "value, design, message",
    [
        ({"delta": 0.7}, None, r"design.robust.delta \(override\): must be a number in \(0, 0.5\)"),
        ({"delta": "wide"}, None, r"design.robust.delta \(override\): "),
        ({"dlta": 0.1}, None, r"design.robust.dlta \(override\): unknown key; did you mean 'delta'\?"),
        ({"delta": 0.1}, "bspline", r"design.robust \(override\): robust applies to density designs only"),
    ],
)
def test_robust_errors_name_the_key(value, design, message):
    with pytest.raises(SpecError, match=message) as err:
        load_spec(CANTILEVER, {"design.robust": value}, design=design, check=False)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("on", ["displacement", "reaction", "energy"])
def test_a_load_path_response_that_reads_no_contact_needs_no_interface(on):
    """The cantilever has no [[contact]]: force-max reads the contact force only with on = "contact"."""
    reads = {"displacement": {"bodies": "beam", "set": "tip", "direction": [0.0, -1.0, 0.0]}}
    reads["reaction"] = {"bodies": "beam", "direction": [0.0, 1.0, 0.0]}
    objective = {"response": "force-max", "steps": 3, "sharpness": 1e4, "on": on, **reads.get(on, {})}
    problem = load_spec(CANTILEVER, {"objective": objective}, check=False).problem
    assert problem.objective.name == "force_max"
    contact = {k: v for k, v in objective.items() if k not in ("on", "bodies", "set", "direction")}
    with pytest.raises(
        SpecError, match=r"objective.response \(override\): 'force-max' needs a \[\[contact\]\] interface"
    ):
        load_spec(CANTILEVER, {"objective": contact}, check=False)
