"""Adjoint sensitivities through contact (paper sections 4-5) and gradient checks."""

from contopt.adjoint.sensitivity import AdjointOptions, AdjointResult, Sensitivity, sensitivities

__all__ = ["AdjointOptions", "AdjointResult", "Sensitivity", "sensitivities"]
