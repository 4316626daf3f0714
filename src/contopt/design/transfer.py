"""A start design from another design: its level set carried to another mesh or design space.

A designed body's volume fraction is ``nu = H(phi)`` with ``phi`` its level set (the filtered
design variables ``G x`` of a density design, the B-spline of a level-set design). The source's
level set is scaled to the target's Heaviside sharpness (``phi eta_s / eta_t``, so that
``nu`` is the same) and evaluated where the target needs it:

* the same parameterization on the same design sites (the same mesh for a density design, the
  same control grid for a B-spline, whatever the mesh): the variables are copied;
* a density target: the source's design field (a density source's variables, interpolated from
  its sites; a B-spline source's spline) at the target's sites, the cell centroids; the target
  filters them as the source did;
* a B-spline target: its control values fitted to the source's level set at the target's free
  cell centroids (least squares within the bounds, :func:`scipy.optimize.lsq_linear`).

Scattered values are interpolated linearly: on a tensor grid of points (a box mesh's centroids)
with :class:`scipy.interpolate.RegularGridInterpolator`, which continues the grid's linear pieces
beyond it (a finer mesh's outer centroids lie outside a coarser one's), else with
:class:`scipy.interpolate.LinearNDInterpolator` and the nearest point outside the points' hull.
A volume-fraction field (a VTU's ``nu``) is turned into a level set by ``H^{-1}``.

A field that knows its body's extent (the source mesh's bounding box) refuses a target body whose
cells reach beyond it by more than :data:`EXTENT_SLACK` of its size: that body has another shape,
and its design would be extrapolated. :func:`meet_volume_limits` lowers a start design's level set
where it exceeds a body's volume limit, so that the optimizer starts from a feasible design.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator, RegularGridInterpolator
from scipy.optimize import lsq_linear
from scipy.spatial import QhullError

from contopt.design.bspline import BSplineGrid
from contopt.design.space import Density, DesignSpace, Part
from contopt.errors import ConfigError

#: a volume fraction is clipped into [NU_CLIP, 1 - NU_CLIP] before H^{-1}
NU_CLIP = 1e-6
#: the weight pulling a B-spline fit's control values towards the level set at their Greville points
#: (decides the control values no free cell sees; 1e-3 of a cell's weight elsewhere)
FIT_DAMPING = 1e-3
#: coordinates equal within this share of the points' extent are one grid line
GRID_TOL = 1e-9
#: a target body's cells may reach beyond the source body's bounding box by this share of its size
EXTENT_SLACK = 0.01
#: a start design above a body's volume limit by more than this (volume fraction) is lowered to it;
#: one within it (a run's own last iterate, which MMA leaves within its tolerance) is kept as it is
VOLUME_TOL = 1e-4
#: bisection steps of the level-set shift that meets a volume limit (2 / 2^60: round-off)
SHIFT_STEPS = 60

Field = Callable[[np.ndarray], np.ndarray]


def _grid(points: np.ndarray, values: np.ndarray) -> RegularGridInterpolator | None:
    """A linear interpolator on the tensor grid ``points`` form, or None when they form none."""
    size = float(np.ptp(points, axis=0).max()) or 1.0
    keys = np.round(points / (GRID_TOL * size)).astype(np.int64)
    axes: list[int] = []
    index: list[np.ndarray] = []
    for d in range(points.shape[1]):
        unique, inverse = np.unique(keys[:, d], return_inverse=True)
        if len(unique) > 1:  # an axis along which the points do not vary is left out
            axes.append(d)
            index.append(inverse.ravel())
    shape = tuple(int(np.max(i)) + 1 for i in index)
    if not axes or int(np.prod(shape)) != len(points):
        return None
    flat = np.ravel_multi_index(tuple(index), shape)
    if len(np.unique(flat)) != len(points):
        return None
    grid = np.empty(len(points))
    grid[flat] = values
    coords: list[np.ndarray] = []
    for d, i in zip(axes, index):
        line = np.zeros(shape[len(coords)])
        np.add.at(line, i, points[:, d])
        coords.append(line / np.bincount(i))
    rgi = RegularGridInterpolator(tuple(coords), grid.reshape(shape), bounds_error=False, fill_value=None)
    return _OnAxes(rgi, axes)


class _OnAxes:
    """An interpolator of some coordinates of (k, 3) points."""

    def __init__(self, interpolator, axes: list):
        self.interpolator, self.axes = interpolator, axes

    def __call__(self, query: np.ndarray) -> np.ndarray:
        return np.asarray(self.interpolator(np.asarray(query, np.float64)[:, self.axes]), dtype=np.float64)


def interpolator(points: np.ndarray, values: np.ndarray) -> Field:
    """``f(query (k, 3)) -> (k,)``: the piecewise-linear interpolant of ``values`` (n,) at ``points`` (n, 3).

    Exact for a linear field on a tensor grid, also beyond it; on scattered points linear inside
    their convex hull and the nearest point's value outside it.
    """
    points = np.asarray(points, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    if len(points) == 0:
        raise ConfigError("a design field needs at least one point")
    grid = _grid(points, values)
    if grid is not None:
        return grid
    nearest = NearestNDInterpolator(points, values)
    try:
        linear = LinearNDInterpolator(points, values)
    except (QhullError, ValueError):  # too few or coplanar points: no tetrahedra
        return lambda query: np.asarray(nearest(query), dtype=np.float64)

    def both(query: np.ndarray) -> np.ndarray:
        out = np.asarray(linear(query), dtype=np.float64)
        outside = np.isnan(out)
        if outside.any():
            out[outside] = nearest(np.asarray(query)[outside])
        return out

    return both


@dataclass(frozen=True, eq=False)
class BodyField:
    """A designed body's level set as functions of position, in units of a Heaviside of sharpness ``eta``.

    design : its design field (a density design's unfiltered variables; a B-spline's spline)
    level_set : its level set ``phi`` (the filtered field of a density design)
    parameterization, sites, x : the source's design variables, for an exact copy (None for a field)
    extent : ((3,), (3,)) the lower and upper corner of the source body's bounding box, or None
        (unknown: not checked)
    """

    body: str
    design: Field
    level_set: Field
    eta: float
    parameterization: Density | BSplineGrid | None = None
    sites: np.ndarray | None = None
    x: np.ndarray | None = None
    extent: tuple[np.ndarray, np.ndarray] | None = None


def _mapped(part: Part) -> Callable[[np.ndarray], np.ndarray]:
    sym = part.spec.symmetry
    return (lambda X: sym.map(np.asarray(X, np.float64))) if sym is not None else (lambda X: np.asarray(X, np.float64))


def body_fields(space: DesignSpace, x: np.ndarray) -> dict[str, BodyField]:
    """The level set of each designed body of ``space`` at the design ``x``, by body name."""
    x = space.check_x(x)
    eta = space.design.heaviside.eta
    out = {}
    for p in space.parts:
        param, mapped, xb = p.spec.parameterization, _mapped(p), x[p.x].copy()
        if isinstance(param, BSplineGrid):
            box = param.box(mapped(p.centroids))
            spline = (lambda g, c, b, m: lambda X: g.values(c, m(X), b))(param, xb, box, mapped)
            design = level_set = spline
        else:
            design = (lambda f, m: lambda X: f(m(X)))(interpolator(p.sites, xb), mapped)
            level_set = interpolator(p.centroids, p.G @ xb)
        out[p.spec.body] = BodyField(p.spec.body, design, level_set, eta, param, p.sites, xb)
    return out


def volume_fraction_field(
    body: str, points: np.ndarray, nu: np.ndarray, eta: float, extent: tuple[np.ndarray, np.ndarray] | None = None
) -> BodyField:
    """The level set ``H^{-1}(nu)`` of a volume fraction ``nu`` (n,) given at ``points`` (n, 3);
    ``extent``: the body's bounding box (see :class:`BodyField`)."""
    f = interpolator(points, np.clip(np.asarray(nu, np.float64), 0.0, 1.0))

    def level(X: np.ndarray) -> np.ndarray:
        v = np.clip(f(X), NU_CLIP, 1.0 - NU_CLIP)
        return np.log(v / (1.0 - v)) / (2.0 * eta)

    return BodyField(body, level, level, eta, extent=extent)


def _fit(part: Part, level_set: Field, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Control values whose spline fits ``level_set`` at the free cells (bounded least squares)."""
    free = part.fixed < 0
    G = part.G[free] if free.any() else part.G
    b = level_set(part.centroids[free] if free.any() else part.centroids)
    prior = np.clip(level_set(part.sites), lower, upper)
    A = sp.vstack([G, FIT_DAMPING * sp.identity(part.n, format="csr")]).tocsr()
    rhs = np.concatenate([b, FIT_DAMPING * prior])
    return np.asarray(lsq_linear(A, rhs, bounds=(lower, upper), lsmr_tol="auto", tol=1e-10).x, dtype=np.float64)


def _scaled(f: Field, scale: float) -> Field:
    return lambda X: f(X) * scale


def _copyable(part: Part, field: BodyField) -> bool:
    return (
        field.x is not None
        and field.sites is not None
        and field.parameterization == part.spec.parameterization
        and field.sites.shape == part.sites.shape
        and bool(np.array_equal(field.sites, part.sites))
    )


def _check_extent(part: Part, field: BodyField) -> None:
    """ConfigError when the target's cells reach beyond the source body's bounding box (its design
    would be extrapolated, not carried)."""
    if field.extent is None:
        return
    lower, upper = (np.asarray(c, dtype=np.float64) for c in field.extent)
    slack = EXTENT_SLACK * float(np.max(upper - lower))
    X = part.centroids
    out = np.any(X < lower - slack, axis=1) | np.any(X > upper + slack, axis=1)
    if out.any():
        box = " x ".join(f"[{a:.4g}, {b:.4g}]" for a, b in zip(lower, upper))
        here = " x ".join(f"[{a:.4g}, {b:.4g}]" for a, b in zip(X.min(axis=0), X.max(axis=0)))
        raise ConfigError(
            f"body {part.spec.body!r} of the start design spans {box}, this one's cell centres span {here} "
            f"({int(out.sum())} of {len(X)} outside): its design cannot be carried to a body of another "
            "shape; start from a design of the same body (its mesh and parameterization may differ)"
        )


def start_design(target: DesignSpace, fields: Mapping[str, BodyField]) -> tuple[np.ndarray, dict[str, str]]:
    """The design of ``target`` whose bodies' volume fractions are those of ``fields`` (by body name).

    Returns ``(x, how)``: x within the target's bounds, and per body "copied", "interpolated" or
    "fitted". ConfigError when a designed body of the target has no field, or reaches beyond its
    field's extent.
    """
    missing = [p.spec.body for p in target.parts if p.spec.body not in fields]
    if missing:
        raise ConfigError(
            f"the start design has no design of body {', '.join(map(repr, missing))} (it designs "
            f"{', '.join(map(repr, fields)) or 'no body'}); start from a design of the same bodies"
        )
    x, how = target.initial(), {}
    eta = target.design.heaviside.eta
    lower, upper = target.lower, target.upper
    for p in target.parts:
        _check_extent(p, fields[p.spec.body])
    for p in target.parts:
        field = fields[p.spec.body]
        scale = field.eta / eta  # the same nu = H(phi) under the target's sharpness
        lo, hi = lower[p.x], upper[p.x]
        if _copyable(p, field):
            assert field.x is not None
            values, how[p.spec.body] = (field.x.copy() if scale == 1.0 else field.x * scale), "copied"
        elif isinstance(p.spec.parameterization, Density):
            # the same filter: its input, which it smooths as the source's did; another: the source's
            # level set, which the target's filter smooths once more
            same = field.parameterization == p.spec.parameterization
            values = (field.design if same else field.level_set)(p.sites) * scale
            how[p.spec.body] = "interpolated"
        else:
            values, how[p.spec.body] = _fit(p, _scaled(field.level_set, scale), lo, hi), "fitted"
        x[p.x] = np.clip(values, lo, hi)
    return x, how


def meet_volume_limits(space: DesignSpace, x: np.ndarray) -> tuple[np.ndarray, dict[str, tuple[float, float]]]:
    """``x`` (n,) with the level set of each body above its volume limit (by more than
    :data:`VOLUME_TOL`) lowered until it meets the limit, and per lowered body its volume fraction
    (before, after).

    The body's variables are shifted by one amount (within the bounds): G's rows sum to one (the
    normalized filter, the B-spline's partition of unity), so its level set moves down uniformly
    and its shape is kept; the shift is found by bisection (the volume fraction grows with it).
    A body whose fixed solid regions alone exceed the limit ends at the lower bound.
    """
    x = space.check_x(x).copy()
    changed: dict[str, tuple[float, float]] = {}
    for k, p in enumerate(space.parts):
        limit = p.spec.volume_fraction
        before = float(space.volume_fractions(space.forward(x))[k])
        if limit is not None and before > limit + VOLUME_TOL:
            x[p.x] = _lowered(space, x, k, limit)
            changed[p.spec.body] = (before, float(space.volume_fractions(space.forward(x))[k]))
    return x, changed


def _lowered(space: DesignSpace, x: np.ndarray, k: int, limit: float) -> np.ndarray:
    """Part k's variables of ``x`` shifted down (within the bounds) to volume fraction ``limit``."""
    p = space.parts[k]
    lo, hi = space.lower[p.x], space.upper[p.x]
    y = x.copy()

    def shifted(shift: float) -> np.ndarray:
        return np.clip(x[p.x] + shift, lo, hi)

    def fraction(shift: float) -> float:
        y[p.x] = shifted(shift)
        return float(space.volume_fractions(space.forward(y))[k])

    down, up = -float(np.max(hi - lo)), 0.0  # fraction(down) is the least, fraction(up) > limit
    if fraction(down) < limit:
        for _ in range(SHIFT_STEPS):
            mid = 0.5 * (down + up)
            down, up = (mid, up) if fraction(mid) <= limit else (down, mid)
    return shifted(down)
