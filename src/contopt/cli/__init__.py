"""The ``contopt`` command line. The CLI owns the terminal: logging goes to stderr."""

from __future__ import annotations

import argparse
import logging
import sys

from contopt import __version__
from contopt.cli.info import cmd_info as _cmd_info
from contopt.cli.progress import Progress, ProgressHandler, duration, progress_line, setup_logging
from contopt.errors import ContoptError


class _Names:
    """A list of names its owner module declares, imported when argparse first needs it (to check a
    value or to show the command's help), so that building the parser does not load JAX. Give the
    argument a ``metavar``: argparse would list the names when the argument is added."""

    def __init__(self, module: str, name: str):
        self.module, self.name = module, name

    def _names(self):
        from importlib import import_module

        return list(getattr(import_module(self.module), self.name))

    def __iter__(self):
        return iter(self._names())

    def __contains__(self, value) -> bool:
        return value in self._names()


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
    for case in FORWARD_CASES.values():
        print(f"  {case.name:20s} {case.description}")
    print("problem files (contopt export NAME writes a copy to edit; contopt run FILE.toml runs it):")
    print(f"  {', '.join(f'{name}.toml' for name in bundled_cases())}")
    print(f"  in {cases_dir()}")
    return 0


def _run_spec(args):
    """What `contopt run` runs: a problem file, a case or a bundled file, with the flags applied."""
    from pathlib import Path

    from contopt.cases.optimization import OPTIMIZATION_CASES
    from contopt.cases.spec import bundled_cases, load_spec
    from contopt.cases.toml_reader import toml_value
    from contopt.errors import ConfigError

    overrides, origins = {}, {}
    flagged = (
        ("optimizer.name", "--optimizer", args.optimizer),
        ("run.max_iter", "--max-iter", args.max_iter),
        ("run.out", "--out", args.out),
        ("run.vtu", "--vtu", args.vtu),
        ("run.plot", "--no-plot", False if args.no_plot else None),
        ("linear.backend", "--solver", args.solver),
    )
    for key, flag, value in flagged:
        if value is not None:
            overrides[key], origins[key] = value, flag
    for item in args.set or ():
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set needs KEY=VALUE (e.g. --set design.bodies[0].volume_fraction=0.3), got {item!r}")
        overrides[key.strip()], origins[key.strip()] = toml_value(text.strip()), "--set"
    flags = dict(overrides=overrides, origins=origins, mesh=args.mesh, design=args.design, eta=args.eta)
    source = args.case
    if source.endswith(".toml") or Path(source).is_file():
        if not Path(source).is_file():
            raise ConfigError(f"no such problem file: {source}")
        return load_spec(Path(source), **flags)
    if source in OPTIMIZATION_CASES:  # a file that names the case: what a run directory keeps of it
        return load_spec(f'case = "{source}"', label=source, **flags)
    bundled = bundled_cases()
    if source in bundled:
        return load_spec(bundled[source], label=f"{source}.toml", **flags)
    raise ConfigError(
        f"unknown optimization case {source!r}; give a case {sorted(OPTIMIZATION_CASES)}, a bundled "
        f"problem file {sorted(bundled)} or the path of a .toml file"
    )


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
    from contopt.optimize.driver import RESUME_AND_OVERWRITE

    if args.resume and args.overwrite:  # before the problem is built
        raise ConfigError(RESUME_AND_OVERWRITE)
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
    spec = _run_spec(args)
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
        return 2
    return 0


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

    bundled = bundled_cases()
    if args.case in bundled:
        text = bundled[args.case].read_text(encoding="utf-8")
    elif args.case in OPTIMIZATION_CASES:  # a case is its bundled file: only where that is not found
        text = case_file_text(args.case)
    else:
        raise ConfigError(f"unknown case {args.case!r}; choose one of {sorted(set(bundled) | set(OPTIMIZATION_CASES))}")
    if args.out == "-":
        sys.stdout.write(text)
        return 0
    path = Path(args.out or f"{args.case}.toml")
    if path.exists() and not args.force:
        raise ConfigError(f"{path} already exists; choose another --out or pass --force to replace it")
    try:
        path.write_text(text, encoding="utf-8")
    except OSError as err:
        raise ConfigError(f"cannot write {path}: {err}") from err
    print(f"wrote {path}; edit it, then: contopt run {path}")
    return 0


def _cmd_report(args) -> int:
    from contopt.io.render import picture_size
    from contopt.io.scene import check_max_triangles
    from contopt.optimize.report import make_pictures, report_text
    from contopt.optimize.report_html import write_report_html

    size = picture_size(args.size)  # bad options fail before anything is printed
    check_max_triangles(args.max_triangles)
    print(report_text(args.dir), flush=True)
    if not args.no_pictures:
        made = make_pictures(args.dir, size=size)
        print("pictures: " + (", ".join(str(path) for path in made.values()) or "none (see the messages above)"))
    if not args.no_html:
        print(f"report: {write_report_html(args.dir, max_triangles=args.max_triangles)} (open it in a browser)")
    return 0


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
    return 0


def _cmd_forward(args) -> int:
    from contopt.config import setup_jax

    setup_jax()
    from contopt.cases.forward import case_options, forward_case, forward_lines, run_forward
    from contopt.errors import ConfigError
    from contopt.solve.linear import LinearSolverOptions
    from contopt.solve.newton import NewtonOptions

    if args.steps is not None and args.steps < 1:
        raise ConfigError(f"--steps must be a positive number of load steps, got {args.steps}")
    model, n_steps = forward_case(
        args.case, friction=args.friction, **case_options(args.case, args.mesh, args.divisions)
    )
    newton = NewtonOptions(n_steps=n_steps if args.steps is None else args.steps)
    summary = run_forward(
        model, args.out, newton=newton, linear=LinearSolverOptions(backend=args.solver), name=args.case
    )
    print("\n".join(forward_lines(args.case, summary)))
    print(f"open {summary['pvd']} in ParaView")
    return 0


def _cmd_check_gradient(args) -> int:
    from contopt.config import setup_jax

    setup_jax()
    from contopt.cases.checks import check_case, check_design_case
    from contopt.cases.forward import FORWARD_CASES
    from contopt.cases.optimization import OPTIMIZATION_CASES
    from contopt.solve.linear import LinearSolverOptions

    if args.case not in FORWARD_CASES and args.case in OPTIMIZATION_CASES:
        # an optimization case only: check df/dx, dg/dx through the whole chain from the design variables
        design = check_design_case(
            args.case,
            mesh=args.mesh,
            design=args.design,
            n_random=args.directions,
            h=args.h or 1e-4,
            tol=args.tol or 1e-5,
            seed=args.seed,
        )
        print(f"{args.case}: design gradient check, {design.seconds:.1f} s")
        print(design.table())
        return 0 if design.passed else 1
    report = check_case(
        args.case,
        mesh=args.mesh,
        divisions=args.divisions,
        enforcement=args.enforcement,
        responses=args.response,
        rho=args.rho,
        n_random=args.directions,
        n_cells=args.cells,
        h=args.h,
        tol=args.tol,
        method=args.method,
        seed=args.seed,
        linear=LinearSolverOptions(backend=args.solver),
    )
    adj = report.adjoint
    print(
        f"{args.case}: primal {report.seconds['primal']:.1f} s ({report.state.newton_iterations} Newton iterations, "
        f"{report.state.alm_updates} ALM updates); adjoint {report.seconds['adjoint']:.2f} s "
        f"({adj.method}, {adj.linear_solves} linear solves for {len(adj.sensitivities)} responses, "
        f"active contact nodes {list(adj.active)}); finite differences {report.seconds['finite_differences']:.1f} s"
    )
    print(report.table())
    return 0 if report.passed else 1


def _export_design_parser(sub) -> None:
    sp = sub.add_parser(
        "export-design",
        help="write the optimized design's surface (STL, PLY or OBJ)",
        description="Write a closed (watertight, manifold) triangle surface of the material of "
        "each designed body of the run in DIR, for CAD, 3D printing or meshing: the level set "
        "phi = 0 of a B-spline design, sampled on a lattice REFINE times finer than the mesh, or "
        "the iso-surface nu = 1/2 of a density design's nodal volume fraction (Taubin-smoothed, "
        "volume kept). Symmetric designs give the whole part. Prints the volume enclosed against "
        "the design's volume fraction times the domain volume.",
    )
    sp.add_argument("dir", metavar="DIR", help="run directory (the --out of `contopt run`)")
    sp.add_argument(
        "--out",
        default=None,
        help="surface file: .stl (binary unless --ascii), .ply or .obj "
        "(default DIR/design.stl); several designed bodies: one file each, NAME_BODY.stl",
    )
    sp.add_argument("--refine", type=int, default=3, help="lattice spacings per mesh cell (default 3)")
    sp.add_argument(
        "--smooth",
        type=int,
        default=None,
        help="Taubin smoothing steps (default: 10 for density designs, 0 for level sets)",
    )
    sp.add_argument(
        "--mirror",
        action="append",
        default=None,
        metavar="AXIS=VALUE",
        help="mirror the modelled part across the plane AXIS = VALUE, e.g. --mirror z=0 for the "
        "sabot, whose upper half is modelled (repeatable)",
    )
    sp.add_argument("--ascii", action="store_true", help="ASCII STL or PLY instead of binary")
    sp.add_argument("--png", default=None, metavar="FILE", help="also draw the surfaces into this picture (headless)")
    sp.set_defaults(func=_cmd_export_design)


def build_parser() -> argparse.ArgumentParser:
    from contopt.io.scene import MAX_TRIANGLES

    # the backends' names are checked by LinearSolverOptions (a one-line error lists them); naming them
    # here would load the solvers (scipy) for every command
    solvers = "sparse solver (default auto: the fastest found; `contopt info` lists them)"

    p = argparse.ArgumentParser(
        prog="contopt",
        description=(
            "Topology optimization of hyperelastic bodies in contact under large deformation. "
            "Run an optimization (run), solve an analysis (forward) or check sensitivities (check-gradient)."
        ),
    )
    p.add_argument("--version", action="version", version=f"contopt {__version__}")
    p.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    p.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sp = sub.add_parser("list", help="list the named cases")
    sp.set_defaults(func=_cmd_list)
    sp = sub.add_parser("info", help="show the version and available sparse solvers")
    sp.set_defaults(func=_cmd_info)
    sp = sub.add_parser("forward", help="solve a forward example and write VTU/PVD per load step")
    sp.add_argument("case", nargs="?", default="block-compression", help="case name (see `contopt list`)")
    sp.add_argument("--out", default="results", help="output directory (default: results)")
    sp.add_argument("--steps", type=int, default=None, help="initial number of load steps")
    sp.add_argument("--divisions", type=int, default=None, help="cells per cube edge (block cases)")
    sp.add_argument("--mesh", default=None, help="mesh variant of the die cases (default: their file's, coarse)")
    sp.add_argument("--friction", type=float, metavar="MU", help="Coulomb friction mu on every contact interface")
    sp.add_argument("--solver", default="auto", help=solvers)
    sp.set_defaults(func=_cmd_forward)
    sp = sub.add_parser(
        "check-gradient",
        help="compare adjoint sensitivities with central finite differences",
        description="Solve the case at a random grey design, compute the sensitivities of its "
        "responses by the adjoint method and compare them with central finite differences of the "
        "full nonlinear solve, on random directions and on single cells (some at the contact "
        "surface). An optimization case that is no analysis case (`contopt list` tells them apart) "
        "gets the check of df/dx and dg/dx from the design variables through the whole chain instead. "
        "Exits with status 1 when a relative error exceeds the tolerance.",
    )
    sp.add_argument("case", nargs="?", default="die-slab", help="case name (see `contopt list`)")
    sp.add_argument(
        "--mesh", default=None, help="mesh variant of the die cases and of an optimization case (default: their file's)"
    )
    sp.add_argument("--divisions", type=int, default=None, help="cells per edge (other cases)")
    sp.add_argument(
        "--enforcement",
        choices=_Names("contopt.contact.laws", "LAWS"),
        metavar="LAW",
        default=None,
        help="contact law: %(choices)s (default: the case's)",
    )
    sp.add_argument(
        "--response",
        action="append",
        default=None,
        metavar="NAME",
        help="built-in response to check (repeatable; default: all that apply to the case; a name "
        "that is none gets the list)",
    )
    sp.add_argument(
        "--rho",
        choices=_Names("contopt.cases.checks", "RHO_FIELDS"),
        default="random",
        metavar="FIELD",
        help="material field to check at: %(choices)s (default %(default)s)",
    )
    sp.add_argument("--directions", type=int, default=1, help="random directions (default 1)")
    sp.add_argument("--cells", type=int, default=5, help="single cells (default 5)")
    sp.add_argument(
        "--h",
        type=float,
        default=None,
        help="finite-difference step in rho, or in x for optimization cases (default 1e-4; 1e-3 with friction)",
    )
    sp.add_argument("--design", default=None, help="design variant of an optimization case (see `contopt list`)")
    sp.add_argument("--tol", type=float, default=None, help="relative tolerance (default 1e-5 ALM, 1e-6 otherwise)")
    sp.add_argument(
        "--method",
        choices=_Names("contopt.adjoint.sensitivity", "METHODS"),
        default="schur-cg",
        metavar="METHOD",
        help="adjoint saddle-point solver for ALM contact: %(choices)s (default %(default)s)",
    )
    sp.add_argument("--seed", type=int, default=0, help="random seed (design and directions)")
    sp.add_argument("--solver", default="auto", help=solvers)
    sp.set_defaults(func=_cmd_check_gradient)
    sp = sub.add_parser(
        "run",
        help="optimize a case or a problem file (checkpointed: --resume continues a run)",
        description="Optimize a case (a bundled problem file, see `contopt list`) or a problem "
        "file (FILE.toml) from the all-grey design. The flags below replace the file's values. Each "
        "iteration appends to OUT/history.csv, writes the design and state to OUT/design.pvd, "
        "redraws OUT/convergence.png and stores a checkpoint; --resume continues a run that was "
        "interrupted (even by kill -9) and reproduces its iterates. Exits with status 2 when the "
        "optimizer failed (its trial designs could not be analysed); what it reached is kept.",
    )
    sp.add_argument(
        "case",
        nargs="?",
        default="cantilever",
        help="case name (see `contopt list`) or the path of a problem file FILE.toml",
    )
    sp.add_argument(
        "--design",
        default=None,
        help="design variant of a case or a file (see `contopt list` and the file's [variants])",
    )
    sp.add_argument("--mesh", default=None, help="mesh variant of a case or a file (as --design)")
    sp.add_argument(
        "--optimizer",
        choices=_Names("contopt.optimize.base", "OPTIMIZERS"),
        metavar="NAME",
        default=None,
        help="optimizer: %(choices)s (default: the case's or the file's; mma when neither says)",
    )
    sp.add_argument("--eta", type=float, default=None, help="Heaviside sharpness eta (default 10)")
    sp.add_argument("--max-iter", type=int, default=None, help="optimizer iterations (default 100)")
    sp.add_argument("--out", default=None, help="run directory (default: the file's run.out, else results)")
    sp.add_argument(
        "--set",
        action="append",
        default=None,
        metavar="KEY=VALUE",
        help="replace a value of the problem file, e.g. --set design.bodies[0].volume_fraction=0.3 (repeatable)",
    )
    sp.add_argument("--resume", action="store_true", help="continue the run in --out")
    sp.add_argument(
        "--solver", default=None, help="linear solver (as for forward; default: the file's [linear] backend, else auto)"
    )
    sp.add_argument("--overwrite", action="store_true", help="start afresh even if --out holds a run")
    sp.add_argument(
        "--vtu",
        choices=_Names("contopt.optimize.driver", "VTU_MODES"),
        default=None,
        metavar="WHEN",
        help="VTU output: %(choices)s (default: every iteration, or the file's run.vtu)",
    )
    sp.add_argument("--no-plot", action="store_true", help="do not redraw convergence.png every iteration")
    sp.set_defaults(func=_cmd_run)
    sp = sub.add_parser(
        "export",
        help="write the problem file (TOML) of a case, to copy and edit",
        description="Write the bundled problem file of a case (see `contopt list`) so that it "
        "can be edited and run with `contopt run FILE.toml`.",
    )
    sp.add_argument("case", help="case name (see `contopt list`)")
    sp.add_argument("--out", default=None, help="file to write (default CASE.toml; - writes to stdout)")
    sp.add_argument("--force", action="store_true", help="replace an existing file")
    sp.set_defaults(func=_cmd_export)
    sp = sub.add_parser(
        "report",
        help="summarize a run directory, draw its pictures, write report.html",
        description="Print a summary of the run in DIR (finished, interrupted or running), "
        "(re)draw DIR/design.png (volume-fraction iso-surfaces), DIR/deformed.png (deformed "
        "bodies coloured by contact pressure), DIR/convergence.png and, with contact, "
        "DIR/pressure_history.png, and write DIR/report.html: the summary, the pictures and an "
        "interactive 3D view in one file that a browser opens offline.",
    )
    sp.add_argument("dir", metavar="DIR", help="run directory (the --out of `contopt run`)")
    sp.add_argument("--no-pictures", action="store_true", help="do not redraw the pictures")
    sp.add_argument("--no-html", action="store_true", help="do not write report.html")
    sp.add_argument(
        "--max-triangles",
        type=int,
        default=MAX_TRIANGLES,
        metavar="N",
        help=f"triangles of report.html's 3D view at most, decimated above (default {MAX_TRIANGLES})",
    )
    sp.add_argument(
        "--size",
        type=int,
        nargs=2,
        metavar=("W", "H"),
        default=[1200, 900],
        help="picture size in pixels (default 1200 900)",
    )
    sp.set_defaults(func=_cmd_report)
    _export_design_parser(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    setup_logging(-1 if args.quiet else args.verbose)
    from contopt.cli import distributed  # under mpiexec: every rank runs it, rank 0 speaks

    return distributed.run(args, _command)


def _command(args) -> int:
    try:
        return args.func(args)
    except ContoptError as e:
        print(f"contopt: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("contopt: interrupted; results written so far are kept", file=sys.stderr)
        return 130
