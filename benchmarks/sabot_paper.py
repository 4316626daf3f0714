"""The paper-size sabot (7.4: 10,780 / 46,816 / 13,552 cells): size, memory and the first analysis.

    python benchmarks/sabot_paper.py [--mesh fine|coarse] [--seconds 900] [--factor-reuse on|off]
        [--solver auto|pardiso|amg]
        [--factor-precision double|single] [--out bench-out/sabot_paper.json] [--quick]

Builds the case, its design space and the grey start, then solves the first analysis (cold, the
case's load steps) and its adjoint, and records: dofs, cells, nonzeros of the tangent and of G,
seconds to build, per load step, per phase of Newton (``seconds_by_phase``: element kernels,
scatter, factorize, solve, contact) and for the adjoint (``adjoint_seconds``), the backend (``solver``),
the Krylov iterations and the AMG's counters where it ran (``krylov_iterations``, ``petsc``), and the peak resident
memory (``peak_mb``: ``ru_maxrss``). The analysis runs in a child process stopped after ``--seconds``; the JSON says
whether it finished and how far it got (the peak memory is reached with the first factorization,
since the pattern, hence the fill-in, is the same for every Newton iteration). ``--quick``: the coarse
mesh (what tests/benchmarks/test_quick.py runs).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import resource
import sys
import time
from dataclasses import replace
from pathlib import Path


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _hwm_mb(pid: int) -> float:
    """The child's peak resident memory so far (Linux /proc; 0 where unavailable)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


def _analysis(
    mesh: str, queue, factor_reuse: bool = False, precision: str | None = None, solver: str | None = None
) -> None:
    import logging

    logging.basicConfig(level=logging.WARNING)
    logging.getLogger("contopt.solve.linear").setLevel(logging.INFO)  # the solver's choices and fall-backs
    from contopt.config import setup_jax

    setup_jax()
    from contopt.adjoint.sensitivity import sensitivities
    from contopt.cases.optimization import optimization_case
    from contopt.optimize.problem import DesignNLP
    from contopt.solve.static import solve_static

    t0 = time.perf_counter()
    problem = optimization_case("sabot", mesh=mesh)
    nlp = DesignNLP(problem)
    fields = nlp.space.forward(nlp.space.initial())
    disc = nlp.system.disc
    info = {
        "mesh": mesh,
        "cells": {b.name: b.mesh.n_cells for b in problem.model.bodies},
        "dofs": disc.n_dofs,
        "free_dofs": int(disc.free.size),
        "n_design": nlp.n,
        "G_nonzeros": nlp.space.summary()[0]["G_nonzeros"],
        "tangent_nonzeros": disc.pattern.nnz,
        "build_seconds": time.perf_counter() - t0,
        "peak_mb_after_build": _peak_mb(),
    }
    queue.put(("info", info))
    steps = []

    def on_step(state):
        steps.append(
            {
                "t": state.t,
                "newton": state.newton_iterations,
                "seconds": time.perf_counter() - t1,
                "peak_mb": _peak_mb(),
            }
        )
        queue.put(("step", steps[-1]))

    linear = replace(problem.linear, factor_reuse=factor_reuse)
    if precision is not None:
        linear = replace(linear, factor_precision=precision)
    if solver is not None:
        linear = replace(linear, backend="petsc" if solver == "amg" else solver)
    t1 = time.perf_counter()
    state = solve_static(
        nlp.system,
        fields.rho,
        newton=problem.newton,
        linear=linear,
        augmentation=problem.augmentation,
        mass=fields.nu,
        on_step=on_step,
    )
    primal = time.perf_counter() - t1
    phases: dict = {}
    for lg in state.logs:  # Newton's own timing of each phase, summed over the solves
        for k, v in lg.seconds.items():
            phases[k] = phases.get(k, 0.0) + v
    t2 = time.perf_counter()
    adj = sensitivities(nlp.system, state, [problem.objective], problem.adjoint, linear)
    queue.put(
        (
            "done",
            {
                "primal_seconds": primal,
                "newton_iterations": state.newton_iterations,
                "alm_updates": state.alm_updates,
                "seconds_by_phase": phases,
                "newton_by_solve": [[lg.t, lg.iterations] for lg in state.logs],
                "factor_reuse": factor_reuse,
                "factor_precision": linear.factor_precision,
                "solver": linear.backend,
                "krylov_iterations": int(sum(sum(lg.krylov) for lg in state.logs)),
                "petsc": dict(getattr(sys.modules.get("contopt.solve.linear.petsc"), "STATISTICS", {})),
                "adjoint_seconds": time.perf_counter() - t2,
                "compliance": adj.sensitivities[0].value,
                "peak_mb": _peak_mb(),
            },
        )
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--mesh", default="fine", choices=["coarse", "fine"])
    p.add_argument("--seconds", type=float, default=900.0, help="stop the analysis after this long")
    p.add_argument("--out", default="bench-out/sabot_paper.json")
    p.add_argument("--factor-reuse", choices=["on", "off"], default="off", help="LinearSolverOptions.factor_reuse")
    p.add_argument(
        "--factor-precision",
        choices=["double", "single"],
        default=None,
        help="LinearSolverOptions.factor_precision (default: the problem file's)",
    )
    p.add_argument(
        "--solver", choices=["auto", "pardiso", "amg"], default=None, help="the backend (default: the problem file's)"
    )
    p.add_argument("--quick", action="store_true", help="the coarse mesh, within 300 s")
    args = p.parse_args(argv)
    if args.quick:
        args.mesh, args.seconds = "coarse", min(args.seconds, 300.0)
    queue = mp.get_context("spawn").Queue()
    work = (args.mesh, queue, args.factor_reuse == "on", args.factor_precision, args.solver)
    proc = mp.get_context("spawn").Process(target=_analysis, args=work)
    started = time.perf_counter()
    proc.start()
    result = {"finished": False, "steps": [], "time_limit_seconds": args.seconds}
    hwm = 0.0
    while proc.is_alive() or not queue.empty():
        hwm = max(hwm, _hwm_mb(proc.pid))
        try:
            kind, data = queue.get(timeout=5.0)
        except Exception:  # queue.Empty: nothing new yet
            if time.perf_counter() - started > args.seconds:
                proc.kill()
                break
            continue
        if kind == "info":
            result.update(data)
        elif kind == "step":
            result["steps"].append(data)
        else:
            result.update(data, finished=True)
        print(kind, json.dumps(data), file=sys.stderr, flush=True)
    proc.join(timeout=10)
    result["wall_seconds"] = time.perf_counter() - started
    result["peak_mb"] = max(
        [s.get("peak_mb", 0.0) for s in result["steps"]]
        + [result.get("peak_mb", 0.0), result.get("peak_mb_after_build", 0.0), hwm]
    )
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=1))
    print(json.dumps({k: v for k, v in result.items() if k != "steps"}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
