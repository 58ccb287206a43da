"""Where numba caches compiled kernels: beside the sources in a checkout, in the user's cache
folder for an installed package, NUMBA_CACHE_DIR always first (.ci/run checks the
installed case end to end in a fresh venv); and the command line saying so when kernels
compile, once, and never when they load from the cache."""

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


KERNEL = '''
from numba import njit

@njit(cache=True)
def twice(x):
    return 2 * x
'''


def _import_fresh(path, name):
    """The module at ``path`` under a new name: a new dispatcher of the same cached kernel."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_compiles_are_announced_once_and_cache_loads_not_at_all(tmp_path, monkeypatch):
    monkeypatch.setattr(_numba.numba.config, "CACHE_DIR", str(tmp_path / "cache"))
    path = tmp_path / "kernel_for_announce.py"
    path.write_text(KERNEL)
    said = []
    with _numba.announce_compiles(lambda: said.append(1)):
        assert _import_fresh(path, "kernel_a").twice(3) == 6  # compiled, cached
        assert _import_fresh(path, "kernel_b").twice(2.5) == 5.0  # another signature: compiled
    assert said == [1]  # once, however many compile
    said.clear()
    with _numba.announce_compiles(lambda: said.append(1)):
        module = _import_fresh(path, "kernel_c")
        assert module.twice(4) == 8  # loaded from the cache: nothing compiles
        assert module.twice.stats.cache_hits and not module.twice.stats.cache_misses
    assert said == []
    _import_fresh(path, "kernel_e").twice(1j)  # compiles outside any block: no listener left
    assert said == []


def test_the_command_line_says_when_kernels_compile_in_its_work(monkeypatch, capsys, tmp_path):
    """Around a command's work (here a run), not around its checks: a refused input keeps its
    one line even when kernels compiled before the refusal."""
    from numba import njit

    import chiptwin.fidelity
    from chiptwin import cli

    def run(scenario, progress=None):  # the work: compiles a kernel, then stops (exit 130)
        njit(lambda x: x - 1)(1)
        raise KeyboardInterrupt

    monkeypatch.setattr(chiptwin.fidelity, "run", run)
    out = ["--out", str(tmp_path / "out")]
    assert cli.main(["run", "pyro_1fmol", *out]) == 130
    assert capsys.readouterr().err.count("compiling numba kernels") == 1
    assert cli.main(["run", "pyro_1fmol", "--quiet", *out]) == 130
    assert "compiling" not in capsys.readouterr().err

    def refused(*args):  # a check that compiles, then refuses the input
        njit(lambda x: x + 7)(1)
        raise cli.ScenarioError("mine.toml", "chip.rows", 0, "must be ≥ 1")

    monkeypatch.setattr(cli, "load_scenario", refused)
    assert cli.main(["run", "pyro_1fmol", *out]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
