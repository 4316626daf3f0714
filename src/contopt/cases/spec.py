"""Design problems described in TOML files: ``load_spec(path_or_text) -> RunSpec``, or only the
model a file describes: ``load_model(path_or_text) -> Model`` (which loads no JAX).

A problem file either describes everything (the long form) or names a
bundled case (the short form). Lists of tables (``[[bodies]]``) are
numbered from 0 in messages: ``bodies[1]`` is the second body. Lengths,
moduli and loads are in whatever consistent units the model uses; angles
are in radians under their plain name (``arc``) or in degrees with the
suffix ``_deg`` (``arc_deg``).

Long form
---------
::

    name, description                 optional strings (shown by `contopt run`)

    [[bodies]]                        one table per body
      name                            unique body name
      mesh = {generator = "box", lengths, divisions, origin, grading}
           | {generator = "cylinder_shell_sector", radius, arc|arc_deg, width, thickness,
              divisions, center, axis, mid_angle|mid_angle_deg, outward}
           | {generator = "annulus", r_inner, r_outer, length, divisions, theta|theta_deg, center}
           | {generator = "cylinder", radius, length, divisions, center, core_size, core_roundness}
           | {file = "part.msh", body = "..."}     (relative to the TOML file; .msh .vtu .e .exo)
      material = {model = "neo-hookean", E, nu, mass_density}
               | {model = "mooney-rivlin", E, nu, b_fraction, mass_density}
               | {model = "mooney-rivlin", kappa, A, B, mass_density}
      fbar = true                     mean-dilatation F-bar
      [[bodies.sets]]                 extra named sets made from the mesh's own
        name                          the new set's name
        from = "all"                  a facet set (gives a facet set and a node set) or a node set
        x, y, z = [min, max]          keep what lies in these ranges (facets by their centre)
        nearest = [x, y, z]           or: the node of `from` nearest to this point (or a list of
                                      points: one node each, in that order)

    [[bodies]]                        a rigid tool (no unknowns, no material; the mortar side of its
      name                            contact; its sets: surface, all; docs/contact.md)
      rigid = {shape = "plane", center, normal, size, divisions}
            | {shape = "cylinder", radius, length, center, axis, divisions, arc|arc_deg, normal}
            | {shape = "sphere", radius, center, divisions, normal, angle|angle_deg}
            | {file = "tool.stl", scale = 1.0}      (relative to the TOML file; any surface meshio reads)
            (and flip = false, thickness = 0.5)
      motion = {value = [ux, uy, uz] | path = [[t, ux, uy, uz], ...],
                rotation = {axis, point = [0, 0, 0], angle|angle_deg = a number or [[t, angle], ...]}}
                                      absent: the tool stays where it is

    [[supports]]                      prescribed displacements (supports and prescribed motions)
      body, set                       a node set (every facet set is also a node set)
      components = "xyz"              which components, e.g. "z" for a roller
      value = 0.0                     one number, or one per component; scaled by the load factor

    [[soft_supports]]                 springs to ground fading as (1 - t), for a body held only by contact
      body, stiffness                 force per length per unit reference volume (see SoftSupport)

    [[loads]]
      type = "traction"      body, set (a facet set), traction = [tx, ty, tz]  (per reference area)
      type = "body-force"    body, force = [bx, by, bz]                       (per reference volume)
      type = "acceleration"  body, acceleration = [ax, ay, az]  (inertia -rho a; needs mass_density)

    [[contact]]                       frictionless mortar contact
      nonmortar = {body, set}         carries the pressure: the finer (or more curved, softer) surface
      mortar = {body, set}
      surfaces = [{body, set}, {body, set}]   instead: the nonmortar side chosen for you (said in the log)
      law = "alm" | "penalty"         the contact law (contopt.contact.laws)
      name                            what responses call it (default "{nonmortar body}-{mortar body}")
      eps, skin, max_angle_deg        optional (see ContactInterface)
      check = {tolerance, enabled}    the check of every converged state (PenetrationCheck)

    [design]
      eta = 10.0, p = 3.0, nu0 = 0.01  Heaviside sharpness, SIMP power, SIMP floor
      robust = {delta = 0.15}         the robust formulation (density designs; docs/optimization.md)
      [[design.bodies]]
        body
        volume_fraction               nu_max of the body's volume constraint (omit: none)
        density = {radius}            cone filter of this radius
        bspline = {control_points = [nx, ny, nz] | patches = [...], degree = 3,
                   lower, upper | origin, lengths}   (box: default the body's bounding box)
        symmetry = {sectors, reflection = true, axis = "z", center, start|start_deg}
        skins = [{radius, side = "inside"|"outside", slope = 5.0, axis = "z", center}, ...]
        solid, void = {lower, upper}, a closed surface (file name or {file, scale}) or a list of them
                                                   cells fixed solid / void
        skin_eps = 1e-4

    [objective]
      response                        strain-energy | compliance | contact-force | pressure-variance
                                      | volume-fraction | stress
      sense = "minimize" | "maximize"
      bodies = "slab" or [...]        strain-energy, compliance, volume-fraction, stress (default all)
      interfaces = ["die-slab"]       contact-force, pressure-variance, friction-force: [[contact]] names
      normalized = false              pressure-variance: divide by the squared mean pressure
      quadrature = "overlap"          contact-force: the pressure over the overlap (the force the
                                      bodies exchange) or "gauss" (the paper's appendix A reading)
      direction = [x, y, z] | "norm"  contact-force: the resultant of the interface's forces along
                                      a direction or its size (the reaction, on curved contacts too)
      p = 8.0, q = 0.5                stress: the p-norm's exponent (>= 2) and the relaxation
                                      rho^q of the von Mises stress (q in [0, 1])
      normalize = "full"              divide by |f| at the full design; "initial", "none" or a number

      combine = "sum" | "worst"       with [[load_cases]]: the cases' weighted sum, or the worst case
    [[constraints]]                   response, its keys as above, upper and/or lower, scale,
                                      case (with [[load_cases]]: the case it holds in; default every case)

    [[load_cases]]                    several load cases over the same bodies, contact and design
      name, weight = 1.0              the case's name and its weight (> 0) in the combined objective
      [[load_cases.supports]]  [[load_cases.soft_supports]]  [[load_cases.loads]]
                                      this case's own, besides the file's (which hold in every case)
      [[load_cases.motions]]          body (a rigid tool), value | path, rotation: its motion in this case

    [optimizer]
      name = "mma" | "ipopt"
      [optimizer.mma]                 MMAOptions: move, kkt_tol, change_tol, asyinit, ...
      [optimizer.ipopt]               IpoptOptions: tol, hessian, print_level, ...
        [optimizer.ipopt.options]     raw IPOPT options, name = value

    [newton]  [augmentation]  [linear]  [adjoint]    NewtonOptions, AugmentationOptions,
                                      LinearSolverOptions, AdjointOptions (their field names)

    [run]
      max_iter = 100, out = "results", vtu = "every" | "final" | "none", plot = true,
      warm_start = true, view_up = "x" | "y" | "z" (the pictures' up axis; default: the push),
      design_from = a run directory, a VTU or a PVD file (the start design; default: the grey one),
      case_workers = 1 (with [[load_cases]]: worker processes that analyse the cases in parallel)

Variants
--------
::

    [variants]                        the file's choices for --mesh and --design (or the
      mesh = ["coarse", "fine"]       [case_options] of a file naming it); the first of each
      design = ["bspline", "density"] list is the file as written
    [[variants.when]]                 replacements that apply when the choices are made
      mesh = "fine"                   the choices (one or both axes)
      set = {"bodies[0].mesh.divisions" = [45, 20, 15]}   key path = value, as --set takes them
                                      (a path may end at a list entry: "design.bodies[0]" = {...});
                                      applied in the order written, before the flags

Short form
----------
::

    case = "die-slab"                 a bundled case (`contopt list`): its problem file
    [case_options]  mesh, design, eta the case's variants and the Heaviside sharpness
    [optimizer]  [run]  [newton]  [augmentation]  [linear]  [adjoint]   as above: their keys
                                      replace the case file's (a table such as [optimizer.mma]
                                      replaces the case's table)

Overrides (``--set``, the flags) apply to the case file's keys, whatever the section.

Errors are :class:`SpecError` (a :class:`~contopt.errors.ConfigError`): one
line ``file: key.path: reason`` naming the allowed values, with a
did-you-mean suggestion for unknown keys and names.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from contopt.assembly.model import Model
from contopt.cases.keys import ABSENT, PRESENT
from contopt.cases.keys_model import COMMON, MODEL
from contopt.cases.keys_run import RUN
from contopt.cases.optimization import OPTIMIZATION_CASES, bundled_cases, cases_dir
from contopt.cases.spec_cases import read_load_cases
from contopt.cases.spec_design import BoxUnion, check_design, read_constraints, read_design, read_objective
from contopt.cases.spec_model import read_model
from contopt.cases.spec_run import (
    RECIPE_FILE,
    RunSpec,
    header_flags,
    read_optimizer,
    read_solver_options,
    read_texts,
)
from contopt.cases.toml_reader import Reader, SpecError, Table, parse_toml
from contopt.errors import ConfigError

__all__ = [
    "BoxUnion",
    "RunSpec",
    "SpecError",
    "bundled_cases",
    "case_file_text",
    "cases_dir",
    "load_model",
    "load_run_spec",
    "load_spec",
]

#: what --mesh and --design choose among: the [variants] of a file
VARIANT_AXES = ("mesh", "design")
_SHORT = MODEL[""].allowed(PRESENT)


def load_spec(
    source,
    overrides: Mapping[str, Any] | None = None,
    *,
    mesh: str | None = None,
    design: str | None = None,
    eta: float | None = None,
    label: str | None = None,
    base_dir=None,
    check: bool = True,
    origins: Mapping[str, str] | None = None,
) -> RunSpec:
    """Read a problem file (or TOML text) into a :class:`RunSpec`.

    Parameters
    ----------
    source : a path (``Path``, or a ``str`` without ``=`` or a newline) or the TOML text itself
    overrides : ``{"run.max_iter": 2, "design.bodies[0].volume_fraction": 0.3, ...}`` replacing (or
        adding) values before the file is checked, so their errors name the key like the file's own
    mesh, design : the variants to use (the file's ``[variants]``, or those of the case it names)
    eta : the Heaviside sharpness ``design.eta``
    label : the name errors give a text source (default ``"<toml>"``)
    base_dir : folder relative mesh files are read from (default: the file's folder, or the cwd for text)
    check : build the model's discretization and every designed body's design matrix now, so that
        what only those reveal (a B-spline box missing cells, a filter radius below the cell size)
        names its ``design.bodies[i]`` entry; the discretization is kept for :meth:`RunSpec.run`
    origins : ``{key path: "--flag"}`` where an override came from, for messages (default "override")
    """
    text, label, base = _read_source(source, label, base_dir)
    recipe = {
        "text": text,
        "label": label,
        "base_dir": str(base.resolve()),
        "overrides": dict(overrides or {}),
        "origins": dict(origins or {}),
        "mesh": mesh,
        "design": design,
        "eta": eta,
    }
    r, data, case = _document(text, label, base, overrides, origins, {"mesh": mesh, "design": design, "eta": eta})
    spec = _long_form(r, data, text, check)
    return dataclasses.replace(spec, case=case, recipe=recipe)


def load_model(
    source,
    overrides: Mapping[str, Any] | None = None,
    *,
    mesh: str | None = None,
    design: str | None = None,
    label: str | None = None,
    base_dir=None,
    origins: Mapping[str, str] | None = None,
) -> Model:
    """Read the model of a problem file (or TOML text): its :class:`~contopt.assembly.model.Model`
    (``[[bodies]]``, ``[[supports]]``, ``[[soft_supports]]``, ``[[loads]]``, ``[[contact]]``).

    The arguments are :func:`load_spec`'s; a file naming a case gives the case's model. Only the
    model's sections are read (and checked): the design, the objective and the options are left
    unread. Neither reading nor the Model loads JAX; the analysis of the Model does.
    """
    text, label, base = _read_source(source, label, base_dir)
    r, data, _ = _document(text, label, base, overrides, origins, {"mesh": mesh, "design": design, "eta": None})
    model, _, _ = read_model(r, _top(r, data))
    return model


def _document(text: str, label: str, base: Path, overrides, origins, flags: dict) -> tuple[Reader, dict, str | None]:
    """``(reader, data, case)``: the long-form document a file stands for, the chosen variants and the
    overrides applied (the case's file, merged with this one's sections, for the short form), the
    reader that names its keys in messages, and the case the file names (None for the long form)."""
    data = parse_toml(text, label)
    origins, overrides = dict(origins or {}), dict(overrides or {})
    short = "case" in data
    for flag, value in flags.items():
        key = f"case_options.{flag}" if short else ("design.eta" if flag == "eta" else f"variants.{flag}")
        if value is not None:
            origins.setdefault(key, f"--{flag}")
            if short or flag == "eta":
                overrides = {key: value, **overrides}
    for key in overrides:
        origins.setdefault(key, "override")
    r = Reader(label, base, origins)
    if short:
        return _short_form(r, data, overrides)
    chosen = {axis: (flags[axis], f"variants.{axis}") for axis in VARIANT_AXES}
    apply_variants(r, data, chosen)
    for key, value in overrides.items():
        r.set(data, key, value)
    return r, data, None


def _read_source(source, label: str | None, base_dir) -> tuple[str, str, Path]:
    """``(text, label, base_dir)`` of a path or a text."""
    if isinstance(source, Path) or (isinstance(source, str) and "=" not in source and "\n" not in source):
        path = Path(source)
        label = label or str(source)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as err:
            raise SpecError(label, "", f"cannot read the problem file: {err}") from None
        return text, label, Path(base_dir) if base_dir is not None else path.parent
    return str(source), label or "<toml>", Path(base_dir) if base_dir is not None else Path.cwd()


def apply_variants(r: Reader, data: dict, chosen: Mapping[str, tuple]) -> None:
    """Make the replacements of ``data``'s ``[variants]`` that the chosen values select, and drop
    ``[variants]`` from ``data``. ``chosen``: axis -> (the value, or None for the file as written;
    the key path that holds it, for its error)."""
    raw = data.pop("variants", None)
    given = {axis: value for axis, value in chosen.items() if value[0] is not None}
    if raw is None:
        axis = next(iter(given), None)
        if axis is not None:
            raise SpecError(
                r.source,
                "",
                f"--{axis} applies to a file that names a registered case (case = ...) "
                f"or declares [variants]; this file has none: edit "
                f"{'bodies[i].mesh' if axis == 'mesh' else 'design.bodies[i]'} instead",
            )
        return
    t = r.table(raw, "variants", RUN["variants"].names)
    lists = {axis: t.names(axis) for axis in VARIANT_AXES if t.has(axis)}
    picked = {axis: names[0] for axis, names in lists.items()}
    for axis, (value, key) in given.items():
        where, _, name = key.rpartition(".")
        if axis not in lists:
            raise r.error(key, f"the file declares no {axis} variants (variants.{axis})")
        picked[axis] = Table(r, {name: value}, where).str(name, choices=lists[axis])
    for w in t.tables("when", (*lists, "set"), ("set",)):
        conditions = {axis: w.str(axis, choices=lists[axis]) for axis in lists if w.has(axis)}
        replacements = w.sub("set")
        if all(picked[axis] == value for axis, value in conditions.items()):
            for key, value in replacements.data.items():
                r.origins.setdefault(key, w.path)
                r.set(data, key, value)


def _short_form(r: Reader, data: dict, overrides: dict) -> tuple[Reader, dict, str]:
    """A file naming a case: the case's file with the chosen variants, this file's sections and the
    overrides; ``(its reader, its data, the case's name)``."""
    first = {k: v for k, v in overrides.items() if k.split(".")[0] in ("case", "case_options")}
    for key, value in first.items():
        r.set(data, key, value)
    top = r.table(data, "")
    top.only(
        _SHORT,
        hint=" (a file that names a case takes only these; describe bodies, supports, design ... "
        "in a file without `case`)",
    )
    name = top.str("case", choices=OPTIMIZATION_CASES)
    path = OPTIMIZATION_CASES[name].path
    opts = top.sub("case_options", RUN["case_options"].names, default=None)
    case = parse_toml(path.read_text(encoding="utf-8"), path.name)
    chosen = {axis: (opts.str(axis, None) if opts else None, f"case_options.{axis}") for axis in VARIANT_AXES}
    apply_variants(r, case, chosen)
    if opts is not None and opts.has("eta"):
        r.origins.setdefault("design.eta", r.origin("case_options.eta") or "case_options.eta")
        case.setdefault("design", {})["eta"] = opts.raw("eta")
    for section in COMMON:  # this file's keys replace the case's, table by table
        if section in data:
            mine, theirs = data[section], case.get(section)
            case[section] = {**theirs, **mine} if isinstance(mine, dict) and isinstance(theirs, dict) else mine
    for key, value in overrides.items():
        if key not in first:
            r.set(case, key, value)
    return Reader(r.source, path.parent, r.origins), case, name


def _long_form(r: Reader, data: dict, text: str, check: bool) -> RunSpec:
    """A file that describes its bodies, conditions, design, objective and options."""
    from contopt.optimize.problem import DesignProblem  # JAX: here, not atop, so load_model loads none

    top = _top(r, data)
    model, by_name, envelopes = read_model(r, top)
    design_table = top.sub("design", RUN["design"].names, RUN["design"].required)
    design, entries = read_design(design_table, by_name, envelopes)
    objective_table = top.sub("objective")
    interfaces = tuple(i.name for i in model.interfaces)
    load_cases = read_load_cases(top, model, by_name)
    names = tuple(c.name for c in load_cases)
    objective, normalize, combine = read_objective(objective_table, by_name, interfaces, names)
    constraints = read_constraints(top, by_name, interfaces, names)
    optimizer, options, outputs, settings = read_optimizer(r, top)
    # the one value DesignProblem checks that the reader passes on unread is objective.normalize
    problem = objective_table.guard(
        None,
        DesignProblem,
        model=model,
        design=design,
        objective=objective,
        constraints=constraints,
        normalize=normalize,
        **settings,
        load_cases=load_cases,
        combine=combine,
        **read_solver_options(r, top),
    )
    disc = top.guard(None, check_design, model, design, entries) if check else None
    title, desc = read_texts(top)
    return RunSpec(
        problem=problem,
        optimizer=optimizer,
        options=options,
        name=title or Path(r.source).stem,
        description=desc,
        source=r.source,
        text=text,
        discretization=disc,
        **outputs,
    )


def _top(r: Reader, data: dict) -> Table:
    """The long-form document's top table, its keys checked."""
    top = r.table(data, "")
    top.only(MODEL[""].allowed(ABSENT))
    top.require(k.name for k in MODEL[""].kind(ABSENT).keys if k.required)
    return top


def load_run_spec(run_dir) -> RunSpec:
    """The RunSpec of the run in ``run_dir``, rebuilt from its stored recipe (``checkpoint/problem.json``).

    A run made before recipes were stored is rebuilt from its ``problem.toml`` and the `contopt run`
    command line in its first comment (the flags --mesh, --design, --eta and --set). ConfigError when
    the directory has neither.
    """
    run_dir = Path(run_dir)
    path = run_dir / RECIPE_FILE
    if path.exists():
        try:
            recipe = json.loads(path.read_text())
        except (OSError, ValueError) as err:
            raise ConfigError(f"cannot read {path}: {err}") from None
        return load_spec(
            recipe["text"],
            recipe.get("overrides"),
            mesh=recipe.get("mesh"),
            design=recipe.get("design"),
            eta=recipe.get("eta"),
            label=recipe.get("label"),
            base_dir=recipe.get("base_dir"),
            origins=recipe.get("origins"),
        )
    copy = run_dir / "problem.toml"
    if not copy.exists():
        raise ConfigError(
            f"{run_dir} does not say which problem ran (no {RECIPE_FILE} or problem.toml, which "
            "`contopt run` writes): it was run from Python with optimize(); rebuild its design "
            "space there"
        )
    return load_spec(copy, **header_flags(copy))


def case_file_text(name: str) -> str:
    """A short-form problem file naming the bundled case ``name``, its options spelled out."""
    if name not in OPTIMIZATION_CASES:
        raise ConfigError(f"unknown case {name!r}; choose one of {sorted(OPTIMIZATION_CASES)}")
    case = OPTIMIZATION_CASES[name]
    options = "".join(
        _commented(f'{axis} = "{choices[0]}"', f"one of {list(choices)}")
        for axis, choices in (("mesh", case.meshes), ("design", case.designs))
        if choices
    )
    return (
        f"# The case {name!r}: {case.description}\n"
        "# A file that names a case takes [case_options] and the [optimizer], [run], [newton], [augmentation],\n"
        "# [linear] and [adjoint] sections; `contopt run THIS.toml` runs it.\n\n"
        f'case = "{name}"\n\n'
        "[case_options]\n" + options + _commented("# eta = 10.0", "Heaviside sharpness") + "\n"
        "[optimizer]\n"
        + _commented(f'name = "{case.optimizer}"', 'or "ipopt"' if case.optimizer == "mma" else 'or "mma"')
        + "\n[run]\n"
        "max_iter = 100\n"
        f'out = "results/{name}"\n'
    )


def _commented(line: str, comment: str) -> str:
    return f"{line:<28}# {comment}\n"
