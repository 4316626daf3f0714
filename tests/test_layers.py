"""The package's layers import downward only (docs/architecture.md, Layers): a lower layer never imports a higher one,
not even inside a function."""

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "contopt"

#: rank of each top-level module or package; a module may import its own rank or lower
LAYERS = {
    "errors": 0,
    "config": 0,
    "export_cache": 0,
    "extras": 0,
    "parallel": 0,
    "io": 0,
    "timing": 0,
    "vectors": 0,
    "mesh": 1,
    "fem": 2,
    "material": 2,
    "assembly": 3,
    "contact": 3,
    "solve": 4,
    "adjoint": 5,
    "design": 5,
    "responses": 5,
    "optimize": 6,
    "cases": 7,
    "cli": 8,
    "__init__": 8,
    "__main__": 8,
}


def _imports(path: Path):
    """(line, imported top-level contopt name) of every import in a module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[0] == "contopt" and len(parts) > 1:
                yield node.lineno, parts[1]


def test_every_module_has_a_layer():
    tops = {
        p.stem if p.is_file() else p.name
        for p in SRC.iterdir()
        if (p.suffix == ".py") or (p.is_dir() and (p / "__init__.py").exists())
    }
    assert tops <= set(LAYERS), sorted(tops - set(LAYERS))


def test_layers_import_downward_only():
    wrong = []
    for path in sorted(SRC.rglob("*.py")):
        top = path.relative_to(SRC).parts[0].removesuffix(".py")
        for line, imported in _imports(path):
            if imported in LAYERS and LAYERS[imported] > LAYERS[top]:
                wrong.append(f"{path.relative_to(SRC)}:{line} ({top}) imports contopt.{imported}")
    assert not wrong, "\n".join(wrong)
