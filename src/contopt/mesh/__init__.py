"""Hex8 meshes with named node and facet sets; generators and meshio I/O."""

from contopt.mesh.core import (
    HEX_FACES,
    Mesh,
    boundary_facets,
    cell_jacobian_dets,
    scaled_jacobian,
    validate,
)
from contopt.mesh.generators import annulus, box, cylinder, cylinder_shell_sector, merge_nodes
from contopt.mesh.io import SUPPORTED_SUFFIXES, read_bodies, read_mesh, write_mesh

__all__ = [
    "HEX_FACES",
    "Mesh",
    "SUPPORTED_SUFFIXES",
    "annulus",
    "boundary_facets",
    "box",
    "cell_jacobian_dets",
    "cylinder",
    "cylinder_shell_sector",
    "merge_nodes",
    "read_bodies",
    "read_mesh",
    "scaled_jacobian",
    "validate",
    "write_mesh",
]
