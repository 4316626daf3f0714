"""Optimizers (MMA, IPOPT), the design problem adapter, history and resume."""

from contopt.optimize.base import STATUSES, Evaluated, EvaluationFailure, IterationInfo, NLP, OptimizerResult

__all__ = ["STATUSES", "Evaluated", "EvaluationFailure", "IterationInfo", "NLP", "OptimizerResult"]
