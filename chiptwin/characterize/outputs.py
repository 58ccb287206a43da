"""A datasheet's outputs: ``emva1288.json``, ``datasheet.md`` and the plots, written atomically.

Everything goes into a fresh temporary folder beside the target, renamed into place at the end:
a crashed or refused characterisation never leaves a half-written folder that looks complete, and
only a folder that is new, empty or a previous characterisation (it holds ``emva1288.json``) is
replaced (:func:`chiptwin.config.outputs.check_out_dir`).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from chiptwin.characterize.datasheet import PARAMETERS, Datasheet

JSON_NAME = "emva1288.json"
STANDARD = "EMVA 1288 Release 4.0 Linear"

#: The summary datasheet's sections and their figures (keys of PARAMETERS).
SECTIONS: dict[str, tuple[str, ...]] = {
    "Sensitivity and temporal noise": (
        "quantum_efficiency", "system_gain", "inverse_system_gain", "responsivity",
        "temporal_dark_noise", "temporal_dark_noise_dn", "saturation_irradiation",
        "saturation_capacity", "snr_max", "snr_max_db", "snr_max_bits",
        "absolute_sensitivity_threshold", "absolute_sensitivity_threshold_area",
        "absolute_sensitivity_threshold_e", "dynamic_range", "dynamic_range_db",
        "dynamic_range_bits"),
    "Dark current": ("dark_current", "dark_current_from_variance", "doubling_temperature"),
    "Spatial nonuniformity": ("dsnu", "dsnu_dn", "dsnu_col", "dsnu_row", "dsnu_pixel", "prnu",
                              "prnu_col", "prnu_row", "prnu_pixel"),
    "Linearity": ("linearity_error", "linearity_error_min", "linearity_error_max"),
    "Offsets": ("dark_offset", "reset_level"),
}


def _num(x: Any) -> Any:
    """A JSON-safe number: finite floats, None for NaN/inf and for None."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def to_json(d: Datasheet, meta: dict[str, Any]) -> dict[str, Any]:
    """The ``emva1288.json`` document: every parameter with its unit, error and scenario value."""
    params = {}
    for key, (name, symbol, unit) in PARAMETERS.items():
        f = d.figures[key]
        scen, src = d.scenario_values.get(key, (None, ""))
        entry = {"name": name, "symbol": symbol, "unit": unit, "value": _num(f.value),
                 "std_error": _num(f.std_error), "upper_limit": f.upper_limit,
                 "resolution": _num(f.resolution), "scenario_value": _num(scen),
                 "scenario_source": src or None, "note": f.note or None}
        if d.input_values:
            entry["input_value"] = _num(d.input_values.get(key))
        params[key] = entry
    cam = dataclasses.asdict(d.camera)
    if meta.get("measured"):  # a camera's data set: its own digital numbers, one output sample
        cam.update(pixel_area_um2=d.camera.pixel_area_um2, cms_samples=1,
                   dn="the camera's digital number, as its images hold it")
    else:
        cam.update(pixel_area_um2=d.camera.pixel_area_um2, fill_factor=d.camera.fill_factor,
                   dn="one ADC LSB; the frame is the CMS difference mean(signal codes) − "
                      "mean(reset codes) before dark subtraction and averaging")
    return {"standard": STANDARD, **meta, "camera": cam, "conditions": d.conditions,
            "flags": d.flags, "notes": d.notes, "parameters": params,
            "fit_ranges": d.fit_ranges,
            "data": {k: [_num(v) for v in np.asarray(a).ravel()] for k, a in d.curves.items()}}


def _cell(value: float | None) -> str:
    return "—" if value is None else f"{value:.4g}"


def markdown(d: Datasheet, meta: dict[str, Any], plots: list[tuple[str, str]]) -> str:
    """``datasheet.md`` in the layout of the standard's summary datasheet: the device and its
    operating point, then the figures by section, then the plots and the notes."""
    lines = [f"# EMVA 1288 datasheet: {meta['scenario']}", ""]
    if meta.get("measured"):
        lines += [f"{STANDARD}, evaluated by chiptwin {meta['chiptwin_version']} from the "
                  f"measured data set {meta['source']} ({meta['wall_time_s']:.2f} s).", ""]
    else:
        lines += [f"{STANDARD}, measured on the chiptwin model (chiptwin "
                  f"{meta['chiptwin_version']}, seed {meta['seed']}, "
                  f"{meta['wall_time_s']:.2f} s).", ""]
    if d.flags["quantisation_regime"]:
        lines += [f"> **{d.notes[0]}**", ""]
    lines += _measured_device(d) if meta.get("measured") else _device(d)
    lines += _figure_tables(d)
    if meta.get("twin"):
        lines += [f"## The twin of this camera ({meta['twin']['scenario']})", "",
                  "The scenario written from this datasheet, read through the data set's own "
                  "protocol (its exposures and photon levels), seed "
                  f"{meta['twin']['seed']}: its figures are the scenario column above; each "
                  "curve's largest residual in standard errors:", ""]
        lines += [f"- {line}" for line in meta["twin"]["findings"]] + [""]
    lines += ["## Plots", ""] + [f"![{cap}]({name})\n\n*{cap}*\n" for name, cap in plots]
    lines += ["## Notes", ""] + [f"- {n}" for n in d.notes] + [""]
    return "\n".join(lines)


def _measured_device(d: Datasheet) -> list[str]:
    """The device section of a camera's data set: what the data set states."""
    cam, cond = d.camera, d.conditions
    pitch = "not stated" if cam.pixel_pitch_um is None else f"{cam.pixel_pitch_um:g} µm"
    spatial = ("none" if cond["spatial_images"] is None else
               f"{cond['spatial_images']} bright + {cond['spatial_images']} dark images at "
               f"{cond['spatial_exposure_s']:.4g} s ({cond['spatial_mu_p_photons']:.4g} "
               "photons/pixel)")
    return ["## Device and operating point", "", "| | |", "|---|---|",
            f"| Sensor | {cam.cols} × {cam.rows} pixels, pitch {pitch}; {cam.adc_bits}-bit "
            f"images |",
            f"| Data set | {cam.descriptor}, EMVA 1288 release {cam.release} |",
            f"| Photon transfer | {cond['ptc_points']} points, exposure "
            f"{cond['ptc_exposure_s'][0]:.4g} … {cond['ptc_exposure_s'][1]:.4g} s, "
            f"{cond['ptc_mu_p_photons'][0]:.4g} … {cond['ptc_mu_p_photons'][1]:.4g} "
            f"photons/pixel, 2 bright + 2 dark images each |",
            f"| Spatial | {spatial} |",
            f"| Clipped values | {cond['clipped_values']} (at 0 or full scale) |", ""]


def _device(d: Datasheet) -> list[str]:
    """The device section of the twin's chip on its bench."""
    cam, cond = d.camera, d.conditions
    return ["## Device and operating point", "", "| | |", "|---|---|",
              f"| Sensor | {cam.rows} × {cam.cols} pixels, pitch {cam.pixel_pitch_um:g} µm, "
              f"photodiode {cam.diode_area_um2:g} µm² (fill factor {100 * cam.fill_factor:.3g} "
              "%) |",
              f"| Readout | per-pixel {cam.adc_bits}-bit ADC over {cam.adc_v_min_V:g}–"
              f"{cam.adc_v_max_V:g} V; CMS of M = {cam.cms_samples} ({cam.dsp_level} DSP); "
              f"{'true' if cam.true_cds else 'no true'} CDS |",
              f"| Light | {cond['wavelength_nm']:g} nm, "
              f"{cond['irradiance_photons_per_s_per_um2']:.4g} photons/s/µm² "
              f"({cond['irradiance_W_per_m2']:.3g} W/m²) at the sensor plane |",
              f"| Temperature | {cond['temperature_C']:g} °C; dark-current series "
              f"{cond['temperature_series_C'][0]:g} … {cond['temperature_series_C'][-1]:g} °C |",
              f"| Photon transfer | {cond['ptc_points']} exposure times "
              f"{cond['ptc_exposure_s'][0]:.4g} … {cond['ptc_exposure_s'][1]:.4g} s, 2 bright + "
              f"2 dark images each ({cond['ptc_values_per_image']} values per image) |",
              f"| Spatial | {cond['spatial_images']} bright + {cond['spatial_images']} dark "
              f"images at {cond['spatial_exposure_s']:.4g} s (50 % of saturation) |", ""]


def _figure_tables(d: Datasheet) -> list[str]:
    """The figures by section; a scenario column when a scenario sets the chip, an input column
    when a datasheet configured it."""
    label = "twin" if d.overlay else "scenario"
    cols = [(label, d.scenario_values)] if d.scenario_values else []
    if d.input_values:
        cols.append(("input", d.input_values))
    out = []
    for section, keys in SECTIONS.items():
        out += [f"## {section}", "",
                "| quantity | symbol | value | unit | ± 1σ |" + "".join(f" {c} |" for c, _ in cols),
                "|---|---|---|---|---|" + "---|" * len(cols)]
        for key in keys:
            name, symbol, unit = PARAMETERS[key]
            f = d.figures[key]
            value = ("≤ " if f.upper_limit else "") + _cell(f.value)
            if f.value is None and f.note:
                value = "not resolved"
            elif f.note.startswith("not significant"):
                value += " (within 2σ of 0)"
            row = f"| {name} | {symbol} | {value} | {unit} | {_cell(f.std_error)} |"
            for c, values in cols:
                v = values.get(key)
                row += f" {_cell(v[0] if c == label and v is not None else v)} |"
            out.append(row)
        out.append("")
    return out


def write_outputs(d: Datasheet, meta: dict[str, Any], out_dir: str | Path) -> Path:
    """Write ``emva1288.json``, ``datasheet.md`` and the plots into ``out_dir``, whole or not at
    all, replacing a previous characterisation there."""
    from chiptwin.characterize.plots import make_plots
    from chiptwin.config.outputs import check_out_dir, replacing

    out = check_out_dir(out_dir, marker=JSON_NAME)
    with replacing(out) as tmp:
        plots = make_plots(d, tmp)
        (tmp / "datasheet.md").write_text(markdown(d, meta, plots))
        (tmp / JSON_NAME).write_text(json.dumps(to_json(d, meta), indent=2,
                                                ensure_ascii=False) + "\n")
    return out


#: The figures printed on the terminal, in order.
HEADLINE = ("quantum_efficiency", "system_gain", "temporal_dark_noise", "temporal_dark_noise_dn",
            "saturation_capacity", "snr_max_db", "absolute_sensitivity_threshold",
            "dynamic_range_db", "dark_current", "doubling_temperature", "dsnu", "prnu",
            "linearity_error")


def headline(d: Datasheet) -> list[str]:
    """Terminal lines: the key figures, and the quantisation regime when it holds."""
    lines = []
    for key in HEADLINE:
        name, symbol, unit = PARAMETERS[key]
        f = d.figures[key]
        value = "not resolved" if f.value is None else (
            ("≤ " if f.upper_limit else "") + f"{f.value:.4g} {unit}")
        err = f" ± {f.std_error:.2g}" if f.std_error is not None and f.value is not None else ""
        lines.append(f"  {symbol:12s} {value}{err}   ({name})")
    if d.flags["quantisation_regime"]:
        lines.append("  " + d.notes[0])
    return lines
