"""The output folder: where a run, a study, a ladder or a characterisation may write.

A run replaces its output folder whole (:func:`replacing`), so the folder is checked before the
run starts (:func:`check_out_dir`): new, empty, or a previous chiptwin output. A refused folder is
bad input (:class:`~chiptwin.config.ScenarioError` naming ``--out``), like a bad scenario file.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from chiptwin.config.fields import ScenarioError

OUTPUT_MARK = "summary.json"
"""A folder holding this file is a previous chiptwin output, which a new run may replace."""


def check_out_dir(out_dir: str | Path, marker: str = OUTPUT_MARK) -> Path:
    """Where a run may write, checked before it starts; returns the resolved folder.

    A run replaces its output folder whole, so the folder must be new, empty, or a previous
    chiptwin output (it holds ``marker``: ``summary.json`` for a run, ``results.sqlite`` for a
    study); never the working folder or one of its parents.

    Raises
    ------
    ScenarioError
        Naming ``--out``, the folder, and what is allowed.
    """
    out = Path(out_dir).resolve()
    cwd = Path.cwd().resolve()
    if out == cwd or out in cwd.parents:
        _refuse(out_dir, "must not be the working folder or one of its parents")
    if out.exists():
        if not out.is_dir():
            _refuse(out_dir, "is a file; must be a folder (new, empty, or a previous output)")
        if any(out.iterdir()) and not (out / marker).is_file():
            _refuse(out_dir, f"holds files but no {marker}: it is not a previous chiptwin "
                             "output, and chiptwin writes over its outputs")
    try:  # the folder that will hold it (never the output folder itself, written last)
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _refuse(out_dir, f"cannot be created ({exc.strerror})")
    if not os.access(out.parent, os.W_OK | os.X_OK):
        _refuse(out_dir, f"cannot be created: {out.parent} is not writable")
    return out


def _refuse(out_dir: str | Path, allowed: str) -> None:
    raise ScenarioError("chiptwin", "--out", str(out_dir), allowed)


@contextmanager
def replacing(out: Path) -> Iterator[Path]:
    """A fresh temporary folder beside ``out`` to write outputs into: when the block ends it
    replaces ``out`` whole; on any error it is removed, so a crashed or refused run never leaves
    a half-written folder that looks complete."""
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        yield tmp
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


__all__ = ["OUTPUT_MARK", "check_out_dir", "replacing"]
