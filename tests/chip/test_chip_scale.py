"""The run at chip scale: memory flat in frames, numbers independent of the thread
count, blocks of frames kept or made giving the same numbers, ``save_frames`` written as read, and
the sparse coupling of many sites against the dense matrix."""

from __future__ import annotations

import tracemalloc
from dataclasses import replace

import numpy as np
import pytest

from chiptwin import limits
from chiptwin.config import budget, load_scenario
from chiptwin.fidelity import run
from chiptwin.pixel import CHUNK_PIXELS
from chiptwin.pixel import frames as frames_module
from chiptwin.report import open_run, write_outputs
from chiptwin.twin import stages
from chiptwin.twin.runner import Recorder, prepare, run_prepared, simulate, stage_rng

#: The small scenario on a 48 × 48 array (2,304 pixels: two chunks of random streams), with frame
#: memory for 20 frames.
WIDE = ["chip.rows=48", "chip.cols=48", "chip.memory.capacity_bits=3000000"]


@pytest.fixture
def wide(small_toml):
    s = load_scenario(small_toml, WIDE)
    assert s.chip.n_pixels > CHUNK_PIXELS
    return s


def test_numbers_do_not_depend_on_the_thread_count(wide, monkeypatch):
    """The whole run with its pixel chunks drawn on 1 and on 3 threads: the same arrays."""
    results = []
    for threads in (1, 3):
        monkeypatch.setattr(frames_module, "default_threads", lambda t=threads: t)
        results.append(run(wide))
    a, b = (r.arrays for r in results)
    assert a.keys() == b.keys()
    for key in a:
        assert np.array_equal(a[key], b[key]), key
    assert results[0].summary["sites"] == results[1].summary["sites"]


def test_blocks_kept_or_made_give_the_same_run(small_toml, monkeypatch):
    """A scene small enough keeps its per-frame moments for its replicates; with the budget at 0
    every block is made when the chip model reaches it: the run is the same bit for bit, and a
    replicate on a prepared scene equals run() (the study contract)."""
    s = load_scenario(small_toml)
    kept = run(s)
    scene = prepare(s)
    assert run_prepared(s, scene).arrays["site_signal_e"].tobytes() == \
        kept.arrays["site_signal_e"].tobytes()
    monkeypatch.setattr(budget, "MOMENTS_KEPT_BYTES", 0)
    made = run(s)
    for key in kept.arrays:
        assert np.array_equal(kept.arrays[key], made.arrays[key]), key
    assert kept.summary["sites"] == made.summary["sites"]


def _peak_bytes(s) -> int:
    tracemalloc.start()
    try:
        run(s)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


#: Bytes a run may hold per frame: the sites' light (n_sites × 8 B), the DSP outputs at the
#: site pixels, the event trace (≈ 10 events per frame) and the memory's occupancy history. The
#: pixels' light, moments and codes for every frame (what the run held before) would be
#: 2,304 pixels × ≥ 3 arrays × 8 B ≈ 55 kB per frame here.
PER_FRAME_BOUND_B = 6_000


def test_peak_memory_does_not_grow_with_frames_beyond_the_trace(wide, monkeypatch):
    """tracemalloc's peak of a 300-frame and a 900-frame run of the 48 × 48 chip, every block
    made on demand (the scene-kept moments are bounded by MOMENTS_KEPT_BYTES, not by frames):
    the 600 extra frames cost at most PER_FRAME_BOUND_B each (measured: ≈ 0.9 kB each; peak
    ≈ 32 MB either way)."""
    monkeypatch.setattr(budget, "MOMENTS_KEPT_BYTES", 0)
    run(wide)  # one-time allocations (kernels loaded, caches filled) outside the measurement
    short = _peak_bytes(replace(wide, run=replace(wide.run, duration_s=300.0)))
    long = _peak_bytes(replace(wide, run=replace(wide.run, duration_s=900.0)))
    assert long - short < 600 * PER_FRAME_BOUND_B, (short, long)


@pytest.mark.parametrize("level", ["binned", "expected"])
def test_saved_frames_are_what_the_dsp_saw(wide, tmp_path, level):
    """Every frame streamed to a .npy file, read back: at the binned level the codes the DSP
    read (the pipeline keeps them with keep_codes), frame for frame; at the expected level the
    expected CMS differences. write_outputs copies them into the run's dataset (``frames`` in
    run.nc) and removes the streamed file."""
    s = replace(wide, run=replace(wide.run, duration_s=60.0))
    path = tmp_path / "frames.npy"
    out = simulate(s, prepare(s), level, stage_rng(s.scenario.seed, "pixel"), Recorder(),
                   keep_codes=True, frames_path=path)
    saved = np.load(path)
    if level == "binned":
        assert saved.dtype == np.uint16 and saved.shape == (60, 4, s.chip.n_pixels)
        seen = np.array(out.dsp.kept)
        assert np.array_equal(saved[:len(seen)].astype(np.int64), seen)
    else:
        assert saved.shape == (60, s.chip.n_pixels)
        scene = prepare(s)
        whole = scene.pixel_frames(s.chip.timing.t_int_s, s.chip.adc.gain_error)
        assert np.array_equal(saved, whole.cds_mean_lsb)
    result = run(replace(wide, run=replace(wide.run, save_frames=True, fidelity=replace(
        wide.run.fidelity, photons=level))))
    streamed = result.frames_path
    frames = np.load(streamed)
    folder = write_outputs(result, tmp_path / "out")
    with open_run(folder) as ds:
        assert np.array_equal(ds["frames"].values.reshape(frames.shape), frames)
    assert not streamed.exists()


def test_sparse_coupling_is_the_dense_one_within_its_tolerance(small_toml, monkeypatch):
    """Above DENSE_COUPLING_ENTRIES (or DENSE_COUPLING_PIXELS) the coupling is one site's kernel
    shifted to every site:
    equal to the dense psf matrix wherever kept, and what it leaves out is below
    COUPLING_DROP_RTOL of the site's own pixel (edges and corners included)."""
    sites = [[r, c] for r in range(0, 24, 3) for c in range(0, 24, 5)]
    s = load_scenario(small_toml, ["chip.rows=24", "chip.cols=24",
                                   f"sites.at_pixels={sites!r}".replace("'", "")])
    dense = stages.coupling(s)
    monkeypatch.setattr(limits, "DENSE_COUPLING_ENTRIES", 0)
    sp = stages.coupling(s)
    monkeypatch.setattr(limits, "DENSE_COUPLING_ENTRIES", 1 << 24)
    monkeypatch.setattr(limits, "DENSE_COUPLING_PIXELS", 0)
    assert (stages.coupling(s) != sp).nnz == 0
    assert sp.shape == dense.shape and sp.nnz < dense.size
    got = sp.toarray()
    kept = got > 0
    np.testing.assert_allclose(got[kept], dense[kept], rtol=1e-9, atol=0)
    own = dense[stages.site_pixel_indices(s), np.arange(len(sites))]
    assert np.all(dense[~kept] <= limits.COUPLING_DROP_RTOL * own[np.nonzero(~kept)[1]] * 1.0001)


def test_an_array_of_sites_gets_its_figures_map_and_histogram(small_toml, tmp_path):
    """Every pixel a site (24 sites): summary['array'] counts the sites called right and gives
    the SNR percentiles, consistent with the per-site rows; the report maps and histograms them."""
    result = run(small_toml, ["sites.at_pixels=\"all\""])
    arr, sites = result.summary["array"], result.summary["sites"]
    right = [c == result.summary["true_sequence"] for c in result.summary["called_sequences"]]
    assert arr["n_sites"] == len(sites) == 24 and arr["sites_called_right"] == sum(right)
    assert arr["fraction_called_right"] == pytest.approx(sum(right) / 24)
    assert arr["snr_power_percentiles"]["p50"] == pytest.approx(
        np.median([site["snr_power"] for site in sites]))
    folder = write_outputs(result, tmp_path / "out")
    assert (folder / "site_map.png").exists() and (folder / "snr_histogram.png").exists()
    assert "sites called right" in (folder / "report.md").read_text()
