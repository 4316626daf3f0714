"""The keys of a problem file's top table and its model: ``[[bodies]]`` (meshes, materials, sets),
``[[supports]]``, ``[[soft_supports]]``, ``[[loads]]``, ``[[contact]]`` (:mod:`contopt.cases.keys`)."""

from __future__ import annotations

from contopt.adjoint.options import AdjointOptions
from contopt.assembly.model import Body, Dirichlet, RigidMotion
from contopt.cases.keys import (
    ABSENT,
    ANGLE,
    LENGTH,
    NO_DEFAULT,
    PRESENT,
    PRESSURE,
    Key,
    Kind,
    Section,
    arg,
    default_of,
    doc_of,
    fields_section,
)
from contopt.cases.optimization import OPTIMIZATION_CASES
from contopt.contact.coulomb import Coulomb
from contopt.contact.interface import ContactInterface
from contopt.contact.laws import LAWS, AugmentationOptions
from contopt.contact.verify import PenetrationCheck
from contopt.design.symmetry import AXES
from contopt.material.hyperelastic import MooneyRivlin
from contopt.mesh import generators, tool
from contopt.mesh.cad import CadOptions
from contopt.mesh.voxel import VoxelOptions
from contopt.solve.linear import LinearSolverOptions
from contopt.solve.newton_options import NewtonOptions

#: the sections every problem file may have, also one that names a case
COMMON = ("name", "description", "optimizer", "run", "newton", "augmentation", "linear", "adjoint")
#: material models: a table with ``model = NAME`` and the keys of one of its forms
MATERIALS = ("mooney-rivlin", "neo-hookean")
#: load types: ``type = NAME`` and the load's own key
LOADS = {"traction": "traction", "body-force": "force", "acceleration": "acceleration"}

#: per mesh generator (a function of contopt.mesh.generators), how each of its arguments is read
MESH_KEYS = {
    "box": {"lengths": "vector", "divisions": "ints", "origin": "vector", "grading": "grading"},
    "cylinder_shell_sector": {
        "radius": "number",
        "arc": "angle",
        "width": "number",
        "thickness": "number",
        "divisions": "ints",
        "center": "vector",
        "axis": "string",
        "mid_angle": "angle",
        "outward": "boolean",
    },
    "annulus": {
        "r_inner": "number",
        "r_outer": "number",
        "length": "number",
        "divisions": "ints",
        "theta": "angles",
        "center": "vector",
    },
    "cylinder": {
        "radius": "number",
        "length": "number",
        "divisions": "ints",
        "center": "vector",
        "core_size": "number",
        "core_roundness": "number",
    },
}
GENERATORS = tuple(sorted(MESH_KEYS))
_MESH_UNITS = {"arc": ANGLE, "mid_angle": ANGLE, "theta": ANGLE, "divisions": "", "axis": "", "outward": ""}
_MESH_UNITS.update(dict.fromkeys(("core_size", "core_roundness", "grading"), ""))
#: what cylinder_shell_sector's docstring says in prose rather than per argument
_SECTOR = {
    "radius": "the radius of the surface the sector is cut from (outer with outward, else inner)",
    "arc": "the angle the sector spans about the axis",
    "width": "the extent along the axis",
    "thickness": "the radial thickness",
    "divisions": "(n_arc, n_width, n_thickness) cells",
    "center": "a point on the cylinder's axis",
    "axis": 'the cylinder\'s axis, "x", "y" or "z"',
    "mid_angle": "the angle of the sector's middle",
    "outward": "the surface of radius `radius` is the outer (convex) one; false: the inner one",
}


def _generator_keys(gen: str) -> tuple[Key, ...]:
    fn = getattr(generators, gen)
    keys = [Key("generator", "string", "the mesh generator", choices=GENERATORS, required=True)]
    for name, kind in MESH_KEYS[gen].items():
        doc = doc_of(fn, name) or _SECTOR.get(name, "")
        default = default_of(fn, name)
        choices = tuple(AXES) if name == "axis" else ()
        unit = _MESH_UNITS.get(name, LENGTH)
        keys.append(
            Key(name, kind, doc, unit, default, choices, required=default is NO_DEFAULT, n=2 if kind == "angles" else 3)
        )
    return tuple(keys) + (TET_KEYS if gen in TET_GENERATORS else ())


#: the generators whose cells are numbered as one structured grid, so that cutting each hex into six tets
#: conforms (cylinder's o-grid does not: contopt.mesh.tets.tetrahedralize refuses it)
TET_GENERATORS = ("annulus", "box", "cylinder_shell_sector")
#: a generated hex8 mesh cut into tetrahedra (tetrahedralize), as a CAD mesh's element / order
TET_KEYS = (
    Key(
        "element",
        "string",
        '"hex8", or "tet": every hex cut into six tets (tet4, or tet10 with order = 2); the sets are kept',
        default="hex8",
        choices=("hex8", "tet"),
    ),
    Key("order", "integer", 'the element order: 1 (hex8 or tet4) or 2 (tet10, with element = "tet")', default=1),
)


#: per rigid tool shape (its function in contopt.mesh.tool), what each argument means and its type
SHAPE_KEYS = {
    "plane": {
        "center": ("vector", "the rectangle's centre"),
        "normal": ("vector", "its outward normal, towards the body it touches"),
        "size": ("value", "its side lengths [a, b], or one length for a square"),
        "divisions": ("ints", "facets along its sides [n_a, n_b] (a runs along the axis least along the normal)"),
    },
    "cylinder": {
        "radius": ("number", "the cylinder's radius"),
        "length": ("number", "its extent along the axis, centred on center"),
        "center": ("vector", "a point on its axis"),
        "axis": ("axis", 'its axis: "x", "y", "z" or a vector [x, y, z]'),
        "divisions": ("ints", "facets [around, along] (the circle is the polygon of its nodes)"),
        "arc": ("angle", "the angle the mantle spans (the full circle by default)"),
        "normal": ("vector", "the outward normal in the arc's middle (default: y for axis x, else x)"),
    },
    "sphere": {
        "radius": ("number", "the sphere's radius"),
        "center": ("vector", "its centre"),
        "divisions": ("integer", "facets along each side of the six cube-sphere patches, or of the cap"),
        "normal": ("vector", "the direction from the centre to the cap's middle (default [0, 0, -1])"),
        "angle": ("angle", "a cap's half-width, up to 60 degrees (absent: the whole sphere)"),
    },
}
#: the function of each shape
SHAPES = {"plane": "plane_surface", "cylinder": "cylinder_surface", "sphere": "sphere_surface"}


def _shape_keys(shape: str) -> tuple[Key, ...]:
    fn = getattr(tool, SHAPES[shape])
    keys = [Key("shape", "string", "the tool's shape", choices=tuple(SHAPES), required=True)]
    for name, (kind, doc) in SHAPE_KEYS[shape].items():
        default = default_of(fn, name)
        required = default is NO_DEFAULT
        default = NO_DEFAULT if default is None else default
        unit = ANGLE if kind == "angle" else "" if kind in ("ints", "integer", "axis") or name == "normal" else LENGTH
        keys.append(Key(name, kind, doc, unit, default, required=required, n=2 if kind in ("ints", "value") else 3))
    return tuple(keys)


_SURFACE = (
    Key("body", "string", "the body's name", required=True),
    Key("set", "string", "a facet set of the body", required=True),
)
_E_NU = (
    arg(MooneyRivlin.from_E_nu, "E", "number", PRESSURE, doc="Young's modulus (small strain)"),
    arg(MooneyRivlin.from_E_nu, "nu", "number", doc="Poisson's ratio (small strain)"),
)
_DENSITY = arg(
    MooneyRivlin, "mass_density", "number", "mass/volume", doc="mass per reference volume (acceleration loads)"
)


#: the top table, the model's tables
MODEL_SECTIONS = (
    Section(
        "",
        "a problem file: describes everything (bodies ... objective), or names a bundled case",
        (
            Key("name", "string", "the problem's name (contopt run shows it)"),
            Key("description", "string", "one line on the problem"),
            Key("optimizer", "table", "the optimizer and its options", table="optimizer"),
            Key("run", "table", "the iteration limit and what a run writes", table="run"),
            *(
                Key(k, "table", f"the {k} options ({cls.__name__})", table=k)
                for k, cls in (
                    ("newton", NewtonOptions),
                    ("augmentation", AugmentationOptions),
                    ("linear", LinearSolverOptions),
                    ("adjoint", AdjointOptions),
                )
            ),
        ),
        (
            Kind(
                "case",
                PRESENT,
                (
                    Key("case", "string", "a bundled case: its problem file", choices=tuple(OPTIMIZATION_CASES)),
                    Key("case_options", "table", "the case's variants and Heaviside sharpness", table="case_options"),
                ),
            ),
            Kind(
                "case",
                ABSENT,
                (
                    Key("bodies", "tables", "the deformable bodies", table="bodies", required=True),
                    Key("supports", "tables", "prescribed displacements", table="supports"),
                    Key("soft_supports", "tables", "springs to ground fading as 1 - t", table="soft_supports"),
                    Key("loads", "tables", "tractions, body forces and accelerations", table="loads"),
                    Key("contact", "tables", "contact interfaces between two bodies", table="contact"),
                    Key("design", "table", "what is designed and how", table="design", required=True),
                    Key(
                        "objective",
                        "table",
                        "the response minimized or maximized",
                        table="objective",
                        required=True,
                    ),
                    Key("constraints", "tables", "responses bounded above and/or below", table="constraints"),
                    Key(
                        "load_cases",
                        "tables",
                        "analyses of the same bodies, contact and design under their own supports, motions and loads",
                        table="load_cases",
                    ),
                    Key("variants", "table", "the file's choices for --mesh and --design", table="variants"),
                ),
            ),
        ),
    ),
    Section(
        "bodies",
        "one body: deformable (mesh and material) or a rigid tool (rigid and motion)",
        (
            Key("name", "string", "the body's name, unique", required=True),
            Key("sets", "tables", "extra named sets made from the mesh's own", table="bodies.sets"),
        ),
        (
            Kind(
                "rigid",
                ABSENT,
                (
                    Key("mesh", "table", "a generated mesh or a mesh file", table="bodies.mesh", required=True),
                    Key(
                        "material", "table", "the body's hyperelastic material", table="bodies.material", required=True
                    ),
                    arg(
                        Body,
                        "fbar",
                        "boolean",
                        doc="mean-dilatation F-bar (plain hex8 locks when nearly incompressible)",
                    ),
                ),
            ),
            Kind(
                "rigid",
                PRESENT,
                (
                    Key(
                        "rigid",
                        "table",
                        "a rigid tool: its surface (no unknowns, no material; the mortar side of its contact)",
                        table="bodies.rigid",
                    ),
                    Key("motion", "table", "the tool's rigid motion (default: it stays)", table="bodies.motion"),
                ),
            ),
        ),
    ),
    Section(
        "bodies.rigid",
        "a rigid tool's surface: shape = NAME with its sizes, or file = PATH; its sets: surface, all",
        (
            Key("flip", "boolean", "reverse the surface's outward normals (a bore instead of a pin)", default=False),
            arg(
                tool.tool_layer,
                "thickness",
                "number",
                doc="the depth of the one hidden cell layer under the surface, a fraction of its facet edges",
            ),
        ),
        (
            Kind(
                "file",
                PRESENT,
                (
                    Key(
                        "file", "string", "a surface file (.stl .obj .ply .vtu .msh ...), relative to the problem file"
                    ),
                    arg(
                        tool.read_surface,
                        "scale",
                        "number",
                        doc="every coordinate times this (a file in mm, a model in m)",
                    ),
                ),
            ),
            *(Kind("shape", shape, _shape_keys(shape)) for shape in SHAPES),
        ),
    ),
    Section(
        "bodies.motion",
        "a rigid tool's motion: x = R(t) (X - point) + point + translation(t)",
        (
            Key("value", "vector", "its translation [ux, uy, uz], scaled by the load factor", LENGTH),
            Key("path", "rows", "instead: rows [t, ux, uy, uz], piecewise linear in t", LENGTH),
            Key("rotation", "table", "its rotation about an axis", table="bodies.motion.rotation"),
        ),
    ),
    Section(
        "load_cases",
        "a load case: its own supports, motions and loads (besides the file's) over the shared bodies and design",
        (
            Key("name", "string", "the case's name (constraints and the history name it)", required=True),
            Key("weight", "number", "its weight (> 0) in the combined objective", default=1.0),
            Key("supports", "tables", "this case's prescribed displacements", table="supports"),
            Key("soft_supports", "tables", "this case's springs to ground", table="soft_supports"),
            Key("loads", "tables", "this case's tractions, body forces and accelerations", table="loads"),
            Key(
                "motions", "tables", "rigid tools' motions in this case (replacing theirs)", table="load_cases.motions"
            ),
        ),
    ),
    Section(
        "load_cases.motions",
        "a rigid tool's motion in this load case: x = R(t) (X - point) + point + translation(t)",
        (
            Key("body", "string", "the rigid tool's name", required=True),
            Key("value", "vector", "its translation [ux, uy, uz], scaled by the load factor", LENGTH),
            Key("path", "rows", "instead: rows [t, ux, uy, uz], piecewise linear in t", LENGTH),
            Key("rotation", "table", "its rotation about an axis", table="bodies.motion.rotation"),
        ),
    ),
    Section(
        "bodies.motion.rotation",
        "a rigid tool's rotation about an axis through a point (right-handed)",
        (
            Key("axis", "axis", 'the rotation axis: "x", "y", "z" or a vector [x, y, z]', required=True),
            arg(RigidMotion, "point", "vector", LENGTH, doc="a point on the axis (it moves with the translation)"),
            Key(
                "angle",
                "angle_path",
                "the angle, scaled by the load factor, or rows [t, angle] piecewise linear in t",
                ANGLE,
                required=True,
            ),
        ),
    ),
    Section(
        "bodies.mesh",
        "a mesh: generator = NAME with its arguments, file = PATH, cad = PATH (meshed by Gmsh) or envelope = PATH "
        "(voxels)",
        kinds=(
            Kind(
                "file",
                PRESENT,
                (
                    Key("file", "string", "a mesh file (.msh .vtu .e .exo), relative to the problem file"),
                    Key("body", "string", "which body of a file holding several"),
                ),
            ),
            Kind(
                "cad",
                PRESENT,
                (
                    Key(
                        "cad",
                        "string",
                        "a CAD file of one solid (.step .stp .iges .igs .brep .stl), relative to the problem "
                        'file, meshed by Gmsh (the cad extra): hex8, or tet4 / tet10 with element = "tet"; '
                        "its surfaces are facet sets",
                    ),
                    arg(CadOptions, "size", "number", LENGTH, required=True),
                    arg(CadOptions, "order", "integer"),
                    arg(CadOptions, "scale", "number"),
                    arg(CadOptions, "element", "string", choices=("hex8", "tet")),
                ),
            ),
            Kind(
                "envelope",
                PRESENT,
                (
                    Key(
                        "envelope",
                        "string",
                        "a closed surface (.stl .ply .obj, or .step .stp .iges .igs .brep through Gmsh), relative to "
                        "the problem file: hex8 voxels of edge size whose centres lie inside; sets boundary and "
                        "xmin .. zmax",
                    ),
                    arg(VoxelOptions, "size", "number", LENGTH, required=True),
                    arg(VoxelOptions, "scale", "number"),
                ),
            ),
            *(Kind("generator", gen, _generator_keys(gen)) for gen in GENERATORS),
        ),
    ),
    Section(
        "bodies.material",
        "a material: model = NAME with its constants",
        (Key("model", "string", "the material model", choices=MATERIALS, required=True),),
        (
            Kind("model", "neo-hookean", (*_E_NU, _DENSITY)),
            Kind(
                "model",
                "mooney-rivlin",
                (
                    *_E_NU,
                    arg(
                        MooneyRivlin.from_E_nu,
                        "b_fraction",
                        "number",
                        doc="B/(A+B): B's share of the shear modulus",
                    ),
                    arg(MooneyRivlin, "kappa", "number", PRESSURE, doc="bulk modulus (instead of E, nu)"),
                    arg(MooneyRivlin, "A", "number", PRESSURE, doc="first Mooney-Rivlin constant", default=0.0),
                    arg(MooneyRivlin, "B", "number", PRESSURE, doc="second Mooney-Rivlin constant"),
                    _DENSITY,
                ),
            ),
        ),
    ),
    Section(
        "bodies.sets",
        "a node (and facet) set selected from one of the mesh's sets",
        (
            Key("name", "string", "the new set's name", required=True),
            Key(
                "from",
                "string",
                "the set it is selected from: a facet set (gives both kinds) or a node set",
                default="all",
            ),
            *(
                Key(a, "range", f"keep what lies in [min, max] of {a} (facets by their centre)", LENGTH, n=2)
                for a in "xyz"
            ),
            Key("nearest", "points", "or: the node nearest to this point [x, y, z] (or to each of a list)", LENGTH),
        ),
    ),
    Section(
        "supports",
        "prescribed displacements of a node set",
        (
            Key("body", "string", "the body's name", required=True),
            Key("set", "string", "a node set (every facet set is also one)", required=True),
            arg(Dirichlet, "components", "string"),
            arg(
                Dirichlet,
                "value",
                "value",
                LENGTH,
                doc="one number, or one per component; scaled by the load factor",
            ),
            Key("path", "rows", "instead: rows [t, one value per component], piecewise linear in t", LENGTH),
        ),
    ),
    Section(
        "soft_supports",
        "springs to ground on every node of a body, fading as 1 - t (a body held only by contact)",
        (
            Key("body", "string", "the body's name", required=True),
            Key("stiffness", "number", "the springs' stiffness", "force/length per reference volume", required=True),
        ),
    ),
    Section(
        "loads",
        "a load: type = NAME",
        (
            Key(
                "type",
                "string",
                "the kind of load",
                choices=tuple(LOADS),
                required=True,
            ),
            Key("body", "string", "the body's name", required=True),
        ),
        (
            Kind(
                "type",
                "traction",
                (
                    Key("set", "string", "a facet set of the body", required=True),
                    Key("traction", "vector", "[tx, ty, tz] per reference area", PRESSURE, required=True),
                ),
            ),
            Kind(
                "type",
                "body-force",
                (Key("force", "vector", "[bx, by, bz] per reference volume", "force/volume", required=True),),
            ),
            Kind(
                "type",
                "acceleration",
                (
                    Key(
                        "acceleration",
                        "vector",
                        "[ax, ay, az]: the inertia load -rho a (needs mass_density)",
                        "length/time^2",
                        required=True,
                    ),
                ),
            ),
        ),
    ),
    Section(
        "contact",
        "mortar contact between two bodies",
        (
            arg(
                ContactInterface,
                "name",
                "string",
                doc='what responses call it, unique; default "{nonmortar body}-{mortar body}"',
                default=NO_DEFAULT,
            ),
            arg(
                ContactInterface,
                "nonmortar",
                "table",
                table="contact.nonmortar",
                doc="the surface that carries the pressure: the finer (or more curved, softer) one",
            ),
            arg(ContactInterface, "mortar", "table", table="contact.mortar", doc="the other surface"),
            arg(
                ContactInterface,
                "surfaces",
                "tables",
                table="contact.surfaces",
                doc="instead of nonmortar and mortar: two surfaces, the nonmortar side chosen for you",
            ),
            arg(
                ContactInterface,
                "law",
                "string",
                choices=tuple(LAWS),
                doc="the contact law: augmented Lagrangian or penalty",
            ),
            Key(
                "eps",
                "number",
                "the law's penalty; default 10 E*/h (alm) or 100 E*/h (penalty)",
                "pressure/length (force/length^3)",
            ),
            arg(ContactInterface, "skin", "number", LENGTH),
            arg(ContactInterface, "max_angle_deg", "number", "degrees"),
            arg(ContactInterface, "check", "table", table="contact.check", default=NO_DEFAULT),
            Key(
                "friction",
                "friction",
                "Coulomb friction: the coefficient mu, or a table {mu, eps, edge}",
                table="contact.friction",
            ),
        ),
    ),
    *(
        Section(f"contact.{side}", "a surface: a facet set of a body", _SURFACE)
        for side in ("nonmortar", "mortar", "surfaces")
    ),
    fields_section("contact.check", PenetrationCheck, "the check of every converged state"),
    fields_section("contact.friction", Coulomb, "Coulomb friction", units={"eps": "pressure/length (force/length^3)"}),
)

#: the sections above by path
MODEL = {s.path: s for s in MODEL_SECTIONS}
