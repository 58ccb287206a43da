"""The twin's reads under a flow-value model (chiptwin.twin.reads): the caller's noise adds the
chemistry's (Monte Carlo against the model's own draws), the key normalisation leaves an
``h``-mer at ``h + a`` as the model states, scenes without a chemistry read exactly as before,
each study replicate draws its own chemistry, the round caller is costed, and the run keeps the
corrected values."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin.config import load_scenario
from chiptwin.config.cost import wall_estimate
from chiptwin.kinetics import pyro
from chiptwin.kinetics.chemistry import FlowModel, draw_flow_values, flow_light
from chiptwin.twin import reads as twin_reads
from tests.kinetics.test_long_reads import assert_each_replicate_prepares_its_own_light

SCENES = "scenarios"

#: The 454 FLX preset's magnitudes, the empty flows' light far from 0 (no clipping: the
#: variance compared is the model's, not the clip's).
MODEL = FlowModel(flow_yield_cv=0.06, flow_noise_sd=0.06, flow_background=0.015,
                  well_noise_cv=0.9, empty_flow_law="lognormal", empty_flow_mean=0.3,
                  empty_flow_sd=0.015)


def test_site_noise_adds_the_chemistry_variance_monte_carlo():
    """With a silent chain, the caller's variance ``floor + shot·h + ref·h²`` (its key-scale
    part ``(cv² + sd²)/K·h²`` aside, which a single draw does not carry; and the empty flows'
    variance off the non-empty ones, 3 % of a 1-mer's here) is the variance of the model's
    flow values, 200,000 draws per length, within 3 % (the draws' own error: < 1 % at the
    well mixture's kurtosis)."""
    key_n = pyro.key_flow_counts("TCAG", "TACG")
    noise = twin_reads.site_noise(np.zeros(key_n.size), 1.0, 0.0, key_n, MODEL)
    key_part = (MODEL.flow_yield_cv**2 + MODEL.flow_noise_sd**2) / int((key_n == 1).sum())
    rng = np.random.default_rng(7)
    for h in range(5):
        y = draw_flow_values(np.full(200_000, h), MODEL, rng)
        predicted = float(noise.var(np.array(float(h)))) - key_part * h * h
        if h:  # one floor for every flow: the empty flows' variance over-counted on the others
            predicted -= MODEL.empty_flow_sd**2
        assert predicted == pytest.approx(float(y.var()), rel=0.03), h
    # without a model: the chain's terms alone, as before
    plain = twin_reads.site_noise(np.full(key_n.size, 4.0), 2.0, 0.2, key_n)
    assert (plain.floor, plain.shot, plain.ref) == (1.0, 0.0, pytest.approx(0.01))


def test_key_scale_leaves_an_h_mer_at_h_plus_the_additive_light():
    """Dividing by the key's 1-mers reads an h-mer as (h + a)/(1 + a); times the key scale it
    reads h + a, the model's value (additive light alone: no draw has a spread)."""
    s = load_scenario(f"{SCENES}/pyro_454_flx.toml", ["assay.flow_yield_cv=0",
                      "assay.flow_noise_sd=0", "assay.well_noise_cv=0",
                      "assay.empty_flow_mean=0", "assay.empty_flow_sd=0"])
    a = s.assay.flow_background
    assert a > 0
    nucs, h = pyro.flow_incorporations(s.assay.template, s.assay.flow_order, 60)
    light = flow_light(h.astype(float), h, twin_reads.flow_model(s),
                       np.random.default_rng(0), 1)[0]
    norm = pyro.normalise_flows(light, pyro.key_flow_counts(s.assay.key, s.assay.flow_order))
    assert np.allclose(norm[h > 1], (h[h > 1] + a) / (1 + a))  # the bias the scale removes
    assert np.allclose(norm * twin_reads.key_scale(s), h + a)


@pytest.mark.parametrize("scene", ["pyro_1fmol", "pyro_long_read"])
def test_a_scene_without_chemistry_reads_as_before(scene):
    """No flow model: no key scale, the caller's input the despilled values
    (the calls' digests: tests/detection/test_caller_equivalence.py)."""
    s = load_scenario(f"{SCENES}/{scene}.toml")
    assert twin_reads.flow_model(s) is None
    assert twin_reads.key_scale(s) == 1.0
    v = np.random.default_rng(1).uniform(0, 3, (3, s.assay.n_flows))
    want = v
    if s.assay.caller == "dephase":
        want = twin_reads.despill(v, twin_reads.spill_ratio(s),
                                  pyro.key_flow_counts(s.assay.key, s.assay.flow_order))
    assert np.array_equal(twin_reads.caller_input(s, v), want)


def _small_flx(*sets: str):
    return load_scenario(f"{SCENES}/pyro_454_flx.toml",
                         ["sites.at_pixels=[[4, 8], [2, 3]]", "assay.n_flows=40",
                          "run.duration_s=2420", *sets])


def test_each_study_replicate_draws_its_own_chemistry():
    """The point's scene is prepared once; with a flow model every replicate (another seed)
    prepares its light again: the same chip (a fixed pattern seed) and another run."""
    from chiptwin.study import engine

    s = _small_flx("chip.fixed_pattern_seed=5", "assay.dna_cv=0")
    assert_each_replicate_prepares_its_own_light(s)
    assert engine._scene_per_row(s)
    assert not engine._scene_per_row(load_scenario(f"{SCENES}/pyro_1fmol.toml"))


def test_both_callers_are_costed():
    """The wall estimate counts the caller's posterior for ``round`` as for ``dephase``."""
    s = load_scenario(f"{SCENES}/pyro_1fmol.toml")
    assert s.assay.caller == "round"
    assert any("the round caller" in t.what for t in wall_estimate(s, beside=False))


def test_run_keeps_each_reads_corrected_values():
    """``read_corrected``: the dephase caller's phase-corrected values, near the true lengths
    over the read's first flows (the chemistry's spread is ≈ 0.1 a 1-mer)."""
    from chiptwin.twin.runner import run

    r = run(_small_flx())
    c, true_n = r.arrays["read_corrected"], r.arrays["read_true_n"]
    assert c.shape == r.arrays["read_calls"].shape
    err = np.abs(c[:, :30] - true_n[:30])
    assert np.median(err) < 0.15 and np.all(np.isfinite(c))
