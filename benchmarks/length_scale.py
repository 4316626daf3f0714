"""The length scale of density designs with and without the robust formulation, measured on the result.

    python benchmarks/length_scale.py RUN_DIR [RUN_DIR ...] [--refine 4]

For each run directory (``contopt run CASE --out RUN_DIR`` of a density design on a box mesh)
it reads the last VTU of the designed body, puts the cells' volume fractions on their grid, and
prints the thinnest member and the smallest gap of the design (nu >= 1/2, the intermediate
design of a robust run) and, where the VTU has them, of the eroded and dilated designs
(:func:`contopt.design.length_scale.member_sizes`, with the mesh's outside void and mirrored;
the measure's resolution is the lattice spacing h / refine), beside the promised minimum
2 R sqrt(delta) (and its value for a wall under the 3D cone filter) when the run is robust.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def measure(run: Path, refine: int) -> dict:
    import meshio

    from contopt.design.length_scale import cell_grid, member_sizes, robust_length_scale

    problem = (run / "checkpoint" / "meta.json").read_text()
    design = json.loads(problem)["fingerprint"]["design"][0]
    body = design["body"]
    vtu = sorted((run / "vtu").glob(f"{body}_*.vtu"))[-1]
    mesh = meshio.read(vtu)
    cells = mesh.cells_dict["hexahedron"]
    out = {"run": str(run), "vtu": vtu.name, "radius": design["radius"]}
    for name in ("nu", "nu_eroded", "nu_dilated"):
        if name in mesh.cell_data:
            grid, h = cell_grid(mesh.points[cells].mean(axis=1), np.asarray(mesh.cell_data[name][0]).ravel())
            out[name] = {"resolution": h / refine}
            for outside in ("void", "mirror"):
                member, gap = member_sizes(grid, h, refine, outside)
                out[name][outside] = {"member": member, "gap": gap}
    if "robust" in design:
        delta = design["robust"]["delta"]
        out["promised"] = {
            "delta": delta,
            "1d": robust_length_scale(design["radius"], delta),
            "3d wall": robust_length_scale(design["radius"], delta, dim=3),
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--refine", type=int, default=4)
    args = ap.parse_args()
    for run in args.runs:
        print(json.dumps(measure(run, args.refine), indent=1))


if __name__ == "__main__":
    main()
