"""The flow-value model (chiptwin.kinetics.chemistry): its sampler against its exact law, the fit
recovering known parameters (Monte Carlo), the presets as scenario keys, the twin's light."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from chiptwin.cli import main
from chiptwin.config import load_scenario
from chiptwin.config.schema import CHEMISTRIES
from chiptwin.kinetics.chemistry import (
    FlowModel,
    draw_flow_values,
    flow_light,
    flow_value_distribution,
)
from chiptwin.kinetics.chemistry_fit import (
    SEARCHED,
    fit_flow_model,
    histograms,
    ks_distance,
    total_variation,
)
from chiptwin.kinetics.chemistry_presets import PRESET_NAMES, PRESETS, preset_values
from chiptwin.twin import stages

#: A 454-like model (the FLX preset's magnitudes, with a homopolymer loss to recover).
TRUE = FlowModel(flow_yield_cv=0.06, flow_noise_sd=0.06, flow_background=0.01,
                 well_noise_cv=0.9, homopolymer_yield_loss=0.01, empty_flow_law="lognormal",
                 empty_flow_mean=0.08, empty_flow_sd=0.03)


def _empirical(values: np.ndarray, h: int) -> np.ndarray:
    return histograms(values, np.full(values.size, h), h)[h]


@pytest.mark.parametrize("law, mean, sd", [("lognormal", 0.08, 0.03), ("normal", -0.05, 0.12)])
@pytest.mark.parametrize("h", [0, 1, 3])
def test_draws_follow_the_stated_law(law, mean, sd, h):
    """200,000 draws of each length against :func:`flow_value_distribution` (chain noise on):
    the histogram's TV to the law is the Monte Carlo floor's (≈ 0.004–0.007 on these bins,
    measured), far below the 0.07–0.12 a wrong law shows (the FLX preset's own fit)."""
    model = replace(TRUE, empty_flow_law=law, empty_flow_mean=mean, empty_flow_sd=sd)
    y = draw_flow_values(np.full(200_000, h), model, np.random.default_rng(7), 1e-4, 1e-4)
    p = flow_value_distribution(h, model, 1e-4, 1e-4)
    assert p.sum() == pytest.approx(1.0, abs=1e-9)
    assert total_variation(_empirical(y, h), p) < 0.015
    assert ks_distance(_empirical(y, h), p) < 0.006  # DKW: P(KS > 0.006) < 1e-6 at n = 2e5


def test_a_wrong_law_is_told_apart():
    """The test above can fail: a 20 % larger yield CV moves a 3-mer's law by more than the
    Monte Carlo floor."""
    y = draw_flow_values(np.full(200_000, 3), TRUE, np.random.default_rng(8))
    wrong = flow_value_distribution(3, replace(TRUE, flow_yield_cv=0.072))
    assert ks_distance(_empirical(y, 3), wrong) > 0.01


@pytest.mark.slow
def test_fit_recovers_known_parameters_from_draws():
    """Monte Carlo: 200,000 seeded draws per length 0–5 from :data:`TRUE`, fitted back (the
    same search the presets came from). Each parameter within 10 % of its value (κ within
    0.003 absolute): the draws' own scatter moves them by a few % (the fit's likelihood on
    1.2 M flows)."""
    rng = np.random.default_rng(2026)
    targets = {h: _empirical(draw_flow_values(np.full(200_000, h), TRUE, rng), h)
               for h in range(6)}
    fit = fit_flow_model(targets, "lognormal").model
    for name in SEARCHED:
        got, want = getattr(fit, name), getattr(TRUE, name)
        tol = 0.003 if name == "homopolymer_yield_loss" else 0.1 * abs(want)
        assert got == pytest.approx(want, abs=tol), name


def test_flow_light_same_seed_same_bits_and_its_mean():
    """The twin's light per site and flow: reproducible from the seed, never negative, and
    over 20,000 sites a 2-mer's mean light is ``2(1 − κ) + background`` within 4 standard
    errors."""
    signal = np.array([1.0, 0.0, 2.0, 1.0])
    one = flow_light(signal, signal, TRUE, np.random.default_rng(3), 20_000)
    two = flow_light(signal, signal, TRUE, np.random.default_rng(3), 20_000)
    assert np.array_equal(one, two)
    assert one.shape == (20_000, 4) and (one >= 0).all()
    mean = 2 * (1 - TRUE.homopolymer_yield_loss) + TRUE.flow_background
    se = one[:, 2].std() / np.sqrt(one.shape[0])
    assert abs(one[:, 2].mean() - mean) < 4 * se


def test_each_parameter_is_range_checked_by_name():
    with pytest.raises(ValueError, match="flow_yield_cv = 0.9"):
        FlowModel(flow_yield_cv=0.9)
    with pytest.raises(ValueError, match="empty_flow_law = 'gamma'"):
        FlowModel(empty_flow_law="gamma")
    with pytest.raises(ValueError, match="lognormal"):
        FlowModel(empty_flow_mean=-0.1)


def test_presets_are_the_scenario_choices_and_explicit_keys_override():
    assert CHEMISTRIES == ("", *PRESET_NAMES)
    s = load_scenario("pyro_long_read", ['assay.chemistry="454_flx"',
                                         "assay.flow_noise_sd=0.2"])
    flx = preset_values("454_flx")
    assert s.assay.flow_yield_cv == flx["flow_yield_cv"]
    assert s.assay.empty_flow_mean == flx["empty_flow_mean"]
    assert s.assay.flow_noise_sd == 0.2  # the scene's own key wins
    assert stages.flow_model(s) == replace(PRESETS["454_flx"], flow_noise_sd=0.2)
    assert stages.flow_model(load_scenario("pyro_long_read")) is None


def test_unknown_preset_exits_2_naming_key_value_and_names(capsys):
    assert main(["run", "pyro_long_read", "--set", 'assay.chemistry="454_gs20"']) == 2
    err = capsys.readouterr().err
    assert "assay.chemistry" in err and "454_gs20" in err
    for name in PRESET_NAMES:
        assert name in err


def test_cascade_refuses_the_flow_model():
    with pytest.raises(ValueError, match="assay.flow_yield_cv"):
        load_scenario("pyro_long_read", ['assay.chemistry="454_flx"',
                                         'run.fidelity.kinetics="cascade"',
                                         "assay.droop_per_flow=0", "assay.dna_cv=0"])


@pytest.mark.slow
def test_a_scene_with_a_chemistry_gives_each_site_its_own_light():
    """Wired where the twin makes its flow signal: per site and flow, drawn from the run's
    seed; without a chemistry, the flowgram every site shares."""
    s = load_scenario("pyro_454_flx")
    n = 5
    light = stages.site_incorporations(s, n)
    assert light.shape == (n, s.assay.n_flows)
    assert np.array_equal(light, stages.site_incorporations(s, n))
    assert not np.array_equal(light[0], light[1])
    plain = load_scenario("pyro_long_read")
    assert stages.site_incorporations(plain, n).shape == (plain.assay.n_flows,)
