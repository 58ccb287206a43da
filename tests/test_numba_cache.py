"""Where numba caches compiled kernels: beside the sources in a checkout, in the user's cache
folder for an installed package, NUMBA_CACHE_DIR always first (issue 11; .ci/run checks the
installed case end to end in a fresh venv)."""

from __future__ import annotations

import os
import subprocess
import sys

from chiptwin import _numba


def test_a_checkout_caches_beside_its_sources(tmp_path):
    (tmp_path / "pyproject.toml").write_text("")
    (tmp_path / "chiptwin").mkdir()
    assert _numba.in_source_tree(tmp_path / "chiptwin")
    assert not _numba.in_source_tree(tmp_path / "site-packages" / "chiptwin")


def test_user_cache_dir_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert _numba.user_cache_dir() == tmp_path / "chiptwin" / "numba"


def test_numba_cache_dir_is_respected(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "mine")}
    out = subprocess.run([sys.executable, "-c", "import chiptwin._numba as n, numba; "
                          "print(n.CACHE_DIR); print(numba.config.CACHE_DIR)"],
                         capture_output=True, text=True, env=env, check=True).stdout.split()
    assert out == [str(tmp_path / "mine")] * 2
