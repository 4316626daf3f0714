"""Tet4 and tet10 against hex8 on a cantilever: tip deflection over the beam's, and cost at equal dofs.

    python benchmarks/tet_cantilever.py [--out FILE.json] [--quick]

A beam 10 x 1 x 1 clamped at x = 0 (neo-Hookean, E = 1, nu = 0.3) under a small end load (tip
deflection ~4e-3: linear), meshed as box cells (hex8 with F-bar) or the same cells cut into six
tets each (``contopt.mesh.tetrahedralize``). Per mesh: ``element``, ``cells``, ``dofs``, ``tip_over_beam`` (the
mean tip deflection over ``P L^3 / 3 E I``), ``evaluate_seconds`` (one residual + tangent evaluation,
mean of 5 after a warm-up) and ``tangent_nonzeros``. Printed as a table, and written as JSON with --out.
``--quick``: the three elements on 10 x 1 x 1 cells only (seconds; tests/benchmarks/test_quick.py runs it).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from contopt.assembly.model import Body, Dirichlet, Model, Traction
from contopt.assembly.system import discretize
from contopt.config import setup_jax
from contopt.material.hyperelastic import neo_hookean
from contopt.mesh import box, tetrahedralize
from contopt.solve.newton import NewtonOptions
from contopt.solve.static import solve_static

L, H, E, NU, P = 10.0, 1.0, 1.0, 0.3, 1e-6
CASES = (("hex8", (20, 2, 2)), ("tet4", (20, 2, 2)), ("tet10", (20, 2, 2)), ("hex8", (40, 4, 4)), ("tet4", (40, 4, 4)))
QUICK = (("hex8", (10, 1, 1)), ("tet4", (10, 1, 1)), ("tet10", (10, 1, 1)))


def run(element: str, divisions: tuple) -> dict:
    mesh = box((L, H, H), divisions)
    if element != "hex8":
        mesh = tetrahedralize(mesh, 1 if element == "tet4" else 2)
    model = Model(
        bodies=[Body("b", mesh, neo_hookean(E, NU))],
        dirichlet=[Dirichlet("b", "xmin", "xyz")],
        loads=[Traction("b", "xmax", (0.0, 0.0, -P / H**2))],
    )
    disc = discretize(model)
    u = disc.body_displacement(solve_static(disc, newton=NewtonOptions(n_steps=1)).u, "b")
    tip = -u[mesh.node_set("xmax"), 2].mean() / (P * L**3 / (3 * E * H**4 / 12))
    v = 1e-3 * np.random.default_rng(0).standard_normal(disc.n_dofs)
    disc.evaluate(v, 1.0)
    start = time.perf_counter()
    for _ in range(5):
        ev = disc.evaluate(v, 1.0)
    seconds = (time.perf_counter() - start) / 5
    return {
        "element": element,
        "box_cells": list(divisions),
        "cells": mesh.n_cells,
        "dofs": disc.n_dofs,
        "tip_over_beam": float(tip),
        "evaluate_seconds": seconds,
        "tangent_nonzeros": int(ev.K_free.nnz),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None, help="JSON file for the rows")
    parser.add_argument("--quick", action="store_true", help="the smallest meshes (seconds)")
    args = parser.parse_args(argv)
    setup_jax()
    rows = [run(*case) for case in (QUICK if args.quick else CASES)]
    print(f"{'element':8s} {'box cells':>10s} {'cells':>6s} {'dofs':>6s} {'tip/beam':>9s} {'evaluate':>9s} {'nnz':>8s}")
    for r in rows:
        cells = "x".join(str(n) for n in r["box_cells"])
        print(
            f"{r['element']:8s} {cells:>10s} {r['cells']:6d} {r['dofs']:6d} {r['tip_over_beam']:9.3f} "
            f"{r['evaluate_seconds'] * 1e3:7.1f}ms {r['tangent_nonzeros']:8d}"
        )
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(rows, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
