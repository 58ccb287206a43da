"""The propagated noise against the spread it predicts, by Monte Carlo over seeds.

One chip (``chip.fixed_pattern_seed`` pinned), the scene prepared once, 500 seeds of the small
pyrosequencing scenario in its 8 key flows of 4 s (36 frames; the 284-frame scene costs 8 times
more per seed and checks the same per-frame propagation). Tolerance: the standard error of a
sample standard deviation of n normal draws is σ/√(2(n−1)) (3.2 % at n = 500); every check
allows 4 of them (12.7 %). The two sites are independent (their own pixels, draws and dark
reference): pooled, their 2 × 500 standardised levels check the level's spread within 4 standard
errors of 1,000 draws (8.9 %), the resolution the single-site checks had at 1,000 seeds.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from chiptwin.config import load_scenario
from chiptwin.twin.runner import prepare, run_prepared

N_SEEDS = 500
TOL = 4 / np.sqrt(2 * (N_SEEDS - 1))
SHORT_FLOWS = ["assay.n_flows=8", "assay.flow_period_s=4.0", "run.duration_s=36.0"]


@pytest.fixture(scope="module")
def seeds_of_small(tmp_path_factory):
    from tests.conftest import SMALL

    path = tmp_path_factory.mktemp("mc") / "small.toml"
    path.write_text(SMALL)
    s = load_scenario(path, ["chip.fixed_pattern_seed=1", *SHORT_FLOWS])
    scene = prepare(s)
    runs = [run_prepared(replace(s, scenario=replace(s.scenario, seed=k)), scene).summary
            for k in range(N_SEEDS)]
    return runs


def test_run_total_level_spread_matches_signal_sd(seeds_of_small):
    """A site's 1-mer level (mean of the key's 1-mer flows) spreads as ``signal_sd_e`` says;
    ``noise_e`` is one flow's noise, and the level spreads less (shared dark reference)."""
    z = []
    for site in range(2):
        level = np.array([r["sites"][site]["signal_e"] for r in seeds_of_small])
        sd = seeds_of_small[0]["sites"][site]["signal_sd_e"]
        noise = seeds_of_small[0]["sites"][site]["noise_e"]
        assert np.std(level, ddof=1) / sd == pytest.approx(1.0, abs=TOL)
        assert sd < noise
        z.append((level - level.mean()) / sd)
    pooled = np.sqrt(np.sum(np.square(z)) / (2 * (N_SEEDS - 1)))  # a mean removed per site
    assert pooled == pytest.approx(1.0, abs=4 / np.sqrt(2 * 2 * (N_SEEDS - 1)))


def test_per_flow_spread_matches_flow_noise(seeds_of_small):
    sums = np.array([[f["signal_e"] for f in r["flows"]] for r in seeds_of_small])
    noise = np.array([f["noise_e"] for f in seeds_of_small[0]["flows"]])
    ratio = np.std(sums, axis=0, ddof=1) / noise
    assert np.all(np.abs(ratio - 1.0) < TOL), ratio
