"""End-to-end runs: reproducibility, the CLI, outputs, and the expected level vs binned runs."""

from __future__ import annotations

import json
import tomllib
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from chiptwin import pixel
from chiptwin.cli import main
from chiptwin.config import ScenarioError, load_scenario
from chiptwin.fidelity import run
from chiptwin.report import open_run
from chiptwin.twin.runner import chip_sensor, prepare, run_prepared
from tests.conftest import NO_TOP, PAPER_CHIP, REDUCED, SCENARIOS

TIMING_KEYS = {"wall_time_s", "stage_time_s"}


def _strip(summary: dict) -> dict:
    """The summary without its clocks, nor ``physical_law``: ``run`` adds that remark beside a
    paper-convention scene (two more runs), ``run_prepared`` (a study's row) does not."""
    return {k: v for k, v in summary.items() if k not in TIMING_KEYS and k != "physical_law"}


def test_small_pyrosequencing_run_calls_the_template(small_toml):
    result = run(small_toml)
    s = result.summary
    assert s["called_sequence"] == s["true_sequence"] == "TCAGGTTCCA"
    assert all(site["detected"] for site in s["sites"])
    assert [f["called_n"] for f in s["flows"]] == [f["true_n"] for f in s["flows"]]
    assert s["fidelity"] == {"kinetics": "closed_form", "photons": "binned", "optics": "psf",
                             "shot": "poisson", "dsp": "float", "adc": "ideal"}


def test_same_seed_same_summary_other_seed_differs(small_toml):
    a, b = run(small_toml).summary, run(small_toml).summary
    assert json.dumps(_strip(a)) == json.dumps(_strip(b))
    c = run(small_toml, seed=8).summary
    assert c["sites"][0]["signal_e"] != a["sites"][0]["signal_e"]


def test_cli_run_writes_every_output(small_toml, tmp_path, capsys):
    out = tmp_path / "result"
    assert main(["run", str(small_toml), "--out", str(out), "--set", "chip.adc.bits=12"]) == 0
    names = {p.name for p in out.iterdir()}
    assert {"summary.json", "run.nc", "report.md", "light_curve.png", "frame.png",
            "pyrogram.png", "memory.png"} <= names
    assert "chip.vcd" not in names and "arrays.npz" not in names  # --vcd asks for the waveform
    summary = json.loads((out / "summary.json").read_text())
    assert summary["chip"]["adc_bits"] == 12 and summary["scenario"] == "small"
    for key in ("scenario", "seed", "chiptwin_version", "fidelity", "wall_time_s", "stage_time_s",
                "sites", "true_sequence", "called_sequence", "flows", "chip"):
        assert key in summary
    with open_run(out) as ds:
        assert ds["trace_t_ns"].size == ds["trace_block"].size > 0
        scenario = tomllib.loads(ds.attrs["scenario_toml"])  # the --set in the scenario
        assert ds.attrs["seed"] == summary["seed"] and scenario["chip"]["adc"]["bits"] == 12
    assert "called sequence" in capsys.readouterr().out
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".result.")]


def test_cli_validate_and_list(small_toml, capsys):
    assert main(["validate", str(small_toml)]) == 0
    assert main(["list"]) == 0
    assert "pyro_1fmol" in capsys.readouterr().out
    assert main(["--version"]) == 0


def test_expected_level_is_the_mean_of_binned_runs(small_toml):
    """The ``expected`` level (no sampling) equals the mean of many ``binned`` runs.

    Tolerance: 5 standard errors of the mean over 40 runs for the flow values, and the spread of
    the binned runs within 35 % of the analytic noise (the sample std of 40 draws has ≈ 11 % rms
    relative error, so 35 % is > 3σ).
    """
    # One chip (its fixed pattern held by chip.fixed_pattern_seed), 40 seeds of temporal noise.
    # 16 dark frames keep the dark reference's noise, common to all flows of a run, from
    # dominating: flows of one run would otherwise not be independent samples.
    common = ["chip.pixel.dark_current_nA_per_cm2=2.0", "chip.fixed_pattern_seed=11",
              "chip.dsp.n_dark_frames=16", "assay.start_s=16", "run.duration_s=296"]
    base = load_scenario(small_toml, common)
    expected = run(load_scenario(small_toml, [*common, "run.fidelity.photons=expected"]))
    exp_flows = np.array([f["signal_e"] for f in expected.summary["flows"]])
    exp_noise = np.array([f["noise_e"] for f in expected.summary["flows"]])
    draws = np.array([[f["signal_e"] for f in run(base, seed=seed).summary["flows"]]
                      for seed in range(40)])
    sem = exp_noise / np.sqrt(len(draws))
    assert np.all(np.abs(draws.mean(axis=0) - exp_flows) < 5 * sem)
    ratio = draws.std(axis=0, ddof=1) / exp_noise
    assert np.all((ratio > 0.65) & (ratio < 1.35)), ratio


def test_one_chip_many_runs(small_toml):
    """A fixed ``chip.fixed_pattern_seed`` keeps the chip (PRNU/DSNU) while the seed varies the
    temporal noise: the expected signals agree exactly, the realised ones differ."""
    a = run(small_toml, ["chip.fixed_pattern_seed=3"], seed=1)
    b = run(small_toml, ["chip.fixed_pattern_seed=3"], seed=2)
    c = run(small_toml, ["chip.fixed_pattern_seed=4"], seed=1)
    peak = [r.summary["sites"][0]["peak_frame_signal_e"] for r in (a, b, c)]
    assert peak[0] == peak[1] != peak[2]
    assert a.summary["sites"][0]["signal_e"] != b.summary["sites"][0]["signal_e"]


@pytest.mark.parametrize("name", ["..", ".", "a/b", "../x", "x y"])
def test_scenario_name_must_be_a_folder_name(small_toml, name):
    with pytest.raises(ScenarioError, match="scenario.name"):
        load_scenario(small_toml, [f'scenario.name="{name}"'])


def test_output_folder_is_never_a_stranger(small_toml, tmp_path, monkeypatch, capsys):
    """A run replaces its output folder whole: the working folder, its parents, a file and a
    folder of someone else's files are refused before the run (exit 2), and nothing changes."""
    keep = tmp_path / "keep"
    keep.mkdir()
    (keep / "notes.txt").write_text("mine")
    monkeypatch.chdir(keep)
    for out in (".", "..", str(keep), str(keep / "notes.txt")):
        assert main(["run", str(small_toml), "--out", out, "--quiet"]) == 2
        assert "--out" in capsys.readouterr().err
    other = tmp_path / "other"
    other.mkdir()
    (other / "data.csv").write_text("1,2")
    assert main(["run", str(small_toml), "--out", str(other), "--quiet"]) == 2
    assert (keep / "notes.txt").read_text() == "mine" and (other / "data.csv").exists()
    assert main(["run", str(small_toml), "--out", str(tmp_path / "fresh"), "--quiet"]) == 0
    assert main(["run", str(small_toml), "--out", str(tmp_path / "fresh"), "--quiet"]) == 0


@pytest.mark.parametrize("sets", [PAPER_CHIP, NO_TOP], ids=["ideal", "as_built"])
def test_noise_model_matches_blank_pixels_of_the_reference_chip(sets):
    """The analytic variance beside every DSP output equals the measured temporal variance of
    the blank pixels of pyro_1fmol (13-bit ADC: read noise 0.13 LSB, so rounding errors of the M
    samples are correlated, the case the M-sample mean's LSB²/12M gets wrong: it was 40 % low).
    69 pixels × 375 outputs: the variance's standard error is 0.9 %; tolerance 3 %. On the ideal
    converter, and as built (0.5 LSB of comparator noise, the 1-LSB bow through the series);
    without the flow cell's lid, whose returned light leaves no pixel dark."""
    from chiptwin.twin.runner import Recorder, prepare, simulate, stage_rng

    s = load_scenario(SCENARIOS / "pyro_1fmol.toml", sets)
    scene = prepare(s)
    out = simulate(s, scene, "binned", stage_rng(s.scenario.seed, "pixel"), Recorder())
    # pixels whose cross-talk stays < 30 photons/frame: its change over time adds < 1 %
    blank = scene.pix_photons.max(axis=1) < 30.0
    values = out.value_e[:, blank]
    measured = np.var(values - values.mean(axis=0), axis=0, ddof=1).mean()
    assert measured == pytest.approx(out.var_e2[:, blank].mean(), rel=0.03)


def _same_result(a, b) -> None:
    """Bit for bit: the summary (timings aside), every array, the event trace."""
    assert json.dumps(_strip(a.summary)) == json.dumps(_strip(b.summary))
    assert a.arrays.keys() == b.arrays.keys()
    for name, arr in a.arrays.items():
        other = b.arrays[name]
        assert arr.dtype == other.dtype and np.array_equal(arr, other, equal_nan=True), name
    assert a.trace.events == b.trace.events


#: The small scenario's 8 key flows of 4 s (36 frames instead of 284): the same path per frame,
#: 16 runs per case.
SHORT_FLOWS = ["assay.n_flows=8", "assay.flow_period_s=4.0", "run.duration_s=36.0"]


@pytest.mark.parametrize("overrides", [
    [], ["chip.dsp.mode=fixed", "chip.dsp.report_error=true"], ["run.fidelity.photons=events"],
    ["run.fidelity.photons=expected"], ["chip.adc.bits=8", "chip.pixel.dark_current_nA_per_cm2=5"],
], ids=["binned", "fixed-dsp", "events", "expected", "8-bit"])
def test_run_prepared_on_one_scene_equals_run_for_each_seed(small_toml, overrides):
    """The contract a study relies on: one scene prepared, then ``run_prepared`` per replicate
    (seeds in any order, one repeated) gives exactly ``run()`` for that seed. With one chip per
    seed (``chip.fixed_pattern_seed = -1``) the replicate's sensor is redrawn, as a study does.
    The scene is the small one in short flows (:data:`SHORT_FLOWS`): bit-for-bit equality
    needs no length."""
    for chip in (["chip.fixed_pattern_seed=5"], ["chip.fixed_pattern_seed=-1"]):
        s = load_scenario(small_toml, [*SHORT_FLOWS, *chip, *overrides])
        scene = prepare(s)
        for seed in (3, 1, 2, 3):
            rep = replace(s, scenario=replace(s.scenario, seed=seed))
            rep_scene = scene if s.chip.fixed_pattern_seed >= 0 else replace(
                scene, sensor=chip_sensor(rep))
            _same_result(run_prepared(rep, rep_scene), run(s, seed=seed))


def test_scene_computes_its_pixel_frames_once(small_toml):
    """Replicates share the scene's expected charge and moments; a scene derived with ``replace``
    (another sensor, other photons) computes its own."""
    s = load_scenario(small_toml)
    scene = prepare(s)
    first = scene.pixel_frames(s.chip.timing.t_int_s, s.chip.adc.gain_error)
    run_prepared(s, scene)
    run_prepared(replace(s, scenario=replace(s.scenario, seed=2)), scene)
    assert scene.pixel_frames(s.chip.timing.t_int_s, s.chip.adc.gain_error) is first
    other = replace(scene, site_photons=scene.site_photons * 2.0)
    assert other.pixel_frames(s.chip.timing.t_int_s, s.chip.adc.gain_error) is not first
    assert not first.mean_e.flags.writeable  # shared by replicates: never changed in place


def test_pixel_frames_are_the_per_frame_functions(small_toml):
    """All frames at once equal :func:`pixel.mean_electrons` and :func:`pixel.expected_frame` on
    one frame at a time, scaled to LSB as the chip model did per frame, bit for bit."""
    s = load_scenario(small_toml, ["chip.adc.gain_error=0.01", "assay.photons_per_incorporation=0"])
    scene = prepare(s)
    got = scene.pixel_frames(s.chip.timing.t_int_s, s.chip.adc.gain_error)
    sensor, t_int, gain = scene.sensor, s.chip.timing.t_int_s, s.chip.adc.gain_error
    dark = sensor.dark_e_per_s * t_int
    args = (sensor.qe, sensor.gain_map, dark, sensor.full_well_e, sensor.ktc_e,
            sensor.read_noise_e, sensor.cms_samples, sensor.true_cds)
    to_lsb = (1.0 + gain) / sensor.e_per_lsb
    read_lsb = sensor.read_noise_e / sensor.e_per_lsb * (1.0 + gain)
    quant_var = 2.0 * pixel.quantization_var_of_mean(sensor.cms_samples, read_lsb)
    full = 0
    for k in range(scene.sch.n_frames):
        photons = scene.pix_photons[:, k]
        lam = pixel.mean_electrons(photons, sensor.qe, sensor.gain_map, dark)
        mean_e, var_e = pixel.expected_frame(photons, *args)
        assert np.array_equal(got.mean_e[k], lam)
        assert np.array_equal(got.cds_mean_lsb[k], mean_e * to_lsb)
        assert np.array_equal(got.cds_var_lsb2[k], var_e * to_lsb**2 + quant_var)
        full += int(np.count_nonzero(lam >= sensor.full_well_e))
    assert got.full_well_pixel_frames == full > 0


@pytest.mark.parametrize("name", sorted(p.stem for p in SCENARIOS.glob("*.toml")))
def test_every_bundled_scenario_writes_its_outputs(name, tmp_path):
    """Each bundled scenario (made small, :data:`tests.conftest.REDUCED`) runs and writes its
    summary, dataset, report and plots: the headline and plot code meet every scene's summary,
    and the dataset names every scene's arrays."""
    from chiptwin.report.outputs import write_outputs

    result = run(load_scenario(SCENARIOS / f"{name}.toml", REDUCED.get(name, [])))
    out = write_outputs(result, tmp_path / "out")
    report = (out / "report.md").read_text()
    assert json.loads((out / "summary.json").read_text())["scenario"] == name
    assert all(f"]({png.name})" in report for png in out.glob("*.png"))
    with open_run(out) as ds:  # every array labelled (chiptwin.report.dataset.VARIABLES)
        unlabelled = [n for n, v in ds.variables.items() if any("_dim" in d for d in v.dims)]
        assert not unlabelled and set(result.arrays) - {"read_quality_offsets"} <= set(
            ds.variables)


# --- The chip model's run in closed form (chiptwin.chip.steady) -------------------------------
# A steady run skips SimPy and hands the DSP whole blocks of jobs (Pipeline.blocks): every output
# must be SimPy's, bit for bit. SimPy is forced by making steady_run() decline.

THREES = ["assay.flow_period_s=21.0", "run.duration_s=298.0"]  # flows of whole 3-frame jobs
STEADY_CASES = [
    [],
    ["chip.dsp.mode=fixed", "chip.dsp.report_error=true"],
    ["chip.dsp.mode=fixed", "chip.dsp.acc_bits=14", "chip.dsp.acc_overflow=WRAP"],
    ["chip.dsp.cms_samples=3", "chip.dsp.average_frames=3", *THREES],
    ["chip.dsp.mode=fixed", "chip.dsp.report_error=true", "chip.dsp.cms_samples=3",
     "chip.dsp.average_frames=3", *THREES],
    ["run.fidelity.photons=expected"],
    ["run.fidelity.photons=events"],
    ["run.save_frames=true"],
]


def _outcome(result) -> tuple:
    arrays = {**result.arrays, **result.trace.to_arrays()}
    return json.dumps(_strip(result.summary), sort_keys=True, default=repr), {
        k: (v.dtype.str, v.shape, np.ascontiguousarray(v).tobytes()) for k, v in arrays.items()}


def _closed_and_simpy(monkeypatch, run_once):
    """``run_once()`` through the closed form (checked to be taken), then through SimPy."""
    import chiptwin.twin.runner as runner

    calls, real = [], runner._steady_chip
    monkeypatch.setattr(runner, "_steady_chip", lambda *a: calls.append(1) or real(*a))
    fast = run_once()
    monkeypatch.setattr(runner, "steady_run", lambda *a: None)
    slow = run_once()
    assert calls == [1]
    return fast, slow


@pytest.mark.parametrize("overrides", STEADY_CASES)
@pytest.mark.parametrize("frame_steps", [True, False])
def test_closed_form_run_is_the_simpy_run(small_toml, monkeypatch, overrides, frame_steps):
    s = load_scenario(small_toml, overrides)
    scene = prepare(s)
    fast, slow = _closed_and_simpy(
        monkeypatch, lambda: run_prepared(s, scene, frame_steps=frame_steps))
    assert _outcome(fast) == _outcome(slow)


@pytest.mark.parametrize("block", [3, 7])
@pytest.mark.parametrize("overrides", [[], ["chip.dsp.mode=fixed", "chip.dsp.report_error=true"],
                                       ["run.fidelity.photons=expected"]])
def test_closed_form_across_blocks_of_frames(small_toml, monkeypatch, block, overrides):
    """Blocks of 3 and 7 frames, jobs and the dark block of 4: jobs span blocks. The chain's
    outputs, the peak frame and the kept codes are SimPy's run's, bit for bit."""
    import chiptwin.limits
    from chiptwin.chip import Recorder
    from chiptwin.twin.runner import simulate, stage_rng

    s = load_scenario(small_toml, overrides)
    level = s.run.fidelity.photons
    monkeypatch.setattr(chiptwin.limits, "BLOCK_SAMPLES", block * 2 * s.chip.dsp.cms_samples
                        * s.chip.n_pixels)
    scene = prepare(s)
    assert scene.block_frames == block
    sites = np.array([7, 16])
    fast, slow = _closed_and_simpy(monkeypatch, lambda: simulate(
        s, scene, level, stage_rng(5, "pixel"), Recorder(frame_steps=False), sites=sites,
        keep_codes=level != "expected"))
    for name in ("block_t_s", "value_e", "mean_e", "var_e2", "dark_var_e2", "peak_frame_e",
                 "pixels"):
        a, b = getattr(fast, name), getattr(slow, name)
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), name
    assert fast.peak_block == slow.peak_block and fast.adc_clipped_samples == \
        slow.adc_clipped_samples
    assert fast.chip.occupancy == slow.chip.occupancy and fast.chip.dropped == slow.chip.dropped
    assert [ks for ks, _ in fast.chip.outputs] == [ks for ks, _ in slow.chip.outputs]
    assert fast.dsp.overflow == slow.dsp.overflow and fast.dsp.error == slow.dsp.error
    if fast.dsp.kept is not None:
        assert np.stack(fast.dsp.kept).tobytes() == np.stack(slow.dsp.kept).tobytes()


def test_closed_form_study_row_of_pyro_1fmol(monkeypatch):
    """The study row of the issue (reduced): the closed form and SimPy give the same result."""
    s = load_scenario(SCENARIOS / "pyro_1fmol.toml", REDUCED["pyro_1fmol"])
    scene = prepare(s)
    fast, slow = _closed_and_simpy(monkeypatch, lambda: run_prepared(s, scene,
                                                                     frame_steps=False))
    assert _outcome(fast) == _outcome(slow)


@settings(max_examples=80, deadline=None)
@given(pixels=st.integers(1, 40), n=st.integers(1, 6), jobs=st.integers(1, 12),
       n_sites=st.integers(1, 20), keep=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_dsp_batch_finds_the_same_peak_and_cut(pixels, n, jobs, n_sites, keep, seed):
    """The chip model's DSP wrapper on a batch of jobs (``blocks``) against job by job
    (``block``): the same outputs at the kept pixels, the same peak output and frame."""
    from chiptwin.dsp.pipeline import Frame, FrameStack, Pipeline
    from chiptwin.twin.runner import _TimedPipeline
    from chiptwin.twin.scene import StageTimer

    rng = np.random.default_rng(seed)
    frames = [Frame(None, rng.normal(0, 1e3, pixels), rng.random(pixels))
              for _ in range(1 + n * jobs)]
    sites = rng.integers(0, pixels, n_sites)  # repeats allowed
    kept = np.unique(rng.integers(0, pixels, 3)) if keep else None
    e = float(rng.uniform(0.1, 300.0))
    one, batch = (_TimedPipeline(Pipeline("float"), StageTimer(), kept, sites, e)
                  for _ in range(2))
    for p in (one, batch):
        p.dark(frames[:1])
    singles = [one.block(frames[1 + j * n:1 + (j + 1) * n]) for j in range(jobs)]
    many = batch.blocks(FrameStack.of(frames[1:]), n)
    for a, b in zip(singles, many, strict=True):
        for name in ("value", "mean", "var"):
            assert getattr(a, name).tobytes() == getattr(b, name).tobytes()
    assert (one.peak_block, one._peak_sum) == (batch.peak_block, batch._peak_sum)
    assert one.peak_frame_e.tobytes() == batch.peak_frame_e.tobytes()
