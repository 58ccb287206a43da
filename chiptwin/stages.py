"""Thin adapters: unpack a :class:`Scenario` into the pure functions of each stage.

The physics lives in the stage packages as array functions with explicit arguments; this module is
the only place that knows both the scenario's field names and those functions' signatures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from chiptwin import kinetics, optics, pixel
from chiptwin.config import Scenario
from chiptwin.kinetics import pyro
from chiptwin.kinetics.pulse_train import PulseTrain

FMOL, AMOL = 1e-15, 1e-18
ZERO_C_K = 273.15


def site_pixels(s: Scenario) -> np.ndarray:
    """(n_sites, 2) array of the [row, col] each site sits above."""
    at = s.sites.at_pixels
    if at == "all":
        return np.array([[r, c] for r in range(s.chip.rows) for c in range(s.chip.cols)])
    if at == "centre":
        return np.array([[s.chip.rows // 2, s.chip.cols // 2]])
    return np.array(at, dtype=np.int64).reshape(-1, 2)


def flow_program(s: Scenario) -> tuple[list[str], np.ndarray]:
    """Nucleotide and incorporations of each flow (pyrosequencing only)."""
    a = s.assay
    return pyro.flow_incorporations(a.template, a.flow_order, a.n_flows)


def light_source(s: Scenario) -> PulseTrain:
    """The closed-form light of every site (Salama et al. 2004, eqs. 12, 13, 19). Unit: photons/s.

    The ``flux`` kind gives light at the sensor plane instead: photons/s on the diode under each
    site (flux × diode area), with :func:`coupling` passing it straight through.
    """
    a, n = s.assay, len(site_pixels(s))
    if a.kind == "pyrosequencing":
        _, n_inc = flow_program(s)
        return kinetics.pyrosequencing(
            np.full(n, a.dna_fmol * FMOL), n_inc, a.flow_period_s, start_s=a.start_s,
            turnover_per_s=a.k_t_per_s, apyrase_per_s=a.k_a_per_s, alpha=a.quantum_yield,
            photons_per_incorporation=a.photons_per_incorporation or None,
        )
    if a.kind == "atp":
        return kinetics.atp_assay(np.full(n, a.atp_fmol * FMOL), a.start_s,
                                  turnover_per_s=a.turnover_per_s, alpha=a.quantum_yield)
    if a.kind == "luciferase_label":
        return kinetics.luciferase_label(np.full(n, a.luciferase_amol * AMOL), a.start_s,
                                         turnover_per_s=a.turnover_per_s, alpha=a.quantum_yield)
    area = s.chip.pixel.diode_w_um * s.chip.pixel.diode_h_um
    return PulseTrain(site=np.arange(n), onset_s=np.full(n, a.start_s),
                      amplitude_per_s=np.full(n, a.photons_per_s_per_um2 * area),
                      decay_per_s=np.zeros(n), n_sites=n)


def coupling(s: Scenario) -> np.ndarray:
    """(n_pixels, n_sites): the share of each site's emitted photons on each pixel's diode."""
    rc = site_pixels(s)
    chip, px, o = s.chip, s.chip.pixel, s.optics
    under = np.zeros((chip.n_pixels, len(rc)))
    under[rc[:, 0] * chip.cols + rc[:, 1], np.arange(len(rc))] = 1.0
    if s.assay.kind == "flux":
        return under
    if o.coupling == "lens":
        eff = optics.collection_efficiency(o.aperture_diameter_um, o.object_distance_um,
                                           convention=o.convention)
        return under * eff * o.transmission
    grid = dict(n_rows=chip.rows, n_cols=chip.cols, pitch_um=chip.pitch_um,
                diode_w_um=px.diode_w_um, diode_h_um=px.diode_h_um,
                site_x_um=(rc[:, 1] + 0.5) * chip.pitch_um,
                site_y_um=(rc[:, 0] + 0.5) * chip.pitch_um,
                height_um=s.sites.height_um, convention=o.convention)
    if s.run.fidelity.optics == "na2":
        c = optics.coupling_na2(**grid)
    else:
        c = optics.coupling_psf(**grid, site_radius_um=s.sites.footprint_radius_um)
    return c * o.transmission


@dataclass(frozen=True)
class SensorModel:
    """Per-pixel constants of the sensor, resolved once per run (fixed pattern drawn here)."""

    qe: float
    gain_map: np.ndarray
    dark_e_per_s: np.ndarray
    full_well_e: float
    ktc_e: float
    read_noise_e: float
    cms_samples: int
    true_cds: bool
    conversion_gain_uV_per_e: float
    pedestal_V: float
    lsb_V: float
    e_per_lsb: float


def sensor_model(s: Scenario, rng: np.random.Generator) -> SensorModel:
    """Resolve the pixel and ADC parameters; draws the PRNU and DSNU maps from ``rng``."""
    px, adc = s.chip.pixel, s.chip.adc
    gain_map, dark_map = pixel.fixed_pattern_maps(rng, s.chip.n_pixels, px.prnu_frac, px.dsnu_frac)
    dark = pixel.dark_current_e_per_s(px.dark_current_nA_per_cm2, px.diode_w_um * px.diode_h_um,
                                      px.temperature_C, px.ref_temp_C, px.dark_doubling_C)
    cg = pixel.conversion_gain_uV_per_e(px.capacitance_fF)
    lsb = pixel.lsb_V(adc.bits, adc.v_min_V, adc.v_max_V)
    return SensorModel(
        qe=px.qe, gain_map=gain_map, dark_e_per_s=dark * dark_map, full_well_e=px.full_well_e,
        ktc_e=pixel.ktc_noise_e(px.capacitance_fF, px.temperature_C + ZERO_C_K),
        read_noise_e=px.read_noise_e, cms_samples=s.chip.dsp.cms_samples, true_cds=px.true_cds,
        conversion_gain_uV_per_e=cg, pedestal_V=px.pedestal_V, lsb_V=lsb,
        e_per_lsb=lsb / (cg * 1e-6),
    )
