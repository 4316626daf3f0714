"""House rules that a review would otherwise have to remember (CONTRIBUTING.md)."""

from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "contopt"
MAX_LINES = 600


def test_no_module_is_over_600_lines():
    long = {
        str(p.relative_to(SRC)): n
        for p in SRC.rglob("*.py")
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES
    }
    assert long == {}, f"split these modules (at most {MAX_LINES} lines): {long}"


def test_no_module_imports_a_private_name_of_another():
    import ast

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
