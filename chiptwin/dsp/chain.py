"""Register formats for the chip's DSP chain, derived once from the ``[chip.dsp]`` numbers.

The chain the chip model runs (:mod:`chiptwin.dsp.pipeline`): CMS of each frame → the dark
reference (mean of K CMS frames) → background subtraction → N-frame averaging. Each step keeps
the fractional bits its division creates, so with M, K and N powers of two the whole chain is
exact (no rounding anywhere); otherwise each step rounds once, RND_CONV, at its output.
Every register is signed from the CMS output on; widths follow REFERENCE §5 word growth.
"""

from __future__ import annotations

from dataclasses import dataclass

from chiptwin.dsp.fixed import Fmt
from chiptwin.dsp.frame_ops import AverageConfig, BackgroundConfig, CmsConfig
from chiptwin.dsp.registers import check_modes, check_positive


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
    adc = Fmt(False, adc_bits, 0)
    f_cms = _bits(cms_samples)
    cms_out = Fmt(True, adc_bits + 1 + f_cms, f_cms)
    modes = {"rounding": rounding, "overflow": overflow}
    cms = CmsConfig(m=cms_samples, in_fmt=adc, out_fmt=cms_out, **modes)
    f_dark = f_cms + _bits(n_dark_frames)
    dark_fmt = Fmt(True, cms_out.int_bits + f_dark, f_dark)
    dark = AverageConfig(n=n_dark_frames, in_fmt=cms_out, out_fmt=dark_fmt, **modes)
    bg_out = Fmt(True, cms_out.int_bits + 1 + f_dark, f_dark)
    background = BackgroundConfig(in_fmt=cms_out, dark_fmt=dark_fmt, out_fmt=bg_out, **modes)
    f_avg = f_dark + _bits(average_frames)
    avg_out = Fmt(True, bg_out.int_bits + f_avg, f_avg)
    average = AverageConfig(n=average_frames, in_fmt=bg_out, out_fmt=avg_out, **modes)
    return ChainConfig(cms=cms, dark=dark, background=background, average=average)
