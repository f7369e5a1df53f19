"""Sphinx configuration of the documentation site.

Build (from the repository root): ``python -m sphinx -W --keep-going -b html docs docs/_build/html``.
Every tutorial (a MyST-NB Markdown notebook) is executed during the build;
``LINKAGE_DOCS_QUICK=1`` gives them their short-horizon setting (what CI runs).
"""

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # document the checkout being built, installed or not
# ... and let the notebooks' kernels (child processes) import the same checkout
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))

import linkage  # noqa: E402

project = "linkage-manifolds"
author = "the linkage-manifolds authors"
copyright = "the linkage-manifolds authors (MIT License)"
version = release = linkage.__version__

extensions = [
    "myst_nb",  # Markdown pages and executed Markdown notebooks (jupytext's MyST format)
    "sphinx.ext.autodoc",  # the API reference from the docstrings
    "sphinx.ext.napoleon",  # ... which are numpy style
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
]
source_suffix = {".md": "myst-nb", ".rst": "restructuredtext"}
exclude_patterns = ["_build", "README.md", "**/.ipynb_checkpoints", "jupyter_execute"]

# -- MyST and notebooks --------------------------------------------------------------------------
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence"]
myst_heading_anchors = 3  # [text](page.md#a-section) links work as on GitHub
nb_execution_mode = "force"  # every build runs every notebook: outputs are always the code's
nb_execution_raise_on_error = True  # a failing cell fails the build
nb_execution_show_tb = True
nb_execution_timeout = 900  # per cell: a cold real128 or multiprecision compile takes tens of seconds
nb_merge_streams = True
nb_mime_priority_overrides = [("html", "image/gif", 15)]  # animations written by linkage.draw.animate

# -- API reference -------------------------------------------------------------------------------
autodoc_default_options = {"members": True, "member-order": "bysource", "show-inheritance": True}
autodoc_typehints = "signature"
autodoc_preserve_defaults = True
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False

# -- HTML ------------------------------------------------------------------------------------------
html_theme = "alabaster"
html_title = f"linkage-manifolds {release}"
html_static_path: list[str] = []
html_theme_options = {"description": "Multi-chart manifolds, heyoka geodesics, linkages", "fixed_sidebar": True,
                      "page_width": "1180px", "sidebar_width": "250px"}
