"""Sphinx configuration of the API reference (built by tests/test_docs.py; ``make docs`` writes it to
build/api). The pages are generated from the docstrings of the public API."""

project = "contopt"
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon"]
autodoc_typehints = "description"
autodoc_member_order = "bysource"
autodoc_default_options = {"undoc-members": False, "show-inheritance": False}
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
html_theme = "alabaster"
exclude_patterns = ["_build"]
# the docstrings use ``name`` for code and name the shapes of arrays; nothing is cross-checked
nitpicky = False
# the same short names (n, n_cells, name, ...) are attributes of several classes: not a defect of the docs
suppress_warnings = ["ref.python"]
