"""Start-up time and memory of the command line: how soon a first result, how much memory.

    python benchmarks/startup_memory.py --out bench-out/startup_memory.json [--levels coarse fine] [--skip-fine]
    python benchmarks/startup_memory.py --out bench-out/startup_memory.json --quick   # help and one warm
        # first iteration (what tests/benchmarks/test_quick.py runs)

Writes JSON with (all walls in seconds, measured from the parent: spawn to event; medians where
several runs are made; the machine's load at the start is in ``environment``):

``help_seconds``
    ``contopt --help`` in a fresh process, median of 5.
``first_iteration_seconds_warm`` / ``first_iteration_seconds_cold``
    Process start to the first Newton iteration of ``contopt -v forward die-slab --mesh coarse
    --out TMP``: the forward command logs no line per Newton iteration, but with ``-v`` the linear
    solver logs ``factorized NxN ... in X s`` (contopt.solve.linear.factorize) once per iteration,
    so the arrival of the first such line on the child's stderr marks the end of the first
    iteration's factorization (the child is stopped there, except in the full run below). Warm:
    the JAX persistent compilation cache of ``$CONTOPT_JAX_CACHE`` (default
    ``~/.cache/contopt/jax``) after one warm-up run; cold: a fresh empty ``CONTOPT_JAX_CACHE``.
    ``first_iteration_samples`` holds every sample and the arrival of the first contact
    evaluation (``segmented ...`` line) and of the end of the first Newton solve (``contact: ...``).
``cantilever_one_iteration_seconds_warm`` / ``_cold``
    Wall of ``contopt run cantilever --max-iter 1 --out TMP --no-plot --vtu none`` (the reference
    analysis of the full design, then one MMA iteration).
``peak_rss_mb``
    ``{"coarse": MB, "fine": MB}``: peak resident memory (``ru_maxrss`` from ``os.wait4`` of the
    child) of the whole ``contopt -v forward die-slab --mesh coarse|fine --out TMP``, each in its own
    process, warm cache. ``memory`` adds per run the wall, and the child's VmRSS/VmHWM sampled from
    ``/proc/PID/status`` as its log lines arrive (first contact evaluation, first factorization,
    each converged load step).
``first_iteration_peak_rss_mb``
    (``--quick`` only) the peak resident memory of the first-iteration child, stopped there.
``phases``
    Where the seconds go from process start to the first factorization, warm and cold, from an
    instrumented in-process replay of ``contopt forward die-slab`` (``python
    benchmarks/startup_memory.py --child-phases coarse --child-out F.json``): the same calls
    (contopt.cli parser, setup_jax, forward_case, run_forward), with the functions of the call
    sequence wrapped by timers (``time.perf_counter``) and JAX's compile events
    (``jax.monitoring``: tracing, lowering to MLIR, XLA compile, persistent-cache retrieval) summed
    per stage; warm: the replay of median total out of ``--repeats``, cold: one, in a fresh cache.
    The kernels' set-up by the export cache (``kernel set-up: ...`` in ``detail``: entries read and
    deserialized, or traced, exported and written) is timed too; ``kernel_sources`` counts the kernel
    variants read from it (``loaded``), traced and exported (``exported``) or plainly jitted (``jit``).
    ``stages`` are sequential and add up to ``total_seconds``; ``detail`` splits the
    first evaluation and factorization. Each stage has VmRSS after it and its own peak (VmHWM,
    reset before the stage through ``/proc/self/clear_refs`` where the kernel allows it; otherwise
    the peak so far). ``imports`` breaks the import time down by top-level package (self times
    of ``python -X importtime``, which inflates them; compare shares). With the fine mesh (warm)
    the same replay gives the per-phase memory picture. ``notes`` says what could not be
    separated cleanly.
``without_export_cache``
    The same first iterations (warm, cold) and cantilever runs with ``CONTOPT_EXPORT_CACHE=0``
    (plain ``jax.jit``: every process traces and lowers the kernels, the state before
    contopt.export_cache), alternating with the default runs so that both see the same load;
    ``phases.coarse.warm_no_export`` is the replay of that mode. ``first_iteration_samples`` and
    ``cantilever_samples`` keep the samples of both.
``environment``
    Python, JAX, numpy, scipy versions, CPU count, load average at the start and the end.

The machine may be busy (the load average says how much): compare ratios and shares, not
absolute walls, between runs.
"""

import argparse
import functools
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections import defaultdict
from pathlib import Path

#: the line the linear solver logs (at -v) once per Newton iteration, after the factorization
FACTORIZED = re.compile(r"^factorized \d+x\d+")
#: the first contact evaluation (segmentation, logged at -v) and the end of a Newton solve (contact summary)
SEGMENTED = re.compile(r"^segmented \d+ pairs")
SOLVE_DONE = re.compile(r"^\s*contact: \[")
STEP_DONE = re.compile(r"^t=(\S+) dt=\S+ converged")
TIMEOUT = {"help": 60, "first": 300, "full": 600, "cantilever": 300, "phases": 600, "imports": 120}


# --------------------------------------------------------------------------------- small helpers
def contopt_exe() -> str:
    """The ``contopt`` console script next to this interpreter (the virtualenv's), else on PATH."""
    here = Path(sys.executable).parent / "contopt"
    found = str(here) if here.exists() else shutil.which("contopt")
    if not found:
        raise SystemExit("startup_memory: no `contopt` command next to this python or on PATH")
    return found


def proc_status(pid: int | str = "self") -> dict:
    """VmRSS and VmHWM (MB) of a process; {} once it is gone."""
    out = {}
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith(("VmRSS:", "VmHWM:")):
                key, value = line.split(":", 1)
                out[key] = int(value.split()[0]) / 1024.0
    except (OSError, ValueError):
        pass
    return out


def median(values) -> float:
    return float(statistics.median(values))


def env_with_cache(cache_dir: str | None, export: bool = True) -> dict:
    env = dict(os.environ)
    if cache_dir is not None:
        env["CONTOPT_JAX_CACHE"] = cache_dir
    env.pop("CONTOPT_EXPORT_CACHE", None)  # the default: <CONTOPT_JAX_CACHE>/export
    if not export:
        env["CONTOPT_EXPORT_CACHE"] = "0"  # plain jax.jit: trace and lower in every process
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env


def default_cache_dir() -> Path:
    return Path(os.environ.get("CONTOPT_JAX_CACHE") or Path.home() / ".cache" / "contopt" / "jax")


def cache_entries(path: Path) -> int:
    return sum(1 for _ in path.iterdir()) if path.is_dir() else 0


# ------------------------------------------------------------------------ a timed child process
class ChildRun:
    """Run ``cmd``, stamping each line of its merged stdout/stderr with the seconds since spawn and
    the child's VmRSS/VmHWM at that moment; stop it at the first line matching ``stop``."""

    def __init__(self, cmd, env=None, timeout=300.0, stop=None, label=""):
        self.cmd, self.env, self.timeout, self.stop, self.label = cmd, env, timeout, stop, label or cmd[0]
        self.lines: list[tuple[float, str, dict]] = []
        self.stopped = False

    def run(self) -> "ChildRun":
        t0 = time.monotonic()
        proc = subprocess.Popen(
            self.cmd, env=self.env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1
        )
        reader = threading.Thread(target=self._read, args=(proc, t0), daemon=True)
        reader.start()
        reader.join(self.timeout)
        if reader.is_alive():
            proc.kill()
            reader.join(10)
            self._reap(proc, t0)
            raise RuntimeError(f"{self.label}: no result within {self.timeout:.0f} s: {self._tail()}")
        self._reap(proc, t0)
        if self.returncode != 0 and not self.stopped:
            raise RuntimeError(f"{self.label}: exit status {self.returncode}: {self._tail()}")
        return self

    def _read(self, proc, t0) -> None:
        for line in proc.stdout:
            self.lines.append((time.monotonic() - t0, line.rstrip("\n"), proc_status(proc.pid)))
            if self.stop is not None and not self.stopped and self.stop.search(line):
                self.stopped = True
                proc.kill()  # the process this run started, by its handle
        proc.stdout.close()

    def _reap(self, proc, t0) -> None:
        _, status, usage = os.wait4(proc.pid, 0)
        self.wall = time.monotonic() - t0
        self.returncode = proc.returncode = os.waitstatus_to_exitcode(status)
        self.peak_rss_mb = usage.ru_maxrss / 1024.0  # KB on Linux

    def first(self, pattern: re.Pattern):
        """(seconds, line, status) of the first line matching pattern, or None."""
        return next((item for item in self.lines if pattern.search(item[1])), None)

    def first_seconds(self, pattern: re.Pattern) -> float | None:
        hit = self.first(pattern)
        return None if hit is None else round(hit[0], 3)

    def _tail(self, n: int = 15) -> str:
        return f"`{' '.join(self.cmd)}`; last output:\n" + "\n".join(line for _, line, _ in self.lines[-n:])


# ----------------------------------------------------------------------------------- measurements
def measure_help(exe: str, repeats: int = 5) -> float:
    walls = []
    for _ in range(repeats):
        t0 = time.monotonic()
        subprocess.run([exe, "--help"], stdout=subprocess.DEVNULL, check=True, timeout=TIMEOUT["help"])
        walls.append(time.monotonic() - t0)
    return median(walls)


def measure_python_startup(repeats: int = 5) -> float:
    walls = []
    for _ in range(repeats):
        t0 = time.monotonic()
        subprocess.run([sys.executable, "-c", "pass"], check=True, timeout=TIMEOUT["help"])
        walls.append(time.monotonic() - t0)
    return median(walls)


def forward_cmd(exe: str, mesh: str, out: str) -> list[str]:
    return [exe, "-v", "forward", "die-slab", "--mesh", mesh, "--out", out]


def first_iteration(
    exe: str, mesh: str, cache: str | None, tmp: Path, full: bool = False, export: bool = True
) -> ChildRun:
    out = tempfile.mkdtemp(dir=tmp, prefix=f"forward-{mesh}-")
    stop = None if full else FACTORIZED
    timeout = TIMEOUT["full"] if full else TIMEOUT["first"]
    env = env_with_cache(cache, export)
    run = ChildRun(forward_cmd(exe, mesh, out), env, timeout, stop, f"forward {mesh}").run()
    if run.first(FACTORIZED) is None:
        raise RuntimeError(f"forward {mesh}: no `factorized` line on stderr (is -v still logging it?): {run._tail()}")
    return run


def iteration_sample(run: ChildRun) -> dict:
    return {
        "first_factorization": run.first_seconds(FACTORIZED),
        "first_contact_evaluation": run.first_seconds(SEGMENTED),
        "first_newton_solve_done": run.first_seconds(SOLVE_DONE),
        "process_wall": round(run.wall, 3),
        "stopped_at_first_iteration": run.stopped,
    }


def memory_timeline(run: ChildRun) -> list[dict]:
    """VmRSS/VmHWM of the child at its first contact evaluation, first factorization and each converged step."""
    marks, seen = [], set()
    for t, line, status in run.lines:
        step = STEP_DONE.search(line)
        event = (
            "first contact evaluation"
            if SEGMENTED.search(line)
            else "first factorization"
            if FACTORIZED.search(line)
            else f"load step t={step.group(1)} converged"
            if step
            else None
        )
        if event is None or event in seen or not status:
            continue
        seen.add(event)
        marks.append({"event": event, "seconds": round(t, 2), **{k: round(v, 1) for k, v in status.items()}})
    return marks


def full_forward(exe: str, mesh: str, tmp: Path) -> tuple[ChildRun, dict]:
    run = first_iteration(exe, mesh, None, tmp, full=True)
    factorizations = [line for _, line, _ in run.lines if FACTORIZED.search(line)]
    summary = {
        "peak_rss_mb": round(run.peak_rss_mb, 1),
        "wall_seconds": round(run.wall, 2),
        "newton_iterations_factorized": len(factorizations),
        "first_factorization_seconds": run.first_seconds(FACTORIZED),
        "timeline": memory_timeline(run),
    }
    return run, summary


def cantilever(exe: str, cache: str | None, tmp: Path, export: bool = True) -> ChildRun:
    out = tempfile.mkdtemp(dir=tmp, prefix="cantilever-")
    cmd = [exe, "run", "cantilever", "--max-iter", "1", "--out", out, "--no-plot", "--vtu", "none"]
    return ChildRun(cmd, env_with_cache(cache, export), TIMEOUT["cantilever"], None, "run cantilever").run()


# -------------------------------------------------------------------------------------- imports
#: what the forward command imports before its first iteration (in the child's order)
IMPORTS = (
    "import contopt.cli; contopt.cli.build_parser(); from contopt.config import setup_jax; setup_jax(); "
    "import contopt.cases.forward, contopt.solve.linear, contopt.solve.newton; "
    "import contopt.cases.die_slab, contopt.contact.system, contopt.io.vtk"
)


def import_breakdown() -> dict:
    """Self import time (python -X importtime) summed per top-level package, largest first."""
    proc = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", IMPORTS],
        capture_output=True,
        text=True,
        timeout=TIMEOUT["imports"],
    )
    if proc.returncode != 0:
        raise RuntimeError(f"python -X importtime failed: {proc.stderr[-2000:]}")
    by_package: dict[str, float] = defaultdict(float)
    count: dict[str, int] = defaultdict(int)
    for line in proc.stderr.splitlines():
        m = re.match(r"import time:\s+(\d+) \|\s+\d+ \| (\s*)(\S+)", line)
        if m:
            top = m.group(3).split(".")[0]
            by_package[top] += int(m.group(1)) / 1e6
            count[top] += 1
    total = sum(by_package.values())
    ranked = sorted(by_package.items(), key=lambda kv: -kv[1])
    head = {
        name: {"seconds": round(s, 3), "share": round(s / total, 3), "modules": count[name]} for name, s in ranked[:12]
    }
    rest = sum(s for _, s in ranked[12:])
    rest_modules = sum(count[name] for name, _ in ranked[12:])
    head["(other)"] = {"seconds": round(rest, 3), "share": round(rest / total, 3), "modules": rest_modules}
    return {"total_self_seconds": round(total, 3), "modules": sum(count.values()), "by_package": head}


# ---------------------------------------------------------------- the instrumented replay (child)
JAX_EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
    "/jax/core/compile/backend_compile_duration": "backend",
    "/jax/compilation_cache/cache_retrieval_time_sec": "cache_load",
}


class Recorder:
    """Sequential stages (seconds, VmRSS after, peak within) and timed wrappers of library functions."""

    def __init__(self):
        self.stages: list[dict] = []
        self.detail: dict[str, dict] = {}
        self.jax: dict[str, float] = defaultdict(float)
        self.active: list[str] = []  # the wrapped calls under way, outermost first
        self.can_reset_peak = self._reset_peak()

    @staticmethod
    def _reset_peak() -> bool:
        try:
            Path("/proc/self/clear_refs").write_text("5")  # resets VmHWM to the current RSS
            return True
        except OSError:
            return False

    def listen_to_jax(self) -> None:
        import jax.monitoring

        def duration(event, seconds, **_):
            if event in JAX_EVENTS:
                self.jax[JAX_EVENTS[event]] += seconds

        def counted(event, **_):
            if event.endswith(("/cache_hits", "/cache_misses")):
                self.jax[event.rsplit("/", 1)[1]] += 1

        jax.monitoring.register_event_duration_secs_listener(duration)
        jax.monitoring.register_event_listener(counted)

    def jax_summary(self, before: dict) -> dict:
        d = {k: self.jax.get(k, 0.0) - before.get(k, 0.0) for k in set(self.jax) | set(before)}
        d = {k: round(v, 3) for k, v in d.items() if v}
        if "backend" in d:  # XLA compile, or on a hit the cache key and read
            d["xla_compile"] = round(d.pop("backend") - d.get("cache_load", 0.0), 3)
        return d

    def add_stage(self, name: str, seconds: float, jax_before: dict | None = None, peak: bool = True) -> None:
        status = proc_status()
        self.stages.append(
            {
                "stage": name,
                "seconds": round(seconds, 3),
                "rss_mb": round(status.get("VmRSS", 0.0), 1),
                "peak_mb": round(status.get("VmHWM", 0.0), 1),
                "jax": self.jax_summary(jax_before or {}) if jax_before is not None else {},
            }
        )
        if peak and self.can_reset_peak:
            self._reset_peak()

    def stage(self, name: str):
        return _Stage(self, name)

    def wrap(self, owner, attr: str, bucket: str, stage: bool = False, after=None, inside: str | None = None):
        """Replace ``owner.attr`` by a timed wrapper adding to ``bucket`` (a stage of its own with
        ``stage``; nested wrappers only add to ``detail``; with ``inside``, only calls made within
        that bucket count); ``after(result)`` runs after each call."""
        original = getattr(owner, attr)

        @functools.wraps(original)
        def timed(*args, **kwargs):
            if inside is not None and inside not in self.active:
                return original(*args, **kwargs)
            jax_before, t0 = dict(self.jax), time.perf_counter()
            self.active.append(bucket)
            try:
                result = original(*args, **kwargs)
            finally:
                self.active.pop()
            self._account(bucket, time.perf_counter() - t0, jax_before, stage)
            if after is not None:
                after(result)
            return result

        setattr(owner, attr, timed)

    def _account(self, bucket: str, seconds: float, jax_before: dict, stage: bool) -> None:
        entry = self.detail.setdefault(bucket, {"seconds": 0.0, "calls": 0, "jax": {}})
        entry["seconds"] += seconds
        entry["calls"] += 1
        for key, value in self.jax_summary(jax_before).items():
            entry["jax"][key] = round(entry["jax"].get(key, 0.0) + value, 3)
        entry["rss_mb_after"] = round(proc_status().get("VmRSS", 0.0), 1)
        if stage:
            self.add_stage(bucket, seconds, jax_before)


class _Stage:
    def __init__(self, rec: Recorder, name: str):
        self.rec, self.name = rec, name

    def __enter__(self):
        self.jax_before, self.t0 = dict(self.rec.jax), time.perf_counter()
        return self

    def __exit__(self, *exc):
        if exc[0] is None:
            self.rec.add_stage(self.name, time.perf_counter() - self.t0, self.jax_before)


#: the detail buckets of the three mortar kernels start so
MORTAR = "mortar kernel: "
#: and those of the export cache (contopt.export_cache) so
KERNEL_SETUP = "kernel set-up: "


class FirstFactorization(BaseException):
    """Raised after the first factorization: the replay stops where the CLI measurement stops."""


def instrument(rec: Recorder) -> None:
    """Timers around the functions the forward command calls until its first factorization."""
    import contopt.assembly.system as asm
    import contopt.cases.forward as fwd
    import contopt.contact.system as csys
    import contopt.export_cache as export_cache
    import contopt.solve.linear as lin
    import contopt.solve.newton as newton
    import contopt.solve.system as ssys
    from contopt.assembly.sparse import SparsePattern, SubPattern

    rec.wrap(asm, "cell_geometry", "discretize: cell geometry (cell_geometry)")
    rec.wrap(SparsePattern, "from_blocks", "discretize: CSR pattern (SparsePattern.from_blocks)")
    rec.wrap(SparsePattern, "restrict", "discretize: free-dof sub-pattern (SparsePattern.restrict)")
    rec.wrap(ssys, "discretize", "discretize (assembly.system.discretize)", stage=True)
    rec.wrap(csys, "discretize_contact", "contact set-up (discretize_contact)", stage=True)
    rec.wrap(fwd, "write_state", "step-0 output (write_state: VTU + PVD)", stage=True)
    rec.wrap(asm, "element_residuals_tangents", "bulk element kernels (JAX)")
    bulk = "bulk evaluate (total)"
    for owner, attr in ((SparsePattern, "assemble_data"), (SparsePattern, "matrix"), (SubPattern, "matrix")):
        rec.wrap(owner, attr, "bulk assembly (CSR data and matrices)", inside=bulk)  # restrict uses matrix too
    rec.wrap(asm.Discretization, "evaluate", bulk)
    rec.wrap(csys, "search", "contact search + segmentation (numpy)")
    rec.wrap(csys, "paired", "contact search + segmentation (numpy)")
    for name in ("pair_values", "pair_values_and_jacobians", "pair_weighted_hessians"):
        rec.wrap(csys, name, f"{MORTAR}{name} (JAX)")
    rec.wrap(csys.ContactDiscretization, "evaluate", "contact evaluate (total)")
    # the kernels' set-up: an entry of the export cache read, or the kernel traced and exported
    rec.wrap(export_cache.Kernel, "_prepare", f"{KERNEL_SETUP}read or export (Kernel._prepare)")
    rec.wrap(export_cache, "read_entry", f"{KERNEL_SETUP}read + deserialize entries (read_entry)")
    rec.wrap(export_cache, "write_entry", f"{KERNEL_SETUP}serialize + write entries (write_entry)")
    rec.wrap(ssys.System, "evaluate", "first evaluation: residual + tangent, bulk + contact", stage=True)
    for name in list(lin._LOADERS):
        lin._LOADERS[name] = _timed_loader(rec, lin._LOADERS[name], f"solver library load: {name}")

    def stop(_):
        raise FirstFactorization

    rec.wrap(newton, "factorize", "first factorization (incl. the solver libraries' load)", stage=True, after=stop)


def _timed_loader(rec: Recorder, load, bucket: str):
    """A dict entry cannot be wrapped by setattr: time the solver library loaders here."""

    def timed():
        t0 = time.perf_counter()
        try:
            return load()
        finally:
            entry = rec.detail.setdefault(bucket, {"seconds": 0.0, "calls": 0})
            entry["seconds"] += time.perf_counter() - t0
            entry["calls"] += 1

    return timed


def child_phases(mesh: str, out: str, t_spawn: float) -> int:
    """The instrumented replay of ``contopt forward die-slab --mesh MESH`` (see the module docstring)."""
    t_main = time.monotonic()
    rec = Recorder()
    rec.add_stage("python start-up (interpreter, site, this script's stdlib imports)", t_main - t_spawn)
    tmp = tempfile.mkdtemp(dir=Path(out).parent, prefix="forward-")  # removed with the parent's folder
    with rec.stage("import contopt.cli, build the parser"):
        import contopt.cli

        args = contopt.cli.build_parser().parse_args(["forward", "die-slab", "--mesh", mesh, "--out", tmp])
        from contopt.cli.progress import setup_logging

        setup_logging(0)
    with rec.stage("setup_jax: import jax, float64, compilation cache"):
        from contopt.config import setup_jax

        setup_jax()
    rec.listen_to_jax()
    with rec.stage("import the forward command (cases.forward, solve.linear, solve.newton)"):
        from contopt.cases.forward import case_options, forward_case, run_forward
        from contopt.solve.linear import LinearSolverOptions
        from contopt.solve.newton import NewtonOptions
    with rec.stage("import what die-slab loads lazily (cases.die_slab/spec, contact.system, io.vtk)"):
        import contopt.cases.die_slab  # noqa: F401
        import contopt.contact.system  # noqa: F401
        import contopt.io.vtk  # noqa: F401
    with rec.stage("JAX runtime start (CPU client: jax.devices())"):
        import jax

        jax.devices()
    with rec.stage("problem file, meshes, model (forward_case)"):
        model, n_steps = forward_case(args.case, **case_options(args.case, args.mesh, args.divisions))
    instrument(rec)
    t0 = time.perf_counter()
    try:
        run_forward(model, tmp, newton=NewtonOptions(n_steps=n_steps), linear=LinearSolverOptions(), name=args.case)
    except FirstFactorization:
        pass
    else:
        raise RuntimeError("the forward solve ended without a factorization")
    staged = sum(s["seconds"] for s in rec.stages if s["stage"] in rec.detail)
    rec.add_stage(
        "other work of run_forward/solve_static before the first factorization", time.perf_counter() - t0 - staged
    )
    t_end = time.monotonic()
    from contopt.export_cache import kernel_sources as export_cache_sources

    result = {
        "mesh": mesh,
        "cache_dir": os.environ.get("CONTOPT_JAX_CACHE") or str(default_cache_dir()),
        "total_seconds": round(t_end - t_spawn, 3),
        "stages": rec.stages,
        "detail": {k: {**v, "seconds": round(v["seconds"], 3)} for k, v in rec.detail.items()},
        "jax_totals": rec.jax_summary({}),
        "peak_is_per_stage": rec.can_reset_peak,
        "kernel_sources": export_cache_sources(),
        "dofs": int(3 * sum(b.mesh.n_nodes for b in model.bodies)),
        "cells": int(sum(b.mesh.n_cells for b in model.bodies)),
    }
    Path(out).write_text(json.dumps(result, indent=2))
    return 0


def run_phases(mesh: str, cache: str | None, tmp: Path, export: bool = True) -> dict:
    out = Path(tempfile.mkdtemp(dir=tmp, prefix="phases-")) / "phases.json"
    cmd = [sys.executable, __file__, "--child-phases", mesh, "--child-out", str(out), "--child-t-spawn"]
    t_spawn = time.monotonic()
    env = env_with_cache(cache, export)
    run = ChildRun([*cmd, repr(t_spawn)], env, TIMEOUT["phases"], None, f"phases {mesh}").run()
    result = json.loads(out.read_text())
    result["process_peak_rss_mb"] = round(run.peak_rss_mb, 1)
    return derive(result)


def derive(result: dict) -> dict:
    """Shares of the stages, and the first evaluation split into its exclusive parts."""
    total = result["total_seconds"]
    for s in result["stages"]:
        s["share"] = round(s["seconds"] / total, 3)
    d = {k: v["seconds"] for k, v in result["detail"].items()}
    bulk, contact = d.get("bulk evaluate (total)", 0.0), d.get("contact evaluate (total)", 0.0)
    first = d.get("first evaluation: residual + tangent, bulk + contact", 0.0)
    kernels, search = d.get("bulk element kernels (JAX)", 0.0), d.get("contact search + segmentation (numpy)", 0.0)
    mortar = sum(v for k, v in d.items() if k.startswith(MORTAR))
    setup = d.get(f"{KERNEL_SETUP}read or export (Kernel._prepare)", 0.0)
    scatter = d.get("bulk assembly (CSR data and matrices)", 0.0)
    factor = d.get("first factorization (incl. the solver libraries' load)", 0.0)
    loaders = sum(v for k, v in d.items() if k.startswith("solver library load: "))
    result["kernel_setup_seconds"] = round(setup, 3)  # within the kernels' times below and step-0 output
    result["first_evaluation_split"] = {
        "bulk element kernels (JAX: trace, compile or cache load, run)": round(kernels, 3),
        "bulk assembly (CSR data, K, K_free)": round(scatter, 3),
        "bulk other (residual scatter, f_ext)": round(bulk - kernels - scatter, 3),
        "contact search + segmentation": round(search, 3),
        "mortar kernels (JAX: trace, compile or cache load, run)": round(mortar, 3),
        "contact law, residual and tangent assembly (scipy)": round(contact - search - mortar, 3),
        "K + K_contact, K_free slicing (System.evaluate)": round(first - bulk - contact, 3),
        **{k: round(v, 3) for k, v in d.items() if k.startswith("solver library load: ")},
        "factorization proper (first_factorization - library load)": round(factor - loaders, 3),
    }
    return result


# ---------------------------------------------------------------------------------------- report
def environment() -> dict:
    import jax
    import numpy
    import scipy

    return {
        "python": sys.version.split()[0],
        "jax": jax.__version__,
        "numpy": numpy.__version__,
        "scipy": scipy.__version__,
        "cpu_count": os.cpu_count(),
        "load_average_start": [round(x, 2) for x in os.getloadavg()],
        "default_jax_cache": str(default_cache_dir()),
    }


def phase_table(phases: dict) -> str:
    """Stages warm vs cold of the coarse replay, as text."""
    warm, cold = phases["coarse"].get("warm"), phases["coarse"].get("cold")
    rows = [f"{'stage':78s} {'warm s':>8s} {'share':>6s} {'cold s':>8s} {'share':>6s}  jax (cold)"]
    cold_by = {s["stage"]: s for s in cold["stages"]} if cold else {}
    for s in warm["stages"]:
        c = cold_by.get(s["stage"], {})
        jax_cold = ", ".join(f"{k} {v:g}" for k, v in c.get("jax", {}).items())
        rows.append(
            f"{s['stage'][:78]:78s} {s['seconds']:8.2f} {s['share']:6.1%} "
            f"{c.get('seconds', float('nan')):8.2f} {c.get('share', float('nan')):6.1%}  {jax_cold}"
        )
    rows.append(
        f"{'total (process start to the first factorization)':78s} {warm['total_seconds']:8.2f} {'':6s} "
        f"{cold['total_seconds'] if cold else float('nan'):8.2f}"
    )
    return "\n".join(rows)


NOTES = [
    "first_iteration_*: the forward command has no per-iteration log line; the -v debug line of "
    "contopt.solve.linear.factorize marks the end of each iteration's factorization (the solve and "
    "line search of the iteration follow, ~0.1-0.2 s coarse).",
    "phases: modules that the die-slab case imports lazily are imported in a stage of their own before the "
    "model is built (the CLI imports them inside forward_case); the sum is unchanged, the order differs.",
    "phases: the JAX CPU client is started explicitly (jax.devices()); in the CLI it starts on first use.",
    "phases: the bulk and mortar kernel times include the kernels' set-up (warm: the entries of the export "
    "cache read, contopt.export_cache; cold or with CONTOPT_EXPORT_CACHE=0: tracing and lowering), XLA "
    "compile or cache load, and the first run; the jax fields split them (xla_compile on a cache hit is "
    "the cache-key computation and deserialization; lower on a warm run is the small jit around the "
    "exported module).",
    "phases: kernels that compile in less than jax_persistent_cache_min_compile_time_secs (0.5 s, "
    "contopt.config) are never cached and compile in every process, warm or cold.",
    "phases: Python's own bytecode cache (__pycache__) and the OS file cache are warm in both runs.",
    "imports.by_package: self times from python -X importtime (inflated by its own overhead); the "
    "import stages of phases are the uninstrumented walls.",
    "peak_rss_mb: ru_maxrss of the whole forward run (all load steps), not only start-up.",
    "phases vs first_iteration: the replay runs without -v and in its own order; its total_seconds and "
    "the CLI's first factorization agree within the noise of a shared 2-core machine (compare "
    "phases.coarse.warm.totals_of_all_runs with first_iteration_samples).",
    "phases.*.stages 'step-0 output': run_forward writes the undeformed state before solving, and "
    "body_fields computes Cauchy stresses with a JAX kernel: that kernel is traced/compiled before the "
    "first iteration too.",
]


def measure(args) -> dict:
    exe, levels = contopt_exe(), [lv for lv in args.levels if not (args.skip_fine and lv == "fine")]
    tmp = Path(tempfile.mkdtemp(prefix="startup_memory_"))
    result: dict = {"environment": environment(), "notes": list(NOTES)}
    cache = default_cache_dir()
    result["environment"]["cache_entries_before"] = cache_entries(cache)
    try:
        steps = _quick_steps(result, exe, tmp) if args.quick else _steps(result, exe, tmp, levels, args.repeats)
        for name, fn in steps:
            t0 = time.monotonic()
            try:
                fn()
            except (RuntimeError, OSError, ValueError, subprocess.SubprocessError) as err:
                result["error"] = f"{name}: {err}"  # what was measured before is kept
                break
            print(f"[{time.monotonic() - T_START:6.1f} s] {name} ({time.monotonic() - t0:.1f} s)", file=sys.stderr)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    result["environment"]["cache_entries_after"] = cache_entries(cache)
    result["environment"]["load_average_end"] = [round(x, 2) for x in os.getloadavg()]
    result["environment"]["benchmark_seconds"] = round(time.monotonic() - T_START, 1)
    return result


def _quick_steps(result: dict, exe: str, tmp: Path):
    """The smallest measurement: ``help_seconds`` (one sample) and one warm ``first_iteration_seconds_warm``
    (its child's peak as ``first_iteration_peak_rss_mb``, not the whole run's ``peak_rss_mb``)."""

    def help_():
        result["help_seconds"] = round(measure_help(exe, repeats=1), 3)

    def first():
        run = first_iteration(exe, "coarse", None, tmp)
        sample = iteration_sample(run)
        result["first_iteration_samples"] = {"warm": [sample]}
        result["first_iteration_seconds_warm"] = sample["first_factorization"]
        result["first_iteration_peak_rss_mb"] = round(run.peak_rss_mb, 1)

    return [("help", help_), ("warm first iteration", first)]


def _steps(result: dict, exe: str, tmp: Path, levels: list[str], repeats: int):
    """The measurements in order, as (name, callable) filling ``result``: the warm-up first."""
    # "*_no_export": the same runs with CONTOPT_EXPORT_CACHE=0 (plain jax.jit, the state before the
    # export cache), alternating with the default ones so that both see the same machine load
    samples: dict[str, list] = {"warm": [], "cold": [], "warm_no_export": [], "cold_no_export": []}
    phases: dict = {"coarse": {}}
    result["phases"] = phases
    result["first_iteration_samples"] = samples
    memory: dict = {}

    def cold_dir():
        return tempfile.mkdtemp(dir=tmp, prefix="jax-cold-")

    def help_():
        result["help_seconds"] = round(measure_help(exe), 3)
        result["python_startup_seconds"] = round(measure_python_startup(), 3)

    def warm_up():
        for export in (True, False):
            first_iteration(exe, "coarse", None, tmp, export=export)
            cantilever(exe, None, tmp, export=export)

    def warm_first():
        for _ in range(max(repeats - 1, 1)):
            for export, kind in ((False, "warm_no_export"), (True, "warm")):
                samples[kind].append(iteration_sample(first_iteration(exe, "coarse", None, tmp, export=export)))

    def full(mesh):
        def go():
            run, memory[mesh] = full_forward(exe, mesh, tmp)
            if mesh == "coarse":
                samples["warm"].append(iteration_sample(run))

        return go

    def cold_first():
        for export, kind in ((False, "cold_no_export"), (True, "cold")):
            run = first_iteration(exe, "coarse", cold_dir(), tmp, export=export)
            samples[kind].append(iteration_sample(run))

    def cantilevers():
        warm: dict[bool, list] = {True: [], False: []}
        for _ in range(max(repeats - 1, 1)):
            for export in (False, True):
                warm[export].append(cantilever(exe, None, tmp, export=export).wall)
        cold_off = cantilever(exe, cold_dir(), tmp, export=False)
        cold = cantilever(exe, cold_dir(), tmp)
        result["cantilever_one_iteration_seconds_warm"] = round(median(warm[True]), 3)
        result["cantilever_one_iteration_seconds_cold"] = round(cold.wall, 3)
        result["cantilever_samples"] = {
            "warm": [round(w, 3) for w in warm[True]],
            "warm_no_export": [round(w, 3) for w in warm[False]],
            "cold_no_export": round(cold_off.wall, 3),
            "cold_peak_rss_mb": round(cold.peak_rss_mb, 1),
        }

    def phase(mesh, kind, n=1):
        def go():
            export = not kind.endswith("_no_export")
            runs = [run_phases(mesh, cold_dir() if kind.startswith("cold") else None, tmp, export) for _ in range(n)]
            runs.sort(key=lambda r: r["total_seconds"])
            chosen = runs[len(runs) // 2]  # the run of median total (the upper one of an even count)
            chosen["totals_of_all_runs"] = [r["total_seconds"] for r in runs]
            phases.setdefault(mesh, {})[kind] = chosen

        return go

    def imports():
        phases["imports"] = import_breakdown()

    def summarize():
        result["first_iteration_seconds_warm"] = median(s["first_factorization"] for s in samples["warm"])
        result["first_iteration_seconds_cold"] = median(s["first_factorization"] for s in samples["cold"])
        result["without_export_cache"] = {  # the same measurements with CONTOPT_EXPORT_CACHE=0, same run
            "first_iteration_seconds_warm": median(s["first_factorization"] for s in samples["warm_no_export"]),
            "first_iteration_seconds_cold": median(s["first_factorization"] for s in samples["cold_no_export"]),
            "cantilever_one_iteration_seconds_warm": median(result["cantilever_samples"]["warm_no_export"]),
            "cantilever_one_iteration_seconds_cold": result["cantilever_samples"]["cold_no_export"],
        }
        result["peak_rss_mb"] = {mesh: memory[mesh]["peak_rss_mb"] for mesh in memory}
        result["memory"] = memory

    steps = [("help", help_), ("warm-up of the compilation cache", warm_up), ("warm first iterations", warm_first)]
    steps += [(f"full forward {mesh}", full(mesh)) for mesh in levels]
    steps += [("cold first iteration", cold_first), ("cantilever warm and cold", cantilevers)]
    steps += [("phases coarse warm", phase("coarse", "warm", repeats)), ("phases coarse cold", phase("coarse", "cold"))]
    steps += [("phases coarse warm, no export cache", phase("coarse", "warm_no_export", repeats))]
    steps += [("phases fine warm", phase("fine", "warm"))] if "fine" in levels else []
    steps += [("imports", imports), ("summary", summarize)]
    return steps


T_START = time.monotonic()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", help="JSON file to write")
    p.add_argument(
        "--levels",
        nargs="+",
        choices=["coarse", "fine"],
        default=["coarse", "fine"],
        help="die-slab meshes whose whole forward run gives peak_rss_mb (fine: also its phases, warm)",
    )
    p.add_argument("--skip-fine", action="store_true", help="leave out the fine mesh (its run takes minutes)")
    p.add_argument("--repeats", type=int, default=3, help="warm samples of the first iteration and cantilever")
    p.add_argument("--quick", action="store_true", help="help and one warm first iteration (seconds)")
    p.add_argument("--child-phases", choices=["coarse", "fine"], help=argparse.SUPPRESS)
    p.add_argument("--child-out", help=argparse.SUPPRESS)
    p.add_argument("--child-t-spawn", type=float, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child_phases:
        return child_phases(args.child_phases, args.child_out, args.child_t_spawn)
    if not args.out:
        p.error("--out is required")
    result = measure(args)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    if "error" in result:
        print(f"startup_memory: error: {result['error']}\n(partial results in {out})", file=sys.stderr)
        return 1
    if "phases" in result:
        print(phase_table(result["phases"]))
    keys = ("help_seconds", "first_iteration_seconds_warm", "first_iteration_seconds_cold")
    keys += ("cantilever_one_iteration_seconds_warm", "cantilever_one_iteration_seconds_cold", "peak_rss_mb")
    for key in (k for k in keys if k in result):
        print(f"{key}: {result[key]}")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
