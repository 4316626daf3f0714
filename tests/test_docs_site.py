"""The API reference builds from the docstrings (Sphinx autodoc), and documents every public name."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

import contopt

ROOT = Path(__file__).resolve().parents[1]


def test_api_reference_builds_and_covers_the_public_api(tmp_path):
    pytest.importorskip("sphinx", reason="sphinx is in the dev extra that make test installs")
    out = subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-q", str(ROOT / "docs" / "api"), str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    # a module or name that does not import is the one failure that leaves a page silently empty
    assert not re.search(r"autodoc: failed|failed to import|No module named", out.stderr), out.stderr[-3000:]
    pages = "".join(p.read_text(encoding="utf-8") for p in tmp_path.glob("*.html"))
    documented = set(re.findall(r'id="contopt\.[\w.]*?\.(\w+)"', pages))
    public = {getattr(contopt, n).__name__ for n in contopt.__all__ if n != "__version__"}  # as defined
    missing = sorted(public - documented)
    assert not missing, f"public names without an entry in the API reference: {missing}"
