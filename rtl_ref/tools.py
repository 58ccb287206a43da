"""The simulators and compilers the co-simulation needs: where they are, their versions, how to
install them.

Pinned to what Debian 12 (bookworm) ships and what CI installs with ``scripts/test.sh``:
Verilator 5.006 and Icarus Verilog 11.0 (tested); older major versions are refused. ``ccache``
is optional: it makes a rebuilt Verilator model cost a fraction of a cold build.
"""

from __future__ import annotations

import functools
import os
import re
import shutil
import subprocess
from dataclasses import dataclass

VERILATOR_TESTED = "5.006"
ICARUS_TESTED = "11.0"
VERILATOR_MIN = (5, 0)
ICARUS_MIN = (11, 0)

INSTALL_HINT = (
    "install the simulators with `sudo apt-get install -y verilator iverilog ccache` "
    f"(Debian 12 ships Verilator {VERILATOR_TESTED} and Icarus Verilog {ICARUS_TESTED}, the tested "
    "versions), or run the project's test command `bash scripts/test.sh`, which installs them"
)


class SimulatorMissing(RuntimeError):
    """A simulator the co-simulation needs is not installed (the message says how to install it)."""


@dataclass(frozen=True)
class Tool:
    """An installed program: ``name``, absolute ``path``, ``version`` string and tuple."""

    name: str
    path: str
    version: str

    @property
    def version_tuple(self) -> tuple[int, ...]:
        """``"5.006"`` → ``(5, 6)``."""
        return tuple(int(p) for p in re.findall(r"\d+", self.version)[:2])


def _version(cmd: list[str], pattern: str) -> str | None:
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=30, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    match = re.search(pattern, out.stdout + out.stderr)
    return match.group(1) if match else None


@functools.cache
def verilator() -> Tool | None:
    """Verilator (``verilator`` on ``PATH``), or None."""
    path = shutil.which("verilator")
    if path is None:
        return None
    version = _version([path, "--version"], r"Verilator (\d+\.\d+)")
    return Tool("verilator", path, version) if version else None


@functools.cache
def icarus() -> Tool | None:
    """Icarus Verilog (``iverilog`` and ``vvp`` on ``PATH``), or None."""
    path = shutil.which("iverilog")
    if path is None or shutil.which("vvp") is None:
        return None
    version = _version([path, "-V"], r"Icarus Verilog version (\d+\.\d+)")
    return Tool("iverilog", path, version) if version else None


@functools.cache
def ccache() -> str | None:
    """``ccache`` when installed and not disabled with ``CHIPTWIN_RTL_CCACHE=0``."""
    if os.environ.get("CHIPTWIN_RTL_CCACHE", "1") == "0":
        return None
    return shutil.which("ccache")


@functools.cache
def cxx() -> Tool | None:
    """The C++ compiler (``$CXX`` or ``g++``)."""
    name = os.environ.get("CXX", "g++")
    path = shutil.which(name)
    if path is None:
        return None
    version = _version([path, "--version"], r"(\d+\.\d+(?:\.\d+)?)")
    return Tool(name, path, version or "unknown")


def require(simulator: str) -> Tool:
    """The tool behind ``"verilator"`` or ``"icarus"``; raises :class:`SimulatorMissing`.

    Verilator also needs a C++ compiler.
    """
    found = {"verilator": verilator, "icarus": icarus}[simulator]()
    if found is None:
        raise SimulatorMissing(f"{simulator} is not installed: {INSTALL_HINT}")
    minimum = VERILATOR_MIN if simulator == "verilator" else ICARUS_MIN
    if found.version_tuple < minimum:
        raise SimulatorMissing(
            f"{simulator} {found.version} is older than {'.'.join(map(str, minimum))}: "
            f"{INSTALL_HINT}"
        )
    if simulator == "verilator" and cxx() is None:
        raise SimulatorMissing(f"no C++ compiler (g++) for Verilator: {INSTALL_HINT}")
    return found


def missing() -> list[str]:
    """Names of the simulators that :func:`require` would refuse (empty when all are usable)."""
    out = []
    for name in ("verilator", "icarus"):
        try:
            require(name)
        except SimulatorMissing:
            out.append(name)
    return out
