"""Surfaces of the bundled cases' coarse runs: volume against the design's, time to export, a figure.

    python benchmarks/design_surfaces.py --runs DIR [--out bench-out/design_surfaces.json]
        [--figure docs/figures/design-surfaces.png] [--only NAME,...] [--quick]

For each coarse case (``die-slab`` B-spline and density, ``die-cantilever`` B-spline and density,
``die-slab-contact-force``, ``sabot``, ``cantilever``) it optimizes into ``DIR/NAME`` unless that
directory already holds a finished run (``summary.json``), then exports the design's surface
(:func:`contopt.cases.export.export_design`, default options, and the sabot mirrored across
z = 0 as the whole part) and records per run (``runs``): the enclosed ``volume``, the
``design_volume`` (the design's volume fraction times the domain volume), their
``relative_difference``, the ``grey_share``, ``triangles``, whether the surface is ``watertight``
and ``manifold``, and the seconds the export took (``seconds_export``, rebuilding the problem
included) and the surface alone (``seconds_surface``). The figure shows the die-slab's column
(``make demo``) and the whole sabot. ``--quick``: the cantilever's density run after one MMA
iteration only (what tests/benchmarks/test_quick.py runs).
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

#: name -> (case, design, export options as SurfaceOptions keywords)
RUNS = {
    "die-slab-bspline": ("die-slab", "bspline", {}),
    "die-slab-density": ("die-slab", "density", {}),
    "die-cantilever-bspline": ("die-cantilever", "bspline", {}),
    "die-cantilever-density": ("die-cantilever", "density", {}),
    "die-slab-contact-force-bspline": ("die-slab-contact-force", "bspline", {}),
    "sabot-bspline": ("sabot", "bspline", {}),
    "sabot-bspline-whole": ("sabot", "bspline", {"mirror": (("z", 0.0),)}),
    "cantilever-density": ("cantilever", "density", {}),
}


def ensure_run(runs: Path, name: str, case: str, design: str, extra: tuple[str, ...] = ()) -> Path:
    """The run directory of a case, optimized first if it holds no finished run."""
    out = runs / name.removesuffix("-whole")
    if not (out / "summary.json").exists():
        cmd = [
            sys.executable,
            "-m",
            "contopt.cli",
            "-q",
            "run",
            case,
            "--mesh",
            "coarse",
            "--design",
            design,
            "--out",
            str(out),
            "--overwrite",
            *extra,
        ]
        subprocess.run(cmd, check=True)
    return out


def export_one(run_dir: Path, target: Path, options: dict) -> dict:
    from contopt.cases.export import export_design
    from contopt.design.surface import SurfaceOptions
    from contopt.io.surface import check_surface

    started = time.perf_counter()
    result = export_design(run_dir, target, SurfaceOptions(**options))
    seconds = time.perf_counter() - started
    (s,) = result.surfaces
    chk = check_surface(s.surface)
    return {
        "run": str(run_dir),
        "file": str(target),
        "options": {k: list(v) for k, v in options.items()},
        "iteration": result.iteration,
        "volume": s.volume,
        "design_volume": s.design_volume,
        "relative_difference": s.relative_difference,
        "grey_share": s.grey_volume / s.design_volume,
        "triangles": s.surface.n_faces,
        "lattice": list(s.lattice),
        "copies": s.copies,
        "watertight": chk.watertight,
        "manifold": chk.manifold and chk.oriented,
        "components": chk.components,
        "seconds_export": seconds,
        "seconds_surface": s.seconds,
    }


def figure(runs: Path, path: Path) -> None:
    """Two pictures side by side: the die-slab's design.stl and the whole sabot (refine 6)."""
    import matplotlib.image as mpimg
    import numpy as np

    from contopt.cases.export import export_design
    from contopt.design.surface import SurfaceOptions
    from contopt.io.render import render_surface

    panels = []
    for name, options, title in (
        ("die-slab-bspline", SurfaceOptions(), "die-slab (make demo): design.stl"),
        (
            "sabot-bspline",
            SurfaceOptions(refine=6, mirror=(("z", 0.0),)),
            "sabot: whole part (5-fold cyclic + reflection, mirrored at z = 0)",
        ),
    ):
        result = export_design(runs / name, runs / f"{name}-figure.stl", options)
        png = runs / f"{name}-figure.png"
        (s,) = result.surfaces
        render_surface([s.surface], png, size=(900, 700), title=title, boxes=[s.bounds])
        panels.append(mpimg.imread(png)[..., :3])
    path.parent.mkdir(parents=True, exist_ok=True)
    mpimg.imsave(path, np.concatenate(panels, axis=1))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", required=True, help="folder of the run directories (made when missing)")
    p.add_argument("--out", default="bench-out/design_surfaces.json")
    p.add_argument("--figure", default=None, help="also draw the docs figure into this PNG")
    p.add_argument("--only", default=None, help="comma-separated names of " + ", ".join(RUNS))
    p.add_argument("--quick", action="store_true", help="cantilever-density after one iteration only")
    args = p.parse_args(argv)
    from contopt.config import setup_jax

    setup_jax()
    runs = Path(args.runs)
    names = ["cantilever-density"] if args.quick else args.only.split(",") if args.only else list(RUNS)
    extra = ("--max-iter", "1", "--vtu", "none", "--no-plot") if args.quick else ()
    results = {}
    for name in names:
        case, design, options = RUNS[name]
        run_dir = ensure_run(runs, name, case, design, extra)
        results[name] = export_one(run_dir, runs / f"{name}.stl", options)
        r = results[name]
        print(
            f"{name}: volume {r['volume']:.6g} vs {r['design_volume']:.6g} ({r['relative_difference']:+.2%}), "
            f"grey {r['grey_share']:.1%}, {r['triangles']} triangles, watertight {r['watertight']}, "
            f"manifold {r['manifold']}, export {r['seconds_export']:.1f} s (surface {r['seconds_surface']:.2f} s)",
            flush=True,
        )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"machine": platform.platform(), "runs": results}, indent=1))
    if args.figure:
        figure(runs, Path(args.figure))
    return 0


if __name__ == "__main__":
    sys.exit(main())
