"""Responses of a solved state (paper eqs. 14, 41-44) with their partial derivatives."""

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

__all__ = [
    "BUILTIN",
    "Combination",
    "Compliance",
    "ContactForce",
    "Fields",
    "FrictionForce",
    "Functional",
    "Partials",
    "PressureVariance",
    "Response",
    "StrainEnergy",
    "VolumeFraction",
    "builtin",
]
