"""Optimizers (MMA, IPOPT), the design problem adapter, history and resume."""

from contopt.optimize.base import NLP, STATUSES, DesignEvaluation, EvaluationFailure, IterationInfo, OptimizerResult
from contopt.optimize.ipopt import IpoptOptions, run_ipopt
from contopt.optimize.mma import MMAOptions, run_mma

__all__ = [
    "STATUSES",
    "DesignEvaluation",
    "EvaluationFailure",
    "IterationInfo",
    "NLP",
    "OptimizerResult",
    "MMAOptions",
    "run_mma",
    "IpoptOptions",
    "run_ipopt",
]
