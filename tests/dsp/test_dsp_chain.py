"""The chip's DSP chain formats: CMS → dark reference → background subtraction → averaging."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.dsp import reference
from chiptwin.dsp.chain import chain_configs
from chiptwin.dsp.fixed import Fmt
from chiptwin.dsp.frame_ops import average_frames_fixed, cms_fixed, subtract_background_fixed


def _run_chain(chain, samples: np.ndarray, k: int, n: int):
    """Fixed and float chains on ADC samples ``(frames, 2M, P)``: reset then signal halves."""
    m = chain.cms.m
    cms = cms_fixed(samples[:, :m], samples[:, m:], chain.cms)
    dark = average_frames_fixed(cms.codes[:k], chain.dark)
    bg = subtract_background_fixed(cms.codes[k:], dark.codes[0], chain.background)
    avg = average_frames_fixed(bg.codes, chain.average)
    f_cms = reference.correlated_multiple_sampling(samples[:, :m], samples[:, m:])
    f_dark = reference.average_frames(f_cms[:k], k)[0]
    f_avg = reference.average_frames(reference.subtract_background(f_cms[k:], f_dark), n)
    overflow = sum(sum(r.total().values()) for r in (cms, dark, bg, avg))
    return avg, f_avg, overflow


@pytest.mark.parametrize("adc_bits, m, k, n", [(13, 4, 16, 4), (13, 2, 4, 8), (10, 8, 64, 16)])
def test_power_of_two_chain_is_exact(adc_bits: int, m: int, k: int, n: int, rng) -> None:
    chain = chain_configs(adc_bits, m, k, n)
    samples = rng.integers(0, 2**adc_bits, (k + 3 * n, 2 * m, 24))
    samples[k : k + n] = 2**adc_bits - 1  # full scale
    samples[k + n : k + 2 * n, :m] = 2**adc_bits - 1  # most negative CMS difference
    samples[k + n : k + 2 * n, m:] = 0
    avg, f_avg, overflow = _run_chain(chain, samples, k, n)
    np.testing.assert_array_equal(avg.values(), f_avg)
    assert overflow == 0


def test_other_counts_round_once_per_step(rng) -> None:
    chain = chain_configs(13, 3, 10, 5)
    samples = rng.integers(0, 2**13, (10 + 20, 6, 16))
    avg, f_avg, overflow = _run_chain(chain, samples, 10, 5)
    assert overflow == 0
    # CMS rounds once (≤ ½ LSB_cms, plus its reciprocal term); its error reaches the output twice
    # at most (through the frames and through the dark reference); the dark reference and the
    # average round once each; the background subtraction is exact.
    lsb = {name: getattr(chain, name).out_fmt.lsb for name in ("cms", "dark", "average")}
    bound = 2 * 0.5 * lsb["cms"] + 0.5 * lsb["dark"] + 0.5 * lsb["average"] + 1e-3
    assert np.abs(avg.values() - f_avg).max() <= bound


def test_chain_formats_for_the_reference_chip() -> None:
    chain = chain_configs(13, 4, 16, 4)
    assert chain.cms.out_fmt == Fmt(True, 16, 2)
    assert chain.dark.out_fmt == Fmt(True, 20, 6)
    assert chain.background.out_fmt == Fmt(True, 21, 6)
    assert chain.average.out_fmt == Fmt(True, 23, 8)
    regs = chain.registers()
    assert list(regs) == ["cms", "dark", "background", "average"]
    assert regs["average"]["acc"] == Fmt(True, 23, 6)


def test_chain_refuses_bad_counts() -> None:
    with pytest.raises(ValueError, match="cms_samples = 0"):
        chain_configs(13, 0, 16, 4)
    with pytest.raises(ValueError, match="rounding"):
        chain_configs(13, 4, 16, 4, rounding="UP")
