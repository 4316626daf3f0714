"""House rules that a review would otherwise have to remember (CONTRIBUTING.md)."""

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "contopt"
TESTS = ROOT / "tests"
MAX_LINES = 600
MAX_FUNCTION_LINES = 100


def test_no_module_is_over_600_lines():
    long = {
        str(p.relative_to(SRC)): n
        for p in SRC.rglob("*.py")
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES
    }
    assert long == {}, f"split these modules (at most {MAX_LINES} lines): {long}"


def test_no_module_imports_a_private_name_of_another():
    found = []
    for path in SRC.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("contopt"):
                own = path.relative_to(SRC.parent).with_suffix("").as_posix().replace("/", ".")
                if node.module == own.removesuffix(".__init__"):
                    continue
                found += [
                    f"{path.relative_to(SRC)}: {node.module}.{a.name}"
                    for a in node.names
                    if a.name.startswith("_") and not a.name.startswith("__")
                ]
    assert found == [], f"make these public or keep them inside their module: {found}"


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def test_no_test_uses_a_private_name_of_the_package():
    """Tests go through what the package offers (tests/ helper modules, ``_tutorial.py`` say, are
    the tests' own): no ``from contopt.x import _name``, no ``contopt.x._name``."""
    import ast

    found = []
    for path in TESTS.rglob("*.py"):
        where = path.relative_to(TESTS)
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "contopt":
                found += [f"{where}:{node.lineno}: {node.module}.{a.name}" for a in node.names if _private(a.name)]
                if any(_private(part) for part in node.module.split(".")):
                    found.append(f"{where}:{node.lineno}: {node.module}")
            elif isinstance(node, ast.Import):
                found += [
                    f"{where}:{node.lineno}: {a.name}"
                    for a in node.names
                    if a.name.split(".")[0] == "contopt" and any(_private(part) for part in a.name.split("."))
                ]
            elif isinstance(node, ast.Attribute) and _private(node.attr):
                chain, value = [node.attr], node.value
                while isinstance(value, ast.Attribute):
                    chain.append(value.attr)
                    value = value.value
                if isinstance(value, ast.Name) and value.id == "contopt":
                    found.append(f"{where}:{node.lineno}: contopt.{'.'.join(reversed(chain))}")
    assert found == [], f"test these through public names (or make them public): {sorted(found)}"


def test_a_problem_file_reads_into_its_model_without_jax():
    """A description needs no JAX: a problem file read into its Model (bodies, materials, supports,
    contact laws, friction) loads none; the kernels come with the analysis (issue 36)."""
    code = f"""
import sys
import contopt as co
from contopt.cases.die_slab import die_slab
from contopt.cases.spec import load_model

tutorial = load_model({str(ROOT / "examples" / "tutorial.toml")!r})
clamp = load_model('case = "friction-clamp"')
assert isinstance(tutorial, co.Model) and tutorial.interfaces and die_slab().interfaces
assert clamp.interfaces[0].friction is not None
print(sorted(m for m in sys.modules if m.split(".")[0] in ("jax", "jaxlib")))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.split() == ["[]"], f"reading a Model loaded JAX: {out.stdout[:500]}"


def test_no_function_is_over_100_lines():
    long = {}
    for path in SRC.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = (node.end_lineno or node.lineno) - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long[f"{path.relative_to(SRC)}:{node.lineno} {node.name}"] = n
    assert long == {}, f"split these functions (at most {MAX_FUNCTION_LINES} lines, docstring included): {long}"
