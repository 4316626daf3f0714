"""The ``contopt`` command line. The CLI owns the terminal: logging goes to stderr."""

from __future__ import annotations

import logging
import signal
import sys
import threading
import traceback

from contopt.cli.describe import cmd_explain, cmd_schema
from contopt.cli.exits import CHECK_FAILED, DONE, FAILED, Terminated, exit_status, out_of_memory
from contopt.cli.info import cmd_info
from contopt.cli.mesh import cmd_mesh
from contopt.cli.parser import build_parser
from contopt.cli.problem import read_problem
from contopt.cli.progress import Progress, ProgressHandler, duration, progress_line, setup_logging
from contopt.errors import ContoptError


def _cmd_list(args) -> int:
    from contopt.cases.forward import FORWARD_CASES
    from contopt.cases.optimization import OPTIMIZATION_CASES
    from contopt.cases.spec import bundled_cases, cases_dir

    print("optimization cases (contopt run NAME [--mesh M] [--design D]; the first variant is the default):")
    for case in OPTIMIZATION_CASES.values():
        variants = "; ".join(
            f"--{axis} {'|'.join(names)}" for axis, names in (("mesh", case.meshes), ("design", case.designs)) if names
        )
        print(f"  {case.name:20s} {case.description}" + (f" [{variants}]" if variants else ""))
    print("analysis cases (contopt forward NAME, contopt check-gradient NAME):")
    for analysis in FORWARD_CASES.values():
        print(f"  {analysis.name:20s} {analysis.description}")
    print(
        "problem files (contopt export NAME writes a copy to edit; contopt run FILE.toml runs it, "
        "contopt check-gradient FILE.toml checks its gradients):"
    )
    print(f"  {', '.join(f'{name}.toml' for name in bundled_cases())}")
    print(f"  in {cases_dir()}")
    return DONE


def run_spec(args):
    """What `contopt run` runs: a problem file, a case or a bundled file, with the flags applied."""
    from pathlib import Path

    flagged = (
        ("optimizer.name", "--optimizer", args.optimizer),
        ("run.max_iter", "--max-iter", args.max_iter),
        ("run.out", "--out", args.out),
        ("run.vtu", "--vtu", args.vtu),
        ("run.plot", "--no-plot", False if args.no_plot else None),
        ("run.case_workers", "--case-workers", args.case_workers),
        ("linear.backend", "--solver", args.solver),
        ("run.design_from", "--design-from", args.design_from and str(Path(args.design_from).absolute())),
    )
    return read_problem(args.case, args.set, flagged, mesh=args.mesh, design=args.design, eta=args.eta)


def _run_command(args) -> str:
    """The `contopt run` command line of ``args`` (for the copy of the problem file in the run directory)."""
    import shlex

    words = ["contopt", "run", args.case]
    for flag, value in (
        ("--design", args.design),
        ("--mesh", args.mesh),
        ("--optimizer", args.optimizer),
        ("--eta", args.eta),
        ("--max-iter", args.max_iter),
        ("--out", args.out),
        ("--vtu", args.vtu),
        ("--solver", args.solver),
        ("--case-workers", args.case_workers),
        ("--design-from", args.design_from),
    ):
        if value is not None:
            words += [flag, str(value)]
    for item in args.set or ():
        words += ["--set", item]
    words += ["--no-plot"] * bool(args.no_plot) + ["--resume"] * bool(args.resume)
    return shlex.join(words)


def _cmd_run(args) -> int:
    from contopt.config import setup_jax

    setup_jax()
    from contopt.errors import ConfigError
    from contopt.optimize.driver import RESUME_AND_OVERWRITE, RESUME_AND_START

    if args.resume and args.overwrite:  # before the problem is built
        raise ConfigError(RESUME_AND_OVERWRITE)
    if args.resume and args.design_from is not None:
        raise ConfigError(RESUME_AND_START)
    if args.verbose == 0:  # the progress lines say what matters; -v shows every Newton solve
        logging.getLogger("contopt").setLevel(logging.WARNING)
    shown = Progress()
    handler = ProgressHandler(shown)
    progress_log = logging.getLogger("contopt.progress")
    progress_log.addHandler(handler)
    progress_log.setLevel(logging.INFO)
    progress_log.propagate = False  # its lines are ours (with -v they would be printed twice)
    try:
        return _run_and_report(args, shown)
    finally:
        shown.stop()
        progress_log.removeHandler(handler)


def _run_and_report(args, shown: Progress) -> int:
    from pathlib import Path

    from contopt.io.files import write_atomically

    shown.line(f"reading the problem: {args.case}")
    spec = run_spec(args)
    max_iter, out = spec.max_iter, Path(spec.out)
    disc = spec.discretization
    size = f"{disc.n_dofs:,} dofs, {disc.n_cells:,} cells; " if disc is not None else ""
    shown.line(
        f"problem {spec.name}: {size}optimizer {spec.optimizer}, at most {max_iter} iterations; results in {out}"
    )
    for iface in spec.problem.model.interfaces:  # the sides contopt chose (contact given as two surfaces)
        if iface.choice:
            shown.line(
                f"contact {iface.nonmortar[0]}/{iface.nonmortar[1]} <-> {'/'.join(iface.mortar)}: {iface.choice}"
            )

    def started(run_dir):  # the run directory is locked and accepted: keep what is run next to the results
        header = f"# {_run_command(args)}\n# (its flags replace values of the file below)\n"
        text = header + spec.text + ("" if spec.text.endswith("\n") else "\n")
        write_atomically(Path(run_dir) / "problem.toml", lambda tmp: tmp.write_text(text, encoding="utf-8"))

    def progress(row, eta):
        shown.line(progress_line(row, eta, max_iter), now=f"iteration {row['iteration'] + 1}: analysis")

    res = spec.run(resume=args.resume, overwrite=args.overwrite, progress=progress, started=started)
    vf = ", ".join(f"{d['body']} {v:.4f}" for d, v in zip(res.design_summary, res.volume_fractions))
    print(
        f"{spec.name}: {res.status} after {res.iterations} iterations ({res.analyses} analyses, "
        f"{duration(res.seconds)}); objective {res.objective:.6g}, f/|f0| {res.normalized_objective:.6g}; "
        f"volume fraction {vf}"
    )
    print(f"results in {out}: {', '.join(_written(out))}")
    if res.status == "failed":  # what was reached is kept; the exit status says it failed
        print(f"the optimization failed: {res.message}", file=sys.stderr)
        return FAILED
    return DONE


def _written(out) -> list[str]:
    """What a run directory holds for a person (the checkpoint and the lock are the run's own)."""
    first = ("report.html", "summary.json")
    names = sorted(p.name for p in out.iterdir() if p.is_file() and not p.name.startswith("."))
    shown = [n for n in first if n in names] + [n for n in names if n not in first]
    vtu = sorted((out / "vtu").glob("*.vtu")) if (out / "vtu").is_dir() else []
    if vtu:
        shown.append(f"vtu/ ({len(vtu)} VTU file{'s' * (len(vtu) != 1)})")
    return shown


def _cmd_export(args) -> int:
    from pathlib import Path

    from contopt.cases.optimization import OPTIMIZATION_CASES
    from contopt.cases.spec import bundled_cases, case_file_text
    from contopt.errors import ConfigError
    from contopt.io.files import write_atomically

    bundled = bundled_cases()
    if args.case in bundled:
        text = bundled[args.case].read_text(encoding="utf-8")
    elif args.case in OPTIMIZATION_CASES:  # a case is its bundled file: only where that is not found
        text = case_file_text(args.case)
    else:
        raise ConfigError(f"unknown case {args.case!r}; choose one of {sorted(set(bundled) | set(OPTIMIZATION_CASES))}")
    if args.out == "-":
        sys.stdout.write(text)
        return DONE
    path = Path(args.out or f"{args.case}.toml")
    if path.exists() and not args.force:
        raise ConfigError(f"{path} already exists; choose another --out or pass --force to replace it")
    write_atomically(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))  # OutputError: one line
    print(f"wrote {path}; edit it, then: contopt run {path}")
    return DONE


def _cmd_report(args) -> int:
    from contopt.io.render import picture_size
    from contopt.io.scene import check_max_triangles
    from contopt.optimize.report import make_pictures, report_text
    from contopt.optimize.report_forward import forward_summary, write_forward_report
    from contopt.optimize.report_html import write_report_html

    size = picture_size(args.size)  # bad options fail before anything is printed
    check_max_triangles(args.max_triangles)
    forward = forward_summary(args.dir)
    if forward is not None:  # a `contopt forward` directory: no design, no checkpoint
        state = "converged" if forward.get("converged") else f"failed ({forward.get('error', '')})".splitlines()[0]
        print(f"forward run {args.dir}: {forward.get('case')}, {state}, {forward.get('load_steps')} load steps")
        if not args.no_html:
            print(f"report: {write_forward_report(args.dir, args.max_triangles)} (open it in a browser)")
        return DONE
    print(report_text(args.dir), flush=True)
    if not args.no_pictures:
        made = make_pictures(args.dir, size=size)
        print("pictures: " + (", ".join(str(path) for path in made.values()) or "none (see the messages above)"))
    if not args.no_html:
        print(f"report: {write_report_html(args.dir, max_triangles=args.max_triangles)} (open it in a browser)")
    return DONE


def _mirror_planes(items) -> tuple:
    """``["z=0", ...]`` -> ``(("z", 0.0), ...)``; ConfigError naming the bad item."""
    from contopt.errors import ConfigError

    planes = []
    for item in items or ():
        axis, sep, value = item.partition("=")
        try:
            planes.append((axis.strip(), float(value)))
        except ValueError:
            sep = ""
        if not sep or axis.strip() not in ("x", "y", "z"):
            raise ConfigError(f"--mirror needs AXIS=VALUE with AXIS x, y or z (e.g. --mirror z=0), got {item!r}")
    return tuple(planes)


def _cmd_export_design(args) -> int:
    from contopt.design.surface import SurfaceOptions
    from contopt.io.surface import surface_format

    options = SurfaceOptions(refine=args.refine, smooth=args.smooth, mirror=_mirror_planes(args.mirror))
    if args.out is not None:
        surface_format(args.out)  # a wrong extension fails before the problem is rebuilt
    from contopt.config import setup_jax

    setup_jax()
    from contopt.cases.export import export_design

    result = export_design(args.dir, args.out, options, binary=not args.ascii)
    print("\n".join(result.lines()), flush=True)
    if args.png:
        from contopt.io.render import render_surface

        bodies = ", ".join(f"{s.body} {s.surface.n_faces} triangles" for s in result.surfaces)
        title = f"{result.run_dir.name}: {bodies}"
        picture = render_surface(
            [s.surface for s in result.surfaces], args.png, title=title, boxes=[s.bounds for s in result.surfaces]
        )
        print(f"picture: {picture}")
    return DONE


def _cmd_forward(args) -> int:
    from contopt.config import setup_jax

    setup_jax()
    import math

    from contopt.cases.forward import FORWARD_CASES, case_options, forward_case, forward_lines, run_forward
    from contopt.errors import ConfigError
    from contopt.solve.newton import NewtonOptions

    if args.steps is not None and args.steps < 1:
        raise ConfigError(f"--steps must be a positive number of load steps, got {args.steps}")
    if args.friction is not None and not (math.isfinite(args.friction) and args.friction >= 0):
        raise ConfigError(f"--friction must be a friction coefficient, a number >= 0 (e.g. 0.3), got {args.friction}")
    linear = _linear_options(args)
    model, n_steps = forward_case(
        args.case, friction=args.friction, **case_options(args.case, args.mesh, args.divisions)
    )
    newton = NewtonOptions(n_steps=n_steps if args.steps is None else args.steps)
    import shlex

    command = shlex.join(["contopt", *sys.argv[1:]]) if sys.argv[1:2] == ["forward"] else None
    summary = run_forward(
        model,
        args.out,
        newton=newton,
        linear=linear,
        name=args.case,
        description=FORWARD_CASES[args.case].description,
        command=command,
    )
    print("\n".join(forward_lines(args.case, summary)))
    print(f"open {summary['pvd']} in ParaView")
    return DONE


def _linear_options(args):
    """The LinearSolverOptions of ``--solver`` (forward, check-gradient); ConfigError naming the flag."""
    from contopt.errors import ConfigError
    from contopt.solve.linear import LinearSolverOptions
    from contopt.solve.linear.options import BACKEND_CHOICES

    if args.solver not in BACKEND_CHOICES:
        raise ConfigError(
            f"--solver: {args.solver!r} is not one of {', '.join(map(repr, BACKEND_CHOICES))} "
            "(`contopt info` lists those installed here)"
        )
    return LinearSolverOptions(backend=args.solver)


def _cmd_check_gradient(args) -> int:
    from contopt.config import setup_jax

    setup_jax()
    from contopt.cases.checks import check_case
    from contopt.cases.forward import FORWARD_CASES
    from contopt.cli.problem import is_problem_file

    if is_problem_file(args.case) or args.case not in FORWARD_CASES:
        # a problem file or an optimization case: df/dx, dg/dx through the whole chain from the design variables
        return _check_design(args)
    if args.set:
        from contopt.errors import ConfigError

        raise ConfigError(
            f"--set replaces values of a problem file; {args.case!r} is an analysis case: use its flags "
            "(--divisions, --mesh, --law), or check a problem file (`contopt export NAME` writes a case's)"
        )
    report = check_case(
        args.case,
        mesh=args.mesh,
        divisions=args.divisions,
        law=args.law,
        responses=args.response,
        rho=args.rho,
        n_random=args.directions,
        n_cells=args.cells,
        h=args.h,
        tol=args.tol,
        method=args.method,
        seed=args.seed,
        linear=_linear_options(args),
    )
    adj = report.adjoint
    print(
        f"{args.case}: primal {report.seconds['primal']:.1f} s ({report.state.newton_iterations} Newton iterations, "
        f"{report.state.alm_updates} ALM updates); adjoint {report.seconds['adjoint']:.2f} s "
        f"({adj.method}, {adj.linear_solves} linear solves for {len(adj.sensitivities)} responses, "
        f"active contact nodes {list(adj.active)}); finite differences {report.seconds['finite_differences']:.1f} s"
    )
    print(report.table())
    return DONE if report.passed else CHECK_FAILED


def _check_design(args) -> int:
    """check-gradient of an optimization problem (a case, a bundled or a user's problem file), read as
    `contopt run` reads it: df/dx and dg/dx of the objective and every constraint along random directions."""
    from contopt.cases.checks import check_design

    spec = _design_check_spec(args)
    disc = spec.discretization
    size = f" ({disc.n_dofs:,} dofs, {disc.n_cells:,} cells)" if disc is not None else ""
    objective = spec.problem.objective
    what = f"objective {getattr(objective, 'name', type(objective).__name__)}"
    print(f"{spec.name}{size}: design gradient check of {args.case}, {what}", flush=True)
    design = check_design(
        spec.problem, spec.name, n_random=args.directions, h=args.h or 1e-4, tol=args.tol or 1e-5, seed=args.seed
    )
    print(f"{spec.name}: design gradient check, {design.seconds:.1f} s")
    print(design.table())
    return DONE if design.passed else CHECK_FAILED


def _design_check_spec(args):
    """The RunSpec check-gradient checks: `contopt run`'s reading of ``args.case`` with --mesh, --design
    and --set, and --law on every contact interface (before --set, which may replace one)."""
    from contopt.cases.forward import FORWARD_CASES

    also = f", an analysis case {sorted(FORWARD_CASES)}"
    read = dict(mesh=args.mesh, design=args.design, kind="case", also=also, purpose="check its design gradients")
    spec = read_problem(args.case, args.set, **read)
    if args.law is None:
        return spec
    flagged = tuple((f"contact[{i}].law", "--law", args.law) for i in range(len(spec.problem.model.interfaces)))
    return read_problem(args.case, args.set, flagged, **read)


#: what each sub-command of :func:`contopt.cli.parser.build_parser` runs
COMMANDS = {
    "list": _cmd_list,
    "info": cmd_info,
    "forward": _cmd_forward,
    "check-gradient": _cmd_check_gradient,
    "run": _cmd_run,
    "export": _cmd_export,
    "report": _cmd_report,
    "export-design": _cmd_export_design,
    "schema": cmd_schema,
    "explain": cmd_explain,
    "mesh": cmd_mesh,
}


def main(argv: list[str] | None = None) -> int:
    """The ``contopt`` command: its exit status (:mod:`contopt.cli.exits`)."""
    try:
        return _main(argv)
    except (MemoryError, ImportError, SystemError) as err:  # parsing loads modules: under `ulimit -v` that can fail
        message = out_of_memory(err)
        if message is None:
            raise
        print(f"contopt: error: {message}", file=sys.stderr)
        return exit_status(err)


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return DONE
    setup_logging(-1 if args.quiet else args.verbose)
    from contopt.cli import distributed  # under mpiexec: every rank runs it, rank 0 speaks

    previous = _catch_sigterm()
    try:
        return distributed.run(args, _command)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _on_sigterm(signum, frame) -> None:
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a second SIGTERM ends the process at once
    raise Terminated()


def _catch_sigterm():
    """End on SIGTERM as on Ctrl-C (:class:`Terminated`); the handler it replaces, or None where it cannot
    (not the main thread: Python takes signals there only)."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _on_sigterm)


def _command(args) -> int:
    """The sub-command's status, or the status of what stopped it (:mod:`contopt.cli.exits`, one table)."""
    try:
        return COMMANDS[args.command](args)
    except KeyboardInterrupt as e:  # Ctrl-C, or SIGTERM (Terminated)
        how = "terminated (SIGTERM)" if isinstance(e, Terminated) else "interrupted"
        print(f"contopt: {how}; results written so far are kept (contopt run --resume continues)", file=sys.stderr)
        return exit_status(e)
    except ContoptError as e:
        print(f"contopt: error: {e}", file=sys.stderr)
        return exit_status(e)
    except Exception as e:  # a bug: its traceback, and a status a script can tell from a failed check
        message = out_of_memory(e)
        if message is not None:  # no bug: the memory allowed is too small for the problem
            print(f"contopt: error: {message}", file=sys.stderr)
            return exit_status(e)
        traceback.print_exc()
        print(
            f"contopt: unexpected error ({type(e).__name__}): please report it with the traceback above",
            file=sys.stderr,
        )
        return exit_status(e)
