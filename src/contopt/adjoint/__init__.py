"""Adjoint sensitivities through contact (paper sections 4-5) and gradient checks.

The names are imported on first use, so that ``contopt.adjoint.options`` (what a problem file's
``[adjoint]`` table holds) loads no JAX.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from contopt.adjoint.options import AdjointOptions
    from contopt.adjoint.sensitivity import AdjointResult, Sensitivity, sensitivities

__all__ = ["AdjointOptions", "AdjointResult", "Sensitivity", "sensitivities"]
_HOME = {"AdjointOptions": "contopt.adjoint.options"}


def __getattr__(name: str):
    if name in __all__:
        value = getattr(import_module(_HOME.get(name, "contopt.adjoint.sensitivity")), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'contopt.adjoint' has no attribute {name!r}")
