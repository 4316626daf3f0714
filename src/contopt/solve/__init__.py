"""Linear and nonlinear solvers."""

from contopt.solve.linear import LinearSolverOptions, available_backends, factorize

__all__ = ["LinearSolverOptions", "available_backends", "factorize"]
