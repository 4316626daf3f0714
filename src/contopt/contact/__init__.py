"""Contact: search -> segmentation topology (numpy) -> mortar integrals (JAX) -> contact laws.

Facets (quads and triangles, :func:`contact_facets`) -> search (:mod:`contopt.contact.search`)
-> :func:`segment_pairs` (clipping topology, held fixed)
-> :func:`pair_values` / :func:`pair_values_and_jacobians` / :func:`pair_weighted_hessians`
(exact derivatives of the weighted gaps) -> the interface's contact law
(:mod:`contopt.contact.laws`) -> residual and tangent (:mod:`contopt.contact.system`) -> the
check of every converged state (:mod:`contopt.contact.verify`).

Names are imported on first use, so that what a Model describes (``interface``, ``laws``,
``coulomb``, ``verify``) loads no JAX; the kernels (``mortar``, ``friction``) do.
"""

from importlib import import_module

_WHERE = {
    "TRIANGLE_DEGREE": "mortar",
    "TRIANGLE_POINTS": "mortar",
    "TRIANGLE_WEIGHTS": "mortar",
    "bilinear_shape": "mortar",
    "inverse_bilinear": "mortar",
    "pair_integrals": "mortar",
    "pair_values": "mortar",
    "pair_values_and_jacobians": "mortar",
    "pair_weighted_hessians": "mortar",
    "MAX_VERTICES": "segment",
    "Reject": "segment",
    "Segmentation": "segment",
    "auxiliary_frame": "segment",
    "segment_pairs": "segment",
    "vertex_coordinates": "segment",
    "triangles": "segment",
    "TRI6_SPLIT": "facets",
    "contact_facets": "facets",
    "ContactInterface": "interface",
    "Coulomb": "coulomb",
    "AugmentationOptions": "laws",
    "AugmentedLagrangian": "laws",
    "ContactLaw": "laws",
    "LAWS": "laws",
    "Penalty": "laws",
    "law_named": "laws",
    "PenetrationCheck": "verify",
}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(import_module(f"contopt.contact.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'contopt.contact' has no attribute {name!r}")
