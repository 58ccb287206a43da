"""The loops that draw are compiled without numba's reference counting (chiptwin._numba.NJIT_NORC).

With it, every inlined draw whose rare path is a call (the ziggurat's edges) leaves an atomic
increment and decrement of the source array's count in the loop, which numba does not prune:
half the sensor chain's time (``benchmarks/bench_sensor_chain.py`` prints both). The draws are
the same bits either way (tests/pixel/test_random.py, test_pixel_chain.py)."""

from __future__ import annotations

import re

import numba
import numpy as np

from chiptwin._numba import NJIT_OPTIONS
from chiptwin.pixel import _kernels, _random


def _normals(source, out):
    for i in range(out.size):
        out[i] = _random.standard_normal(source)


def _loop_ir(nrt: bool) -> str:
    """The LLVM of :func:`_normals`, compiled fresh (cached code cannot be inspected)."""
    kernel = numba.njit(**{**NJIT_OPTIONS, "cache": False, "_nrt": nrt})(_normals)
    source = _random.state_of(np.random.Generator(np.random.SFC64(1)))
    kernel(source, np.empty(4))
    (ir,) = kernel.inspect_llvm().values()
    return ir


def _calls(ir: str, name: str) -> int:
    return len(re.findall(rf"call void @{name}\(", ir))


def test_reference_counting_puts_an_atomic_pair_around_each_draw_and_norc_removes_it():
    """Counted: an incref and a decref inside the loop besides the arguments' own; NORC: none."""
    counted, norc = _loop_ir(True), _loop_ir(False)
    assert _calls(counted, "NRT_incref") >= 3  # the two arguments, and the draw's
    assert _calls(norc, "NRT_incref") == 0 and _calls(norc, "NRT_decref") == 0


def test_the_drawing_loops_are_compiled_without_reference_counting():
    for kernel in (_kernels._chain_pixels, _kernels._frame_loop, _kernels.convert_rows_into,
                   _random.fill):
        assert kernel.targetoptions.get("_nrt") is False, kernel.py_func.__name__
    for kernel in (_kernels.chain_chunk, _kernels.frame_codes):  # they allocate the buffers
        assert kernel.targetoptions.get("_nrt", True) is not False
