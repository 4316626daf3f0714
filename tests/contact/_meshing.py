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


def _graded_box(h, fine, length, below, width=None):
    """A box on x in [-length, length] and z in [-length, 0] (``below``) or [0, length], one cell
    of ``width`` (default h) in y, cells of h up to ``fine`` from x = 0 and z = 0, graded beyond."""
    from contopt.mesh.generators import box

    xs = graded(h, fine, length)
    return box(grading=(np.concatenate([-xs[:0:-1], xs]), np.array([0.0, width or h]), -xs[::-1] if below else xs))


def indenter_on_block(block, indenter, push, interface_options, faces=("side_min", "side_max", "inner", "outer")):
    """The Model of a plane-strain slice (one cell thick in y, u_y = 0 on both faces of both
    bodies): the Body ``block`` clamped at its bottom, under the Body ``indenter`` (a shell sector)
    whose inner surface moves by ``push(X, t)``. Nonmortar: the block's top; mortar: the indenter's
    outer surface; ``interface_options``: the ContactInterface's law and friction. ``faces``: the
    indenter's node sets of its two y faces, its driven surface and its contact surface."""
    from contopt.assembly.model import Dirichlet, Model
    from contopt.contact.interface import ContactInterface

    b, d = block.name, indenter.name
    return Model(
        bodies=(block, indenter),
        dirichlet=(
            Dirichlet(b, "zmin", "xyz"),
            Dirichlet(b, "ymin", "y"),
            Dirichlet(b, "ymax", "y"),
            Dirichlet(d, faces[0], "y"),
            Dirichlet(d, faces[1], "y"),
            Dirichlet(d, faces[2], "xyz", push),
        ),
        interfaces=(ContactInterface(nonmortar=(b, "zmax"), mortar=(d, faces[3]), **interface_options),),
    )


def cylinder_on_block(h, fine, length, arc_half, block_material, cyl_material, push, interface_options):
    """:func:`indenter_on_block` with a block on x in [-length, length], z in [-length, 0], cells of
    h up to ``fine`` from the contact (graded beyond), and a cylinder shell sector of radius 1 (arc
    ``+-arc_half``, facets <= h). Returns the Model and the cylinder's facet length."""
    from contopt.assembly.model import Body
    from contopt.mesh.generators import cylinder_shell_sector

    block = _graded_box(h, fine, length, below=True)
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


def parabola_on_block(h, fine, length, material, push, interface_options, mortar_ratio=1.1, flat_beyond=0.3):
    """Two bodies of one ``material`` (Dundurs' beta = 0): a block as in :func:`cylinder_on_block`
    (nonmortar: its top, clamped at its bottom) and above it a block of the same size whose bottom
    is bent to the parabola ``z = x^2/2`` (the Hertz profile of a cylinder of radius 1; beyond
    ``|x| = flat_beyond`` its tangent line), meshed with facets ``mortar_ratio`` x h (so that no
    edges of the two surfaces coincide). Its top (node set "zmax") moves by ``push(X, t)``; mortar:
    its bottom. Plane strain as in :func:`indenter_on_block`. Returns the Model."""
    from dataclasses import replace

    from contopt.assembly.model import Body

    block = _graded_box(h, fine, length, below=True)
    upper = _graded_box(mortar_ratio * h, fine, length, below=False, width=h)
    p = np.array(upper.points)
    ax = np.abs(p[:, 0])
    profile = np.where(ax <= flat_beyond, ax**2 / 2, flat_beyond**2 / 2 + flat_beyond * (ax - flat_beyond))
    p[:, 2] += profile * (1 - p[:, 2] / length)  # the bend fades out towards the driven top
    upper = replace(upper, points=p)
    return indenter_on_block(
        Body("block", block, material),
        Body("upper", upper, material),
        push,
        interface_options,
        faces=("ymin", "ymax", "zmax", "zmin"),
    )


def roller_on_block(law, slide=0.03, friction=None, surfaces=False):
    """The Model of a stiff 16-gon roller (all its nodes driven: a rigid tool) pressed 0.03 into a block
    clamped at its bottom and slid by ``slide`` along x. The block's coarse flat top is nonmortar, or
    (``surfaces``) the side the mortar rule chooses."""
    from contopt.assembly.model import Body, Dirichlet, Model
    from contopt.contact.interface import ContactInterface
    from contopt.material import neo_hookean
    from contopt.mesh.generators import box, cylinder

    pair = (("block", "zmax"), ("roller", "outer"))
    sides = {"surfaces": pair} if surfaces else {"nonmortar": pair[0], "mortar": pair[1]}
    block = box((1.0, 0.4, 0.3), (6, 2, 3), origin=(-0.5, 0.0, -0.3))
    roller = cylinder(radius=0.2, length=0.6, divisions=(4, 1, 2))
    roller = roller.transformed(np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]), [0.0, 0.2, 0.2])
    return Model(
        bodies=(Body("block", block, neo_hookean(1.0, 0.3)), Body("roller", roller, neo_hookean(100.0, 0.3))),
        dirichlet=(
            Dirichlet("block", "zmin", "xyz"),
            Dirichlet("roller", "all", "xyz", (slide, 0.0, -0.03)),
        ),
        interfaces=(ContactInterface(**sides, law=law, friction=friction),),
    )
