"""Chip-level equivalence of the multi-core binned path: on an array of more than one
chunk of random streams, the pixels of chunk 0 draw exactly what the frame-by-frame
``sample_frame`` path draws (tests/pixel/test_pixel_chunks.py, test_pixel_frames.py), and the
pixels of the other chunks, drawn from their own streams on other threads, must give DSP outputs
with the same distribution, whose mean is what the ``expected`` level propagates.

Eight seeds of the small scenario on a 48 × 48 chip (2,304 pixels: chunk 0 holds pixels
0 … 2,047, chunk 1 the other 256): one DSP output per blank pixel per seed (block 20, so the
samples are independent: the blocks of one pixel share its dark reference). A DSP output of a
blank pixel lies on the lattice of one ADC code over M·N = 8 samples; compared in lattice steps
(integers) so that the expected level's tiny per-pixel means (≈ 1e-8 e⁻) do not split ties.
Tolerances: KS p > 1e-3 between the chunks; in each chunk the mean of (output − expected mean)
within 4 standard errors of 0, and its variance within 10 % of the expected level's variance
(the standard error of a variance of ≥ 2,000 samples is ≈ 3 %).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from chiptwin.config import load_scenario
from chiptwin.pixel import CHUNK_PIXELS
from chiptwin.twin import stages
from chiptwin.twin.runner import Recorder, prepare, simulate, stage_rng

WIDE = ["chip.rows=48", "chip.cols=48", "chip.memory.capacity_bits=3000000"]
SEEDS = range(8)
BLOCK = 20


def test_chunks_draw_the_same_distribution_whose_mean_is_expected(small_toml):
    s = load_scenario(small_toml, WIDE)
    scene = prepare(s)
    expected = simulate(s, scene, "expected", stage_rng(0, "pixel"), Recorder())
    far = np.ones(s.chip.n_pixels, bool)
    for p in stages.site_pixel_indices(s):  # blanks: out of reach of the sites' light
        r, c = divmod(int(p), s.chip.cols)
        rows, cols = np.divmod(np.arange(s.chip.n_pixels), s.chip.cols)
        far &= np.maximum(abs(rows - r), abs(cols - c)) > 3
    step = scene.sensor.e_per_lsb / (s.chip.dsp.cms_samples * s.chip.dsp.average_frames)
    k, dev = [], []
    for seed in SEEDS:
        out = simulate(s, scene, "binned", stage_rng(seed, "pixel"), Recorder())
        k.append(np.rint(out.value_e[BLOCK] / step))
        dev.append(out.value_e[BLOCK] - expected.mean_e[BLOCK])
    k, dev = np.array(k), np.array(dev)
    var = expected.var_e2[BLOCK] + expected.dark_var_e2
    index = np.arange(s.chip.n_pixels)
    chunks = [far & (index < CHUNK_PIXELS), far & (index >= CHUNK_PIXELS)]
    assert chunks[1].sum() >= 200 and chunks[0].sum() >= 1500
    assert stats.ks_2samp(k[:, chunks[0]].ravel(), k[:, chunks[1]].ravel()).pvalue > 1e-3
    for chunk in chunks:
        d = dev[:, chunk].ravel()
        assert abs(d.mean()) < 4 * d.std() / np.sqrt(d.size)
        assert d.var() == pytest.approx(var[chunk].mean(), rel=0.10)
