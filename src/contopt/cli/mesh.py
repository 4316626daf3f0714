"""``contopt mesh FILE``: mesh a CAD file once with Gmsh (hex8) and write it, or list the named surfaces
of a CAD file or the sets of a mesh file (no JAX loaded)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from contopt.cli.exits import DONE
from contopt.errors import ConfigError


def cmd_mesh(args) -> int:
    """Mesh ``args.file`` (CAD) at ``--size`` and write ``--out``; with ``--list``, list its surfaces or sets."""
    from contopt.mesh.cad import CAD_SUFFIXES, cad_surfaces, mesh_cad
    from contopt.mesh.core import scaled_jacobian
    from contopt.mesh.io import SUPPORTED_SUFFIXES, read_mesh, write_mesh

    path = Path(args.file)
    suffix = path.suffix.lower()
    if getattr(args, "envelope", False):
        return _voxels(args, path)
    if suffix not in CAD_SUFFIXES and not (args.list and suffix in SUPPORTED_SUFFIXES):
        readable = ", ".join(CAD_SUFFIXES) + "; with --list also " + ", ".join(SUPPORTED_SUFFIXES)
        raise ConfigError(f"contopt mesh reads CAD files ({readable}), not {path.name}")
    if suffix in SUPPORTED_SUFFIXES:
        mesh = read_mesh(path)
    elif args.size is None:
        if not args.list:
            raise ConfigError("contopt mesh needs --size (the elements' edge length, in the model's unit), or --list")
        print(f"{path}: surfaces of its solid (the facet sets contopt mesh makes; area in the unit squared):")
        for s in cad_surfaces(path, scale=args.scale):
            print(f"  {s.name:24s} Gmsh tag {s.tag:<5d} area {s.area:.6g}")
        return DONE
    else:
        mesh = mesh_cad(path, args.size, order=args.order, scale=args.scale, element=getattr(args, "element", "hex8"))
        if mesh.element == "hex8":
            quality = scaled_jacobian(mesh)
            print(
                f"meshed {path}: {mesh.n_cells} hex8 cells, {mesh.n_nodes} nodes; scaled Jacobian min "
                f"{quality.min():.3f}, mean {quality.mean():.3f} (1: a cube)"
            )
        else:
            print(f"meshed {path}: {mesh.n_cells} {mesh.element} cells, {mesh.n_nodes} nodes")
    if args.list:
        _list_sets(mesh)
    if suffix in CAD_SUFFIXES:
        out = Path(args.out) if args.out else Path(path.stem + ".msh")
        write_mesh(out, mesh)
        print(f"wrote {out} (its sets: contopt mesh {out} --list)")
    return DONE


def _voxels(args, path: Path) -> int:
    """``--envelope``: the voxel mesh of a closed surface (contopt.mesh.voxel), written to ``--out``."""
    from contopt.mesh.io import write_mesh
    from contopt.mesh.voxel import mesh_envelope

    if args.size is None:
        raise ConfigError("contopt mesh --envelope needs --size (the cubes' edge, in the model's unit)")
    mesh = mesh_envelope(path, args.size, scale=args.scale)
    lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)
    print(
        f"voxels of {path}: {mesh.n_cells} hex8 cells of edge {args.size:g}, {mesh.n_nodes} nodes, "
        f"volume {mesh.n_cells * args.size**3:.6g}, box {np.round(lo, 6).tolist()} to {np.round(hi, 6).tolist()}"
    )
    if args.list:
        _list_sets(mesh)
    out = Path(args.out) if args.out else Path(path.stem + ".msh")
    write_mesh(out, mesh)
    print(f"wrote {out} (its sets: contopt mesh {out} --list)")
    return DONE


def _list_sets(mesh) -> None:
    """Print each facet set (faces, area) and each node set that is not one (nodes)."""
    from contopt.fem.cells import face_quadrature
    from contopt.mesh.tool import QuadSurface

    print("facet sets (faces, area):")
    for name in sorted(mesh.facet_sets):
        facets = mesh.facet_set(name)
        if not len(facets):
            area = 0.0
        elif mesh.element == "hex8":
            area = float(QuadSurface(mesh.points, mesh.facet_nodes(facets)).areas().sum())
        else:  # tri3 / tri6 faces: their quadrature's weights
            area = float(face_quadrature(mesh.points, mesh.cells, facets)[1].sum())
        print(f"  {name:24s} {len(facets):7d} faces, area {float(area):.6g}")
    others = sorted(set(mesh.node_sets) - set(mesh.facet_sets))
    if others:
        print("node sets (nodes):")
        for name in others:
            print(f"  {name:24s} {len(mesh.node_set(name)):7d} nodes")
    lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)
    print(f"bounding box {np.round(lo, 6).tolist()} .. {np.round(hi, 6).tolist()}")
