"""Builds of a simulation top: a Verilator C++ testbench executable, an Icarus ``.vvp`` file.

Every build lands in ``rtl_ref/build/`` (git-ignored; ``CHIPTWIN_RTL_BUILD`` moves it) under a
directory named by the hash of everything that goes into it: the RTL sources, the generated
top, the testbench, the defines, the flags and the tool versions. An identical build is never
redone; a build is made in a temporary directory and renamed into place, so concurrent test
sessions in one checkout never see a half-written one.

Verilator: ``verilator --cc`` generates C++; this module compiles it itself, as two unity
translation units (hot code at ``OPT_FAST``, construction code at ``-O0``), plus the testbench,
and links them with a Verilator runtime library compiled once per Verilator version. Compiles go
through ``ccache`` when installed, with relative paths so that its hits survive the temporary
directory names.
"""

from __future__ import annotations

import functools
import hashlib
import os
import re
import shutil
import subprocess
import tempfile
import threading
import time
from collections.abc import Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from rtl_ref import tools
from rtl_ref.design import Instance, top_verilog

HERE = Path(__file__).resolve().parent
RTL_DIR = HERE / "rtl"
TB_DIR = HERE / "tb"
OPT_FAST = "-O1"
"""Optimisation of the model's hot code: at -O1 the builds stay short and 1e6 beats still
simulate in a fraction of a second (benchmarks/bench_rtl.py)."""

CXX_FLAGS = (
    "-std=gnu++17", "-faligned-new", "-fcf-protection=none", "-Wno-bool-operation",
    "-Wno-sign-compare", "-Wno-uninitialized", "-Wno-unused-but-set-variable",
    "-Wno-unused-parameter", "-Wno-unused-variable", "-Wno-shadow",
)
_JOBS = threading.BoundedSemaphore(max(1, os.cpu_count() or 1))
_RUNTIME_LOCK = threading.Lock()


class BuildError(RuntimeError):
    """A tool failed; the message carries its command and output."""


@dataclass(frozen=True)
class Build:
    """A finished build: the file to run, the simulator, and how long it took (0 when cached)."""

    simulator: str
    path: Path
    key: str
    seconds: float
    cached: bool


def rtl_sources() -> list[Path]:
    """The DSP RTL, every ``rtl_ref/rtl/*.v``."""
    return sorted(RTL_DIR.glob("*.v"))


def build_root() -> Path:
    """Where builds live: ``$CHIPTWIN_RTL_BUILD``, else ``rtl_ref/build`` when writable (a
    source checkout), else ``~/.cache/chiptwin/rtl`` (an installed package)."""
    if "CHIPTWIN_RTL_BUILD" in os.environ:
        root = Path(os.environ["CHIPTWIN_RTL_BUILD"])
    else:
        root = HERE / "build"
        try:
            root.mkdir(parents=True, exist_ok=True)
        except OSError:
            root = Path.home() / ".cache" / "chiptwin" / "rtl"
        if not os.access(root, os.W_OK):
            root = Path.home() / ".cache" / "chiptwin" / "rtl"
    root.mkdir(parents=True, exist_ok=True)
    return root


def _run(cmd: Sequence[str], cwd: Path | None = None, jobs: bool = True) -> str:
    if jobs:
        _JOBS.acquire()
    try:
        proc = subprocess.run(list(cmd), cwd=cwd, capture_output=True, text=True, check=False)
    finally:
        if jobs:
            _JOBS.release()
    if proc.returncode != 0:
        raise BuildError(f"$ {' '.join(cmd)}\n{proc.stdout}{proc.stderr}")
    return proc.stdout + proc.stderr


def _digest(parts: Iterable[str | bytes]) -> str:
    h = hashlib.sha256()
    for part in parts:
        h.update(part.encode() if isinstance(part, str) else part)
        h.update(b"\0")
    return h.hexdigest()[:16]


def _publish(tmp: Path, final: Path) -> None:
    """Move a finished build into place; if another process got there first, keep theirs."""
    try:
        os.rename(tmp, final)
    except OSError:
        shutil.rmtree(tmp, ignore_errors=True)
        if not final.exists():
            raise


def _cxx(*args: str) -> list[str]:
    cc = tools.cxx()
    if cc is None:
        raise BuildError(f"no C++ compiler: {tools.INSTALL_HINT}")
    launcher = [tools.ccache()] if tools.ccache() else []
    return launcher + [cc.path, *args]


@functools.cache
def verilator_root() -> Path:
    """``$VERILATOR_ROOT`` as Verilator reports it."""
    tool = tools.require("verilator")
    out = _run([tool.path, "--getenv", "VERILATOR_ROOT"], jobs=False).strip().splitlines()
    return Path(out[-1])


def _inc() -> list[str]:
    root = verilator_root()
    return [f"-I{root / 'include'}", f"-I{root / 'include' / 'vltstd'}"]


def _defines(trace: bool) -> list[str]:
    t = "1" if trace else "0"
    return ["-DVM_COVERAGE=0", "-DVM_SC=0", f"-DVM_TRACE={t}", "-DVM_TRACE_FST=0",
            f"-DVM_TRACE_VCD={t}"]


def runtime_library(trace: bool) -> Path:
    """The Verilator runtime (``verilated.cpp`` …) as a static library, built once per version."""
    tool = tools.require("verilator")
    cc = tools.cxx()
    srcs = ["verilated.cpp", "verilated_threads.cpp"] + (["verilated_vcd_c.cpp"] if trace else [])
    flags = [*CXX_FLAGS, "-Os", *_defines(trace), *_inc()]
    key = _digest([tool.version, cc.version if cc else "", *flags, *srcs])
    final = build_root() / f"runtime-verilator-{tool.version}-{key}"
    lib = final / "libverilated.a"
    with _RUNTIME_LOCK:
        if lib.exists():
            return lib
        tmp = Path(tempfile.mkdtemp(prefix="tmp-runtime-", dir=build_root()))
        inc = verilator_root() / "include"
        with ThreadPoolExecutor(len(srcs)) as pool:
            list(pool.map(
                lambda s: _run(_cxx(*flags, "-c", str(inc / s), "-o", s.replace(".cpp", ".o")),
                               cwd=tmp),
                srcs,
            ))
        _run(["ar", "rcs", "libverilated.a", *[s.replace(".cpp", ".o") for s in srcs]], cwd=tmp)
        _publish(tmp, final)
    return lib


def _design_key(simulator: str, top: str, defines: Sequence[str], extra: Sequence[str]) -> str:
    parts: list[str | bytes] = [simulator, top, *defines, *extra]
    for path in rtl_sources() + sorted(TB_DIR.iterdir()):
        parts += [path.name, path.read_bytes()]
    return _digest(parts)


_BLANK = " \\\t"


def _classes(obj: Path) -> tuple[list[str], list[str]]:
    """(fast, slow) generated .cpp files, from ``Vct_top_classes.mk``."""
    text = (obj / "Vct_top_classes.mk").read_text()
    lists: dict[str, list[str]] = {}
    for name, body in re.findall(r"^(VM_\w+) \+= \\\n((?:\t.*\\\n)*)", text, flags=re.M):
        words = [w.strip(_BLANK) for w in body.splitlines()]
        lists[name] = [w + ".cpp" for w in words if w]
    fast = lists.get("VM_CLASSES_FAST", []) + lists.get("VM_SUPPORT_FAST", [])
    slow = lists.get("VM_CLASSES_SLOW", []) + lists.get("VM_SUPPORT_SLOW", [])
    return fast, slow


def _compile_verilator(d: Path, top: str, defines: Sequence[str], trace: bool) -> None:
    tool = tools.require("verilator")
    (d / "ct_top.v").write_text(top)
    cmd = [tool.path, "--cc", "--prefix", "Vct_top", "--top-module", "ct_top", "--Mdir", "obj",
           "-Wno-fatal", "-Wno-lint", "-Wno-style", *(["--trace"] if trace else []),
           *[f"-D{x}" for x in defines], "ct_top.v", *[str(p) for p in rtl_sources()]]
    _run(cmd, cwd=d)
    obj = d / "obj"
    shutil.copy(TB_DIR / "tb_verilator.cpp", obj / "tb_verilator.cpp")
    fast, slow = _classes(obj)
    if trace:
        fast += [p.name for p in obj.glob("Vct_top__Trace*.cpp") if p.name not in fast + slow]
    (obj / "unity_fast.cpp").write_text("".join(f'#include "{f}"\n' for f in fast))
    (obj / "unity_slow.cpp").write_text("".join(f'#include "{f}"\n' for f in slow))
    base = [*CXX_FLAGS, *_defines(trace), "-I.", *_inc()]
    units = [("unity_fast.cpp", OPT_FAST), ("unity_slow.cpp", "-O0"), ("tb_verilator.cpp", "-O2")]
    with ThreadPoolExecutor(len(units)) as pool:
        list(pool.map(
            lambda u: _run(_cxx(*base, u[1], "-c", u[0], "-o", u[0].replace(".cpp", ".o")),
                           cwd=obj),
            units,
        ))
    objs = [u[0].replace(".cpp", ".o") for u in units]
    _run(_cxx(*objs, str(runtime_library(trace)), "-pthread", "-lpthread", "-latomic",
              "-o", "../tb"), cwd=obj)
    shutil.rmtree(obj)  # keep the executable and the top, not 10s of MB of objects


def build_verilator(
    instances: Sequence[Instance], defines: Sequence[str] = (), trace: bool = False
) -> Build:
    """The Verilator testbench executable of ``instances`` (cached)."""
    tool = tools.require("verilator")
    cc = tools.cxx()
    top = top_verilog(instances)
    key = _design_key("verilator", top, defines,
                      [tool.version, cc.version if cc else "", OPT_FAST, str(trace)])
    final = build_root() / f"verilator-{key}"
    if (final / "tb").exists():
        return Build("verilator", final / "tb", key, 0.0, True)
    t0 = time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix="tmp-verilator-", dir=build_root()))
    try:
        _compile_verilator(tmp, top, defines, trace)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    _publish(tmp, final)
    return Build("verilator", final / "tb", key, time.perf_counter() - t0, False)


def build_icarus(instances: Sequence[Instance], defines: Sequence[str] = ()) -> Build:
    """The Icarus Verilog simulation (``sim.vvp``) of ``instances`` (cached)."""
    tool = tools.require("icarus")
    top = top_verilog(instances)
    key = _design_key("icarus", top, defines, [tool.version])
    final = build_root() / f"icarus-{key}"
    if (final / "sim.vvp").exists():
        return Build("icarus", final / "sim.vvp", key, 0.0, True)
    t0 = time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix="tmp-icarus-", dir=build_root()))
    try:
        (tmp / "ct_top.v").write_text(top)
        # sources named relative to the build (sim.vvp records them for its messages): a build
        # names no folder of the machine it was made on, and its sibling `final` reads the same
        sources = [os.path.relpath(p, tmp) for p in (TB_DIR / "tb_icarus.v", *rtl_sources())]
        _run([tool.path, "-g2005", "-Wall", "-Wno-timescale", "-o", "sim.vvp", "-s", "tb_icarus",
              *[f"-D{x}" for x in defines], sources[0], "ct_top.v", *sources[1:]], cwd=tmp)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    _publish(tmp, final)
    return Build("icarus", final / "sim.vvp", key, time.perf_counter() - t0, False)


def build(
    simulator: str, instances: Sequence[Instance], defines: Sequence[str] = (), trace: bool = False
) -> Build:
    """:func:`build_verilator` or :func:`build_icarus` (Icarus always can dump a VCD)."""
    if simulator == "verilator":
        return build_verilator(instances, defines, trace)
    if simulator == "icarus":
        return build_icarus(instances, defines)
    raise ValueError(f"simulator = {simulator!r}: allowed verilator, icarus")


def lint(instances: Sequence[Instance] | None = None, top_module: str | None = None) -> str:
    """``verilator --lint-only -Wall`` of the RTL (and of a generated top); returns its output.

    Raises :class:`BuildError` on any warning.
    """
    tool = tools.require("verilator")
    with tempfile.TemporaryDirectory() as d:
        files = [str(p) for p in rtl_sources()]
        cmd = [tool.path, "--lint-only", "-Wall"]
        if instances is not None:
            (Path(d) / "ct_top.v").write_text(top_verilog(instances))
            cmd += ["--top-module", "ct_top", str(Path(d) / "ct_top.v")]
        elif top_module is not None:
            cmd += ["--top-module", top_module]
        return _run(cmd + files, cwd=Path(d), jobs=False)
