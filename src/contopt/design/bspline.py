"""Uniform tensor-product B-splines on a box grid: ``phi = G d`` (paper eq. 34, appendix B).

A grid of ``n_x x n_y x n_z`` uniform patches of degree ``k`` has
``(n_x + k)(n_y + k)(n_z + k)`` control points (``(n+3)`` per direction for
the paper's tri-cubic splines); each point inside the box depends on
``(k+1)^3`` of them (64 for cubic). Control points are numbered C-order over
``(i_x, i_y, i_z)``, the last index fastest, as in appendix B.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from contopt.errors import ConfigError

#: points this far outside the box (relative to the patch size) are clamped onto it
OUTSIDE_TOL = 1e-8


def uniform_basis(t: np.ndarray, degree: int) -> np.ndarray:
    """The ``degree + 1`` nonzero uniform B-spline functions on one patch.

    Cox-de Boor recursion on integer knots (all denominators equal ``j``).

    Parameters
    ----------
    t : (k,) local coordinates in [0, 1]
    degree : polynomial degree (1 linear, 2 quadratic, 3 cubic, ...)

    Returns
    -------
    (k, degree + 1): column ``a`` multiplies control point ``patch + a``
    """
    t = np.asarray(t, dtype=np.float64)
    N = np.zeros((t.size, degree + 1))
    N[:, 0] = 1.0
    for j in range(1, degree + 1):
        saved = np.zeros(t.size)
        for r in range(j):
            left = t + (j - r) - 1.0  # s - knot[p + 1 - (j - r)]
            right = (r + 1) - t  # knot[p + r + 1] - s
            temp = N[:, r] / j
            N[:, r] = saved + right * temp
            saved = left * temp
        N[:, j] = saved
    return N


@dataclass(frozen=True)
class BSplineGrid:
    """A uniform B-spline grid over an axis-aligned box.

    patches : (n_x, n_y, n_z) number of patches per direction
    degree : 3 (tri-cubic, the paper's choice), 2 or 1 (tri-linear)
    origin, lengths : the box; ``None`` takes the bounding box of the points the grid is evaluated at
    """

    patches: tuple
    degree: int = 3
    origin: tuple | None = None
    lengths: tuple | None = None

    def __post_init__(self):
        try:
            patches = tuple(int(n) for n in self.patches)
        except (TypeError, ValueError):
            raise ConfigError(f"bspline.patches must be three positive integers, got {self.patches!r}") from None
        if len(patches) != 3 or min(patches) < 1 or patches != tuple(self.patches):
            raise ConfigError(f"bspline.patches must be three positive integers, got {self.patches!r}")
        object.__setattr__(self, "patches", patches)
        if self.degree not in (1, 2, 3, 4, 5):
            raise ConfigError(f"bspline.degree must be 1, 2, 3, 4 or 5, got {self.degree!r}")
        for key in ("origin", "lengths"):
            v = getattr(self, key)
            if v is not None:
                v = np.asarray(v, dtype=np.float64)
                if v.shape != (3,) or not np.all(np.isfinite(v)):
                    raise ConfigError(f"bspline.{key} must be three numbers, got {getattr(self, key)!r}")
                object.__setattr__(self, key, tuple(float(c) for c in v))
        if self.lengths is not None and min(self.lengths) <= 0:
            raise ConfigError(f"bspline.lengths must be positive, got {self.lengths!r}")

    @classmethod
    def with_control_points(cls, control_points, degree: int = 3, origin=None, lengths=None) -> BSplineGrid:
        """The grid with this many control points per direction (``patches = control - degree``)."""
        control = tuple(int(c) for c in control_points)
        if len(control) != 3 or min(control) <= degree:
            raise ConfigError(
                f"a degree-{degree} B-spline grid needs more than {degree} control points per "
                f"direction, got {control_points!r}"
            )
        return cls(tuple(c - degree for c in control), degree, origin, lengths)

    @property
    def shape(self) -> tuple:
        """Control points per direction ``(n_x + k, n_y + k, n_z + k)``."""
        return tuple(n + self.degree for n in self.patches)

    @property
    def n_control(self) -> int:
        return int(np.prod(self.shape))

    def box(self, points: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(origin (3,), lengths (3,))``: the given box, or the points' bounding box."""
        if self.origin is not None and self.lengths is not None:
            return np.array(self.origin), np.array(self.lengths)
        if points is None:
            raise ConfigError("bspline: give origin and lengths, or points to take the bounding box of")
        lo, hi = points.min(axis=0), points.max(axis=0)
        origin = np.array(self.origin) if self.origin is not None else lo
        lengths = np.array(self.lengths) if self.lengths is not None else hi - origin
        if np.any(lengths <= 0):
            raise ConfigError(
                f"bspline: the box from origin {origin.tolist()} has non-positive lengths "
                f"{lengths.tolist()}; give bspline.lengths"
            )
        return origin, lengths

    def matrix(self, points: np.ndarray, box: tuple | None = None) -> sp.csr_matrix:
        """``G`` with ``G[i, j] = N_j(X_i)``: (k, n_control), ``(degree+1)^3`` nonzeros a row.

        Raises ConfigError for points outside the box.
        """
        points = np.asarray(points, dtype=np.float64)
        origin, lengths = box if box is not None else self.box(points)
        n = np.array(self.patches)
        s = (points - origin) / lengths * n  # patch coordinates
        outside = np.any((s < -OUTSIDE_TOL) | (s > n + OUTSIDE_TOL), axis=1)
        if outside.any():
            bad = points[np.flatnonzero(outside)[0]]
            raise ConfigError(
                f"{outside.sum()} point(s) lie outside the B-spline box origin {origin.tolist()}, lengths "
                f"{lengths.tolist()} (e.g. {bad.round(6).tolist()}); enlarge the box or omit it"
            )
        s = np.clip(s, 0.0, n)
        patch = np.minimum(np.floor(s).astype(np.int64), n - 1)
        t = s - patch
        k1 = self.degree + 1
        bx, by, bz = (uniform_basis(t[:, d], self.degree) for d in range(3))
        values = (bx[:, :, None, None] * by[:, None, :, None] * bz[:, None, None, :]).reshape(len(points), -1)
        a = np.arange(k1)
        ix = patch[:, 0, None, None, None] + a[None, :, None, None]
        iy = patch[:, 1, None, None, None] + a[None, None, :, None]
        iz = patch[:, 2, None, None, None] + a[None, None, None, :]
        cols = np.ravel_multi_index((ix, iy, iz), self.shape).reshape(len(points), -1)
        rows = np.repeat(np.arange(len(points)), k1**3)
        G = sp.csr_matrix((values.ravel(), (rows, cols.ravel())), shape=(len(points), self.n_control))
        G.sort_indices()
        return G

    def values(self, coefficients: np.ndarray, points: np.ndarray, box: tuple) -> np.ndarray:
        """``phi (k,) = sum_j N_j(X) d_j`` at points (k, 3) with control values ``d`` (n_control,).

        Equal to ``matrix(points, box) @ d`` inside the box, without forming the matrix. Points
        outside the box get the polynomial pieces of the nearest patch continued (no error, no
        clamping): a surface export samples the level set up to the body's boundary, beyond
        the cell centroids the box spans by default.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        d = np.asarray(coefficients, dtype=np.float64).reshape(self.shape)
        origin, lengths = box
        n = np.array(self.patches)
        s = (points - origin) / lengths * n
        patch = np.clip(np.floor(s).astype(np.int64), 0, n - 1)
        basis = [uniform_basis(s[:, k] - patch[:, k], self.degree) for k in range(3)]
        out = np.zeros(len(points))
        for a in range(self.degree + 1):
            for b in range(self.degree + 1):
                wab = basis[0][:, a] * basis[1][:, b]
                for c in range(self.degree + 1):
                    out += wab * basis[2][:, c] * d[patch[:, 0] + a, patch[:, 1] + b, patch[:, 2] + c]
        return out

    def greville(self, box: tuple) -> np.ndarray:
        """(n_control, 3) Greville abscissae: control values ``c(X_j)`` reproduce any linear field ``c``."""
        origin, lengths = box
        axes = [
            origin[d] + lengths[d] / self.patches[d] * (np.arange(self.shape[d]) - (self.degree - 1) / 2.0)
            for d in range(3)
        ]
        grid = np.meshgrid(*axes, indexing="ij")
        return np.stack([g.ravel() for g in grid], axis=1)
