"""Voxel meshes of a closed surface (contopt.mesh.voxel): cells, volume error and time by size.

    python benchmarks/voxel_envelope.py [--quick] [--out voxel.json]

The envelope is the tests' bracket (tests/_envelope.py: an L-shaped prism 2 x 0.8 x 2 with a
45-degree gusset, 24 triangles, volume 1.296). For each size (``rows``) it reports the kept ``cells``, the
voxels' ``volume`` against the envelope's (``relative_error``, first order in the size: the error halves
with it) and the ``seconds`` :func:`~contopt.mesh.voxel.voxelize` takes (the inside test and the mesh). ``--quick``
runs the two coarsest sizes (about a second).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from _envelope import DEPTH, bracket, profile_area  # noqa: E402 (the tests' bracket, written once)

from contopt.mesh.voxel import voxelize  # noqa: E402

SIZES = (0.2, 0.1, 0.05, 0.025)


def measure(sizes) -> list[dict]:
    surface, exact = bracket(), profile_area() * DEPTH
    rows = []
    for h in sizes:
        t0 = time.perf_counter()
        mesh = voxelize(surface, h)
        seconds = time.perf_counter() - t0
        volume = mesh.n_cells * h**3
        rows.append(
            {
                "size": h,
                "cells": mesh.n_cells,
                "nodes": mesh.n_nodes,
                "volume": volume,
                "exact": exact,
                "relative_error": (volume - exact) / exact,
                "seconds": round(seconds, 3),
            }
        )
        print(
            f"size {h:<6g} {mesh.n_cells:>8d} cells  volume {volume:.5f} "
            f"({rows[-1]['relative_error']:+.2%})  {seconds:.2f} s"
        )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="the two coarsest sizes only")
    ap.add_argument("--out", type=Path, help="write the rows as JSON here")
    args = ap.parse_args()
    rows = measure(SIZES[:2] if args.quick else SIZES)
    if args.out:
        args.out.write_text(json.dumps({"benchmark": "voxel_envelope", "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
