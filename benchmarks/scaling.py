"""The die-slab forward and adjoint at growing mesh sizes, direct (Pardiso) against iterative (CG + GAMG).

    python benchmarks/scaling.py --out bench-out/scaling.json [--levels coarse fine xl xxl] [--backends pardiso amg]
    python benchmarks/scaling.py --out bench-out/scaling.json --quick   # coarse, auto (tests/benchmarks/test_quick.py)

Each (level, backend) runs in a child process of its own (``--child``): the die-slab model of
``contopt forward die-slab --mesh LEVEL``, :func:`contopt.solve.static.solve_static` with
``LinearSolverOptions(backend=...)`` (``amg`` is ``petsc``; ``auto`` is the library's own choice, to
compare with the best of the others), then the adjoint of the strain energy.
The JSON is ``{level: {backend: {...}}}`` with, per run: ``dofs``, ``wall_seconds`` (forward +
adjoint, the child's own clock, imports and JAX compilation excluded), ``forward_seconds``,
``adjoint_seconds``, ``newton_iterations``, ``krylov_iterations`` (total over the forward, and
per Newton solve on average), ``preconditioner_setups``, ``peak_memory_mb`` (the child's
``ru_maxrss``: whole process), ``seconds`` (per phase: kernels, scatter, contact, factorize, solve,
adjoint), ``adjoint_phases`` (the adjoint's own: evaluate, factorize, solve, vjp, ...),
``adjoint_krylov_iterations`` and ``adjoint_solves``, ``strain_energy`` and ``contact_force``
(the two backends must agree), or ``error``.
``amg-2ranks`` runs the child under ``mpiexec -n 2`` (``peak_memory_mb`` is then per rank: the
largest of the two).
A level whose Pardiso run would not fit (``--pardiso-max-dofs``) is skipped for Pardiso.

``--one-solve`` measures instead, per level and backend, one linear solve of the die-slab's first
tangent (the bulk at u = 0, contact not yet closed), each in its own process: ``seconds``
(Pardiso: factorization + solve; CG + GAMG: matrix, set-up and solve to 1e-8), ``krylov_iterations``
and ``peak_memory_mb``: where the direct and the iterative solver cross, for ``iterative_above``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

BACKENDS = {"pardiso": "pardiso", "amg": "petsc", "amg-2ranks": "petsc", "auto": "auto"}
#: MPI ranks of each backend's runs
RANKS = {"pardiso": 1, "amg": 1, "amg-2ranks": 2, "auto": 1}


def child(level: str, backend: str, out: str) -> None:
    from contopt.config import setup_jax

    setup_jax()
    import numpy as np

    from contopt.adjoint import sensitivities
    from contopt.cases.forward import forward_case
    from contopt.parallel import world
    from contopt.responses import StrainEnergy
    from contopt.solve.linear import LinearSolverOptions
    from contopt.solve.linear import petsc as petsc_backend
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    model, n_steps = forward_case("die-slab", mesh=level)
    system = System.of(model)
    linear = LinearSolverOptions(backend=BACKENDS[backend])
    t0 = time.perf_counter()
    state = solve_static(system, newton=NewtonOptions(n_steps=n_steps), linear=linear)
    t1 = time.perf_counter()
    krylov_before = petsc_backend.STATISTICS["iterations"]
    adj = sensitivities(system, state, [StrainEnergy()], linear=linear)
    t2 = time.perf_counter()
    krylov = [sum(lg.krylov) for lg in state.logs if lg.krylov]
    seconds = {k: round(v, 3) for k, v in state.seconds.items()}
    seconds["adjoint"] = round(t2 - t1, 3)
    lam = tuple(r.lam for r in state.contact)
    result = {
        "dofs": int(system.disc.n_dofs),
        "free_dofs": int(system.disc.free.size),
        "wall_seconds": round(t2 - t0, 3),
        "forward_seconds": round(t1 - t0, 3),
        "adjoint_seconds": round(t2 - t1, 3),
        "newton_iterations": state.newton_iterations,
        "alm_updates": state.alm_updates,
        "krylov_iterations": int(sum(krylov)),
        "krylov_per_newton": round(sum(krylov) / max(state.newton_iterations, 1), 2),
        "preconditioner_setups": petsc_backend.STATISTICS["setups"],
        "ranks": world().size,
        "peak_memory_mb": round(_peak_per_rank_mb(), 1),
        "seconds": seconds,
        "adjoint_phases": {k: round(v, 3) for k, v in adj.seconds.items()},
        "adjoint_krylov_iterations": petsc_backend.STATISTICS["iterations"] - krylov_before,
        "adjoint_solves": adj.linear_solves,
        "strain_energy": float(system.disc.strain_energy(state.u, state.rho)),
        "contact_force": np.asarray(system.contact.total_force(state.u, lam)).tolist(),
        "strain_energy_adjoint": float(adj.sensitivities[0].value),
    }
    if world().rank == 0:
        with open(out, "w") as f:
            json.dump(result, f, indent=2)


def child_one_solve(level: str, backend: str, out: str) -> None:
    from contopt.config import setup_jax

    setup_jax()
    import numpy as np

    from contopt.cases.forward import forward_case
    from contopt.solve.linear import factorize
    from contopt.solve.system import System

    system = System.of(forward_case("die-slab", mesh=level)[0])
    disc = system.disc
    ev = disc.evaluate(np.zeros(disc.n_dofs), 0.0)
    K = ev.K_free
    b = np.random.default_rng(0).standard_normal(K.shape[0])
    t0 = time.perf_counter()
    f = factorize(K, BACKENDS[backend], system.geometry())
    x = f.solve(b, rtol=1e-8)
    seconds = time.perf_counter() - t0
    result = {
        "free_dofs": int(K.shape[0]),
        "seconds": round(seconds, 3),
        "krylov_iterations": int(sum(f.info.get("iterations", []))),
        "relative_residual": float(np.linalg.norm(K @ x - b) / np.linalg.norm(b)),
        "peak_memory_mb": round(_peak_per_rank_mb(), 1),
    }
    with open(out, "w") as fh:
        json.dump(result, fh, indent=2)


def _peak_per_rank_mb() -> float:
    """The largest peak resident memory of the ranks (the process's own in a serial run)."""
    from contopt.parallel import world

    comm = world()
    peaks = [0.0] * comm.size
    peaks[comm.rank] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return float(max(comm.sum(peaks)))


def run(level: str, backend: str, timeout: float, mode: str = "--child") -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "r.json")
        cmd = [sys.executable, __file__, mode, level, backend, out]
        if RANKS[backend] > 1:
            cmd = [os.path.join(os.path.dirname(sys.executable), "mpiexec"), "-n", str(RANKS[backend]), *cmd]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return {"error": f"did not finish in {timeout:.0f} s"}
        if proc.returncode != 0 or not os.path.exists(out):
            return {"error": proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else f"exit {proc.returncode}"}
        with open(out) as f:
            return json.load(f)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=False)
    ap.add_argument("--levels", nargs="+", default=["coarse", "fine", "xl", "xxl"])
    ap.add_argument("--backends", nargs="+", default=list(BACKENDS), choices=list(BACKENDS))
    ap.add_argument("--pardiso-max-dofs", type=int, default=400_000, help="skip Pardiso above this (memory)")
    ap.add_argument("--timeout", type=float, default=3600.0, help="seconds per run")
    ap.add_argument("--one-solve", action="store_true", help="one linear solve per level and backend (see above)")
    ap.add_argument("--child", nargs=3, metavar=("LEVEL", "BACKEND", "OUT"), help=argparse.SUPPRESS)
    ap.add_argument("--child-one-solve", nargs=3, help=argparse.SUPPRESS)
    ap.add_argument("--quick", action="store_true", help="the coarse level with the auto backend only")
    args = ap.parse_args(argv)
    if args.child:
        child(*args.child)
        return 0
    if args.child_one_solve:
        child_one_solve(*args.child_one_solve)
        return 0
    if not args.out:
        ap.error("--out is required")
    if args.quick:
        args.levels, args.backends = ["coarse"], ["auto"]
    from contopt.cases.forward import forward_case

    results: dict = {}
    for level in args.levels:
        model, _ = forward_case("die-slab", mesh=level)
        dofs = 3 * sum(b.mesh.n_nodes for b in model.bodies)
        results[level] = {}
        for backend in args.backends:
            if backend == "pardiso" and dofs > args.pardiso_max_dofs:
                results[level][backend] = {"skipped": f"{dofs} dofs > --pardiso-max-dofs {args.pardiso_max_dofs}"}
                continue
            print(f"{level} ({dofs} dofs), {backend} ...", flush=True)
            if args.one_solve and RANKS[backend] > 1:
                continue
            mode = "--child-one-solve" if args.one_solve else "--child"
            results[level][backend] = run(level, backend, args.timeout, mode)
            print("   ", json.dumps(results[level][backend]), flush=True)
        with open(args.out, "w") as f:
            json.dump({"levels": results, "load_average": os.getloadavg()}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
