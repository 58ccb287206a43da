"""What every block adapter provides: the RTL instance of a model config, the beats that feed it,
the model's answer for the same inputs, and the way back from RTL outputs to a model result.

The fixed-point model (:mod:`chiptwin.dsp`) is the specification: a block adapter only calls its
public routines and config dataclasses, and reads the register formats from ``cfg.registers()``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from chiptwin.dsp.fixed import Fmt, overflow_code, rounding_code
from chiptwin.dsp.registers import FixedResult, is_power_of_two, reciprocal_code, reciprocal_fmt
from rtl_ref.design import Instance, Port, literal

Inputs = Mapping[str, np.ndarray]


@dataclass(frozen=True)
class Expected:
    """The model's answer, as the output beats the RTL must produce, in order.

    ``d0``/``d1``: expected words (int64, one per output beat); ``cmp0``/``cmp1``: which beats
    carry a meaningful word (False: not compared); ``tag``: expected ``out_flags`` bit 0 (None:
    not compared); ``overflow``: the model's counts (``register -> {"sat", "wrap"}``, or
    ``step -> register -> …`` for a chain); ``results``: the model's results by name.
    """

    d0: np.ndarray
    d1: np.ndarray
    cmp0: np.ndarray
    cmp1: np.ndarray
    tag: np.ndarray | None
    overflow: dict
    results: dict[str, FixedResult]


def port(name: str, fmt: Fmt) -> Port:
    """A data port carrying codes of ``fmt``."""
    return Port(name, fmt.word_bits, fmt.signed)


def fmt_params(prefix: str, fmt: Fmt) -> list[tuple[str, str]]:
    """``PREFIX_W``, ``PREFIX_F``, ``PREFIX_S`` of a register."""
    return [
        (f"{prefix}_W", literal(fmt.word_bits)),
        (f"{prefix}_F", literal(fmt.frac_bits)),
        (f"{prefix}_S", literal(int(fmt.signed))),
    ]


def mode_params(rounding: str, overflow: str, prefix: str = "") -> list[tuple[str, str]]:
    """``RMODE``/``OMODE``: the kernel codes of the model's mode names."""
    return [
        (f"{prefix}RMODE", literal(rounding_code(rounding))),
        (f"{prefix}OMODE", literal(overflow_code(overflow))),
    ]


def recip_params(n: int, recip_word_bits: int, prefix: str = "") -> list[tuple[str, str]]:
    """The divide-by-``n`` constants (``RECIP`` unused when ``n`` is a power of two)."""
    if is_power_of_two(n):
        return []
    fmt = reciprocal_fmt(n, recip_word_bits)
    return [
        (f"{prefix}RECIP_W", literal(fmt.word_bits)),
        (f"{prefix}RECIP_F", literal(fmt.frac_bits)),
        (f"{prefix}RECIP", literal(reciprocal_code(n, recip_word_bits), 64)),
    ]


def divide_shift(src_frac: int, n: int, recip_word_bits: int, out: Fmt) -> tuple[int, int]:
    """``(multiplier, SH)`` of the divide step: pre-rounding value = ``value · multiplier``
    with ``SH`` fractional bits to drop (:func:`chiptwin.dsp.registers.divide`)."""
    if is_power_of_two(n):
        return 1, src_frac + n.bit_length() - 1 - out.frac_bits
    fmt = reciprocal_fmt(n, recip_word_bits)
    return reciprocal_code(n, recip_word_bits), src_frac + fmt.frac_bits - out.frac_bits


def pair(counts: Mapping[str, int], sat: str, wrap: str) -> dict[str, int]:
    """``{"sat": counts[sat], "wrap": counts[wrap]}``."""
    return {"sat": int(counts[sat]), "wrap": int(counts[wrap])}


ZERO = {"sat": 0, "wrap": 0}


class Block(ABC):
    """An RTL block bound to one model config.

    Subclasses set ``routine`` (the model routine's name) and implement the methods below.
    """

    routine: str = ""
    n_pixels: int = 1

    @abstractmethod
    def instance(self) -> Instance:
        """The RTL instance (module, parameters, port map)."""

    @abstractmethod
    def beats(self, inputs: Inputs) -> np.ndarray:
        """Input beats in stream order: int64 ``(n_beats, 2)`` (``in_d0``, ``in_d1``)."""

    @abstractmethod
    def n_outputs(self, inputs: Inputs) -> int:
        """Output beats the block makes from ``inputs`` (from their shape alone)."""

    @abstractmethod
    def expected(self, inputs: Inputs) -> Expected:
        """The model's answer on ``inputs``."""

    @abstractmethod
    def overflow(self, counters: Mapping[str, int]) -> dict:
        """The RTL counters (by port name) as the model's overflow dict."""

    def result(self, d0: np.ndarray, counters: Mapping[str, int], inputs: Inputs) -> FixedResult:
        """The RTL's output words ``out_d0`` as the model routine's :class:`FixedResult`.

        Blocks that mirror one model routine override this; a block that chains several
        routines (:class:`~rtl_ref.chain_block.ChainBlock`) has no single result to give.
        """
        raise TypeError(f"{type(self).__name__} chains several model routines: it has no "
                        "single FixedResult (use rtl_ref.pipeline for the chain)")

    @abstractmethod
    def sources(self, inputs: Inputs, k: int) -> str:
        """Where output beat ``k`` sits and the input beats it depends on (for reports)."""

    def pre_round(self, inputs: Inputs) -> tuple[np.ndarray, int] | None:
        """Exact values before the output rounding and the bits it drops (coverage of ties)."""
        return None

    def counter_names(self) -> tuple[str, ...]:
        """Counter ports, ``cnt_idx`` order."""
        return self.instance().counters

    def label(self) -> str:
        """A short description for reports."""
        return f"{self.routine}"


def beat_index_text(beats: np.ndarray, idx: list[int], names: tuple[str, str]) -> str:
    """``beat 12 (x=5, dark=3)`` for each index, comma-separated."""
    parts = []
    for i in idx:
        words = f"{names[0]}={int(beats[i, 0])}"
        if names[1]:
            words += f", {names[1]}={int(beats[i, 1])}"
        parts.append(f"beat {i} ({words})")
    return "; ".join(parts)
