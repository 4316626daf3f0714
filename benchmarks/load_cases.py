"""The load cases in worker processes against one after the other: two-way-press, serial vs 2 workers.

    python benchmarks/load_cases.py [--evaluations 8] [--workers 2] [--out bench-out/load_cases.json] [--quick]

Two NLPs of the bundled ``two-way-press`` (two load cases, the worst case) live in one process: one
analyses its cases here, one hands them to a :func:`contopt.optimize.case_pool.case_pool` of
``--workers`` processes. Both evaluate the same designs in turn (a walk of small random steps from
the grey design, each case warm-started from its own last state, as an MMA iteration's one
evaluation is: the primal and adjoint of every case and the design chain), the serial NLP first,
then the pooled one, design by design, so that both see the same machine load. After the start
design (``first_serial_seconds``, ``first_workers_seconds``: the first analyses, with the
reference solve of the full design, which alone took ``reference_serial_seconds`` and
``reference_workers_seconds``, the scales ``reference_difference`` apart relative to their size,
and again by fresh NLPs once both paths are warm, ``reference_again_serial_seconds`` and
``reference_again_workers_seconds``;
``pool_start_seconds`` is the time to start the pool, the workers' own start is in their first
task, the reference) the figures are per evaluation:
``serial_seconds`` and ``workers_seconds`` (lists), their medians ``serial_median`` and
``workers_median``, ``ratio`` = serial_median / workers_median (above 1: the workers are
faster) and ``ratios`` (design by design), with ``cpus`` (the cores this process may use) and
``max_difference`` (the largest difference of f, g and their gradients between the two, relative to
their size). The machine may be shared: the ratio measured in one run, design by design, is what
to compare, not the seconds.
``--quick``: two evaluations (tests/benchmarks/test_quick.py runs it).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import time
from pathlib import Path

import numpy as np


def _difference(a, b) -> float:
    out = 0.0
    for name in ("f", "g", "df", "dg"):
        u, v = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        out = max(out, float(np.abs(u - v).max() / max(np.abs(u).max(), 1e-300)))
    return out


def measure(evaluations: int, workers: int, seed: int = 0) -> dict:
    from contopt.cases.optimization import optimization_case
    from contopt.optimize.case_pool import case_pool
    from contopt.optimize.multicase import design_nlp

    problem = dataclasses.replace(optimization_case("two-way-press"), case_workers=workers)
    rng = np.random.default_rng(seed)
    out: dict = {"case": "two-way-press", "workers": workers, "cpus": len(os.sched_getaffinity(0))}
    serial = design_nlp(problem)
    t = time.perf_counter()
    scale = serial.objective_scale()  # the reference: the full design in each case, here
    out["reference_serial_seconds"] = time.perf_counter() - t
    x = serial.start(serial.space.initial())  # the worst case's beta: the start design analysed
    serial.evaluate(x)
    out["first_serial_seconds"] = time.perf_counter() - t
    t = time.perf_counter()
    with case_pool(problem) as pool:
        out["pool_start_seconds"] = time.perf_counter() - t
        pooled = design_nlp(problem, pool=pool)
        t = time.perf_counter()
        out["reference_difference"] = abs(pooled.objective_scale() - scale) / abs(scale)  # in the workers
        out["reference_workers_seconds"] = time.perf_counter() - t
        pooled.start(pooled.space.initial())
        pooled.evaluate(x)
        out["first_workers_seconds"] = time.perf_counter() - t
        # the reference again, each path warm (kernels compiled here, workers started): a fresh NLP each
        for name, nlp in (("serial", design_nlp(problem)), ("workers", design_nlp(problem, pool=pool))):
            t = time.perf_counter()
            nlp.objective_scale()
            out[f"reference_again_{name}_seconds"] = time.perf_counter() - t
        times: dict[str, list] = {"serial": [], "workers": []}
        difference = 0.0
        n = serial.space.n
        for _ in range(evaluations):
            x = x.copy()
            x[:n] = np.clip(x[:n] + 0.05 * rng.standard_normal(n), serial.space.lower, serial.space.upper)
            results = []
            for name, nlp in (("serial", serial), ("workers", pooled)):
                t = time.perf_counter()
                results.append(nlp.evaluate(x))
                times[name].append(time.perf_counter() - t)
            difference = max(difference, _difference(*results))
    out["serial_seconds"], out["workers_seconds"] = times["serial"], times["workers"]
    out["serial_median"] = statistics.median(times["serial"])
    out["workers_median"] = statistics.median(times["workers"])
    out["ratio"] = out["serial_median"] / out["workers_median"]
    out["ratios"] = [a / b for a, b in zip(times["serial"], times["workers"])]
    out["max_difference"] = difference
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--evaluations", type=int, default=8, help="designs evaluated by both after the start")
    ap.add_argument("--workers", type=int, default=2, help="worker processes of the pooled NLP")
    ap.add_argument("--out", default="bench-out/load_cases.json")
    ap.add_argument("--quick", action="store_true", help="two evaluations")
    args = ap.parse_args(argv)
    if args.quick:
        args.evaluations = 2
    from contopt.config import setup_jax

    setup_jax()
    result = measure(args.evaluations, args.workers)
    result["quick"] = args.quick
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(
        f"two-way-press, {result['cpus']} cores: serial {result['serial_median']:.2f} s, "
        f"{args.workers} workers {result['workers_median']:.2f} s per evaluation (ratio {result['ratio']:.2f}); "
        f"max relative difference {result['max_difference']:.1e}; the reference (the full design) "
        f"{result['reference_serial_seconds']:.2f} s serial, {result['reference_workers_seconds']:.2f} s "
        f"in the workers (scales {result['reference_difference']:.1e} apart); again, warm: "
        f"{result['reference_again_serial_seconds']:.2f} s and {result['reference_again_workers_seconds']:.2f} s"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
