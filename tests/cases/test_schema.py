"""The problem file's JSON Schema and `contopt explain` (contopt.cases.schema): the bundled files pass
the schema, and the schema and the reader know the same keys, table by table."""

import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import jsonschema
import pytest

from contopt.cases.keys_model import GENERATORS, LOADS, SHAPES
from contopt.cases.schema import SECTIONS, explain, json_schema
from contopt.cases.spec import bundled_cases, load_spec
from contopt.cases.toml_reader import SpecError, Table
from contopt.cli import main
from contopt.responses.catalog import RESPONSES

ROOT = Path(__file__).resolve().parents[2]
FILES = sorted(bundled_cases().values()) + sorted((ROOT / "examples").glob("*.toml"))

BASE = """\
[[bodies]]
name = "block"
mesh = { generator = "box", lengths = [1.0, 1.0, 0.5], divisions = [2, 2, 1] }
material = { model = "neo-hookean", E = 1.0, nu = 0.3 }

[[bodies]]
name = "punch"
mesh = { generator = "box", lengths = [0.6, 0.6, 0.4], divisions = [1, 1, 1], origin = [0.2, 0.2, 0.5] }
material = { model = "neo-hookean", E = 10.0, nu = 0.3 }

[[supports]]
body = "block"
set = "zmin"

[[supports]]
body = "punch"
set = "zmax"
value = [0.0, 0.0, -0.05]

[[contact]]
nonmortar = { body = "punch", set = "zmin" }
mortar = { body = "block", set = "zmax" }

[design]

[[design.bodies]]
body = "block"
density = { radius = 0.6 }

[objective]
response = "strain-energy"
"""

BLOCK = {"generator": "box", "lengths": [1.0, 1.0, 0.5]}
BOX = {"lower": [0.0, 0.0, 0.0], "upper": [1.0, 1.0, 1.0]}
PLATE = {"shape": "plane", "center": [0.5, 0.5, 0.5], "normal": [0.0, 0.0, -1.0], "size": 0.6}
#: (file text, overrides) that lead the reader into every table and every form of one
VISITS = [
    *((BASE, {"bodies[0].mesh": {"generator": g}}) for g in GENERATORS),
    (BASE, {"bodies[0].mesh": {"file": "nowhere.msh"}}),
    (BASE, {"bodies[0].mesh": {"cad": "nowhere.step"}}),
    (BASE, {"bodies[0].mesh": {"envelope": "nowhere.stl"}}),
    (BASE, {"bodies[0].material": {"model": "neo-hookean"}}),
    (BASE, {"bodies[0].material": {"model": "mooney-rivlin", "kappa": 1.0}}),
    (BASE, {"bodies[0].material": {"model": "mooney-rivlin", "E": 1.0, "nu": 0.3}}),
    (BASE, {"bodies[0].sets": [{"name": "top", "z": [0.5, 0.5]}]}),
    *((BASE, {"bodies[1]": {"name": "punch", "rigid": {"shape": shape}}}) for shape in SHAPES),
    (BASE, {"bodies[1]": {"name": "punch", "rigid": {"file": "nowhere.stl"}}}),
    (BASE, {"bodies[1]": {"name": "punch", "rigid": PLATE, "motion": {"rotation": {"axis": "z"}}}}),
    (BASE, {"soft_supports": [{"body": "block", "stiffness": 1.0}]}),
    *((BASE, {"loads": [{"type": kind, "body": "block"}]}) for kind in LOADS),
    (BASE, {"contact[0].check": {"tolerance": 1e-3}, "contact[0].friction": {"mu": 0.3}}),
    (BASE, {"contact[0]": {"surfaces": [{"body": "punch", "set": "zmin"}, {"body": "block", "set": "zmax"}]}}),
    (BASE, {"design.bodies[0]": {"body": "block", "bspline": {"control_points": [4, 4, 4]}}}),
    (BASE, {"design.bodies[0].symmetry": {"sectors": 2}, "design.bodies[0].skins": [{"radius": 0.1}]}),
    (BASE, {"design.bodies[0].solid": BOX, "design.bodies[0].void": [BOX]}),
    (BASE, {"design.robust": {"delta": 0.1}}),
    (BASE, {"design.eta_continuation": {"start": 4}}),
    *((BASE, {"objective": {"response": name}}) for name in RESPONSES),
    *((BASE, {"constraints": [{"response": name, "upper": 1.0}]}) for name in RESPONSES),
    (BASE, {"optimizer": {"name": "mma", "mma": {}, "ipopt": {}}, "run": {"max_iter": 1}}),
    (BASE, {"newton": {}, "augmentation": {}, "linear": {}, "adjoint": {}}),
    (BASE + '[variants]\nmesh = ["a"]\n[[variants.when]]\nmesh = "a"\nset = {}\n', {}),
    (BASE, {"load_cases": [{"name": "a", "motions": [{"body": "punch"}]}]}),
    (
        BASE,
        {"bodies[1]": {"name": "punch", "rigid": PLATE}, "load_cases": [{"name": "a", "motions": [{"body": "punch"}]}]},
    ),
    ('case = "die-slab"\n[case_options]\nmesh = "coarse"\n', {}),
]


def test_the_schema_is_a_json_schema_and_every_bundled_file_passes_it():
    schema = json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    validator = jsonschema.Draft202012Validator(schema)
    assert FILES and all(p.exists() for p in FILES)
    for path in FILES:
        errors = [
            f"{list(e.absolute_path)}: {e.message[:200]}"
            for e in validator.iter_errors(tomllib.loads(path.read_text()))
        ]
        assert errors == [], path.name


def test_the_schema_rejects_what_the_reader_rejects():
    validator = jsonschema.Draft202012Validator(json_schema())
    good = tomllib.loads(BASE)
    assert list(validator.iter_errors(good)) == []
    for path, value in (
        (("contact", 0, "law"), "exact"),  # not a law
        (("contact", 0, "lw"), "alm"),  # not a key
        (("bodies", 0, "mesh", "radius"), 1.0),  # not a key of a box
        (("objective", "interfaces"), ["punch-block"]),  # not an option of strain-energy
        (("newton", "max_iter"), 2.5),  # not an integer
    ):
        bad = tomllib.loads(BASE)
        node = bad
        for step in path[:-1]:
            node = node.setdefault(step, {}) if isinstance(step, str) else node[step]
        node[path[-1]] = value
        assert list(validator.iter_errors(bad)), path


def test_every_key_has_a_description_and_the_reader_allows_exactly_the_schema_s_keys(monkeypatch):
    """The reader's lists of allowed keys (Table.only, also under Reader.table and read_options),
    collected while it reads a table of every section in each of its forms, are the schema's."""
    for section in SECTIONS.values():
        for key in section.all_keys():
            assert key.doc, f"{section.path}.{key.name} has no description"
    allowed: dict[str, set] = {}
    only = Table.only

    def recording(self, keys, hint=""):
        keys = tuple(keys)
        allowed.setdefault(re.sub(r"\[\d+\]", "", self.path), set()).update(keys)
        return only(self, keys, hint)

    monkeypatch.setattr(Table, "only", recording)
    for text, overrides in VISITS:
        try:
            load_spec(text, overrides, check=False)
        except SpecError:  # the table was reached: its keys were checked before its values
            pass
    expected = {path: set(s.names) for path, s in SECTIONS.items() if not s.free}
    assert {path: allowed.get(path, set()) for path in expected} == expected


@pytest.mark.parametrize("key", ["contact.law", "design.bodies.bspline", "newton.max_iter", "bodies[0].mesh.arc_deg"])
def test_explain_says_what_a_key_means_its_type_default_and_allowed_values(key, capsys):
    assert main(["explain", key]) == 0
    out = capsys.readouterr().out
    assert out.startswith(re.sub(r"\[\d+\]", "", key) + ": ") and "type: " in out
    if key == "contact.law":
        assert 'default: "alm"' in out and "allowed: alm, penalty" in out
    if key == "newton.max_iter":
        assert "type: integer" in out and "default: 25" in out
    if key == "design.bodies.bspline":
        assert "control_points" in out
    if key.endswith("arc_deg"):
        assert "[degrees]" in out or "degrees" in out


def test_an_unknown_key_is_one_line_with_a_suggestion_and_status_2(capsys):
    assert main(["explain", "contact.lw"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("contopt: error: unknown key 'contact.lw'; did you mean 'contact.law'?")
    with pytest.raises(Exception, match="unknown key"):
        explain("newton.nope")


def test_schema_writes_the_file_an_editor_reads(tmp_path, capsys):
    out = tmp_path / "contopt.schema.json"
    assert main(["schema", "--out", str(out)]) == 0
    assert json.loads(out.read_text()) == json.loads(json.dumps(json_schema()))
    assert "#:schema ./contopt.schema.json" in capsys.readouterr().out


def test_schema_and_explain_load_no_jax():
    code = (
        "import sys; from contopt.cases.schema import json_schema, explain; json_schema(); explain('contact.law'); "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('jax', 'jaxlib')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["[]"]
