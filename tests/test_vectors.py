"""contopt.vectors: dot products and norms summed in the calling thread, against exact sums."""

import math
from fractions import Fraction

import numpy as np

from contopt.vectors import dot, norm


def test_dot_and_norm_match_exact_sums(rng):
    # longer than OpenBLAS's threading threshold (10,000 entries), entries spread over 12 decades
    a = rng.standard_normal(33_128) * 10.0 ** rng.uniform(-6, 6, 33_128)
    b = rng.standard_normal(33_128)
    exact = float(sum(Fraction(x) * Fraction(y) for x, y in zip(a.tolist(), b.tolist())))
    scale = float(np.abs(a) @ np.abs(b))  # the sum's condition: rounding is relative to it
    assert abs(dot(a, b) - exact) <= 1e-13 * scale
    squares = float(sum(Fraction(x) ** 2 for x in a.tolist()))
    assert math.isclose(norm(a), math.sqrt(squares), rel_tol=1e-14)
    assert isinstance(dot(a, b), float) and isinstance(norm(a), float)


def test_norm_of_non_finite_and_empty_vectors():
    assert norm(np.zeros(0)) == 0.0
    assert math.isinf(norm(np.array([1.0, np.inf])))
    assert math.isnan(norm(np.array([1.0, np.nan])))
    assert norm(np.array([3.0, -4.0])) == 5.0
