"""The documentation site (docs/, Sphinx with MyST) builds with no warning, its API reference documents
every public name, and its gallery has every bundled case with its problem file."""

import html
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

import contopt
from contopt.cases.optimization import bundled_cases

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The built site (``make docs`` runs the same command): its folder, and what Sphinx printed."""
    pytest.importorskip("sphinx", reason="sphinx is in the dev extra that make test installs")
    pytest.importorskip("myst_parser", reason="myst-parser is in the dev extra that make test installs")
    out_dir = tmp_path_factory.mktemp("site")
    command = [
        sys.executable,
        "-m",
        "sphinx",
        "-b",
        "html",
        "-q",
        "-W",
        "--keep-going",
        str(ROOT / "docs"),
        str(out_dir),
    ]
    out = subprocess.run(command, capture_output=True, text=True, timeout=600)
    return out_dir, out


def test_the_site_builds_without_a_warning(site):
    out_dir, out = site
    assert out.returncode == 0 and out.stderr.strip() == "", out.stderr[-5000:]
    pages = {p.relative_to(out_dir).as_posix() for p in out_dir.rglob("*.html")}
    guides = {f"{p.stem}.html" for p in (ROOT / "docs").glob("*.md")}  # every Markdown page is in the site
    assert guides <= pages, sorted(guides - pages)
    assert {"index.html", "gallery.html", "getting-started.html", "api/index.html"} <= pages


def test_the_api_reference_covers_the_public_api(site):
    out_dir, out = site
    # a module or name that does not import is the one failure that leaves a page silently empty
    assert not re.search(r"autodoc: failed|failed to import|No module named", out.stderr), out.stderr[-3000:]
    pages = "".join(p.read_text(encoding="utf-8") for p in (out_dir / "api").glob("*.html"))
    documented = set(re.findall(r'id="contopt\.[\w.]*?\.(\w+)"', pages))
    public = {getattr(contopt, n).__name__ for n in contopt.__all__ if n != "__version__"}  # as defined
    missing = sorted(public - documented)
    assert not missing, f"public names without an entry in the API reference: {missing}"


def test_the_gallery_shows_every_bundled_case_with_its_file(site):
    out_dir, _ = site
    page = (out_dir / "gallery.html").read_text(encoding="utf-8")
    sections = re.findall(r'<section id="([\w-]+)">', page)
    assert sections[1:] == sorted(bundled_cases()), sections  # the page's own section, then the cases
    for name, path in bundled_cases().items():
        section = page.split(f'<section id="{name}">')[1].split("</section>")[0]
        text = html.unescape(re.sub(r"<[^>]+>", "", section))
        assert f"contopt run {name} --out results/{name}" in text
        missing = [line for line in path.read_text(encoding="utf-8").splitlines() if line.strip() not in text]
        assert missing == [], f"{name}: the problem file is not on the page whole: {missing[:3]}"
    assert len(re.findall(r'<img alt="[\w-]+" src="_images/', page)) == 5  # the cases with a picture


def test_the_house_docstring_style_reads_as_fields():
    """``name : what it is`` entries become fields under a heading, a definition list without one, and
    the text after a section stays text (numpy style would read it as more parameters)."""
    pytest.importorskip("sphinx", reason="sphinx is in the dev extra that make test installs")
    spec = importlib.util.spec_from_file_location(
        "contopt_docstrings", ROOT / "docs" / "_ext" / "contopt_docstrings.py"
    )
    docstrings = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(docstrings)
    lines = ["Solve.", "", "Parameters", "----------", "x : (n,) the field", "    at the nodes", "y, z : scales", ""]
    lines += ["Raises ConfigError when x is empty.", "", "rtol : the tolerance", "atol : the floor", "    (absolute)"]
    assert docstrings.house_style(lines) == [
        "Solve.",
        "",
        "",
        ":param x: (n,) the field at the nodes",
        ":param y, z: scales",
        "",
        "",
        "Raises ConfigError when x is empty.",
        "",
        "",
        "``rtol``",
        "   the tolerance",
        "",
        "",
        "``atol``",
        "   the floor",
        "   (absolute)",
        "",
    ]
