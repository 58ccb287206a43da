"""Block adapter of the whole chain (``ct_chain``): CMS → dark reference → background → average."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from chiptwin.dsp.chain import ChainConfig
from chiptwin.dsp.fixed import overflow_code
from chiptwin.dsp.frame_ops import average_frames_fixed, cms_fixed, subtract_background_fixed
from chiptwin.dsp.registers import FixedResult
from rtl_ref.block import (
    ZERO,
    Block,
    Expected,
    Inputs,
    beat_index_text,
    divide_shift,
    mode_params,
    pair,
    port,
    recip_params,
)
from rtl_ref.design import Instance, literal

COUNTERS = (
    "cnt_cms_reset_sat", "cnt_cms_reset_wrap", "cnt_cms_signal_sat", "cnt_cms_signal_wrap",
    "cnt_cms_out_sat", "cnt_cms_out_wrap", "cnt_dark_acc_sat", "cnt_dark_acc_wrap",
    "cnt_dark_out_sat", "cnt_dark_out_wrap", "cnt_bg_out_sat", "cnt_bg_out_wrap",
    "cnt_avg_acc_sat", "cnt_avg_acc_wrap", "cnt_avg_out_sat", "cnt_avg_out_wrap",
)


def _fmt(prefix: str, fmt) -> list[tuple[str, str]]:
    return [(f"{prefix}_W", literal(fmt.word_bits)), (f"{prefix}_F", literal(fmt.frac_bits)),
            (f"{prefix}_S", literal(int(fmt.signed)))]


def _acc(prefix: str, cfg) -> list[tuple[str, str]]:
    return [(f"{prefix}_ACC_W", literal(cfg.acc_fmt.word_bits)),
            (f"{prefix}_ACC_S", literal(int(cfg.acc_fmt.signed))),
            (f"{prefix}_AOMODE", literal(overflow_code(cfg.acc_overflow)))]


def check_chain(chain: ChainConfig) -> None:
    """Refuse a chain whose steps do not hand each other the same formats."""
    links = {
        "dark.in_fmt = cms.out_fmt": chain.dark.in_fmt == chain.cms.out_fmt,
        "background.in_fmt = cms.out_fmt": chain.background.in_fmt == chain.cms.out_fmt,
        "background.dark_fmt = dark.out_fmt": chain.background.dark_fmt == chain.dark.out_fmt,
        "average.in_fmt = background.out_fmt": chain.average.in_fmt == chain.background.out_fmt,
    }
    broken = [k for k, ok in links.items() if not ok]
    if broken:
        raise ValueError(f"ct_chain needs consistent formats: {', '.join(broken)} do not hold")


class ChainBlock(Block):
    """``ct_chain`` for a :class:`ChainConfig`. Inputs: ``samples`` (F, 2M, P), the first K
    frames dark (K = ``chain.dark.n``), then runs of N = ``chain.average.n`` frames.

    Output beats: the P dark-reference words (``out_tag`` 0, in ``out_d1``), then one average
    per pixel per run (``out_tag`` 1, in ``out_d0``).
    """

    routine = "chain"

    def __init__(self, chain: ChainConfig, n_pixels: int) -> None:
        check_chain(chain)
        self.chain = chain
        self.n_pixels = int(n_pixels)

    def instance(self) -> Instance:
        ch = self.chain
        cms, dark, bg, avg = ch.cms, ch.dark, ch.background, ch.average
        params = [("NPIX", literal(self.n_pixels))] + _fmt("CMS_IN", cms.in_fmt)
        params += [("M", literal(cms.m))] + _acc("CMS", cms)
        params += recip_params(cms.m, cms.recip_word_bits, "CMS_") + _fmt("CMS_OUT", cms.out_fmt)
        params += mode_params(cms.rounding, cms.overflow, "CMS_")
        params += [("K", literal(dark.n))] + _acc("DARK", dark)
        params += recip_params(dark.n, dark.recip_word_bits, "DARK_")
        params += _fmt("DARK_OUT", dark.out_fmt)
        params += mode_params(dark.rounding, dark.overflow, "DARK_")
        params += _fmt("BG_OUT", bg.out_fmt) + mode_params(bg.rounding, bg.overflow, "BG_")
        params += [("N", literal(avg.n))] + _acc("AVG", avg)
        params += recip_params(avg.n, avg.recip_word_bits, "AVG_") + _fmt("AVG_OUT", avg.out_fmt)
        params += mode_params(avg.rounding, avg.overflow, "AVG_")
        return Instance(
            module="ct_chain",
            params=tuple(params),
            inputs=(port("in_x", cms.in_fmt),),
            outputs=(port("out_avg", avg.out_fmt), port("out_dark", dark.out_fmt)),
            flags=("out_tag",),
            counters=COUNTERS,
        )

    def _split(self, inputs: Inputs) -> tuple[np.ndarray, int, int]:
        s = np.asarray(inputs["samples"], dtype=np.int64)
        k, n, m = self.chain.dark.n, self.chain.average.n, self.chain.cms.m
        if s.ndim != 3 or s.shape[1:] != (2 * m, self.n_pixels):
            raise ValueError(f"chain: samples {s.shape} must be (frames, {2 * m}, {self.n_pixels})")
        if s.shape[0] < k or (s.shape[0] - k) % n:
            raise ValueError(f"chain: {s.shape[0]} frames must be K = {k} dark frames plus runs "
                             f"of N = {n}")
        return s, k, m

    def beats(self, inputs: Inputs) -> np.ndarray:
        s, _, _ = self._split(inputs)
        return np.stack([s.ravel(), np.zeros(s.size, np.int64)], axis=1)

    def n_outputs(self, inputs: Inputs) -> int:
        s, k, _ = self._split(inputs)
        return self.n_pixels * (1 + (s.shape[0] - k) // self.chain.average.n)

    def model(self, inputs: Inputs) -> dict[str, FixedResult]:
        """The four steps through the fixed-point model (:mod:`chiptwin.dsp.frame_ops`)."""
        s, k, m = self._split(inputs)
        ch = self.chain
        out = {"cms": cms_fixed(s[:, :m], s[:, m:], ch.cms)}
        out["dark"] = average_frames_fixed(out["cms"].codes[:k], ch.dark)
        if s.shape[0] > k:
            out["background"] = subtract_background_fixed(
                out["cms"].codes[k:], out["dark"].codes[0], ch.background)
            out["average"] = average_frames_fixed(out["background"].codes, ch.average)
        return out

    def expected(self, inputs: Inputs) -> Expected:
        res = self.model(inputs)
        p = self.n_pixels
        dark = res["dark"].codes[0]
        avg = res["average"].codes.ravel() if "average" in res else np.zeros(0, np.int64)
        d0 = np.concatenate([np.zeros(p, np.int64), avg])
        d1 = np.concatenate([dark, np.zeros(avg.size, np.int64)])
        tag = np.concatenate([np.zeros(p, np.int64), np.ones(avg.size, np.int64)])
        overflow = {name: res[name].overflow if name in res else self._zero(name)
                    for name in ("cms", "dark", "background", "average")}
        return Expected(d0, d1, tag == 1, tag == 0, tag, overflow, res)

    def _zero(self, step: str) -> dict:
        regs = {"background": ("diff", "output"), "average": ("acc", "output")}[step]
        return {r: dict(ZERO) for r in regs}

    def overflow(self, counters: Mapping[str, int]) -> dict:
        c = counters
        return {
            "cms": {"sum_reset": pair(c, *COUNTERS[0:2]), "sum_signal": pair(c, *COUNTERS[2:4]),
                    "diff": dict(ZERO), "output": pair(c, *COUNTERS[4:6])},
            "dark": {"acc": pair(c, *COUNTERS[6:8]), "output": pair(c, *COUNTERS[8:10])},
            "background": {"diff": dict(ZERO), "output": pair(c, *COUNTERS[10:12])},
            "average": {"acc": pair(c, *COUNTERS[12:14]), "output": pair(c, *COUNTERS[14:16])},
        }

    def sources(self, inputs: Inputs, k: int) -> str:
        p, m = self.n_pixels, self.chain.cms.m
        kd, n = self.chain.dark.n, self.chain.average.n
        beats = self.beats(inputs)
        if k < p:
            frames = range(kd)
            what = f"dark reference, pixel {k}, from dark frames 0…{kd - 1}"
        else:
            run, k = divmod(k - p, p)
            frames = range(kd + run * n, kd + run * n + n)
            what = f"average of run {run} (frames {frames[0]}…{frames[-1]}), pixel {k}"
        idx = [(f * 2 * m + r) * p + k for f in frames for r in range(2 * m)][:16]
        return what + ", first samples: " + beat_index_text(beats, idx, ("x", ""))

    def pre_round(self, inputs: Inputs) -> tuple[np.ndarray, int] | None:
        res = self.model(inputs)
        if "background" not in res:
            return None
        avg = self.chain.average
        acc = res["background"].codes.reshape(-1, avg.n, self.n_pixels).sum(axis=1).ravel()
        mult, sh = divide_shift(avg.in_fmt.frac_bits, avg.n, avg.recip_word_bits, avg.out_fmt)
        return acc * mult, sh

    def label(self) -> str:
        return f"chain M={self.chain.cms.m} K={self.chain.dark.n} N={self.chain.average.n}"

