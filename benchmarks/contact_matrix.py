"""A matrix of users' contact problems, measured (issue 35 §5; :mod:`contopt.cases.contact_matrix`).

    python benchmarks/contact_matrix.py --out bench-out/contact_matrix.json [--subset fast|all]
        [--geometries flat-punch cylinder ...] [--ratios 1 1e4] [--budget 300] [--markdown FILE]
        [--quick]

Grid: E ratio of the tool to the soft body x the soft body's nu x law (penalty, alm) x nonmortar
side (soft, tool) x geometry. Each cell runs in a worker process within ``--budget`` seconds of wall
(over it: "timed out"). Writes JSON (``machine``, ``cells``: one dict per cell, see
:func:`contopt.cases.contact_matrix.run_cell`: ``converged``, ``newton_iterations``, ``wall_seconds``, ...),
rewritten after every cell so that a run cut short
keeps what it measured, prints a short table and, with ``--markdown``, writes it as markdown.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

COLUMNS = ("geometry", "E ratio", "nu", "law", "nonmortar", "result", "Newton it", "updates", "wall s",
           "pen/h", "force vs R", "spread")  # fmt: skip


def _g(x, fmt="{:.1e}") -> str:
    return "-" if x is None else fmt.format(x)


def row(r: dict) -> list[str]:
    """One cell's table row; a failure shows the first words of its error."""
    if r["converged"]:
        result = "converged"
    else:
        words = r["error"].split(":", 1)[-1].split()
        result = " ".join(words[:8]) + (" ..." if len(words) > 8 else "")
    its = r.get("newton_iterations")
    conv = r.get("newton_iterations_converged")
    return [
        r["geometry"],
        f"{r['ratio']:g}",
        f"{r['nu']:g}",
        r["law"],
        r["nonmortar"],
        result,
        "-" if its is None else f"{its} ({conv})" if its != conv else str(its),
        str(r.get("alm_updates", "-")),
        f"{r['wall_seconds']:.1f}",
        _g(r.get("penetration_over_h"), "{:.2g}"),
        _g(r.get("force_vs_reaction")),
        _g(r.get("pressure_spread"), "{:.2f}"),
    ]


def markdown(results: list[dict]) -> str:
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(row(r)) + " |" for r in results]
    lines.append("")
    lines.append(
        "Newton it: all iterations (those of converged solves in brackets where fewer); pen/h: deepest "
        "pointwise penetration over the nonmortar facet size; force vs R: relative difference of the "
        "force the interfaces transmit and the held body's reaction; spread: std/mean of the fully "
        "covered active pressures where the pressure should be uniform."
    )
    return "\n".join(lines) + "\n"


def machine() -> dict:
    return {
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "processor": platform.processor(),
        "cpus": os.cpu_count(),
        "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
    }


def main(argv=None) -> int:
    from contopt.cases import contact_matrix as cm

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True)
    p.add_argument("--subset", choices=["fast", "all"], default="all")
    p.add_argument("--geometries", nargs="+", choices=cm.GEOMETRIES, default=None)
    p.add_argument("--ratios", nargs="+", type=float, default=None)
    p.add_argument("--nus", nargs="+", type=float, default=None)
    p.add_argument("--budget", type=float, default=300.0, help="wall seconds per cell")
    p.add_argument("--markdown", default=None)
    p.add_argument(
        "--quick",
        action="store_true",
        help="the smallest run, seconds: what tests/benchmarks/test_quick.py runs (the fast subset's first cell)",
    )
    args = p.parse_args(argv)
    if args.quick:
        cells = cm.fast_subset()[:1]
    elif args.subset == "fast":
        cells = [c for c in cm.fast_subset() if args.geometries is None or c.geometry in args.geometries]
    else:
        cells = cm.grid(
            geometries=args.geometries or cm.GEOMETRIES, ratios=args.ratios or cm.RATIOS, nus=args.nus or cm.NUS
        )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    info = machine()
    results: list[dict] = []
    t0 = time.perf_counter()

    def on_result(r):
        results.append(r)
        out.write_text(json.dumps({"machine": info, "budget_seconds": args.budget, "cells": results}, indent=2))
        print(" | ".join(row(r)), flush=True)

    print(" | ".join(COLUMNS), flush=True)
    cm.run_cells(cells, budget=args.budget, on_result=on_result)
    failed = sum(not r["converged"] for r in results)
    print(f"{len(results)} cells, {failed} not converged, {time.perf_counter() - t0:.0f} s", flush=True)
    if args.markdown:
        Path(args.markdown).write_text(markdown(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
