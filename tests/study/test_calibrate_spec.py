"""A calibrate study file is read strictly: every bad key, range, column or unit is one
ScenarioError naming the file, the key, the value and what is allowed, before anything runs.

The shared pieces of the calibrate tests live here too: :data:`TINY` (a 2 × 2 chip under uniform
light, a run of 2 ms), :data:`STUDY` (a calibration of its QE to an SNR table) and
:func:`write_study`.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from chiptwin.config import ScenarioError
from chiptwin.study import load_study
from chiptwin.study.calibrate_targets import key_unit, merge_replicates, same_unit

#: A 2 × 2 chip under uniform light (kind flux), 16-bit converter (its LSB, 15 e⁻ at 1 pF, well
#: below the shot noise of a frame), 4 dark and 8 light frames: one run ≈ 2 ms.
TINY = """
[scenario]
name = "tiny_flux"
seed = 3

[assay]
kind = "flux"
photons_per_s_per_um2 = 0.5
start_s = 4.0

[sites]
at_pixels = "all"

[chip]
rows = 2
cols = 2

[chip.pixel]
qe = 0.4
read_noise_e = 100.0
dark_current_nA_per_cm2 = 0.05
prnu_frac = 0.0
dsnu_frac = 0.0

[chip.adc]
bits = 16
clock_hz = 100.0e6

[chip.memory]
word_bits = 24

[chip.dsp]
n_dark_frames = 4
cms_samples = 2
average_frames = 1

[chip.timing]
frame_period_s = 1.0
t_int_s = 0.99

[run]
duration_s = 12.0
"""

#: The table's x key, and its values in :data:`TABLE`.
X = "assay.photons_per_s_per_um2"
TABLE = f"""# SNR of the tiny chip at five light levels
{X} [photons/s/um2], snr_power [1], snr_power_se [1]
0.3, 110.0, 5.0
0.6, 500.0, 17.0
1.0, 1380.0, 16.0
1.5, 3200.0, 50.0
2.0, 5650.0, 35.0
"""

STUDY = f"""
[study]
name = "cal_tiny"
kind = "calibrate"
scenario = "tiny.toml"
seed = 3
replicates = 3
optimiser = {{ popsize = 4, generations = 4 }}

[[study.parameter]]
key = "chip.pixel.qe"
range = [0.2, 0.8]
why = "a front-side CMOS diode at 560 nm: 0.3-0.6, widened"

[study.target]
kind = "table"
path = "target.csv"
x = "{X}"
y = "snr_power"
"""


def write_study(folder: Path, study: str = STUDY, table: str = TABLE,
                scenario: str = TINY) -> Path:
    """The scenario, the table and the study side by side in ``folder``."""
    (folder / "tiny.toml").write_text(scenario, encoding="utf-8")
    (folder / "target.csv").write_text(table, encoding="utf-8")
    path = folder / "study.toml"
    path.write_text(study, encoding="utf-8")
    return path


def refused(folder: Path, study: str = STUDY, table: str = TABLE) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        load_study(write_study(folder, study, table))
    exc = info.value
    assert exc.source and exc.key and exc.allowed, exc
    return exc


def test_a_valid_calibration_loads_with_its_axis_metric_and_parameters(tmp_path):
    study = load_study(write_study(tmp_path))
    cal = study.calibration
    assert study.kind == "calibrate" and cal.objective == "chi2" and cal.replicates == 3
    assert [a.key for a in study.axes] == [X] and study.axes[0].values == (0.3, 0.6, 1.0, 1.5,
                                                                           2.0)
    assert study.metrics == ("snr_power",)
    (p,) = cal.parameters
    assert (p.key, p.lo, p.hi, p.log, p.reference) == ("chip.pixel.qe", 0.2, 0.8, False, 0.4)
    assert p.value(0.5) == pytest.approx(0.5) and p.unit(0.8) == pytest.approx(1.0)


def test_a_range_over_a_decade_is_searched_in_log_space(tmp_path):
    text = STUDY.replace('key = "chip.pixel.qe"\nrange = [0.2, 0.8]',
                         'key = "chip.pixel.read_noise_e"\nrange = [10.0, 1000.0]')
    (p,) = load_study(write_study(tmp_path, text)).calibration.parameters
    assert p.log and p.value(0.5) == pytest.approx(100.0)  # the geometric middle
    assert p.unit(100.0) == pytest.approx(0.5)


@pytest.mark.parametrize(("old", "new", "key", "says"), [
    ('key = "chip.pixel.qe"', 'key = "chip.pixel.qee"', "study.parameter[0].key",
     "did you mean 'qe'"),
    ('key = "chip.pixel.qe"', 'key = "chip.pixel.true_cds"', "study.parameter[0].key",
     "not a choice or a switch"),
    ('key = "chip.pixel.qe"', 'key = "chip.dsp.mode"', "study.parameter[0].key",
     "not a choice or a switch"),
    ("range = [0.2, 0.8]", "range = [0.2, 1.5]", "study.parameter[0].range",
     "outside the key's own range"),
    ("range = [0.2, 0.8]", "range = [0.8, 0.2]", "study.parameter[0].range", "lo must be below"),
    ("range = [0.2, 0.8]", "range = [0.2, nan]", "study.parameter[0].range", "finite"),
    ("range = [0.2, 0.8]", "range = [0.2]", "study.parameter[0].range", "two finite numbers"),
    ('why = "a front-side CMOS diode at 560 nm: 0.3-0.6, widened"', 'why = " "',
     "study.parameter[0].why", "physically meaningful"),
    ("seed = 3", "seed = 3\nreplicates_ = 2", "study.replicates_", "did you mean"),
    ("seed = 3", 'seed = 3\nsearch = "grid"', "study.search", 'kind = "calibrate"'),
    ("replicates = 3", "replicates = 1", "study.replicates", "[2, 1000]"),
    ('path = "target.csv"', 'path = "missing.csv"', "study.target.path", "no such file"),
    ('kind = "table"', 'kind = "flowgram"', "study.target.kind",
     "not built yet: the reads' calibration (SFF/BAM flowgrams) is not built; targets "
     "supported: table, emva1288"),
    ('kind = "table"', 'kind = "csv"', "study.target.kind", "'table', 'emva1288'"),
    (f'x = "{X}"', 'x = "chip.pixel.true_cds"', "study.target.x", "not a number"),
    ('y = "snr_power"', 'y = "sites_detected"', "study.target.y", "a rate or a loss"),
    ('y = "snr_power"', 'y = "base_error_rate"', "study.target.y", "a rate or a loss"),
    ('y = "snr_power"', 'y = "q20_read_length"', "study.target.y", "needs base calls"),
    ('y = "snr_power"', 'y = "light"', "study.target.y", "a metric with a number per run"),
    ("seed = 3", 'seed = 3\nobjective = "l1"', "study.objective", "'chi2', 'wls'"),
    ("seed = 3", "seed = 3\nconfidence = 1.5", "study.confidence", "[0.5, 0.999]"),
    ("popsize = 4", "popsize = 2", "study.optimiser.popsize", "[4, 50]"),
    ("popsize = 4", "popsize = 4, seed = 2", "study.optimiser.seed", "unknown key"),
    ("seed = 3", 'seed = 3\nset = { "chip.pixel.qe" = 0.5 }', "study.parameter[0].key",
     "fixed by study.set"),
])
def test_bad_study_keys_are_refused_naming_the_key(tmp_path, old, new, key, says):
    assert old in STUDY
    exc = refused(tmp_path, STUDY.replace(old, new, 1))
    assert exc.source.endswith("study.toml") and exc.key == key and says in exc.allowed, exc


def test_a_parameter_listed_twice_or_on_the_tables_x_is_refused(tmp_path):
    twice = STUDY.replace("[study.target]", '[[study.parameter]]\nkey = "chip.pixel.qe"\n'
                          'range = [0.3, 0.6]\nwhy = "again"\n\n[study.target]')
    assert "listed twice" in refused(tmp_path, twice).allowed
    on_x = STUDY.replace('key = "chip.pixel.qe"\nrange = [0.2, 0.8]',
                         f'key = "{X}"\nrange = [0.1, 5.0]')
    assert "the table's x" in refused(tmp_path, on_x).allowed


def test_no_parameter_and_no_target_are_refused(tmp_path):
    none = re.sub(r"\[\[study.parameter\]\].*?\n\n", "", STUDY, flags=re.S)
    assert refused(tmp_path, none).key == "study.parameter"
    no_target = STUDY.split("[study.target]")[0]
    assert refused(tmp_path, no_target).key == "study.target"


@pytest.mark.parametrize(("old", "new", "key", "says"), [
    ("snr_power [1], snr_power_se", "snr_power [dB], snr_power_se", "line 2, column snr_power",
     "the unit of snr_power is [1]"),
    ("[photons/s/um2]", "[photons/s/mm2]", f"line 2, column {X}", "photons/s/µm²"),
    ("snr_power_se [1]", "snr_power_sd [1]", "line 2 (header)", "not a column of this fit"),
    ("snr_power_se [1]", "snr_power_se", "line 2 (header)", "`name [unit]`"),
    (", snr_power [1]", ", snr_power_x [1]", "line 2 (header)", "not a column"),
    ("0.6, 500.0, 17.0", "0.6, 500.0", "line 4", "must hold 3 values"),
    ("0.6, 500.0, 17.0", "0.6, 500.0, 0.0", "line 4, column snr_power_se", "> 0"),
    ("0.6, 500.0, 17.0", "0.6, inf, 17.0", "line 4, column snr_power", "finite"),
    ("0.6, 500.0, 17.0", "-0.6, 500.0, 17.0", f"line 4, column {X}", "must be a number"),
])
def test_bad_tables_are_refused_naming_the_file_line_and_column(tmp_path, old, new, key, says):
    assert old in TABLE
    exc = refused(tmp_path, table=TABLE.replace(old, new, 1))
    assert exc.source.endswith("target.csv") and exc.key == key and says in exc.allowed, exc


def test_fewer_points_than_a_fit_needs_are_refused(tmp_path):
    two = "\n".join(TABLE.splitlines()[:4]) + "\n"  # comment, header, two rows
    two_params = STUDY.replace("[study.target]", '[[study.parameter]]\nkey = '
                               '"chip.pixel.read_noise_e"\nrange = [10.0, 400.0]\nwhy = "x"\n\n'
                               "[study.target]")
    exc = refused(tmp_path, two_params, two)
    assert exc.key == "study.target.path" and "fewer points than a fit needs (3" in exc.allowed
    load_study(write_study(tmp_path, STUDY, two))  # one key: two points are enough


def test_chi2_needs_standard_errors_and_wls_is_the_default_without(tmp_path):
    no_se = "\n".join(",".join(line.split(",")[:2]) for line in TABLE.splitlines()) + "\n"
    assert load_study(write_study(tmp_path, STUDY, no_se)).calibration.objective == "wls"
    exc = refused(tmp_path, STUDY.replace("seed = 3", 'seed = 3\nobjective = "chi2"'), no_se)
    assert exc.key == "study.objective" and "snr_power_se" in exc.allowed


def test_replicate_rows_are_merged_by_inverse_variance():
    x, y, se, n = merge_replicates([2.0, 1.0, 2.0], [10.0, 5.0, 20.0], [1.0, 1.0, 2.0])
    assert x == (1.0, 2.0) and n == (1, 2)
    assert y[1] == pytest.approx((10.0 / 1 + 20.0 / 4) / (1 + 1 / 4))
    assert se[1] == pytest.approx(1 / math.sqrt(1.25))
    assert merge_replicates([1, 1], [2.0, 4.0], None)[1:3] == ((3.0,), None)


@pytest.mark.parametrize(("key", "unit"), [
    ("chip.pixel.capacitance_fF", "fF"), ("chip.pixel.read_noise_e", "e⁻"),
    ("chip.pixel.dark_current_nA_per_cm2", "nA/cm²"), ("chip.adc.bits", "1"),
    ("assay.photons_per_s_per_um2", "photons/s/µm²"), ("assay.turnover_per_s", "1/s"),
    ("chip.timing.t_int_s", "s"), ("chip.pitch_um", "µm"), ("chip.pixel.qe", "1"),
    ("chip.adc.comparator_noise_uV", "µV"), ("chip.pixel.temperature_C", "°C"),
])
def test_a_keys_unit_comes_from_its_name(key, unit):
    assert key_unit(key) == unit


@pytest.mark.parametrize(("a", "b", "same"), [
    ("photons/s/um2", "photons/s/µm²", True), ("e-", "e⁻", True), ("nA/cm^2", "nA/cm²", True),
    ("degC", "°C", True), ("fF", "pF", False), ("1", "dB", False), ("s", "ms", False),
])
def test_unit_spellings(a, b, same):
    assert same_unit(a, b) is same


def test_an_absent_emva_data_set_is_refused_naming_the_path_looked_for(tmp_path):
    text = STUDY.split("[study.target]")[0].replace("replicates = 3\n", "") + \
        '[study.target]\nkind = "emva1288"\npath = "no_such_set"\n'
    exc = refused(tmp_path, text)
    assert exc.key == "study.target.path" and exc.value == "no_such_set"
    assert str((tmp_path / "no_such_set" / "EMVA1288_Data.txt").resolve()) in exc.allowed


def test_nothing_is_written_when_a_study_is_refused(tmp_path):
    from chiptwin.cli import main

    path = write_study(tmp_path, STUDY.replace("range = [0.2, 0.8]", "range = [0.2, 2.0]"))
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_changed_table_changes_the_studys_identity(tmp_path):
    a = load_study(write_study(tmp_path)).hash
    b = load_study(write_study(tmp_path, table=TABLE.replace("5650.0", "5651.0"))).hash
    assert a != b
