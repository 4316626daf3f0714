"""Cyclic + reflection symmetry by mapping evaluation points (paper 7.4).

``phi(r, alpha) = phi(r, alpha*)`` with ``alpha* = |mod(alpha + beta/2, beta) - beta/2|``
and ``beta = 2 pi / n_sectors``: every point maps into the first half sector
``0 <= alpha* <= beta/2`` (or, without reflection, into the first sector
``0 <= alpha* < beta``). The design then lives on that region only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from contopt.errors import ConfigError

AXES = {"x": (1, 2, 0), "y": (2, 0, 1), "z": (0, 1, 2)}  # (first in-plane, second in-plane, axial)


@dataclass(frozen=True)
class CyclicSymmetry:
    """n_sectors equal sectors about an axis; ``reflection`` also mirrors each about its midplane.

    axis : "x", "y" or "z"; center : a point on the axis
    start : angle (radians) where the first sector begins, measured in the plane
        normal to the axis from its first in-plane direction (x for axis z)
    """

    n_sectors: int
    reflection: bool = True
    axis: str = "z"
    center: tuple = (0.0, 0.0, 0.0)
    start: float = 0.0

    def __post_init__(self):
        if not isinstance(self.n_sectors, (int, np.integer)) or self.n_sectors < 1:
            raise ConfigError(f"symmetry.n_sectors must be a positive integer, got {self.n_sectors!r}")
        if self.axis not in AXES:
            raise ConfigError(f"symmetry.axis must be one of {sorted(AXES)}, got {self.axis!r}")
        if not isinstance(self.reflection, bool):
            raise ConfigError(f"symmetry.reflection must be true or false, got {self.reflection!r}")
        c = np.asarray(self.center, dtype=np.float64)
        if c.shape != (3,):
            raise ConfigError(f"symmetry.center must be three numbers, got {self.center!r}")
        object.__setattr__(self, "center", tuple(float(v) for v in c))

    @property
    def sector_angle(self) -> float:
        return 2.0 * np.pi / self.n_sectors

    def reduced_angle(self, alpha: np.ndarray) -> np.ndarray:
        """alpha (measured from ``start``) -> alpha* in the fundamental region."""
        beta = self.sector_angle
        if self.reflection:
            return np.abs(np.mod(alpha + beta / 2.0, beta) - beta / 2.0)
        return np.mod(alpha, beta)

    def map(self, points: np.ndarray) -> np.ndarray:
        """(k, 3) points -> (k, 3) their images in the fundamental region (same radius and axial position)."""
        points = np.asarray(points, dtype=np.float64)
        i, j, _ = AXES[self.axis]
        rel = points - np.array(self.center)
        r = np.hypot(rel[:, i], rel[:, j])
        alpha = np.arctan2(rel[:, j], rel[:, i]) - self.start
        a = self.reduced_angle(alpha) + self.start
        out = points.copy()
        out[:, i] = self.center[i] + r * np.cos(a)
        out[:, j] = self.center[j] + r * np.sin(a)
        return out
