"""OutputOptions.curves: the load-path curves (two analyses from zero after the loop) only when asked."""

import pytest
from _cantilever import cantilever_problem  # tests/optimize/_cantilever.py

from contopt.errors import ConfigError
from contopt.optimize.driver import OutputOptions, optimize
from contopt.optimize.mma import MMAOptions


@pytest.mark.parametrize("curves", [True, False])
def test_curves_are_solved_only_when_asked(curves, tmp_path):
    problem = cantilever_problem("density", divisions=(6, 2, 2))
    optimize(problem, "mma", MMAOptions(max_iter=1), out=tmp_path, outputs=OutputOptions(vtu="none", curves=curves))
    assert (tmp_path / "curves.json").exists() == curves
    assert (tmp_path / "summary.json").exists()


def test_curves_must_be_a_boolean():
    with pytest.raises(ConfigError, match="output.curves must be true or false"):
        OutputOptions(curves="no")
