"""Sphinx configuration: MyST pages, executed MyST notebooks (myst-nb), napoleon for the numpy
docstrings, furo. Built by ``bash scripts/docs.sh`` with warnings as errors."""

from __future__ import annotations

import logging
import os
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path[:0] = [str(ROOT), str(HERE / "_ext")]
# the notebooks' kernels import the same chiptwin as this build, and the figure runs of
# _ext/gallery_runs.py
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), str(HERE / "_ext"),
                                                        os.environ.get("PYTHONPATH")]))
# Figures reach the pages as the PNG files the twin writes (IPython.display.Image), never through
# plt.show(): the twin's plotting selects matplotlib's Agg backend, which shows nothing in a
# kernel. Agg here too, so this process never looks for a display.
os.environ.setdefault("MPLBACKEND", "Agg")
# No kernel chatter in the build's output (`-q` shows warnings and errors only): ipykernel's
# "running over TCP without encryption" and its debugger's frozen-modules note, nbclient's
# "Executing notebook" line. The kernels read their log level from a profile made here.
os.environ.setdefault("PYDEVD_DISABLE_FILE_VALIDATION", "1")
_ipython = Path(tempfile.mkdtemp(prefix="chiptwin-docs-ipython-"))
(_ipython / "profile_default").mkdir()
(_ipython / "profile_default" / "ipython_kernel_config.py").write_text(
    'c.IPKernelApp.log_level = "ERROR"\n')
os.environ["IPYTHONDIR"] = str(_ipython)
logging.getLogger("traitlets").setLevel(logging.WARNING)

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
# "--set" stays two hyphens: a command copied from a page must run
smartquotes = False

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
html_static_path = ["_static"]
html_css_files = ["chiptwin.css"]
