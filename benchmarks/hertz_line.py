"""Hertz line contact at the size of Kratos Multiphysics' mesh (issue 41 §1, issue 35 §3).

    python benchmarks/hertz_line.py --out bench-out/hertz_line.json [--law penalty|alm|both] [--quick] [--h H]
        [--steps 5] [--watchdog N] [--active-set N] [--solver auto|pardiso|amg] [--log debug]

A cylinder (R = 1, E = 1000) pressed 0.02 onto a block (E = 1), nu = 0.3, plane strain through a
slab one cell thick: tests/contact/_hertz.py ``hertz_model`` (tests/contact/_meshing.py
``cylinder_on_block``) with cells of h = 0.00305 near the contact, 8,216 hex8 cells and 33,128
equations, the size of Kratos' Hertz line-contact mesh (about 8,200 cells, 33k equations);
``--quick``: h = 0.02 (802 cells, a few seconds once compiled); tests/contact/test_hertz.py's mesh
is h = 0.0075. Laws: penalty ``100 E*/h`` and the augmented Lagrangian with its defaults
(``10 E*/h``, multipliers to 1e-6), each in ``--steps`` load steps of the quadratic load path.

Per law the JSON holds ``newton_iterations`` (converged solves), ``newton_iterations_all`` (failed
attempts included), ``iterations_per_step`` (per converged load step, its solves' iterations),
``solves`` (every Newton solve: t, dt, iterations, converged, residuals, line-search alphas),
``multiplier_updates`` (ALM), ``seconds_per_phase`` (every phase the Newton logs time, summed over
all solves, and ``wall``), ``ratio_to_factorize``, ``peak_rss_mb`` (``ru_maxrss`` after the solve:
the process' peak so far), ``solver`` (the backend asked for; ``amg`` is CG + GAMG),
``krylov_iterations`` (summed over the solves) and ``petsc`` (the AMG's counters: set-ups, solves,
fall-backs to a factorization; empty where PETSc was not loaded), ``n_cells``, ``n_equations``,
``contact_force`` (the pressure resultant per unit length) and ``hertz`` (tests/contact/_hertz.py
``hertz_errors``: peak pressure and half-width against plane-strain Hertz for that load). A solve
that fails is reported, not raised: ``error`` says why, ``t`` the load it reached, the rest counts
the solves up to the failure. The first run compiles the kernels (counted in their phases); with the
persistent compilation cache a second run is the one to time.
"""

from __future__ import annotations

import argparse
import json
import logging
import platform
import resource
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from contopt.config import setup_jax

ROOT = Path(__file__).resolve().parents[1]
#: h near the contact: Kratos' size (8,216 cells, 33,128 equations) and --quick's (802 cells)
H_FULL, H_QUICK = 0.00305, 0.02


def _petsc_statistics() -> dict:
    """The AMG's counters (set-ups, solves, fall-backs to a factorization) where PETSc was loaded."""
    module = sys.modules.get("contopt.solve.linear.petsc")
    return dict(module.STATISTICS) if module is not None else {}


def run(law_name: str, h: float, newton, solver: str = "auto") -> dict:
    """Solve the Hertz model with cells of ``h``, the law ``law_name`` and the linear-solver backend
    ``solver`` (``amg`` is ``petsc``); its row of the JSON."""
    sys.path.insert(0, str(ROOT / "tests" / "contact"))
    from _hertz import E_STAR, hertz_errors, hertz_model

    from contopt.contact.laws import AugmentedLagrangian, Penalty
    from contopt.errors import ConvergenceError
    from contopt.solve.linear import LinearSolverOptions
    from contopt.solve.static import State, solve_static
    from contopt.solve.system import System

    law = Penalty(eps=100.0 * E_STAR / h) if law_name == "penalty" else AugmentedLagrangian(eps=10.0 * E_STAR / h)
    model, h_cyl = hertz_model(h, law)
    system = System.of(model)
    disc = system.disc
    t0 = time.perf_counter()
    error = ""
    try:
        linear = LinearSolverOptions(backend="petsc" if solver == "amg" else solver)
        state = solve_static(system, newton=newton, linear=linear)
    except ConvergenceError as err:  # reported with the solves up to the failure, not raised
        error, state = str(err), replace(err.last_state or State(u=np.zeros(disc.n_dofs), t=0.0), logs=tuple(err.logs))
    wall = time.perf_counter() - t0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    seconds = {k: round(v, 3) for k, v in state.seconds.items()} | {"wall": round(wall, 2)}
    per_step: dict[float, int] = {}
    for lg in state.logs:
        if lg.converged:
            per_step[lg.t] = per_step.get(lg.t, 0) + lg.iterations
    hertz = None if error else hertz_errors(system, model, state, h, h_cyl)
    return {
        "law": law_name,
        "solver": solver,
        "krylov_iterations": int(sum(sum(lg.krylov) for lg in state.logs)),
        "petsc": _petsc_statistics(),
        "error": error,
        "eps": law.eps,
        "h": h,
        "n_cells": int(disc.n_cells),
        "n_dofs": int(disc.n_dofs),
        "n_equations": int(disc.free.size),
        "t": state.t,
        "load_steps": len(per_step),
        "newton_iterations": int(state.newton_iterations),
        "newton_iterations_all": int(sum(lg.iterations for lg in state.logs)),
        # with the active-set prediction, its extra factorizations counted (else one an iteration)
        "factorizations_all": int(sum(lg.extra.get("factorizations", lg.iterations) for lg in state.logs)),
        "iterations_per_step": list(per_step.values()),
        "multiplier_updates": int(state.alm_updates) if law_name == "alm" else None,
        "solves": [
            {
                "t": lg.t,
                "dt": lg.dt,
                "iterations": lg.iterations,
                "converged": lg.converged,
                "message": lg.message,
                "residuals": list(lg.residuals),
                "alphas": list(lg.alphas),
            }
            for lg in state.logs
        ],
        "seconds_per_phase": seconds,
        "ratio_to_factorize": {k: round(v / max(seconds["factorize"], 1e-12), 3) for k, v in seconds.items()},
        "peak_rss_mb": round(rss, 1),
        "contact_force": None if hertz is None else hertz["force"],
        "hertz": hertz,
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="JSON file to write")
    p.add_argument("--law", choices=["penalty", "alm", "both"], default="both")
    p.add_argument("--quick", action="store_true", help=f"the smallest mesh (h = {H_QUICK})")
    p.add_argument("--h", type=float, default=None, help=f"cell size near the contact (default {H_FULL})")
    p.add_argument("--steps", type=int, default=5, help="load steps")
    p.add_argument("--watchdog", type=int, default=None, help="NewtonOptions.watchdog (default: its default)")
    p.add_argument("--active-set", type=int, default=None, help="NewtonOptions.active_set (default: its default)")
    p.add_argument("--solver", choices=["auto", "pardiso", "amg"], default="auto", help="linear-solver backend")
    p.add_argument("--log", default=None, help="log level of contopt (debug: Newton's residuals and watchdog)")
    args = p.parse_args(argv)
    if args.log:
        logging.basicConfig(format="%(relativeCreated)9.0f ms %(name)s: %(message)s")
        logging.getLogger("contopt").setLevel(args.log.upper())
    setup_jax()
    from contopt.solve.newton import NewtonOptions

    newton = NewtonOptions(n_steps=args.steps)
    if args.watchdog is not None:
        newton = NewtonOptions(n_steps=args.steps, watchdog=args.watchdog)
    if args.active_set is not None:
        newton = replace(newton, active_set=args.active_set)
    h = args.h or (H_QUICK if args.quick else H_FULL)
    laws = ["penalty", "alm"] if args.law == "both" else [args.law]
    result = {
        "h": h,
        "steps": args.steps,
        "watchdog": getattr(newton, "watchdog", None),  # None: a version before the watchdog
        "active_set": getattr(newton, "active_set", None),
        "solver": args.solver,
        "laws": {law: run(law, h, newton, args.solver) for law in laws},
        "machine": {"python": sys.version.split()[0], "platform": platform.platform()},
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1))
    for r in result["laws"].values():
        s, hz = r["seconds_per_phase"], r["hertz"]
        print(
            f"{r['law']}: {r['n_cells']} cells, {r['n_equations']} equations; Newton {r['newton_iterations']} "
            f"({'/'.join(map(str, r['iterations_per_step']))}; all {r['newton_iterations_all']}, "
            f"factorizations {r['factorizations_all']})"
            + (f", {r['multiplier_updates']} multiplier updates" if r["multiplier_updates"] is not None else "")
            + f"; wall {s['wall']:.1f} s, factorize {s['factorize']:.1f} s, peak RSS {r['peak_rss_mb']:.0f} MB"
        )
        print("  seconds: " + ", ".join(f"{k} {v:.2f}" for k, v in s.items()))
        if r["error"]:
            print(f"  FAILED at t = {r['t']:.4g}: {r['error']}")
            continue
        print(
            f"  force {r['contact_force']:.6e}; Hertz p0 {hz['p0_hertz']:.5g} a {hz['a_hertz']:.5g}; "
            f"peak {hz['peak']:+.2%}, a_fit {hz['a_fit']:+.2%}, p0_fit {hz['p0_fit']:+.2%}, "
            f"a_mom {hz['a_mom']:+.2%}, rms {hz['rms']:.2%}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
