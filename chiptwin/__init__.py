"""chiptwin — a digital twin of a CMOS bioluminescence detection chip.

The signal travels through these stages, in this order (:data:`STAGES`)::

    kinetics ──► optics ──► pixel ──► adc ──► memory ──► dsp ──► detection ──► report
    photons/s    photons/    e⁻        codes   frames     results  SNR, calls
    per site     pixel

* kinetics: light emitted per assay site (Salama et al. 2004, eqs. 2–19). Unit: photons/s.
* optics: the share of it reaching each pixel's photodiode (NA², PSF coupling). Unit: photons/pixel.
* pixel: photodiode and readout (QE, dark current, shot, kTC, read noise, full well). Unit: e⁻.
* adc: per-pixel ADC. Unit: codes (LSB).
* memory: on-chip frame memory of finite capacity. Unit: frames (bits).
* dsp: background subtraction, correlated multiple sampling, averaging, ... Unit: codes.
* detection: per-site SNR (power ratio, eq. 22, and amplitude ratio), decisions, base calls.

Start with :func:`chiptwin.run.run` or the ``chiptwin`` command.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

STAGES: tuple[str, ...] = (
    "kinetics",
    "optics",
    "pixel",
    "adc",
    "memory",
    "dsp",
    "detection",
    "report",
)
"""The stages in signal order, written once."""

try:
    __version__ = version("chiptwin")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"

__all__ = ["STAGES", "__version__"]
