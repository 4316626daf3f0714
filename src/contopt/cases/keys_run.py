"""The keys of a problem file's design and how it is run: ``[design]``, ``[objective]``,
``[[constraints]]``, ``[optimizer]``, ``[run]``, the solvers' options, ``[variants]`` and a named
case's ``[case_options]`` (:mod:`contopt.cases.keys`)."""

from __future__ import annotations

from contopt.adjoint.options import METHODS, AdjointOptions
from contopt.cases.keys import (
    ANGLE,
    LENGTH,
    NO_DEFAULT,
    Key,
    Kind,
    Section,
    arg,
    fields_section,
)
from contopt.contact.laws import INTERMEDIATE, AugmentationOptions
from contopt.design import (
    BSplineGrid,
    CyclicSymmetry,
    DesignedBody,
    EtaContinuation,
    Heaviside,
    RadialSkin,
    Robust,
    Simp,
)
from contopt.design.space import SKIN_SIDES
from contopt.design.symmetry import AXES
from contopt.optimize.base import OPTIMIZERS
from contopt.optimize.ipopt import HESSIANS, MU_STRATEGIES, IpoptOptions
from contopt.optimize.load_case import COMBINES
from contopt.optimize.mma import MMAOptions
from contopt.optimize.output_options import VIEW_AXES, VTU_MODES, OutputOptions
from contopt.responses.catalog import OPTIONS, RESPONSES
from contopt.solve.linear import options as linear
from contopt.solve.newton_options import LINE_SEARCHES, NewtonOptions

#: the objective's sense
SENSES = ("maximize", "minimize")

_BOX = (
    Key("lower", "vector", "the box's lowest corner (-inf allowed)", LENGTH),
    Key("upper", "vector", "the box's highest corner (inf allowed)", LENGTH),
    Key(
        "file",
        "string",
        "instead of a box: a closed surface (.stl .ply .obj, or .step .stp .iges .igs .brep through Gmsh), "
        "relative to the problem file; a bare file name stands for {file = NAME}",
    ),
    Key("scale", "number", "the file's coordinates are multiplied by it", default=1.0),
)


def _response_section(path: str, doc: str, extra: tuple[Key, ...]) -> Section:
    """[objective] or [[constraints]]: response = NAME, its options, and the table's own ``extra`` keys."""
    common = (
        Key("response", "string", "the built-in response", choices=tuple(RESPONSES), required=True),
        Key("name", "string", OPTIONS["name"].doc),
        *extra,
    )
    kinds = tuple(
        Kind(
            "response",
            name,
            tuple(
                Key(
                    o,
                    OPTIONS[o].type,
                    OPTIONS[o].doc,
                    OPTIONS[o].unit,
                    choices=OPTIONS[o].choices,
                    table=OPTIONS[o].table,
                    required=o in kind.required,
                )
                for o in kind.options
            ),
        )
        for name, kind in RESPONSES.items()
    )
    return Section(path, doc, common, kinds)


#: the design's tables, the responses', the options' and the variants'
RUN_SECTIONS = (
    Section(
        "design",
        "the design maps and the designed bodies",
        (
            arg(Heaviside, "eta", "number", doc="Heaviside sharpness (level set -> volume fraction)"),
            arg(Simp, "p", "number", doc="SIMP power"),
            arg(Simp, "nu0", "number", doc="SIMP floor: the stiffness share void keeps"),
            Key("bodies", "tables", "one table per designed body", table="design.bodies", required=True),
            Key(
                "robust",
                "table",
                "the robust formulation (density designs): the worst of the eroded, intermediate and dilated designs",
                table="design.robust",
            ),
            Key(
                "eta_continuation",
                "table",
                "raise the Heaviside sharpness within the run, from start to eta (density and B-spline designs)",
                table="design.eta_continuation",
            ),
        ),
    ),
    Section(
        "design.eta_continuation",
        "a continuation of the Heaviside sharpness: start at eta = start, multiply it by factor after every `every` "
        "iterations or as soon as the optimizer converges, up to [design] eta; the design variables are rescaled so "
        "that the volume fraction is kept",
        (
            arg(EtaContinuation, "start", "number", doc="the first sharpness, > 0 and below [design] eta"),
            arg(EtaContinuation, "factor", "number", doc="eta's growth per step, > 1"),
            arg(EtaContinuation, "every", "integer", doc="iterations at each sharpness before it is raised, >= 1"),
        ),
    ),
    Section(
        "design.robust",
        "the robust formulation: projections at the thresholds 1/2 + delta, 1/2 and 1/2 - delta of the filtered "
        "density",
        (arg(Robust, "delta", "number", doc="the threshold's shift, in (0, 0.5)"),),
    ),
    Section(
        "design.bodies",
        "how one body is designed: density or bspline, and what else constrains it",
        (
            arg(DesignedBody, "body", "string", required=True, default=NO_DEFAULT),
            arg(DesignedBody, "volume_fraction", "number", default=NO_DEFAULT),
            Key(
                "density",
                "table",
                "the density method: one variable per cell, cone filter",
                table="design.bodies.density",
            ),
            Key(
                "bspline",
                "table",
                "a B-spline level set on a grid of control points",
                table="design.bodies.bspline",
            ),
            Key(
                "symmetry",
                "table",
                "cyclic symmetry (and reflection) about an axis",
                table="design.bodies.symmetry",
            ),
            Key("skins", "tables", "solid skins by radius about an axis", table="design.bodies.skins"),
            Key(
                "solid",
                "regions",
                "cells fixed solid: a box {lower, upper}, a closed surface (a file name, or {file, scale}), or a list "
                "of them (by cell centre)",
                table="design.bodies.solid",
            ),
            Key(
                "void",
                "regions",
                "cells fixed void: a box {lower, upper}, a closed surface (a file name, or {file, scale}), or a list "
                "of them (by cell centre)",
                table="design.bodies.void",
            ),
            arg(DesignedBody, "skin_eps", "number"),
        ),
    ),
    Section(
        "design.bodies.density",
        "the density method",
        (Key("radius", "number", "the cone filter's radius", LENGTH, required=True),),
    ),
    Section(
        "design.bodies.bspline",
        "a B-spline grid: control_points or patches; its box lower, upper or origin, lengths (default: the "
        "body's bounding box)",
        (
            Key("control_points", "ints", "control points per direction [nx, ny, nz]"),
            arg(BSplineGrid, "patches", "ints", default=NO_DEFAULT),
            arg(BSplineGrid, "degree", "integer"),
            Key("lower", "vector", "the grid box's lowest corner", LENGTH),
            Key("upper", "vector", "the grid box's highest corner", LENGTH),
            Key("origin", "vector", "the grid box's lowest corner (with lengths)", LENGTH),
            Key("lengths", "vector", "the grid box's edge lengths (with origin)", LENGTH),
        ),
    ),
    Section(
        "design.bodies.symmetry",
        "cyclic symmetry",
        (
            arg(
                CyclicSymmetry,
                "n_sectors",
                "integer",
                key="sectors",
                doc="the number of equal sectors",
                required=True,
                default=NO_DEFAULT,
            ),
            arg(CyclicSymmetry, "reflection", "boolean", doc="also mirror each sector about its midplane"),
            arg(CyclicSymmetry, "axis", "string", choices=tuple(AXES)),
            arg(CyclicSymmetry, "center", "vector", LENGTH),
            arg(CyclicSymmetry, "start", "angle", ANGLE),
        ),
    ),
    fields_section(
        "design.bodies.skins",
        RadialSkin,
        "a solid skin",
        units={"radius": LENGTH, "center": LENGTH},
        choices={"side": SKIN_SIDES, "axis": tuple(AXES)},
        types={"center": "vector"},
    ),
    Section("design.bodies.solid", "a box or a closed surface of cells fixed solid", _BOX),
    Section("design.bodies.void", "a box or a closed surface of cells fixed void", _BOX),
    _response_section(
        "objective",
        "the response minimized or maximized",
        (
            Key(
                "sense",
                "string",
                "minimize or maximize the response",
                choices=SENSES,
                default="minimize",
            ),
            Key(
                "normalize",
                "normalize",
                'divide by |f| at the "full" design, the "initial" one, "none", or a number',
                default="full",
            ),
            Key(
                "combine",
                "string",
                'with [[load_cases]]: the weighted "sum" of the cases\' objectives or the "worst" case',
                choices=COMBINES,
                default="sum",
            ),
        ),
    ),
    _response_section(
        "constraints",
        "a response bounded above and/or below",
        (
            Key("upper", "number", "its upper bound"),
            Key("lower", "number", "its lower bound"),
            Key("scale", "number", "the constraint's scale (default: its value at the start)"),
            Key("case", "string", "with [[load_cases]]: the case it holds in (default: every case)"),
        ),
    ),
    Section(
        "optimizer",
        "the optimizer",
        (
            Key("name", "string", "the optimizer", choices=OPTIMIZERS, default=OPTIMIZERS[0]),
            Key("mma", "table", "MMA's options", table="optimizer.mma"),
            Key("ipopt", "table", "IPOPT's options", table="optimizer.ipopt"),
        ),
    ),
    fields_section(
        "optimizer.mma", MMAOptions, "MMA's options (the iteration limit is run.max_iter)", exclude=("max_iter",)
    ),
    fields_section(
        "optimizer.ipopt",
        IpoptOptions,
        "IPOPT's options (the iteration limit is run.max_iter)",
        exclude=("max_iter",),
        choices={"hessian": HESSIANS, "mu_strategy": MU_STRATEGIES},
        tables={"options": "optimizer.ipopt.options"},
    ),
    Section("optimizer.ipopt.options", "raw IPOPT options, name = value (a string, integer or number)", free=True),
    Section(
        "run",
        "the iteration limit and what a run writes",
        (
            arg(
                MMAOptions,
                "max_iter",
                "integer",
                doc="optimizer iterations after the initial design (either optimizer)",
            ),
            Key("out", "string", "the run directory", default="results"),
            arg(OutputOptions, "vtu", "string", choices=VTU_MODES),
            arg(OutputOptions, "plot", "boolean"),
            Key("warm_start", "boolean", "start each analysis from the last design's state", default=True),
            Key(
                "case_workers",
                "integer",
                "with [[load_cases]]: worker processes that analyse the cases in parallel (1: one after the other)",
                default=1,
            ),
            Key(
                "design_from",
                "string",
                "start from this design instead of the grey one: a run directory (its last iteration's "
                "design), a VTU file of a designed body (its nu) or a run's design.pvd; carried to this "
                "mesh and design space and lowered to the volume limits (relative to the working "
                "directory, as out; a resumed run keeps its own start)",
            ),
            arg(OutputOptions, "view_up", "string", choices=VIEW_AXES),
        ),
    ),
    fields_section("newton", NewtonOptions, "Newton and the load steps", choices={"line_search": LINE_SEARCHES}),
    fields_section(
        "augmentation", AugmentationOptions, "the augmented-Lagrangian loop", choices={"intermediate": INTERMEDIATE}
    ),
    fields_section(
        "linear",
        linear.LinearSolverOptions,
        "the sparse linear solver",
        choices={
            "backend": linear.BACKEND_CHOICES,
            "pardiso_matrix_type": tuple(linear.PARDISO_MATRIX_TYPES),
            "pardiso_scaling": linear.PARDISO_SCALINGS,
            "singular_check": linear.SINGULAR_CHECKS,
            "forcing": linear.FORCINGS,
            "preconditioner": linear.PRECONDITIONERS,
            "factor_precision": linear.FACTOR_PRECISIONS,
            "unsymmetric_krylov": linear.UNSYMMETRIC_KRYLOVS,
        },
    ),
    fields_section("adjoint", AdjointOptions, "the adjoint solve", choices={"method": METHODS}),
    Section(
        "variants",
        "the file's choices for --mesh and --design; the first of each list is the file as written",
        (
            Key("mesh", "names", "the names --mesh chooses among"),
            Key("design", "names", "the names --design chooses among"),
            Key("when", "tables", "replacements that apply when choices are made", table="variants.when"),
        ),
    ),
    Section(
        "variants.when",
        "replacements made when the choices are made",
        (
            Key("mesh", "string", "the --mesh choice this applies to"),
            Key("design", "string", "the --design choice this applies to"),
            Key(
                "set",
                "table",
                'key path = value, as --set takes them ("bodies[0].mesh.divisions" = [...])',
                table="variants.when.set",
                required=True,
            ),
        ),
    ),
    Section("variants.when.set", "key path = value", free=True),
    Section(
        "case_options",
        "the named case's choices",
        (
            Key("mesh", "string", "the case's mesh variant (contopt list)"),
            Key("design", "string", "the case's design variant (contopt list)"),
            arg(Heaviside, "eta", "number", doc="Heaviside sharpness", default=NO_DEFAULT),
        ),
    ),
)

#: the sections above by path
RUN = {s.path: s for s in RUN_SECTIONS}
