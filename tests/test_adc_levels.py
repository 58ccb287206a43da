"""The ADC's two levels on the ladder and under ``auto``: the ideal converter is
a cheaper level of the ADC when the scene's converter is not ideal, with its measured error, and
``auto`` takes it only within the budget."""

from __future__ import annotations

import pytest

from chiptwin.config import load_scenario
from chiptwin.fidelity import resolve
from chiptwin.fidelity.ladder import plan, run_ladder
from chiptwin.twin.levels import CachedEstimates, reference_levels, with_levels
from tests.conftest import REDUCED, SCENARIOS, SMALL

AS_BUILT = ["chip.adc.comparator_noise_uV=0", "chip.adc.comparator_noise_lsb=0.5",
            "chip.adc.inl_max_lsb=2"]
CHEAP_REFERENCE = {"kinetics": "closed_form", "photons": "expected", "optics": "psf",
                   "dsp": "float"}
#: The small scenario's 8 key flows of 4 s (36 frames, not 284): the ladder runs every rung (the
#: events and cascade rows cost ~10 ms a frame), and the adc row's error is per frame.
SHORT_FLOWS = ["assay.n_flows=8", "assay.flow_period_s=4.0", "run.duration_s=36.0"]


@pytest.fixture(autouse=True)
def _own_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


def _small(tmp_path, extra=()):
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    return load_scenario(path, list(extra))


def test_ladder_has_an_ideal_adc_row_with_its_error(tmp_path):
    """A converter with comparator noise and INL: the ladder's adc row ``ideal`` runs, and its
    noise error is far from 0 (0.5 LSB of comparator noise against 0.13 LSB of read noise)."""
    s = _small(tmp_path, [*AS_BUILT, *SHORT_FLOWS])
    ladder = run_ladder(s, replicates=2, reference=CHEAP_REFERENCE)
    assert ladder["reference"]["adc"] == "as_built"
    rows = [r for r in ladder["rows"] if r["stage"] == "adc"]
    assert [r["level"] for r in rows] == ["ideal"]
    assert rows[0]["errors"]["noise_rel"]["value"] > 0.05
    cheapest = next(r for r in ladder["rows"] if r["stage"] == "cheapest")
    assert cheapest["fidelity"]["adc"] == "ideal"


def test_an_ideal_converter_has_no_adc_row_and_costs_nothing(tmp_path):
    s = _small(tmp_path)
    assert all(r.stage != "adc" for r in plan(s))
    est = CachedEstimates(s, reference_levels(s), tmp_path / "est.sqlite")
    got = est.estimate("adc", "ideal", reference_levels(s))
    assert set(got.errors.values()) == {0.0} and "ideal" in got.how


def test_ideal_level_zeroes_every_as_built_effect(tmp_path):
    s = _small(tmp_path, [*AS_BUILT, "chip.adc.dnl_rms_lsb=0.3", "chip.adc.gain_sigma=0.01"])
    adc = with_levels(s, {"adc": "ideal"}).chip.adc
    assert not adc.as_built_keys and adc.bits == s.chip.adc.bits
    assert with_levels(s, {"adc": "as_built"}).chip.adc == s.chip.adc


def test_auto_keeps_as_built_within_a_tight_budget_and_takes_ideal_within_a_loose_one():
    """pyro_1fmol (reduced, 8 key flows of 4 s: 52 frames) with comparator noise and INL: the
    ideal converter misses the comparator's noise (power SNR ≈ 90 % too high on the scene's
    isotropic light; 62 % with 60 s flows). A budget of 1 % keeps the converter as built; one of
    100 % (the largest allowed) lets auto take the ideal one; both
    say why in the summary's reasons. (The calibrations are expected-level runs: no draws, the
    same pick every time.)"""
    base = [*REDUCED["pyro_1fmol"], "assay.flow_period_s=4.0", "run.duration_s=52.0", *AS_BUILT,
            'run.fidelity.adc="auto"']
    path = SCENARIOS / "pyro_1fmol.toml"
    tight = load_scenario(path, [*base, "run.error_budget.snr_rel=0.01"])
    _, choice = resolve(tight)
    assert choice.levels["adc"] == "as_built"
    reason = choice.summary()["fidelity_reason"]["adc"]
    assert "not ideal" in reason and "comparator_noise_lsb 0.5" in reason
    loose = load_scenario(path, [*base, "run.error_budget.snr_rel=1.0"])
    resolved, choice = resolve(loose)
    assert choice.levels["adc"] == "ideal"
    assert choice.summary()["fidelity_reason"]["adc"].startswith("ideal: calibration")
    assert not resolved.chip.adc.as_built_keys and "adc" in choice.cached
