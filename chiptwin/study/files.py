"""Writing a study's files: each through a temporary name and a rename, so a reader never sees
half a file (shared by :mod:`chiptwin.study.outputs` and :mod:`chiptwin.study.calibrate_outputs`).
"""

from __future__ import annotations

import os
from pathlib import Path


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)
