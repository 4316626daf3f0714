"""The plane-strain Hertz line contact shared by tests/contact/test_hertz.py and benchmarks/hertz_line.py.

The model (``hertz_model``): tests/contact/_meshing.py ``cylinder_on_block``, a cylinder of radius
R = 1 (E = 1000) pressed by ``0.02 scale^2`` onto a block (E = 1), nu = 0.3, cells of ``h`` near the
contact. The comparison (``hertz_errors``): the FE pressures against plane-strain Hertz for the load
the FE contact carries; the test's docstring says what each measure is.
"""

from dataclasses import replace

import numpy as np
from _meshing import cylinder_on_block  # tests/contact/_meshing.py

from contopt.fem.hex8 import gauss_legendre
from contopt.material import neo_hookean

R = 1.0
E_BLOCK, E_CYL, NU = 1.0, 1000.0, 0.3
E_STAR = 1.0 / ((1 - NU**2) / E_BLOCK + (1 - NU**2) / E_CYL)


def hertz_model(h: float, law, scale: float = 1.0):
    """``(model, R h_cyl)``: the Hertz model with cells of ``h`` near the contact, every other length
    but R scaled by ``scale`` (indentation by scale^2: a/R ~ 0.1 scale), the contact ``law``."""
    indent = 0.02 * scale**2

    def push(X, t):
        return np.tile([0.0, 0.0, -indent * t**2], (len(X), 1))

    model, h_cyl = cylinder_on_block(
        h,
        0.13 * scale,
        2.5 * scale,
        0.2 * scale,
        neo_hookean(E_BLOCK, NU),
        neo_hookean(E_CYL, NU),
        push,
        {"law": law},
    )
    return model, R * h_cyl


def rigid_hertz_model(h: float, law, scale: float = 1.0):
    """``(model, R h_cyl)``: :func:`hertz_model` with the cylinder a rigid tool (its outer surface, the
    same arc and facets: ``contopt.mesh.tool``), pressed along the same path (the load steps' ends of
    a 4-step solve); its contact modulus is the block's ``E'`` alone (:data:`E_RIGID`)."""
    from contopt.assembly.model import Body, LoadPath, Model, RigidMotion
    from contopt.mesh.tool import cylinder_surface, tool_layer

    deformable, h_cyl = hertz_model(h, law, scale)
    arc_half = 0.2 * scale
    n_arc = int(np.ceil(2 * arc_half / h))
    surface = cylinder_surface(1.0, h, (0.0, h / 2, 1.0), "y", (n_arc, 1), arc=2 * arc_half, normal=(0.0, 0.0, -1.0))
    indent = 0.02 * scale**2
    path = LoadPath(tuple((t, 0.0, 0.0, -indent * t**2) for t in (0.25, 0.5, 0.75, 1.0)))
    cyl = Body("cyl", tool_layer(surface), rigid=RigidMotion(translation=path))
    block = [bc for bc in deformable.dirichlet if bc.body == "block"]
    iface = replace(deformable.interfaces[0], mortar=("cyl", "surface"))
    return Model(bodies=(deformable.body("block"), cyl), dirichlet=tuple(block), interfaces=(iface,)), R * h_cyl


#: the contact modulus against a rigid cylinder: the block's plane-strain modulus
E_RIGID = E_BLOCK / (1 - NU**2)


def hertz_line(p_line: float, e_star: float = E_STAR, radius: float = R) -> tuple[float, float]:
    """Plane-strain Hertz ``(a, p0)`` for the load per unit length ``p_line``: ``a = sqrt(4 P' R / (pi E*))``,
    ``p0 = 2 P' / (pi a)``."""
    a = np.sqrt(4 * p_line * radius / (np.pi * e_star))
    return float(a), float(2 * p_line / (np.pi * a))


def pressure_moments(x_facets: np.ndarray, lam_facets: np.ndarray, axes: tuple = (0,)) -> tuple[float, float]:
    """(int p_h da, int r^2 p_h da) over deformed bilinear facets (F, 4, 3) with nodal pressures (F, 4),
    r^2 the sum of the squared coordinates ``axes`` (x^2 by default; (0, 1): the distance from the z axis).

    2x2 Gauss points: exact for the x^2 p_h of a flat strip (cubic along x).
    """
    s, w = gauss_legendre(2)
    m0 = m2 = 0.0
    for si, wi in zip(s, w):
        for ti, wj in zip(s, w):
            N = 0.25 * np.array([(1 - si) * (1 - ti), (1 + si) * (1 - ti), (1 + si) * (1 + ti), (1 - si) * (1 + ti)])
            dN_s = 0.25 * np.array([-(1 - ti), (1 - ti), (1 + ti), -(1 + ti)])
            dN_t = 0.25 * np.array([-(1 - si), -(1 + si), (1 + si), (1 - si)])
            da = np.linalg.norm(np.cross(dN_s @ x_facets, dN_t @ x_facets), axis=1) * wi * wj
            p = lam_facets @ N
            r2 = np.sum((N @ x_facets)[:, list(axes)] ** 2, axis=1)
            m0 += float(np.sum(p * da))
            m2 += float(np.sum(p * r2 * da))
    return m0, m2


def hertz_errors(system, model, state, h: float, h_cyl: float, e_star: float = E_STAR, driven: str = "inner") -> dict:
    """The converged ``state`` of ``hertz_model(h, ...)`` against Hertz: relative deviations of the
    peak pressure (``peak``), the elliptic fit's ``a_fit`` and ``p0_fit``, the second moment's
    ``a_mom`` and the profile's ``rms``; the preconditions of the comparison (``a_over_R``,
    ``facets_across``, ``h_cyl_over_h``, ``reaction``: the driven surface's reaction against the
    pressure resultant, ``moment_force``); and the absolute values (``force`` per unit length,
    Hertz's ``a_hertz`` and ``p0_hertz``, the FE's ``p0_peak`` and ``a_mom_value``)."""
    block = system.contact.blocks[0]
    lam = state.contact[0].lam
    x = system.contact.X + state.u.reshape(-1, 3)
    W = h  # slice thickness

    force = float(system.contact.total_force(state.u, (lam,))[0])
    p_line = force / W
    cyl_inner = system.disc.blocks[model.body_index("cyl")].node_offset + model.body("cyl").mesh.node_set(driven)
    reaction_line = -float(state.reactions[3 * cyl_inner + 2].sum()) / W
    a_h, p0_h = hertz_line(p_line, e_star)

    xn = x[block.nodes, 0]
    act = lam > 0
    A = np.stack([np.ones(act.sum()), -(xn[act] ** 2)], axis=1)
    c0, c1 = np.linalg.lstsq(A, lam[act] ** 2, rcond=None)[0]
    a_fit, p0_fit = np.sqrt(c0 / c1), np.sqrt(c0)

    m0, m2 = pressure_moments(x[block.nm_facet_nodes], lam[block.nm_local])
    a_mom = 2.0 * np.sqrt(m2 / m0)

    near = np.abs(xn) <= 1.25 * a_h
    ellipse = p0_h * np.sqrt(np.clip(1.0 - xn**2 / a_h**2, 0.0, None))
    rms = float(np.sqrt(np.mean((lam - ellipse)[near] ** 2)) / p0_h)
    return {
        "a_over_R": a_h / R,
        "facets_across": 2 * a_h / h,
        "h_cyl_over_h": h_cyl / h,
        "reaction": reaction_line / p_line - 1,
        "moment_force": m0 / force - 1,
        "peak": float(lam.max() / p0_h - 1),
        "a_fit": float(a_fit / a_h - 1),
        "p0_fit": float(p0_fit / p0_h - 1),
        "a_mom": float(a_mom / a_h - 1),
        "rms": rms,
        "force": p_line,
        "a_hertz": a_h,
        "p0_hertz": p0_h,
        "p0_peak": float(lam.max()),
        "a_mom_value": float(a_mom),
    }
