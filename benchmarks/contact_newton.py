"""Newton's effort on contact that closes along a curved surface (issue 35, part 3).

    python benchmarks/contact_newton.py --out FILE.json [--only tutorial|hertz] [--press 0.25 0.6]
        [--setup first current] [--quick]

Runs the tutorial (examples/tutorial.toml as it was: beam under a stiff 16-gon roller, the beam's top
nonmortar, penalty contact) with the roller pressed ``--press`` into the beam, each as ``contopt run
FILE --max-iter 1`` solves it:
the full design (the reference), the grey design (warm from the full one) and the first trial
design (the design MMA's first step gives, warm from the grey one, with the cold fall-back); and
the penalty Hertz line contact (tests/contact/_meshing.py ``cylinder_on_block``, 2394 cells,
penalty 100 E*/h, 5 load steps). Per analysis the JSON holds ``newton_iterations`` (converged
solves, as the CLI reports), ``newton_iterations_all`` (failed attempts included), ``load_steps``,
``cold``, ``seconds`` and the answer, ``contact_force`` (norm of the reactions on the prescribed
dofs). Iteration counts are deterministic; the seconds depend on the machine.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from contopt.config import setup_jax

ROOT = Path(__file__).resolve().parents[1]


def _row(name: str, state, seconds: float, cold: bool, constrained) -> dict:
    return {
        "analysis": name,
        "newton_iterations": int(state.newton_iterations),
        "newton_iterations_all": int(sum(lg.iterations for lg in state.logs)),
        "load_steps": int(sum(1 for lg in state.logs if lg.converged)),
        "cold": bool(cold),
        "seconds": round(seconds, 2),
        "contact_force": float(np.linalg.norm(state.reactions[constrained])),
    }


def tutorial(press: float, setup: str = "first") -> list[dict]:
    """The three analyses of ``contopt run examples/tutorial.toml --max-iter 1`` with the roller pressed ``press``:
    ``setup`` "first" (the 16-gon roller under the beam's top as nonmortar, as the issue measured it) or "current"
    (the tutorial as it is: the 64-gon roller, the sides chosen by contopt)."""
    from contopt.cases.spec import load_spec
    from contopt.optimize.driver import OutputOptions, optimize

    sys.path.insert(0, str(ROOT / "tests"))
    from _tutorial import tutorial_text  # tests/_tutorial.py: the first set-up, shared with the trust tests

    text = tutorial_text(first=setup == "first", press=press)
    spec = load_spec(text, base_dir=ROOT / "examples")
    problem = dataclasses.replace(spec.problem, model=spec.discretization)
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        # the analyses only: no pictures, no load-path curves (two more solves from zero, not what is measured)
        outputs = OutputOptions(vtu="none", plot=False, curves=False)
        optimize(problem, spec.optimizer, dataclasses.replace(spec.options, max_iter=1), out=out, outputs=outputs)
        wall = round(time.perf_counter() - t0, 2)
        rows = []
        for f in sorted((Path(out) / "checkpoint").glob("eval_*.npz")):  # the grey design, then the trial
            d = np.load(f, allow_pickle=True)
            rows.append(
                {"analysis": "grey" if int(d["index"]) == 0 else "trial", "press": press, "setup": setup}
                | {"wall_run": wall}
                | {k: d[k].item() for k in ("newton_iterations", "cold", "seconds")}
            )
    return rows


def hertz(h: float = 0.0075) -> dict:
    """The penalty Hertz line contact (cells of ``h`` at the contact: 2394 cells at 0.0075, 5 load steps)."""
    sys.path.insert(0, str(ROOT / "tests" / "contact"))
    from _hertz import E_STAR, hertz_model  # tests/contact/_hertz.py

    from contopt.contact.laws import Penalty
    from contopt.solve.newton import NewtonOptions
    from contopt.solve.static import solve_static
    from contopt.solve.system import System

    model, _ = hertz_model(h, Penalty(eps=100.0 * E_STAR / h))
    system = System.of(model)
    t0 = time.perf_counter()
    state = solve_static(system, newton=NewtonOptions(n_steps=5))
    return _row("hertz-penalty", state, time.perf_counter() - t0, True, system.disc.constrained)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True)
    p.add_argument("--only", choices=["tutorial", "hertz"], default=None)
    p.add_argument("--press", type=float, nargs="+", default=[0.25, 0.6])
    p.add_argument("--setup", choices=["first", "current"], nargs="+", default=["first", "current"])
    p.add_argument(
        "--quick",
        action="store_true",
        help="the smallest run, seconds: what tests/benchmarks/test_quick.py runs (the Hertz line only, h = 0.02)",
    )
    args = p.parse_args(argv)
    setup_jax()
    out: dict = {"tutorial": [], "hertz": None}
    if args.quick:
        args.only = "hertz"
    if args.only != "hertz":
        for setup in args.setup:
            for press in args.press:
                out["tutorial"] += tutorial(press, setup)
    if args.only != "tutorial":
        out["hertz"] = hertz(0.02 if args.quick else 0.0075)
    Path(args.out).write_text(json.dumps(out, indent=1))
    print(f"{'analysis':>16} {'setup':>8} {'press':>6} {'Newton':>7} {'cold':>5} {'seconds':>8}")
    for r in out["tutorial"]:
        row = f"{r['analysis']:>16} {r['setup']:>8} {r['press']:>6} {r['newton_iterations']:>7} {r['cold']!s:>5}"
        print(row, f"{r['wall_run']:8.1f}")
    if out["hertz"]:
        r = out["hertz"]
        print(
            f"{'hertz-penalty':>16} {'':>6} {r['newton_iterations']:>7} {'':>5} {r['seconds']:8.1f}",
            f"F {r['contact_force']:.6e}",
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
