"""Problem files (TOML): the bundled ones build the paper's problems with their variants; a bad file fails
on one line that names the key."""

import re
from pathlib import Path

import numpy as np
import pytest
from _compare import problem_differences  # tests/_compare.py

from contopt.cases.optimization import OPTIMIZATION_CASES, optimization_case
from contopt.cases.spec import BoxUnion, SpecError, bundled_cases, load_spec
from contopt.cases.two_blocks import two_blocks
from contopt.contact.laws import AugmentedLagrangian
from contopt.design import BoxRegion, CyclicSymmetry, RadialSkin
from contopt.errors import ConfigError
from contopt.material.hyperelastic import MooneyRivlin

BUNDLED = bundled_cases()

#: the two-blocks model (contopt.cases.two_blocks, divisions=4) with a design: small and quick to check
TWO_BLOCKS = """\
[[bodies]]
name = "block"
mesh = { generator = "box", lengths = [1.0, 1.0, 0.5], divisions = [4, 4, 2] }
material = { model = "neo-hookean", E = 1.0, nu = 0.3 }

[[bodies]]
name = "punch"
mesh = { generator = "box", lengths = [0.6, 0.6, 0.4], divisions = [3, 3, 1], origin = [0.2, 0.2, 0.5] }
material = { model = "neo-hookean", E = 10.0, nu = 0.3 }

[[supports]]
body = "block"
set = "zmin"

[[supports]]
body = "punch"
set = "zmax"
value = [0.02, 0.0, -0.06]

[[contact]]
nonmortar = { body = "punch", set = "zmin" }
mortar = { body = "block", set = "zmax" }

[design]
eta = 10.0

[[design.bodies]]
body = "block"
volume_fraction = 0.4
density = { radius = 0.3 }

[objective]
response = "strain-energy"
bodies = "block"
sense = "maximize"

[optimizer.mma]
move = 0.1
"""


def two_blocks_problem():
    from contopt.design import Density, Design, DesignedBody
    from contopt.optimize.problem import DesignProblem
    from contopt.responses import StrainEnergy

    return DesignProblem(
        model=two_blocks(4),
        objective=-StrainEnergy(bodies="block"),
        design=Design(DesignedBody("block", Density(0.3), volume_fraction=0.4)),
    )


def write(tmp_path, text, name="case.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


# ------------------------------------------------------------------------------- the bundled files
@pytest.mark.parametrize("name", sorted(BUNDLED))
def test_bundled_file_is_its_case(name):
    spec = load_spec(BUNDLED[name])
    case = OPTIMIZATION_CASES[name]
    assert (spec.name, spec.optimizer, spec.eta, spec.out) == (name, case.optimizer, 10.0, f"results/{name}")
    assert (
        spec.discretization is not None
        and spec.discretization.n_cells == spec.problem.design.build(spec.discretization).n_cells
    )
    assert problem_differences(optimization_case(name), spec.problem) == []
    assert case.description == spec.description and case.meshes[0] == "coarse"


@pytest.mark.parametrize("name", sorted(BUNDLED))
def test_every_variant_of_a_bundled_file_reads(name):
    case = OPTIMIZATION_CASES[name]
    for mesh in case.meshes:
        for design in case.designs:
            problem = optimization_case(name, design, mesh)
            kind = type(problem.design.bodies[0].parameterization).__name__
            assert kind == {"bspline": "BSplineGrid", "density": "Density"}[design], (mesh, design)


#: the cells of the bundled meshes: the paper's (die 7.1-7.3, sabot 7.4) and the cantilever's
MESH_CELLS = {
    ("die-slab", "coarse"): 23 * 10 * 8,
    ("die-slab", "fine"): 45 * 20 * 15,
    ("cantilever", "coarse"): 24 * 8 * 4,
    ("cantilever", "fine"): 48 * 16 * 8,
    ("sabot", "fine"): 10_780 + 46_816 + 13_552,
}


@pytest.mark.parametrize("name, mesh", list(MESH_CELLS))
def test_mesh_variants_have_the_papers_cells(name, mesh):
    model = optimization_case(name, mesh=mesh).model
    designed = {"die-slab": ("slab",), "cantilever": ("beam",), "sabot": ("slug", "sabot", "annulus")}[name]
    assert sum(model.body(b).mesh.n_cells for b in designed) == MESH_CELLS[name, mesh]


def test_an_optimization_case_takes_another_contact_law_for_every_interface():
    from contopt.contact.laws import AugmentedLagrangian, Penalty

    assert isinstance(optimization_case("friction-clamp").model.interfaces[0].law, Penalty)
    clamp = optimization_case("friction-clamp", law="alm").model
    assert isinstance(clamp.interfaces[0].law, AugmentedLagrangian) and clamp.interfaces[0].friction.mu == 0.5
    with pytest.raises(SpecError, match="--law must be one of .*lagrange"):
        optimization_case("friction-clamp", law="lagrange")


def test_cantilever_variants_keep_two_cells_of_filter_and_a_patch_per_two_cells():
    for mesh, h in (("coarse", 0.125), ("fine", 0.0625)):
        divisions = optimization_case("cantilever", mesh=mesh).model.body("beam").mesh.n_cells
        assert optimization_case("cantilever", "density", mesh).design.bodies[0].parameterization.radius == 2 * h
        grid = optimization_case("cantilever", "bspline", mesh).design.bodies[0].parameterization
        assert np.prod(grid.patches) * 8 == divisions and grid.lengths == (3.0, 1.0, 0.5)


def test_die_slab_model_and_design_summary_in_detail():
    """The paper's die-slab problem (7.1), spelled out: meshes, supports, interfaces, materials, design."""
    from contopt.assembly.system import discretize
    from contopt.material.hyperelastic import neo_hookean

    spec = load_spec(BUNDLED["die-slab"]).problem
    model = spec.model
    assert [(b.name, b.material, b.fbar) for b in model.bodies] == [
        ("slab", neo_hookean(1.0, 0.3), True),
        ("die", neo_hookean(1000.0, 0.3), True),
    ]
    slab, die = (model.body(n).mesh for n in ("slab", "die"))
    np.testing.assert_allclose([slab.points.min(axis=0), slab.points.max(axis=0)], [[0, 0, 0], [9, 4, 3]])
    outer = die.points[die.node_set("outer")]
    np.testing.assert_allclose(np.hypot(outer[:, 0] - 4.5, outer[:, 2] - 6.4045), 3.0)  # radius 3 about y
    # it starts 0.4045 above the slab (fitted to the paper's |f_a^0|, docs/die.md)
    assert outer[:, 2].min() == pytest.approx(3.4045) and np.ptp(outer[:, 1]) == pytest.approx(4.6)
    assert die.n_cells == 12 * 8 * 1
    assert [(x.body, x.node_set, x.components, np.atleast_1d(x.value).tolist()) for x in model.dirichlet] == [
        ("slab", "zmin", "xyz", [0.0]),
        ("die", "inner", "xyz", [0.0, 0.0, -0.6]),
    ]
    assert [(i.nonmortar, i.mortar, i.law) for i in model.interfaces] == [
        (("slab", "zmax"), ("die", "outer"), AugmentedLagrangian())
    ]
    summary = spec.design.build(discretize(model)).summary()
    assert (summary[0]["n_design"], summary[0]["G_nonzeros"]) == (728, 1840 * 64)  # paper table 1
    assert spec.objective.name == "-strain_energy" and spec.normalize == "full" and spec.newton.n_steps == 6


def test_density_variant_and_problem_differences_can_fail():
    text = BUNDLED["die-slab"].read_text()
    line = next(ln for ln in text.splitlines() if ln.startswith("bspline = "))
    density = load_spec(text.replace(line, "density = { radius = 0.7 }"), base_dir=BUNDLED["die-slab"].parent)
    assert problem_differences(density.problem, optimization_case("die-slab", "density")) == []
    assert density.problem.design.build(density.discretization).summary()[0]["n_design"] == 1840
    # and the comparison sees a difference where there is one
    bspline = optimization_case("die-slab", "bspline")
    diffs = problem_differences(density.problem, bspline)
    assert len(diffs) == 1 and "parameterization" in diffs[0]
    diffs = problem_differences(load_spec(BUNDLED["die-slab"], eta=6.0).problem, bspline)
    assert len(diffs) == 1 and diffs[0].startswith("design maps")
    moved = text.replace("value = [0.0, 0.0, -0.6]", "value = [0.0, 0.0, -0.5]")
    diffs = problem_differences(load_spec(moved, check=False).problem, bspline)
    assert diffs and diffs[0].startswith("supports[1] value")


def test_variants_are_replacements_applied_in_order_before_the_overrides():
    text = (
        TWO_BLOCKS
        + """
[variants]
mesh = ["coarse", "fine"]
design = ["density", "bspline"]

[[variants.when]]
mesh = "fine"
set = { "bodies[0].mesh.divisions" = [8, 8, 4], "design.bodies[0].density.radius" = 0.15 }

[[variants.when]]
design = "bspline"
set = { "design.bodies[0]" = { body = "block", bspline = { patches = [2, 2, 1] } } }
"""
    )
    assert load_spec(text, check=False).model.body("block").mesh.n_cells == 32
    fine = load_spec(text, mesh="fine", check=False)
    assert (
        fine.model.body("block").mesh.n_cells == 256 and fine.problem.design.bodies[0].parameterization.radius == 0.15
    )
    both = load_spec(text, {"bodies[0].mesh.divisions": [6, 6, 2]}, mesh="fine", design="bspline", check=False)
    assert both.model.body("block").mesh.n_cells == 72 and both.problem.design.bodies[0].volume_fraction is None
    with pytest.raises(
        SpecError,
        match=r"^<toml>: --design must be one of \['bspline', 'density'\], got 'level' "
        r"\(variants.design\)$",
    ):
        load_spec(text, design="level")
    bad = text.replace("[8, 8, 4]", "[8, 8]")
    with pytest.raises(SpecError, match=r"^<toml>: bodies\[0\].mesh.divisions \(variants.when\[0\]\): must be a list"):
        load_spec(bad, mesh="fine")
    with pytest.raises(SpecError, match=r"^<toml>: variants.when\[1\].design: must be one of"):
        load_spec(text.replace('design = "bspline"\nset', 'design = "bsplin"\nset'))


def test_two_blocks_file_matches_the_model_builder():
    spec = load_spec(TWO_BLOCKS)
    assert problem_differences(spec.problem, two_blocks_problem()) == []
    assert spec.options.move == 0.1 and spec.name == "<toml>"


# ------------------------------------------------------------------------------- short form and overrides
def test_short_form_names_a_registered_case():
    spec = load_spec(
        'case = "die-slab"\n[case_options]\ndesign = "bspline"\neta = 8.0\n'
        '[newton]\nmax_iter = 30\n[optimizer]\nname = "ipopt"\n[run]\nmax_iter = 7\nout = "x"\n'
    )
    ref = load_spec(BUNDLED["die-slab"], {"newton.max_iter": 30}, eta=8.0, check=False).problem
    assert problem_differences(spec.problem, ref) == []
    assert spec.problem.newton.max_iter == 30 != optimization_case("die-slab").newton.max_iter
    assert spec.problem.newton.n_steps == 6  # the case's own load steps are kept
    assert (spec.case, spec.optimizer, spec.max_iter, spec.out, spec.eta) == ("die-slab", "ipopt", 7, "x", 8.0)
    fine = load_spec('case = "die-slab"', mesh="fine", design="density")
    assert fine.model.body("slab").mesh.n_cells == 45 * 20 * 15
    assert fine.problem.design.bodies[0].parameterization.radius == 0.7
    # the overrides reach the case's own keys, after its variants
    edited = load_spec(
        'case = "die-slab"', {"bodies[0].mesh.divisions": [9, 4, 3], "newton.n_steps": 2}, mesh="fine", check=False
    )
    assert edited.model.body("slab").mesh.n_cells == 9 * 4 * 3 and edited.problem.newton.n_steps == 2


def test_overrides_replace_file_values():
    spec = load_spec(
        BUNDLED["die-slab"],
        {"run.max_iter": 3, "optimizer.name": "ipopt", "run.vtu": "none", "design.bodies[0].volume_fraction": 0.3},
        eta=6.0,
    )
    assert (spec.optimizer, spec.max_iter, spec.options.tol, spec.vtu, spec.eta) == ("ipopt", 3, 1e-3, "none", 6.0)
    assert spec.problem.design.bodies[0].volume_fraction == 0.3


# ------------------------------------------------------------------------------- what the schema expresses
def test_mesh_file_is_read_relative_to_the_problem_file(tmp_path, monkeypatch):
    from contopt.mesh.generators import box
    from contopt.mesh.io import write_mesh

    (tmp_path / "meshes").mkdir()
    mesh = box((1.0, 1.0, 0.5), (4, 4, 2))
    write_mesh(tmp_path / "meshes" / "block.vtu", mesh)
    text = TWO_BLOCKS.replace(
        'mesh = { generator = "box", lengths = [1.0, 1.0, 0.5], divisions = [4, 4, 2] }',
        'mesh = { file = "meshes/block.vtu" }',
    )
    path = write(tmp_path, text)
    monkeypatch.chdir(tmp_path / "meshes")  # not where the file is
    spec = load_spec(path)
    np.testing.assert_array_equal(spec.model.body("block").mesh.points, mesh.points)
    assert problem_differences(spec.problem, two_blocks_problem()) == []


def test_every_generator_argument_has_a_key():
    """A new generator argument must be added to the schema (or it could not be set from a file)."""
    import inspect

    from contopt.cases import spec_model
    from contopt.mesh import generators

    assert set(spec_model.GENERATORS) == {"annulus", "box", "cylinder", "cylinder_shell_sector"}
    for name in spec_model.GENERATORS:
        assert set(inspect.signature(getattr(generators, name)).parameters) == set(spec_model.MESH_KEYS[name]), name


def test_generator_arguments_and_angles_in_degrees():
    text = BUNDLED["die-slab"].read_text().replace("arc_deg = 100.0", f"arc = {float(np.deg2rad(100.0))!r}")
    assert problem_differences(load_spec(text, check=False).problem, optimization_case("die-slab")) == []
    with pytest.raises(SpecError, match=r"^<toml>: bodies\[1\].mesh.arc_deg: give arc \(radians\) or arc_deg"):
        load_spec(text.replace("arc = ", "arc_deg = 100.0\narc = "))
    graded = load_spec(
        TWO_BLOCKS.replace(
            "divisions = [4, 4, 2] }", 'divisions = [4, 4, 2], grading = [1.0, "uniform", [0.0, 0.1, 0.5]] }'
        ),
        check=False,
    )
    z = np.unique(graded.model.body("block").mesh.points[:, 2])
    np.testing.assert_allclose(z, [0.0, 0.1, 0.5])


def test_materials_sets_and_fixed_regions():
    text = TWO_BLOCKS.replace(
        'material = { model = "neo-hookean", E = 10.0, nu = 0.3 }',
        'material = { model = "mooney-rivlin", E = 10.0, nu = 0.3, b_fraction = 0.25, mass_density = 2.0 }\n'
        '[[bodies.sets]]\nname = "corner"\nnearest = [0.8, 0.8, 0.9]\n'
        '[[bodies.sets]]\nname = "left"\nfrom = "zmin"\nx = [0.0, 0.41]',
    ).replace(
        "density = { radius = 0.3 }",
        "density = { radius = 0.3 }\nsolid = [{ lower = [-inf, -inf, 0.3], upper = [inf, inf, inf] },"
        "{ lower = [0.0, 0.0, 0.0], upper = [0.25, 0.25, 0.25] }]\nvoid = { lower = [0.7, 0.7, 0.0], "
        "upper = [1.0, 1.0, 0.25] }",
    )
    spec = load_spec(text)
    punch = spec.model.body("punch")
    assert punch.material == MooneyRivlin.from_E_nu(10.0, 0.3, 0.25, 2.0)
    np.testing.assert_array_equal(punch.mesh.points[punch.mesh.node_set("corner")], [[0.8, 0.8, 0.9]])
    left = punch.mesh.facet_set("left")  # punch bottom facets with centres x in [0.2, 0.41]: one column of 3
    assert len(left) == 3 and set(punch.mesh.node_set("left")) <= set(punch.mesh.node_set("zmin"))
    body = spec.problem.design.bodies[0]
    assert isinstance(body.solid, BoxUnion) and isinstance(body.void, BoxRegion)
    summary = spec.problem.design.build(spec.discretization).summary()[0]
    assert (summary["fixed_solid"], summary["fixed_void"]) == (16 + 1, 1)  # top layer + a corner cell; a corner
    stiff = load_spec(
        text.replace("b_fraction = 0.25,", "kappa = 5.0, A = 1.0, B = 0.5,").replace(
            "E = 10.0, nu = 0.3, kappa", "kappa"
        )
    )
    assert stiff.model.body("punch").material == MooneyRivlin(5.0, 1.0, 0.5, 2.0)


#: paper 7.4 on the coarse mesh of the bundled sabot.toml: three bodies from the cylinder and annulus
#: generators, inertia loads, fading springs, two interfaces, cyclic symmetry and two skins
SABOT = """\
[[bodies]]
name = "slug"
material = { model = "neo-hookean", E = 69000.0, nu = 0.33, mass_density = 2.7e-9 }
mesh = { generator = "cylinder", radius = 25.3, length = 25.4, divisions = [6, 4, 4], center = [0.0, 0.0, 12.7] }
sets = [{ name = "AB", nearest = [[-25.3, 0.0, 0.0], [25.3, 0.0, 0.0]] }]

[[bodies]]
name = "sabot"
material = { model = "neo-hookean", E = 6000.0, nu = 0.33, mass_density = 1.8e-9 }
sets = [{ name = "CD", nearest = [[-25.4, 0.0, 0.0], [25.4, 0.0, 0.0]] }]
[bodies.mesh]
generator = "annulus"
r_inner = 25.4
r_outer = 50.7
length = 25.4
divisions = [60, 8, 4]
center = [0.0, 0.0, 12.7]

[[bodies]]
name = "annulus"
material = { model = "neo-hookean", E = 210000.0, nu = 0.26, mass_density = 7.85e-9 }
[bodies.mesh]
generator = "annulus"
r_inner = 50.8
r_outer = 76.2
length = 25.4
divisions = [40, 3, 4]
center = [0.0, 0.0, 12.7]

[[supports]]
body = "slug"
set = "zmin"
components = "z"

[[supports]]
body = "sabot"
set = "zmin"
components = "z"

[[supports]]
body = "annulus"
set = "zmin"
components = "z"

[[supports]]
body = "annulus"
set = "outer"
components = "xy"

[[supports]]
body = "slug"
set = "AB"
components = "y"

[[supports]]
body = "sabot"
set = "CD"
components = "y"

[[loads]]
type = "acceleration"
body = "slug"
acceleration = [98100000.0, 0.0, 0.0]

[[loads]]
type = "acceleration"
body = "sabot"
acceleration = [98100000.0, 0.0, 0.0]

[[soft_supports]]
body = "slug"
stiffness = 2.6487000000000003

[[soft_supports]]
body = "sabot"
stiffness = 1.7658

[[contact]]
nonmortar = { body = "sabot", set = "inner" }
mortar = { body = "slug", set = "outer" }

[[contact]]
nonmortar = { body = "sabot", set = "outer" }
mortar = { body = "annulus", set = "inner" }

[[design.bodies]]
body = "sabot"
volume_fraction = 0.5
bspline = { control_points = [11, 6, 6] }
symmetry = { sectors = 5, reflection = true }
skins = [{ radius = 28.575, side = "inside", slope = 5.0 }, { radius = 47.625, side = "outside", slope = 5.0 }]

[objective]
response = "compliance"

[newton]
n_steps = 4

[linear]
backend = "auto"
iterative_above = 100_000_000
factor_reuse = true
factor_precision = "single"
"""


def test_sabot_is_expressible():
    spec = load_spec(SABOT)
    model = spec.model
    assert [b.name for b in model.bodies] == ["slug", "sabot", "annulus"]
    assert [type(load).__name__ for load in model.loads] == ["Acceleration", "Acceleration"]
    assert [(i.nonmortar, i.mortar) for i in model.interfaces] == [
        (("sabot", "inner"), ("slug", "outer")),
        (("sabot", "outer"), ("annulus", "inner")),
    ]
    slug = model.body("slug").mesh
    np.testing.assert_allclose(slug.points[slug.node_set("AB")], [[-25.3, 0, 0], [25.3, 0, 0]], atol=1e-12)
    body = spec.problem.design.bodies[0]
    assert body.symmetry == CyclicSymmetry(5, reflection=True)
    assert body.skins == (RadialSkin(28.575, "inside"), RadialSkin(47.625, "outside"))
    space = spec.problem.design.build(spec.discretization)
    assert space.summary()[0]["n_design"] == 11 * 6 * 6 == 396
    fields = space.forward(space.initial())
    part = space.parts[0]
    r = np.hypot(part.centroids[:, 0], part.centroids[:, 1])
    nu = fields.nu[part.cells]
    skin = (r < 28.0) | (r > 48.0)
    assert skin.sum() == 2 * 60 * 4 and np.all(nu[skin] > 0.99)
    # cells mirrored about the x axis (a sector's midplane) get the same value
    angle = np.arctan2(part.centroids[:, 1], part.centroids[:, 0])
    key = np.round(np.column_stack([r, part.centroids[:, 2], np.abs(angle)]), 6)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    pairs = counts[inverse.ravel()] == 2
    assert pairs.sum() > len(nu) // 2
    for group in np.unique(inverse.ravel()[pairs]):
        values = nu[inverse.ravel() == group]
        assert values[0] == pytest.approx(values[1], abs=1e-12)
    assert problem_differences(spec.problem, optimization_case("sabot")) == []


# ------------------------------------------------------------------------------- bad files: one line naming the key
BAD = [
    # (what, replace this, with this, key, fragment)
    (
        "unknown key",
        'material = { model = "neo-hookean", E = 1.0',
        'materal = { model = "neo-hookean", E = 1.0',
        "bodies[0].materal",
        "unknown key; did you mean 'material'?",
    ),
    (
        "bad enum",
        'model = "neo-hookean", E = 10.0',
        'model = "neohook", E = 10.0',
        "bodies[1].material.model",
        "must be one of ['mooney-rivlin', 'neo-hookean'], got 'neohook'",
    ),
    ("negative E", "E = 1.0, nu", "E = -1.0, nu", "bodies[0].material.E", "must be > 0, got -1.0"),
    (
        "unknown body",
        'body = "block"\nset = "zmin"',
        'body = "blok"\nset = "zmin"',
        "supports[0].body",
        "unknown body 'blok'; did you mean 'block'?",
    ),
    (
        "missing key",
        'mesh = { generator = "box", lengths = [1.0, 1.0, 0.5], divisions = [4, 4, 2] }\n',
        "",
        "bodies[0].mesh",
        "required key is missing",
    ),
    (
        "bad set",
        'set = "zmin"',
        'set = "zmn"',
        "supports[0].set",
        "body 'block' has no node set 'zmn'; did you mean 'zmin'?",
    ),
    (
        "bad facet set",
        'mortar = { body = "block", set = "zmax" }',
        'mortar = { body = "block", set = "top" }',
        "contact[0].mortar.set",
        "body 'block' has no facet set 'top'",
    ),
    (
        "deeper mesh error",
        "divisions = [4, 4, 2] }",
        "divisions = [4, 4, 2], grading = [1.0, 1.0, [0.0, 0.3, 0.2]] }",
        "bodies[0].mesh.grading",
        "strictly increasing",
    ),
    (
        "deeper contact error",
        'nonmortar = { body = "punch", set = "zmin" }',
        'nonmortar = { body = "punch", set = "zmax" }',
        "contact[0]",
        "do not face each other",
    ),
    (
        "deeper design error",
        "density = { radius = 0.3 }",
        "bspline = { patches = [2, 2, 1], lower = [0.0, 0.0, 0.0], upper = [1.0, 1.0, 0.2] }",
        "design.bodies[0]",
        "lie outside the B-spline box",
    ),
    ("optimizer option", "move = 0.1", "move = 2.0", "optimizer.mma.move", "must lie in (0, 1], got 2.0"),
    ("iteration limit", "move = 0.1", "max_iter = 5", "optimizer.mma.max_iter", "run.max_iter"),
    (
        "response option",
        'bodies = "block"\nsense',
        'interfaces = ["punch-block"]\nsense',
        "objective.interfaces",
        "not an option of response 'strain-energy'",
    ),
    (
        "acceleration",
        "[design]",
        '[[loads]]\ntype = "acceleration"\nbody = "block"\nacceleration = [1.0, 0.0, 0.0]\n[design]',
        "loads[0].body",
        "mass_density > 0",
    ),
    (
        "load type",
        "[design]",
        '[[loads]]\ntype = "pressure"\nbody = "block"\n[design]',
        "loads[0].type",
        "must be one of ['acceleration', 'body-force', 'traction'], got 'pressure'",
    ),
    (
        "newton option",
        "[design]",
        "[newton]\nline_serch = 'none'\n[design]",
        "newton.line_serch",
        "did you mean 'line_search'?",
    ),
    (
        "soft support",
        "[design]",
        '[[soft_supports]]\nbody = "punch"\nstiffness = -1.0\n[design]',
        "soft_supports[0].stiffness",
        "must be finite and > 0, got -1.0",
    ),
    (
        "friction",
        'mortar = { body = "block", set = "zmax" }',
        'mortar = { body = "block", set = "zmax" }\nfriction = -0.2',
        "contact[0].friction",
        "must be a number >= 0 (the friction coefficient), got -0.2",
    ),
    (
        "surfaces and sides",
        'mortar = { body = "block", set = "zmax" }',
        'mortar = { body = "block", set = "zmax" }\nsurfaces = [{ body = "punch", set = "zmin" }]',
        "contact[0].nonmortar",
        "not both",
    ),
    (
        "one surface",
        'nonmortar = { body = "punch", set = "zmin" }\nmortar = { body = "block", set = "zmax" }',
        'surfaces = [{ body = "punch", set = "zmin" }]',
        "contact[0].surfaces",
        "must be two surfaces",
    ),
    (
        "no mortar",
        'mortar = { body = "block", set = "zmax" }',
        "",
        "contact[0].mortar",
        "or give surfaces",
    ),
    (
        "friction table",
        'mortar = { body = "block", set = "zmax" }',
        'mortar = { body = "block", set = "zmax" }\nfriction = { mu = 0.2, eps = 0.0 }',
        "contact[0].friction.eps",
        "must be a positive number",
    ),
    (
        "support path",
        'set = "zmax"\nvalue = [0.02, 0.0, -0.06]',
        'set = "zmax"\nvalue = [0.02, 0.0, -0.06]\npath = [[1.0, 0.0, 0.0, -0.06]]',
        "supports[1].path",
        "either value",
    ),
    (
        "support path rows",
        'set = "zmax"\nvalue = [0.02, 0.0, -0.06]',
        'set = "zmax"\npath = [[0.5, 0.0, 0.0, -0.06], [0.4, 0.02, 0.0, -0.06]]',
        "supports[1].path",
        "increasing load factors",
    ),
    (
        "stress exponent",
        "[optimizer.mma]",
        '[[constraints]]\nresponse = "stress"\np = 1.0\nupper = 0.1\n[optimizer.mma]',
        "constraints[0].p",
        "must be a number >= 2 (the p-norm's exponent), got 1.0",
    ),
    (
        "stress relaxation",
        "[optimizer.mma]",
        '[[constraints]]\nresponse = "stress"\nq = "half"\nupper = 0.1\n[optimizer.mma]',
        "constraints[0].q",
        "must be a number",
    ),
    (
        "stress aggregate",
        "[optimizer.mma]",
        '[[constraints]]\nresponse = "stress"\naggregate = "max"\nupper = 0.1\n[optimizer.mma]',
        "constraints[0].aggregate",
        "must be one of",
    ),
    (
        "stress KS without its sharpness",
        "[optimizer.mma]",
        '[[constraints]]\nresponse = "stress"\naggregate = "ks"\nupper = 0.1\n[optimizer.mma]',
        "constraints[0].sharpness",
        'is needed with aggregate = "ks"',
    ),
    (
        "stress KS with the p-norm's exponent",
        "[optimizer.mma]",
        '[[constraints]]\nresponse = "stress"\naggregate = "ks"\np = 8.0\nsharpness = 50.0\n[optimizer.mma]',
        "constraints[0].p",
        "is the p-norm's exponent",
    ),
    (
        "stress sharpness of the p-norm",
        "[optimizer.mma]",
        '[[constraints]]\nresponse = "stress"\nsharpness = 50.0\nupper = 0.1\n[optimizer.mma]',
        "constraints[0].sharpness",
        'set aggregate = "ks"',
    ),
    (
        "stress KS sharpness",
        "[optimizer.mma]",
        '[[constraints]]\nresponse = "stress"\naggregate = "ks"\nsharpness = 0.0\nupper = 0.1\n[optimizer.mma]',
        "constraints[0].sharpness",
        "must be a number > 0",
    ),
    (
        "stress option on another response",
        'bodies = "block"\nsense',
        'bodies = "block"\nq = 0.5\nsense',
        "objective.q",
        "not an option of response 'strain-energy'",
    ),
    (
        "point set",
        "[[supports]]",
        '[[bodies.sets]]\nname = "tip"\nnearest = [[0.8, 0.8], [0.2, 0.2, 0.9]]\n[[supports]]',
        "bodies[1].sets[0].nearest",
        "must be a point [x, y, z] or a list of points",
    ),
]


@pytest.mark.parametrize("what, old, new, key, fragment", BAD, ids=[b[0] for b in BAD])
def test_bad_file_is_one_line_naming_the_key(tmp_path, what, old, new, key, fragment):
    assert TWO_BLOCKS.count(old) >= 1, old
    path = write(tmp_path, TWO_BLOCKS.replace(old, new, 1))
    with pytest.raises(SpecError) as info:
        load_spec(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: {key}: "), message
    assert fragment in message, message
    assert isinstance(info.value, ConfigError) and info.value.key == key


def test_syntax_error_gives_file_line_and_column(tmp_path):
    path = write(tmp_path, TWO_BLOCKS.replace("divisions = [4, 4, 2] }", "divisions = [4, 4, 2 }"))
    with pytest.raises(SpecError) as info:
        load_spec(path)
    message = str(info.value)
    assert re.fullmatch(rf"{re.escape(str(path))}:3:\d+: TOML syntax error: .+", message), message


@pytest.mark.parametrize(
    "overrides, flags, origins, expected",
    [
        ({"run.max_iter": -1}, {}, {}, "run.max_iter (override): must be an integer >= 0, got -1"),
        ({}, {"eta": 0.0}, {}, "--eta must be a number > 0, got 0.0 (design.eta)"),
        ({"design.bodies[2].body": "x"}, {}, {}, "design.bodies[2] (override): no such entry in the file"),
        (
            {"optimizer.name": "snopt"},
            {},
            {"optimizer.name": "--optimizer"},
            "--optimizer must be one of ['ipopt', 'mma'], got 'snopt'",
        ),
        (
            {"newton.n_steps": 0},
            {},
            {"newton.n_steps": "--set"},
            "--set newton.n_steps must be a positive integer, got 0",
        ),
    ],
)
def test_bad_override_names_the_key_and_where_it_came_from(tmp_path, overrides, flags, origins, expected):
    path = write(tmp_path, TWO_BLOCKS)
    with pytest.raises(SpecError) as info:
        load_spec(path, overrides, origins=origins, **flags)
    assert str(info.value).startswith(f"{path}: {expected}"), str(info.value)
    assert "\n" not in str(info.value)


def test_case_flags_on_a_full_description_and_bad_case_options(tmp_path):
    with pytest.raises(SpecError, match=r"--mesh applies to a file that names a registered case"):
        load_spec(write(tmp_path, TWO_BLOCKS), mesh="fine")
    with pytest.raises(
        SpecError,
        match=r"^<toml>: case: must be one of \[.*'die-slab'.*\], got 'die-slb'; "
        r"did you mean 'die-slab'\?$",
    ):
        load_spec('case = "die-slb"')
    with pytest.raises(SpecError, match=r"^<toml>: case_options.design: must be one of \['bspline'\], got 'density'"):
        load_spec('case = "die-slab-contact-force"\n[case_options]\ndesign = "density"')
    with pytest.raises(SpecError, match=r"^<toml>: bodies: unknown key; .*[(]a file that names a case"):
        load_spec('case = "cantilever"\n[[bodies]]\nname = "x"')


def test_a_named_case_brings_its_optimizer_and_options_unless_the_file_says_otherwise():
    sabot = load_spec('case = "sabot"\n[case_options]\nmesh = "coarse"\n', label="s.toml")
    assert sabot.optimizer == OPTIMIZATION_CASES["sabot"].optimizer == "ipopt"
    die = load_spec('case = "die-slab"\n', label="d.toml")
    assert die.optimizer == "mma" and die.options.kkt_tol == 5e-5 and die.options.change_tol == 0.0
    given = load_spec('case = "die-slab"\n[optimizer]\nname = "mma"\n[optimizer.mma]\nmove = 0.1\n', label="d.toml")
    assert given.options.move == 0.1 and given.options.kkt_tol == 1e-3  # the file's table replaces the case's


def test_the_contact_force_quadrature_is_read_from_the_file():
    from contopt.responses import ContactForce

    text = (Path(__file__).resolve().parents[2] / "examples" / "tutorial.toml").read_text()
    gauss = load_spec(text.replace('response = "contact-force"', 'response = "contact-force"\nquadrature = "gauss"'))
    objective = gauss.problem.objective
    inner = objective.parts[0] if not isinstance(objective, ContactForce) else objective
    assert isinstance(inner, ContactForce) and inner.quadrature == "gauss"
    assert load_spec(text).problem.objective.parts[0].quadrature == "overlap"
    with pytest.raises(ConfigError, match="quadrature"):
        load_spec(text.replace('response = "contact-force"', 'response = "contact-force"\nquadrature = "exact"'))


def test_friction_is_read_as_a_coefficient_or_a_table():
    from contopt.contact.coulomb import Coulomb

    def interface(text):
        spec = load_spec(TWO_BLOCKS.replace(MORTAR, MORTAR + '\nlaw = "penalty"\n' + text))
        return spec.problem.model.interfaces[0]

    assert interface("").friction is None
    assert interface("friction = 0.3").friction == Coulomb(0.3)
    assert interface("friction = { mu = 0.5, eps = 200.0 }").friction == Coulomb(0.5, eps=200.0)
    # an optimization through friction with the file's own law (the augmented Lagrangian): the path
    # adjoint differentiates either normal law
    alm = load_spec(TWO_BLOCKS.replace(MORTAR, MORTAR + "\nfriction = 0.3")).problem.model.interfaces[0]
    assert isinstance(alm.law, AugmentedLagrangian) and alm.friction == Coulomb(0.3)


MORTAR = 'mortar = { body = "block", set = "zmax" }'


def test_the_contact_law_s_old_key_says_its_new_name():
    with pytest.raises(SpecError, match=r'contact\[0\]\.enforcement: the key is now called law: write law = "penalty"'):
        load_spec(TWO_BLOCKS.replace(MORTAR, MORTAR + '\nenforcement = "penalty"'))


def test_responses_name_contact_interfaces_which_have_unique_names():
    from contopt.responses import ContactForce

    force = 'response = "contact-force"\nsense'
    named = TWO_BLOCKS.replace('response = "strain-energy"\nbodies = "block"\nsense', force)
    default = load_spec(named.replace("sense", 'interfaces = ["punch-block"]\nsense', 1))
    assert default.model.interfaces[0].name == "punch-block"
    assert default.problem.objective.parts[0].interfaces == ("punch-block",)
    seat = load_spec(
        named.replace(MORTAR, MORTAR + '\nname = "seat"').replace("sense", 'interfaces = "seat"\nsense', 1)
    )
    assert seat.model.interfaces[0].name == "seat"
    objective = seat.problem.objective.parts[0]
    assert isinstance(objective, ContactForce) and objective.interfaces == ("seat",)
    with pytest.raises(SpecError, match=r"objective\.interfaces: unknown contact interface 'punch'; did you mean"):
        load_spec(named.replace("sense", 'interfaces = ["punch"]\nsense', 1))
    with pytest.raises(SpecError, match=r"objective\.interfaces: give the interfaces' names, not their numbers"):
        load_spec(named.replace("sense", "interfaces = [0]\nsense", 1))
    contact = TWO_BLOCKS[TWO_BLOCKS.index("[[contact]]") : TWO_BLOCKS.index("[design]")]
    twice = TWO_BLOCKS.replace(contact, contact + contact)
    with pytest.raises(SpecError, match=r"contact\[1\]\.name: duplicate contact interface name 'punch-block' \(also"):
        load_spec(twice)
    assert len(load_spec(twice.replace(MORTAR, MORTAR + '\nname = "other"', 1)).model.interfaces) == 2


def test_contact_given_as_two_surfaces_gets_its_nonmortar_side_chosen():
    """The punch's bottom (facets of 0.2) and the block's top (0.25) count as one size (within 0.8), both flat:
    the softer block (E = 1 against 10) is chosen, whichever surface the file names first."""
    sides = 'nonmortar = { body = "punch", set = "zmin" }\nmortar = { body = "block", set = "zmax" }'
    for pair in (
        '{ body = "block", set = "zmax" }, { body = "punch", set = "zmin" }',
        '{ body = "punch", set = "zmin" }, { body = "block", set = "zmax" }',
    ):
        spec = load_spec(TWO_BLOCKS.replace(sides, f"surfaces = [{pair}]"), label="surfaces.toml")
        iface = spec.problem.model.interfaces[0]
        assert (iface.nonmortar, iface.mortar, iface.sides) == (("block", "zmax"), ("punch", "zmin"), "chosen")
        assert iface.choice.startswith("nonmortar block/zmax: the softer surface")


def test_a_cad_mesh_is_meshed_relative_to_the_problem_file_and_its_surfaces_are_sets(tmp_path, monkeypatch):
    gmsh = pytest.importorskip("gmsh")
    from contopt.mesh.cad import mesh_cad

    (tmp_path / "cad").mkdir()
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.occ.addBox(0.2, 0.2, 0.5, 0.6, 0.6, 0.4)  # the punch; OCC's faces 5 and 6: z min and z max
    gmsh.model.occ.synchronize()
    gmsh.write(str(tmp_path / "cad" / "punch.step"))
    gmsh.finalize()
    text = (
        TWO_BLOCKS.replace(
            'mesh = { generator = "box", lengths = [0.6, 0.6, 0.4], divisions = [3, 3, 1], origin = [0.2, 0.2, 0.5] }',
            'mesh = { cad = "cad/punch.step", size = 0.25 }',
        )
        .replace('body = "punch"\nset = "zmax"', 'body = "punch"\nset = "surface_6"')
        .replace('nonmortar = { body = "punch", set = "zmin" }', 'nonmortar = { body = "punch", set = "surface_5" }')
    )
    path = write(tmp_path, text)
    monkeypatch.chdir(tmp_path / "cad")  # not where the file is
    punch = load_spec(path).model.body("punch").mesh
    expected = mesh_cad(tmp_path / "cad" / "punch.step", 0.25)
    np.testing.assert_array_equal(punch.points, expected.points)
    assert set(punch.facet_sets) == {f"surface_{n}" for n in range(1, 7)}
    assert np.all(punch.points[punch.node_set("surface_5"), 2] == 0.5)
    for key, value, said in (
        ("order", "2", 'order = 2 is tet10: set element = "tet"'),
        ("element", '"hexa"', "element"),
        ("size", "-1.0", "size: must be a number > 0"),  # replaces the file's size
        ("scale", "0", "scale: must be a number > 0"),
        ("file", '"x.msh"', "cad: give one of file (a mesh file), cad (a CAD file Gmsh meshes) or envelope"),
    ):
        given = f"{key} = {value}" if key == "size" else f"size = 0.25, {key} = {value}"
        bad = text.replace("size = 0.25 }", given + " }")
        with pytest.raises(SpecError, match=re.escape(said)) as err:
            load_spec(write(tmp_path, bad))
        assert "bodies[1].mesh" in str(err.value) and "\n" not in str(err.value)
    tet = load_spec(write(tmp_path, text.replace("size = 0.25 }", 'size = 0.25, element = "tet" }'))).model
    assert tet.body("punch").mesh.element == "tet4"  # and its contact on triangle facets is accepted


def test_a_stress_constraint_is_read_with_its_options():
    from contopt.responses import Stress

    text = TWO_BLOCKS.replace(
        "[optimizer.mma]",
        '[[constraints]]\nresponse = "stress"\nbodies = "block"\np = 6\nq = 0.25\nupper = 0.05\n[optimizer.mma]',
    )
    (constraint,) = load_spec(text).problem.constraints
    stress = constraint.response
    assert isinstance(stress, Stress) and (stress.bodies, stress.p, stress.q) == (("block",), 6.0, 0.25)
    assert constraint.upper == 0.05 and constraint.rows()[0][0] == "stress<=0.05"


def test_a_ks_stress_constraint_is_read_with_its_sharpness():
    from contopt.cases.problem_summary import response_words
    from contopt.responses import Stress

    text = TWO_BLOCKS.replace(
        "[optimizer.mma]",
        '[[constraints]]\nresponse = "stress"\naggregate = "ks"\nsharpness = 40\nupper = 0.05\n[optimizer.mma]',
    )
    (constraint,) = load_spec(text).problem.constraints
    stress = constraint.response
    assert isinstance(stress, Stress) and (stress.aggregate, stress.sharpness) == ("ks", 40.0)
    assert "the KS function, sharpness 40," in response_words(stress)[1]


def test_a_stress_region_is_read_as_the_design_boxes_are():
    from contopt.cases.problem_summary import response_words
    from contopt.design import BoxRegion

    box = "region = { lower = [0.0, 0.0, 0.0], upper = [0.5, 1.0, 1.0] }"
    text = TWO_BLOCKS.replace(
        "[optimizer.mma]",
        f'[[constraints]]\nresponse = "stress"\nbodies = "block"\n{box}\nupper = 0.05\n[optimizer.mma]',
    )
    (constraint,) = load_spec(text).problem.constraints
    region = constraint.response.region
    assert isinstance(region, BoxRegion) and (region.lower, region.upper) == ((0.0, 0.0, 0.0), (0.5, 1.0, 1.0))
    assert response_words(constraint.response)[1].endswith(
        "of block, cells with centre in the box (0, 0, 0) to (0.5, 1, 1)"
    )
    bad = text.replace("upper = [0.5, 1.0, 1.0]", "upper = [0.5, 1.0]")
    with pytest.raises(SpecError, match=r"constraints\[0\]\.region.*upper") as err:
        load_spec(bad)
    assert "\n" not in str(err.value)
