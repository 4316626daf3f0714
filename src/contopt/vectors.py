"""Dot products and norms of long vectors, summed in the calling thread.

NumPy hands ``a @ b`` and ``np.linalg.norm(a)`` of 1-d float64 vectors to BLAS (OpenBLAS's ``ddot``), which
splits a vector of more than 10,000 entries over its threads. On a machine whose cores are busy with other
processes each such call waits for its second thread to be scheduled: 4-16 ms for one dot of 33k entries
against 9 µs in one thread (docs/performance.md, "Hertz line contact at the size of Kratos' mesh"). Newton's
residual norms and line-search slopes are such dots, a dozen per iteration. :func:`dot` and :func:`norm` sum
with NumPy's own pairwise summation instead: no threads, and no less accurate than BLAS (the last bits
differ from it, as BLAS's own do between thread counts).
"""

from __future__ import annotations

import math

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """``a . b`` of two vectors of the same length."""
    return float(np.sum(np.multiply(a, b)))  # np.add.reduce: pairwise, one thread


def norm(a: np.ndarray) -> float:
    """The Euclidean norm ``sqrt(a . a)`` of a vector (as ``np.linalg.norm`` of a 1-d array, without scaling)."""
    return math.sqrt(dot(a, a))
