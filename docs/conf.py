"""Sphinx configuration of the flexmor documentation site (``make docs``; output in docs/_build/html).

The pages are the Markdown files of docs/ (MyST), the README sections they include, the API reference
generated from the docstrings of ``flexmor.__all__`` (autosummary, autodoc, numpydoc) and the gallery of
docs/gallery, whose scripts run the examples of examples/ at a small size while the site is built.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))
sys.path.insert(0, str(ROOT / "examples"))
os.environ.setdefault("MPLBACKEND", "Agg")

import flexmor  # noqa: E402

project = "flexmor"
copyright = "the flexmor authors (BSD-3-Clause)"
version = release = flexmor.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "flexmor_docs",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "gallery/README.txt", "gallery/*.py", "**.ipynb_checkpoints"]
templates_path = ["_templates"]

# MyST: the Markdown pages, $...$ / $$...$$ math, heading anchors for links such as README.md#concepts
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
# the README and the pages it includes nest their sections under the page's own title
suppress_warnings = ["myst.header"]

# API reference: a page per public name, numpydoc sections, members in source order
autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"members": True, "member-order": "bysource"}
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_xref_param_type = False
# a public name without a docstring fails the build (with -W); see also flexmor_docs.check_public_names
numpydoc_validation_checks = {"GL08"}
numpydoc_validation_exclude = {r"\.__init__$", r"\.__post_init__$"}

# gallery: docs/gallery/plot_*.py run the examples at a small size while the site is built
sphinx_gallery_conf = {
    "examples_dirs": "gallery",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "matplotlib_animations": False,
    "plot_gallery": "True",
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
}

html_theme = "pydata_sphinx_theme"
html_title = f"flexmor {release}"
html_static_path = ["_static"]
html_css_files = ["flexmor.css"]
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": [],
}
# pages without sub-pages need no section navigation: their text gets the width
html_sidebars = {
    "**": ["sidebar-nav-bs"],
    **{page: [] for page in ("index", "guide/getting-started", "tutorial", "theory", "benchmark", "architecture",
                             "contributing")},
}
html_show_sourcelink = False
