"""A twin of a measured camera: the ``[chip.pixel]`` and ``[chip.adc]`` of a scenario from a
camera's EMVA 1288 datasheet, each value with its measured standard error, written as TOML.

The values come from the datasheet's inverse through the twin's model
(:func:`chiptwin.config.datasheet.datasheet_values`, the same inverse ``from_datasheet`` uses),
on a chip shaped as the camera: its image size, its pixel pitch with the photodiode filling the
pixel (EMVA's η is per pixel area, so the twin's QE is η), its bit depth over a 1 V range, one
sample per CDS (a camera converts the CDS difference once), and the camera's black level as the
pedestal (its dark offset at zero exposure is the reset code that the CMS frame then removes).
A figure the data set does not resolve (within 2σ of zero, or absent) is not used; the scenario
keeps the twin's default for it and the comment says so.

Standard errors are propagated to each scenario value by perturbing one figure at a time by its
standard error (the figures taken as independent, which they are not quite: K enters η, σ_d and
μ_e.sat; the stated errors are each figure's own share).
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

from chiptwin.characterize.datasheet import Datasheet
from chiptwin.config import Scenario, ScenarioError

#: The converter's range of the camera's twin (choice: the schema's default 0 … 1 V; only the
#: LSB in volts enters, through the capacitance that gives the measured gain). Unit: V.
V_RANGE: tuple[float, float] = (0.0, 1.0)

#: Bits of a frame-memory word of the camera's twin (the schema's default; a camera's 8-16-bit
#: codes fit).
WORD_BITS: int = 16

#: Figures whose standard errors are propagated to the scenario's values.
PROPAGATED = ("quantum_efficiency", "system_gain", "temporal_dark_noise_dn",
              "temporal_dark_noise", "saturation_capacity", "dark_current", "prnu", "dsnu",
              "dark_offset")

#: The scenario keys a camera's datasheet sets, in the order written.
KEYS = ("chip.pixel.qe", "chip.pixel.capacitance_fF", "chip.pixel.read_noise_e",
        "chip.pixel.full_well_e", "chip.pixel.dark_current_nA_per_cm2", "chip.pixel.prnu_frac",
        "chip.pixel.dsnu_frac", "chip.pixel.pedestal_V", "chip.adc.bits")


def camera_doc(d: Datasheet, doc: dict[str, Any]) -> dict[str, Any]:
    """The datasheet document as the inverse reads a camera's: the black level as the reset
    level, no figure the data set does not resolve."""
    out = copy.deepcopy(doc)
    params = out["parameters"]
    for entry in params.values():
        note = entry.get("note") or ""
        if entry.get("value") is None or note.startswith("not significant"):
            entry["value"] = None
    params["reset_level"] = dict(params["dark_offset"])
    out["camera"]["fill_factor"] = None  # the twin's diode fills the pixel: QE = η
    return out


def base_raw(d: Datasheet, name: str) -> dict[str, Any]:
    """The camera as a scenario before the datasheet's values: its shape and protocol."""
    cam, cond = d.camera, d.conditions
    pitch = cam.pixel_pitch_um
    t_max = float(cond["ptc_exposure_s"][1])
    return {
        "scenario": {"name": name, "seed": 1,
                     "description": f"a twin of the camera measured in {cam.descriptor} (EMVA "
                                    f"1288 release {cam.release}): pixel and converter from its "
                                    "datasheet"},
        "assay": {"kind": "flux",
                  "photons_per_s_per_um2": float(cond["irradiance_photons_per_s_per_um2"]),
                  "start_s": 2.0 * t_max},  # after the one dark frame
        "sites": {"at_pixels": "centre"},
        "chip": {"rows": cam.rows, "cols": cam.cols, "pitch_um": pitch,
                 "pixel": {"diode_w_um": pitch, "diode_h_um": pitch, "true_cds": True,
                           "prnu_frac": 0.0, "dsnu_frac": 0.0},
                 "adc": {"bits": cam.adc_bits, "v_min_V": V_RANGE[0], "v_max_V": V_RANGE[1],
                         "range_below_full_well_ok": True},
                 "dsp": {"cms_samples": 1, "n_dark_frames": 1, "average_frames": 1},
                 # the DSP's block of one frame (reset and signal words), the dark reference
                 # and what the default program holds: 16-bit words, 8 an image (choice: the
                 # loader's rule asks for 3 on the default program)
                 "memory": {"capacity_bits": 8 * WORD_BITS * cam.rows * cam.cols},
                 "timing": {"t_int_s": t_max, "frame_period_s": 2.0 * t_max}},
        "run": {"duration_s": 4.0 * t_max},
    }


def scenario_values(d: Datasheet, doc: dict[str, Any], raw: dict[str, Any], source: str
                    ) -> dict[str, tuple[Any, float | None, str]]:
    """Scenario key → (value, standard error or None, the datasheet figure it comes from)."""
    from chiptwin.config.datasheet import DatasheetDoc, datasheet_values
    from chiptwin.config.load import scenario_from_dict

    base = scenario_from_dict(copy.deepcopy(raw), source)
    cdoc = camera_doc(d, doc)
    values = datasheet_values(DatasheetDoc(Path(source), cdoc), base)
    out: dict[str, tuple[Any, float | None, str]] = {}
    shifts: dict[str, float] = dict.fromkeys(values, 0.0)
    for fig in PROPAGATED:
        entry = cdoc["parameters"].get(fig) or {}
        if entry.get("value") is None or not entry.get("std_error"):
            continue
        moved = copy.deepcopy(cdoc)
        moved["parameters"][fig]["value"] = entry["value"] + entry["std_error"]
        if fig == "dark_offset":
            moved["parameters"]["reset_level"]["value"] = moved["parameters"][fig]["value"]
        try:
            shifted = datasheet_values(DatasheetDoc(Path(source), moved), base)
        except ScenarioError:  # a 1σ step past a consistency check: that share is not stated
            continue
        for key, (value, _) in values.items():
            if isinstance(value, float) and key in shifted:
                shifts[key] += (shifted[key][0] - value) ** 2
    for key, (value, origin) in values.items():
        se = math.sqrt(shifts[key]) if isinstance(value, float) else None
        out[key] = (value, se, origin.replace("parameters.", "").replace(".value", ""))
    return out


def write_scenario(d: Datasheet, doc: dict[str, Any], path: str | Path) -> Scenario:
    """Write the camera's twin as a scenario file; returns it, loaded and checked.

    Refused (:class:`ScenarioError`) before anything is written: a datasheet without the pixel
    pitch (the data set does not carry it), a value the twin's model cannot take.
    """
    from chiptwin.config.load import scenario_from_dict

    path = Path(path)
    if d.camera.pixel_pitch_um is None:
        raise ScenarioError("chiptwin", "--pixel-pitch-um", None,
                            "is needed with --write-scenario: an EMVA 1288 data set gives "
                            "photons per pixel, not the pixel's size, and the twin's diode, "
                            "dark current density and light are per area")
    if path.suffix != ".toml" or not path.parent.is_dir():
        raise ScenarioError("chiptwin", "--write-scenario", str(path),
                            "must be a .toml file in an existing folder")
    raw = base_raw(d, path.stem)
    values = scenario_values(d, doc, raw, str(path))
    for key, (value, _, _) in values.items():
        _, section, leaf = key.split(".")
        raw["chip"][section][leaf] = value
    text = toml_text(raw, values, d)
    s = scenario_from_dict(copy.deepcopy(raw), str(path))  # what is written loads
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)
    return s


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, float):
        return repr(float(f"{v:.7g}"))
    return str(v)


def toml_text(raw: dict[str, Any], values: dict[str, tuple[Any, float | None, str]],
              d: Datasheet) -> str:
    """The scenario as TOML, each measured value with its standard error and figure beside."""
    cam = d.camera
    lines = [f"# A twin of the camera measured in {cam.descriptor} (EMVA 1288 release "
             f"{cam.release}),",
             "# written by `chiptwin characterize --measured … --write-scenario`: each measured "
             "value",
             "# carries its standard error (± 1σ) and the datasheet figure it comes from; the "
             "rest are",
             "# the camera's shape and the protocol's longest exposure. The photodiode fills "
             "the pixel",
             "# (EMVA's η is per pixel area), one conversion per CDS, the black level as the "
             "pedestal.",
             "# Emitter law: none enters: the light is given at the sensor plane (assay kind "
             "\"flux\"), as the",
             "# camera's bench lit it.", ""]
    unresolved = [k for k in ("prnu", "dsnu") if d.figures[k].value is None
                  or d.figures[k].note.startswith("not significant")]
    for section, table in _tables(raw):
        lines.append(f"[{section}]")
        for leaf, value in table.items():
            key = f"{section}.{leaf}"
            comment = ""
            if key in values:
                _, se, origin = values[key]
                err = f" ± {se:.2g}" if se is not None and se > 0 else ""
                comment = f"  # measured{err} (from {origin})"
            elif leaf in ("prnu_frac", "dsnu_frac") and leaf[:4] in unresolved:
                comment = (f"  # the data set does not resolve {leaf[:4].upper()}₁₂₈₈ (within 2σ "
                           "of 0): none")
            lines.append(f"{leaf} = {_toml_value(value)}{comment}")
        lines.append("")
    return "\n".join(lines)


def _tables(raw: dict[str, Any], prefix: str = ""):
    """(section name, its scalar keys) in order, sub-tables after their parent."""
    scalars = {k: v for k, v in raw.items() if not isinstance(v, dict)}
    if prefix and scalars:
        yield prefix, scalars
    for k, v in raw.items():
        if isinstance(v, dict):
            yield from _tables(v, f"{prefix}.{k}" if prefix else k)


def replay_twin(c, path: str | Path, seed: int | None = None):
    """Write the camera's twin to ``path``, read it through the data set's protocol and set its
    figures and curves beside the measured ones (the datasheet's scenario column, the overlay
    figure, ``meta["twin"]``). ``c`` is the measured
    :class:`~chiptwin.characterize.Characterization`; it is returned, completed."""
    from chiptwin.characterize.datasheet import evaluate_measurement
    from chiptwin.characterize.overlay import Z_FOLLOWS, curves, findings
    from chiptwin.characterize.replay import ReplayPlan, replay
    from chiptwin.twin.scene import stage_rng

    d = c.datasheet
    s = write_scenario(d, c.to_json(), path)
    seed = s.scenario.seed if seed is None else seed
    m = d.measurement
    twin = replay(s, ReplayPlan.from_measurement(m), stage_rng(seed, "characterize.replay"))
    e = evaluate_measurement(twin)
    d.scenario_values = {k: (f.value, f"the twin ({Path(path).name}) through the data set's "
                             "protocol") for k, f in e.figures.items()}
    d.overlay = curves(m, twin)
    lines = findings(d.overlay)
    c.meta["twin"] = {
        "scenario": Path(path).name, "seed": seed, "follows_within_sigma": Z_FOLLOWS,
        "largest_z_below_saturation": {cv.name: cv.largest(True)[0] for cv in d.overlay},
        "largest_z": {cv.name: cv.largest(False)[0] for cv in d.overlay},
        "findings": lines}
    return c


__all__ = ["camera_doc", "replay_twin", "scenario_values", "write_scenario"]
