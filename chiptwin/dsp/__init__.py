"""The on-chip DSP: float reference, bit-accurate fixed point, the chip-model pipeline.

* :mod:`.reference` — float64 reference of every routine (the level the others are measured
  against).
* :mod:`.fixed` — the fixed-point core: :class:`Fmt`, exact :func:`quantize` / :func:`requantize`,
  full-precision :func:`add` / :func:`sub` / :func:`mul` / :func:`accumulate`, hardware
  accumulators (:func:`accumulate_into`), overflow counting. numba kernels in ``_kernels``.
* :mod:`.frame_ops`, :mod:`.filters` — the bit-accurate routines, one frozen config per routine
  declaring every register's format; results are :class:`FixedResult` with per-register
  saturation and wrap counts.
* :mod:`.chain` — consistent formats for the chip's chain (CMS → dark → background → average).
* :mod:`.errors` — fixed-vs-float error report against each routine's analytic bound;
  :mod:`.stress` — stress data.
* :mod:`.pipeline` — the DSP stage the chip model calls.
* :mod:`.program` — ``[chip.dsp] program``: the stages, their order, their memory and cycles;
  :mod:`.program_pipeline` — the chip model's DSP running a program (kinetics, line binning,
  8-tap FIR, Wiener equalizer after the chain), noise propagated as a covariance.
"""

from chiptwin.dsp.chain import ChainConfig, chain_configs
from chiptwin.dsp.errors import Case, compare, error_report, format_error_table
from chiptwin.dsp.filters import (
    FirConfig,
    KineticsConfig,
    WienerConfig,
    WienerEqualizer,
    design_wiener,
    fir_fixed,
    kinetics_weighted_fixed,
    wiener_equalize_fixed,
)
from chiptwin.dsp.fixed import (
    OVERFLOW_MODES,
    ROUNDING_MODES,
    Fmt,
    OverflowCounter,
    accumulate,
    accumulate_into,
    accumulator_bits_needed,
    add,
    mul,
    quantize,
    requantize,
    sub,
)
from chiptwin.dsp.frame_ops import (
    AverageConfig,
    BackgroundConfig,
    BinningConfig,
    CmsConfig,
    accumulate_frames_fixed,
    average_frames_fixed,
    bin_lines_fixed,
    cms_fixed,
    subtract_background_fixed,
)
from chiptwin.dsp.registers import FixedResult

__all__ = [
    "OVERFLOW_MODES",
    "ROUNDING_MODES",
    "AverageConfig",
    "BackgroundConfig",
    "BinningConfig",
    "Case",
    "ChainConfig",
    "CmsConfig",
    "FirConfig",
    "FixedResult",
    "Fmt",
    "KineticsConfig",
    "OverflowCounter",
    "WienerConfig",
    "WienerEqualizer",
    "accumulate",
    "accumulate_frames_fixed",
    "accumulate_into",
    "accumulator_bits_needed",
    "add",
    "average_frames_fixed",
    "bin_lines_fixed",
    "chain_configs",
    "cms_fixed",
    "compare",
    "design_wiener",
    "error_report",
    "fir_fixed",
    "format_error_table",
    "kinetics_weighted_fixed",
    "mul",
    "quantize",
    "requantize",
    "sub",
    "subtract_background_fixed",
    "wiener_equalize_fixed",
]
