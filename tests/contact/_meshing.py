"""Mesh helpers shared by the contact tests."""

import numpy as np


def graded(h: float, fine: float, length: float, ratio: float = 1.3) -> np.ndarray:
    """Node coordinates from 0 to ``length``: uniform h up to ``fine``, then each cell ``ratio`` x longer."""
    x = list(np.arange(0.0, fine + 1e-9 * h, h))
    dx = h
    while x[-1] < length - 1e-12:
        dx *= ratio
        x.append(min(x[-1] + dx, length))
    if x[-1] - x[-2] < 0.5 * (x[-2] - x[-3]):  # no sliver cell at the end
        x.pop(-2)
    return np.array(x)
