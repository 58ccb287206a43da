"""Keys that move together, and refusals in the user's terms.

The node capacitance follows the diode (junction × area + sidewall × perimeter + readout) unless
it is given; the pitch does not follow the diode, and its refusal names both keys and values that
work; a refused ``--set`` names the override, not the file; the frame schedule's refusal speaks
in seconds and states the smallest period allowed; a range refusal states its bound.
"""

from __future__ import annotations

import re

import pytest

from chiptwin.cli import main
from chiptwin.config import ScenarioError, load_scenario
from chiptwin.config.fields import unit_of
from chiptwin.config.schema_chip import Pixel


def _refusal(path, overrides) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, overrides)
    return info.value


# ------------------------------------------------------------------------------ the coupling


def test_the_reference_diode_derives_the_reference_capacitance_bit_for_bit():
    """0.08 fF/µm² × 100 × 100 µm + 0.25 fF/µm × 400 µm + 100 fF = 1000 fF exactly: a scene that
    leaves the capacitance to the diode runs the reference chip's 1 pF node unchanged."""
    assert Pixel().capacitance_fF == 0.0  # not given: derived
    assert Pixel().derived_capacitance_fF == 1000.0


def test_bundled_reference_chip_capacitance_is_unchanged():
    """The headline scene states 1 pF; the same scene with its capacitance left to the diode
    derives the same value, and a scene that never gave one (crosstalk_microarray) has it too."""
    assert load_scenario("pyro_1fmol").chip.pixel.capacitance_fF == 1000.0
    derived = load_scenario("pyro_1fmol", ["chip.pixel.capacitance_fF=0"])
    assert derived.chip.pixel.capacitance_fF == 1000.0
    assert load_scenario("crosstalk_microarray").chip.pixel.capacitance_fF == 1000.0


@pytest.mark.parametrize(("w", "h"), [(50.0, 50.0), (100.0, 40.0), (20.0, 20.0)])
def test_a_set_of_the_diode_moves_the_capacitance_as_stated(small_toml, w, h):
    """C = junction × w·h + sidewall × 2(w + h) + readout, with the defaults 0.08 fF/µm², 0.25
    fF/µm and 100 fF (a 50 µm diode: 200 + 50 + 100 = 350 fF)."""
    s = load_scenario(small_toml, [f"chip.pixel.diode_w_um={w}", f"chip.pixel.diode_h_um={h}",
                                   "chip.adc.range_below_full_well_ok=true"])
    assert s.chip.pixel.capacitance_fF == pytest.approx(0.08 * w * h + 0.25 * 2 * (w + h) + 100)
    if (w, h) == (50.0, 50.0):
        assert s.chip.pixel.capacitance_fF == pytest.approx(350.0)


def test_each_coupling_key_moves_the_capacitance(small_toml):
    base = load_scenario(small_toml).chip.pixel.capacitance_fF
    for key, value, expected in (("junction_fF_per_um2", 0.1, base + 0.02 * 1e4),
                                 ("sidewall_fF_per_um", 0.5, base + 0.25 * 400),
                                 ("readout_fF", 20.0, base - 80.0)):
        s = load_scenario(small_toml, [f"chip.pixel.{key}={value}",
                                       "chip.adc.range_below_full_well_ok=true"])
        assert s.chip.pixel.capacitance_fF == pytest.approx(expected), key


def test_a_given_capacitance_wins_over_the_diode(small_toml):
    s = load_scenario(small_toml, ["chip.pixel.capacitance_fF=500", "chip.pixel.diode_w_um=50",
                                   "chip.pixel.junction_fF_per_um2=1.0",
                                   "chip.adc.range_below_full_well_ok=true"])
    assert s.chip.pixel.capacitance_fF == 500.0


def test_a_capacitance_between_zero_and_its_range_is_refused(small_toml):
    """0 means derived; 5e-324 (a float's smallest) is no capacitance at all."""
    err = _refusal(small_toml, ["chip.pixel.capacitance_fF=5e-324"])
    assert err.key == "chip.pixel.capacitance_fF"
    assert "0 (derived from the diode) or a number in [0.1, 1e+07]" in str(err)


def test_a_derived_capacitance_out_of_range_names_the_keys_it_came_from(small_toml):
    err = _refusal(small_toml, ["chip.pitch_um=10000", "chip.pixel.diode_w_um=10000",
                                "chip.pixel.diode_h_um=10000",
                                "chip.pixel.junction_fF_per_um2=2.0",
                                "chip.adc.range_below_full_well_ok=true"])
    assert err.key == "chip.pixel.capacitance_fF"
    for word in ("junction_fF_per_um2", "sidewall_fF_per_um", "readout_fF", "[0.1, 1e+07] fF"):
        assert word in err.allowed, word


def test_a_smaller_node_names_the_full_well_that_fits(small_toml):
    """full_well_e is in electrons and does not follow: the range refusal says the capacitance
    was derived and which full well fits; that value is then accepted."""
    diode = ["chip.pixel.diode_w_um=50", "chip.pixel.diode_h_um=50"]
    err = _refusal(small_toml, diode)
    assert err.key == "chip.adc.v_max_V"
    assert "C = 350 fF, derived from the diode" in err.allowed
    fits = int(re.search(r"chip\.pixel\.full_well_e ≤ (\d+)", err.allowed).group(1))
    s = load_scenario(small_toml, [*diode, f"chip.pixel.full_well_e={fits}"])
    assert s.chip.pixel.full_well_e == fits
    with pytest.raises(ScenarioError, match="chip.adc.v_max_V"):
        load_scenario(small_toml, [*diode, f"chip.pixel.full_well_e={fits * 1.01}"])


# ------------------------------------------------------------------- refusals in user terms


def test_the_pitch_refusal_names_every_key_and_a_value_that_works(small_toml):
    err = _refusal(small_toml, ["chip.pitch_um=80"])
    assert str(err).startswith("--set chip.pitch_um=80: chip.pitch_um = 80.0 µm: ")
    for text in ("chip.pixel.diode_w_um = 100 µm", "chip.pixel.diode_h_um = 100 µm",
                 "≤ 80", "chip.pitch_um ≥ 100"):
        assert text in err.allowed, text
    assert load_scenario(small_toml, ["chip.pitch_um=100"]).chip.pitch_um == 100.0
    one = _refusal(small_toml, ["chip.pitch_um=80", "chip.pixel.diode_h_um=60",
                                "chip.adc.range_below_full_well_ok=true"])
    assert "diode_h_um" not in one.allowed and "set chip.pixel.diode_w_um ≤ 80" in one.allowed


def test_a_refused_override_is_named_by_the_override_not_the_file(small_toml):
    own = _refusal(small_toml, ["chip.adc.bits=40"])
    assert own.source == "--set chip.adc.bits=40" and str(small_toml) not in str(own)
    caused = _refusal(small_toml, ["chip.timing.t_int_s=2.0"])  # refuses the frame period
    assert caused.key == "chip.timing.frame_period_s"
    assert caused.source == f"{small_toml} with --set chip.timing.t_int_s=2.0"
    file_only = small_toml.parent / "bad.toml"
    file_only.write_text(small_toml.read_text().replace("rows = 4", "rows = 0"))
    assert _refusal(file_only, []).source == str(file_only)
    malformed = _refusal(small_toml, ["chip.adc.bits"])
    assert malformed.source == "command line"


def test_the_cli_prints_the_override(capsys):
    assert main(["validate", "pyro_1fmol", "--set", "chip.pitch_um=80"]) == 2
    err = capsys.readouterr().err
    assert "--set chip.pitch_um=80: chip.pitch_um = 80.0 µm: must be ≥ the diode" in err
    assert "pyro_1fmol.toml" not in err


def test_the_schedule_refusal_is_in_seconds_with_the_smallest_period(small_toml):
    """t_int_s = 1.5 s in a 1 s frame: the smallest period is reset + integration + 2M
    conversions, stated in s (rounded up, 5 digits), never in ns; that period passes."""
    err = _refusal(small_toml, ["chip.timing.t_int_s=1.5"])
    assert err.key == "chip.timing.frame_period_s"
    assert not re.search(r"\d ns\b", str(err)), str(err)
    m = re.search(r"is below the smallest allowed, ([\d.]+) s: reset ", err.allowed)
    assert m, err.allowed
    smallest = float(m.group(1))
    conv_s = 2**13 / 20e6  # 13 bits, 20 MHz: 0.4096 ms
    assert smallest == pytest.approx(1e-5 + 1.5 + 4 * conv_s, abs=1e-4)
    assert f"chip.timing.frame_period_s ≥ {m.group(1)}" in err.allowed
    ok = ["chip.timing.t_int_s=1.5", f"chip.timing.frame_period_s={smallest}"]
    try:
        load_scenario(small_toml, ok)
    except ScenarioError as later:  # the assay's timing may need the new period; not this rule
        assert later.key != "chip.timing.frame_period_s", str(later)
    short = _refusal(small_toml, [f"chip.timing.frame_period_s={smallest - 1e-4}",
                                  "chip.timing.t_int_s=1.5"])
    assert short.source == f"--set chip.timing.frame_period_s={smallest - 1e-4}"


def test_the_frame_period_user_report():
    """frame_period_s = 0.001 on pyro_1fmol: below the 0.99 s of integration alone."""
    err = _refusal("pyro_1fmol", ["chip.timing.frame_period_s=0.001"])
    assert "is below the smallest allowed, 0.99329 s" in err.allowed
    assert "set chip.timing.frame_period_s ≥ 0.99329" in err.allowed


@pytest.mark.parametrize(("override", "text"), [
    ("chip.timing.frame_period_s=1e-10", "is below the smallest allowed, 1e-09 s; must be a "
                                         "number in [1e-09, 1e+07]"),
    ("chip.pitch_um=2e4", "is above the largest allowed, 10000 µm; must be a number in"),
    ("chip.pixel.junction_fF_per_um2=5", "is above the largest allowed, 2 fF/µm²"),
    ("chip.adc.bits=40", "is above the largest allowed, 24; must be an integer in [1, 24]"),
])
def test_a_range_refusal_states_its_bound_in_the_keys_unit(small_toml, override, text):
    assert text in _refusal(small_toml, [override]).allowed


@pytest.mark.parametrize(("key", "unit"), [
    ("chip.timing.frame_period_s", "s"), ("chip.pitch_um", "µm"), ("chip.adc.clock_hz", "Hz"),
    ("chip.pixel.capacitance_fF", "fF"), ("chip.pixel.junction_fF_per_um2", "fF/µm²"),
    ("chip.pixel.sidewall_fF_per_um", "fF/µm"), ("assay.k_a_per_s", "1/s"),
    ("chip.pixel.temperature_C", "°C"), ("chip.pixel.full_well_e", "e⁻"), ("chip.adc.bits", ""),
    ("assay.photons_per_s_per_um2", ""), ("chip.pixel.qe", ""),
])
def test_unit_of_reads_the_unit_in_the_name(key, unit):
    assert unit_of(key) == unit


@pytest.mark.parametrize(("override", "nearest", "works"), [
    ("assay.start_s=9.0", "the nearest allowed are 8 s and 12 s", "assay.start_s=12.0"),
    ("assay.flow_period_s=21.0", "the nearest allowed are 20 s and 24 s",
     "assay.flow_period_s=20.0"),
    ("assay.flow_period_s=2.0", "the nearest allowed is 4 s", None),
])
def test_a_value_off_the_block_grid_is_given_its_nearest_allowed(small_toml, override, nearest,
                                                                  works):
    """small.toml: 4 dark frames of 1 s, then blocks of 4 frames (4 s)."""
    err = _refusal(small_toml, [override])
    assert err.allowed.endswith(nearest), err.allowed
    if works:
        try:
            load_scenario(small_toml, [works])
        except ScenarioError as later:  # a later rule (the run's length) may refuse; not this
            assert later.key != works.split("=")[0], str(later)


def test_a_refused_value_is_shown_in_its_keys_unit(small_toml):
    """A key with a unit in its name shows the value with it; a count shows none."""
    assert "chip.timing.frame_period_s = 0.001 s: " in str(
        _refusal(small_toml, ["chip.timing.frame_period_s=0.001"]))
    assert "chip.adc.bits = 40: " in str(_refusal(small_toml, ["chip.adc.bits=40"]))
    assert "chip.memory.capacity_bits = 10: " in str(
        _refusal(small_toml, ["chip.memory.capacity_bits=10"]))
