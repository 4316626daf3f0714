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


def indenter_on_block(block, indenter, push, interface_options):
    """The Model of a plane-strain slice (one cell thick in y, u_y = 0 on both faces of both
    bodies): the Body ``block`` clamped at its bottom, under the Body ``indenter`` (a shell sector)
    whose inner surface moves by ``push(X, t)``. Nonmortar: the block's top; mortar: the indenter's
    outer surface; ``interface_options``: the ContactInterface's law and friction."""
    from contopt.assembly.model import Dirichlet, Model
    from contopt.contact.interface import ContactInterface

    b, d = block.name, indenter.name
    return Model(
        bodies=(block, indenter),
        dirichlet=(
            Dirichlet(b, "zmin", "xyz"),
            Dirichlet(b, "ymin", "y"),
            Dirichlet(b, "ymax", "y"),
            Dirichlet(d, "side_min", "y"),
            Dirichlet(d, "side_max", "y"),
            Dirichlet(d, "inner", "xyz", push),
        ),
        interfaces=(ContactInterface(nonmortar=(b, "zmax"), mortar=(d, "outer"), **interface_options),),
    )


def cylinder_on_block(h, fine, length, arc_half, block_material, cyl_material, push, interface_options):
    """:func:`indenter_on_block` with a block on x in [-length, length], z in [-length, 0], cells of
    h up to ``fine`` from the contact (graded beyond), and a cylinder shell sector of radius 1 (arc
    ``+-arc_half``, facets <= h). Returns the Model and the cylinder's facet length."""
    from contopt.assembly.model import Body
    from contopt.mesh.generators import box, cylinder_shell_sector

    xs = graded(h, fine, length)
    block = box(grading=(np.concatenate([-xs[:0:-1], xs]), np.array([0.0, h]), -xs[::-1]))
    n_arc = int(np.ceil(2 * arc_half / h))
    cyl = cylinder_shell_sector(
        radius=1.0,
        arc=2 * arc_half,
        width=h,
        thickness=0.1,
        divisions=(n_arc, 1, 4),
        center=(0.0, h / 2, 1.0),
        axis="y",
        mid_angle=-np.pi / 2,
    )
    model = indenter_on_block(
        Body("block", block, block_material), Body("cyl", cyl, cyl_material), push, interface_options
    )
    return model, 2 * arc_half / n_arc
