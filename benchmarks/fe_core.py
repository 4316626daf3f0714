"""FE core benchmark: the paper's fine slab mesh (45x20x15 = 13,500 hex8) compressed to large strain.

    python benchmarks/fe_core.py --out bench-out/fe_core.json [--divisions 45 20 15] [--strain 0.3] [--quick]

Writes JSON with ``dofs``, ``newton_iterations``, ``seconds`` (per Newton
iteration: ``kernels``, ``scatter``, ``factorize``, ``solve``),
``overhead_ratio = (kernels + scatter) / factorize`` (target <= 0.5) and the
observed ``convergence_orders`` of every load step (2 = quadratic). The first
(compiling) solve is a warm-up and is not timed.
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import sys
import time
from pathlib import Path

import numpy as np

from contopt.config import setup_jax


def build(divisions, strain):
    from contopt.assembly.model import Body, Dirichlet, Model
    from contopt.material import neo_hookean
    from contopt.mesh.generators import box

    mesh = box((9.0, 4.0, 3.0), divisions)
    return Model(
        bodies=(Body("slab", mesh, neo_hookean(1.0, 0.3)),),
        dirichlet=(Dirichlet("slab", "zmin", "xyz", 0.0), Dirichlet("slab", "zmax", "xyz", (0.0, 0.0, -strain * 3.0))),
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="JSON file to write")
    p.add_argument("--divisions", type=int, nargs=3, default=[45, 20, 15])
    p.add_argument("--strain", type=float, default=0.3, help="nominal compressive strain of the slab")
    p.add_argument("--steps", type=int, default=3, help="load steps")
    p.add_argument("--solver", default="auto")
    p.add_argument(
        "--quick", action="store_true", help="a 6 x 3 x 2 slab, 1 step (seconds; tests/benchmarks/test_quick.py)"
    )
    args = p.parse_args(argv)
    if args.quick:
        args.divisions, args.steps = [6, 3, 2], 1
    setup_jax()
    from contopt.assembly.system import discretize
    from contopt.solve.linear import LinearSolverOptions, available_backends
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static

    model = build(tuple(args.divisions), args.strain)
    t0 = time.perf_counter()
    disc = discretize(model)
    t_pre = time.perf_counter() - t0
    newton = NewtonOptions(n_steps=args.steps)
    # exact solves: the orders measured are the tangent's (a kept factor solves to krylov_rtol only)
    linear = LinearSolverOptions(backend=args.solver, factor_reuse=False)
    # warm-up: compiles the kernels (the persistent cache makes later runs cheap)
    disc.evaluate(np.zeros(disc.n_dofs), 0.0)
    t0 = time.perf_counter()
    state = solve_static(disc, newton=newton, linear=linear)
    wall = time.perf_counter() - t0
    its = state.newton_iterations
    sec = state.seconds
    n_factor = its  # one factorization per Newton iteration
    per_it = {k: sec[k] / max(n_factor, 1) for k in ("kernels", "scatter", "factorize", "solve")}
    ratio = (per_it["kernels"] + per_it["scatter"]) / per_it["factorize"]
    rates = [lg.convergence_rates for lg in state.logs if lg.converged]
    result = {
        "mesh": list(args.divisions),
        "cells": int(disc.n_cells),
        "dofs": int(disc.n_dofs),
        "free_dofs": int(disc.free.size),
        "nnz_free": int(disc.free_pattern.indices.size),
        "strain": args.strain,
        "load_steps": len([lg for lg in state.logs if lg.converged]),
        "newton_iterations": its,
        "residual_histories": [list(lg.residuals) for lg in state.logs],
        "convergence_orders": rates,
        "seconds": per_it,
        "seconds_total": {**{k: sec[k] for k in per_it}, "wall": wall, "precompute": t_pre},
        "overhead_ratio": ratio,
        "solver": linear.backend if linear.backend != "auto" else available_backends()[0],
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "machine": {"python": sys.version.split()[0], "platform": platform.platform()},
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print(json.dumps({k: result[k] for k in ("dofs", "newton_iterations", "seconds", "overhead_ratio")}, indent=2))
    print("convergence orders per step:", [[round(r, 2) for r in rr] for rr in rates])
    return 0


if __name__ == "__main__":
    sys.exit(main())
