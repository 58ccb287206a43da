"""The output folder: where a run, a study, a ladder or a characterisation may write.

A run replaces its output folder whole (:func:`replacing`), so the folder is checked before the
run starts (:func:`check_out_dir`): new, empty, or a previous chiptwin output. A refused folder is
bad input (:class:`~chiptwin.config.ScenarioError` naming ``--out``), like a bad scenario file.

One writer per output folder (:func:`output_lock`): a command holds ``<out>.lock`` beside the
folder (beside it, since a run replaces the folder whole) for its whole life: an ``flock`` on a
file holding the writer's pid. A second command on the same folder is refused naming that pid; a
lock left by a process that is gone (the kernel drops an ``flock`` with its holder) is taken over
with a message naming the old pid.

Outputs get the modes the user's umask gives (:func:`new_file_mode`), also those made first as
private temporary files or folders (``tempfile``'s 0600 and 0700) and renamed into place.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterator
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
        tmp.chmod(new_file_mode(folder=True))  # mkdtemp's 0700, not the user's choice
        yield tmp
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def umask() -> int:
    """The process's file-mode creation mask: from ``/proc/self/status`` where Linux gives it,
    else set and restored at once (``os.umask`` has no read-only form)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def new_file_mode(folder: bool = False) -> int:
    """The mode ``open`` or ``mkdir`` would give a new file (0o666) or folder (0o777) under the
    user's umask: for what ``tempfile`` creates private (0o600, 0o700) before it becomes an
    output."""
    return (0o777 if folder else 0o666) & ~umask()


def lock_path(out: Path) -> Path:
    """The lock file of an output folder: ``<out>.lock``, beside it."""
    return out.with_name(out.name + ".lock")


def _note(message: str) -> None:
    print(f"chiptwin: note: {message}", file=sys.stderr)


@contextmanager
def output_lock(out: Path, note: Callable[[str], None] = _note) -> Iterator[Path]:
    """Hold the output folder ``out`` for one writer while the block runs.

    Raises
    ------
    ScenarioError
        Naming ``--out`` and the pid of the command that holds the folder.
    """
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock (the folder rules still hold)
        yield lock_path(out)
        return
    path = lock_path(out)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)  # the umask decides
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = _read_pid(fd)
            os.close(fd)
            _refuse(str(out), f"is being written by another chiptwin command (pid {holder}, "
                              f"lock {path}); wait for it to finish, stop it, or choose "
                              "another --out")
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:  # not a file its last holder unlinked while we waited
            break
        os.close(fd)
    old = _read_pid(fd)
    if old and old != os.getpid():
        note(f"took over the lock of {out} left by pid {old}, which is no longer running")
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    try:
        yield path
    finally:
        path.unlink(missing_ok=True)
        os.close(fd)  # releases the flock


def _read_pid(fd: int) -> int | None:
    try:
        return int(os.pread(fd, 32, 0).decode().strip() or 0) or None
    except (OSError, ValueError):
        return None


__all__ = ["OUTPUT_MARK", "check_out_dir", "lock_path", "new_file_mode", "output_lock",
           "replacing", "umask"]
