"""One writer per output folder: ``<out>.lock`` held for a command's life."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from chiptwin.cli import main
from chiptwin.config import ScenarioError
from chiptwin.config.outputs import lock_path, output_lock


def test_a_second_writer_is_refused_naming_the_pid(tmp_path):
    out = tmp_path / "out"
    with output_lock(out) as lock:
        assert lock == tmp_path / "out.lock"
        assert lock.read_text().strip() == str(os.getpid())
        with pytest.raises(ScenarioError, match=rf"pid {os.getpid()}\b.*--out"), \
                output_lock(out):
            pass
    assert not lock_path(out).exists()  # removed with the command
    with output_lock(out):  # and free again
        pass


def test_a_stale_lock_is_taken_over_with_a_message(tmp_path):
    out = tmp_path / "out"
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    lock_path(out).write_text(gone + "\n")  # left by a process that no longer runs
    notes = []
    with output_lock(out, note=notes.append) as lock:
        assert lock.read_text().strip() == str(os.getpid())
    assert len(notes) == 1 and f"pid {gone}" in notes[0] and "no longer running" in notes[0]


@pytest.mark.parametrize("command", [
    ["run", "{small}"], ["ladder", "{small}"], ["characterize", "{small}"],
    ["study", "{study}", "--workers", "1"]])
def test_every_command_that_writes_a_folder_takes_the_lock(tmp_path, small_toml, command,
                                                           capsys):
    from tests.study.conftest import write_study

    study = write_study(tmp_path)
    out = tmp_path / "held"
    argv = [c.format(small=small_toml, study=study) for c in command]
    with output_lock(out):
        assert main([*argv, "--out", str(out), "--quiet"] if command[0] != "ladder"
                    else [*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"pid {os.getpid()}" in err[0] and "--out" in err[0]
    assert not out.exists() or not any(Path(out).iterdir())
