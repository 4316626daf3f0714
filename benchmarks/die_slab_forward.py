"""The paper's die-slab forward problem (section 7.1 geometry, full material).

    python benchmarks/die_slab_forward.py --mesh coarse|fine --out FILE.json [--steps 6] [--vtu DIR] [--quick]
        [--die-element hex8|tet4|tet10]

Writes JSON with ``load_steps``, ``newton_iterations_total`` (every attempt,
cut-back ones included; ``newton_iterations_in_failed_attempts`` of them), ``alm_updates``,
``contact_force`` (total, on the slab), ``strain_energy`` (slab),
``peak_memory_mb``, ``factor_reuse`` (``--factor-reuse on|off``, default off as in the library: the kept factor's
GMRES solves, iterations and refactorizations), ``seconds`` (totals: ``kernels``, ``contact`` = search +
segmentation + mortar kernels + contact assembly, ``scatter``, ``factorize``,
``solve``) and ``contact_overhead_ratio`` = contact seconds per Newton
iteration / factorize seconds per Newton iteration, all measured after
compilation (``compile_seconds``, reported apart). The paper needed 6 load
steps, 100 Newton iterations and 18 multiplier updates.

Adjoint of the slab's strain energy (the paper's ``f_a``) at the converged
state, reusing the converged tangent: ``adjoint_seconds`` (evaluation of the
response partials, factorization, solves, residual vjp; after compilation),
``adjoint_linear_solves``, ``adjoint_ratio`` = adjoint seconds / primal
seconds (wall), for the default method, and ``adjoint_methods`` with the
same figures for each saddle-point method (``schur-cg``, ``uzawa``,
``direct``). The paper needed 5 linear solves per adjoint. ``--quick``: the coarse mesh and the default
adjoint method only (what tests/benchmarks/test_quick.py runs).
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

from contopt.config import setup_jax


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--mesh", choices=["coarse", "fine"], default="coarse")
    p.add_argument("--out", required=True)
    p.add_argument("--steps", type=int, default=6)
    p.add_argument("--law", choices=["alm", "penalty"], default="alm")
    p.add_argument("--eps", type=float, default=None)
    p.add_argument(
        "--die",
        choices=["fitted", "resting"],
        default="fitted",
        help="the files' die (fitted to the paper's |f_a^0|) or the earlier one resting on the slab (docs/die.md)",
    )
    p.add_argument(
        "--die-element",
        choices=["hex8", "tet4", "tet10"],
        default="hex8",
        help="the die's elements: the file's hex8, or each hex cut into six tets (docs/cad.md, Tetrahedra)",
    )
    p.add_argument("--vtu", default=None, help="also write VTU/PVD per load step into this directory")
    p.add_argument("-q", "--quiet", action="store_true", help="no per-step log on stderr")
    p.add_argument(
        "--factor-reuse",
        choices=["on", "off"],
        default="off",
        help="precondition GMRES with the kept factor of an earlier tangent (LinearSolverOptions.factor_reuse)",
    )
    p.add_argument("--quick", action="store_true", help="the coarse mesh, the default adjoint method only")
    args = p.parse_args(argv)
    if args.quick:
        args.mesh = "coarse"
    import logging

    logging.basicConfig(level=logging.WARNING if args.quiet else logging.INFO, format="%(asctime)s %(message)s")
    for noisy in ("jax", "absl"):
        logging.getLogger(noisy).setLevel(logging.WARNING)
    setup_jax()
    from contopt.cases.die_slab import die_slab
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    model = die_slab(args.mesh, law=args.law, eps=args.eps, die=args.die, die_element=args.die_element)
    system = System.of(model)
    on_step = None
    if args.vtu:
        from contopt.io.vtk import PVDSeries, write_state

        series = PVDSeries(Path(args.vtu) / "die_slab.pvd")
        count = [0]

        def on_step(state):
            count[0] += 1
            lam = tuple(r.lam for r in state.contact)
            fields = system.contact.pressure_fields(lam, model.bodies, [b.node_offset for b in system.disc.blocks])
            write_state(args.vtu, system.disc, state.u, state.rho, state.t, count[0], series, extra_point_data=fields)

    # compilation (or loading from the persistent cache) is reported on its own, so that
    # the per-iteration figures are steady-state ones
    from contopt.contact.mortar import precompile

    t0 = time.perf_counter()
    precompile()
    system.evaluate(np.zeros(system.disc.n_dofs), 0.0, system.disc.layout(), system.start_states())
    compile_seconds = time.perf_counter() - t0
    t0 = time.perf_counter()
    from contopt.solve.linear import LinearSolverOptions, reuse

    linear = LinearSolverOptions(factor_reuse=args.factor_reuse == "on")
    state = solve_static(system, newton=NewtonOptions(n_steps=args.steps), linear=linear, on_step=on_step)
    wall = time.perf_counter() - t0
    sec = state.seconds
    its = sum(lg.iterations for lg in state.logs)  # failed attempts (cut back) included: they cost time too
    lam = tuple(r.lam for r in state.contact)
    slab_energy = float(system.disc.strain_energy(state.u, per_cell=True)[system.disc.cell_slice("slab")].sum())
    result = {
        "mesh": args.mesh,
        "die": args.die,
        "die_element": args.die_element,
        "dofs": int(system.disc.n_dofs),
        "law": args.law,
        "eps": system.contact.blocks[0].eps,
        "load_steps": len({round(lg.t, 12) for lg in state.logs if lg.converged}),
        "newton_iterations_total": its,
        "newton_iterations_in_failed_attempts": its - state.newton_iterations,
        "alm_updates": state.alm_updates,
        "contact_force": float(system.contact.total_force(state.u, lam).sum()),
        "strain_energy": slab_energy,
        "active_nodes": int(sum(r.n_active for r in state.contact)),
        "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "seconds": {k: sec.get(k, 0.0) for k in ("kernels", "contact", "check", "scatter", "factorize", "solve")},
        "wall_seconds": wall,
        "compile_seconds": compile_seconds,
        "contact_overhead_ratio": sec.get("contact", 0.0) / max(sec.get("factorize", 1e-300), 1e-300),
        "factor_reuse": dict(reuse.STATISTICS, on=linear.factor_reuse),
        "residual_histories": [list(lg.residuals) for lg in state.logs],
        "convergence_orders": [lg.convergence_rates for lg in state.logs if lg.converged],
    }
    result.update(_adjoint(system, state, wall, quick=args.quick))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    show = (
        "die_element",
        "dofs",
        "compile_seconds",
        "wall_seconds",
        "load_steps",
        "newton_iterations_total",
        "alm_updates",
        "contact_force",
        "strain_energy",
        "seconds",
        "contact_overhead_ratio",
        "factor_reuse",
        "peak_memory_mb",
        "adjoint_seconds",
        "adjoint_linear_solves",
        "adjoint_ratio",
        "adjoint_methods",
    )
    print(json.dumps({k: result[k] for k in show}, indent=2))
    return 0


def _adjoint(system, state, primal_seconds: float, quick: bool = False) -> dict:
    from contopt.adjoint import AdjointOptions, sensitivities
    from contopt.responses import StrainEnergy

    response = StrainEnergy(bodies="slab")
    t0 = time.perf_counter()
    sensitivities(system, state, response)  # compiles the response and vjp kernels
    compile_seconds = time.perf_counter() - t0
    methods = {}
    for method in (AdjointOptions().method,) if quick else ("schur-cg", "uzawa", "direct"):
        t0 = time.perf_counter()
        res = sensitivities(system, state, response, AdjointOptions(method=method))
        seconds = time.perf_counter() - t0
        methods[method] = {
            "seconds": seconds,
            "linear_solves": res.linear_solves,
            "factorizations": res.factorizations,
            "iterations": res[0].iterations,
            "constraint_residual": res[0].residual,
            "ratio": seconds / primal_seconds,
            "by_phase": res.seconds,
        }
    default = methods[AdjointOptions().method]
    return {
        "adjoint_method": AdjointOptions().method,
        "adjoint_seconds": default["seconds"],
        "adjoint_linear_solves": default["linear_solves"],
        "adjoint_ratio": default["ratio"],
        "adjoint_compile_seconds": compile_seconds,
        "adjoint_active_nodes": int(sum(res.active)),
        "adjoint_methods": methods,
    }


if __name__ == "__main__":
    sys.exit(main())
