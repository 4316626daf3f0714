"""The old name of :mod:`contopt.cases` (renamed in 0.1: "problem" now means only the design
problem, :class:`contopt.optimize.problem.DesignProblem`, and the problem files that describe one).

``from contopt.problems.spec import load_spec`` and the other old paths keep working until 0.2,
with a DeprecationWarning; import from ``contopt.cases`` (or the names ``contopt`` exports).
"""

from __future__ import annotations

import importlib
import sys
import warnings

warnings.warn("contopt.problems was renamed contopt.cases; the old name goes in 0.2", DeprecationWarning, stacklevel=2)

#: the submodules an old import path may name
_MODULES = (
    "checks",
    "die_slab",
    "export",
    "forward",
    "optimization",
    "spec",
    "spec_design",
    "spec_model",
    "spec_run",
    "toml_reader",
    "two_blocks",
)

for _name in _MODULES:
    sys.modules[f"{__name__}.{_name}"] = importlib.import_module(f"contopt.cases.{_name}")


def __getattr__(name: str):
    if name in _MODULES:
        return sys.modules[f"{__name__}.{name}"]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
