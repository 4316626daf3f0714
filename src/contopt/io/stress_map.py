"""The stress map of a design: the deformed solid cells coloured by their von Mises stress (PNG).

The cell array ``von_mises`` of the VTU output (:func:`contopt.solve.fields.body_fields`: the von Mises
stress of the cell-average Cauchy stress, scaled by the cell's stiffness factor: the stress of the
material that is there) on the cells of each designed body with ``nu >= solid``, in the deformed
configuration; the other bodies (a die, a tool) are drawn faintly, so the peaks under them show.
Drawn like :func:`contopt.io.render.render_deformed` (same camera, size and headless set-up).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from contopt.io.render import (
    DEFAULT_SIZE,
    SOLID_LEVEL,
    body_grids,
    boundary_surface,
    design_focus,
    flat_scalar,
    new_plotter,
    picture_size,
    save_picture,
    up_axis,
)

#: colour map of the stress (zero = its dark end, the peaks bright)
STRESS_CMAP = "inferno"


def has_stress(bodies) -> bool:
    """Whether any designed body (cell array ``nu``) of ``bodies`` carries the cell array ``von_mises``."""
    return any("nu" in g.cell_data and "von_mises" in g.cell_data for _, g in body_grids(bodies))


def render_stress(
    bodies,
    path: str | os.PathLike,
    size: Sequence[int] = DEFAULT_SIZE,
    solid: float = SOLID_LEVEL,
    title: str = "",
    up: str | None = None,
) -> Path:
    """The deformed designed bodies' cells with ``nu >= solid`` coloured by ``von_mises``, as a PNG.

    bodies : a run directory (its last VTU per body), VTU paths or :class:`contopt.io.render.BodyGrid` s
        with point data ``displacement`` (n, 3) and cell data ``nu`` and ``von_mises`` (m,)
    up : the axis drawn upwards (:func:`contopt.io.render.up_axis`). Returns ``path``.
    """
    size = picture_size(size)
    grids = body_grids(bodies)
    axis = up_axis(grids, up)
    pv, pl = new_plotter(size)
    shown = []
    for _name, grid in grids:
        for key in ("nu", "von_mises"):
            flat_scalar(grid, key)
        if "displacement" in grid.point_data:
            grid.points = grid.points + np.asarray(grid.point_data["displacement"]).reshape(-1, 3)
        if "nu" not in grid.cell_data or "von_mises" not in grid.cell_data:
            pl.add_mesh(boundary_surface(grid), color="steelblue", opacity=0.15)
            continue
        pl.add_mesh(boundary_surface(grid), color="lightgrey", opacity=0.12)
        kept = grid.threshold(solid, scalars="nu", preference="cell")
        if kept.n_cells:
            shown.append(kept)
    top = max((float(np.max(g.cell_data["von_mises"])) for g in shown), default=1.0) or 1.0
    font = max(8, size[1] // 45)
    bar = dict(title="von Mises stress", color="black", vertical=True, position_x=0.8, position_y=0.2, height=0.6)
    bar.update(width=0.06, fmt="%.3g", title_font_size=font, label_font_size=font)
    for i, grid in enumerate(shown):
        pl.add_mesh(
            grid,
            scalars="von_mises",
            preference="cell",
            cmap=STRESS_CMAP,
            clim=(0.0, top),
            show_scalar_bar=i == 0,
            scalar_bar_args=bar,
        )
    return save_picture(pl, path, size, title, axis, design_focus(grids))
