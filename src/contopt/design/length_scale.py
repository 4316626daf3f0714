"""The length scale of a density design: what the robust formulation promises, and what a design has.

**Promised** (:func:`robust_length_scale`). With the robust formulation
(:class:`~contopt.design.maps.Robust`) every member of the intermediate design is also in the
eroded design (a member the eroded design loses makes its response the worst), so the filtered
density reaches ``1/2 + delta`` inside it. The thinnest such member is a straight wall of
design variables just wide enough for that; its intermediate width, where the filtered density
crosses 1/2, is the minimum member size. For the linear ("hat") filter of radius R in one
dimension (Qian & Sigmund 2013, the 1D analysis behind Wang, Lazarov & Sigmund 2011)::

    b_min = 2 R sqrt(delta)               for delta <= 1/4
    b_min = 2 R (1 - sqrt(1/2 - delta))   for delta >= 1/4

and, by the same argument on the void with the dilated design, the same minimum gap. The cone
filter of a 2D or 3D mesh averages a wall over a disc or a ball, which gives slightly smaller
values (``dim``, computed by quadrature).

**Measured** (:func:`member_sizes`). A design on a structured grid of cells is interpolated to a
finer lattice, thresholded at nu = 1/2, and each solid (void) point gets its local thickness: the
diameter of the largest ball inside the solid (void) that contains it (Hildebrand & Rüegsegger
1997), from Euclidean distance transforms (``scipy.ndimage``). The thinnest member is the least
local thickness over the solid's medial axis (``skimage.morphology.skeletonize``), so that the
rounding of convex corners does not count; the smallest gap alike. Outside the grid is void.
"""

from __future__ import annotations

import numpy as np

from contopt.errors import ConfigError

#: what lies beyond the lattice when thicknesses are measured (local_thickness)
OUTSIDE = ("void", "mirror")


def _wall_profile(dim: int, n: int = 2001) -> tuple[np.ndarray, np.ndarray]:
    """The cone filter of radius 1 in ``dim`` dimensions averaged along a wall: ``(s, cdf(s))``,
    the share of the filter's weight at signed distance < s across the wall, s in [-1, 1]."""
    s = np.linspace(-1.0, 1.0, n)
    if dim == 1:
        k = np.maximum(1.0 - np.abs(s), 0.0)
    else:
        t = np.linspace(0.0, 1.0, n)
        w = np.maximum(1.0 - np.hypot(s[:, None], t[None, :]), 0.0)
        k = np.asarray(np.trapezoid(w * (2.0 * np.pi * t if dim == 3 else 2.0), t, axis=1), dtype=np.float64)
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (k[1:] + k[:-1]) * np.diff(s))])
    return s, cdf / cdf[-1]


def robust_length_scale(radius: float, delta: float, dim: int = 1) -> float:
    """The minimum member size (and gap) of a robust design: filter radius ``radius``, threshold
    shift ``delta`` in (0, 0.5), the filter's dimension ``dim`` (1: the closed form above)."""
    if not radius > 0 or not 0.0 < delta < 0.5 or dim not in (1, 2, 3):
        raise ConfigError(f"need radius > 0, delta in (0, 0.5) and dim 1, 2 or 3, got {radius!r}, {delta!r}, {dim!r}")
    if dim == 1:
        return 2.0 * radius * (np.sqrt(delta) if delta <= 0.25 else 1.0 - np.sqrt(0.5 - delta))
    from scipy.optimize import brentq

    s, cdf = _wall_profile(dim)

    def filtered(d, a):  # the filtered density at distance d from the middle of a wall |x| < a
        return np.interp(d + a, s, cdf, left=0.0, right=1.0) - np.interp(d - a, s, cdf, left=0.0, right=1.0)

    a = brentq(lambda a: filtered(0.0, a) - (0.5 + delta), 1e-12, 1.0, xtol=1e-12)
    return 2.0 * radius * brentq(lambda d: filtered(d, a) - 0.5, 0.0, 2.0, xtol=1e-12)


def local_thickness(mask: np.ndarray, spacing: float, outside: str = "void") -> np.ndarray:
    """Per point of the boolean lattice ``mask`` (2D or 3D), the diameter of the largest ball inside
    ``mask`` that contains it (0 outside); balls are tried at radii in steps of ``spacing / 2``.
    ``outside``: "void" (beyond the lattice is not in mask) or "mirror" (the lattice mirrored at its
    faces, as the normalized filter sees a design at the boundary of its domain)."""
    from scipy.ndimage import distance_transform_edt

    if outside not in OUTSIDE:
        raise ConfigError(f"outside must be one of {OUTSIDE}, got {outside!r}")
    if outside == "mirror":
        # a ball of the mirrored mask reaches at most twice the deepest point's depth past a face
        depth = int(np.ceil(distance_transform_edt(np.pad(mask, 1)).max()))
        width = min(4 * depth + 2, max(mask.shape))
        big = _mirror(mask, width)
        return local_thickness(big, spacing)[tuple(slice(width, width + n) for n in mask.shape)]
    padded = np.pad(mask, 1)  # outside the lattice is not in mask
    inner = distance_transform_edt(padded) * spacing  # distance to the nearest point outside
    out = np.zeros(padded.shape)
    r = 0.5 * spacing
    while True:
        core = inner > r  # the centres of balls of radius r inside the mask
        if not core.any():
            break
        covered = distance_transform_edt(~core) * spacing <= r
        out[padded & covered] = 2.0 * r
        r += 0.5 * spacing
    return out[tuple(slice(1, -1) for _ in range(mask.ndim))]


def cell_grid(centroids: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, float]:
    """Cell values of a structured box mesh on their grid: ``(grid (nx, ny, nz), h)`` from the cells'
    (m, 3) centroids and (m,) values; h the smallest spacing of the centroids."""
    axes = [np.unique(np.round(c, 9)) for c in np.asarray(centroids).T]
    index = tuple(np.searchsorted(a, np.round(c, 9)) for a, c in zip(axes, np.asarray(centroids).T))
    grid = np.full([len(a) for a in axes], np.nan)
    grid[index] = values
    if np.isnan(grid).any() or len(values) != grid.size:
        raise ConfigError("the cells do not form a structured grid: the length scale is measured on box meshes")
    return grid, min(float(np.diff(a).min()) for a in axes if len(a) > 1)


def _mirror(mask: np.ndarray, width: int) -> np.ndarray:
    """``mask`` mirrored at its faces repeatedly until ``width`` points lie beyond each."""
    out, pad = mask, 0
    while pad < width:
        step = min(min(out.shape), width - pad)
        out, pad = np.pad(out, step, mode="symmetric"), pad + step
    return out


def member_sizes(nu: np.ndarray, h: float, refine: int = 4, outside: str = "void") -> tuple[float, float]:
    """``(thinnest member, smallest gap)`` of a design of cell values ``nu`` (nx, ny[, nz]) on a grid of
    cell size ``h``: interpolated ``refine`` times finer, thresholded at 1/2 (module docstring).
    A grid with one cell along an axis is measured in the plane of the other two; inf where the
    design has no solid (no void). ``outside``: see :func:`local_thickness` ("mirror": a member
    along the grid's boundary counts twice as thick, as the filter sees it)."""
    from scipy.ndimage import zoom
    from skimage.morphology import skeletonize

    nu = np.squeeze(np.asarray(nu, dtype=np.float64))
    if nu.ndim not in (2, 3):
        raise ConfigError(f"member_sizes needs a 2D or 3D grid of cell values, got shape {np.shape(nu)}")
    fine = zoom(np.pad(nu, 1, mode="edge"), refine, order=1)[tuple(slice(refine, -refine) for _ in nu.shape)]
    spacing = h / refine
    solid = fine > 0.5
    sizes = []
    for part in (solid, ~solid):
        if not part.any():
            sizes.append(float("inf"))
            continue
        thick = local_thickness(part, spacing, outside)
        axis = skeletonize(part)
        sizes.append(float(thick[axis].min()) if axis.any() else float(thick[part].max()))
    return sizes[0], sizes[1]
