"""``run(scenario, overrides, seed)``: the one entry point the CLI and the Python API share.

The run goes through :data:`chiptwin.STAGES` in order: the light of every site over every
integration window (kinetics), onto the pixels (optics), through the chip model (pixel, ADC, frame
memory and DSP as SimPy events), to per-site estimates (detection). Each stage draws from its own
named random stream (:func:`stage_rng`), so adding a stage never shifts another's numbers.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from chiptwin import __version__, pixel, stages
from chiptwin.chip import ChipRun, Recorder, Schedule, simulate_chip
from chiptwin.config import Scenario, load_scenario
from chiptwin.config.consistency import check_consistency, scenario_warnings
from chiptwin.detection import SNR_DEFINITION, required_signal_e, window_sums
from chiptwin.dsp.pipeline import Frame, Pipeline, chain_for
from chiptwin.results import detect, light_decay_per_s
from chiptwin.scene import ChainOutput, PixelFrames, Scene, StageTimer, stage_rng


@dataclass
class Result:
    """A finished run: the summary (as in ``summary.json``), the arrays, and the event trace."""

    summary: dict[str, Any]
    arrays: dict[str, np.ndarray]
    trace: Recorder
    scenario: Scenario


def run(
    scenario: Scenario | str | Path,
    overrides: Iterable[str] = (),
    seed: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Result:
    """Run a scenario end to end.

    Parameters
    ----------
    scenario : Scenario, or a path to a TOML file
    overrides : ``"section.key=value"`` strings (only with a path)
    seed : replaces ``scenario.seed``
    progress : ``progress(frames_done, n_frames)``, called once per frame
    """
    t_start = time.perf_counter()
    if isinstance(scenario, Scenario):
        if overrides:
            raise TypeError("overrides apply to scenario files; use dataclasses.replace here")
        s = scenario if seed is None else replace(
            scenario, scenario=replace(scenario.scenario, seed=seed))
    else:
        s = load_scenario(scenario, overrides, seed)
    check_consistency(s)  # a Scenario built or replaced in Python meets the file's rules too
    timer = StageTimer()
    return run_prepared(s, prepare(s, timer), timer, progress, t_start)


def run_prepared(s: Scenario, scene: Scene, timer: StageTimer | None = None,
                 progress: Callable[[int, int], None] | None = None,
                 t_start: float | None = None) -> Result:
    """The chip model and the detection for a scene :func:`prepare` made of ``s``.

    A study prepares a point once and calls this per replicate with ``s`` carrying the
    replicate's seed: the result is bit for bit the one :func:`run` gives for that seed (the
    random draws all happen here, from ``s.scenario.seed``'s named streams).
    """
    t_start = time.perf_counter() if t_start is None else t_start
    timer = timer or StageTimer()
    rec = Recorder()
    out = simulate(s, scene, s.run.fidelity.photons, stage_rng(s.scenario.seed, "pixel"), rec,
                   timer, progress)
    with timer("detection"):
        summary, arrays = detect(s, scene, out)
        if s.assay.kind == "flux":
            idx = stages.site_pixel_indices(s)
            summary["required_flux_photons_per_s_per_um2"] = _required_flux(s, idx)
            summary["required_flux_snr_power"] = s.run.detection_snr_power
    summary.update(
        scenario=s.scenario.name, description=s.scenario.description, seed=s.scenario.seed,
        chiptwin_version=__version__,
        fidelity=fidelity_used(s),
        stage_time_s={k: round(v, 6) for k, v in timer.seconds.items()},
        wall_time_s=round(time.perf_counter() - t_start, 6),
        snr_definition=SNR_DEFINITION,
        warnings=scenario_warnings(s),
    )
    return Result(summary=summary, arrays=arrays, trace=rec, scenario=s)


def fidelity_used(s: Scenario) -> dict[str, str]:
    """The level each stage ran at; ``none`` where the scene bypassed it (light given at the
    sensor plane skips kinetics and optics)."""
    flux = s.assay.kind == "flux"
    return {"kinetics": "none" if flux else s.run.fidelity.kinetics,
            "photons": s.run.fidelity.photons,
            "optics": "none" if flux else s.run.fidelity.optics,
            "dsp": s.dsp_level}


def prepare(s: Scenario, timer: StageTimer | None = None) -> Scene:
    """Kinetics and optics: photons per site and per pixel in every integration window."""
    timer = timer or StageTimer()
    sch = Schedule.from_chip(s.chip, s.run.duration_s)
    with timer("kinetics"):
        source = stages.light_source(s)
        edges = np.array([sch.window_s(k) for k in range(sch.n_frames)]).reshape(-1)
        site_photons = source.photons(edges)[:, ::2]
    with timer("optics"):
        coupling = stages.coupling(s)
        pix_photons = coupling @ site_photons
    return Scene(sch, source, site_photons, coupling, pix_photons, chip_sensor(s))


def chip_sensor(s: Scenario) -> stages.SensorModel:
    """The sensor of this chip: its PRNU/DSNU maps drawn from ``chip.fixed_pattern_seed``, or
    from ``scenario.seed`` when that is -1 (one chip per seed)."""
    chip_seed = s.chip.fixed_pattern_seed if s.chip.fixed_pattern_seed >= 0 else s.scenario.seed
    return stages.sensor_model(s, stage_rng(chip_seed, "fixed_pattern"))


def simulate(s: Scenario, scene: Scene, photons_level: str, rng: np.random.Generator,
             rec: Recorder, timer: StageTimer | None = None, progress=None,
             keep_codes: bool = False) -> ChainOutput:
    """Pixel → ADC → memory → DSP through the chip model, for photons per pixel per frame.

    What no random draw enters, the expected charge and CMS moments of every frame, is computed
    once per scene (:meth:`Scene.pixel_frames`) and shared by its replicates. At the ``binned``
    and ``events`` levels the codes are drawn ahead, a batch of frames at a time and in frame
    order (:class:`_FrameReader`), so the draws are those of reading frame by frame. The fused
    sampling and conversion is booked to the ``pixel`` stage; ``adc`` counts the clipped samples.
    """
    timer = timer or StageTimer()
    with timer("pixel"):
        expected = scene.pixel_frames(s.chip.timing.t_int_s, s.chip.adc.gain_error)
    reader = _FrameReader(s, scene, expected, photons_level, rng, timer)
    pipeline = _TimedPipeline(_dsp_level(s, keep_codes), timer)
    inner = ("pixel", "adc", "dsp")
    inner_before = sum(timer.seconds[k] for k in inner)
    t0 = time.perf_counter()
    chip = simulate_chip(scene.sch, reader, pipeline, rec, progress)
    inner_s = sum(timer.seconds[k] for k in inner) - inner_before
    timer.seconds["memory"] += time.perf_counter() - t0 - inner_s  # the event engine itself
    out = _chain_output(chip, scene.sch, pipeline.inner, scene.sensor.e_per_lsb)
    out.adc_clipped_samples = reader.clipped
    out.full_well_pixel_frames = expected.full_well_pixel_frames
    if reader.events is not None:
        events = reader.events
        out.saturation_s = np.array(events.saturation_s).reshape(-1, len(events.pixels))
    return out


def _dsp_level(s: Scenario, keep_codes: bool) -> Pipeline:
    """The DSP at the scenario's level: float, bit-accurate fixed point, or the RTL."""
    chain = chain_for(s.chip) if s.dsp_level in ("fixed", "rtl") else None
    if s.dsp_level == "rtl":
        from chiptwin.rtl import RtlPipeline

        return RtlPipeline(chain, report_error=s.chip.dsp.report_error, keep_codes=keep_codes)
    return Pipeline(s.dsp_level, chain, report_error=s.chip.dsp.report_error,
                    keep_codes=keep_codes)


#: ADC samples drawn ahead at most, per batch of frames (bounds the codes held to 8 MiB).
_BATCH_SAMPLES = 1 << 20


class _FrameReader:
    """``read_frame(k)`` of the chip model: frame ``k`` as the ADCs deliver it.

    Its moments are rows of the scene's :class:`~chiptwin.scene.PixelFrames`. Its codes (at the
    ``binned`` and ``events`` levels) come from a batch of frames drawn ahead in one call of
    :func:`chiptwin.pixel.binned_codes`: the chip model reads frames in order, each once, so
    drawing ``k … k + batch − 1`` when frame ``k`` is first asked for draws what reading them one
    by one would. At the ``events`` level the site pixels' charge is counted by
    :class:`~chiptwin.stages.EventPixels` (its own stream) and replaces their Poisson draws.
    """

    def __init__(self, s: Scenario, scene: Scene, expected: PixelFrames, photons_level: str,
                 rng: np.random.Generator, timer: StageTimer) -> None:
        self.s, self.scene, self.expected, self.rng, self.timer = s, scene, expected, rng, timer
        self.sampled = photons_level in ("binned", "events")
        self.events = None
        if photons_level == "events":
            self.events = stages.EventPixels(
                scene.source, scene.coupling, stages.site_pixel_indices(s), scene.sensor,
                stage_rng(s.scenario.seed, "events"))
        samples_per_frame = 2 * scene.sensor.cms_samples * scene.sensor.gain_map.size
        self.batch = max(1, _BATCH_SAMPLES // max(samples_per_frame, 1))
        self.codes = np.empty((0, 0, 0), np.int64)  # the batch drawn last
        self.first = 0  # its first frame
        self.clipped = 0  # ADC samples at code 0 or full scale

    def __call__(self, k: int) -> Frame:
        codes = None
        if self.sampled:
            if not self.first <= k < self.first + len(self.codes):
                self._draw(k)
            codes = self.codes[k - self.first]
        return Frame(codes=codes, mean=self.expected.cds_mean_lsb[k],
                     var=self.expected.cds_var_lsb2[k])

    def _draw(self, k: int) -> None:
        """Draw the codes of frames ``k …`` (the next batch) and count the clipped samples."""
        following = self.first + len(self.codes)
        if k != following:
            raise RuntimeError(f"frame {k} read out of order: the next one is {following}")
        stop = min(k + self.batch, self.scene.sch.n_frames)
        sensor, adc = self.scene.sensor, self.s.chip.adc
        with self.timer("pixel"):
            pixels, counted = (), None
            if self.events is not None:
                pixels = self.events.pixels
                counted = np.array([self.events.collect(*self.scene.sch.window_s(j))
                                    for j in range(k, stop)])
            self.codes = pixel.binned_codes(
                self.rng, self.expected.mean_e[k:stop], full_well_e=sensor.full_well_e,
                ktc_e=sensor.ktc_e, read_noise_e=sensor.read_noise_e,
                n_samples=sensor.cms_samples, true_cds=sensor.true_cds,
                conversion_gain_uV_per_e=sensor.conversion_gain_uV_per_e,
                pedestal_V=sensor.pedestal_V, bits=adc.bits, v_min_V=adc.v_min_V,
                v_max_V=adc.v_max_V, offset_lsb=adc.offset_error_lsb, gain_error=adc.gain_error,
                counted_pixels=pixels, counted_e=counted)
            self.first = k
        with self.timer("adc"):
            top = 2**adc.bits - 1
            self.clipped += int(np.count_nonzero((self.codes == 0) | (self.codes == top)))


class _TimedPipeline:
    """Wraps the DSP so its wall time is booked to the ``dsp`` stage."""

    def __init__(self, inner: Pipeline, timer: StageTimer) -> None:
        self.inner, self.timer = inner, timer

    def dark(self, frames):
        with self.timer("dsp"):
            return self.inner.dark(frames)

    def block(self, frames):
        with self.timer("dsp"):
            return self.inner.block(frames)


def _chain_output(chip: ChipRun, sch: Schedule, dsp: Pipeline, e_per_lsb: float) -> ChainOutput:
    n_pix = len(dsp.dark_mean) if dsp.dark_mean is not None else 0
    mids = [np.mean([sum(sch.window_s(k)) / 2 for k in ks]) for ks, _ in chip.outputs]

    def stack(name: str) -> np.ndarray:
        return np.array([getattr(o, name) for _, o in chip.outputs]).reshape(-1, n_pix)

    return ChainOutput(
        chip=chip, block_t_s=np.array(mids), value_e=stack("value") * e_per_lsb,
        mean_e=stack("mean") * e_per_lsb, var_e2=stack("var") * e_per_lsb**2,
        dark_var_e2=(dsp.dark_var if dsp.dark_var is not None else np.zeros(0)) * e_per_lsb**2,
        dsp=dsp,
    )


def _required_flux(s: Scenario, idx: np.ndarray) -> float:
    """Flux at the diode that gives power SNR = ``run.detection_snr_power`` (site 0).

    The chain is linear in the flux below the full well: signal S = a·flux and variance
    var0 + k·S. Both come from the ``expected`` level run at a reference flux of 1 photon/s/µm²
    and in darkness, so the answer does not depend on the scenario's own flux.
    """
    unit = replace(s, assay=replace(s.assay, photons_per_s_per_um2=1.0))
    edges = np.array([s.assay.start_s, s.run.duration_s])
    n = s.chip.dsp.average_frames
    lit = prepare(unit)
    figures = []
    for flux in (1.0, 0.0):
        scene = replace(lit, pix_photons=lit.pix_photons * flux)
        out = simulate(unit, scene, "expected", stage_rng(s.scenario.seed, "required_flux"),
                       Recorder())  # the expected level draws nothing
        sig, var = window_sums(out.block_t_s, out.mean_e, out.var_e2, out.dark_var_e2, n, edges,
                               light_decay_per_s(s))
        figures.append((sig[0, idx[0]], var[0, idx[0]]))
    (a, v1), (_, v0) = figures
    needed = required_signal_e(s.run.detection_snr_power, v0, (v1 - v0) / a)
    return float(needed / a)
