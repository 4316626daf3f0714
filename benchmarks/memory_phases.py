"""Where the peak memory of a die-slab forward goes, phase by phase.

    python benchmarks/memory_phases.py [--cases fine,33k] [--out bench-out/memory_phases.json] [--quick]

Each case runs ``contopt forward die-slab`` in-process (the same calls as the command: the case's
model, ``run_forward``, Pardiso) in a child process of its own, and records:

``peak_rss_mb``
    ``ru_maxrss`` of the child: the number the issue's targets are about.
``phases_rss_mb``
    Resident memory (VmRSS, MB, after ``malloc_trim`` so that freed heap is not counted) after
    each set-up phase: the runtime (Python, numpy, scipy, JAX and its CPU client, contopt's
    modules), the discretization (cell geometry, CSR pattern, scatter map), the step-0 output
    (the stress kernel), the first evaluation (the bulk kernels), and at the end of the solve (every
    mortar kernel variant loaded); each with its increment over the previous one.
``at_peak``
    A sampler thread reads VmRSS every 2 ms with the innermost phase under way (evaluation,
    factorization, solve, line search, output): the phase of the largest sample; the RSS just
    before the factorization that reached it; the factor's nonzeros and Pardiso's own peak
    (``iparm(15..17)``); the sizes of the arrays alive then (the free-free tangent, its upper
    triangle, the row indices) and of the discretization's arrays.

Cases: ``fine`` (the paper's 45 x 20 x 15 slab, 47k dofs) and ``33k`` (a 40 x 18 x 13 slab, 33k
dofs: the size of the 8,208-cell Hertz mesh of the comparison with Kratos); ``--quick`` runs ``tiny``
(a 9 x 4 x 3 slab, seconds: what tests/benchmarks/test_quick.py runs).
"""

from __future__ import annotations

import argparse
import functools
import json
import multiprocessing as mp
import os
import resource
import sys
import tempfile
import threading
import time
from pathlib import Path

CASES = {"fine": (45, 20, 15), "33k": (40, 18, 13), "coarse": (23, 10, 8), "tiny": (9, 4, 3)}
PAGE_MB = os.sysconf("SC_PAGE_SIZE") / 2**20


def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * PAGE_MB


def _trimmed_rss_mb() -> float:
    from contopt.solve.linear.base import return_free_heap

    return_free_heap()
    return round(_rss_mb(), 1)


class _Sampler:
    """The largest VmRSS sample per innermost phase label (a daemon thread, every 2 ms)."""

    def __init__(self):
        self.stack = ["set-up"]
        self.best: dict[str, float] = {}
        threading.Thread(target=self._run, daemon=True).start()

    def _run(self):
        while True:
            rss, label = _rss_mb(), self.stack[-1]
            if rss > self.best.get(label, 0.0):
                self.best[label] = rss
            time.sleep(0.002)

    def wrap(self, owner, attr: str, label: str, after=None):
        original = getattr(owner, attr)

        @functools.wraps(original)
        def wrapped(*args, **kwargs):
            self.stack.append(label)
            try:
                result = original(*args, **kwargs)
            finally:
                self.stack.pop()
            if after is not None:
                after(args, result)
            return result

        setattr(owner, attr, wrapped)


def _mb(*arrays) -> float:
    return round(sum(a.nbytes for a in arrays) / 2**20, 1)


def measure(case: str) -> dict:
    """The record of one case (runs in the child process)."""
    sampler = _Sampler()
    from contopt.config import setup_jax

    setup_jax()
    import jax

    jax.devices()
    import contopt.cases.forward as fwd
    import contopt.solve.linear as lin
    import contopt.solve.newton as newton
    import contopt.solve.system as ssys
    from contopt.assembly.system import Discretization
    from contopt.cases.die_slab import die_slab
    from contopt.contact.system import ContactDiscretization
    from contopt.solve.linear import LinearSolverOptions, pardiso
    from contopt.solve.linear.base import Factor
    from contopt.solve.newton import NewtonOptions

    marks = {"runtime": _trimmed_rss_mb()}  # resident memory after each phase, and the discretization
    model = die_slab(slab_divisions=CASES[case])
    dofs = 3 * sum(b.mesh.n_nodes for b in model.bodies)
    factorizations = []  # per factorization: rss before, sizes of the arrays handed to it, factor info

    original_factorize = newton.factorize

    def factorize(K, *a, **k):
        factorizations.append({"rss_before_mb": round(_rss_mb(), 1), "K_free_mb": _mb(K.data, K.indices, K.indptr)})
        return original_factorize(K, *a, **k)

    newton.factorize = factorize
    original_init = pardiso._PardisoFactor.__init__

    def init(self, K, rows, *a, **k):
        original_init(self, K, rows, *a, **k)
        h = self._handle
        factorizations[-1].update(
            rows_mb=_mb(rows),
            upper_mb=_mb(h.a, h.ia, h.ja),
            nnz_factor=self.info["nnz_factor"],
            factor_mb=round(8 * self.info["nnz_factor"] / 2**20, 1),
            pardiso_peak_mb=round(self.info["peak_memory_kb"] / 1024, 1),
        )

    pardiso._PardisoFactor.__init__ = init
    sampler.wrap(ssys, "discretize", "discretize", after=lambda a, r: marks.setdefault("disc", r))
    sampler.wrap(Discretization, "evaluate", "bulk evaluation")
    sampler.wrap(ContactDiscretization, "evaluate", "contact evaluation")
    sampler.wrap(lin, "_first_that_factors", "factorization")
    sampler.wrap(Factor, "solve", "solve")
    sampler.wrap(newton, "watched_line_search", "line search")
    sampler.wrap(fwd, "write_state", "output (VTU)")

    def after_evaluate(args, result):
        if "first" not in marks:
            marks["first"] = _trimmed_rss_mb()

    sampler.wrap(ssys.System, "evaluate", "system evaluation", after=after_evaluate)
    original_write = fwd.write_state

    def write_state(*a, **k):
        out = original_write(*a, **k)
        marks.setdefault("step0", _trimmed_rss_mb())
        return out

    fwd.write_state = write_state
    t0 = time.perf_counter()
    fwd.run_forward(model, tempfile.mkdtemp(), newton=NewtonOptions(n_steps=6), linear=LinearSolverOptions())
    seconds = time.perf_counter() - t0
    marks["end"] = _trimmed_rss_mb()  # every mortar kernel variant loaded, the last tangent and factor freed
    disc = marks["disc"]
    label, peak_sample = max(sampler.best.items(), key=lambda kv: kv[1])
    worst = max(factorizations, key=lambda f: f["rss_before_mb"] + f.get("pardiso_peak_mb", 0.0))
    return {
        "case": case,
        "slab_divisions": CASES[case],
        "dofs": dofs,
        "seconds": round(seconds, 1),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "phases_rss_mb": {
            "runtime": marks["runtime"],
            "after step-0 output (discretization, contact set-up, stress kernel)": marks["step0"],
            "after the first evaluation (bulk kernels, first mortar kernels)": marks["first"],
            "end of the solve (every mortar kernel variant loaded)": marks["end"],
        },
        "discretization_arrays_mb": {
            "cell gradients": _mb(*(b.geometry.grad for b in disc.blocks)),
            "scatter map": _mb(*disc.pattern.scatter),
            "CSR pattern": _mb(disc.pattern.indices, disc.pattern.indptr),
            "free sub-pattern": _mb(disc.free_pattern.indices, disc.free_pattern.take, disc.free_pattern.indptr),
        },
        "at_peak": {"phase": label, "sampled_rss_mb": round(peak_sample, 1), "factorization": worst},
        "factorizations": len(factorizations),
        "peak_by_phase_mb": {k: round(v, 1) for k, v in sorted(sampler.best.items(), key=lambda kv: -kv[1])},
    }


def _child(case: str, queue) -> None:
    try:
        queue.put(measure(case))
    except BaseException as err:  # noqa: BLE001 (reported to the parent)
        queue.put({"case": case, "error": repr(err)})


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", default="fine,33k", help=f"comma-separated, of {sorted(CASES)}")
    p.add_argument("--out", default="bench-out/memory_phases.json")
    p.add_argument("--quick", action="store_true", help="the tiny case only (seconds)")
    args = p.parse_args(argv)
    if args.quick:
        args.cases = "tiny"
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        p.error(f"unknown case(s) {unknown}; choose from {sorted(CASES)}")
    ctx = mp.get_context("spawn")  # a fresh process per case: its peak is its own
    results = []
    for case in cases:
        queue = ctx.Queue()
        proc = ctx.Process(target=_child, args=(case, queue))
        proc.start()
        result = queue.get()
        proc.join()
        results.append(result)
        print(json.dumps(result, indent=1), file=sys.stderr, flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"cases": results, "cpus": os.cpu_count()}, indent=1))
    print(f"wrote {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
