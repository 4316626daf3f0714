"""Responses of a solved state (paper eqs. 14, 41-44) with their partial derivatives.

The names are imported on first use, so that ``contopt.responses.catalog`` (the built-in responses
as problem files name them) loads no JAX.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from contopt.responses.base import Combination, Fields, Partials, Response
    from contopt.responses.functionals import (
        BUILTIN,
        Compliance,
        ContactForce,
        FrictionForce,
        Functional,
        PressureVariance,
        StrainEnergy,
        VolumeFraction,
        builtin,
    )
    from contopt.responses.path import ForceMax, ForceMin, ForceTarget
    from contopt.responses.quantities import MeanDisplacement, Reaction
    from contopt.responses.stress import Stress

__all__ = [
    "BUILTIN",
    "Combination",
    "Compliance",
    "ContactForce",
    "Fields",
    "ForceMax",
    "ForceMin",
    "ForceTarget",
    "FrictionForce",
    "Functional",
    "MeanDisplacement",
    "Partials",
    "PressureVariance",
    "Reaction",
    "Response",
    "StrainEnergy",
    "Stress",
    "VolumeFraction",
    "builtin",
]
_BASE = ("Combination", "Fields", "Partials", "Response")
_PATH = ("ForceMax", "ForceMin", "ForceTarget")
_STRESS = ("Stress",)
_QUANTITIES = ("MeanDisplacement", "Reaction")


def __getattr__(name: str):
    if name in __all__:
        home = (
            "contopt.responses.base"
            if name in _BASE
            else "contopt.responses.path"
            if name in _PATH
            else "contopt.responses.stress"
            if name in _STRESS
            else "contopt.responses.quantities"
            if name in _QUANTITIES
            else "contopt.responses.functionals"
        )
        value = getattr(import_module(home), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'contopt.responses' has no attribute {name!r}")
