"""A contact-free 3D cantilever for compliance minimization (the classic top3d benchmark).

Beam ``[0, L] x [0, H] x [0, W]``, clamped at ``x = 0``, loaded at the free end
by a downward traction ``-load e_y`` on the bottom quarter of the face ``x = L``
(the top3d line load, spread over a band of facets so that it is a proper
traction). With a small load the neo-Hookean answer approaches linear
elasticity, which makes the case a check of the whole optimization chain
against a linear SIMP code.
"""

from __future__ import annotations

import numpy as np

from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.design import BSplineGrid, Density, Design, DesignedBody, Heaviside, Simp
from contopt.errors import ConfigError
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh.generators import box
from contopt.optimize.problem import DesignProblem
from contopt.responses.functionals import Compliance

DESIGN_BODY = "beam"
PARAMETERIZATIONS = ("density", "bspline")


def cantilever(divisions=(24, 8, 4), lengths=(3.0, 1.0, 0.5), load: float = 1e-6, E: float = 1.0,
               nu: float = 0.3, fbar: bool = True) -> Model:
    """The beam model (see the module docstring); ``load`` is the traction magnitude.

    ``fbar=False`` uses the plain fully integrated hex8 (stiffer in bending: 1 % on the
    default mesh), which is what a linear top3d-style code computes.
    """
    mesh = box(lengths, divisions)
    facets = mesh.facet_set("xmax")
    centres = mesh.points[mesh.facet_nodes(facets)].mean(axis=1)
    band = facets[centres[:, 1] < 0.25 * lengths[1]]
    if not len(band):
        raise ConfigError("the cantilever mesh needs at least 4 cells across its height for the load band")
    mesh = mesh.with_sets(facet_sets={"tip": band})
    return Model(bodies=(Body(DESIGN_BODY, mesh, neo_hookean(E, nu), fbar=fbar),),
                 dirichlet=(Dirichlet(DESIGN_BODY, "xmin", "xyz", 0.0),),
                 loads=(Traction(DESIGN_BODY, "tip", (0.0, -float(load), 0.0)),))


def cantilever_design(parameterization: str = "density", volume_fraction: float = 0.3, radius: float | None = None,
                      patches=None, degree: int = 3, eta: float = 10.0, p: float = 3.0, nu0: float = 1e-2,
                      divisions=(24, 8, 4), lengths=(3.0, 1.0, 0.5)) -> Design:
    """The beam's design: cone filter of ``radius`` (default two cells) or a B-spline grid
    (default one patch per two cells)."""
    if parameterization not in PARAMETERIZATIONS:
        raise ConfigError(f"design must be one of {PARAMETERIZATIONS}, got {parameterization!r}")
    h = min(l / n for l, n in zip(lengths, divisions))
    if parameterization == "density":
        param = Density(radius=float(radius) if radius is not None else 2.0 * h)
    else:
        param = BSplineGrid(tuple(patches) if patches is not None else tuple(max(1, n // 2) for n in divisions),
                            degree=degree, origin=(0.0, 0.0, 0.0), lengths=tuple(lengths))
    return Design(bodies=(DesignedBody(DESIGN_BODY, param, volume_fraction=volume_fraction),),
                  heaviside=Heaviside(eta), simp=Simp(p, nu0))


def cantilever_problem(parameterization: str = "density", divisions=(24, 8, 4), lengths=(3.0, 1.0, 0.5),
                       load: float = 1e-6, volume_fraction: float = 0.3, normalize="full", fbar: bool = True,
                       **design) -> DesignProblem:
    """Minimize compliance (eq. 42) of the beam under a volume fraction ``volume_fraction``."""
    divisions = tuple(int(n) for n in np.atleast_1d(divisions))
    return DesignProblem(
        model=cantilever(divisions, lengths, load, fbar=fbar),
        design=cantilever_design(parameterization, volume_fraction, divisions=divisions, lengths=lengths, **design),
        objective=Compliance(),
        normalize=normalize,
    )
