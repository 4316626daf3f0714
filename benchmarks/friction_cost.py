"""What Coulomb friction costs a contact evaluation: the sliding block with and without friction.

    python benchmarks/friction_cost.py [--divisions 4,8] [--out bench-out/friction_cost.json] [--quick]

For each mesh (``divisions`` cells across the block) the case ``sliding-block`` is solved once with
friction (mu = 0.3); at its converged state the contact evaluation (search, segmentation, mortar
kernels, node laws, residual and tangent) is timed five times with the friction and five times with
the same interface frictionless, after one warm-up call each (kernels compiled or loaded). The
figures are the fastest of the five and their ratio, measured in one process one after the other: per
mesh (``cases``) ``divisions``, ``pairs``, ``frictionless_seconds``, ``friction_seconds`` and ``ratio``.
``--quick``: divisions 2 only (seconds; tests/benchmarks/test_quick.py runs it).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path


def measure(divisions: int, repeats: int = 5) -> dict:
    from contopt.cases.sliding_block import sliding_block
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    model = sliding_block(divisions=divisions)
    t0 = time.perf_counter()
    state = solve_static(model)
    solve_seconds = time.perf_counter() - t0
    frictionless = replace(model, interfaces=tuple(replace(i, friction=None) for i in model.interfaces))
    out: dict = {"divisions": divisions, "pairs": state.contact[0].n_pairs, "solve_seconds": solve_seconds}
    for name, m, laws in (
        ("frictionless", frictionless, None),
        ("friction", model, state.laws),
    ):
        system = System.of(m)
        contact = system.contact
        states = contact.begin_step(laws if laws is not None else system.start_states(), state.u)
        contact.evaluate(state.u, states)
        times = []
        for _ in range(repeats):
            t = time.perf_counter()
            contact.evaluate(state.u, states)
            times.append(time.perf_counter() - t)
        out[f"{name}_seconds"] = min(times)
    out["ratio"] = out["friction_seconds"] / out["frictionless_seconds"]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--divisions", default="4,8", help="cells across the block, comma-separated")
    ap.add_argument("--out", default="bench-out/friction_cost.json")
    ap.add_argument("--quick", action="store_true", help="divisions 2 only (seconds)")
    args = ap.parse_args(argv)
    if args.quick:
        args.divisions = "2"
    from contopt.config import setup_jax

    setup_jax()
    rows = [measure(int(d)) for d in args.divisions.split(",")]
    for r in rows:
        print(
            f"divisions {r['divisions']}: {r['pairs']} pairs, contact evaluation "
            f"{r['frictionless_seconds'] * 1e3:.1f} ms frictionless, "
            f"{r['friction_seconds'] * 1e3:.1f} ms with friction ({r['ratio']:.2f}x)"
        )
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps({"cases": rows}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
