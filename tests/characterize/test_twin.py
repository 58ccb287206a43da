"""From a datasheet to a twin: ``[chip.pixel] from_datasheet`` and ``characterize --from``.

A datasheet the bench wrote configures a scenario's pixel and ADC (each value the inverse of its
figure through the twin's model), the twin so configured measures back to the same datasheet,
and malformed or self-contradicting datasheets are refused with one line naming the file, the
key, the value and what is allowed (exit 2, nothing written).
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from chiptwin.characterize import characterize
from chiptwin.characterize.bench import Bench
from chiptwin.characterize.estimators import var_se
from chiptwin.cli import main
from chiptwin.config import ScenarioError, load_scenario
from chiptwin.config.datasheet import full_well_at_saturation
from chiptwin.constants import Q_E

SCENARIO = """
[scenario]
name = "from_sheet"
seed = 3

[assay]
kind = "flux"
start_s = 16.0

[sites]
at_pixels = "centre"

[chip]
rows = 64
cols = 64
pitch_um = 12.0

[chip.pixel]
diode_w_um = 10.0
diode_h_um = 10.0
{extra}
from_datasheet = "{sheet}"

[chip.memory]
capacity_bits = 8388608

[chip.dsp]
cms_samples = 1

[run]
duration_s = 20.0
"""


@pytest.fixture(scope="module")
def sheet(characterized):
    """The 10-bit chip's datasheet document (the emva1288.json layout)."""
    return characterized("adc10").to_json()


def _write(folder: Path, doc: dict, extra: str = "", name: str = "ds.json") -> Path:
    (folder / name).write_text(json.dumps(doc))
    path = folder / "s.toml"
    path.write_text(SCENARIO.format(sheet=name, extra=extra))
    return path


def _value(doc: dict, key: str) -> float:
    return doc["parameters"][key]["value"]


def test_datasheet_configures_the_scenario(sheet, tmp_path):
    """Every pixel and ADC value is its figure inverted through the model: qe = η/fill factor,
    C = q/(K·LSB), read noise from σ_y.dark through the twin's CMS, full well = μ_e.sat + the
    dark charge at saturation,
    J at the reference temperature, T_d, PRNU, DSNU/(μ_I·t_spatial), pedestal from the reset
    level, ADC bits."""
    s = load_scenario(_write(tmp_path, sheet))
    px, adc = s.chip.pixel, s.chip.adc
    lsb = 1.0 / 2**10
    assert adc.bits == 10
    assert px.qe == pytest.approx(_value(sheet, "quantum_efficiency") / 100 / (100 / 144))
    assert px.capacitance_fF == pytest.approx(Q_E / (_value(sheet, "system_gain") * lsb) * 1e15)
    # read noise: the twin's dark CMS frame has the datasheet's σ_y.dark (true CDS, M samples)
    from chiptwin.pixel.adc import quantization_var_of_mean

    k, m, r = _value(sheet, "system_gain"), sheet["camera"].get("cms_samples", 1), px.read_noise_e
    assert px.true_cds
    twin = k * k * 2 * r * r / m + 2 * quantization_var_of_mean(m, k * r)
    assert twin == pytest.approx(_value(sheet, "temporal_dark_noise_dn") ** 2, rel=1e-9)
    t_sat = _value(sheet, "saturation_irradiation") / (
        sheet["conditions"]["irradiance_photons_per_s_per_um2"] * 144.0)
    e_sat, dark = _value(sheet, "saturation_capacity"), _value(sheet, "dark_current") * t_sat
    assert px.full_well_e == pytest.approx(
        full_well_at_saturation(e_sat, dark, _value(sheet, "prnu") / 100), rel=1e-9)
    assert 0.01 < px.full_well_e / (e_sat + dark) - 1 < 0.1  # the peak a few PRNU below
    assert px.dark_current_nA_per_cm2 == pytest.approx(
        _value(sheet, "dark_current") * Q_E / 1e-6 * 1e9)  # 100 µm² = 1e-6 cm², at 25 °C
    assert px.dark_doubling_C == _value(sheet, "doubling_temperature")
    assert px.prnu_frac == pytest.approx(_value(sheet, "prnu") / 100)
    assert px.dsnu_frac == pytest.approx(_value(sheet, "dsnu") / (
        _value(sheet, "dark_current") * sheet["conditions"]["spatial_exposure_s"]))
    assert px.pedestal_V == pytest.approx(_value(sheet, "reset_level") * lsb)
    assert px.pedestal_V == pytest.approx(0.05, abs=lsb / 100)  # the chip's 0.05 V came back


def test_values_the_scenario_also_sets_must_agree(sheet, tmp_path):
    """A key set both ways is an error naming the datasheet, its key and value, and the
    scenario's setting; the same value twice is not a conflict."""
    with pytest.raises(ScenarioError) as err:
        load_scenario(_write(tmp_path, sheet, extra="qe = 0.5"))
    e = err.value
    assert e.source.endswith("ds.json") and e.key == "parameters.quantum_efficiency.value"
    assert "chip.pixel.qe" in e.allowed and "0.5" in e.allowed
    same = load_scenario(_write(tmp_path, sheet, extra="prnu_frac = "
                                + repr(_value(sheet, "prnu") / 100)))
    assert same.chip.pixel.prnu_frac == pytest.approx(_value(sheet, "prnu") / 100)


def test_path_relative_to_the_scenario_and_set_override(sheet, tmp_path, monkeypatch):
    """The path is relative to the scenario file's folder; ``--set`` can name a datasheet too."""
    folder = tmp_path / "scen"
    folder.mkdir()
    path = _write(folder, sheet)
    monkeypatch.chdir(tmp_path)
    assert load_scenario(path).chip.adc.bits == 10
    text = path.read_text().replace('from_datasheet = "ds.json"\n', "")
    path.write_text(text)
    s = load_scenario(path, [f"chip.pixel.from_datasheet={folder / 'ds.json'}"])
    assert s.chip.adc.bits == 10


def test_twin_from_a_datasheet_measures_back_to_it(sheet, tmp_path):
    """datasheet → twin → datasheet: the second datasheet's η, K, σ_d, μ_I and T_d equal the
    first's within 5 combined standard errors; DSNU and PRNU equal the design values the twin
    got from the first within 5 standard errors with its own maps' sampling spread added (the
    twin is another chip of that design). The saturation capacity comes back lower by where the
    variance peaks below the full well (a few PRNU), ± one grid step: the standard's μ_e.sat is
    not a full well, and the twin's full well is the one whose variance peaks there
    (config.datasheet.full_well_at_saturation; taking μ_e.sat + dark lost 3.5–4.2 %)."""
    twin = load_scenario(_write(tmp_path, sheet))
    back = characterize(twin).to_json()["parameters"]
    first = sheet["parameters"]
    for key in ("quantum_efficiency", "system_gain", "temporal_dark_noise", "dark_current",
                "doubling_temperature"):
        a, b = first[key], back[key]
        tol = 5 * np.hypot(a["std_error"], b["std_error"])
        assert abs(a["value"] - b["value"]) <= tol, (key, a["value"], b["value"], tol)
    bench = Bench(twin)
    maps = {"prnu": (bench.sensor.gain_map, 100 * twin.chip.pixel.prnu_frac),
            "dsnu": (bench.sensor.dark_e_per_s, first["dsnu"]["value"])}
    for key, (m, design) in maps.items():
        sampling = design * var_se(m) / m.var() / 2
        if key == "prnu":  # the cross term σ_dark/(σ_photo √n), as in test_roundtrip.test_prnu
            sigma_photo = design / 100 * first["saturation_capacity"]["value"] / 2
            sampling = np.hypot(sampling, design * first["dsnu"]["value"]
                                / (sigma_photo * np.sqrt(m.size)))
        assert abs(back[key]["value"] - design) <= 5 * np.hypot(back[key]["std_error"], sampling)
    loss = 1 - back["saturation_capacity"]["value"] / first["saturation_capacity"]["value"]
    step = first["saturation_capacity"]["resolution"] / first["saturation_capacity"]["value"]
    assert abs(loss) <= step, (loss, step)


def _bad(doc: dict, path: tuple, value) -> dict:
    out = copy.deepcopy(doc)
    node = out
    for key in path[:-1]:
        node = node[key]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return out


_DELETE = object()

MALFORMED = {
    "missing gain": (("parameters", "system_gain"), _DELETE, "parameters.system_gain"),
    "gain a string": (("parameters", "system_gain", "value"), "high",
                      "parameters.system_gain.value"),
    "negative gain": (("parameters", "system_gain", "value"), -0.01,
                      "parameters.system_gain.value"),
    "QE above the diode's": (("parameters", "quantum_efficiency", "value"), 90.0,
                             "parameters.quantum_efficiency.value"),
    "bits out of range": (("camera", "adc_bits"), 30, "camera.adc_bits"),
    "PRNU beyond the schema": (("parameters", "prnu", "value"), 80.0, "parameters.prnu.value"),
    "SNR_max not √μ_e.sat": (("parameters", "snr_max", "value"), 250.0,
                            "parameters.snr_max.value"),
    "DSNU without dark current": (("parameters", "dark_current", "value"), 0.0,
                                  "parameters.dsnu.value"),
    "no parameters": (("parameters",), [], "parameters"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_datasheet_exit_2_one_line_nothing_written(case, sheet, tmp_path, capsys):
    """Refused before anything runs: exit 2, one line naming the datasheet file and the key, no
    output folder."""
    where, value, key = MALFORMED[case]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(_bad(sheet, where, value)))
    out = tmp_path / "out"
    code = main(["characterize", str(chip_scenario_file(tmp_path)), "--from", str(bad), "--out",
                 str(out), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert "bad.json" in err[0] and key in err[0], err[0]
    assert not out.exists()


def test_saturation_above_the_adc_range(sheet, tmp_path, capsys):
    """A saturation capacity the ADC cannot reach from the reset level contradicts the bits (the
    issue's example): refused on the datasheet's key with the code it would reach."""
    doc = copy.deepcopy(sheet)
    p = doc["parameters"]
    p["saturation_capacity"]["value"] *= 3  # consistent companions, unreachable code
    p["snr_max"]["value"] = float(np.sqrt(p["saturation_capacity"]["value"]))
    p["saturation_irradiation"]["value"] *= 3
    p["dynamic_range"]["value"] *= 3
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    code = main(["characterize", "--from", str(bad), "--out", str(tmp_path / "o"), "--quiet",
                 str(chip_scenario_file(tmp_path))])
    err = capsys.readouterr().err
    assert code == 2 and "above the ADC's range" in err and "saturation_capacity" in err


@pytest.mark.parametrize("text", ["{not json", "", "[1, 2]"])
def test_unreadable_datasheets(text, tmp_path, capsys):
    """Not JSON, empty, or not an object: exit 2, one line, for ``run`` too."""
    bad = tmp_path / "bad.json"
    bad.write_text(text)
    scen = tmp_path / "s.toml"
    scen.write_text(SCENARIO.format(sheet="bad.json", extra=""))
    assert main(["run", str(scen), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.json" in err[0]
    assert not (tmp_path / "o").exists()


def test_missing_datasheet_names_where_it_looked(tmp_path, capsys):
    scen = tmp_path / "s.toml"
    scen.write_text(SCENARIO.format(sheet="nowhere.json", extra=""))
    assert main(["validate", str(scen)]) == 2
    err = capsys.readouterr().err
    assert "chip.pixel.from_datasheet" in err and "nowhere.json" in err


def chip_scenario_file(folder: Path) -> Path:
    """The 10-bit chip as a scenario file (without a datasheet), for the CLI."""
    path = folder / "chip.toml"
    if not path.exists():
        path.write_text(SCENARIO.format(sheet="x", extra="").replace(
            'from_datasheet = "x"\n', ""))
    return path


def test_the_bench_reads_through_the_chips_converters_as_built():
    """EMVA 1288 measures the chip a run simulates: with comparator noise, gain mismatch and INL
    on ([chip.adc]), the bench's CMS frames are bit for bit the run's chain reading through the
    chip's converters (the bench once read through an ideal ADC: σ_y.dark 2.87 DN where the chip
    has 3.91, PRNU 1.05 % for 3.54 %), and its dark frames carry the comparator's 2 LSB:
    the pair's variance exceeds the ideal ADC's by 2·2²/M ± 25 % (M samples a side)."""
    from chiptwin import pixel
    from chiptwin.characterize.bench import Bench
    from tests.characterize.conftest import chip_scenario

    built = Bench(chip_scenario("adc10", comparator_noise_lsb=2.0, gain_sigma=0.03,
                                inl_max_lsb=8.0))
    ideal = Bench(chip_scenario("adc10", comparator_noise_lsb=0.0))
    s = built.sensor
    assert not s.converter.ideal
    dark = built.expected_e(s, 0.0, 0.02, 1)
    got = [img for img, _ in built.read(np.random.default_rng(0), s, [dark, dark], 2)]
    kw = dict(qe=1.0, dark_e=0.0, full_well_e=s.full_well_e, read_noise_e=s.read_noise_e,
              conversion_gain_uV_per_e=s.conversion_gain_uV_per_e, ktc_e=s.ktc_e,
              true_cds=s.true_cds, n_samples=s.cms_samples, read_reset=True,
              pedestal_V=s.pedestal_V, converter=s.converter)
    want = [built.cms(r, sg) for r, sg in
            pixel.sensor_chain(np.random.default_rng(0), iter([dark, dark]), **kw)]
    assert all(np.array_equal(a, b) for a, b in zip(got, want, strict=True))
    pair = [img for img, _ in ideal.read(np.random.default_rng(0), ideal.sensor,
                                         [dark, dark], 2)]
    extra = np.var(got[0] - got[1]) / 2 - np.var(pair[0] - pair[1]) / 2
    assert extra == pytest.approx(2 * 2.0**2 / s.cms_samples, rel=0.25)


def test_a_datasheet_measured_at_0_celsius_takes_its_kTC_at_0_celsius(tmp_path):
    """``temperature_C = 0.0`` is a temperature, not a missing one (it once read as absent and
    took the scenario's 25 °C): with true_cds = false the read noise makes the twin's dark CMS
    frame σ²_y.dark = K²σ_d² + 1/12 with kTC at 0 °C, K²(2σ_r²/M + 2kTC²) + 2q(M, Kσ_r), to
    1e-9 DN², and at 25 °C it does not."""
    from chiptwin.constants import K_B, Q_E
    from chiptwin.pixel.adc import quantization_var_of_mean

    doc = {"camera": {"adc_bits": 10, "cms_samples": 1, "temperature_C": 0.0},
           "parameters": {"quantum_efficiency": {"value": 40.0},
                          "system_gain": {"value": 0.0164},
                          "temporal_dark_noise": {"value": 60.0},
                          "saturation_capacity": {"value": 30000.0}}}
    (tmp_path / "ds.json").write_text(json.dumps(doc))
    (tmp_path / "s.toml").write_text(SCENARIO.format(
        sheet="ds.json", extra="true_cds = false\ntemperature_C = 25.0"))
    s = load_scenario(tmp_path / "s.toml")
    k, r = 0.0164, s.chip.pixel.read_noise_e
    target = (k * 60.0) ** 2 + 1 / 12

    def dark_var(temp_c):
        ktc2 = K_B * (temp_c + 273.15) * s.chip.pixel.capacitance_fF * 1e-15 / Q_E**2
        return k * k * (2 * r * r + 2 * ktc2) + 2 * quantization_var_of_mean(1, k * r)

    assert dark_var(0.0) == pytest.approx(target, abs=1e-9)
    assert abs(dark_var(25.0) - target) > 1e-4


def test_the_full_well_puts_the_variance_peak_at_the_saturation_capacity():
    """Monte Carlo of the twin's pixels (Poisson charge over lognormal gains of PRNU 1.5 %,
    chiptwin.pixel.fixed_pattern_maps, 200 e⁻ of dark, clipped at the full well the inversion
    gives for μ_e.sat = 10,000 e⁻): the temporal variance, half the mean squared difference of
    two frames over 200,000 pixels, is highest at μ_e.sat of the exposures 4 % either side
    (each difference beyond 4 SE), where F = μ_e.sat + dark puts the peak more than 3 % low."""
    from chiptwin.pixel import fixed_pattern_maps

    rng = np.random.default_rng(1288)
    e_sat, dark, prnu, n = 1e4, 200.0, 0.015, 200_000
    full = full_well_at_saturation(e_sat, dark, prnu)
    assert 0.03 < full / (e_sat + dark) - 1 < 0.06
    gain, _ = fixed_pattern_maps(rng, n, prnu, 0.0)

    def variance(mu: float) -> tuple[float, float]:
        a, b = (np.minimum(rng.poisson(gain * mu + dark), full) for _ in range(2))
        d2 = (a - b).astype(float) ** 2 / 2
        return float(d2.mean()), float(d2.std() / np.sqrt(n))

    (lo, se_lo), (at, se_at), (hi, se_hi) = (variance(f * e_sat) for f in (0.96, 1.0, 1.04))
    assert at - lo > 4 * np.hypot(se_at, se_lo) and at - hi > 4 * np.hypot(se_at, se_hi)
