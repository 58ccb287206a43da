"""Common random numbers across levels: the kTC, read-noise and comparator normals have a stream
of their own, so two runs of one seed that differ in a level the counts do not see, or in the
light under the ``gaussian`` shot level (the same ``z`` a pixel-frame whatever the mean), share
their draws and a few seeds resolve a small difference (:func:`chiptwin.fidelity.ladder.
common_draws`). And every level still gives the same bits for the same seed."""

from __future__ import annotations

import json

import numpy as np
import pytest

from chiptwin.config import load_scenario
from chiptwin.fidelity.compare import ratio_of_means
from chiptwin.fidelity.ladder import LEVELS, common_draws, reference_levels, with_levels
from chiptwin.twin.runner import prepare, run_prepared
from tests.conftest import SCENARIOS

#: atp_glow cut to 30 s, the gaussian shot level, a 16-bit ADC (95 e⁻ an LSB: the 13-bit ADC's
#: 762, its 0.29-LSB rounding re-drawn when the light moves hides the coupling of the counts).
FINE = ["run.duration_s=30.0", 'run.fidelity.shot="gaussian"', "chip.adc.bits=16",
        "chip.adc.clock_hz=60e6"]


def _signals(sv, scene, seeds):
    out = []
    for seed in seeds:
        sv = with_seed(sv, seed)
        out.append([y["signal_e"] for y in run_prepared(sv, scene).summary["sites"]])
    return np.array(out)


def with_seed(sv, seed):
    return sv.__class__(**{**sv.__dict__, "scenario": sv.scenario.__class__(
        **{**sv.scenario.__dict__, "seed": seed})})


def test_a_light_swap_on_common_numbers_resolves_with_few_seeds():
    """optics raytrace against psf (≈ 1 % apart) over 5 seeds: the paired interval of every
    site's signal ≥ 5× narrower than the same runs on independent seeds (measured 28-80×)."""
    s = load_scenario(SCENARIOS / "atp_glow.toml", FINE)
    a, b = with_levels(s, {"optics": "raytrace"}), with_levels(s, {"optics": "psf"})
    levels = {st: getattr(a.run.fidelity, st) for st in ("kinetics", "photons", "optics", "shot")}
    assert common_draws(levels, {**levels, "optics": "psf"})
    scenes = prepare(a), prepare(b)
    x = _signals(a, scenes[0], range(5))
    paired = ratio_of_means(x, _signals(b, scenes[1], range(5)))
    independent = ratio_of_means(x, _signals(b, scenes[1], range(100, 105)))
    for p, q in zip(paired, independent, strict=True):
        assert 5 * p.half <= q.half, (p, q)


def test_what_common_draws_says():
    ref = {"kinetics": "cascade", "photons": "events", "optics": "psf", "shot": "poisson",
           "dsp": "fixed", "adc": "as_built"}
    assert common_draws({**ref, "dsp": "float", "adc": "ideal"}, ref)
    assert common_draws({**ref, "photons": "binned"}, ref)  # the same counts
    assert not common_draws({**ref, "shot": "gaussian"}, ref)
    assert not common_draws({**ref, "photons": "expected"}, ref)  # no draws against draws
    binned = {**ref, "photons": "binned"}
    assert not common_draws({**binned, "optics": "na2"}, binned)  # Poisson of other means
    gauss = {**binned, "shot": "gaussian"}
    assert common_draws({**gauss, "optics": "na2", "kinetics": "closed_form"}, gauss)
    assert common_draws({**gauss, "photons": "events", "optics": "na2"}, gauss)
    assert common_draws({**ref, "photons": "expected"}, {**gauss, "photons": "expected"})


@pytest.mark.parametrize("stage", list(LEVELS))
def test_same_seed_same_bits_at_every_level(stage):
    """Each level of each stage (the others at the reference's), run twice on one seed: the
    same summary, bit for bit (wall times aside)."""
    s = load_scenario(SCENARIOS / "atp_glow.toml", ["run.duration_s=25.0"])
    ref = reference_levels(s)
    for level in LEVELS[stage]:
        sv = with_levels(s, {**ref, "photons": "binned", stage: level})
        try:
            scene = prepare(sv)
        except Exception as exc:  # a level the scene refuses (na2 under a top surface)
            assert "ScenarioError" in type(exc).__name__
            continue
        a, b = (run_prepared(with_seed(sv, 3), scene).summary for _ in range(2))
        for x in (a, b):
            x.pop("wall_time_s"), x.pop("stage_time_s")
        assert json.dumps(a, sort_keys=True, default=str) == json.dumps(b, sort_keys=True,
                                                                        default=str)
