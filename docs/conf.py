"""Sphinx configuration: MyST pages, executed MyST notebooks (myst-nb), napoleon for the numpy
docstrings, furo. Built by ``bash scripts/docs.sh`` with warnings as errors."""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path[:0] = [str(ROOT), str(HERE / "_ext")]
# the notebooks' kernels import the same chiptwin as this build
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
os.environ.setdefault("MPLBACKEND", "Agg")

import chiptwin  # noqa: E402

project = "chiptwin"
author = "chiptwin developers"
copyright = "2026, chiptwin developers"
release = version = chiptwin.__version__

extensions = [
    "myst_nb",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "chiptwin_reference",
]
exclude_patterns = ["_build", "jupyter_execute", ".jupyter_cache", "**.ipynb_checkpoints"]
source_suffix = {".md": "myst-nb"}

myst_enable_extensions = ["colon_fence", "dollarmath", "deflist"]
myst_heading_anchors = 3

# Tutorials run at every build: a cell that raises fails the build.
nb_execution_mode = "force"
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_execution_timeout = 300
nb_merge_streams = True

napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # the numpy docstrings say the types; signatures stay readable
autodoc_default_options = {"members": True, "show-inheritance": False}

html_theme = "furo"
html_title = f"chiptwin {release}"
html_static_path: list[str] = []
