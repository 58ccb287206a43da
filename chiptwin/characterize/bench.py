"""The chip on the test bench: expected charge per pixel → ADC codes → the CMS frame, in DN.

The chip is the scenario's as configured: its sensor (QE, PRNU/DSNU maps drawn from
``chip.fixed_pattern_seed`` as in a run, dark current at the temperature, kTC, read noise, full
well, M reset and M signal samples), its per-pixel ADC (bits, range, offset and gain error) and
its DSP's correlated multiple sampling at the scenario's level (float, or the bit-accurate CMS
register for ``fixed`` and ``rtl``, which is bit-exact with the RTL). The frame the bench reads is
the CMS difference ``mean(signal codes) − mean(reset codes)`` before dark subtraction and
averaging. **DN** is one ADC LSB: the CMS frame is in ADC codes, with steps of 1/M.

Codes come from :func:`chiptwin.pixel.sensor_chain` (multi-core; the same statistics as the run's
``binned_codes``, tested in ``tests/pixel``), fed the expected charge ``qe·PRNU·photons + dark``
of :func:`chiptwin.pixel.mean_electrons` as its "photons" with unit QE and gain: the same law.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chiptwin import pixel
from chiptwin.config import Scenario
from chiptwin.constants import C_LIGHT, H_PLANCK
from chiptwin.dsp import reference
from chiptwin.dsp.frame_ops import CmsConfig, cms_fixed
from chiptwin.twin.stages import SensorModel

#: Wavelength at which the twin's QE is given (schema: "qe at 560 nm"; Salama et al. 2004:
#: luciferase emission peaks at 562 nm). Unit: nm.
WAVELENGTH_NM: float = 560.0

Progress = Callable[[int, int], None]

#: The Gaussian count's lowest mean when a read asks for smooth draws: every count (the sampler
#: needs a positive bound). Unit: e⁻.
SMOOTH_MIN_MEAN_E: float = 1e-9


def photon_energy_J(wavelength_nm: float = WAVELENGTH_NM) -> float:
    """``h·c/λ``. Unit: J per photon (3.55e-19 J at 560 nm)."""
    return H_PLANCK * C_LIGHT / (wavelength_nm * 1e-9)


@dataclass(frozen=True)
class Camera:
    """What a datasheet says about the device under test besides its measured figures."""

    rows: int
    cols: int
    pixel_pitch_um: float
    diode_area_um2: float
    adc_bits: int
    adc_v_min_V: float
    adc_v_max_V: float
    cms_samples: int
    dsp_level: str
    true_cds: bool
    temperature_C: float
    wavelength_nm: float = WAVELENGTH_NM

    @property
    def n_pixels(self) -> int:
        return self.rows * self.cols

    @property
    def pixel_area_um2(self) -> float:
        """The pixel's area, pitch²: EMVA's photons per pixel fall on it. Unit: µm²."""
        return self.pixel_pitch_um**2

    @property
    def fill_factor(self) -> float:
        """Photodiode area / pixel area: EMVA's η is the twin's QE times this."""
        return self.diode_area_um2 / self.pixel_area_um2


def camera_of(s: Scenario) -> Camera:
    """The :class:`Camera` facts of a scenario's chip."""
    c, px = s.chip, s.chip.pixel
    level = s.dsp_level
    return Camera(rows=c.rows, cols=c.cols, pixel_pitch_um=c.pitch_um,
                  diode_area_um2=px.diode_w_um * px.diode_h_um, adc_bits=c.adc.bits,
                  adc_v_min_V=c.adc.v_min_V, adc_v_max_V=c.adc.v_max_V,
                  cms_samples=c.dsp.cms_samples, dsp_level=level, true_cds=px.true_cds,
                  temperature_C=px.temperature_C)


def at_temperature(s: Scenario, temperature_C: float) -> Scenario:
    """The same scenario with the chip at another temperature (dark current, kTC)."""
    px = dataclasses.replace(s.chip.pixel, temperature_C=temperature_C)
    return dataclasses.replace(s, chip=dataclasses.replace(s.chip, pixel=px))


class Bench:
    """The scenario's chip with a light source and a frame grabber.

    Parameters
    ----------
    s : Scenario
        Any scenario; only its ``[chip]`` matters (the bench replaces the assay's light).
    """

    def __init__(self, s: Scenario) -> None:
        from chiptwin.dsp.pipeline import chain_for
        from chiptwin.twin.runner import chip_sensor

        self.scenario, self.camera = s, camera_of(s)
        self.sensor: SensorModel = chip_sensor(s)
        self._chip_sensor = chip_sensor
        self.cms_cfg: CmsConfig | None = (
            chain_for(s.chip).cms if s.dsp_level in ("fixed", "rtl") else None)
        self.clipped = 0  # ADC samples at code 0 or full scale, over every image read

    # --- nominal figures (what the design says; the bench uses them only to plan exposures) ---
    @property
    def lsb_V(self) -> float:
        a = self.scenario.chip.adc
        return pixel.lsb_V(a.bits, a.v_min_V, a.v_max_V)

    @property
    def gain_dn_per_e(self) -> float:
        """Nominal system gain K: conversion gain × (1 + gain error) / LSB. Unit: DN/e⁻."""
        a = self.scenario.chip.adc
        return self.sensor.conversion_gain_uV_per_e * 1e-6 * (1.0 + a.gain_error) / self.lsb_V

    @property
    def reset_level_dn(self) -> float:
        """Nominal code of the reset level (pedestal, ADC offset and gain error). Unit: DN."""
        a, px = self.scenario.chip.adc, self.scenario.chip.pixel
        return (px.pedestal_V - a.v_min_V) / self.lsb_V * (1.0 + a.gain_error) + a.offset_error_lsb

    @property
    def saturation_e(self) -> float:
        """Nominal saturation: the full well, or the charge that takes the signal samples to the
        ADC's top code if that comes first. Unit: e⁻."""
        top = 2.0**self.camera.adc_bits - 1.0
        adc_e = (top + 0.5 - self.reset_level_dn) / self.gain_dn_per_e
        return float(min(self.sensor.full_well_e, adc_e))

    def sensor_at(self, temperature_C: float) -> SensorModel:
        """This chip (same fixed pattern) at another temperature."""
        return self._chip_sensor(at_temperature(self.scenario, temperature_C))

    # --- acquisition ---
    def expected_e(self, sensor: SensorModel, photons_per_diode: float, t_s: float,
                   tiles: int) -> NDArray[np.float64]:
        """Expected charge of every pixel of a mosaic of ``tiles`` frames. Unit: e⁻.

        ``photons_per_diode`` is the light on each photodiode in the exposure; dark charge is
        the pixel's dark current × ``t_s`` (DSNU map included).
        """
        gain = np.tile(sensor.gain_map, tiles)
        dark = np.tile(sensor.dark_e_per_s, tiles) * t_s
        return pixel.mean_electrons(np.full(gain.shape, photons_per_diode), sensor.qe, gain, dark)

    def read(self, rng: np.random.Generator, sensor: SensorModel,
             frames: Iterable[NDArray[np.float64]], n_frames: int,
             progress: Progress | None = None, shot_noise: str = "poisson"
             ) -> Iterator[tuple[NDArray[np.float64], float]]:
        """Read frames of expected charge: the CMS image (DN) and the mean reset code (DN).

        Parameters
        ----------
        rng : numpy.random.Generator
            The series' stream (seeds the chain's per-chunk streams).
        sensor : SensorModel
            The chip at the series' temperature.
        frames : iterable of ndarray
            Expected charge per pixel of each frame (:meth:`expected_e`), all one shape.
        n_frames : int
            How many (for progress).
        shot_noise : {"poisson", "gaussian"}
            ``"gaussian"``: every count drawn as ``rint(λ + √λ·z)``, one normal a count whatever
            its mean, so the draws move continuously with the light (a fit's common random
            numbers); the Poisson mean and variance, +1/12 e⁻² of rounding. Default: exact
            Poisson below :data:`chiptwin.pixel.chain.GAUSSIAN_MIN_MEAN_E`.
        """
        a = self.scenario.chip.adc
        frames = iter(frames)
        first = next(frames)
        # the chip's converters as built (comparator noise, mismatch, INL/DNL), each pixel's own
        # under every tile of the mosaic: the bench once read through an ideal ADC, so none of
        # them reached the datasheet
        conv = sensor.converter.at(np.arange(first.size) % sensor.converter.n_pixels)
        chain = pixel.sensor_chain(
            rng, itertools.chain([first], frames), qe=1.0, dark_e=0.0,
            full_well_e=sensor.full_well_e, read_noise_e=sensor.read_noise_e,
            conversion_gain_uV_per_e=sensor.conversion_gain_uV_per_e, ktc_e=sensor.ktc_e,
            true_cds=sensor.true_cds, n_samples=sensor.cms_samples, read_reset=True,
            pedestal_V=sensor.pedestal_V, converter=conv, shot_noise=shot_noise,
            **({"gaussian_min_mean_e": SMOOTH_MIN_MEAN_E} if shot_noise == "gaussian" else {}))
        top = 2**a.bits - 1
        for done, (reset, signal) in enumerate(chain, start=1):
            self.clipped += int(np.count_nonzero((reset == 0) | (reset == top)))
            self.clipped += int(np.count_nonzero((signal == 0) | (signal == top)))
            image = self.cms(reset, signal), float(reset.mean())
            if progress is not None:
                progress(done, n_frames)
            yield image

    def cms(self, reset: np.ndarray, signal: np.ndarray) -> NDArray[np.float64]:
        """The DSP's CMS of one frame at the scenario's level. Unit: DN (ADC LSB).

        ``reset``, ``signal``: ``(M, n)`` codes. Float: ``mean(signal) − mean(reset)``; fixed and
        rtl: the bit-accurate CMS register (:func:`chiptwin.dsp.frame_ops.cms_fixed`), read as a
        number.
        """
        if self.cms_cfg is None:
            return reference.correlated_multiple_sampling(reset, signal)
        out = cms_fixed(reset, signal, self.cms_cfg)
        return self.cms_cfg.out_fmt.to_float(out.codes)
