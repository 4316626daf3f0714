"""Hyperelastic energies and the SIMP interpolation."""

from contopt.material.hyperelastic import (
    Material,
    MooneyRivlin,
    energy_of_F,
    invariants,
    mooney_rivlin_energy,
    neo_hookean,
    simp,
)

__all__ = ["Material", "MooneyRivlin", "energy_of_F", "invariants", "mooney_rivlin_energy", "neo_hookean", "simp"]
