"""Hyperelastic materials (:mod:`~contopt.material.hyperelastic`, no JAX), their energy kernels
(:mod:`~contopt.material.energy`, imported on first use) and the SIMP interpolation."""

from importlib import import_module

from contopt.material.hyperelastic import Material, MooneyRivlin, neo_hookean, simp

#: the kernels, imported on first use so that a material (and a Model) loads no JAX
_KERNELS = ("energy_of_F", "invariants", "mooney_rivlin_energy")

__all__ = ["Material", "MooneyRivlin", "energy_of_F", "invariants", "mooney_rivlin_energy", "neo_hookean", "simp"]


def __getattr__(name: str):
    if name in _KERNELS:
        return getattr(import_module("contopt.material.energy"), name)
    raise AttributeError(f"module 'contopt.material' has no attribute {name!r}")
