"""The datasheet: every EMVA 1288 figure of the measured chip with its unit, its standard error,
and the value the scenario's parameters imply, assembled from the evaluation
(:mod:`chiptwin.characterize.evaluate`) of a :class:`~chiptwin.characterize.measure.Measurement`.

The figures and their order follow the standard's summary datasheet (EMVA 1288 Release 4.0
Linear): sensitivity and noise (η, K, σ_d, SNR_max, μ_p.min, DR), dark current
(μ_I, T_d), nonuniformity (DSNU₁₂₈₈, PRNU₁₂₈₈), linearity (LE).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from chiptwin import pixel
from chiptwin.characterize import evaluate as ev
from chiptwin.characterize.bench import Bench, Camera
from chiptwin.characterize.evaluate import Figure
from chiptwin.characterize.measure import Measurement
from chiptwin.config import Scenario

#: key → (name, symbol, unit), in the summary datasheet's order.
PARAMETERS: dict[str, tuple[str, str, str]] = {
    "quantum_efficiency": ("Quantum efficiency (pixel area, fill factor included)", "η", "%"),
    "system_gain": ("System gain", "K", "DN/e⁻"),
    "inverse_system_gain": ("Inverse system gain", "1/K", "e⁻/DN"),
    "responsivity": ("Responsivity", "R", "DN/photon"),
    "temporal_dark_noise": ("Temporal dark noise", "σ_d", "e⁻"),
    "temporal_dark_noise_dn": ("Temporal dark noise", "σ_y.dark", "DN"),
    "saturation_irradiation": ("Saturation irradiation", "μ_p.sat", "photons/pixel"),
    "saturation_capacity": ("Saturation capacity", "μ_e.sat", "e⁻"),
    "snr_max": ("Maximum SNR", "SNR_max", "1"),
    "snr_max_db": ("Maximum SNR", "SNR_max", "dB"),
    "snr_max_bits": ("Maximum SNR", "SNR_max", "bit"),
    "absolute_sensitivity_threshold": ("Absolute sensitivity threshold", "μ_p.min",
                                       "photons/pixel"),
    "absolute_sensitivity_threshold_area": ("Absolute sensitivity threshold per area",
                                            "μ_p.min.area", "photons/µm²"),
    "absolute_sensitivity_threshold_e": ("Absolute sensitivity threshold", "μ_e.min", "e⁻"),
    "dynamic_range": ("Dynamic range", "DR", "1"),
    "dynamic_range_db": ("Dynamic range", "DR", "dB"),
    "dynamic_range_bits": ("Dynamic range", "DR", "bit"),
    "dark_current": ("Dark current (from the mean)", "μ_I", "e⁻/s"),
    "dark_current_from_variance": ("Dark current (from the variance)", "μ_I.var", "e⁻/s"),
    "doubling_temperature": ("Dark current doubling temperature", "T_d", "°C"),
    "dsnu": ("Dark signal nonuniformity", "DSNU₁₂₈₈", "e⁻"),
    "dsnu_dn": ("Dark signal nonuniformity", "DSNU₁₂₈₈", "DN"),
    "dsnu_col": ("DSNU, column part", "DSNU₁₂₈₈.col", "e⁻"),
    "dsnu_row": ("DSNU, row part", "DSNU₁₂₈₈.row", "e⁻"),
    "dsnu_pixel": ("DSNU, pixel part", "DSNU₁₂₈₈.pixel", "e⁻"),
    "prnu": ("Photo-response nonuniformity", "PRNU₁₂₈₈", "%"),
    "prnu_col": ("PRNU, column part", "PRNU₁₂₈₈.col", "%"),
    "prnu_row": ("PRNU, row part", "PRNU₁₂₈₈.row", "%"),
    "prnu_pixel": ("PRNU, pixel part", "PRNU₁₂₈₈.pixel", "%"),
    "linearity_error": ("Linearity error", "LE", "%"),
    "linearity_error_min": ("Linearity error, most negative deviation", "LE_min", "%"),
    "linearity_error_max": ("Linearity error, most positive deviation", "LE_max", "%"),
    "dark_offset": ("Dark offset (zero exposure)", "μ_y.dark", "DN"),
    "reset_level": ("Reset level (raw reset samples, dark)", "y_reset", "DN"),
}


@dataclass
class Datasheet:
    """A chip's EMVA 1288 datasheet.

    Attributes
    ----------
    camera : Camera
    figures : dict of Figure, keyed as :data:`PARAMETERS`
    scenario_values : dict key → (value, what in the scenario it comes from)
    flags : dict of bool
    notes : list of str
    conditions : dict  the measurement conditions (exposures, irradiance, temperatures, …)
    fit_ranges : dict
    curves : dict of ndarray  the plotted series
    measurement : Measurement
    """

    camera: Camera
    figures: dict[str, Figure]
    scenario_values: dict[str, tuple[float | None, str]]
    flags: dict[str, bool]
    notes: list[str]
    conditions: dict[str, Any]
    fit_ranges: dict[str, Any]
    curves: dict[str, np.ndarray]
    measurement: Measurement = field(repr=False)
    input_values: dict[str, float | None] = field(default_factory=dict)
    #: A measured camera's curves beside its twin's (:mod:`chiptwin.characterize.overlay`).
    overlay: list | None = None


#: Why a figure is missing, by the first word of its key: the series behind it is not in the data.
_UNMEASURED = {"dark": "one exposure time: the dark current needs the exposure varied",
               "dsnu": "the data set has no spatial stacks",
               "prnu": "the data set has no spatial stacks",
               "reset": "a camera's output carries no raw reset samples"}


@dataclass(frozen=True)
class Evaluation:
    """The standard's figures of a measurement, the twin's or a camera's, before any scenario is
    set beside them: the figures (every key of :data:`PARAMETERS`; ``Figure(None, note=…)`` where
    the data cannot give one), the flags, and what the curves and fit ranges are drawn from."""

    figures: dict[str, Figure]
    flags: dict[str, bool]
    linearity: ev.Linearity
    i_sat: int
    gain: float
    qe: float
    sigma_y: Figure
    sigma_d: Figure


def evaluate_measurement(m: Measurement) -> Evaluation:
    """Every figure of the standard from a measurement's series (EMVA 1288 Release 4.0 Linear).

    A series the measurement does not have (a camera's data set has no temperature series, and
    may have no spatial stacks) leaves its figures unresolved with the reason in their note.
    """
    t = m.temporal
    i_sat = ev.saturation_index(t)
    gain, gain_se = ev.system_gain(t, i_sat)
    resp, resp_se = ev.responsivity(t, i_sat)
    qe, rel_qe = _qe(gain, gain_se, resp, resp_se)
    var0 = ev.dark_variance(t)
    sigma_y, sigma_d = ev.temporal_dark_noise(var0, gain, gain_se)
    f: dict[str, Figure] = {
        "quantum_efficiency": Figure(100 * qe, 100 * qe * rel_qe),
        "system_gain": Figure(gain, gain_se),
        "inverse_system_gain": Figure(1 / gain, gain_se / gain**2),
        "responsivity": Figure(resp, resp_se),
        "temporal_dark_noise": sigma_d,
        "temporal_dark_noise_dn": sigma_y,
    }
    f.update(_saturation_figures(m, i_sat, sigma_y, gain, gain_se, resp, resp_se))
    if np.unique(t.t_exp_s).size >= 2:
        f["dark_current"], f["dark_current_from_variance"] = ev.dark_current(t, gain, gain_se)
    f["doubling_temperature"] = (
        ev.doubling_temperature(m.temperature, gain) if m.temperature is not None
        else Figure(None, note="the data set has no dark series at several temperatures"))
    if m.spatial is not None:
        f.update(ev.nonuniformity(m.spatial, gain, gain_se))
    lin = ev.linearity(t, i_sat)
    f["linearity_error"] = Figure(lin.le)
    f["linearity_error_min"], f["linearity_error_max"] = Figure(lin.le_min), Figure(lin.le_max)
    f["dark_offset"] = ev.dark_offset(t)
    if np.isfinite(t.reset_level_dn):
        f["reset_level"] = Figure(t.reset_level_dn, t.reset_level_se_dn)
    for key in PARAMETERS:
        if key not in f:
            f[key] = Figure(None, note=_UNMEASURED[key.split("_")[0]])
    flags = {
        "quantisation_regime": bool(sigma_y.value < ev.QUANTISATION_REGIME_DN),
        "saturation_reached": bool(i_sat < len(t.t_exp_s) - 1),
        "sigma_d_upper_limit": sigma_d.upper_limit,
    }
    return Evaluation({k: f[k] for k in PARAMETERS}, flags, lin, i_sat, gain, qe, sigma_y,
                      sigma_d)


def build_datasheet(m: Measurement, s: Scenario) -> Datasheet:
    """Evaluate the twin's measurement into the datasheet (and the scenario's own values
    beside it)."""
    e = evaluate_measurement(m)
    bench = Bench(s)
    return Datasheet(
        camera=m.camera, figures=e.figures, scenario_values=scenario_values(s, bench, m),
        flags=e.flags, notes=_notes(m, bench, e.flags, e.sigma_y, e.gain),
        conditions=_conditions(m), fit_ranges=fit_ranges(m.temporal, e.i_sat, e.linearity),
        curves=curves(m, e), measurement=m)


def _qe(gain: float, gain_se: float, resp: float, resp_se: float) -> tuple[float, float]:
    """η = R/K and its relative standard error."""
    return resp / gain, float(np.hypot(resp_se / resp, gain_se / gain))


def _saturation_figures(m: Measurement, i_sat: int, sigma_y: Figure, gain: float,
                        gain_se: float, resp: float, resp_se: float) -> dict[str, Figure]:
    """μ_p.sat, μ_e.sat, SNR_max, μ_p.min, μ_e.min and DR, with errors and grid resolution, from
    the system gain K and the responsivity R (η = R/K) with their standard errors."""
    qe, rel_qe = _qe(gain, gain_se, resp, resp_se)
    t, area = m.temporal, m.camera.pixel_area_um2
    # the grid's step at saturation (a camera's data set need not be equally spaced)
    step = float(np.diff(t.mu_p)[max(i_sat - 1, 0)])
    p_sat = float(t.mu_p[i_sat])
    e_sat = qe * p_sat
    p_min = ev.sensitivity_threshold(qe, sigma_y.value, gain)
    # μ_p.min = (√(u² + 1/4) + 1/2)/η with u = σ_y.dark/K (e⁻); u's error unless floored.
    s_y = max(sigma_y.value, np.sqrt(ev.QUANTISATION_FLOOR_DN2))
    u = s_y / gain
    floored = sigma_y.value ** 2 < ev.QUANTISATION_FLOOR_DN2
    rel_u = gain_se / gain if floored else np.hypot((sigma_y.std_error or 0) / s_y, gain_se / gain)
    du = u / np.sqrt(u * u + 0.25) * u * rel_u  # error of η·μ_p.min from u
    # μ_p.min = (√(σ_y² + K²/4) + K/2)/R: K's error nearly cancels (η = R/K and u = σ_y/K both
    # carry it; counting it in each stated σ 9× its Monte Carlo spread), so each input's own term
    root = np.sqrt(s_y * s_y + gain * gain / 4)
    s_y_se = 0.0 if floored else (sigma_y.std_error or 0.0)
    p_min_se = float(np.sqrt((s_y / root * s_y_se) ** 2 + ((gain / (4 * root) + 0.5) * gain_se)
                             ** 2 + (p_min * resp_se) ** 2) / resp)
    dr, rel_dr = p_sat / p_min, p_min_se / p_min
    snr, db = float(np.sqrt(e_sat)), 20.0 / np.log(10.0)
    return {
        "saturation_irradiation": Figure(p_sat, None, resolution=step),
        "saturation_capacity": Figure(e_sat, e_sat * rel_qe, resolution=qe * step),
        "snr_max": Figure(snr, snr * rel_qe / 2),
        "snr_max_db": Figure(20 * np.log10(snr), db * rel_qe / 2),
        "snr_max_bits": Figure(float(np.log2(snr)), rel_qe / 2 / np.log(2.0)),
        "absolute_sensitivity_threshold": Figure(p_min, p_min_se),
        "absolute_sensitivity_threshold_area": (
            Figure(p_min / area, p_min_se / area) if area is not None
            else Figure(None, note="needs the pixel's size, which the data set does not give")),
        "absolute_sensitivity_threshold_e": Figure(qe * p_min, float(du)),
        "dynamic_range": Figure(dr, dr * rel_dr, resolution=step / p_min),
        "dynamic_range_db": Figure(20 * np.log10(dr), db * rel_dr),
        "dynamic_range_bits": Figure(float(np.log2(dr)), rel_dr / np.log(2.0)),
    }


def scenario_values(s: Scenario, bench: Bench, m: Measurement
                    ) -> dict[str, tuple[float | None, str]]:
    """What the scenario's parameters say each figure is: the ideal linear camera with the twin's
    QE, gain, noise, dark current and nonuniformity (None where no parameter sets it)."""
    px, cam = s.chip.pixel, m.camera
    sensor = bench.sensor
    gain = bench.gain_dn_per_e
    qe = px.qe * cam.fill_factor
    m_cms = sensor.cms_samples
    sigma_d = float(np.sqrt(2 * sensor.read_noise_e**2 / m_cms
                            + (0.0 if sensor.true_cds else 2 * sensor.ktc_e**2)))
    quant = 2 * pixel.quantization_var_of_mean(m_cms, sensor.read_noise_e * gain)
    sigma_y = float(np.sqrt((gain * sigma_d) ** 2 + quant))
    dark = pixel.dark_current_e_per_s(px.dark_current_nA_per_cm2, cam.diode_area_um2,
                                      px.temperature_C, px.ref_temp_C, px.dark_doubling_C)
    e_sat = _photo_electrons_at_saturation(bench, m, dark)
    p_sat = e_sat / qe
    p_min = ev.sensitivity_threshold(qe, sigma_y, gain)
    dr = p_sat / p_min
    dsnu = px.dsnu_frac * dark * m.spatial.t_exp_s
    qe_src, noise_src = "chip.pixel.qe × fill factor", "chip.pixel.read_noise_e, cms_samples"
    sat_src = "chip.pixel.full_well_e or ADC range, less the dark charge"
    return {
        "quantum_efficiency": (100 * qe, qe_src),
        "system_gain": (gain, "chip.pixel.capacitance_fF, chip.adc"),
        "inverse_system_gain": (1 / gain, "chip.pixel.capacitance_fF, chip.adc"),
        "responsivity": (gain * qe, "K × η"),
        "temporal_dark_noise": (sigma_d, noise_src),
        "temporal_dark_noise_dn": (sigma_y, noise_src + ", 2M conversions' rounding"),
        "saturation_irradiation": (p_sat, sat_src + ", dark charge"),
        "saturation_capacity": (e_sat, sat_src),
        "snr_max": (float(np.sqrt(e_sat)), sat_src),
        "snr_max_db": (float(10 * np.log10(e_sat)), sat_src),
        "snr_max_bits": (float(np.log2(e_sat) / 2), sat_src),
        "absolute_sensitivity_threshold": (p_min, noise_src + ", qe"),
        "absolute_sensitivity_threshold_area": (p_min / cam.pixel_area_um2, noise_src + ", qe"),
        "absolute_sensitivity_threshold_e": (qe * p_min, noise_src),
        "dynamic_range": (dr, sat_src + ", noise"),
        "dynamic_range_db": (float(20 * np.log10(dr)), sat_src + ", noise"),
        "dynamic_range_bits": (float(np.log2(dr)), sat_src + ", noise"),
        "dark_current": (dark, "chip.pixel.dark_current_nA_per_cm2 at temperature_C"),
        "dark_current_from_variance": (dark, "chip.pixel.dark_current_nA_per_cm2"),
        "doubling_temperature": (px.dark_doubling_C, "chip.pixel.dark_doubling_C"),
        "dsnu": (dsnu, "chip.pixel.dsnu_frac × dark current × spatial exposure"),
        "dsnu_dn": (dsnu * gain, "chip.pixel.dsnu_frac"),
        "prnu": (100 * px.prnu_frac, "chip.pixel.prnu_frac"),
        "dark_offset": (0.0, "CMS removes the reset level"),
        "reset_level": (bench.reset_level_dn, "chip.pixel.pedestal_V, chip.adc offset/gain"),
    }


def _photo_electrons_at_saturation(bench: Bench, m: Measurement, dark_e_per_s: float) -> float:
    """The nominal μ_e.sat: photo-electrons of the mean pixel when photo plus dark charge reach
    the nominal saturation under the bench's light (the standard counts photo-electrons,
    ``η·μ_p.sat``; the well also holds the dark charge of that exposure). Unit: e⁻."""
    photo_rate = (m.temporal.irradiance_photons_per_s_per_um2 * m.camera.diode_area_um2
                  * bench.sensor.qe)
    return bench.saturation_e * photo_rate / (photo_rate + dark_e_per_s)


def regime_notes(flags: dict[str, bool], sigma_y: Figure, why: str = "",
                 remedy: str = "") -> list[str]:
    """The notes every datasheet leads with when they hold: the quantisation regime (the
    chip's own ``why`` and ``remedy`` around the standard's statement) and a saturation the
    series does not reach."""
    notes = []
    if flags["quantisation_regime"]:
        notes.append(
            f"QUANTISATION REGIME: the temporal dark noise σ_y.dark = {sigma_y.value:.3g} DN is "
            f"below {ev.QUANTISATION_REGIME_DN} DN; {why}K and σ_d are biased (EMVA 1288 Release "
            f"4.0 Linear).{remedy}")
    if not flags["saturation_reached"]:
        notes.append("The temporal variance has no maximum inside the series: saturation is the "
                     "last point, a lower bound.")
    return notes


def _notes(m: Measurement, bench: Bench, flags: dict[str, bool], sigma_y: Figure,
           gain: float) -> list[str]:
    cam = m.camera
    notes = regime_notes(flags, sigma_y, "the ADC's rounding, not the pixel, sets the noise "
                         "floor, and ", " A finer ADC LSB (more bits over the same range) or "
                         "more gain moves the chip out of it.")
    m_cms = cam.cms_samples
    quant = 2 * pixel.quantization_var_of_mean(m_cms, bench.sensor.read_noise_e * gain)
    notes.append(
        f"DN is one ADC LSB. The chip's frame is the CMS difference of M = {m_cms} signal and "
        f"{m_cms} reset conversions: it carries ≈ {quant:.3g} DN² of rounding (the 2M "
        "conversions' rounding errors, correlated when the read noise is below ≈ 0.5 LSB), not "
        "the standard's single-conversion σ²_q = 1/12 DN², which σ_d subtracts as the standard "
        "prescribes.")
    notes.append(
        f"η is per pixel area (pitch {cam.pixel_pitch_um:g} µm): the photodiode covers "
        f"{100 * cam.fill_factor:.3g} % of it, so η = QE of the diode × {cam.fill_factor:.4g}.")
    if m.tiles > 1:
        notes.append(
            f"Each temporal image is a mosaic of {m.tiles} frames of the {cam.n_pixels}-pixel "
            f"chip ({m.temporal.n_values} values); spatial images are single frames.")
    return notes


def _conditions(m: Measurement) -> dict[str, Any]:
    t, sp, ts, cam = m.temporal, m.spatial, m.temperature, m.camera
    from chiptwin.characterize.bench import photon_energy_J

    irr = t.irradiance_photons_per_s_per_um2
    return {
        "wavelength_nm": cam.wavelength_nm,
        "temperature_C": cam.temperature_C,
        "irradiance_photons_per_s_per_um2": irr,
        "irradiance_W_per_m2": irr * 1e12 * photon_energy_J(cam.wavelength_nm),
        "ptc_points": len(t.t_exp_s),
        "ptc_exposure_s": [float(t.t_exp_s[0]), float(t.t_exp_s[-1])],
        "ptc_frames_per_image": m.tiles,
        "ptc_values_per_image": t.n_values,
        "spatial_exposure_s": sp.t_exp_s,
        "spatial_mu_p_photons": sp.mu_p,
        "spatial_images": sp.n_images,
        "temperature_series_C": [float(x) for x in ts.temperature_C],
        "temperature_series_exposure_s": [float(ts.t_exp_s[0]), float(ts.t_exp_s[-1])],
        "adc_clipped_samples": m.clipped_samples,
    }


def fit_ranges(t, i_sat: int, lin: ev.Linearity) -> dict[str, Any]:
    sens = ev.sensitivity_range(t, i_sat)
    return {
        "saturation_index": i_sat,
        "sensitivity": {"first": 0, "last": sens.stop - 1,
                        "rule": "μ_y − μ_y.dark from the first point to 70 % of saturation"},
        "linearity": {"first": lin.fit_range.start, "last": lin.fit_range.stop - 1,
                      "rule": "5 % … 95 % of saturation, weights 1/y"},
    }


def curves(m: Measurement, e: Evaluation) -> dict[str, np.ndarray]:
    """The plotted series of a measurement and its evaluation."""
    t, qe, sigma_d, gain, lin = m.temporal, e.qe, e.sigma_d, e.gain, e.linearity
    col = t.column
    mu_y, var_y = col("bright", "mean"), col("bright", "var")
    signal = mu_y - col("dark", "mean")
    s2d = sigma_d.value**2 + ev.SIGMA2_Q / gain**2
    mu_i, mu_i_se, temps = np.empty(0), np.empty(0), np.empty(0)
    if m.temperature is not None:
        mu_i, mu_i_se = ev.dark_current_by_temperature(m.temperature, gain)
        temps = m.temperature.temperature_C
    return {
        "t_exp_s": t.t_exp_s, "mu_p": t.mu_p, "mu_y": mu_y, "var_y": var_y,
        "mu_y_dark": col("dark", "mean"), "var_y_dark": col("dark", "var"),
        "snr_measured": signal / np.sqrt(np.maximum(var_y, 1e-300)),
        "snr_model": qe * t.mu_p / np.sqrt(s2d + qe * t.mu_p),
        "snr_ideal": np.sqrt(t.mu_p), "snr_shot_limit": np.sqrt(qe * t.mu_p),
        "linearity_deviation_pct": lin.deviation_pct,
        "linearity_fit": lin.offset + lin.slope * t.mu_p,
        "temperature_C": temps,
        "dark_current_e_per_s": mu_i, "dark_current_se_e_per_s": mu_i_se,
    }
