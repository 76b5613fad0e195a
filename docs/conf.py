"""Sphinx configuration of the skfem-granular documentation.

Build (warnings are errors, as in CI)::

    pip install -e ".[docs]"
    sphinx-build -W -b html docs docs/_build/html

The notebooks (``docs/notebooks`` is a link to ``notebooks/``) are executed
during the build in smoke mode (``SMOKE=1``: small meshes, few steps, about
1.5 min together), so the pages show their outputs; set
``SKFEM_DOCS_EXECUTE=0`` to render them without running them.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the checkout's package, also without an install

import skfem_granular  # noqa: E402

project = "skfem-granular"
author = "the skfem-granular developers"
copyright = "the skfem-granular developers"
release = version = skfem_granular.__version__

extensions = [
    "myst_nb",  # Markdown pages (MyST) and the notebooks
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
]

exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "**/.ipynb_checkpoints",
                    "notebooks/out", "jupyter_execute"]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}

html_theme = "furo"
html_title = f"skfem-granular {release}"
html_static_path: list[str] = []

# ---------------------------------------------------------------- API reference
autodoc_default_options = {"members": True, "show-inheritance": False,
                           "member-order": "bysource"}
autodoc_typehints = "none"  # the numpydoc sections say the types
autoclass_content = "class"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# ---------------------------------------------------------------- Markdown and notebooks
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
nb_execution_mode = "off" if os.environ.get("SKFEM_DOCS_EXECUTE", "1") == "0" else "force"
nb_execution_timeout = 900
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_merge_streams = True
os.environ.setdefault("SMOKE", "1")
os.environ.setdefault("NOTEBOOK_OUT", tempfile.mkdtemp(prefix="skfem-granular-docs-"))
os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")

suppress_warnings = ["mystnb.unknown_mime_type"]


# ---------------------------------------------------------------- optional pages
#: Pages listed in the index when their file is there (``OPTIONAL_PAGES`` in index.md).
OPTIONAL_PAGES = ("meshing", "sedimentation", "collapse")
HERE = Path(__file__).resolve().parent


def _optional_pages(app, docname, source):
    if docname == "index":
        present = [p for p in OPTIONAL_PAGES if (HERE / f"{p}.md").exists()]
        source[0] = source[0].replace("OPTIONAL_PAGES", "\n".join(present))


def setup(app):
    app.connect("source-read", _optional_pages)
