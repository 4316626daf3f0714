"""Design parameterizations: x -> level set phi -> volume fraction nu -> stiffness factor rho (paper section 6)."""

from contopt.design.bspline import BSplineGrid, uniform_basis
from contopt.design.filter import cone_filter
from contopt.design.maps import REALIZATIONS, EtaContinuation, Heaviside, Robust, Simp, r_union, r_union_partials
from contopt.design.space import (
    BoxRegion,
    Density,
    Design,
    DesignedBody,
    DesignFields,
    DesignSpace,
    RadialSkin,
    SurfaceRegion,
    cell_centroids,
)
from contopt.design.symmetry import CyclicSymmetry

__all__ = [
    "BSplineGrid",
    "BoxRegion",
    "CyclicSymmetry",
    "Density",
    "Design",
    "DesignedBody",
    "DesignFields",
    "DesignSpace",
    "EtaContinuation",
    "Heaviside",
    "REALIZATIONS",
    "RadialSkin",
    "Robust",
    "Simp",
    "SurfaceRegion",
    "cell_centroids",
    "cone_filter",
    "r_union",
    "r_union_partials",
    "uniform_basis",
]
