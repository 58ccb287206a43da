"""Register formats for the chip's DSP chain, derived once from the ``[chip.dsp]`` numbers.

The chain the chip model runs (:mod:`chiptwin.dsp.pipeline`): CMS of each frame → the dark
reference (mean of K CMS frames) → background subtraction → N-frame averaging. Each step keeps
the fractional bits its division creates, so with M, K and N powers of two the whole chain is
exact (no rounding anywhere); otherwise each step rounds once, RND_CONV, at its output.
Every register is signed from the CMS output on; widths follow fixed-point word growth
(docs/background/sources.md F4).

A count whose registers no 64-bit DSP holds raises :class:`FormatLimit` (a ``ValueError``) that
names the ``[chip.dsp]`` key, its value and the largest values that fit, so that validation
refuses it by name (:mod:`chiptwin.config.consistency`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

from chiptwin.dsp.fixed import Fmt
from chiptwin.dsp.frame_ops import AverageConfig, BackgroundConfig, CmsConfig
from chiptwin.dsp.registers import check_modes, check_positive, is_power_of_two

#: Widest register of the DSP (its multiplier, accumulators and words). Unit: bit.
MAX_REGISTER_BITS = 64


class FormatLimit(ValueError):
    """A DSP setting whose registers would be wider than :data:`MAX_REGISTER_BITS`.

    ``key`` is the setting as ``[chip.dsp]`` (or ``[chip.adc]``) names it (``"acc_bits"``,
    ``"average_frames"``, …; ``"program"`` for a stage), ``allowed`` what would fit.
    """

    def __init__(self, key: str, value: object, allowed: str) -> None:
        super().__init__(f"{key} = {value}: {allowed}")
        self.key, self.value, self.allowed = key, value, allowed


def _fits(build: Callable[[], object]) -> bool:
    try:
        build()
    except ValueError:
        return False
    return True


def count_limit(key: str, n: int, what: str, build: Callable[[int], object]) -> FormatLimit:
    """The refusal of a count ``n`` whose registers ``build(n)`` cannot make: the largest power
    of two and the largest other count that fit (a power of two divides by a shift, any other
    count by a reciprocal product, which is wider)."""
    pow2 = other = 0
    for b in range(32):
        if _fits(lambda b=b: build(2**b)):
            pow2 = 2**b
        if b >= 2 and _fits(lambda b=b: build(2**b - 1)):
            other = 2**b - 1
    try:
        build(n)
        reason = ""
    except ValueError as err:
        reason = f" ({err})"
    if not pow2:
        return FormatLimit(key, n, f"{what} needs registers wider than {MAX_REGISTER_BITS} bits "
                                   f"for any {key}{reason}")
    powers = "a power of two" + (f" ≤ {pow2}" if pow2 < 2**31 else "")
    return FormatLimit(
        key, n, f"{what} needs registers wider than {MAX_REGISTER_BITS} bits{reason}; with "
                f"these widths {key} must be {powers} (the divide is a shift)"
                + (f" or ≤ {other}" if other else ""))


def _bits(n: int) -> int:
    """``⌈log2 n⌉``: the fractional bits a division by ``n`` needs to be exact (n a power of 2)."""
    return (n - 1).bit_length()


@dataclass(frozen=True)
class ChainConfig:
    """The four routine configs of the chain, formats consistent from one step to the next.

    Attributes
    ----------
    cms : CmsConfig
        ADC codes (unsigned, ``adc_bits``) → ``Q(adc_bits + 1).⌈log2 M⌉``.
    dark : AverageConfig
        K CMS frames → the dark reference, ``⌈log2 K⌉`` more fractional bits.
    background : BackgroundConfig
        CMS frame − dark reference → one more integer bit, the dark reference's fractional bits.
    average : AverageConfig
        N background-subtracted frames → their mean, ``⌈log2 N⌉`` more fractional bits.
    """

    cms: CmsConfig
    dark: AverageConfig
    background: BackgroundConfig
    average: AverageConfig

    def registers(self) -> dict[str, dict[str, Fmt]]:
        """Every register of the chain: ``step -> register -> Fmt``."""
        return {
            "cms": self.cms.registers(),
            "dark": self.dark.registers(),
            "background": self.background.registers(),
            "average": self.average.registers(),
        }


def chain_configs(
    adc_bits: int,
    cms_samples: int,
    n_dark_frames: int,
    average_frames: int,
    rounding: str = "RND_CONV",
    overflow: str = "SAT",
) -> ChainConfig:
    """Formats for the chain from the scenario's ``[chip.adc] bits`` and ``[chip.dsp]`` counts.

    Parameters
    ----------
    adc_bits : int
        ADC resolution (JSSC 2006: 13).
    cms_samples, n_dark_frames, average_frames : int
        M, K and N of ``[chip.dsp]``.
    rounding, overflow : str
        Mode of every output register (accumulators are full precision and cannot overflow).

    Returns
    -------
    ChainConfig
    """
    check_positive(
        "chain_configs",
        adc_bits=adc_bits,
        cms_samples=cms_samples,
        n_dark_frames=n_dark_frames,
        average_frames=average_frames,
    )
    check_modes("chain_configs", rounding=rounding, overflow=overflow)
    modes = {"rounding": rounding, "overflow": overflow}
    cms = _step("cms_samples", cms_samples, "the CMS of 2M samples",
                lambda m: _cms(adc_bits, m, modes))
    dark = _step("n_dark_frames", n_dark_frames,
                 f"the dark reference of K frames of {cms.out_fmt.q}",
                 lambda k: _dark(cms.out_fmt, k, modes))
    bg_out = Fmt(True, cms.out_fmt.int_bits + 1 + dark.out_fmt.frac_bits, dark.out_fmt.frac_bits)
    background = BackgroundConfig(in_fmt=cms.out_fmt, dark_fmt=dark.out_fmt, out_fmt=bg_out,
                                  **modes)
    average = _step("average_frames", average_frames, f"the average of N frames of {bg_out.q}",
                    lambda n: _average(bg_out, n, modes))
    return ChainConfig(cms=cms, dark=dark, background=background, average=average)


def _step(key: str, n: int, what: str, build: Callable[[int], object]):
    """``build(n)``, or the :class:`FormatLimit` of ``n`` when its registers cannot be made."""
    try:
        return build(n)
    except ValueError:
        raise count_limit(key, n, what, build) from None


def _cms(adc_bits: int, m: int, modes: dict[str, str]) -> CmsConfig:
    f_cms = _bits(m)
    out = Fmt(True, adc_bits + 1 + f_cms, f_cms)
    return CmsConfig(m=m, in_fmt=Fmt(False, adc_bits, 0), out_fmt=out, **modes)


def _dark(cms_out: Fmt, k: int, modes: dict[str, str]) -> AverageConfig:
    f_dark = cms_out.frac_bits + _bits(k)
    out = Fmt(True, cms_out.int_bits + f_dark, f_dark)
    return AverageConfig(n=k, in_fmt=cms_out, out_fmt=out, **modes)


def _average(bg_out: Fmt, n: int, modes: dict[str, str]) -> AverageConfig:
    f_avg = bg_out.frac_bits + _bits(n)
    out = Fmt(True, bg_out.int_bits + f_avg, f_avg)
    return AverageConfig(n=n, in_fmt=bg_out, out_fmt=out, **modes)


def _a(n: int) -> str:
    """The article of a number read aloud ("an 18-bit", "a 64-bit")."""
    return "an" if n in (8, 11, 18) or 80 <= n <= 89 else "a"


def with_accumulator(chain: ChainConfig, acc_bits: int, acc_overflow: str) -> ChainConfig:
    """The chain with its N-frame accumulator narrowed to ``acc_bits`` (``[chip.dsp]``).

    Raises :class:`FormatLimit` (key ``acc_bits``) when the divide by a count N that is not a
    power of two would multiply the accumulator by its reciprocal into a product wider than
    :data:`MAX_REGISTER_BITS`.
    """
    avg = chain.average

    def build(bits: int) -> AverageConfig:
        return replace(avg, acc_fmt=Fmt(True, bits, avg.in_fmt.frac_bits),
                       acc_overflow=acc_overflow)

    try:
        return replace(chain, average=build(acc_bits))
    except ValueError:
        pass
    top = next((b for b in range(acc_bits - 1, 0, -1) if _fits(lambda b=b: build(b))), 0)
    wide = acc_bits + avg.recip_word_bits
    shift = "" if is_power_of_two(avg.n) else (
        "use a power-of-two average_frames (the divide is then a shift) or ")
    raise FormatLimit(
        "acc_bits", acc_bits,
        f"with average_frames = {avg.n} the 1/N divide multiplies the accumulator by "
        f"{_a(avg.recip_word_bits)} {avg.recip_word_bits}-bit reciprocal, {_a(wide)} {wide}-bit "
        f"product: the DSP's multiplier is at most {MAX_REGISTER_BITS} bits; {shift}acc_bits ≤ "
        f"{top}")
