"""Contact: segmentation topology (numpy) and mortar integrals (JAX) of facet pairs.

Search -> :func:`segment_pairs` (clipping topology, held fixed) ->
:func:`pair_values` / :func:`pair_values_and_jacobians` /
:func:`pair_weighted_hessians` (exact derivatives of the weighted gaps)
-> enforcement.
"""

from contopt.contact.mortar import (
    TRIANGLE_DEGREE,
    TRIANGLE_POINTS,
    TRIANGLE_WEIGHTS,
    bilinear_shape,
    inverse_bilinear,
    pair_integrals,
    pair_values,
    pair_values_and_jacobians,
    pair_weighted_hessians,
)
from contopt.contact.segment import (
    MAX_VERTICES,
    Reject,
    Segmentation,
    auxiliary_frame,
    segment_pairs,
    vertex_coordinates,
)

__all__ = [
    "MAX_VERTICES",
    "Reject",
    "Segmentation",
    "TRIANGLE_DEGREE",
    "TRIANGLE_POINTS",
    "TRIANGLE_WEIGHTS",
    "auxiliary_frame",
    "bilinear_shape",
    "inverse_bilinear",
    "pair_integrals",
    "pair_values",
    "pair_values_and_jacobians",
    "pair_weighted_hessians",
    "segment_pairs",
    "vertex_coordinates",
]
