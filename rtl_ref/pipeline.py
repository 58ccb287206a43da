"""The chip model's DSP stage through the RTL: ``[chip.dsp] mode = "rtl"``.

:class:`RtlPipeline` is the ``"fixed"`` level of :class:`chiptwin.dsp.pipeline.Pipeline` with
its four fixed-point routines (CMS → dark reference → background subtraction → N-frame
averaging, formats from :func:`chiptwin.dsp.pipeline.chain_for`) replaced by the RTL of the
whole chain, ``ct_chain``, simulated by Verilator (or Icarus) on the ADC samples. The two
levels agree bit for bit (``tests/rtl/test_rtl_pipeline.py``).

The simulation keeps no state between DSP jobs: each ``block`` streams the K dark frames again,
then its N frames, and checks that the dark reference comes out as before (a few ms per job).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from chiptwin.dsp.chain import ChainConfig
from chiptwin.dsp.pipeline import BlockOut, ErrorStats, Frame, Pipeline
from chiptwin.dsp.registers import FixedResult
from rtl_ref import sim, tools
from rtl_ref.chain_block import ChainBlock, check_chain
from rtl_ref.cosim import Bank


@dataclass(frozen=True)
class ChainResult:
    """Results of the chain on a run of frames, as the fixed-point routines return them.

    ``dark``: the dark reference (1, P); ``average``: (n_runs, P) or None without block
    frames; ``overflow``: ``step -> register -> {"sat", "wrap"}`` over the whole run.
    """

    dark: FixedResult
    average: FixedResult | None
    overflow: dict


_BANKS: dict[tuple, Bank] = {}


def _bank(chain: ChainConfig, n_pixels: int) -> Bank:
    key = (chain, n_pixels)
    if key not in _BANKS:
        _BANKS[key] = Bank([ChainBlock(chain, n_pixels)])
    return _BANKS[key]


def run_chain_rtl(
    samples: np.ndarray,
    chain: ChainConfig,
    simulator: str = "verilator",
    p_valid: float = 1.0,
    p_ready: float = 1.0,
    seed: int = 1,
) -> ChainResult:
    """The chain in RTL on ADC samples ``(K + r·N, 2M, P)`` (first K frames dark).

    Raises :class:`rtl_ref.tools.SimulatorMissing` without the simulator, and
    :class:`RuntimeError` when the RTL disagrees with the model's shape of output (never the
    values: those are what the co-simulation tests compare).
    """
    samples = np.asarray(samples, dtype=np.int64)
    block = ChainBlock(chain, samples.shape[-1])
    b = _bank(chain, samples.shape[-1]).build(simulator)
    beats = block.beats({"samples": samples})
    n_runs = (samples.shape[0] - chain.dark.n) // chain.average.n
    p = samples.shape[-1]
    out = sim.run(b, 0, beats, p * (1 + n_runs), len(block.counter_names()), p_valid, p_ready,
                  seed)
    tags = out.flags & 1
    if len(tags) != p * (1 + n_runs) or tags[:p].any() or not tags[p:].all():
        raise RuntimeError(f"ct_chain produced {len(tags)} tagged outputs, expected "
                           f"{p} dark words then {p * n_runs} averages")
    overflow = block.overflow(dict(zip(block.counter_names(), out.counters, strict=True)))
    dark = FixedResult(out.d1[:p].reshape(1, p), chain.dark.out_fmt, overflow["dark"])
    avg = None
    if n_runs:
        avg = FixedResult(out.d0[p:].reshape(n_runs, p), chain.average.out_fmt,
                          overflow["average"])
    return ChainResult(dark, avg, overflow)


def run_chain_fixed(samples: np.ndarray, chain: ChainConfig) -> ChainResult:
    """The same chain through the fixed-point model routines."""
    samples = np.asarray(samples, dtype=np.int64)
    res = ChainBlock(chain, samples.shape[-1]).model({"samples": samples})
    overflow = {k: r.overflow for k, r in res.items()}
    return ChainResult(res["dark"], res.get("average"), overflow)


class RtlPipeline:
    """The chip model's DSP stage at level ``"rtl"``: :class:`chiptwin.dsp.pipeline.Pipeline`
    at level ``"fixed"``, with the four fixed-point routines replaced by ``ct_chain``.

    Same interface and fields as the fixed level: ``dark(frames)``, ``block(frames) ->
    BlockOut``, ``level``, ``chain``, ``dark_mean``, ``dark_var``, ``overflow``
    (``"step.register" -> {"sat", "wrap"}``), ``error`` (:class:`ErrorStats` against the float
    reference when ``report_error``), ``kept``. ``mean``, ``var``, the float reference and the
    kept codes come from a float :class:`Pipeline` inside, so every field but ``value`` and the
    overflow counts is the float pipeline's own.

    Parameters
    ----------
    chain : ChainConfig
        Register formats: ``chiptwin.dsp.pipeline.chain_for(scenario.chip)``.
    report_error, keep_codes : bool
        As for :class:`Pipeline`.
    simulator : str
        ``"verilator"`` (default) or ``"icarus"``.
    """

    level = "rtl"

    def __init__(self, chain: ChainConfig, report_error: bool = False, keep_codes: bool = False,
                 simulator: str = "verilator") -> None:
        if chain is None:
            raise ValueError("the rtl DSP level needs its register formats (chain)")
        check_chain(chain)
        tools.require(simulator)  # fail before the run starts, with the install hint
        self.chain = chain
        self.simulator = simulator
        self.overflow: dict[str, dict[str, int]] = {}
        self.error = ErrorStats(chain.average.out_fmt.lsb) if report_error else None
        self._float = Pipeline("float", keep_codes=keep_codes)
        self._dark_samples: np.ndarray | None = None
        self._dark_codes: np.ndarray | None = None
        self._dark_cms: dict = {}

    @property
    def dark_mean(self) -> np.ndarray | None:
        """Expected dark reference (LSB), as the float level."""
        return self._float.dark_mean

    @property
    def dark_var(self) -> np.ndarray | None:
        """Variance of the dark reference (LSB²), as the float level."""
        return self._float.dark_var

    @property
    def kept(self) -> list[np.ndarray] | None:
        """With ``keep_codes``: every frame's ADC samples as read."""
        return self._float.kept

    def dark(self, frames: list[Frame]) -> None:
        """Average K dark frames into the dark reference (in RTL)."""
        self._float.dark(frames)
        if frames[0].codes is None:
            return
        self._dark_samples = np.stack([f.codes for f in frames]).astype(np.int64)
        res = run_chain_rtl(self._dark_samples, self.chain, self.simulator)
        self._dark_codes = res.dark.codes[0]
        self._dark_cms = res.overflow["cms"]
        self._book("cms", res.overflow["cms"])
        self._book("dark", res.overflow["dark"])

    def block(self, frames: list[Frame]) -> BlockOut:
        """Subtract the dark reference from N frames and average them (in RTL)."""
        out = self._float.block(frames)
        if frames[0].codes is None:
            return out
        samples = np.concatenate([self._dark_samples, np.stack([f.codes for f in frames])])
        res = run_chain_rtl(samples, self.chain, self.simulator)
        if not np.array_equal(res.dark.codes[0], self._dark_codes):
            raise RuntimeError("ct_chain: the dark reference changed between DSP jobs")
        self._book("cms", _add(res.overflow["cms"], self._dark_cms, -1))  # this block's frames
        self._book("background", res.overflow["background"])
        self._book("average", res.overflow["average"])
        value = res.average.values()[0]
        if self.error is not None:
            self.error.add(value, out.value)
        return dataclasses.replace(out, value=value)

    def _book(self, step: str, regs: dict) -> None:
        for reg, counts in regs.items():
            book = self.overflow.setdefault(f"{step}.{reg}", {"sat": 0, "wrap": 0})
            for kind in ("sat", "wrap"):
                book[kind] += counts[kind]


def _add(a: dict, b: dict, sign: int = 1) -> dict:
    """``register -> {"sat", "wrap"}`` dicts added (or subtracted) register by register."""
    out = {reg: dict(c) for reg, c in a.items()}
    for reg, counts in b.items():
        slot = out.setdefault(reg, {"sat": 0, "wrap": 0})
        for kind in ("sat", "wrap"):
            slot[kind] += sign * counts[kind]
    return out
