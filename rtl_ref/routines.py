"""Drop-in RTL twins of the model's routines: same arguments, same :class:`FixedResult`.

``subtract_background_rtl(frames, dark, cfg)`` returns what ``subtract_background_fixed(frames,
dark, cfg)`` returns — codes, format and per-register overflow counts — computed by simulating
the block's RTL (Verilator by default). One build per config (cached, see :mod:`rtl_ref.build`).
"""

from __future__ import annotations

import numpy as np

from chiptwin.dsp.filters import FirConfig, KineticsConfig
from chiptwin.dsp.frame_ops import AverageConfig, BackgroundConfig, CmsConfig
from chiptwin.dsp.registers import FixedResult
from rtl_ref import sim
from rtl_ref.block import Block, Inputs
from rtl_ref.cosim import Bank
from rtl_ref.filter_blocks import FirBlock, KineticsBlock
from rtl_ref.frame_blocks import AverageBlock, BackgroundBlock, CmsBlock

_BANKS: dict[object, Bank] = {}


def _run(block: Block, inputs: Inputs, simulator: str, p_valid: float, p_ready: float
         ) -> FixedResult:
    key = (block.instance(), simulator)
    bank = _BANKS.setdefault(key, Bank([block]))
    names = block.counter_names()
    out = sim.run(bank.build(simulator), 0, block.beats(inputs), block.n_outputs(inputs),
                  len(names), p_valid, p_ready)
    return block.result(out.d0, dict(zip(names, out.counters, strict=True)), inputs)


def _shaped(res: FixedResult, shape: tuple[int, ...]) -> FixedResult:
    return FixedResult(res.codes.reshape(shape), res.fmt, res.overflow)


def subtract_background_rtl(frames: np.ndarray, dark: np.ndarray, cfg: BackgroundConfig,
                            simulator: str = "verilator", p_valid: float = 1.0,
                            p_ready: float = 1.0) -> FixedResult:
    """:func:`chiptwin.dsp.frame_ops.subtract_background_fixed` on ``ct_background``."""
    frames = np.asarray(frames)
    flat = frames.reshape(-1, frames.shape[-1])
    res = _run(BackgroundBlock(cfg), {"frames": flat, "dark": dark}, simulator, p_valid, p_ready)
    return _shaped(res, frames.shape)


def average_frames_rtl(frames: np.ndarray, cfg: AverageConfig, simulator: str = "verilator",
                       p_valid: float = 1.0, p_ready: float = 1.0) -> FixedResult:
    """:func:`chiptwin.dsp.frame_ops.average_frames_fixed` on ``ct_average``."""
    frames = np.asarray(frames)
    flat = frames.reshape(frames.shape[0], -1)
    res = _run(AverageBlock(cfg, flat.shape[1]), {"frames": flat}, simulator, p_valid, p_ready)
    return _shaped(res, (frames.shape[0] // cfg.n,) + frames.shape[1:])


def cms_rtl(reset: np.ndarray, signal: np.ndarray, cfg: CmsConfig, simulator: str = "verilator",
            p_valid: float = 1.0, p_ready: float = 1.0) -> FixedResult:
    """:func:`chiptwin.dsp.frame_ops.cms_fixed` on ``ct_cms``."""
    reset, signal = np.asarray(reset), np.asarray(signal)
    flat = {"reset": reset.reshape(-1, *reset.shape[-2:]),
            "signal": signal.reshape(-1, *signal.shape[-2:])}
    res = _run(CmsBlock(cfg, reset.shape[-1]), flat, simulator, p_valid, p_ready)
    return _shaped(res, reset.shape[:-2] + reset.shape[-1:])


def fir_rtl(frames: np.ndarray, cfg: FirConfig, simulator: str = "verilator",
            p_valid: float = 1.0, p_ready: float = 1.0) -> FixedResult:
    """:func:`chiptwin.dsp.filters.fir_fixed` on ``ct_fir`` (filtered along axis 0)."""
    frames = np.asarray(frames)
    flat = frames.reshape(frames.shape[0], -1)
    res = _run(FirBlock(cfg, flat.shape[1]), {"frames": flat}, simulator, p_valid, p_ready)
    return _shaped(res, frames.shape)


def kinetics_weighted_rtl(frames: np.ndarray, cfg: KineticsConfig, simulator: str = "verilator",
                          p_valid: float = 1.0, p_ready: float = 1.0) -> FixedResult:
    """:func:`chiptwin.dsp.filters.kinetics_weighted_fixed` on ``ct_kinetics``."""
    frames = np.asarray(frames)
    flat = frames.reshape(-1, *frames.shape[-2:])
    res = _run(KineticsBlock(cfg, frames.shape[-1]), {"frames": flat}, simulator, p_valid,
               p_ready)
    return _shaped(res, frames.shape[:-2] + frames.shape[-1:])
