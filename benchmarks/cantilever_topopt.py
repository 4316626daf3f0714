"""Seconds per design iteration of the cantilever compliance optimization, split by stage.

    python benchmarks/cantilever_topopt.py --out FILE.json [--mesh coarse|fine] [--iterations 15]
        [--optimizer mma|ipopt|both] [--design density|bspline|both] [--quick]

For each parameterization (density: cone filter of radius 2 cells; bspline:
tri-cubic, one patch per two cells) and optimizer, runs the optimization for
``--iterations`` iterations from the grey design and writes, per run:
``seconds_per_iteration`` with ``primal`` (nonlinear solve), ``adjoint``
(response partials, factorization, solves, residual vjp), ``design`` (design
maps forward and vjp, volume constraint), ``optimizer`` (everything between
two iterations that is not an analysis: the MMA subproblem or IPOPT's step)
and ``iteration`` (their sum with output, none here), averaged over the
iterations after the first (which compiles); ``shares`` (each stage over the
iteration); ``analyses`` (design evaluations), ``newton_iterations``,
``n_design``, ``G_nonzeros``, ``objective_first``, ``objective_last``
(f/|f^0|) and ``volume_fraction``.
"""

from __future__ import annotations

import argparse
import json
import logging
import platform
import sys
from pathlib import Path

import numpy as np

from contopt.config import setup_jax

STAGES = ("primal", "adjoint", "design", "optimizer", "output", "iteration")


def run_one(design: str, optimizer: str, mesh: str, iterations: int) -> dict:
    from contopt.cases.optimization import optimization_case
    from contopt.optimize.driver import OutputOptions, optimize
    from contopt.optimize.ipopt import IpoptOptions
    from contopt.optimize.mma import MMAOptions

    problem = optimization_case("cantilever", design=design, mesh=mesh)
    # no early stop: every run makes the same number of iterations
    options = (
        MMAOptions(max_iter=iterations, kkt_tol=1e-12, change_tol=0.0)
        if optimizer == "mma"
        else IpoptOptions(max_iter=iterations, tol=1e-12)
    )
    res = optimize(problem, optimizer, options, outputs=OutputOptions(vtu="none", plot=False))
    rows = res.history[1:] or res.history
    per_it = {k: float(np.mean([r["seconds"][k] for r in rows])) for k in STAGES}
    return {
        "design": design,
        "optimizer": optimizer,
        "mesh": mesh,
        "iterations": res.iterations,
        "analyses": res.analyses,
        "newton_iterations": int(sum(r["newton_iterations"] for r in res.history)),
        "n_design": res.design_summary[0]["n_design"],
        "G_nonzeros": res.design_summary[0]["G_nonzeros"],
        "n_cells": res.design_summary[0]["n_cells"],
        "seconds_per_iteration": per_it,
        "shares": {k: per_it[k] / per_it["iteration"] for k in STAGES if k != "iteration"},
        "first_iteration_seconds": res.history[0]["seconds"]["iteration"],
        "objective_first": res.history[0]["objective"],
        "objective_last": res.normalized_objective,
        "volume_fraction": float(res.volume_fractions[0]),
        "status": res.status,
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True)
    p.add_argument("--mesh", choices=["coarse", "fine"], default="coarse")
    p.add_argument("--iterations", type=int, default=15)
    p.add_argument("--optimizer", choices=["mma", "ipopt", "both"], default="both")
    p.add_argument("--design", choices=["density", "bspline", "both"], default="both")
    p.add_argument(
        "--quick",
        action="store_true",
        help="the smallest run, seconds: what tests/benchmarks/test_quick.py runs (density, MMA, 2 iterations)",
    )
    args = p.parse_args(argv)
    if args.quick:
        args.mesh, args.iterations, args.optimizer, args.design = "coarse", 2, "mma", "density"
    logging.basicConfig(level=logging.WARNING)
    setup_jax()
    designs = ("density", "bspline") if args.design == "both" else (args.design,)
    optimizers = ("mma", "ipopt") if args.optimizer == "both" else (args.optimizer,)
    runs = []
    for design in designs:
        for optimizer in optimizers:
            r = run_one(design, optimizer, args.mesh, args.iterations)
            s = r["seconds_per_iteration"]
            print(
                f"{design:8s} {optimizer:5s} n_d {r['n_design']:5d} nnz(G) {r['G_nonzeros']:7d}  "
                f"s/it {s['iteration']:.3f} = primal {s['primal']:.3f} + adjoint {s['adjoint']:.3f} + "
                f"design {s['design']:.4f} + optimizer {s['optimizer']:.4f}  "
                f"f/|f0| {r['objective_first']:.4g} -> {r['objective_last']:.4g}",
                file=sys.stderr,
            )
            runs.append(r)
    out = {"benchmark": "cantilever_topopt", "machine": platform.platform(), "runs": runs}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
