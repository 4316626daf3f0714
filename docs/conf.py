"""Sphinx configuration of the documentation site: the guides (Markdown, read by MyST), the gallery of
the bundled cases (written from the case files when the page is read, _ext/contopt_gallery.py) and the
API reference (api/, from the docstrings). ``make docs`` builds it into build/docs; tests/test_docs_site.py
builds it with warnings as errors."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))

project = "contopt"
author = "the contopt authors"
extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon", "contopt_docstrings", "contopt_gallery"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_ext"]

# --- the Markdown guides -------------------------------------------------------------------------------
# links to a heading of a page (`optimization.md#the-design-as-a-surface`), as GitHub makes them
myst_heading_anchors = 3

# --- the gallery: a bundled case's picture, when docs/figures has one -----------------------------------
gallery_pictures = {
    "die-slab": ("figures/die-slab-design.png", "the coarse B-spline run (make demo): iso-surfaces nu = 0.1 and 0.9"),
    "die-cantilever": ("figures/paper_tables/table3-bspline-coarse/design.png", "the coarse B-spline run"),
    "die-slab-contact-force": ("figures/paper_tables/contact-force-coarse/design.png", "the coarse B-spline run"),
    "sabot": ("figures/paper_tables/sabot/design.png", "the coarse run (IPOPT)"),
    "friction-clamp": ("figures/friction/clamp-mu0.5-design.png", "mu = 0.5, the file's"),
}

# --- the API reference ---------------------------------------------------------------------------------
autodoc_typehints = "description"
autodoc_member_order = "bysource"
autodoc_default_options = {"undoc-members": False, "show-inheritance": False}
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
# a class's "Attributes" as a field list: autodoc documents the dataclass fields themselves
napoleon_use_ivar = True
# the docstrings use ``name`` for code and name the shapes of arrays; nothing is cross-checked
nitpicky = False
# the same short names (n, n_cells, name, ...) are attributes of several classes: not a defect of the docs
suppress_warnings = ["ref.python"]

html_theme = "alabaster"
html_title = "contopt"
html_sidebars = {"**": ["about.html", "navigation.html", "relations.html", "searchbox.html"]}
# wide enough for a problem file's lines (120 characters) without a scroll bar
html_theme_options = {"description": "topology optimization of hyperelastic bodies in contact", "page_width": "1280px"}
