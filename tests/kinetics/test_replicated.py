"""One kinetics evaluation shared by identical sites: bit for bit the per-site source."""

from __future__ import annotations

import numpy as np
import pytest

from chiptwin import kinetics
from chiptwin.config import load_scenario
from chiptwin.kinetics import PulseTrain, Replicated
from chiptwin.twin import stages


def _train(n: int) -> PulseTrain:
    return PulseTrain(site=np.repeat(np.arange(n), 3), onset_s=np.tile([0.0, 1.5, 4.0], n),
                      amplitude_per_s=np.tile([1e6, 3e5, 2e4], n),
                      decay_per_s=np.tile([0.7, 0.0, 2.5], n), n_sites=n)


def test_rows_are_the_per_site_sources_bit_for_bit():
    edges = np.array([0.0, 0.3, 1.5, 1.5, 2.0, 7.25, 100.0])
    shared, per_site = Replicated(_train(1), 5), _train(5)
    assert np.array_equal(shared.photons(edges), per_site.photons(edges))
    assert np.array_equal(shared.rate(edges), per_site.rate(edges))
    assert shared.photons(edges).shape == (5, 6) and isinstance(shared, kinetics.LightSource)


def test_only_a_one_site_source_is_shared():
    with pytest.raises(ValueError, match="2 sites"):
        Replicated(_train(2), 4)


def test_identical_sites_of_a_scene_share_one_evaluation():
    s = load_scenario("pyro_array_256")
    edges = np.linspace(0.0, 40.0, 81)
    src = stages.light_source(s)
    assert isinstance(src, Replicated) and src.n_sites == len(stages.site_pixels(s))
    full = stages._closed_form_source(s, src.n_sites)
    assert np.array_equal(src.photons(edges), full.photons(edges))


def test_per_site_amounts_are_not_shared():
    s = load_scenario("atp_dose_response")
    assert isinstance(stages.light_source(s), PulseTrain)
