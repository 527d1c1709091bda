"""Sphinx configuration of the panomap manual: the Markdown pages of docs/ (MyST) and the API reference
(autodoc, numpydoc). Build it with ``python -m sphinx -W --keep-going -b html docs docs/_build/html``."""

from __future__ import annotations

import panomap

project = "panomap"
author = "the panomap developers"
copyright = "the panomap developers"
version = release = panomap.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
]

source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build"]
# Headings down to level 3 get anchors, so that links such as reliability.md#live-streams resolve.
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]

# The API reference: every name of panomap.__all__ (docs/api.md), documented from its docstring.
autosummary_generate = False
autodoc_member_order = "bysource"
autodoc_typehints = "none"
autodoc_preserve_defaults = True
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

html_theme = "pydata_sphinx_theme"
html_title = f"panomap {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
}
html_static_path: list[str] = []
# Every page's sidebar lists the whole manual (docs/_templates/sidebar-nav-all.html): the theme's own lists
# the pages under the current top-level page, and the manual's pages have none, so it was empty.
templates_path = ["_templates"]
html_sidebars = {"**": ["sidebar-nav-all"]}

# Every documented object has a docstring, and every parameter of a public function is documented.
numpydoc_validation_checks = {"GL08"}
