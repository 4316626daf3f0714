"""Hex8, tet4 and tet10 meshes with named node and facet sets; generators and meshio I/O."""

from contopt.mesh.core import (
    HEX_FACES,
    TET_FACES,
    Mesh,
    boundary_facets,
    cell_jacobian_dets,
    scaled_jacobian,
    validate,
)
from contopt.mesh.generators import annulus, box, cylinder, cylinder_shell_sector, merge_nodes
from contopt.mesh.io import SUPPORTED_SUFFIXES, read_bodies, read_mesh, write_mesh
from contopt.mesh.tets import tetrahedralize, to_tet10

__all__ = [
    "HEX_FACES",
    "Mesh",
    "SUPPORTED_SUFFIXES",
    "TET_FACES",
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
    "tetrahedralize",
    "to_tet10",
    "validate",
    "write_mesh",
]
