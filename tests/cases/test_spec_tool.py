"""Rigid tools in a problem file (contopt.cases.spec_tool): ``rigid = {...}`` and ``motion = {...}`` in
[[bodies]] read into the Model the Python API builds, and a bad one is one line naming the key."""

import numpy as np
import pytest

from contopt.assembly.model import LoadPath, RigidMotion
from contopt.cases.spec import SpecError, load_spec
from contopt.errors import ConfigError
from contopt.mesh.tool import cylinder_surface, plane_surface, sphere_surface, tool_layer

#: a block pressed by a rigid cylinder arc that turns as it presses
ROLLER = """\
[[bodies]]
name = "block"
mesh = { generator = "box", lengths = [1.0, 1.0, 0.5], divisions = [4, 4, 2] }
material = { model = "neo-hookean", E = 1.0, nu = 0.3 }

[[bodies]]
name = "roller"
rigid = { shape = "cylinder", radius = 0.3, length = 1.2, center = [0.5, 0.5, 0.8], axis = "y", arc_deg = 90.0, normal = [0.0, 0.0, -1.0], divisions = [8, 2] }
motion = { path = [[0.5, 0.0, 0.0, -0.05], [1.0, 0.2, 0.0, -0.05]], rotation = { axis = "y", point = [0.5, 0.5, 0.8], angle_deg = [[0.5, 0.0], [1.0, -38.2]] } }

[[supports]]
body = "block"
set = "zmin"

[[contact]]
surfaces = [{ body = "roller", set = "surface" }, { body = "block", set = "zmax" }]

[design]

[[design.bodies]]
body = "block"
volume_fraction = 0.4
density = { radius = 0.3 }

[objective]
response = "contact-force"
interfaces = "roller-block"
direction = [0.0, 0.0, 1.0]
"""
RIGID = 'rigid = { shape = "cylinder", radius = 0.3, length = 1.2, center = [0.5, 0.5, 0.8], axis = "y", arc_deg = 90.0, normal = [0.0, 0.0, -1.0], divisions = [8, 2] }'
MOTION = next(line for line in ROLLER.splitlines() if line.startswith("motion"))


def test_a_rigid_tool_reads_into_the_model_the_python_builds():
    spec = load_spec(ROLLER, check=False)
    roller = spec.model.body("roller")
    surface = cylinder_surface(0.3, 1.2, (0.5, 0.5, 0.8), "y", (8, 2), arc=np.pi / 2, normal=(0, 0, -1.0))
    np.testing.assert_allclose(roller.mesh.points, tool_layer(surface).points, atol=1e-15)
    assert roller.rigid == RigidMotion(
        translation=LoadPath(((0.5, 0.0, 0.0, -0.05), (1.0, 0.2, 0.0, -0.05))),
        axis=(0.0, 1.0, 0.0),
        point=(0.5, 0.5, 0.8),
        angle=LoadPath(((0.5, 0.0), (1.0, np.deg2rad(-38.2)))),
    )
    assert spec.model.interfaces[0].nonmortar == ("block", "zmax")  # the tool is the mortar side
    assert [bc.body for bc in spec.model.dirichlet] == ["block", "roller"]


def test_every_shape_and_a_surface_file_read(tmp_path):
    plane = 'rigid = { shape = "plane", center = [0.5, 0.5, 0.8], normal = [0, 0, 1], size = [1.2, 0.8], divisions = [3, 2], flip = true }'
    body = load_spec(ROLLER.replace(RIGID, plane).replace(MOTION, ""), check=False).model.body("roller")
    expected = plane_surface((0.5, 0.5, 0.8), (0, 0, 1), (1.2, 0.8), (3, 2)).flipped()  # facing down
    np.testing.assert_allclose(body.mesh.points, tool_layer(expected).points, atol=1e-15)
    assert body.rigid == RigidMotion()  # no motion: it stays
    cap = 'rigid = { shape = "sphere", radius = 0.4, center = [0.5, 0.5, 0.9], divisions = 4, angle_deg = 30.0, thickness = 0.25 }'
    body = load_spec(ROLLER.replace(RIGID, cap), check=False).model.body("roller")
    expected = sphere_surface(0.4, (0.5, 0.5, 0.9), 4, angle=np.pi / 6)
    np.testing.assert_allclose(body.mesh.points, tool_layer(expected, 0.25).points, atol=1e-15)
    # a surface file, relative to the problem file, in mm for a model in m
    points = 1000 * np.array([[0.0, 0, 0.5], [1, 0, 0.5], [1, 1, 0.5], [0, 1, 0.5]])
    (tmp_path / "tools").mkdir()
    facets = "".join(
        f"facet normal 0 0 -1\nouter loop\n{''.join(f'vertex {p[0]} {p[1]} {p[2]}' + chr(10) for p in points[t])}"
        "endloop\nendfacet\n"
        for t in ([0, 2, 1], [0, 3, 2])
    )
    (tmp_path / "tools" / "plate.stl").write_text(f"solid plate\n{facets}endsolid plate\n")
    text = ROLLER.replace(RIGID, 'rigid = { file = "tools/plate.stl", scale = 0.001 }')
    (tmp_path / "case.toml").write_text(text)
    body = load_spec(tmp_path / "case.toml", check=False).model.body("roller")
    face = body.mesh.points[body.mesh.facet_nodes("surface")]
    assert len(face) == 6 and np.allclose(face[..., 2], 0.5)
    area = 0.5 * np.cross(face[:, 2] - face[:, 0], face[:, 3] - face[:, 1])
    np.testing.assert_allclose(area.sum(axis=0), [0.0, 0.0, -1.0], atol=1e-12)  # facing down, 1 x 1


BAD = [
    # (what, replace this, with this, key, fragment)
    (
        "material on a tool",
        MOTION,
        'material = { model = "neo-hookean", E = 1.0, nu = 0.3 }',
        "bodies[1].material",
        "a rigid tool takes no mesh, material or fbar",
    ),
    ("motion without rigid", RIGID, "", "bodies[1].motion", "give its surface as rigid = {...}"),
    ("no shape", 'shape = "cylinder", ', "", "bodies[1].rigid", "needs shape (one of ['plane', 'cylinder', 'sphere'])"),
    ("bad shape", 'shape = "cylinder"', 'shape = "cone"', "bodies[1].rigid.shape", "must be one of"),
    ("a plane's key", "arc_deg = 90.0, normal", "size = 1.0, normal", "bodies[1].rigid.size", "unknown key"),
    (
        "negative radius",
        "radius = 0.3, length",
        "radius = -0.3, length",
        "bodies[1].rigid.radius",
        "must be a number > 0",
    ),
    ("bad axis", 'axis = "y", arc', 'axis = "w", arc', "bodies[1].rigid.axis", "must be one of ['x', 'y', 'z']"),
    ("no file", RIGID, 'rigid = { file = "none.stl" }', "bodies[1].rigid.file", "no such file"),
    ("two translations", "motion = { path", "motion = { value = [0, 0, 1], path", "bodies[1].motion.path", "not both"),
    ("no angle", ", angle_deg = [[0.5, 0.0], [1.0, -38.2]]", "", "bodies[1].motion.rotation.angle_deg", "missing"),
    (
        "two angles",
        "angle_deg = [[0.5",
        "angle = 0.1, angle_deg = [[0.5",
        "bodies[1].motion.rotation.angle_deg",
        "one of the two",
    ),
    (
        "bad path",
        "[[0.5, 0.0], [1.0, -38.2]]",
        "[[0.5, 0.0], [0.9, -38.2]]",
        "bodies[1].motion.rotation.angle_deg",
        "ending at 1",
    ),
    (
        "support on a tool",
        'set = "zmin"',
        'set = "zmin"\n\n[[supports]]\nbody = "roller"\nset = "surface"',
        "supports[1].body",
        "body 'roller' is rigid: its motion prescribes every node",
    ),
    (
        "tool as nonmortar",
        'surfaces = [{ body = "roller", set = "surface" }, { body = "block", set = "zmax" }]',
        'nonmortar = { body = "roller", set = "surface" }\nmortar = { body = "block", set = "zmax" }',
        "contact[0]",
        "must be the mortar side: swap nonmortar and mortar",
    ),
    (
        "designed tool",
        'body = "block"\nvolume_fraction',
        'body = "roller"\nvolume_fraction',
        "design.bodies[0].body",
        "rigid tool",
    ),
]


@pytest.mark.parametrize("what, old, new, key, fragment", BAD, ids=[b[0] for b in BAD])
def test_a_bad_tool_is_one_line_naming_the_key(what, old, new, key, fragment):
    assert ROLLER.count(old) == 1, old
    with pytest.raises(SpecError) as info:
        load_spec(ROLLER.replace(old, new))
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"<toml>: {key}: "), message
    assert fragment in message, message
    assert isinstance(info.value, ConfigError)
