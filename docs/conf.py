"""Sphinx configuration of the documentation site: ``make docs`` builds it into ``build/docs/html``.

The source folder is the repository's root (``sphinx-build -c docs . build/docs/html``), narrowed by
``include_patterns`` to ``docs/``, the notebooks, ``benchmarks/REPORT.md`` and ``README.md``: a page's relative link
(``../notebooks/04_knn.ipynb``, ``../benchmarks/REPORT.md``, ``../README.md``) names the same file on GitHub and
in the site. ``docs/index.md`` is the root; its links, in their order, are the site's navigation
(``_ext/site_toctree.py``). The notebooks, stored without outputs, are executed during the build (myst-nb, cached
under ``build/docs/jupyter_cache``); a cell that raises fails the build.
"""
from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE / "_ext"))

from mocapviz import __version__

project = "mocapviz"
author = "the mocapviz authors"
copyright = "the mocapviz authors, MIT licence"
release = version = __version__

root_doc = "docs/index"
include_patterns = ["docs/**", "notebooks/*.ipynb", "benchmarks/REPORT.md", "README.md"]
exclude_patterns = ["docs/_templates/**", "docs/_ext/**", "**/.ipynb_checkpoints", ".venv", "build", ".cache", ".git"]
templates_path = ["_templates"]  # relative to this folder

extensions = [
    "myst_nb",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinxarg.ext",
    "site_toctree",
    "references",
]

# MyST: GitHub's heading anchors (page.md#a-heading), so that a link works on GitHub and here alike
myst_heading_anchors = 4
myst_enable_extensions = ["dollarmath", "colon_fence"]

# myst-nb: execute the notebooks (stored without outputs) once per change, in their own folder, as nbmake does
nb_execution_mode = "cache"
nb_execution_cache_path = str(ROOT / "build" / "docs" / "jupyter_cache")
nb_execution_timeout = 600  # seconds per cell
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_merge_streams = True
# HoloViews and Panel outputs carry, beside their text/html, JavaScript bundles for a live kernel
# (application/vnd.holoviews_load.v0+json, ..._exec...) that myst-nb has no renderer for: the page shows the HTML
suppress_warnings = ["mystnb.unknown_mime_type"]

# API reference from the numpydoc docstrings: the pages docs/api*.rst say what is documented
autodoc_typehints = "none"  # the numpydoc sections give the types, shapes and units
autodoc_member_order = "bysource"
autosummary_generate = False
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

# every internal cross-reference must resolve (-W makes a miss an error); no intersphinx: the machine is offline,
# so a reference into Python, NumPy or pandas is left as text, not checked
nitpicky = True
nitpick_ignore_regex = []

html_theme = "pydata_sphinx_theme"
html_title = f"mocapviz {release}"
html_theme_options = {"navigation_depth": 2, "show_toc_level": 2, "secondary_sidebar_items": ["page-toc"]}
html_sidebars = {"**": []}  # every page is a top-level entry of the navigation bar: no section to list beside it
html_additional_pages = {"index": "redirect.html"}  # the site's root sends to docs/index.html
html_show_sourcelink = False
