"""Benchmarks that cannot rot (issue 41 §5): every script in benchmarks/ has a ``--quick`` mode, and
this runs it and checks that its JSON holds the keys its docstring documents (the ones the docs'
tables quote).

Each runs in a process of its own, as a user runs it; the persistent compilation cache (on in the
tests) is handed down through ``CONTOPT_JAX_CACHE``, so only the first run of a kernel compiles.
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BENCHMARKS = ROOT / "benchmarks"

#: script -> (its arguments besides ``--quick --out FILE``, {where the records are: the keys each has}).
#: Where: "" the JSON itself, "name" a key, "name.*" every item of a list or every value of a dict.
QUICK = {
    "cantilever_topopt": (
        [],
        {"runs.*": ["seconds_per_iteration", "shares", "analyses", "newton_iterations", "n_design",
                    "G_nonzeros", "objective_first", "objective_last", "volume_fraction"]},
    ),
    "contact_matrix": ([], {"": ["machine", "cells"], "cells.*": ["converged", "newton_iterations", "wall_seconds"]}),
    "contact_newton": ([], {"hertz": ["newton_iterations", "newton_iterations_all", "load_steps", "cold", "seconds",
                                      "contact_force"]}),
    "design_surfaces": (
        ["--runs", "{tmp}/runs"],
        {"runs.*": ["volume", "design_volume", "relative_difference", "grey_share", "triangles", "watertight",
                    "manifold", "seconds_export", "seconds_surface"]},
    ),
    "die_recovery": ([], {"": ["paper_energy", "rows"], "rows.*": ["energy", "energy_over_paper", "contact_force",
                                                                   "max_pressure"]}),
    "die_slab_forward": (
        ["-q"],
        {"": ["load_steps", "newton_iterations_total", "alm_updates", "contact_force", "strain_energy",
              "peak_memory_mb", "seconds", "contact_overhead_ratio", "compile_seconds", "adjoint_seconds",
              "adjoint_linear_solves", "adjoint_ratio", "adjoint_methods"]},
    ),
    "fe_core": ([], {"": ["dofs", "newton_iterations", "seconds", "overhead_ratio", "convergence_orders"]}),
    "friction_cost": ([], {"cases.*": ["divisions", "pairs", "frictionless_seconds", "friction_seconds", "ratio"]}),
    "hertz_sphere": (
        ["--element", "tet10", "--h", "0.05", "--length", "0.6"],  # the tet10 path, 17k dofs (a minute)
        {"rows.*": ["element", "n_dofs", "newton_iterations", "wall", "peak_rss_mb", "error_p0", "error_a",
                    "error_p0_fit", "error_a_fit"]},
    ),
    "hertz_front": (
        [],
        {"": ["baseline", "oracle", "max_difference"],
         "baseline": ["newton_iterations", "iterations_per_step", "steps"],
         "oracle": ["newton_iterations", "iterations_per_step", "steps"],
         "baseline.steps.*": ["t", "solve", "alphas", "active"]},
    ),
    "hertz_line": (
        ["--law", "alm"],
        {"laws.*": ["newton_iterations", "newton_iterations_all", "iterations_per_step", "solves",
                    "multiplier_updates", "seconds_per_phase", "ratio_to_factorize", "peak_rss_mb", "n_cells",
                    "n_equations", "contact_force", "hertz", "solver", "krylov_iterations", "petsc"]},
    ),
    "length_scale": ([], {"*": ["run", "radius", "nu"]}),
    "load_cases": ([], {"": ["cpus", "serial_median", "workers_median", "ratio", "max_difference",
                             "pool_start_seconds", "reference_serial_seconds", "reference_workers_seconds",
                             "reference_difference", "reference_again_serial_seconds",
                             "reference_again_workers_seconds"]}),
    "linear_solvers": ([], {"results.*": ["n", "dofs", "nnz", "backends"]}),
    "memory_phases": ([], {"cases.*": ["peak_rss_mb", "phases_rss_mb", "at_peak"]}),
    "paper_tables": (
        ["--only", "table1-density-coarse", "--max-iter", "1", "--doc", "{tmp}/results.md", "--runs", "{tmp}/runs"],
        {"runs.*": ["status", "iterations", "seconds_per_iteration", "peak_memory_mb", "normalized_objective",
                    "volume_fraction"]},
    ),
    "sabot_paper": (
        [],
        {"": ["finished", "dofs", "cells", "seconds_by_phase", "adjoint_seconds", "peak_mb", "solver",
              "krylov_iterations", "petsc"]},
    ),
    "scaling": (
        [],
        {"levels.*.*": ["dofs", "wall_seconds", "forward_seconds", "adjoint_seconds", "newton_iterations",
                        "krylov_iterations", "preconditioner_setups", "peak_memory_mb", "seconds",
                        "adjoint_phases", "strain_energy", "contact_force"]},
    ),
    "startup_memory": ([], {"": ["help_seconds", "first_iteration_seconds_warm", "first_iteration_samples"]}),
    # tests/validation runs the Hertz and stacked-block models; the arch here
    "validation": (["--case", "arch"], {"": ["case", "quick", "seconds"]}),
    "voxel_envelope": ([], {"rows.*": ["size", "cells", "volume", "relative_error", "seconds"]}),
    "tet_cantilever": ([], {"*": ["element", "cells", "dofs", "tip_over_beam", "evaluate_seconds",
                                  "tangent_nonzeros"]}),
}  # fmt: skip


def _records(data, where: str) -> list:
    """The records at ``where`` (see :data:`QUICK`) of a JSON document."""
    records = [data]
    for part in where.split(".") if where else []:
        if part == "*":
            records = [v for r in records for v in (r.values() if isinstance(r, dict) else r)]
        else:
            records = [r[part] for r in records]
    return records


def _docstring(script: str) -> str:
    return ast.get_docstring(ast.parse((BENCHMARKS / f"{script}.py").read_text())) or ""


def test_every_benchmark_has_a_quick_mode_that_is_run_here():
    scripts = sorted(p.stem for p in BENCHMARKS.glob("*.py") if not p.name.startswith("_"))
    assert scripts == sorted(QUICK), "add the new benchmark (its --quick arguments and keys) to QUICK"
    for script in scripts:
        assert "--quick" in (BENCHMARKS / f"{script}.py").read_text(), script


@pytest.mark.parametrize("script", sorted(QUICK))
def test_the_keys_checked_are_the_documented_ones(script):
    documented = _docstring(script)
    for keys in QUICK[script][1].values():
        assert not [k for k in keys if k not in documented], f"{script}: its docstring should name these JSON keys"


@pytest.mark.parametrize("script", sorted(QUICK))
def test_quick_mode_runs_and_writes_the_documented_keys(script, tmp_path):
    args, where_keys = QUICK[script]
    out = tmp_path / f"{script}.json"
    cmd = [sys.executable, str(BENCHMARKS / f"{script}.py"), "--quick", "--out", str(out)]
    cmd += [a.format(tmp=tmp_path) for a in args]
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    proc = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, f"{script} --quick failed:\n{proc.stderr[-3000:]}"
    data = json.loads(out.read_text())
    for where, keys in where_keys.items():
        records = _records(data, where)
        assert records, f"{script}: no records at {where!r}"
        for record in records:
            assert not (isinstance(record, dict) and record.get("error")), f"{script}: {record['error']}"
            missing = [k for k in keys if k not in record]
            assert not missing, f"{script}: {where or 'the JSON'} lacks {missing}"
