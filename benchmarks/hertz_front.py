"""Where the penalty Hertz line's Newton iterations go, and what the right active set is worth (issue 35 §3).

    python benchmarks/hertz_front.py --out bench-out/hertz_front.json [--quick] [--h H] [--steps 5]

The penalty (``100 E*/h``) Hertz line of benchmarks/hertz_line.py (tests/contact/_hertz.py), solved twice:

* ``baseline``: the solver as it is without its predicted active set (``NewtonOptions.active_set = 0``),
  with every Newton iteration's landing recorded (per Newton solve,
  its load factor ``t`` and ``solve``, its index in the step: ``alphas``, the line search's factors, and
  ``active``, the nodes with pressure after each iteration, the predictor's first);
* ``oracle``: the same, but every tangent of a load step's first Newton solve counts as closed the
  nodes with pressure in the baseline's converged state of that step, and the linear system's
  right-hand side gets the closed branch's affine term ``eps gbar w`` of those of them still open
  (the linear model of a primal-dual active-set step; the residual and the line search's energy are
  the true ones, so the answer is the same: ``max_difference``, the largest difference of u).

Per run the JSON holds ``newton_iterations`` (converged solves), ``iterations_per_step`` and
``steps``; ``max_difference`` compares the two states. The oracle reads its active sets from the
baseline, so it says what a predicted active set could save, not how to predict it
(docs/performance.md, "Where the iterations past the predictor go"). Both runs wrap public functions
of ``contopt.solve`` (the landing's record, the oracle's right-hand side) and the penalty law's
``node_terms``: a diagnostic, not a solver option.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np

from contopt.config import setup_jax

ROOT = Path(__file__).resolve().parents[1]
#: h near the contact: Kratos' size (8,216 cells) and --quick's (802 cells), as in hertz_line.py
H_FULL, H_QUICK = 0.00305, 0.02


@contextmanager
def patched(owner, name, value):
    """``owner.name`` replaced by ``value`` inside the block."""
    old = getattr(owner, name)
    setattr(owner, name, value)
    try:
        yield
    finally:
        setattr(owner, name, old)


def recording(search, steps: list):
    """``newton.search`` that records each landing's alpha and nodes with pressure in ``steps[-1]``."""

    def wrapped(step, x, system, direction, it):
        x, ev = search(step, x, system, direction, it)
        record = steps[-1]
        record["alphas"].append(float(x.alphas[-1]))
        record["active"].append(int(sum(res.n_active for res in ev.contact)))
        return x, ev

    return wrapped


def solve(system, newton, oracle: dict | None = None) -> tuple:
    """``(state, steps)``: the penalty solve, its landings recorded per Newton solve; with ``oracle``
    ({load factor: (n_nodes,) bool}) the tangents of each step's first solve count those nodes closed,
    with the closed branch's affine term in the right-hand side."""
    from contopt.solve import newton as newton_module
    from contopt.solve import static
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    steps: list = []
    affine: dict = {}
    evaluate, linear_system, newton_step = System.evaluate, newton_module.linear_system, static.newton_step

    def forced_evaluate(self, u, t, layout, states, tangent=True, touch=0.0, full=True, closed=None):
        forced = None if oracle is None or not tangent else oracle.get(round(t, 9))
        if forced is None or not steps or steps[-1]["solve"] > 0:
            return evaluate(self, u, t, layout, states, tangent, touch, full, closed)
        ev = evaluate(self, u, t, layout, states, tangent, touch, full, (forced,))
        res, law = ev.contact[0], self.contact.blocks[0].law
        gbar = np.where(res.has_overlap, res.g / np.where(res.has_overlap, res.a, 1.0), 0.0)
        open_closed = forced & (res.lam <= 0) & res.has_overlap
        affine[id(ev)] = res.W.T @ np.where(open_closed, law.eps * gbar, 0.0)
        return ev

    def affine_system(step, x, ev):
        K, system_ = linear_system(step, x, ev)
        term = affine.pop(id(ev), None)
        return (K, system_) if term is None else (K, replace(system_, rhs=system_.rhs - term[step.free]))

    def counted_newton_step(*args, **kwargs):
        t = args[5]
        solves = sum(1 for s in steps if s["t"] == t)
        steps.append({"t": t, "solve": solves, "alphas": [], "active": []})
        return newton_step(*args, **kwargs)

    with (
        patched(System, "evaluate", forced_evaluate),
        patched(newton_module, "linear_system", affine_system),
        patched(newton_module, "search", recording(newton_module.search, steps)),
        patched(static, "newton_step", counted_newton_step),
    ):
        state = solve_static(system, newton=newton, record_path=True)
    return state, steps


def summary(state, steps: list, wall: float) -> dict:
    """A run's row of the JSON."""
    per_step: dict[float, int] = {}
    for lg in state.logs:
        if lg.converged:
            per_step[lg.t] = per_step.get(lg.t, 0) + lg.iterations
    return {
        "newton_iterations": int(state.newton_iterations),
        "newton_iterations_all": int(sum(lg.iterations for lg in state.logs)),
        "iterations_per_step": list(per_step.values()),
        "steps": steps,
        "wall": round(wall, 2),
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="JSON file to write")
    p.add_argument("--quick", action="store_true", help=f"the smallest mesh (h = {H_QUICK})")
    p.add_argument("--h", type=float, default=None, help=f"cell size near the contact (default {H_FULL})")
    p.add_argument("--steps", type=int, default=5, help="load steps")
    args = p.parse_args(argv)
    setup_jax()
    sys.path.insert(0, str(ROOT / "tests" / "contact"))
    from _hertz import E_STAR, hertz_model

    from contopt.contact.laws import Penalty
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.system import System

    h = args.h or (H_QUICK if args.quick else H_FULL)
    model, _ = hertz_model(h, Penalty(eps=100.0 * E_STAR / h))
    system = System.of(model)
    # the solver without its predicted active set (NewtonOptions.active_set), whose creep this diagnoses
    newton = NewtonOptions(n_steps=args.steps, active_set=0)
    t0 = time.perf_counter()
    base, base_steps = solve(system, newton)
    t1 = time.perf_counter()
    closed = {round(s.t, 9): s.contact[0].lam > 0 for s in base.path}
    oracle, oracle_steps = solve(system, newton, oracle=closed)
    t2 = time.perf_counter()
    result = {
        "h": h,
        "steps": args.steps,
        "n_cells": int(system.disc.n_cells),
        "n_equations": int(system.disc.free.size),
        "baseline": summary(base, base_steps, t1 - t0),
        "oracle": summary(oracle, oracle_steps, t2 - t1),
        "max_difference": float(np.abs(oracle.u - base.u).max()),
        "machine": {"python": platform.python_version(), "node": platform.node()},
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1))
    for name in ("baseline", "oracle"):
        row = result[name]
        per = "/".join(str(n) for n in row["iterations_per_step"])
        print(f"{name}: Newton {row['newton_iterations']} ({per}); wall {row['wall']:.1f} s")
    for s in base_steps:
        print(f"  t={s['t']:.3g} solve {s['solve']}: active {s['active']}, alpha {[round(a, 3) for a in s['alphas']]}")
    print(f"max |u_oracle - u_baseline| = {result['max_difference']:.2e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
