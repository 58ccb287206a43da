"""The kinetics and photon levels selected from a scenario: cascade and events in the chip."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.cli import main
from chiptwin.config import ScenarioError, load_scenario
from chiptwin.fidelity import run
from chiptwin.pixel import dark_current_e_per_s
from tests.conftest import IDEAL_ADC, SCENARIOS


def test_cascade_level_calls_the_template_and_reports_its_level(small_toml):
    result = run(small_toml, ["run.fidelity.kinetics=cascade"])
    assert result.summary["fidelity"]["kinetics"] == "cascade"
    assert result.summary["called_sequence"] == result.summary["true_sequence"]


def test_cascade_light_matches_the_closed_form_with_the_measured_yield(small_toml):
    """The cascade calibrated to the same measured yield emits the same photons per site (1 %)."""
    closed = run(small_toml).arrays["site_photons"].sum(axis=1)
    cascade = run(small_toml, ["run.fidelity.kinetics=cascade"]).arrays["site_photons"].sum(axis=1)
    np.testing.assert_allclose(cascade, closed, rtol=0.01)


def test_cascade_is_pyrosequencing_only(capsys):
    assert main(["validate", str(SCENARIOS / "atp_glow.toml"),
                 "--set", "run.fidelity.kinetics=cascade"]) == 2
    assert "run.fidelity.kinetics" in capsys.readouterr().err


def test_events_level_agrees_with_expected(small_toml):
    """Counting exact arrivals gives the flow values of the expected level within 5 σ."""
    events = run(small_toml, ["run.fidelity.photons=events"]).summary
    expected = run(small_toml, ["run.fidelity.photons=expected"]).summary
    assert events["fidelity"]["photons"] == "events"
    for fe, fx in zip(events["flows"], expected["flows"], strict=True):
        assert abs(fe["signal_e"] - fx["signal_e"]) < 5 * fx["noise_e"]
    assert events["sites"][0]["saturated_frames"] == 0
    assert events["sites"][0]["first_saturation_s"] is None


def test_events_level_times_the_well_filling():
    """Constant light r e⁻/s fills a well of W e⁻ after the W-th arrival: W/r on average with
    standard deviation √W/r (Gamma(W, r)); tolerance 5 σ. Counts per window cannot say this."""
    flux = 1.0e4  # photons/s/µm², 3e7 e⁻/s on a 100 µm diode at QE 0.3
    s = load_scenario(SCENARIOS / "snr10_requirement.toml",
                      [f"assay.photons_per_s_per_um2={flux}", "run.fidelity.photons=events",
                       ])
    site = run(s).summary["sites"][0]
    px = s.chip.pixel
    rate = flux * 1e4 * px.qe + dark_current_e_per_s(px.dark_current_nA_per_cm2, 1e4, 25.0)
    window_start = s.assay.start_s + s.chip.timing.t_reset_s + 2 * s.chip.adc.conversion_time_s
    assert site["saturated_frames"] == 1
    t_fill = site["first_saturation_s"] - window_start
    assert t_fill == pytest.approx(px.full_well_e / rate, abs=5 * np.sqrt(px.full_well_e) / rate)


def test_unbuilt_level_is_refused(small_toml):
    with pytest.raises(ScenarioError, match="run.fidelity.optics"):
        load_scenario(small_toml, ["run.fidelity.optics=raytrace"])


def test_fixed_dsp_needs_codes(small_toml):
    """The expected level carries no ADC codes: a fixed or RTL DSP would compute nothing."""
    with pytest.raises(ScenarioError, match="run.fidelity.photons"):
        load_scenario(small_toml, ["run.fidelity.photons=expected", "chip.dsp.mode=fixed"])


def test_run_checks_a_scenario_built_in_python(small_toml):
    """A Scenario changed with dataclasses.replace meets the same rules as a file."""
    from dataclasses import replace

    s = load_scenario(small_toml)
    bad = replace(s, chip=replace(s.chip, timing=replace(s.chip.timing, t_int_s=5.0)))
    with pytest.raises(ScenarioError, match="frame_period_s"):
        run(bad)


def test_required_flux_does_not_depend_on_the_scenes_flux():
    """The flux for power SNR 10 is a property of the chip: the same from 0.5 or 0 photons/s/µm²
    (1e-9: the chain is linear below the full well)."""
    path = SCENARIOS / "snr10_requirement.toml"
    lit = run(path).summary["required_flux_photons_per_s_per_um2"]
    dark = run(path, ["assay.photons_per_s_per_um2=0"]).summary
    assert dark["required_flux_photons_per_s_per_um2"] == pytest.approx(lit, rel=1e-9)
    assert dark["fidelity"]["kinetics"] == dark["fidelity"]["optics"] == "none"
    assert not dark["sites"][0]["detected"]


def test_dropped_frames_make_results_invalid(small_toml):
    s = run(small_toml, ["chip.dsp.clock_hz=20", "chip.memory.capacity_bits=16000"]).summary
    assert s["results_valid"] is False
    assert run(small_toml).summary["results_valid"] is True


def test_matched_filter_estimates_the_same_light_with_less_noise(small_toml):
    """``run.light_estimator = "matched"`` weights each DSP output by exp(−k t) (eq. 19's decay).

    For light that is a pure exponential from the window's start (the first flow; an ATP glow) it
    is unbiased: the same expected total as the plain sum (1e-9), with a smaller variance."""
    plain = run(small_toml, ["run.fidelity.photons=expected"]).summary
    matched = run(small_toml, ["run.fidelity.photons=expected",
                               "run.light_estimator=matched"]).summary
    assert matched["flows"][0]["signal_e"] == pytest.approx(plain["flows"][0]["signal_e"],
                                                             rel=1e-9)
    assert all(m["noise_e"] < p["noise_e"] for m, p in zip(matched["flows"], plain["flows"],
                                                             strict=True))
    assert matched["light_estimator"] == "matched"
    assert run(small_toml, ["run.light_estimator=matched"]).summary["called_sequence"] == (
        plain["true_sequence"])
    # the ideal converter: the as-built one's INL bow bends the light's law (by 5e-7 here)
    atp = [run(SCENARIOS / "atp_glow.toml", [*IDEAL_ADC, "run.fidelity.photons=expected",
                                             f"run.light_estimator={e}"]).summary["sites"][0]
           for e in ("sum", "matched")]
    assert atp[1]["signal_e"] == pytest.approx(atp[0]["signal_e"], rel=1e-9)
    assert atp[1]["noise_e"] < 0.5 * atp[0]["noise_e"]
