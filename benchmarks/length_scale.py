"""The length scale of density designs with and without the robust formulation, measured on the result.

    python benchmarks/length_scale.py RUN_DIR [RUN_DIR ...] [--refine 4] [--out FILE.json]
    python benchmarks/length_scale.py --quick --out FILE.json   # one MMA iteration of the coarse cantilever, measured

For each run directory (``contopt run CASE --out RUN_DIR`` of a density design on a box mesh)
it reads the last VTU of the designed body, puts the cells' volume fractions on their grid, and
prints the thinnest member and the smallest gap of the design (nu >= 1/2, the intermediate
design of a robust run) and, where the VTU has them, of the eroded and dilated designs
(:func:`contopt.design.length_scale.member_sizes`, with the mesh's outside void and mirrored;
the measure's resolution is the lattice spacing h / refine), beside the promised minimum
2 R sqrt(delta) (and its value for a wall under the 3D cone filter) when the run is robust. With
``--out``, a JSON list: per run ``run``, ``radius`` (the filter's R), ``nu`` and, where present,
``nu_eroded`` and ``nu_dilated`` (each its ``member`` and ``gap``), and ``promised``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
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


def quick_run(where: Path) -> Path:
    """A density run to measure in seconds: the coarse cantilever, one MMA iteration."""
    run = where / "cantilever"
    cmd = [sys.executable, "-m", "contopt.cli", "-q", "run", "cantilever", "--mesh", "coarse", "--design"]
    subprocess.run(
        [*cmd, "density", "--max-iter", "1", "--vtu", "final", "--no-plot", "--out", str(run), "--overwrite"],
        check=True,
    )
    return run


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", nargs="*", type=Path)
    ap.add_argument("--refine", type=int, default=4)
    ap.add_argument("--out", default=None, help="also write the measures as JSON (a list, one per run)")
    ap.add_argument(
        "--quick", action="store_true", help="measure a run made here (what tests/benchmarks/test_quick.py runs)"
    )
    args = ap.parse_args(argv)
    if not args.runs and not args.quick:
        ap.error("give RUN_DIR (a density run's directory) or --quick")
    with tempfile.TemporaryDirectory() as tmp:
        runs = args.runs or [quick_run(Path(tmp))]
        rows = [measure(run, args.refine) for run in runs]
    for row in rows:
        print(json.dumps(row, indent=1))
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
