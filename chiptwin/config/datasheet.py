"""From a datasheet to a twin: an EMVA 1288 datasheet (the ``emva1288.json`` layout) → the
``[chip.pixel]`` and ``[chip.adc]`` values of a scenario (``from_datasheet = "FILE.json"``).

The inverse of the datasheet's figures, through the twin's model (El Gamal & Eltoukhy 2005; EMVA
1288 Release 4.0 Linear):

=========================  ===================================================================
datasheet figure           scenario value
=========================  ===================================================================
η (%)                      ``chip.pixel.qe = η / fill factor`` (the datasheet's
                           ``camera.fill_factor`` if it has one, else the scenario's diode
                           area / pitch²): the diode's QE, independent of the geometry
K (DN/e⁻), ADC bits        ``chip.adc.bits``; ``chip.pixel.capacitance_fF = q(1 + gain error)
                           / (K·LSB)`` with the scenario's ADC range
σ_d (e⁻), M                ``chip.pixel.read_noise_e = √((σ_d² − 2σ_kTC²[no true CDS])·M/2)``:
                           σ_d is the noise of a CMS difference of M + M samples. An upper
                           limit (quantisation regime) is used as the value: the worst case
                           the datasheet allows
μ_I (e⁻/s) at T, T_d       ``dark_current_nA_per_cm2`` at the scenario's ``ref_temp_C``
                           (``μ_I·q/A_diode·2^((T_ref − T)/T_d)``), ``dark_doubling_C = T_d``
DSNU₁₂₈₈ (e⁻)              ``dsnu_frac = DSNU / (μ_I · spatial exposure time)``
PRNU₁₂₈₈ (%)               ``prnu_frac = PRNU / 100``
μ_e.sat (e⁻)               ``full_well_e``: the well whose temporal variance peaks at μ_e.sat
                           with the dark charge of that exposure (``μ_I·t_sat``, ``t_sat =
                           μ_p.sat/(irradiance·pitch²)`` when the datasheet gives them) and the
                           PRNU: the standard's saturation is where the variance peaks, a few
                           PRNU below the full well (:func:`full_well_at_saturation`)
reset level (DN)           ``pedestal_V = v_min + (reset − offset)·LSB/(1 + gain error)``
=========================  ===================================================================

Only the figures present are used; the scenario keeps its own values for the others. Refused,
naming the datasheet, the key, the value and what is allowed: a file that is not such a JSON
document, a figure that is not a positive finite number, a derived value outside the scenario
field's range, figures that contradict each other (``SNR_max ≠ √μ_e.sat``, ``μ_e.sat ≠ η·μ_p.sat``,
``DR ≠ μ_p.sat/μ_p.min``, ``1/K``, ``DSNU`` in DN, each within 1 %), a saturation above the ADC's
range, a DSNU without a dark current, and a value the scenario also sets to something else.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from chiptwin.config.fields import ScenarioError, allowed_text
from chiptwin.config.schema import Adc, Pixel, Scenario
from chiptwin.constants import K_B, Q_E, ZERO_C_K

#: Figures a datasheet must give.
REQUIRED = ("quantum_efficiency", "system_gain", "temporal_dark_noise", "saturation_capacity")

#: Relative disagreement above which two figures of one datasheet contradict each other.
CONSISTENCY_TOL: float = 0.01



def _fields(cls: type) -> dict[str, dataclasses.Field]:
    return {f.name: f for f in dataclasses.fields(cls)}


_FIELDS = {"chip.pixel": _fields(Pixel), "chip.adc": _fields(Adc)}


class DatasheetDoc:
    """A parsed datasheet with checked access to its figures."""

    def __init__(self, path: Path, doc: Any) -> None:
        self.path, self.source = path, str(path)
        if not isinstance(doc, dict) or not isinstance(doc.get("parameters"), dict):
            raise ScenarioError(self.source, "parameters", None if not isinstance(doc, dict)
                                else doc.get("parameters"),
                                "must be an object of figures (the emva1288.json layout)")
        self.params, self.camera = doc["parameters"], doc.get("camera") or {}
        self.conditions = doc.get("conditions") or {}
        if not isinstance(self.camera, dict) or not isinstance(self.conditions, dict):
            raise ScenarioError(self.source, "camera", self.camera, "must be an object")

    def figure(self, key: str, lo: float = 0.0, lo_open: bool = True) -> float | None:
        """``parameters.<key>.value``: None when absent or null, else a checked number."""
        entry = self.params.get(key)
        if entry is None:
            return None
        where = f"parameters.{key}"
        if not isinstance(entry, dict) or "value" not in entry:
            raise ScenarioError(self.source, where, entry, 'must be an object with a "value"')
        return self.number(where + ".value", entry["value"], lo, lo_open, allow_none=True)

    def upper_limit(self, key: str) -> bool:
        return bool((self.params.get(key) or {}).get("upper_limit", False))

    def number(self, where: str, value: Any, lo: float = 0.0, lo_open: bool = True,
               allow_none: bool = False) -> float | None:
        if value is None and allow_none:
            return None
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if not ok or not math.isfinite(value) or value < lo or (lo_open and value == lo):
            raise ScenarioError(self.source, where, value,
                                f"must be a finite number {'>' if lo_open else '≥'} {lo:g}")
        return float(value)

    def camera_value(self, key: str, lo: float = 0.0) -> float | None:
        if key not in self.camera or self.camera[key] is None:
            return None
        return self.number(f"camera.{key}", self.camera[key], lo)

    def fail(self, key: str, value: Any, allowed: str) -> None:
        raise ScenarioError(self.source, key, value, allowed)


def read_datasheet(path: Path) -> DatasheetDoc:
    """Parse a datasheet file; unreadable or malformed files are :class:`ScenarioError`."""
    try:
        text = path.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(str(path), "(file)", str(path),
                            f"must be a readable UTF-8 datasheet ({exc})") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ScenarioError(str(path), "(file)", str(path), f"must be valid JSON ({exc})") from None
    return DatasheetDoc(path, doc)


def resolve_path(value: Any, source: str) -> Path:
    """The datasheet named by ``from_datasheet``: absolute, or relative to the scenario file's
    folder if it is there, else to the working folder."""
    if not isinstance(value, str) or not value:
        raise ScenarioError(source, "chip.pixel.from_datasheet", value,
                            "must be the path of a datasheet JSON file (a string)")
    path = Path(value)
    if path.is_absolute():
        candidates = [path]
    else:
        candidates = [Path(source).parent / path, Path.cwd() / path]
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    raise ScenarioError(source, "chip.pixel.from_datasheet", value,
                        "must name an existing file (looked for "
                        + ", ".join(str(c) for c in candidates) + ")")


def probe_table(raw: dict[str, Any]) -> dict[str, Any]:
    """A copy of a scene's table to read a datasheet's values against. The scene without the
    datasheet gives only the converter and timing; its node and full well are the datasheet's to
    set (the capacitance from K, the full well from μ_e.sat), so the converter's range is checked
    on the scene the values make, not on the node its diode alone would give."""
    probe = copy.deepcopy(raw)
    chip = probe.setdefault("chip", {})
    if isinstance(chip, dict):
        chip.setdefault("adc", {})["range_below_full_well_ok"] = True
    return probe


def apply_datasheet(raw: dict[str, Any], source: str,
                    build: Callable[[dict[str, Any]], Scenario]) -> dict[str, Any]:
    """The raw scenario table with ``chip.pixel.from_datasheet`` replaced by the values the
    datasheet gives (checked); ``build`` makes a validated scenario of a raw table."""
    raw = copy.deepcopy(raw)
    pixel_raw = raw["chip"]["pixel"]
    doc = read_datasheet(resolve_path(pixel_raw.pop("from_datasheet"), source))
    base = build(probe_table(raw))
    values = datasheet_values(doc, base)
    for key, (value, origin) in values.items():
        section, leaf = key.rsplit(".", 1)
        table = raw.setdefault("chip", {}).setdefault(section.split(".")[1], {})
        if leaf in table and not _same(table[leaf], value):
            doc.fail(origin, _origin_value(doc, origin), f"gives {key} = {value:.6g}, but "
                     f"{source} sets "
                     f"{key} = {table[leaf]!r}: remove one of them")
        table[leaf] = value
    return raw


def bundled_datasheet(name: str | Path, folder: Path) -> Path:
    """A datasheet path as given if it exists, else the one of that name in ``folder`` (the
    bundled ``scenarios/datasheets``, e.g. ``pyro_1fmol_chip``)."""
    path = Path(name)
    if path.exists():
        return path
    for candidate in (folder / path.name, folder / f"{path.name}.json"):
        if candidate.is_file():
            return candidate
    return path


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, bool) or isinstance(b, bool) or not isinstance(a, (int, float)):
        return a == b
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=0.0)


def datasheet_values(doc: DatasheetDoc, s: Scenario) -> dict[str, tuple[Any, str]]:
    """Scenario key → (value, the datasheet key it comes from), every value checked."""
    for key in REQUIRED:
        if doc.figure(key) is None:
            doc.fail(f"parameters.{key}", None, "is required (a figure with a value)")
    bits = doc.camera.get("adc_bits")
    if type(bits) is not int or not 1 <= bits <= 24:
        doc.fail("camera.adc_bits", bits, "must be an integer in [1, 24]")
    adc, px = s.chip.adc, s.chip.pixel
    lsb = (adc.v_max_V - adc.v_min_V) / 2.0**bits
    gain = doc.figure("system_gain")
    out: dict[str, tuple[Any, str]] = {"chip.adc.bits": (bits, "camera.adc_bits")}
    cap_fF = Q_E * (1.0 + adc.gain_error) / (gain * lsb) * 1e15
    out["chip.pixel.capacitance_fF"] = (cap_fF, "parameters.system_gain.value")
    fill = doc.camera_value("fill_factor") or px.diode_w_um * px.diode_h_um / s.chip.pitch_um**2
    out["chip.pixel.qe"] = (doc.figure("quantum_efficiency") / 100.0 / fill,
                            "parameters.quantum_efficiency.value")
    out["chip.pixel.read_noise_e"] = (_read_noise(doc, s, cap_fF, gain),
                                      "parameters.temporal_dark_noise.value")
    prnu = doc.figure("prnu", lo_open=False)
    full_well = full_well_at_saturation(doc.figure("saturation_capacity"),
                                        _dark_at_saturation(doc), (prnu or 0.0) / 100.0)
    out["chip.pixel.full_well_e"] = (full_well, "parameters.saturation_capacity.value")
    if prnu is not None:
        out["chip.pixel.prnu_frac"] = (prnu / 100.0, "parameters.prnu.value")
    reset = doc.figure("reset_level", lo=-math.inf)
    if reset is not None:
        out["chip.pixel.pedestal_V"] = (
            adc.v_min_V + (reset - adc.offset_error_lsb) * lsb / (1.0 + adc.gain_error),
            "parameters.reset_level.value")
    out.update(_dark(doc, s))
    _check_ranges(doc, out)
    _check_consistency(doc, s, gain, bits, reset)
    return out


def full_well_at_saturation(e_sat: float, dark_e: float, prnu_frac: float) -> float:
    """The full well whose temporal variance peaks where the datasheet's saturation lies.

    EMVA 1288's saturation is the exposure of the temporal variance's maximum, and μ_e.sat the
    mean pixel's photo-electrons there: the brightest pixels (PRNU) and the upper tail of the
    shot noise are clipped by then, so the peak sits below the full well ``F`` (a few PRNU:
    taking ``F = μ_e.sat + dark`` lost 3.5–4.2 % of the saturation capacity on every
    datasheet → twin → datasheet round trip). This inverts the twin's own model: per pixel
    ``N ~ N(gμ + d, gμ + d)`` (the Poisson charge, dark ``d``), collected ``min(N, F)``, the
    gain ``g`` lognormal of mean 1 and CV ``prnu_frac`` (:func:`chiptwin.pixel.sensor.
    fixed_pattern_maps`, 64 Gauss–Hermite nodes), the read noise added after the clip (it
    moves no peak); ``V(μ) = E_g[Var(min(N, F))]`` from the censored normal's moments, and
    ``F`` found so that its maximum is at ``μ = e_sat`` (a fixed point, ``dμ*/dF ≈ 1``).
    Unit: e⁻."""
    from scipy.optimize import minimize_scalar
    from scipy.special import ndtr

    z, w = np.polynomial.hermite_e.hermegauss(64)
    w = w / w.sum()
    sl = math.sqrt(math.log1p(prnu_frac * prnu_frac))
    g = np.exp(sl * z - 0.5 * sl * sl)

    def minus_variance(mu: float, full: float) -> float:
        m = g * mu + dark_e
        s = np.sqrt(np.maximum(m, 1e-300))
        a = (full - m) / s
        cdf, pdf = ndtr(a), np.exp(-0.5 * a * a) / math.sqrt(2.0 * math.pi)
        first = -pdf + a * (1.0 - cdf)  # E[min(Z, a)], then E[min(Z, a)²]
        second = cdf - a * pdf + a * a * (1.0 - cdf)
        return -float(w @ (m * (second - first * first)))

    full = e_sat + dark_e
    for _ in range(60):
        peak = minimize_scalar(minus_variance, bounds=(0.5 * e_sat, 1.5 * full), args=(full,),
                               method="bounded", options={"xatol": 1e-10 * full}).x
        step = e_sat - peak
        full += step
        if abs(step) <= 1e-9 * full:
            break
    return full


def _dark_at_saturation(doc: DatasheetDoc) -> float:
    """Dark charge in the well at the saturation exposure: μ_e.sat counts photo-electrons only.
    ``μ_I · μ_p.sat / (irradiance · pixel area)`` when the datasheet gives them, else 0.
    Unit: e⁻."""
    dark, p_sat = doc.figure("dark_current", lo_open=False), doc.figure("saturation_irradiation")
    irr = doc.conditions.get("irradiance_photons_per_s_per_um2")
    pitch = doc.camera_value("pixel_pitch_um")
    if not dark or p_sat is None or irr is None or pitch is None:
        return 0.0
    irr = doc.number("conditions.irradiance_photons_per_s_per_um2", irr)
    return dark * p_sat / (irr * pitch * pitch)


def _read_noise(doc: DatasheetDoc, s: Scenario, cap_fF: float, gain: float) -> float:
    """Read noise per sample σ_r whose CMS dark frame has the datasheet's temporal dark noise.

    The datasheet's σ_y.dark (DN; else ``K²σ_d² + 1/12``: EMVA's σ_d removes one LSB²/12) is the
    twin's dark CMS frame, the mean of M signal samples minus the mean of M reset samples:
    ``σ²_y.dark = K²·(2σ_r²/M + 2·kTC²) + 2·q(M, K·σ_r)`` DN², kTC² only without true CDS and
    ``q`` the rounding variance of a mean of M codes
    (:func:`~chiptwin.pixel.adc.quantization_var_of_mean`, 1/12 at no noise, 1/(12M) from
    ≈ 0.5 LSB). ``q`` falls as the noise grows, so in the quantisation regime two read noises
    can give the same σ_y.dark: the larger is taken (the worst chip the datasheet allows). Until
    a review found it this took σ_d for pure pixel noise, √(σ_d²·M/2): a round trip added
    (2/12 − 1/12)/K² e⁻² of noise each time (σ_d +12 % on a 10-bit chip), and the reference
    datasheet's twin read 426 e⁻ for the chip's 100."""
    from scipy.optimize import brentq

    from chiptwin.pixel.adc import quantization_var_of_mean

    sigma_d = doc.figure("temporal_dark_noise")
    m = doc.camera.get("cms_samples", 1)
    if type(m) is not int or m < 1:
        doc.fail("camera.cms_samples", m, "must be an integer ≥ 1 (the CMS samples M)")
    ktc2 = 0.0
    if not s.chip.pixel.true_cds:
        temp_c = doc.camera_value("temperature_C", lo=-273.15)
        if temp_c is None:  # not `or`: a datasheet measured at 0 °C states a temperature
            temp_c = s.chip.pixel.temperature_C
        ktc2 = K_B * (temp_c + ZERO_C_K) * cap_fF * 1e-15 / Q_E**2
    sigma_y = doc.figure("temporal_dark_noise_dn")
    target = sigma_y**2 if sigma_y is not None else (gain * sigma_d) ** 2 + 1.0 / 12

    def excess(sr: float) -> float:
        return (gain * gain * (2.0 * sr * sr / m + 2.0 * ktc2)
                + 2.0 * quantization_var_of_mean(m, gain * sr) - target)

    # the rounding term changes only below ≈ 1 LSB of read noise: finely there (a root pair
    # can sit within it), coarsely above, where the excess only grows
    top = math.sqrt(target * m / 2.0) / gain * 1.01 + 1e-9  # excess(top) > 0
    fine = min(top, 1.5 / gain)
    grid = [fine * i / 300 for i in range(301)] + [fine + (top - fine) * i / 20
                                                     for i in range(1, 21)]
    values = [excess(x) for x in grid]
    below = [i for i in range(len(grid) - 1) if values[i] <= 0.0 < values[i + 1]]
    if not below:
        doc.fail("parameters.temporal_dark_noise.value", sigma_d,
                 f"is below what the scenario's chip can read: no read noise gives σ_y.dark = "
                 f"{math.sqrt(target):.4g} DN through its CMS (M = {m}: the rounding of the "
                 "means" + (", and the kTC noise without true CDS" if ktc2 else "") + ")")
    i = below[-1]
    return float(brentq(excess, grid[i], grid[i + 1], xtol=1e-12, rtol=1e-12))


def _dark(doc: DatasheetDoc, s: Scenario) -> dict[str, tuple[Any, str]]:
    """Dark current density, doubling temperature and DSNU."""
    px, out = s.chip.pixel, {}
    doubling = doc.figure("doubling_temperature")
    if doubling is not None:
        out["chip.pixel.dark_doubling_C"] = (doubling, "parameters.doubling_temperature.value")
    dark = doc.figure("dark_current", lo_open=False)
    dsnu = doc.figure("dsnu", lo_open=False)
    if dark is not None:
        t_meas = doc.camera_value("temperature_C", lo=-273.15)
        t_meas = px.temperature_C if t_meas is None else t_meas
        area_um2 = doc.camera_value("diode_area_um2") or px.diode_w_um * px.diode_h_um
        td = doubling or px.dark_doubling_C
        amps = dark * Q_E * 2.0 ** ((px.ref_temp_C - t_meas) / td)
        out["chip.pixel.dark_current_nA_per_cm2"] = (amps / (area_um2 * 1e-8) * 1e9,
                                                     "parameters.dark_current.value")
    if dsnu is not None:
        t_spatial = doc.conditions.get("spatial_exposure_s")
        if not dark or t_spatial is None:
            doc.fail("parameters.dsnu.value", dsnu,
                     "needs a dark current > 0 and conditions.spatial_exposure_s: the twin's "
                     "DSNU is a spread of the dark current")
        t_spatial = doc.number("conditions.spatial_exposure_s", t_spatial)
        out["chip.pixel.dsnu_frac"] = (dsnu / (dark * t_spatial), "parameters.dsnu.value")
    return out


def _check_ranges(doc: DatasheetDoc, values: dict[str, tuple[Any, str]]) -> None:
    """Every derived value against its scenario field's rule, reported on the datasheet's key."""
    from chiptwin.config.fields import check_value

    for key, (value, origin) in values.items():
        section, leaf = key.rsplit(".", 1)
        field = _FIELDS[section][leaf]
        try:
            check_value(field, value, doc.source, origin)
        except ScenarioError:
            doc.fail(origin, _origin_value(doc, origin),
                     f"gives {key} = {value:.6g}, which {allowed_text(field)}")


def _origin_value(doc: DatasheetDoc, origin: str) -> Any:
    parts = origin.split(".")
    node: Any = {"parameters": doc.params, "camera": doc.camera, "conditions": doc.conditions}
    for part in parts:
        node = node.get(part) if isinstance(node, dict) else None
    return node


def _check_consistency(doc: DatasheetDoc, s: Scenario, gain: float, bits: int,
                       reset: float | None) -> None:
    """Figures that contradict each other, and a saturation beyond the ADC's range."""
    qe, e_sat = doc.figure("quantum_efficiency") / 100.0, doc.figure("saturation_capacity")
    p_sat, p_min = doc.figure("saturation_irradiation"), doc.figure(
        "absolute_sensitivity_threshold")
    checks = [("snr_max", math.sqrt(e_sat), "√μ_e.sat"),
              ("saturation_irradiation", e_sat / qe, "μ_e.sat/η"),
              ("inverse_system_gain", 1.0 / gain, "1/K")]
    if p_sat is not None and p_min is not None:
        checks.append(("dynamic_range", p_sat / p_min, "μ_p.sat/μ_p.min"))
    dsnu = doc.figure("dsnu", lo_open=False)
    if dsnu:
        checks.append(("dsnu_dn", dsnu * gain, "DSNU₁₂₈₈ (e⁻) × K"))
    for key, expected, formula in checks:
        given = doc.figure(key, lo_open=False)
        if given is not None and abs(given - expected) > CONSISTENCY_TOL * abs(expected):
            doc.fail(f"parameters.{key}.value", given,
                     f"contradicts the datasheet's other figures: {formula} = {expected:.6g} "
                     f"(tolerance {100 * CONSISTENCY_TOL:g} %)")
    a = s.chip.adc
    if reset is None:
        lsb = (a.v_max_V - a.v_min_V) / 2.0**bits
        reset = (s.chip.pixel.pedestal_V - a.v_min_V) / lsb * (1 + a.gain_error) + \
            a.offset_error_lsb
    top = reset + e_sat * gain
    if top > 2**bits - 1 + 0.5:
        doc.fail("parameters.saturation_capacity.value", e_sat,
                 f"is above the ADC's range: reset level {reset:.6g} DN + μ_e.sat·K = "
                 f"{e_sat * gain:.6g} DN reaches code {top:.6g} > {2**bits - 1} "
                 f"({bits} bits)")
