"""Block adapters of the frame operations: background subtraction, N-frame average, CMS."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from chiptwin.dsp.fixed import accumulate_into, overflow_code
from chiptwin.dsp.frame_ops import (
    AverageConfig,
    BackgroundConfig,
    CmsConfig,
    accumulate_frames_fixed,
    average_frames_fixed,
    cms_fixed,
    subtract_background_fixed,
)
from chiptwin.dsp.registers import FixedResult
from rtl_ref.block import (
    ZERO,
    Block,
    Expected,
    Inputs,
    beat_index_text,
    divide_shift,
    fmt_params,
    mode_params,
    pair,
    port,
    recip_params,
)
from rtl_ref.design import Instance, Port, literal

OUT_COUNTERS = ("cnt_out_sat", "cnt_out_wrap")
ACC_COUNTERS = ("cnt_acc_sat", "cnt_acc_wrap")


def _ones(n: int) -> np.ndarray:
    return np.ones(n, dtype=bool)


def _check_pixels(frames: np.ndarray, n_pixels: int, what: str) -> None:
    if frames.shape[-1] != n_pixels:
        raise ValueError(f"{what}: {frames.shape[-1]} pixels per frame; the RTL has {n_pixels}")


class BackgroundBlock(Block):
    """``ct_background`` for a :class:`BackgroundConfig`.

    Inputs: ``frames`` (F, P), ``dark`` (P,); stateless, so any P.
    """

    routine = "background"

    def __init__(self, cfg: BackgroundConfig) -> None:
        self.cfg = cfg

    def instance(self) -> Instance:
        c = self.cfg
        params = fmt_params("IN", c.in_fmt) + fmt_params("DK", c.dark_fmt)
        params += fmt_params("OUT", c.out_fmt) + mode_params(c.rounding, c.overflow)
        return Instance(
            module="ct_background",
            params=tuple(params),
            inputs=(port("in_x", c.in_fmt), port("in_dark", c.dark_fmt)),
            outputs=(port("out_y", c.out_fmt),),
            flags=("out_sat", "out_wrap"),
            counters=OUT_COUNTERS,
        )

    def beats(self, inputs: Inputs) -> np.ndarray:
        frames = np.asarray(inputs["frames"], dtype=np.int64)
        dark = np.broadcast_to(np.asarray(inputs["dark"], dtype=np.int64), frames.shape)
        return np.stack([frames.ravel(), dark.ravel()], axis=1)

    def n_outputs(self, inputs: Inputs) -> int:
        return int(np.size(inputs["frames"]))

    def expected(self, inputs: Inputs) -> Expected:
        res = subtract_background_fixed(inputs["frames"], inputs["dark"], self.cfg)
        d0 = res.codes.ravel()
        n = d0.size
        return Expected(d0, np.zeros(n, np.int64), _ones(n), ~_ones(n), None, res.overflow,
                        {"output": res})

    def overflow(self, counters: Mapping[str, int]) -> dict:
        return {"diff": dict(ZERO), "output": pair(counters, *OUT_COUNTERS)}

    def result(self, d0: np.ndarray, counters: Mapping[str, int], inputs: Inputs) -> FixedResult:
        """RTL outputs as the model's :class:`FixedResult`."""
        shape = np.shape(inputs["frames"])
        return FixedResult(d0.reshape(shape), self.cfg.out_fmt, self.overflow(counters))

    def sources(self, inputs: Inputs, k: int) -> str:
        p = np.shape(inputs["frames"])[-1]
        return f"frame {k // p}, pixel {k % p}: " + beat_index_text(
            self.beats(inputs), [k], ("x", "dark")
        )

    def pre_round(self, inputs: Inputs) -> tuple[np.ndarray, int]:
        diff_fmt = self.cfg.registers()["diff"]
        f = diff_fmt.frac_bits
        x = np.asarray(inputs["frames"], np.int64) << (f - self.cfg.in_fmt.frac_bits)
        d = np.asarray(inputs["dark"], np.int64) << (f - self.cfg.dark_fmt.frac_bits)
        return (x - d).ravel(), f - self.cfg.out_fmt.frac_bits


class AverageBlock(Block):
    """``ct_average`` for an :class:`AverageConfig`. Inputs: ``frames`` (F, P), F a multiple of n.

    ``out_d0`` is the mean (:func:`average_frames_fixed`), ``out_d1`` the sum
    (:func:`accumulate_frames_fixed`); both are compared.
    """

    routine = "average"

    def __init__(self, cfg: AverageConfig, n_pixels: int) -> None:
        self.cfg = cfg
        self.n_pixels = int(n_pixels)

    def instance(self) -> Instance:
        c = self.cfg
        params = fmt_params("IN", c.in_fmt) + [
            ("ACC_W", literal(c.acc_fmt.word_bits)),
            ("ACC_S", literal(int(c.acc_fmt.signed))),
            ("AOMODE", literal(overflow_code(c.acc_overflow))),
            ("N", literal(c.n)),
            ("NPIX", literal(self.n_pixels)),
        ]
        params += recip_params(c.n, c.recip_word_bits)
        params += fmt_params("OUT", c.out_fmt) + mode_params(c.rounding, c.overflow)
        return Instance(
            module="ct_average",
            params=tuple(params),
            inputs=(port("in_x", c.in_fmt),),
            outputs=(port("out_y", c.out_fmt), port("out_acc", c.acc_fmt)),
            flags=("out_sat", "out_wrap"),
            counters=ACC_COUNTERS + OUT_COUNTERS,
        )

    def beats(self, inputs: Inputs) -> np.ndarray:
        frames = np.asarray(inputs["frames"], dtype=np.int64)
        _check_pixels(frames, self.n_pixels, "average")
        return np.stack([frames.ravel(), np.zeros(frames.size, np.int64)], axis=1)

    def n_outputs(self, inputs: Inputs) -> int:
        return int(np.size(inputs["frames"])) // self.cfg.n

    def expected(self, inputs: Inputs) -> Expected:
        avg = average_frames_fixed(inputs["frames"], self.cfg)
        acc = accumulate_frames_fixed(inputs["frames"], self.cfg)
        n = avg.codes.size
        return Expected(avg.codes.ravel(), acc.codes.ravel(), _ones(n), _ones(n), None,
                        avg.overflow, {"output": avg, "acc": acc})

    def overflow(self, counters: Mapping[str, int]) -> dict:
        return {"acc": pair(counters, *ACC_COUNTERS), "output": pair(counters, *OUT_COUNTERS)}

    def result(self, d0: np.ndarray, counters: Mapping[str, int], inputs: Inputs) -> FixedResult:
        """RTL outputs as the result of :func:`average_frames_fixed`."""
        return FixedResult(
            d0.reshape(-1, self.n_pixels), self.cfg.out_fmt, self.overflow(counters)
        )

    def sources(self, inputs: Inputs, k: int) -> str:
        p, n = self.n_pixels, self.cfg.n
        run, pix = divmod(k, p)
        idx = [(run * n + j) * p + pix for j in range(n)]
        return f"run {run} (frames {run * n}…{run * n + n - 1}), pixel {pix}: " + beat_index_text(
            self.beats(inputs), idx, ("x", "")
        )

    def pre_round(self, inputs: Inputs) -> tuple[np.ndarray, int]:
        c = self.cfg
        acc = accumulate_frames_fixed(inputs["frames"], c).codes.ravel()
        mult, sh = divide_shift(c.in_fmt.frac_bits, c.n, c.recip_word_bits, c.out_fmt)
        return acc * mult, sh


class CmsBlock(Block):
    """``ct_cms`` for a :class:`CmsConfig`. Inputs: ``reset``, ``signal`` (F, M, P).

    Beats per frame: the M reset rows, then the M signal rows. ``out_d0`` is the CMS output,
    ``out_d1`` the full-precision ``sum_signal - sum_reset``; both are compared.
    """

    routine = "cms"

    def __init__(self, cfg: CmsConfig, n_pixels: int) -> None:
        self.cfg = cfg
        self.n_pixels = int(n_pixels)

    def instance(self) -> Instance:
        c = self.cfg
        params = fmt_params("IN", c.in_fmt) + [
            ("ACC_W", literal(c.acc_fmt.word_bits)),
            ("ACC_S", literal(int(c.acc_fmt.signed))),
            ("AOMODE", literal(overflow_code(c.acc_overflow))),
            ("M", literal(c.m)),
            ("NPIX", literal(self.n_pixels)),
        ]
        params += recip_params(c.m, c.recip_word_bits)
        params += fmt_params("OUT", c.out_fmt) + mode_params(c.rounding, c.overflow)
        return Instance(
            module="ct_cms",
            params=tuple(params),
            inputs=(port("in_x", c.in_fmt),),
            outputs=(port("out_y", c.out_fmt), Port("out_diff", c.acc_fmt.word_bits + 2, True)),
            flags=("out_sat", "out_wrap"),
            counters=("cnt_reset_sat", "cnt_reset_wrap", "cnt_signal_sat", "cnt_signal_wrap")
            + OUT_COUNTERS,
        )

    def beats(self, inputs: Inputs) -> np.ndarray:
        rows = np.concatenate(
            [np.asarray(inputs["reset"], np.int64), np.asarray(inputs["signal"], np.int64)],
            axis=-2,
        )
        _check_pixels(rows, self.n_pixels, "cms")
        return np.stack([rows.ravel(), np.zeros(rows.size, np.int64)], axis=1)

    def _sums(self, inputs: Inputs) -> np.ndarray:
        c = self.cfg
        sums = [
            accumulate_into(inputs[k], c.in_fmt, c.acc_fmt, c.acc_overflow, axis=-2)
            for k in ("signal", "reset")
        ]
        return (sums[0] - sums[1]).ravel()

    def n_outputs(self, inputs: Inputs) -> int:
        return int(np.size(inputs["reset"])) // self.cfg.m

    def expected(self, inputs: Inputs) -> Expected:
        res = cms_fixed(inputs["reset"], inputs["signal"], self.cfg)
        n = res.codes.size
        return Expected(res.codes.ravel(), self._sums(inputs), _ones(n), _ones(n), None,
                        res.overflow, {"output": res})

    def overflow(self, counters: Mapping[str, int]) -> dict:
        return {
            "sum_reset": pair(counters, "cnt_reset_sat", "cnt_reset_wrap"),
            "sum_signal": pair(counters, "cnt_signal_sat", "cnt_signal_wrap"),
            "diff": dict(ZERO),
            "output": pair(counters, *OUT_COUNTERS),
        }

    def result(self, d0: np.ndarray, counters: Mapping[str, int], inputs: Inputs) -> FixedResult:
        """RTL outputs as the result of :func:`cms_fixed`."""
        shape = np.shape(inputs["reset"])
        shape = shape[:-2] + shape[-1:]
        return FixedResult(d0.reshape(shape), self.cfg.out_fmt, self.overflow(counters))

    def sources(self, inputs: Inputs, k: int) -> str:
        p, m = self.n_pixels, self.cfg.m
        frame, pix = divmod(k, p)
        idx = [(frame * 2 * m + r) * p + pix for r in range(2 * m)]
        return f"frame {frame}, pixel {pix} (M reset then M signal samples): " + beat_index_text(
            self.beats(inputs), idx, ("x", "")
        )

    def pre_round(self, inputs: Inputs) -> tuple[np.ndarray, int]:
        c = self.cfg
        mult, sh = divide_shift(c.in_fmt.frac_bits, c.m, c.recip_word_bits, c.out_fmt)
        return self._sums(inputs) * mult, sh
