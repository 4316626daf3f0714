"""The problem in plain words (contopt.cases.problem_summary): every fact it states is the problem
file's, read here from the TOML itself; and `contopt run` keeps it for report.html."""

import tomllib
from pathlib import Path

import numpy as np
import pytest

from contopt.assembly.model import Body, Dirichlet, LoadPath, Model
from contopt.cases.problem_summary import model_summary, problem_summary
from contopt.cases.spec import bundled_cases, load_spec
from contopt.material.hyperelastic import MooneyRivlin
from contopt.mesh.generators import box

ROOT = Path(__file__).resolve().parents[2]
FILES = {**bundled_cases(), "tutorial": ROOT / "examples" / "tutorial.toml"}


def _g(v) -> str:
    return "0" if float(v) == 0 else f"{float(v):g}"


def _by(components: str, value) -> str:
    values = np.broadcast_to(np.atleast_1d(np.asarray(value, dtype=float)), (len(components),))
    if components == "xyz":
        return "(" + ", ".join(_g(v) for v in values) + ")"
    if len(components) == 1:
        return f"{_g(values[0])} in {components}"
    return "(" + ", ".join(_g(v) for v in values) + ") in " + ", ".join(components)


@pytest.fixture(scope="module", params=sorted(FILES))
def read(request):
    """(the file's TOML as data, {topic: sentence}, the spec) of a bundled problem file or the tutorial's."""
    path = FILES[request.param]
    spec = load_spec(path, check=False)
    words = {s.topic: s.text for s in problem_summary(spec.problem)}
    return tomllib.loads(path.read_text(encoding="utf-8")), words, spec


def test_bodies_with_their_cells_and_materials(read):
    data, words, spec = read
    assert words["bodies"].split(":")[0] in ("One body", "Two bodies", "Three bodies")
    for entry in data["bodies"]:
        mesh = spec.model.body(entry["name"]).mesh
        if "rigid" in entry:  # a tool: its facets, no material
            assert f"{entry['name']} (a rigid tool, {len(mesh.cells):,} facets)" in words["bodies"]
            continue
        if entry["mesh"].get("generator") == "box":  # the file says how many cells
            assert len(mesh.cells) == int(np.prod(entry["mesh"]["divisions"]))
        material = entry["material"]
        said = f"{entry['name']} (hex8, {len(mesh.cells):,} cells, neo-Hookean, E = {_g(material['E'])}, "
        assert said + f"nu = {_g(material['nu'])}" in words["bodies"], said


def test_supports_and_prescribed_motions(read):
    data, words, spec = read
    steps = data.get("newton", {}).get("n_steps", 1)
    for entry in data.get("supports", []):
        where, components = f"{entry['body']}/{entry['set']}", entry.get("components", "xyz")
        if "path" in entry:
            stops = [f"{_by(components, row[1:])} at load factor {_g(row[0])}" for row in entry["path"]]
            assert f"{where} moved along a path through {stops[0]}" in words["motions"]
            assert stops[-1] in words["motions"]
        elif np.any(entry.get("value", 0.0)):
            assert f"{where} moved by {_by(components, entry['value'])}" in words["motions"]
        else:
            assert f"{where} fixed in {', '.join(components)}" in words["supports"]
    for entry in data["bodies"]:  # a rigid tool moved by a translation (the bundled tools' motion)
        if "value" in entry.get("motion", {}):
            assert (
                f"{entry['name']}/all moved rigidly: translated by {_by('xyz', entry['motion']['value'])}"
                in words["motions"]
            )
    if "motions" in words:
        assert words["motions"].startswith(f"Prescribed motions over {steps} load step")


def test_contact_interfaces_with_the_nonmortar_side_and_who_chose_it(read):
    data, words, spec = read
    entries = data.get("contact", [])
    assert ("contact" in words) == bool(entries)
    for entry, iface in zip(entries, spec.model.interfaces, strict=True):
        law = {"alm": "augmented Lagrangian", "penalty": "penalty"}[entry.get("law", "alm")]
        if "nonmortar" in entry:
            nonmortar, mortar = entry["nonmortar"], entry["mortar"]
            name = entry.get("name", f"{nonmortar['body']}-{mortar['body']}")
            side = f"nonmortar side {nonmortar['body']}/{nonmortar['set']} (given by the user)"
            assert f"interface {name}: {side}, mortar side {mortar['body']}/{mortar['set']}, {law}" in words["contact"]
        else:  # two surfaces: contopt chose, and the summary says which and why
            a, b = entry["surfaces"]
            name = entry.get("name", f"{a['body']}-{b['body']}")
            chosen = "/".join(iface.nonmortar)
            assert chosen in (f"{a['body']}/{a['set']}", f"{b['body']}/{b['set']}")
            tools = {body["name"] for body in data["bodies"] if "rigid" in body}
            rigid = bool(tools & {a["body"], b["body"]})
            why = "the deformable surface (the other is a rigid tool)" if rigid else "the finer surface"
            assert f"interface {name}: nonmortar side {chosen} (chosen: {why}" in words["contact"]
        friction = entry.get("friction")
        assert ("frictionless" if friction is None else f"Coulomb friction mu = {_g(friction['mu'])}") in words[
            "contact"
        ]


def test_the_design_and_the_objective(read):
    data, words, _ = read
    for entry in data["design"]["bodies"]:
        assert f"{entry['body']} (" in words["design"]
        if "density" in entry:
            assert f"cone filter radius {_g(entry['density']['radius'])}" in words["design"]
        else:
            assert f"{' x '.join(str(n) for n in entry['bspline']['control_points'])} control points" in words["design"]
        assert f"volume fraction \u2264 {_g(entry['volume_fraction'])}" in words["design"]
    objective = data["objective"]
    sense = objective.get("sense", "minimize")
    assert words["objective"].startswith(f"Objective: {sense} the {objective['response'].replace('-', ' ')} ")
    bodies = objective.get("bodies")
    if isinstance(bodies, str):
        assert f"of {bodies}" in words["objective"]
    for name in objective.get("interfaces", []):
        assert f"at interface {name}" in words["objective"]
    if objective.get("normalize", "full") == "full":
        assert words["objective"].endswith("divided by its value at the full design.")


def test_a_model_built_in_python():
    """Motions as a path, as a function and along some components; a Mooney-Rivlin body; no contact."""
    mesh = box((1.0, 1.0, 1.0), (2, 2, 2))
    model = Model(
        bodies=(Body("cube", mesh, MooneyRivlin.from_E_nu(2.0, 0.45, b_fraction=0.25), fbar=False),),
        dirichlet=(
            Dirichlet("cube", "zmin", "z", 0.0),
            Dirichlet("cube", "zmax", "z", -0.1),
            Dirichlet("cube", "xmax", "xy", LoadPath(((0.5, 0.0, 0.1), (1.0, 0.2, 0.1)))),
            Dirichlet("cube", "xmin", "xy", lambda X, t: 0 * X[:, :2]),
        ),
    )
    words = {s.topic: s.text for s in model_summary(model, n_steps=3)}
    assert words["bodies"] == "One body: cube (hex8, 8 cells, Mooney-Rivlin, E = 2, nu = 0.45, b_fraction = 0.25)."
    assert words["supports"] == "Supports: cube/zmin fixed in z."
    assert words["motions"] == (
        "Prescribed motions over 3 load steps: cube/zmax moved by -0.1 in z; cube/xmax moved along a path "
        "through (0, 0.1) in x, y at load factor 0.5 and (0.2, 0.1) in x, y at load factor 1; "
        "cube/xmin moved as a function of position and load factor."
    )
    assert set(words) == {"bodies", "supports", "motions"}


def test_the_summary_says_what_a_load_path_response_reads():
    from contopt.cases.optimization import optimization_case
    from contopt.cases.problem_summary import response_words
    from contopt.responses.path import ForceMax

    assert response_words(optimization_case("press-pad").objective) == (
        "minimize",
        "the force target (the mean squared miss of the contact force at every interface from its target curve at 6 "
        "load steps)",
    )
    extreme = -ForceMax(4, 10.0, interfaces=["a"], direction=[0.0, 0.0, -1.0])
    assert response_words(extreme) == (
        "maximize",
        "the force max (the largest contact force at interface a along (0, 0, -1) over 4 load steps, smoothly)",
    )


def test_the_summary_says_what_the_stress_response_aggregates():
    from contopt.cases.optimization import optimization_case
    from contopt.cases.problem_summary import response_words
    from contopt.responses import Stress

    (limit,) = optimization_case("die-slab-stress").constraints
    assert response_words(limit.response) == (
        "minimize",
        "the stress (the 8-norm of the von Mises stress relaxed as rho^0.5) of slab",
    )
    assert response_words(Stress(p=6, q=0.25))[1].endswith("relaxed as rho^0.25) of all bodies")
