"""A design domain from a shape: a bracket envelope (an STL) voxelized, a keep-in box and a keep-out
closed surface, solved, optimized a little and exported (docs/cad.md, "A design domain from a shape")."""

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
from _envelope import DEPTH, PROFILE, bracket, write_bracket  # tests/_envelope.py

from contopt.cases.spec import SpecError, load_spec
from contopt.design import SurfaceRegion
from contopt.design.surface import body_surface
from contopt.io.surface import write_surface
from contopt.optimize.driver import optimize
from contopt.optimize.mma import MMAOptions
from contopt.optimize.problem import DesignNLP
from contopt.solve.static import solve_static
from contopt.solve.system import System

SIZE = 0.2
TRACTION = 1e-4
#: the bracket: its wall's top clamped, the foot's end pulled down; a boss at the foot's end kept solid
#: and a slot through the foot kept void (a closed surface)
BRACKET = f"""
name = "bracket"
[[bodies]]
name = "bracket"
mesh = {{ envelope = "bracket.stl", size = {SIZE} }}
material = {{ model = "neo-hookean", E = 1.0, nu = 0.3 }}

[[supports]]
body = "bracket"
set = "zmax"
components = "xyz"

[[loads]]
type = "traction"
body = "bracket"
set = "xmax"
traction = [0.0, 0.0, -{TRACTION}]

[design]
eta = 10.0

[[design.bodies]]
body = "bracket"
volume_fraction = 0.4
density = {{ radius = 0.3 }}
solid = {{ lower = [1.55, -1.0, -1.0], upper = [3.0, 3.0, 3.0] }}
void = "slot.stl"

[objective]
response = "compliance"
normalize = "full"

[optimizer]
name = "mma"
"""


def _files(tmp_path) -> Path:
    write_bracket(tmp_path / "bracket.stl")
    slot = np.array([(0.75, -1.0), (1.25, -1.0), (1.25, 1.0), (0.75, 1.0)])  # x 0.75..1.25, through the foot
    write_surface(bracket(slot, 0.4, origin=(0.0, 0.2, 0.0)), tmp_path / "slot.stl")  # y 0.2..0.6
    path = tmp_path / "bracket.toml"
    path.write_text(BRACKET)
    return path


@pytest.fixture(scope="module")
def problem(tmp_path_factory):
    return load_spec(_files(tmp_path_factory.mktemp("bracket"))).problem


def test_the_clamp_takes_the_load(problem):
    """Small load: the reactions on the clamped top balance the traction on the foot's end."""
    model = problem.model
    mesh = model.body("bracket").mesh
    system = System.of(model)
    state = solve_static(system)
    clamped = mesh.node_set("zmax")
    reaction = np.asarray(state.reactions).reshape(-1, 3)[clamped].sum(axis=0)
    area = len(mesh.facet_set("xmax")) * SIZE**2
    np.testing.assert_allclose(reaction, [0.0, 0.0, TRACTION * area], atol=1e-6 * TRACTION * area)
    tip = np.asarray(state.u).reshape(-1, 3)[mesh.node_set("xmax"), 2]
    assert np.all(tip < 0)  # pulled down


def test_keep_in_and_keep_out_hold_after_a_few_iterations(problem):
    nlp = DesignNLP(problem)
    part = nlp.space.parts[0]
    X = part.centroids
    solid = X[:, 0] >= 1.55
    slot = (np.abs(X[:, 0] - 1.0) < 0.25) & (X[:, 1] > 0.2) & (X[:, 1] < 0.6) & (X[:, 2] < 1.0)
    np.testing.assert_array_equal(part.fixed == 1, solid)
    np.testing.assert_array_equal(part.fixed == 0, slot)
    assert slot.sum() and solid.sum()
    # no bleed: a free cell's filtered value reads no fixed cell's variable
    assert part.G[part.fixed < 0][:, part.fixed >= 0].nnz == 0
    res = optimize(problem, "mma", MMAOptions(max_iter=2))
    nu = res.fields.nu[part.cells]
    np.testing.assert_array_equal(nu[solid], 1.0)
    np.testing.assert_array_equal(nu[slot], 0.0)
    assert res.iterations == 2
    assert np.ptp(nu[~solid & ~slot]) > 0.1  # the free cells did move


def _outside(P: np.ndarray) -> np.ndarray:
    """Distance of points (k, 3) outside the bracket (0 inside): the profile's in x-z, y's beyond the depth."""
    x, z = P[:, 0], P[:, 2]
    a, b = PROFILE, np.roll(PROFILE, -1, axis=0)
    d = np.full(len(P), np.inf)
    crossings = np.zeros(len(P), int)
    for (ax, az), (bx, bz) in zip(a, b):
        ex, ez = bx - ax, bz - az
        s = np.clip(((x - ax) * ex + (z - az) * ez) / (ex * ex + ez * ez), 0.0, 1.0)
        d = np.minimum(d, np.hypot(x - ax - s * ex, z - az - s * ez))
        up = (az <= z) != (bz <= z)
        crossings += up & (x < ax + (z - az) * ex / np.where(ez == 0, 1.0, ez))
    d_xz = np.where(crossings % 2 == 1, 0.0, d)
    d_y = np.maximum(0.0, np.maximum(-P[:, 1], P[:, 1] - DEPTH))
    return np.hypot(d_xz, d_y)


def _all_solid_surface(problem):
    nlp = DesignNLP(problem)
    x = nlp.space.initial()
    x[:] = 1.0  # all the material there may be: the surface reaches the envelope everywhere
    return body_surface(nlp.space, x, nlp.system.disc)


def test_the_exported_surface_is_cut_to_the_envelope(problem):
    """The reader hands the envelope to the design, and the export cuts the voxels' staircase to it:
    no vertex lies more than a tenth of a cube outside (the lattice's spacing is a third of a cube,
    Taubin smoothing moves vertices by less than that); without the envelope the staircase sticks out
    by more than that, so the test can fail."""
    assert problem.design.bodies[0].envelope is not None
    trimmed = _all_solid_surface(problem)
    assert _outside(trimmed.surface.vertices).max() <= 0.1 * SIZE
    assert trimmed.volume < 1.296  # the slot is cut out of the envelope's volume
    body = dataclasses.replace(problem.design.bodies[0], envelope=None)
    staircase = _all_solid_surface(
        dataclasses.replace(problem, design=dataclasses.replace(problem.design, bodies=(body,)))
    )
    excess = _outside(staircase.surface.vertices)
    assert 0.1 * SIZE < excess.max() <= SIZE


def test_bad_envelope_keys_are_refused_in_one_line(tmp_path):
    path = _files(tmp_path)
    for old, new, said in (
        (f", size = {SIZE} }}", " }", "bodies[0].mesh.size: required"),
        (f"size = {SIZE} }}", f"size = {SIZE}, order = 2 }}", "bodies[0].mesh.order: unknown key"),
        (f"size = {SIZE} }}", "size = -1 }", "bodies[0].mesh.size: must be"),
        (f"size = {SIZE} }}", f'size = {SIZE}, file = "x.msh" }}', "give one of file"),
        (f"size = {SIZE} }}", f'size = {SIZE}, element = "tet" }}', "element"),
        ('"bracket.stl"', '"missing.stl"', "bodies[0].mesh.envelope: no such file"),
        ('void = "slot.stl"', 'void = { file = "slot.stl", lower = [0, 0, 0] }', "lower: give a box"),
        ('void = "slot.stl"', "void = { lower = [0, 0, 0] }", "needs a box"),
        ('void = "slot.stl"', 'void = { file = "nope.stl" }', "void.file: no such file"),
        ('void = "slot.stl"', 'void = ["slot.stl", { lower = [0, 0, 0], upper = 1 }]', r"void\[1\]\.upper"),
    ):
        path.write_text(BRACKET.replace(old, new))
        with pytest.raises(SpecError, match=re.escape(said) if "\\" not in said else said) as err:
            load_spec(path, check=False)
        assert "\n" not in str(err.value), str(err.value)


def test_regions_from_surfaces_scaled_listed_and_in_a_stress_response(tmp_path):
    """A list of surfaces is their union; scale = 2 doubles the slot about the origin; a stress's
    region takes a surface as the design's void does."""
    from contopt.cases.problem_summary import response_words

    path = _files(tmp_path)
    path.write_text(
        BRACKET.replace('void = "slot.stl"', 'void = [{ file = "slot.stl", scale = 2.0 }, "slot.stl"]')
        + '\n[[constraints]]\nresponse = "stress"\nregion = "slot.stl"\nupper = 1.0\n'
    )
    problem = load_spec(path, check=False).problem
    void = problem.design.bodies[0].void
    assert [type(r) for r in void.boxes] == [SurfaceRegion, SurfaceRegion]
    X = np.array([[1.0, 0.4, 0.2], [2.2, 0.8, 0.2], [2.2, 0.3, 0.2]])  # in the slot, in it doubled, in neither
    np.testing.assert_array_equal(void(X), [True, True, False])
    np.testing.assert_array_equal(void.boxes[1](X), [True, False, False])
    region = problem.constraints[0].response.region
    assert isinstance(region, SurfaceRegion) and region.name == "slot.stl"
    assert response_words(problem.constraints[0].response)[1].endswith("cells in its region")
