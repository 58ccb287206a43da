"""Equivalence tests of the "model only what the scene needs" shortcuts
(:mod:`chiptwin.twin.shortcuts`).

Carried dark pixels: on a 32 × 32 chip with 64 sites at a 4-pixel pitch (the geometry of
``pyro_array_256``, smaller), the run that draws only the kept, lit and clip-prone pixels must give

* exactly the full path's moments (mean and variance of every kept output to 1e-12, the dark
  reference's variance at every pixel), chip trace, memory history and full-well count;
* the full path's law at the sites (other draws: Monte Carlo over seeds, one block per seed so
  the samples are independent; mean of the standardised deviation within 4 standard errors of 0,
  its variance within 10 % of 1 — the standard error of a variance of 2,560 samples is 2.8 % —,
  and KS p > 1e-3 between the two paths);
* at the carried pixels of the peak frame, the expected level's mean and variance (same bounds);
* the full path bit for bit wherever it does not apply.

Trace without frame steps (``Recorder(frame_steps=False)``): on nine bundled scenarios the same
chip outputs and memory history, and exactly the full trace's other events, in order.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from chiptwin.config import load_scenario
from chiptwin.twin import shortcuts, stages
from chiptwin.twin.runner import Recorder, prepare, simulate, stage_rng

GRID = [f"[{r}, {c}]" for r in range(1, 32, 4) for c in range(1, 32, 4)]
#: The small scenario's 8 key flows of 4 s (36 frames, 8 output blocks) instead of 14 of 20 s
#: (284 frames): every claim below holds per frame or per block, and 80 runs of the law test
#: cost 8 times less.
WIDE = ["chip.rows=32", "chip.cols=32", "chip.memory.capacity_bits=2000000", "assay.dna_fmol=0.01",
        f"sites.at_pixels=[{', '.join(GRID)}]", "assay.n_flows=8", "assay.flow_period_s=4.0",
        "run.duration_s=36.0"]
SEEDS = range(40)
#: The block of the law test: the dimmest flow's (≈ 540 e⁻ at a site against ≈ 229 e⁻ of read
#: and dark noise), read-noise dominated as the near-dark block of the 284-frame scene was.
BLOCK = 4


@pytest.fixture(scope="module")
def wide(tmp_path_factory):
    from tests.conftest import SMALL

    path = tmp_path_factory.mktemp("wide") / "small.toml"
    path.write_text(SMALL)
    s = load_scenario(path, WIDE)
    return s, prepare(s), stages.site_pixel_indices(s)


def _run(wide, seed: int, carry: bool, level: str = "binned", **kw):
    s, scene, idx = wide
    rec = Recorder()
    out = simulate(s, scene, level, stage_rng(seed, "pixel"), rec, sites=kw.pop("sites", idx),
                   carry_dark=carry, **kw)
    return out, rec


def test_split_carries_only_dark_clip_safe_pixels_and_keeps_the_sites(wide):
    """Slow obvious reference: the largest light of each pixel over every frame, frame by frame."""
    s, scene, idx = wide
    split = shortcuts.split_dark(s, scene, np.unique(idx))
    assert split is not None and len(split.drawn) < scene.n_pixels // 2
    assert np.isin(idx, split.drawn).all()
    assert np.array_equal(np.sort(np.concatenate([split.drawn, split.carried])),
                          np.arange(scene.n_pixels))
    sen = scene.sensor
    light = np.max([sen.qe * sen.gain_map * scene.photons_block(k, k + 1)[0]
                    for k in range(scene.sch.n_frames)], axis=0)
    dark = sen.dark_e_per_s * s.chip.timing.t_int_s
    noise = np.sqrt(dark + 2 * sen.read_noise_e**2 / sen.cms_samples)  # true CDS
    assert (light[split.carried] <= shortcuts.DARK_LIGHT_NOISE_FRACTION * noise[
        split.carried]).all()


def test_clip_safe_refuses_a_pedestal_at_the_adc_floor(wide):
    s, scene, _ = wide
    lam = np.array([10.0, 1e3])
    assert shortcuts.clip_safe(lam, scene.sensor, s.chip.adc).all()
    low = type(scene.sensor)(**{**scene.sensor.__dict__, "pedestal_V": s.chip.adc.v_min_V})
    assert not shortcuts.clip_safe(lam, low, s.chip.adc).any()
    full = type(scene.sensor)(**{**scene.sensor.__dict__, "full_well_e": 1e3})
    assert list(shortcuts.clip_safe(lam, full, s.chip.adc)) == [True, False]


def test_carried_run_has_the_full_paths_moments_trace_and_flags(wide):
    full, rec_full = _run(wide, 0, False)
    cut, rec_cut = _run(wide, 0, True)
    assert np.array_equal(full.pixels, cut.pixels)
    np.testing.assert_allclose(cut.mean_e, full.mean_e, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(cut.var_e2, full.var_e2, rtol=1e-12)
    np.testing.assert_allclose(cut.dark_var_e2, full.dark_var_e2, rtol=1e-12)
    np.testing.assert_array_equal(cut.block_t_s, full.block_t_s)
    assert rec_cut.events == rec_full.events
    assert cut.chip.occupancy == full.chip.occupancy and cut.chip.dropped == full.chip.dropped
    assert (cut.full_well_pixel_frames, cut.adc_clipped_samples) == (
        full.full_well_pixel_frames, full.adc_clipped_samples)
    assert cut.peak_frame_e.shape == full.peak_frame_e.shape
    assert not np.array_equal(cut.value_e, full.value_e)  # other draws: a statistical equality
    assert full.carried_pixels == 0 and cut.carried_pixels > 0


def test_converters_as_built_are_carried_with_their_pixels(tmp_path):
    """A chip whose converters differ per pixel (offset and gain mismatch, DNL, comparator noise)
    keeps each drawn pixel's converter: the moments are the full path's to 1e-12. (The sub-scene
    once kept the whole array's converters: a reshape error on every such run.)"""
    from tests.conftest import SMALL

    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    s = load_scenario(path, [*WIDE, "chip.adc.offset_sigma_lsb=3.0", "chip.adc.gain_sigma=0.01",
                             "chip.adc.dnl_rms_lsb=0.2", "chip.adc.comparator_noise_lsb=0.5"])
    built = (s, prepare(s), stages.site_pixel_indices(s))
    assert not built[1].sensor.converter.ideal
    full, _ = _run(built, 0, False)
    cut, _ = _run(built, 0, True)
    assert cut.carried_pixels > 0 and np.array_equal(full.pixels, cut.pixels)
    np.testing.assert_allclose(cut.mean_e, full.mean_e, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(cut.var_e2, full.var_e2, rtol=1e-12)
    kept = full.pixels
    np.testing.assert_allclose(cut.dark_var_e2[kept], full.dark_var_e2[kept], rtol=1e-12)
    # the converters' exact moments are computed where the run reads them: the kept pixels
    assert np.isfinite(full.dark_var_e2[kept]).all()
    assert np.isnan(np.delete(full.dark_var_e2, kept)).all()


def test_converter_moments_only_where_read_change_nothing_read(tmp_path):
    """With converters as built, a run that keeps the sites' outputs computes the converters'
    exact moments at those pixels only (:func:`chiptwin.twin.runner.moments_read_at`): the
    sites' values are the every-pixel run's bit for bit, their moments to 1e-12."""
    from tests.conftest import SMALL

    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    s = load_scenario(path, [*WIDE, "chip.adc.offset_sigma_lsb=3.0", "chip.adc.gain_sigma=0.01",
                             "chip.adc.inl_max_lsb=1.0", "chip.adc.comparator_noise_lsb=0.5"])
    built = (s, prepare(s), stages.site_pixel_indices(s))
    at_sites, _ = _run(built, 3, False)
    everywhere, _ = _run(built, 3, False, sites=None)
    cols = at_sites.pixels
    assert len(cols) < built[1].n_pixels
    np.testing.assert_array_equal(at_sites.value_e, everywhere.value_e[:, cols])
    np.testing.assert_allclose(at_sites.mean_e, everywhere.mean_e[:, cols], rtol=1e-12)
    np.testing.assert_allclose(at_sites.var_e2, everywhere.var_e2[:, cols], rtol=1e-12)
    np.testing.assert_allclose(at_sites.dark_var_e2[cols], everywhere.dark_var_e2[cols],
                               rtol=1e-12)
    assert np.isfinite(everywhere.dark_var_e2).all()


def test_fixed_dsp_overflow_counts_are_the_full_paths(wide):
    """The bit-accurate DSP: its overflow counts (the drawn pixels' on the shortcut) and the
    moments are the full path's."""
    from dataclasses import replace

    s, scene, idx = wide
    fixed = replace(s, chip=replace(s.chip, dsp=replace(s.chip.dsp, mode="fixed")))
    full, cut = (simulate(fixed, scene, "binned", stage_rng(1, "pixel"), Recorder(), sites=idx,
                          carry_dark=carry) for carry in (False, True))
    assert full.dsp.level == cut.dsp.level == "fixed"
    assert cut.dsp.overflow == full.dsp.overflow
    np.testing.assert_allclose(cut.var_e2, full.var_e2, rtol=1e-12)


def test_sites_have_the_full_paths_law(wide):
    s, _, idx = wide
    z = {}
    for carry in (False, True):
        devs = []
        for seed in SEEDS:
            out, _ = _run(wide, seed, carry)
            cols = out.columns(idx)
            sd = np.sqrt(out.var_e2[BLOCK, cols] + out.dark_var_e2[idx])
            devs.append((out.value_e[BLOCK, cols] - out.mean_e[BLOCK, cols]) / sd)
        z[carry] = np.concatenate(devs)
        d = z[carry]
        assert abs(d.mean()) < 4 * d.std() / np.sqrt(d.size)
        assert d.var() == pytest.approx(1.0, rel=0.10)
    assert stats.ks_2samp(z[False], z[True]).pvalue > 1e-3


def test_carried_pixels_of_the_peak_frame_have_the_expected_law(wide):
    s, scene, idx = wide
    split = shortcuts.split_dark(s, scene, np.unique(idx))
    expected, _ = _run(wide, 0, False, level="expected", sites=None)
    c = split.carried
    devs = []
    for seed in range(4):
        out, _ = _run(wide, seed, True)
        b = out.peak_block
        sd = np.sqrt(expected.var_e2[b, c] + expected.dark_var_e2[c])
        devs.append((out.peak_frame_e[c] - expected.mean_e[b, c]) / sd)
    d = np.concatenate(devs)
    assert abs(d.mean()) < 4 * d.std() / np.sqrt(d.size)
    assert d.var() == pytest.approx(1.0, rel=0.10)


@pytest.mark.parametrize("case", ["no_sites", "report_error", "expected", "off"])
def test_where_it_does_not_apply_the_run_is_the_full_path_bit_for_bit(wide, case):
    from dataclasses import replace

    s, scene, idx = wide
    kw: dict = {}
    carry, level, s2 = True, "binned", s
    if case == "no_sites":
        kw["sites"] = None
    elif case == "report_error":
        s2 = replace(s, chip=replace(s.chip, dsp=replace(s.chip.dsp, report_error=True)))
    elif case == "expected":
        level = "expected"
    else:
        carry = None  # default: off (the scenario has no carry_dark_pixels)
    a = simulate(s2, scene, level, stage_rng(3, "pixel"), Recorder(),
                 sites=kw.get("sites", idx), carry_dark=carry)
    b = simulate(s2, scene, level, stage_rng(3, "pixel"), Recorder(),
                 sites=kw.get("sites", idx), carry_dark=False)
    np.testing.assert_array_equal(a.value_e, b.value_e)
    np.testing.assert_array_equal(a.dark_var_e2, b.dark_var_e2)


# --- Frame steps not recorded (Recorder(frame_steps=False)) -------------------------------------

QUICK = ("pyro_1fmol", "ccd_100fmol", "atp_glow", "atp_dose_response", "luciferase_label",
         "crosstalk_microarray", "ccd_two_wells", "snr10_requirement", "pyro_paper_yield",
         "slow_dsp_40", "slow_dsp_20")
#: The small scenario with a DSP too slow for its frames (clock 40 or 20 Hz) and a memory of a
#: block and a half: most frames are dropped, writes and frees meet at every tick.
SLOW = {"slow_dsp_40": ["chip.memory.capacity_bits=6528", "chip.dsp.clock_hz=40"],
        "slow_dsp_20": ["chip.memory.capacity_bits=9600", "chip.dsp.clock_hz=20"]}


def _quick(name: str, tmp_path):
    """A bundled scenario (at the expected level where its DSP allows) or a :data:`SLOW` one."""
    from tests.conftest import SCENARIOS, SMALL

    if name in SLOW:
        path = tmp_path / "small.toml"
        path.write_text(SMALL)
        return load_scenario(path, [*SLOW[name], "run.fidelity.photons=expected"])
    fast = [] if name in ("crosstalk_microarray", "ccd_two_wells") else [
        "run.fidelity.photons=expected"]  # those two run a fixed DSP: codes needed
    return load_scenario(SCENARIOS / f"{name}.toml", fast)


@pytest.mark.parametrize("name", QUICK)
def test_compact_trace_is_the_full_trace_without_the_frame_steps(name, tmp_path):
    """Same chip outputs, memory history, drops, DSP time and end, and the same events in the same
    order at the same ticks once the full trace's frame steps are taken out (at the expected level
    where the DSP allows: the chip model does not depend on the photon level)."""
    from chiptwin.chip.trace import FRAME_STEPS

    s = _quick(name, tmp_path)
    scene = prepare(s)
    runs = []
    for steps in (True, False):
        rec = Recorder(frame_steps=steps)
        out = simulate(s, scene, s.run.fidelity.photons, stage_rng(0, "pixel"), rec)
        runs.append((out, rec))
    (full, rec_full), (cut, rec_cut) = runs
    kept = [e for e in rec_full.events if (e[1], e[2]) not in FRAME_STEPS]
    assert rec_cut.events == kept and len(kept) < len(rec_full.events)
    a, b = full.chip, cut.chip
    assert (a.occupancy, a.dropped, a.dsp_busy_ns, a.end_ns, a.last_write_ns,
            a.unprocessed_frames) == (b.occupancy, b.dropped, b.dsp_busy_ns, b.end_ns,
                                      b.last_write_ns, b.unprocessed_frames)
    assert [ks for ks, _ in a.outputs] == [ks for ks, _ in b.outputs]
    np.testing.assert_array_equal(full.value_e, cut.value_e)
    assert not rec_cut.to_arrays()["trace_frame_steps"]


def _dsp_one_get_per_frame(env, sch, dsp, memory, rec, run):
    """The DSP process as it was, waking once per frame (one ``store.get()`` each): the slow
    obvious reference of the block get."""
    size, first = sch.dark_frames, True
    while True:
        items = []
        for _ in range(size):
            items.append((yield memory.store.get()))
        rec.record(env.now, "dsp", "job_start", len(items))
        frames = [payload for _, payload in items]
        out = None if first else dsp.block(frames)
        spread = -(-sch.dsp_ns_per_output // sch.block_frames)
        duration = size * (sch.dsp_ns_per_frame - spread)
        if out is not None:
            duration += sch.dsp_ns_per_output
        yield env.timeout(duration)
        run.dsp_busy_ns += duration
        if first:
            dsp.dark(frames)
        elif out is not None:
            run.outputs.append(([k for k, _ in items], out))
        rec.record(env.now, "dsp", "job_end", len(items))
        memory.free(size)
        size, first = sch.block_frames, False


@pytest.mark.parametrize("name", QUICK)
def test_block_get_is_one_get_per_frame(name, monkeypatch, tmp_path):
    """The DSP's one wake-up per job (``_FrameStore.get_block``) against one per frame: the same
    trace, event for event, and the same chip outputs."""
    from chiptwin.chip import des

    s = _quick(name, tmp_path)
    scene = prepare(s)
    runs = []
    for reference in (True, False):
        with monkeypatch.context() as m:
            if reference:
                m.setattr(des, "_dsp", _dsp_one_get_per_frame)
            rec = Recorder()
            out = simulate(s, scene, s.run.fidelity.photons, stage_rng(0, "pixel"), rec)
        runs.append((out, rec))
    (a, rec_a), (b, rec_b) = runs
    assert rec_a.events == rec_b.events
    assert (a.chip.occupancy, a.chip.dropped, a.chip.dsp_busy_ns, a.chip.end_ns,
            a.chip.unprocessed_frames) == (b.chip.occupancy, b.chip.dropped, b.chip.dsp_busy_ns,
                                           b.chip.end_ns, b.chip.unprocessed_frames)
    assert [ks for ks, _ in a.chip.outputs] == [ks for ks, _ in b.chip.outputs]
    np.testing.assert_array_equal(a.value_e, b.value_e)


def test_the_scenario_key_turns_it_on_and_the_summary_says_so():
    """``[run] carry_dark_pixels = true``: the summary counts the carried pixels, or says the
    shortcut does not apply (the events level) and carries none."""
    from chiptwin.fidelity import run
    from tests.conftest import REDUCED, SCENARIOS

    sets = [*REDUCED["pyro_1fmol"], "assay.flow_period_s=4.0", "run.duration_s=52.0",
            "run.carry_dark_pixels=true"]  # 8 flows of 4 s: the events run in 52 frames
    on = run(load_scenario(SCENARIOS / "pyro_1fmol.toml", sets)).summary["shortcuts"]
    assert on["carry_dark_pixels"]["applies"] and on["carry_dark_pixels"]["carried_pixels"] > 0
    events = run(load_scenario(SCENARIOS / "pyro_1fmol.toml",
                               [*sets, 'run.fidelity.photons="events"'])).summary["shortcuts"]
    assert not events["carry_dark_pixels"]["applies"]
    assert events["carry_dark_pixels"]["carried_pixels"] == 0


def test_sparse_light_made_in_chunks_is_the_blockwise_product_bit_for_bit(wide, monkeypatch):
    """A sparse coupling's light is made several blocks at a time (``PHOTON_CHUNK_BYTES``): every
    block, in order and out of order, is the one-block product to the last bit."""
    from dataclasses import replace

    from scipy import sparse

    import chiptwin.twin.scene as scene_module

    _, scene, _ = wide
    monkeypatch.setattr(scene_module, "frames_per_block", lambda n_pixels, samples: 2)
    monkeypatch.setattr(scene_module, "PHOTON_CHUNK_BYTES", 8 * scene.n_pixels * 6)  # 3 blocks
    chunked = replace(scene, coupling=sparse.csr_matrix(scene.coupling))
    n = chunked.site_photons.shape[1]
    assert n > 12 and chunked.block_frames == 2
    for start in [*range(0, n, 2), 4, 0, 10]:
        stop = min(start + 2, n)
        direct = (chunked.coupling @ chunked.site_photons[:, start:stop]).T
        np.testing.assert_array_equal(chunked.photons_block(start, stop), direct)
    assert chunked._memo["photons_chunk"][1].shape == (6, scene.n_pixels)
