"""Block adapters of the filters: the 8-tap FIR and the kinetics-weighted accumulator."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from chiptwin.dsp.filters import FirConfig, KineticsConfig, fir_fixed, kinetics_weighted_fixed
from chiptwin.dsp.fixed import accumulate_into, mul, overflow_code
from chiptwin.dsp.registers import FixedResult
from rtl_ref.block import (
    ZERO,
    Block,
    Expected,
    Inputs,
    beat_index_text,
    fmt_params,
    mode_params,
    pair,
    port,
)
from rtl_ref.design import Instance, literal, packed

ACC_COUNTERS = ("cnt_acc_sat", "cnt_acc_wrap")
OUT_COUNTERS = ("cnt_out_sat", "cnt_out_wrap")


def _ones(n: int) -> np.ndarray:
    return np.ones(n, dtype=bool)


def _acc_params(acc_fmt, acc_overflow: str) -> list[tuple[str, str]]:
    return [
        ("ACC_W", literal(acc_fmt.word_bits)),
        ("ACC_S", literal(int(acc_fmt.signed))),
        ("AOMODE", literal(overflow_code(acc_overflow))),
    ]


class FirBlock(Block):
    """``ct_fir`` for a :class:`FirConfig`. Inputs: ``frames`` (T, P), filtered along T.

    ``out_d0`` is the filter output, ``out_d1`` the accumulator (the model's, read through an
    output register as wide as the accumulator: no rounding, no overflow); both are compared.
    """

    routine = "fir"

    def __init__(self, cfg: FirConfig, n_pixels: int) -> None:
        self.cfg = cfg
        self.n_pixels = int(n_pixels)

    def instance(self) -> Instance:
        c = self.cfg
        params = fmt_params("IN", c.in_fmt) + [("TAPS", literal(c.taps))]
        params += fmt_params("COEF", c.coef_fmt)
        params.append(("COEFS", packed(c.coef_codes, c.coef_fmt.word_bits)))
        params += _acc_params(c.acc_fmt, c.acc_overflow) + [("NPIX", literal(self.n_pixels))]
        params += fmt_params("OUT", c.out_fmt) + mode_params(c.rounding, c.overflow)
        return Instance(
            module="ct_fir",
            params=tuple(params),
            inputs=(port("in_x", c.in_fmt),),
            outputs=(port("out_y", c.out_fmt), port("out_acc", c.acc_fmt)),
            flags=("out_sat", "out_wrap"),
            counters=ACC_COUNTERS + OUT_COUNTERS,
        )

    def beats(self, inputs: Inputs) -> np.ndarray:
        frames = np.asarray(inputs["frames"], dtype=np.int64)
        if frames.ndim != 2 or frames.shape[1] != self.n_pixels:
            raise ValueError(f"fir: frames {frames.shape} must be (n_frames, {self.n_pixels})")
        return np.stack([frames.ravel(), np.zeros(frames.size, np.int64)], axis=1)

    def _acc(self, inputs: Inputs) -> np.ndarray:
        wide = dataclasses.replace(self.cfg, out_fmt=self.cfg.acc_fmt)
        return fir_fixed(inputs["frames"], wide).codes.ravel()

    def n_outputs(self, inputs: Inputs) -> int:
        return int(np.size(inputs["frames"]))

    def expected(self, inputs: Inputs) -> Expected:
        res = fir_fixed(inputs["frames"], self.cfg)
        n = res.codes.size
        return Expected(res.codes.ravel(), self._acc(inputs), _ones(n), _ones(n), None,
                        res.overflow, {"output": res})

    def overflow(self, counters: Mapping[str, int]) -> dict:
        return {
            "coef": {"sat": self.cfg.coef_sat, "wrap": 0},  # ROM contents, a design-time count
            "product": dict(ZERO),
            "acc": pair(counters, *ACC_COUNTERS),
            "output": pair(counters, *OUT_COUNTERS),
        }

    def result(self, d0: np.ndarray, counters: Mapping[str, int], inputs: Inputs) -> FixedResult:
        """RTL outputs as the result of :func:`fir_fixed`."""
        return FixedResult(
            d0.reshape(np.shape(inputs["frames"])), self.cfg.out_fmt, self.overflow(counters)
        )

    def sources(self, inputs: Inputs, k: int) -> str:
        p = self.n_pixels
        t, pix = divmod(k, p)
        idx = [(t - j) * p + pix for j in range(self.cfg.taps) if t - j >= 0]
        return f"frame {t}, pixel {pix} (newest sample first): " + beat_index_text(
            self.beats(inputs), idx, ("x", "")
        )

    def pre_round(self, inputs: Inputs) -> tuple[np.ndarray, int]:
        return self._acc(inputs), self.cfg.acc_fmt.frac_bits - self.cfg.out_fmt.frac_bits


class KineticsBlock(Block):
    """``ct_kinetics`` for a :class:`KineticsConfig`. Inputs: ``frames`` (R, N, P), runs of N.

    ``out_d0`` is the amplitude, ``out_d1`` the accumulator ``Σ w_j y_j`` (recomputed with the
    model's public :func:`mul` and :func:`accumulate_into`); both are compared.
    """

    routine = "kinetics"

    def __init__(self, cfg: KineticsConfig, n_pixels: int) -> None:
        if cfg.norm_fmt.signed:
            raise ValueError("kinetics: the RTL holds an unsigned normalisation constant")
        self.cfg = cfg
        self.n_pixels = int(n_pixels)

    def instance(self) -> Instance:
        c = self.cfg
        params = fmt_params("IN", c.in_fmt) + [("N", literal(len(c.t_s)))]
        params += fmt_params("COEF", c.coef_fmt)
        params.append(("WEIGHTS", packed(c.weight_codes, c.coef_fmt.word_bits)))
        params += _acc_params(c.acc_fmt, c.acc_overflow)
        params += [
            ("NORM_W", literal(c.norm_fmt.word_bits)),
            ("NORM_F", literal(c.norm_fmt.frac_bits)),
            ("NORM", literal(c.norm_code, 64)),
            ("NPIX", literal(self.n_pixels)),
        ]
        params += fmt_params("OUT", c.out_fmt) + mode_params(c.rounding, c.overflow)
        return Instance(
            module="ct_kinetics",
            params=tuple(params),
            inputs=(port("in_x", c.in_fmt),),
            outputs=(port("out_y", c.out_fmt), port("out_acc", c.acc_fmt)),
            flags=("out_sat", "out_wrap"),
            counters=ACC_COUNTERS + OUT_COUNTERS,
        )

    def beats(self, inputs: Inputs) -> np.ndarray:
        frames = np.asarray(inputs["frames"], dtype=np.int64)
        n = len(self.cfg.t_s)
        if frames.ndim != 3 or frames.shape[1:] != (n, self.n_pixels):
            raise ValueError(
                f"kinetics: frames {frames.shape} must be (runs, {n}, {self.n_pixels})")
        return np.stack([frames.ravel(), np.zeros(frames.size, np.int64)], axis=1)

    def _acc(self, inputs: Inputs) -> np.ndarray:
        c = self.cfg
        w = np.array(c.weight_codes, dtype=np.int64)[:, None]
        prod, prod_fmt = mul(inputs["frames"], c.in_fmt, w, c.coef_fmt)
        return accumulate_into(prod, prod_fmt, c.acc_fmt, c.acc_overflow, axis=-2).ravel()

    def n_outputs(self, inputs: Inputs) -> int:
        return int(np.size(inputs["frames"])) // len(self.cfg.t_s)

    def expected(self, inputs: Inputs) -> Expected:
        res = kinetics_weighted_fixed(inputs["frames"], self.cfg)
        n = res.codes.size
        return Expected(res.codes.ravel(), self._acc(inputs), _ones(n), _ones(n), None,
                        res.overflow, {"output": res})

    def overflow(self, counters: Mapping[str, int]) -> dict:
        return {
            "weights": {"sat": self.cfg.weight_sat, "wrap": 0},  # ROM contents, design time
            "product": dict(ZERO),
            "acc": pair(counters, *ACC_COUNTERS),
            "norm": dict(ZERO),
            "scaled": dict(ZERO),
            "output": pair(counters, *OUT_COUNTERS),
        }

    def result(self, d0: np.ndarray, counters: Mapping[str, int], inputs: Inputs) -> FixedResult:
        """RTL outputs as the result of :func:`kinetics_weighted_fixed`."""
        return FixedResult(d0.reshape(-1, self.n_pixels), self.cfg.out_fmt, self.overflow(counters))

    def sources(self, inputs: Inputs, k: int) -> str:
        p, n = self.n_pixels, len(self.cfg.t_s)
        run, pix = divmod(k, p)
        idx = [(run * n + j) * p + pix for j in range(n)]
        return f"run {run}, pixel {pix} (frames j = 0…{n - 1}): " + beat_index_text(
            self.beats(inputs), idx, ("y", "")
        )

    def pre_round(self, inputs: Inputs) -> tuple[np.ndarray, int]:
        c = self.cfg
        sh = c.acc_fmt.frac_bits + c.norm_fmt.frac_bits - c.out_fmt.frac_bits
        return self._acc(inputs) * c.norm_code, sh
