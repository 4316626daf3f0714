"""The argument parser of the ``contopt`` command line: one function per sub-command.

Building it loads no JAX and no solver: the lists of names a flag takes are imported when argparse
first needs them (:class:`Names`). ``args.command`` names the sub-command that the package runs.
"""

from __future__ import annotations

import argparse
import textwrap

from contopt import __version__
from contopt.cli.exits import CHECK_FAILED, FAILED, epilog

#: the help of --solver of forward and check-gradient. The backends' names are checked by
#: LinearSolverOptions (a one-line error lists them); naming them here would load the solvers (scipy)
#: for every command
SOLVER_HELP = "sparse solver (default auto: the fastest found; `contopt info` lists them)"


class Names:
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


def build_parser() -> argparse.ArgumentParser:
    """The parser of every sub-command; ``args.command`` is None when none is given."""
    description = (
        "Topology optimization of hyperelastic bodies in contact under large deformation. "
        "Run an optimization (run), solve an analysis (forward) or check sensitivities (check-gradient)."
    )
    p = argparse.ArgumentParser(
        prog="contopt",
        description=textwrap.fill(description, 100),
        epilog=epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,  # the table of exit statuses as written
    )
    p.add_argument("--version", action="version", version=f"contopt {__version__}")
    p.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    p.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.add_parser("list", help="list the named cases")
    sub.add_parser("info", help="show the version and available sparse solvers")
    _forward_parser(sub)
    _check_gradient_parser(sub)
    _run_parser(sub)
    _export_parser(sub)
    _report_parser(sub)
    _export_design_parser(sub)
    _describe_parsers(sub)
    _mesh_parser(sub)
    return p


def _forward_parser(sub) -> None:
    sp = sub.add_parser("forward", help="solve a forward example and write VTU/PVD per load step")
    sp.add_argument("case", nargs="?", default="block-compression", help="case name (see `contopt list`)")
    sp.add_argument("--out", default="results", help="output directory (default: results)")
    sp.add_argument("--steps", type=int, default=None, help="initial number of load steps")
    sp.add_argument("--divisions", type=int, default=None, help="cells per cube edge (block cases)")
    sp.add_argument("--mesh", default=None, help="mesh variant of the die cases (default: their file's, coarse)")
    sp.add_argument("--friction", type=float, metavar="MU", help="Coulomb friction mu on every contact interface")
    sp.add_argument("--solver", default="auto", help=SOLVER_HELP)


def _check_gradient_parser(sub) -> None:
    sp = sub.add_parser(
        "check-gradient",
        help="compare adjoint sensitivities with central finite differences",
        description="Solve the case at a random grey design, compute the sensitivities of its "
        "responses by the adjoint method and compare them with central finite differences of the "
        "full nonlinear solve, on random directions and on single cells (some at the contact "
        "surface). An optimization case that is no analysis case (`contopt list` tells them apart), "
        "or a problem file FILE.toml read as `contopt run` reads it (with --mesh, --design and --set), "
        "gets the check of df/dx and dg/dx from the design variables through the whole chain instead. "
        f"Exits with status {CHECK_FAILED} when a relative error exceeds the tolerance "
        "(`contopt --help` lists every status).",
    )
    sp.add_argument(
        "case",
        nargs="?",
        default="die-slab",
        help="case name (see `contopt list`) or the path of a problem file FILE.toml",
    )
    sp.add_argument(
        "--mesh", default=None, help="mesh variant of the die cases and of an optimization case (default: their file's)"
    )
    sp.add_argument("--divisions", type=int, default=None, help="cells per edge (other cases)")
    sp.add_argument(
        "--law",
        choices=Names("contopt.contact.laws", "LAWS"),
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
        choices=Names("contopt.cases.checks", "RHO_FIELDS"),
        default="random",
        metavar="FIELD",
        help="material field to check at: %(choices)s (default %(default)s)",
    )
    _check_gradient_numerics(sp)
    sp.add_argument(
        "--set",
        action="append",
        default=None,
        metavar="KEY=VALUE",
        help="replace a value of the problem file (of an optimization case or FILE.toml), as for run, "
        "e.g. --set objective.response=force-max (repeatable)",
    )


def _check_gradient_numerics(sp) -> None:
    """The options of check-gradient that say how it checks: directions, steps, tolerance, solvers."""
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
        choices=Names("contopt.adjoint.options", "METHODS"),
        default="schur-cg",
        metavar="METHOD",
        help="adjoint saddle-point solver for ALM contact: %(choices)s (default %(default)s)",
    )
    sp.add_argument("--seed", type=int, default=0, help="random seed (design and directions)")
    sp.add_argument("--solver", default="auto", help=SOLVER_HELP)


def _run_parser(sub) -> None:
    sp = sub.add_parser(
        "run",
        help="optimize a case or a problem file (checkpointed: --resume continues a run)",
        description="Optimize a case (a bundled problem file, see `contopt list`) or a problem "
        "file (FILE.toml) from the all-grey design (or --design-from another run's). The flags "
        "below replace the file's values. Each "
        "iteration appends to OUT/history.csv, writes the design and state to OUT/design.pvd, "
        "redraws OUT/convergence.png and stores a checkpoint; --resume continues a run that was "
        "interrupted (even by kill -9) and reproduces its iterates. Exits with status "
        f"{FAILED} when an analysis or the optimizer failed (its trial designs could not be analysed); what it "
        "reached is kept (`contopt --help` lists every status).",
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
        choices=Names("contopt.optimize.base", "OPTIMIZERS"),
        metavar="NAME",
        default=None,
        help="optimizer: %(choices)s (default: the case's or the file's; mma when neither says)",
    )
    sp.add_argument("--eta", type=float, default=None, help="Heaviside sharpness eta (default 10)")
    sp.add_argument("--max-iter", type=int, default=None, help="optimizer iterations (default 100)")
    sp.add_argument("--out", default=None, help="run directory (default: the file's run.out, else results)")
    _run_output_options(sp)


def _run_output_options(sp) -> None:
    """The options of run from --set on: replacements, the run directory's fate and what it gets."""
    sp.add_argument(
        "--set",
        action="append",
        default=None,
        metavar="KEY=VALUE",
        help="replace a value of the problem file, e.g. --set design.bodies[0].volume_fraction=0.3 (repeatable)",
    )
    sp.add_argument("--resume", action="store_true", help="continue the run in --out")
    sp.add_argument(
        "--design-from",
        default=None,
        metavar="RUN",
        help="start from another run's last design (its directory), a VTU file of a designed body or a "
        "run's design.pvd, carried to this mesh and design space and lowered to the volume limits "
        "(default: the file's run.design_from, else the all-grey design; not with --resume)",
    )
    sp.add_argument(
        "--solver", default=None, help="linear solver (as for forward; default: the file's [linear] backend, else auto)"
    )
    sp.add_argument("--overwrite", action="store_true", help="start afresh even if --out holds a run")
    sp.add_argument(
        "--vtu",
        choices=Names("contopt.optimize.output_options", "VTU_MODES"),
        default=None,
        metavar="WHEN",
        help="VTU output: %(choices)s (default: every iteration, or the file's run.vtu)",
    )
    sp.add_argument("--no-plot", action="store_true", help="do not redraw convergence.png every iteration")
    sp.add_argument(
        "--case-workers",
        type=int,
        default=None,
        metavar="N",
        help="analyse the load cases in N worker processes (default: the file's run.case_workers, else 1)",
    )


def _export_parser(sub) -> None:
    sp = sub.add_parser(
        "export",
        help="write the problem file (TOML) of a case, to copy and edit",
        description="Write the bundled problem file of a case (see `contopt list`) so that it "
        "can be edited and run with `contopt run FILE.toml`.",
    )
    sp.add_argument("case", help="case name (see `contopt list`)")
    sp.add_argument("--out", default=None, help="file to write (default CASE.toml; - writes to stdout)")
    sp.add_argument("--force", action="store_true", help="replace an existing file")


def _describe_parsers(sub) -> None:
    sp = sub.add_parser(
        "schema",
        help="write the JSON Schema of a problem file (for an editor's TOML support)",
        description="Write the JSON Schema (draft 2020-12) of a problem file: every key with its type, "
        "allowed values, unit, default and description. Taplo / Even Better TOML use it for completion and "
        'checks: "#:schema ./contopt.schema.json" atop a problem file (docs/schema.md).',
    )
    sp.add_argument("--out", default=None, help="file to write (default: standard output)")
    sp = sub.add_parser(
        "explain",
        help="say what a key of a problem file means, its type, default and allowed values",
        description="Say what a key of a problem file means: its description, type, unit, default and "
        "allowed values. KEY is its path without list indices, e.g. contact.law, newton.max_iter.",
    )
    sp.add_argument("key", metavar="KEY", help="e.g. contact.law, design.bodies.bspline, newton.max_iter")


def _report_parser(sub) -> None:
    from contopt.io.scene import MAX_TRIANGLES

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


def _mesh_parser(sub) -> None:
    sp = sub.add_parser(
        "mesh",
        help="mesh a CAD file (STEP, IGES, BREP, STL) with hex8 by Gmsh, or list its named surfaces",
        description="Mesh the one solid of a CAD file with hex8 cells (Gmsh's tetrahedra, each split into "
        "four hexes; the cad extra) and write the mesh with its surfaces as named facet sets (the CAD's "
        "names, else surface_N), to inspect it or to give as mesh = { file = ... }. --list lists a CAD "
        "file's surfaces (without --size: no meshing) or a mesh file's sets.",
    )
    sp.add_argument(
        "file", metavar="FILE", help="CAD file (.step .stp .iges .igs .brep .stl); with --list also a mesh file"
    )
    sp.add_argument("--size", type=float, default=None, help="the elements' edge length, about, in the model's unit")
    sp.add_argument(
        "--order", type=int, default=1, help="element order: 1 (hex8 or tet4) or 2 (tet10, with --element tet)"
    )
    sp.add_argument(
        "--element", choices=("hex8", "tet"), default="hex8", help="hex8 (tets split into hexes) or tet (Gmsh's tets)"
    )
    sp.add_argument("--scale", type=float, default=1.0, help="multiply the CAD's coordinates (0.001: mm to m)")
    sp.add_argument("--out", default=None, help="mesh file to write: .msh, .vtu or .e (default FILE's name .msh, here)")
    sp.add_argument("--list", action="store_true", help="list the named surfaces (facet sets) and the bounding box")
    sp.add_argument(
        "--envelope",
        action="store_true",
        help="voxels instead: the hex8 cubes of edge --size whose centres lie inside FILE, a closed surface "
        "(.stl .ply .obj, or a CAD solid); sets boundary and xmin .. zmax (as mesh = { envelope = ... })",
    )
