"""Pixel and ADC: photons on each photodiode → electrons → volts → ADC codes.

The readout modelled, per frame (Eltoukhy et al., JSSC 2006; El Gamal & Eltoukhy, IEEE Circuits &
Devices 21(3), 2005)::

    reset ─► M reset samples ─► integrate t_int ─► M signal samples ─► (next frame's reset)
             kTC + read noise                       charge + kTC + read noise

* Charge: one merged Poisson draw per pixel of ``qe·gain·photons + dark_e`` (QE thinning of a
  Poisson count is Poisson; signal plus dark, both Poisson, is Poisson), clipped at the full well.
  ``photons`` is the expected count in the window, the exact integral of the photon rate.
* Fixed pattern: a PRNU gain map and a DSNU dark map, each of mean exactly 1
  (:func:`fixed_pattern_maps`).
* Reset (kTC) noise ``√(kTC)/q``: with true CDS the reset samples are taken right after this
  frame's reset, so they carry the same kTC realisation as its signal samples and it cancels in
  ``signal − reset``; without it (e.g. a 3T pixel read signal-then-reset) the reset samples carry
  an independent kTC draw and the difference keeps ``2σ_kTC²``.
* Read noise: white, independent in every sample; averaging M samples divides its variance by M.
* Polarity (a choice): the ADC input rises with collected charge (``to_volts``: pedestal plus
  charge × conversion gain); the differential readout inverts the falling sense-node voltage.
* ADC: ``LSB = (v_max − v_min)/2^bits``, round to nearest (unbiased), clipped to
  ``[0, 2^bits − 1]``, with offset and gain error (:mod:`chiptwin.pixel.adc`); as built
  (:mod:`chiptwin.pixel.converter`): comparator noise, INL and DNL as transition levels per ramp,
  per-converter offset and gain mismatch, all 0 by default (then today's codes, bit for bit).

The DSP, not this package, forms ``mean(signal) − mean(reset)``. Photon-statistics levels:
``expected`` (:func:`expected_frame`, :func:`adc_expected`: moments, no sampling) and ``binned``
(:func:`sample_frame` → :func:`to_volts` → :func:`adc_convert`; :func:`binned_codes`, the same
draws and codes for many frames of a small array in one call; or the fused multi-core fast path
:func:`sensor_chain` for large arrays). Randomness only through a passed ``numpy.random.Generator``.
"""

from __future__ import annotations

from chiptwin.pixel.adc import (
    adc_convert,
    adc_expected,
    lsb_V,
    quantization_var_of_mean,
    to_volts,
)
from chiptwin.pixel.chain import sensor_chain
from chiptwin.pixel.converter import Converter, build_converter
from chiptwin.pixel.expected_adc import cms_moments
from chiptwin.pixel.frames import CHUNK_PIXELS, binned_codes, chunk_streams, code_dtype
from chiptwin.pixel.ramp import AsBuilt, check_transition_table, load_transition_table
from chiptwin.pixel.sensor import (
    clipped_poisson_moments,
    conversion_gain_uV_per_e,
    dark_current_e_per_s,
    expected_frame,
    fixed_pattern_maps,
    ktc_noise_e,
    mean_electrons,
    read_out,
    sample_frame,
)

__all__ = [
    "CHUNK_PIXELS",
    "AsBuilt",
    "Converter",
    "build_converter",
    "check_transition_table",
    "load_transition_table",
    "adc_convert",
    "adc_expected",
    "binned_codes",
    "code_dtype",
    "chunk_streams",
    "clipped_poisson_moments",
    "cms_moments",
    "conversion_gain_uV_per_e",
    "dark_current_e_per_s",
    "expected_frame",
    "fixed_pattern_maps",
    "ktc_noise_e",
    "lsb_V",
    "quantization_var_of_mean",
    "mean_electrons",
    "read_out",
    "sample_frame",
    "sensor_chain",
    "to_volts",
]
